"""Equilibria of the frozen field: every finite real solution of ``Q = R = 0``.

At a frozen time ``t`` the reduced field (paper, eqs. (eq-m2), (eq-qr)) is a pair
of quadratic polynomials in ``(q, r)``, so its equilibria are the intersections
of two conics: at most four by Bezout, counted with multiplicity and including
points at infinity and complex points. They are found algebraically, never by
Newton from guesses:

1. rotate ``(q, r) -> (u, v)`` by an angle for which both conics keep a clearly
   non-zero ``v^2`` coefficient (a diagonal tensor's ``R`` does not depend on
   ``r`` at all, so ``v = r`` would lose a degree);
2. eliminate ``v`` with the Sylvester resultant, a polynomial of degree <= 4 in
   ``u``; leading coefficients at rounding-noise level (relative to the same
   formula evaluated on absolute values) are exact zeros: branches at infinity;
3. all roots of the resultant (companion eigenvalues); the near-real ones are
   candidates (a double root comes out as a near-real pair);
4. at each candidate ``u`` every real root ``v`` of either conic is tested; the
   points near both curves are polished by a few Newton steps with the exact
   Jacobian (polishing only: a step is kept only if it lowers the residual) and
   accepted if both ``Q`` and ``R`` vanish relative to the size of their terms;
   a cluster of k (nearly) equal real roots of the resultant yields at most k
   distinct points.

The energy identity explains the counts (see ``docs/equilibria.md``): since
``T' = alpha lambda`` is quadratic, the cubic part of ``(I omega, omega')``
vanishes, ``l1 Q2 + l3 R2 == 0`` for the quadratic parts ``Q2, R2`` and two
coprime linear forms ``l1, l3``. So ``Q2`` and ``R2`` share a linear factor and
the conics always meet at infinity: at most three finite equilibria, for any
tensor and any ``t`` (unless ``Q`` and ``R`` share a whole component).

:func:`equilibrium_tracks` follows the equilibria over one forcing period.
``python -m explorer_core.analyses.equilibria`` prints the counts for the paper's cases.
"""

from __future__ import annotations

import csv
import functools
import itertools
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from explorer_core import export
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, run
from explorer_core.system.model import ROW_Q, ROW_R, Model, coefficients_at
from explorer_core.system.params import ParameterError, Params

#: Equilibrium types, as used in :attr:`Equilibria.types` and the CSV/JSON output.
TYPES = ("saddle", "stable node", "unstable node", "stable focus", "unstable focus", "centre", "degenerate")

_EPS = np.finfo(float).eps
# Candidate rotations (cos, sin); odd angles so that no axis-aligned or
# diagonal conic direction (q, r, q = +-r) falls on one of them.
_ROT = tuple((math.cos(0.377 + k * math.pi / 8), math.sin(0.377 + k * math.pi / 8)) for k in range(8))
# A resultant coefficient smaller than this times its absolute-value bound is noise.
_NOISE = 1e4 * _EPS
# Jump accepted at the bisection limit (compactified plane; crossing infinity is ~2).
_LOOSE_JUMP = 0.5
# Length floor of the residual scale (units of q, r): only matters at an exact root at the origin.
_L0 = 1e-12


# ---------------------------------------------------------------------------
# Results.


@dataclass(frozen=True, eq=False)
class Equilibria(Drawable):
    """Equilibria of the frozen field at one time ``t``.

    Attributes
    ----------
    t : float
        The frozen time.
    q, r : (n,) arrays
        Coordinates, sorted by ``q`` then ``r``.
    eigenvalues : (n, 2) complex array
        Eigenvalues of the Jacobian; larger real part first, ``+im`` first in a pair.
    types : tuple of str
        One of :data:`TYPES` per point.
    at_infinity : int
        Intersections of the two conics lost at infinity: Bezout's 4 minus the
        finite (real or complex) roots of the resultant, with multiplicity.
    n_complex : int
        Finite non-real intersections (roots of the resultant off the real axis).
    degenerate : bool
        ``Q`` and ``R`` share a common component (a whole curve of equilibria);
        no points are returned then.
    message : str
        Why the result is degenerate, or empty.
    """

    t: float
    q: np.ndarray
    r: np.ndarray
    eigenvalues: np.ndarray
    types: tuple[str, ...]
    at_infinity: int = 0
    n_complex: int = 0
    degenerate: bool = False
    message: str = ""

    def __len__(self) -> int:
        return int(self.q.size)

    @property
    def points(self) -> np.ndarray:
        """``(n, 2)`` array of ``(q, r)``."""
        return np.column_stack([self.q, self.r])

    def to_dict(self, full: bool = False) -> dict[str, Any]:
        """JSON form ``{"t": t, "equilibria": [{"q", "r", "eigenvalues": [[re, im], [re, im]], "type"}]}``.

        With ``full=True`` also ``at_infinity``, ``n_complex``, ``degenerate`` and ``message``.
        """
        out: dict[str, Any] = {
            "t": float(self.t),
            "equilibria": [
                {
                    "q": float(self.q[i]),
                    "r": float(self.r[i]),
                    "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues[i]],
                    "type": self.types[i],
                }
                for i in range(len(self))
            ],
        }
        if full:
            out.update(
                at_infinity=self.at_infinity, n_complex=self.n_complex, degenerate=self.degenerate, message=self.message
            )
        return out


# ---------------------------------------------------------------------------
# Algebra on two conics given as coefficient rows (1, q, r, q^2, q r, r^2).


