"""The Poincare map as an object with verbs, and the one Newton on ``P^n(x) - x``.

``P`` is the stroboscopic map over one forcing period (the paper's poi-map): ``x_(k+1) = P(x_k)``,
``x_k = (q, r)(t0 + k T)``. A :class:`PoincareMap` holds what an analysis needs to ask for it -- the
system (one parameter set for every point, or one per member) and the numerics -- and answers with
verbs, as DynamicalSystemsBase's ``StroboscopicMap`` and ``TangentDynamicalSystem`` do:

* :meth:`PoincareMap.iterate`: the section points of a batch, streamed in chunks (cancellable);
* :meth:`PoincareMap.start` and :meth:`PoincareMap.advance`: a batch of trajectories at the section, moved
  on by ``n`` iterates (section points, statuses), for analyses that keep their own loop;
* :meth:`PoincareMap.derivative`: ``P^n(x)`` with ``DP^n(x)`` (the monodromy of the tangent system) and
  the members' statuses.

Analyses use the verbs and never assemble kernel inputs themselves. :func:`newton` is the one Newton on
``F(x) = P^n(x) - x`` (batched over seeds and periods, a trust region, a coarse map far from the orbit,
the least period of every converged point); periodic orbits, continuation's start, the charts' cycle
detection, basins and manifolds all go through it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from explorer_core.solve import rk
from explorer_core.solve.integrators import Batch, coefficients, run, run_at
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import SectionChunk, iter_section
from explorer_core.solve.tangent import Monodromy, monodromy, monodromy_at
from explorer_core.status import Status
from explorer_core.system.model import Model
from explorer_core.system.params import Params


@dataclass(frozen=True)
class PoincareMap:
    """``P`` for one parameter set, or one per member (see the module docstring).

    Build it with :meth:`of` (one system), :meth:`members` (one :class:`Params` per member: members that
    share the section times run in lock-step blocks, so finite differences in a parameter see one step
    sequence) or :meth:`rows` (a chart's members: a coefficient table per row, one ``t0`` and period).
    ``workers`` and ``block`` say how its integrations are spread (a map used inside a worker thread
    takes ``workers=1``).
    """

    numerics: Numerics
    params: tuple[Params, ...] = ()
    coefs: rk.Coefficients | None = None
    t0: float = 0.0
    period: float = 2.0 * math.pi
    workers: int | None = None
    block: int = 32

    @classmethod
    def of(cls, params: Params, numerics: Numerics | None = None, **kw: Any) -> PoincareMap:
        return cls(numerics or Numerics(), (params,), **kw)

    @classmethod
    def members(cls, params: Sequence[Params], numerics: Numerics, **kw: Any) -> PoincareMap:
        return cls(numerics, tuple(params), **kw)

    @classmethod
    def rows(cls, coefs: rk.Coefficients, t0: float, period: float, numerics: Numerics, **kw: Any) -> PoincareMap:
        return cls(numerics, (), coefs, float(t0), float(period), **kw)

    @property
    def shared(self) -> bool:
        """One system for every point."""
        return self.coefs is None and len(self.params) == 1

    def with_numerics(self, numerics: Numerics) -> PoincareMap:
        return replace(self, numerics=numerics)

    @cached_property
    def model(self) -> Model:
        """The coefficient tables of a shared map's system (built once)."""
        if not self.shared:
            raise ValueError("a map with one system per member has no single model")
        return Model(self.params[0])

    def start(self, ics: np.ndarray, direction: int = 1) -> Batch:
        """Trajectories at ``ics`` (n, 2) on the section at ``t0`` (``direction=-1``: iterates of ``P^-1``)."""
        ics = np.asarray(ics, dtype=float).reshape(-1, 2)
        if self.coefs is not None:  # a map of coefficient rows: one t0 and period for all
            return Batch.start(ics, self.t0, direction * self.period)
        p = self.params[0] if self.shared else None
        if p is None:
            raise ValueError("start a batch of a shared map (PoincareMap.of) or of coefficient rows (PoincareMap.rows)")
        return Batch.start(ics, p.t0, direction * p.period)

    def advance(self, batch: Batch, n: int, *, store: bool = True, **kw: Any) -> tuple[np.ndarray, np.ndarray]:
        """Move the live members of ``batch`` on by ``n`` iterates: ``(points (m, n, 2), npts (m,))``; statuses in
        ``batch.status``. ``kw`` overrides the map's numerics for this call (e.g. a tighter escape ``bound``).
        A map of coefficient rows (:meth:`rows`) moves member ``i`` under row ``coefs.row[i]``."""
        kk = {**self.numerics.kernel_kwargs(), "workers": self.workers, **kw}
        coefs = self.coefs if self.coefs is not None else coefficients(self.model, n=batch.n)
        return run(rk.FIELD, coefs, batch, int(n), store=store, **kk)

    def advance_lyapunov(
        self, batch: Batch, n: int, members: np.ndarray | None = None, **kw: Any
    ) -> tuple[np.ndarray, np.ndarray]:
        """Move a batch of the Lyapunov system (the state with its tangent basis, :func:`tangent.start`) on by
        ``n`` periods of a map of coefficient rows: ``(records (m, n, .), npts (m,))``, the records holding
        ``log R_ii`` and ``int div`` of each period. Member ``i`` runs under row ``coefs.row[members[i]]``
        (default: ``coefs.row[i]``), in blocks of the map's ``block``; ``kw`` overrides the numerics."""
        if self.coefs is None:
            raise ValueError("advance_lyapunov takes a map of coefficient rows (PoincareMap.rows)")
        coefs = (
            self.coefs if members is None else self.coefs._replace(row=np.ascontiguousarray(self.coefs.row[members]))
        )
        kk = {**self.numerics.kernel_kwargs(), "workers": self.workers, "block": self.block, **kw}
        return run(rk.LYAPUNOV, coefs, batch, int(n), **kk)

    def image(self, x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``(P^n(x), status)`` at the rows of ``x`` (m, 2): point ``j`` under member ``j`` (a shared map: all
        under its system), members that share the section times in lock-step blocks of ``block``."""
        x = np.asarray(x, dtype=float).reshape(-1, 2)
        if self.coefs is not None:
            raise ValueError("image takes a map of Params (PoincareMap.of or .members)")
        y, _, status, _ = run_at(rk.FIELD, list(self.params), x, int(n), workers=self.workers, block=self.block,
                                 **self.numerics.kernel_kwargs())  # fmt: skip
        return y, status

    def derivative(self, x: np.ndarray, n: int, members: np.ndarray | None = None) -> Monodromy:
        """``P^n``, ``DP^n`` and ``int div dt`` at the rows of ``x`` (m, 2); point ``j`` under member ``members[j]``
        (ignored for a shared map; default ``0 .. m-1``). Statuses in :attr:`Monodromy.status`."""
        x = np.asarray(x, dtype=float).reshape(-1, 2)
        idx = np.arange(x.shape[0]) if members is None else np.asarray(members, dtype=np.int64)
        if self.coefs is not None:
            co = self.coefs._replace(row=np.ascontiguousarray(self.coefs.row[idx]))
            return monodromy(co, x, int(n), self.t0, self.period, self.numerics, workers=self.workers,
                             block=self.block)  # fmt: skip
        if self.shared:
            # One system: the one group run_at would form, without its grouping and copies (the same batch, the
            # same numbers; Newton asks this once per iteration: ~40 us of ~100 saved a call).
            p = self.params[0]
            return monodromy(coefficients(self.model, n=x.shape[0]), x, int(n), p.t0, p.period, self.numerics,
                             workers=self.workers, block=self.block)  # fmt: skip
        params = [self.params[int(i)] for i in idx]
        return monodromy_at(params, x, int(n), self.numerics, workers=self.workers, block=self.block)

    def iterate(
        self,
        x: np.ndarray,
        n: int,
        *,
        transient: int = 0,
        direction: int = 1,
        cancel: Callable[[], bool] | None = None,
        **kw: Any,
    ) -> Iterator[SectionChunk]:
        """Stream ``P^k(x)``, ``k = transient + 1 .. transient + n``, in chunks (see :func:`~.section.iter_section`)."""
        if not self.shared:
            raise ValueError("iterate streams one system: build the map with PoincareMap.of")
        yield from iter_section(self.params[0], x, n, transient=transient, numerics=self.numerics,
                                direction=direction, cancel=cancel, workers=self.workers, **kw)  # fmt: skip


# ---------------------------------------------------------------------------
# The one Newton.

#: Newton gives up on a seed whose best residual has not halved in this many iterations.
PATIENCE = 6
#: A seed whose iterate comes this close (relative) to a point of an orbit already found (of a period
#: dividing its own) would converge to that orbit: it stops as a duplicate.
DUPLICATE_TOL = 1e-4
#: Far from an orbit Newton needs no accurate map: iterates integrate 1e4 times less accurately (DOP853 takes
#: ~3x fewer steps) until the residual is below ``COARSE_UNTIL (1 + |x|)``.
COARSE_UNTIL = 1e-5
#: Farther still (residual above ``FAR_UNTIL (1 + |x|)``) the iterates integrate ``FAR_LOOSEN`` times less
#: accurately than the orbit (at most ``FAR_RTOL``): a Newton step from a point that far is only a direction, and
#: the map at 1e-6 takes ~0.6 of the steps at 1e-8 (Fig. 8B, periods 1-8). Most of a grid search's work is
#: there (seeds that stall, seeds on their way to an orbit found already).
FAR_UNTIL = 1e-2
FAR_LOOSEN = 1e6
FAR_RTOL = 1e-6
#: Constants of Newton's iterations (built once: ~2 us each a call, Newton iterates thousands of times).
_EYE2 = np.eye(2)[None]
_OK = int(Status.OK)


@dataclass(frozen=True)
class Converged:
    """Seed ``i`` converged to ``x`` (a fixed point of ``P^n``) in ``iterations``; ``least`` is its least period
    (the least ``d`` dividing ``n`` with ``P^d(x) = x`` at the resolution asked); ``mono`` is ``DP^n`` at ``x``."""

    i: int
    x: np.ndarray
    mono: Monodromy
    iterations: int
    least: int


@dataclass(frozen=True)
class NewtonFailure:
    """Seed ``i`` found no fixed point of ``P^period``, and why: ``status`` in the one vocabulary (``not_converged``,
    ``cancelled``, or the engine failure of the seed's trajectory), ``reason`` the detail."""

    i: int
    period: int
    reason: str
    iterations: int
    status: Status = Status.NOT_CONVERGED


@dataclass
class NewtonResult:
    converged: list[Converged] = field(default_factory=list)
    failures: list[NewtonFailure] = field(default_factory=list)
    #: Seeds that ran into an orbit already found (in neither list).
    duplicates: int = 0
    cancelled: bool = False


def least_period(chain: np.ndarray, n: int, tol: float) -> int:
    """The least ``d`` dividing ``n`` with ``|P^d(x) - x| <= tol`` (``chain`` = ``x, P(x), ..., P^n(x)``)."""
    x = chain[0]
    for d in range(1, n):
        if n % d == 0 and np.linalg.norm(chain[d] - x) <= tol:
            return d
    return n


def _twins(x: np.ndarray, res: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Iterates near an orbit (the accurate phase) within :data:`DUPLICATE_TOL` of another, chained: each such
    cluster converges to one point, so one member goes on, the one with the smallest last residual (then the
    smallest ``(q, r)``: whatever the seeds' order). ``out`` marks members stopped already. Returns the others'
    mask."""
    m = x.shape[0]
    twin = np.zeros(m, bool)
    live = np.flatnonzero(~out)
    live = live[np.all(np.isfinite(x[live]), axis=1)]
    if live.size < 2:
        return twin
    xs = x[live]
    # Chained pairs within either point's tolerance, in memory linear in m (a dense m x m distance matrix, or
    # every pair of a dense cluster, would take 1.6 GB for 10^4 seeds of one orbit in the accurate phase together):
    # points sharing a cell of side tol.min() / 2 are within tolerance of each other; cells are linked where their
    # first points (lexicographic) are. Links found are true ones, so a cluster never joins two orbits' iterates;
    # it may miss a chain (more iterates go on: more work, the same orbits).
    tol = DUPLICATE_TOL * (1.0 + np.linalg.norm(xs, axis=1))
    _, cell = np.unique(np.floor(xs / (0.5 * tol.min())).astype(np.int64), axis=0, return_inverse=True)
    cell = cell.ravel()
    by_xy = np.lexsort((xs[:, 1], xs[:, 0]))
    _, first = np.unique(cell[by_xy], return_index=True)
    rep = by_xy[first]  # the first point of each cell, cells in order
    pairs = cKDTree(xs[rep]).query_pairs(float(tol.max()), output_type="ndarray").reshape(-1, 2)
    d = np.linalg.norm(xs[rep[pairs[:, 0]]] - xs[rep[pairs[:, 1]]], axis=1)
    pairs = pairs[d <= np.maximum(tol[rep[pairs[:, 0]]], tol[rep[pairs[:, 1]]])]
    graph = coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(rep.size, rep.size))
    label = connected_components(graph, directed=False)[1][cell]
    order = np.lexsort((xs[:, 1], xs[:, 0], res[live]))  # the survivor of each cluster comes first
    seen: set[int] = set()
    for k in order:
        if int(label[k]) in seen:
            twin[live[k]] = True
        seen.add(int(label[k]))
    return twin


def _norms(v: np.ndarray) -> np.ndarray:
    """Euclidean norms of the rows of ``v`` (m, 2): ``np.linalg.norm(v, axis=1)``'s arithmetic without its checks
    (~4 us a call; Newton takes three an iteration)."""
    return np.sqrt(np.add.reduce(v * v, axis=1))


def _solve2(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a^-1 b`` for stacks of 2x2 systems (closed form) and the determinants."""
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        x0 = (a[:, 1, 1] * b[:, 0] - a[:, 0, 1] * b[:, 1]) / det
        x1 = (a[:, 0, 0] * b[:, 1] - a[:, 1, 0] * b[:, 0]) / det
    return np.column_stack([x0, x1]), det


def newton(
    pmap: PoincareMap,
    seeds: np.ndarray,
    periods: np.ndarray,
    *,
    ftol: float,
    max_iter: int,
    max_step: float = 1.0,
    patience: int | None = PATIENCE,
    coarse: bool = True,
    near: np.ndarray | float = math.inf,
    dedupe: bool = True,
    same: np.ndarray | float | None = None,
    cancel: Callable[[], bool] | None = None,
) -> NewtonResult:
    """Newton on ``P^n(x) - x`` from every ``(seeds[i], periods[i])``, all at once.

    Every iteration integrates the tangent system of all unfinished seeds of one period in one lock-step
    batch (``pmap.derivative``; seed ``i`` is member ``i`` of a map with one system per member), then
    updates them together. Globalisation is a trust region on the step: a step is at most ``max_step``
    long (``inf``: plain Newton), and an iterate whose residual did not decrease (or whose trajectory
    failed) is pulled half way back with the radius halved.

    Parameters
    ----------
    ftol : convergence: ``|P^n(x) - x| <= ftol (1 + |x|)``.
    patience : a seed stops after this many iterations without halving its residual (None: only
        ``max_iter`` stops it).
    coarse : iterate with a map 1e6 times less accurate (at most :data:`FAR_RTOL`) until the residual is below
        :data:`FAR_UNTIL`, then 1e4 times less accurate until it is below :data:`COARSE_UNTIL`.
    near : a seed whose iterate goes farther than this (max-norm) from the seed fails (the fixed point is
        not the one the seed was near).
    dedupe : a seed whose iterate reaches a point of an orbit found already stops as a duplicate.
    same : the least period's resolution, absolute (per seed); default ``max(100 ftol, 1e-7) (1 + |x|)``.
    cancel : polled between iterations.
    """
    m = seeds.shape[0]
    numerics = pmap.numerics
    # The coarse maps choose their method again by the "auto" rule (DOP853 at these tolerances, where it needs
    # fewer steps than vern9), unless the user chose the method.
    loose = (min(1e-6, numerics.rtol * 1e4), min(1e-6, numerics.atol * 1e4))
    rough = pmap.with_numerics(numerics.loosened(*loose)) if coarse else pmap
    looser = (max(loose[0], min(FAR_RTOL, numerics.rtol * FAR_LOOSEN)),
              max(loose[1], min(FAR_RTOL, numerics.atol * FAR_LOOSEN)))  # fmt: skip
    roughest = pmap.with_numerics(numerics.loosened(*looser)) if coarse else pmap
    fine = np.full(m, not coarse)  # the accurate map
    far = np.full(m, coarse)  # the roughest map (until the residual is below FAR_UNTIL)
    x0 = seeds.astype(float)
    x = x0.copy()
    near = np.broadcast_to(np.asarray(near, dtype=float), (m,))
    same_at = None if same is None else np.broadcast_to(np.asarray(same, dtype=float), (m,))
    period = periods.astype(np.int64)
    prev, prev_res = x.copy(), np.full(m, np.inf)
    best, since = np.full(m, np.inf), np.zeros(m, np.int64)
    radius = np.full(m, float(max_step))
    iters, backtracks = np.zeros(m, np.int64), np.zeros(m, np.int64)
    done = np.zeros(m, bool)
    out = NewtonResult()
    known: list[tuple[int, np.ndarray]] = []  # (period, its points) of the converged

    def fail(idx: np.ndarray, reason: Callable[[int], str], status: Status = Status.NOT_CONVERGED) -> None:
        for i in idx:
            done[i] = True
            out.failures.append(NewtonFailure(int(i), int(period[i]), reason(int(i)), int(iters[i]), status))

    for _ in range(max_iter):
        active = np.flatnonzero(~done)
        if active.size == 0:
            break
        if cancel is not None and cancel():
            out.cancelled = True
            break
        tier = np.where(fine, 2, np.where(far, 0, 1))
        groups = np.unique(3 * period[active] + tier[active])  # (period, tier) in order, without a Python loop
        for n, level in zip((groups // 3).tolist(), (groups % 3).tolist(), strict=True):
            accurate = level == 2
            now = np.where(fine[active], 2, np.where(far[active], 0, 1))  # as earlier groups left them
            idx = active[(period[active] == n) & (now == level)]
            if dedupe:  # an iterate next to a point of an orbit found already (of a period dividing n)
                dup = np.zeros(idx.size, bool)
                for kn, pts in known:
                    if n % kn == 0:
                        d = np.linalg.norm(x[idx, None, :] - pts[None, :, :], axis=-1).min(axis=1)
                        dup |= d <= DUPLICATE_TOL * (1.0 + np.linalg.norm(x[idx], axis=1))
                if accurate:
                    dup |= _twins(x[idx], prev_res[idx], dup)
                done[idx[dup]] = True
                out.duplicates += int(dup.sum())
                idx = idx[~dup]
                if idx.size == 0:
                    continue
            mono = (pmap, rough, roughest)[2 - level].derivative(x[idx], n, idx)
            iters[idx] += 1
            xi = x[idx]
            bad = mono.status != _OK
            res = np.where(bad, np.inf, _norms(mono.end - xi))
            scale = 1.0 + _norms(xi)
            ok = ~bad & (res <= ftol * scale) & accurate
            for j in np.flatnonzero(ok):
                i = int(idx[j])
                done[i] = True
                chain = np.vstack([xi[j][None, :], mono.points[j]])
                tol = max(100.0 * ftol, 1e-7) * scale[j] if same_at is None else float(same_at[i])
                least = least_period(chain, n, tol)
                out.converged.append(Converged(i, xi[j].copy(), mono.member(j), int(iters[i]), least))
                known.append((n, chain[:n]))
            # No progress (or the trajectory failed): pull back half way, shrink the trust radius.
            back = ~ok & ~(res < prev_res[idx]) & np.isfinite(prev_res[idx])
            if back.any():  # (most iterations have none: their bookkeeping skipped)
                backtracks[idx[back]] += 1
                radius[idx[back]] *= 0.5
                stalled = back & (backtracks[idx] > (patience or 8))
                fail(idx[stalled], lambda i: "Newton stalled: no decrease of the residual")
                pull = back & ~stalled
                x[idx[pull]] = 0.5 * (prev[idx[pull]] + xi[pull])
            first_bad = ~ok & ~back & bad
            for j in np.flatnonzero(first_bad):
                c = Status.of(int(mono.status[j]))
                fail(idx[j : j + 1], lambda i, c=c: f"the trajectory from the seed failed: {c.label}", c)
            step_ = ~ok & ~back & ~bad
            sel = idx[step_]
            if sel.size == 0:
                continue
            rs, xs, ss = res[step_], xi[step_], scale[step_]
            backtracks[sel] = 0
            prev[sel] = xs
            prev_res[sel] = rs
            improved = rs < 0.5 * best[sel]
            since[sel] = np.where(improved, 0, since[sel] + 1)
            best[sel] = np.where(improved, rs, best[sel])
            # Close enough for the accurate map (its residual is not comparable: the trust region starts over).
            if not accurate:
                switch = rs <= COARSE_UNTIL * ss
                fine[sel[switch]] = True
                prev_res[sel[switch]] = np.inf
                if level == 0:  # close enough for the rough map: likewise
                    closer = (rs <= FAR_UNTIL * ss) & ~switch
                    far[sel[closer | switch]] = False
                    prev_res[sel[closer]] = np.inf
            slow = since[sel] > (patience if patience is not None else max_iter)
            if slow.any():
                fail(sel[slow], lambda i: f"no convergence: the residual stalled at {best[i]:.3g}")
            jac = mono.matrix[step_] - _EYE2
            dx, det = _solve2(jac, -(mono.end[step_] - xs))
            singular = ~np.isfinite(det) | (np.abs(det) < 1e-14 * np.maximum(1.0, np.abs(jac).max(axis=(1, 2)) ** 2))
            if singular.any():
                fail(sel[~slow & singular], lambda i: "singular: a multiplier is 1 (det(DP^n - I) = 0)")
            go = ~slow & ~singular
            length = _norms(dx)
            shrink = np.where(length > radius[sel], radius[sel] / np.maximum(length, 1e-300), 1.0)
            new = xs + dx * shrink[:, None]
            x[sel[go]] = new[go]
            over = go & ~np.isfinite(new).all(axis=1)
            if over.any():
                fail(sel[over], lambda i: "the Newton step overflowed")
            away = go & ~over & (np.abs(new - x0[sel]).max(axis=1) > near[sel])
            if away.any():
                fail(sel[away], lambda i: f"Newton left the seed's neighbourhood ({near[i]:.3g})")
    if out.cancelled:
        fail(np.flatnonzero(~done), lambda i: "cancelled before Newton converged", Status.CANCELLED)
    fail(np.flatnonzero(~done), lambda i: f"no convergence in {int(iters[i])} iterations (residual {prev_res[i]:.3g})")
    return out
