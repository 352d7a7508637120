"""Charts of dynamical regimes on a plane of two parameters (paper, Fig. 11).

Every pixel ``(x_i, y_j)`` of the parameter plane is classified from the
trajectory of one or more initial conditions: after a transient, ``periods``
section points are computed together with the largest Lyapunov exponent
(:mod:`explorer_core.analyses.lyapunov`'s kernel) and the regime is

* ``periodic`` with period ``p`` (``1 <= p <= p_max``): the section point
  returns to itself after ``p`` iterations within ``tol`` over the last part of
  the measurement -- a stable cycle;
* ``chaotic``: no period and largest exponent ``> lyap_threshold`` (per unit time);
* ``quasi-periodic``: no period and largest exponent ``<= lyap_threshold``
  (an invariant curve, or a cycle longer than ``p_max``);
* ``escaped``: the trajectory left the bound (noncompact motion);
* ``failed``: any other integration failure; ``invalid``: the parameters do not
  define a system (e.g. a tensor that is not positive definite).

The work is organised in **tiles**: :func:`compute_tile` is a pure function of
a :class:`ChartSpec` and a :class:`TileSpec` (both plain picklable data), so a
task scheduler can run tiles anywhere. :func:`plan_tiles` orders them
progressively -- every ``coarse``-th pixel first, then each finer level -- and
:func:`iter_chart` streams partial charts (with :meth:`Chart.filled` showing a
coarse picture at once) while both cores work.
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

from explorer_core import config
from explorer_core.analyses.orbits import find_orbits
from explorer_core.analyses.sweeps import check_param, detect_period, params_at, sweep_values
from explorer_core.parallel.executor import Executor, local_executor
from explorer_core.solve import tangent
from explorer_core.solve.integrators import Status, coefficients, lockstep_groups, run
from explorer_core.solve.numerics import Numerics, check_ics
from explorer_core.solve.rk import LYAPUNOV
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

#: Regime codes of :attr:`Chart.regime`.
NOT_COMPUTED, PERIODIC, QUASI_PERIODIC, CHAOTIC, ESCAPED, FAILED, INVALID = range(7)
REGIMES = ("not_computed", "periodic", "quasi_periodic", "chaotic", "escaped", "failed", "invalid")
#: Defaults: charts need the regime, not 1e-10 accuracy; cycles attract integration errors anyway.
DEFAULT_CHART_TOL = 1e-8


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
        points, with tolerance ``tol * (1 + max |x|)``.
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
        p = detect_period(tail, p_max, tol * (1.0 + float(np.abs(tail).max())))
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
    transient: int = 500
    periods: int = 500
    p_max: int = 16
    tol: float = 1e-5
    lyap_threshold: float = 5e-3
    numerics: Numerics = field(default_factory=lambda: Numerics(rtol=DEFAULT_CHART_TOL, atol=DEFAULT_CHART_TOL))

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
        }


def chart_spec(
    params: Params,
    x_param: str,
    x_range: Sequence[float],
    y_param: str,
    y_range: Sequence[float],
    grid: Sequence[int],
    *,
    ics: Any = ((0.1, 0.1),),
    transient: int = 500,
    periods: int = 500,
    p_max: int = 16,
    tol: float = 1e-5,
    lyap_threshold: float = 5e-3,
    numerics: Numerics | None = None,
) -> ChartSpec:
    """Validated :class:`ChartSpec` over ``x_range x y_range`` with ``grid = (nx, ny)`` pixels.

    Pixel centres include both ends of each range. ``ics`` are used at every pixel
    (several: multistability is seen per pixel).
    """

    xp, yp = check_param(x_param), check_param(y_param)
    if xp == yp:
        raise ParameterError(f"x and y parameters must differ, both are {xp!r}")
    try:
        nx, ny = (int(v) for v in grid)
    except (TypeError, ValueError):
        raise ParameterError(f"grid must be two integers NX,NY, got {grid!r}") from None
    for n in (nx, ny):
        if not 1 <= n <= config.MAX_GRID:
            raise ParameterError(f"grid must be between 1 and {config.MAX_GRID} per axis, got {grid!r}")
    ics = check_ics(ics)
    for name, v, lo, hi in (("transient", transient, 0, config.MAX_PERIODS), ("periods", periods, 4, 10**6)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
            raise ParameterError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
    if isinstance(p_max, bool) or not isinstance(p_max, int | np.integer) or not 1 <= p_max < periods // 2:
        raise ParameterError(f"p_max must be an integer in [1, periods/2), got {p_max!r}")
    if not (isinstance(tol, int | float) and 0 < tol < 1):
        raise ParameterError(f"tol must be in (0, 1), got {tol!r}")
    if not (isinstance(lyap_threshold, int | float) and np.isfinite(lyap_threshold)):
        raise ParameterError(f"lyap_threshold must be a finite number, got {lyap_threshold!r}")
    if nx * ny * ics.shape[0] * periods > 50 * config.MAX_POINTS:
        raise ParameterError(f"chart of {nx}x{ny} pixels x {ics.shape[0]} ICs x {periods} periods is too large")
    return ChartSpec(
        params=params,
        x_param=xp,
        x_values=sweep_values(x_range, nx),
        y_param=yp,
        y_values=sweep_values(y_range, ny),
        ics=ics,
        transient=int(transient),
        periods=int(periods),
        p_max=int(p_max),
        tol=float(tol),
        lyap_threshold=float(lyap_threshold),
        numerics=numerics or Numerics(rtol=DEFAULT_CHART_TOL, atol=DEFAULT_CHART_TOL),
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

    def pixels(self) -> list[tuple[int, int]]:
        """``(j, i)`` of the tile's pixels, row by row."""
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
    return tiles


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


