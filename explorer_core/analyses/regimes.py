"""Charts of dynamical regimes on a plane of two parameters (paper, Fig. 11).

Every pixel ``(x_i, y_j)`` of the parameter plane is classified from the
trajectory of one or more initial conditions: after a transient, ``periods``
section points are computed together with the largest Lyapunov exponent
(:mod:`explorer_core.analyses.lyapunov`'s kernel) and the regime is

* ``periodic`` with period ``p`` (``1 <= p <= p_max``): the section point
  returns to itself after ``p`` iterations within ``tol`` over the last part of
  the measurement -- a stable cycle;
* ``chaotic``: no period and largest exponent ``> lyap_threshold`` (per unit time) -- or, decided early, two
  deviation vectors that align while stretching (SALI, ``chaos_test="sali"``, the default; see :func:`compute_tile`);
* ``quasi-periodic``: no period and largest exponent ``<= lyap_threshold``
  (an invariant curve, or a cycle longer than ``p_max``);
* ``escaped``: the trajectory left the bound (noncompact motion);
* ``failed``: any other integration failure; ``invalid``: the parameters do not
  define a system (e.g. a tensor that is not positive definite).

Why a pixel has no regime is its :class:`~explorer_core.status.Status` (``Chart.status``, the one
vocabulary, beside the regime codes): ``ok`` for a classified pixel, ``escaped``, the engine failure
that ended it (``step_collapsed``, ``too_many_steps``, ``nonfinite``), ``cancelled`` (the measurement
stopped short), ``invalid`` (refused parameters) and ``not_run`` (not computed).

The work is organised in **tiles**: :func:`compute_tile` is a pure function of
a :class:`ChartSpec` and a :class:`TileSpec` (both plain picklable data), so a
task scheduler can run tiles anywhere. :func:`plan_tiles` orders them
progressively -- every ``coarse``-th pixel first, then each finer level -- and
:func:`iter_chart` streams partial charts (with :meth:`Chart.filled` showing a
coarse picture at once) while both cores work. Members stop as soon as their regime
is decided (:func:`compute_tile`); :func:`compute_tile_each` is the reference that runs
every member the whole way. With ``refine=True`` the finer levels are computed only
where the coarser one is not uniform (:func:`refine_level`) and the other pixels are
filled (``Chart.inferred``).

Files (NPZ and CSV) hold what was not measured as missing, never as a number that averages: ``period`` is
NaN (``nan`` in CSV) unless the regime is periodic, ``lyap`` NaN for a pixel that escaped, failed, is
invalid, was not computed or was filled from its neighbours (:meth:`Chart.measured`). Until issue 35 they
held ``period = 0`` and ``lyap = 0.0`` there.
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.specs import Checking
from explorer_core.analyses.sweeps import check_param, params_at, sweep_values
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.parallel.executor import Executor, LocalExecutor, local_executor
from explorer_core.progress import Progress
from explorer_core.progress import run as run_updates
from explorer_core.solve import tangent
from explorer_core.solve.checks import check_range
from explorer_core.solve.integrators import coefficients, lockstep_groups
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.options import (
    BOOL,
    SETTLING,
    Arg,
    Check,
    NewtonOptions,
    choice,
    declare,
    fraction,
    ics,
    instance,
    integer,
    number,
    optional_of,
)
from explorer_core.solve.poincare import PoincareMap, newton
from explorer_core.solve.recurrence import CHART, NEAR, recurrence
from explorer_core.solve.rk import Coefficients
from explorer_core.status import Status, count_names, status_names
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

#: Regime codes of :attr:`Chart.regime` (the classification; pinned charts keep them). Codes 0 and 4-6 are
#: "no regime": the reason is the pixel's :class:`~explorer_core.status.Status` in :attr:`Chart.status`
#: (NOT_COMPUTED: ``not_run``; ESCAPED: ``escaped``; FAILED: the engine failure, or ``cancelled``;
#: INVALID: ``invalid``).
NOT_COMPUTED, PERIODIC, QUASI_PERIODIC, CHAOTIC, ESCAPED, FAILED, INVALID = range(7)
REGIMES = ("not_computed", "periodic", "quasi_periodic", "chaotic", "escaped", "failed", "invalid")
#: Defaults: charts need the regime, not 1e-10 accuracy; cycles attract integration errors anyway.
DEFAULT_CHART_TOL = 1e-8
#: Early chaos tests of :attr:`ChartSpec.chaos_test` (:func:`compute_tile`).
CHAOS_TESTS = ("sali", "lyapunov")
#: The chart's default, which ``reproduce`` shares (its Lyapunov stage and its chart).
DEFAULT_CHAOS_TEST = "sali"


def classify(
    points: np.ndarray, npts: int, status: int, lyap: float, *, p_max: int, tol: float, lyap_threshold: float
) -> tuple[int, int]:
    """Regime and period of one trajectory.

    Parameters
    ----------
    points : (m, 2) section points after the transient; the first ``npts`` are valid.
    status : integration status (:class:`~explorer_core.solve.integrators.Status`).
    lyap : largest Lyapunov exponent over the measurement (per unit time).
    p_max, tol : cycles up to period ``p_max`` are detected over the second half of the
        points, with tolerance ``tol * (1 + max |x|)`` (:data:`~explorer_core.solve.recurrence.CHART`).
    lyap_threshold : exponents above it are chaos.

    Returns
    -------
    (regime, period) with ``period = 0`` unless the regime is periodic.
    """
    if status == Status.ESCAPED:
        return ESCAPED, 0
    if status != Status.OK or npts < points.shape[0]:
        return FAILED, 0
    tail = points[max(0, points.shape[0] // 2 - 1) :]
    if tail.shape[0] > p_max:
        p = int(recurrence(tail, CHART, tol=tol, p_max=p_max).period)
        if p:
            return PERIODIC, p
    return (CHAOTIC if lyap > lyap_threshold else QUASI_PERIODIC), 0


@dataclass(frozen=True)
class ChartSpec:
    """Everything that defines a chart (plain data: picklable, hashable by value of its JSON)."""

    params: Params
    x_param: str
    x_values: np.ndarray
    y_param: str
    y_values: np.ndarray
    ics: np.ndarray
    transient: int
    periods: int
    p_max: int
    tol: float
    lyap_threshold: float
    numerics: Numerics
    #: Newton on a member's settled cycle (:func:`settled_cycles`).
    newton: NewtonOptions
    #: How a member with no cycle is called chaotic early (:data:`CHAOS_TESTS`; :func:`compute_tile`).
    chaos_test: str

    @property
    def shape(self) -> tuple[int, int]:
        """``(ny, nx)``: rows are ``y`` values, columns ``x`` values."""
        return self.y_values.size, self.x_values.size

    def pixel_params(self, j: int, i: int) -> Params | str:
        """Parameters at pixel ``(y_j, x_i)``, or why they are invalid."""
        p = params_at(self.params, self.x_param, float(self.x_values[i]))
        if isinstance(p, str):
            return p
        return params_at(p, self.y_param, float(self.y_values[j]))

    def as_dict(self) -> dict[str, Any]:
        return {
            "params": self.params.as_dict(),
            "x_param": self.x_param,
            "x_range": [float(self.x_values[0]), float(self.x_values[-1])],
            "y_param": self.y_param,
            "y_range": [float(self.y_values[0]), float(self.y_values[-1])],
            "grid": [int(self.x_values.size), int(self.y_values.size)],
            "ics": self.ics.tolist(),
            "transient": self.transient,
            "periods": self.periods,
            "p_max": self.p_max,
            "tol": self.tol,
            "lyap_threshold": self.lyap_threshold,
            "numerics": self.numerics.as_dict(),
            "newton": self.newton.as_dict(),
            "newton_numerics": self.newton.at(self.numerics, DEFAULT_CHART_TOL)[0].as_dict(),
            "chaos_test": self.chaos_test,
        }


#: A chart's default numerics: DOP853 at DEFAULT_CHART_TOL (the "auto" rule).
CHART_NUMERICS = Numerics(rtol=DEFAULT_CHART_TOL, atol=DEFAULT_CHART_TOL)


def chart_numerics() -> Numerics:
    """A chart's default numerics: :data:`CHART_NUMERICS` (DOP853 at DEFAULT_CHART_TOL, the "auto" rule)."""
    return CHART_NUMERICS


