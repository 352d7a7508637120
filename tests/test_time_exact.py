"""A large section phase ``t0`` is its phase reduced exactly: the engine's clock starts at ``t0 mod T``.

References are independent of the code under test: the reduction by mpmath at 50 digits, and scipy's DOP853
at tolerance 1e-13 on the naive field started at the reduced phase.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from naive import solve_ivp_section

from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import section
from explorer_core.system.params import Params, reduce_time

FIG8B = Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1, g1=1.0, omega=1.0)
ICS = np.array([[0.3, 0.2], [0.5, -0.1], [-0.4, 0.3]])


def _mp_reduced(t: float, omega: float) -> float:
    """``t`` less ``trunc(t / T)`` periods ``T = 2 pi / omega``, at 50 digits."""
    with mpmath.workdps(50):
        period = 2 * mpmath.pi / mpmath.mpf(omega)
        x = mpmath.mpf(t)
        return float(x - int(x / period) * period)


@pytest.mark.parametrize("omega", [1.0, 0.8, 3.7, 1e-3])
@pytest.mark.parametrize("t", [1e11, -1e11, 4.3e12, 123456.789, 2.0**40 + 0.5, -7.25])
def test_reduction_equals_fifty_digit_arithmetic(t: float, omega: float) -> None:
    got = reduce_time(t, omega)
    assert got == _mp_reduced(t, omega)
    assert abs(got) < 2 * math.pi / omega and (got == 0.0 or math.copysign(1, got) == math.copysign(1, t))


def test_a_phase_within_one_period_is_kept_bit_for_bit() -> None:
    for t in (0.0, -0.0, 1.1, -1.1, math.nextafter(2 * math.pi, 0.0), 0.5e-300):
        assert reduce_time(t, 1.0) == t and math.copysign(1, reduce_time(t, 1.0)) == math.copysign(1, t)
    assert Params(t0=-1.1, omega=0.8).phase == -1.1
    # No period (a constant or a test's forcing table): nothing to reduce.
    assert reduce_time(1e11, 0.0) == 1e11 and reduce_time(1e11, math.inf) == 1e11


@pytest.mark.parametrize(
    "numerics",
    [Numerics(), Numerics(method="dop853", rtol=1e-8, atol=1e-8), Numerics(method="rk4", steps_per_period=400)],
    ids=["default", "dop853-1e-8", "rk4"],
)
def test_a_section_at_t0_1e11_is_the_reduced_phases_to_the_tolerance(numerics: Numerics) -> None:
    # Before: the default run collapsed its steps (step_collapsed) and the others were ok with errors of
    # 4e-6 (dop853 1e-8) and 3e-7 (rk4), the stage times rounded to ulp(1e11) = 1.5e-5.
    params = FIG8B.with_(t0=1e11)
    reduced = FIG8B.with_(t0=_mp_reduced(1e11, FIG8B.omega))
    sec = section(params, ICS, 20, numerics=numerics)
    assert sec.status_labels() == ["ok"] * 3
    budget = {"default": 1e-8, "dop853-1e-8": 1e-6, "rk4": 3e-8}[
        "default" if numerics == Numerics() else "rk4" if numerics.method == "rk4" else "dop853-1e-8"
    ]
    for i, ic in enumerate(ICS):
        ref = solve_ivp_section(reduced, ic, 20, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(sec.points[i], ref, rtol=0, atol=budget)
    # And the same run as from the reduced phase itself, to the last bit.
    np.testing.assert_array_equal(sec.points, section(reduced, ICS, 20, numerics=numerics).points)


def test_the_tangent_system_at_a_large_t0_is_the_reduced_phases() -> None:
    # Lyapunov exponents run the tangent system through the same clock.
    params = FIG8B.with_(t0=-3e10)
    reduced = FIG8B.with_(t0=_mp_reduced(-3e10, FIG8B.omega))
    a = lyapunov_spectrum(params, ICS[:2], 30, numerics=Numerics(method="rk4", steps_per_period=200))
    b = lyapunov_spectrum(reduced, ICS[:2], 30, numerics=Numerics(method="rk4", steps_per_period=200))
    np.testing.assert_array_equal(a.exponents, b.exponents)


# --- The model evaluated at a user's time: T' map, equilibria (one time, tracks), the symmetry's field check ----

FIG10ISH = Params(inertia=(1.0, 4.0, 2.0, 0.3, 0.0, 0.0), alpha=0.2, g1=1.1, g2=0.4, omega=0.8)
BIG = [1e11, -3.7e10, 2.0**36 + 0.25]


def test_reduce_times_equals_fifty_digit_arithmetic_on_a_grid() -> None:
    from explorer_core.system.params import reduce_times

    for t0 in [*BIG, 2.5]:
        ts = t0 + FIG10ISH.period * np.linspace(0.0, 1.0, 9)
        got = reduce_times(ts, FIG10ISH.omega)
        m = int(mpmath.mpf(float(ts[0])) / (2 * mpmath.pi / FIG10ISH.omega))
        with mpmath.workdps(50):
            want = [float(mpmath.mpf(float(t)) - m * 2 * mpmath.pi / mpmath.mpf(FIG10ISH.omega)) for t in ts]
        assert np.allclose(got, want, rtol=0, atol=4e-16 * FIG10ISH.period), (t0, got - want)


@pytest.mark.parametrize("t", BIG)
def test_the_tprime_map_at_a_large_t_is_the_reduced_phases(t: float) -> None:
    """T' at t = 1e11 was evaluated with cos(omega t) of a double t: an error of ~1e-5 in g."""
    from explorer_core.analyses.tprime import tprime_map

    big = tprime_map(FIG10ISH, t, (-2, 2), (-2, 2), 40)
    small = tprime_map(FIG10ISH, _mp_reduced(t, FIG10ISH.omega), (-2, 2), (-2, 2), 40)
    scale = np.abs(small.values).max()
    assert np.allclose(big.values, small.values, rtol=0, atol=1e-13 * scale)


