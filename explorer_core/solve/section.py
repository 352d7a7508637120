"""Stroboscopic (Poincare) sections: points ``(q_k, r_k) = (q, r)(t0 + k T)``.

The paper's map (poi-map) ``x_{k+1} = F(x_k)`` sampled for many initial
conditions. Only section points are stored, never the trajectory between them.

:func:`iter_section` streams the work in chunks of periods so a caller (the web
app, the CLI's progress line) can draw points as they come and stop early;
:func:`section` collects the chunks into a :class:`Section`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress
from explorer_core.solve.integrators import Batch, Status, advance
from explorer_core.solve.numerics import Numerics, check_ics, check_int
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, check_time


@dataclass(frozen=True)
class SectionChunk:
    """Section points of one chunk of periods.

    ``points[i, :npts[i]]`` are trajectory ``i``'s points at ``k = k_first + j``
    (``j < npts[i]``); ``status`` is each trajectory's status after the chunk.
    """

    k_first: int
    points: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    done_periods: int
    total_periods: int
    elapsed_s: float

    def long(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Valid points as flat columns ``(traj, k, q, r)``."""
        return _long(self.points, self.npts, self.k_first, self.k_step)

    @property
    def progress(self) -> Progress:
        return Progress(self.done_periods, self.total_periods, "periods", self.elapsed_s)

    @property
    def k_step(self) -> int:
        return 1 if self.k_first >= 0 else -1

    def rows(self) -> int:
        """Its CSV rows: the valid points."""
        return int(self.npts.sum())

    def csv_rows(self) -> str:
        """Its valid points as CSV rows in the file's order (:data:`CSV_HEADER`)."""
        return _csv_rows(self.points, self.npts, self.k_first, self.k_step)


#: The section CSV's columns. Its rows are k-major: every trajectory's point at ``k`` in trajectory order, then
#: ``k + 1``, ...: the order the run computes them in, so the file streamed while it runs
#: (:meth:`Section.streamed`) is the one :meth:`Section.to_csv` writes, byte for byte.
CSV_HEADER = ("traj", "k", "q", "r")
#: Rows :meth:`Section.to_csv` formats at a time (a bounded piece of text in memory).
_CSV_BLOCK_ROWS = 100_000


def _csv_rows(points: np.ndarray, npts: np.ndarray, k_first: int, k_step: int) -> str:
    """``traj,k,q,r`` rows, k-major, of the valid points ``points[i, :npts[i]]`` at ``k_first + k_step * j``:
    numbers as ``csv.writer`` writes ``repr`` (the shortest text that reads back to the same double), ``\\r\\n``
    ended (one ``%`` per row: a third of the time of ``csv.writer``)."""
    j, i = np.nonzero(np.arange(points.shape[1])[:, None] < npts[None, :])  # row-major: by j, then by i
    cols = (i.tolist(), (k_first + k_step * j).tolist(), points[i, j, 0].tolist(), points[i, j, 1].tolist())
    return "".join(map("%d,%d,%r,%r\r\n".__mod__, zip(*cols, strict=True)))


def _long(points: np.ndarray, npts: np.ndarray, k_first: int, k_step: int = 1):
    n, m = points.shape[0], points.shape[1]
    mask = np.arange(m)[None, :] < npts[:, None]
    traj = np.broadcast_to(np.arange(n)[:, None], (n, m))[mask]
    k = np.broadcast_to(k_first + k_step * np.arange(m)[None, :], (n, m))[mask]
    return traj, k, points[..., 0][mask], points[..., 1][mask]


#: A growing chunk is kept to about this many seconds at the pace of the last one: a stop request (Ctrl-C, a
#: closed tab, a new slider value) waits at most about this long for the engine, whatever the number of ICs.
CHUNK_SECONDS = 0.25


def _chunk_schedule(total: int, chunk: int | None, first: int, max_chunk: int = 512) -> Generator[int, float, None]:
    """Chunk sizes: fixed, or growing 1, 2, 4, ... up to ``max_chunk`` so the first points come at once, and no
    longer than :data:`CHUNK_SECONDS` at the last chunk's pace (``send`` each chunk's seconds)."""
    done = 0
    size = first
    while done < total:
        step = min(chunk if chunk else size, total - done)
        took = yield step
        done += step
        if not chunk:
            size = min(size * 2, max_chunk)
            if took:  # the pace measured: a chunk of this size would take about CHUNK_SECONDS
                size = max(1, min(size, int(step * CHUNK_SECONDS / took)))


