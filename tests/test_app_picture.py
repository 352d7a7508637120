"""The picture the paper shows (issue 36, item 4), without a browser: the selected trajectory is drawn so that an
attractor under it stays visible, a selection can be cleared (a control, ``sel=none`` in the URL), and Pause and
Step keep the periodic orbits found while a parameter played."""

from __future__ import annotations

import math

import numpy as np
import pytest
from jobs import Jobs
from test_app_play import page_for

from app.layers.orbits import MAX_SETTLED, settled_cycles, unfollowed
from app.page import Page
from app.runner import WARM
from app.state import NO_SELECTION, state_from_query
from app.views import SectionFigure
from explorer_core.analyses.orbits import find_orbits


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


FIG8B = {"scene": "fig8B", "n": "6", "periods": "200", "tracks": "0", "tprime": "off"}


def fig8b_page(query: dict[str, str] | None = None) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page({**FIG8B, **(query or {})}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page, jobs


def ink(glyph: object, fill: bool) -> float:
    """The ink (px², opacity-weighted) of one marker of a Scatter glyph: its disc when filled, else its ring."""
    size = float(glyph.size)  # type: ignore[attr-defined]
    if fill:
        return math.pi * (size / 2) ** 2 * float(glyph.fill_alpha)  # type: ignore[attr-defined]
    return math.pi * size * float(glyph.line_width) * float(glyph.line_alpha)  # type: ignore[attr-defined]


def test_the_selected_trajectorys_ring_adds_less_ink_than_the_point_it_rings() -> None:
    """Fig. 8B's attractor was buried under the selected trajectory's 1,000 black rings (6 px, 0.8 px lines at 0.7:
    twice the ink of the point under each). A ring now adds less ink than one section point, and is only a little
    wider than it: the attractor's points and colours show through."""
    fig = SectionFigure((-2.0, 1.5), (-3.5, 0.5))
    sel = fig.fig.select_one({"name": "selected_points"}).glyph
    pts = fig.fig.select_one({"name": "section_points"}).glyph
    assert sel.fill_color is None
    assert ink(sel, fill=False) < ink(pts, fill=True)
    assert float(sel.size) <= 1.5 * float(pts.size)


def test_sel_none_round_trips_through_the_url_and_typed_none_clears_the_selection() -> None:
    state, errors = state_from_query({"scene": "fig8B", "sel": "none"})
    assert errors == [] and state.selected == NO_SELECTION
    assert state.to_query()["sel"] == "none"
    again, errors = state_from_query(state.to_query())
    assert errors == [] and again.selected == NO_SELECTION
    state, errors = state_from_query({"scene": "fig8B", "sel": "3"})
    assert state.selected == 3 and state.to_query()["sel"] == "3"
    state, errors = state_from_query({"scene": "fig8B", "sel": "nothing"})
    assert errors and "nothing" in errors[0] and state.selected == 0


def test_no_selection_rings_nothing_and_the_k_series_say_why() -> None:
    page, jobs = fig8b_page()
    assert len(page.fig.selected.data["q"]) == 200 and page.ui.series["k"]  # trajectory 0, ringed
    assert page.commit("selected", "none") is None
    jobs.drain()
    assert page.state.selected == NO_SELECTION and page.ui.values["selected"] == "none"
    assert len(page.fig.selected.data["q"]) == 0 and page.ui.series["k"] == []
    view = page.ui.view["section"]
    assert view["series_caption"].startswith("No trajectory selected") and view["series_note"]
    # a new run (another periods) keeps no selection: the finished run does not pick one again
    assert page.commit("periods", "150") is None
    jobs.drain()
    assert page.session.n_points and page.session.section.shown_periods == (150, 150)
    assert page.state.selected == NO_SELECTION
    assert len(page.fig.selected.data["q"]) == 0
    # a number selects again
    assert page.commit("selected", "2") is None
    jobs.drain()
    traj, _, q, _ = page.session.data()
    assert len(page.fig.selected.data["q"]) == np.count_nonzero(traj == 2) > 0
    assert page.ui.view["section"]["series_note"] == ""
    np.testing.assert_array_equal(np.sort(page.fig.selected.data["q"]), np.sort(q[traj == 2]))


def test_the_body_view_and_the_analysis_tabs_do_without_a_selection() -> None:
    page, jobs = fig8b_page({"sel": "none", "body": "1"})
    assert page.state.selected == NO_SELECTION
    assert "no trajectory is selected" in page.ui.view["section"]["body"]["status"]
    bench = page._open_tab("bench")
    ics = page.state.initial_conditions()
    assert bench._ic() == (float(ics[0, 0]), float(ics[0, 1]))  # type: ignore[attr-defined]  # the first, not the last


def test_pause_keeps_the_orbits_found_while_playing_and_step_follows_them_to_the_next_frame() -> None:
    """With the orbits layer on and nothing to search from (no clicked seed, no grid), the orbits a played frame
    shows are those its settled trajectories gave Newton; Pause used to drop them (the layer had nothing to search
    from, so it cleared), and Step too. Now Pause keeps every one, and Step shows them at the next frame's value,
    as an independent Newton from the paused orbits finds them there."""
    page, jobs, clock = page_for({"n": "10", "alpha": "-0.36", "play_dir": "backward"})
    assert page.session.orbits == [] and page.state.show_orbits and not page.state.orbit_view
    page.handle({"action": "play"})
    for _ in range(3):
        jobs.drain()
        clock.advance(0.2)
    jobs.drain()
    played = sorted((o["period"], round(o["q"], 6), round(o["r"], 6)) for o in page.session.orbits)
    assert played, "the played frames found no orbit from their settled trajectories"
    page.handle({"action": "pause"})
    jobs.drain()
    assert sorted((o["period"], round(o["q"], 6), round(o["r"], 6)) for o in page.session.orbits) == played
    assert len(page.fig.orbit_data()["q"]) == sum(p for p, _, _ in played)  # every point of every orbit drawn
    paused = page.state.alpha
    page.handle({"action": "step"})
    jobs.drain()
    assert page.state.alpha != paused
    stepped = sorted((o["period"], o["q"], o["r"]) for o in page.session.orbits)
    assert len(stepped) >= len(played)
    expected = find_orbits(page.state.system(), [(q, r) for _, q, r in played], sorted({p for p, _, _ in played}))
    for n, q, r in stepped:
        assert any(o.period == n and np.abs(o.points - (q, r)).max(axis=1).min() < 1e-7 for o in expected.orbits)


def test_a_still_shows_the_orbits_its_trajectories_settle_on_as_a_frame_does() -> None:
    """Fig. 10 played from -0.36 down to -0.42 with the orbits followed, then paused; Step wraps to -0.35: of the
    orbits followed there only the period-1 one exists, and the trajectories settle on a cycle no followed orbit is
    near. As a played frame does, the still hands its settled trajectories to Newton once its section is done:
    every cycle they settle on has its orbit."""
    page, jobs, clock = page_for({"n": "10", "alpha": "-0.36", "play_dir": "backward"})
    page.handle({"action": "play"})
    while page.state.alpha > -0.419:
        jobs.drain()
        clock.advance(0.2)
    jobs.drain()
    page.handle({"action": "pause"})
    jobs.drain()
    assert page.session.orbits
    page.handle({"action": "step"})
    jobs.drain()
    assert page.state.alpha == pytest.approx(-0.35)
    layer = page.session.layers["orbits"]
    cycles = settled_cycles(*page.session.data(), page.state.orbit_period)
    assert cycles and len(cycles) <= MAX_SETTLED
    assert unfollowed(cycles, layer.orbits) == []  # type: ignore[attr-defined]


def test_no_selection_restarts_no_density_run_and_survives_clearing_the_clicked_points() -> None:
    """A density view keeps the selected trajectory's points: choosing none has nothing to keep (no restart), and
    Clear clicked points, which selects the first trajectory when a clicked one was selected, keeps none."""
    page, jobs = fig8b_page({"render": "density", "ics": "0.1,-1"})
    started = page.session.section.t_start
    assert page.commit("selected", "none") is None
    jobs.drain()
    assert page.session.section.t_start == started and page.state.selected == NO_SELECTION
    page.handle({"action": "clear"})
    jobs.drain()
    assert page.state.clicked == [] and page.state.selected == NO_SELECTION
    assert len(page.fig.selected.data["q"]) == 0 and page.ui.series["k"] == []
