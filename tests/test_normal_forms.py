"""Normal-form coefficients (explorer_core.analyses.continuation.normal_forms) against independent computations:
sympy's exact derivatives and eigenvectors in the invariant formulas, and formulas that do not use them (the
period-2 orbit's size at a flip, the two fixed points' multipliers at a fold, the Taylor coefficients of a planar
map at a Neimark-Sacker point); on this system, the first doubling of Fig. 10 against brute force."""

from __future__ import annotations

import cmath

import numpy as np
import pytest
import sympy as sp

from explorer_core.analyses.continuation import _System
from explorer_core.analyses.continuation.normal_forms import eigenpair, normal_form, resonance
from explorer_core.analyses.continuation.testmaps import DelayedLogistic, Henon
from explorer_core.analyses.orbits import ORBIT_NUMERICS, newton
from explorer_core.scenes import get_scene
from explorer_core.solve.poincare import PoincareMap

X, Y, A = sp.symbols("x y a", real=True)
V = sp.Matrix([X, Y])


def _forms(f: sp.Matrix, at: dict):
    """The Jacobian, B and C of ``f`` at ``at``, exact."""

    def b(u, v):
        return sp.Matrix([sum(sp.diff(f[i], V[j], V[k]) * u[j] * v[k] for j in range(2) for k in range(2))
                          for i in range(2)]).subs(at)  # fmt: skip

    def c(u, v, w):
        r = range(2)
        return sp.Matrix([sum(sp.diff(f[i], V[j], V[k], V[m]) * u[j] * v[k] * w[m] for j in r for k in r for m in r)
                          for i in r]).subs(at)  # fmt: skip

    return f.jacobian(V).subs(at), b, c


def _dot(p: sp.Matrix, v: sp.Matrix):
    return sp.simplify((p.H * v)[0])


def _real_pair(j: sp.Matrix, mu: int):
    """``q`` (unit, largest component positive) and ``p`` (``p . q = 1``) for the real multiplier ``mu``."""
    q = (j - mu * sp.eye(2)).nullspace()[0]
    q = q / sp.sqrt((q.T * q)[0])
    q = q if max(q, key=lambda v: abs(float(v))) > 0 else -q
    p = (j.T - mu * sp.eye(2)).nullspace()[0]
    return q, p / (p.T * q)[0]


def _henon(b):
    return sp.Matrix([1 - A * X**2 + Y, b * X])


def _numeric(cmap, kind: str, x, a: float):
    x = np.array([float(v) for v in x])
    return normal_form(cmap, kind, x, [float(a)], 1, cmap.orbit(x, [float(a)], 1)[1])


def test_the_henon_flip_coefficient_is_the_exact_one_and_the_period_two_orbits_size() -> None:
    b = sp.Rational(3, 10)
    a = 3 * (1 - b) ** 2 / 4
    x0 = (1 - b) / (2 * a)
    j, bf, cf = _forms(_henon(b).subs(A, a), {X: x0, Y: b * x0})
    q, p = _real_pair(j, -1)
    h2 = (sp.eye(2) - j).solve(bf(q, q))
    exact = sp.nsimplify(sp.simplify(_dot(p, cf(q, q, q)) / 6 + _dot(p, bf(q, h2)) / 2))
    # Independent of the formula: w -> -(1 + beta) w + b w^3 has the period-2 orbit w^2 = beta / b, so
    # b = lim 4 beta / |x1 - x2|^2, beta = -1 - mu(a). The Henon 2-cycle: x1 + x2 = (1 - b)/a,
    # x1 x2 = ((1 - b)^2 - a)/a^2, y_i = b x_(other).
    s, prod = (1 - b) / A, ((1 - b) ** 2 - A) / A**2
    xf = (-(1 - b) + sp.sqrt((1 - b) ** 2 + 4 * A)) / (2 * A)
    jf = sp.Matrix([[-2 * A * xf, 1], [b, 0]])
    mu = (jf.trace() - sp.sqrt(jf.trace() ** 2 - 4 * jf.det())) / 2
    assert sp.limit(4 * (-1 - mu) / ((s**2 - 4 * prod) * (1 + b**2)), A, a, "+") == exact
    nf = _numeric(Henon(["a"], b=0.3), "period_doubling", (x0, b * x0), a)
    assert exact == sp.Rational(3087, 22672) and nf.criticality == "supercritical"
    assert abs(nf.coefficient - float(exact)) < 1e-10 and nf.error < 1e-10


