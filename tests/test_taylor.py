"""Taylor's method (explorer_core.solve.taylor) against independent computations.

Its series against sympy's (tests/naive.py: Picard iteration on the naive field), its sections against
solve_ivp at 1e-13, convergence as the tolerance falls, the statuses, and results that do not depend on
where a range of periods ends, the block or the number of workers.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from naive import ivp_map, sympy_taylor_coefficients

from explorer_core.scenes import get_scene
from explorer_core.solve import rk
from explorer_core.solve.integrators import Batch, advance, coefficients, get_method, run
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.rk import Status
from explorer_core.solve.taylor import MAX_ORDER, series_at, taylor_order
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

#: A general tensor (fig8B's) and a forcing with every term and another frequency: all table entries used.
GENERAL = Params(inertia=(1.0, 2.0, 4.0, 0.5, 0.3, 0.1), alpha=-0.45, g0=0.2, g1=0.9, g2=0.3, omega=1.7, t0=0.4)
REGULAR = Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1)


@pytest.mark.parametrize(("params", "t0", "q0", "r0"), [(REGULAR, 0.3, 0.5, -0.7), (GENERAL, 2.0, -1.2, 1.9)],
                         ids=["diagonal", "general"])  # fmt: skip
def test_series_match_sympy(params: Params, t0: float, q0: float, r0: float) -> None:
    order = 7  # sympy's series of the multiplier's quotient takes most of a minute at this order
    co = coefficients(Model(params), n=1)
    ref = sympy_taylor_coefficients(params, t0, q0, r0, order)
    ours = series_at(co, 0, t0, q0, r0, order)
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-13 * float(np.abs(ref).max()))
    assert np.all(np.abs(ref[:, -1]) > 1e-8)  # the highest order is not trivially zero


def test_order_follows_the_tolerance() -> None:
    assert taylor_order(1e-6) == 8 and taylor_order(1e-10) == 13 and taylor_order(1e-15) == 19
    assert taylor_order(1.0) == 2
    for bad in (0.0, -1e-6, math.nan, 2.0, "1e-6"):
        with pytest.raises(ValueError, match="rtol"):
            taylor_order(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=str(MAX_ORDER)):
        taylor_order(1e-40)


@pytest.mark.parametrize("params", [REGULAR, GENERAL, get_scene("fig8B").params], ids=["regular", "general", "fig8B"])
def test_sections_match_solve_ivp(params: Params) -> None:
    ics = np.array([[0.3, 0.2], [-0.8, 0.6], [0.05, -1.1]])
    n = 8
    for block in (1, 8):
        b = Batch.start(ics, params.t0, params.period)
        out, npts = advance(Model(params), b, n, method="taylor", rtol=1e-14, atol=1e-14, workers=1, block=block)
        assert np.all(b.status == 0) and np.all(npts == n)
        for i, ic in enumerate(ics):
            for k in (1, n):
                np.testing.assert_allclose(out[i, k - 1], ivp_map(params, ic, k), rtol=0, atol=2e-10)


def test_error_falls_with_the_tolerance() -> None:
    ics = np.array([[0.3, 0.2], [0.5, -0.4]])
    n = 20
    ref = np.array([ivp_map(REGULAR, ic, n) for ic in ics])
    errors, steps = [], []
    for tol in (1e-5, 1e-7, 1e-9, 1e-11):
        b = Batch.start(ics, REGULAR.t0, REGULAR.period)
        out, _ = advance(Model(REGULAR), b, n, method="taylor", rtol=tol, atol=tol, workers=1, block=1)
        errors.append(float(np.max(np.abs(out[:, -1] - ref))))
        steps.append(int(b.nsteps.sum()))
        assert errors[-1] <= 1e3 * tol, (tol, errors[-1])  # 20 periods, ~25 steps each
    assert all(a > b for a, b in itertools.pairwise(errors)), errors
    assert errors[-1] < 1e-9


def test_a_range_of_periods_split_anywhere_gives_the_same_bits() -> None:
    # Every period starts afresh at its section time: where a call ends changes nothing.
    ics = np.array([[0.3, 0.2], [-0.8, 0.6], [0.05, -1.1], [1.0, 1.0]])
    model = Model(GENERAL)
    whole = Batch.start(ics, GENERAL.t0, GENERAL.period)
    out, _ = advance(model, whole, 10, method="taylor", rtol=1e-11, atol=1e-11, workers=1, block=4)
    parts = Batch.start(ics, GENERAL.t0, GENERAL.period)
    first, _ = advance(model, parts, 3, method="taylor", rtol=1e-11, atol=1e-11, workers=1, block=4)
    second, _ = advance(model, parts, 7, method="taylor", rtol=1e-11, atol=1e-11, workers=1, block=4)
    np.testing.assert_array_equal(np.concatenate([first, second], axis=1), out)
    np.testing.assert_array_equal(parts.y, whole.y)
    assert parts.k == whole.k == 10


def test_workers_do_not_change_the_result_and_blocks_only_within_the_tolerance() -> None:
    rng = np.random.default_rng(3)
    ics = rng.uniform(-1.0, 1.0, (40, 2))
    model = Model(REGULAR)
    outs = {}
    for block, workers in ((1, 1), (16, 1), (16, 2)):
        b = Batch.start(ics, REGULAR.t0, REGULAR.period)
        outs[block, workers], _ = advance(model, b, 5, method="taylor", rtol=1e-12, atol=1e-12, workers=workers,
                                          block=block)  # fmt: skip
        assert np.all(b.status == 0)
    np.testing.assert_array_equal(outs[16, 1], outs[16, 2])
    np.testing.assert_allclose(outs[16, 1], outs[1, 1], rtol=0, atol=1e-10)


def test_per_member_parameters_in_one_block() -> None:
    # Members with different parameter sets in one lock-step block: each as if run alone.
    ps = [REGULAR, Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.3), GENERAL.__class__(
        inertia=GENERAL.inertia, alpha=0.2, g0=0.2, g1=0.9, g2=0.3, omega=1.0, t0=0.0)]  # fmt: skip
    models = [Model(p) for p in ps]
    ics = np.array([[0.3, 0.2], [0.3, 0.2], [-0.5, 0.4], [0.1, 0.9]])
    rows = np.array([0, 1, 2, 0])
    co = coefficients(models, rows)
    b = Batch.start(ics, 0.0, 2 * math.pi)
    rec, npts = run(rk.FIELD, co, b, 4, method="taylor", rtol=1e-13, atol=1e-13, workers=1, block=4)
    assert np.all(npts == 4)
    for i in range(ics.shape[0]):
        np.testing.assert_allclose(rec[i, -1], ivp_map(ps[rows[i]], ics[i], 4), rtol=0, atol=1e-10)


def test_statuses_as_the_engine() -> None:
    drift = get_scene("fig1A").params
    model = Model(drift)
    # On the noncompact drift (the bench's drift case, r falls by ~0.3 per period); outside; in the island.
    ics = np.array([[0.750728, -17.75087], [50.0, 50.0], [0.3, 0.2]])
    for meth in ("dop853", "taylor"):
        b = Batch.start(ics, drift.t0, drift.period)
        out, npts = advance(model, b, 80, method=meth, rtol=1e-10, atol=1e-10, bound=30.0, workers=1, block=1)
        assert list(b.status) == [Status.ESCAPED, Status.ESCAPED, Status.OK], (meth, b.status)
        assert npts[1] == 0 and 0 < npts[0] < 80 and npts[2] == 80
        np.testing.assert_array_equal(b.y[0], out[0, npts[0] - 1])  # the last section state is kept
        np.testing.assert_array_equal(b.y[1], ics[1])
    # The step budget: 10 steps cannot cover a period at 1e-14.
    b = Batch.start(ics[2:], drift.t0, drift.period)
    _, npts = advance(model, b, 3, method="taylor", rtol=1e-14, atol=1e-14, max_steps=10, workers=1, block=1)
    assert b.status[0] == Status.TOO_MANY_STEPS and npts[0] == 0 and b.nsteps[0] == 10
    np.testing.assert_array_equal(b.y[0], ics[2])
    # A state so large that its series overflow: nonfinite, never a silent inf.
    b = Batch.start(np.array([[1e150, 1e150], [0.3, 0.2]]), drift.t0, drift.period)
    _, npts = advance(model, b, 2, method="taylor", rtol=1e-10, atol=1e-10, bound=math.inf, workers=1, block=2)
    assert list(b.status) == [Status.NONFINITE, Status.OK] and list(npts) == [0, 2]
    # A non-finite initial condition never runs.
    b = Batch.start(np.array([[math.nan, 0.0]]), drift.t0, drift.period)
    advance(model, b, 2, method="taylor", workers=1, block=1)
    assert b.status[0] == Status.NONFINITE and b.nsteps[0] == 0


def test_backward_in_time_returns_to_the_start() -> None:
    ics = np.array([[0.3, 0.2], [-0.8, 0.6]])
    model = Model(GENERAL)
    b = Batch.start(ics, GENERAL.t0, GENERAL.period)
    advance(model, b, 3, method="taylor", rtol=1e-14, atol=1e-14, workers=1, block=1)
    back = Batch.start(b.y, GENERAL.t0, -GENERAL.period, k=-3)
    advance(model, back, 3, method="taylor", rtol=1e-14, atol=1e-14, workers=1, block=1)
    np.testing.assert_allclose(back.y, ics, rtol=0, atol=1e-11)


def test_taylor_is_a_method_the_numerics_accept() -> None:
    num = Numerics(method="TAYLOR", rtol=1e-12, atol=1e-12)
    assert num.method == "taylor" and num.kernel_kwargs()["adaptive"] is True
    assert get_method("taylor").kind == "taylor"
    b = Batch.start(np.array([[0.3, 0.2]]), 0.0, 2 * math.pi)
    with pytest.raises(ValueError, match="fixed-step"):
        advance(Model(REGULAR), b, 1, method="taylor", adaptive=False)
    bt = Batch.start(np.array([[0.3, 0.2]]), 0.0, 2 * math.pi, dim=rk.STATE_SIZE[rk.TANGENT])
    with pytest.raises(ParameterError, match="sections only"):
        run(rk.TANGENT, coefficients(Model(REGULAR), n=1), bt, 1, method="taylor")
    with pytest.raises(ParameterError, match="unknown method"):
        Numerics(method="taylor2")