@functools.lru_cache(maxsize=16)
def _model_of(params: Params) -> Model:
    # Building the coefficient tables costs ~2 ms, 15x the solve: reuse them per Params.
    return Model(params)


def _as_model(model_or_params: Model | Params) -> Model:
    if isinstance(model_or_params, Model):
        return model_or_params
    if isinstance(model_or_params, Params):
        return _model_of(model_or_params)
    raise ParameterError(f"expected a Model or Params, got {type(model_or_params).__name__}: {model_or_params!r}")


def _check_t(name: str, t: Any) -> float:
    try:
        v = float(t)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {t!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {t!r}")
    return v


def _check_positive(name: str, v: Any, allow_zero: bool = False) -> None:
    ok = isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or v < 0 or (v == 0 and not allow_zero):
        raise ParameterError(f"{name} must be a {'non-negative' if allow_zero else 'positive'} number, got {v!r}")


def _choose_angle(cq: list[float], cr: list[float]) -> tuple[float, float]:
    """The candidate rotation whose smaller relative leading ``v`` coefficient (of the two conics) is largest."""
    best, choice = -1.0, _ROT[0]
    for cs, sn in _ROT:
        score = math.inf
        for c in (cq, cr):
            quad = abs(c[3]) + abs(c[4]) + abs(c[5])
            if quad > 0.0:
                score = min(score, abs(c[3] * sn * sn - c[4] * cs * sn + c[5] * cs * cs) / quad)
            else:  # a line (or a constant): keep its v coefficient instead
                lin = abs(c[1]) + abs(c[2])
                if lin > 0.0:
                    score = min(score, abs(c[2] * cs - c[1] * sn) / lin)
        if score > best:
            best, choice = score, (cs, sn)
    return choice


def _in_v(c: list[float], cs: float, sn: float) -> list[list[float]] | None:
    """The conic in ``(u, v)`` (``q = cs u - sn v``, ``r = sn u + cs v``) as ``[a0(u), a1(u), a2]``.

    Each ``a_k`` is a coefficient list in ``u`` (low -> high). Vanishing top
    powers of ``v`` are dropped; ``None`` for a conic that is a constant.
    """
    c0, c1, c2, c3, c4, c5 = c
    a2 = c3 * sn * sn - c4 * cs * sn + c5 * cs * cs
    a1 = [c2 * cs - c1 * sn, 2.0 * (c5 - c3) * cs * sn + c4 * (cs * cs - sn * sn)]
    a0 = [c0, c1 * cs + c2 * sn, c3 * cs * cs + c4 * cs * sn + c5 * sn * sn]
    if a2 != 0.0:
        return [a0, a1, [a2]]
    if a1[0] != 0.0 or a1[1] != 0.0:
        return [a0, a1]
    return None


def _pmul(p: list[float], q: list[float]) -> list[float]:
    out = [0.0] * (len(p) + len(q) - 1)
    for i, x in enumerate(p):
        for j, y in enumerate(q):
            out[i + j] += x * y
    return out


def _padd(p: list[float], q: list[float], sign: float) -> list[float]:
    if len(p) < len(q):
        p = p + [0.0] * (len(q) - len(p))
    out = list(p)
    for i, y in enumerate(q):
        out[i] += sign * y
    return out


def _resultant(a: list[list[float]], b: list[list[float]], sign: float = -1.0) -> list[float]:
    """Sylvester resultant in ``v`` of ``sum a[k](u) v^k`` and ``sum b[k](u) v^k`` (degree 1 or 2 in v).

    With ``sign=+1`` and absolute values of the coefficients it is a bound on the
    terms summed in each coefficient: the scale of its rounding noise.
    """
    m = _pmul
    if len(a) == 2 and len(b) == 3:
        a, b = b, a
    if len(a) == 3 and len(b) == 3:
        x = _padd(m(a[2], b[0]), m(a[0], b[2]), sign)
        y = _padd(m(a[2], b[1]), m(a[1], b[2]), sign)
        z = _padd(m(a[1], b[0]), m(a[0], b[1]), sign)
        return _padd(m(x, x), m(y, z), sign)
    if len(a) == 3:  # (2, 1): a2 b0^2 - a1 b0 b1 + a0 b1^2
        return _padd(_padd(m(a[2], m(b[0], b[0])), m(a[1], m(b[0], b[1])), sign), m(a[0], m(b[1], b[1])), 1.0)
    return _padd(m(a[1], b[0]), m(a[0], b[1]), sign)


def _poly_roots(p: list[float]) -> list[complex]:
    """All roots of ``sum p[k] u^k`` (``p[-1] != 0``): closed form up to degree 2, else companion eigenvalues."""
    deg = len(p) - 1
    if deg == 1:
        return [complex(-p[0] / p[1])]
    if deg == 2:
        return _quadratic(p[2], p[1], p[0])
    last = [-x / p[-1] for x in p[:-1]]
    if not all(math.isfinite(x) for x in last):
        return _poly_roots(p[:-1])  # overflow: that root is at infinity for all purposes
    comp = np.zeros((deg, deg))
    comp[1:, :-1] = np.eye(deg - 1)
    comp[:, -1] = last
    return [complex(z) for z in np.linalg.eigvals(comp)]


def _quadratic(a: float, b: float, c: float) -> list[complex]:
    """Roots of ``a x^2 + b x + c`` (``a != 0``), the stable way (no cancellation in ``-b +- sqrt``)."""
    disc = b * b - 4.0 * a * c
    if disc >= 0.0:
        s = -0.5 * (b + math.copysign(math.sqrt(disc), b))
        if s == 0.0:
            return [0j, 0j]
        return [complex(s / a), complex(c / s)]
    re, im = -b / (2.0 * a), math.sqrt(-disc) / (2.0 * abs(a))
    return [complex(re, im), complex(re, -im)]


def _residual(cq: list[float], cr: list[float], q: float, r: float) -> float:
    """``max(|Q| / scale_Q, |R| / scale_R)`` with ``scale = sum_k |c_k| rho^deg_k``, ``rho = |x| + L0``.

    0 at an exact root, O(eps) at a rounded one, O(1) off the curves. ``L0``
    keeps the scale finite at the origin (an exact root in the diagonal case).
    """
    rho = math.hypot(q, r) + _L0
    worst = 0.0
    for c in (cq, cr):
        f = c[0] + q * (c[1] + c[3] * q + c[4] * r) + r * (c[2] + c[5] * r)
        scale = abs(c[0]) + rho * (abs(c[1]) + abs(c[2]) + rho * (abs(c[3]) + abs(c[4]) + abs(c[5])))
        if f != 0.0:
            worst = max(worst, abs(f) / scale if scale > 0.0 else math.inf)
    return worst


def _polish(cq: list[float], cr: list[float], q: float, r: float, steps: int = 8) -> tuple[float, float, float]:
    """Newton on ``Q = R = 0`` with the exact Jacobian; a step is kept only if it lowers the residual."""
    res = _residual(cq, cr, q, r)
    for _ in range(steps):
        if res <= 2.0 * _EPS:
            break
        fq = cq[0] + q * (cq[1] + cq[3] * q + cq[4] * r) + r * (cq[2] + cq[5] * r)
        fr = cr[0] + q * (cr[1] + cr[3] * q + cr[4] * r) + r * (cr[2] + cr[5] * r)
        j11 = cq[1] + 2.0 * cq[3] * q + cq[4] * r
        j12 = cq[2] + cq[4] * q + 2.0 * cq[5] * r
        j21 = cr[1] + 2.0 * cr[3] * q + cr[4] * r
        j22 = cr[2] + cr[4] * q + 2.0 * cr[5] * r
        det = j11 * j22 - j12 * j21
        if det == 0.0:
            break
        q1 = q - (j22 * fq - j12 * fr) / det
        r1 = r - (j11 * fr - j21 * fq) / det
        res1 = _residual(cq, cr, q1, r1) if math.isfinite(q1) and math.isfinite(r1) else math.inf
        if not res1 < res:
            break
        q, r, res = q1, r1, res1
    return q, r, res


@dataclass(frozen=True, eq=False)
class ConicSolution:
    """Finite real intersections of two conics, see :func:`solve_conics`."""

    q: np.ndarray
    r: np.ndarray
    at_infinity: int
    n_complex: int
    degenerate: bool
    message: str


def _empty(at_infinity: int, n_complex: int = 0, message: str = "") -> ConicSolution:
    return ConicSolution(np.zeros(0), np.zeros(0), at_infinity, n_complex, bool(message), message)


def solve_conics(
    cq: Any,
    cr: Any,
    *,
    inf_norm: float = 1e8,
    imag_tol: float = 1e-5,
    accept_tol: float = 1e-9,
    dedupe_tol: float = 1e-7,
) -> ConicSolution:
    """All finite real intersections of two conics ``c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2 = 0``.

    Parameters
    ----------
    cq, cr : sequences of 6 floats
        Monomial coefficients in the order ``(1, q, r, q^2, q r, r^2)`` (:data:`explorer_core.system.model.MONOMIALS`).
    inf_norm : float
        Points with ``|(q, r)| > inf_norm`` are counted as at infinity.
    imag_tol : float
        A resultant root ``u`` is a real candidate if ``|Im u| <= imag_tol (|u| + max_k |u_k|)``.
        Generous on purpose (a double root splits into a near-real pair): the residual test decides.
    accept_tol : float
        Largest residual (see :func:`_residual`) of an accepted, polished point.
    dedupe_tol : float
        Points closer than ``dedupe_tol (1 + |x|)`` are one point (a double root).

    Returns
    -------
    ConicSolution
        Points sorted by ``q`` then ``r``; ``at_infinity = 4 -`` (finite roots of the
        resultant, real or not, with multiplicity); ``degenerate`` when the conics
        share a component (the resultant vanishes identically).
    """
    cq = [float(x) for x in cq]
    cr = [float(x) for x in cr]
    for c, name in ((cq, "Q"), (cr, "R")):
        if all(x == 0.0 for x in c):
            return _empty(0, 0, f"{name} vanishes identically: every point on the other curve is an equilibrium")
    cs, sn = _choose_angle(cq, cr)
    a = _in_v(cq, cs, sn)
    b = _in_v(cr, cs, sn)
    if a is None or b is None:
        return _empty(4)  # a non-zero constant: no equilibria at all
    res = _resultant(a, b)
    bound = _resultant([[abs(x) for x in p] for p in a], [[abs(x) for x in p] for p in b], sign=1.0)
    # Coefficients at rounding-noise level are exact zeros; leading ones are intersections at infinity.
    signal = [k for k, (x, s) in enumerate(zip(res, bound, strict=True)) if abs(x) > _NOISE * s]
    if not signal:
        return _empty(
            0,
            0,
            "Q and R have a common factor (their resultant vanishes identically): "
            "a whole curve of equilibria, not isolated points",
        )
    deg = signal[-1]
    roots = _poly_roots(res[: deg + 1]) if deg > 0 else []
    roots = [z for z in roots if math.isfinite(z.real) and math.isfinite(z.imag) and abs(z) <= inf_norm]
    at_infinity = 4 - len(roots)
    umax = max((abs(z) for z in roots), default=0.0)
    real_u = sorted(z.real for z in roots if abs(z.imag) <= imag_tol * (abs(z) + umax))
    n_complex = len(roots) - len(real_u)
    # Clusters of (nearly) equal real roots with their multiplicity: a cluster of k
    # roots holds at most k intersections, which stops one ill-conditioned point
    # (nearly singular Jacobian, far out) from being reported twice.
    clusters: list[list[float]] = []
    for u in real_u:
        if clusters and u - clusters[-1][-1] <= 1e-6 * abs(u) + 1e-9 * umax:
            clusters[-1].append(u)
        else:
            clusters.append([u])
    # Every real root v of either conic at each u (two points may share u), polished.
    found: list[tuple[float, float, float]] = []
    for u in sorted(set(real_u)):
        for p in (a, b):
            k = [sum(x * u**j for j, x in enumerate(pk)) for pk in p]
            if len(k) == 3 and k[2] != 0.0:
                vs = {z.real for z in _quadratic(k[2], k[1], k[0])}
            elif k[1] != 0.0:
                vs = {-k[0] / k[1]}
            else:
                continue
            for v in vs:
                q0, r0 = cs * u - sn * v, sn * u + cs * v
                if _residual(cq, cr, q0, r0) > 1e-3:
                    continue  # on one conic only, far from the other
                q0, r0, rs = _polish(cq, cr, q0, r0)
                if rs <= accept_tol and math.hypot(q0, r0) <= inf_norm:
                    found.append((rs, q0, r0))
    # Each point goes to the cluster nearest its own u (two roots can be close, and a
    # candidate from one may polish into the other's point); best residual first.
    found.sort()
    kept = [0] * len(clusters)
    pts: list[tuple[float, float]] = []
    for _, q0, r0 in found:
        u0 = cs * q0 + sn * r0
        c = min(range(len(clusters)), key=lambda i: min(abs(u0 - u) for u in clusters[i]))
        if kept[c] == len(clusters[c]):
            continue
        if all(math.hypot(q0 - q1, r0 - r1) > dedupe_tol * (1.0 + math.hypot(q0, r0)) for q1, r1 in pts):
            pts.append((q0, r0))
            kept[c] += 1
    pts.sort()
    return ConicSolution(
        np.array([x[0] for x in pts]), np.array([x[1] for x in pts]), at_infinity, n_complex, False, ""
    )


# ---------------------------------------------------------------------------
# Classification.


def _eig2(j11: float, j12: float, j21: float, j22: float) -> tuple[complex, complex]:
    """Eigenvalues of a real 2x2 matrix, larger real part first, ``+im`` first in a pair."""
    half = 0.5 * (j11 + j22)
    det = j11 * j22 - j12 * j21
    # (j11 - j22)^2 / 4 + j12 j21 is the discriminant without the cancellation of half^2 - det.
    disc = 0.25 * (j11 - j22) ** 2 + j12 * j21
    if disc >= 0.0:
        s = math.sqrt(disc)
        big = half + math.copysign(s, half) if half != 0.0 else s
        small = det / big if big != 0.0 else half - s
        return (complex(big), complex(small)) if big >= small else (complex(small), complex(big))
    s = math.sqrt(-disc)
    return complex(half, s), complex(half, -s)


def _type(j11: float, j12: float, j21: float, j22: float, rtol: float) -> str:
    tr = j11 + j22
    det = j11 * j22 - j12 * j21
    n2 = j11 * j11 + j12 * j12 + j21 * j21 + j22 * j22
    if abs(det) <= rtol * n2:
        return "degenerate"
    if det < 0.0:
        return "saddle"
    if abs(tr) <= rtol * math.sqrt(n2):
        return "centre"
    if tr * tr >= 4.0 * det:
        return "stable node" if tr < 0.0 else "unstable node"
    return "stable focus" if tr < 0.0 else "unstable focus"


def classify(jacobian: Any, rtol: float = 1e-12) -> tuple[np.ndarray, tuple[str, ...]]:
    """Eigenvalues and type of each 2x2 Jacobian of a ``(n, 2, 2)`` stack.

    Types (:data:`TYPES`): ``|det| <= rtol |J|^2``: degenerate; ``det < 0``: saddle;
    ``det > 0`` and ``|tr| <= rtol |J|``: centre (the linearisation cannot decide,
    e.g. the origin at ``g' = 0`` in the diagonal case); otherwise node if
    ``tr^2 >= 4 det`` else focus, stable if ``tr < 0``. ``|J|`` is the Frobenius norm.
    """
    jac = np.asarray(jacobian, dtype=float).reshape(-1, 2, 2)
    eig = np.zeros((jac.shape[0], 2), dtype=complex)
    types = []
    for i, m in enumerate(jac.tolist()):
        (j11, j12), (j21, j22) = m
        eig[i] = _eig2(j11, j12, j21, j22)
        types.append(_type(j11, j12, j21, j22, rtol))
    return eig, tuple(types)


# ---------------------------------------------------------------------------
# Public entry points.


def _coefficients(model: Model, t: float) -> tuple[list[float], list[float]]:
    g, gp = model.g(t)
    out = np.empty((2, 6))
    coefficients_at(model.num[:2], model.gpc[:2], model.den, g, gp, out)
    return out[ROW_Q].tolist(), out[ROW_R].tolist()


def equilibria(
    model_or_params: Model | Params,
    t: float,
    *,
    inf_norm: float = 1e8,
    rtol: float = 1e-12,
) -> Equilibria:
    """Every finite real equilibrium of the frozen field at time ``t`` (paper, eq. (eq-qr)).

    Parameters
    ----------
    model_or_params : Model or Params
        The system; a :class:`Params` is turned into a :class:`Model` (cached for
        the last 16 parameter sets: building one takes ~2 ms, the solve ~0.1 ms).
    t : float
        Frozen time.
    inf_norm : float
        Intersections farther than this from the origin count as at infinity.
    rtol : float
        Relative tolerance of the classification (see :func:`classify`).

    Returns
    -------
    Equilibria
        Points, Jacobian eigenvalues and types. ``degenerate=True`` (and no
        points) when ``Q`` and ``R`` share a component, e.g. ``alpha = 0`` with a
        diagonal tensor, where the whole line ``q = 0`` is at rest.
    """
    t = _check_t("t", t)
    _check_positive("inf_norm", inf_norm)
    _check_positive("rtol", rtol, allow_zero=True)
    model = _as_model(model_or_params)
    cq, cr = _coefficients(model, t)
    return _finish(t, cq, cr, solve_conics(cq, cr, inf_norm=inf_norm), rtol)


def _finish(t: float, cq: list[float], cr: list[float], sol: ConicSolution, rtol: float) -> Equilibria:
    n = sol.q.size
    eig = np.zeros((n, 2), dtype=complex)
    types = []
    for i, (q, r) in enumerate(zip(sol.q.tolist(), sol.r.tolist(), strict=True)):
        # Exact Jacobian from the same coefficients the roots were computed from.
        j11 = cq[1] + 2.0 * cq[3] * q + cq[4] * r
        j12 = cq[2] + cq[4] * q + 2.0 * cq[5] * r
        j21 = cr[1] + 2.0 * cr[3] * q + cr[4] * r
        j22 = cr[2] + cr[4] * q + 2.0 * cr[5] * r
        eig[i] = _eig2(j11, j12, j21, j22)
        types.append(_type(j11, j12, j21, j22, rtol))
    for arr in (sol.q, sol.r, eig):
        arr.setflags(write=False)
    return Equilibria(
        t=t,
        q=sol.q,
        r=sol.r,
        eigenvalues=eig,
        types=tuple(types),
        at_infinity=sol.at_infinity,
        n_complex=sol.n_complex,
        degenerate=sol.degenerate,
        message=sol.message,
    )


# ---------------------------------------------------------------------------
# Tracks over one period.


@dataclass(frozen=True, eq=False)
class Tracks(Drawable):
    """Equilibria followed continuously over one forcing period.

    Rows are sorted by branch, then time. A branch ends where its point is born
    or dies with a partner (the count changes), runs off to infinity, or jumps
    by more than the continuity tolerance even after bisection: branches are
    never joined across infinity.

    Attributes
    ----------
    model : Model
        The system tracked.
    branch, t, q, r : (m,) arrays
        One row per (sample time, equilibrium); branch ids are numbered by first appearance.
    types : tuple of str
        Type of each row.
    eigenvalues : (m, 2) complex array
    sample_t, sample_count : arrays
        Every time evaluated (grid and bisection points, sorted) and the number of
        equilibria there; ``sample_degenerate`` flags a common component.
    t_start, period : float
        The covered interval ``[t_start, t_start + period]``.
    """

    model: Model = field(repr=False)
    t_start: float
    period: float
    branch: np.ndarray
    t: np.ndarray
    q: np.ndarray
    r: np.ndarray
    types: tuple[str, ...]
    eigenvalues: np.ndarray
    sample_t: np.ndarray
    sample_count: np.ndarray
    sample_degenerate: np.ndarray
    #: False when cancelled: the tracks then cover only the start of the period (``lost`` says how much).
    completed: bool = True
    lost: tuple[Loss, ...] = ()

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    @property
    def n_branches(self) -> int:
        return int(self.branch.max()) + 1 if self.branch.size else 0

    def branches(self) -> Iterator[dict[str, Any]]:
        """Per-branch arrays: ``{"branch", "t", "q", "r", "types", "eigenvalues"}``."""
        bounds = np.flatnonzero(np.diff(self.branch)) + 1
        for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, self.branch.size], strict=True):
            if hi > lo:
                yield {
                    "branch": int(self.branch[lo]),
                    "t": self.t[lo:hi],
                    "q": self.q[lo:hi],
                    "r": self.r[lo:hi],
                    "types": self.types[lo:hi],
                    "eigenvalues": self.eigenvalues[lo:hi],
                }

    def section(self) -> Equilibria:
        """Equilibria at the section phase ``params.t0`` (the frozen field the Poincare map starts from).

        With the default ``t_start = t0`` the same points are the rows ``rows_at(t_start)``,
        which also carry their branch ids.
        """
        return equilibria(self.model, self.model.params.t0)

    def summary(self) -> dict[str, Any]:
        """Plain-JSON overview: the interval, the counts per sample, and each branch's ends."""

        def end(b: dict[str, Any], k: int) -> dict[str, Any]:
            return {"t": float(b["t"][k]), "q": float(b["q"][k]), "r": float(b["r"][k]), "type": b["types"][k]}

        counts, freq = np.unique(self.sample_count, return_counts=True)
        return {
            "t_start": self.t_start,
            "period": self.period,
            "n_samples": int(self.sample_t.size),
            "count_samples": {str(int(c)): int(f) for c, f in zip(counts, freq, strict=True)},
            "n_branches": self.n_branches,
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "branches": [
                {"branch": b["branch"], "n": int(b["t"].size), "start": end(b, 0), "end": end(b, -1)}
                for b in self.branches()
            ],
        }

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "set of tracks"
        )

    def rows_at(self, t: float) -> np.ndarray:
        """Indices of the rows at sample time ``t`` (exact match), e.g. ``rows_at(tracks.t_start)``."""
        return np.flatnonzero(self.t == t)

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write ``branch,t,q,r,type,eig1_re,eig1_im,eig2_re,eig2_im`` rows."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["branch", "t", "q", "r", "type", "eig1_re", "eig1_im", "eig2_re", "eig2_im"])
            for i in range(self.branch.size):
                e = self.eigenvalues[i]
                w.writerow(
                    [int(self.branch[i])]
                    + [repr(float(x)) for x in (self.t[i], self.q[i], self.r[i])]
                    + [self.types[i]]
                    + [repr(float(x)) for x in (e[0].real, e[0].imag, e[1].real, e[1].imag)]
                )