def test_the_henon_fold_coefficient_is_the_exact_one_and_the_fixed_points_multipliers() -> None:
    b = sp.Rational(3, 10)
    a = -((1 - b) ** 2) / 4
    x0 = 2 / (1 - b)
    j, bf, _ = _forms(_henon(b).subs(A, a), {X: x0, Y: b * x0})
    q, p = _real_pair(j, 1)
    exact = sp.simplify(_dot(p, bf(q, q)) / 2)
    # Independent: eta -> eta + beta + a eta^2 has fixed points +-eta0 with multipliers 1 +- 2 a eta0, so
    # a = lim (mu_+ - mu_-) / (2 q . (x_+ - x_-)) over the two fixed points as they meet.
    xs = [(-(1 - b) + sg * sp.sqrt((1 - b) ** 2 + 4 * A)) / (2 * A) for sg in (1, -1)]
    mus = []
    for xv in xs:
        jv = sp.Matrix([[-2 * A * xv, 1], [b, 0]])
        mus.append((jv.trace() + sp.sqrt(jv.trace() ** 2 - 4 * jv.det())) / 2)
    dq = (q.T * sp.Matrix([xs[0] - xs[1], b * (xs[0] - xs[1])]))[0]
    assert sp.simplify(sp.limit((mus[0] - mus[1]) / (2 * dq), A, a, "+") - exact) == 0
    nf = _numeric(Henon(["a"], b=0.3), "fold", (x0, b * x0), a)
    assert abs(nf.coefficient - float(exact)) < 1e-10 and nf.error < 1e-10
    assert nf.criticality == "" and float(exact) > 0


def test_the_delayed_logistic_neimark_sacker_coefficient_is_the_exact_one_and_the_taylor_formulas() -> None:
    f = sp.Matrix([2 * X * (1 - Y), X])
    x0 = sp.Matrix([sp.Rational(1, 2), sp.Rational(1, 2)])
    j, bf, cf = _forms(f, {X: x0[0], Y: x0[1]})
    mu = sp.Rational(1, 2) + sp.I * sp.sqrt(3) / 2  # e^{i pi/3}
    q = (j - mu * sp.eye(2)).nullspace()[0]
    q = q / sp.sqrt(sp.simplify((q.H * q)[0]))
    p = (j.T - sp.conjugate(mu) * sp.eye(2)).nullspace()[0]
    p = p / sp.conjugate(_dot(p, q))
    qb = q.conjugate()
    h11 = (sp.eye(2) - j).solve(bf(q, qb))
    h20 = (mu**2 * sp.eye(2) - j).solve(bf(q, q))
    d = sp.conjugate(mu) / 2 * (_dot(p, cf(q, q, qb)) + 2 * _dot(p, bf(q, h11)) + _dot(p, bf(qb, h20)))
    exact = sp.nsimplify(sp.N(sp.re(sp.simplify(d)), 30))
    # Independent: Kuznetsov's a(0) from the Taylor coefficients g_kl of the map in the coordinate z = <p, x - x0>
    # (x = x0 + z q + conj(z q)), no B, C or resolvents.
    z, zb = sp.symbols("z zb")
    xz = x0 + z * q + zb * qb
    g = sp.expand((p.H * (f.subs({X: xz[0], Y: xz[1]}, simultaneous=True) - x0))[0])
    gkl = lambda k, m: sp.diff(g, z, k, zb, m).subs({z: 0, zb: 0})  # noqa: E731
    g20, g11, g02, g21 = gkl(2, 0), gkl(1, 1), gkl(0, 2), gkl(2, 1)
    e = mu
    a0 = (sp.re(sp.conjugate(e) * g21 / 2) - sp.re((1 - 2 * e) * sp.conjugate(e) ** 2 / (2 * (1 - e)) * g20 * g11)
          - sp.Abs(g11) ** 2 / 2 - sp.Abs(g02) ** 2 / 4)  # fmt: skip
    assert abs(complex(sp.N(a0, 30)) - float(exact)) < 1e-25
    assert exact == -1
    nf = _numeric(DelayedLogistic(["a"]), "neimark_sacker", (0.5, 0.5), 2.0)
    assert abs(nf.coefficient - float(exact)) < 1e-9 and nf.error < 1e-9
    assert abs(nf.coefficient - float(exact)) <= 2 * nf.error  # the estimate is not an under-statement
    assert nf.criticality == "supercritical" and nf.resonance is None  # theta = pi/3: 1:6, not strong


