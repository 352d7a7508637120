"""Charts' early stops: the work they save (load-independent counts) and that they do not depend on when a member
is looked at."""

from __future__ import annotations

import numpy as np
import pytest

from explorer_core.analyses import regimes
from explorer_core.analyses.regimes import PERIODIC, chart_spec, compute_tile, compute_tile_each, plan_tiles
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import coefficients
from explorer_core.system.model import Model

FIG11 = get_scene("fig11").params
ICS = [(-0.09, -2.0), (-0.5, -1.0)]


def _spec(x_range=(-0.6, -0.36), grid=(8, 5), transient=150, periods=100):
    return chart_spec(FIG11, "alpha", x_range, "I11", (1.0, 2.0), grid, ics=ICS, transient=transient, periods=periods)


def _asked(monkeypatch) -> list[tuple[int, int]]:
    """Record every point handed to Newton: (period asked, least period of the attracting cycle found or 0)."""
    seen: list[tuple[int, int]] = []
    real = regimes.settled_cycles

    def spy(coefs, x, p, *a, **kw):
        out = real(coefs, x, p, *a, **kw)
        ps = np.broadcast_to(np.asarray(p), (len(out),))
        seen.extend((int(q), 0 if c is None else c[0]) for q, c in zip(ps, out, strict=True))
        return out

    monkeypatch.setattr(regimes, "settled_cycles", spy)
    return seen


def test_members_spiralling_onto_a_fixed_point_hand_over_to_newton_on_the_map_itself(monkeypatch) -> None:
    """Period-1 members that return best after 2, 3, 5 ... iterations (a rotation near 1/p around the fixed point)
    are handed to Newton on ``P``, not ``P^p``: Newton integrates one period per iteration, not p. (Before: 1.6
    periods asked per point found, most on P^3.)"""
    spec = _spec(x_range=(-0.4, -0.36), grid=(4, 3))
    asked = _asked(monkeypatch)
    found = 0
    for t in plan_tiles(spec.shape, 4, 16):
        res = compute_tile(spec, t)
        found += int(((res.regime == PERIODIC) & (res.period == 1)).sum())
    assert found >= 12
    one = [p for p, least in asked if least == 1]
    assert len(one) >= found and sum(one) <= 1.1 * len(one), sorted(one)


