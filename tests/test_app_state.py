"""The app's state objects without a browser: parameters -> core calls -> data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.controller import ExplorerSession
from app.runner import WARM, InlineExecutor, Runner
from app.state import MAX_DENSITY_POINTS, MAX_POINTS, ExplorerState, parse_query, state_from_query
from explorer_core.scenes import get_scene
from explorer_core.solve.section import section


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def make_session(**state_kw) -> ExplorerSession:
    state = ExplorerState(**state_kw)
    runner = Runner(lambda fn: fn(), executor=InlineExecutor())
    return ExplorerSession(state, runner)


def test_default_state_is_the_default_scene() -> None:
    s = ExplorerState()
    assert s.scene == "fig1C"
    assert s.system() == get_scene("fig1C").params
    assert s.initial_conditions().shape == (60, 2)


def test_query_round_trip() -> None:
    s = ExplorerState(scene="fig8B")
    s.param.update(alpha=-0.41, I13=0.45, g2=0.1, clicked=[(0.1, -0.2), (1.5, 2.0)], periods=123, method="dp5",
                   show_tprime=True, tprime_kind="per-period", q_range=(-1.0, 2.0))  # fmt: skip
    restored, errors = state_from_query(s.to_query())
    assert errors == []
    for f in ("alpha", "I13", "g2", "clicked", "periods", "method", "tprime_kind", "q_range", "r_range", "box", "seed"):
        assert getattr(restored, f) == getattr(s, f), f
    assert restored.scene == "custom"


@pytest.mark.parametrize(
    ("query", "needle"),
    [
        ({"alpha": "nan"}, "URL parameter alpha: α must be finite"),
        ({"I11": "<script>"}, "I11 must be a number"),
        ({"periods": "99999999"}, "URL parameter periods: Periods must be between"),
        ({"n": "-1"}, "URL parameter n: Random initial conditions must be between"),
        ({"method": "euler"}, "must be one of dop853"),
        ({"box": "1,0,0,1"}, "qmin < qmax"),
        ({"qr": "2,1"}, "lo < hi"),
        ({"ics": "1,2;3"}, "ics needs 2"),
        ({"scene": "<b>x</b>"}, "unknown scene"),
        ({"tprime": "maybe"}, "inst, period, off"),
    ],
)
def test_bad_query_values_are_reported_and_skipped(query, needle) -> None:
    updates, errors = parse_query(query)
    assert len(errors) == 1 and needle in errors[0]
    assert not any(k in updates for k in ("alpha", "I11", "periods", "n_random", "method", "box"))


def test_invalid_tensor_in_url_is_refused_with_a_message_and_the_scene_value_kept() -> None:
    state, errors = state_from_query({"scene": "fig1C", "I12": "5", "alpha": "0.2"})
    assert len(errors) == 1 and "URL parameter I12" in errors[0] and "not positive definite" in errors[0]
    assert "I12=5" in errors[0] and "using I12 = 0" in errors[0]
    assert state.I12 == 0.0 and state.alpha == 0.2 and state.scene == "custom"
    sess = ExplorerSession(state, Runner(lambda fn: fn(), executor=InlineExecutor()))
    sess.recompute()
    assert sess.error == "" and len(sess.fig.points.data["q"]) == 60 * 500


def test_typed_values_are_applied_or_refused_with_the_value_in_use_named() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=2, periods=5)
    for name, text, needle in [
        ("I11", "0", "not positive definite"),
        ("I11", "", "I11 is empty"),
        ("alpha", "nan", "α must be finite"),
        ("omega", "-1", "omega must be > 0"),
        ("periods", "0", "Periods must be between 1 and 100000"),
        ("periods", "2.5", "Periods must be a whole number"),
        ("n_random", "20000", "Random initial conditions must be between 0 and 10000"),
        ("method", "euler", "Method must be one of dop853"),
        ("chart_grid", "500,3", "grid NX,NY must be between 2 and 120"),
        ("bif_range", "1e300,1e301", "within ±1e+06"),
        ("lyap_ic", "a,b", "Initial condition q,r must be a number"),
    ]:
        before = getattr(sess.state, name)
        msg = sess.commit(name, text)
        assert msg is not None and needle in msg and "still using" in msg, (name, text, msg)
        assert getattr(sess.state, name) == before, name
    assert sess.commit("alpha", "0.25") is None and sess.state.alpha == 0.25 and sess.state.scene == "custom"
    assert sess.commit("periods", " 7 ") is None and sess.state.periods == 7
    assert sess.commit("lyap_ic", "") is None and sess.state.lyap_ic == ()
    assert sess.commit("bif_range", "-0.2, -0.1") is None and sess.state.bif_range == (-0.2, -0.1)


def test_a_value_that_makes_the_work_too_large_is_refused() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=100, periods=10, render="points")
    msg = sess.commit("periods", "5000")  # 100 trajectories x 5000 periods > 400,000 points drawn as points
    assert msg is not None and str(MAX_POINTS) in msg and "density" in msg and sess.state.periods == 10
    sess.state.param.update(render="auto", n_random=200)  # beyond the point bound: a density image, up to 10^7
    assert sess.commit("periods", "2100") is None  # 420,000 points
    msg = sess.commit("periods", "60000")
    assert msg is not None and str(MAX_DENSITY_POINTS) in msg and sess.state.periods == 2100


def test_recompute_streams_the_section_the_core_computes() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=5, periods=20)
    n = len(sess.fig.points.data["q"])
    assert n == 5 * 20
    ref = section(sess.state.system(), sess.state.initial_conditions(), 20, numerics=sess.state.numerics())
    traj, k, q, r = ref.long()
    np.testing.assert_array_equal(np.sort(np.asarray(sess.fig.points.data["q"])), np.sort(q))
    assert "100 points" in sess.status and not sess.running and "computing" not in sess.status


def test_moving_alpha_changes_the_points_and_layers() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=3, periods=10)
    before = np.asarray(sess.fig.points.data["q"]).copy()
    eq_before = list(sess.fig.equilibria.data["q"])
    sess.state.alpha = 0.3
    after = np.asarray(sess.fig.points.data["q"])
    assert after.size == before.size and not np.allclose(after, before)
    assert list(sess.fig.equilibria.data["q"]) != eq_before
    assert len(sess.fig.tprime.data["image"]) == 1


def test_invalid_tensor_is_refused_and_the_picture_kept() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=3, periods=10)
    before = np.asarray(sess.fig.points.data["q"]).copy()
    msg = sess.commit("I12", "3")
    assert "not positive definite" in msg and "I12=3" in msg and sess.state.I12 == 0.0
    np.testing.assert_array_equal(np.asarray(sess.fig.points.data["q"]), before)
    assert not sess.running and "computing" not in sess.status


def test_no_initial_conditions_is_reported_and_nothing_runs() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=3, periods=10)
    sess.state.n_random = 0
    assert "no initial conditions" in sess.error and not sess.running and "computing" not in sess.status
    sess.state.n_random = 2
    assert sess.error == "" and "20 points" in sess.status


def test_click_adds_one_trajectory_selects_it_and_counts_it() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=2, periods=15)
    sess.add_initial_condition(0.3, 0.4)
    traj, k, q, r = sess.data()
    assert sorted(set(traj.tolist())) == [0, 1, 2]
    assert np.count_nonzero(traj == 2) == 15  # the clicked one is numbered after the random ones
    assert sess.state.selected == 2 and sess.state.clicked == [(0.3, 0.4)]
    ics = sess.state.initial_conditions()
    assert tuple(ics[2]) == (0.3, 0.4)
    ref = section(sess.state.system(), ics, 15, numerics=sess.state.numerics())
    np.testing.assert_array_equal(sess.series.data["q"], ref.trajectory(2)[1])  # the clicked IC's orbit
    np.testing.assert_array_equal(sess.fig.selected.data["q"], ref.trajectory(2)[1])  # ringed in the section
    assert sess.status.startswith("45 points · 3 trajectories")
    assert "ics=0.3,0.4" in "&".join(f"{a}={b}" for a, b in sess.state.to_query().items())


def test_series_is_the_selected_trajectory_with_its_energy() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=3, periods=12)
    sess.state.selected = 1
    d = sess.series.data
    ref = section(sess.state.system(), sess.state.initial_conditions(), 12, numerics=sess.state.numerics())
    k, q, r = ref.trajectory(1)
    np.testing.assert_array_equal(d["k"], k)
    np.testing.assert_allclose(d["q"], q)
    assert np.all(np.asarray(d["T"]) > 0)


def test_stale_results_never_overwrite_newer_ones() -> None:
    """Deliver the callbacks of an older job after a newer one: they must be dropped."""
    queue: list = []
    state = ExplorerState(scene="fig1C")
    state.param.update(n_random=2, periods=5)
    sess = ExplorerSession(state, Runner(queue.append, executor=InlineExecutor()))
    older = list(queue)
    queue.clear()
    state.alpha = 0.25  # a newer job
    newer = list(queue)
    for fn in newer + older:  # the old ones arrive late
        fn()
    ref = section(state.system(), state.initial_conditions(), 5, numerics=state.numerics())
    np.testing.assert_array_equal(np.sort(np.asarray(sess.fig.points.data["q"])), np.sort(ref.long()[2]))


def test_escaped_trajectories_are_listed() -> None:
    sess = make_session(scene="fig3")
    sess.state.param.update(periods=2000, q_range=(-1.0, 1.0), r_range=(-5.0, 5.0))  # leaves |r| < 1e3 at k ~ 1400
    assert sess.escaped == [0]
    assert "1 escaped" in sess.status


def test_csv_export_has_settings_and_rows() -> None:
    sess = make_session(scene="fig1C")
    sess.state.param.update(n_random=2, periods=3)
    text = sess.csv("section").decode()
    lines = text.strip().splitlines()
    assert lines[1].startswith("# Bilimovich Explorer section; scene=fig1C")
    assert lines[0] == "traj,k,q,r" and len(lines) == 2 + 6


def test_scene_selection_sets_every_control() -> None:
    sess = make_session(scene="fig1C")
    sess.apply_scene("fig8B")
    s = sess.state
    assert (s.I13, s.I23, s.alpha, s.transient) == (0.5, 0.3, -0.45, 100)
    assert s.scene == "fig8B" and s.q_range == get_scene("fig8B").q_range


def test_selection_moves_to_a_trajectory_with_points() -> None:
    sess = make_session(scene="fig3")
    sess.state.n_random = 0
    # (0, 12), above the chaotic layer, drifts past the escape bound (k ~ 1230) during the
    # transient: no points at all. ((0, 8) wanders in the chaotic layer first: its escape time
    # depends on round-off.)
    sess.state.param.update(q_range=(-1.0, 1.0), r_range=(-5.0, 5.0))  # escape bound 1e3
    sess.state.param.update(clicked=[(0.0, 12.0), (0.1, 0.1)], periods=5, transient=1500)
    traj = sess.data()[0]
    assert sess.escaped == [0] and 0 not in set(traj.tolist())
    assert sess.state.selected == 1
    assert len(sess.series.data["k"]) == 5


def test_stop_ends_the_run_and_nothing_stays_computing() -> None:
    """Jobs queued, not run: Stop cancels them; the status says stopped, Stop is disabled."""
    queue: list = []
    state = ExplorerState(scene="fig1C")
    state.param.update(n_random=2, periods=5)

    class Held:  # an executor that holds jobs until told
        def submit(self, fn):
            queue.append(fn)

    sess = ExplorerSession(state, Runner(lambda fn: fn(), executor=Held()))
    sess.recompute()
    assert sess.running and "computing" in sess.status
    sess.stop()
    assert not sess.running and "computing" not in sess.status
    for fn in queue:  # the cancelled jobs start late: they must end without a trace
        fn()
    assert not sess.running and "computing" not in sess.status and len(sess.fig.points.data["q"]) == 0


@pytest.mark.parametrize("method", ["vern9", "auto"])
def test_the_section_menus_verner_and_auto_compute_what_solve_ivp_does(method: str) -> None:
    """The section's method menu offers Verner 9(8) and auto (as the command line does): at 'high' accuracy the
    app's section points agree with solve_ivp at 1e-13 (an independent integration), and the URL keeps the choice."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from jobs import Jobs
    from naive import solve_ivp_section

    from app.page import Page
    from app.runner import WARM

    WARM.set()
    jobs = Jobs()
    page = Page({"scene": "fig1A", "n": "0", "ics": "0.1,0.2", "periods": "20", "method": method, "accuracy": "high"},
                lambda fn: fn(), executor=jobs)  # fmt: skip
    page.start()
    jobs.drain()
    assert page.state.to_query()["method"] == method and not page.session.error
    assert page.state.numerics().method == "vern9"  # auto at 1e-12: Verner
    traj, k, q, r = page.session.data()
    ref = solve_ivp_section(page.state.system(), (0.1, 0.2), 20, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(np.column_stack([q, r]), ref[: q.size], rtol=0, atol=1e-9)
    assert q.size == 20


def test_a_url_key_that_is_not_a_setting_is_reported_with_the_nearest_one() -> None:
    """A typo in a link (``acc=high`` for ``accuracy=high``) was ignored without a word: the page showed the scene's
    accuracy as if the link had asked for it. Now each such key is named, with the nearest setting; Bokeh's own keys
    (``bokeh-*``) are not settings and pass silently; the settings that are right still apply."""
    state, errors = state_from_query({"scene": "fig1A", "acc": "high", "alhpa": "0.1", "zzz": "1", "periods": "50",
                                      "bokeh-session-id": "x"})  # fmt: skip
    assert errors == [
        "URL parameter 'acc' is not a setting of this page: ignored (did you mean accuracy?)",
        "URL parameter 'alhpa' is not a setting of this page: ignored (did you mean alpha?)",
        "URL parameter 'zzz' is not a setting of this page: ignored",
    ]
    assert state.periods == 50 and state.accuracy == "plot"


def test_a_plots_events_are_checked_like_the_urls_values() -> None:
    """A click and a pan's view as a client sends them (any JSON): finite numbers within ±MAX_MAGNITUDE, lo < hi
    (the URL's qr/rr checks); what no pointer gives names the bad value."""
    import re

    from app.state import plot_point, plot_view
    from explorer_core.system.params import ParameterError

    assert plot_point(0.5, -2) == (0.5, -2.0)
    assert plot_view(-3.5, 3.5, -5, 5.5) == ((-3.5, 3.5), (-5.0, 5.5))
    for args, needle in (((float("nan"), 0.0), "q must be a finite number, got 'nan'"),
                         (("abc", 0.0), "'abc'"), (([1, 2], 0.0), "[1, 2]"), ((True, 0.0), "True"),
                         ((0.0, 1e308), "within ±1e+06, got (0, 1e+308)")):  # fmt: skip
        with pytest.raises(ParameterError, match=re.escape(needle)):
            plot_point(*args)
    for args, needle in (((1e300, -5.0, 0.0, 1.0), "qr needs lo < hi"), ((1.0, 1.0, 0.0, 1.0), "qr needs lo < hi"),
                         ((0.0, 1.0, 0.0, float("inf")), "rr must be a finite number"),
                         ((-1e12, 1e12, 0.0, 1.0), "qr must lie within ±1e+06"), (("a", 1, 0, 1), "'a'")):  # fmt: skip
        with pytest.raises(ParameterError, match=re.escape(needle)):
            plot_view(*args)


def test_url_initial_conditions_lie_within_the_pages_bounds() -> None:
    """A URL's ``ics`` is refused beyond ±MAX_MAGNITUDE as a click is (1e308 gave numpy overflow warnings)."""
    from app.controls import MAX_MAGNITUDE

    st, errors = state_from_query({"ics": "1e308,0"})
    assert errors and "ics must lie within" in " ".join(map(str, errors)) and st.clicked == []
    st, errors = state_from_query({"ics": f"{MAX_MAGNITUDE:g},-1;0.5,0.25"})
    assert not errors and st.clicked == [(MAX_MAGNITUDE, -1.0), (0.5, 0.25)]


def test_fig9_shows_its_noncompact_curve_in_the_k_series() -> None:
    """Fig. 9 is about a noncompact attractive curve; its k-series showed trajectory 0, which stays on the bounded
    attractor. The scene's own point (failures.py's 'exponential escape (Fig. 9)') is selected: it drifts off."""
    sess = make_session(scene="fig1C")
    sess.apply_scene("fig9")
    s = sess.state
    assert s.selected == s.n_random and s.clicked == [(0.8663, -2.1588)]
    sc = get_scene("fig9")
    sec = section(sc.params, [s.clicked[0]], sc.periods, numerics=sc.numerics())
    _, q, r = np.asarray(sec.trajectory(0))
    assert np.all(np.diff(np.hypot(q, r)[10:]) > 0) and np.hypot(q[-1], r[-1]) > 100 * np.hypot(q[10], r[10])
