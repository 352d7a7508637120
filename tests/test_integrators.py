"""Integrator kernels: tableaus, agreement with slow references, order, status."""

from __future__ import annotations

import numpy as np
import pytest
from naive import rk4_section, solve_ivp_section
from scipy.integrate._ivp import dop853_coefficients, rk

from explorer_core.solve import tableaus
from explorer_core.solve.integrators import METHODS, Batch, Status, advance
from explorer_core.system.model import Model
from explorer_core.system.params import Params

FIG1C = Params(inertia=(1, 4, 2, 0, 0, 0), alpha=0.1)
REGULAR_IC = (0.32, 0.688)


@pytest.mark.parametrize("name", ["rk4", "dp5", "dop853", "vern9"])
def test_tableau_invariants(name: str) -> None:
    m = METHODS[name]
    assert m.b.sum() == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(m.a.sum(axis=1), m.c, atol=1e-14)
    assert np.all(np.triu(m.a) == 0.0), "explicit methods only"
    if m.adaptive:
        # Error weights of an embedded pair sum to zero (both solutions are consistent).
        for e in (m.e, m.e3, m.e5):
            assert e.sum() == pytest.approx(0.0, abs=1e-14)


def test_tableaus_equal_published_values() -> None:
    np.testing.assert_array_equal(tableaus.DP5_B, rk.RK45.B)
    np.testing.assert_array_equal(tableaus.DP5_E, rk.RK45.E)
    np.testing.assert_array_equal(tableaus.DOP853_A, dop853_coefficients.A[:12, :12])
    np.testing.assert_array_equal(tableaus.DOP853_E5, dop853_coefficients.E5)


def _run(params: Params, ics, periods: int, **kw) -> tuple[np.ndarray, np.ndarray, Batch]:
    batch = Batch.start(np.atleast_2d(ics), params.t0, params.period)
    out, npts = advance(Model(params), batch, periods, **kw)
    return out, npts, batch


def test_rk4_kernel_matches_plain_python_rk4() -> None:
    params = Params(inertia=(1, 2, 4, 0, 0.5, 0.3), alpha=-0.2, g0=0.1, g2=0.4, omega=1.5, t0=0.3)
    out, npts, _ = _run(params, [0.4, -0.3], 3, method="rk4", steps_per_period=50)
    ref = rk4_section(params, [0.4, -0.3], 3, 50)
    np.testing.assert_allclose(out[0], ref, rtol=1e-12, atol=1e-13)


def test_rk4_lock_step_blocks_match_plain_python_rk4_per_trajectory() -> None:
    # More trajectories than one RK4 block, some failing (overflow at once, escapes at
    # different periods) so members leave the packed range while the others go on.
    rng = np.random.default_rng(7)
    ics = np.concatenate([rng.uniform(-1.5, 1.5, (70, 2)), [[1e200, 1e200]], [[0.0, 13.5], [0.0, 14.0]]])
    out, npts, batch = _run(FIG1A, ics, 30, method="rk4", steps_per_period=40, bound=20.0)
    assert batch.status[70] == Status.NONFINITE and npts[70] == 0
    assert batch.status[71] == batch.status[72] == Status.ESCAPED and npts[71] > npts[72]
    for i in (*range(0, 70, 7), 71, 72):
        ref = rk4_section(FIG1A, ics[i], int(npts[i]), 40)
        np.testing.assert_allclose(out[i, : npts[i]], ref, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize(
    ("method", "steps", "lo", "hi"),
    [
        ("rk4", [40, 80, 160, 320], 3.7, 4.5),
        ("dp5", [40, 80, 160], 4.6, 5.6),
        ("dop853", [10, 14, 20, 28], 7.5, 9.8),
        ("vern9", [8, 11, 16, 22], 8.3, 10.5),
    ],
)
def test_measured_convergence_order(method: str, steps: list[int], lo: float, hi: float) -> None:
    ref = solve_ivp_section(FIG1C, REGULAR_IC, 5, rtol=2.3e-14, atol=1e-14)
    errs = []
    for n in steps:
        out, _, _ = _run(FIG1C, REGULAR_IC, 5, method=method, adaptive=False, steps_per_period=n)
        errs.append(np.abs(out[0] - ref).max())
    order = -np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert lo <= order <= hi, (order, errs)


@pytest.mark.parametrize("method", ["dp5", "dop853", "vern9"])
def test_adaptive_error_follows_tolerance(method: str) -> None:
    ref = solve_ivp_section(FIG1C, REGULAR_IC, 20, rtol=1e-13, atol=1e-13)
    errs = []
    for tol in (1e-6, 1e-8, 1e-10):
        out, _, batch = _run(FIG1C, REGULAR_IC, 20, method=method, rtol=tol, atol=tol)
        assert batch.status[0] == Status.OK
        errs.append(np.abs(out[0] - ref).max())
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-7


def test_batch_split_across_threads_is_bitwise_identical() -> None:
    rng = np.random.default_rng(5)
    ics = rng.uniform(-1, 1, (37, 2))
    a, na, ba = _run(FIG1C, ics, 6, workers=1)
    b, nb_, bb = _run(FIG1C, ics, 6, workers=2)
    np.testing.assert_array_equal(na, nb_)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ba.nsteps, bb.nsteps)


