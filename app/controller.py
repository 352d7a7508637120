"""One browser session: state changes -> layers' jobs -> figures.

:class:`ExplorerSession` watches an :class:`~app.state.ExplorerState` and coordinates the layers of the
section plot (:mod:`app.layers`): the section itself, then each phase-plane layer. It decides which run and
when (a layer's own settings, the section's settings, the view), cancels what a change makes stale, starts
jobs on a :class:`~app.runner.Runner` and applies their results on the document thread. What a layer computes,
draws and says is the layer's, and so are the session's fields it publishes (created from the layers'
declarations), the page's actions it answers and its CSV download: the session names no layer but the section.
Invalid input shows a message and leaves the last valid picture in place.

What the page shows as running ("computing", Stop enabled) is derived from the runner's busy
state (:meth:`~app.runner.Runner.busy`), never set by hand, so it ends with the work however
the work ends. Values reach the state only through :func:`app.state.commit`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
import param

from app.layers import KEEP, LAYERS, Layer
from app.layers.base import Action, Download, plain
from app.layers.section import SectionLayer
from app.runner import Emit, Runner
from app.state import (
    _ORDER,
    BY_NAME,
    CONTROLS,
    MAX_CLICKED,
    NO_SELECTION,
    SYSTEM_FIELDS,
    TABS,
    ExplorerState,
    SectionRequest,
    commit,
)
from app.views import SectionFigure, SeriesData
from explorer_core.system.params import ParameterError, Params

ANALYSIS_FIELDS = tuple(c.name for c in CONTROLS if c.area in TABS[1:])
PLAY_FIELDS = tuple(c.name for c in CONTROLS if c.area == "play")
#: The body view's own settings (speed, axis traced, drawing): in the URL while it is open.
BODY_FIELDS = tuple(c.name for c in CONTROLS if c.area == "bodyview")
_UNSET = object()


def _field(default: Any) -> param.Parameter:
    """The session's field for a value a layer publishes (its type from the value it starts with)."""
    if isinstance(default, bool):
        return param.Boolean(default=default)
    if isinstance(default, int):
        return param.Integer(default=default)
    if isinstance(default, str):
        return param.String(default=default)
    if isinstance(default, list):
        return param.List(default=default)
    return param.Parameter(default=default)


@functools.cache
def _with_fields(base: type, layers: tuple[type[Layer], ...]) -> type:
    """``base`` with one watched field per value the ``layers`` publish (:attr:`app.layers.base.Layer.publishes`);
    two layers, or a layer and the session, publishing one name is refused."""
    owner: dict[str, str] = {}
    for cls in layers:
        for name in cls.publishes:
            if name in owner or name in base.param:
                raise ValueError(f"layer {cls.name!r} publishes {name!r}, which is {owner.get(name, 'the session')}'s")
            owner[name] = repr(cls.name)
    fields = {name: _field(default) for cls in layers for name, default in cls.publishes.items()}
    return type(base)(base.__name__, (base,), {"__module__": base.__module__, "__doc__": base.__doc__, **fields})


