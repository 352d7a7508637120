"""The app as layers (issue 21, item 1; issue 31, item 7): each layer of the section plot is one module declaring
what it watches and computes, its settings (controls, picks, URL keys), the session's fields it publishes, the
page's actions it answers and its CSV download; the controller and the page drive them alike, so a new layer is
one file. Each control is declared once (its state attribute and its URL key generated from its entry); the plot's
size is one constant; a slider's move builds one system and rebuilds the page's view once."""

from __future__ import annotations

import inspect
import math
import sys
from collections.abc import Callable, Iterator
from typing import Any, ClassVar

import numpy as np
import pytest
from jobs import Jobs

import app.controller
import app.page
import app.state
from app.controller import ExplorerSession
from app.layers import LAYERS, Layer
from app.layers.base import Action, Table
from app.layers.section import SectionLayer
from app.page import Page
from app.runner import HEAVY, LAYER, POINTS, WARM, InlineExecutor, Runner, job_kind
from app.state import (
    BY_NAME,
    CONTROLS,
    PLOT_PIXELS,
    URL_KEYS,
    URL_OF,
    ExplorerState,
    SectionRequest,
    parse_query,
    state_from_query,
)
from explorer_core import export
from explorer_core.system.params import ParameterError, Params

ALL = (SectionLayer, *LAYERS)


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def session(layers: tuple[type[Layer], ...] = LAYERS, **state: Any) -> ExplorerSession:
    st = ExplorerState(scene="fig1C", **state)
    return ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor()), layers=layers)


# --- each layer declares its fields, its channels and its job ---------------------------------------------


@pytest.mark.parametrize("cls", ALL, ids=lambda c: c.__name__)
def test_each_layer_declares_the_fields_it_watches_and_its_job(cls: type[Layer]) -> None:
    assert cls.name and cls.name in cls.channels  # its main channel carries its name
    assert cls.fields and set(cls.fields) <= set(ExplorerState.param)
    assert set(cls.depends) <= set(ExplorerState.param)
    assert set(cls.channels.values()) <= {POINTS, LAYER}  # a layer is never a heavy analysis
    if cls is not SectionLayer:  # the section's job is its streaming run (SectionLayer.start)
        for method in ("inputs", "job", "apply", "clear"):
            assert getattr(cls, method) is not getattr(Layer, method), f"{cls.__name__}.{method}"
        assert inspect.isgeneratorfunction(cls.job)  # results drawn as they come
    # the scheduler's own defaults agree with what the layer declares
    for channel, kind in cls.channels.items():
        assert job_kind(channel) == kind


def test_channels_are_derived_from_the_layers_once_each() -> None:
    s = session()
    declared = [c for cls in ALL for c in cls.channels]
    assert len(set(declared)) == len(declared)
    assert s.channels == tuple(declared)
    for cls in ALL:
        for channel, kind in cls.channels.items():
            assert s.runner.kind(channel) == kind
    assert s.runner.kind("chart") == HEAVY  # an analysis tab's


def test_the_controller_names_no_layer_channel_by_hand() -> None:
    src = inspect.getsource(app.controller)
    for channel in ("section", "tracks", "tprime", "basins", "reliability"):
        assert f'"{channel}"' not in src, channel


def test_the_controller_and_the_page_name_no_layer_and_the_state_lists_no_layers_setting() -> None:
    """Fails on the old code: the controller and the page named the orbits and manifolds layers (their actions, their
    CSVs, their fields), the state listed every layer's controls and picks."""
    sources = {m.__name__: inspect.getsource(m) for m in (app.controller, app.page)}
    for name, src in sources.items():
        assert 'layers["' not in src and "layers.get(" not in src, name
        for cls in LAYERS:
            assert f'"{cls.name}"' not in src, (name, cls.name)
            for field in cls.publishes:  # the session's fields of a layer come from the layer
                assert f"{field} = param." not in src and f".{field}" not in src, (name, field)
    state_src = inspect.getsource(app.state)
    for cls in LAYERS:
        for c in cls.controls:
            assert BY_NAME[c.name] is c and f'"{c.name}"' not in state_src, c.name  # the layer's entry, used as is
        for u in cls.urls:
            assert u in URL_KEYS and f'"{u.key}"' not in state_src, u.key
        for pick in cls.picks:
            assert pick in ExplorerState.param and pick not in state_src, pick
    # the modes of "Click in the plot" beyond adding and selecting are the layers' click actions
    modes = [v for v, _ in BY_NAME["click_mode"].options]
    assert modes == ["add", "select", *(a.name for cls in LAYERS for a in cls.actions if a.click)]


