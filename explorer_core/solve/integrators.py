"""Batches of trajectories and the driver that runs them through the engine, period by period.

Every call advances each trajectory from one section time ``t0 + k T`` to the next and lands on it
exactly (see :mod:`explorer_core.solve.rk`, the one Runge-Kutta engine), so section points carry
no interpolation error.

Methods (:mod:`explorer_core.solve.tableaus`)
---------------------------------------------
``rk4``
    Classical fixed-step Runge-Kutta, ``steps_per_period`` steps per period.
``dp5``
    Dormand-Prince 5(4) with FSAL and standard error control.
``dop853``
    Hairer's DOP853, 8th order with the combined 5th/3rd-order error estimate.
``taylor``
    Taylor's method (:mod:`explorer_core.solve.taylor`), order and step from the tolerance (Jorba & Zou);
    the field (``FIELD``) only.

The kernel releases the GIL (``nogil=True``); :func:`run` splits a batch across threads so both
cores work at once. Failures are recorded per trajectory in ``status`` (see :class:`Status`); a
failed trajectory keeps its last good section state and is never advanced again.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cache
from typing import TYPE_CHECKING

import numpy as np

from explorer_core import config
from explorer_core.solve import rk, taylor
from explorer_core.solve.rk import FIELD, Status
from explorer_core.solve.tableaus import METHODS, Method, get_method, resolve_method
from explorer_core.system.model import Model, field_form, form_of
from explorer_core.system.params import Params, check_time, reduce_time

if TYPE_CHECKING:
    from explorer_core.solve.numerics import Numerics

__all__ = [
    "FIXED_BLOCK",
    "METHODS",
    "Batch",
    "Method",
    "Status",
    "advance",
    "advance_body",
    "body_start",
    "coefficients",
    "get_method",
    "run",
    "run_at",
]

#: Trajectories advanced together at fixed steps (lock-step costs nothing there: every member takes
#: the same steps; the block only bounds the scratch arrays so they stay in cache).
FIXED_BLOCK = 64
#: Lock-step blocks are formed from the live trajectories (grouped by the size of their state) at a batch's
#: first call and every this many periods after it, whatever the calls: so how a run is cut into calls (the
#: chunks of a stream, which follow the machine's pace) does not change any trajectory's steps. (A batch
#: taken anew for every short call, as the charts and basins do, forms its blocks at each: as before.)
REGROUP_PERIODS = 64
#: ``Status.OK`` as a plain int: numpy compares an array with it ~5x faster than with the enum member.
_OK = int(Status.OK)


@dataclass
class Batch:
    """Mutable state of a batch of trajectories between section times.

    ``y`` is ``(n, STATE_SIZE[system])``: ``(q, r)`` for sections, more for derived systems (the tangent
    system of :mod:`explorer_core.solve.tangent`). ``k`` is the section index of the current state (time
    ``t0 + k * period``; ``period`` is negative for backward integration).
    """

    y: np.ndarray  # (n, dim)
    h: np.ndarray  # (n,) adaptive step memory
    status: np.ndarray  # (n,) int64, Status codes
    nsteps: np.ndarray  # (n,) int64, steps taken (accepted + rejected)
    k: int
    t0: float
    period: float
    #: The lock-step blocks in use (block size, the section index they were first formed at, member indices of
    #: each): kept between calls, re-formed every :data:`REGROUP_PERIODS` periods (see :meth:`blocks_at`).
    blocks: tuple[int, int, list[np.ndarray]] | None = field(default=None, repr=False, compare=False)

    @classmethod
    def start(cls, ics: np.ndarray, t0: float, period: float, k: int = 0, dim: int = 2) -> Batch:
        """Trajectories from ``ics`` (n, 2) at section index ``k``; the state's other components are 0."""
        ics = np.asarray(ics, dtype=float).reshape(-1, 2)
        n = ics.shape[0]
        y = np.zeros((n, dim))
        y[:, :2] = ics
        status = np.zeros(n, dtype=np.int64)
        status[~np.all(np.isfinite(ics), axis=1)] = int(Status.NONFINITE)
        return cls(y, np.zeros(n), status, np.zeros(n, dtype=np.int64), k, float(t0), float(period))

    @property
    def n(self) -> int:
        return self.y.shape[0]

    def take(self, idx: np.ndarray) -> Batch:
        """Members ``idx`` as a new batch (copies) at the same section index."""
        return Batch(self.y[idx], self.h[idx], self.status[idx], self.nsteps[idx], self.k, self.t0, self.period)

    def put(self, idx: np.ndarray, part: Batch) -> None:
        """Write ``part`` (from :meth:`take`, advanced) back into members ``idx``; the batch is now at its section."""
        self.y[idx], self.h[idx], self.status[idx], self.nsteps[idx] = part.y, part.h, part.status, part.nsteps
        self.k = part.k
        self.blocks = None  # its members moved on outside its blocks

    def regroups(self, size: int) -> int:
        """The section index of the first of the blocks' re-formings: its current index if it has no blocks of
        ``size`` members yet; every :data:`REGROUP_PERIODS` after it are the others."""
        return self.k if self.blocks is None or self.blocks[0] != size else self.blocks[1]

    def blocks_at(self, size: int) -> list[np.ndarray]:
        """The lock-step blocks of up to ``size`` members for the next period: the kept ones, or new ones at the
        first call and every :data:`REGROUP_PERIODS` periods after: the live members sorted by the size of their
        state (a proxy for how fast they rotate; ties by index), so that members of a block take similar steps."""
        first = self.regroups(size)
        if self.blocks is None or self.blocks[0] != size or (self.k - first) % REGROUP_PERIODS == 0:
            alive = np.flatnonzero(self.status == _OK)
            if alive.size > 1:
                speed = np.max(np.abs(self.y[alive, :2]), axis=1)
                order = alive[np.argsort(speed, kind="stable")]
            else:  # nothing to sort (Newton and the diagram's sweeps call with one member, thousands of times)
                order = alive
            self.blocks = (size, first, [np.ascontiguousarray(order[i : i + size], dtype=np.int64)
                                         for i in range(0, order.size, size)])  # fmt: skip
        return self.blocks[2]


