"""The one recurrence module (:mod:`explorer_core.solve.recurrence`).

(a) Each preset gives, bit for bit, what the detector it replaced gave: those detectors are copied below verbatim
(frozen references, from main c3075ef) and run on random points, exact cycles with decaying transients, noise at
the tolerance, exact ties, NaN and infinite points and short windows. (b) The issue's case, every preset's answer
written down. (c) No second detector: an ``ast`` scan of ``explorer_core/`` and ``app/`` for a function that
takes the distance between an array and itself shifted by a loop variable (the period); it flags each of the
frozen references and none of the wrappers that replaced them.
"""

from __future__ import annotations

import ast
import inspect
import math
from pathlib import Path

import numpy as np
import pytest

from explorer_core.analyses import basins, bifurcation, orbits, regimes
from explorer_core.analyses.sweeps import detect_period
from explorer_core.solve import recurrence as rec
from explorer_core.solve.recurrence import (
    CHART,
    DIAGRAM,
    NEAR,
    PLAY,
    PRESETS,
    SEEDS,
    SWEEP,
    RecurrenceRule,
    recurrence,
)
from explorer_core.system.params import ParameterError

ROOT = Path(__file__).resolve().parents[1]
#: The old detectors subtract infinite points (inf - inf: NaN, with numpy's warning).
pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")

# ---------------------------------------------------------------------------------------------------------------
# Frozen references: the seven detectors as they were (bodies verbatim; module constants inlined by name).

SETTLE_WINDOW, SETTLE_P_MAX = 8, 16  # bifurcation's
SETTLED, NEAR_PLAY, SETTLED_TAIL = 1e-3, 5e-2, 3  # app/layers/orbits.py's
_SEARCH = 0  # basins'


def old_detect_period(points: np.ndarray, p_max: int, tol: float) -> int:
    pts = np.asarray(points, dtype=float)
    m = pts.shape[0]
    for p in range(1, min(p_max, m - 1) + 1):
        d = np.abs(pts[p:] - pts[:-p]).max()
        if d <= tol:
            return p
    return 0


def old_returns(rings: np.ndarray, p_max: int) -> np.ndarray:
    n = rings.shape[1]
    d = np.empty((rings.shape[0], max(0, min(p_max, n - 1))))
    for p in range(1, d.shape[1] + 1):  # slices, not an index array: ~20x faster at 48 points
        d[:, p - 1] = np.abs(rings[:, p:] - rings[:, :-p]).max(axis=(1, 2))
    return d


def old_first_return(d: np.ndarray, tol: np.ndarray) -> np.ndarray:
    hit = d <= np.asarray(tol)[:, None]
    return np.where(hit.any(axis=1), hit.argmax(axis=1) + 1, 0)


def old_near_returns(rings: np.ndarray, p_max: int, pairs: int) -> np.ndarray:
    m, n = rings.shape[:2]
    d = np.full((m, p_max), np.inf)
    for p in range(1, min(p_max, n - pairs) + 1):
        d[:, p - 1] = np.abs(rings[:, n - pairs :] - rings[:, n - pairs - p : n - p]).max(axis=(1, 2))
    return d


def old_repeat_period(x: np.ndarray, tol: float) -> int:
    m = x.shape[0]
    for p in range(1, SETTLE_P_MAX + 1):
        if m < p + SETTLE_WINDOW:
            break
        a, b = x[m - SETTLE_WINDOW :], x[m - SETTLE_WINDOW - p : m - p]
        if np.all(np.abs(a - b) <= tol * (1.0 + np.abs(a))):
            return p
    return 0


def old_basin_returns(ring: np.ndarray, state: np.ndarray, slots: np.ndarray, window: int, p_max: int, tol: float,
                      out: np.ndarray, nan_fails: bool = False) -> None:  # fmt: skip
    # (a numba kernel; run as Python here: the same arithmetic. ``nan_fails``: a NaN distance fails, as in the
    # rule; the kernel let it pass, since ``nan > lim`` is False)
    w = ring.shape[1]
    for m in range(slots.shape[0]):
        s = slots[m]
        out[m] = 0
        n = state[s, 10]
        if n < window or state[s, 0] != _SEARCH:
            continue
        big = 0.0
        for j in range(window):
            pos = (n - 1 - j) % w
            big = max(big, abs(ring[s, pos, 0]), abs(ring[s, pos, 1]))
        lim = tol * (1.0 + big)
        for p in range(1, p_max + 1):
            ok = True
            for j in range(window - p):
                a = (n - 1 - j) % w
                b = (n - 1 - j - p) % w
                if abs(ring[s, a, 0] - ring[s, b, 0]) > lim or abs(ring[s, a, 1] - ring[s, b, 1]) > lim:
                    ok = False
                    break
                dq, dr = abs(ring[s, a, 0] - ring[s, b, 0]), abs(ring[s, a, 1] - ring[s, b, 1])
                if nan_fails and not (dq <= lim and dr <= lim):
                    ok = False
                    break
            if ok:
                out[m] = p
                break