# --- a new layer is one file: a stand-in plugs in without editing the controller ----------------------------


class Doubler(Layer):
    """A stand-in layer: for the system on screen and its own setting, two results (a coarse, a final one)."""

    name = "doubler"
    channels: ClassVar[dict[str, str]] = {"doubler": LAYER, "doubler_click": POINTS}
    fields = ("basin_grid",)
    depends = ("alpha", "basin_grid")
    dedupe = True
    publishes: ClassVar[dict[str, Any]] = {"doubler_status": ""}
    actions = (Action("double_again", "again"), Action("doubler_at", "at", "doubles the click", click=True))
    download = "doubled"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.shown: list[tuple[Any, ...]] = []
        self.jobs = 0
        self.text = ""
        self.stop_calls: list[bool] = []

    def inputs(self) -> tuple[float, int] | None:
        p = self.host.system()
        return None if p is None else (p.alpha, self.host.state.basin_grid)

    def prepare(self, inputs: tuple[float, int]) -> tuple[float, int]:
        if inputs[1] == 13:
            raise ParameterError("13 pixels across is refused by the stand-in")
        self.text = "doubling…"
        return inputs

    def refused(self, exc: BaseException) -> None:
        self.text = f"doubler: {exc}"

    def job(self, inputs: tuple[float, int], cancelled: Callable[[], bool]) -> Iterator[int]:
        self.jobs += 1
        yield inputs[1]
        yield 2 * inputs[1]

    def current(self, inputs: tuple[float, int]) -> bool:
        p = self.host.system()
        return p is not None and p.alpha == inputs[0]

    def apply(self, inputs: tuple[float, int], result: int) -> None:
        self.shown.append((inputs, result))
        self.text = f"doubled: {result}"

    def clear(self) -> None:
        self.shown = []
        self.text = ""

    def status(self) -> str:
        return self.text

    def published(self) -> dict[str, Any]:
        return {"doubler_status": self.text}  # its own field: declared nowhere but here

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        self.stop_calls.append(busy)

    def again(self) -> None:
        self.host.run(self, self.inputs())  # once more, even for the same inputs

    def at(self, q: float, r: float) -> None:
        self.text = f"clicked at {q:g}, {r:g}"
        self.host.publish(self)

    def table(self) -> Table | None:
        rows = [(i, inputs[1], result) for i, (inputs, result) in enumerate(self.shown)]
        settings = {"bas_n": str(self.host.state.basin_grid)}
        return Table("doubled", settings, ("i", "n", "doubled"), rows) if rows else None


def test_a_new_layer_plugs_in_without_editing_the_controller() -> None:
    s = session(layers=(*LAYERS, Doubler))
    d = s.layer("doubler")
    assert isinstance(d, Doubler) and "doubler" in s.channels and "doubler_click" in s.channels
    assert s.runner.kind("doubler") == LAYER and s.runner.kind("doubler_click") == POINTS
    s.recompute()
    assert [r for _, r in d.shown] == [80, 160] and s.doubler_status == "doubled: 160"
    # the section's numerics change: the same inputs, not redone (dedupe)
    assert s.commit("periods", "40") is None
    assert d.jobs == 1
    # its own setting redoes it
    assert s.commit("basin_grid", "20") is None
    assert d.jobs == 2 and d.shown[-1][1] == 40
    # a refusal of its inputs is its status, not a failed job
    assert s.commit("basin_grid", "13") is None
    assert d.jobs == 2 and s.doubler_status.startswith("doubler: 13 pixels") and s.error == ""
    assert s.commit("basin_grid", "20") is None
    assert d.jobs == 3
    # a new system redoes it; Stop tells it
    assert s.commit("alpha", "0.2") is None
    assert d.jobs == 4 and d.shown[-1][0][0] == 0.2
    s.stop()
    assert d.stop_calls == [False]
    # a click-like job on its second channel, joined to the current generation (no cancel)
    s.run(d, (0.2, 7), channel="doubler_click", bump=False)
    assert d.shown[-1] == ((0.2, 7), 14)
    # its own field is on the session only: another session, without the layer, has none
    assert "doubler_status" in s.param and "doubler_status" not in session().param