#: A sweepable parameter, canonical (``Omega`` is ``omega``); the message is :func:`check_param`'s.
SWEEP_PARAM = Check(lambda n, v: check_param(v), "alpha, I11..I23, g0, g1, g2 or omega", "str")
#: A parameter's range ``lo < hi``, refused as "range" (:func:`sweep_values`' message).
_SWEEP_RANGE = Check(lambda n, v: check_range("range", v), "two numbers lo < hi", "str")


def _grid(name: str, grid: Any) -> tuple[int, int]:
    """``(nx, ny)``: two whole numbers in ``[1, MAX_GRID]`` (``int()`` of each, as charts have always taken)."""
    try:
        nx, ny = (int(v) for v in grid)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be two integers NX,NY, got {grid!r}") from None
    if not (1 <= nx <= config.MAX_GRID and 1 <= ny <= config.MAX_GRID):
        raise ParameterError(f"{name} must be between 1 and {config.MAX_GRID} per axis, got {grid!r}")
    return nx, ny


@declare(
    x_param=Arg("the x parameter", "str", required=True, positional=True, check=SWEEP_PARAM),
    x_range=Arg("the x parameter's range", "range", metavar="A,B", required=True, positional=True, check=_SWEEP_RANGE),
    y_param=Arg("the y parameter", "str", required=True, positional=True, check=SWEEP_PARAM),
    y_range=Arg("the y parameter's range", "range", metavar="C,D", required=True, positional=True, check=_SWEEP_RANGE),
    grid=Arg(
        "pixels",
        "ints",
        metavar="NX,NY",
        positional=True,
        default=(40, 40),
        check=Check(_grid, f"2 integers NX,NY in [1, {config.MAX_GRID}]", "str"),
    ),
    ics=Arg(
        "initial condition at every pixel (repeatable)",
        "points",
        flag="--ic",
        scene="points",
        default=((0.1, 0.1),),
        check=ics(),
    ),
    transient=Arg("periods dropped first", "int", default=500, check=integer(0, config.MAX_PERIODS)),
    periods=Arg("measured periods", "int", default=500, check=integer(4, 10**6)),
    p_max=Arg("longest cycle detected", "int", default=16, checked_with=("periods",)),
    tol=Arg("return tolerance (relative to 1 + |x|)", default=1e-5, check=fraction()),
    lyap_threshold=Arg("chaos above this exponent (per unit time)", default=5e-3, check=number()),
    numerics=Arg(
        "the chart's integration", cli=False, default=CHART_NUMERICS, check=optional_of(Numerics, CHART_NUMERICS)
    ),
    newton=Arg("Newton on a member's settled cycle", cli=False, default=SETTLING, check=instance(NewtonOptions)),
    chaos_test=Arg("early chaos test: sali (alignment of two tangent vectors) or lyapunov (a bound on the exponent)",
                   "str", default=DEFAULT_CHAOS_TEST, check=choice(CHAOS_TESTS)),
)  # fmt: skip
def chart_spec(
    params: Params,
    x_param: str,
    x_range: tuple[float, float],
    y_param: str,
    y_range: tuple[float, float],
    grid: tuple[int, int],
    *,
    ics: np.ndarray,
    transient: int,
    periods: int,
    p_max: int,
    tol: float,
    lyap_threshold: float,
    numerics: Numerics,
    newton: NewtonOptions,
    chaos_test: str,
) -> ChartSpec:
    """Validated :class:`ChartSpec` over ``x_range x y_range`` with ``grid = (nx, ny)`` pixels (default 40 x 40).

    Pixel centres include both ends of each range. ``ics`` are used at every pixel
    (several: multistability is seen per pixel). ``numerics``: default :data:`CHART_NUMERICS`. ``newton``: Newton
    on a member's settled cycle (its map follows ``numerics``' tolerance:
    :meth:`~explorer_core.solve.options.NewtonOptions.at`). ``chaos_test``: ``"sali"`` (default) lets the alignment
    index call a member chaotic from :data:`SALI_START` periods on, ``"lyapunov"`` only the bound on its exponent
    (the chart as it was before issue 34). The options are declared above: defaults, checks (run before this
    body), flags.
    """
    nx, ny = grid
    with Checking() as at:
        at("y_param")
        if x_param == y_param:
            raise ParameterError(f"x and y parameters must differ, both are {x_param!r}")
        at("p_max")
        if isinstance(p_max, bool) or not isinstance(p_max, int | np.integer) or not 1 <= p_max < periods // 2:
            raise ParameterError(f"p_max must be an integer in [1, periods/2), got {p_max!r}")
    if nx * ny * ics.shape[0] * periods > 50 * config.MAX_POINTS:
        raise ParameterError(f"chart of {nx}x{ny} pixels x {ics.shape[0]} ICs x {periods} periods is too large")
    return ChartSpec(
        params=params,
        x_param=x_param,
        x_values=sweep_values(x_range, nx),
        y_param=y_param,
        y_values=sweep_values(y_range, ny),
        ics=ics,
        transient=transient,
        periods=periods,
        p_max=int(p_max),
        tol=tol,
        lyap_threshold=lyap_threshold,
        numerics=numerics,
        newton=newton,
        chaos_test=chaos_test,
    )


# ---------------------------------------------------------------------------
# Tiles.


@dataclass(frozen=True)
class TileSpec:
    """A block of pixels at one refinement level.

    The tile covers rows ``j0 <= j < j1`` and columns ``i0 <= i < i1`` and holds
    the pixels on the ``stride`` lattice (``i % stride == 0 == j % stride``) that
    no coarser level (``2 * stride`` lattice, up to ``coarsest``) has computed.
    """

    stride: int
    coarsest: int
    j0: int
    j1: int
    i0: int
    i1: int
    #: The pixels themselves, when a refinement chose them (then the block and lattice are not used).
    only: tuple[tuple[int, int], ...] = ()

    def pixels(self) -> list[tuple[int, int]]:
        """``(j, i)`` of the tile's pixels, row by row."""
        if self.only:
            return list(self.only)
        s = self.stride
        out = []
        for j in range(self.j0 + (-self.j0) % s, self.j1, s):
            for i in range(self.i0 + (-self.i0) % s, self.i1, s):
                if s < self.coarsest and j % (2 * s) == 0 and i % (2 * s) == 0:
                    continue  # done at a coarser level
                out.append((j, i))
        return out


def plan_tiles(shape: tuple[int, int], coarse: int = 8, tile_pixels: int = 64) -> list[TileSpec]:
    """Tiles covering every pixel of a ``(ny, nx)`` chart exactly once, coarse levels first.

    ``coarse`` (a power of two) is the stride of the first level; every level is
    split into blocks of about ``tile_pixels`` pixels.
    """
    ny, nx = shape
    if coarse < 1 or coarse & (coarse - 1):
        raise ParameterError(f"coarse must be a power of two, got {coarse!r}")
    if tile_pixels < 1:
        raise ParameterError(f"tile_pixels must be >= 1, got {tile_pixels!r}")
    tiles = []
    stride = coarse
    while stride >= 1:
        # Side in pixels of a block holding ~tile_pixels lattice points of this level.
        side = max(stride, round(float(np.sqrt(tile_pixels))) * stride)
        for j0 in range(0, ny, side):
            for i0 in range(0, nx, side):
                t = TileSpec(stride, coarse, j0, min(ny, j0 + side), i0, min(nx, i0 + side))
                if t.pixels():
                    tiles.append(t)
        stride //= 2
    # The last tiles in quarters: a core that finishes early waits for the other's last tile at most a quarter
    # as long (every member is computed alone, so tiles change nothing but the order).
    tail = []
    for t in tiles[-TAIL_TILES:]:
        jm, im = (t.j0 + t.j1 + 1) // 2, (t.i0 + t.i1 + 1) // 2
        quarters = [(t.j0, jm, t.i0, im), (t.j0, jm, im, t.i1), (jm, t.j1, t.i0, im), (jm, t.j1, im, t.i1)]
        tail += [q for q in (TileSpec(t.stride, t.coarsest, *b) for b in quarters) if q.pixels()]
    return tiles[: max(0, len(tiles) - TAIL_TILES)] + tail


#: Tiles at the end of :func:`plan_tiles` split in four.
TAIL_TILES = 4