def test_verdicts_do_not_depend_on_how_often_members_are_looked_at(monkeypatch) -> None:
    """Metamorphic: looking for cycles every 5 periods instead of every 10 changes when a member stops, not what it
    is. Regimes, periods, statuses and the exponents of every member that ran to the end or was decided chaotic
    are the same to the bit (the chaos bounds are taken over the same blocks at the same periods); a cycle's
    exponent is its own, the same cycle's to Newton's accuracy."""
    spec = _spec()
    tiles = plan_tiles(spec.shape, 4, 16)
    a = [compute_tile(spec, t) for t in tiles]
    monkeypatch.setattr(regimes, "SETTLE_CHUNK", 5)
    b = [compute_tile(spec, t) for t in tiles]
    stopped_sooner = 0
    for x, y in zip(a, b, strict=True):
        for name in ("regime", "period", "status"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
        per = x.regime == PERIODIC
        np.testing.assert_array_equal(x.lyap[~per], y.lyap[~per])
        np.testing.assert_allclose(x.lyap[per], y.lyap[per], rtol=1e-6)
        stopped_sooner += int((y.periods_run[per] < x.periods_run[per]).sum())
    assert stopped_sooner > 10


def test_work_counts_and_the_reference() -> None:
    """Every member of the reference runs transient + periods (unless it escaped); early stops run fewer."""
    spec = _spec(grid=(4, 3), transient=60, periods=40)
    t = plan_tiles(spec.shape, 4, 64)[0]
    a, b = compute_tile(spec, t), compute_tile_each(spec, t)
    whole = b.regime != regimes.ESCAPED
    assert np.all(b.periods_run[whole] == 100) and np.all(b.steps[whole] > 100 * 10)
    assert np.all(a.periods_run <= b.periods_run) and a.steps.sum() < b.steps.sum()


def test_settled_cycles_take_one_period_per_point() -> None:
    """One Newton for points asked with different periods gives what one Newton per period gives."""
    at = get_scene("fig10").params.with_(alpha=-0.35)
    seed = np.array([[-0.0959, -1.962], [-0.0959, -1.962], [-0.0959, -1.962]])
    co = coefficients(Model(at), n=3)
    mixed = regimes.settled_cycles(co, seed, np.array([1, 2, 3]), at.t0, at.period)
    for k, p in enumerate((1, 2, 3)):
        alone = regimes.settled_cycles(coefficients(Model(at), n=1), seed[k : k + 1], p, at.t0, at.period)[0]
        assert mixed[k] is not None and mixed[k][0] == alone[0] == 1
        assert mixed[k][1] == pytest.approx(alone[1], rel=1e-12)


@pytest.mark.parametrize("p_max", [1, 2, 16])
def test_cycles_stop_early_whatever_the_longest_period(p_max: int) -> None:
    """A member on the period-1 cycle stops early even when the ring of points is shorter than SETTLE_POINTS
    returns (p_max < 4: the ring holds 3 p_max points)."""
    spec = chart_spec(FIG11, "alpha", (-0.36, -0.35), "I11", (1.0, 1.1), (2, 2), ics=ICS[:1], transient=150,
                      periods=100, p_max=p_max)  # fmt: skip
    for t in plan_tiles(spec.shape, 1, 64):
        res = compute_tile(spec, t)
        assert np.all(res.regime == PERIODIC) and np.all(res.period == 1)
        assert np.all(res.periods_run <= 30), res.periods_run


def _codes(regime: np.ndarray, period: np.ndarray) -> np.ndarray:
    return np.where(regime == PERIODIC, period.astype(np.int64), -regime.astype(np.int64))


def test_early_stops_agree_with_the_whole_run_off_the_boundaries() -> None:
    """Where the reference (every member the whole way) has the same regime and period at a pixel and its eight
    neighbours for an initial condition, stopping early must give that regime and period too: early stops may
    differ only where the regime changes (transient chaos, cycles the reference's tail had not converged on).
    (Chaos decided from 30 periods, or SETTLE_TOL 0.3, break it: 5 and 7 differences.)"""
    spec = _spec(grid=(10, 8))
    ny, nx = spec.shape
    early = np.zeros((ny, nx, 2), dtype=np.int64)
    ref = np.zeros_like(early)
    for t in plan_tiles(spec.shape, 4, 64):
        a, b = compute_tile(spec, t), compute_tile_each(spec, t)
        early[a.jj, a.ii] = _codes(a.regime, a.period)
        ref[b.jj, b.ii] = _codes(b.regime, b.period)
    interior = np.zeros_like(ref, dtype=bool)
    for j in range(ny):
        for i in range(nx):
            block = ref[max(0, j - 1) : j + 2, max(0, i - 1) : i + 2]
            interior[j, i] = np.all(block == ref[j, i][None, None, :], axis=(0, 1))
    assert interior.sum() >= 40
    np.testing.assert_array_equal(early[interior], ref[interior])
    assert np.count_nonzero(early != ref) <= 3, np.argwhere(early != ref)


@pytest.mark.parametrize(("window", "done", "transient"), [(3, 95, 100), (48, 40, 0), (4, 500, 600)])
def test_a_chunks_records_go_where_the_loop_over_periods_put_them(window: int, done: int, transient: int) -> None:
    # The loop the tile ran before (frozen reference): period by period, the ring slot written once per period, so a
    # chunk longer than the ring leaves each slot with its latest period. Members that failed stop recording.
    rng = np.random.default_rng(7)
    n, step, total = 9, 10, 700
    rec = rng.normal(size=(6, step, 5))
    npts = np.array([10, 0, 3, 10, 7, 1])
    live = np.array([8, 0, 3, 5, 2, 7])

    def arrays() -> tuple[np.ndarray, ...]:
        return np.zeros((n, window, 2)), np.zeros((n, total)), np.zeros((n, total, 2)), np.arange(n) * 2

    recent, every, points, measured = arrays()
    for c in range(step):
        kk = done + c
        ok = npts > c
        recent[live[ok], kk % window] = rec[ok, c, :2]
        every[live[ok], kk] = rec[ok, c, 2]
        if kk >= transient:
            points[live[ok], kk - transient] = rec[ok, c, :2]
            measured[live[ok]] += 1
    got = arrays()
    regimes._record(rec, npts, live, done, transient, *got)
    for a, b in zip(got, (recent, every, points, measured), strict=True):
        np.testing.assert_array_equal(a, b)
