"""Messages that go away when they stop being true, in the controls' own words, on the tab they concern."""

from __future__ import annotations

import pytest
from test_app_orbits import Jobs, page_for

from app.page import Page
from app.runner import WARM
from app.state import CONTROLS, commit, state_from_query

#: Attribute names a student never sees (the controls show labels).
INTERNAL = ("n_random", "steps_per_period", "orbit_period", "basin_grid", "chart_xrange", "seed-period")


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def _page(query: dict) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page({"n": "2", "periods": "5", **query}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page, jobs


def test_refusals_name_the_controls_by_their_labels() -> None:
    """Fails on the old code: 'n_random must be between … — still using n_random = 60'."""
    from app.state import plain_label

    state, _ = state_from_query({})
    for name, text in [("n_random", "20000"), ("steps_per_period", "3"), ("orbit_period", "99"),
                       ("basin_grid", "1"), ("chart_xrange", "2,1"), ("chart_grid", "1,1")]:  # fmt: skip
        msg = commit(state, name, text)
        assert msg is not None and plain_label(name) in msg, (name, msg)
        assert not any(word in msg for word in INTERNAL), msg
    assert plain_label("n_random") == "Random initial conditions" and plain_label("alpha") == "α"
    _, errors = state_from_query({"n": "20000000", "orb_n": "0", "ch_xr": "a"})
    assert len(errors) == 3 and not any(word in e for e in errors for word in INTERNAL), errors
    for c in CONTROLS:  # every control has words of its own for messages
        assert plain_label(c.name)


def test_the_orbit_search_says_what_it_did_in_plain_words() -> None:
    """Fails on the old code: '51 seed-period pairs found none'."""
    page, jobs = page_for({"orb_all": "1", "orb_n": "2"})
    status = page.ui.view["section"]["orbit_status"]
    assert "periodic orbits of period 1..2 from 100 starting points" in status, status
    assert "seed" not in status


def test_a_new_scene_clears_the_url_errors_and_the_refusals() -> None:
    """Fails on the old code: the URL's errors stayed under every later scene."""
    page, jobs = _page({"scene": "fig1C", "I12": "5", "alpha": "nan"})
    assert len(page.ui.view["section"]["errors"]) == 2
    assert page.commit("I11", "0") is not None
    assert len(page.ui.view["section"]["errors"]) == 3
    assert page.commit("scene", "fig8B") is None
    jobs.drain()
    assert page.ui.view["section"]["errors"] == [] and page.ui.messages == {}


def test_retyping_the_value_in_use_clears_its_refusal() -> None:
    """The server's half (the page's half is a browser test): the value in use, sent again, answers the refusal."""
    page, jobs = _page({"scene": "fig1C"})
    for text in ("0", "-1", "abc"):
        assert page.commit("I11", text) is not None
    assert len(page.ui.view["section"]["errors"]) == 1  # one line per control, the latest refusal
    assert page.commit("I11", "1") is None  # the value in use
    assert page.ui.view["section"]["errors"] == [] and "I11" not in page.ui.messages


def test_url_errors_of_an_analysis_tab_are_shown_on_that_tab() -> None:
    """?tab=chart&ch_grid=1000,1000: the refusal and the value used instead are on the chart tab, not on the
    hidden section tab (fails on the old code)."""
    page, jobs = _page({"tab": "chart", "ch_grid": "1000,1000", "I12": "5"})
    chart = page.ui.view["chart"]["errors"]
    section = page.ui.view["section"]["errors"]
    assert any(e.startswith("URL parameter ch_grid:") and "using grid NX,NY = 40,30" in e for e in chart), chart
    assert not any("ch_grid" in e for e in section), section
    # The system's error concerns the chart too: shown on the tab the user is on, and on the section tab.
    assert any(e.startswith("URL parameter I12:") for e in chart) and any("I12" in e for e in section)
    # Typing the grid answers the URL's refusal.
    assert page.commit("chart_grid", "6,4") is None
    assert not any("ch_grid" in e for e in page.ui.view["chart"]["errors"])
    page.handle({"action": "tab", "tab": "section"})
    assert not any(e.startswith("URL parameter I12:") for e in page.ui.view["chart"]["errors"])
    assert any("I12" in e for e in page.ui.view["section"]["errors"])


#: Values Panel's query parsing raised on (blank page, server traceback) or turned into other types.
HOSTILE = {
    "n": "²",  # str.isdigit() but not int()
    "periods": "9" * 5000,  # beyond int()'s 4300 digits
    "ics": "[1,2]",  # JSON: arrived as a list
    "alpha": '{"a": 1}',  # literal_eval: arrived as a dict
    "I11": "1e999999",
    "seed": "\x00",
}


def test_the_app_reads_the_raw_query_itself_and_reports_every_hostile_value_by_its_key() -> None:
    """Fails on the old code: ``pn.state.location.query_params`` raised on ``?n=²`` (a blank page)."""
    from panel.io.location import Location

    from app.main import AppLocation, raw_query

    class Request:  # what Bokeh's request proxy gives the session: raw bytes per key
        def __init__(self) -> None:
            self.arguments = {k: [v.encode()] for k, v in HOSTILE.items()}

    query = raw_query(Request())
    assert query == {k: [v.encode()] for k, v in HOSTILE.items()}
    page, jobs = _page(query)
    errors = page.ui.view["section"]["errors"]
    for key in HOSTILE:
        assert any(e.startswith(f"URL parameter {key}:") for e in errors), (key, errors)
    assert page.session.n_points > 0  # the page works with the values in use
    # Panel's own Location parses every query it is given; the app's never does.
    with pytest.raises(ValueError):
        Location().search = "?n=%C2%B2"
    AppLocation().search = "?n=%C2%B2&periods=" + "9" * 5000