def compute_tile(spec: ChartSpec, tile: TileSpec) -> TileResult:
    """Classify every pixel of ``tile`` (a pure function of its arguments; single-threaded).

    Every pixel and initial condition runs with the tangent system on its own step sequence (lock-step
    blocks across pixels were measured slower: a block steps at its most demanding member's pace, and
    escaping or chaotic members multiplied the steps of the whole block ~8x). Every
    :data:`SETTLE_CHUNK` periods a member may stop early:

    * **on an attracting cycle**: once its last :func:`settle_window` section points return within
      :data:`SETTLE_TOL` after ``p <= p_max`` iterations it is handed to Newton on ``P^p(x) - x``
      (:func:`settled_cycle`: least period at the resolution ``tol``, multipliers). If the cycle
      attracts (``max |mu| < 1``) and lies within that tolerance of the member, the member is periodic
      with that period and its exponent is the cycle's own, ``log max |mu| / (p T)`` (which a
      finite-time average only approaches). Otherwise it is tried again :data:`SETTLE_RETRY` periods
      later, or never again once its points return within ``tol`` (the whole run decides, as before);
    * **escaped**: ``|q|`` or ``|r|`` passed :data:`ESCAPE_BOUND` (or the integration's bound if smaller);
    * **chaotic**: after :data:`CHAOS_MIN_PERIODS` measured periods with no return within ``tol``, if
      the mean per-period ``log R_11`` minus :data:`CHAOS_Z` standard errors (:func:`chaos_bound`) is
      above :data:`CHAOS_MARGIN` times the threshold; its exponent is the mean so far.

    Every other member runs the whole transient and measurement and is classified exactly as
    :func:`compute_tile_each` does (to the last bit: chunked runs continue each step sequence
    unchanged). Differences from that reference (``benchmarks/chart_speed.py``) are on regime
    boundaries: cycles the reference's finite tail had not converged on (Newton finds them), and long
    chaotic transients that settle after the chaos decision.
    """
    return _tile(spec, tile, _classify_members)