@cache
def kernel_tableau(name: str) -> rk.Tableau:
    """The method as the engine reads it (arrays contiguous and writable: one compiled kernel for all)."""
    m = get_method(name)
    e = np.ascontiguousarray(np.stack([m.e, m.e5, m.e3]))
    return rk.Tableau(
        np.ascontiguousarray(m.a),
        np.ascontiguousarray(m.b.reshape(1, -1)),
        np.ascontiguousarray(m.c),
        e,
        float(m.order),
        float(m.error_order),
        m.dop853_error,
    )


def coefficients(models: Model | Sequence[Model], rows: np.ndarray | None = None, n: int = 0) -> rk.Coefficients:
    """Tables of one model (shared by ``n`` trajectories) or of several (``rows[i]``: trajectory ``i``'s model).

    Several models must share the section times (``t0`` and the forcing frequency): the members of a
    lock-step block land on the same section times.
    """
    if isinstance(models, Model):
        return tables(models.num, models.gpc, models.den, models.forcing, np.zeros(n, dtype=np.int64),
                      alpha=[models.params.alpha], form=form_of(*models.used))  # fmt: skip
    ms = list(models)
    if rows is None:
        raise ValueError("several models need rows (the model of each trajectory)")
    p0 = ms[0].params
    for m in ms[1:]:
        if m.params.t0 != p0.t0 or m.params.omega != p0.omega:
            raise ValueError(
                f"lock-step members must share the section times: t0 {m.params.t0} / omega {m.params.omega} "
                f"against {p0.t0} / {p0.omega}"
            )
    row = np.asarray(rows, dtype=np.int64)
    if row.size and (row.min() < 0 or row.max() >= len(ms)):
        raise ValueError(f"rows must index the {len(ms)} models")
    used_q = used_r = 0  # the monomials any of the models holds
    for m in ms:
        used_q, used_r = used_q | m.used[0], used_r | m.used[1]
    form = form_of(used_q, used_r)
    return tables(*(np.stack([getattr(m, name) for m in ms], axis=0) for name in ("num", "gpc", "den", "forcing")), row,
                  stacked=True, alpha=[m.params.alpha for m in ms], form=form)  # fmt: skip


