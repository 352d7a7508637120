"""The periodic-orbits layer of the section tab: a click finds an orbit, the URL carries the layer."""

from __future__ import annotations

import numpy as np
import pytest
from bokeh.events import Tap
from jobs import Jobs

from app.page import Page
from app.runner import WARM

FLIP = (-0.0377, -2.3979)  # Fig. 8B's flip saddle


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def page_for(query: dict) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page({"scene": "fig8B", "n": "2", "periods": "5", **query}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page, jobs


def tap(page: Page, q: float, r: float) -> None:
    page._on_tap(Tap(page.fig.fig, x=q, y=r))


def test_a_click_in_orbit_mode_finds_the_orbit_and_draws_it() -> None:
    page, jobs = page_for({"click": "orbit", "orb_n": "2"})
    assert page.state.click_mode == "orbit"
    tap(page, *FLIP)
    jobs.drain()
    rows = page.session.orbits
    assert [r["type"] for r in rows] == ["flip saddle"]
    assert rows[0]["period"] == 1 and "−" not in rows[0]["mu"] and "-3.028" in rows[0]["mu"]
    src = page.fig.orbit_data()
    assert src["type"] == ["flip saddle"] and page.fig.orbit_sources["saddle"].data["type"] == ["flip saddle"]
    np.testing.assert_allclose([src["q"][0], src["r"][0]], FLIP, atol=1e-3)
    view = page.ui.view["section"]
    assert view["n_orbits"] == 1 and "flip saddle" in view["orbit_status"]
    q = page.state.to_query()
    assert q["orb"].startswith("-0.0377,") and q["click"] == "orbit"
    csv = page.session.csv("orbits").decode()
    assert csv.splitlines()[1].startswith("# Bilimovich Explorer periodic orbits") and ",flip saddle,0,0," in csv


def test_a_click_where_there_is_no_orbit_says_so() -> None:
    page, jobs = page_for({"click": "orbit", "orb_n": "1"})
    tap(page, 0.9, -0.1)  # Newton from here goes elsewhere or fails: either an orbit or a stated reason
    jobs.drain()
    status = page.ui.view["section"]["orbit_status"]
    numerics, _, said = status.rpartition(" · ")  # the numerics Newton ran on come first when an orbit was found
    assert said.startswith("from (0.9, -0.1):") and (not numerics or numerics.startswith("Newton on vern9"))


def test_the_url_restores_the_orbits_and_a_new_system_recomputes_them() -> None:
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1"})
    assert [r["type"] for r in page.session.orbits] == ["flip saddle"]
    before = page.session.orbits[0]["q"]
    assert page.commit("alpha", "-0.44") is None
    jobs.drain()
    (row,) = page.session.orbits
    assert row["type"] == "flip saddle" and row["q"] != before  # the orbit of the new system
    page.handle({"action": "clear_orbits"})
    assert page.session.orbits == [] and page.state.orbit_seeds == [] and page.fig.orbit_data()["q"] == []


def test_every_orbit_in_view_and_the_layer_switch() -> None:
    page, jobs = page_for({"orb_n": "1", "qr": "-1.7,1", "rr": "-4.5,0.5"})
    page.handle({"action": "find_orbits"})
    jobs.drain()
    kinds = sorted(r["type"] for r in page.session.orbits)
    assert kinds == ["flip saddle", "saddle", "unstable focus"]
    assert page.state.to_query()["orb_all"] == "1" and page.ui.view["section"]["orbit_view"]
    assert page.commit("show_orbits", "false") is None
    jobs.drain()
    assert page.session.orbits == [] and page.fig.orbit_data()["q"] == []
    assert page.state.to_query()["orbits"] == "0"


def test_bad_orbit_values_in_the_url_are_reported() -> None:
    page, _ = page_for({"orb": "1,2,3", "orb_n": "40"})
    errors = page.ui.view["section"]["errors"]
    assert any("orb:" in e for e in errors) and any("orb_n" in e for e in errors)
    assert page.state.orbit_seeds == [] and page.state.orbit_period == 4
