"""The reduced equations against an independent symbolic derivation (sympy)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from explorer_core.system.model import Model, build_tables, tensor_tables
from explorer_core.system.params import ParameterError, Params, inertia_entries


def _random_spd(rng: np.random.Generator) -> tuple[float, ...]:
    a = rng.normal(size=(3, 3))
    m = a @ a.T + 0.5 * np.eye(3)
    return inertia_entries(m)


def _sympy_field(params: Params):
    """Q, R, lambda, T and T' derived from scratch: I w' = (I w) x w + lambda a."""
    q, r, t = sp.symbols("q r t", real=True)
    i11, i22, i33, i12, i13, i23 = (sp.nsimplify(v, rational=True) for v in params.inertia)
    inertia = sp.Matrix([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]])
    g0, g1, g2, w, alpha = (
        sp.nsimplify(v, rational=True) for v in (params.g0, params.g1, params.g2, params.omega, params.alpha)
    )
    g = g0 + g1 * sp.cos(w * t) + g2 * sp.sin(w * t)
    p = alpha + g * q
    om = sp.Matrix([p, q, r])
    a = sp.Matrix([1, -g, 0])
    lam = sp.Symbol("lam")
    wdot = inertia.inv() * ((inertia * om).cross(om) + lam * a)
    # d/dt (p - g q) = 0 with p, q evolving by wdot: wdot[0] - g' q - g wdot[1] = 0.
    cond = wdot[0] - sp.diff(g, t) * q - g * wdot[1]
    lam_sol = sp.solve(cond, lam)[0]
    wdot = wdot.subs(lam, lam_sol)
    energy = (om.T * inertia * om)[0] / 2
    return (q, r, t), wdot[1], wdot[2], lam_sol, energy, alpha * lam_sol, wdot[0]


@pytest.mark.parametrize("seed", range(6))
def test_field_matches_symbolic_derivation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    params = Params(
        inertia=_random_spd(rng),
        alpha=float(rng.normal()),
        g0=float(rng.normal()),
        g1=float(rng.normal()),
        g2=float(rng.normal()),
        omega=float(rng.uniform(0.3, 3.0)),
    )
    model = Model(params)
    (q, r, t), qe, re_, lam, energy, tprime, _pdot = _sympy_field(params)
    f = sp.lambdify((q, r, t), [qe, re_, lam, energy, tprime], "math")
    for _ in range(8):
        qv, rv, tv = rng.normal(scale=3.0, size=3)
        qs, rs, ls, es, ts = f(qv, rv, tv)
        Q, R = model.field(qv, rv, tv)
        scale = 1.0 + abs(qv) + abs(rv)
        assert Q == pytest.approx(qs, rel=1e-9, abs=1e-9 * scale**2)
        assert R == pytest.approx(rs, rel=1e-9, abs=1e-9 * scale**2)
        assert model.multiplier(qv, rv, tv) == pytest.approx(ls, rel=1e-9, abs=1e-9 * scale**2)
        assert model.energy(qv, rv, tv) == pytest.approx(es, rel=1e-12)
        assert model.tprime(qv, rv, tv) == pytest.approx(ts, rel=1e-9, abs=1e-9 * scale**2)


def test_jacobian_matches_symbolic_derivative() -> None:
    rng = np.random.default_rng(7)
    params = Params(inertia=_random_spd(rng), alpha=-0.3, g0=0.2, g1=0.7, g2=-0.4, omega=1.3)
    model = Model(params)
    (q, r, t), qe, re_, *_ = _sympy_field(params)
    jac = sp.lambdify((q, r, t), sp.Matrix([qe, re_]).jacobian([q, r]).tolist(), "math")
    for _ in range(5):
        qv, rv, tv = rng.normal(scale=2.0, size=3)
        np.testing.assert_allclose(
            model.jacobian(qv, rv, tv), np.array(jac(qv, rv, tv), dtype=float), rtol=1e-9, atol=1e-9
        )


def test_field_is_quadratic_in_q_r() -> None:
    """Q and R are quadratic polynomials in (q, r): third differences vanish."""
    rng = np.random.default_rng(3)
    params = Params(inertia=_random_spd(rng), alpha=0.4, g2=0.5)
    (q, r, t), qe, re_, *_ = _sympy_field(params)
    for expr in (qe, re_):
        poly = sp.Poly(sp.simplify(expr.subs(t, sp.Rational(7, 10))), q, r)
        assert poly.total_degree() <= 2


@pytest.mark.parametrize("diag", [(1.0, 2.0, 4.0), (4.0, 2.0, 1.0), (1.0, 4.0, 2.0), (4.0, 1.0, 2.0)])
def test_diagonal_case_matches_paper_formula(diag: tuple[float, float, float]) -> None:
    a, b, c = diag
    alpha = 0.1
    model = Model(Params(inertia=(a, b, c, 0, 0, 0), alpha=alpha))
    rng = np.random.default_rng(1)
    for qv, rv, tv in rng.normal(scale=2.0, size=(10, 3)):
        g, gp = math.cos(tv), -math.sin(tv)
        q_paper = -(alpha * (a - c) * rv + g * (a - b) * qv * rv + a * g * gp * qv) / (g * g * a + b)
        r_paper = (a - b) * (g * qv + alpha) * qv / c
        Q, R = model.field(qv, rv, tv)
        assert Q == pytest.approx(q_paper, rel=1e-12, abs=1e-13)
        assert R == pytest.approx(r_paper, rel=1e-12, abs=1e-13)


def test_energy_is_conserved_at_alpha_zero() -> None:
    model = Model(Params(inertia=(1, 2, 3, 0.1, 0.2, 0.3), alpha=0.0, g2=0.3))
    assert np.allclose(model.tprime(np.linspace(-3, 3, 7), np.linspace(-2, 5, 7), 0.8), 0.0, atol=1e-14)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"inertia": (1, 2, 4, 3, 0, 0)}, "not positive definite"),
        ({"inertia": (1, 2, 4, 0, 0, float("nan"))}, "I23"),
        ({"inertia": (1, 2, 4, 0, 0)}, "six numbers"),
        ({"inertia": (-1, 2, 4, 0, 0, 0)}, "not positive definite"),
        ({"alpha": float("inf")}, "alpha"),
        ({"omega": 0.0}, "omega must be > 0"),
        ({"omega": -2.0}, "-2.0"),
        ({"g1": "abc"}, "g1 must be a finite number"),
        ({"t0": float("nan")}, "t0 must be finite"),
    ],
)
def test_bad_parameters_are_rejected_with_the_bad_value(kwargs: dict, needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        Params(**kwargs)


def test_non_symmetric_matrix_rejected() -> None:
    m = np.array([[1.0, 0.1, 0.0], [0.2, 2.0, 0.0], [0.0, 0.0, 3.0]])
    with pytest.raises(ParameterError, match=r"not symmetric: I12=0\.1"):
        inertia_entries(m)
    assert Params(inertia=np.diag([1.0, 2.0, 3.0])).inertia == (1.0, 2.0, 3.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("alpha", [0.0, 1.0, -0.4125760851, 3.7, -250.0])
def test_tables_scaled_by_powers_of_alpha_equal_a_build_at_alpha(alpha: float) -> None:
    """alpha enters omega linearly, so each monomial's coefficient is alpha^k times that of alpha = 1."""
    p = Params(inertia=(1.3, 2.1, 4.2, 0.1, 0.5, 0.3), alpha=alpha)
    for fast, direct in zip(build_tables(p), tensor_tables(p), strict=True):
        np.testing.assert_allclose(fast, direct, rtol=1e-14, atol=1e-15 * np.abs(direct).max())


@pytest.mark.parametrize(
    ("inertia", "reason"),
    [
        ((1e13, 2, 4, 0, 0, 0), "too ill-conditioned"),  # positive definite: not "off-diagonal too large"
        ((0, 2, 4, 0, 0, 0), "I11 <= 0"),
        ((1, 2, -4, 0, 0, 0), "I33 <= 0"),
        ((1, 2, 4, 3, 0, 0), "off-diagonal entries are too large"),
    ],
)
def test_a_refused_tensor_gives_the_right_reason(inertia, reason) -> None:
    with pytest.raises(ParameterError, match=reason) as err:
        Params(inertia=inertia)
    assert ("off-diagonal" in str(err.value)) == (reason.startswith("off-diagonal"))
