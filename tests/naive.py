"""Slow, obviously-correct reference implementations the fast code is tested against.

None of these use the polynomial coefficient tables or the numba kernels: the
field comes straight from I w' = (I w) x w + lambda a with 3x3 linear algebra.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from explorer_core.analyses.equilibria import ConicSolution
from explorer_core.system.model import Model
from explorer_core.system.params import Params


class NaiveField:
    """Q, R, lambda and T from the Lagrange-d'Alembert equations, term by term."""

    def __init__(self, params: Params) -> None:
        self.p = params
        self.inertia = params.inertia_matrix
        self.minv = np.linalg.inv(self.inertia)

    def g(self, t: float) -> tuple[float, float]:
        p = self.p
        w = p.omega
        return (
            p.g0 + p.g1 * math.cos(w * t) + p.g2 * math.sin(w * t),
            w * (p.g2 * math.cos(w * t) - p.g1 * math.sin(w * t)),
        )

    def omega_dot(self, t: float, q: float, r: float) -> tuple[np.ndarray, float]:
        g, gp = self.g(t)
        om = np.array([self.p.alpha + g * q, q, r])
        a = np.array([1.0, -g, 0.0])
        euler = self.minv @ np.cross(self.inertia @ om, om)
        minv_a = self.minv @ a
        lam = (-(a @ euler) + gp * q) / (a @ minv_a)
        return euler + lam * minv_a, lam

    def rhs(self, t: float, y) -> list[float]:
        wd, _ = self.omega_dot(t, y[0], y[1])
        return [wd[1], wd[2]]

    def energy(self, t: float, q: float, r: float) -> float:
        g, _ = self.g(t)
        om = np.array([self.p.alpha + g * q, q, r])
        return 0.5 * om @ self.inertia @ om


def rk4_section(params: Params, ic, periods: int, steps: int) -> np.ndarray:
    """Fixed-step RK4 in plain Python; section points k = 1..periods."""
    f = NaiveField(params)
    T = params.period
    h = T / steps
    y = np.array(ic, dtype=float)
    out = []
    for k in range(periods):
        ta = params.t0 + k * T
        for m in range(steps):
            t = ta + m * h
            k1 = np.array(f.rhs(t, y))
            k2 = np.array(f.rhs(t + h / 2, y + h / 2 * k1))
            k3 = np.array(f.rhs(t + h / 2, y + h / 2 * k2))
            k4 = np.array(f.rhs(t + h, y + h * k3))
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(y.copy())
    return np.array(out)


def solve_ivp_section(params: Params, ic, periods: int, rtol: float = 1e-12, atol: float = 1e-12, direction: int = 1):
    """Section points k = 1..periods by scipy's DOP853 on the naive field."""
    f = NaiveField(params)
    T = direction * params.period
    t_eval = params.t0 + T * np.arange(1, periods + 1)
    sol = solve_ivp(
        f.rhs, (params.t0, t_eval[-1]), np.asarray(ic, float), method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval
    )
    assert sol.success, sol.message
    return sol.y.T


# ---------------------------------------------------------------------------
# Lyapunov exponents (reference for explorer_core.analyses.lyapunov).


def complex_step_jacobian(field: NaiveField, t: float, q: float, r: float, h: float = 1e-30) -> np.ndarray:
    """Jacobian of the naive field by complex-step differentiation (exact to rounding).

    Independent of the coefficient tables: it differentiates the 3x3 linear algebra
    of ``NaiveField.omega_dot`` evaluated at complex ``(q, r)``.
    """
    jac = np.empty((2, 2))
    for col, (dq, dr) in enumerate(((1j * h, 0.0), (0.0, 1j * h))):
        g, gp = field.g(t)
        om = np.array([field.p.alpha + g * (q + dq), q + dq, r + dr], dtype=complex)
        a = np.array([1.0, -g, 0.0])
        euler = field.minv @ np.cross(field.inertia @ om, om)
        minv_a = field.minv @ a
        lam = (-(a @ euler) + gp * (q + dq)) / (a @ minv_a)
        wd = euler + lam * minv_a
        jac[:, col] = wd[1:].imag / h
    return jac