class _Out(NamedTuple):
    """A tile's result arrays, ``[pixel, ic]``."""

    regime: np.ndarray
    period: np.ndarray
    lyap: np.ndarray
    status: np.ndarray


def _tile(spec: ChartSpec, tile: TileSpec, fill: Callable[..., None]) -> TileResult:
    """The tile's arrays; ``fill(spec, params, at, out)`` classifies its valid members into ``out``."""
    start = time.perf_counter()
    pix = tile.pixels()
    n_ic = spec.ics.shape[0]
    regime = np.zeros((len(pix), n_ic), dtype=np.int8)
    period = np.zeros((len(pix), n_ic), dtype=np.int16)
    lyap = np.zeros((len(pix), n_ic))
    status = np.zeros((len(pix), n_ic), dtype=np.int8)
    errors = []
    members: list[tuple[int, int]] = []
    member_params: list[Params] = []
    for n, (j, i) in enumerate(pix):
        p = spec.pixel_params(j, i)
        if isinstance(p, str):
            regime[n] = INVALID
            errors.append(p)
            continue
        errors.append("")
        members += [(n, k) for k in range(n_ic)]
        member_params += [p] * n_ic
    if members:
        at = np.array(members, dtype=np.int64)
        fill(spec, member_params, at, _Out(regime, period, lyap, status))
    jj = np.array([j for j, _ in pix], dtype=np.int64)
    ii = np.array([i for _, i in pix], dtype=np.int64)
    return TileResult(tile, jj, ii, regime, period, lyap, status, tuple(errors), time.perf_counter() - start)


#: Periods between two looks for members that have settled on a cycle (each look is one engine call).
SETTLE_CHUNK = 10
#: A member whose last section points return within this (relative, as ``tol``) is handed to Newton: the
#: cycle Newton finds decides, so the points need not have converged to ``tol`` yet (a member on a cycle
#: with ``|mu| = 0.9`` returns within 1e-3 ~60 periods before it does within 1e-5).
SETTLE_TOL = 1e-3
#: Periods to wait before a member that returned within SETTLE_TOL but gave no attracting cycle is tried again.
SETTLE_RETRY = 50
#: Charts stop a member once ``|q|`` or ``|r|`` passes this (and the integration's own bound): escaped. On the
#: Fig. 11 window no bounded orbit goes beyond 6.1 and every escaping one passes 100 within ~20 periods, then
#: spends ~95% of its steps on the way to 1e4 (steps grow with the speed of rotation).
ESCAPE_BOUND = 100.0
#: A member is decided chaotic once it has measured this many periods and the confidence bound below holds.
CHAOS_MIN_PERIODS = 100
#: Chaos bound: the mean of the per-period ``log R_11`` over blocks of SETTLE_CHUNK periods, minus CHAOS_Z
#: standard errors of that mean, above CHAOS_MARGIN times the threshold (per period).
CHAOS_Z = 4.0
CHAOS_MARGIN = 1.5


def settle_window(p_max: int) -> int:
    """Section points a cycle must repeat over before its member is checked for an early stop: 3 longest cycles."""
    return 3 * p_max


def settled_cycle(
    params: Params, x: np.ndarray, p: int, near: float | None = None, same: float = 0.0
) -> tuple[int, float] | None:
    """``(least period, exponent)`` of the attracting cycle Newton finds near ``x`` for ``P^p``, or None.

    None when Newton fails, the cycle does not attract (``max |mu| >= 1``) or, with ``near``, Newton went
    farther than ``near`` (max-norm) from ``x``: the cycle is not the one the trajectory is close to.
    Points of the cycle within ``same`` (max-norm) of its first are one point: the period is the least
    ``d`` dividing it with ``P^d(x) = x`` at that resolution (a fixed point with a multiplier near 1 can
    come back from Newton on ``P^2`` as a "period-2 orbit" whose points differ by ~1e-8); the exponent,
    ``log max |mu| / (p T)``, is the same for the cycle and its multiples.
    """
    x = np.asarray(x, dtype=float).reshape(1, 2)
    search = find_orbits(params, x, [int(p)], patience=None)
    if not search.orbits:
        return None
    orbit = search.orbits[0]
    if near is not None and np.abs(orbit.points - x).max(axis=1).min() > near:
        return None
    mu = float(np.abs(orbit.multipliers).max())
    if not 0.0 < mu < 1.0:
        return None
    n = orbit.period
    least = next(
        d for d in range(1, n + 1) if n % d == 0 and np.abs(orbit.points[d % n] - orbit.points[0]).max() <= same
    )
    return least, math.log(mu) / (n * params.period)