def old_settled_cycles(traj: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray,
                       max_period: int) -> list[tuple[float, float, int]]:  # fmt: skip
    need = SETTLED_TAIL + max_period
    if max_period < 1 or traj.size == 0:
        return []
    order = np.lexsort((k, traj))
    t_sorted = traj[order]
    ends = np.flatnonzero(np.r_[t_sorted[1:] != t_sorted[:-1], True])  # the last point of each trajectory
    starts = np.r_[0, ends[:-1] + 1]
    ends = ends[ends - starts + 1 >= need]
    if ends.size == 0:
        return []
    idx = order[ends[:, None] + np.arange(1 - need, 1)]  # (trajectories, need): each one's last points, in k order
    x = np.stack([q[idx], r[idx]], axis=-1)
    last = x[:, -SETTLED_TAIL:]
    tol = SETTLED * (1.0 + np.abs(last).max(axis=2))
    period = np.zeros(x.shape[0], dtype=int)  # 0: not settled (yet)
    for n in range(max_period, 0, -1):  # the least period wins
        before = x[:, need - SETTLED_TAIL - n : need - n]
        with np.errstate(invalid="ignore"):
            ok = np.all(np.linalg.norm(last - before, axis=2) < tol, axis=1)
        period[ok] = n
    out: list[tuple[float, float, int]] = []
    tails: list[np.ndarray] = []  # the points of each cycle found (a second trajectory on it adds nothing)
    for i in np.flatnonzero(period):
        n, end = int(period[i]), x[i, -1]
        scale = NEAR_PLAY * (1.0 + float(np.abs(end).max()))
        if not any(np.linalg.norm(c - end, axis=1).min() < scale for c in tails):
            tails.append(x[i, -n:])
            out.append((float(end[0]), float(end[1]), n))
    return out


def old_return_seeds(points: np.ndarray, npts: np.ndarray, max_period: int, tol: float) -> list[tuple[np.ndarray, int]]:
    out = []
    for t in range(points.shape[0]):
        x = points[t, : int(npts[t])]
        for n in range(1, max_period + 1):
            if x.shape[0] <= n:
                break
            d = np.linalg.norm(x[n:] - x[:-n], axis=1)
            k = int(np.argmin(d))
            if d[k] <= tol:
                out.append((x[k].copy(), n))
    return out


OLD = (old_detect_period, old_returns, old_near_returns, old_repeat_period, old_basin_returns, old_settled_cycles,
       old_return_seeds)  # fmt: skip

# ---------------------------------------------------------------------------------------------------------------
# Inputs.

#: Relative tolerances tried (the chart's 1e-5, the diagram's 1e-9 and jump 1e-3, NEAR's 3e-2, PLAY's 1e-3 ...).
TOLS = (0.0, 1e-12, 1e-9, 1e-6, 1e-5, 1e-3, 3e-2, 0.5)


