"""Density images of long sections: binning against numpy's histogram, accuracy against solve_ivp."""

from __future__ import annotations

import numpy as np
import pytest
from naive import solve_ivp_section

from explorer_core.analyses.density import (
    DENSITY_WINDOW,
    MAX_DENSITY_POINTS,
    accumulate,
    density,
    density_numerics,
    iter_density,
)
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics, random_ics
from explorer_core.solve.section import section
from explorer_core.system.params import ParameterError


def test_binning_against_numpy_histogram2d() -> None:
    rng = np.random.default_rng(0)
    q, r = rng.normal(size=50_000), rng.normal(size=50_000) * 2
    view = (-1.5, 2.0, -3.0, 2.5)
    counts = np.zeros((37, 53), dtype=np.int64)
    inside = accumulate(counts, q, r, view)
    ref, _, _ = np.histogram2d(r, q, bins=[37, 53], range=[[view[2], view[3]], [view[0], view[1]]])
    # histogram2d closes the last bin on the right; the image's pixels are half-open: compare away from it.
    np.testing.assert_array_equal(counts[:-1, :-1], ref[:-1, :-1])
    assert abs(inside - ref.sum()) <= 2


def test_the_image_counts_every_point_of_the_section_in_view() -> None:
    s = get_scene("fig1C")
    ics = random_ics(20, s.box, seed=3)
    view = (*s.q_range, *s.r_range)
    num = density_numerics(view, (200, 150), s.bound)
    img = density(s.params, ics, 300, view=view, pixels=(200, 150), numerics=num)
    sec = section(s.params, ics, 300, numerics=num)
    _, _, q, r = sec.long()
    ref = np.zeros((150, 200), dtype=np.int64)
    accumulate(ref, q, r, view)
    np.testing.assert_array_equal(img.counts, ref)
    assert img.points == q.size and img.in_view == ref.sum() and img.completed


def test_density_tolerance_keeps_points_within_a_quarter_pixel_over_its_window() -> None:
    """The promise of density_numerics, checked against scipy's DOP853 on the naive field (regular orbits)."""
    s = get_scene("fig1C")
    view, px = (*s.q_range, *s.r_range), (800, 600)
    pixel = min((view[1] - view[0]) / px[0], (view[3] - view[2]) / px[1])
    num = density_numerics(view, px, s.bound)
    ics = np.array([[0.3, 0.5], [-0.8, 1.2], [1.1, -0.4]])
    ours = section(s.params, ics, DENSITY_WINDOW, numerics=num)
    for i, ic in enumerate(ics):
        ref = solve_ivp_section(s.params, ic, DENSITY_WINDOW)
        err = np.max(np.linalg.norm(ours.points[i] - ref, axis=1))
        assert err < 0.25 * pixel, (i, err / pixel)


def test_an_attractor_image_matches_a_high_accuracy_one() -> None:
    """Fig. 8B's attractor: the image at the density tolerance and at 1e-12 hold the same distribution
    (L1 distance of the normalised coarse images within the sampling noise of a second seed)."""
    s = get_scene("fig8B")
    view = (*s.q_range, *s.r_range)
    kw = dict(view=view, pixels=(40, 40), transient=100)
    a = density(s.params, random_ics(200, s.box, seed=1), 200, **kw)
    b = density(s.params, random_ics(200, s.box, seed=1), 200, numerics=Numerics(rtol=1e-12, atol=1e-12,
                                                                                  bound=s.bound), **kw)  # fmt: skip
    c = density(s.params, random_ics(200, s.box, seed=2), 200, **kw)

    def l1(x, y):
        return np.abs(x.counts / x.counts.sum() - y.counts / y.counts.sum()).sum()

    assert a.in_view > 20_000
    assert l1(a, b) <= 1.5 * l1(a, c) + 0.02, (l1(a, b), l1(a, c))


def test_stream_keeps_the_asked_trajectories_and_cancels() -> None:
    s = get_scene("fig1C")
    ics = random_ics(10, s.box, seed=0)
    view = (*s.q_range, *s.r_range)
    kept: dict[int, list] = {2: [], 5: []}
    images = []
    for img, part in iter_density(s.params, ics, 100, view=view, pixels=(50, 50), keep=[2, 5], max_chunk=16):
        images.append(img.done_periods)
        for i, rows in part.items():
            kept[i].append(rows)
    assert images[-1] == 100 and images == sorted(images)
    sec = section(s.params, ics, 100, numerics=density_numerics(view, (50, 50), 1e4))
    for i, rows in kept.items():
        rows = np.concatenate(rows)
        np.testing.assert_array_equal(rows[:, 0], np.arange(1, 101))
        np.testing.assert_allclose(rows[:, 1:], sec.points[i], rtol=0, atol=1e-12)
    calls = []
    last = density(s.params, ics, 5000, view=view, pixels=(50, 50), cancel=lambda: calls.append(1) or len(calls) > 3)
    assert not last.completed and last.done_periods < 5000


def test_bad_input_is_refused() -> None:
    s = get_scene("fig1C")
    with pytest.raises(ParameterError, match="at most"):
        density(s.params, np.zeros((1000, 2)), MAX_DENSITY_POINTS // 1000 + 1, view=(-1, 1, -1, 1))
    with pytest.raises(ParameterError, match="view"):
        density(s.params, [[0.1, 0.2]], 10, view=(1, -1, -1, 1))
    with pytest.raises(ParameterError, match="pixels"):
        density(s.params, [[0.1, 0.2]], 10, view=(-1, 1, -1, 1), pixels=(0, 10))


def test_cli_density_npz_and_json(tmp_path) -> None:
    import json

    from clirun import run_cli

    out = tmp_path / "d.npz"
    rc, stdout, err = run_cli("density", "--scene", "fig8B", "--random", "50", "--periods", "40", "--transient", "10",
                              "--pixels", "64,48", "--out", str(out), "--json")  # fmt: skip
    assert rc == 0, err
    data = json.loads(stdout)
    npz = np.load(out)
    assert npz["counts"].shape == (48, 64) and npz["counts"].sum() == data["in_view"] > 0
    assert npz["q_edges"].size == 65 and npz["r_edges"].size == 49
    assert data["points"] <= 50 * 40 and data["completed"] and data["scene"] == "fig8B"
    for args, needle in ((["--pixels", "0,3"], "--pixels"), (["--random", "1000", "--periods", "20000"], "at most"),
                         (["--view", "1,0,0,1"], "--view")):  # fmt: skip
        rc, _, err = run_cli("density", "--scene", "fig8B", *args)
        assert rc == 2 and needle in err and "Traceback" not in err