Point = tuple[float, float]


def _compact(x: Point) -> Point:
    """``x / (1 + |x|)``: the plane squeezed into the unit disc, infinity on its rim."""
    s = 1.0 / (1.0 + math.hypot(x[0], x[1]))
    return x[0] * s, x[1] * s


def _match(a: list[Point], b: list[Point], jump: float) -> tuple[list[tuple[int, int]], bool]:
    """Nearest assignment of the points ``a`` to the points ``b``.

    The assignment minimises the total of ``min(distance, jump)``: a pair farther
    apart than ``jump`` will be cut anyway, so it must not pull the others into a
    crossed assignment (a point passing through infinity jumps by ~2, as far as
    two crossed pairs of ~1 each).

    Distances are taken between the compactified points ``x / (1 + |x|)``: about
    ``|dx| / (1 + |x|)`` for a sideways move, so a branch running off to infinity
    stays continuous, while passing through infinity (from the far side of the
    rim to the other) is a jump of ~2. Returns the pairs within ``jump`` and
    whether the match is clearly continuous: same count, every pair within
    ``jump``, and no pair ambiguous (each distance under half the distance from
    either end to any other point).
    """
    if not a or not b:
        return [], len(a) == len(b)
    ca = [_compact(x) for x in a]
    cb = [_compact(y) for y in b]
    d = [[math.hypot(x[0] - y[0], x[1] - y[1]) for y in cb] for x in ca]
    if min(len(a), len(b)) <= 4:
        # At most 3 equilibria here: trying every assignment is cheaper than scipy.
        if len(a) <= len(b):
            perms = itertools.permutations(range(len(b)), len(a))
            best = min(perms, key=lambda p: sum(min(d[i][j], jump) for i, j in enumerate(p)))
            assign = list(enumerate(best))
        else:
            perms = itertools.permutations(range(len(a)), len(b))
            best = min(perms, key=lambda p: sum(min(d[i][j], jump) for j, i in enumerate(p)))
            assign = [(i, j) for j, i in enumerate(best)]
    else:
        rows, cols = linear_sum_assignment(np.minimum(np.array(d), jump))
        assign = list(zip(rows.tolist(), cols.tolist(), strict=True))
    pairs = []
    clear = len(a) == len(b)
    for i, j in assign:
        dij = d[i][j]
        if dij <= jump:
            pairs.append((i, j))
        else:
            clear = False
        others = [d[i][k] for k in range(len(b)) if k != j] + [d[k][j] for k in range(len(a)) if k != i]
        if others and dij > 0.5 * min(others):
            clear = False
    return pairs, clear


