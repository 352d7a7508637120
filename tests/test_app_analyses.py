"""Analysis tabs without a browser: widgets -> core analyses -> figures and messages."""

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
    tab = LyapunovTab(session("fig8B"))
    tab.ic.value = "-0.5,-1"
    tab.transient.value, tab.periods.value, tab.ensemble.value = 50, 60, 2
    tab.run()
    text = tab.result.object
    assert "Λ1 =" in text and "Λ3 = 0" in text and "divergence" in text
    assert len(tab.source.data["k"]) > 0
    l1, l2 = tab.source.data["l1"][-1], tab.source.data["l2"][-1]
    assert l1 > l2


def test_lyapunov_tab_rejects_bad_input_with_a_message() -> None:
    tab = LyapunovTab(session("fig8B"))
    tab.ic.value = "a,b"
    tab.run()
    assert tab.error.visible and "initial condition" in tab.error.object


def test_bifurcation_tab_draws_points_of_the_scene_sweep() -> None:
    tab = BifurcationTab(session("fig10"))
    assert tab.param.value == "alpha" and tab.range.value == "-0.42,-0.35"
    tab.n_values.value, tab.points.value, tab.transient.value = 6, 5, 20
    tab.run()
    xs = np.asarray(tab.source.data["x"])
    assert xs.size > 0 and xs.min() >= -0.42 and xs.max() <= -0.35
    assert "6 values" in tab.message.object


def test_chart_tab_fills_the_image_and_a_click_sets_the_parameters() -> None:
    sess = session("fig11")
    tab = ChartTab(sess)
    assert (tab.x_param.value, tab.y_param.value) == ("alpha", "I11")
    tab.grid.value, tab.periods.value, tab.transient.value = "4,3", 30, 30
    tab.run()
    img = tab.source.data["image"][0]
    assert img.shape == (3, 4) and np.all(img > 0)  # every pixel classified
    assert "tiles" in tab.message.object
    tab._on_tap(SimpleNamespace(x=-0.55, y=1.4))
    assert sess.state.alpha == -0.55 and sess.state.I11 == 1.4 and sess.state.scene == "custom"
    assert len(tab._npz().getvalue()) > 100


def test_chart_tab_bounds_the_work() -> None:
    tab = ChartTab(session("fig11"))
    tab.grid.value = "500,500"
    tab.run()
    assert tab.error.visible and "grid must be between 2 and 120" in tab.error.object