def tables(num, gpc, den, forcing, row: np.ndarray, stacked: bool = False, alpha=None, form: int | None = None
           ) -> rk.Coefficients:  # fmt: skip
    """Coefficient tables in the model's format (``num`` (3, 6, 5) etc., or stacked) as the engine reads them.

    Any quadratic field in this format works (e.g. a linear test field); its form (the monomials the kernels
    compute, :func:`~explorer_core.system.model.field_form`) is read off the tables' exact zeros unless given
    (``form``: one that holds them, e.g. the models' own). The arrays are
    fresh, contiguous and writable, so every call meets the one compiled kernel. ``alpha`` (one per parameter set) is
    read by the body's system only (``p = alpha + g q``); without it the tables serve the other systems.
    """

    if stacked and np.unique(np.asarray(forcing, dtype=float)[:, 3]).size > 1:
        # Lock-step members land on the same section times, and the engine shares cos/sin(omega t).
        raise ValueError(f"stacked tables must share omega, got {sorted(set(np.asarray(forcing)[:, 3].tolist()))}")

    def fresh(a: np.ndarray, rows: int | None) -> np.ndarray:
        a = np.asarray(a, dtype=float)
        a = a if stacked else a[None]
        return np.array(a[:, :rows] if rows else a, dtype=float, order="C", copy=True)

    alphas = np.zeros(0) if alpha is None else np.array(alpha, dtype=float, copy=True).reshape(-1)
    num, gpc = fresh(num, 2), fresh(gpc, 2)
    # The kernels compute and evaluate only the monomials of the tables' form (their structural zeros skipped).
    return rk.Coefficients(num, gpc, fresh(den, None), fresh(forcing, None), np.array(row, dtype=np.int64, copy=True),
                           alphas, field_form(num, gpc) if form is None else form)  # fmt: skip


_executor_lock = threading.Lock()
_executor: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    global _executor
    with _executor_lock:
        if _executor is None:
            _executor = ThreadPoolExecutor(max_workers=config.N_WORKERS, thread_name_prefix="bilimovich-kernel")
        return _executor


def run_threads(fn: Callable[[], None], parts: int) -> None:
    """Call ``fn`` in ``parts`` threads of the kernel pool at once (each takes its own work) and wait."""
    if parts <= 1:
        fn()
        return
    futures = [_pool().submit(fn) for _ in range(parts)]
    for f in futures:
        f.result()


