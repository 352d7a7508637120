"""Sections of millions of points as a density image of the view: the points are binned, never kept.

A section of 10^6-10^7 points is more than a browser can draw point by point and more than a server
should hold (16 bytes a point). What a picture of it needs is how many points fall in each pixel of
the view: :func:`iter_density` streams the section (:func:`explorer_core.solve.section.iter_section`,
the one engine, both cores) and adds every chunk into a ``(pixels_r, pixels_q)`` count image with one
``bincount``, so the memory is the image and one chunk, whatever the number of points.

Accuracy: a density image shows *where* points fall, not *when*. On a regular orbit the integration
error is a phase drift along the invariant curve (a point moves along the curve, not off it), and on a
chaotic attractor pointwise error grows anyway (the picture is right in the shadowing sense). So the
tolerance keeps every point within a quarter pixel of its exact orbit over a window of
:data:`DENSITY_WINDOW` periods (:func:`density_numerics`), not over the whole run as the point view's
"plot" tolerance does; ``tests/test_density.py`` checks the images against a 1e-12 integration.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.sections import PERIODS_ARG, SEED_ARG, TRANSIENT_ARG
from explorer_core.analyses.specs import Checking
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress
from explorer_core.progress import run as run_updates
from explorer_core.scenes import plot_tolerance
from explorer_core.solve.numerics import Numerics, check_box, check_ics, check_int, random_ics
from explorer_core.solve.options import Arg, declare, ics, ints, optional_of
from explorer_core.solve.options import box as box_check
from explorer_core.solve.section import iter_section
from explorer_core.status import Status, count_names
from explorer_core.system.params import ParameterError, Params

#: Periods over which a density point stays within a quarter pixel of its exact orbit.
DENSITY_WINDOW = 100
#: Most points one density image may ask for (the per-session bound of the point view is far lower).
MAX_DENSITY_POINTS = 10_000_000
#: Most pixels of a density image along either axis.
MAX_PIXELS = 4096


@dataclass(frozen=True)
class Density(Drawable):
    """Counts of section points per pixel of ``view`` after ``done_periods`` of ``total_periods``.

    ``counts`` (pixels_r, pixels_q) int64, row 0 at ``r0`` (the bottom of the view), column 0 at ``q0``;
    ``points``: every section point computed; ``in_view``: those counted; ``status`` (n,) per trajectory
    (:class:`~explorer_core.solve.rk.Status`).
    """

    counts: np.ndarray
    view: Sequence[float]
    points: int
    in_view: int
    done_periods: int
    total_periods: int
    status: np.ndarray
    elapsed_s: float
    completed: bool
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def progress(self) -> Progress:
        # a completed image has nothing left to compute, even if every trajectory escaped early
        done = self.total_periods if self.completed else self.done_periods
        return Progress(done, self.total_periods, "periods", self.elapsed_s)

    def write(self, path: str, summary: dict[str, Any] | None = None) -> dict[str, Any]:
        """``.npz``: ``counts``, ``q_edges``, ``r_edges`` and ``summary`` (JSON text; default :meth:`summary`);
        ``.json``: the summary."""
        summary = self.summary() if summary is None else summary
        (q0, q1, r0, r1), (ny, nx) = self.view, self.counts.shape
        edges = {"q_edges": np.linspace(q0, q1, nx + 1), "r_edges": np.linspace(r0, r1, ny + 1)}

        def npz(p: str) -> None:
            export.write_npz(p, counts=self.counts, **edges, summary=export.dumps(summary))

        return export.write_by_suffix(path, {".npz": npz, ".json": lambda p: export.write_json(p, summary)}, "density")

    @property
    def escaped(self) -> int:
        return int(np.count_nonzero(self.status == Status.ESCAPED))

    @property
    def lost(self) -> list[Loss]:
        """Periods not computed (cancelled), trajectories that escaped or failed (their later points)."""
        out = []
        if self.completed is False and self.done_periods < self.total_periods:
            out.append(Loss("periods not computed", self.total_periods - self.done_periods, "cancelled"))
        if self.escaped:
            out.append(Loss("trajectories", self.escaped, "escaped: no points after the escape"))
        if self.failed:
            out.append(Loss("trajectories", self.failed, "the integration failed: no points after the failure"))
        return out

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    @property
    def failed(self) -> int:
        return int(np.count_nonzero((self.status != Status.OK) & (self.status != Status.ESCAPED)))

    def report(self) -> list[str]:
        return [f"{self.points:,} points, {self.in_view:,} in view, {self.escaped} escaped, {self.failed} failed, "
                f"{self.elapsed_s:.2f} s"]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        return {"view": list(self.view), "pixels": [int(self.counts.shape[1]), int(self.counts.shape[0])],
                "points": self.points, "in_view": self.in_view, "done_periods": self.done_periods,
                "total_periods": self.total_periods, "trajectories": int(self.status.size), "escaped": self.escaped,
                "failed": self.failed, "statuses": count_names(self.status), "completed": self.completed,
                "complete": self.complete, "lost": [loss.as_dict() for loss in self.lost],
                "elapsed_s": round(self.elapsed_s, 6), **self.extra}  # fmt: skip


class DensityUpdate(NamedTuple):
    """Yielded by :func:`iter_density`: the image so far and the kept trajectories' points of this chunk
    (unpacks as ``image, kept``); the last update's ``result`` is the final image."""

    density: Density
    kept: dict[int, np.ndarray]

    @property
    def progress(self) -> Progress:
        return self.density.progress

    @property
    def result(self) -> Density:
        return self.density