def test_a_new_layers_actions_and_download_go_through_the_session(tmp_path: Any) -> None:
    s = session(layers=(*LAYERS, Doubler))
    d = s.layer("doubler")
    assert s.csv("doubled") is None  # nothing on screen yet
    s.recompute()
    jobs = d.jobs
    assert s.act("double_again") and d.jobs == jobs + 1  # its button
    assert s.act("doubler_at", 0.5, -1.0) and s.doubler_status == "clicked at 0.5, -1"  # its click mode
    assert not s.act("doubler_at") and not s.act("double_again", 1.0, 2.0)  # a button is no click, and back
    assert not s.act("no_such_action")
    # its CSV: exactly what the core's CSV writer writes for its table, with its settings as a comment line
    data = s.csv("doubled")
    table = d.table()
    export.write_csv(str(tmp_path / "t.csv"), table.header, table.rows, ["Bilimovich Explorer doubled; bas_n=80"])
    assert data == (tmp_path / "t.csv").read_bytes()
    assert data.startswith(b"i,n,doubled\r\n# Bilimovich Explorer doubled; bas_n=80\n0,80,80\r\n")


def test_two_layers_cannot_publish_one_field_nor_answer_one_action() -> None:
    class Twin(Doubler):
        name = "twin"
        channels: ClassVar[dict[str, str]] = {"twin": LAYER}
        actions = ()

    with pytest.raises(ValueError, match="doubler_status"):
        session(layers=(Doubler, Twin))

    class Clicker(Doubler):
        name = "clicker"
        channels: ClassVar[dict[str, str]] = {"clicker": LAYER}
        publishes: ClassVar[dict[str, Any]] = {}

    with pytest.raises(ValueError, match="double_again"):
        session(layers=(Doubler, Clicker))


def test_a_result_for_a_system_no_longer_on_screen_is_not_applied() -> None:
    queue: list[Callable[[], None]] = []
    st = ExplorerState(scene="fig1C")
    s = ExplorerSession(st, Runner(queue.append, executor=InlineExecutor()), layers=(Doubler,))
    d = s.layer("doubler")
    s.refresh(d)
    st.param.update(alpha=0.3)  # the system moved on before the results were delivered
    for fn in list(queue):
        fn()
    assert all(inputs[0] == 0.3 for inputs, _ in d.shown)


# --- each control declared once ------------------------------------------------------------------------------


@pytest.mark.parametrize("c", CONTROLS, ids=lambda c: c.name)
def test_each_controls_attribute_is_generated_from_its_entry(c: Any) -> None:
    p = ExplorerState.param[c.name]
    assert p.default == c.default
    if c.kind == "int":
        assert p.bounds == c.bounds  # the one declaration of its bounds
    if c.kind in ("select", "radio") and c.name != "scene":
        assert list(p.objects) == [v for v, _ in c.options]


def test_every_url_key_is_in_one_table_and_round_trips() -> None:
    keys = [u.key for u in URL_KEYS]
    assert len(set(keys)) == len(keys)
    assert {c.url for c in CONTROLS if c.url} <= set(keys)
    s = ExplorerState(scene="fig1C")
    s.param.update(manifold_saddles=[(0.5, 0.25, 2)], orbit_seeds=[(0.1, 0.2)], orbit_view=True, tab="chart",
                   presentation=True, bif_orbits=False, show_basins=True, basin_grid=30, render="points",
                   click_mode="orbit", tprime_kind="per-period", lyap_ic=(0.1, 0.2), ftle="backward", ftle_grid=30,
                   ftle_periods=12)  # fmt: skip
    s.param.update(play_param="g1", play_from=(0.5,), play_to=(1.5,), play_frames=30, play_fps=12, play_dir="bounce",
                   tour="fig8B", tour_step=2, tour_url="/tours/class.json", show_body=True, body_speed="2",
                   body_axis="1", body_shape="ellipsoid")  # fmt: skip
    q = s.to_query()
    analysis = {c.url for c in CONTROLS if c.area in ("lyapunov", "bifurcation", "chart", "bench")}
    # every key written when its value is not the default (the analysis tabs' are at theirs but two)
    assert set(q) == set(keys) - analysis | {"ly_ic", "bif_orb"}
    updates, errors = parse_query(q)
    assert not errors
    for field in updates:
        assert field in URL_OF
    restored, errors = state_from_query(q)
    assert not errors and restored.to_query() == q


def test_the_plot_size_is_one_constant() -> None:
    s = ExplorerState(scene="fig1C", render="density")
    req = s.section_request()
    assert isinstance(req, SectionRequest) and req.density
    assert s.pixel_size() == min(s.q_range[1] - s.q_range[0], s.r_range[1] - s.r_range[0]) / PLOT_PIXELS[0]
    src = "".join(inspect.getsource(m) for m in (app.controller,))
    assert "800" not in src and "600" not in src