def solve_ivp_lyapunov(params: Params, ic, periods: int, rtol: float = 1e-12, atol: float = 1e-12):
    """Per-period ``log R_ii`` and divergence integrals by solve_ivp on (state, Phi, int div).

    The 7-D system ``(q, r, Phi (2x2), s)`` with ``Phi' = J Phi``, ``s' = tr J``
    is integrated period by period with scipy's DOP853; at each section time
    ``Phi = Q R`` by numpy's QR (signs fixed so ``R_ii > 0``) and ``Phi <- Q``.

    Returns
    -------
    logs : (periods, 2), divs : (periods,), points : (periods, 2)
    """
    f = NaiveField(params)
    T = params.period

    def rhs(t, y):
        jac = complex_step_jacobian(f, t, y[0], y[1])
        phi = y[2:6].reshape(2, 2)  # rows: [v1x v2x; v1y v2y]
        return np.concatenate([f.rhs(t, y[:2]), (jac @ phi).ravel(), [np.trace(jac)]])

    y = np.concatenate([np.asarray(ic, float), np.eye(2).ravel(), [0.0]])
    logs, divs, pts = [], [], []
    for k in range(periods):
        ta = params.t0 + k * T
        sol = solve_ivp(rhs, (ta, ta + T), y, method="DOP853", rtol=rtol, atol=atol)
        assert sol.success, sol.message
        yk = sol.y[:, -1]
        qm, rm = np.linalg.qr(yk[2:6].reshape(2, 2))
        sign = np.sign(np.diag(rm))
        qm = qm * sign[None, :]
        rm = rm * sign[:, None]
        logs.append(np.log(np.diag(rm)))
        divs.append(yk[6])
        pts.append(yk[:2].copy())
        y = np.concatenate([yk[:2], qm.ravel(), [0.0]])
    return np.array(logs), np.array(divs), np.array(pts)


# ---------------------------------------------------------------------------
# Periodic orbits (reference for explorer_core.analyses.orbits and .continuation).


def ivp_map(params: Params, x, n: int, rtol: float = 1e-13, atol: float = 1e-13) -> np.ndarray:
    """``P^n(x)`` by scipy's DOP853 on the naive field (the time-``n T`` map from ``t0``)."""
    f = NaiveField(params)
    sol = solve_ivp(f.rhs, (params.t0, params.t0 + n * params.period), np.asarray(x, float), method="DOP853",
                    rtol=rtol, atol=atol)  # fmt: skip
    assert sol.success, sol.message
    return sol.y[:, -1]


def fd_monodromy(params: Params, x, n: int, h: float = 1e-6) -> np.ndarray:
    """``DP^n(x)`` by central differences of :func:`ivp_map` (independent of the variational equations)."""
    x = np.asarray(x, float)
    cols = [(ivp_map(params, x + h * e, n) - ivp_map(params, x - h * e, n)) / (2 * h) for e in np.eye(2)]
    return np.column_stack(cols)


def ivp_monodromy(params: Params, x, n: int, rtol: float = 1e-13, atol: float = 1e-13) -> tuple[np.ndarray, np.ndarray]:
    """``(P^n(x), DP^n(x))`` by scipy's DOP853 on the naive field with ``Phi' = J Phi``, ``J`` by complex steps.

    Independent of the coefficient tables and of the engine: a reference for the monodromy matrix
    precise enough (~1e-12) to check the sign of a test function a few 1e-9 away from a bifurcation.
    """
    f = NaiveField(params)

    def rhs(t, y):
        jac = complex_step_jacobian(f, t, y[0], y[1])
        return np.concatenate([f.rhs(t, y[:2]), (jac @ y[2:].reshape(2, 2)).ravel()])

    y0 = np.concatenate([np.asarray(x, float), np.eye(2).ravel()])
    sol = solve_ivp(rhs, (params.t0, params.t0 + n * params.period), y0, method="DOP853", rtol=rtol, atol=atol)
    assert sol.success, sol.message
    return sol.y[:2, -1], sol.y[2:, -1].reshape(2, 2)