def run(
    system: int,
    coefs: rk.Coefficients,
    batch: Batch,
    n_periods: int,
    *,
    method: str = config.DEFAULT_METHOD,
    rtol: float = config.DEFAULT_RTOL,
    atol: float = config.DEFAULT_ATOL,
    steps_per_period: int = config.DEFAULT_STEPS_PER_PERIOD,
    bound: float = config.DEFAULT_ESCAPE_BOUND,
    max_steps: int = config.DEFAULT_MAX_STEPS_PER_PERIOD,
    adaptive: bool = True,
    store: bool = True,
    workers: int | None = None,
    block: int = config.BLOCK_SIZE,
    samples: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Advance every live trajectory of ``batch`` by ``n_periods`` periods of ``system`` (see the engine, ``rk``).

    ``adaptive=False`` runs an embedded pair (dp5, dop853) at ``steps_per_period`` fixed steps; rk4 is
    always fixed-step. With ``block > 1`` the adaptive methods integrate blocks of up to ``block``
    trajectories in lock-step: trajectories are grouped by the size of their state (a proxy for how
    fast they rotate), deterministically, so results do not depend on the number of workers; workers
    pull the next block when they finish one, the costly (large) ones first. ``block=1`` gives each
    trajectory its own step sequence.

    Returns
    -------
    records : (n, n_periods, RECORD_SIZE[system]) array
        ``records[i, :npts[i]]`` are data (the rest is unset); ``(q, r)`` for sections. The body's system
        (``rk.BODY``) records ``samples`` frames per period: ``(n, n_periods samples, 6)``.
    npts : (n,) int array
        Number of periods each trajectory completed in this call (BODY: frames recorded).
    """
    meth = get_method(resolve_method(method, float(rtol), bool(adaptive)))
    n = batch.n
    n_periods = int(n_periods)
    if batch.y.shape[1] != rk.STATE_SIZE[system]:
        raise ValueError(f"system {system} has {rk.STATE_SIZE[system]} state components, the batch {batch.y.shape[1]}")
    samples = int(samples)
    if system == rk.BODY:
        if samples < 1:
            raise ValueError(f"the body's frames per period must be >= 1, got {samples}")
        if coefs.alpha.shape[0] != coefs.num.shape[0]:
            raise ValueError(
                f"the body's system needs alpha for each of the {coefs.num.shape[0]} parameter sets, "
                f"got {coefs.alpha.shape[0]} (build the tables with coefficients() or tables(alpha=))"
            )
    elif samples != 1:
        raise ValueError(f"only the body's system records frames inside a period, got samples={samples}")
    frames = n_periods * samples if system == rk.BODY else n_periods
    rec = np.empty((n, frames if store else 1, rk.RECORD_SIZE[system]))
    npts = np.zeros(n, dtype=np.int64)
    if n == 0 or n_periods <= 0:
        return rec[:, :0], npts
    if coefs.row.shape[0] != n:
        raise ValueError(f"coefficient rows for {coefs.row.shape[0]} trajectories, the batch has {n}")
    # The horizon's end must still resolve the forcing phase (else the steps freeze: t + h == t).
    check_time("the horizon's end t", batch.t0 + (batch.k + n_periods) * batch.period, batch.period)
    is_taylor = meth.kind == "taylor"
    if is_taylor and not adaptive:
        raise ValueError("the Taylor method has no fixed-step mode (its step follows the tolerance): adaptive=True")
    fixed = 0 if (adaptive and meth.adaptive) else int(steps_per_period)
    if system == rk.BODY and fixed % samples:
        raise ValueError(
            f"fixed steps land on the body's frames only if steps_per_period ({fixed}) is a multiple "
            f"of the frames per period ({samples})"
        )
    tab = None if is_taylor else kernel_tableau(meth.name)
    ctl = rk.Control(float(rtol), float(atol), int(max_steps), float(bound), fixed)
    # The clock starts at t0 less whole forcing periods (exactly): a large t0 would round every stage time.
    t_base = reduce_time(batch.t0, float(coefs.forcing[0, 3]))
    clock = rk.Clock(t_base, batch.period, int(batch.k), n_periods, bool(store), samples)
    arr = rk.Arrays(batch.y, batch.h, batch.status, batch.nsteps, rec, npts)
    parts = max(1, min(workers or config.N_WORKERS, n))

    if fixed == 0 and block > 1:
        # Cut where the blocks are re-formed (every REGROUP_PERIODS after the first time): a kernel call a part.
        k0, k_end = int(batch.k), int(batch.k) + n_periods
        first = batch.regroups(block)
        after = first + ((k0 - first) // REGROUP_PERIODS + 1) * REGROUP_PERIODS
        cuts = [k0, *range(after, k_end, REGROUP_PERIODS), k_end]
        one = len(cuts) == 2  # one part: the kernel writes straight into the call's records
        for ka, kb in itertools.pairwise(cuts):
            part_rec = rec if one else np.empty((n, (kb - ka) * samples if store else 1, rec.shape[2]))
            part_npts = npts if one else np.zeros(n, dtype=np.int64)
            blocks = batch.blocks_at(block)
            part_arr = rk.Arrays(batch.y, batch.h, batch.status, batch.nsteps, part_rec, part_npts)
            part_clock = clock._replace(k_first=ka, n_periods=kb - ka)
            _run_blocks(system, tab, coefs, part_clock, ctl, part_arr, blocks, parts, is_taylor)
            if not one:
                if store:
                    off = (ka - k0) * samples
                    rec[:, off : off + part_rec.shape[1]] = part_rec
                npts += part_npts
            batch.k = kb
        return rec, npts
    else:
        size = 1 if block <= 1 else max(block, FIXED_BLOCK)
        # Interleaved shares balance cost (drifting, expensive trajectories tend to cluster);
        # each worker touches only its own rows of the shared arrays.
        shares = iter([np.arange(w, n, parts, dtype=np.int64) for w in range(parts)])
        share_lock = threading.Lock()

        def work() -> None:
            with share_lock:
                idx = next(shares)
            if is_taylor:
                taylor.advance_blocks(system, coefs, clock, ctl, arr, idx, size)
            else:
                rk.advance_blocks(system, tab, coefs, clock, ctl, arr, idx, size)

        run_threads(work, parts)
    batch.k += n_periods
    return rec, npts


def _run_blocks(system: int, tab, coefs: rk.Coefficients, clock: rk.Clock, ctl: rk.Control, arr: rk.Arrays,
                blocks: list[np.ndarray], parts: int, is_taylor: bool) -> None:  # fmt: skip
    """The lock-step ``blocks`` through one kernel call each; workers pull the next block when they finish one,
    the costly (large states, last) first."""
    queue = iter(blocks[::-1])
    queue_lock = threading.Lock()

    def work() -> None:
        while True:
            with queue_lock:
                b = next(queue, None)
            if b is None:
                return
            if is_taylor:
                taylor.advance_blocks(system, coefs, clock, ctl, arr, b, b.shape[0])
            else:
                rk.advance_blocks(system, tab, coefs, clock, ctl, arr, b, b.shape[0])

    run_threads(work, min(parts, len(blocks)))


def advance(
    model: Model,
    batch: Batch,
    n_periods: int,
    **kw,
) -> tuple[np.ndarray, np.ndarray]:
    """Advance the section trajectories of ``batch`` by ``n_periods`` periods of ``model`` (see :func:`run`).

    Returns
    -------
    points : (n, n_periods, 2) array
        Section points; only ``points[i, :npts[i]]`` are data (the rest is unset).
    npts : (n,) int array
        Number of valid section points each trajectory produced in this call.
    """
    return run(FIELD, coefficients(model, n=batch.n), batch, n_periods, **kw)


def run_at(
    system: int,
    params: Sequence[Params],
    y0: np.ndarray,
    n_periods: int,
    *,
    workers: int | None = None,
    block: int = config.BLOCK_SIZE,
    **kw,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`run` of state ``y0[i]`` under ``params[i]`` from ``t0`` (one parameter set each, or one for all).

    Members whose systems share the section times (``t0`` and the forcing period) go in lock-step blocks
    with per-member coefficients: finite differences in a parameter then see one step sequence and are
    smooth in the parameter. Systems with other section times (a change of ``omega`` or ``t0``) run as
    separate batches. Returns the end states (m, dim), the records (m, n_periods, RECORD_SIZE), the
    statuses and step counts.
    """
    y0 = np.asarray(y0, dtype=float)
    params = list(params)
    if len(params) == 1 and y0.shape[0] > 1:
        params = params * y0.shape[0]
    if len(params) != y0.shape[0]:
        raise ValueError(f"{len(params)} parameter sets for {y0.shape[0]} states")
    m = y0.shape[0]
    end, status, nsteps = np.zeros_like(y0), np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64)
    recs = np.zeros((m, int(n_periods), rk.RECORD_SIZE[system]))
    for idx, coefs, batch in lockstep_groups(params, y0):
        rec, _ = run(system, coefs, batch, n_periods, workers=workers, block=block, **kw)
        end[idx], recs[idx], status[idx], nsteps[idx] = batch.y, rec, batch.status, batch.nsteps
    return end, recs, status, nsteps


