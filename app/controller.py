"""One browser session: state changes -> core computations -> figures.

:class:`ExplorerSession` watches an :class:`~app.state.ExplorerState`, starts
jobs on a :class:`~app.runner.Runner` and applies their results to the figures
on the document thread. Invalid input shows a message and leaves the last valid
picture in place. All numerics are calls into :mod:`explorer_core`.

What the page shows as running ("computing", Stop enabled) is derived from the runner's busy
state (:meth:`~app.runner.Runner.busy`), never set by hand, so it ends with the work however
the work ends. Values reach the state only through :func:`app.state.commit`.
"""

from __future__ import annotations

import io
import logging
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import param

from app.runner import Runner
from app.state import (
    CONTROLS,
    MAX_CLICKED,
    MAX_MAGNITUDE,
    MAX_MANIFOLDS,
    MAX_ORBIT_SEEDS,
    PLOT_PIXELS,
    SYSTEM_FIELDS,
    TABS,
    ExplorerState,
    SectionRequest,
    commit,
    key_words,
    url_keys,
)
from app.views import SectionFigure, SeriesData, as_drawn
from explorer_core.analyses.basins import ESCAPE, FAILED, UNDECIDED, Basins, basin_spec, iter_basins
from explorer_core.analyses.density import iter_density
from explorer_core.analyses.equilibria import equilibrium_tracks
from explorer_core.analyses.manifolds import Manifolds, iter_manifolds, saddle_orbit
from explorer_core.analyses.orbits import Orbit, OrbitSearch, find_orbits, grid_seeds, same_orbit
from explorer_core.analyses.reliability import assess
from explorer_core.analyses.tprime import energy_change_map, tprime_map
from explorer_core.solve.integrators import Status
from explorer_core.solve.section import iter_section
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

log = logging.getLogger(__name__)
#: BILIMOVICH_TRACE=1 logs the timeline of each recompute (latency work).
TRACE = bool(os.environ.get("BILIMOVICH_TRACE"))

#: State fields whose change invalidates the section.
SECTION_FIELDS = (*SYSTEM_FIELDS, "method", "accuracy", "steps_per_period", "n_random", "seed", "periods", "transient")
SECTION_FIELDS += ("box", "render")
LAYER_FIELDS = ("show_tracks", "show_tprime", "tprime_kind")
ORBIT_FIELDS = ("show_orbits", "orbit_period")
MANIFOLD_FIELDS = ("manifold_saddles", "manifold_length")
BASIN_FIELDS = ("show_basins", "basin_grid")
#: What Stop stops in the section view, and what makes it "running".
SECTION_CHANNELS = ("section", "tracks", "tprime", "reliability", "orbit", "orbits", "manifolds", "basins")
#: Basins: a colour per attractor id (cycled), and the pixels that reach none.
BASIN_COLOURS = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#1f78b4")
#: Escaped pixels mid grey, failed ones dark grey (the old light grey at half opacity looked like the page's white);
#: undecided ones are left blank, and the legend says so.
OUTCOME_COLOURS = {ESCAPE: "#555555", FAILED: "#000000", UNDECIDED: "#ffffff"}
OUTCOME_NAMES = {ESCAPE: "escape (noncompact drift)", FAILED: "integration failed", UNDECIDED: "undecided (blank)"}
#: A click picks the saddle whose point is nearest, within this fraction of the view's width and height.
PICK_RADIUS = 0.03
#: Seeds of the "every orbit in view" search: a grid over the plot window.
ORBIT_GRID = (10, 10)
#: Orbits listed in the table (all of them are drawn and in the CSV).
ORBIT_ROWS = 40
ANALYSIS_FIELDS = tuple(c.name for c in CONTROLS if c.area in TABS[1:])
#: The URL keys (state.to_query) of the settings each result on screen depends on: what its export's header
#: and a note on screen name when the result is not that of the controls (e.g. a Stop before the new points).
SYSTEM_KEYS = url_keys(SYSTEM_FIELDS)
SECTION_KEYS = url_keys((*SECTION_FIELDS, "clicked"))
ORBIT_KEYS = url_keys((*SYSTEM_FIELDS, "orbit_period"))
VIEW_KEYS = url_keys(("q_range", "r_range"))
MANIFOLD_KEYS = url_keys((*SYSTEM_FIELDS, "manifold_length", "q_range", "r_range"))
BASIN_KEYS = url_keys((*SYSTEM_FIELDS, "basin_grid", "q_range", "r_range"))
#: Longest chunk streamed to the browser: bounds how long a cancel waits.
MAX_CHUNK = 32
#: Time between point updates sent to the browser: starts here, doubles up to the max (seconds).
EMIT_INTERVAL = 0.5
MAX_EMIT_INTERVAL = 1.0
#: The layers (T' map, tracks) of a new setting are computed once the section is done, or
#: this long (seconds) into a longer run: computed alongside, they would take CPU (and the
#: GIL: the tracks are Python) from the section's first points, and every update they send
#: makes the browser redraw the whole plot while the points are still coming.
LAYER_DELAY = 1.0
TRACK_SAMPLES = 360
TPRIME_GRID = 160
PER_PERIOD_GRID = 80


