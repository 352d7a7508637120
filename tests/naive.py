"""Slow, obviously-correct reference implementations the fast code is tested against.

None of these use the polynomial coefficient tables or the numba kernels: the
field comes straight from I w' = (I w) x w + lambda a with 3x3 linear algebra.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from explorer_core.model import Params


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