def check_pixels(pixels: Sequence[int]) -> list[int]:
    """An image's size ``(pixels_q, pixels_r)``, each a whole number in ``[1, MAX_PIXELS]``."""
    return [check_int(name, v, 1, MAX_PIXELS) for name, v in zip(("pixels (q)", "pixels (r)"), pixels, strict=True)]


def density_numerics(view: Sequence[float], pixels: Sequence[int], bound: float, method: str = "dop853") -> Numerics:
    """DOP853 keeping each point within a quarter pixel of the view over :data:`DENSITY_WINDOW` periods."""
    q0, q1, r0, r1 = check_box(view, "view")
    px = check_pixels(pixels)
    pixel = min((q1 - q0) / px[0], (r1 - r0) / px[1])
    tol = plot_tolerance(pixel, DENSITY_WINDOW)
    return Numerics(method=method, rtol=tol, atol=tol, bound=bound)


def accumulate(counts: np.ndarray, q: np.ndarray, r: np.ndarray, view: Sequence[float]) -> int:
    """Add points ``(q, r)`` to ``counts`` (pixels_r, pixels_q) over ``view``; return how many fell inside."""
    ny, nx = counts.shape
    q0, q1, r0, r1 = view
    i = np.floor((q - q0) * (nx / (q1 - q0)))
    j = np.floor((r - r0) * (ny / (r1 - r0)))
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    flat = j[inside].astype(np.int64) * nx + i[inside].astype(np.int64)
    if flat.size:
        counts += np.bincount(flat, minlength=nx * ny).reshape(ny, nx)
    return int(flat.size)


def iter_density(
    params: Params,
    ics: Any,
    periods: int,
    *,
    view: Sequence[float],
    pixels: Sequence[int] = (800, 600),
    transient: int = 0,
    numerics: Numerics | None = None,
    keep: Sequence[int] = (),
    max_chunk: int = 64,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Iterator[DensityUpdate]:
    """Stream the density image of a section over ``view``: one update per chunk of periods.

    Parameters
    ----------
    ics : (n, 2) initial conditions at ``t0``; ``periods`` section points each after ``transient``.
    view, pixels : the window ``(q0, q1, r0, r1)`` and the image's size ``(pixels_q, pixels_r)``.
    numerics : default :func:`density_numerics` for the view.
    keep : trajectories whose points are also returned (e.g. the ones a user clicked or selected).
    max_chunk : longest chunk of periods (bounds how long a cancel waits; chunks grow 1, 2, 4, ... up to it).

    Yields
    ------
    DensityUpdate (Density, kept) : the image so far (the same array, updated in place: copy it to keep a snapshot) and,
        for each trajectory in ``keep``, its section points of this chunk as ``(k, q, r)`` rows.
    """
    start = time.perf_counter()
    ics = check_ics(ics)
    periods = check_int("periods", periods, 1, config.MAX_PERIODS)
    transient = check_int("transient", transient, 0, config.MAX_PERIODS)
    box = check_box(view, "view")
    px = check_pixels(pixels)
    if ics.shape[0] * periods > MAX_DENSITY_POINTS:
        raise ParameterError(f"{ics.shape[0]} trajectories x {periods} periods = {ics.shape[0] * periods} points; "
                             f"a density image takes at most {MAX_DENSITY_POINTS}")  # fmt: skip
    keep = [int(i) for i in keep if 0 <= int(i) < ics.shape[0]]
    numerics = numerics or density_numerics(box, px, config.DEFAULT_ESCAPE_BOUND)
    counts = np.zeros((px[1], px[0]), dtype=np.int64)
    extra = {"rtol": numerics.rtol}
    total = inside = 0
    status = np.zeros(ics.shape[0], dtype=np.int64)
    done = 0
    for chunk in iter_section(params, ics, periods, transient=transient, numerics=numerics, max_chunk=max_chunk,
                              cancel=cancel, workers=workers):  # fmt: skip
        valid = np.arange(chunk.points.shape[1])[None, :] < chunk.npts[:, None]
        q, r = chunk.points[..., 0][valid], chunk.points[..., 1][valid]
        total += q.size
        inside += accumulate(counts, q, r, box)
        kept = {}
        for i in keep:
            m = int(chunk.npts[i])
            ks = chunk.k_first + np.arange(m)
            kept[i] = np.column_stack([ks, chunk.points[i, :m]])
        status = chunk.status
        done = chunk.done_periods
        elapsed = time.perf_counter() - start
        yield DensityUpdate(Density(counts, box, total, inside, done, periods, status, elapsed, False, extra), kept)
    completed = not (cancel is not None and cancel())
    elapsed = time.perf_counter() - start
    yield DensityUpdate(Density(counts, box, total, inside, done, periods, status, elapsed, completed, extra), {})


@dataclass(frozen=True)
class DensitySpec:
    """A density image to compute: ``random`` initial conditions uniform in ``box`` from ``seed``, ``periods``
    section points each after ``transient``, binned over ``view`` into ``pixels`` ``(W, H)``."""

    params: Params
    periods: int
    transient: int
    random: int
    seed: int
    box: tuple[float, float, float, float]
    view: tuple[float, float, float, float]
    pixels: tuple[int, int]
    numerics: Numerics
    #: Initial conditions given beside the random ones (after them).
    points: tuple[tuple[float, float], ...]

    @property
    def ics(self) -> np.ndarray:
        drawn = random_ics(self.random, self.box, seed=self.seed) if self.random else np.empty((0, 2))
        return np.concatenate([drawn, np.array(self.points, dtype=float).reshape(-1, 2)])

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "numerics": self.numerics.as_dict(),
                "ics": {"random": self.random, "box": list(self.box), "seed": self.seed,
                        "points": [list(p) for p in self.points]},
                "transient": self.transient, "view": list(self.view), "pixels": list(self.pixels)}  # fmt: skip


