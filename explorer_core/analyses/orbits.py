"""Periodic orbits of the Poincare map: fixed points of ``P^n``, their multipliers and their type.

An orbit of period ``n`` is a solution of ``F(x) = P^n(x) - x = 0``. Newton's method uses the exact
derivative ``DP^n(x)``: the monodromy matrix of the tangent system (:mod:`explorer_core.solve.tangent`),
integrated with the state by the one engine and landing exactly on the section times. Many seeds are
iterated together (one lock-step batch per period and iteration). Globalisation is a trust region on
the step: a step is at most ``max_step`` long, and an iterate whose residual did not decrease (or whose
trajectory failed, e.g. escaped) is pulled half way back with the radius halved.

Each orbit reports its ``n`` points (starting with the lexicographically smallest: cyclic shifts are one
orbit), its multipliers ``mu1, mu2`` (eigenvalues of ``DP^n``, largest modulus first), ``det DP^n``
checked against Liouville's ``exp(int div dt)`` over the ``n`` periods, the residual, the iterations and
its type (:func:`classify`). The period is minimal: a fixed point found as a 2-cycle is reported as a
fixed point. A seed where Newton fails is a :class:`OrbitFailure` with its reason, never an orbit.

Reference: Kuznetsov, *Elements of Applied Bifurcation Theory*, ch. 10 (fixed points of maps);
MatContM (Govaerts, Kuznetsov, Meijer et al.) for the same objects in MATLAB.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.specs import Checking
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step
from explorer_core.progress import run as run_updates
from explorer_core.solve import poincare
from explorer_core.solve.checks import check_fraction, check_point
from explorer_core.solve.numerics import Numerics, check_box, check_ics, check_int, random_ics
from explorer_core.solve.options import (
    BOOL,
    ORBITS,
    Arg,
    NewtonOptions,
    declare,
    instance,
    integer,
    ints,
    optional_of,
)
from explorer_core.solve.options import box as box_check
from explorer_core.solve.poincare import PATIENCE, NewtonResult, PoincareMap, least_period
from explorer_core.solve.recurrence import PLAY, SEEDS, recurrence
from explorer_core.solve.tangent import Monodromy
from explorer_core.status import Status
from explorer_core.system.params import ParameterError, Params

#: Integration settings for orbits: the residual can only be as small as ``P^n`` is accurate. The settings are
#: the ``ORBITS`` preset of :class:`~explorer_core.solve.options.NewtonOptions` (declared there once): vern9 at
#: 1e-12 by the "auto" rule, ``|P^n(x) - x| <= 1e-9 (1 + |x|)``, 40 iterations.
ORBIT_NUMERICS = Numerics(rtol=ORBITS.rtol, atol=ORBITS.rtol)
#: Longest period searched (``P^n`` of a chaotic region has multipliers ~ e^(lambda n T): Newton's basin shrinks).
MAX_PERIOD = 64
FTOL = ORBITS.ftol
MAX_ITER = ORBITS.max_iter
#: ``det DP^n`` below this many ulps of ``max |DP^n|^2`` is rounding noise (see :func:`orbit_from`).
DET_ROUNDING = 64.0
#: ``|mu| = 1`` within this: neutral (real) or elliptic (complex pair).
UNIT_TOL = 1e-6
TYPES = ("stable node", "stable focus", "unstable node", "unstable focus", "saddle", "flip saddle", "elliptic",
         "neutral")  # fmt: skip


@dataclass(frozen=True)
class Orbit(Drawable):
    """A periodic orbit of the Poincare map (see the module docstring).

    ``points`` (n, 2): ``x, P(x), ..., P^(n-1)(x)``; ``matrix`` (2, 2): ``DP^n`` at ``points[0]``;
    ``multipliers`` (2,) complex, largest modulus first; ``det`` = ``det DP^n``; ``liouville`` =
    ``exp(int_0^{nT} div dt)`` (equal to ``det`` up to integration error); ``residual`` =
    ``|P^n(x) - x|`` at ``points[0]``.
    """

    period: int
    points: np.ndarray
    matrix: np.ndarray
    multipliers: np.ndarray
    det: float
    liouville: float
    residual: float
    iterations: int
    kind: str
    seed: tuple[float, float] = (math.nan, math.nan)
    #: False when ``det DP^n`` is below the rounding of its entries: ``det`` (and the small real multiplier)
    #: are then Liouville's ``exp(int div dt)`` (and it over ``mu1``).
    det_resolved: bool = True

    @property
    def stable(self) -> bool:
        """Asymptotically stable: every multiplier inside the unit circle (beyond :data:`UNIT_TOL`)."""
        return bool(np.all(np.abs(self.multipliers) < 1.0 - UNIT_TOL))

    def as_dict(self) -> dict[str, Any]:
        return {
            "period": self.period,
            "points": [[float(q), float(r)] for q, r in self.points],
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "type": self.kind,
            "stable": self.stable,
            "det": float(self.det),
            "liouville": float(self.liouville),
            "residual": float(self.residual),
            "iterations": int(self.iterations),
            "seed": [float(self.seed[0]), float(self.seed[1])],
            "det_resolved": self.det_resolved,
        }


@dataclass(frozen=True)
class OrbitFailure:
    """A seed where Newton did not find an orbit of the asked period, and why (``status``: the one vocabulary)."""

    seed: tuple[float, float]
    period: int
    reason: str
    iterations: int
    status: Status = Status.NOT_CONVERGED

    def as_dict(self) -> dict[str, Any]:
        return {"seed": [float(self.seed[0]), float(self.seed[1])], "period": self.period, "status": self.status.label,
                "reason": self.reason, "iterations": self.iterations}  # fmt: skip


@dataclass(frozen=True)
class OrbitSearch(Drawable):
    """The distinct orbits found from a set of seeds, and the seeds that found none."""

    params: Params
    numerics: Numerics
    orbits: list[Orbit]
    failures: list[OrbitFailure]
    seeds: int
    elapsed_s: float
    completed: bool = True
    extra: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        return {
            "orbits": [o.as_dict() for o in self.orbits],
            "failures": [f.as_dict() for f in self.failures],
            "seeds": self.seeds,
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
            **self.extra,
        }

    @property
    def lost(self) -> list[Loss]:
        """Searches a cancel stopped (Newton's from a seed for a period, unfinished or never run): the orbits they
        would have found are not here. A seed that found none is an outcome (``failures``), not a loss."""
        if self.completed:
            return []
        stopped = sum(f.status in (Status.CANCELLED, Status.NOT_RUN) for f in self.failures)
        stopped += int(self.extra.get("unsearched", 0))  # the seed groups a cancel left (orbit_search)
        return [Loss("searches", stopped, "cancelled before they ended")] if stopped else []

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def report(self) -> list[str]:
        """What the command line prints: one line per orbit (period, type, first point, multipliers)."""
        out = []
        for o in self.orbits:
            mu = ", ".join(f"{m.real:.6g}{m.imag:+.6g}i" if m.imag else f"{m.real:.6g}" for m in o.multipliers)
            out.append(f"period {o.period} {o.kind:15s} at ({o.points[0, 0]:.10g}, {o.points[0, 1]:.10g})  mu = {mu}")
        return [*out, f"{len(self.orbits)} orbits, {len(self.failures)} seeds without one, {self.elapsed_s:.2f} s"]

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "orbit search"
        )

    def to_csv(self, path: str) -> int:
        """One row per orbit point: ``orbit,period,type,stable,j,q,r,mu1_re,mu1_im,mu2_re,mu2_im``, whole or not at
        all; a cancelled search says so after its header (``# `` lines)."""
        rows = 0
        with export.atomic(path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["orbit", "period", "type", "stable", "j", "q", "r", "mu1_re", "mu1_im", "mu2_re", "mu2_im"])
            fh.writelines(export.comment_lines(export.partial(self)))
            for i, o in enumerate(self.orbits):
                mu = o.multipliers
                for j, (q, r) in enumerate(o.points):
                    w.writerow([i, o.period, o.kind, int(o.stable), j, float(q), float(r), float(mu[0].real),
                                float(mu[0].imag), float(mu[1].real), float(mu[1].imag)])  # fmt: skip
                    rows += 1
        return rows


# ---------------------------------------------------------------------------
# Multipliers and types.


def multipliers(matrix: np.ndarray) -> np.ndarray:
    """Eigenvalues of a 2x2 matrix (complex), largest modulus first."""
    mu = np.linalg.eigvals(np.asarray(matrix, dtype=float)).astype(complex)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def classify(mu: np.ndarray, unit_tol: float = UNIT_TOL) -> str:
    """Type of a fixed point of a planar map from its multipliers (one of :data:`TYPES`).

    Complex pair: focus (stable inside the unit circle, unstable outside) or elliptic (on it). Real:
    a node (both inside, or both outside), a saddle (one each side; a *flip* saddle when the
    expanding multiplier is negative, so the unstable manifold flips sides each iterate), or neutral
    when a multiplier is on the unit circle.
    """
    mu = np.asarray(mu, dtype=complex)
    a = np.abs(mu)
    if abs(mu[0].imag) > unit_tol * max(1.0, a[0]):
        if abs(a[0] - 1.0) <= unit_tol:
            return "elliptic"
        return "stable focus" if a[0] < 1.0 else "unstable focus"
    if np.any(np.abs(a - 1.0) <= unit_tol):
        return "neutral"
    if a[0] < 1.0:
        return "stable node"
    if a[1] > 1.0:
        return "unstable node"
    return "flip saddle" if mu[0].real < 0.0 else "saddle"


# ---------------------------------------------------------------------------
# Newton on P^n(x) - x, many seeds at once.


def newton(
    params: Params,
    seeds: np.ndarray,
    periods: np.ndarray,
    *,
    numerics: Numerics = ORBIT_NUMERICS,
    ftol: float = FTOL,
    max_iter: int = MAX_ITER,
    max_step: float = 1.0,
    patience: int | None = PATIENCE,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> tuple[list[tuple[int, np.ndarray, Monodromy, int]], list[OrbitFailure]]:
    """:func:`~explorer_core.solve.poincare.newton` under one system (low-level call).

    Returns the converged ``(i, x, monodromy at x, iterations)`` and the failures with their reasons; seeds
    that ran into an orbit already found stop as duplicates (in neither list). The period of a converged
    point is the one asked (see :func:`find_orbits` for the least one).
    """
    res = _newton(params, seeds, periods, numerics=numerics, ftol=ftol, max_iter=max_iter, max_step=max_step,
                  patience=patience, cancel=cancel, workers=workers)  # fmt: skip
    return [(c.i, c.x, c.mono, c.iterations) for c in res.converged], _failures(res, seeds)


def _newton(params: Params, seeds: np.ndarray, periods: np.ndarray, *, numerics: Numerics, workers: int | None,
            **kw: Any) -> NewtonResult:  # fmt: skip
    return poincare.newton(PoincareMap.of(params, numerics, workers=workers), seeds, periods, **kw)


def _failures(res: NewtonResult, seeds: np.ndarray) -> list[OrbitFailure]:
    return [OrbitFailure((float(seeds[f.i, 0]), float(seeds[f.i, 1])), f.period, f.reason, f.iterations, f.status)
            for f in res.failures]  # fmt: skip


def at_least_orbit_accuracy(numerics: Numerics) -> Numerics:
    """``numerics`` at least as accurate as an orbit's (:data:`ORBIT_NUMERICS`: 1e-12), the method chosen again
    by the rule if it chose: the map a saddle and its eigenvectors are computed on before its manifolds grow."""
    return numerics.loosened(min(numerics.rtol, ORBIT_NUMERICS.rtol))


def orbit_from(
    params: Params,
    x: np.ndarray,
    period: int,
    mono: Monodromy,
    iterations: int,
    seed: Any,
    unit_tol: float = UNIT_TOL,
    numerics: Numerics = ORBIT_NUMERICS,
) -> Orbit:
    """An :class:`Orbit` from a converged point ``x`` and the monodromy of ``period`` periods there (computed on
    ``numerics``, the map Newton ran on: the matrix at another point of the orbit is computed on it too)."""
    pts = np.vstack([x[None, :], mono.points[0, : period - 1]])
    shift = int(np.lexsort((pts[:, 1], pts[:, 0]))[0])
    a = mono.matrix[0]
    if shift:
        # DP^n at another point of the orbit is conjugate (same multipliers); recompute it there exactly.
        x0 = pts[shift]
        mono = PoincareMap.of(params, numerics).derivative(x0, period)
        a = mono.matrix[0]
        pts = np.roll(pts, -shift, axis=0)
        res = float(np.linalg.norm(mono.end[0] - x0))
    else:
        res = float(np.linalg.norm(mono.end[0] - x))
    mu = multipliers(a)
    liouville = math.exp(float(mono.div[0]))
    det = float(np.linalg.det(a))
    # det from the entries carries a rounding error ~eps |a|^2: on a long, strongly contracting orbit it is all
    # noise (of either sign). Liouville's exp(int div dt) is the same number without the cancellation.
    resolved = abs(det) > DET_ROUNDING * np.finfo(float).eps * float(np.abs(a).max()) ** 2
    if not resolved:
        det = liouville
        if abs(mu[0].imag) == 0.0 and mu[0] != 0:
            mu = np.array([mu[0], liouville / mu[0].real], dtype=complex)  # mu1 mu2 = det
    return Orbit(period, pts, a, mu, det, liouville, res, int(iterations), classify(mu, unit_tol),
                 (float(seed[0]), float(seed[1])), det_resolved=bool(resolved))  # fmt: skip


def minimal_period(points: np.ndarray, end: np.ndarray, period: int, tol: float) -> int:
    """The least ``d`` dividing ``period`` with ``P^d(x) = x`` within ``tol`` (``points`` are ``x, P(x), ...``)."""
    return least_period(points, period, tol * (1.0 + float(np.linalg.norm(points[0]))))


def same_orbit(a: Orbit, b: Orbit, tol: float = 1e-6) -> bool:
    """True for the same period and a shared point (any cyclic shift)."""
    if a.period != b.period:
        return False
    d = np.linalg.norm(a.points[:, None, :] - b.points[None, 0, :], axis=-1)
    return bool(d.min() <= tol * (1.0 + np.linalg.norm(b.points[0])))


def find_orbits(
    params: Params,
    seeds: Any,
    periods: Sequence[int] | int,
    *,
    numerics: Numerics | None = None,
    ftol: float = FTOL,
    max_iter: int = MAX_ITER,
    max_step: float = 1.0,
    patience: int | None = PATIENCE,
    coarse: bool = ORBITS.coarse,
    bound: Sequence[float] | None = None,
    unit_tol: float = UNIT_TOL,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> OrbitSearch:
    """The distinct periodic orbits Newton finds from every seed for every period in ``periods``.

    Parameters
    ----------
    seeds : (m, 2) points of the section at ``t0``.
    periods : one period or several (each seed is tried with each); at most :data:`MAX_PERIOD`.
    numerics : integration of ``P^n`` (default :data:`ORBIT_NUMERICS`, vern9 at 1e-12 by the "auto" rule).
    ftol : convergence: ``|P^n(x) - x| <= ftol (1 + |x|)``.
    max_step : the trust radius: a Newton step moves at most this far.
    patience : a seed stops after this many iterations without halving its residual (None: only
        ``max_iter`` stops it; slower, finds slowly converging orbits from more seeds).
    coarse : the first iterations on a less accurate map (:func:`~explorer_core.solve.poincare.newton`).
    bound : ``(q0, q1, r0, r1)``: orbits with a point outside are dropped (counted in ``extra``).
    cancel : polled between iterations; True stops with ``completed=False``.

    Returns
    -------
    OrbitSearch : orbits sorted by period, then position; failures with their reasons.
    """
    start = time.perf_counter()
    numerics = numerics or ORBIT_NUMERICS
    seeds = check_ics(seeds)
    per = [periods] if isinstance(periods, int | np.integer) else list(periods)
    if not per:
        raise ParameterError("give at least one period")
    per = [check_int("period", p, 1, MAX_PERIOD) for p in per]
    ftol = check_fraction("ftol", ftol)
    check_int("max_iter", max_iter, 1, 10_000)
    if not (math.isfinite(max_step) and max_step > 0):
        raise ParameterError(f"max_step must be a positive number, got {max_step!r}")
    box = check_box(bound, "bound") if bound is not None else None
    if seeds.shape[0] * len(per) > config.MAX_TRAJECTORIES:
        raise ParameterError(f"{seeds.shape[0]} seeds x {len(per)} periods exceeds {config.MAX_TRAJECTORIES}")
    all_seeds = np.repeat(seeds, len(per), axis=0)
    all_periods = np.tile(np.array(per, dtype=np.int64), seeds.shape[0])
    res = _newton(params, all_seeds, all_periods, numerics=numerics, ftol=ftol, max_iter=max_iter,
                  max_step=max_step, patience=patience, coarse=coarse, cancel=cancel, workers=workers)  # fmt: skip
    failures = _failures(res, all_seeds)
    orbits: list[Orbit] = []
    outside = 0
    for c in res.converged:
        mono, n = c.mono, int(all_periods[c.i])
        if c.least < n:
            mono, n = PoincareMap.of(params, numerics).derivative(c.x, c.least), c.least  # the orbit's own period
        orb = orbit_from(params, c.x, n, mono, c.iterations, all_seeds[c.i], unit_tol, numerics)
        if box is not None and not np.all(
            (orb.points[:, 0] >= box[0])
            & (orb.points[:, 0] <= box[1])
            & (orb.points[:, 1] >= box[2])
            & (orb.points[:, 1] <= box[3])
        ):
            outside += 1
            continue
        if not any(same_orbit(o, orb) for o in orbits):
            orbits.append(orb)
    orbits.sort(key=lambda o: (o.period, float(o.points[0, 0]), float(o.points[0, 1])))
    return OrbitSearch(params, numerics, orbits, failures, int(seeds.shape[0]), time.perf_counter() - start,
                       completed=not (cancel is not None and cancel()),
                       extra={"periods": per, "outside_bound": outside})  # fmt: skip


# ---------------------------------------------------------------------------
# Seeds.


#: The one ladder of distances (relative to ``1 + |x|``) at which a new orbit is sought along a multiplier's
#: eigenvector from an orbit's point: the doubled orbit at a period doubling (the continuation's branch switching,
#: tried nearest first until Newton lands on it) and, while a parameter is played, the orbit born at a doubling or
#: the partner born at a fold since the last frame (the app's following). The born orbit's distance grows like
#: the square root of the parameter's distance from the bifurcation: the continuation switches at the doubling
#: itself (the short rungs), a played frame may be well past it (the long ones).
SWITCH_LADDER = (1e-3, 3e-3, 1e-2, 3e-2, 1e-1)


def eigenvector(matrix: np.ndarray, mu: float) -> np.ndarray:
    """The unit (real part of the) eigenvector of ``matrix`` whose multiplier is nearest ``mu`` (-1: a doubling's,
    +1: a fold's)."""
    w, vecs = np.linalg.eig(matrix)
    v = np.real(vecs[:, int(np.argmin(np.abs(w - mu)))])
    return v / np.linalg.norm(v)


def ladder_seeds(x: np.ndarray, v: np.ndarray, *, both: bool = False,
                 ladder: Sequence[float] = SWITCH_LADDER) -> list[np.ndarray]:  # fmt: skip
    """Points from the orbit's point ``x`` along the unit direction ``v`` at the distances of ``ladder`` (relative
    to ``1 + |x|``), nearest first; ``both``: on both sides."""
    scale = 1.0 + float(np.abs(x).max())
    return [x + s * h * scale * v for h in ladder for s in ((1.0, -1.0) if both else (1.0,))]


def pixel_centres(box: Sequence[float], nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """The centres ``q`` (nx,) and ``r`` (ny,) of an ``nx`` x ``ny`` grid of pixels over ``box = (q0, q1, r0, r1)``
    (validated by the caller)."""
    q0, q1, r0, r1 = box
    return q0 + (np.arange(nx) + 0.5) * (q1 - q0) / nx, r0 + (np.arange(ny) + 0.5) * (r1 - r0) / ny


def grid_seeds(box: Sequence[float], nx: int, ny: int) -> np.ndarray:
    """Pixel centres of an ``nx`` x ``ny`` grid over ``box = (q0, q1, r0, r1)``, row-major (row ``j`` at ``r[j]``)."""
    q, r = pixel_centres(
        check_box(box), check_int("nx", nx, 1, config.MAX_GRID), check_int("ny", ny, 1, config.MAX_GRID)
    )
    qq, rr = np.meshgrid(q, r)
    return np.column_stack([qq.ravel(), rr.ravel()])


def return_seeds(points: np.ndarray, npts: np.ndarray, max_period: int, tol: float) -> list[tuple[np.ndarray, int]]:
    """Near-returns of computed section points: candidates ``(x_k, n)`` with ``|x_(k+n) - x_k| <= tol``.

    ``points`` (traj, k, 2) with ``npts[traj]`` valid; for each trajectory and each ``n`` the closest
    return (the orbit is near where the trajectory almost repeats itself after ``n`` iterations; the rule
    :data:`~explorer_core.solve.recurrence.SEEDS`).
    """
    pts = np.asarray(points, dtype=float)
    count = np.minimum(np.asarray(npts, dtype=np.int64), pts.shape[1])
    found = recurrence(pts, SEEDS, tol=tol, p_max=max_period, count=count, distances=True)
    return [(pts[t, found.at[t, j]].copy(), int(j) + 1) for t, j in zip(*np.nonzero(found.hit), strict=True)]


def settled_seeds(traj: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray, max_period: int,
                  near: float) -> list[tuple[float, float, int]]:  # fmt: skip
    """The cycles trajectories end on, ``(q, r, n)`` each (the last point and the least period ``n <= max_period``),
    one per cycle: a trajectory whose last points repeat with period ``n`` by the rule
    :data:`~explorer_core.solve.recurrence.PLAY` (3 points, each within ``1e-3 (1 + |x|)`` of the point ``n``
    before). A trajectory ending within ``near`` (relative to ``1 + |x|``) of a cycle found before adds nothing.

    The points are given as columns: trajectory ``traj``, index ``k`` along it, ``(q, r)``, in any order.
    Chaotic, quasi-periodic, escaping or still transient trajectories, those with fewer than ``PLAY.pairs +
    max_period`` points (every period is judged on the same points), and cycles longer than ``max_period`` give
    none. One sort of the points and one call on every trajectory's tail (a frame may have thousands of them).
    """
    need = PLAY.pairs + max_period
    if max_period < 1 or traj.size == 0:
        return []
    order = np.lexsort((k, traj))
    t_sorted = traj[order]
    ends = np.flatnonzero(np.r_[t_sorted[1:] != t_sorted[:-1], True])  # the last point of each trajectory
    starts = np.r_[0, ends[:-1] + 1]
    ends = ends[ends - starts + 1 >= need]
    if ends.size == 0:
        return []
    idx = order[ends[:, None] + np.arange(1 - need, 1)]  # (trajectories, need): each one's last points, in k order
    x = np.stack([q[idx], r[idx]], axis=-1)
    period = recurrence(x, PLAY, p_max=max_period).period  # 0: not settled (yet)
    out: list[tuple[float, float, int]] = []
    tails: list[np.ndarray] = []  # the points of each cycle found (a second trajectory on it adds nothing)
    for i in np.flatnonzero(period):
        n, end = int(period[i]), x[i, -1]
        scale = near * (1.0 + float(np.abs(end).max()))
        if not any(np.linalg.norm(c - end, axis=1).min() < scale for c in tails):
            tails.append(x[i, -n:])
            out.append((float(end[0]), float(end[1]), n))
    return out


# ---------------------------------------------------------------------------
# A search as a spec: where the seeds come from, which periods, the numerics and Newton's options.


@dataclass(frozen=True)
class OrbitSpec:
    """What defines a search for periodic orbits (``bilimovich orbits``), made by :func:`orbit_spec`.

    ``seeds`` are tried with every period of ``periods``; ``grid`` (NX, NY) adds the pixel centres of a grid over
    ``box``; ``returns`` adds the near-returns of a section of that many random trajectories in ``box`` (each
    with its own period); ``in_box`` keeps only orbits whose points are all in ``box``. Newton iterates the map
    of ``numerics`` to ``newton.ftol``.
    """

    params: Params
    periods: tuple[int, ...]
    seeds: tuple[tuple[float, float], ...]
    box: tuple[float, float, float, float]
    grid: tuple[int, int] | None
    returns: int | None
    in_box: bool
    numerics: Numerics
    newton: NewtonOptions

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "periods": list(self.periods), "seeds": [list(s) for s in self.seeds],
                "box": list(self.box), "grid": None if self.grid is None else list(self.grid),
                "returns": self.returns, "in_box": self.in_box, "numerics": self.numerics.as_dict(),
                "newton": self.newton.as_dict()}  # fmt: skip


@declare(
    period=Arg("this period only", "int", default=None, check=integer(1, MAX_PERIOD, optional=True)),
    max_period=Arg("periods 1..N (default 1)", "int", default=None, check=integer(1, MAX_PERIOD, optional=True)),
    seeds=Arg("a starting point (repeatable)", "points", flag="--seed", default=(), checked_with=("numerics",)),
    box=Arg(
        "the box of the grid of seeds and of --returns",
        "box",
        metavar="Q0,Q1,R0,R1",
        scene="box",
        default=(-2.0, 2.0, -2.0, 2.0),
        check=box_check(),
    ),
    grid=Arg(
        "a grid of NX x NY seeds over --box (default 10,10 without --seed)",
        "ints",
        flag="--seeds",
        metavar="NX,NY",
        default=None,
        check=ints(2, 1, config.MAX_GRID, optional=True),
    ),
    returns=Arg(
        "also seed from near-returns of a section of N random trajectories in the box",
        "int",
        metavar="N",
        default=None,
        check=integer(1, 10_000, optional=True),
    ),
    in_box=Arg("keep only orbits whose points are all in the box", "switch", default=False, check=BOOL),
    thorough=Arg("no early stop of slow seeds (slower, finds more)", "switch", default=False, check=BOOL),
    numerics=Arg(
        "the map Newton iterates", cli=False, default=ORBIT_NUMERICS, check=optional_of(Numerics, ORBIT_NUMERICS)
    ),
    newton=Arg("Newton's options", cli=False, default=ORBITS, check=instance(NewtonOptions)),
)
def orbit_spec(
    params: Params,
    *,
    period: int | None,
    max_period: int | None,
    seeds: Any,
    box: tuple[float, float, float, float],
    grid: tuple[int, int] | None,
    returns: int | None,
    in_box: bool,
    thorough: bool,
    numerics: Numerics,
    newton: NewtonOptions,
) -> OrbitSpec:
    """A validated :class:`OrbitSpec`; a bad value raises ParameterError naming it (``exc.option``: its keyword).

    ``period`` (that period only) or ``max_period`` (periods 1..N; default 1), not both, in [1, MAX_PERIOD].
    Without ``seeds`` nor ``returns`` the seeds are a 10 x 10 ``grid``. ``thorough``: no early stop of slow seeds
    and 80 iterations (``newton`` with ``patience=None, max_iter=80``). The options are declared above: defaults,
    checks (run before this body), flags.
    """
    with Checking() as at:
        at("period")
        if period is not None and max_period is not None:
            raise ParameterError(
                f"give period (that period only) or max_period (1..N), not both: {period}, {max_period}"
            )
        cap = period or max_period or 1
        periods = (cap,) if period is not None else tuple(range(1, cap + 1))
        at("seeds")
        points = () if seeds is None or len(seeds) == 0 else tuple(
            check_point("seed", s, numerics.bound) for s in np.asarray(seeds, dtype=float).reshape(-1, 2))  # fmt: skip
        grid_ = grid
        if grid_ is None and not (points or returns):
            grid_ = (10, 10)
        if thorough:
            newton = newton.replace(patience=None, max_iter=80)
    return OrbitSpec(params, periods, points, box, grid_, returns, in_box, numerics, newton)  # type: ignore[arg-type]


def iter_orbit_search(spec: OrbitSpec, cancel: Callable[[], bool] | None = None) -> Iterator[Step[OrbitSearch]]:
    """The search of ``spec``: one Newton per group of seeds with the same periods (progress in seed groups); the
    last update's result is the :class:`OrbitSearch` (distinct orbits sorted by period, then position)."""
    start = time.perf_counter()
    pairs: list[tuple[tuple[float, float], tuple[int, ...]]] = [(s, spec.periods) for s in spec.seeds]
    if spec.grid is not None:
        pairs += [((float(q), float(r)), spec.periods) for q, r in grid_seeds(spec.box, *spec.grid)]
    if spec.returns:
        from explorer_core.solve.section import section

        sec = section(spec.params, random_ics(spec.returns, spec.box, seed=0), 200, transient=300,
                      numerics=spec.numerics)  # fmt: skip
        tol = 0.02 * max(spec.box[1] - spec.box[0], spec.box[3] - spec.box[2])
        pairs += [((float(x[0]), float(x[1])), (n,)) for x, n in
                  return_seeds(sec.points, sec.npts, spec.periods[-1], tol) if n in spec.periods]  # fmt: skip
    by_periods: dict[tuple[int, ...], list[tuple[float, float]]] = {}
    for seed, per in pairs:
        by_periods.setdefault(per, []).append(seed)
    found: list[Orbit] = []
    failures: list[OrbitFailure] = []
    work = 0.0
    done, completed = 0, True
    opts = spec.newton
    for per, group in by_periods.items():
        yield Step(Progress(done, len(by_periods), "seed groups", time.perf_counter() - start),
                   f"{len(group)} seeds x periods {per[0]}..{per[-1]}")  # fmt: skip
        res = find_orbits(spec.params, np.array(group), list(per), numerics=spec.numerics, ftol=opts.ftol,
                          max_iter=opts.max_iter, max_step=opts.max_step, patience=opts.patience, coarse=opts.coarse,
                          bound=spec.box if spec.in_box else None, cancel=cancel)  # fmt: skip
        work += res.elapsed_s
        failures += res.failures
        for o in res.orbits:  # one by one: an orbit of this group is compared with those added before it too
            if not any(same_orbit(o, f) for f in found):
                found.append(o)
        if not res.completed:
            completed = False
            break
        done += 1
    found.sort(key=lambda o: (o.period, float(o.points[0, 0]), float(o.points[0, 1])))
    left = sum(len(g) * len(p) for p, g in list(by_periods.items())[done + 1 :]) if not completed else 0
    result = OrbitSearch(spec.params, spec.numerics, found, failures, len(pairs), work, completed,
                         {"periods": list(spec.periods), "spec": spec.as_dict(), "unsearched": left})  # fmt: skip
    yield Step(Progress(done, max(1, len(by_periods)), "seed groups", time.perf_counter() - start), None, result)


def orbit_search(
    spec: OrbitSpec, progress: Callable[[Any], None] | None = None, cancel: Callable[[], bool] | None = None
) -> OrbitSearch:
    """:func:`iter_orbit_search` run to its end (``progress`` gets every update)."""
    return run_updates(iter_orbit_search(spec, cancel=cancel), progress)
