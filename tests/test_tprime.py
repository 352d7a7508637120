"""T' = alpha * lambda: against the naive field, the energy's derivative, the full 3-D system."""

from __future__ import annotations

import numpy as np
import pytest
from naive import NaiveField
from scipy.integrate import solve_ivp

from explorer_core.analyses.tprime import energy_change_map, tprime_map
from explorer_core.solve.numerics import Numerics
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

GENERAL = Params(inertia=(1, 2, 4, 0, 0.5, 0.3), alpha=-0.45, g0=0.1, g2=0.3, omega=1.2, t0=0.4)


def test_instantaneous_map_matches_naive_multiplier() -> None:
    m = tprime_map(GENERAL, 0.9, (-2, 1), (-3, 0.5), (31, 17))
    assert m.values.shape == (17, 31)
    nf = NaiveField(GENERAL)
    for j, i in [(0, 0), (5, 30), (16, 7), (8, 15)]:
        _, lam = nf.omega_dot(0.9, m.q[i], m.r[j])
        assert m.values[j, i] == pytest.approx(GENERAL.alpha * lam, rel=1e-10, abs=1e-12)
    f = m.fractions()
    assert f["gain"] + f["loss"] == pytest.approx(1.0) and f["failed"] == 0.0


def test_tprime_is_the_derivative_of_energy_along_a_trajectory() -> None:
    model = Model(GENERAL)
    nf = NaiveField(GENERAL)
    sol = solve_ivp(nf.rhs, (0.4, 3.0), [0.3, -0.5], method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    h = 1e-5
    for t in np.linspace(0.6, 2.8, 9):
        e = [nf.energy(tt, *sol.sol(tt)) for tt in (t - h, t + h)]
        deriv = (e[1] - e[0]) / (2 * h)
        assert model.tprime(*sol.sol(t), t) == pytest.approx(deriv, rel=1e-6, abs=1e-8)


def test_full_three_dimensional_system_keeps_the_constraint_and_agrees() -> None:
    """Integrate I w' = (I w) x w + lambda a for (p, q, r): p - g q - alpha stays 0, (q, r) match."""
    nf = NaiveField(GENERAL)

    def full(t, w):
        om = np.asarray(w)
        g, gp = nf.g(t)
        a = np.array([1.0, -g, 0.0])
        euler = nf.minv @ np.cross(nf.inertia @ om, om)
        lam = (-(a @ euler) + gp * om[1]) / (a @ nf.minv @ a)
        return euler + lam * nf.minv @ a

    q0, r0 = 0.3, -0.5
    g0, _ = nf.g(0.4)
    t_end = 0.4 + 3 * GENERAL.period
    full_sol = solve_ivp(
        full,
        (0.4, t_end),
        [GENERAL.alpha + g0 * q0, q0, r0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    model = Model(GENERAL)
    red = solve_ivp(
        lambda t, y: list(model.field(y[0], y[1], t)),
        (0.4, t_end),
        [q0, r0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    for t in np.linspace(0.4, t_end, 25):
        p, q, r = full_sol.sol(t)
        g, _ = nf.g(t)
        assert abs(p - g * q - GENERAL.alpha) < 1e-9
        np.testing.assert_allclose(red.sol(t), [q, r], atol=1e-8)


def test_per_period_energy_change_equals_integral_of_tprime() -> None:
    m = energy_change_map(GENERAL, (-1, 0.5), (-2, 0), 5, numerics=Numerics(rtol=1e-12, atol=1e-12))
    model = Model(GENERAL)
    nf = NaiveField(GENERAL)

    def aug(t, y):
        return [*nf.rhs(t, y[:2]), float(model.tprime(y[0], y[1], t))]

    for j, i in [(0, 0), (2, 3), (4, 4)]:
        sol = solve_ivp(
            aug,
            (GENERAL.t0, GENERAL.t0 + GENERAL.period),
            [m.q[i], m.r[j], 0.0],
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
        )
        assert m.ok[j, i]
        assert m.values[j, i] == pytest.approx(sol.y[2, -1], rel=1e-7, abs=1e-9)


def test_failed_cells_are_flagged_not_nan() -> None:
    p = Params(inertia=(1, 2, 4, 0, 0, 0), alpha=0.1)
    m = energy_change_map(p, (-1, 1), (-1, 12), 6, numerics=Numerics(bound=5.0))
    assert not m.ok.all() and m.ok.any()
    assert np.all(np.isfinite(m.values))
    assert np.all(m.values[~m.ok] == 0) and np.all(m.sign[~m.ok] == 0)
    assert np.all(m.status[~m.ok] == 1)  # escaped


def test_energy_conserved_at_alpha_zero() -> None:
    p = Params(inertia=(1, 2, 4, 0, 0.5, 0.3), alpha=0.0)
    assert np.all(tprime_map(p, 0.3, (-2, 2), (-2, 2), 20).values == 0.0)
    m = energy_change_map(p, (-1, 1), (-1, 1), 6, numerics=Numerics(rtol=1e-12, atol=1e-12))
    assert np.abs(m.values).max() < 1e-9


def test_npz_round_trip(tmp_path) -> None:
    m = tprime_map(GENERAL, 0.0, (-1, 1), (-1, 1), 8)
    path = tmp_path / "t.npz"
    m.to_npz(str(path))
    with np.load(path) as z:
        np.testing.assert_array_equal(z["values"], m.values)
        np.testing.assert_array_equal(z["sign"], m.sign)
        assert str(z["kind"]) == "instantaneous"


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"grid": 1}, "grid must be between 2"),
        ({"grid": 10**6}, "grid must be between 2"),
        ({"q_range": (1, 0)}, "q_range must be finite with lo < hi"),
        ({"r_range": (0, float("inf"))}, "r_range"),
        ({"t": float("nan")}, "t must be finite"),
    ],
)
def test_bad_grid_inputs(kw, needle) -> None:
    args = {"t": 0.0, "q_range": (-1, 1), "r_range": (-1, 1), "grid": 10} | kw
    with pytest.raises(ParameterError, match=needle):
        tprime_map(GENERAL, **args)