@declare(
    periods=PERIODS_ARG,
    random=Arg("random initial conditions in --box", "int", metavar="N", default=1000, checked_with=("ics",)),
    ics=Arg(
        "initial condition beside the random ones (repeatable)",
        "points",
        flag="--ic",
        default=None,
        check=ics(optional=True),
    ),
    seed=SEED_ARG,
    box=Arg("box of the initial conditions", "box", scene="box", positional=True, check=box_check()),
    transient=TRANSIENT_ARG,
    view=Arg("the image's window (default: --box)", "box", scene="view", default=None, check=box_check(optional=True)),
    pixels=Arg("the image's size", "ints", metavar="W,H", default=(800, 600), check=ints(2, 1, MAX_PIXELS, "W,H")),
    bound=Arg("", scene="bound", flag="", default=None, checked_with=("numerics",)),
    numerics=Arg("default: for the view's pixels", cli=False, default=None, check=optional_of(Numerics)),
)
def density_spec(
    params: Params,
    periods: int,
    box: tuple[float, float, float, float],
    *,
    random: int,
    seed: int,
    ics: np.ndarray | None,
    transient: int,
    view: tuple[float, float, float, float] | None,
    pixels: tuple[int, int],
    bound: float | None,
    numerics: Numerics | None,
) -> DensitySpec:
    """A validated :class:`DensitySpec` (a bad value raises ParameterError naming it, ``exc.option``: its keyword).
    ``random`` may be 0 beside given ``ics``. ``numerics`` default: :func:`density_numerics` for the view, escaping
    at ``bound`` (default the project's escape bound). The options are declared above: defaults, checks (run before
    this body), flags."""
    with Checking() as at:
        points = () if ics is None else tuple((float(q), float(r)) for q, r in ics)
        at("random")
        random = check_int("random", random, 0 if points else 1, config.MAX_TRAJECTORIES)
        n = random + len(points)
        if n * periods > MAX_DENSITY_POINTS:
            raise ParameterError(f"{n} initial conditions x {periods} periods = {n * periods} points; "
                                 f"a density image takes at most {MAX_DENSITY_POINTS}")  # fmt: skip
        view = box if view is None else view
        at("numerics")
        bound = config.DEFAULT_ESCAPE_BOUND if bound is None else float(bound)
        if numerics is None:
            numerics = density_numerics(view, pixels, bound)
    return DensitySpec(params, periods, transient, random, seed, box, view, pixels, numerics, points)  # type: ignore[arg-type]


def density(
    first: DensitySpec | Params,
    *args: Any,
    progress: Callable[[DensityUpdate], None] | None = None,
    **kw: Any,
) -> Density:
    """The final image of :func:`iter_density` (same arguments), or of a :class:`DensitySpec` (its record in
    the image's summary); ``progress`` gets each of its updates."""
    if not isinstance(first, DensitySpec):
        return run_updates(iter_density(first, *args, **kw), progress)
    spec = first
    run = {k: kw.pop(k) for k in ("cancel", "workers") if k in kw}
    if args or kw:
        raise TypeError(f"a DensitySpec comes alone, not with {', '.join(map(repr, args)) or ', '.join(kw)}")
    updates = iter_density(spec.params, spec.ics, spec.periods, view=spec.view, pixels=spec.pixels,
                           transient=spec.transient, numerics=spec.numerics, **run)  # fmt: skip
    img = run_updates(updates, progress)
    return replace(img, extra={**img.extra, **spec.as_dict()})
