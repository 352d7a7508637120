"""The manifolds layer of the section tab: a click on a saddle draws its manifolds, the URL carries them."""

from __future__ import annotations

import numpy as np
import pytest
from test_app_orbits import FLIP, page_for, tap

from app.runner import WARM


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def test_a_click_on_a_saddle_draws_its_manifolds_and_the_homoclinic_points() -> None:
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "click": "manifolds", "man_len": "4"})
    assert page.state.click_mode == "manifolds"
    tap(page, FLIP[0] + 0.01, FLIP[1] - 0.01)  # near the cross, not on it
    assert page.state.manifold_saddles and page.state.manifold_saddles[0][2] == 1
    jobs.drain()
    data = page.fig.manifolds.data
    assert sorted(set(data["kind"])) == ["stable", "unstable"] and len(data["xs"]) >= 4
    assert all(len(x) == len(y) >= 2 for x, y in zip(data["xs"], data["ys"], strict=True))
    # Every piece starts at the saddle (or continues a split branch): the first one does.
    np.testing.assert_allclose([data["xs"][0][0], data["ys"][0][0]], FLIP, atol=1e-3)
    assert len(page.fig.crossings.data["q"]) > 0
    view = page.ui.view["section"]
    assert view["n_manifolds"] == 1
    assert view["manifold_status"].startswith("flip saddle (period 1)") and "homoclinic" in view["manifold_status"]
    q = page.state.to_query()
    assert q["man"].startswith("-0.0376") and q["man"].endswith(",1") and q["man_len"] == "4"
    assert q["click"] == "manifolds"
    csv = page.session.csv("manifolds").decode().splitlines()
    assert csv[1].startswith("# Bilimovich Explorer manifolds") and csv[0] == "saddle,branch,kind,s,q,r"
    assert {row.split(",")[2] for row in csv[2:]} == {"stable", "unstable"}


def test_a_second_click_removes_and_clear_empties_the_layer() -> None:
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "click": "manifolds", "man_len": "2"})
    tap(page, *FLIP)
    jobs.drain()
    assert page.fig.manifolds.data["xs"]
    tap(page, *FLIP)  # the same saddle again: removed
    jobs.drain()
    assert page.state.manifold_saddles == [] and page.fig.manifolds.data["xs"] == []
    tap(page, *FLIP)
    jobs.drain()
    page.handle({"action": "clear_manifolds"})
    jobs.drain()
    assert page.state.manifold_saddles == [] and page.fig.manifolds.data["xs"] == []
    assert page.fig.crossings.data["q"] == [] and page.ui.view["section"]["n_manifolds"] == 0
    assert "man" not in page.state.to_query()


def test_a_click_away_from_any_saddle_says_so() -> None:
    page, jobs = page_for({"click": "manifolds"})
    tap(page, 0.5, -1.0)
    assert page.state.manifold_saddles == []
    assert "no saddle" in page.ui.view["section"]["manifold_status"]
    page, jobs = page_for({"orb": "-0.019,0.077", "orb_n": "1", "click": "manifolds"})  # an unstable focus only
    tap(page, -0.019, 0.077)
    assert page.state.manifold_saddles == [] and "no saddle" in page.ui.view["section"]["manifold_status"]


def test_the_url_restores_the_manifolds_and_a_new_system_regrows_them() -> None:
    page, jobs = page_for({"man": f"{FLIP[0]},{FLIP[1]},1", "man_len": "2"})
    first = [np.asarray(x).copy() for x in page.fig.manifolds.data["xs"]]
    assert first
    assert page.commit("alpha", "-0.44") is None
    jobs.drain()
    again = page.fig.manifolds.data["xs"]
    assert again and not np.allclose(first[0][:5], np.asarray(again[0])[:5])
    assert "flip saddle" in page.ui.view["section"]["manifold_status"]


def test_a_saddle_that_is_no_longer_one_is_reported() -> None:
    page, jobs = page_for({"man": "-0.019,0.077,1"})  # Newton from here finds the unstable focus
    assert page.fig.manifolds.data["xs"] == []
    assert "not a saddle" in page.ui.view["section"]["manifold_status"]


@pytest.mark.parametrize("value", ["1,2", "1,2,0", "1,2,1.5", "nan,2,1", "1,2,1;3,4,1;5,6,1;7,8,1;9,9,1"])
def test_bad_manifold_values_in_the_url_are_reported(value: str) -> None:
    page, _ = page_for({"man": value, "man_len": "0"})
    errors = page.ui.view["section"]["errors"]
    assert any(e.startswith("URL parameter man:") for e in errors), errors
    assert any(e.startswith("URL parameter man_len:") for e in errors), errors
    assert page.state.manifold_saddles == [] and page.state.manifold_length == 10
