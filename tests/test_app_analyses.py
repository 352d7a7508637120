"""Analysis tabs without a browser: settings in the state -> core analyses -> figures and messages."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from app.analyses import BifurcationTab, ChartTab, LyapunovTab
from app.controller import ExplorerSession
from app.runner import WARM, InlineExecutor, Runner
from app.state import ExplorerState


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def session(scene: str) -> ExplorerSession:
    st = ExplorerState(scene=scene)
    st.param.update(n_random=2, periods=10)
    return ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor()))


def test_lyapunov_tab_reports_exponents_and_the_divergence_check() -> None:
    sess = session("fig8B")
    tab = LyapunovTab(sess)
    sess.state.param.update(lyap_ic=(-0.5, -1.0), lyap_transient=50, lyap_periods=60, lyap_ensemble=2)
    tab.figure()
    tab.run()
    text = "\n".join(tab.view["result"])
    assert "Λ1 =" in text and "Λ3 = 0" in text and "divergence" in text and "members used: 2 of 2" in text
    assert len(tab.source.data["k"]) > 0
    l1, l2 = tab.source.data["l1"][-1], tab.source.data["l2"][-1]
    assert l1 > l2


def test_lyapunov_tab_with_every_member_failed_reports_no_numbers() -> None:
    sess = session("fig3")
    tab = LyapunovTab(sess)
    # Beyond the tab's bound (1e4): every member is "escaped" at once.
    sess.state.param.update(lyap_ic=(0.0, 5e4), lyap_transient=10, lyap_periods=20, lyap_ensemble=2)
    tab.run()
    text = "\n".join(tab.view["result"])
    assert text.startswith("No exponents: none of the 2 members") and "escaped" in text
    assert "Λ1" not in text and "=" not in text.split(":", 1)[0]
    assert not any(ch.isdigit() for ch in text.split("(")[0].replace("2 members", ""))
    assert len(tab.source.data["k"]) == 0  # no running estimate from failed members either


def test_lyapunov_tab_without_initial_conditions_says_why() -> None:
    sess = session("fig1C")
    sess.state.param.update(n_random=0, clicked=[])
    tab = LyapunovTab(sess)
    tab.run()
    assert "no initial condition" in tab.view["error"]


def test_bifurcation_tab_draws_points_of_the_scene_sweep() -> None:
    sess = session("fig10")
    tab = BifurcationTab(sess)
    assert sess.state.bif_param == "alpha" and sess.state.bif_range == (-0.42, -0.35)
    sess.state.param.update(bif_values=6, bif_points=5, bif_transient=20)
    tab.run()
    xs = np.asarray(tab.source.data["x"])
    assert xs.size > 0 and xs.min() >= -0.42 and xs.max() <= -0.35
    assert "6 values" in tab.view["message"] and "points; trajectories" in tab.view["result"][0]


def test_bifurcation_tab_says_how_much_was_copied_from_settled_cycles() -> None:
    """Members on an attracting cycle stop integrating (their later points are the cycle's): the tab says how many
    and how many periods were copied, the numbers of the result's own ``settled_summary``."""
    sess = session("fig10")
    tab = BifurcationTab(sess)
    sess.state.param.update(bif_values=6, bif_points=60, bif_transient=200, bif_range=(-0.36, -0.35))
    tab.run()
    s = tab._data.settled_summary()
    assert s["repeated"] + s["newton"] > 0  # period 1 there: every member settles
    line = next(x for x in tab.view["result"] if "settled on an attracting cycle" in x)
    assert line.startswith(f"{s['repeated'] + s['newton']} of {tab._data.status.size} trajectories")
    assert f"{s['periods_copied']:,} periods copied" in line


def test_bifurcation_tab_says_when_no_point_survives() -> None:
    sess = session("fig3")
    # Beyond the sweep's bound (1e3): every trajectory escapes before its first point.
    sess.state.param.update(clicked=[(0.0, 5e3)], n_random=0, bif_values=3, bif_points=5, bif_transient=10,
                            bif_range=(0.09, 0.11))  # fmt: skip
    tab = BifurcationTab(sess)
    tab.run()
    assert tab.view["result"][0].startswith("No points: every trajectory escaped or failed")
    assert len(tab.source.data["x"]) == 0


def test_chart_tab_fills_the_image_and_a_click_lands_on_the_pixel_centre() -> None:
    sess = session("fig11")
    tab = ChartTab(sess)
    st = sess.state
    assert (st.chart_x, st.chart_y) == ("alpha", "I11")
    st.param.update(chart_grid=(4, 3), chart_periods=30, chart_transient=30)
    assert tab.npz_bytes() is None and not tab.view["download"]  # nothing to download yet
    tab.figure()
    tab.run()
    img = tab.source.data["image"][0]
    assert img.shape == (3, 4) and np.all(img > 0)  # every pixel classified
    assert "tiles" in tab.view["message"] and tab.view["result"][0].startswith("pixels:")
    xs, ys = tab.chart.spec.x_values, tab.chart.spec.y_values
    # A click off-centre inside pixel (1, 2) sets the pixel's centre values.
    tab._on_tap(SimpleNamespace(x=xs[1] + 0.3 * (xs[1] - xs[0]), y=ys[2] - 0.4 * (ys[1] - ys[0])))
    assert st.alpha == pytest.approx(xs[1]) and st.I11 == pytest.approx(ys[2]) and st.scene == "custom"
    # The cross marks the current parameters.
    assert tab.current.data == {"x": [pytest.approx(xs[1])], "y": [pytest.approx(ys[2])]}
    st.alpha = -0.5
    assert tab.current.data["x"] == [-0.5]
    assert len(tab.npz_bytes()) > 100 and tab.view["download"]


def test_chart_tab_click_on_an_invalid_system_keeps_the_state() -> None:
    sess = session("fig11")
    st = sess.state
    st.param.update(chart_y="I12", chart_yrange=(-0.5, 0.5), chart_grid=(2, 2), chart_periods=10, chart_transient=10)
    tab = ChartTab(sess)
    tab.run()
    before = (st.alpha, st.I12)
    tab.chart.spec = SimpleNamespace(x_param="alpha", y_param="I12", x_values=np.array([-0.6, -0.4]),
                                     y_values=np.array([5.0, 6.0]))  # fmt: skip
    tab._on_tap(SimpleNamespace(x=-0.6, y=5.0))
    assert (st.alpha, st.I12) == before and "not positive definite" in tab.view["error"]


def test_bifurcation_tab_says_whether_a_doubling_is_supercritical() -> None:
    """The continued orbits' bifurcations are listed in the command line's words: the criticality from the normal
    form's coefficient (Fig. 10's first doubling is supercritical, b = 7.4, docs/architecture.md), in the list and the
    points' tooltips."""
    sess = session("fig10")
    tab = BifurcationTab(sess)
    sess.state.param.update(bif_values=4, bif_points=5, bif_transient=50, bif_range=(-0.38, -0.37))
    tab.figure()
    tab.run()
    line = next(x for x in tab.view["result"] if "orbit at alpha = -0.3753448" in x)
    assert line.startswith("supercritical period doubling of the period-1 orbit") and "(b = 7.4" in line, line
    assert "supercritical period doubling" in tab.bifs.data["kind"]


# --- codimension-two points and the curves on the chart (Henon's map: closed forms, well under a second) --------


@pytest.fixture(scope="module")
def henon_curves():
    """Henon's flip curve ``a = 3 (1 - b)^2 / 4`` with R2 at (3, -1) and fold curve ``a = -(1 - b)^2 / 4`` with R1 at
    (-1, -1) (tests/test_codim2.py checks both against their closed forms), in (a, b)."""
    from explorer_core.analyses.continuation import continue_map
    from explorer_core.analyses.continuation.testmaps import Henon

    flip = continue_map(Henon(b=0.3), "a", (0.2, 1.0), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                        range2=(-1.5, 0.6), window1=(-2.0, 5.0))  # fmt: skip
    fold = continue_map(Henon(b=0.3), "a", (-0.1, -0.2), Henon.fixed_point(-0.1, 0.3), 1, param2="b",
                        range2=(-1.5, 0.6), window1=(-2.0, 1.0))  # fmt: skip
    return flip, fold


def _chart_tab_with(parts) -> ChartTab:
    tab = ChartTab(session("fig11"))
    tab.figure()
    tab.chart = SimpleNamespace(spec=SimpleNamespace(x_param="a", y_param="b"))
    tab._curves(parts)
    return tab


def test_the_chart_marks_and_lists_the_codimension_two_points_once(henon_curves) -> None:
    """Fails on the old code (no mark, no list): R1 and R2 marked where they are, each with its kind's marker and
    colour, named in the hover and listed under the plot in the command line's words; the flip curve followed twice
    (two continuations of one orbit) still gives one R2."""
    from app.analyses import CODIM2_STYLE

    flip, fold = henon_curves
    tab = _chart_tab_with([flip, fold, flip])
    d = tab.codim2.data
    assert d["label"] == ["R2 (1:2 resonance)", "R1 (1:1 resonance)"]
    np.testing.assert_allclose(np.c_[d["x"], d["y"]], [[3.0, -1.0], [-1.0, -1.0]], atol=1e-6)
    assert [d["marker"], d["color"]] == [[CODIM2_STYLE[k][0] for k in ("R2", "R1")],
                                         [CODIM2_STYLE[k][1] for k in ("R2", "R1")]]  # fmt: skip
    assert d["name"][0] == "R2 (1:2 resonance) of the period-1 orbit" and d["values"][0].startswith("(a, b) = (3")
    assert " ± " in d["values"][0]
    lines = tab.view["result"]
    i = lines.index("codimension-two points: 2")
    assert lines[i + 1].startswith(
        "R2 (1:2 resonance) of the period-1 orbit on the period doubling curve at (a, b) = (3"
    )
    assert lines[i + 2].startswith("R1 (1:1 resonance) of the period-1 orbit on the fold curve at (a, b) = (-1")
    # a legend in the plot (curves and marks), and a hover on the marks
    assert tab.figure().legend[0].visible
    from bokeh.models import HoverTool

    hovers = [t for t in tab.figure().toolbar.tools if isinstance(t, HoverTool)]
    assert any(r.name == "chart_codim2_marks" for h in hovers for r in h.renderers)
    # every kind its own marker and colour
    assert len({m for m, _ in CODIM2_STYLE.values()}) == len({c for _, c in CODIM2_STYLE.values()}) == 8


def test_a_chart_without_codimension_two_points_says_so(henon_curves) -> None:
    from explorer_core.analyses.continuation import Curve

    flip, _ = henon_curves
    plain = SimpleNamespace(curves=[Curve("period_doubling", 1, list(flip.curves[0].rows))], bifurcations=[1],
                            messages=[], lost=[])  # fmt: skip
    tab = _chart_tab_with([plain])
    assert tab.view["result"][-1] == "codimension-two points: none in this window"
    assert tab.codim2.data["x"] == []


def test_the_curves_of_one_kind_differ_by_their_period_dash() -> None:
    """Fails on the old code: three period-doubling curves, three identical black lines."""
    from app.analyses import curve_dash
    from explorer_core.analyses.continuation import Curve

    rows = [(0.0, 1.0, 0.0, 0.0), (0.1, 1.1, 0.0, 0.0)]
    curves = [Curve("period_doubling", p, rows) for p in (1, 2, 3, 4)]
    tab = _chart_tab_with([SimpleNamespace(curves=curves, bifurcations=[1], messages=[], lost=[])])
    dashes = tab.curves.data["dash"]
    assert len(set(dashes)) == 4 and dashes == [curve_dash(p) for p in (1, 2, 3, 4)] and dashes[0] == "solid"
    assert "by period: 1 solid, 2 dashed, 3 dotted, 4 dash-dotted" in tab.view["result"][-2]
    assert tab.curves.data["color"] == ["#000000"] * 4


def test_the_boundaries_npz_entries_carry_the_codimension_two_points(henon_curves) -> None:
    """Fails on the old code (the curves only): each point's kind, period, values, error and the curve it lies on."""
    from explorer_core.analyses.continuation import Boundaries

    flip, fold = henon_curves
    entries = Boundaries([flip, fold]).npz_entries()
    assert entries["codim2_kind"].tolist() == ["R2", "R1"] and entries["codim2_period"].tolist() == [1, 1]
    np.testing.assert_allclose(entries["codim2_values"], [[3.0, -1.0], [-1.0, -1.0]], atol=1e-6)
    points = [flip.curves[0].codim2[0], fold.curves[0].codim2[0]]
    np.testing.assert_array_equal(entries["codim2_values"], [p.values for p in points])
    np.testing.assert_array_equal(entries["codim2_error"], [p.error for p in points])
    assert entries["curve_kind"][entries["codim2_curve"]].tolist() == ["period_doubling", "fold"]
    empty = Boundaries().npz_entries()
    assert empty["codim2_values"].shape == (0, 2) and empty["codim2_kind"].size == 0