def test_the_runner_is_configured_through_its_methods() -> None:
    calls: list[str] = []
    r = Runner(lambda fn: fn(), executor=InlineExecutor(), on_busy=calls.append)
    ExplorerSession(ExplorerState(scene="fig1C"), r)
    r.start("section", lambda cancelled, emit: None)
    assert calls and set(calls) == {"section"}  # the page's callback kept (set_on_busy does not replace it)
    r2 = Runner(lambda fn: fn(), executor=InlineExecutor())
    s2 = ExplorerSession(ExplorerState(scene="fig1C"), r2)
    s2.recompute()
    assert not s2.running  # the session's own callback: "running" follows the runner


def test_the_initial_page_has_no_more_bokeh_models_than_before_the_layers() -> None:
    """The refactor builds the same page: 73 models in one Page's document (a4bc0e5: 73), no layer adds any; 63 since
    one filter serves every view and the clicked points are a layer built on the first click (each model is ~1 ms
    of the server's event loop per page, docs/load.md)."""
    from bokeh.document import Document

    doc = Document()
    page = Page({}, lambda fn: fn(), executor=InlineExecutor())
    doc.add_root(page.ui.get_root(doc))
    assert len(list(doc.models)) <= 63
    page.fig.set_ics(np.zeros((0, 2)))  # none clicked: nothing built
    assert len(list(doc.models)) <= 63 and "ics_source" not in {m.name for m in doc.models}
    page.fig.set_ics(np.array([[0.1, -0.2]]))  # the first click: the layer joins the plot, in its place
    names = [r.name for r in page.fig.fig.renderers]
    assert names.index("frozen_field_equilibria") + 1 == names.index("clicked_points")
    assert list(doc.select_one({"name": "ics_source"}).data["q"]) == [0.1]
    page.close()


# --- one system and one view per move of a slider ------------------------------------------------------------


def test_a_slider_move_builds_one_system_and_rebuilds_the_view_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fails on the old code (c3075ef): a move of α rebuilt the page's view 4 times before its jobs ran (11 times with
    their results) and the app built ``Params`` 4 times (7 with its jobs; the core builds one more, for the
    coefficient tables of a new α, which is not the app's)."""
    jobs = Jobs()
    page = Page({}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    counts = {"views": 0, "params": 0}
    section_view, init = Page._section_view, Params.__init__

    def counted_view(self: Page) -> dict[str, Any]:
        counts["views"] += 1
        return section_view(self)

    def counted_init(self: Params, *args: Any, **kwargs: Any) -> None:
        if sys._getframe(1).f_globals.get("__name__", "").startswith("app."):  # built by the app
            counts["params"] += 1
        init(self, *args, **kwargs)

    monkeypatch.setattr(Page, "_section_view", counted_view)
    monkeypatch.setattr(Params, "__init__", counted_init)
    assert page.handle({"commit": "alpha", "text": "0.105"}) is None  # a slider released at a new value
    assert counts == {"views": 1, "params": 1}
    view = page.ui.view["section"]
    assert view["running"] and "computing" in view["status"]  # the one view is the move's: its jobs are on their way
    jobs.drain()  # the section, its reliability check and the layers: each result shown as it comes
    assert counts["params"] == 1  # every job, check and layer used the system the commit built
    assert page.state.system() is page.state.system() and page.state.system().alpha == 0.105
    assert page.commit("alpha", "-0.0") is None and math.copysign(1.0, page.state.system().alpha) == -1.0


def test_the_tracks_are_a_layer_of_their_own_module_with_todays_url_and_checkbox() -> None:
    """The equilibrium tracks, split out of app/layers/frozen.py with no edit outside app/layers/: the same checkbox,
    the same URL key (``tracks=0|1``, written as before), drawn and cleared as before."""
    from app.layers.tracks import TracksLayer

    assert TracksLayer in LAYERS and TracksLayer.__module__ == "app.layers.tracks"
    assert BY_NAME["show_tracks"] is TracksLayer.controls[0] and URL_OF["show_tracks"] == "tracks"
    st, errors = state_from_query({"tracks": "0"})
    assert not errors and st.show_tracks is False and st.to_query()["tracks"] == "0"
    st, errors = state_from_query({})
    assert not errors and st.show_tracks is True and st.to_query()["tracks"] == "1"
    s = session()
    s.recompute()
    assert s.fig.tracks.data["xs"] and list(s.fig.equilibria.data["q"])
    assert s.commit("show_tracks", "false") is None
    assert s.fig.tracks.data["xs"] == [] and list(s.fig.equilibria.data["q"]) == []
