"""The section as a density image of the view: how many points fall in each pixel, binned on the server.

A long section (beyond the points bound, or ``render=density``) is never sent or kept point by point: the
core bins it as it is computed; only the trajectories in ``req.keep`` (the clicked ones, drawn over the image,
and the selected one, for its k-series) keep their points. It runs in the section's channel and shares its
status line (:class:`app.layers.section.SectionLayer` owns one :class:`DensityImage`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from app.layers.stream import MAX_CHUNK, Cadence
from app.runner import Emit, Job
from app.state import PLOT_PIXELS, SectionRequest
from explorer_core.analyses.density import iter_density


class DensityImage:
    """The density image on screen (None when the section is drawn as points) and the request it is of."""

    def __init__(self, section: Any) -> None:  # the SectionLayer that owns it
        self.section = section
        #: (points computed, points in view) of the image on screen, or None when points are drawn.
        self.counts: tuple[int, int] | None = None
        self.req: SectionRequest | None = None
        self.first_clicked = 0  # trajectories numbered from here are drawn as points over the image

    def forget(self) -> None:
        """A run drawn as points replaced the image."""
        self.counts = None
        self.req = None
        self.section.host.fig.set_density(None)

    def job(self, req: SectionRequest, start_layers: Callable[[], None] | None, query: dict[str, str]) -> Job:
        """The section's job for a density run (binned as computed; only ``req.keep``'s points kept)."""
        self.req = req
        self.first_clicked = self.section.host.state.n_random

        def job(cancelled: Callable[[], bool], emit: Emit) -> None:
            pending: list[tuple[np.ndarray, ...]] = []
            cadence = Cadence(start_layers)
            last = None

            def flush(img: Any) -> None:
                cols = tuple(np.concatenate([p[i] for p in pending]) if pending else np.zeros(0) for i in range(4))
                pending.clear()
                image = img.counts.astype(np.float32)  # a snapshot: the core keeps adding into its array
                counts = (img.points, img.in_view)
                status, done, total = img.status.copy(), img.done_periods, img.total_periods
                new_run = req if cadence.sent() else None
                emit(lambda: self.apply(image, req.view, counts, cols, status, done, total, new_run, query))

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
            done = not cancelled(wait=False)  # the image is computed: only whether it is still wanted
            cadence.layers_at_end(done)
            status = last.status.copy() if last is not None else None
            emit(lambda: self.section.finish(done, status))

        return job

    def apply(self, image: np.ndarray, view: tuple[float, float, float, float], counts: tuple[int, int],
              cols: tuple[np.ndarray, ...], status: np.ndarray, done: int, total: int,
              new_run: SectionRequest | None, query: dict[str, str]) -> None:  # fmt: skip
        sec, fig = self.section, self.section.host.fig
        traj, k, q, r = cols
        drawn = traj >= self.first_clicked  # over the image only the clicked ones (the selected is ringed)
        if new_run is not None:
            sec.reset(new_run, query)
            fig.replace_points(traj[drawn], k[drawn], q[drawn], r[drawn])
        else:
            fig.stream_points(traj[drawn], k[drawn], q[drawn], r[drawn])
        if traj.size:
            sec.chunks.append(cols)
        self.counts = counts
        fig.set_density(image, view)
        sec.set_status(status, done, total, running=True)
        if traj.size and np.any(traj == sec.host.state.selected):
            sec.update_series()