# --- failures are data ------------------------------------------------------------

FIG1A = Params(inertia=(1, 2, 4, 0, 0, 0), alpha=0.1)


@pytest.mark.parametrize("method", ["rk4", "dp5", "dop853"])
def test_drift_beyond_bound_is_flagged_escaped(method: str) -> None:
    # Fig. 3's initial condition: inside a period the state passes 11 within 3 periods for every method (when
    # it passes 20, in the chaotic sea, depends on the method's digits: rk4 met that bound or not by luck).
    out, npts, batch = _run(FIG1A, [0.0, 8.0], 200, method=method, bound=11.0, steps_per_period=400)
    assert batch.status[0] == Status.ESCAPED
    assert 0 < npts[0] < 200
    valid = out[0, : npts[0]]
    assert np.all(np.isfinite(valid)) and np.all(np.abs(valid) <= 11.0)


def test_step_budget_exhaustion_is_flagged() -> None:
    _, npts, batch = _run(FIG1C, REGULAR_IC, 5, method="dop853", max_steps=10, rtol=1e-12, atol=1e-12)
    assert batch.status[0] == Status.TOO_MANY_STEPS
    assert npts[0] == 0


def test_step_collapse_is_flagged() -> None:
    # A state of 1e13 with no escape bound needs a step below the round-off floor of the time: it must be seen
    # to collapse. (A huge t0 no longer does: it is reduced exactly to its phase, tests/test_time_exact.py.)
    _, npts, batch = _run(FIG1C, [1e13, 1e13], 3, method="dop853", bound=np.inf)
    assert batch.status[0] == Status.STEP_COLLAPSED
    assert npts[0] == 0


@pytest.mark.parametrize("method", ["dp5", "dop853"])
def test_overflow_is_flagged_nonfinite(method: str) -> None:
    out, npts, batch = _run(FIG1A, [[1e155, 1e155], [0.1, 0.2]], 2, method=method, bound=np.inf)
    assert batch.status.tolist() == [Status.NONFINITE, Status.OK]
    assert npts.tolist() == [0, 2]
    assert np.all(np.isfinite(out[1]))


def test_rk4_overflow_is_flagged_nonfinite() -> None:
    _, npts, batch = _run(FIG1A, [1e150, 1e150], 3, method="rk4", steps_per_period=4, bound=np.inf)
    assert batch.status[0] == Status.NONFINITE
    assert npts[0] == 0


def test_nonfinite_initial_condition_never_runs() -> None:
    batch = Batch.start(np.array([[np.nan, 0.0], [0.1, 0.1]]), 0.0, FIG1C.period)
    _, npts = advance(Model(FIG1C), batch, 2)
    assert batch.status.tolist() == [Status.NONFINITE, Status.OK]
    assert npts.tolist() == [0, 2]


# --- the lock-step block kernel ---------------------------------------------------------