@pytest.mark.parametrize("t", BIG)
def test_equilibria_at_a_large_t_are_the_reduced_phases(t: float) -> None:
    from explorer_core.analyses.equilibria import equilibria, equilibrium_tracks

    big, small = equilibria(FIG10ISH, t), equilibria(FIG10ISH, _mp_reduced(t, FIG10ISH.omega))
    assert len(big) == len(small) > 0
    assert np.allclose(big.q, small.q, rtol=0, atol=1e-11) and np.allclose(big.r, small.r, rtol=0, atol=1e-11)
    # Tracked over the period from t: the same branches at the same phases; the rows say the user's times.
    tb = equilibrium_tracks(FIG10ISH, 60, t)
    ts = equilibrium_tracks(FIG10ISH, 60, _mp_reduced(t, FIG10ISH.omega))
    assert tb.t_start == t and tb.rows_at(t).size == ts.rows_at(ts.t_start).size > 0
    assert tb.q.size == ts.q.size and tb.n_branches == ts.n_branches
    assert np.allclose(tb.q, ts.q, rtol=0, atol=1e-10) and np.allclose(tb.r, ts.r, rtol=0, atol=1e-10)
    assert np.allclose(tb.t - t, ts.t - ts.t_start, rtol=0, atol=4 * np.spacing(abs(t)))


def test_the_symmetry_checks_at_a_large_centre_are_those_at_its_phase() -> None:
    """The field identities and g's evenness about s are properties of s's phase: at s = 1e11 (2 s - t once
    rounded to 3e-5, sin(omega s) to 1e-5) they give what they give at the phase, for a centre of the
    involution and for a time that is not one."""
    from explorer_core.analyses.symmetry import field_residual, g_is_even_about

    rev = Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1, g1=1.0, g2=0.5, omega=1.0)
    centre = math.atan2(rev.g2, rev.g1)  # g even about it
    for m in (1.6e10, 3e9):
        whole = float(mpmath.mpf(m) * 2 * mpmath.pi)  # ~m periods, as a double: its phase is ~ulp(whole)
        for s in (whole, whole + 1.0):
            phase = _mp_reduced(s, rev.omega)
            assert field_residual(rev, s) == pytest.approx(field_residual(rev, phase), rel=1e-6, abs=1e-14)
            assert g_is_even_about(rev, s) == g_is_even_about(rev, phase)
    assert g_is_even_about(rev, centre) and field_residual(rev, centre) < 1e-13
    assert not g_is_even_about(rev, centre + 1.0) and field_residual(rev, centre + 1.0) > 1e-3
