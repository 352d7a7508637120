"""Bifurcation (orbit) diagrams of the Poincare map over one parameter.

For each value of the swept parameter (``alpha``, an inertia entry, ``g0``,
``g1``, ``g2`` or ``omega``) a trajectory is run through a transient and then
``points`` section points ``x_k`` are kept (the paper's Fig. 10 sweeps
``alpha`` over ``[-0.42, -0.35]`` for the tensor (i3)). Seeding:

``continuation``
    the first value starts from the given initial conditions, every next value
    from the previous value's final state. A **forward** sweep (increasing
    values) and a **backward** sweep (decreasing) follow different branches
    where attractors coexist, which exposes hysteresis.
``fixed``
    every value starts from the same initial conditions; values are independent
    and are computed in parallel.

Escaped (noncompact) or failed trajectories are marked by their status, never
drawn: their points are not part of the diagram. A value for which the system
is not defined (e.g. a tensor that is not positive definite) is marked
``invalid`` and a value never run (cancelled) ``not_run`` (:class:`~explorer_core.status.Status`); a
continuation sweep carries its state across an invalid value.

The sweep engine (:func:`sweep_orbits`) is independent of the ODE: it takes a
function that computes orbits at one value, so it is tested on the logistic
map, whose period-doubling points are known.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import closing
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.analyses.sweeps import check_param, params_at, sweep_values
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.parallel.executor import Executor
from explorer_core.progress import Progress, stream
from explorer_core.progress import run as run_updates
from explorer_core.solve.checks import check_choice, check_range
from explorer_core.solve.integrators import lockstep_groups
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.options import (
    JUMPS,
    Arg,
    Check,
    NewtonOptions,
    choice,
    declare,
    ics,
    instance,
    integer,
    optional_of,
)
from explorer_core.solve.poincare import PoincareMap, newton
from explorer_core.solve.recurrence import CHART, DIAGRAM, recurrence
from explorer_core.status import Status, count_names
from explorer_core.system.params import ParameterError, Params

SEEDINGS = ("continuation", "fixed")
SWEEPS = ("forward", "backward")
#: The initial conditions at ``t0`` unless the caller gives its own.
ICS = ((0.1, 0.1),)


# ---------------------------------------------------------------------------
# The engine: any "orbits at one value" function.

#: ``orbits(value_index, ics (n, 2), workers) -> (points (n, m, 2), npts (n,), status (n,), final (n, 2)[,
#: settled (n, 3)])``: the optional fifth array says where members were found on a cycle (:func:`bilimovich_orbits`).
OrbitFn = Callable[[int, np.ndarray, int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def check_sweeps(seeding: str, sweeps: Sequence[str]) -> tuple[str, ...]:
    """The sweeps a run has: ``("fixed",)`` for fixed seeding, else the validated continuation sweeps."""
    check_choice("seeding", seeding, SEEDINGS)
    sweeps = tuple(sweeps)
    if seeding == "fixed":
        return ("fixed",)
    if not sweeps or any(s not in SWEEPS for s in sweeps) or len(set(sweeps)) != len(sweeps):
        raise ParameterError(f"sweeps must be distinct entries of {', '.join(SWEEPS)}, got {sweeps!r}")
    return sweeps


def sweep_order(sweep: str, n_values: int, valid: np.ndarray) -> list[int]:
    """Value indices a sweep visits, in order; invalid values are skipped (continuation carries across them)."""
    order = range(n_values - 1, -1, -1) if sweep == "backward" else range(n_values)
    return [v for v in order if valid[v]]


def next_seed(status: np.ndarray, final: np.ndarray, ics: np.ndarray) -> np.ndarray:
    """Continuation: the next value starts from the final state; a failed trajectory restarts from its IC."""
    return np.where((np.asarray(status) == Status.OK)[:, None], final, ics)


def empty_sweep_arrays(n_sweeps: int, valid: np.ndarray, n_ics: int, n_points: int) -> dict[str, np.ndarray]:
    """``points, npts, status, final, settled`` of a sweep before any value ran (``Status.NOT_RUN`` /
    ``Status.INVALID``; nothing settled)."""
    shape = (n_sweeps, valid.size, n_ics)
    status = np.full(shape, Status.NOT_RUN, dtype=np.int64)
    status[:, ~valid] = Status.INVALID
    return {
        "points": np.zeros((*shape, n_points, 2)),
        "npts": np.zeros(shape, dtype=np.int64),
        "status": status,
        "final": np.zeros((*shape, 2)),
        "settled": np.zeros((*shape, 3), dtype=np.int64),
    }


@dataclass(frozen=True)
class SweepProgress:
    """Yielded by :func:`iter_bifurcation_diagram` (passed to ``progress``) after each computed value; the
    last one carries the diagram."""

    done: int
    total: int
    elapsed_s: float
    result: OrbitDiagram | None = None

    @property
    def progress(self) -> Progress:
        return Progress(self.done, self.total, "values", self.elapsed_s)


def sweep_orbits(
    orbits: OrbitFn,
    n_values: int,
    ics: np.ndarray,
    n_points: int,
    *,
    valid: np.ndarray | None = None,
    seeding: str = "continuation",
    sweeps: Sequence[str] = SWEEPS,
    workers: int | None = None,
    progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, np.ndarray]:
    """Run ``orbits`` over every value, seeded by continuation or from fixed ``ics``.

    Returns arrays indexed ``[sweep, value, ic]``: ``points`` (+ ``(n_points, 2)``),
    ``npts``, ``status``, ``final`` (+ ``(2,)``) and ``settled`` (+ ``(3,)``). With ``fixed`` seeding there is one
    sweep; with ``continuation`` one per entry of ``sweeps``.
    """
    sweeps = check_sweeps(seeding, sweeps)
    valid = np.ones(n_values, bool) if valid is None else np.asarray(valid, bool)
    arrays = empty_sweep_arrays(len(sweeps), valid, ics.shape[0], n_points)
    points, npts, status, final, settled = (arrays[k] for k in ("points", "npts", "status", "final", "settled"))
    total = int(valid.sum()) * len(sweeps)
    done = [0]
    start = time.perf_counter()
    workers = max(1, workers or config.N_WORKERS)

    def record(s: int, v: int, out: tuple) -> None:
        pts, n, st, fin, *more = out
        if more:
            settled[s, v] = more[0]
        points[s, v] = pts
        npts[s, v] = n
        status[s, v] = st
        final[s, v] = fin
        done[0] += 1
        if progress is not None:
            progress(SweepProgress(done[0], total, time.perf_counter() - start))

    def stopped() -> bool:
        return cancel is not None and bool(cancel())

    if seeding == "fixed":
        todo = [v for v in range(n_values) if valid[v]]
        if workers <= 1 or len(todo) <= 1:
            for v in todo:
                if stopped():
                    break
                record(0, v, orbits(v, ics, workers))
        else:
            # Values are independent: one per thread (the kernels release the GIL).
            with ThreadPoolExecutor(max_workers=workers) as pool:
                it = iter(todo)
                running = {}
                for v in it:
                    running[pool.submit(orbits, v, ics, 1)] = v
                    if len(running) >= 2 * workers:
                        break
                while running:
                    fut = next(iter(running))
                    v = running.pop(fut)
                    record(0, v, fut.result())
                    if not stopped():
                        nxt = next(it, None)
                        if nxt is not None:
                            running[pool.submit(orbits, nxt, ics, 1)] = nxt
    else:

        def run_sweep(s: int, threads: int) -> None:
            seed = ics.copy()
            for v in sweep_order(sweeps[s], n_values, valid):  # invalid values: the state carries across
                if stopped():
                    return
                out = orbits(v, seed, threads)
                record(s, v, out)
                seed = next_seed(out[2], out[3], ics)

        if len(sweeps) > 1 and workers > 1:
            with ThreadPoolExecutor(max_workers=len(sweeps)) as pool:
                futs = [pool.submit(run_sweep, s, max(1, workers // len(sweeps))) for s in range(len(sweeps))]
                for f in futs:
                    f.result()
        else:
            for s in range(len(sweeps)):
                run_sweep(s, workers)
    return {"sweeps": np.array(sweeps), **arrays}


# ---------------------------------------------------------------------------
# The Bilimovich system.


@dataclass(frozen=True)
class OrbitDiagram(Drawable):
    """A bifurcation diagram: section points per parameter value, sweep and initial condition.

    ``points[s, v, i, :npts[s, v, i]]`` are the points of initial condition ``i`` at
    ``values[v]`` in sweep ``sweeps[s]``, at ``k = transient + 1, ...``; only
    trajectories with ``status == 0`` (ok) belong to the diagram (see :meth:`long`).
    ``errors[v]`` says why ``values[v]`` is invalid (empty if valid). ``settled[s, v, i] = (p, k)``: the
    trajectory was found on a period-``p`` cycle after ``k`` integrated periods (continuation sweeps) and its
    later points repeat the cycle's last ``p`` (``(0, 0)``: every point integrated).
    """

    params: Params
    param: str
    values: np.ndarray
    sweeps: np.ndarray
    seeding: str
    ics: np.ndarray
    transient: int
    n_points: int
    points: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    final: np.ndarray
    errors: tuple[str, ...]
    numerics: Numerics
    elapsed_s: float
    completed: bool
    settled: np.ndarray
    #: what the diagram lost: trajectories not computed (cancelled), invalid values, trajectories that stopped
    lost: list[Loss] = field(default_factory=list)
    #: Newton on a settling member's cycle (the spec's; its map follows ``numerics``: :meth:`newton_map`).
    newton: NewtonOptions = JUMPS

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def report(self) -> list[str]:
        """What the command line prints."""
        return [f"{self.values.size} values x {self.sweeps.size} sweeps, status {self.summary()['status']}, "
                f"{self.elapsed_s:.2f} s"]  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "orbit diagram"
        )

    def losses(self) -> list[Loss]:
        """What is not in the diagram, and why (computed from the statuses)."""
        lost = []
        n = int(np.count_nonzero(self.status == Status.NOT_RUN))
        if n:
            lost.append(Loss("trajectories not computed", n, "cancelled"))
        bad = [(v, e) for v, e in zip(self.values, self.errors, strict=True) if e]
        if bad:
            first = f"{self.param} = {bad[0][0]:.12g}: {bad[0][1]}"
            lost.append(Loss("values", len(bad), f"not a valid system (first: {first})"))
        codes = self.status[
            (self.status != Status.NOT_RUN) & (self.status != Status.INVALID) & (self.status != Status.OK)
        ]
        for code in np.unique(codes):
            lost.append(Loss("trajectories", int(np.count_nonzero(codes == code)),
                             f"not drawn: {Status(int(code)).word}"))  # fmt: skip
        return lost

    @property
    def valid(self) -> np.ndarray:
        return np.array([not e for e in self.errors])

    def drawn(self) -> np.ndarray:
        """Mask ``[sweep, value, ic]`` of trajectories whose points are drawn (completed, ok)."""
        return (self.status == Status.OK) & (self.npts == self.n_points)

    def long(self) -> tuple[np.ndarray, ...]:
        """Drawn points as flat columns ``(sweep, value_index, value, ic, k, q, r)``."""
        s, v, i, j = np.nonzero(self.drawn()[..., None] & (np.arange(self.n_points) >= 0))
        pts = self.points[s, v, i, j]
        return s, v, self.values[v], i, self.transient + 1 + j, pts[:, 0], pts[:, 1]

    def periods(self, p_max: int = 16, tol: float = 1e-6) -> np.ndarray:
        """Detected period per ``[sweep, value, ic]`` (0: none up to ``p_max``; -1: not drawn): every drawn point
        returns within ``tol (1 + max |x|)`` (:data:`~explorer_core.solve.recurrence.CHART`)."""
        out = np.full(self.status.shape, -1, dtype=np.int64)
        drawn = self.drawn()
        out[drawn] = recurrence(self.points[drawn], CHART, tol=tol, p_max=p_max).period
        return out

    def status_counts(self) -> dict[str, int]:
        return count_names(self.status)

    def settled_summary(self) -> dict[str, int]:
        """How much of the diagram is copied from cycles it settled on: trajectories (by how they were found)
        and periods not integrated."""
        p, k, how = self.settled[..., 0], self.settled[..., 1], self.settled[..., 2]
        on = p > 0
        copied = np.where(on, self.transient + self.n_points - k, 0)
        return {"repeated": int(np.count_nonzero(how == REPEATED)),
                "newton": int(np.count_nonzero(how == NEWTON_CYCLE)),
                "periods_copied": int(copied.sum())}  # fmt: skip

    def to_csv(self, path: str) -> int:
        """Rows ``sweep,value_index,value,ic,k,q,r,status``: every drawn point, plus one row
        with empty ``k,q,r`` for each trajectory that is not drawn (escaped, failed, invalid)."""
        # Written as text a trajectory at a time (csv.writer's row per point took 2.2 s of the 4.6 s Fig. 10
        # diagram); the same bytes: csv's \r\n line ends, repr of each float (the shortest that reads back).
        rows = 0
        end = "\r\n"
        ks = [str(self.transient + 1 + j) for j in range(self.n_points)]
        with open(path, "w", newline="") as fh:
            fh.write("sweep,value_index,value,ic,k,q,r,status" + end)
            fh.writelines(export.comment_lines(export.partial(self)))  # a stopped diagram says so
            drawn = self.drawn()
            for s in range(self.sweeps.size):
                for v in range(self.values.size):
                    head = f"{self.sweeps[s]},{v},{float(self.values[v])!r},"
                    for i in range(self.ics.shape[0]):
                        if drawn[s, v, i]:
                            pre = f"{head}{i},"
                            texts = _point_texts(self.points[s, v, i, : self.n_points], end)
                            fh.write("".join([f"{pre}{k},{qr}" for k, qr in zip(ks, texts, strict=True)]))
                            rows += len(texts)
                        else:
                            # ok but short of its points: only a cancel stops an ok trajectory
                            lab = Status.of(int(self.status[s, v, i]) or Status.CANCELLED).label
                            fh.write(f"{head}{i},,,,{lab}{end}")
                            rows += 1
        return rows

    def summary(self, p_max: int = 16) -> dict[str, Any]:
        """JSON summary: settings, status counts, detected periods per value (first IC)."""
        per = self.periods(p_max)
        return {
            "param": self.param,
            "range": [float(self.values[0]), float(self.values[-1])],
            "n_values": int(self.values.size),
            "seeding": self.seeding,
            "sweeps": [str(s) for s in self.sweeps],
            "ics": self.ics.tolist(),
            "transient": self.transient,
            "points": self.n_points,
            "status": self.status_counts(),
            "invalid_values": [
                {"value": float(v), "error": e} for v, e in zip(self.values, self.errors, strict=True) if e
            ],
            "periods": {str(s): per[k, :, 0].tolist() for k, s in enumerate(self.sweeps)},
            "settled": self.settled_summary(),
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
            "newton": self.newton.as_dict(),
            "newton_numerics": self.newton.at(self.numerics, DIAGRAM_RTOL)[0].as_dict(),
        }


def _point_texts(pts: np.ndarray, end: str) -> list[str]:
    """``"q,r,ok" + end`` of each row of ``pts`` (n, 2), each float as its repr. A settled trajectory repeats its
    cycle, so each distinct point is formatted once (keyed by its bits: 0.0 and -0.0 stay apart): 2.5x faster on
    the Fig. 10 diagram, whose csv was 0.16 s of the command."""
    bits = np.ascontiguousarray(pts).view(np.int64)
    seen: dict[tuple[int, int], str] = {}
    out = []
    keys = zip(bits[:, 0].tolist(), bits[:, 1].tolist(), strict=True)
    for key, q, r in zip(keys, pts[:, 0].tolist(), pts[:, 1].tolist(), strict=True):
        text = seen.get(key)
        if text is None:
            text = seen[key] = f"{q!r},{r!r},ok{end}"
        out.append(text)
    return out


#: A continuation sweep's members stop integrating once they are on an attracting cycle; they are looked at
#: every SETTLE_CHUNK periods (transient and recorded points alike) and every later point, the recorded ones
#: and the final state, is the cycle's point at that phase (copied, not integrated; the diagram's ``settled``
#: says which trajectories and from where). A member is on its cycle when
#:
#: * **repeated**: its last 8 points repeat after one period ``p <= 16`` to SETTLE_TOL (relative, per
#:   component: the rule :data:`~explorer_core.solve.recurrence.DIAGRAM`; not the chart's, whose tolerance is
#:   relative to the window's largest ``|x|`` and which checks every pair: with it two chaotic-band values of
#:   the Fig. 10 sweeps settled differently, measured). The numerical map is deterministic, so a member on an
#:   attracting cycle repeats it to rounding. (A member converging slowly, a multiplier near the unit circle,
#:   settles only once its steps are below SETTLE_TOL; its remaining motion is below
#:   ``SETTLE_TOL |mu| / (1 - |mu|)``.)
#: * **Newton's cycle**: in the transient, its points repeat to JUMP_TOL only; Newton on ``P^p`` from its last
#:   point finds the cycle ``x*`` and its monodromy ``M``, and the rest of the transient would bring the member
#:   within SETTLE_TOL / JUMP_SAFETY of it: ``|M^j (x - x*)| <= SETTLE_TOL (1 + |x*|) / JUMP_SAFETY`` with ``j``
#:   the whole turns of the cycle left in the transient (the linearisation about an attracting cycle). Members
#:   started from the previous value's cycle repeat it to JUMP_TOL within a chunk but to SETTLE_TOL only after
#:   ~140 periods (Fig. 10, median): the transient's work is then mostly skipped. At most JUMP_TRIES attempts
#:   per member and value (each costs ~3 p periods of the tangent system).
SETTLE_CHUNK = 48
#: The first look comes sooner: a member started on the previous value's cycle is usually ready for Newton.
SETTLE_FIRST = 24
SETTLE_TOL = DIAGRAM.tol
#: The tolerance a diagram's numerics have by default (``Numerics()``): Newton's ``ftol`` follows the ratio of
#: the diagram's tolerance to it (:meth:`~explorer_core.solve.options.NewtonOptions.at`).
DIAGRAM_RTOL = config.DEFAULT_RTOL
#: A diagram's numerics unless the caller gives its own.
DIAGRAM_NUMERICS = Numerics()
#: The tolerance of a diagram as a picture (the app's Accuracy "plot"): its points are far below its pixels
#: (vern9 by the "auto" rule).
DIAGRAM_PLOT_RTOL = 1e-9
#: Its escape bound as a picture: a trajectory beyond it is off any diagram's axes (and stops costing work).
DIAGRAM_PLOT_BOUND = 1e3
JUMP_TOL = 1e-3
JUMP_SAFETY = 10.0
JUMP_TRIES = 2
#: How a trajectory settled (``OrbitDiagram.settled[..., 2]``).
REPEATED, NEWTON_CYCLE = 1, 2
#: ``Status.OK`` as a plain int (numpy compares with it ~5x faster than with the enum member).
_OK = int(Status.OK)


def _newton_cycles(pmap: PoincareMap, x: np.ndarray, periods: np.ndarray, turns: np.ndarray,
                   options: NewtonOptions = JUMPS) -> list[np.ndarray | None]:  # fmt: skip
    """For each member ``x[m]`` (the point at the end of a chunk) whose points repeat to JUMP_TOL after
    ``periods[m]``: the cycle's points ``P(x*) .. P^p(x*)`` (p, 2) if Newton (``options``, default
    :data:`~explorer_core.solve.options.JUMPS`: 6 plain steps to ``ftol`` 1e-10 on ``pmap``'s own map, ``ftol``
    following its tolerance) finds an attracting cycle ``x*`` near it that ``turns[m]`` more turns would bring
    it within SETTLE_TOL / JUMP_SAFETY of, else None."""
    out: list[np.ndarray | None] = [None] * x.shape[0]
    scale = 1.0 + np.abs(x).max(axis=1)
    inner, ftol = options.at(pmap.numerics, DIAGRAM_RTOL)
    res = newton(pmap.with_numerics(inner), x, periods, ftol=ftol, near=10 * JUMP_TOL * scale, dedupe=False,
                 **options.newton_kwargs())  # fmt: skip
    for c in res.converged:
        m = c.i
        mono = c.mono.matrix[0]
        if not np.all(np.isfinite(mono)) or np.abs(np.linalg.eigvals(mono)).max() >= 1.0:
            continue  # not attracting: the member is in a transient near a saddle, or at a bifurcation
        dev = np.linalg.matrix_power(mono, int(turns[m])) @ (x[m] - c.x)
        if np.abs(dev).max() <= SETTLE_TOL * (1.0 + np.abs(c.x).max()) / JUMP_SAFETY:
            out[m] = c.mono.points[0, : int(periods[m])].copy()
    return out


def bilimovich_orbits(
    params: Params,
    ics: np.ndarray,
    transient: int,
    n_points: int,
    numerics: Numerics,
    workers: int = 1,
    settle: bool = False,
    newton_options: NewtonOptions = JUMPS,
) -> tuple[np.ndarray, ...]:
    """Orbits of the Poincare map at one parameter set: transient, then ``n_points`` points.

    ``settle``: a member on an attracting cycle stops integrating and the rest of its trajectory, transient or
    recorded points, is that cycle's (copied at the right phase; :data:`SETTLE_TOL`); for continuation sweeps,
    whose members start on the previous value's attractor.

    Returns ``(points (n, n_points, 2), npts (n,), status (n,), final (n, 2), settled (n, 3))``;
    ``settled[i] = (p, k, how)``: member ``i`` was on a period-``p`` cycle after ``k`` integrated periods (how:
    :data:`REPEATED` or :data:`NEWTON_CYCLE`) and every later point is the cycle's (``(0, 0, 0)``: every point
    integrated).
    """
    pmap = PoincareMap.of(params, numerics, workers=workers)
    batch = pmap.start(ics)
    n, transient, total = batch.n, int(transient), int(transient) + int(n_points)
    settled = np.zeros((n, 3), dtype=np.int64)
    if not settle:
        if transient:
            pmap.advance(batch, transient, store=False)
        pts, npts = pmap.advance(batch, n_points)
        pts[np.arange(n_points)[None, :] >= npts[:, None]] = 0.0  # not data (unset memory): reproducible results
        return pts, npts, batch.status.copy(), batch.y.copy(), settled
    # Every point is kept (700 periods of Fig. 10 are 11 kB a member): the settle test looks back over chunks.
    traj = np.zeros((n, total, 2))
    got = np.zeros(n, dtype=np.int64)
    tries = np.zeros(n, dtype=np.int64)
    done = 0

    def finish(i: int, chain: np.ndarray, how: int) -> None:
        """Member ``i``'s points after ``done`` are the cycle ``chain`` = its points at ``done + 1 .. done + p``."""
        p = chain.shape[0]
        traj[i, done:] = chain[np.arange(total - done) % p]
        got[i] = total
        settled[i] = (p, done, how)

    run = np.flatnonzero(batch.status == _OK)
    while done < total and run.size:
        c = min(SETTLE_FIRST if done == 0 else SETTLE_CHUNK, total - done)
        part = batch.take(run)
        pts, npts = pmap.advance(part, c)
        batch.put(run, part)
        for j, i in enumerate(run):
            traj[i, got[i] : got[i] + npts[j]] = pts[j, : npts[j]]
            got[i] += npts[j]
        done += c
        run = run[batch.status[run] == _OK]
        if done == total:
            break
        loose = []
        for i in run:
            p = int(recurrence(traj[i, :done], DIAGRAM, tol=SETTLE_TOL).period)
            if p:
                finish(i, traj[i, done - p : done].copy(), REPEATED)
            elif (done < transient and tries[i] < JUMP_TRIES
                  and (q := int(recurrence(traj[i, :done], DIAGRAM, tol=JUMP_TOL).period))):  # fmt: skip
                loose.append((i, q))
        if loose:
            idx = np.array([i for i, _ in loose])
            per = np.array([q for _, q in loose])
            tries[idx] += 1
            chains = _newton_cycles(pmap, traj[idx, done - 1], per, (transient - done) // per, newton_options)
            for i, chain in zip(idx, chains, strict=True):
                if chain is not None:
                    finish(int(i), chain, NEWTON_CYCLE)
        run = run[got[run] < total]
    final = batch.y.copy()
    whole = got == total
    final[whole] = traj[whole, total - 1]
    # Points never reached (a member that escaped or failed) stay the zeros traj started with.
    pts = np.ascontiguousarray(traj[:, transient:])
    npts = np.clip(got - transient, 0, int(n_points))
    return pts, npts, batch.status.copy(), final, settled


@dataclass(frozen=True)
class SweepSpec:
    """What defines the orbits at every value of a diagram (plain data: picklable, sent to Dask workers)."""

    params: Params
    param: str
    values: np.ndarray
    ics: np.ndarray
    transient: int
    n_points: int
    numerics: Numerics
    #: Newton on a settling member's cycle (continuation sweeps: :func:`_newton_cycles`).
    newton: NewtonOptions = JUMPS

    def params_at(self, v: int) -> Params | str:
        return params_at(self.params, self.param, float(self.values[v]))

    def orbits(self, v: int, seed: np.ndarray, threads: int = 1, settle: bool = False) -> tuple[np.ndarray, ...]:
        """:func:`bilimovich_orbits` at ``values[v]`` from ``seed`` (results do not depend on ``threads``)."""
        p = self.params_at(v)
        if isinstance(p, str):
            raise ParameterError(p)
        return bilimovich_orbits(p, seed, self.transient, self.n_points, self.numerics, threads, settle=settle,
                                 newton_options=self.newton)  # fmt: skip

    def orbits_settled(self, v: int, seed: np.ndarray, threads: int = 1) -> tuple[np.ndarray, ...]:
        """:meth:`orbits` whose transient ends once the members settle on a cycle (continuation sweeps)."""
        return self.orbits(v, seed, threads, settle=True)


#: Fixed seeding in lock-step: members (value, IC) per block, and periods per engine call (cancel and
#: progress are looked at between calls).
LOCKSTEP_BLOCK = 16
LOCKSTEP_CHUNK = 100


def fixed_lockstep(
    spec: SweepSpec,
    valid: np.ndarray,
    *,
    workers: int | None = None,
    progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, np.ndarray]:
    """:func:`sweep_orbits` with ``fixed`` seeding, every value and IC at once in lock-step blocks.

    Every member starts from its IC, so neighbouring values (similar dynamics) share a block of
    :data:`LOCKSTEP_BLOCK` with one row of coefficients each (:func:`~explorer_core.solve.integrators.
    lockstep_groups`): the block's loops run over its members together, each member still meets the
    tolerance (a step is accepted only if every member's error is), so the points agree with the
    value-by-value computation to the tolerance (bit for bit only on cycles' ends, not on chaotic orbits).
    """
    start = time.perf_counter()
    n_ic = spec.ics.shape[0]
    out = {"sweeps": np.array(["fixed"]), **empty_sweep_arrays(1, valid, n_ic, spec.n_points)}
    todo = [int(v) for v in np.flatnonzero(valid)]
    members = [(v, i) for v in todo for i in range(n_ic)]
    if not members:
        return out
    pset = [spec.params_at(v) for v in todo]
    plist = [pset[k // n_ic] for k in range(len(members))]
    y0 = spec.ics[[i for _, i in members]]
    total_periods = spec.transient + spec.n_points
    done_periods = 0

    def stopped() -> bool:
        return cancel is not None and bool(cancel())

    def report() -> None:
        if progress is not None:
            done = len(todo) * done_periods // total_periods
            progress(SweepProgress(done, len(todo), time.perf_counter() - start))

    groups = lockstep_groups(plist, y0)
    for idx, coefs, batch in groups:
        pmap = PoincareMap.rows(coefs, batch.t0, batch.period, spec.numerics, workers=workers)
        left = spec.transient
        while left > 0:
            if stopped():
                return out
            c = min(LOCKSTEP_CHUNK, left)
            pmap.advance(batch, c, store=False, block=LOCKSTEP_BLOCK)
            left -= c
            done_periods += c * idx.size // len(members)
            report()
        if stopped():
            return out
        pts, npts = pmap.advance(batch, spec.n_points, block=LOCKSTEP_BLOCK)
        pts[np.arange(spec.n_points)[None, :] >= npts[:, None]] = 0.0  # not data: make results reproducible
        for j, m in enumerate(idx):
            v, i = members[m]
            out["points"][0, v, i] = pts[j]
            out["npts"][0, v, i] = npts[j]
            out["status"][0, v, i] = batch.status[j]
            out["final"][0, v, i] = batch.y[j]
    done_periods = total_periods
    report()
    return out


@dataclass(frozen=True)
class SweepChunk:
    """Orbits at consecutive values of one sweep; arrays are ``[k, ic, ...]`` for ``indices[k]``."""

    sweep: int
    indices: tuple[int, ...]
    points: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    final: np.ndarray
    settled: np.ndarray
    seed: np.ndarray  # where a continuation sweep goes on after this chunk
    elapsed_s: float


def sweep_chunk(
    spec: SweepSpec, sweep: int, indices: Sequence[int], seed: np.ndarray, continuation: bool, threads: int = 1
) -> SweepChunk:
    """Orbits at ``values[indices]`` in that order: a pure function of its arguments (a Dask task).

    With ``continuation`` the first value starts from ``seed`` and every next one
    from the previous final state (:func:`next_seed`), exactly as :func:`sweep_orbits`
    does; otherwise every value starts from ``spec.ics``.
    """
    start = time.perf_counter()
    outs = []
    seed = np.asarray(seed, dtype=float)
    for v in indices:
        out = spec.orbits_settled(int(v), seed, threads) if continuation else spec.orbits(int(v), spec.ics, threads)
        outs.append(out)
        if continuation:
            seed = next_seed(out[2], out[3], spec.ics)
    return SweepChunk(
        sweep,
        tuple(int(v) for v in indices),
        *(np.stack([o[k] for o in outs]) for k in range(5)),
        seed=seed,
        elapsed_s=time.perf_counter() - start,
    )


@dataclass(frozen=True)
class DiagramSpec:
    """What defines an orbit diagram (paper, Fig. 10): the orbits at every value (:class:`SweepSpec`), how each
    value is seeded (``"continuation"``: forward/backward sweeps from the previous final state; ``"fixed"``:
    every value from the ICs) and which continuation sweeps run. Made by :func:`diagram_spec`."""

    sweep: SweepSpec
    seeding: str
    sweeps: tuple[str, ...]

    @property
    def numerics(self) -> Numerics:
        return self.sweep.numerics

    def as_dict(self) -> dict[str, Any]:
        sw = self.sweep
        return {"params": sw.params.as_dict(), "param": sw.param, "values": sw.values.tolist(), "ics": sw.ics.tolist(),
                "transient": sw.transient, "points": sw.n_points, "numerics": sw.numerics.as_dict(),
                "newton": sw.newton.as_dict(), "seeding": self.seeding, "sweeps": list(self.sweeps)}  # fmt: skip


def _values(n: str, v: Any) -> np.ndarray:
    """The parameter's values given as such (1-D, finite, at least one; its Check is optional: None, the values from
    ``value_range``, never reaches here)."""
    vals = np.asarray(v, dtype=float).ravel()
    if vals.size == 0 or not np.all(np.isfinite(vals)):
        raise ParameterError(f"{n} must be a non-empty list of finite numbers, got {v!r}")
    return vals


@declare(
    param=Arg(
        "alpha, I11..I23, g0, g1, g2 or omega",
        "str",
        required=True,
        positional=True,
        check=Check(lambda n, v: check_param(v), "a sweepable parameter", "str"),
    ),
    values=Arg(
        "the parameter values", cli=False, default=None, check=Check(_values, "finite numbers or none", optional=True)
    ),
    # value_range and n_values: checked as sweep_values checks them (under its names), whether used or not.
    value_range=Arg(
        "the parameter's range",
        "range",
        flag="--range",
        metavar="A,B",
        required=True,
        default=None,
        check=Check(lambda n, v: check_range("range", v), "two numbers lo < hi", "str", True),
    ),
    n_values=Arg("values over the range", "int", metavar="N", default=200, check=integer(1, config.MAX_GRID * 16)),
    points=Arg("section points per value", "int", default=200, check=integer(1, 1_000_000)),
    transient=Arg("periods run first at every value", "int", default=500, check=integer(0, config.MAX_PERIODS)),
    seeding=Arg("how each value is seeded", "str", choices=SEEDINGS, default="continuation", check=choice(SEEDINGS)),
    sweeps=Arg(
        "continuation sweeps",
        "list",
        metavar="forward,backward",
        default=SWEEPS,
        checked_with=("seeding",),
    ),
    ics=Arg(
        "initial condition (repeatable)",
        "points",
        flag="--ic",
        scene="points",
        default=ICS,
        check=ics(optional=True, none_is=ICS),
    ),
    numerics=Arg(
        "integration settings (escape bound included)",
        cli=False,
        default=DIAGRAM_NUMERICS,
        check=optional_of(Numerics, DIAGRAM_NUMERICS),
    ),
    newton=Arg("Newton on a settling member's cycle", cli=False, default=JUMPS, check=instance(NewtonOptions)),
)
def diagram_spec(
    params: Params,
    param: str,
    values: np.ndarray | None,
    *,
    value_range: Sequence[float] | None,
    n_values: int,
    points: int,
    transient: int,
    seeding: str,
    ics: np.ndarray,
    sweeps: Sequence[str],
    numerics: Numerics,
    newton: NewtonOptions,
) -> DiagramSpec:
    """A validated :class:`DiagramSpec`; every bad value raises :class:`ParameterError` naming it. The options are
    declared above (defaults, checks run before this body, flags); the body checks what needs several of them.

    Parameters
    ----------
    params : the system at the other parameters' values.
    param : one of :data:`SWEEP_PARAMS` (case-insensitive).
    values : the parameter values (1-D, in sweep order for ``forward``), e.g.
        :func:`sweep_values` ``((lo, hi), n)``; or ``value_range = (lo, hi)`` and ``n_values`` (not both). A
        value that is not a valid system is no error: the diagram says so at that value (``errors``).
    points : section points kept per value and initial condition.
    transient : periods run first at every value.
    seeding : ``"continuation"`` or ``"fixed"``.
    ics : (n, 2) initial conditions at ``t0`` (default :data:`ICS`; None: the default).
    sweeps : the continuation sweeps to run (``"forward"``, ``"backward"``); both run at once.
    numerics : integration settings (escape bound included; default :data:`DIAGRAM_NUMERICS`; None: the default).
    newton : Newton on a settling member's cycle (default :data:`~explorer_core.solve.options.JUMPS`).
    """
    with Checking() as at:
        at("values")
        if (values is None) == (value_range is None):
            given = None if values is None else values.tolist()
            raise ParameterError(f"give values or value_range (not both), got {given!r} and {value_range!r}")
        if values is None:
            values = sweep_values(value_range, n_values)
        at("sweeps")
        names = check_sweeps(seeding, sweeps)
        at("points")
        n_sweeps = 1 if seeding == "fixed" else len(tuple(sweeps))
        if n_sweeps * values.size * ics.shape[0] * points > config.MAX_POINTS:
            raise ParameterError(
                f"{values.size} values x {ics.shape[0]} ICs x {points} points exceeds {config.MAX_POINTS}"
            )
    sweep = SweepSpec(params, param, values, ics, transient, points, numerics, newton)
    return DiagramSpec(sweep, seeding, names)


def iter_bifurcation_diagram(
    spec: DiagramSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    executor: Executor | None = None,
    lockstep: bool = True,
    **kw: Any,
) -> Iterator[SweepProgress]:
    """:func:`bifurcation_diagram` (same arguments) as a stream of :class:`SweepProgress` (values done of
    values to compute); the last update's ``result`` is the diagram. The spec (or the keyword form's) is
    checked at the call."""
    spec = spec_of(DiagramSpec, diagram_spec, spec, args, kw)

    def work(emit: Callable[[SweepProgress], None], stop: Callable[[], bool]) -> SweepProgress:
        last = [0, 0]

        def report(p: SweepProgress) -> None:
            last[:] = [p.done, p.total]
            emit(p)

        d = _diagram(spec, progress=report, cancel=stop, workers=workers, executor=executor, lockstep=lockstep)
        d = dataclasses.replace(d, lost=d.losses())
        done = last[0] if not d.completed else max(last[1], int(np.count_nonzero(d.valid)))
        return SweepProgress(done, max(done, last[1], int(np.count_nonzero(d.valid))), d.elapsed_s, d)

    return stream(work, cancel)


def bifurcation_diagram(
    spec: DiagramSpec | Params,
    *args: Any,
    progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> OrbitDiagram:
    """Orbit diagram of the Poincare map over ``param`` (paper, Fig. 10): ``bifurcation_diagram(spec)`` with a
    :class:`DiagramSpec`, or the keyword form ``bifurcation_diagram(params, param, values, **options)`` (the
    options of :func:`diagram_spec`); ``workers``, ``executor`` and ``lockstep`` say how it runs
    (:func:`_diagram`); ``progress`` gets every update of :func:`iter_bifurcation_diagram`. A cancelled
    diagram has ``completed=False`` and the trajectories not computed in ``lost``."""
    return run_updates(iter_bifurcation_diagram(spec, *args, cancel=cancel, **kw), progress)


def _diagram(
    dspec: DiagramSpec,
    *,
    progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    executor: Executor | None = None,
    lockstep: bool = True,
) -> OrbitDiagram:
    """The orbit diagram of ``dspec``.

    Parameters
    ----------
    dspec : what to compute (:func:`diagram_spec`).
    progress, cancel : called / polled after each value.
    workers : threads (default: both cores).
    executor : ``None`` (this process: values one by one, both sweeps at once), or an executor
        (:mod:`explorer_core.parallel.executor`, e.g. a Dask cluster's) that runs chunks of values as
        tasks, with identical results.
    lockstep : with ``fixed`` seeding in this process, integrate the values in lock-step blocks
        (:func:`fixed_lockstep`); False: one value at a time, as the executors do.
    """
    start = time.perf_counter()
    spec, seeding, sweeps = dspec.sweep, dspec.seeding, dspec.sweeps
    vals, ics = spec.values, spec.ics
    errors = tuple("" if isinstance(p, Params) else p for p in (spec.params_at(v) for v in range(vals.size)))
    valid = np.array([not e for e in errors])
    if executor is not None:
        out = sweep_tasks(spec, valid, seeding, sweeps, executor, progress=progress, cancel=cancel)
    elif seeding == "fixed" and lockstep:
        out = fixed_lockstep(spec, valid, workers=workers, progress=progress, cancel=cancel)
    else:
        out = sweep_orbits(
            spec.orbits if seeding == "fixed" else spec.orbits_settled,
            vals.size,
            ics,
            spec.n_points,
            valid=valid,
            seeding=seeding,
            sweeps=sweeps,
            workers=workers,
            progress=progress,
            cancel=cancel,
        )
    return OrbitDiagram(
        params=spec.params,
        param=spec.param,
        values=vals,
        sweeps=out["sweeps"],
        seeding=seeding,
        ics=ics,
        transient=spec.transient,
        n_points=spec.n_points,
        points=out["points"],
        npts=out["npts"],
        status=out["status"],
        final=out["final"],
        settled=out["settled"],
        errors=errors,
        numerics=spec.numerics,
        elapsed_s=time.perf_counter() - start,
        completed=not np.any(out["status"] == Status.NOT_RUN),
        newton=spec.newton,
    )


def sweep_tasks(
    spec: SweepSpec,
    valid: np.ndarray,
    seeding: str,
    sweeps: Sequence[str],
    executor: Executor,
    *,
    progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    chunk: int | None = None,
) -> dict[str, np.ndarray]:
    """:func:`sweep_orbits` of ``spec`` as tasks of ``executor``: the same result dict, bit for bit.

    One task per chunk of values (:func:`sweep_chunk`); a continuation sweep submits its next chunk
    from the previous chunk's final state, so forward and backward sweeps run side by side, one chunk
    at a time each. ``progress`` is called once per value, in bursts of a chunk. ``chunk`` values per
    task (default: about four tasks per executor thread with fixed seeding, 16 chunks per sweep).
    """
    start = time.perf_counter()
    names = check_sweeps(seeding, sweeps)
    valid = np.asarray(valid, bool)
    out = empty_sweep_arrays(len(names), valid, spec.ics.shape[0], spec.n_points)
    orders = [sweep_order(s, valid.size, valid) for s in names]
    total = sum(len(o) for o in orders)
    continuation = seeding != "fixed"
    if chunk is None:
        n = max(len(o) for o in orders) if orders else 0
        chunk = math.ceil(n / 16) if continuation else math.ceil(n / (4 * executor.threads()))
    chunk = max(1, min(64, int(chunk)))
    pieces = [[o[i : i + chunk] for i in range(0, len(o), chunk)] for o in orders]
    todo: deque = deque()
    if continuation:  # each sweep's next chunk needs the previous one's final state
        todo.extend(
            ((s, 0), sweep_chunk, (spec, s, pieces[s][0], spec.ics, True)) for s in range(len(names)) if pieces[s]
        )
    else:
        todo.extend(((0, k), sweep_chunk, (spec, 0, p, spec.ics, False)) for k, p in enumerate(pieces[0]))
    done = 0
    with closing(executor.stream(todo, cancel)) as stream:
        for batch in stream:
            for (s, k), res in batch:
                for j, v in enumerate(res.indices):
                    for name in ("points", "npts", "status", "final", "settled"):
                        out[name][s, v] = getattr(res, name)[j]
                    done += 1
                    if progress is not None:
                        progress(SweepProgress(done, total, time.perf_counter() - start))
                if continuation and k + 1 < len(pieces[s]):
                    todo.append(((s, k + 1), sweep_chunk, (spec, s, pieces[s][k + 1], res.seed, True)))
    return {"sweeps": np.array(names), **out}