def lattice(n: int, stride: int) -> np.ndarray:
    """Indices ``0, stride, 2 stride, ...`` of an axis of ``n`` pixels, and its last index ``n - 1``."""
    return np.unique(np.r_[np.arange(0, n, stride), n - 1])


def _bracket(coords: np.ndarray, v: int, ring: int) -> np.ndarray:
    """The entries of ``coords`` (sorted) that enclose ``v``, with ``ring`` more on each side."""
    a = int(np.searchsorted(coords, v, side="right")) - 1
    hi = a + 1 if coords[a] == v else a + 2
    return coords[max(0, a - ring) : min(coords.size, hi + ring)]


def refine_level(
    code: np.ndarray, shape: tuple[int, int], stride: int, ring: int = 1
) -> tuple[list[tuple[int, int]], list[tuple[int, int, int, int]]]:
    """Which pixels of the ``stride`` lattice to compute and which to fill from the ``2 stride`` lattice.

    ``code`` ``[j, i, ic]`` (:meth:`Chart.code`) is known on the ``2 stride`` lattice (:func:`lattice` of both
    axes). A new pixel is filled when every known pixel of its enclosing cell and of ``ring`` cells around
    it has the same code for every initial condition (a region of one regime and period); otherwise it is
    computed. Returns ``(compute [(j, i)], fill [(j, i, source j, source i)])``, the source being the
    nearest corner of the cell.
    """
    ny, nx = shape
    ys, xs = lattice(ny, stride), lattice(nx, stride)
    ys2, xs2 = lattice(ny, 2 * stride), lattice(nx, 2 * stride)
    old_y, old_x = np.isin(ys, ys2), np.isin(xs, xs2)
    compute, fill = [], []
    for a, j in enumerate(ys):
        rows = _bracket(ys2, int(j), ring)
        for b, i in enumerate(xs):
            if old_y[a] and old_x[b]:
                continue
            cols = _bracket(xs2, int(i), ring)
            block = code[np.ix_(rows, cols)].reshape(-1, code.shape[-1])
            if np.all(block == block[0]):
                sj = int(rows[np.argmin(np.abs(rows - j))])
                si = int(cols[np.argmin(np.abs(cols - i))])
                fill.append((int(j), int(i), sj, si))
            else:
                compute.append((int(j), int(i)))
    return compute, fill


@dataclass(frozen=True)
class TileResult:
    """Regimes of a tile's pixels; arrays are indexed ``[pixel, ic]`` in ``tile.pixels()`` order."""

    tile: TileSpec
    jj: np.ndarray
    ii: np.ndarray
    regime: np.ndarray
    period: np.ndarray
    lyap: np.ndarray
    status: np.ndarray
    errors: tuple[str, ...]
    elapsed_s: float
    #: Work done per member (load-independent, for profiles): periods integrated with the tangent system and
    #: the engine's steps (accepted + rejected) over them; Newton's work on settled cycles is not included.
    periods_run: np.ndarray | None = None
    steps: np.ndarray | None = None


def compute_tile(spec: ChartSpec, tile: TileSpec, stop: Callable[[], bool] | None = None) -> TileResult | None:
    """Classify every pixel of ``tile`` (a pure function of its arguments; single-threaded); None if ``stop``
    (polled at every look, every :data:`SETTLE_CHUNK` periods) returned True: a stopped tile computed nothing,
    as a tile never started (its pixels are not kept half done, so the others are exactly an uninterrupted
    chart's).

    Every pixel and initial condition runs with the tangent system on its own step sequence (lock-step
    blocks across pixels were measured slower: a block steps at its most demanding member's pace, and
    escaping or chaotic members multiplied the steps of the whole block ~8x). Every
    :data:`SETTLE_CHUNK` periods a member may stop early:

    * **on an attracting cycle**: once its section points return within :data:`SETTLE_TOL` after
      ``p <= p_max`` iterations :data:`SETTLE_POINTS` times in a row (the rule
      :data:`~explorer_core.solve.recurrence.NEAR`), and its
      ``log R_11`` over the last :data:`CONTRACT_SPAN` periods has a negative mean (it contracts: near a
      saddle, as a chaotic orbit's close returns are, it does not), it is handed to Newton
      (:func:`settled_cycles`: least period at the resolution ``tol``, multipliers) on ``P^d`` for the least
      divisor ``d`` of ``p`` whose returns are within :data:`SETTLE_DIVISOR` times that tolerance (a member
      spiralling onto a fixed point returns best after ``p`` iterations; Newton on ``P`` costs a ``p``-th),
      else on ``P^p``. If the cycle attracts (``max |mu| < 1``) and lies within that tolerance of the member,
      the member is periodic with that period and its exponent is the cycle's own, ``log max |mu| / (p T)``
      (which a finite-time average only approaches). A divisor that gave nothing is not tried again (the
      next look asks for ``P^p``); a ``P^p`` that gave nothing is tried again :data:`SETTLE_RETRY` periods
      later, or never again once the points return within ``tol`` (the whole run decides, as before);
    * **escaped**: ``|q|`` or ``|r|`` passed :data:`ESCAPE_BOUND` (or the integration's bound if smaller);
    * **chaotic** (looked at every :data:`CHAOS_BLOCK` periods, whatever :data:`SETTLE_CHUNK`): after
      :data:`CHAOS_MIN_PERIODS` measured periods with no return within ``tol``, if the mean per-period
      ``log R_11`` minus :data:`CHAOS_Z` standard errors (:func:`chaos_bound`) is above
      :data:`CHAOS_MARGIN` times the threshold; its exponent is the mean so far. A strongly chaotic member
      is decided from :data:`CHAOS_EARLY_PERIODS` periods on, in the transient, by a stricter bound over the
      second half of its periods so far (its exponent is their mean): above :data:`CHAOS_EARLY_MARGIN`
      times the threshold, or :data:`CHAOS_LATER_MARGIN` times from :data:`CHAOS_LATER_PERIODS` on. With
      ``spec.chaos_test == "sali"`` (the default) the SALI decides first, at :data:`SALI_START` periods, in at most
      :data:`SALI_PERIODS` more (its exponent: the mean ``log R_11`` over the second half of its periods so far).

    Every other member runs the whole transient and measurement and is classified exactly as
    :func:`compute_tile_each` does (to the last bit: chunked runs continue each step sequence
    unchanged). Differences from that reference (``benchmarks/chart_speed.py``,
    ``benchmarks/chart_work.py --reference``) are on regime boundaries: cycles the reference's finite tail
    had not converged on (Newton finds them; near a period doubling, the least period), and long chaotic
    transients that settle (or escape) after the chaos decision.
    """
    return _tile(spec, tile, _classify_members, stop)


class _Out(NamedTuple):
    """A tile's result arrays, ``[pixel, ic]``."""

    regime: np.ndarray
    period: np.ndarray
    lyap: np.ndarray
    status: np.ndarray
    periods_run: np.ndarray
    steps: np.ndarray


class _TileStopped(Exception):
    """A tile's ``stop`` returned True: it ends with nothing."""


def _tile(
    spec: ChartSpec, tile: TileSpec, fill: Callable[..., None], stop: Callable[[], bool] | None = None
) -> TileResult | None:
    """The tile's arrays; ``fill(spec, params, at, out)`` classifies its valid members into ``out`` (with
    ``stop=stop`` when given: None if it stopped)."""
    start = time.perf_counter()
    pix = tile.pixels()
    n_ic = spec.ics.shape[0]
    regime = np.zeros((len(pix), n_ic), dtype=np.int8)
    period = np.zeros((len(pix), n_ic), dtype=np.int16)
    lyap = np.zeros((len(pix), n_ic))
    status = np.zeros((len(pix), n_ic), dtype=np.int8)
    periods_run = np.zeros((len(pix), n_ic), dtype=np.int64)
    steps = np.zeros((len(pix), n_ic), dtype=np.int64)
    errors = []
    members: list[tuple[int, int]] = []
    member_params: list[Params] = []
    for n, (j, i) in enumerate(pix):
        p = spec.pixel_params(j, i)
        if isinstance(p, str):
            regime[n], status[n] = INVALID, Status.INVALID
            errors.append(p)
            continue
        errors.append("")
        members += [(n, k) for k in range(n_ic)]
        member_params += [p] * n_ic
    if members:
        at = np.array(members, dtype=np.int64)
        out = _Out(regime, period, lyap, status, periods_run, steps)
        try:
            fill(spec, member_params, at, out) if stop is None else fill(spec, member_params, at, out, stop=stop)
        except _TileStopped:
            return None
    jj = np.array([j for j, _ in pix], dtype=np.int64)
    ii = np.array([i for _, i in pix], dtype=np.int64)
    return TileResult(tile, jj, ii, regime, period, lyap, status, tuple(errors), time.perf_counter() - start,
                      periods_run, steps)  # fmt: skip