def chaos_bound(logs: np.ndarray, block: int = SETTLE_CHUNK) -> tuple[float, float]:
    """Mean per-period ``log R_11`` of ``logs`` (1-D) and the standard error of that mean from block means.

    Blocks of ``block`` consecutive periods (the tail beyond whole blocks is left out) are nearly
    independent on a chaotic orbit, so their spread measures the uncertainty of the mean.
    """
    nb = logs.size // block
    if nb < 2:
        return math.nan, math.inf
    b = logs[: nb * block].reshape(nb, block).mean(axis=1)
    return float(b.mean()), float(b.std(ddof=1)) / math.sqrt(nb)


def _classify_members(spec: ChartSpec, params: list[Params], at: np.ndarray, out: _Out) -> None:
    """Fill the tile's arrays at ``at[m] = (pixel, ic)`` for member ``m`` under ``params[m]`` (see compute_tile)."""
    regime, period, lyap, status = out
    kw = spec.numerics.kernel_kwargs()
    kw["bound"] = min(kw["bound"], ESCAPE_BOUND)
    total = spec.transient + spec.periods
    window = settle_window(spec.p_max)
    y0 = tangent.start(spec.ics[at[:, 1]], 0.0, 1.0).y
    for idx, coefs, batch in lockstep_groups(params, y0):
        n = idx.size
        points = np.zeros((n, spec.periods, 2))  # the measurement's section points
        logs = np.zeros((n, spec.periods))  # log R_11 of each period of the measurement
        measured = np.zeros(n, dtype=np.int64)  # periods of the measurement completed
        recent = np.zeros((n, window, 2))  # the last `window` section points (a ring)
        may_stop, stopped = np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        next_try = np.zeros(n, dtype=np.int64)  # no Newton before this many periods
        live = np.flatnonzero(batch.status == Status.OK)
        done = 0
        while done < total and live.size:
            step = min(SETTLE_CHUNK, total - done)
            part = batch.take(live)
            rec, npts = run(LYAPUNOV, coefs._replace(row=np.ascontiguousarray(coefs.row[live])), part, step,
                            workers=1, block=1, **kw)  # fmt: skip
            batch.put(live, part)
            for c in range(step):  # this chunk's records into the ring and the measurement
                kk = done + c
                ok = npts > c  # period c completed (a member that failed stops recording)
                recent[live[ok], kk % window] = rec[ok, c, :2]
                if kk >= spec.transient:
                    points[live[ok], kk - spec.transient] = rec[ok, c, :2]
                    logs[live[ok], kk - spec.transient] = rec[ok, c, 2]
                    measured[live[ok]] += 1
            done += step
            live = live[part.status == Status.OK]
            if done < window or done >= total:
                continue
            keep = []
            for m in live:
                pm = params[idx[m]]
                ring = np.roll(recent[m], -(done % window), axis=0)  # oldest first
                scale = 1.0 + float(np.abs(ring).max())
                returns = detect_period(ring, spec.p_max, spec.tol * scale)
                if may_stop[m] and done >= next_try[m]:
                    p = returns or detect_period(ring, spec.p_max, max(SETTLE_TOL, spec.tol) * scale)
                    cycle = (
                        settled_cycle(pm, ring[-1], p, near=max(SETTLE_TOL, spec.tol) * scale, same=spec.tol * scale)
                        if p
                        else None
                    )
                    if cycle is not None:
                        pix, k = at[idx[m]]
                        regime[pix, k], status[pix, k] = PERIODIC, Status.OK
                        period[pix, k], lyap[pix, k] = cycle
                        stopped[m] = True
                        continue
                    if returns:
                        may_stop[m] = False  # returns within tol but no attracting cycle: the whole run decides
                    elif p:
                        next_try[m] = done + SETTLE_RETRY  # close, not yet a cycle Newton confirms
                got = int(measured[m])
                if not returns and got >= CHAOS_MIN_PERIODS:
                    mean, err = chaos_bound(logs[m, :got])
                    if mean - CHAOS_Z * err > CHAOS_MARGIN * spec.lyap_threshold * abs(pm.period):
                        pix, k = at[idx[m]]
                        regime[pix, k], status[pix, k], period[pix, k] = CHAOTIC, Status.OK, 0
                        lyap[pix, k] = logs[m, :got].sum() / (got * pm.period)
                        stopped[m] = True
                        continue
                keep.append(m)
            live = np.array(keep, dtype=np.int64)
        for row in np.flatnonzero(~stopped):
            m = idx[row]
            pix, k = at[m]
            s, got = int(batch.status[row]), int(measured[row])
            lyap[pix, k] = logs[row, :got].sum() / (max(got, 1) * params[m].period)
            status[pix, k] = s
            regime[pix, k], period[pix, k] = classify(points[row], got, s, lyap[pix, k], p_max=spec.p_max,
                                                      tol=spec.tol, lyap_threshold=spec.lyap_threshold)  # fmt: skip


