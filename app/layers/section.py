"""The section points: every trajectory's points of the stroboscopic map, streamed, and the status line.

The section is the layer the others follow: its settings (``fields``) restart it and the layers of the
system; the frozen-field layers start once its first points are out (:class:`Cadence`). Drawn as a density
image instead (many points) by :mod:`app.layers.density`, which keeps its picture in the same channel.
The reliability check (a priori: the numerics against the scene; then the states reached) is this layer's
second channel.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from app.layers.base import Layer, Table, stale_note, stopped_lines
from app.layers.density import DensityImage
from app.layers.stream import MAX_CHUNK, Cadence
from app.runner import LAYER, POINTS, Emit
from app.state import NO_SELECTION, SYSTEM_FIELDS, SectionRequest, key_words, url_keys
from app.words import counted
from explorer_core.analyses.reliability import assess
from explorer_core.losses import Loss
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
#: The URL keys of the settings the section on screen depends on (its export's header and the stale note).
SECTION_KEYS = url_keys((*SECTION_FIELDS, "clicked"))
VIEW_KEYS = url_keys(("q_range", "r_range"))


def _assess(
    req: SectionRequest,
    traj: np.ndarray | None,
    q: np.ndarray | None,
    r: np.ndarray | None,
    status: np.ndarray | None,
    window: tuple[float, ...],
    pixel: float,
) -> list[dict[str, Any]]:
    """The reliability warnings of ``req`` (:func:`assess`) given the states reached (``traj is None``: none known)."""
    try:
        found = assess(
            req.params, req.numerics, periods=req.periods, transient=req.transient, ics=req.ics,
            points=np.column_stack([q, r]) if traj is not None else None, traj=traj, status=status,
            window=window, pixel=pixel,
        )  # fmt: skip
    except Exception:  # a failed check must never break the page
        log.exception("reliability check failed")
        found = []
    return [w.as_dict() for w in found]


class SectionLayer(Layer):
    """The section on screen: its points (or density image), the statuses of its trajectories, the status line."""

    name = "section"
    channels: ClassVar[dict[str, str]] = {"section": POINTS, "reliability": LAYER}
    fields = SECTION_FIELDS
    depends = (*SECTION_FIELDS, "clicked")
    #: The status line, the trajectories escaped and failed, the points on screen (the CSV download is offered
    #: only then) and the reliability warnings (explorer_core.reliability) as dicts: level, code, message.
    publishes: ClassVar[dict[str, Any]] = {"status": "", "escaped": [], "failed": [], "n_points": 0,
                                           "reliability": []}  # fmt: skip
    download = "section"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.params: Params | None = None  # system of the data on screen
        self.chunks: list[tuple[np.ndarray, ...]] = []
        self.n_traj = 0
        self.t_start = 0.0
        self.elapsed = 0.0
        self.progress: tuple[int | None, int | None] | None = None
        #: ``(done, total)`` periods of the run whose points are on screen, as its last points came (its export
        #: says what a Stop lost: a Stop before the next run's points leaves this run's).
        self.shown_periods: tuple[int, int] | None = None
        self.outcome = ""  # "", "stopped" or "failed": how the last run ended short
        self.status_arr = np.zeros(0, dtype=np.int8)  # status of each trajectory on screen
        self.run_n = 0  # trajectories of the run in flight (or the last one)
        self.run_transient = 0  # periods integrated before the first point (the core yields none meanwhile)
        self.text = ""
        self.escaped: list[int] = []
        self.failed: list[int] = []
        self.n_points = 0
        self.warnings: list[dict[str, Any]] = []
        self.density = DensityImage(self)
        self.t_req = time.perf_counter()

    def trace(self, label: str) -> None:
        if TRACE:
            log.warning("trace %.3f %8.1f ms %s", time.time(), 1e3 * (time.perf_counter() - self.t_req), label)

    def status(self) -> str:
        return self.text

    def published(self) -> dict[str, Any]:
        return {"status": self.text, "escaped": self.escaped, "failed": self.failed, "n_points": self.n_points,
                "reliability": self.warnings}  # fmt: skip

    def view(self) -> dict[str, Any]:
        status = self.text
        if self.escaped:
            ids = ", ".join(str(i) for i in self.escaped[:12]) + (" …" if len(self.escaped) > 12 else "")
            status += f"  |  escaped (noncompact drift, left the bound): {ids}"
        if self.failed:
            status += f"  |  failed: {', '.join(str(i) for i in self.failed[:12])}"
        return {"status": status, "warnings": [{"level": w["level"], "message": w["message"]} for w in self.warnings],
                "n_points": self.n_points, "density": self.density.counts is not None}  # fmt: skip

    # --- a run --------------------------------------------------------------------------------

    def start(
        self, req: SectionRequest, start_layers: Callable[[], None] | None = None, *, frame: bool = False
    ) -> None:
        """Restart the section with ``req`` (its points replace those on screen when they come); ``frame``: a played
        parameter's frame (never a density run)."""
        self.t_start = time.perf_counter()
        self.progress = (0, req.periods)
        self.run_transient = req.transient
        self.outcome = ""
        self.run_n = req.ics.shape[0]
        query = self.host.state.to_query()  # the settings of this run: its points' export header
        if req.periods != self.host.state.periods:  # a played parameter's frame: fewer periods than a still
            query["periods"] = str(req.periods)
        # A played parameter's frame is drawn whole, once its layers are done too: they start with it (the
        # controller starts them), and the one reliability check is of the states the frame reached.
        if req.density:
            job = self.density.job(req, start_layers, query)
        else:
            job = self._points_job(req, None if frame else start_layers, query, whole=frame)
        self.host.runner.start("section", job, first=not frame)
        if frame:
            self.host.runner.cancel("reliability")  # a still's check still running is of other settings
        else:
            self.check_reliability(req)  # a priori: the new numerics against the states on screen

    def _points_job(self, req: SectionRequest, start_layers: Callable[[], None] | None, query: dict[str, str], *,
                    whole: bool) -> Any:  # fmt: skip
        # ``whole``: a played parameter's frame, drawn whole (streamed, each frame would flash its first chunk alone).
        st = self.host.state
        window, pixel = (*st.q_range, *st.r_range), st.pixel_size()

        def job(cancelled: Callable[[], bool], emit: Emit) -> None:
            self.trace("section job starts")
            last_status = None
            pending: list[tuple[np.ndarray, ...]] = []
            cadence = Cadence(start_layers)

            def flush(status: np.ndarray, done: int, total: int) -> tuple[np.ndarray, ...]:
                cols = tuple(np.concatenate([p[i] for p in pending]) for i in range(4))
                pending.clear()
                replace = cadence.sent()
                emit(lambda: self.apply_chunk(cols, status, done, total, req if replace else None, query))
                return cols

            # A frame in one call for the transient and one for the points: each call takes the GIL a few times, and
            # the frame's layers run beside it in Python (a chunk's wait for the GIL is up to the switch interval).
            most = max(req.periods, req.transient, 1) if whole else MAX_CHUNK
            for chunk in iter_section(req.params, req.ics, req.periods, transient=req.transient,
                                      numerics=req.numerics, first_chunk=most if whole else 1, max_chunk=most,
                                      cancel=cancelled):  # fmt: skip
                pending.append(chunk.long())
                last_status = chunk.status
                if not whole and cadence.due():
                    flush(chunk.status, chunk.done_periods, chunk.total_periods)
                cadence.layers_if_late()
            warnings = None
            if pending and last_status is not None:
                traj, _, q, r = flush(last_status, req.periods, req.periods)
                if whole:  # a frame's one reliability check, of the states it reached, in its own job (no second job)
                    warnings = _assess(req, traj, q, r, last_status, window, pixel)
            done = not cancelled(wait=False)  # the points are computed: only whether they are still wanted
            cadence.layers_at_end(done)
            emit(lambda: self.finish(done, last_status, warnings))

        return job

    def reset(self, req: SectionRequest, query: dict[str, str]) -> None:
        """The first update of a new run: what is on screen is forgotten (in the same update that replaces it)."""
        st = self.host.state
        self.params = req.params
        self.shown_query = query
        self.chunks = []
        if not req.density:
            self.density.forget()
        self.n_traj = req.ics.shape[0]
        self.status_arr = np.zeros(self.n_traj, dtype=np.int8)
        self.escaped, self.failed = [], []
        self.host.fig.set_ics(np.array(st.clicked, dtype=float).reshape(-1, 2))
        if st.selected >= self.n_traj:
            st.selected = 0
        self.host.series.set(*(np.zeros(0),) * 4)

    def apply_chunk(self, cols: tuple[np.ndarray, ...], status: np.ndarray, done: int, total: int,
                    new_run: SectionRequest | None, query: dict[str, str]) -> None:  # fmt: skip
        traj, k, q, r = cols
        if new_run is not None:
            # The old picture stays until the new run's first points replace it, in one
            # update: no blank plot, and the browser redraws once, not twice.
            self.trace("first chunk on the document thread")
            self.reset(new_run, query)
            self.chunks.append(cols)
            self.host.fig.replace_points(traj, k, q, r)
        else:
            self.chunks.append(cols)
            self.host.fig.stream_points(traj, k, q, r)
        self.set_status(status, done, total, running=True)
        if traj.size and np.any(traj == self.host.state.selected):
            self.update_series()
        self.trace(f"{traj.size} points applied")

    def finish(self, done: bool, status: np.ndarray | None, warnings: list[dict[str, Any]] | None = None) -> None:
        """The run is over; ``warnings``: its reliability check, done by its job (a played frame's), else one starts."""
        self.trace("last chunk on the document thread")
        self.progress = None
        if not done:
            self.outcome = "stopped"
        if status is not None:
            self.set_status(status, None, None, running=False)
            if warnings is not None:
                self._warn(warnings)
            else:
                self.check_reliability(None, status)
        traj, st = self.data()[0], self.host.state
        if traj.size and st.selected != NO_SELECTION and not np.any(traj == st.selected):
            # The selected trajectory left (e.g. escaped in the transient): show one that has points.
            st.selected = int(traj.min())
        self.update_series()

    def stop(self) -> None:
        """Stop pressed while the section ran (before its jobs are cancelled)."""
        self.outcome = "stopped"
        self.elapsed = time.perf_counter() - self.t_start

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        self.refresh_status()

    def failed_run(self) -> None:
        self.outcome = "failed"
        self.refresh_status()

    # --- the status line -----------------------------------------------------------------------

    def set_status(self, status: np.ndarray, done: int | None, total: int | None, *, running: bool) -> None:
        """Statuses of the main run's trajectories (a chunk or the end of the run)."""
        self.status_arr[: status.size] = status
        self.progress = (done, total) if running and done is not None else None
        if running and done is not None and total is not None:
            self.shown_periods = (done, total)
        self.elapsed = time.perf_counter() - self.t_start
        self.refresh_status()

    def refresh_status(self) -> None:
        """The status line from the data on screen and whether the section runs (document thread)."""
        arr = self.status_arr
        self.escaped = [int(i) for i in np.flatnonzero(arr == Status.ESCAPED)]
        self.failed = [int(i) for i in np.flatnonzero((arr != Status.OK) & (arr != Status.ESCAPED))]
        escaped, failed = self.escaped, self.failed
        n_points = self.n_points = sum(c[0].size for c in self.chunks)
        running = self.host.runner.busy("section")
        if running:
            self.elapsed = time.perf_counter() - self.t_start
        n_traj = self.n_traj if n_points else self.run_n  # nothing on screen yet: the run's count
        parts = [counted(n_points, "point", grouped=True), counted(n_traj, "trajectory"), f"{self.elapsed:.2f} s"]
        counts = self.density.counts
        if counts is not None:
            n_traj = self.n_traj or self.run_n
            n_drawn = sum(int(np.count_nonzero(c[0] >= self.density.first_clicked)) for c in self.chunks)
            drawn = f" ({n_drawn:,} of them drawn as points: the clicked trajectories)" if n_drawn else ""
            parts = [f"{counts[0]:,} points as a density image, {counts[1]:,} in view{drawn}",
                     counted(n_traj, "trajectory"), f"{self.elapsed:.2f} s"]  # fmt: skip
        if running:
            done, total = self.progress or (None, None)
            if done == 0 and self.run_transient:
                # The core yields nothing during the transient: say what it does instead of "0/100" for seconds.
                parts.insert(0, f"computing: transient of {self.run_transient} periods first (no points before "
                                f"it ends), then {total} periods")  # fmt: skip
            else:
                parts.insert(0, f"computing {done}/{total} periods" if done is not None else "computing…")
        if escaped:
            parts.append(f"{len(escaped)} escaped")
        if failed:
            parts.append(f"{len(failed)} failed")
        if not running and self.outcome:
            parts.append(self.outcome)
        if not running and (n_points or counts is not None):
            keys = (*SECTION_KEYS, *VIEW_KEYS) if counts is not None else SECTION_KEYS
            note = stale_note(self.shown_query, self.host.state.to_query(), keys, key_words)
            if note:
                parts.append(f"the picture is for {note}")
        shown = n_points or n_traj or running or self.outcome or counts
        self.text = " · ".join(parts) if shown else ""
        self.host.publish(self)

    # --- the reliability check ----------------------------------------------------------------

    def check_reliability(self, req: SectionRequest | None, status: np.ndarray | None = None) -> None:
        """Warn when the method is unreliable for this scene (explorer_core.reliability.assess).

        The check integrates a few probe states (RK4's error estimate), so it runs as a job
        of its own, after the section's job has started: it never delays the first points.
        """
        st = self.host.state
        try:
            req = req or st.section_request()
        except ParameterError:
            return
        # Points on screen tell how large the states get, if they belong to this system.
        same = self.params == req.params and bool(self.chunks)
        traj, _, q, r = self.data() if same else (None, None, None, None)
        status = status if status is not None and status.size == req.ics.shape[0] else None
        window, pixel = (*st.q_range, *st.r_range), st.pixel_size()

        def job(cancelled: Callable[[], bool], emit: Emit) -> None:
            warnings = _assess(req, traj if same else None, q, r, status, window, pixel)
            emit(lambda: self._warn(warnings))

        self.host.runner.start("reliability", job)

    def _warn(self, warnings: list[dict[str, Any]]) -> None:
        self.warnings = warnings
        self.host.publish(self)

    # --- data out ------------------------------------------------------------------------------

    def data(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All section points on screen as ``(traj, k, q, r)``."""
        if not self.chunks:
            z = np.zeros(0)
            return z.astype(int), z.astype(int), z, z
        return tuple(np.concatenate([c[i] for c in self.chunks]) for i in range(4))  # type: ignore[return-value]

    def update_series(self) -> None:
        """The selected trajectory: its k-series below and its points ringed in the section."""
        traj, k, q, r = self.data()
        sel = traj == self.host.state.selected
        fig = self.host.fig
        if self.params is None or not sel.any():
            self.host.series.set(*(np.zeros(0),) * 4)
            fig.set_selected(np.zeros(0), np.zeros(0))
            return
        order = np.argsort(k[sel], kind="stable")
        ks, qs, rs = k[sel][order], q[sel][order], r[sel][order]
        energy = Model(self.params).energy(qs, rs, self.params.t0)
        self.host.series.set(ks, qs, rs, energy)
        if self.density.counts is None:
            fig.set_selected(qs, rs)
        else:  # rings over a density image would hide it: the k-series below shows the trajectory
            fig.set_selected(np.zeros(0), np.zeros(0))

    def table(self) -> Table | None:
        """The section on screen, ``traj,k,q,r``, under the settings it was computed with."""
        if not self.n_points:
            return None
        traj, k, q, r = self.data()
        notes = () if self.density.counts is None else (
            f"a density view: only the trajectories drawn as points (clicked, selected); the image holds "
            f"{self.density.counts[0]} points",)  # fmt: skip
        # k-major, as the command line's CSV (every trajectory's point at k, then k + 1): one file order.
        order = np.lexsort((traj, k))
        rows = zip(*(a[order].tolist() for a in (traj, k, q, r)), strict=True)
        return Table("section", self.shown_query or self.host.state.to_query(), ("traj", "k", "q", "r"), rows, notes,
                     self.partial())  # fmt: skip

    def partial(self) -> tuple[str, ...]:
        """What the run on screen did not compute, in the core's words (:func:`stopped_lines`); () when it ended."""
        done, total = self.shown_periods or (0, 0)
        if done >= total:
            return ()
        how = "still running" if self.host.runner.busy(self.name) else "stopped"
        lost = Loss(f"periods of each of the {self.n_traj} trajectories", total - done,
                    f"not computed: the section was {how} after {done} of its {total} periods")  # fmt: skip
        return stopped_lines([lost])
