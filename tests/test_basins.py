"""Basins of attraction: coexisting attractors, agreement with long solve_ivp runs and with Newton, progress."""

from __future__ import annotations

import json

import numpy as np
import pytest
from naive import ivp_fate, nearest_attractor

from explorer_core.analyses.basins import (
    ESCAPE,
    FAILED,
    LOCATING,
    NOT_COMPUTED,
    UNDECIDED,
    basin_spec,
    basins,
    iter_basins,
)
from explorer_core.analyses.orbits import find_orbits, same_orbit
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status, names
from explorer_core.system.params import ParameterError

#: Fig. 11's tensor at alpha = -0.5, I11 = 1.6: a period-1 and a period-3 attractor coexist.
FIG11 = get_scene("fig11").params.with_(I11=1.6, alpha=-0.5)
#: Fig. 8B: the strange attractor, and escape along the noncompact curve.
FIG8B = get_scene("fig8B").params
BOX = (-1.7, 1.5, -3.0, 1.0)


@pytest.fixture(scope="module")
def fig11() -> object:
    return basins(FIG11, BOX, (24, 24))


@pytest.fixture(scope="module")
def fig8b() -> object:
    return basins(FIG8B, BOX, (16, 16))


def _boundary_pixels(label: np.ndarray) -> np.ndarray:
    """``(j, i)`` of pixels with a neighbour of another label."""
    diff = np.zeros(label.shape, bool)
    diff[:, 1:] |= label[:, 1:] != label[:, :-1]
    diff[:, :-1] |= label[:, 1:] != label[:, :-1]
    diff[1:] |= label[1:] != label[:-1]
    diff[:-1] |= label[1:] != label[:-1]
    return np.argwhere(diff)


def _sample(b, n_random: int, n_boundary: int, seed: int = 0) -> list[tuple[int, int]]:
    rng = np.random.default_rng(seed)
    ny, nx = b.label.shape
    picks = [(int(j), int(i)) for j, i in zip(rng.integers(0, ny, n_random), rng.integers(0, nx, n_random),
                                               strict=True)]  # fmt: skip
    edge = _boundary_pixels(b.label)
    for k in rng.choice(len(edge), size=min(n_boundary, len(edge)), replace=False):
        picks.append((int(edge[k][0]), int(edge[k][1])))
    return picks


def test_fig11_tensor_has_two_coexisting_periodic_attractors(fig11) -> None:
    kinds = sorted((a.kind, a.period) for a in fig11.attractors)
    assert kinds == [("periodic", 1), ("periodic", 3)]
    assert fig11.completed and fig11.computed.all()
    ids = {a.id for a in fig11.attractors}
    assert set(np.unique(fig11.label)) == ids
    for a in fig11.attractors:
        assert np.all(np.abs(a.multipliers) < 1.0)
        assert 0.2 < a.fraction < 0.8
        assert a.points.shape == (a.period, 2)
    assert sum(a.fraction for a in fig11.attractors) == pytest.approx(1.0)
    assert fig11.statuses == {"ok": 24 * 24} and (fig11.status == Status.OK).all()


def test_periodic_attractors_are_the_stable_orbits_newton_finds(fig11) -> None:
    # Newton from a grid of seeds, independently of the basins' trajectories: the stable cycles of
    # periods 1 and 3 in the box are exactly the two attractors, with the same multipliers.
    qs, rs = np.meshgrid(np.linspace(-1.5, 1.3, 4), np.linspace(-2.8, 0.8, 4))
    search = find_orbits(FIG11, np.column_stack([qs.ravel(), rs.ravel()]), [1, 3])
    stable = [o for o in search.orbits if o.stable]
    assert len(stable) == len(fig11.attractors) == 2
    for a in fig11.attractors:
        (o,) = [o for o in stable if o.period == a.period]
        assert same_orbit(o, find_orbits(FIG11, a.points[:1], [a.period]).orbits[0])
        np.testing.assert_allclose(np.sort(np.abs(a.multipliers)), np.sort(np.abs(o.multipliers)), atol=1e-6)
        d = np.linalg.norm(a.points[:, None] - o.points[None], axis=-1).min(axis=1)
        assert d.max() < 1e-7


def _agree_fig11(b, n_random: int, n_boundary: int, seed: int, periods: int = 100) -> None:
    # `periods` of scipy's DOP853 at 1e-10 on the naive field end on the attractor the pixel is
    # labelled with (|mu| = 0.87 and 0.5 per 3 periods).
    atts = [(a.id, a.points) for a in b.attractors]
    for j, i in _sample(b, n_random, n_boundary, seed):
        pts, escaped = ivp_fate(FIG11, (b.q[i], b.r[j]), periods, bound=300.0)
        ident, dist = nearest_attractor(pts, escaped, atts)
        assert ident == b.label[j, i], (j, i)
        assert dist < 1e-2  # the cycles are ~1 apart; a pixel next to a boundary may still be converging