def compute_tile_each(spec: ChartSpec, tile: TileSpec) -> TileResult:
    """:func:`compute_tile` without early stops: every pixel and IC the whole way with the tangent system.

    The chart as it was computed before (every member's exponent is
    :func:`~explorer_core.analyses.lyapunov.lyapunov_spectrum`'s to the last bit); the benchmark
    (``benchmarks/chart_speed.py``) compares the two.
    """
    return _tile(spec, tile, _fill_each)


def _fill_each(spec: ChartSpec, params: list[Params], at: np.ndarray, out: _Out) -> None:
    regime, period, lyap, status = out
    n_ic = spec.ics.shape[0]
    for first in range(0, len(params), n_ic):  # a pixel's ICs are consecutive members
        p, n = params[first], at[first, 0]
        coefs = coefficients(Model(p), n=n_ic)
        batch = tangent.start(spec.ics, p.t0, p.period)
        if spec.transient:
            tangent.advance_lyapunov(coefs, batch, spec.transient, spec.numerics, 1, store=False)
        logs, _, pts, npts = tangent.advance_lyapunov(coefs, batch, spec.periods, spec.numerics, 1)
        for k in range(n_ic):
            m = int(npts[k])
            lyap[n, k] = logs[k, :m, 0].sum() / (max(m, 1) * p.period)
            status[n, k] = batch.status[k]
            regime[n, k], period[n, k] = classify(pts[k], m, int(batch.status[k]), lyap[n, k], p_max=spec.p_max,
                                                  tol=spec.tol, lyap_threshold=spec.lyap_threshold)  # fmt: skip


# ---------------------------------------------------------------------------
# The chart.