class ExplorerSession(param.Parameterized):
    """Controller of one session. ``error`` is plain text for the page and ``running`` says whether Stop applies;
    the other fields are what the layers publish (:attr:`app.layers.base.Layer.publishes`): each session is of a
    subclass with the fields of its layers (the section's ``status``, ``n_points``, ...), made once per set of
    layers."""

    error = param.String(default="")
    #: Something of the section view runs (the section, a clicked trajectory, a layer): Stop applies.
    running = param.Boolean(default=False)

    def __new__(cls, *args: Any, layers: Sequence[type[Layer]] = LAYERS, **kwargs: Any) -> ExplorerSession:
        return super().__new__(_with_fields(cls, (SectionLayer, *layers)))

    def __init__(
        self,
        state: ExplorerState,
        runner: Runner,
        section_fig: SectionFigure | None = None,
        series: SeriesData | None = None,
        *,
        on_query: Callable[[dict[str, str]], None] | None = None,
        layers: Sequence[type[Layer]] = LAYERS,
    ) -> None:
        super().__init__()
        self.state = state
        self.runner = runner
        self.fig = section_fig or SectionFigure(state.q_range, state.r_range)
        self.series = series or SeriesData()
        self._on_query = on_query
        self._suspend = False
        self.section = SectionLayer(self)
        #: The phase-plane layers, by name, in the order they start.
        self.layers: dict[str, Layer] = {}
        for cls in layers:
            layer = cls(self)
            self.layers[layer.name] = layer
        #: The section and the phase-plane layers: everything of the section view.
        self.every: tuple[Layer, ...] = (self.section, *self.layers.values())
        #: What Stop stops in the section view, and what makes it "running": every layer's channels.
        self.channels: tuple[str, ...] = tuple(c for layer in self.every for c in layer.channels)
        for layer in self.every:
            runner.declare(layer.channels)
        #: The page's actions the layers answer: buttons and modes of "Click in the plot", by name.
        self.actions: dict[str, tuple[Layer, Action]] = {}
        for layer in self.every:
            for action in layer.actions:
                if action.name in self.actions:
                    raise ValueError(f"layers {self.actions[action.name][0].name!r} and {layer.name!r} both answer "
                                     f"the page's action {action.name!r}")  # fmt: skip
                self.actions[action.name] = (layer, action)
        #: The inputs of each deduplicating layer's last job (see refresh).
        self._inputs: dict[str, Any] = {}
        #: While a parameter is played (app/play.py): periods per trajectory of a frame (None: the state's),
        #: and the last frame's orbits (q, r, period) that the orbits layer continues to the next frame.
        self.frame_periods: int | None = None
        self.follow_orbits: tuple[tuple[float, float, int], ...] = ()
        runner.set_on_busy(self.on_busy)
        state.param.watch(self._on_section_change, list(self.section.fields))
        for layer in self.layers.values():
            state.param.watch(self._watcher(layer), list(layer.fields))
        state.param.watch(self._on_view_change, ["q_range", "r_range"])
        state.param.watch(lambda *e: self._on_selected(), ["selected"])
        state.param.watch(lambda *e: self.recompute(), ["clicked"])
        state.param.watch(
            lambda *e: self._publish_query(),
            [
                "selected",
                "show_body",
                *BODY_FIELDS,
                "tab",
                "presentation",
                "tour",
                "tour_step",
                *PLAY_FIELDS,
                *ANALYSIS_FIELDS,
            ],
        )

    def layer(self, name: str) -> Layer:
        return self.layers[name]

    # --- input ------------------------------------------------------------------------------

    def commit(self, name: str, text: Any) -> str | None:
        """A typed value for control ``name``: applied (None), or refused with the reason (state unchanged)."""
        if name == "scene":
            msg = commit(self.state, "scene", text)
            if msg is None and self.state.scene != "custom":
                self._set_view()
            return msg
        return commit(self.state, name, text)

    def on_busy(self, channel: str) -> None:
        """A channel started or stopped (document thread): the section view runs while any of its channels do."""
        if channel in self.channels:
            running = any(self.runner.busy(c) for c in self.channels)
            if running != self.running:
                self.running = running
            if channel == self.section.name:
                self.section.refresh_status()

    def busy(self) -> bool:
        """Whether a job of the section view has not ended, now (``running`` follows on the document thread's next
        turn: the runner tells it through ``deliver``)."""
        return any(self.runner.busy(c) for c in self.channels)

    def system(self) -> Params | None:
        """The system on screen; None while a typed value is refused (recompute shows why)."""
        try:
            return self.state.system()
        except ParameterError:
            return None

    # --- the layers: one pattern for all -------------------------------------------------------

    def refresh(self, layer: Layer, *, from_job: bool = False) -> None:
        """Redo ``layer`` for the state: off (cleared), kept (invalid system), unchanged (the same inputs as
        its last job, for a deduplicating layer) or a new job (the old one cancelled)."""
        inputs = layer.inputs()
        if layer.dedupe and inputs is not None and inputs is not KEEP and self._inputs.get(layer.name) == inputs:
            return  # on screen or on its way (only the section's settings changed)
        self._inputs[layer.name] = inputs
        for channel in layer.channels:
            self.runner.cancel(channel)
        if inputs is None:
            if from_job:  # the section's job starts the layers that follow it: figures change on the document thread
                self.runner.ui(lambda: self.clear(layer))
            else:
                self.clear(layer)
        elif inputs is not KEEP:
            self.run(layer, inputs, from_job=from_job)

    def clear(self, layer: Layer) -> None:
        """Nothing of ``layer`` on screen, and its fields say so."""
        layer.clear()
        self.publish(layer)

    def run(self, layer: Layer, inputs: Any, *, channel: str | None = None, bump: bool = True,
            from_job: bool = False) -> None:  # fmt: skip
        """Start ``layer``'s job for ``inputs`` on its channel; each result it yields is applied on the document
        thread while the layer still shows what the state asks (:meth:`Layer.current`)."""
        publish = (lambda: self.runner.ui(lambda: self.publish(layer))) if from_job else (lambda: self.publish(layer))
        try:
            arg = layer.prepare(inputs)
        except ParameterError as exc:
            layer.refused(exc)
            publish()
            return
        publish()

        def job(cancelled: Callable[[], bool], emit: Emit) -> None:
            for result in layer.job(arg, cancelled):  # the layer's own polls yield its slot between chunks
                if cancelled(wait=False):  # a result computed is sent at once if still wanted
                    return
                emit(lambda r=result: self._apply(layer, inputs, r))

        self.runner.start(channel or layer.name, job, bump=bump)

    def _apply(self, layer: Layer, inputs: Any, result: Any) -> None:
        if layer.current(inputs):
            layer.apply(inputs, result)
            self.publish(layer)

    def publish(self, layer: Layer) -> None:
        """A layer's text and counts to the session's fields the page shows: those that changed, in one update
        (the page's view is rebuilt once for them)."""
        changed = {name: value for name, value in layer.published().items() if getattr(self, name) != value}
        if changed:
            self.param.update(**changed)

    def _watcher(self, layer: Layer) -> Callable[..., None]:
        """A watcher of a layer's own settings: redo the layer and publish the URL (not during a scene)."""

        def watcher(*events: Any) -> None:
            if not self._suspend:
                self.refresh(layer)
                self._publish_query()

        return watcher

    def _follow_section(self, from_job: bool = False) -> None:
        """The layers that start once the section's first points are out."""
        for layer in self.layers.values():
            if layer.after_section:
                self.refresh(layer, from_job=from_job)

    @contextlib.contextmanager
    def suspended(self) -> Iterator[None]:
        """State changes made meanwhile redo no layer and publish no URL (the caller does what they need)."""
        self._suspend = True
        try:
            yield
        finally:
            self._suspend = False

    # --- reacting to the state ------------------------------------------------------------

    def _on_section_change(self, *events: Any) -> None:
        if self._suspend:
            return
        for e in events:
            # A clicked trajectory is numbered after the random ones: the selection follows it.
            if e.name == "n_random" and self.state.selected >= e.old and self.state.clicked:
                self.state.selected = max(0, self.state.selected + e.new - e.old)
        self.recompute()

    def _set_view(self) -> None:
        q_range, r_range = self.state.q_range, self.state.r_range
        self.runner.ui(lambda: self.fig.set_view(q_range, r_range))

    def _on_view_change(self, *events: Any) -> None:
        if not self._suspend:
            self._set_view()
            self._view_layers()
            self._publish_query()

    def _view_layers(self) -> None:
        for layer in self.layers.values():
            if layer.on_view():
                self.refresh(layer)

    def apply_scene(self, scene_id: str) -> None:
        """Set every control from a scene and recompute once."""
        with self.suspended():
            self.state.apply_scene(scene_id)
        self._set_view()
        self.recompute()
        self._follow_section()

    def apply_settings(self, scene_id: str, updates: dict[str, Any], **fields: Any) -> None:
        """A scene, then values from a link (checked as a URL's are: a refused one keeps the scene's), then
        ``fields`` (e.g. the tour's step); everything recomputed once."""
        with self.suspended():
            self.state.apply_scene(scene_id)
            changed = False
            for name in sorted(updates, key=lambda n: _ORDER.index(n) if n in _ORDER else len(_ORDER)):
                try:
                    if name in BY_NAME:
                        self.state.check(name, updates[name])
                except ParameterError:
                    continue
                changed |= name in SYSTEM_FIELDS and updates[name] != getattr(self.state, name)
                setattr(self.state, name, updates[name])
            self.state.param.update(**fields, **({"scene": "custom"} if changed else {}))
        self._set_view()
        self.recompute()
        for layer in self.layers.values():
            if not layer.on_section and not layer.after_section:
                self.refresh(layer)
        self._follow_section()

    def set_view_from_plot(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> None:
        """The user panned/zoomed: remember the window (URL) and redo what depends on the view."""
        with self.suspended():
            self.state.param.update(q_range=tuple(q_range), r_range=tuple(r_range))
        if self.state.density_view():
            self._restart_section()  # the image, its tolerance and its seeds are those of the view
        self._view_layers()
        self._publish_query()

    # --- the section ------------------------------------------------------------------------

    def recompute(self) -> None:
        """Validate, then restart the section and the layers; a bad value keeps the last picture."""
        self.section.t_req = time.perf_counter()
        self.section.trace("recompute")
        try:
            req = self.state.section_request()
        except ParameterError as exc:
            self.error = str(exc)
            self.runner.cancel(self.section.name)
            self.section.refresh_status()  # the picture kept is of other settings: the status says which
            self._publish_query()
            return
        self.error = ""
        frame = self.frame_periods is not None and not req.density  # a frame of a played parameter
        if frame and req.periods > self.frame_periods:
            req = dataclasses.replace(req, periods=self.frame_periods)
        self.section.start(req, start_layers=lambda: self._follow_section(from_job=True), frame=frame)
        for layer in self.layers.values():
            if layer.on_section:
                self.refresh(layer)
        if frame:
            # Its layers start now, beside the section's integration (numba, off the GIL), not after it: the frame
            # is drawn whole once all are done, and nothing of it streams meanwhile (app/layers/section.py).
            self._follow_section()
        self._publish_query()

    def _restart_section(self) -> None:
        """The section again with the state's request (a density view after a zoom or a new selection)."""
        try:
            req = self.state.section_request()
        except ParameterError as exc:
            self.error = str(exc)
            return
        self.section.start(req)

    def _on_selected(self) -> None:
        req = self.section.density.req
        sel = self.state.selected
        if req is not None and self.state.density_view() and sel != NO_SELECTION and sel not in req.keep:
            self._restart_section()  # a density run keeps only the selected trajectory's points: keep this one
        else:
            self.runner.ui(self.section.update_series)

    def stop(self) -> None:
        """Stop everything of the section view in flight; what was computed stays on screen, and says which
        settings it belongs to when the controls have moved on (the new settings' results never came)."""
        if self.runner.busy(self.section.name):
            self.section.stop()
        busy = {c for c in self.channels if self.runner.busy(c)}
        self._inputs.clear()  # a stopped layer is computed again next time
        for channel in self.channels:
            self.runner.cancel(channel)
        now = self.state.to_query()
        for layer in self.every:
            layer.stopped(bool(busy & set(layer.channels)), now)
            self.publish(layer)

    def failed_job(self, channel: str, exc: BaseException) -> None:
        """A job of the section view raised (document thread): say so; nothing stays "computing"."""
        self.error = f"{channel} computation failed: {plain(exc)}"
        for layer in self.layers.values():
            if channel in layer.channels:
                self._inputs.pop(layer.name, None)  # tried again on the next change
        if channel == self.section.name:
            self.section.failed_run()

    # --- clicks --------------------------------------------------------------------------------

    def add_initial_condition(self, q: float, r: float) -> None:
        """Add a trajectory where the user clicked, select it and recompute the section.

        Clicked points come after the random ones among the initial conditions: a click never
        renumbers the random trajectories (their ids in the escaped list and the CSV stay). The whole
        section is recomputed (the default scene in ~0.1 s of CPU), and every count, colour and index
        on screen belongs to one consistent run.
        """
        if not (np.isfinite(q) and np.isfinite(r)):
            return
        if len(self.state.clicked) >= MAX_CLICKED:
            self.error = f"at most {MAX_CLICKED} clicked initial conditions; clear some first"
            return
        clicked = [*self.state.clicked, (float(q), float(r))]
        try:
            self.state.check_work(len(clicked) + self.state.n_random, self.state.periods)
        except ParameterError as exc:
            self.error = str(exc)
            return
        self.state.param.update(clicked=clicked, selected=self.state.n_random + len(clicked) - 1)

    def select_nearest(self, q: float, r: float) -> None:
        """Select the trajectory whose section point is nearest the click (in screen-like units)."""
        traj, k, qq, rr = self.data()
        if traj.size == 0:
            return
        sq = self.state.q_range[1] - self.state.q_range[0]
        sr = self.state.r_range[1] - self.state.r_range[0]
        i = int(np.argmin(((qq - q) / sq) ** 2 + ((rr - r) / sr) ** 2))
        self.state.selected = int(traj[i])

    def clear_clicked(self) -> None:
        if self.state.clicked:
            # A clicked trajectory selected is gone: the first one instead (no selection stays none).
            self.state.param.update(clicked=[], selected=min(self.state.selected, 0))

    # --- the layers' actions and downloads ------------------------------------------------------------

    def act(self, name: str, *where: float) -> bool:
        """The page's action ``name`` (:class:`app.layers.base.Action`): a button's, or a click in the plot in the
        mode ``name`` with its ``q, r``, run by the layer that declares it. False when no layer answers it."""
        found = self.actions.get(name)
        if found is None or found[1].click != bool(where):
            return False
        layer, action = found
        getattr(layer, action.method)(*where)
        self._publish_query()  # seeds, picks or modes the action changed
        return True

    def csv(self, what: str) -> bytes | None:
        """The CSV download ``what`` of the layer that offers it (:attr:`app.layers.base.Layer.download`), or None
        when no layer offers it or nothing of it is on screen."""
        for layer in self.every:
            if layer.download and layer.download == what:
                return layer.csv()
        return None

    def download(self, what: str) -> Download | None:
        """The download ``what`` of the layer that offers it (:meth:`app.layers.base.Layer.file`: its name says
        whether its run was stopped), or None when no layer offers it or nothing of it is on screen."""
        for layer in self.every:
            if layer.download and layer.download == what:
                return layer.file()
        return None

    # --- data out ------------------------------------------------------------------------------

    def data(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All section points on screen as ``(traj, k, q, r)``."""
        return self.section.data()

    def _publish_query(self) -> None:
        if self._on_query is not None:
            self._on_query(self.state.to_query())


__all__ = ["ExplorerSession", "SectionRequest"]