def iter_section(
    params: Params,
    ics: Any,
    periods: int,
    *,
    transient: int = 0,
    numerics: Numerics | None = None,
    direction: int = 1,
    chunk_periods: int | None = None,
    first_chunk: int = 1,
    max_chunk: int = 512,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Iterator[SectionChunk]:
    """Stream a section in chunks of periods.

    Parameters
    ----------
    params : the system.
    ics : (n, 2) initial conditions ``(q, r)`` at ``t0``.
    periods : section points wanted per trajectory, at ``k = transient + 1, ..., transient + periods``.
    transient : periods integrated first and not returned.
    numerics : method, tolerances, escape bound, step budget.
    direction : +1 forward, -1 backward (points at ``t0 - k T``, reported with negative ``k``).
    chunk_periods : fixed chunk size; default grows 1, 2, 4, ... up to ``max_chunk``
        (a smaller cap bounds how long a cancel waits).
    cancel : polled between chunks; returning True stops the stream.
    """
    numerics = numerics or Numerics()
    ics = check_ics(ics)
    periods = check_int("periods", periods, 1, config.MAX_PERIODS)
    transient = check_int("transient", transient, 0, config.MAX_PERIODS)
    if direction not in (1, -1) or isinstance(direction, bool):
        raise ParameterError(f"direction must be +1 or -1, got {direction!r}")
    # The whole horizon is checked before any work (the engine would refuse it only at the chunk that passes it).
    check_time("the horizon's end t", params.t0 + direction * (transient + periods) * params.period, params.period)
    model = Model(params)
    batch = Batch.start(ics, params.t0, direction * params.period)
    kw = numerics.kernel_kwargs()
    start = time.perf_counter()
    sizes = _chunk_schedule(transient, None, max(1, first_chunk), max_chunk)
    size = next(sizes, 0) if transient else 0
    while size:
        if cancel is not None and cancel():
            return
        t = time.perf_counter()
        advance(model, batch, size, store=False, workers=workers, **kw)
        size = _send(sizes, time.perf_counter() - t)
    done = 0
    sizes = _chunk_schedule(periods, chunk_periods, max(1, first_chunk), max_chunk)
    size = next(sizes)
    while size:
        if cancel is not None and cancel():
            return
        k_first = batch.k + 1
        t = time.perf_counter()
        pts, npts = advance(model, batch, size, workers=workers, **kw)
        took = time.perf_counter() - t
        done += size
        yield SectionChunk(
            k_first=direction * k_first,
            points=pts,
            npts=npts,
            status=batch.status.copy(),
            nsteps=batch.nsteps.copy(),
            done_periods=done,
            total_periods=periods,
            elapsed_s=time.perf_counter() - start,
        )
        if not np.any(batch.status == Status.OK):
            return
        size = _send(sizes, took)


def _send(sizes: Generator[int, float, None], took: float) -> int:
    """The schedule's next size given the last chunk's seconds (0 when the run is done)."""
    try:
        return sizes.send(took)
    except StopIteration:
        return 0


@dataclass
class Section(Drawable):
    """A computed section: per-trajectory points, status and cost.

    ``points[i, :npts[i]]`` are the valid points of trajectory ``i`` at
    ``k = k_first, k_first + 1, ...`` (negative and decreasing when backward).
    Points after a failure do not exist: use :meth:`trajectory` or :meth:`long`.
    """

    params: Params
    numerics: Numerics
    ics: np.ndarray
    k_first: int
    points: np.ndarray = field(repr=False)
    npts: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    elapsed_s: float
    completed: bool = True
    periods: int = 0
    transient: int = 0

    @property
    def n(self) -> int:
        return self.ics.shape[0]

    @property
    def k_step(self) -> int:
        return 1 if self.k_first >= 0 else -1

    def trajectory(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(k, q, r)`` of trajectory ``i``'s valid points."""
        m = int(self.npts[i])
        k = self.k_first + self.k_step * np.arange(m)
        return k, self.points[i, :m, 0].copy(), self.points[i, :m, 1].copy()

    def long(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every valid point as flat columns ``(traj, k, q, r)``."""
        return _long(self.points, self.npts, self.k_first, self.k_step)

    def status_labels(self) -> list[str]:
        return [Status(int(s)).label for s in self.status]

    def summary(self) -> dict[str, Any]:
        """JSON summary: one entry per trajectory plus timing and settings."""
        return {
            "trajectories": [
                {"ic": [float(q), float(r)], "status": lab, "points": int(n), "steps": int(s)}
                for (q, r), lab, n, s in zip(self.ics, self.status_labels(), self.npts, self.nsteps, strict=True)
            ],
            "elapsed_s": round(self.elapsed_s, 6),
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "periods": self.periods,
            "transient": self.transient,
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
        }

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "section"
        )

    @property
    def lost(self) -> list[Loss]:
        """Trajectories that stopped before their last period (by status), and the periods a cancel left out."""
        out = [Loss("trajectories", int(np.count_nonzero(self.status == code)),
                    f"stopped before their last period: {Status(int(code)).word}")
               for code in np.unique(self.status[self.status != Status.OK])]  # fmt: skip
        if not self.completed:
            left = int(np.sum(self.periods - self.npts[self.status == Status.OK]))
            out.append(Loss("periods not computed", left, "cancelled"))
        return out

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def to_csv(self, path: str) -> int:
        """Write ``traj,k,q,r`` rows (valid points only) in k-major order (:data:`CSV_HEADER`), whole or not at
        all; a section whose run was stopped says so after its header (``# `` lines, see
        :func:`explorer_core.export.partial`). Returns the row count."""
        block = max(1, _CSV_BLOCK_ROWS // max(1, self.n))
        with export.atomic(path) as tmp, open(tmp, "w", newline="") as fh:
            fh.write(export.csv_head(CSV_HEADER, export.partial(self)))
            for j in range(0, int(self.npts.max(initial=0)), block):
                npts = np.clip(self.npts - j, 0, block)
                fh.write(_csv_rows(self.points[:, j : j + block], npts, self.k_first + self.k_step * j, self.k_step))
        return int(self.npts.sum())

    @classmethod
    def streamed(cls, path: str) -> export.StreamedCsv | None:
        """A writer of ``path`` fed the run's chunks while it goes (its ``feed``: the run's ``progress``), whose
        ``write_result(section)`` ends the file as :meth:`write` would write it (:meth:`to_csv`, byte for byte);
        None for a file written only at the end (not ``.csv``)."""
        if not os.fspath(path).lower().endswith(".csv"):
            return None
        return export.StreamedCsv(path, CSV_HEADER, SectionChunk.csv_rows, SectionChunk.rows)


def section(
    params: Params,
    ics: Any,
    periods: int,
    *,
    transient: int = 0,
    numerics: Numerics | None = None,
    direction: int = 1,
    chunk_periods: int | None = None,
    progress: Callable[[SectionChunk], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Section:
    """Compute a whole section (see :func:`iter_section` for the parameters).

    ``progress`` is called after each chunk. If ``cancel`` stops the work, the
    points computed so far are returned with ``completed=False``.
    """
    numerics = numerics or Numerics()
    ics = check_ics(ics)
    periods = check_int("periods", periods, 1, config.MAX_PERIODS)
    transient = check_int("transient", transient, 0, config.MAX_PERIODS)
    if direction not in (1, -1) or isinstance(direction, bool):
        raise ParameterError(f"direction must be +1 or -1, got {direction!r}")
    n = ics.shape[0]
    if n * periods > config.MAX_POINTS:
        raise ParameterError(
            f"{n} trajectories x {periods} periods = {n * periods} points exceeds the limit {config.MAX_POINTS}"
        )
    points = np.empty((n, periods, 2))
    npts = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    start = time.perf_counter()
    done = 0
    nsteps = np.zeros(n, dtype=np.int64)
    k_first = direction * (transient + 1)

    def track_cancel() -> bool:
        return bool(cancel and cancel())

    stream = iter_section(
        params,
        ics,
        periods,
        transient=transient,
        numerics=numerics,
        direction=direction,
        chunk_periods=chunk_periods,
        first_chunk=max(1, chunk_periods or 16),
        cancel=track_cancel,
        workers=workers,
    )
    for chunk in stream:
        m = chunk.points.shape[1]
        points[:, done : done + m] = chunk.points
        # Trajectory i's points stay contiguous: it contributes only while alive.
        npts += chunk.npts
        status = chunk.status
        nsteps = chunk.nsteps
        done += m
        if progress is not None:
            progress(chunk)
    return Section(
        params=params,
        numerics=numerics,
        ics=ics,
        k_first=k_first,
        points=points,
        npts=npts,
        status=status,
        nsteps=nsteps,
        elapsed_s=time.perf_counter() - start,
        completed=done == periods or not np.any(status == Status.OK),
        periods=periods,
        transient=transient,
    )