class ExplorerSession(param.Parameterized):
    """Controller of one session. ``status`` and ``error`` are plain text for the page."""

    status = param.String(default="")
    error = param.String(default="")
    #: Something of the section view runs (the section, a clicked trajectory, a layer): Stop applies.
    running = param.Boolean(default=False)
    escaped = param.List(default=[])
    failed = param.List(default=[])
    #: Reliability warnings (explorer_core.reliability) as dicts: level, code, message.
    reliability = param.List(default=[])
    #: Section points on screen (the CSV download is offered only then).
    n_points = param.Integer(default=0)
    #: Periodic orbits on screen, as table rows (:func:`orbit_row`), and what the last search said.
    orbits = param.List(default=[])
    orbit_status = param.String(default="")
    #: Saddles whose manifolds are on screen, and what the last growth said.
    n_manifolds = param.Integer(default=0)
    manifold_status = param.String(default="")
    #: The basins layer: what it says, and its legend rows (colour, text).
    basin_status = param.String(default="")
    basin_legend = param.List(default=[])

    def __init__(
        self,
        state: ExplorerState,
        runner: Runner,
        section_fig: SectionFigure | None = None,
        series: SeriesData | None = None,
        on_query: Callable[[dict[str, str]], None] | None = None,
    ) -> None:
        super().__init__()
        self.state = state
        self.runner = runner
        self.fig = section_fig or SectionFigure(state.q_range, state.r_range)
        self.series = series or SeriesData()
        self._on_query = on_query
        self._params: Params | None = None  # system of the data on screen
        #: The settings (state.to_query()) each result on screen was computed with: its export's header, and
        #: what the screen names when the controls have moved on (a Stop before the new result came).
        self._shown_query: dict[str, str] | None = None  # the section
        self._orbits_query: dict[str, str] | None = None
        self._manifolds_query: dict[str, str] | None = None
        self._basins_query: dict[str, str] | None = None
        #: The systems of the frozen-field tracks and the T' map on screen (no text of their own: cleared
        #: by a Stop that leaves them for another system).
        self._tracks_params: Params | None = None
        self._tprime_params: Params | None = None
        self._chunks: list[tuple[np.ndarray, ...]] = []
        self._n_traj = 0
        self._t_start = 0.0
        self._elapsed = 0.0
        self._progress: tuple[int, int] | None = None
        self._outcome = ""  # "", "stopped" or "failed": how the last run ended short
        self._status_arr = np.zeros(0, dtype=np.int8)  # status of each trajectory on screen
        self._run_n = 0  # trajectories of the run in flight (or the last one)
        #: The density image on screen: (points computed, points in view), or None when points are drawn.
        self._density: tuple[int, int] | None = None
        self._density_req: SectionRequest | None = None
        self._first_clicked = 0
        self._run_transient = 0  # periods integrated before the first point (the core yields none meanwhile)
        self._suspend = False
        self._t_req = time.perf_counter()
        if runner._on_busy is None:
            runner._on_busy = self.on_busy
        state.param.watch(self._on_section_change, list(SECTION_FIELDS))
        state.param.watch(self._on_layers_change, list(LAYER_FIELDS))
        state.param.watch(self._on_view_change, ["q_range", "r_range"])
        state.param.watch(lambda *e: self._on_selected(), ["selected"])
        state.param.watch(lambda *e: self.recompute(), ["clicked"])
        state.param.watch(self._layer_watcher(self.recompute_orbits), list(ORBIT_FIELDS))
        self._orbits: list[Orbit] = []
        self._manifolds: list[Manifolds] = []
        #: The inputs of each phase-plane layer's last job (see _new_inputs).
        self._layer_inputs: dict[str, Any] = {}
        state.param.watch(self._layer_watcher(self.recompute_manifolds), list(MANIFOLD_FIELDS))
        state.param.watch(self._layer_watcher(self.recompute_basins), list(BASIN_FIELDS))
        state.param.watch(lambda *e: self._publish_query(), ["selected", "tab", "presentation", *ANALYSIS_FIELDS])

    # --- input ------------------------------------------------------------------------------

    def commit(self, name: str, text: Any) -> str | None:
        """A typed value for control ``name``: applied (None), or refused with the reason (state unchanged)."""
        if name == "scene":
            msg = commit(self.state, "scene", text)
            if msg is None and self.state.scene != "custom":
                q_range, r_range = self.state.q_range, self.state.r_range
                self.runner.ui(lambda: self.fig.set_view(q_range, r_range))
            return msg
        return commit(self.state, name, text)

    @property
    def density_shown(self) -> bool:
        """The section on screen is a density image (not points)."""
        return self._density is not None

    def on_busy(self, channel: str) -> None:
        """A channel started or stopped (document thread): the section view runs while any of its channels do."""
        if channel in SECTION_CHANNELS:
            running = any(self.runner.busy(c) for c in SECTION_CHANNELS)
            if running != self.running:
                self.running = running
            if channel == "section":
                self._refresh_status()

    # --- reacting to the state ------------------------------------------------------------

    def _system(self) -> Params | None:
        """The system on screen; None while a typed value is refused (recompute shows why)."""
        try:
            return self.state.system()
        except ParameterError:
            return None

    def _layer_watcher(self, recompute: Callable[[], None]) -> Callable[..., None]:
        """A watcher of a layer's own settings: recompute the layer and publish the URL (not during a scene)."""

        def watcher(*events: Any) -> None:
            if not self._suspend:
                recompute()
                self._publish_query()

        return watcher

    def _on_section_change(self, *events: Any) -> None:
        if self._suspend:
            return
        for e in events:
            # A clicked trajectory is numbered after the random ones: the selection follows it.
            if e.name == "n_random" and self.state.selected >= e.old and self.state.clicked:
                self.state.selected = max(0, self.state.selected + e.new - e.old)
        self.recompute()

    def _on_layers_change(self, *events: Any) -> None:
        if not self._suspend:
            self._start_layers()
            self._publish_query()

    def _on_view_change(self, *events: Any) -> None:
        if not self._suspend:
            q_range, r_range = self.state.q_range, self.state.r_range
            self.runner.ui(lambda: self.fig.set_view(q_range, r_range))
            self._start_layers(tracks=False)
            self._publish_query()

    def apply_scene(self, scene_id: str) -> None:
        """Set every control from a scene and recompute once."""
        self._suspend = True
        try:
            self.state.apply_scene(scene_id)
        finally:
            self._suspend = False
        q_range, r_range = self.state.q_range, self.state.r_range
        self.runner.ui(lambda: self.fig.set_view(q_range, r_range))
        self.recompute()
        self._start_layers()

    def set_view_from_plot(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> None:
        """The user panned/zoomed: remember the window (URL) and refresh the T' map (and the view's orbits)."""
        self._suspend = True
        try:
            self.state.param.update(q_range=tuple(q_range), r_range=tuple(r_range))
        finally:
            self._suspend = False
        self._start_layers(tracks=False)
        if self.state.density_view():
            self._restart_section()  # the image, its tolerance and its seeds are those of the view
        if self.state.orbit_view:
            self.recompute_orbits()
        if self.state.manifold_saddles:
            self.recompute_manifolds()  # refined for the new view's pixels
        if self.state.show_basins:
            self.recompute_basins()  # the initial conditions are the new view's pixels
        self._publish_query()

    # --- the section ------------------------------------------------------------------------

    def _trace(self, label: str) -> None:
        if TRACE:
            log.warning("trace %.3f %8.1f ms %s", time.time(), 1e3 * (time.perf_counter() - self._t_req), label)

    def recompute(self) -> None:
        """Validate, then restart the section and the layers; a bad value keeps the last picture."""
        self._t_req = time.perf_counter()
        self._trace("recompute")
        try:
            req = self.state.section_request()
        except ParameterError as exc:
            self.error = str(exc)
            self.runner.cancel("section")
            self._refresh_status()  # the picture kept is of other settings: the status says which
            self._publish_query()
            return
        self.error = ""
        self._start_section(req, start_layers=self._start_layers)
        self.recompute_orbits()
        self.recompute_manifolds()
        self.recompute_basins()
        self._publish_query()

    def _restart_section(self) -> None:
        """The section again with the state's request (a density view after a zoom or a new selection)."""
        try:
            req = self.state.section_request()
        except ParameterError as exc:
            self.error = str(exc)
            return
        self._start_section(req)

    def _on_selected(self) -> None:
        req = self._density_req
        if req is not None and self.state.density_view() and self.state.selected not in req.keep:
            self._restart_section()  # a density run keeps only the selected trajectory's points: keep this one
        else:
            self.runner.ui(self._update_series)

    def _start_section(self, req: SectionRequest, start_layers: Callable[[], None] | None = None) -> None:
        self._t_start = time.perf_counter()
        self._progress = (0, req.periods)
        self._run_transient = req.transient
        self._outcome = ""
        self._run_n = req.ics.shape[0]
        query = self.state.to_query()  # the settings of this run: its points' export header
        if req.density:
            self._start_density(req, start_layers, query)
            return

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            self._trace("section job starts")
            last_status = None
            pending: list[tuple[np.ndarray, ...]] = []
            cadence = _Cadence(start_layers)

            def flush(status: np.ndarray, done: int, total: int) -> None:
                cols = tuple(np.concatenate([p[i] for p in pending]) for i in range(4))
                pending.clear()
                replace = cadence.sent()
                emit(lambda: self._apply_chunk(cols, status, done, total, req if replace else None, query))

            for chunk in iter_section(
                req.params,
                req.ics,
                req.periods,
                transient=req.transient,
                numerics=req.numerics,
                max_chunk=MAX_CHUNK,
                cancel=cancelled,
            ):
                pending.append(chunk.long())
                last_status = chunk.status
                if cadence.due():
                    flush(chunk.status, chunk.done_periods, chunk.total_periods)
                cadence.layers_if_late()
            if pending and last_status is not None:
                flush(last_status, req.periods, req.periods)
            done = not cancelled()
            cadence.layers_at_end(done)
            emit(lambda: self._finish(done, last_status))

        self.runner.start("section", job)
        self._update_reliability(req)  # a priori: the new numerics against the states on screen

    def _start_density(self, req: SectionRequest, start_layers: Callable[[], None] | None,
                       query: dict[str, str]) -> None:  # fmt: skip
        """The section as a density image of the view (binned as computed; only ``req.keep``'s points kept)."""
        self._density_req = req
        self._first_clicked = self.state.n_random  # trajectories numbered from here are drawn as points

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            pending: list[tuple[np.ndarray, ...]] = []
            cadence = _Cadence(start_layers)
            last = None

            def flush(img: Any) -> None:
                cols = tuple(np.concatenate([p[i] for p in pending]) if pending else np.zeros(0) for i in range(4))
                pending.clear()
                image = img.counts.astype(np.float32)  # a snapshot: the core keeps adding into its array
                counts = (img.points, img.in_view)
                status, done, total = img.status.copy(), img.done_periods, img.total_periods
                new_run = req if cadence.sent() else None
                emit(lambda: self._apply_density(image, req.view, counts, cols, status, done, total, new_run, query))

            for img, kept in iter_density(req.params, req.ics, req.periods, view=req.view, pixels=PLOT_PIXELS,
                                          transient=req.transient, numerics=req.numerics, keep=req.keep,
                                          max_chunk=MAX_CHUNK, cancel=cancelled):  # fmt: skip
                last = img
                for i, rows in kept.items():
                    if rows.shape[0]:
                        traj = np.full(rows.shape[0], i, dtype=np.int64)
                        pending.append((traj, rows[:, 0].astype(np.int64), rows[:, 1], rows[:, 2]))
                if cadence.due():
                    flush(img)
                cadence.layers_if_late()
            if last is not None:
                flush(last)
            done = not cancelled()
            cadence.layers_at_end(done)
            status = last.status.copy() if last is not None else None
            emit(lambda: self._finish(done, status))

        self.runner.start("section", job)
        self._update_reliability(req)

    def _apply_density(self, image: np.ndarray, view: tuple[float, float, float, float], counts: tuple[int, int],
                       cols: tuple[np.ndarray, ...], status: np.ndarray, done: int, total: int,
                       new_run: SectionRequest | None, query: dict[str, str]) -> None:  # fmt: skip
        traj, k, q, r = cols
        drawn = traj >= self._first_clicked  # over the image only the clicked ones (the selected is ringed)
        if new_run is not None:
            self._reset(new_run, query)
            self.fig.replace_points(traj[drawn], k[drawn], q[drawn], r[drawn])
        else:
            self.fig.stream_points(traj[drawn], k[drawn], q[drawn], r[drawn])
        if traj.size:
            self._chunks.append(cols)
        self._density = counts
        self.fig.set_density(image, view)
        self._set_status(status, done, total, running=True)
        if traj.size and np.any(traj == self.state.selected):
            self._update_series()

    def _new_inputs(self, layer: str, inputs: Any) -> bool:
        """Whether ``layer`` must be recomputed: its inputs differ from those of its last job (None: nothing
        to compute, always handled). A layer of the system and the view need not be redone when only the
        section's numerics or initial conditions change."""
        if inputs is not None and self._layer_inputs.get(layer) == inputs:
            return False
        self._layer_inputs[layer] = inputs
        return True

    def stop(self) -> None:
        """Stop everything of the section view in flight; what was computed stays on screen, and says which
        settings it belongs to when the controls have moved on (the new settings' results never came)."""
        stopped = self.runner.busy("section")
        busy = {c for c in SECTION_CHANNELS if self.runner.busy(c)}
        self._layer_inputs.clear()  # a stopped layer is computed again next time
        for channel in SECTION_CHANNELS:
            self.runner.cancel(channel)
        if stopped:
            self._outcome = "stopped"
            self._elapsed = time.perf_counter() - self._t_start
        self._refresh_status()
        self._label_stopped_layers(busy)

    def _label_stopped_layers(self, busy: set[str]) -> None:
        """After a Stop: each layer's status says whether what it shows is of the controls' settings."""
        now = self.state.to_query()
        if self.state.show_orbits and (busy & {"orbit", "orbits"} or self._orbits):
            note = stale_note(self._orbits_query, now, ORBIT_KEYS) if self._orbits else ""
            if note:
                self.orbit_status = f"stopped: the {len(self._orbits)} periodic orbits shown are for {note}"
            elif busy & {"orbit", "orbits"}:
                self.orbit_status = f"stopped: {len(self._orbits)} periodic orbits shown (the search did not end)"
        if self.state.manifold_saddles:
            note = stale_note(self._manifolds_query, now, MANIFOLD_KEYS) if self._manifolds else ""
            if note:
                self.manifold_status = f"stopped: the manifolds shown are for {note}"
            elif "manifolds" in busy:
                self.manifold_status = "stopped: " + self.manifold_status.removeprefix("growing… ")
        if self.state.show_basins:
            note = stale_note(self._basins_query, now, BASIN_KEYS)
            if note:
                self.basin_status = f"stopped: the basins shown are for {note}"
            elif "basins" in busy:
                shown = self._basins_query is not None
                self.basin_status = "stopped: " + (self.basin_status if shown else "no basins computed yet")
        system = self._system()
        if self._tracks_params is not None and self._tracks_params != system:
            self._show_tracks(None, [], None)  # no text says whose they are: not left under other settings
        if self._tprime_params is not None and self._tprime_params != system:
            self._show_tprime(None, None, "")

    def failed_job(self, channel: str, exc: BaseException) -> None:
        """A job of the section view raised (document thread): say so; nothing stays "computing"."""
        msg = _plain(exc)
        self.error = f"{channel} computation failed: {msg}"
        self._layer_inputs.pop(channel, None)  # tried again on the next change
        if channel == "section":
            self._outcome = "failed"
            self._refresh_status()

    def _reset(self, req: SectionRequest, query: dict[str, str]) -> None:
        self._params = req.params
        self._shown_query = query
        self._chunks = []
        if not req.density:
            self._density = None
            self._density_req = None
            self.fig.set_density(None)
        self._n_traj = req.ics.shape[0]
        self._status_arr = np.zeros(self._n_traj, dtype=np.int8)
        self.escaped, self.failed = [], []
        self.fig.set_ics(np.array(self.state.clicked, dtype=float).reshape(-1, 2))
        if self.state.selected >= self._n_traj:
            self.state.selected = 0
        self.series.set(*(np.zeros(0),) * 4)

    def _apply_chunk(
        self,
        cols: tuple[np.ndarray, ...],
        status: np.ndarray,
        done: int,
        total: int,
        new_run: SectionRequest | None,
        query: dict[str, str],
    ) -> None:
        traj, k, q, r = cols
        if new_run is not None:
            # The old picture stays until the new run's first points replace it, in one
            # update: no blank plot, and the browser redraws once, not twice.
            self._trace("first chunk on the document thread")
            self._reset(new_run, query)
            self._chunks.append(cols)
            self.fig.replace_points(traj, k, q, r)
        else:
            self._chunks.append(cols)
            self.fig.stream_points(traj, k, q, r)
        self._set_status(status, done, total, running=True)
        if traj.size and np.any(traj == self.state.selected):
            self._update_series()
        self._trace(f"{traj.size} points applied")

    def _finish(self, done: bool, status: np.ndarray | None) -> None:
        self._trace("last chunk on the document thread")
        self._progress = None
        if not done:
            self._outcome = "stopped"
        if status is not None:
            self._set_status(status, None, None, running=False, stopped=not done)
            self._update_reliability(None, status)
        traj = self.data()[0]
        if traj.size and not np.any(traj == self.state.selected):
            # The selected trajectory left (e.g. escaped in the transient): show one that has points.
            self.state.selected = int(traj.min())
        self._update_series()

    def _set_status(self, status: np.ndarray, done: int | None, total: int | None, *, running: bool,
                    stopped: bool = False) -> None:  # fmt: skip
        """Statuses of the main run's trajectories (a chunk or the end of the run)."""
        arr = self._status_arr
        arr[: status.size] = status
        self._progress = (done, total) if running and done is not None else None
        self._elapsed = time.perf_counter() - self._t_start
        self._refresh_status()

    def _refresh_status(self) -> None:
        """The status line from the data on screen and whether the section runs (document thread)."""
        arr = self._status_arr
        escaped = [int(i) for i in np.flatnonzero(arr == Status.ESCAPED)]
        failed = [int(i) for i in np.flatnonzero((arr != Status.OK) & (arr != Status.ESCAPED))]
        if escaped != self.escaped:
            self.escaped = escaped
        if failed != self.failed:
            self.failed = failed
        n_points = sum(c[0].size for c in self._chunks)
        if n_points != self.n_points:
            self.n_points = n_points
        running = self.runner.busy("section")
        if running:
            self._elapsed = time.perf_counter() - self._t_start
        n_traj = self._n_traj if n_points else self._run_n  # nothing on screen yet: the run's count
        parts = [f"{n_points:,} points", f"{n_traj} trajectories", f"{self._elapsed:.2f} s"]
        if self._density is not None:
            n_traj = self._n_traj or self._run_n
            n_drawn = sum(int(np.count_nonzero(c[0] >= self._first_clicked)) for c in self._chunks)
            drawn = f" ({n_drawn:,} of them drawn as points: the clicked trajectories)" if n_drawn else ""
            parts = [f"{self._density[0]:,} points as a density image, {self._density[1]:,} in view{drawn}",
                     f"{n_traj} trajectories", f"{self._elapsed:.2f} s"]  # fmt: skip
        if running:
            done, total = self._progress or (None, None)
            if done == 0 and self._run_transient:
                # The core yields nothing during the transient: say what it does instead of "0/100" for seconds.
                parts.insert(0, f"computing: transient of {self._run_transient} periods first (no points before "
                                f"it ends), then {total} periods")  # fmt: skip
            else:
                parts.insert(0, f"computing {done}/{total} periods" if done is not None else "computing…")
        if escaped:
            parts.append(f"{len(escaped)} escaped")
        if failed:
            parts.append(f"{len(failed)} failed")
        if not running and self._outcome:
            parts.append(self._outcome)
        if not running and (n_points or self._density is not None):
            keys = (*SECTION_KEYS, *VIEW_KEYS) if self._density is not None else SECTION_KEYS
            note = stale_note(self._shown_query, self.state.to_query(), keys)
            if note:
                parts.append(f"the picture is for {note}")
        shown = n_points or n_traj or running or self._outcome or self._density
        self.status = " · ".join(parts) if shown else ""

    def _update_reliability(self, req: SectionRequest | None, status: np.ndarray | None = None) -> None:
        """Warn when the method is unreliable for this scene (explorer_core.reliability.assess).

        The check integrates a few probe states (RK4's error estimate), so it runs as a job
        of its own, after the section's job has started: it never delays the first points.
        """
        st = self.state
        try:
            req = req or st.section_request()
        except ParameterError:
            return
        # Points on screen tell how large the states get, if they belong to this system.
        same = self._params == req.params and bool(self._chunks)
        traj, _, q, r = self.data() if same else (None, None, None, None)
        status = status if status is not None and status.size == req.ics.shape[0] else None
        window, pixel = (*st.q_range, *st.r_range), st.pixel_size()

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            try:
                found = assess(
                    req.params, req.numerics, periods=req.periods, transient=req.transient, ics=req.ics,
                    points=np.column_stack([q, r]) if same else None, traj=traj, status=status,
                    window=window, pixel=pixel,
                )  # fmt: skip
            except Exception:  # a failed check must never break the page
                log.exception("reliability check failed")
                found = []
            warnings = [w.as_dict() for w in found]
            emit(lambda: setattr(self, "reliability", warnings))

        self.runner.start("reliability", job)

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
            self.state.param.update(clicked=[], selected=0)

    # --- periodic orbits of the map ------------------------------------------------------------

    def find_orbit_at(self, q: float, r: float) -> None:
        """Newton from a click, for every period up to the setting; drawn as soon as found (one job)."""
        if not (np.isfinite(q) and np.isfinite(r)) or max(abs(q), abs(r)) > MAX_MAGNITUDE:
            return
        st = self.state
        if len(st.orbit_seeds) >= MAX_ORBIT_SEEDS:
            self.orbit_status = f"at most {MAX_ORBIT_SEEDS} orbit seeds; clear the orbits first"
            return
        params = self._system()
        if params is None:
            return
        seed = (float(q), float(r))
        st.orbit_seeds = [*st.orbit_seeds, seed]
        query = st.to_query()
        if not st.show_orbits:
            st.show_orbits = True  # recomputes every seed, this one included
            return
        periods = list(range(1, st.orbit_period + 1))

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            res = find_orbits(params, [seed], periods, cancel=cancelled)
            if not cancelled():
                emit(lambda: self._merge_orbits(params, res, f"from ({q:.4g}, {r:.4g})", query))

        # One job per click, all kept: a second click does not cancel the first.
        self.runner.start("orbit", job, bump=False)
        self._publish_query()

    def find_orbits_in_view(self) -> None:
        """Also search from a grid of seeds over the plot window (kept in the URL; redone on a new view)."""
        if self.state.orbit_view and self.state.show_orbits:
            return
        self._suspend = True
        try:
            self.state.param.update(orbit_view=True, show_orbits=True)
        finally:
            self._suspend = False
        self.recompute_orbits()
        self._publish_query()

    def clear_orbits(self) -> None:
        self.runner.cancel("orbit")
        self.runner.cancel("orbits")
        self.state.param.update(orbit_seeds=[], orbit_view=False)
        self._orbits = []
        self._orbits_query = None
        self.orbit_status = ""
        self._show_orbits()
        self._publish_query()

    def recompute_orbits(self) -> None:
        """All orbits from the seeds (and the view's grid) for the system on screen: a layer job."""
        self.runner.cancel("orbit")
        st = self.state
        seeds = list(st.orbit_seeds)
        if st.orbit_view:
            seeds += [tuple(x) for x in grid_seeds((*st.q_range, *st.r_range), *ORBIT_GRID)]
        if not st.show_orbits or not seeds:
            self.runner.cancel("orbits")
            self._orbits = []
            self._orbits_query = None
            self.orbit_status = ""
            self._show_orbits()
            return
        params = self._system()
        if params is None:
            return
        periods = list(range(1, st.orbit_period + 1))
        query = st.to_query()
        self.orbit_status = (f"finding periodic orbits (periods 1..{st.orbit_period}) from {len(seeds)} starting "
                             "points…")  # fmt: skip

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            res = find_orbits(params, seeds, periods, cancel=cancelled)
            if cancelled():
                return
            emit(lambda: self._set_orbits(params, res, query))

        self.runner.start("orbits", job)

    def _set_orbits(self, params: Params, res: OrbitSearch, query: dict[str, str]) -> None:
        self._orbits = []
        self._merge_orbits(params, res, "", query)

    def _merge_orbits(self, params: Params, res: OrbitSearch, where: str, query: dict[str, str]) -> None:
        if params != self._system():
            return  # found for a system no longer on screen
        if stale_note(self._orbits_query, query, SYSTEM_KEYS):
            self._orbits = []  # those on screen are another system's (a Stop kept them): never mixed
        self._orbits_query = query
        new = [o for o in res.orbits if not any(same_orbit(o, k) for k in self._orbits)]
        self._orbits = sorted([*self._orbits, *new], key=lambda o: (o.period, float(o.points[0, 0])))
        self._show_orbits()
        if where:
            if new:
                what = ", ".join(f"period {o.period} ({o.kind})" for o in new)
                self.orbit_status = f"{where}: {what}"
            elif res.orbits:
                self.orbit_status = f"{where}: an orbit already shown (period {res.orbits[0].period})"
            else:
                reason = res.failures[0].reason if res.failures else "nothing found"
                self.orbit_status = f"{where}: no orbit of period ≤ {max(res.extra.get('periods', [0]))} ({reason})"
        else:
            periods = list(res.extra.get("periods", [])) or [0]
            tries = res.seeds * len(periods)
            self.orbit_status = (f"{len(self._orbits)} periodic orbits of period 1..{max(periods)} from {res.seeds} "
                                 f"starting points ({len(res.failures)} of the {tries} Newton searches, one per "
                                 f"starting point and period, found none; {res.elapsed_s:.2f} s)")  # fmt: skip

    def _show_orbits(self) -> None:
        rows = [orbit_row(o) for o in self._orbits]
        self.fig.set_orbits(rows)
        self.orbits = rows[:ORBIT_ROWS]

    def orbits_csv(self) -> io.BytesIO:
        """The orbits on screen as CSV (one row per orbit point), the settings in a comment header."""
        buf = io.StringIO()
        settings = "&".join(f"{a}={b}" for a, b in (self._orbits_query or self.state.to_query()).items())
        buf.write("# Bilimovich Explorer periodic orbits; " + settings)
        buf.write("\norbit,period,type,stable,j,q,r,mu1_re,mu1_im,mu2_re,mu2_im,det,liouville,residual\n")
        for i, o in enumerate(self._orbits):
            m = o.multipliers
            for j, (q, r) in enumerate(o.points):
                nums = (q, r, m[0].real, m[0].imag, m[1].real, m[1].imag, o.det, o.liouville, o.residual)
                buf.write(f"{i},{int(o.period)},{o.kind},{int(o.stable)},{j},{','.join(_num(x) for x in nums)}\n")
        return io.BytesIO(buf.getvalue().encode())

    # --- stable and unstable manifolds of saddles ----------------------------------------------

    def manifolds_at(self, q: float, r: float) -> None:
        """A click in "manifolds" mode: the saddle of the orbits layer nearest the click (drawn, or removed)."""
        if not (np.isfinite(q) and np.isfinite(r)):
            return
        st = self.state
        sq = st.q_range[1] - st.q_range[0]
        sr = st.r_range[1] - st.r_range[0]
        best, where = None, np.inf
        for o in self._orbits:
            if o.kind not in ("saddle", "flip saddle"):
                continue
            d = float(np.min(np.hypot((o.points[:, 0] - q) / sq, (o.points[:, 1] - r) / sr)))
            if d < where:
                best, where = o, d
        if best is None or where > PICK_RADIUS:
            self.manifold_status = (
                "no saddle ✕ near the click: find the orbits first ('Find orbits in view', or click with "
                "'finds a periodic orbit')"
                if best is None
                else f"no saddle ✕ near ({q:.4g}, {r:.4g}): click on a saddle's cross"
            )
            return
        x = best.points[0]
        entry = (float(x[0]), float(x[1]), int(best.period))
        kept = [s for s in st.manifold_saddles if not _same_saddle(s, entry, sq, sr)]
        if len(kept) < len(st.manifold_saddles):
            st.manifold_saddles = kept  # a second click on a drawn saddle removes its manifolds
            return
        if len(kept) >= MAX_MANIFOLDS:
            self.manifold_status = f"at most {MAX_MANIFOLDS} saddles at once: click a drawn one to remove it"
            return
        st.manifold_saddles = [*kept, entry]

    def clear_manifolds(self) -> None:
        self.runner.cancel("manifolds")
        self.state.manifold_saddles = []  # the watcher clears the layer
        self.manifold_status = ""

    def recompute_manifolds(self) -> None:
        """The manifolds of every chosen saddle for the system and the view on screen: a layer job, streamed."""
        st = self.state
        saddles = list(st.manifold_saddles)
        params = self._system()
        view = (*st.q_range, *st.r_range)
        length = float(st.manifold_length)
        query = st.to_query()
        if not self._new_inputs("manifolds", (params, view, tuple(saddles), length) if saddles and params else None):
            return  # these manifolds are on screen or on their way (only the section's settings changed)
        self.runner.cancel("manifolds")
        if not saddles:
            self.n_manifolds = 0
            self._manifolds = []
            self._manifolds_query = None
            self.manifold_status = ""
            self.fig.set_manifolds([], [])
            return
        if params is None:
            return  # the error is already shown by recompute
        self.manifold_status = f"growing the manifolds of {len(saddles)} saddle(s)…"

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            done: list[Manifolds] = []
            notes: list[str] = []
            for q, r, n in saddles:
                try:
                    orbit = saddle_orbit(params, (q, r), n)
                except ParameterError as exc:  # e.g. no longer a saddle for this system
                    notes.append(f"({q:.4g}, {r:.4g}): {_plain(exc)}")
                    continue
                for m in iter_manifolds(params, orbit, length=length, view=view, pixels=PLOT_PIXELS, others=done,
                                        cancel=cancelled):  # fmt: skip
                    if cancelled():
                        return
                    shown = [*done, m]
                    text = "; ".join([*(_manifold_text(x) for x in shown), *notes])
                    if not m.completed:
                        text = "growing… " + text
                    emit(lambda s=shown, t=text: self._show_manifolds(params, s, t, query))
                done.append(m)
            if not done:
                emit(lambda: self._show_manifolds(params, [], "; ".join(notes), query))

        self.runner.start("manifolds", job)

    def _show_manifolds(self, params: Params, shown: list[Manifolds], text: str, query: dict[str, str]) -> None:
        if params != self._system():
            return  # grown for a system no longer on screen
        self._manifolds = shown
        self._manifolds_query = query
        self.n_manifolds = len(shown)  # on screen (the CSV download offers exactly these)
        lines = [(p[:, 1], p[:, 2], b.kind) for m in shown for b in m.branches for p in b.pieces]
        marks = [(c.q, c.r, f"{c.kind}: unstable {c.unstable}, stable {c.stable}") for m in shown for c in m.crossings]
        self.fig.set_manifolds(lines, marks)
        self.manifold_status = text

    def manifolds_csv(self) -> io.BytesIO:
        """The manifolds on screen as CSV ``saddle,branch,kind,s,q,r`` with the settings in a comment header."""
        buf = io.StringIO()
        settings = self._manifolds_query or self.state.to_query()
        buf.write("# Bilimovich Explorer manifolds; " + "&".join(f"{a}={b}" for a, b in settings.items()))
        buf.write("\nsaddle,branch,kind,s,q,r\n")
        for i, m in enumerate(self._manifolds):
            for label, kind, s_, q, r in m.rows():
                buf.write(f"{i},{label},{kind},{_num(s_)},{_num(q)},{_num(r)}\n")
        return io.BytesIO(buf.getvalue().encode())

    # --- basins of attraction over the view ----------------------------------------------------

    def recompute_basins(self) -> None:
        """Which attractor each pixel centre of the view reaches: a layer job, coarse to fine."""
        st = self.state
        params = self._system()
        box = (*st.q_range, *st.r_range)
        n = st.basin_grid
        query = st.to_query()
        if not self._new_inputs("basins", (params, box, n) if st.show_basins and params else None):
            return  # these basins are on screen or on their way (only the section's settings changed)
        self.runner.cancel("basins")
        if not st.show_basins:
            self.fig.set_basins(None)
            self.basin_status, self.basin_legend = "", []
            self._basins_query = None
            return
        if params is None:
            return  # the error is already shown by recompute
        try:
            spec = basin_spec(params, box, (n, n))
        except ParameterError as exc:
            self.basin_status = f"basins: {_plain(exc)}"
            return
        self.basin_status = f"basins of attraction on {n} x {n} initial conditions in view…"

        def job(cancelled: Callable[[], bool], emit: Callable[[Callable[[], None]], None]) -> None:
            for upd in iter_basins(spec, cancel=cancelled):
                if cancelled():
                    return
                b = upd.basins
                done = f"{upd.done_pixels}/{upd.total_pixels}"
                emit(lambda b=b, d=done: self._show_basins(params, box, b, d, query))

        self.runner.start("basins", job)

    def _show_basins(self, params: Params, box: tuple[float, ...], b: Basins, done: str,
                     query: dict[str, str]) -> None:  # fmt: skip
        if params != self._system() or box != (*self.state.q_range, *self.state.r_range):
            return  # for a system or a view no longer on screen
        self._basins_query = query
        labels = b.filled()
        colours = {a.id: BASIN_COLOURS[i % len(BASIN_COLOURS)] for i, a in enumerate(b.attractors)}
        colours.update(OUTCOME_COLOURS)
        self.fig.set_basins(labels, box, colours)
        legend = []
        for a in b.attractors:
            if a.kind == "escape":
                continue
            if not a.attracting:  # invariant curves of a conservative island: no attractor
                what = "conservative island (not an attractor)"
            elif a.kind == "periodic":
                what = f"period-{a.period} cycle"
            else:
                what = a.kind.replace("_", "-") + " attractor"
            if a.orbit_type:
                what += f" ({a.orbit_type})"
            if len(a.points):
                what += f" at ({a.points[0, 0]:.4g}, {a.points[0, 1]:.4g})"
            legend.append([as_drawn(colours[a.id]), f"{what}: {100 * b.fraction.get(a.id, 0.0):.1f}%"])
        for code, name in OUTCOME_NAMES.items():
            if b.fraction.get(code, 0.0) > 0:
                legend.append([as_drawn(OUTCOME_COLOURS[code]), f"{name}: {100 * b.fraction[code]:.1f}%"])
        self.basin_legend = legend
        n_att = sum(a.kind != "escape" and a.attracting for a in b.attractors)
        if b.completed:
            head = f"basins on {b.label.shape[1]} x {b.label.shape[0]} initial conditions: {n_att} attractor(s)"
            if not n_att:
                head += " (none found: every pixel escaped, failed or was undecided)"
            said = [*b.warnings, *(loss.line() for loss in b.lost)]
            self.basin_status = f"{head}, {b.elapsed_s:.2f} s" + "".join(f"; {w}" for w in said[:3])
        else:
            self.basin_status = f"basins: {done} pixels, {n_att} attractor(s) so far…"

    # --- layers: equilibrium tracks and the T' map ---------------------------------------------

    def _start_layers(self, tracks: bool = True) -> None:
        params = self._system()
        if params is None:
            return  # the error is already shown by recompute
        st = self.state
        show_tracks, show_tp, kind = st.show_tracks, st.show_tprime, st.tprime_kind
        q_range, r_range = st.q_range, st.r_range
        numerics = st.numerics()

        if tracks:

            def tracks_job(cancelled, emit) -> None:
                if not show_tracks:
                    emit(lambda: self._show_tracks(None, [], None))
                    return
                tr = equilibrium_tracks(params, n_t=TRACK_SAMPLES, cancel=cancelled)
                if not tr.completed:  # a newer setting: its own tracks job is on the way
                    return
                segments = _segments_by_type(tr.branches())
                at_t0 = tr.section()
                emit(lambda: self._show_tracks(params, segments, at_t0))

            self.runner.start("tracks", tracks_job)

        def tprime_job(cancelled, emit) -> None:
            if not show_tp:
                emit(lambda: self._show_tprime(None, None, ""))
                return
            if kind == "per-period":
                m = energy_change_map(params, q_range, r_range, PER_PERIOD_GRID, numerics=numerics)
                title = "ΔT over a period: red gain, blue loss"  # fits the plot's height at 1280x720
            else:
                m = tprime_map(params, params.t0, q_range, r_range, TPRIME_GRID)
                title = "T′ at t0: red energy gain, blue loss"
            emit(lambda: self._show_tprime(params, m, title))

        self.runner.start("tprime", tprime_job)

    def _show_tracks(self, params: Params | None, segments: list, at_t0: Any) -> None:
        self._tracks_params = params
        self.fig.set_tracks(segments)
        if at_t0 is None:
            self.fig.set_equilibria([], [], ())
        else:
            self.fig.set_equilibria(at_t0.q, at_t0.r, at_t0.types)

    def _show_tprime(self, params: Params | None, m: Any, title: str) -> None:
        self._tprime_params = params
        if m is None:
            self.fig.set_tprime(None, np.zeros(0), np.zeros(0), "")
        else:
            self.fig.set_tprime(m.values, m.q, m.r, title)

    # --- data out ------------------------------------------------------------------------------

    def data(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All section points on screen as ``(traj, k, q, r)``."""
        if not self._chunks:
            z = np.zeros(0)
            return z.astype(int), z.astype(int), z, z
        return tuple(np.concatenate([c[i] for c in self._chunks]) for i in range(4))  # type: ignore[return-value]

    def _update_series(self) -> None:
        """The selected trajectory: its k-series below and its points ringed in the section."""
        traj, k, q, r = self.data()
        sel = traj == self.state.selected
        if self._params is None or not sel.any():
            self.series.set(*(np.zeros(0),) * 4)
            self.fig.set_selected(np.zeros(0), np.zeros(0))
            return
        order = np.argsort(k[sel], kind="stable")
        ks, qs, rs = k[sel][order], q[sel][order], r[sel][order]
        energy = Model(self._params).energy(qs, rs, self._params.t0)
        self.series.set(ks, qs, rs, energy)
        if self._density is None:
            self.fig.set_selected(qs, rs)
        else:  # rings over a density image would hide it: the k-series below shows the trajectory
            self.fig.set_selected(np.zeros(0), np.zeros(0))

    def csv_bytes(self) -> io.BytesIO:
        """The section on screen as CSV ``traj,k,q,r`` with the settings in a comment header."""
        traj, k, q, r = self.data()
        buf = io.StringIO()
        settings = self._shown_query or self.state.to_query()
        buf.write("# Bilimovich Explorer section; " + "&".join(f"{a}={b}" for a, b in settings.items()))
        if self._density is not None:
            buf.write(f"\n# a density view: only the trajectories drawn as points (clicked, selected); the image "
                      f"holds {self._density[0]} points")  # fmt: skip
        buf.write("\ntraj,k,q,r\n")
        for row in zip(traj.tolist(), k.tolist(), q.tolist(), r.tolist(), strict=True):
            buf.write(f"{row[0]},{row[1]},{row[2]!r},{row[3]!r}\n")
        return io.BytesIO(buf.getvalue().encode())

    def _publish_query(self) -> None:
        if self._on_query is not None:
            self._on_query(self.state.to_query())


class _Cadence:
    """When a streaming section job sends an update, and when it starts the layers.

    The first update goes out at once; later ones back off (EMIT_INTERVAL doubling up to MAX_EMIT_INTERVAL):
    each makes the browser redraw every point, which costs more than the data. The layers start
    LAYER_DELAY into a long run, or at the end of a shorter one that was not cancelled.
    """

    def __init__(self, start_layers: Callable[[], None] | None) -> None:
        self._first = True
        self._last = 0.0
        self._interval = EMIT_INTERVAL
        self._t0 = time.perf_counter()
        self._layers = start_layers

    def due(self) -> bool:
        return self._first or time.perf_counter() - self._last >= self._interval

    def sent(self) -> bool:
        """An update goes out now; whether it is the run's first (it replaces the picture on screen)."""
        first, self._first = self._first, False
        self._last = time.perf_counter()
        if not first:
            self._interval = min(2 * self._interval, MAX_EMIT_INTERVAL)
        return first

    def layers_if_late(self) -> None:
        if self._layers is not None and time.perf_counter() - self._t0 >= LAYER_DELAY:
            self._start_layers()  # a long run: the layers need not wait for its end

    def layers_at_end(self, done: bool) -> None:
        if self._layers is not None and done:
            self._start_layers()  # stale runs start none: the newer run starts its own

    def _start_layers(self) -> None:
        start, self._layers = self._layers, None
        start()  # type: ignore[misc]


def stale_note(then: dict[str, str] | None, now: dict[str, str], keys: tuple[str, ...], most: int = 3) -> str:
    """ "" when the settings ``keys`` of a result (``then``) are those in use (``now``); else what differs, in
    the controls' words: "α = 0.1 (the controls: 0.3)"."""
    if then is None:
        return ""
    diff = [k for k in keys if then.get(k) != now.get(k)]
    parts = [f"{key_words(k)} = {_short(then.get(k))} (the controls: {_short(now.get(k))})" for k in diff[:most]]
    if len(diff) > most:
        parts.append(f"and {len(diff) - most} more settings")
    return ", ".join(parts)


def _num(x: Any) -> str:
    """A number for a CSV cell: the shortest text that reads back to the same float (never ``np.float64(…)``)."""
    return repr(float(x))


def _short(v: str | None, limit: int = 40) -> str:
    v = v or "(none)"
    return v if len(v) <= limit else v[: limit - 1] + "…"


def _plain(exc: BaseException, limit: int = 300) -> str:
    """An exception as one short line of text (never a multi-line array dump)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _same_saddle(a: tuple, b: tuple, sq: float, sr: float) -> bool:
    """The same saddle entry ``(q, r, period)``: equal periods, points within a thousandth of the view."""
    return a[2] == b[2] and abs(a[0] - b[0]) <= 1e-3 * sq and abs(a[1] - b[1]) <= 1e-3 * sr


def _manifold_text(m: Manifolds) -> str:
    o = m.orbit
    ends = sorted({b.status for b in m.branches})
    homoclinic = sum(c.kind == "homoclinic" for c in m.crossings)
    hetero = len(m.crossings) - homoclinic
    text = (f"{o.kind} (period {o.period}) at ({o.points[0, 0]:.4g}, {o.points[0, 1]:.4g}): "
            f"{len(m.branches)} branches to s = {m.length:g} ({', '.join(ends)})")  # fmt: skip
    if m.completed:
        text += f", {homoclinic} homoclinic" + (f" and {hetero} heteroclinic" if hetero else "") + " points"
        escaped = sum(b.escaped for b in m.branches)
        if escaped:
            text += f", {escaped} points escaped (pieces split)"
        text += f", {m.elapsed_s:.2f} s"
    return text


def _segments_by_type(branches) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """Split each track where the equilibrium's type changes, so each piece has one colour."""
    out: list[tuple[np.ndarray, np.ndarray, str]] = []
    for b in branches:
        q, r, types = b["q"], b["r"], b["types"]
        start = 0
        for i in range(1, len(types) + 1):
            if i == len(types) or types[i] != types[start]:
                # Overlap one sample so consecutive pieces join.
                end = min(i + 1, len(types))
                if end - start >= 2:
                    out.append((q[start:end], r[start:end], types[start]))
                start = i
    return out


def _mu_text(mu: np.ndarray) -> str:
    parts = []
    for m in mu:
        parts.append(f"{m.real:.5g}{m.imag:+.5g}i" if abs(m.imag) > 1e-12 else f"{m.real:.6g}")
    return ", ".join(parts) + f"  (|μ| {abs(mu[0]):.4g}, {abs(mu[1]):.4g})"


def orbit_row(o: Orbit) -> dict[str, Any]:
    """An orbit as plain data for the page (table) and the figure (markers, hover)."""
    return {
        "period": int(o.period),
        "type": o.kind,
        "stable": bool(o.stable),
        "q": float(o.points[0, 0]),
        "r": float(o.points[0, 1]),
        "points": [[float(a), float(b)] for a, b in o.points],
        "mu": _mu_text(o.multipliers),
        "det": float(o.det),
    }
