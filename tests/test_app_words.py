"""Clear words (issue 21, item 4): stable trajectory numbers, modes that say they are on, honest progress."""

from __future__ import annotations

import numpy as np
import pytest
from test_app_orbits import page_for

from app.runner import WARM


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def test_a_click_does_not_renumber_the_random_trajectories() -> None:
    """Metamorphic: adding a clicked initial condition leaves every random trajectory's number, points and fate
    as they were. Fails on the old code (clicked ones came first: every random id shifted by one, the escaped
    list and the CSV's ids with them)."""
    page, jobs = page_for({"n": "40", "periods": "150", "transient": "0"})
    traj0, k0, q0, r0 = page.session.data()
    escaped0 = list(page.session.escaped)
    assert escaped0, "Fig. 8B: some of 40 random trajectories escape"
    page.session.add_initial_condition(0.1, -1.0)
    jobs.drain()
    traj, k, q, r = page.session.data()
    assert page.state.selected == 40 and set(traj[traj >= 40].tolist()) <= {40}  # the clicked one: number 40
    assert page.ui.view["section"]["series_caption"].startswith("Trajectory 40 (clicked):")
    # Each random trajectory keeps its number: the same count of points, and its first point to within the
    # integration tolerance (the core's batch shares its adaptive steps, so a trajectory's numbers move at the
    # tolerance level with the batch's make-up, and chaos grows that later on: only the first is compared).
    for i in range(40):
        assert np.count_nonzero(traj == i) == np.count_nonzero(traj0 == i), i
        if np.any(traj0 == i):
            a, b = np.argmin(np.where(traj0 == i, k0, np.inf)), np.argmin(np.where(traj == i, k, np.inf))
            assert abs(q0[a] - q[b]) + abs(r0[a] - r[b]) < 1e-4, i
    assert [i for i in page.session.escaped if i < 40] == escaped0
    # More random ones: the clicked trajectory keeps the selection (renumbered after them).
    assert page.commit("n_random", "45") is None
    jobs.drain()
    assert page.state.selected == 45
    assert tuple(page.state.initial_conditions()[45]) == (0.1, -1.0)


def test_a_long_transient_says_so_instead_of_zero_periods() -> None:
    """Fails on the old code: 'computing 0/100 periods' for the whole transient (the core yields no point then)."""
    from test_app_orbits import Jobs

    from app.page import Page

    jobs = Jobs()
    page = Page({"scene": "fig8B", "n": "2", "periods": "100", "transient": "500"}, lambda fn: fn(), executor=jobs)
    page.start()  # the section job is queued, not run: nothing has come back yet
    status = page.ui.view["section"]["status"]
    assert "transient of 500 periods" in status and "0/100" not in status, status
    jobs.drain()
    assert "transient" not in page.ui.view["section"]["status"]


def test_find_orbits_in_view_says_when_it_is_a_mode() -> None:
    """Fails on the old code: the button only greyed out (the search stays on and is redone on every pan)."""
    page, jobs = page_for({"orb_n": "1"})
    assert page.ui.view["section"]["find_label"] == "Find orbits in view"
    page.handle({"action": "find_orbits"})
    jobs.drain()
    view = page.ui.view["section"]
    assert view["find_label"] == "Orbits in view: on"
    assert "pan or zoom" in view["find_title"] and "Clear orbits" in view["find_title"]
    page.handle({"action": "clear_orbits"})
    assert page.ui.view["section"]["find_label"] == "Find orbits in view"


def test_a_new_chart_parameter_gets_a_range_of_its_own() -> None:
    """Fails on the old code: the y range stayed I11's (1, 2) after choosing g0 as the y parameter."""
    from app.state import commit, state_from_query

    state, _ = state_from_query({"scene": "fig8B"})
    assert commit(state, "chart_y", "g0") is None
    lo, hi = state.chart_yrange
    assert lo < state.g0 < hi and (lo, hi) != (1.0, 2.0)
    for end in (lo, hi):
        state.system(g0=end)  # valid systems at both ends
    assert commit(state, "chart_x", "I12") is None
    lo, hi = state.chart_xrange
    assert lo < state.I12 < hi
    assert commit(state, "chart_yrange", "0.1,0.2") is None and state.chart_yrange == (0.1, 0.2)
    assert commit(state, "chart_y", "g0") is None and state.chart_yrange == (0.1, 0.2)  # the same: kept


def test_the_fig11_scene_points_to_the_chart_tab() -> None:
    """Fails on the old code: 16 points and two warnings on the section tab, nothing saying where Fig. 11 is."""
    page, jobs = page_for({"scene": "fig11"})
    assert "'Chart of regimes' tab" in page.ui.view["section"]["scene_info"]
    page2, _ = page_for({"scene": "fig8A"})
    assert "' tab" not in page2.ui.view["section"]["scene_info"]


def test_the_chart_says_the_colours_of_the_curves_it_draws() -> None:
    """Fails on the old code: 'period doubling: black, fold: magenta' with no fold drawn, and no hover."""
    from types import SimpleNamespace

    from bokeh.models import HoverTool

    from explorer_core.analyses.continuation import Curve

    page, jobs = page_for({})
    page.handle({"action": "tab", "tab": "chart"})
    tab = page.tabs["chart"]
    pd = Curve("period_doubling", 1, [(0.0, 1.0, 0.0, 0.0), (0.1, 1.1, 0.0, 0.0)])
    tab._curves([SimpleNamespace(curves=[pd], bifurcations=[1], messages=[], lost=[])])
    line = next(x for x in tab.view["result"] if x.startswith("boundaries:"))  # then the codimension-two points
    assert "period doubling: black" in line and "magenta" not in line, line
    assert tab.curves.data["kind"] == ["period doubling of the period-1 cycle"]
    fold = Curve("fold", 2, [(0.0, 1.0, 0.0, 0.0), (0.1, 1.1, 0.0, 0.0)])
    tab._curves([SimpleNamespace(curves=[pd, fold], bifurcations=[1, 2], messages=[], lost=[])])
    assert "fold: magenta" in tab.view["result"][-2] and tab.curves.data["color"] == ["#000000", "#e377c2"]
    hovers = [t for t in tab.figure().toolbar.tools if isinstance(t, HoverTool)]
    assert any(r.name == "chart_curve_lines" for h in hovers for r in h.renderers)