@pytest.mark.parametrize(("theta", "expected"), [(2 * np.pi / 3, "1:3"), (np.pi / 2 + 1e-3, "1:4"), (1e-3, "1:1"),
                                                 (np.pi / 3, None), (np.pi / 2 + 0.05, None)])  # fmt: skip
def test_the_resonance_check_names_the_strong_resonances(theta: float, expected: str | None) -> None:
    assert resonance(cmath.exp(1j * theta)) == expected


def test_the_first_doubling_of_fig10_is_supercritical_as_brute_force_shows() -> None:
    # The doubling located by the continuation (tests/test_continuation.py's cascade).
    fig10 = get_scene("fig10").params
    value, x = -0.3753448528065428, np.array([-0.08354067469, -2.07836333934])
    sys = _System(fig10, ["alpha"], ORBIT_NUMERICS, 1)
    _, a, _ = sys.orbit(x, [value], 1)
    nf = normal_form(sys, "period_doubling", x, [value], 1, a)
    assert nf.criticality == "supercritical" and nf.error < 1e-3 * nf.coefficient
    # Brute force just past it (alpha below the doubling: the fixed point is unstable there): iterated from near the
    # fixed point, the trajectory settles on a stable period-2 orbit of the size the normal form predicts,
    # |x1 - x2| = 2 sqrt(beta / b), beta = -1 - mu (up to O(beta)).
    p = fig10.with_(alpha=value - 2e-5)
    conv, _ = newton(p, x[None, :], np.array([1]), numerics=ORBIT_NUMERICS, workers=1)
    _, xf, mono, _ = conv[0]
    mu = np.linalg.eigvals(mono.matrix[0])
    beta = -1.0 - float(mu[np.argmin(np.abs(mu + 1))].real)
    assert 0 < beta < 1e-2
    pmap = PoincareMap.of(p, ORBIT_NUMERICS, workers=1)
    q = eigenpair(a, "period_doubling")[0]
    pts, _ = pmap.advance(pmap.start((xf + 1e-3 * q)[None, :]), 4000)
    x1, x2, x3 = pts[0, -3:]
    assert np.linalg.norm(x3 - x1) < 1e-8  # period 2 ...
    sep = np.linalg.norm(x2 - x1)
    assert abs(sep / (2 * np.sqrt(beta / nf.coefficient)) - 1) < 0.01, (sep, beta)  # ... born at the doubling


def test_an_area_preserving_neimark_sacker_point_has_no_criticality() -> None:
    # Henon at b = -1 has det DP = 1 everywhere: Re d = 0 identically (an invariant area), rounding only.
    a = 1.0
    x = Henon.fixed_point(a, -1.0)
    nf = _numeric(Henon(["a"], b=-1.0), "neimark_sacker", x, a)
    assert abs(nf.coefficient) < 1e-12 and nf.criticality == ""