def ivp_fixed_point(params: Params, x, n: int, iterations: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Newton on ``P^n(x) - x`` with :func:`ivp_monodromy`: the orbit point and ``DP^n`` there."""
    x = np.asarray(x, float)
    for _ in range(iterations):
        end, a = ivp_monodromy(params, x, n)
        x = x - np.linalg.solve(a - np.eye(2), end - x)
    return x, ivp_monodromy(params, x, n)[1]


# ---------------------------------------------------------------------------
# Invariant manifolds (reference for explorer_core.analyses.manifolds).


def naive_segment_crossings(a, b) -> list[tuple[int, int, float, float]]:
    """Every ``(i, j, u, v)``: segment ``a[i] a[i+1]`` at fraction ``u`` in [0, 1) crosses ``b[j] b[j+1]`` at ``v``."""
    out = []
    for i in range(len(a) - 1):
        for j in range(len(b) - 1):
            (x1, y1), (x2, y2) = a[i], a[i + 1]
            (x3, y3), (x4, y4) = b[j], b[j + 1]
            den = (x2 - x1) * (y4 - y3) - (y2 - y1) * (x4 - x3)
            if den == 0:
                continue
            u = ((x3 - x1) * (y4 - y3) - (y3 - y1) * (x4 - x3)) / den
            v = ((x3 - x1) * (y2 - y1) - (y3 - y1) * (x2 - x1)) / den
            if 0 <= u < 1 and 0 <= v < 1:
                out.append((i, j, u, v))
    return out


def ivp_manifold_points(params: Params, x, v, mu: float, n: int, levels: int, count: int, delta: float, sign: int = 1):
    """Brute force: ``count`` points evenly on the segment ``x + sign s v``, ``s`` in ``[delta, |mu| delta)``,
    each mapped ``levels`` times by ``P^n`` (``mu``: the eigenvalue, expanding; ``n < 0`` maps backwards) with
    scipy's DOP853 on the naive field. Returns (levels, count, 2)."""
    s = delta * np.abs(mu) ** (np.arange(count) / count)
    pts = np.asarray(x, float)[None, :] + sign * s[:, None] * np.asarray(v, float)[None, :]
    out = []
    for _ in range(levels):
        pts = np.array([ivp_map(params, p, n, rtol=1e-12, atol=1e-12) for p in pts])
        out.append(pts)
    return np.array(out)


# ---------------------------------------------------------------------------
# Basins of attraction (reference for explorer_core.analyses.basins).


def ivp_fate(params: Params, ic, periods: int, bound: float, rtol: float = 1e-10, atol: float = 1e-10):
    """Section points ``k = 1..`` of one long trajectory by scipy's DOP853 on the naive field, to escape.

    Integrates period by period (no cell grid, no early stop, no engine); stops early only when
    ``max(|q|, |r|)`` passes ``bound`` (a terminal event). Returns ``(points (k, 2), escaped)``.
    """
    f = NaiveField(params)
    T = params.period

    def out(t, y):
        return bound - max(abs(y[0]), abs(y[1]))

    out.terminal = True
    y = np.asarray(ic, float)
    pts = []
    for k in range(periods):
        ta = params.t0 + k * T
        sol = solve_ivp(f.rhs, (ta, ta + T), y, method="DOP853", rtol=rtol, atol=atol, events=out)
        assert sol.status in (0, 1), sol.message
        if sol.status == 1:
            return np.array(pts).reshape(-1, 2), True
        y = sol.y[:, -1]
        pts.append(y.copy())
    return np.array(pts), False


def nearest_attractor(points: np.ndarray, escaped: bool, attractors: list[tuple[int, np.ndarray]], tail: int = 20):
    """Which of ``attractors`` (``(id, its points (m, 2))``) the end of a trajectory lies on, or -1 (escape).

    The trajectory's last ``tail`` section points are compared with each attractor's points: the one
    with the smallest largest-nearest-neighbour distance wins (a cycle: the distance is the convergence
    error; a chaotic attractor: the sampling gap). Returns ``(id, that distance)``; ``(-1, 0)`` if escaped.
    """
    if escaped:
        return -1, 0.0
    end = points[-tail:]
    best, dist = None, math.inf
    for ident, pts in attractors:
        d = np.linalg.norm(end[:, None, :] - pts[None, :, :], axis=-1).min(axis=1).max()
        if d < dist:
            best, dist = ident, float(d)
    return best, dist


# ---------------------------------------------------------------------------
# Taylor coefficients (reference for explorer_core.solve.taylor).


def sympy_taylor_coefficients(params: Params, t0: float, q0: float, r0: float, order: int) -> np.ndarray:
    """``(2, order + 1)``: the Taylor coefficients in ``tau`` of the solution through ``(q0, r0)`` at ``t0``.

    Picard iteration ``x <- x0 + int_0^tau f(x(s), t0 + s) ds`` on sympy series of the naive field (the
    Lagrange-d'Alembert equations with 3x3 matrices, ``g`` and ``g'`` by sympy's own derivatives, the
    multiplier's division by sympy's series; no coefficient tables): each iteration fixes one more
    coefficient, so ``order`` iterations give them all, in 40-digit floats, rounded to doubles at the end.
    """
    import sympy as sp

    tau = sp.Symbol("tau")
    digits = 40

    def num(v: float):
        return sp.Float(float(v), digits)

    p = params
    inertia = sp.Matrix(3, 3, [num(v) for v in np.asarray(p.inertia_matrix).ravel()])
    minv = inertia.inv()
    ts = sp.Symbol("t")
    g = num(p.g0) + num(p.g1) * sp.cos(num(p.omega) * ts) + num(p.g2) * sp.sin(num(p.omega) * ts)
    # Taylor series of g and g' at t0 by sympy's derivatives, evaluated in 40 digits.
    derivs = [g]
    for _ in range(order + 1):
        derivs.append(sp.diff(derivs[-1], ts))
    at = [sp.N(d.subs(ts, num(t0)), digits) for d in derivs]
    gs = sum(at[k] / sp.factorial(k) * tau**k for k in range(order + 1))
    gps = sum(at[k + 1] / sp.factorial(k) * tau**k for k in range(order + 1))

    def trunc(e):
        e = sp.expand(e)
        return sum(e.coeff(tau, k) * tau**k for k in range(order + 1))

    def field(qs, rs):
        om = sp.Matrix([num(p.alpha) + gs * qs, qs, rs])
        a = sp.Matrix([1, -gs, 0])
        euler = (minv * (inertia * om).cross(om)).applyfunc(trunc)
        minv_a = (minv * a).applyfunc(trunc)
        den = trunc((a.T * minv_a)[0])
        lam_num = trunc(-(a.T * euler)[0] + gps * qs)
        lam = trunc(sp.series(lam_num / den, tau, 0, order + 1).removeO())
        wd = euler + lam * minv_a
        return trunc(wd[1]), trunc(wd[2])

    qs, rs = num(q0), num(r0)
    for _ in range(order):
        fq, fr = field(qs, rs)
        qs = trunc(num(q0) + sp.integrate(fq, tau))
        rs = trunc(num(r0) + sp.integrate(fr, tau))
    out = np.empty((2, order + 1))
    for k in range(order + 1):
        out[0, k] = float(qs.coeff(tau, k))
        out[1, k] = float(rs.coeff(tau, k))
    return out


# ---------------------------------------------------------------------------
# The body's orientation (reference for explorer_core.analyses.body).


def ivp_body(params: Params, ic, t_start: float, t_eval, rtol: float = 1e-12, atol: float = 1e-12):
    """``(omega (F, 3), R (F, 3, 3))`` at the times ``t_eval`` by scipy's DOP853 on the full 3-D system.

    ``I omega' = (I omega) x omega + lambda a`` with all three components of ``omega`` integrated (``p`` is
    not eliminated: the constraint ``p = alpha + g q`` holds because ``lambda`` keeps ``df/dt = 0``), the
    multiplier from the current ``omega``, and the orientation as a 3x3 matrix, ``R' = R [omega]_x`` (body
    -> space), 3 + 9 equations. Starts at ``t_start`` from ``(q, r) = ic``, ``p = alpha + g q``, ``R = I``.
    No quaternion, no coefficient tables, no engine.
    """
    f = NaiveField(params)
    inertia, minv = f.inertia, f.minv

    def rhs(t, y):
        om = y[:3]
        rot = y[3:].reshape(3, 3)
        g, gp = f.g(t)
        a = np.array([1.0, -g, 0.0])
        euler = minv @ np.cross(inertia @ om, om)
        minv_a = minv @ a
        lam = (-(a @ euler) + gp * om[1]) / (a @ minv_a)
        skew = np.array([[0.0, -om[2], om[1]], [om[2], 0.0, -om[0]], [-om[1], om[0], 0.0]])
        return np.concatenate([euler + lam * minv_a, (rot @ skew).ravel()])

    g0, _ = f.g(t_start)
    y0 = np.concatenate([[params.alpha + g0 * ic[0], ic[0], ic[1]], np.eye(3).ravel()])
    t_eval = np.asarray(t_eval, float)
    sol = solve_ivp(rhs, (t_start, t_eval[-1]), y0, method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval)
    assert sol.success, sol.message
    return sol.y[:3].T, sol.y[3:].T.reshape(-1, 3, 3)


# ---------------------------------------------------------------------------
# The frozen field's equilibria (reference for explorer_core.analyses.equilibria and its kernels in
# explorer_core.analyses.conics): the plain-Python solver of two conics, lists and all, as it was before
# it became a numba kernel, the classification and the tracks' matching. The conics' coefficients are
# the input here (Model.coefficients), not recomputed.

_EPS = np.finfo(float).eps
# Candidate rotations (cos, sin); odd angles so that no axis-aligned or
# diagonal conic direction (q, r, q = +-r) falls on one of them.
_ROT = tuple((math.cos(0.377 + k * math.pi / 8), math.sin(0.377 + k * math.pi / 8)) for k in range(8))
# A resultant coefficient smaller than this times its absolute-value bound is noise.
_NOISE = 1e4 * _EPS
# Length floor of the residual scale (units of q, r): only matters at an exact root at the origin.
_L0 = 1e-12


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


def _empty(at_infinity: int, n_complex: int = 0, message: str = "") -> ConicSolution:
    return ConicSolution(np.zeros(0), np.zeros(0), at_infinity, n_complex, bool(message), message)


def naive_solve_conics(
    cq: Any,
    cr: Any,
    *,
    inf_norm: float = 1e8,
    imag_tol: float = 1e-5,
    accept_tol: float = 1e-9,
    dedupe_tol: float = 1e-7,
) -> ConicSolution:
    """The plain-Python ``equilibria.solve_conics``: the finite real intersections of two conics.

    The conics are ``c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2 = 0``.

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


def naive_equilibria(model: Model, t: float, inf_norm: float = 1e8, rtol: float = 1e-12) -> dict[str, Any]:
    """``equilibria(model, t)`` in plain Python: ``{"q", "r", "eigenvalues", "types", "at_infinity",
    "n_complex", "degenerate"}``."""
    c = model.coefficients(t)
    cq, cr = c[0].tolist(), c[1].tolist()
    sol = naive_solve_conics(cq, cr, inf_norm=inf_norm)
    eig = np.zeros((sol.q.size, 2), dtype=complex)
    types = []
    for i, (q, r) in enumerate(zip(sol.q.tolist(), sol.r.tolist(), strict=True)):
        j11 = cq[1] + 2.0 * cq[3] * q + cq[4] * r
        j12 = cq[2] + cq[4] * q + 2.0 * cq[5] * r
        j21 = cr[1] + 2.0 * cr[3] * q + cr[4] * r
        j22 = cr[2] + cr[4] * q + 2.0 * cr[5] * r
        eig[i] = _eig2(j11, j12, j21, j22)
        types.append(_type(j11, j12, j21, j22, rtol))
    return {
        "q": sol.q,
        "r": sol.r,
        "eigenvalues": eig,
        "types": tuple(types),
        "at_infinity": sol.at_infinity,
        "n_complex": sol.n_complex,
        "degenerate": sol.degenerate,
    }


def _compact(x: tuple[float, float]) -> tuple[float, float]:
    s = 1.0 / (1.0 + math.hypot(x[0], x[1]))
    return x[0] * s, x[1] * s


def naive_match(a: list, b: list, jump: float) -> tuple[list[tuple[int, int]], bool]:
    """``equilibria._match`` as it was: every assignment tried, the first of least total ``min(d, jump)``."""
    if not a or not b:
        return [], len(a) == len(b)
    ca = [_compact(x) for x in a]
    cb = [_compact(y) for y in b]
    d = [[math.hypot(x[0] - y[0], x[1] - y[1]) for y in cb] for x in ca]
    if len(a) <= len(b):
        perms = itertools.permutations(range(len(b)), len(a))
        best = min(perms, key=lambda p: sum(min(d[i][j], jump) for i, j in enumerate(p)))
        assign = list(enumerate(best))
    else:
        perms = itertools.permutations(range(len(a)), len(b))
        best = min(perms, key=lambda p: sum(min(d[i][j], jump) for j, i in enumerate(p)))
        assign = [(i, j) for j, i in enumerate(best)]
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


def naive_tracks(
    model: Model,
    n_t: int,
    t_start: float | None = None,
    jump: float = 0.05,
    max_depth: int = 12,
    max_refine: int | None = None,
    inf_norm: float = 1e8,
) -> dict[str, np.ndarray]:
    """``equilibrium_tracks`` in plain Python, one frozen time at a time: ``{"branch", "t", "q", "r",
    "sample_t", "sample_count"}`` (rows sorted by branch, then time)."""
    max_refine = 4 * n_t if max_refine is None else max_refine
    t_start = model.params.t0 if t_start is None else t_start
    period = model.params.period
    cache: dict[float, list[tuple[float, float]]] = {}

    def solve(t: float) -> list[tuple[float, float]]:
        if t not in cache:
            e = naive_equilibria(model, t, inf_norm)
            cache[t] = list(zip(e["q"].tolist(), e["r"].tolist(), strict=True))
        return cache[t]

    grid = (t_start + period * np.linspace(0.0, 1.0, n_t)).tolist()
    grid[-1] = t_start + period
    links: dict[tuple[float, int], tuple[float, int]] = {}
    budget = max_refine
    for k in range(n_t - 1):
        stack = [(grid[k], grid[k + 1], 0)]
        while stack:
            ta, tb, depth = stack.pop()
            pairs, clear = naive_match(solve(ta), solve(tb), jump)
            tm = 0.5 * (ta + tb)
            if not clear and depth < max_depth and budget > 0 and ta < tm < tb:
                budget -= 1
                stack.append((tm, tb, depth + 1))
                stack.append((ta, tm, depth + 1))
                continue
            if not clear:
                pairs, _ = naive_match(solve(ta), solve(tb), max(jump, 0.5))
            for i, j in pairs:
                links[(ta, i)] = (tb, j)
    times = sorted(cache)
    branch_of: dict[tuple[float, int], int] = {}
    rows: list[tuple[int, float, int]] = []
    n_branches = 0
    for t in times:
        for i in range(len(cache[t])):
            if (t, i) not in branch_of:
                branch_of[(t, i)] = n_branches
                n_branches += 1
            rows.append((branch_of[(t, i)], t, i))
            nxt = links.get((t, i))
            if nxt is not None:
                branch_of[nxt] = branch_of[(t, i)]
    rows.sort()
    return {
        "branch": np.array([b for b, _, _ in rows], dtype=np.int64),
        "t": np.array([t for _, t, _ in rows]),
        "q": np.array([cache[t][i][0] for _, t, i in rows]),
        "r": np.array([cache[t][i][1] for _, t, i in rows]),
        "sample_t": np.array(times),
        "sample_count": np.array([len(cache[t]) for t in times], dtype=np.int64),
    }


def naive_basin_entropy(labels: Any, valid: Any, box: int) -> tuple[float | None, float | None, int, int, int]:
    """Basin entropy S_b and boundary basin entropy S_bb (Daza et al., Sci. Rep. 6, 31416 (2016)) box by box, cell by
    cell: whole ``box x box`` boxes from cell (0, 0), a box with an invalid cell skipped. Returns ``(S_b, S_bb, N,
    N_b, skipped)``, None where there is no box (no boundary box)."""
    ny, nx = len(labels), len(labels[0])
    total, n, nb, skipped = 0.0, 0, 0, 0
    for j0 in range(0, ny - box + 1, box):
        for i0 in range(0, nx - box + 1, box):
            cells = [(j, i) for j in range(j0, j0 + box) for i in range(i0, i0 + box)]
            if not all(valid[j][i] for j, i in cells):
                skipped += 1
                continue
            count: dict[int, int] = {}
            for j, i in cells:
                count[int(labels[j][i])] = count.get(int(labels[j][i]), 0) + 1
            s = 0.0
            for c in count.values():
                p = c / len(cells)
                s -= p * math.log(p)
            total += s
            n += 1
            nb += len(count) > 1
    return (total / n if n else None), (total / nb if nb else None), n, nb, skipped


def naive_uncertain_fraction(labels: Any, valid: Any, eps: list[int]) -> list[tuple[int, int]]:
    """``(judged, uncertain)`` at every distance ``k`` of ``eps``: a cell at least ``max(eps)`` from every edge, valid
    with its four neighbours ``k`` cells away along the axes, is uncertain when one of them has another label."""
    ny, nx, m = len(labels), len(labels[0]), max(eps)
    out = []
    for k in eps:
        judged = uncertain = 0
        for j in range(m, ny - m):
            for i in range(m, nx - m):
                near = [(j, i + k), (j, i - k), (j + k, i), (j - k, i)]
                if not valid[j][i] or not all(valid[a][b] for a, b in near):
                    continue
                judged += 1
                uncertain += any(labels[a][b] != labels[j][i] for a, b in near)
        out.append((judged, uncertain))
    return out


# --- chaos indicators (explorer_core.analyses.indicators, ftle): plain loops, no numpy vector arithmetic ---------


def naive_weighted_birkhoff(values) -> float:
    """``sum w(n/N) f_n / sum w(n/N)`` with ``w(t) = exp(-1/(t(1-t)))`` (Das et al. 2017), term by term."""
    n = len(values)
    num = den = 0.0
    for k in range(1, n):
        t = k / n
        w = math.exp(-1.0 / (t * (1.0 - t)))
        num += w * float(values[k])
        den += w
    return num / den


def naive_birkhoff_digits(values) -> float:
    """``-log10 |WB_N(first half) - WB_N(second half)|`` (16 when they agree to the last bit)."""
    n = len(values) // 2
    d = abs(naive_weighted_birkhoff(values[:n]) - naive_weighted_birkhoff(values[n : 2 * n]))
    return 16.0 if d == 0.0 else min(16.0, -math.log10(d))


def naive_rotation_number(points) -> float:
    """Rotation number in [0, 1) of points (n, 2) about their weighted average: the weighted average of the angle
    increments, each brought into (-pi, pi] by adding or subtracting whole turns."""
    cq = naive_weighted_birkhoff([p[0] for p in points])
    cr = naive_weighted_birkhoff([p[1] for p in points])
    incs = []
    for a, b in itertools.pairwise(points):
        d = math.atan2(b[1] - cr, b[0] - cq) - math.atan2(a[1] - cr, a[0] - cq)
        while d > math.pi:
            d -= 2.0 * math.pi
        while d <= -math.pi:
            d += 2.0 * math.pi
        incs.append(d)
    return (naive_weighted_birkhoff(incs) / (2.0 * math.pi)) % 1.0


def naive_sali(jacobians, u1=(1.0, 0.0), u2=(0.0, 1.0)) -> tuple[list[float], list[float]]:
    """SALI and GALI_2 after each of the 2x2 matrices ``jacobians`` applied in turn to two unit vectors, each
    renormalised after every step (Skokos 2001; Skokos et al. 2007)."""
    a, b = list(u1), list(u2)
    sali, gali = [], []
    for m in jacobians:
        a = [m[0][0] * a[0] + m[0][1] * a[1], m[1][0] * a[0] + m[1][1] * a[1]]
        b = [m[0][0] * b[0] + m[0][1] * b[1], m[1][0] * b[0] + m[1][1] * b[1]]
        na, nb = math.hypot(a[0], a[1]), math.hypot(b[0], b[1])
        a, b = [a[0] / na, a[1] / na], [b[0] / nb, b[1] / nb]
        sali.append(min(math.hypot(a[0] + b[0], a[1] + b[1]), math.hypot(a[0] - b[0], a[1] - b[1])))
        gali.append(abs(a[0] * b[1] - a[1] * b[0]))
    return sali, gali


def naive_ftle(jacobians, v=(1.0, 0.0)) -> float:
    """Largest finite-time exponent per step of the product of ``jacobians``: the log growth of one vector,
    renormalised after every step, averaged."""
    x, y = v
    total = 0.0
    for m in jacobians:
        x, y = m[0][0] * x + m[0][1] * y, m[1][0] * x + m[1][1] * y
        n = math.hypot(x, y)
        total += math.log(n)
        x, y = x / n, y / n
    return total / len(jacobians)
