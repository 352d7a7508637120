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
