"""Guided tours of the paper (issue 23, item 2): data in one file, checked on load (a bad entry refused by name);
a step's settings change the state and the URL (tour and step in it), what to look at is marked on the plot,
next/back (buttons and arrow keys) move one step, and a teacher's own file loads from this server or an upload."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from jobs import Jobs

import app.tours
from app.page import Page
from app.runner import WARM
from app.state import state_from_query
from app.tours import TOURS, TourError, parse_tours, read_tour_url
from app.ui import ESM, check_message

FLIP = (-0.0377, -2.3979)  # Fig. 8B's period-1 flip saddle (bilimovich orbits --scene fig8B --max-period 2)


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def page_for(query: dict[str, str]) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page(query, lambda fn: fn(), executor=jobs, schedule=lambda d, fn: None)
    page.start()
    jobs.drain()
    return page, jobs


def test_the_paper_tours_cover_figures_1_4_7_8_10_11_with_3_to_6_steps() -> None:
    scenes = {t.scene[:4] for t in TOURS.values()}
    assert {"fig1", "fig4", "fig7", "fig8"} <= scenes and {"fig10", "fig11"} <= {t.scene for t in TOURS.values()}
    for t in TOURS.values():
        assert 3 <= len(t.steps) <= 6, t.id


def test_a_link_to_a_step_shows_it_and_next_back_move_one_step() -> None:
    published: list[dict[str, str]] = []
    jobs = Jobs()
    page = Page({"tour": "fig8B", "step": "2", "n": "2", "periods": "5"}, lambda fn: fn(), executor=jobs,
                publish_url=published.append, schedule=lambda d, fn: None)  # fmt: skip
    page.start()
    jobs.drain()
    st = page.state
    assert (st.tour, st.tour_step, st.scene, st.show_orbits, st.orbit_view, st.orbit_period) == (
        "fig8B", 2, "fig8B", True, True, 2)  # fmt: skip
    marks = page.fig.marks_data()
    assert marks["label"][0] == "flip saddle (period 1)"
    assert (marks["q"][0], marks["r"][0]) == pytest.approx(FLIP)
    # the mark is where the orbits layer drew the flip saddle (what the step says to look at is there)
    flips = [o for o in page.session.orbits if o["type"] == "flip saddle" and o["period"] == 1]
    assert flips and (flips[0]["q"], flips[0]["r"]) == pytest.approx(FLIP, abs=1e-3)
    view = page.ui.view["section"]["tour"]
    assert view["step"] == 2 and view["steps"] == 4 and "flip saddle" in view["text"]
    page.handle({"action": "tour_step", "value": "next"})
    jobs.drain()
    assert st.tour_step == 3 and st.manifold_saddles and published[-1]["step"] == "3"
    assert published[-1]["tour"] == "fig8B" and published[-1]["man"].startswith("-0.03766")
    page.handle({"action": "tour_step", "value": "back"})
    page.handle({"action": "tour_step", "value": "back"})
    page.handle({"action": "tour_step", "value": "back"})  # not before the first
    jobs.drain()
    assert st.tour_step == 1 and not st.orbit_view and page.fig.marks_data()["q"] == []
    assert published[-1]["step"] == "1"
    page.handle({"action": "tour", "value": ""})
    assert st.tour == "" and "tour" not in page.state.to_query()


@pytest.mark.parametrize("tour", sorted(TOURS))
def test_every_step_of_every_tour_applies_its_settings(tour: str) -> None:
    for n, step in enumerate(TOURS[tour].steps, 1):
        st, errors = state_from_query({"scene": TOURS[tour].scene, **step.settings})
        assert not errors, (tour, n, errors)
        q = st.to_query()
        for k, v in step.settings.items():
            assert q.get(k) == v or float(q[k]) == float(v), (tour, n, k)


def test_a_step_url_round_trips() -> None:
    page, jobs = page_for({"tour": "fig10", "step": "3", "n": "2", "periods": "5", "orb_n": "1"})
    q = page.state.to_query()
    assert q["tour"] == "fig10" and q["step"] == "3" and q["alpha"] == "-0.38" and q["play_to"] == "-0.42"
    again, errors = state_from_query(q)
    assert not errors and again.to_query() == q


def test_an_unknown_tour_in_the_url_is_said_and_the_page_still_works() -> None:
    page, jobs = page_for({"tour": "nope", "n": "2", "periods": "5"})
    assert page.state.tour == "" and "no tour 'nope'" in page.ui.view["section"]["tour"]["message"]
    assert page.session.n_points == 10


def _doc(**step: Any) -> str:
    base: dict[str, Any] = {"text": "Look.", "settings": {"alpha": "-0.4"}}
    base.update(step)
    return json.dumps({"tours": [{"id": "mine", "title": "Mine", "scene": "fig8B",
                                  "steps": [{"text": "One."}, base]}]})  # fmt: skip


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("{", "not JSON"),
        (json.dumps({"tour": []}), '{"tours": [...]}'),
        (_doc(settings={"alfa": "1"}), "tour 'mine' step 2: setting 'alfa'"),
        (_doc(settings={"alpha": "x"}), "tour 'mine' step 2: URL parameter alpha"),
        (_doc(settings={"I11": "-1"}), "tour 'mine' step 2: URL parameter I11"),
        (_doc(text=""), "tour 'mine' step 2: 'text'"),
        (_doc(look=[{"q": 1, "r": "x"}]), "tour 'mine' step 2: look #1"),
        (_doc(colour="red"), "tour 'mine' step 2: unknown field 'colour'"),
        (json.dumps({"tours": [{"id": "a b", "title": "t", "scene": "fig8B", "steps": []}]}), "tour #1: 'id'"),
        (
            json.dumps({"tours": [{"id": "x", "title": "t", "scene": "fig99", "steps": [{"text": "a"}]}]}),
            "tour 'x': unknown scene 'fig99'",
        ),
        (
            json.dumps({"tours": [{"id": "x", "title": "t", "scene": "fig8B", "steps": [{"text": "a"}] * 7}]}),
            "tour 'x': 'steps'",
        ),
    ],
)
def test_a_bad_tours_file_is_refused_naming_the_entry(text: str, words: str) -> None:
    with pytest.raises(TourError) as err:
        parse_tours(text, "mine.json")
    assert words in str(err.value) and str(err.value).startswith("mine.json")


def test_the_shipped_file_is_checked_the_same_way(tmp_path: Path) -> None:
    bad = json.loads(app.tours.TOURS_FILE.read_text())
    bad["tours"][3]["steps"][1]["settings"]["orb_n"] = "99"
    path = tmp_path / "tours.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(TourError, match=r"tour 'fig8B' step 2: URL parameter orb_n"):
        app.tours.load_tours(path)


def test_a_teachers_tours_load_from_this_server_or_an_upload(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(app.tours, "TOURS_DIR", tmp_path)
    (tmp_path / "class.json").write_text(_doc())
    assert list(read_tour_url("/tours/class.json")) == ["mine"]
    for url in ("/tours/../tours.json", "/etc/passwd.json", "/tours/none.json"):
        with pytest.raises(TourError):
            read_tour_url(url)
    assert "tour_url" in str(state_from_query({"tour_url": "https://example.com/t.json"})[1])
    page, jobs = page_for({"tour_url": "/tours/class.json", "tour": "mine", "step": "2", "n": "2", "periods": "5"})
    assert (
        page.state.tour == "mine"
        and page.state.alpha == -0.4
        and page.state.to_query()["tour_url"] == "/tours/class.json"
    )
    # an upload: checked the same way, a bad one refused by name, the paper's tours kept
    msg = check_message({"action": "tour_file", "value": _doc(settings={"alfa": "1"})})
    page.handle(msg)
    assert "the uploaded file: tour 'mine' step 2: setting 'alfa'" in page.ui.view["section"]["tour"]["message"]
    page.handle(check_message({"action": "tour_file", "value": _doc(text="Uploaded.")}))
    page.handle({"action": "tour", "value": "mine"})
    page.handle({"action": "tour_step", "value": "next"})
    assert page.ui.view["section"]["tour"]["text"] == "Uploaded." and "fig8B" in page.tours


def test_the_page_wires_buttons_and_arrow_keys_to_the_tour_and_play() -> None:
    for words in ('"ArrowRight"', '"ArrowLeft"', 'action: "tour_step", value: "next"',
                  'action: "tour_step", value: "back"', 'action: "shown"', '"pause" : "play"',
                  'action: "step"'):  # fmt: skip
        assert words in ESM, words
    assert check_message({"action": "tour_step", "value": "next"}) == {"action": "tour_step", "value": "next"}
    assert check_message({"action": "tour", "value": "x" * 201}) is None


def test_every_step_shown_in_a_page_sets_its_settings_marks_and_url() -> None:
    """Each step of each paper tour through the page (the jobs left queued: only the settings are checked)."""
    published: list[dict[str, str]] = []
    page = Page({"n": "2", "periods": "5"}, lambda fn: fn(), executor=Jobs(), publish_url=published.append,
                schedule=lambda d, fn: None)  # fmt: skip
    for tour in TOURS.values():
        for n, step in enumerate(tour.steps, 1):
            page.show_tour(tour.id, 1) if n == 1 else page.handle({"action": "tour_step", "value": "next"})
            q = published[-1]
            assert (q["tour"], q["step"]) == (tour.id, str(n))
            for k, v in step.settings.items():
                assert q.get(k) == v or float(q[k]) == float(v), (tour.id, n, k, q.get(k))
            assert page.state.tab == step.settings.get("tab", "section")
            assert page.fig.marks_data()["label"] == [m.label for m in step.look]
            assert not page.ui.view["section"]["errors"], (tour.id, n)


#: A small orbit diagram (the tour's scene sets its range; these stay from the link).
SMALL_DIAGRAM = {"bif_n": "4", "bif_pts": "3", "bif_tr": "5", "bif_orb": "0", "n": "2", "periods": "5"}


def test_a_step_that_opens_an_analysis_tab_presses_its_run_once() -> None:
    """Fig. 10's first step said "Press Run on this tab" on a tab where the tour's text was not shown: now the page
    presses it, and going back to the step shows that run's diagram instead of computing it again."""
    step = TOURS["fig10"].steps[0]
    assert step.run and step.tab == "bifurcation" and "Press Run" not in step.text
    assert TOURS["fig11"].steps[0].run and TOURS["fig11"].steps[0].tab == "chart"
    page, jobs = page_for({"tour": "fig10", "step": "1", **SMALL_DIAGRAM})
    tab = page.tabs["bifurcation"]
    assert page.state.tab == "bifurcation" and page.tabs["bifurcation"].view["result"]  # computed: 4 values
    assert page.ui.view["bifurcation"]["message"].startswith("4 values")
    runs: list[int] = []
    tab.run = lambda run=tab.run: (runs.append(1), run())[1]  # type: ignore[method-assign]
    page.handle({"action": "tour_step", "value": "next"})
    page.handle({"action": "tour_step", "value": "back"})
    jobs.drain()
    assert page.state.tab == "bifurcation" and runs == [] and tab.view["result"]
    page.handle({"action": "run", "tab": "bifurcation"})  # the user's own Run: the step presses it again after it
    page.handle({"action": "tour_step", "value": "next"})
    page.handle({"action": "tour_step", "value": "back"})
    assert runs == [1, 1]


