"""Long sections as a density image: auto switch at the point bound, zoom recomputes for the view."""

from __future__ import annotations

import numpy as np
import pytest
from test_app_orbits import page_for

from app.runner import WARM
from app.state import MAX_POINTS


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def image(page) -> np.ndarray | None:
    d = page.fig.density.data
    return np.asarray(d["image"][0]) if d["image"] else None


def test_a_density_view_bins_every_point_and_keeps_only_the_selected_trajectory() -> None:
    page, jobs = page_for({"render": "density", "n": "40", "periods": "200"})
    img = image(page)
    assert img is not None and img.shape == (600, 800)
    assert np.nansum(img) > 0.5 * 40 * 200  # Fig. 8B: some escape, most stay in view
    status = page.ui.view["section"]["status"]
    assert "points as a density image" in status and "in view" in status
    assert page.ui.view["section"]["density"]  # the page shows the image's legend
    # No clicked trajectory: no points over the image; the selected one (0 escaped in the transient: the first
    # kept one with points took over) is ringed and its k-series shown; only a few trajectories are kept.
    assert len(page.fig.points.data["q"]) == 0
    sel = page.state.selected
    assert sel in page.session.section.density.req.keep and len(page.session.section.density.req.keep) <= 9
    assert page.series.data["k"].size == 200 and len(page.fig.selected.data["q"]) == 0  # no rings over the image
    assert set(page.session.data()[0].tolist()) <= set(page.session.section.density.req.keep)
    assert page.state.to_query()["render"] == "density"
    csv = page.session.csv("section").decode().splitlines()
    assert csv[2].startswith("# a density view")  # the header, the settings, then the notes


def test_auto_draws_points_up_to_the_bound_and_a_density_beyond() -> None:
    page, jobs = page_for({"n": "4", "periods": "50"})
    assert image(page) is None and len(page.fig.points.data["q"]) > 0
    assert page.state.render == "auto" and "render" not in page.state.to_query()
    assert page.commit("n_random", "100") is None
    assert page.commit("periods", str(MAX_POINTS // 100 + 10)) is None  # 100 x 4010 > 400,000: density
    jobs.drain()
    assert image(page) is not None and "density image" in page.ui.view["section"]["status"]
    assert page.commit("periods", "50") is None  # back under the bound: points, no image
    jobs.drain()
    assert image(page) is None and len(page.fig.points.data["q"]) > 100
    assert not page.ui.view["section"]["density"]


def test_zooming_a_density_view_recomputes_it_for_the_view_with_seeds_in_it() -> None:
    page, jobs = page_for({"render": "density", "n": "30", "periods": "50"})
    assert image(page) is not None
    zoom = ((-0.5, 0.0), (-2.6, -2.2))
    page.session.set_view_from_plot(*zoom)
    jobs.drain()
    d = page.fig.density.data
    assert (d["x"][0], d["y"][0]) == (-0.5, -2.6) and d["dw"][0] == pytest.approx(0.5)
    req = page.session.section.density.req
    assert req is not None and req.view == (-0.5, 0.0, -2.6, -2.2)
    inside = (req.ics[:, 0] >= -0.5) & (req.ics[:, 0] <= 0.0) & (req.ics[:, 1] >= -2.6) & (req.ics[:, 1] <= -2.2)
    assert inside.all()  # the random seeds start in the view
    assert req.numerics.rtol < 1e-7  # a finer view: a tighter tolerance
    page.session.set_view_from_plot((-3.0, 2.5), (-4.5, 1.0))  # zoomed out past the box: the box's seeds again
    jobs.drain()
    box = page.state.box
    ics = page.session.section.density.req.ics
    assert ics[:, 0].min() >= box[0] and ics[:, 0].max() <= box[1]
    assert ics[:, 0].max() - ics[:, 0].min() > 0.5 * (box[1] - box[0])


def test_selecting_another_trajectory_in_a_density_view_keeps_its_points() -> None:
    page, jobs = page_for({"render": "density", "n": "30", "periods": "40"})
    assert page.commit("selected", "20") is None  # not among the kept: the image is recomputed keeping it
    jobs.drain()
    assert 20 in page.session.section.density.req.keep
    assert page.commit("selected", "3") is None
    jobs.drain()
    assert 3 in page.session.section.density.req.keep and page.series.data["k"].size > 0


def test_points_only_is_refused_for_a_density_sized_section() -> None:
    page, jobs = page_for({"n": "1000", "periods": "1000"})
    assert image(page) is not None
    msg = page.commit("render", "points")
    assert msg is not None and "as points" in msg and page.state.render == "auto"