def trajectory(rng: np.random.Generator, n: int) -> np.ndarray:
    """One of: random points, an exact cycle with a decaying transient, a cycle plus noise near a tolerance,
    small integers (exact ties with integer tolerances), with NaN or infinite points, at |x| ~ 1 or ~ 50."""
    kind = rng.integers(7)
    size = (1.0, 50.0)[rng.integers(2)]
    if kind == 0:
        return rng.normal(size=(n, 2)) * size
    p = int(rng.integers(1, 7))
    cycle = rng.normal(size=(p, 2)) * size
    x = cycle[np.arange(n) % p]
    if kind in (1, 4, 5):  # decaying transient, down to the tolerances tried
        lam = rng.uniform(0.3, 0.97)
        x = x + rng.normal(size=2) * size * lam ** np.arange(n)[:, None]
    if kind == 2:  # noise of the size of a tolerance
        x = x + rng.uniform(-1, 1, size=(n, 2)) * (1 + np.abs(x)) * TOLS[rng.integers(1, len(TOLS))]
    if kind == 3:  # small integers: distances equal to integer tolerances
        x = rng.integers(-3, 4, size=(n, 2)).astype(float)
        x[n // 2 :] = x[n // 2 :][np.arange(n - n // 2) % p]
    if kind == 4 and n:
        x[rng.integers(n, size=rng.integers(1, 3))] = np.nan
    if kind == 5 and n:
        x[rng.integers(n, size=rng.integers(1, 3)), rng.integers(2)] = (np.inf, -np.inf)[rng.integers(2)]
    return x


def trajectories(seed: int, count: int, lengths: tuple[int, int] = (0, 70)) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [trajectory(rng, int(rng.integers(*lengths))) for _ in range(count)]


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Bit for bit (NaN where NaN)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype.kind == b.dtype.kind and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


# ---------------------------------------------------------------------------------------------------------------
# (a) Each preset is the detector it replaced, bit for bit.


@pytest.mark.parametrize("seed", range(4))
def test_sweep_is_detect_period(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    for x in trajectories(seed, 300):
        for tol in (*TOLS, 1.0, 2.0, 3.0):  # integer tolerances: ties with the integer points
            p_max = int(rng.integers(0, 20))
            want = old_detect_period(x, p_max, tol)
            assert detect_period(x, p_max, tol) == want
            assert recurrence(x, SWEEP, tol=tol, p_max=p_max).period == want


@pytest.mark.parametrize("seed", range(4))
def test_chart_is_the_chart_s_returns_and_its_classification(seed: int) -> None:
    """The early look over the ring (``first_return(returns(..))`` once the ring is full, its distances too) and
    the final classification (``detect_period`` at ``tol (1 + max |x|)``), as ``regimes`` called them."""
    rng = np.random.default_rng(200 + seed)
    for _ in range(60):
        p_max = int(rng.integers(1, 17))
        window = 3 * p_max
        n = int(rng.integers(0, window + 1))  # a ring not yet full, or full
        rings = np.stack([trajectory(rng, n) for _ in range(int(rng.integers(1, 6)))])
        for tol in TOLS:
            with np.errstate(invalid="ignore"):
                scale = 1.0 + np.abs(rings).max(axis=(1, 2)) if n else np.ones(rings.shape[0])
            d = old_returns(rings, p_max)
            want = old_first_return(d, tol * scale) if n >= window else np.zeros(rings.shape[0], dtype=np.int64)
            got = recurrence(rings, CHART.with_(window=window), tol=tol, p_max=p_max)
            assert same(got.period, want)
            every = recurrence(rings, CHART, tol=tol, p_max=p_max, distances=True)
            if d.shape[1]:  # (first_return cannot take no periods)
                assert same(every.period, old_first_return(d, tol * scale))
            else:
                assert np.all(every.period == 0)
            assert same(every.dist[:, : d.shape[1]], d) and np.all(every.dist[:, d.shape[1] :] == np.inf)
            assert same(every.limit, tol * scale)
            for m in range(rings.shape[0]):
                tail = rings[m]
                if tail.shape[0] > p_max:  # regimes.classify
                    old = old_detect_period(tail, p_max, tol * (1.0 + float(np.abs(tail).max())))
                    assert old == recurrence(tail, CHART, tol=tol, p_max=p_max).period


@pytest.mark.parametrize("seed", range(4))
def test_near_is_the_chart_s_close_returns(seed: int) -> None:
    """``near_returns`` and its least period within ``max(SETTLE_TOL, tol) (1 + max |x|)`` as the chart asks."""
    rng = np.random.default_rng(300 + seed)
    for _ in range(60):
        p_max = int(rng.integers(1, 17))
        window = 3 * p_max
        pairs = min(regimes.SETTLE_POINTS, window - p_max)
        rings = np.stack([trajectory(rng, int(rng.integers(0, window + 1)))])
        rings = np.concatenate([rings, *[trajectory(rng, rings.shape[1])[None] for _ in range(3)]])
        for tol in TOLS:
            loose = max(regimes.SETTLE_TOL, tol)
            with np.errstate(invalid="ignore"):
                scale = 1.0 + np.abs(rings).max(axis=(1, 2)) if rings.shape[1] else np.ones(rings.shape[0])
            near = old_near_returns(rings, p_max, pairs)
            got = recurrence(rings, NEAR.with_(pairs=pairs), tol=loose, p_max=p_max, distances=True)
            assert same(got.dist, near)
            assert same(got.limit, loose * scale)
            # The one deliberate change: a period with too few points (distance inf) never returns; near_returns'
            # inf returned within an infinite limit (an infinite point in the ring: never in a chart, which stops
            # a member beyond ESCAPE_BOUND).
            near[:, max(0, rings.shape[1] - pairs) :] = np.nan
            assert same(got.period, old_first_return(near, loose * scale))
            assert same(got.hit, near <= (loose * scale)[:, None])


@pytest.mark.parametrize("seed", range(4))
def test_diagram_is_repeat_period(seed: int) -> None:
    for x in trajectories(seed, 300, (0, 40)):
        for tol in TOLS:
            assert recurrence(x, DIAGRAM, tol=tol).period == old_repeat_period(x, tol)


@pytest.mark.parametrize("seed", range(4))
def test_basin_is_the_basins_kernel(seed: int) -> None:
    """The basins' hand-over (now CHART over the ring of 3 p_max points, in place: point ``k`` at ``k % w``,
    wrapping; slots asked in any order), as the run calls it. A NaN distance in the
    window is the one deliberate change: the kernel let it pass (``abs(nan) > lim`` is False), the rule never does
    (the run never writes one: the ring holds the points of members whose integration is ok)."""
    rng = np.random.default_rng(400 + seed)
    for _ in range(40):
        p_max = int(rng.integers(1, 17))
        window = 3 * p_max
        w = window + int(rng.integers(0, 9))
        slots = int(rng.integers(1, 6))
        ring, state = np.zeros((slots, w, 2)), np.zeros((slots, 11), np.int64)
        for s in range(slots):
            n = int(rng.integers(0, 2 * w))
            x = trajectory(rng, n)
            for k in range(n):
                ring[s, k % w] = x[k]
            state[s, 10] = n
        search = rng.permutation(slots)[: rng.integers(1, slots + 1)].astype(np.int64)  # the slots asked, any order
        bad = np.array([not np.isfinite(_window(ring[s], state[s, 10], window)).all() for s in search])
        for tol in TOLS:
            want = np.zeros(search.size, np.int64)
            old_basin_returns(ring, state, search, window, p_max, tol, want)
            rule = CHART.with_(tol=tol, p_max=p_max, window=window)
            got = recurrence(ring, rule, count=state[search, 10], rows=search, ring=True).period
            assert same(got[~bad], want[~bad])
            old_basin_returns(ring, state, search, window, p_max, tol, want, nan_fails=True)
            assert same(got, want)


def _window(ring: np.ndarray, n: int, window: int) -> np.ndarray:
    w = ring.shape[0]
    return ring[[(n - 1 - j) % w for j in range(min(n, window))]]


def _frame(rng: np.random.Generator, count: int) -> tuple[np.ndarray, ...]:
    """A played frame's points as the app holds them: columns (traj, k, q, r), shuffled."""
    xs = [trajectory(rng, int(rng.integers(0, 40))) for _ in range(count)]
    # some trajectories on one cycle, at another phase: one cycle, not two
    xs += [np.roll(x, 1, axis=0) for x in xs[: count // 3]]
    traj = np.concatenate([np.zeros(0), *[np.full(x.shape[0], i) for i, x in enumerate(xs)]]).astype(np.int64)
    k = np.concatenate([np.zeros(0), *[np.arange(x.shape[0]) for x in xs]]).astype(np.int64)
    pts = np.concatenate([np.zeros((0, 2)), *xs])
    order = rng.permutation(traj.size)
    return traj[order], k[order], pts[order, 0].copy(), pts[order, 1].copy()


@pytest.mark.parametrize("seed", range(4))
def test_play_is_the_app_s_settled_cycles(seed: int) -> None:
    from app.layers.orbits import settled_cycles

    rng = np.random.default_rng(500 + seed)
    for _ in range(40):
        traj, k, q, r = _frame(rng, int(rng.integers(0, 12)))
        for max_period in (0, 1, 2, 3, 6, 9):
            want = old_settled_cycles(traj, k, q, r, max_period)
            assert orbits.settled_seeds(traj, k, q, r, max_period, NEAR_PLAY) == want
            assert settled_cycles(traj, k, q, r, max_period) == want


@pytest.mark.parametrize("seed", range(4))
def test_seeds_are_return_seeds(seed: int) -> None:
    rng = np.random.default_rng(600 + seed)
    for _ in range(40):
        n = int(rng.integers(0, 50))
        points = np.stack([trajectory(rng, n) for _ in range(int(rng.integers(1, 5)))])
        npts = rng.integers(0, n + 1, size=points.shape[0])
        for tol in (*TOLS, 1.0, 2.0):
            max_period = int(rng.integers(0, 12))
            want = old_return_seeds(points, npts, max_period, tol)
            got = orbits.return_seeds(points, npts, max_period, tol)
            assert len(got) == len(want)
            assert all(same(a, c) and b == d for (a, b), (c, d) in zip(got, want, strict=True))


# ---------------------------------------------------------------------------------------------------------------
# (b) The issue's case: one period-2 orbit at |x| ~ 50 with a decaying transient, the same relative tolerance.


def issue_orbit() -> np.ndarray:
    """300 section points: a period-2 cycle at |x| ~ 50, a transient 2 * 0.98^k along (1, -1)."""
    k = np.arange(300)
    cycle = np.array([[50.0, -48.0], [46.0, 52.0]])
    return cycle[k % 2] + 2.0 * 0.98 ** k[:, None] * np.array([1.0, -1.0])


def test_the_issue_s_period_two_orbit_under_every_preset() -> None:
    """Each preset as its analysis applies it, at the relative tolerance 1e-5 (SWEEP's and SEEDS' callers pass an
    absolute one: ``1e-5 (1 + max |x|)`` here, as the diagram's ``periods`` and ``bilimovich reproduce`` do).
    The transient's returns at period 2 are ``0.0792 * 0.98^(k-2)`` per component: within
    ``1e-5 (1 + 52) = 5.3e-4`` from k ~ 250 on. Every rule that looks at the last points (the chart's and the
    basin's ring of 48, NEAR's 5 pairs, DIAGRAM's 8, PLAY's 3, SEEDS' closest) says period 2; those that ask
    every pair of the measurement's second half (k >= 149: the chart's classification, SWEEP) say none."""
    x = issue_orbit()
    tail = x[149:]  # the chart's classification: the second half of 300 measured points
    ring = x[-48:]  # a chart's or a basin's ring: 3 p_max points
    tol = 1e-5 * (1.0 + np.abs(tail).max())
    answers = {
        "chart (classification)": recurrence(tail, CHART, tol=1e-5, p_max=16).period,
        "chart (ring)": recurrence(ring, CHART.with_(window=48), tol=1e-5, p_max=16).period,
        "sweep": recurrence(tail, SWEEP, tol=tol, p_max=16).period,
        "near": recurrence(ring, NEAR, tol=1e-5, p_max=16).period,
        "diagram": recurrence(x, DIAGRAM, tol=1e-5).period,
        "basin": recurrence(x, CHART.with_(window=48), tol=1e-5, p_max=16).period,
        "play": recurrence(x[-(3 + 16) :], PLAY, tol=1e-5, p_max=16).period,
        "seeds": recurrence(x, SEEDS, tol=tol, p_max=16).period,
    }
    assert {k: int(v) for k, v in answers.items()} == {
        "chart (classification)": 0, "chart (ring)": 2, "sweep": 0, "near": 2, "diagram": 2, "basin": 2,
        "play": 2, "seeds": 2,
    }  # fmt: skip
    # the old detectors said the same
    assert old_detect_period(tail, 16, tol) == 0
    assert old_first_return(old_returns(ring[None], 16), np.array([1e-5 * (1.0 + np.abs(ring).max())]))[0] == 2
    assert old_repeat_period(x, 1e-5) == 2
    assert [n for _, n in old_return_seeds(x[None], np.array([300]), 16, tol)] == [2]
    # with NEAR's own 3e-2 (the chart's hand-over): period 2 from the ring's first points, long before 1e-5
    assert recurrence(x[:60], NEAR, p_max=16).period == 2


# ---------------------------------------------------------------------------------------------------------------
# The rule itself.


def test_presets_are_named_and_json() -> None:
    # (the basins' own preset, BASIN, was the chart's rule field for field: merged into CHART)
    assert set(PRESETS) == {"chart", "sweep", "near", "diagram", "play", "seeds"}
    for name, rule in PRESETS.items():
        assert getattr(rec, name.upper()) is rule
        d = rule.as_dict()
        assert RecurrenceRule(**d) == rule and set(d) == {"tol", "scale", "norm", "window", "pairs", "agree",
                                                          "strict", "p_max"}  # fmt: skip
    assert DIAGRAM.as_dict() == {"tol": 1e-9, "scale": "component", "norm": "max", "window": 0, "pairs": 8,
                                 "agree": "all", "strict": False, "p_max": 16}  # fmt: skip
    assert CHART.with_(window=48).window == 48 and CHART.window == 0  # a copy


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"tol": -1.0}, "tol"), ({"tol": math.nan}, "tol"), ({"tol": math.inf}, "tol"), ({"tol": "1e-5"}, "tol"),
        ({"scale": "relative"}, "scale"), ({"norm": "l1"}, "norm"), ({"agree": "most"}, "agree"),
        ({"window": -1}, "window"), ({"window": 2.5}, "window"), ({"pairs": True}, "pairs"),
        ({"strict": 1}, "strict"), ({"p_max": 0.5}, "p_max"), ({"p_max": 10**6}, "p_max"),
        ({"agree": "closest", "scale": "point"}, "closest"), ({"window": 4, "pairs": 4}, "pairs"),
    ],
)  # fmt: skip
def test_a_bad_rule_is_refused_naming_the_field_and_value(changes: dict, words: str) -> None:
    with pytest.raises(ParameterError, match=words) as err:
        RecurrenceRule(**changes)
    assert repr(next(iter(changes.values())))[:6] in str(err.value)