def equilibrium_tracks(
    model_or_params: Model | Params,
    n_t: int = 400,
    t_start: float | None = None,
    *,
    progress: Callable[[Step[Tracks]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> Tracks:
    """Equilibria of the frozen field followed over one period (:func:`iter_equilibrium_tracks`'s
    arguments); ``progress`` gets each of its updates."""
    return run(iter_equilibrium_tracks(model_or_params, n_t, t_start, cancel=cancel, **kw), progress)


#: Updates :func:`iter_equilibrium_tracks` yields over a period (at most; one per grid interval if fewer).
TRACK_UPDATES = 100


def iter_equilibrium_tracks(
    model_or_params: Model | Params,
    n_t: int = 400,
    t_start: float | None = None,
    *,
    jump: float = 0.05,
    max_depth: int = 12,
    max_refine: int | None = None,
    inf_norm: float = 1e8,
    rtol: float = 1e-12,
    cancel: Callable[[], bool] | None = None,
) -> Iterator[Step[Tracks]]:
    """Equilibria of the frozen field followed over one period ``[t_start, t_start + T]``.

    Yields a :class:`~explorer_core.progress.Step` (grid intervals done of ``n_t - 1``) about
    :data:`TRACK_UPDATES` times; the last one's ``result`` is the :class:`Tracks`.

    Parameters
    ----------
    model_or_params : Model or Params
    n_t : int
        Grid samples over the period (both ends included), ``2 <= n_t <= 1e6``.
    t_start : float, optional
        Start of the period; default ``params.t0`` (the section phase).
    jump : float
        Consecutive points of a branch are at most ``jump`` apart on the compactified
        plane ``x / (1 + |x|)`` (about ``|dx| <= jump (1 + |x|)`` for a sideways
        move; a point running off to infinity stays continuous up to the rim).
    max_depth, max_refine : int
        A grid interval whose match is not clearly continuous (count change, large
        or ambiguous jump) is bisected, at most ``max_depth`` levels deep and with
        at most ``max_refine`` extra evaluations in total (default ``4 n_t``).
        Where it is still unclear at the limit, pairs closer than 0.5 on the
        compactified plane are joined and the others cut: so a branch through
        infinity (``g -> 0`` in the diagonal case, where ``x2* = (-alpha/g,
        I11 g'/(I22 - I33))``) ends and a new one starts.
    inf_norm, rtol : float
        As in :func:`equilibria`.
    cancel : callable, optional
        Polled between grid intervals; once it returns True the work stops and the tracks
        computed so far come back with ``completed=False`` and the rest of the period in ``lost``.

    Yields
    ------
    Step[Tracks]
    """
    model = _as_model(model_or_params)
    if isinstance(n_t, bool) or not isinstance(n_t, int | np.integer):
        raise ParameterError(f"n_t must be an integer, got {n_t!r}")
    if not 2 <= n_t <= 1_000_000:
        raise ParameterError(f"n_t must be between 2 and 1000000, got {n_t!r}")
    t_start = model.params.t0 if t_start is None else _check_t("t_start", t_start)
    _check_positive("jump", jump)
    _check_positive("inf_norm", inf_norm)
    _check_positive("rtol", rtol, allow_zero=True)
    for name, v in (("max_depth", max_depth), ("max_refine", max_refine)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0):
            raise ParameterError(f"{name} must be a non-negative integer, got {v!r}")
    if max_refine is None:
        max_refine = 4 * n_t
    period = model.params.period

    cache: dict[float, Equilibria] = {}

    def solve(t: float) -> list[tuple[float, float]]:
        if t not in cache:
            cq, cr = _coefficients(model, t)
            cache[t] = _finish(t, cq, cr, solve_conics(cq, cr, inf_norm=inf_norm), rtol)
        e = cache[t]
        return list(zip(e.q.tolist(), e.r.tolist(), strict=True))

    grid = (t_start + period * np.linspace(0.0, 1.0, n_t)).tolist()
    grid[-1] = t_start + period
    # links[(t, i)] = (t_next, j): point i at time t continues as point j at t_next.
    links: dict[tuple[float, int], tuple[float, int]] = {}
    budget = max_refine
    lost: tuple[Loss, ...] = ()
    start = time.perf_counter()
    every = max(1, (n_t - 1) // TRACK_UPDATES)
    done = 0
    for k in range(n_t - 1):
        if k and k % every == 0:
            yield Step(Progress(k, n_t - 1, "intervals", time.perf_counter() - start))
        done = k
        if cancel is not None and cancel():
            why = f"cancelled: the tracks cover t in [{grid[0]:.6g}, {grid[k]:.6g}] of [{grid[0]:.6g}, {grid[-1]:.6g}]"
            lost = (Loss("grid intervals", n_t - 1 - k, why),)
            break
        stack = [(grid[k], grid[k + 1], 0)]
        while stack:
            ta, tb, depth = stack.pop()
            pairs, clear = _match(solve(ta), solve(tb), jump)
            tm = 0.5 * (ta + tb)
            if not clear and depth < max_depth and budget > 0 and ta < tm < tb:
                budget -= 1
                stack.append((tm, tb, depth + 1))
                stack.append((ta, tm, depth + 1))
                continue
            if not clear:
                # Still unclear at the limit: the interval is tiny, so accept any pair that
                # does not cross infinity (an antipodal jump of ~2 on the compactified plane).
                pairs, _ = _match(solve(ta), solve(tb), max(jump, _LOOSE_JUMP))
            for i, j in pairs:
                links[(ta, i)] = (tb, j)
        done = k + 1

    times = sorted(cache)
    branch_of: dict[tuple[float, int], int] = {}
    rows: list[tuple[int, float, int]] = []
    n_branches = 0
    for t in times:
        for i in range(len(cache[t])):
            if (t, i) not in branch_of:
                branch_of[(t, i)] = n_branches
                n_branches += 1
            b = branch_of[(t, i)]
            rows.append((b, t, i))
            nxt = links.get((t, i))
            if nxt is not None:
                branch_of[nxt] = b
    rows.sort()
    n = len(rows)
    eig = np.array([cache[t].eigenvalues[i] for _, t, i in rows], dtype=complex).reshape(n, 2)
    tracks = Tracks(
        model=model,
        t_start=float(t_start),
        period=float(period),
        branch=np.array([b for b, _, _ in rows], dtype=np.int64),
        t=np.array([t for _, t, _ in rows], dtype=float),
        q=np.array([cache[t].q[i] for _, t, i in rows], dtype=float),
        r=np.array([cache[t].r[i] for _, t, i in rows], dtype=float),
        types=tuple(cache[t].types[i] for _, t, i in rows),
        eigenvalues=eig,
        sample_t=np.array(times),
        sample_count=np.array([len(cache[t]) for t in times], dtype=np.int64),
        sample_degenerate=np.array([cache[t].degenerate for t in times], dtype=bool),
        completed=not lost,
        lost=lost,
    )
    yield Step(Progress(done, n_t - 1, "intervals", time.perf_counter() - start), None, tracks)


# ---------------------------------------------------------------------------
# The counts for the paper's cases (docs/equilibria.md).

#: The paper's tensors and alphas with g = cos t.
PAPER_CASES: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...] = (
    ("diag(1,2,4)", (1.0, 2.0, 4.0, 0.0, 0.0, 0.0), (0.1,)),
    ("diag(4,2,1)", (4.0, 2.0, 1.0, 0.0, 0.0, 0.0), (0.1,)),
    ("diag(1,4,2)", (1.0, 4.0, 2.0, 0.0, 0.0, 0.0), (0.1, 0.4)),
    ("diag(4,1,2)", (4.0, 1.0, 2.0, 0.0, 0.0, 0.0), (0.1, 0.4)),
    ("[[1,0,.1],[0,2,0],[.1,0,4]]", (1.0, 2.0, 4.0, 0.0, 0.1, 0.0), (0.1, -0.1, 0.4, -0.4)),
    ("[[1,0,.5],[0,2,.3],[.5,.3,4]]", (1.0, 2.0, 4.0, 0.0, 0.5, 0.3), (-0.001, -0.01, -0.05, -0.37, -0.45, -0.5)),
)


def count_survey(params: Params, n_t: int = 20000, n_track: int = 1000) -> dict[str, Any]:
    """How many equilibria there are over one period, and where they go.

    Parameters
    ----------
    params : Params
    n_t : int
        Grid for the counts: midpoints ``t0 + T (k + 1/2) / n_t``, so that an exact
        singular instant such as ``g = 0`` is not sampled by accident.
    n_track : int
        Grid of the :func:`equilibrium_tracks` run that locates the events.

    Returns
    -------
    dict
        ``fraction``: share of the grid with each number of real equilibria;
        ``changes``: ``(t, before, after)`` where that number changes between grid
        points; ``n_complex``, ``at_infinity``: their (min, max) over the grid;
        ``through_infinity``: times where a tracked point passes through infinity
        (its branch is cut and continues from the opposite direction);
        ``pair_events``: other times where a branch ends or starts inside the
        period (a pair is born or dies).
    """
    model = Model(params)
    ts = params.t0 + params.period * (np.arange(n_t) + 0.5) / n_t
    n_real, n_cx, n_inf = [], [], []
    for t in ts.tolist():
        e = equilibria(model, t)
        n_real.append(len(e))
        n_cx.append(e.n_complex)
        n_inf.append(e.at_infinity)
    n_real_a = np.array(n_real)
    change = np.flatnonzero(np.diff(n_real_a)) + 1
    values, freq = np.unique(n_real_a, return_counts=True)
    tracks = equilibrium_tracks(model, n_track)
    t_end = tracks.t_start + tracks.period
    starts = [(float(b["t"][0]), _compact((b["q"][0], b["r"][0]))) for b in tracks.branches()]
    reappear: set[int] = set()
    through_inf: list[float] = []
    pair_events: list[float] = []
    h = tracks.period / (n_track - 1)  # one grid step: the bisection stays inside it
    for b in tracks.branches():
        te = float(b["t"][-1])
        if te >= t_end:
            continue
        x = _compact((b["q"][-1], b["r"][-1]))
        # A branch cut where another one starts within a grid step on the opposite
        # side of the rim of the compactified plane is a passage through infinity.
        far = [
            (math.hypot(x[0] - y[0], x[1] - y[1]), k)
            for k, (t, y) in enumerate(starts)
            if te < t <= te + h and k not in reappear
        ]
        dist, k = max(far, default=(0.0, -1))
        if dist > 1.0:
            reappear.add(k)
            through_inf.append(te)
        else:
            pair_events.append(te)
    pair_events += [t for k, (t, _) in enumerate(starts) if t > tracks.t_start and k not in reappear]
    return {
        "fraction": {int(v): float(f) / n_t for v, f in zip(values, freq, strict=True)},
        "changes": [(float(ts[i]), int(n_real_a[i - 1]), int(n_real_a[i])) for i in change],
        "n_complex": (min(n_cx), max(n_cx)),
        "at_infinity": (min(n_inf), max(n_inf)),
        "through_infinity": sorted({round(t, 4) for t in through_inf}),
        "pair_events": sorted({round(t, 4) for t in pair_events}),
    }


def main() -> None:
    """Print :func:`count_survey` for :data:`PAPER_CASES` (``python -m explorer_core.analyses.equilibria``)."""
    for name, inertia, alphas in PAPER_CASES:
        for alpha in alphas:
            s = count_survey(Params(inertia=inertia, alpha=alpha))
            frac = ", ".join(f"{k}: {v:.4f}" for k, v in s["fraction"].items())
            ch = "; ".join(f"{t:.4f} {a}->{b}" for t, a, b in s["changes"]) or "none"
            inf = ", ".join(f"{t:.4f}" for t in s["through_infinity"]) or "none"
            pair = ", ".join(f"{t:.4f}" for t in s["pair_events"]) or "none"
            print(
                f"{name} alpha={alpha:+g}: real count (share of period) {{{frac}}}, "
                f"complex {s['n_complex']}, at infinity {s['at_infinity']}\n"
                f"    count changes at t = {ch}\n    a point passes through infinity at t = {inf}\n"
                f"    a pair is born or dies at t = {pair}"
            )


if __name__ == "__main__":
    main()
