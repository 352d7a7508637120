"""Slow, obviously-correct reference implementations the fast code is tested against.

None of these use the polynomial coefficient tables or the numba kernels: the
field comes straight from I w' = (I w) x w + lambda a with 3x3 linear algebra.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

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