def test_a_call_missing_what_the_rule_leaves_to_it_is_refused() -> None:
    x = issue_orbit()
    with pytest.raises(ParameterError, match="tol"):
        recurrence(x, SWEEP, p_max=4)
    with pytest.raises(ParameterError, match="p_max"):
        recurrence(x, CHART, tol=1e-5)
    with pytest.raises(ParameterError, match="shape"):
        recurrence(x[:, 0], DIAGRAM)
    with pytest.raises(ParameterError, match="count"):
        recurrence(x[None], DIAGRAM, count=np.array([301]))


def test_a_nan_never_returns() -> None:
    x = np.tile([[1.0, 2.0]], (20, 1))
    assert recurrence(x, SWEEP, tol=0.0, p_max=3).period == 1
    x[5, 1] = np.nan
    for rule in (CHART, SWEEP, CHART.with_(window=20), SEEDS):
        assert recurrence(x, rule, tol=0.1, p_max=3).period == 0, rule
    # rules that look at the last points only do not see it
    assert recurrence(x, DIAGRAM).period == 1 and recurrence(x, PLAY, p_max=3).period == 1
    assert recurrence(x, NEAR, p_max=3).period == 0  # (its tolerance is relative to the whole ring's |x|)


# ---------------------------------------------------------------------------------------------------------------
# (c) One detector: a function that takes the distance between an array and itself shifted by a loop variable.