@dataclass
class Chart:
    """A (possibly partial) chart of regimes. Arrays are ``[row j (y), column i (x), ic]``.

    ``regime`` holds the codes of :data:`REGIMES`; ``period`` the cycle's period
    (0 unless periodic); ``lyap`` the largest exponent per unit time; ``status``
    the integration status. ``computed[j, i]`` says whether a pixel is done.
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

    @classmethod
    def empty(cls, spec: ChartSpec) -> Chart:
        ny, nx = spec.shape
        n = spec.ics.shape[0]
        return cls(
            spec,
            np.zeros((ny, nx, n), dtype=np.int8),
            np.zeros((ny, nx, n), dtype=np.int16),
            np.zeros((ny, nx, n)),
            np.zeros((ny, nx, n), dtype=np.int8),
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

    def summary(self) -> dict[str, Any]:
        return {
            **self.spec.as_dict(),
            "computed": int(self.computed.sum()),
            "pixels": int(self.computed.size),
            "counts": self.counts(),
            "multistable_pixels": int(self.multistable()[self.computed].sum()),
            "invalid_pixels": len(self.errors),
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
        }

    def to_npz(self, path: str) -> None:
        """Arrays plus the spec as JSON, so the file says what it holds."""
        np.savez_compressed(
            path,
            x=self.spec.x_values,
            y=self.spec.y_values,
            regime=self.regime,
            period=self.period,
            lyap=self.lyap,
            status=self.status,
            computed=self.computed,
            regimes=np.array(REGIMES),
            spec=json.dumps(self.spec.as_dict()),
        )

    def to_csv(self, path: str) -> int:
        """Rows ``i,j,x,y,ic,regime,period,lyap,status`` for the computed pixels."""
        rows = 0
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["i", "j", self.spec.x_param, self.spec.y_param, "ic", "regime", "period", "lyap", "status"])
            for j, i in zip(*np.nonzero(self.computed), strict=True):
                for k in range(self.spec.ics.shape[0]):
                    st = int(self.status[j, i, k])
                    w.writerow(
                        (int(i), int(j), repr(float(self.spec.x_values[i])), repr(float(self.spec.y_values[j])), k,
                         REGIMES[self.regime[j, i, k]], int(self.period[j, i, k]), repr(float(self.lyap[j, i, k])),
                         Status(st).label)
                    )  # fmt: skip
                    rows += 1
        return rows


@dataclass(frozen=True)
class ChartUpdate:
    """Yielded by :func:`iter_chart` after each tile; ``chart`` is the live (partial) chart."""

    tile: TileResult
    done_tiles: int
    total_tiles: int
    chart: Chart


def iter_chart(
    spec: ChartSpec,
    *,
    coarse: int = 8,
    tile_pixels: int = 64,
    workers: int | None = None,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
) -> Iterator[ChartUpdate]:
    """Compute the chart tile by tile, coarse levels first, yielding after every tile.

    Tiles are tasks of ``executor`` (:mod:`explorer_core.parallel.executor`; default: ``workers`` threads
    of this process, both cores) -- a Dask executor runs them on a cluster with the same updates and
    the same chart. ``cancel`` is polled whenever a tile finishes; no new tile starts once it returns True.
    """
    start = time.perf_counter()
    tiles = plan_tiles(spec.shape, coarse, tile_pixels)
    chart = Chart.empty(spec)
    done = 0
    todo = deque((n, compute_tile, (spec, tile)) for n, tile in enumerate(tiles))
    with closing(local_executor(executor, workers).stream(todo, cancel)) as stream:
        for batch in stream:
            # Tiles that finish together: coarser first, so the picture refines in order.
            for _, res in sorted(batch, key=lambda tr: tr[1].tile.stride, reverse=True):
                chart.add(res)
                done += 1
                chart.elapsed_s = time.perf_counter() - start
                chart.completed = done == len(tiles)
                yield ChartUpdate(res, done, len(tiles), chart)


def regime_chart(
    spec: ChartSpec,
    *,
    coarse: int = 8,
    tile_pixels: int = 64,
    workers: int | None = None,
    progress: Callable[[ChartUpdate], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    executor: Executor | None = None,
) -> Chart:
    """The whole chart (see :func:`iter_chart`); a cancelled chart has ``completed=False``."""
    chart = Chart.empty(spec)
    kw = {"coarse": coarse, "tile_pixels": tile_pixels, "workers": workers, "cancel": cancel, "executor": executor}
    for upd in iter_chart(spec, **kw):
        chart = upd.chart
        if progress is not None:
            progress(upd)
    return chart