@pytest.mark.parametrize("method", ["dp5", "dop853", "vern9"])
def test_block_kernel_meets_tolerance_like_the_single_one(method: str) -> None:
    ics = np.array([REGULAR_IC, (0.94, 1.238), (0.2, -0.5), (-1.0, 0.3)])
    ref = np.stack([solve_ivp_section(FIG1C, ic, 30, rtol=1e-13, atol=1e-13) for ic in ics])
    blk, _, bb = _run(FIG1C, ics, 30, method=method, rtol=1e-10, atol=1e-10, block=16)
    one, _, b1 = _run(FIG1C, ics, 30, method=method, rtol=1e-10, atol=1e-10, block=1)
    assert np.abs(blk - ref).max() < 1e-7 and np.abs(one - ref).max() < 1e-7
    # One step sequence for the block: every member takes as many steps as the fastest.
    assert len(set(bb.nsteps.tolist())) == 1 and bb.nsteps[0] >= b1.nsteps.max()


def test_failure_in_a_block_does_not_stop_the_others() -> None:
    ics = np.array([[0.0, 8.0], REGULAR_IC, [1e155, 1e155], (0.2, -0.5)])
    out, npts, batch = _run(FIG1A, ics, 200, rtol=1e-8, atol=1e-8, bound=20.0, block=16)
    assert batch.status.tolist() == [Status.ESCAPED, Status.OK, Status.NONFINITE, Status.OK]
    assert npts[1] == npts[3] == 200 and 0 < npts[0] < 200 and npts[2] == 0
    single, _, _ = _run(FIG1A, ics[[1, 3]], 200, rtol=1e-8, atol=1e-8, block=1)
    np.testing.assert_allclose(out[[1, 3]], single, atol=1e-5)


def test_block_results_do_not_depend_on_worker_count() -> None:
    ics = np.random.default_rng(2).uniform(-2, 2, (50, 2))
    a, _, ba = _run(FIG1C, ics, 8, block=16, workers=1)
    b, _, bb = _run(FIG1C, ics, 8, block=16, workers=2)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ba.nsteps, bb.nsteps)


def test_block_packs_out_members_that_fail_at_different_times() -> None:
    # Members leave the packed live range one by one (escape at different k, overflow at
    # once); every survivor must still follow its own trajectory, as with block=1.
    rng = np.random.default_rng(5)
    regular = np.column_stack([rng.uniform(-1.5, 1.5, 30), rng.uniform(-0.5, 0.5, 30)])
    # Above the chaotic layer of Fig. 1A the drift is regular: these escape at k = 20, 15, 10.
    drift = np.column_stack([np.zeros(3), [10.0, 10.5714, 11.1429]])
    ics = np.concatenate([regular[:10], drift[:2], [[1e155, 1e155]], regular[10:], drift[2:]])
    out, npts, batch = _run(FIG1A, ics, 60, rtol=1e-9, atol=1e-9, bound=16.0, block=32)
    single, snpts, sb = _run(FIG1A, ics, 60, rtol=1e-9, atol=1e-9, bound=16.0, block=1)
    np.testing.assert_array_equal(batch.status, sb.status)
    assert np.count_nonzero(batch.status == Status.ESCAPED) == 3
    assert batch.status[12] == Status.NONFINITE
    esc = np.flatnonzero(batch.status == Status.ESCAPED)
    assert len(set(npts[esc].tolist())) == 3  # they left at different periods
    np.testing.assert_array_equal(npts[esc], snpts[esc])
    ok = np.flatnonzero(batch.status == Status.OK)
    assert np.all(npts[ok] == 60)
    np.testing.assert_allclose(out[ok], single[ok], atol=1e-6)


# --- the one engine: per-member parameters, methods as data ---------------------------------------