@pytest.mark.parametrize(("step", "shown", "words"), [("99", 4, "there is no step 99"), ("0", 1, "there is no step 0"),
                                                       ("5", 4, "there is no step 5"),
                                                       ("abc", 1, "'abc' is not a step number")])  # fmt: skip
def test_a_step_the_tour_does_not_have_shows_the_nearest_and_says_so(step: str, shown: int, words: str) -> None:
    page, jobs = page_for({"tour": "fig10", "step": step, **SMALL_DIAGRAM})
    view = page.ui.view["section"]["tour"]
    assert page.state.tour_step == shown and view["step"] == shown and view["problem"]
    assert f"URL parameter step: {words}" in view["message"] and f"showing step {shown}" in view["message"]
    assert "has steps 1 to 4" in view["message"] and not page.ui.view["section"]["errors"]
    page.handle({"action": "tour_step", "value": "next" if shown == 1 else "back"})
    assert page.ui.view["section"]["tour"]["message"] == ""  # said once: moving on leaves it


def test_a_missing_tours_file_is_named_and_not_taken_for_a_missing_tour() -> None:
    page, jobs = page_for({"tour_url": "/tours/nope.json", "tour": "mine", "n": "2", "periods": "5"})
    view = page.ui.view["section"]["tour"]
    assert view["problem"] and "tour_url: no tours file '/tours/nope.json' on this server" in view["message"]
    assert "no tour 'mine'" not in view["message"] and "'mine'" in view["message"]
    assert page.state.tour == "" and page.session.n_points == 10  # the page works, with the paper's tours
    # A tour of the paper's with the file missing: shown, and the file still named.
    page, jobs = page_for({"tour_url": "/tours/nope.json", "tour": "fig8B", "step": "2", "n": "2", "periods": "5"})
    view = page.ui.view["section"]["tour"]
    assert view["step"] == 2 and "no tours file '/tours/nope.json'" in view["message"]
    # A tour that is in no file: "no tour".
    page, jobs = page_for({"tour": "mine", "n": "2", "periods": "5"})
    assert "URL parameter tour: no tour 'mine'" in page.ui.view["section"]["tour"]["message"]


@pytest.mark.parametrize(
    ("step", "words"),
    [({"run": "yes"}, "'run' must be true or false"), ({"run": True}, "'run' presses the Run of the tab"),
     ({"run": True, "settings": {"tab": "bench"}}, "got 'bench'")],
)  # fmt: skip
def test_a_step_that_presses_run_must_open_a_tab_with_a_run(step: dict[str, Any], words: str) -> None:
    with pytest.raises(TourError, match=words):
        parse_tours(_doc(**step), "mine.json")
    assert parse_tours(_doc(run=True, settings={"tab": "chart"}))["mine"].steps[1].run


def test_the_teachers_template_shows_a_step_that_presses_the_charts_run() -> None:
    page, jobs = page_for({"tour_url": "/tours/example.json", "tour": "example", "step": "3", "ch_n": "10",
                           "ch_tr": "0", "ch_curves": "0", "n": "2", "periods": "5"})  # fmt: skip
    assert page.state.tab == "chart" and page.state.chart_grid == (20, 15)
    assert page.tabs["chart"].chart is not None and page.ui.view["chart"]["message"] == "24/24 tiles"