def test_fig11_labels_agree_with_long_solve_ivp_runs(fig11) -> None:
    _agree_fig11(fig11, 2, 2, seed=0)  # two random pixels and two next to a basin boundary


@pytest.mark.slow
def test_fig11_labels_agree_with_long_solve_ivp_runs_at_more_pixels() -> None:
    # next to a boundary (a saddle's stable manifold) transients are long: 250 periods
    _agree_fig11(basins(FIG11, BOX, (64, 64)), 6, 14, seed=2, periods=250)


def test_fig8b_is_one_strange_attractor_and_escape(fig8b) -> None:
    (chaos,) = [a for a in fig8b.attractors if a.kind == "chaotic"]
    (esc,) = [a for a in fig8b.attractors if a.kind == "escape"]
    assert esc.id == ESCAPE and chaos.period is None
    # Fig. 8B's largest exponent is 0.082 per unit time (paper); a 300-period estimate from one point.
    assert 0.05 < chaos.lyapunov < 0.12
    assert chaos.fraction + esc.fraction == pytest.approx(1.0)
    assert 0.6 < chaos.fraction < 0.9
    assert set(np.unique(fig8b.label)) == {ESCAPE, chaos.id}


def _agree_fig8b(b, per_label: int, seed: int) -> None:
    # An escaping pixel passes 300 (three times the engine's bound) within 250 periods; a pixel of the
    # strange attractor stays bounded for 250 periods and its last points lie among the attractor's.
    # (Escapes take up to ~190 periods of chaotic transient: 100 periods are not enough to tell.)
    (chaos,) = [a for a in b.attractors if a.kind == "chaotic"]
    rng = np.random.default_rng(seed)
    picks = []
    for lab in (ESCAPE, chaos.id):
        cand = np.argwhere(b.label == lab)
        picks += [tuple(cand[k]) for k in rng.choice(len(cand), per_label, replace=False)]
    for j, i in picks:
        pts, escaped = ivp_fate(FIG8B, (b.q[i], b.r[j]), 250, bound=300.0)
        ident, dist = nearest_attractor(pts, escaped, [(chaos.id, chaos.points)])
        assert ident == b.label[j, i], (j, i)
        assert dist < 0.5


def test_fig8b_labels_agree_with_long_solve_ivp_runs(fig8b) -> None:
    _agree_fig8b(fig8b, 1, seed=1)


@pytest.mark.slow
def test_fig8b_labels_agree_with_long_solve_ivp_runs_at_more_pixels() -> None:
    _agree_fig8b(basins(FIG8B, BOX, (64, 64)), 6, seed=3)


def test_coarse_to_fine_levels_reuse_the_attractors_and_cancel_stops() -> None:
    spec = basin_spec(FIG11, BOX, (16, 12))
    ups = list(iter_basins(spec))
    levels = [u for u in ups if u.level_done]
    assert [u.stride for u in levels] == [4, 2, 1]
    for u in ups:  # every label is an attractor's id or a documented negative code
        ids = {a.id for a in u.basins.attractors}
        assert set(np.unique(u.basins.label)) <= ids | {ESCAPE, FAILED, UNDECIDED, NOT_COMPUTED, LOCATING}
    masks = [u.basins.computed for u in levels]
    assert masks[0][::4, ::4].all()  # (finer pixels run alongside once slots are free)
    assert np.all(masks[0] <= masks[1]) and masks[1][::2, ::2].all() and masks[2].all()
    assert levels[-1].basins.completed and not levels[0].basins.completed
    # finer levels find no new attractor: the ids of the coarse level are the ids at the end
    assert {a.id for a in levels[0].basins.attractors} == {a.id for a in levels[-1].basins.attractors}
    # coarse pixels keep their labels; the filled image has no hole
    fin = levels[-1].basins.label
    assert np.array_equal(levels[0].basins.label[::4, ::4], fin[::4, ::4])
    assert (levels[0].basins.filled() != NOT_COMPUTED).all()
    # the plain function gives the same labels (deterministic: lock-step blocks do not depend on threads)
    assert np.array_equal(basins(FIG11, BOX, (16, 12)).label, fin)
    calls = {"n": 0}

    def cancel() -> bool:
        calls["n"] += 1
        return calls["n"] > 3

    last = list(iter_basins(spec, cancel=cancel))[-1].basins
    assert not last.completed and (last.label == NOT_COMPUTED).any()
    assert np.array_equal(last.status == Status.NOT_RUN, last.label == NOT_COMPUTED)  # not computed: not_run


