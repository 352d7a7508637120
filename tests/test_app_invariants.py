"""The page's promises under random use (hypothesis state machine, no browser).

A page (app/page.py) is driven with random sequences of what a user does: typed values (good,
bad, empty, absurd), URL parameters, Stop, tab switches, runs, clicks, with jobs held in a
queue and run at random moments. After every step:

* every control shows the value in use (a refused value is never displayed as if used), and a
  refused one has a message saying so next to the control;
* nothing is "running" (Stop enabled, "computing" in a status) unless a job of that view is
  queued or running; once the work is done, failed or cancelled, nothing says "computing";
* a download is offered only when there is data to download;
* an analysis whose result is empty or whose members all failed says so and reports no numbers.

The browser side of the same promises (the DOM shows these values) is tests/browser.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from app.page import TAB_CLASSES, Page
from app.runner import WARM
from app.state import BY_NAME, CONTROLS, SYSTEM_FIELDS, TABS, parse_control
from explorer_core.system.params import ParameterError


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


class HeldJobs:
    """An executor that keeps submitted jobs until the test runs them (a server's jobs run later too)."""

    def __init__(self) -> None:
        self.queue: list[Any] = []

    def submit(self, fn, /, *args, **kwargs) -> None:
        self.queue.append(lambda: fn(*args, **kwargs))

    def run_one(self, i: int) -> None:
        if self.queue:
            self.queue.pop(i % len(self.queue))()

    def drain(self) -> None:
        while self.queue:
            self.queue.pop(0)()


SMALL = {"n": "3", "periods": "8", "ly_n": "12", "ly_tr": "5", "ly_m": "2", "bif_n": "4", "bif_pts": "3",
         "bif_tr": "5", "ch_grid": "3,2", "ch_n": "12", "ch_tr": "5"}  # fmt: skip
#: Controls a user can type into (analysis work kept small: big values are refused by the bounds below).
TYPED = [c.name for c in CONTROLS if c.name not in ("scene",)]
BAD_TEXT = st.sampled_from(["", " ", "nan", "inf", "-inf", "abc", "1e400", "1,2,3", "0x10", "½", "1e9", "-1", "2.5",
                            "<b>x</b>", "9" * 60])  # fmt: skip
#: Upper bounds that keep one run quick (the text is still typed: a bigger value gets refused).
QUICK_MAX = {"n_random": 6, "periods": 20, "transient": 20, "steps_per_period": 60, "lyap_periods": 30,
             "lyap_transient": 20, "lyap_ensemble": 3, "bif_values": 6, "bif_points": 5, "bif_transient": 20,
             "chart_periods": 20, "chart_transient": 10, "bench_periods": 4, "seed": 10**6, "selected": 8,
             "basin_grid": 12, "manifold_length": 3}  # fmt: skip


def texts_for(name: str) -> st.SearchStrategy[Any]:
    c = BY_NAME[name]
    if c.kind == "float":
        good = st.floats(-3, 6, allow_nan=False).map(lambda v: repr(round(v, 3)))
    elif c.kind == "int":
        lo = int(c.bounds[0])
        good = st.integers(lo - 2, QUICK_MAX.get(name, lo + 20)).map(str)
    elif c.kind in ("select", "radio"):
        good = st.sampled_from([v for v, _ in c.options] + ["bogus"])
    elif c.kind == "check":
        good = st.sampled_from([True, False, "true", "maybe"])
    elif name == "chart_grid":
        good = st.sampled_from(["2,2", "3,2", "4,3", "500,500", "1,1", "2"])
    else:  # ranges and points
        pair = st.tuples(st.floats(-2, 2, allow_nan=False), st.floats(-2, 2, allow_nan=False))
        good = st.one_of(pair.map(lambda p: f"{p[0]:.3f},{p[1]:.3f}"), st.just(""))
    return st.one_of(good, BAD_TEXT)


def _typed(names: list[str]) -> st.SearchStrategy[tuple[str, Any]]:
    return st.sampled_from(names).flatmap(lambda n: st.tuples(st.just(n), texts_for(n)))


section_typed = _typed([n for n in TYPED if BY_NAME[n].area not in TAB_CLASSES])
analysis_typed = _typed([n for n in TYPED if BY_NAME[n].area in TAB_CLASSES])
URL_KEYS = [c.url for c in CONTROLS if c.url] + ["box", "qr", "rr", "ics", "tprime", "tab", "present"]
URL_TEXTS = ["0", "1", "2", "fig8B", "fig11", "chart", "lyapunov", "rk4", "0.3,-0.2", "-1,1", "1,2;3,4", "inst", "off"]
url_queries = st.dictionaries(
    st.sampled_from(URL_KEYS),
    st.one_of(BAD_TEXT, st.sampled_from(URL_TEXTS)),
    max_size=5,
)
NUMBERS = re.compile(r"[=:]\s*-?\d")


class PageMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.jobs = HeldJobs()
        self.page = self._page({})

    def _page(self, query: dict[str, str]) -> Page:
        q = dict(SMALL)
        q.update(query)
        self.last: tuple[str, Any, Any, str | None] | None = None
        page = Page(q, lambda fn: fn(), executor=self.jobs)
        page.start()
        return page

    # --- what a user does ---------------------------------------------------------------------

    @rule(query=url_queries)
    def open_url(self, query: dict[str, str]) -> None:
        self.page.close()
        self.jobs.queue.clear()
        self.page = self._page(query)
        st_ = self.page.state
        for key, text in query.items():  # a URL value that is not in use is reported
            c = next((c for c in CONTROLS if c.url == key), None)
            if c is None or key in ("tracks",):
                continue
            try:
                value = parse_control(c.name, text, key)
            except ParameterError:
                assert any(e.startswith(f"URL parameter {key}:") for e in self.page.url_errors), (key, text)
                continue
            if getattr(st_, c.name) != value and c.name != "scene":
                assert any(e.startswith(f"URL parameter {key}:") for e in self.page.url_errors), (key, text)

    @rule(ct=section_typed)
    def type_a_sidebar_value(self, ct: tuple[str, Any]) -> None:
        self.type_value(ct)

    @rule(ct=section_typed)
    def type_another_sidebar_value(self, ct: tuple[str, Any]) -> None:
        self.type_value(ct)

    @rule(ct=analysis_typed)
    def type_an_analysis_value(self, ct: tuple[str, Any]) -> None:
        self.type_value(ct)

    def type_value(self, ct: tuple[str, Any]) -> None:
        name, text = ct
        before = getattr(self.page.state, name)
        problem = self.page.handle({"commit": name, "text": text}) or self.page.messages.get(name)
        self.last = (name, text, before, problem)

    @rule(tab=st.sampled_from(TABS))
    def switch_tab(self, tab: str) -> None:
        self.page.handle({"action": "tab", "tab": tab})
        assert self.page.ui.tab == tab and self.page.state.tab == tab

    @rule(tab=st.sampled_from(TABS))
    def stop(self, tab: str) -> None:
        self.page.handle({"action": "stop", "tab": tab})
        assert not self.page.running(tab)

    @precondition(lambda self: all(getattr(self.page.state, n) <= QUICK_MAX[n] for n in QUICK_MAX))
    @rule(tab=st.sampled_from(["lyapunov", "bifurcation", "chart"]))
    def run(self, tab: str) -> None:
        self.page.handle({"action": "run", "tab": tab})

    @rule(q=st.floats(-3, 3), r=st.floats(-5, 5))
    def click(self, q: float, r: float) -> None:
        self.page._on_tap(type("Tap", (), {"x": q, "y": r})())

    @rule()
    def clear(self) -> None:
        self.page.handle({"action": "clear"})

    @rule(action=st.sampled_from(["find_orbits", "clear_orbits", "clear_manifolds"]))
    def layer_button(self, action: str) -> None:
        self.page.handle({"action": action})

    @rule(i=st.integers(0, 5))
    def work_a_little(self, i: int) -> None:
        self.jobs.run_one(i)

    @rule()
    def work_until_done(self) -> None:
        self.jobs.drain()
        for tab in ("section", *self.page.tabs):
            assert not self.page.running(tab), tab

    # --- what must always hold ------------------------------------------------------------------

    @invariant()
    def controls_show_the_values_in_use(self) -> None:
        page = self.page
        for c in CONTROLS:
            assert page.ui.values[c.name] == page.state.display(c.name), c.name
        if self.last is not None:
            name, text, before, problem = self.last
            now = getattr(page.state, name)
            if problem:
                assert now == before and "still using" in problem, (name, text, problem)
                assert page.ui.messages.get(name) == problem
            else:
                assert name not in page.ui.messages
            self.last = None

    @invariant()
    def nothing_runs_without_work(self) -> None:
        page = self.page
        view = page.ui.view
        queued = bool(self.jobs.queue)
        for tab in ("section", *page.tabs):
            v = view[tab]
            assert v["running"] == page.running(tab), tab
            if not queued:
                assert not v["running"], tab
            if not v["running"]:
                text = v.get("status", "") if tab == "section" else v.get("message", "")
                assert "computing" not in text, (tab, text)

    @invariant()
    def downloads_only_with_data(self) -> None:
        page = self.page
        s = page.ui.view["section"]
        assert bool(s["n_points"]) == bool(page.session.data()[0].size)
        assert bool(s["n_manifolds"]) == bool(
            page.session.layer("manifolds").manifolds
        )  # the manifolds CSV offers exactly these
        if not page.state.show_basins:
            assert not s["basin_legend"] and not page.fig.basins.data["image"]
        if "chart" in page.tabs:
            assert page.ui.view["chart"]["download"] == (page.tabs["chart"].npz_bytes() is not None)

    @invariant()
    def empty_results_report_no_numbers(self) -> None:
        for tab in page_tabs(self.page):
            lines = self.page.ui.view[tab]["result"]
            if lines and lines[0].startswith(("No exponents", "No points", "No pixel")):
                head = lines[0].split("(")[0]
                assert not NUMBERS.search(head), lines

    def teardown(self) -> None:
        self.page.close()


def page_tabs(page: Page) -> list[str]:
    return [t for t in page.tabs if t in TAB_CLASSES]


TestPage = PageMachine.TestCase
TestPage.settings = settings(max_examples=60, stateful_step_count=20, deadline=None,
                             suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])  # fmt: skip


def test_a_refused_value_names_itself_and_the_value_kept() -> None:
    jobs = HeldJobs()
    page = Page(dict(SMALL), lambda fn: fn(), executor=jobs)
    page.start()
    for name, text in [("I11", "0"), ("alpha", ""), ("periods", "1e9"), ("chart_grid", "500,500")]:
        problem = page.commit(name, text)
        assert problem and "still using" in problem and page.ui.messages[name] == problem
        assert page.ui.values[name] == page.state.display(name)
        area = BY_NAME[name].area
        shown = page.ui.view.get(area, page.ui.view["section"]) if area in TAB_CLASSES else page.ui.view["section"]
        if area not in TAB_CLASSES:
            assert problem in shown["errors"]  # in the main area too
    assert page.commit("alpha", "0.2") is None and "alpha" not in page.ui.messages
    jobs.drain()
    assert not page.running() and "computing" not in page.ui.view["section"]["status"]
    assert set(SYSTEM_FIELDS) <= set(page.ui.values)
    assert np.isfinite(page.state.alpha)
