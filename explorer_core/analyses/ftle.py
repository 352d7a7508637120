"""Finite-time Lyapunov exponent (FTLE) maps: the largest exponent over ``n`` periods at every pixel of a grid.

The FTLE of a pixel's initial condition ``x`` is ``(1 / n T) log |DP^n(x)|`` (the growth of the most stretched
direction, per unit time as :mod:`explorer_core.analyses.lyapunov` reports it; times ``T`` per iteration). It is
measured exactly as the Lyapunov spectrum is: the engine's Lyapunov system (:func:`explorer_core.solve.tangent.
advance_lyapunov`: the tangent basis re-orthonormalised at every section time and inside a period when it becomes
ill-conditioned) accumulates ``log R_11`` over the ``n`` periods, so ``DP^n`` never overflows on chaos. One picture
shows the chaotic sea (large FTLE), the islands (FTLE near 0) and, forward and backward, the ridges that mark
the stable and unstable manifolds (transport barriers).

**Backward.** ``P^-1`` is computable here by integrating the field backwards in time (the section at
``t0 - k T``; the field is smooth and defined for every ``t``), so the backward map is the same run with a
negative period. Backward trajectories of a dissipative map leave attractors and may escape the bound: those
pixels are lost with their reason, as forward ones that escape or fail are: their value is missing (NaN in the
arrays, ``nan`` in the CSV, never a number that would average silently) and their status says why.

The pixels are tasks of an executor in tiles (:mod:`explorer_core.parallel.executor`: threads of this process by
default, both cores; a Dask cluster if one is passed), each tile's trajectories one batch of the engine, each
member with its own steps (lock-step blocks of 8 or 32 pixels took 2x and 3.4x as long on Fig. 8B's box: its
pixels differ too much in stiffness, those near the noncompact curve dictating the steps of the whole block).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.indicators import NUMERICS_ARG, spec_dict
from explorer_core.analyses.orbits import grid_seeds, pixel_centres
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.parallel.executor import Executor, local_executor
from explorer_core.progress import Progress, Step
from explorer_core.progress import run as run_updates
from explorer_core.solve import tangent
from explorer_core.solve.integrators import coefficients
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.options import Arg, choice, declare, integer, ints
from explorer_core.solve.options import box as box_check
from explorer_core.status import Status, count_names, status_names
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

DIRECTIONS = ("forward", "backward", "both")
#: Most pixels along either axis of an FTLE map.
MAX_GRID = 1024
#: Pixels of one task (a tile of the grid, one batch of the engine).
TILE_PIXELS = 64
_OK = int(Status.OK)


@dataclass(frozen=True)
class FtleSpec:
    """An FTLE map: the pixels' centres of ``box`` on an ``nx x ny`` ``grid``, ``periods`` periods, forward,
    backward or both (``direction``), with ``numerics``."""

    params: Params
    box: tuple[float, float, float, float]
    grid: tuple[int, int]
    periods: int
    direction: str
    numerics: Numerics

    @property
    def signs(self) -> tuple[int, ...]:
        return {"forward": (1,), "backward": (-1,), "both": (1, -1)}[self.direction]

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """The pixels' centres: ``q`` (nx,), ``r`` (ny,)."""
        return pixel_centres(self.box, *self.grid)

    def ics(self) -> np.ndarray:
        """(ny * nx, 2) initial conditions, row-major (row ``j`` at ``r[j]``)."""
        return grid_seeds(self.box, *self.grid)

    def as_dict(self) -> dict[str, Any]:
        return spec_dict(self)