DISTANCE_CALLS = {"abs", "fabs", "norm", "hypot", "sqrt"}
#: Known, and why not this module's: Newton's least period of a converged cycle (the least divisor ``d`` of ``n``
#: with ``P^d(x) = x``, on the chain ``x .. P^n(x)``), in solve/poincare.py.
KNOWN = {"explorer_core/solve/poincare.py:least_period"}


def _names(node: ast.AST) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}


class _Function:
    """One function's loop variables, the names bound to one expression (followed), and each node's parent."""

    def __init__(self, fn: ast.AST) -> None:
        self.loops: set[str] = set()
        self.alias: dict[str, ast.AST] = {}
        self.parents: dict[ast.AST, ast.AST] = {}
        for node in ast.walk(fn):
            self.parents.update({c: node for c in ast.iter_child_nodes(node)})
            if isinstance(node, ast.For | ast.comprehension):
                self.loops |= _names(node.target)
            if isinstance(node, ast.Assign) and len(node.targets) == 1:
                t, v = node.targets[0], node.value
                if isinstance(t, ast.Name):
                    self.alias.setdefault(t.id, v)
                elif isinstance(t, ast.Tuple) and isinstance(v, ast.Tuple) and len(t.elts) == len(v.elts):
                    self.alias.update({a.id: b for a, b in zip(t.elts, v.elts, strict=True) if isinstance(a, ast.Name)})

    def bound(self, name: str) -> bool:
        return name in self.alias and name not in self.loops

    def resolve(self, e: ast.AST, depth: int = 3) -> ast.AST:
        while depth and isinstance(e, ast.Name) and self.bound(e.id):
            e, depth = self.alias[e.id], depth - 1
        return e

    def names(self, e: ast.AST, depth: int = 3) -> set[str]:
        """The names ``e`` uses, and those the names bound in the function use."""
        out = _names(e)
        for n in list(out):
            if depth and self.bound(n):
                out |= self.names(self.alias[n], depth - 1)
        return out

    def is_distance(self, node: ast.AST) -> bool:
        """``node`` is inside an ``abs``, ``norm``, ``hypot``, ``sqrt`` or a comparison (in its statement)."""
        p = self.parents.get(node)
        while p is not None and not isinstance(p, ast.stmt):
            if isinstance(p, ast.Compare):
                return True
            if isinstance(p, ast.Call):
                f = p.func
                if (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")) in DISTANCE_CALLS:
                    return True
            p = self.parents.get(p)
        return False

    def shifted(self, node: ast.BinOp) -> bool:
        """``node`` is ``x[..] - x[..]``, the two subscripts of one array shifted by a loop variable: in a slice
        (``x[p:] - x[:-p]``) or in one index only (``x[k + p] - x[k]``; not ``x[i + 1] - x[i]``, nor a transpose
        ``m[i, j] - m[j, i]``)."""
        a, b = self.resolve(node.left), self.resolve(node.right)
        if not (isinstance(a, ast.Subscript) and isinstance(b, ast.Subscript)):
            return False
        if ast.dump(a.value) != ast.dump(b.value) or ast.dump(a.slice) == ast.dump(b.slice):
            return False
        ia = a.slice.elts if isinstance(a.slice, ast.Tuple) else [a.slice]
        ib = b.slice.elts if isinstance(b.slice, ast.Tuple) else [b.slice]
        if len(ia) != len(ib):
            return False
        differ = [(ea, eb) for ea, eb in zip(ia, ib, strict=True) if ast.dump(ea) != ast.dump(eb)]
        if any((self.names(ea) | self.names(eb)) & self.loops for ea, eb in differ
               if isinstance(ea, ast.Slice) or isinstance(eb, ast.Slice)):  # fmt: skip
            return True
        return bool((self.names(a.slice) ^ self.names(b.slice)) & self.loops)


def recurrence_detectors(source: str) -> list[str]:
    """Names of the functions in ``source`` that take a return distance: ``|x[..p..] - x[..]|`` (``abs``, ``norm``,
    ``hypot``, ``sqrt`` of it, or a comparison) of one array and itself shifted by a loop variable (the period;
    names bound to such subscripts or indices are followed)."""
    found = []
    for fn in ast.walk(ast.parse(source)):
        if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            f = _Function(fn)
            if any(isinstance(node, ast.BinOp) and isinstance(node.op, ast.Sub) and f.shifted(node)
                   and f.is_distance(node) for node in ast.walk(fn)):  # fmt: skip
                found.append(fn.name)
    return found


def test_the_scan_flags_each_of_the_seven_old_detectors() -> None:
    for old in OLD:
        assert recurrence_detectors(inspect.getsource(old)) == [old.__name__], old.__name__
    # and not what is no recurrence: consecutive differences, a transpose, two arrays, a shift by a constant
    clean = """
def f(x, m, a, b, n):
    for i in range(n):
        d = abs(x[i + 1] - x[i]) + abs(m[i, n] - m[n, i]) + np.abs(a[i] - b[i])
    step = np.linalg.norm(x[1:] - x[:-1], axis=1)
    for i in range(n):
        z = np.linalg.norm(x[n + i, :m] - x[i, :m], axis=1)
"""
    assert recurrence_detectors(clean) == []


def test_no_second_recurrence_detector_in_the_core_or_the_app() -> None:
    """The wrappers (``detect_period``, ``return_seeds``, ``settled_seeds``, the app's ``settled_cycles``) call
    :func:`~explorer_core.solve.recurrence.recurrence`; a new detector belongs in that module, as a preset."""
    found = set()
    for path in sorted([*ROOT.glob("explorer_core/**/*.py"), *ROOT.glob("app/**/*.py")]):
        rel = path.relative_to(ROOT).as_posix()
        if rel == "explorer_core/solve/recurrence.py":
            continue
        found |= {f"{rel}:{name}" for name in recurrence_detectors(path.read_text())}
    assert found == KNOWN, sorted(found - KNOWN)
    for wrapper in (detect_period, orbits.return_seeds, orbits.settled_seeds, basins._Run.step,
                    bifurcation.bilimovich_orbits, regimes._classify_members, regimes.classify):  # fmt: skip
        assert "recurrence(" in inspect.getsource(wrapper)


# ---------------------------------------------------------------------------------------------------------------
# The measured merge decision (docs/architecture.md, "Recurrence"): which presets judge realistic inputs alike.

MERGE_TIMES = (100, 200, 400, 700, 1000)


def merge_inputs() -> dict[str, list[np.ndarray]]:
    """1000 periods of Fig. 10's 140 sweep values, Fig. 11's 20x20 chart pixels and a 20x20 grid of ICs of the
    basins' example (Fig. 11's tensor at alpha = -0.5, I11 = 1.6), at the analyses' default accuracies."""
    from explorer_core.analyses.sweeps import sweep_values
    from explorer_core.scenes import get_scene
    from explorer_core.solve.numerics import Numerics
    from explorer_core.solve.section import section

    def run(params, ics, rtol: float, bound: float = 1e4) -> list[np.ndarray]:
        s = section(params, ics, 1000, numerics=Numerics(rtol=rtol, atol=rtol, bound=bound), workers=1)
        return [s.points[i, : s.npts[i]] for i in range(s.points.shape[0])]

    fig10, fig11 = get_scene("fig10").params, get_scene("fig11").params
    sweep = [x for a in sweep_values((-0.42, -0.35), 140) for x in run(fig10.with_(alpha=float(a)), [IC10], 1e-9)]
    chart = [x for a in np.linspace(-0.6, -0.4, 20) for i11 in np.linspace(1.0, 2.0, 20)
             for x in run(fig11.with_(alpha=float(a), I11=float(i11)), [(0.1, 0.1)], 1e-8, 100.0)]  # fmt: skip
    q, r = np.meshgrid(np.linspace(-1.7, 1.5, 20), np.linspace(-3.0, 1.0, 20))
    grid = run(fig11.with_(alpha=-0.5, I11=1.6), np.column_stack([q.ravel(), r.ravel()]), 1e-8)
    return {"fig10": sweep, "fig11": chart, "basins": grid}


IC10 = (-0.0959, -1.962)
#: The basins' preset before the merge, as it was defined: every pair of the last 3 p_max points.
OLD_BASIN = RecurrenceRule(scale="window")


def merge_verdicts(x: np.ndarray, common: float | None) -> dict[str, int]:
    """Every preset's least period of the trajectory ``x`` so far, as its analysis applies it (``common``: every
    tolerance that one, relative; SWEEP's and SEEDS' ``common (1 + max |x|)`` of their window)."""

    def own(t: float) -> float:
        return t if common is None else common

    p_max, ring = 16, x[-48:]
    half = x[max(0, x.shape[0] // 2 - 1) :]
    tail_scale = 1.0 + float(np.abs(ring).max())
    out = {
        "CHART": recurrence(half, CHART, tol=own(1e-5), p_max=p_max).period if half.shape[0] > p_max else 0,
        "CHART ring": recurrence(ring, CHART.with_(window=48), tol=own(1e-5), p_max=p_max).period,
        "BASIN": recurrence(x, OLD_BASIN.with_(window=48), tol=own(1e-5), p_max=p_max).period,
        "NEAR": recurrence(ring, NEAR, tol=own(3e-2), p_max=p_max).period,
        "DIAGRAM": recurrence(x, DIAGRAM, tol=own(1e-9)).period,
        "PLAY": recurrence(x[-(PLAY.pairs + p_max) :], PLAY, tol=own(1e-3), p_max=p_max).period,
        # a cell's diagonal (64 cells across the basins' box) for the located check; 2% of the box for seeds
        "SWEEP": recurrence(ring, SWEEP, tol=0.08 if common is None else common * tail_scale, p_max=p_max).period,
    }
    return {k: int(v) for k, v in out.items()}


@pytest.mark.slow
def test_the_merge_decision() -> None:
    """BASIN was CHART over the ring: they never differ (merged). SWEEP is CHART with an absolute tolerance: alike
    at one tolerance, apart at their callers' (kept). Every other pair differs on these inputs even at one
    tolerance (kept apart). ``pytest -s`` prints the table of docs/architecture.md."""
    sets = merge_inputs()
    names = list(merge_verdicts(np.zeros((50, 2)), None))
    pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]
    table: dict[str, dict[str, list[int]]] = {"own": {}, "1e-5": {}}
    for mode, common in (("own", None), ("1e-5", 1e-5)):
        for trajs in sets.values():
            rows = [merge_verdicts(x[:t], common) for x in trajs for t in MERGE_TIMES if x.shape[0] >= t]
            for a, b in pairs:
                table[mode].setdefault(f"{a} | {b}", []).append(sum(r[a] != r[b] for r in rows))
    for mode, counts in table.items():
        print(f"\nsamples whose least periods differ ({mode} tolerances), fig10 / fig11 / basins:")
        for k, v in counts.items():
            print(f"  {k:24s} {' / '.join(map(str, v))}")
    assert table["own"]["CHART ring | BASIN"] == [0, 0, 0] == table["1e-5"]["CHART ring | BASIN"]
    assert table["1e-5"]["CHART ring | SWEEP"] == [0, 0, 0] and sum(table["own"]["CHART ring | SWEEP"]) > 0
    for (a, b), key in zip(pairs, table["1e-5"], strict=True):
        if {a, b} not in ({"CHART ring", "BASIN"}, {"CHART ring", "SWEEP"}, {"BASIN", "SWEEP"}):
            assert sum(table["1e-5"][key]) > 0, key