def test_the_analysis_tabs_still_start_from_the_clicked_points_first() -> None:
    """The clicked points are numbered after the random ones in the section; the chart (one initial condition),
    the orbit diagram (four) and the Lyapunov tab still start from the clicked/scene points first."""
    from app.state import state_from_query

    state, _ = state_from_query({"scene": "fig1A", "n": "5"})  # Fig. 1A: one point of its own, 5 random
    assert tuple(state.initial_conditions()[5]) == tuple(state.clicked[0])
    assert tuple(state.analysis_ics()[0]) == tuple(state.clicked[0])
    assert state.analysis_ics().shape == (6, 2) and state.selected == 5  # the scene's own point is shown


# --- the numerics' messages in the page's words; values where the model is meaningless refused (issue 36, item 5) ---

#: Words of the code and the command line that a student cannot act on here (the page has no max_steps).
CODE_WORDS = ("rho*T/beta", "max_steps", "too_many_steps", "step_collapsed", "10*eps*|t|", "rho*h", "rtol")


def _core_warnings() -> list[str]:
    """The reliability messages of the core that name its options and formulas, as it writes them."""
    from explorer_core.analyses.reliability import assess
    from explorer_core.scenes import get_scene
    from explorer_core.solve.numerics import Numerics

    base = get_scene("fig8B").params
    fast = base.with_(alpha=1e6)
    out = []
    out += [w.message for w in assess(fast, Numerics(), periods=10, ics=[(0.1, -1.0)])]
    out += [w.message for w in assess(base, Numerics(), periods=10, ics=[(0.1, -1.0)],
                                      status=["step_collapsed", "too_many_steps", "ok"])]  # fmt: skip
    out += [w.message for w in assess(base, Numerics(method="rk4", steps_per_period=8), periods=1000,
                                      ics=[(30.0, -40.0)], window=(-2, 2, -4, 1), pixel=0.01)]  # fmt: skip
    out += [w.message for w in assess(base, Numerics(rtol=1e-3, atol=1e-3), periods=5000, ics=[(0.1, -1.0)],
                                      window=(-2, 2, -4, 1), pixel=1e-4)]  # fmt: skip
    return out


def test_the_numerics_messages_are_in_the_pages_words() -> None:
    """Fails on the old code: 'rho*T/beta', 'max_steps', 'too_many_steps', 'step_collapsed', '10*eps*|t|' and
    'Raise max_steps' (a setting the page does not have) reached the page as the core wrote them."""
    from app.words import page_words

    messages = _core_warnings()
    said = " ".join(messages)
    assert all(w in said for w in ("rho*T/beta", "max_steps", "'too_many_steps'", "'step_collapsed'", "10*eps*|t|"))
    for m in messages:
        words = page_words(m)
        assert not [w for w in CODE_WORDS if w in words], words
    joined = " ".join(page_words(m) for m in messages)
    assert "'step collapsed'" in joined and "step budget of" in joined and "Compute fewer periods" in joined
    assert "'RK4 steps per period'" in joined and "Accuracy" in joined


def test_the_section_shows_its_warnings_in_the_pages_words() -> None:
    page, jobs = page_for({})
    (message,) = [m for m in _core_warnings() if "max_steps =" in m and "ran out" in m]
    page.session.section._warn([{"level": "error", "code": "too_many_steps", "message": message}])
    page._refresh_views()
    (shown,) = page.ui.view["section"]["warnings"]
    assert "max_steps" not in shown["message"] and "the page's step budget is fixed" in shown["message"]


@pytest.mark.parametrize(("name", "text"), [("alpha", "1e308"), ("alpha", "1e7"), ("g1", "1e200"), ("omega", "1e-300")])
def test_a_value_that_leaves_nothing_to_compute_is_refused_with_the_reason(name: str, text: str) -> None:
    """Fails on the old code: alpha = 1e308 was accepted and every trajectory failed after seconds of work."""
    from app.state import commit, state_from_query

    state, _ = state_from_query({"scene": "fig1C"})
    before = getattr(state, name)
    problem = commit(state, name, text)
    assert problem is not None and getattr(state, name) == before
    assert "leaves the model nothing to compute" in problem or "must" in problem, problem
    assert commit(state, "alpha", "0.2") is None and commit(state, "alpha", "1000") is None  # slow, but it runs


def test_counts_take_the_number_of_their_noun() -> None:
    from app.words import counted

    assert [counted(n, "trajectory") for n in (0, 1, 2)] == ["0 trajectories", "1 trajectory", "2 trajectories"]
    assert counted(1, "periodic orbit") == "1 periodic orbit" and counted(3, "periodic orbit") == "3 periodic orbits"
    assert counted(2, "branch") == "2 branches" and counted(2, "Newton search") == "2 Newton searches"
    assert counted(2, "day") == "2 days" and counted(12345, "point", grouped=True) == "12,345 points"