@pytest.mark.parametrize(
    ("kw", "words"),
    [
        ({"box": (1.0, 0.0, 0.0, 1.0)}, "qmin < qmax"),
        ({"box": (0.0, float("nan"), 0.0, 1.0)}, "finite"),
        ({"grid": (0, 10)}, "grid NX"),
        ({"grid": (10, 3000)}, "grid NY"),
        ({"grid": (2000, 2000)}, "4000000 pixels"),
        ({"grid": "ab"}, "grid NX"),
        ({"cells": (0, 5)}, "cells NQ"),
        ({"max_periods": 0}, "max_periods"),
        ({"tol": 2.0}, "tol"),
    ],
)
def test_bad_input_names_the_value(kw, words) -> None:
    args = {"box": BOX, "grid": (8, 8), **kw}
    with pytest.raises(ParameterError, match=words):
        basin_spec(FIG11, args.pop("box"), args.pop("grid"), **args)


def test_summary_is_the_issues_json_and_npz_has_the_arrays(fig11, tmp_path) -> None:
    s = json.loads(json.dumps(fig11.summary()))
    for a in s["attractors"]:
        assert set(a) >= {"id", "kind", "period", "points", "fraction"}
        assert a["kind"] in ("periodic", "chaotic", "quasi_periodic", "escape")
    assert s["grid"] == [24, 24] and s["completed"] is True
    path = tmp_path / "b.npz"
    fig11.to_npz(str(path))
    with np.load(path) as z:
        assert z["q"].shape == (24,) and z["r"].shape == (24,) and z["label"].shape == (24, 24)
        assert np.array_equal(z["label"], fig11.label)
        assert np.array_equal(z["status"], fig11.status) and z["status_names"][Status.ESCAPED] == "escaped"
        np.testing.assert_allclose(z["q"][[0, -1]], [-1.7 + 3.2 / 48, 1.5 - 3.2 / 48])


def test_all_members_failing_is_said_and_gives_no_attractor() -> None:
    b = basins(FIG11, BOX, (4, 4), numerics=Numerics(rtol=1e-8, atol=1e-8, max_steps=10, bound=100.0))
    assert (b.label == FAILED).all()
    assert b.attractors == []
    s = b.summary()
    assert s["attractors"] == [] and "no attractor" in s["note"]
    assert s["statuses"] == {"too_many_steps": 16}
    assert names(b.status) == [["too_many_steps"] * 4] * 4  # the pixel says WHICH engine failure


def test_pixels_without_a_fate_in_max_periods_are_undecided() -> None:
    b = basins(FIG11, BOX, (4, 3), max_periods=3)
    assert (b.label == UNDECIDED).all() and b.attractors == []
    s = b.summary()
    assert s["statuses"] == {"undecided": 12} and s["undecided_fraction"] == 1.0
    assert (b.status == Status.UNDECIDED).all()
    assert "no attractor" in s["note"]


def test_labelling_by_basin_cells_is_an_option() -> None:
    # Attractors.jl's consecutive basin steps: off by default (it mislabels pixels at basin boundaries).
    b = basins(FIG8B, BOX, (12, 12), hit_basin=10)
    assert b.spec.hit_basin == 10 and b.completed
    assert {a.kind for a in b.attractors} == {"chaotic", "escape"}
    assert set(b.statuses) <= {"ok", "escaped"}
    assert np.array_equal(b.status == Status.ESCAPED, b.label == ESCAPE)


def test_labels_do_not_depend_on_how_many_trajectories_are_in_flight() -> None:
    # Which trajectory finds an attractor first depends on the slots; the labels must not (they did when a
    # long transient's cells were kept as a cycle's: 130 of 40000 pixels at 200 x 200 changed basin).
    few = basins(FIG11, BOX, (40, 40), inflight=24)
    many = basins(FIG11, BOX, (40, 40), inflight=1600)
    assert np.array_equal(few.label, many.label)
    assert [(a.kind, a.period) for a in few.attractors] == [(a.kind, a.period) for a in many.attractors]


def test_a_cycle_found_after_a_long_transient_keeps_only_its_own_cells() -> None:
    # From (-0.044, 0.11) the trajectory wanders ~1000 periods near the basin boundary, revisiting its
    # cells 100 times in a row (a "recurrence"), before it falls on the period-1 focus. The 128 cells
    # it marked while locating were kept as the cycle's before, and captured pixels of the period-3
    # basin (130 of 40000 at 200 x 200, with 128 in flight); now the cycle owns its point's cell only.
    from explorer_core.analyses.basins import _Run

    x = (-0.044, 0.11)
    spec = basin_spec(FIG11, (x[0] - 1e-3, x[0] + 1e-3, x[1] - 1e-3, x[1] + 1e-3), (1, 1),
                      cell_box=(-4.9, 4.7, -7.0, 5.0), cells=(192, 192))  # fmt: skip
    run = _Run(spec)
    queue = [0]
    while queue or (run.pixel >= 0).any():
        run.step(queue)
    assert run.age[0] > 1000  # it was a recurrence, not a settled cycle
    ((ident, found),) = run.found.items()
    assert (found.kind, found.period) == ("periodic", 1)
    assert int(np.count_nonzero(run.att == ident + 1)) == 1