def lockstep_groups(params: Sequence[Params], y0: np.ndarray) -> list[tuple[np.ndarray, rk.Coefficients, Batch]]:
    """State ``y0[i]`` under ``params[i]``, grouped by section times: ``(members, coefficients, batch)`` each.

    Members of a group share ``t0`` and the forcing period, so they can run in lock-step blocks; each
    distinct parameter set gets one row of coefficient tables (one set for all: the shared fast path).
    Every batch starts at section index 0 (time ``t0``).
    """
    groups: dict[tuple[float, float], list[int]] = {}
    for i, p in enumerate(params):
        groups.setdefault((p.t0, p.period), []).append(i)
    out = []
    for (t0, period), members in groups.items():
        idx = np.array(members, dtype=np.int64)
        unique: dict[Params, int] = {}
        rows = np.array([unique.setdefault(params[i], len(unique)) for i in idx], dtype=np.int64)
        models = [Model(p) for p in unique]
        coefs = coefficients(models[0], n=idx.size) if len(models) == 1 else coefficients(models, rows)
        batch = Batch(np.array(y0[idx], dtype=float), np.zeros(idx.size), np.zeros(idx.size, dtype=np.int64),
                      np.zeros(idx.size, dtype=np.int64), 0, t0, period)  # fmt: skip
        batch.status[~np.all(np.isfinite(batch.y), axis=1)] = int(Status.NONFINITE)
        out.append((idx, coefs, batch))
    return out