#: Periods between two looks for members that have settled on a cycle (each look is one engine call, and one
#: Newton for the members handed over; a Newton costs ~1 ms of Python whatever its points: looking every 5
#: periods stopped members 2.5 periods sooner but doubled the Newtons).
SETTLE_CHUNK = 10
#: A member whose section points return after ``p <= p_max`` iterations within SETTLE_TOL (relative, as
#: ``tol``) SETTLE_POINTS times in a row (its last ``p + SETTLE_POINTS`` points) is handed to Newton: the cycle
#: Newton finds decides, so the points need not have converged to ``tol`` yet. (Fig. 11 window, 40x40 x 2 ICs:
#: period-1 members hand over after 46 periods on average when the last ``p_max + 8`` points had to return
#: within 1e-2 for every ``p``, 24 now; 1e-1 handed over sooner still but changed 7 more members' periods.
#: 5 returns instead of 8: 2% fewer steps, the same verdicts on the 40x40 and 60x30 charts.)
SETTLE_TOL = NEAR.tol
SETTLE_POINTS = NEAR.pairs
#: Newton is asked for the cycle of the least divisor ``d`` of that ``p`` whose returns are within
#: SETTLE_DIVISOR times SETTLE_TOL: a member spiralling onto a fixed point with a rotation near ``1/p``
#: returns best after ``p`` iterations, yet the fixed point is Newton's on ``P`` at a ``p``-th of the cost
#: (``|P(x) - x| <= |1 - mu| |x - x*| <= 2 sqrt 2 |x - x*|`` in the max-norm near a fixed point of multipliers
#: ``|mu| <= 1``, and Newton's fixed point must lie within SETTLE_TOL of the member). If that gives no cycle,
#: the member's next look asks for ``P^p``. (Fig. 11 window: 1400 of 1600 period-1 cycles were found on
#: ``P^2 .. P^7`` before.)
SETTLE_DIVISOR = 3.0
#: A member is handed to Newton only if its ``log R_11`` over the last CONTRACT_SPAN periods has a negative mean:
#: a chaotic orbit's close returns pass near saddle cycles, on which Newton converges in vain (at SETTLE_TOL 3e-2
#: without this test, 1770 of 5364 hand-overs found a cycle that does not attract: 2/3 of Newton's steps).
CONTRACT_SPAN = 10
#: Periods to wait before a member that returned within SETTLE_TOL but gave no attracting cycle is tried again.
SETTLE_RETRY = 50
#: Charts stop a member once ``|q|`` or ``|r|`` passes this (and the integration's own bound): escaped. On the
#: Fig. 11 window no bounded orbit goes beyond 6.1 and every escaping one passes 100 within ~20 periods, then
#: spends ~95% of its steps on the way to 1e4 (steps grow with the speed of rotation).
ESCAPE_BOUND = 100.0
#: A member is decided chaotic once it has measured this many periods and the confidence bound below holds.
CHAOS_MIN_PERIODS = 100
#: Periods per block of the chaos bound (block means of ``log R_11`` are nearly independent on a chaotic
#: orbit); the chaos bounds are checked every CHAOS_BLOCK periods.
CHAOS_BLOCK = 10
#: Chaos bound: the mean of the per-period ``log R_11`` over blocks of CHAOS_BLOCK periods, minus CHAOS_Z
#: standard errors of that mean, above CHAOS_MARGIN times the threshold (per period).
CHAOS_Z = 4.0
CHAOS_MARGIN = 1.5
#: A strongly chaotic member is decided sooner, still in the transient: from CHAOS_EARLY_PERIODS periods on,
#: if the bound over the second half of its periods so far, with CHAOS_EARLY_Z standard errors, is above
#: CHAOS_EARLY_MARGIN times the threshold. (Measured on the Fig. 11 window, 60x30 x 2 ICs: chaotic members
#: cost half as much; one more member of 3600 is called chaotic that a long transient brings to a cycle.)
#: Earlier decisions cost more of those: from 100 periods, 3-6 times as many on the 40x40 chart.
CHAOS_EARLY_PERIODS = 200
CHAOS_EARLY_Z = 5.0
CHAOS_EARLY_MARGIN = 8.0
#: From CHAOS_LATER_PERIODS periods on, that bound need only be above CHAOS_LATER_MARGIN times the threshold.
#: (Chaotic members of the Fig. 11 window have exponents 10-16 times the threshold and a standard error of
#: ~1.6 times it over 100 periods: most missed the first margin and ran to 300-600 periods. Measured on every
#: member run the whole way, 40x40 and 60x30 x 2 ICs: margin 3 from 300 periods, 16% fewer chaotic periods, 2
#: and 0 more members called chaotic that the reference calls otherwise, all on boundaries; margin 2, 2.5%
#: fewer again and no other member; margin 3 from 250 periods instead: 1 and 3 more members.)
CHAOS_LATER_PERIODS = 300
CHAOS_LATER_MARGIN = 2.0
#: ``chaos_test="sali"``: at SALI_START periods (the Lyapunov bound's own guard against chaotic transients that
#: settle), every member with no return within ``tol`` carries two deviation vectors by the tangent map for at most
#: SALI_PERIODS periods (:func:`~explorer_core.analyses.indicators.alignment`; SALI decided Fig. 8B's attractor in
#: 10-13 periods, docs/indicators.md). It is chaotic when they align (SALI < SALI_TOL from MIN_ALIGN_PERIODS on)
#: while stretching by more than CHAOS_MARGIN times the threshold per period, and its finite-time exponent over the
#: second half of its run so far (the value shown) is above CHAOS_MARGIN times the threshold too; any other member
#: goes on as with the Lyapunov test alone. (Fig. 11 window, 40x40 x 2 ICs, against chaos_test="lyapunov": from 200
#: periods 5 of 3200 members differ, from 150 10, from 100 22, every one on a boundary between regimes and called
#: chaotic where the whole run settles on a cycle, escapes or stays below the threshold; time 0.73, 0.75 and 0.65 of
#: the Lyapunov test's, one run each at load ~10; work at 200: 0.88 of the periods. docs/indicators.md.)
SALI_START = CHAOS_EARLY_PERIODS
SALI_PERIODS = 25


def settle_window(p_max: int) -> int:
    """Section points a cycle must repeat over before its member is checked for an early stop: 3 longest cycles."""
    return 3 * p_max


#: Newton for settled cycles is the spec's ``newton`` (default :data:`~explorer_core.solve.options.SETTLING`: the
#: map at 1e-10 for a chart at DEFAULT_CHART_TOL, ``|P^p(x) - x| <= 1e-8 (1 + |x|)``, 8 plain iterations, the first
#: ones on a coarse map: a member hands over within SETTLE_TOL of its cycle, ~3 suffice), its map following the
#: chart's tolerance by :meth:`~explorer_core.solve.options.NewtonOptions.at`.


def settled_cycles(
    coefs: Coefficients,
    x: np.ndarray,
    p: int | np.ndarray,
    t0: float,
    period: float,
    near: np.ndarray | float = math.inf,
    same: np.ndarray | float = 1e-6,
    *,
    numerics: Numerics | None = None,
    newton_options: NewtonOptions = SETTLING,
) -> list[tuple[int, float] | None]:
    """``(least period, exponent)`` of the attracting cycle Newton finds near each ``x[m]`` for ``P^p[m]``, or None.

    ``coefs`` holds one row of coefficients per point (``coefs.row``, as a chart's members), so the points
    of many pixels go through one batch per iteration. None when Newton fails, when it goes farther than
    ``near[m]`` (max-norm) from ``x[m]`` (not the cycle the trajectory is close to), or when the cycle does
    not attract (``max |mu| >= 1``). Points of the cycle within ``same[m]`` (Euclidean) of its first are one
    point: the period is the least ``d`` dividing ``p`` with ``P^d(x) = x`` at that resolution (Newton on
    ``P^2`` converges to a fixed point too); the exponent ``log max |mu| / (p T)`` is the same for a cycle
    and its multiples. ``p`` is one period for every point or one per point (one Newton for all). ``numerics``:
    the chart's (default DOP853 at DEFAULT_CHART_TOL), from which ``newton_options`` derive Newton's map.
    """
    x0 = np.asarray(x, dtype=float).reshape(-1, 2)
    m = x0.shape[0]
    ps = np.broadcast_to(np.asarray(p, dtype=np.int64), (m,))
    inner, ftol = newton_options.at(numerics or chart_numerics(), DEFAULT_CHART_TOL)
    pmap = PoincareMap.rows(coefs, t0, period, inner, workers=1, block=1)
    res = newton(pmap, x0, ps.copy(), ftol=ftol, near=near, dedupe=False, same=same,
                 **newton_options.newton_kwargs())  # fmt: skip
    out: list[tuple[int, float] | None] = [None] * m
    for c in res.converged:
        mu = float(np.abs(np.linalg.eigvals(c.mono.matrix[0])).max())
        if 0.0 < mu < 1.0:  # a saddle or a repeller: no early stop
            out[c.i] = (c.least, math.log(mu) / (int(ps[c.i]) * period))
    return out