@declare(
    box=Arg("the grid's box", "box", scene="box", positional=True, check=box_check()),
    grid=Arg("pixels", "ints", metavar="NX,NY", default=(64, 64), check=ints(2, 1, MAX_GRID, "NX,NY")),
    periods=Arg("periods of each pixel's exponent", "int", default=50, check=integer(1, config.MAX_PERIODS)),
    direction=Arg("forward (P), backward (P^-1, integrating back in time) or both", "str", choices=DIRECTIONS,
                  default="forward", check=choice(DIRECTIONS)),
    numerics=NUMERICS_ARG,
)  # fmt: skip
def ftle_spec(
    params: Params,
    box: tuple[float, float, float, float],
    *,
    grid: tuple[int, int],
    periods: int,
    direction: str,
    numerics: Numerics,
) -> FtleSpec:
    """A validated :class:`FtleSpec` (a bad value raises ParameterError naming it; ``exc.option`` its keyword)."""
    with Checking() as at:
        at("periods")
        pixels = int(grid[0]) * int(grid[1])
        if pixels * periods > 100 * config.MAX_POINTS:
            raise ParameterError(f"{pixels} pixels x {periods} periods exceeds the limit {100 * config.MAX_POINTS}")
    return FtleSpec(params, tuple(box), (int(grid[0]), int(grid[1])), periods, direction, numerics)  # type: ignore[arg-type]


def ftle_tile(params: Params, numerics: Numerics, ics: np.ndarray, periods: int, sign: int) -> tuple[np.ndarray, ...]:
    """One task: the FTLE per unit time of every row of ``ics`` over ``periods`` periods of ``P`` (``sign = 1``)
    or ``P^-1`` (``-1``), its status and the periods done. A member that failed has no FTLE (NaN; its status
    says why)."""
    batch = tangent.start(ics, params.t0, sign * params.period)
    logs, _, _, npts = tangent.advance_lyapunov(coefficients(Model(params), n=ics.shape[0]), batch, periods,
                                                numerics, workers=1)  # fmt: skip
    done = (batch.status == _OK) & (npts == periods)
    ftle = np.full(ics.shape[0], np.nan)
    # only the members that ran every period: a failed member's records past its failure are not data
    ftle[done] = logs[done, :, 0].sum(axis=1) / (periods * params.period)
    return ftle, batch.status.copy(), npts