def test_a_lock_step_block_of_members_with_different_parameters_meets_each_ones_reference() -> None:
    from explorer_core.solve.integrators import coefficients, run, run_at
    from explorer_core.solve.rk import FIELD

    systems = [FIG1C, FIG1C.with_(alpha=0.2), FIG1C.with_(inertia=(1.5, 4, 2, 0.1, 0, 0.2), alpha=-0.1)]
    ics = np.array([REGULAR_IC, (0.2, -0.5), (0.4, 0.3), (-0.3, 0.1)])
    rows = np.array([0, 1, 2, 1])
    batch = Batch.start(ics, FIG1C.t0, FIG1C.period)
    out, npts = run(FIELD, coefficients([Model(p) for p in systems], rows), batch, 12, rtol=1e-11, atol=1e-11,
                    block=4, workers=1)  # fmt: skip
    assert npts.tolist() == [12] * 4
    assert len(set(batch.nsteps.tolist())) == 1  # one block, one step sequence
    for i, r in enumerate(rows):
        ref = solve_ivp_section(systems[r], ics[i], 12, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(out[i], ref, atol=1e-8)
    # run_at groups by section times and gives the same points
    end, rec, status, _ = run_at(FIELD, [systems[r] for r in rows], ics, 12, rtol=1e-11, atol=1e-11, block=4,
                                 workers=1)  # fmt: skip
    assert np.all(status == Status.OK)
    np.testing.assert_array_equal(rec, out)


def test_members_with_other_section_times_cannot_share_a_block() -> None:
    from explorer_core.solve.integrators import coefficients

    with pytest.raises(ValueError, match="share the section times"):
        coefficients([Model(FIG1C), Model(FIG1C.with_(omega=2.0))], np.array([0, 1]))


def test_a_tableau_that_breaks_the_order_conditions_is_refused() -> None:
    from explorer_core.solve.tableaus import Method

    with pytest.raises(ValueError, match=r"sum\(b\)"):
        Method("bad", 4, False, tableaus.RK4_A, tableaus.RK4_B * 1.01, tableaus.RK4_C)
    with pytest.raises(ValueError, match="rows of a do not sum to c"):
        Method("bad", 4, False, tableaus.RK4_A, tableaus.RK4_B, tableaus.RK4_C + 0.1)
    with pytest.raises(ValueError, match="error weights"):
        Method("bad", 5, True, tableaus.DP5_A, tableaus.DP5_B, tableaus.DP5_C, 4, e=tableaus.DP5_E + 0.1)


# --- Verner's 9(8) pair ---------------------------------------------------------------------


def _rooted_trees(order: int) -> dict[int, list[tuple]]:
    """The rooted trees with up to ``order`` nodes: ``trees[n][i]`` is the tuple of the keys ``(n', i')`` of its
    children (a multiset, keys non-increasing), so every tree appears once (1, 1, 2, 4, 9, 20, 48, 115, 286)."""
    trees: dict[int, list[tuple]] = {1: [()]}
    keys = [(1, 0)]

    def forests(total: int, top: tuple[int, int]):
        if total == 0:
            yield ()
            return
        for key in sorted((k for k in keys if k <= top and k[0] <= total), reverse=True):
            for rest in forests(total - key[0], key):
                yield (key, *rest)

    for n in range(2, order + 1):
        trees[n] = list(forests(n - 1, (n, 0)))
        keys = sorted(keys + [(n, i) for i in range(len(trees[n]))])
    return trees


def _worst_order_condition(a: np.ndarray, b: np.ndarray, order: int) -> float:
    """The largest ``|gamma(t) b . Phi(t) - 1|`` over the rooted trees ``t`` with up to ``order`` nodes (Butcher)."""
    trees = _rooted_trees(order)
    phi: dict[tuple[int, int], np.ndarray] = {}
    gamma: dict[tuple[int, int], int] = {}
    worst = 0.0
    for n in range(1, order + 1):
        for i, children in enumerate(trees[n]):
            v = np.ones(b.shape[0])
            g = n
            for k in children:
                v = v * (a @ phi[k])
                g *= gamma[k]
            phi[(n, i)], gamma[(n, i)] = v, g
            worst = max(worst, abs(g * float(b @ v) - 1.0))
    return worst


def test_tree_count() -> None:
    assert [len(t) for t in _rooted_trees(9).values()] == [1, 1, 2, 4, 9, 20, 48, 115, 286]


def test_vern9_satisfies_every_order_condition_through_nine() -> None:
    m = METHODS["vern9"]
    s = m.stages
    # The 486 conditions of order <= 9 for b and the 200 of order <= 8 for the embedded b_hat = b - e; the next
    # order fails (the orders are what the pair claims, and the check can fail: DOP853's b is order 8 only).
    assert _worst_order_condition(m.a, m.b, 9) < 1e-13
    assert _worst_order_condition(m.a, m.b, 10) > 1e-3
    assert _worst_order_condition(m.a, m.b - m.e[:s], 8) < 1e-13
    assert _worst_order_condition(m.a, m.b - m.e[:s], 9) > 1e-3
    assert m.e[s] == 0.0  # not FSAL: the extra stage f(t + h, y_new) is not in the estimate
    d = METHODS["dop853"]
    assert _worst_order_condition(d.a, d.b, 8) < 1e-13 and _worst_order_condition(d.a, d.b, 9) > 1e-3


def test_vern9_agrees_with_solve_ivp_and_heyoka_and_needs_fewer_evaluations_than_dop853() -> None:
    ics = np.array([REGULAR_IC, (0.2, -0.5), (-0.7, 0.4)])
    ref = np.stack([solve_ivp_section(FIG1C, ic, 40, rtol=1e-13, atol=1e-13) for ic in ics])
    v9, _, bv = _run(FIG1C, ics, 40, method="vern9", rtol=1e-12, atol=1e-12, block=1)
    d8, _, bd = _run(FIG1C, ics, 40, method="dop853", rtol=1e-12, atol=1e-12, block=1)
    assert np.all(bv.status == Status.OK)
    assert np.abs(v9 - ref).max() < 1e-10
    # Work by counts (load-independent): 16 evaluations a step against DOP853's 12, fewer in all at 1e-12.
    assert 16 * bv.nsteps.sum() < 0.95 * 12 * bd.nsteps.sum()
    hy = pytest.importorskip("heyoka")
    del hy
    from explorer_core.studies import bench

    href = np.array(bench._peer_heyoka(Model(FIG1C), ics, 40, "batch", 1e-16)[0])
    err_v9, err_d8 = np.abs(v9 - href).max(), np.abs(d8 - href).max()
    assert err_v9 < 1e-10 and err_v9 < 2.0 * err_d8


def test_vern9_monodromy_matches_finite_differences_of_the_map() -> None:
    from naive import fd_monodromy

    from explorer_core.solve import tangent
    from explorer_core.solve.integrators import coefficients
    from explorer_core.solve.numerics import Numerics

    x = np.array([[0.2, -0.5], [REGULAR_IC[0], REGULAR_IC[1]]])
    num = Numerics(method="vern9", rtol=1e-12, atol=1e-12)
    mono = tangent.monodromy(coefficients(Model(FIG1C), n=2), x, 3, FIG1C.t0, FIG1C.period, num)
    assert np.all(mono.ok)
    for j in range(2):
        fd = fd_monodromy(FIG1C, x[j], 3)
        np.testing.assert_allclose(mono.matrix[j], fd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("method", ["dop853", "vern9", "rk4"])
def test_the_map_does_not_depend_on_when_it_starts(method: str) -> None:
    """The forcing is periodic, so ``P^n`` from section ``k`` is one map for every ``k``: the engine keeps time
    inside the period, and the same points come out to the bit whether the run starts at t = 0 or 10^4 periods
    later. Before (time kept as t0 + k T + t), stage times were rounded to ulp(t) ~ 1e-11 at t ~ 6e4: the
    same 100-period map from k = 10^4 was 1.4e-10 off at rtol 1e-13, with more steps (heyoka: 5e-12)."""
    ics = np.array([[0.3, -0.2], [-0.7, 0.5], [0.1, 0.9]])
    runs = []
    for k in (0, 10_000):
        batch = Batch.start(ics, FIG1C.t0, FIG1C.period, k=k)
        out, npts = advance(Model(FIG1C), batch, 30, method=method, rtol=1e-13, atol=1e-13, steps_per_period=200)
        runs.append((out, npts, batch.nsteps.copy()))
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    # and the points are the map's (solve_ivp at 1e-13 from t0)
    ref = solve_ivp_section(FIG1C, ics[0], 30, rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(runs[1][0][0] - ref)) < (1e-8 if method == "rk4" else 1e-9)  # rk4: 200 fixed steps
