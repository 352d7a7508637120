"""Basins: a pixel's label does not depend on the box around it; conservative islands are no attractors.

Each test here fails on the code before the recurrence cells were sized from the attractors (a5b2768):
in a +-500 box the cells (64 across it) were wider than the gap between Fig. 11's period-1 focus and
period-3 cycle, and every pixel got the one attractor found first; the invariant curves of Fig. 4A's and
Fig. 5A's islands were reported as so many "quasi-periodic attractors".
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from naive import ivp_fate, nearest_attractor

from explorer_core.analyses.basins import (
    ESCAPE,
    FAILED,
    NOT_COMPUTED,
    UNDECIDED,
    Basins,
    basin_spec,
    basins,
    iter_basins,
)
from explorer_core.analyses.orbits import find_orbits
from explorer_core.scenes import get_scene

#: Fig. 11's tensor at alpha = -0.5, I11 = 1.6: a period-1 focus and a period-3 cycle coexist, ~0.85 apart.
FIG11 = get_scene("fig11").params.with_(I11=1.6, alpha=-0.5)
FOCUS = (-0.1744, -2.1855)
CYCLE3 = (0.0355, -1.3653)  # one point of the period-3 cycle


def _identity(b: Basins, j: int, i: int) -> tuple:
    """What the pixel ``(j, i)`` reaches, by the attractor itself (kind, period, points), not its id."""
    lab = int(b.label[j, i])
    if lab < 0:
        return ("outcome", lab)
    a = b.attractor(lab)
    return (a.kind, a.period, a)


def _same(x: tuple, y: tuple) -> bool:
    if x[:2] != y[:2]:
        return False
    if x[0] != "periodic":
        return x[0] != "outcome" or x == y
    # the same cycle: every point of one is a point of the other
    d = np.linalg.norm(x[2].points[:, None] - y[2].points[None], axis=-1)
    return bool(d.min(axis=1).max() < 1e-6)


def _centred(x: tuple[float, float], half: float, n: int) -> Basins:
    """Basins on an odd ``n x n`` grid over ``x +- half``: ``x`` is the centre pixel."""
    return basins(FIG11, (x[0] - half, x[0] + half, x[1] - half, x[1] + half), (n, n))


def _check_box_independence(pixels: list[tuple[float, float]], ivp: bool = True) -> None:
    cycles = [o for o in find_orbits(FIG11, np.array([FOCUS, CYCLE3]), [1, 3]).orbits if o.stable]
    atts = [(k, o.points) for k, o in enumerate(cycles)]
    for x in pixels:
        small, large = _centred(x, 5.0, 11), _centred(x, 500.0, 31)
        assert small.q[5] == pytest.approx(x[0]) and large.q[15] == pytest.approx(x[0])
        assert small.r[5] == pytest.approx(x[1]) and large.r[15] == pytest.approx(x[1])
        a, b = _identity(small, 5, 5), _identity(large, 15, 15)
        assert _same(a, b), (x, a[:2], b[:2])
        for res in (small, large):
            assert res.complete and res.lost == [] and res.computed.all()
        if not ivp:
            continue
        # and it is the attractor an independent solve_ivp run (DOP853 at 1e-10) ends on
        pts, escaped = ivp_fate(FIG11, x, 100, bound=300.0)
        k, dist = nearest_attractor(pts, escaped, atts)
        assert dist < 1e-2 and a[0] == "periodic" and a[1] == cycles[k].period, x


def test_a_pixels_attractor_does_not_depend_on_the_box_around_it() -> None:
    # Two pixels next to the period-1 focus and one next to a point of the period-3 cycle, each the centre
    # of a +-5 and a +-500 box. Before: in the +-500 box the pixels next to the focus got the period-3 cycle.
    _check_box_independence([(FOCUS[0] + 0.04, FOCUS[1] - 0.03), (FOCUS[0] - 0.06, FOCUS[1] + 0.05),
                             (CYCLE3[0] + 0.05, CYCLE3[1] - 0.04)])  # fmt: skip


@pytest.mark.slow
def test_a_5x5_patch_around_each_attractor_does_not_depend_on_the_box() -> None:
    offsets = np.linspace(-0.1, 0.1, 5)
    # (the attractor each ends on is checked against solve_ivp at the three pixels of the test above)
    _check_box_independence(
        [(c[0] + dq, c[1] + dr) for c in (FOCUS, CYCLE3) for dq in offsets for dr in offsets], ivp=False
    )


def test_the_tester_s_500_box_finds_both_attractors_with_their_basins() -> None:
    # The reported case: `bilimovich basins` at alpha = -0.5, I11 = 1.6, box +-500, 30 x 30 pixels. Before:
    # one period-3 attractor over 100 %; 281 of the 900 pixels end on the period-1 focus.
    b = basins(FIG11, (-500.0, 500.0, -500.0, 500.0), (30, 30))
    kinds = sorted((a.kind, a.period) for a in b.attractors)
    assert kinds == [("periodic", 1), ("periodic", 3)]
    (focus,) = [a for a in b.attractors if a.period == 1]
    assert np.linalg.norm(focus.points[0] - FOCUS) < 1e-3
    assert int(np.count_nonzero(b.label == focus.id)) == 281
    # the cells used resolve the attractors, and the result says they were refined from them
    s = b.summary()
    assert s["cell_refinements"] >= 1 and s["complete"] is True and s["lost"] == []
    assert np.hypot(*b.spec.cell_size) <= s["attractor_scale"] / 8


def test_cells_the_caller_gives_are_kept_and_an_unresolved_grid_is_a_loss() -> None:
    b = basins(FIG11, (-500.0, 500.0, -500.0, 500.0), (6, 6), cells=(64, 64))
    assert b.spec.cells == (64, 64) and not b.spec.adapt_cells
    assert not b.complete
    (loss,) = [x for x in b.lost if x.what == "attractors possibly merged"]
    assert "cells" in loss.why
    assert json.loads(json.dumps(b.summary()))["lost"][0]["count"] == 1


#: Fig. 4A's elliptic point is at (0, -0.0033), Fig. 5A's at (0, 0.0133) (Newton, multipliers on the unit circle).
@pytest.mark.parametrize(("scene", "box"), [("fig4A", (-0.4, 0.4, -0.4, 0.4)), ("fig5A", (-0.6, 0.6, -0.6, 0.6))])
def test_invariant_curves_of_a_conservative_island_are_no_attractors(scene: str, box: tuple) -> None:
    # Before: each pixel's invariant curve was a "quasi_periodic" attractor of its own (4 of them, no word).
    b = basins(get_scene(scene).params, box, (4, 4))
    assert [a.kind for a in b.attractors] == ["conservative"]
    (island,) = b.attractors
    assert island.attracting is False and island.fraction == 1.0
    assert abs(island.log_det) < 1.0 and island.measured >= 50
    assert b.warnings and "conservative invariant curves" in b.warnings[0]
    s = json.loads(json.dumps(b.summary()))
    assert "conservative" in s["note"] and s["attractors"][0]["attracting"] is False
    # not a loss: every pixel has its answer
    assert b.complete and b.lost == []


def test_periodic_attractors_say_they_attract() -> None:
    b = basins(FIG11, (-1.7, 1.5, -3.0, 1.0), (8, 8))
    assert all(a.attracting is True for a in b.attractors)
    assert all(a.as_dict()["attracting"] is True for a in b.attractors)


def test_nothing_is_lost_in_silence() -> None:
    # undecided pixels
    b = basins(FIG11, (-1.7, 1.5, -3.0, 1.0), (4, 3), max_periods=3)
    assert not b.complete and [(x.what, x.count) for x in b.lost] == [("pixels undecided", 12)]
    assert "3 periods" in b.lost[0].why
    # failed pixels, with the engine's reason
    from explorer_core.solve.numerics import Numerics

    b = basins(FIG11, (-1.7, 1.5, -3.0, 1.0), (4, 4), numerics=Numerics(rtol=1e-8, atol=1e-8, max_steps=10,
                                                                         bound=100.0))  # fmt: skip
    assert (b.label == FAILED).all() and not b.complete
    assert [(x.what, x.count) for x in b.lost] == [("pixels failed", 16)] and "too_many_steps" in b.lost[0].why
    # cancelled: the pixels not computed are counted
    calls = {"n": 0}

    def cancel() -> bool:
        calls["n"] += 1
        return calls["n"] > 2

    spec = basin_spec(FIG11, (-1.7, 1.5, -3.0, 1.0), (16, 16))
    last = list(iter_basins(spec, cancel=cancel))[-1].basins
    n = int(np.count_nonzero(last.label == NOT_COMPUTED))
    assert n and not last.complete
    assert ("pixels not computed", n) in [(x.what, x.count) for x in last.lost]
    assert any("cancelled" in x.why for x in last.lost)
    # a complete run: complete, nothing lost, and the JSON/NPZ say so with plain numbers
    done = basins(FIG11, (-1.7, 1.5, -3.0, 1.0), (6, 6))
    assert done.complete and done.lost == []
    assert not ({ESCAPE, FAILED, UNDECIDED, NOT_COMPUTED} & set(np.unique(done.label)))
    s = json.loads(json.dumps(done.summary()))
    assert s["complete"] is True and s["lost"] == []


def test_labels_do_not_depend_on_the_order_pixels_are_processed(monkeypatch) -> None:
    # The pixels in reverse order (the finest level first, the last pixel first): the same attractor at
    # every pixel. Before, in the +-500 box, whichever attractor was found first took every pixel.
    import explorer_core.analyses.basins as mod

    box, grid = (-500.0, 500.0, -500.0, 500.0), (20, 20)
    ahead = basins(FIG11, box, grid)
    levels = mod._levels
    monkeypatch.setattr(mod, "_levels", lambda ny, nx: [(s, p[::-1]) for s, p in levels(ny, nx)][::-1])
    behind = basins(FIG11, box, grid)
    assert ahead.complete and behind.complete
    for j, i in np.ndindex(ahead.label.shape):
        assert _same(_identity(ahead, j, i), _identity(behind, j, i)), (j, i)


def test_fig4a_box_is_one_island_and_one_chaotic_attractor() -> None:
    # Fig. 4A's box: invariant curves of islands (no trend in log|det DP^k|) and a chaotic set that
    # contracts area. Before: 4 "quasi_periodic" attractors (separate invariant curves) beside the chaotic one.
    params = get_scene("fig4A").params
    b = basins(params, (-3.0, 3.0, -2.5, 2.5), (16, 16))
    assert sorted(a.kind for a in b.attractors) == ["chaotic", "conservative"]
    (chaos,) = [a for a in b.attractors if a.kind == "chaotic"]
    (island,) = [a for a in b.attractors if a.kind == "conservative"]
    assert chaos.attracting and chaos.log_det < -1.0 and chaos.lyapunov > 5e-3
    assert island.attracting is False and island.log_det > -1.0  # no contraction (a layer may drift up)
    assert b.complete and island.fraction + chaos.fraction == pytest.approx(1.0)
    # a separate 1000-period Lyapunov run from the pixels themselves: the island's are ~0, the chaotic ones not
    from explorer_core.analyses.lyapunov import lyapunov_spectrum

    rng = np.random.default_rng(0)
    picks = {a.id: np.argwhere(b.label == a.id) for a in (chaos, island)}
    picks = {k: v[rng.choice(len(v), 3, replace=False)] for k, v in picks.items()}
    ics = np.array([[b.q[i], b.r[j]] for k in (chaos.id, island.id) for j, i in picks[k]])
    lam = lyapunov_spectrum(params, ics, 1000).exponents[:, 0]
    assert (lam[:3] > 2e-3).all() and (np.abs(lam[3:]) < 2e-3).all(), lam


def test_the_cells_length_scale_comes_from_the_attractors() -> None:
    from explorer_core.analyses.basins import RESOLVE, _Found, attractor_scale, refined_cells

    def found(kind: str, pts: list) -> _Found:
        return _Found(0, kind, len(pts) if kind == "periodic" else None, np.array(pts, float), None, None, (0, 0))

    focus = found("periodic", [FOCUS])
    cycle = found("periodic", [CYCLE3, (-1.8459, -1.258), (1.0469, -3.15)])
    # the gap between the two cycles (0.85) sets it; a lone fixed point has 1 + |x|
    assert attractor_scale([focus, cycle]) == pytest.approx(np.hypot(0.2099, 0.8202), rel=1e-3)
    assert attractor_scale([focus]) == pytest.approx(1 + np.hypot(*FOCUS))
    # conservative sets (invariant curves) do not count; nothing classified: no scale
    curve = found("conservative", [(FOCUS[0] + 1e-3, FOCUS[1])])
    assert attractor_scale([focus, cycle, curve]) == attractor_scale([focus, cycle])
    assert attractor_scale([curve]) is None and attractor_scale([]) is None
    # the refined grid resolves it, covers the attractors, and does not depend on any box
    scale = attractor_scale([focus, cycle])
    box, cells = refined_cells([focus, cycle], scale)
    h = ((box[1] - box[0]) / cells[0], (box[3] - box[2]) / cells[1])
    assert np.hypot(*h) <= scale / RESOLVE and h[0] == pytest.approx(h[1])
    assert box[0] < -1.8459 and box[1] > 1.0469 and box[2] < -3.15 and box[3] > -1.258