def body_start(params: Params, x: np.ndarray, k: int = 0) -> Batch:
    """The body's system (``rk.BODY``) at section ``k`` of ``params``: ``(q, r) = x`` (one point or (n, 2)) and the
    identity orientation."""
    batch = Batch.start(np.asarray(x, dtype=float).reshape(-1, 2), params.t0, params.period, k=int(k),
                        dim=rk.STATE_SIZE[rk.BODY])  # fmt: skip
    batch.y[:, 2] = 1.0  # the quaternion (w, x, y, z) = (1, 0, 0, 0)
    return batch


def advance_body(
    params: Params, batch: Batch, n_periods: int, samples: int, numerics: Numerics
) -> tuple[np.ndarray, np.ndarray]:
    """Move the body's system on by ``n_periods``: ``(frames (n, n_periods samples, 6), nframes (n,))``, the state
    ``(q, r, w, x, y, z)`` at ``samples`` equally spaced times of each period (see :func:`run`); statuses in
    ``batch.status``."""
    return run(rk.BODY, coefficients(Model(params), n=batch.n), batch, n_periods, samples=samples, workers=1,
               **numerics.kernel_kwargs())  # fmt: skip


def warmup() -> None:
    """Compile (or load from the on-disk cache) the engine: one kernel serves every method and system."""
    from explorer_core.system.params import Params

    model = Model(Params())
    batch = Batch.start(np.array([[0.1, 0.2], [0.3, 0.1]]), 0.0, 2 * math.pi)
    advance(model, batch, 1, workers=1, block=2)
    body = body_start(model.params, np.array([0.1, 0.2]))  # the body's orientation (one trajectory)
    run(rk.BODY, coefficients(model, n=1), body, 1, samples=4, workers=1)