@dataclass(frozen=True)
class FtleMap(Drawable):
    """An FTLE map of a :class:`FtleSpec`.

    ``q`` (nx,), ``r`` (ny,): the pixels' centres; ``forward``, ``backward`` (ny, nx): FTLE per unit time (None
    when not asked; NaN where the pixel has none: failed, escaped, not computed); ``status_forward``,
    ``status_backward`` (ny, nx): :class:`~explorer_core.status.Status` codes (``not_run``: not computed, the run
    was cancelled)."""

    spec: FtleSpec
    q: np.ndarray
    r: np.ndarray
    forward: np.ndarray | None
    backward: np.ndarray | None
    status_forward: np.ndarray | None
    status_backward: np.ndarray | None
    elapsed_s: float
    completed: bool = True

    def maps(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """``(direction, ftle, status)`` of each direction computed."""
        both = (("forward", self.forward, self.status_forward), ("backward", self.backward, self.status_backward))
        return [(d, v, s) for d, v, s in both if v is not None]

    @property
    def status(self) -> np.ndarray:
        return np.concatenate([s.ravel() for _, _, s in self.maps()])

    @property
    def lost(self) -> list[Loss]:
        out = []
        for d, _, s in self.maps():
            for code in np.unique(s[s != _OK]):
                st = Status(int(code))
                why = ("cancelled before it was computed" if st == Status.NOT_RUN
                       else f"{st.label} within the periods ({st.meaning}): no exponent")  # fmt: skip
                out.append(Loss(f"pixels ({d})", int(np.count_nonzero(s == code)), why))
        return out

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {"units": f"per unit time (x T = {self.spec.params.period:.12g} per iteration)"}
        for d, v, s in self.maps():
            ok = s == _OK
            out[d] = {"statuses": count_names(s), "min": float(v[ok].min()) if ok.any() else None,
                      "max": float(v[ok].max()) if ok.any() else None,
                      "mean": float(v[ok].mean()) if ok.any() else None}  # fmt: skip
        return {**out, "elapsed_s": round(self.elapsed_s, 6), "completed": self.completed, "complete": self.complete,
                "lost": [loss.as_dict() for loss in self.lost], "spec": self.spec.as_dict()}  # fmt: skip

    def report(self) -> list[str]:
        lines = []
        for d, stats in ((d, self.summary()[d]) for d, _, _ in self.maps()):
            if stats["mean"] is None:
                lines.append(f"{d}: no pixel computed")
            else:
                lines.append(f"{d}: FTLE in [{stats['min']:.4g}, {stats['max']:.4g}], mean {stats['mean']:.4g} "
                             f"per unit time; {stats['statuses']}")  # fmt: skip
        return [*lines, f"{self.elapsed_s:.2f} s"]

    def rows(self) -> Iterator[tuple]:
        maps = self.maps()
        for j, r in enumerate(self.r):
            for i, q in enumerate(self.q):
                row: list[Any] = [float(q), float(r)]
                for _, v, s in maps:
                    row += [float(v[j, i]), Status(int(s[j, i])).label]
                yield tuple(row)

    def write(self, path: str) -> dict[str, Any]:
        """``.npz``: ``q``, ``r``, ``forward``/``backward`` (ny, nx), their status codes with ``status_names``, and
        ``summary`` (JSON text); ``.csv``: one row per pixel; ``.json``: the summary."""
        header = ["q", "r"] + [f"{k}_{d}" for d, _, _ in self.maps() for k in ("ftle", "status")]

        def npz(p: str) -> None:
            arrays = {d: v for d, v, _ in self.maps()} | {f"status_{d}": s for d, _, s in self.maps()}
            export.write_npz(p, q=self.q, r=self.r, **arrays, status_names=status_names(),
                             summary=export.dumps(self.summary()))  # fmt: skip

        csv_ = lambda p: export.write_csv(p, header, self.rows(), export.partial(self))  # noqa: E731
        return export.write_by_suffix(path, {".npz": npz, ".csv": csv_,
                                             ".json": lambda p: export.write_json(p, self.summary())},
                                      "FTLE map")  # fmt: skip


def _tiles(n: int) -> list[slice]:
    return [slice(a, min(a + TILE_PIXELS, n)) for a in range(0, n, TILE_PIXELS)]


def iter_ftle(
    spec: FtleSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[FtleMap]]:
    """Stream an FTLE map tile by tile (every direction asked; tiles as tasks of ``executor``, default this
    process's threads); each update carries the live map, the last one the final map."""
    spec = spec_of(FtleSpec, ftle_spec, spec, args, kw)
    start = time.perf_counter()
    q, r = spec.axes()
    ics = spec.ics()
    shape = (spec.grid[1], spec.grid[0])
    values = {s: np.full(ics.shape[0], np.nan) for s in spec.signs}
    codes = {s: np.full(ics.shape[0], int(Status.NOT_RUN), dtype=np.int64) for s in spec.signs}
    tiles = _tiles(ics.shape[0])
    todo = deque(((s, t), ftle_tile, (spec.params, spec.numerics, ics[t], spec.periods, s))
                 for s in spec.signs for t in tiles)  # fmt: skip
    total, done = len(todo), 0
    ex = local_executor(executor, workers)

    def live(completed: bool) -> FtleMap:
        def grid(d: dict[int, np.ndarray], s: int) -> np.ndarray | None:
            return d[s].reshape(shape).copy() if s in d else None

        return FtleMap(spec, q, r, grid(values, 1), grid(values, -1), grid(codes, 1), grid(codes, -1),
                       time.perf_counter() - start, completed)  # fmt: skip

    for batch in ex.stream(todo, cancel):
        for (s, t), (ftle, status, _) in batch:
            values[s][t], codes[s][t] = ftle, status
            done += 1
        yield Step(Progress(done, total, "tiles", time.perf_counter() - start), result=live(False))
    res = live(done == total)
    yield Step(Progress(total if res.completed else done, total, "tiles", res.elapsed_s), result=res)


def ftle_map(
    spec: FtleSpec | Params,
    *args: Any,
    progress: Callable[[Any], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
    workers: int | None = None,
    **kw: Any,
) -> FtleMap:
    """The FTLE map of :func:`iter_ftle`'s last update."""
    return run_updates(iter_ftle(spec, *args, cancel=cancel, executor=executor, workers=workers, **kw), progress)
