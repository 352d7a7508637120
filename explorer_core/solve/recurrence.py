"""Recurrence: do section points repeat after ``p`` iterations? The one place that says so.

Every analysis that asks whether a trajectory of the map ``P`` has settled on a cycle (a chart pixel, a diagram
value, a basin cell, a played frame, the seeds of a search for orbits) calls :func:`recurrence` with a
:class:`RecurrenceRule`: how close a return must be (the tolerance and what it is relative to), in which norm,
over which points and pairs, up to which period. The rules the analyses use are the named presets below
(:data:`PRESETS`); each reproduces, bit for bit, the detector its analysis had before this module (the tests
keep those detectors, copied verbatim, as references).

A return at period ``p`` compares the points ``x_k`` with ``x_(k-p)``, oldest first, for the *later* points
``x_k`` the rule names (every point of the window with one ``p`` before it, or the last ``pairs`` points). Like
Attractors.jl's recurrence mapper (Datseris & Wagemakers, *Chaos* 32, 2022), whose options are one struct, the
rule is plain data, validated on construction and recorded in JSON (:meth:`RecurrenceRule.as_dict`).

A NaN never returns: a pair with a NaN distance fails, and a NaN in the window makes a window-relative tolerance
NaN (nothing returns). (Inf is a number: ``|inf - x| = inf`` returns only within an infinite tolerance.)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from explorer_core.solve.checks import check_choice, check_int
from explorer_core.system.params import ParameterError

#: What the tolerance is relative to: nothing; ``1 + max |x|`` over the window's points (every component);
#: ``1 + max(|q|, |r|)`` of the later point of each pair; ``1 + |x_c|`` of the later point, per component.
SCALES = ("absolute", "window", "point", "component")
#: The distance of a pair: the largest component (Chebyshev) or the Euclidean norm.
NORMS = ("max", "euclidean")
#: How a period is judged from its pairs: every pair within tolerance, or the closest pair (where the trajectory
#: comes nearest to repeating itself: a seed for Newton, not a verdict on the whole window).
AGREE = ("all", "closest")
#: The longest period a rule may ask for (a cycle of the map longer than this is no cycle for any analysis).
MAX_PERIOD = 10_000


@dataclass(frozen=True)
class RecurrenceRule:
    """When points of the map are said to repeat with period ``p``. Validated on construction.

    Fields
    ------
    tol : the tolerance, ``>= 0`` (``None``: the caller gives it at every call).
    scale : what ``tol`` is relative to (:data:`SCALES`): the limit is ``tol`` (``absolute``),
        ``tol (1 + max |x|)`` over the window (``window``), ``tol (1 + max(|q|, |r|))`` of each pair's later point
        (``point``) or ``tol (1 + |x_c|)`` per component of it (``component``).
    norm : the distance of a pair (:data:`NORMS`).
    window : the last ``window`` points are judged, and a verdict needs that many (``0``: every point given).
    pairs : at period ``p`` the last ``pairs`` points of the window are compared with the points ``p`` before them
        (a period needs ``p + pairs`` points); ``0``: every point of the window that has one ``p`` before it.
    agree : every pair within the limit (``all``), or the closest one (``closest``; ``absolute`` or ``window``
        scales only: one limit for every pair).
    strict : a return is ``d < limit`` (``True``) or ``d <= limit``.
    p_max : the longest period judged (``None``: the caller gives it at every call).
    """

    tol: float | None = None
    scale: str = "absolute"
    norm: str = "max"
    window: int = 0
    pairs: int = 0
    agree: str = "all"
    strict: bool = False
    p_max: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "tol", _check_tol(self.tol, "tol", none=True))
        for name, choices in (("scale", SCALES), ("norm", NORMS), ("agree", AGREE)):
            check_choice(name, getattr(self, name), choices)
        for name in ("window", "pairs"):
            object.__setattr__(self, name, _check_count(getattr(self, name), name, 0))
        if not isinstance(self.strict, bool | np.bool_):
            raise ParameterError(f"strict must be True or False, got {self.strict!r}")
        object.__setattr__(self, "strict", bool(self.strict))
        object.__setattr__(self, "p_max", _check_p_max(self.p_max, none=True))
        if self.agree == "closest" and self.scale not in ("absolute", "window"):
            raise ParameterError(f"agree='closest' needs one limit for every pair (scale absolute or window), "
                                 f"got scale {self.scale!r}")  # fmt: skip
        if self.window and self.pairs >= self.window:
            raise ParameterError(f"pairs must be fewer than the window's {self.window} points, got {self.pairs}")

    def with_(self, **changes: Any) -> RecurrenceRule:
        """A copy with ``changes`` (validated)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The rule as plain data (JSON)."""
        return asdict(self)

    def codes(self) -> tuple[int, int, int, int, bool, bool]:
        """``(scale, norm, window, pairs, closest, strict)`` as the kernel :func:`_judge` takes them."""
        return (SCALES.index(self.scale), NORMS.index(self.norm), self.window, self.pairs, self.agree == "closest",
                self.strict)  # fmt: skip


def _check_tol(v: Any, name: str, none: bool = False) -> float | None:
    if v is None and none:
        return None
    if isinstance(v, bool) or not isinstance(v, int | float | np.floating | np.integer) or not (0 <= v < math.inf):
        raise ParameterError(f"{name} must be a finite number >= 0, got {v!r}")
    return float(v)


def _check_count(v: Any, name: str, lo: int, hi: int = MAX_PERIOD * 100) -> int:
    return check_int(name, v, lo, hi)


def _check_p_max(v: Any, none: bool = False) -> int | None:
    if v is None and none:
        return None
    return _check_count(v, "p_max", 0, MAX_PERIOD)


#: The chart of regimes (and the periods of an orbit diagram's values, and ``bilimovich reproduce``): every pair
#: of the points given returns within ``tol (1 + max |x|)`` (max-norm). A chart's early look uses it over the
#: ring of its last ``3 p_max`` points (``window``); its final verdict over the measurement's second half. The
#: basins hand a member to Newton by it, over the same ring (once a preset of its own, ``BASIN``: the same rule,
#: merged; docs/architecture.md, "Recurrence").
CHART = RecurrenceRule(scale="window")
#: ``sweeps.detect_period``: every pair within an absolute ``tol`` (max-norm); a basin's located attractor uses it
#: with the diagonal of a cell.
SWEEP = RecurrenceRule(scale="absolute")
#: A chart's hand-over to Newton: the last 5 points return within ``3e-2 (1 + max |x|)`` of the ring's points
#: (max-norm; the chart asks for ``max(3e-2, tol)`` and fewer pairs if ``p_max`` is small; the measurements
#: behind the numbers are at ``regimes.SETTLE_TOL``).
NEAR = RecurrenceRule(tol=3e-2, scale="window", pairs=5)
#: An orbit diagram's settled members: the last 8 points return to ``tol (1 + |x_c|)`` per component, ``p <= 16``
#: (``bifurcation.SETTLE_TOL``; its jumps ask for ``JUMP_TOL``).
DIAGRAM = RecurrenceRule(tol=1e-9, scale="component", pairs=8, p_max=16)
#: A played frame's trajectories that settled: the last 3 points within ``1e-3 (1 + max(|q|, |r|))`` of the point
#: ``p`` before (Euclidean, strictly).
PLAY = RecurrenceRule(tol=1e-3, scale="point", norm="euclidean", pairs=3, strict=True)
#: Seeds from near-returns (``orbits.return_seeds``): the closest return at each period within an absolute
#: ``tol`` (Euclidean).
SEEDS = RecurrenceRule(scale="absolute", norm="euclidean", agree="closest")
#: Every preset by name.
PRESETS: dict[str, RecurrenceRule] = {
    "chart": CHART, "sweep": SWEEP, "near": NEAR, "diagram": DIAGRAM, "play": PLAY, "seeds": SEEDS,
}  # fmt: skip


class Recurrence(NamedTuple):
    """What :func:`recurrence` found; ``...`` is the shape of the members (``()`` for one trajectory).

    period : (...) the least ``p <= p_max`` with a return (0: none).
    limit : (...) the limit of a return, ``tol`` times the window's scale (``scale='window'``), else ``tol``; NaN
        where the window is not full.
    dist : (..., p_max) the distance at each period: the largest pair's (``all``) or the closest (``closest``),
        NaN if a pair's is; inf where there are too few points for the period. ``None`` unless asked for.
    at : (..., p_max) the index (among the points judged, oldest first) of the earlier point of that pair; -1 where
        there is none. ``None`` unless asked for.
    hit : (..., p_max) whether each period returns. ``None`` unless asked for.
    """

    period: np.ndarray
    limit: np.ndarray
    dist: np.ndarray | None = None
    at: np.ndarray | None = None
    hit: np.ndarray | None = None


def recurrence(
    points: np.ndarray,
    rule: RecurrenceRule,
    *,
    tol: float | None = None,
    p_max: int | None = None,
    count: np.ndarray | None = None,
    rows: np.ndarray | None = None,
    ring: bool = False,
    distances: bool = False,
) -> Recurrence:
    """Whether ``points`` repeat with a period ``p <= p_max`` under ``rule``, and the least such period.

    Parameters
    ----------
    points : (n, 2) consecutive section points of one trajectory, oldest first, or (m, n, 2) of ``m``.
    rule : the :class:`RecurrenceRule` (a preset of :data:`PRESETS`, or one of its ``with_`` copies).
    tol, p_max : the tolerance and longest period, if the rule leaves them to the caller (or to override them).
    count : (m,) the points of each member: its first ``count[i]`` (default every point); with ``ring``, the
        points written so far into its row of ``n``, point ``k`` at ``k % n`` (the last ``min(count, n)`` valid).
    rows : judge only the members ``rows`` (``count`` is then theirs); the answers are in that order.
    ring : the members are rings (see ``count``): a basin's, judged in place.
    distances : also return the distance, the pair and the verdict at every period (else the search stops at
        the least period, and at the first pair out of tolerance).
    """
    tol = _check_tol(rule.tol if tol is None else tol, "tol", none=True)
    p_max = _check_p_max(rule.p_max if p_max is None else p_max, none=True)
    if tol is None or p_max is None:
        raise ParameterError(f"the rule leaves {'tol' if tol is None else 'p_max'} to the caller: give it")
    x = np.asarray(points, dtype=float)
    one = x.ndim == 2
    if one:
        x = x[None]
    if x.ndim != 3 or x.shape[2] != 2:
        raise ParameterError(f"points must be (n, 2) or (m, n, 2), got shape {np.shape(points)}")
    x = np.ascontiguousarray(x)  # (no copy of a C-ordered float array: a basin's rings are judged in place)
    if not x.flags.writeable:
        x = x.copy()  # (a readonly array would compile the kernel again)
    n = x.shape[1]
    which = np.arange(x.shape[0], dtype=np.int64) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
    m = which.size
    if m and (which.min() < 0 or which.max() >= x.shape[0]):
        raise ParameterError(f"rows must be in [0, {x.shape[0] - 1}], got {which.min()}..{which.max()}")
    counts = np.full(m, n, dtype=np.int64) if count is None else np.asarray(count)
    counts = np.ascontiguousarray(np.broadcast_to(counts, (m,)), dtype=np.int64)
    if m and (counts.min() < 0 or (counts.max() > n and not ring)):
        raise ParameterError(f"count must be in [0, {n}] (the points given), got {counts.min()}..{counts.max()}")
    shape = (m, p_max) if distances else (0, 0)
    period = np.zeros(m, dtype=np.int64)
    limit = np.empty(m)
    dist, at, hit = np.empty(shape), np.empty(shape, dtype=np.int64), np.empty(shape, dtype=np.bool_)
    _judge(x, which, counts, bool(ring), p_max, tol, *rule.codes(), period, limit, dist, at, hit)
    if not distances:
        return Recurrence(period[0], limit[0]) if one else Recurrence(period, limit)
    if one:
        return Recurrence(period[0], limit[0], dist[0], at[0], hit[0])
    return Recurrence(period, limit, dist, at, hit)


@njit(nogil=True, cache=True)
def _judge(x: np.ndarray, rows: np.ndarray, count: np.ndarray, ring: bool, p_max: int, tol: float, scale: int,
           norm: int, window: int, pairs: int, closest: bool, strict: bool, period: np.ndarray, limit: np.ndarray,
           dist: np.ndarray, at: np.ndarray, hit: np.ndarray) -> None:  # fmt: skip
    """:func:`recurrence` of the members ``x[rows[i]]`` (the rule as :meth:`RecurrenceRule.codes`).

    ``dist``, ``at``, ``hit`` are (m, p_max) to fill, or (0, 0): then each member stops at its least period, and a
    period at its first pair out of tolerance (the verdicts are the same).
    """
    full = dist.shape[0] > 0
    w = x.shape[1]
    for i in range(rows.shape[0]):
        r = rows[i]
        period[i] = 0
        limit[i] = math.nan
        if full:
            for p in range(p_max):
                dist[i, p], at[i, p], hit[i, p] = math.inf, -1, False
        c = min(count[i], w)  # valid points; the j-th (oldest first) at x[r, base + j], or + w if negative (a ring)
        base = (count[i] - c) % w if ring and c > 0 else 0
        if base + c > w:
            base -= w
        if window > 0:
            if c < window:
                continue
            n = window
        else:
            n = c
        first = c - n  # the window's oldest point
        lim = tol
        if scale == 1:  # the window's largest |x| (NaN propagates: then nothing returns)
            big = 0.0
            for j in range(first, c):
                jj = base + j
                jj += w if jj < 0 else 0
                for k in range(2):
                    v = abs(x[r, jj, k])
                    if v > big or v != v:
                        big = v
                if big != big:
                    break
            lim = tol * (1.0 + big)
        limit[i] = lim
        for p in range(1, p_max + 1):
            if pairs > 0:
                lo = c - pairs  # the later points: the last `pairs`
                if lo - p < first:
                    continue
            else:
                lo = first + p  # every point with one p before it in the window
                if lo >= c:
                    continue
            red = math.nan
            where = -1
            ok = True
            for j in range(lo, c):
                a = base + j
                a += w if a < 0 else 0
                b = base + j - p
                b += w if b < 0 else 0
                dq = x[r, a, 0] - x[r, b, 0]
                dr = x[r, a, 1] - x[r, b, 1]
                if norm == 0:
                    aq, ar = abs(dq), abs(dr)
                    d = aq if (aq >= ar or aq != aq) else ar
                else:
                    d = math.sqrt(dq * dq + dr * dr)
                if closest:  # the first least distance (the first NaN, as numpy's argmin)
                    if where < 0 or (red == red and (d != d or d < red)):
                        red, where = d, j - p - first
                    continue
                if full and (where < 0 or (red == red and (d != d or d > red))):
                    red, where = d, j - p - first  # the first largest distance (the first NaN, as argmax)
                if scale == 3:  # per component, relative to the later point
                    lq = tol * (1.0 + abs(x[r, a, 0]))
                    lr = tol * (1.0 + abs(x[r, a, 1]))
                    good = (abs(dq) < lq and abs(dr) < lr) if strict else (abs(dq) <= lq and abs(dr) <= lr)
                else:
                    if scale == 2:  # relative to the later point's largest component
                        aq, ar = abs(x[r, a, 0]), abs(x[r, a, 1])
                        lim = tol * (1.0 + (aq if (aq >= ar or aq != aq) else ar))
                    good = d < lim if strict else d <= lim
                if not good:
                    ok = False
                    if not full:
                        break
            if closest:
                ok = red < lim if strict else red <= lim
            if full:
                dist[i, p - 1], at[i, p - 1], hit[i, p - 1] = red, where, ok
            if ok and period[i] == 0:
                period[i] = p
                if not full:
                    break