def settled_cycle(
    params: Params, x: np.ndarray, p: int, near: float = math.inf, same: float = 1e-6
) -> tuple[int, float] | None:
    """:func:`settled_cycles` of one point under ``params``."""
    coefs = coefficients(Model(params), n=1)
    return settled_cycles(coefs, np.asarray(x, dtype=float).reshape(1, 2), int(p), params.t0, params.period, near,
                          same)[0]  # fmt: skip


def chaos_bound(logs: np.ndarray, block: int = CHAOS_BLOCK) -> tuple[float, float]:
    """Mean per-period ``log R_11`` of ``logs`` (1-D) and the standard error of that mean from block means.

    Blocks of ``block`` consecutive periods (the tail beyond whole blocks is left out) are nearly
    independent on a chaotic orbit, so their spread measures the uncertainty of the mean.
    """
    mean, err = chaos_bounds(np.asarray(logs)[None, :], block)
    return float(mean[0]), float(err[0])


def chaos_bounds(logs: np.ndarray, block: int = CHAOS_BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chaos_bound` of every row of ``logs`` (m, n): ``(means, standard errors)``."""
    m, n = logs.shape
    nb = n // block
    if nb < 2:
        return np.full(m, math.nan), np.full(m, math.inf)
    b = logs[:, : nb * block].reshape(m, nb, block).mean(axis=2)
    return b.mean(axis=1), b.std(axis=1, ddof=1) / math.sqrt(nb)


def _divisors(p: int) -> list[int]:
    return [d for d in range(1, p + 1) if p % d == 0]


def _classify_members(
    spec: ChartSpec, params: list[Params], at: np.ndarray, out: _Out, stop: Callable[[], bool] | None = None
) -> None:
    """Fill the tile's arrays at ``at[m] = (pixel, ic)`` for member ``m`` under ``params[m]`` (see compute_tile);
    raises :class:`_TileStopped` once ``stop`` returns True at a look."""
    regime, period, lyap, status = out[:4]
    bound = min(spec.numerics.bound, ESCAPE_BOUND)
    total = spec.transient + spec.periods
    window = settle_window(spec.p_max)
    # Returns within tol over the whole ring (once it is full): what the classification sees. Close returns
    # (fewer if p_max < SETTLE_POINTS / 2): the hand-over to Newton.
    back_rule = CHART.with_(tol=spec.tol, p_max=spec.p_max, window=window)
    near_rule = NEAR.with_(tol=max(SETTLE_TOL, spec.tol), p_max=spec.p_max,
                           pairs=min(SETTLE_POINTS, window - spec.p_max))  # fmt: skip
    y0 = tangent.start(spec.ics[at[:, 1]], 0.0, 1.0).y
    for idx, coefs, batch in lockstep_groups(params, y0):
        pmap = PoincareMap.rows(coefs, batch.t0, batch.period, spec.numerics, workers=1, block=1)
        n = idx.size
        points = np.zeros((n, spec.periods, 2))  # the measurement's section points
        every = np.zeros((n, total))  # log R_11 of every period (the measurement's: from spec.transient on)
        logs = every[:, spec.transient :]
        measured = np.zeros(n, dtype=np.int64)  # periods of the measurement completed
        ran = np.zeros(n, dtype=np.int64)  # periods integrated
        recent = np.zeros((n, window, 2))  # the last `window` section points (a ring)
        may_stop, stopped = np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        next_try = np.zeros(n, dtype=np.int64)  # no Newton before this many periods
        whole = np.zeros(n, dtype=bool)  # Newton on the return's period itself (a divisor failed)
        live = np.flatnonzero(batch.status == Status.OK)
        done = 0
        while done < total and live.size:
            if stop is not None and stop():
                raise _TileStopped
            # Looks every SETTLE_CHUNK periods, landing on every multiple of CHAOS_BLOCK (the chaos bounds').
            step = min(SETTLE_CHUNK, CHAOS_BLOCK - done % CHAOS_BLOCK, total - done)
            part = batch.take(live)
            rec, npts = pmap.advance_lyapunov(part, step, members=live, bound=bound)
            batch.put(live, part)
            ran[live] += npts
            _record(rec, npts, live, done, spec.transient, recent, every, points, measured)
            done += step
            live = live[part.status == Status.OK]
            if done >= total or not live.size:
                continue
            # The valid points of the ring, oldest first.
            rings = np.roll(recent[live], -(done % window), axis=1)[:, -min(done, window) :]
            scale = 1.0 + np.abs(rings).max(axis=(1, 2))  # Newton's resolution of the least period: tol * scale
            back = recurrence(rings, back_rule).period
            close_by = recurrence(rings, near_rule, distances=True)
            near, loose = close_by.dist, close_by.limit
            close = np.where(back > 0, back, close_by.period)
            # Only members that contract: on (or near) an attracting cycle the tangent vector shrinks, near a
            # saddle (a chaotic orbit's close returns) it grows, and Newton would find a cycle that does not attract.
            contracting = every[live, max(0, done - CONTRACT_SPAN) : done].mean(axis=1) < 0
            ask = np.flatnonzero(may_stop[live] & (next_try[live] <= done) & (close > 0) & contracting)
            # Newton's verdict for the members asked, and whether it was for the return's own period.
            cycles: dict[int, tuple[tuple[int, float] | None, bool]] = {}
            if ask.size:
                # Newton's period: the least divisor of the return's whose returns are nearly as close.
                first = np.array([next(d for d in _divisors(int(close[a])) if near[a, d - 1] <= SETTLE_DIVISOR *
                                       loose[a] or d == close[a]) for a in ask], dtype=np.int64)  # fmt: skip
                first = np.where(whole[live[ask]], close[ask], first)
                found = _cycles(coefs, live, rings, scale, loose, ask, first, batch, spec)
                # A divisor that gave no cycle is not tried again for that member: the return's own period is.
                whole[live[ask[(first < close[ask]) & np.array([f is None for f in found], dtype=bool)]]] = True
                cycles = dict(zip(ask.tolist(), zip(found, first == close[ask], strict=True), strict=True))
            # Chaos bounds of every live member at once (all have run `done` periods, `got` of the measurement).
            chaotic, spans = np.zeros(live.size, dtype=bool), every[live, :0]
            got = max(0, done - spec.transient)
            if done % CHAOS_BLOCK == 0 and (got >= CHAOS_MIN_PERIODS or done >= CHAOS_EARLY_PERIODS):
                # The measurement so far, or (before it is long enough) the second half of the run so far.
                early = got < CHAOS_MIN_PERIODS
                spans = every[live, (done // 2) // CHAOS_BLOCK * CHAOS_BLOCK if early else spec.transient : done]
                z, margin = (CHAOS_EARLY_Z, CHAOS_EARLY_MARGIN) if early else (CHAOS_Z, CHAOS_MARGIN)
                if early and done >= CHAOS_LATER_PERIODS:
                    margin = CHAOS_LATER_MARGIN
                mean, err = chaos_bounds(spans)
                chaotic = (back == 0) & (mean - z * err > margin * spec.lyap_threshold * abs(batch.period))
            shown = None  # the exponents (per period) of members the SALI called chaotic
            if spec.chaos_test == "sali" and done == SALI_START:
                found_cycle = np.array([a in cycles and cycles[a][0] is not None for a in range(live.size)], dtype=bool)
                shown = _sali_chaos(spec, pmap, batch, live, every, done, (back == 0) & ~found_cycle & ~chaotic, ran,
                                    stop)  # fmt: skip
                chaotic = chaotic | ~np.isnan(shown)
            keep = []
            for a, m in enumerate(live):
                if a in cycles:
                    cycle, own = cycles[a]
                    if cycle is not None:
                        pix, k = at[idx[m]]
                        regime[pix, k], status[pix, k] = PERIODIC, Status.OK
                        period[pix, k], lyap[pix, k] = cycle
                        stopped[m] = True
                        continue
                    if back[a] and own:
                        may_stop[m] = False  # returns within tol but no attracting cycle: the whole run decides
                    elif own:
                        next_try[m] = done + SETTLE_RETRY  # close, not yet a cycle Newton confirms
                if chaotic[a]:
                    pix, k = at[idx[m]]
                    regime[pix, k], status[pix, k], period[pix, k] = CHAOTIC, Status.OK, 0
                    by_sali = shown is not None and not np.isnan(shown[a])
                    lyap[pix, k] = (shown[a] if by_sali else spans[a].mean()) / params[idx[m]].period
                    stopped[m] = True
                    continue
                keep.append(m)
            live = np.array(keep, dtype=np.int64)
        out.periods_run[at[idx, 0], at[idx, 1]] = ran
        out.steps[at[idx, 0], at[idx, 1]] = batch.nsteps
        for row in np.flatnonzero(~stopped):
            m = idx[row]
            pix, k = at[m]
            s, got = int(batch.status[row]), int(measured[row])
            lyap[pix, k] = logs[row, :got].sum() / (max(got, 1) * params[m].period)
            regime[pix, k], period[pix, k] = classify(points[row], got, s, lyap[pix, k], p_max=spec.p_max,
                                                      tol=spec.tol, lyap_threshold=spec.lyap_threshold)  # fmt: skip
            status[pix, k] = _pixel_status(regime[pix, k], s)


def _record(rec: np.ndarray, npts: np.ndarray, live: np.ndarray, done: int, transient: int, recent: np.ndarray,
            every: np.ndarray, points: np.ndarray, measured: np.ndarray) -> None:  # fmt: skip
    """A chunk's records (``rec[j, c]``: period ``done + c`` of member ``live[j]``, completed for ``c < npts[j]``: a
    member that failed stops recording) into the ring of recent points, ``log R_11`` of every period, and the
    measurement from period ``transient`` on; all periods at once (a loop over them cost a chart ~10 % of its
    Python). Each member's ring gets only its last ``window`` periods: one write a slot, the latest."""
    window = recent.shape[1]
    j, c = np.nonzero(np.arange(rec.shape[1])[None, :] < npts[:, None])
    rows, kk = live[j], done + c
    last = c >= npts[j] - window
    recent[rows[last], kk[last] % window] = rec[j[last], c[last], :2]
    every[rows, kk] = rec[j, c, 2]
    meas = kk >= transient
    points[rows[meas], kk[meas] - transient] = rec[j[meas], c[meas], :2]
    measured[live] += np.bincount(j[meas], minlength=live.size)


def _sali_chaos(
    spec: ChartSpec,
    pmap: PoincareMap,
    batch: Any,
    live: np.ndarray,
    every: np.ndarray,
    done: int,
    asked: np.ndarray,
    ran: np.ndarray,
    stop: Callable[[], bool] | None = None,
) -> np.ndarray:
    """Per member ``live[a]``: its finite-time exponent per period (the mean ``log R_11`` over the second half of its
    run so far) where the SALI test (see :data:`SALI_START`) calls it chaotic, NaN elsewhere; only the members
    ``asked`` are tested. Their periods of the alignment are added to ``ran``; ``stop`` is polled every 16 of them
    (a stopped alignment calls no member chaotic, and the tile stops at its next look)."""
    # Deferred: indicators imports the Lyapunov analysis, which the chart does not otherwise need at import.
    from explorer_core.analyses.indicators import CHAOTIC as ALIGNED_CHAOS
    from explorer_core.analyses.indicators import alignment

    shown = np.full(live.size, np.nan)
    cand = np.flatnonzero(asked)
    rows = live[cand]
    per_period = spec.lyap_threshold * abs(batch.period)
    half = (done // 2) // CHAOS_BLOCK * CHAOS_BLOCK
    finite = every[rows, half:done].mean(axis=1)  # the finite-time exponent shown, per period
    big = finite > CHAOS_MARGIN * per_period
    cand, rows, finite = cand[big], rows[big], finite[big]
    if not cand.size:
        return shown

    def advance(x: np.ndarray, sub: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        mono = pmap.derivative(x, 1, members=rows[sub])
        return mono.end, mono.matrix, mono.status

    a = alignment(advance, batch.y[rows, :2], SALI_PERIODS, stretch_tol=CHAOS_MARGIN * per_period, cancel=stop)
    if not a.completed:
        return shown
    ran[rows] += a.npts
    yes = a.verdict == ALIGNED_CHAOS
    shown[cand[yes]] = finite[yes]
    return shown


def _cycles(
    coefs: Coefficients,
    live: np.ndarray,
    rings: np.ndarray,
    scale: np.ndarray,
    loose: np.ndarray,
    ask: np.ndarray,
    periods: np.ndarray,
    batch: Any,
    spec: ChartSpec,
) -> list[tuple[int, float] | None]:
    """:func:`settled_cycles` at the last point of the members ``live[ask]`` for ``P^periods`` (one Newton)."""
    co = coefs._replace(row=np.ascontiguousarray(coefs.row[live[ask]]))
    return settled_cycles(co, rings[ask, -1], periods, batch.t0, batch.period, near=loose[ask],
                          same=spec.tol * scale[ask], numerics=spec.numerics, newton_options=spec.newton)  # fmt: skip


def _pixel_status(regime: int, engine: int) -> int:
    """The member's :class:`~explorer_core.status.Status`: the engine's, or ``cancelled`` for a measurement that
    stopped short with the integration ok (only a cancel does that)."""
    return int(Status.CANCELLED) if regime == FAILED and engine == Status.OK else engine


def compute_tile_each(spec: ChartSpec, tile: TileSpec) -> TileResult:
    """:func:`compute_tile` without early stops: every pixel and IC the whole way with the tangent system.

    The chart as it was computed before (every member's exponent is
    :func:`~explorer_core.analyses.lyapunov.lyapunov_spectrum`'s to the last bit); the benchmark
    (``benchmarks/chart_speed.py``) compares the two.
    """
    return _tile(spec, tile, _fill_each)


def _fill_each(spec: ChartSpec, params: list[Params], at: np.ndarray, out: _Out) -> None:
    regime, period, lyap, status = out[:4]
    n_ic = spec.ics.shape[0]
    for first in range(0, len(params), n_ic):  # a pixel's ICs are consecutive members
        p, n = params[first], at[first, 0]
        coefs = coefficients(Model(p), n=n_ic)
        batch = tangent.start(spec.ics, p.t0, p.period)
        if spec.transient:
            out.periods_run[n] = tangent.advance_lyapunov(coefs, batch, spec.transient, spec.numerics, 1,
                                                          store=False)[3]  # fmt: skip
        logs, _, pts, npts = tangent.advance_lyapunov(coefs, batch, spec.periods, spec.numerics, 1)
        out.periods_run[n] += npts
        out.steps[n] = batch.nsteps
        for k in range(n_ic):
            m = int(npts[k])
            lyap[n, k] = logs[k, :m, 0].sum() / (max(m, 1) * p.period)
            regime[n, k], period[n, k] = classify(pts[k], m, int(batch.status[k]), lyap[n, k], p_max=spec.p_max,
                                                  tol=spec.tol, lyap_threshold=spec.lyap_threshold)  # fmt: skip
            status[n, k] = _pixel_status(regime[n, k], int(batch.status[k]))


# ---------------------------------------------------------------------------
# The chart.


@dataclass
class Chart(Drawable):
    """A (possibly partial) chart of regimes. Arrays are ``[row j (y), column i (x), ic]``.

    ``regime`` holds the codes of :data:`REGIMES`; ``period`` the cycle's period
    (0 unless periodic); ``lyap`` the largest exponent per unit time; ``status``
    the :class:`~explorer_core.status.Status` code of each pixel and IC (``ok`` when
    classified; otherwise why not, ``not_run`` until computed). ``computed[j, i]``
    says whether a pixel is done.
    """

    spec: ChartSpec
    regime: np.ndarray
    period: np.ndarray
    lyap: np.ndarray
    status: np.ndarray
    computed: np.ndarray
    errors: dict[tuple[int, int], str] = field(default_factory=dict)
    elapsed_s: float = 0.0
    completed: bool = False
    #: ``[j, i]``: True where a refined chart filled the pixel from its neighbours instead of computing it.
    inferred: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.inferred is None:
            self.inferred = np.zeros(self.computed.shape, dtype=bool)

    @classmethod
    def empty(cls, spec: ChartSpec) -> Chart:
        ny, nx = spec.shape
        n = spec.ics.shape[0]
        return cls(
            spec,
            np.zeros((ny, nx, n), dtype=np.int8),
            np.zeros((ny, nx, n), dtype=np.int16),
            np.zeros((ny, nx, n)),
            np.full((ny, nx, n), Status.NOT_RUN, dtype=np.int8),
            np.zeros((ny, nx), dtype=bool),
        )

    def add(self, res: TileResult) -> None:
        self.regime[res.jj, res.ii] = res.regime
        self.period[res.jj, res.ii] = res.period
        self.lyap[res.jj, res.ii] = res.lyap
        self.status[res.jj, res.ii] = res.status
        self.computed[res.jj, res.ii] = True
        for j, i, e in zip(res.jj, res.ii, res.errors, strict=True):
            if e:
                self.errors[(int(j), int(i))] = e

    def infer(self, fill: Sequence[tuple[int, int, int, int]]) -> None:
        """Pixels ``(j, i)`` take the values of ``(source j, source i)`` (see :func:`refine_level`)."""
        if not fill:
            return
        j, i, sj, si = (np.array(v, dtype=np.int64) for v in zip(*fill, strict=True))
        for arr in (self.regime, self.period, self.lyap, self.status):
            arr[j, i] = arr[sj, si]
        self.computed[j, i] = True
        self.inferred[j, i] = True

    def code(self) -> np.ndarray:
        """One integer per pixel and IC for colouring: ``p`` for a period-``p`` cycle, else ``-regime``."""
        return np.where(self.regime == PERIODIC, self.period.astype(np.int64), -self.regime.astype(np.int64))

    def filled(self) -> Chart:
        """A copy where every uncomputed pixel shows its nearest computed coarser-lattice pixel."""
        out = Chart(
            self.spec,
            self.regime.copy(),
            self.period.copy(),
            self.lyap.copy(),
            self.status.copy(),
            self.computed.copy(),
            dict(self.errors),
            self.elapsed_s,
            self.completed,
            self.inferred.copy(),
        )
        ny, nx = self.computed.shape
        jj, ii = np.mgrid[0:ny, 0:nx]
        s = 2
        while not out.computed.all() and s <= 2 * max(ny, nx):
            pj, pi = (jj // s) * s, (ii // s) * s
            take = ~out.computed & self.computed[pj, pi]
            for arr, src in ((out.regime, self.regime), (out.period, self.period), (out.lyap, self.lyap)):
                arr[take] = src[pj[take], pi[take]]
            out.status[take] = self.status[pj[take], pi[take]]
            out.computed |= take
            s *= 2
        return out

    def measured(self) -> tuple[np.ndarray, np.ndarray]:
        """``(period, lyap)`` as the files hold them: floats, NaN where nothing was measured.

        ``period`` only where the regime is periodic (a chaotic or quasi-periodic pixel has none, an escaped
        one was never judged); ``lyap`` only where a computed pixel settled on a regime (periodic,
        quasi-periodic, chaotic): an escape or a failure ends the measurement early, and a pixel filled from
        its neighbours (``inferred``) copied its neighbour's exponent.
        """
        done = (self.computed & ~self.inferred)[..., None]
        period = np.where(self.computed[..., None] & (self.regime == PERIODIC), self.period, np.nan)
        settled = np.isin(self.regime, (PERIODIC, QUASI_PERIODIC, CHAOTIC))
        return period, np.where(done & settled, self.lyap, np.nan)

    def multistable(self) -> np.ndarray:
        """``[j, i]``: True where the initial conditions found different regimes or periods."""
        c = self.code()
        return np.any(c != c[..., :1], axis=-1)

    def counts(self, ic: int = 0) -> dict[str, int]:
        """Pixels per regime (periodic split by period) for initial condition ``ic``."""
        out: dict[str, int] = {}
        sel = self.computed
        for code in np.unique(self.code()[..., ic][sel]):
            key = f"period_{code}" if code > 0 else REGIMES[-code]
            out[key] = int(np.count_nonzero(self.code()[..., ic][sel] == code))
        return out

    @property
    def lost(self) -> list[Loss]:
        """What this chart does not hold of what its spec asked for, and why."""
        out = []
        missing = int((~self.computed).sum())
        if missing:
            out.append(Loss("pixels", missing, "not computed: the chart was stopped before them"))
        inferred = int(self.inferred.sum())
        if inferred:
            out.append(Loss("pixels", inferred, "not computed: filled from computed neighbours of the same regime "
                                                "(refine); a window narrower than the computed lattice is not "
                                                "seen: compute every pixel to see it"))  # fmt: skip
        if self.errors:
            first = next(iter(self.errors.values()))
            out.append(Loss("pixels", len(self.errors), f"not a valid system (e.g. {first})"))
        failed = self.computed & ~self.inferred
        failed = (self.regime == FAILED) & failed[..., None]
        for code, n in count_names(self.status[failed]).items():
            st = Status.of(code)
            why = "the measurement ended before a verdict" if st == Status.CANCELLED else "the integration failed"
            out.append(Loss("pixel-ICs", n, f"{why} ({st.label}: {st.meaning})"))
        return out

    @property
    def complete(self) -> bool:
        return not self.lost

    def summary(self) -> dict[str, Any]:
        return {
            **self.spec.as_dict(),
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "computed": int(self.computed.sum()),
            "pixels": int(self.computed.size),
            "counts": self.counts(),
            "statuses": count_names(self.status[self.computed]),
            "multistable_pixels": int(self.multistable()[self.computed].sum()),
            "invalid_pixels": len(self.errors),
            "inferred_pixels": int(self.inferred.sum()),
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
        }

    def report(self) -> list[str]:
        """What the command line prints."""
        s = self.summary()
        return [f"{s['computed']}/{s['pixels']} pixels, {s['counts']}, {self.elapsed_s:.1f} s"]

    def write(self, path: str) -> dict[str, Any]:
        """``.npz``: :meth:`to_npz`; ``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        npz = lambda p: export.write_through(p, self.to_npz)  # noqa: E731
        return export.write_by_suffix(
            path, {".npz": npz, ".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "chart"
        )

    def to_npz(self, path: str) -> None:
        """Arrays plus the spec as JSON, so the file says what it holds; ``period`` and ``lyap`` are floats with
        NaN where nothing was measured (:meth:`measured`); ``complete`` and ``lost`` (JSON, as the summary's): a
        stopped chart says so, its pixels not computed are ``computed`` False."""
        period, lyap = self.measured()
        np.savez_compressed(
            path,
            x=self.spec.x_values,
            y=self.spec.y_values,
            regime=self.regime,
            period=period,
            lyap=lyap,
            status=self.status,
            computed=self.computed,
            inferred=self.inferred,
            regimes=np.array(REGIMES),
            status_names=status_names(),
            spec=json.dumps(self.spec.as_dict()),
            complete=self.complete,
            lost=json.dumps([loss.as_dict() for loss in self.lost]),
        )

    def to_csv(self, path: str) -> int:
        """Rows ``i,j,x,y,ic,regime,period,lyap,status,inferred`` for the computed pixels; ``period`` and ``lyap``
        are ``nan`` where nothing was measured (:meth:`measured`; not an empty field: ``numpy.genfromtxt``
        with ``dtype=None`` fills an empty field of an integer column with -1), ``inferred`` is 1 for a pixel
        filled from its neighbours."""
        period, lyap = self.measured()
        rows = 0
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["i", "j", self.spec.x_param, self.spec.y_param, "ic", "regime", "period", "lyap", "status",
                        "inferred"])  # fmt: skip
            fh.writelines(export.comment_lines(export.partial(self)))  # a stopped chart says so
            for j, i in zip(*np.nonzero(self.computed), strict=True):
                for k in range(self.spec.ics.shape[0]):
                    st = int(self.status[j, i, k])
                    per = float(period[j, i, k])
                    w.writerow(
                        (int(i), int(j), repr(float(self.spec.x_values[i])), repr(float(self.spec.y_values[j])), k,
                         REGIMES[self.regime[j, i, k]], int(per) if math.isfinite(per) else "nan",
                         repr(float(lyap[j, i, k])), Status(st).label, int(self.inferred[j, i]))
                    )  # fmt: skip
                    rows += 1
        return rows


@dataclass(frozen=True)
class ChartUpdate:
    """Yielded by :func:`iter_chart` after each tile; ``chart`` is the live (partial) chart."""

    tile: TileResult | None  # None on the last update of a chart cancelled before any tile finished
    done_tiles: int
    total_tiles: int
    chart: Chart

    @property
    def progress(self) -> Progress:
        return Progress(self.done_tiles, self.total_tiles, "tiles", self.chart.elapsed_s)

    @property
    def result(self) -> Chart:
        """The live chart (the last update's is the result)."""
        return self.chart


def iter_chart(
    spec: ChartSpec,
    *,
    coarse: int = 8,
    tile_pixels: int = 64,
    workers: int | None = None,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
    refine: bool = False,
    stop: Callable[[], bool] | None = None,
) -> Iterator[ChartUpdate]:
    """Compute the chart tile by tile, coarse levels first, yielding after every tile.

    Tiles are tasks of ``executor`` (:mod:`explorer_core.parallel.executor`; default: ``workers`` threads
    of this process, both cores) -- a Dask executor runs them on a cluster with the same updates and
    the same chart. ``cancel`` is polled whenever a tile finishes; no new tile starts once it returns True.
    ``stop`` (thread-safe, returning at once: a stop flag) is polled by the running tiles too, every
    :data:`SETTLE_CHUNK` periods, on this machine's threads (a cluster's tiles run to their end); a tile it
    stops computed nothing, as one never started, so a stop waits for a look, not for the tiles to end.

    ``refine``: compute the ``coarse`` lattice (:func:`lattice`: every ``coarse``-th pixel and the last
    row and column), then each finer level only where the coarser one is not uniform around a pixel
    (:func:`refine_level`); the other pixels are filled from their neighbours (``Chart.inferred``).
    Levels run one after another (each needs the previous one); ``total_tiles`` of an update counts
    the tiles planned so far.
    """
    ex = local_executor(executor, workers)
    stop = stop if isinstance(ex, LocalExecutor) else None  # a cluster's task cannot poll this process
    if refine:
        yield from _iter_refined(spec, coarse, tile_pixels, ex, cancel, stop)
        return
    start = time.perf_counter()
    tiles = plan_tiles(spec.shape, coarse, tile_pixels)
    chart = Chart.empty(spec)
    done = 0
    todo = deque(_task(n, spec, tile, stop) for n, tile in enumerate(tiles))
    with closing(ex.stream(todo, cancel)) as stream:
        for batch in stream:
            # Tiles that finish together: coarser first, so the picture refines in order (a stopped one: nothing).
            for _, res in sorted(_finished(batch), key=lambda tr: tr[1].tile.stride, reverse=True):
                chart.add(res)
                done += 1
                chart.elapsed_s = time.perf_counter() - start
                chart.completed = done == len(tiles)
                yield ChartUpdate(res, done, len(tiles), chart)
    if done == 0:  # cancelled before any tile: the last update still carries the chart (the contract)
        chart.elapsed_s = time.perf_counter() - start
        chart.completed = False
        yield ChartUpdate(None, done, len(tiles), chart)


#: Cells around a pixel's own that must share its code before :func:`refine_level` fills it (0: the cell only).
REFINE_RING = 1


def _task(tag: Any, spec: ChartSpec, tile: TileSpec, stop: Callable[[], bool] | None) -> tuple:
    """An executor's task computing ``tile`` (polling ``stop`` if there is one: a cluster's task has none)."""
    return (tag, compute_tile, (spec, tile) if stop is None else (spec, tile, stop))


def _finished(batch: list[tuple[Any, TileResult | None]]) -> list[tuple[Any, TileResult]]:
    """The tiles of a batch that ended (not stopped)."""
    return [(tag, res) for tag, res in batch if res is not None]


def _iter_refined(
    spec: ChartSpec,
    coarse: int,
    tile_pixels: int,
    ex: Executor,
    cancel: Callable[[], bool] | None,
    stop: Callable[[], bool] | None = None,
) -> Iterator[ChartUpdate]:
    """:func:`iter_chart` with ``refine=True`` (a stopped tile leaves its level unfinished: no level after it is
    planned, nothing is inferred from it)."""
    if coarse < 1 or coarse & (coarse - 1):
        raise ParameterError(f"coarse must be a power of two, got {coarse!r}")
    start = time.perf_counter()
    ny, nx = spec.shape
    chart = Chart.empty(spec)
    todo: deque = deque()
    level, pending, done, planned = coarse, 0, 0, 0

    def push(pixels: list[tuple[int, int]], stride: int) -> int:
        # Small tiles: a level must finish before the next is planned, so its last tile should be short.
        size = max(4, min(tile_pixels, math.ceil(len(pixels) / (4 * ex.threads()))))
        for k in range(0, len(pixels), size):
            tile = TileSpec(stride, coarse, 0, ny, 0, nx, only=tuple(pixels[k : k + size]))
            todo.append(_task(None, spec, tile, stop))
        return math.ceil(len(pixels) / size)

    first = [(int(j), int(i)) for j in lattice(ny, coarse) for i in lattice(nx, coarse)]
    pending = planned = push(first, coarse)
    with closing(ex.stream(todo, cancel)) as stream:
        for batch in stream:
            for _, res in _finished(batch):
                chart.add(res)
                done += 1
                pending -= 1
                while pending == 0 and level > 1:  # a level is complete: plan the next
                    level //= 2
                    compute, fill = refine_level(chart.code(), spec.shape, level, REFINE_RING)
                    invalid = [f for f in fill if isinstance(spec.pixel_params(f[0], f[1]), str)]
                    if invalid:  # never inferred: computed, so the chart says why
                        fill = [f for f in fill if f not in invalid]
                        compute += [(j, i) for j, i, _, _ in invalid]
                    chart.infer(fill)
                    if compute:
                        pending = push(compute, level)
                        planned += pending
                chart.elapsed_s = time.perf_counter() - start
                chart.completed = pending == 0 and level == 1
                yield ChartUpdate(res, done, planned, chart)
    if done == 0:  # cancelled before any tile: the last update still carries the chart (the contract)
        chart.elapsed_s = time.perf_counter() - start
        chart.completed = False
        yield ChartUpdate(None, done, planned, chart)


def _power_of_two(name: str, v: Any) -> int:
    """A whole number ``2**k``, ``k >= 0`` (a lattice's stride), as a plain ``int``."""
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1 or v & (v - 1):
        raise ParameterError(f"{name} must be a power of two, got {v!r}")
    return int(v)


@declare(
    coarse=Arg(
        "stride of the first coarse pass", "int", default=8, check=Check(_power_of_two, "a power of two", "int")
    ),
    tile_pixels=Arg("pixels per tile", cli=False, default=64, check=integer(1, config.MAX_GRID**2)),
    refine=Arg("finer levels only where neighbours differ (README)", "switch", default=False, check=BOOL),
)
def regime_chart(
    spec: ChartSpec,
    *,
    coarse: int,
    tile_pixels: int,
    workers: int | None = None,
    progress: Callable[[ChartUpdate], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
    refine: bool,
    stop: Callable[[], bool] | None = None,
) -> Chart:
    """The whole chart (see :func:`iter_chart`); a cancelled chart has ``completed=False``. The options are
    declared above (defaults, checks, flags); ``workers``, ``progress``, ``cancel``, ``executor``, ``stop`` (a
    thread-safe cancel the running tiles poll): the run's plumbing."""
    kw = {"coarse": coarse, "tile_pixels": tile_pixels, "workers": workers, "cancel": cancel, "executor": executor,
          "refine": refine, "stop": stop}  # fmt: skip
    return run_updates(iter_chart(spec, **kw), progress)
