"""The drivers: one-parameter continuation with its events and switching, from a seed (:func:`iter_continue_orbit`),
from many seeds (:func:`iter_continue_from_seeds`) and from a chart's regions (:func:`iter_chart_boundaries`).

Each ``iter_X`` is a plain generator (no thread): it steps the engine's generator (:meth:`~.engine._Engine.follow`)
and, at every point the engine accepts, decides itself whether the orbit kept its period, whether a bifurcation
was crossed (it locates it, and queues the doubled branch at a period doubling), and whether the branch ends
there (its birth point); then it yields a :class:`~explorer_core.progress.Step` that carries the live result.
``X(..., progress=None, cancel=None)`` is ``progress.run(iter_X(..., cancel=cancel), progress)``. ``cancel`` is
polled before every step of the engine, before every branch's curves and before every seed's orbit or chart
direction; closing the iterator early stops the run at its next poll too (:func:`~explorer_core.progress.stoppable`),
and the live result is left as a cancelled run leaves it: ``completed`` False, the rest in ``lost``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.curves import NOT_OFFERED, SWITCHES, _follow_curve, _switch_codim2
from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.events import _crossed, _located
from explorer_core.analyses.continuation.options import (
    BoundariesSpec,
    ContinuationSpec,
    MapSpec,
    SeedsSpec,
    boundaries_spec,
    continuation_spec,
    map_spec,
    seeds_spec,
)
from explorer_core.analyses.continuation.problems import _BranchProblem
from explorer_core.analyses.continuation.results import (
    CODIM2_NAMES,
    Boundaries,
    Branch,
    Codim2Point,
    Continuation,
    Curve,
)
from explorer_core.analyses.continuation.switching import _birth, _switch
from explorer_core.analyses.continuation.system import ContinuationMap, _Stop, _System
from explorer_core.analyses.orbits import find_orbits, minimal_period, newton
from explorer_core.analyses.specs import spec_of
from explorer_core.losses import Loss
from explorer_core.progress import Cancel, Progress, Step, run, stoppable
from explorer_core.solve.poincare import PoincareMap
from explorer_core.system.params import ParameterError, Params


class _Meter:
    """Where a run made of parts is (branches, orbits, directions): ``done`` never decreasing, the current part
    counted by its own share. Every update carries the live ``result`` (the contract's partial result)."""

    def __init__(self, unit: str, result: Any) -> None:
        self.unit, self.result = unit, result
        self.start = time.perf_counter()
        self.done = 0.0

    def at(self, done: float, total: float, detail: Any = None) -> Step[Any]:
        self.done = max(self.done, min(float(done), total))
        return Step(Progress(self.done, total, self.unit, time.perf_counter() - self.start), detail, self.result)

    def last(self, completed: bool, total: float, elapsed_s: float, detail: Any = None) -> Step[Any]:
        """The last update: ``total`` done when the run reached its end, as far as it came if cancelled."""
        done = total if completed else min(self.done, total)
        return Step(Progress(done, total, self.unit, elapsed_s), detail, self.result)


class _OrbitRun:
    """One continuation of a periodic orbit as an explicit state: made from a spec (Newton finds the orbit at the
    range's first value, or a :class:`ParameterError` says why not), ``result`` is the live :class:`Continuation`;
    iterating runs it, a :class:`~explorer_core.progress.Step` in ``branches`` after every point (see
    :func:`iter_continue_orbit`).

    Follows the period-``spec.period`` orbit near ``spec.seed`` over ``spec.param`` from ``spec.range[0]`` to
    ``spec.range[1]`` (see :func:`continuation_spec` for the settings). Every branch stops at the range's end, at
    its birth point (a doubled orbit collapsing onto the orbit it was born from), on escape or integration failure,
    on leaving the valid parameters (e.g. a tensor that is not positive definite), after ``max_points``, or where
    a step is refused at ``ds_min``; its ``stop`` says which, and every stop but the first two is in ``lost``. A
    cancelled run (``stop()`` True) ends with ``completed`` False and the rest in ``lost``.
    """

    def __init__(self, spec: ContinuationSpec, stop: Cancel, workers: int | None) -> None:
        self.start = time.perf_counter()
        self.spec, self.stop = spec, stop
        params, param, (a, _), period, numerics = spec.params, spec.param, spec.range, spec.period, spec.numerics
        x0 = np.array(spec.seed, dtype=float)
        self.base = params.with_(**{param: a})
        self.sys: ContinuationMap = _System(self.base, [param], numerics, workers)
        self.eng = _Engine(spec.options, stop)
        self.workers = workers

        conv, failures = newton(self.base, x0[None, :], np.array([period]), numerics=numerics, workers=workers)
        if not conv:
            raise ParameterError(
                f"no period-{period} orbit found from {x0.tolist()} at {param} = {a}: {failures[0].reason}"
            )
        _, x_start, mono, _ = conv[0]
        chain = np.vstack([x_start[None, :], mono.points[0]])
        d = minimal_period(chain, mono.end[0], period, 1e-6)
        if d != period:
            raise ParameterError(
                f"the orbit found from {x0.tolist()} has period {d}, not {period}: ask for --period {d}"
            )
        self._begin(Continuation(params, param, spec.range, numerics, [], [], options=spec.options, spec=spec), x_start)

    def _begin(self, result: Continuation, x_start: np.ndarray) -> None:
        self.result = result
        #: the branches to follow: (period, a point of the orbit, its parameter, the bifurcation it was born at)
        self.queue: list[tuple[int, np.ndarray, float, int | None]] = [(self.spec.period, x_start, self.spec.range[0],
                                                                         None)]  # fmt: skip
        self.meter = _Meter("branches", self.result)

    def _step(self, finished: int, total: int, value: float | None) -> Step[Continuation]:
        """An update: ``finished`` branches (and curves) of ``total`` done, the current one by the share of the
        range its furthest point ``value`` covers."""
        a, b = self.spec.range
        share = 0.0 if value is None else min(1.0, max(0.0, (value - a) / (b - a)))
        return self.meter.at(finished + share, total, (self.result.n_points, value))

    def __iter__(self) -> Iterator[Step[Continuation]]:
        spec, res, opts, eng = self.spec, self.result, self.spec.options, self.eng
        param, (a, b) = spec.param, spec.range
        stopped = False
        while self.queue and not stopped:
            n, x, p, parent = self.queue.pop(0)
            br = Branch(n, parent=parent)
            res.branches.append(br)
            k = len(res.branches) - 1
            prob = _BranchProblem(self.sys, (a, b), n, opts.corrector.ftol)
            what = f"branch {k} (period {n}, from {param} = {p:.12g})"
            try:
                # A doubled branch leaves its doubling point on the side where it exists.
                away = p - res.bifurcations[parent].value if parent is not None else 0.0
                direction = math.copysign(1.0, away / (b - a)) if abs(away) > 1e-14 * (1 + abs(p)) else 1.0
                pt = eng.first(prob, np.array([x[0], x[1], prob.scaled(p)]), np.array([0.0, 0.0, direction]))
                br.add(p, pt)
                walk = eng.walk(pt, opts.ds_max)
                for w in eng.follow(prob, walk):
                    try:
                        value, w.stop = self._judge(prob, br, k, w.pt, w.new)
                    except _Stop as exc:
                        w.refusal = exc  # retried shorter by the engine
                        continue
                    yield self._step(k, len(res.branches) + len(self.queue), value)
                reason, lost, br.status = walk.reason, walk.lost, walk.status
                if reason == "range end":
                    reason = "range end" if walk.pt.X[2] >= 0.5 else "back at the range's start (after a fold)"
            except _Stop as exc:
                reason, lost, br.status = str(exc), True, exc.status
            br.stop = reason
            if lost:
                res.lost.append(Loss(what, 1, reason))
            if reason == "cancelled":
                stopped = True
        if stopped:
            if self.queue:
                res.lost.append(Loss("branches not started", len(self.queue), "cancelled"))
            if spec.param2 is not None:
                res.lost.append(Loss("two-parameter curves", 1, "cancelled before they were followed"))
        if spec.param2 is not None and not stopped:
            res.param2, res.range2 = spec.param2, spec.range2
            c, d = spec.range2  # type: ignore[misc]
            todo = list(res.bifurcations)  # folds, doublings and Neimark-Sacker points alike
            w1 = (a, b) if spec.window1 is None else spec.window1
            for bif in todo:
                yield self._step(len(res.branches) + len(res.curves), len(res.branches) + len(todo), None)
                if self.stop():
                    stopped = True
                    res.lost.append(Loss(f"the {bif.kind} curve from {param} = {bif.value:.12g}", 1, "cancelled"))
                    continue
                curve, losses = _follow_curve(eng, self.sys, res.param2, bif, w1, (c, d), spec.codim2_nf, res.messages)
                res.curves.append(curve)
                res.lost += losses
                stopped = stopped or "cancelled" in curve.stop
                if spec.switch and not stopped:
                    res.lost += self._switch_codim2(curve, w1, (c, d))
        res.elapsed_s = time.perf_counter() - self.start
        res.completed = not stopped

    def _switch_codim2(self, curve: Curve, w1: tuple[float, float], w2: tuple[float, float]) -> list[Loss]:
        """The curves switched onto at ``curve``'s R2, LPPD and GPD points (:func:`~.curves._switch_codim2`), each
        once (an LPPD is on a fold and a flip curve), up to ``max_period``; their losses."""
        res, spec, lost = self.result, self.spec, []
        sys2 = self.sys.over([spec.param, res.param2])
        for c in curve.codim2:
            if self.stop():
                continue
            if c.kind in NOT_OFFERED:
                self._no_switch(c, f"not offered: {NOT_OFFERED[c.kind]}")
            elif c.kind in SWITCHES and 2 * c.period > spec.max_period:
                self._no_switch(c, f"the period-{2 * c.period} orbit is beyond max_period = {spec.max_period}")
            if c.kind not in SWITCHES or 2 * c.period > spec.max_period:
                continue
            near = 1e-6 * (1.0 + max(abs(v) for v in c.values))
            if any(o.origin is not None and o.origin.kind == c.kind and o.origin.period == c.period
                   and max(abs(u - v) for u, v in zip(o.origin.values, c.values, strict=True)) <= near
                   for o in res.curves):  # fmt: skip
                continue
            new, losses = _switch_codim2(self.eng, sys2, c, w1, w2, res.messages, spec.codim2_nf)
            if new is not None:
                res.curves.append(new)
                lost += losses
                for c2 in new.codim2:  # switching is not repeated from a curve switched onto
                    if c2.kind in SWITCHES or c2.kind in NOT_OFFERED:
                        self._no_switch(c2, "it lies on a curve switched onto (switching is not repeated)")
        return lost

    def _no_switch(self, c: Codim2Point, why: str) -> None:
        """Say in ``messages`` (once) why the curves that emanate from ``c`` are not followed: a switch asked for
        is never answered by silence."""
        res = self.result
        say = (f"no switching at {c.kind} ({CODIM2_NAMES[c.kind]}) of the period-{c.period} orbit at "
               f"({res.param}, {res.param2}) = ({c.values[0]:.12g}, {c.values[1]:.12g}): {why}")  # fmt: skip
        if say not in res.messages:
            res.messages.append(say)

    def _judge(self, prob: _BranchProblem, br: Branch, k: int, pt: _Point, new: _Point) -> tuple[float, str | None]:
        """The driver's word on ``new``, a point the engine accepted on branch ``k`` after ``pt``: it records the
        point and the bifurcations crossed since ``pt`` (located, and at a period doubling the doubled branch
        queued), and returns the value of the branch's last point and a reason to end the branch there (its birth
        point) or None. Raises :class:`_Stop` to refuse ``new`` (the orbit collapsed onto a divisor period, a
        bifurcation could not be located): the engine retries the step shorter."""
        spec, res, opts, eng = self.spec, self.result, self.spec.options, self.eng
        n = prob.n
        d = minimal_period(new.pts, new.pts[0], n, opts.period_tol)
        birth = _birth(eng, prob, pt, new)
        if d < n and birth is None:
            raise _Stop(f"the corrector converged onto a period-{d} orbit")
        found = [(kind, *_located(eng, prob, kind, pt, new, k)) for kind in _crossed(pt, new)]
        # In branch order, each bifurcation is a point of the branch (where its stability changes).
        along = lambda q: float(pt.t @ (q.X - pt.X))  # noqa: E731
        found.sort(key=lambda f: along(f[2]))
        if birth is not None:  # what lies beyond the birth point is the same orbit again
            found = [f for f in found if along(f[2]) < along(birth[0]) and f[0] != "fold"]
        for kind, bif, at, why in found:
            res.bifurcations.append(bif)
            if why:
                res.messages.append(why)
            br.add(bif.value, at)
            if kind == "period_doubling" and spec.switch and 2 * n <= spec.max_period:
                try:
                    xs, ps = _switch(eng, _BranchProblem(self.sys, spec.range, 2 * n, opts.corrector.ftol), at)
                    self.queue.append((2 * n, xs, ps, len(res.bifurcations) - 1))
                except _Stop as exc:
                    res.messages.append(f"period doubling at {spec.param} = {bif.value:.12g}: {exc}")
                    res.lost.append(Loss(f"the period-{2 * n} branch born at {spec.param} = {bif.value:.12g}", 1,
                                         str(exc)))  # fmt: skip
        last = new if birth is None else birth[0]
        br.add(prob.p(last.X), last)
        if birth is not None:
            return prob.p(last.X), (f"the period-{n} orbit collapsed onto a period-{birth[1]} orbit at {spec.param} "
                                    f"= {prob.p(birth[0].X):.12g} (its birth point)")  # fmt: skip
        return prob.p(last.X), None


def continue_orbit(
    spec: ContinuationSpec | Params,
    *args: Any,
    progress: Callable[[Step[Continuation]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Continuation:
    """Follow the period-``period`` orbit near ``seed`` over ``param``; ``progress`` gets every update of
    :func:`iter_continue_orbit`.

    ``continue_orbit(spec)`` with a :class:`ContinuationSpec`, or the keyword form ``continue_orbit(params,
    param, value_range, seed, period, **options)``, which builds the spec with :func:`continuation_spec`.
    """
    return run(iter_continue_orbit(spec, *args, cancel=cancel, workers=workers, **kw), progress)


def iter_continue_orbit(
    spec: ContinuationSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[Continuation]]:
    """:func:`continue_orbit` as a stream of :class:`~explorer_core.progress.Step`: after every point, in
    ``branches`` (the branches and curves done, the current one counted by the share of the range its
    furthest point covers, of those started or queued); ``detail`` is ``(points, value)``, ``result`` the live
    continuation. The last update's ``result`` is the continuation (see :class:`_OrbitRun` for where branches
    stop). The spec (or the keyword form's) is checked at the call; Newton at the seed runs at the first update."""
    spec = spec_of(ContinuationSpec, continuation_spec, spec, args, kw)

    def updates(stop: Cancel) -> Iterator[Step[Continuation]]:
        one = _OrbitRun(spec, stop, workers)
        yield from one
        res = one.result
        yield one.meter.last(res.completed, len(res.branches) + len(res.curves), res.elapsed_s, (res.n_points, None))

    return stoppable(updates, cancel)


class _MapRun(_OrbitRun):
    """:class:`_OrbitRun` on a map in closed form (:class:`~.options.MapSpec`): the same branches, events,
    switching and curves; Newton on ``P^n(x) - x`` (the map's own ``DP^n``) finds the orbit at the range's first
    value."""

    def __init__(self, spec: MapSpec, stop: Cancel) -> None:
        self.start = time.perf_counter()
        self.spec, self.stop, self.workers = spec, stop, 1
        a = spec.range[0]
        self.sys = spec.params.over([spec.param])
        self.eng = _Engine(spec.options, stop)
        x = np.array(spec.seed, dtype=float)
        for _ in range(spec.options.max_iter):
            end, mono, pts = self.sys.orbit(x, [a], spec.period)
            dx = np.linalg.solve(mono - np.eye(2), x - end)
            x = x + dx
            if np.linalg.norm(dx) <= 1e-14 * (1.0 + np.linalg.norm(x)):
                break
        end, _, pts = self.sys.orbit(x, [a], spec.period)
        if not np.linalg.norm(end - x) <= 1e-12 * (1.0 + np.linalg.norm(x)):
            raise ParameterError(f"no period-{spec.period} orbit found from {list(spec.seed)} at {spec.param} = {a}")
        d = minimal_period(np.vstack([x[None, :], pts]), end, spec.period, 1e-6)
        if d != spec.period:
            raise ParameterError(f"the orbit found from {list(spec.seed)} has period {d}, not {spec.period}")
        self._begin(Continuation(spec.params, spec.param, spec.range, None, [], [], options=spec.options, spec=spec), x)


def continue_map(cmap: ContinuationMap, *args: Any, cancel: Callable[[], bool] | None = None,
                 **kw: Any) -> Continuation:  # fmt: skip
    """The continuation of an orbit of a map in closed form (:mod:`.testmaps`): ``continue_map(cmap, param,
    value_range, seed, period, **options)`` with the arguments of :func:`~.options.map_spec`; the result as
    :func:`continue_orbit`'s (its ``params`` the map, no ``numerics``)."""
    one = _MapRun(map_spec(cmap, *args, **kw), cancel or (lambda: False))
    for _ in one:
        pass
    return one.result


def continue_from_seeds(
    spec: SeedsSpec | Params,
    *args: Any,
    progress: Callable[[Step[Continuation]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Continuation:
    """Every distinct orbit Newton finds from the seeds, continued: ``continue_from_seeds(spec)`` with a
    :class:`SeedsSpec`, or the keyword form ``continue_from_seeds(params, param, value_range, seeds, **options)``
    (:func:`seeds_spec`); ``progress`` gets every update of :func:`iter_continue_from_seeds`."""
    return run(iter_continue_from_seeds(spec, *args, cancel=cancel, workers=workers, **kw), progress)


def iter_continue_from_seeds(
    spec: SeedsSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[Continuation]]:
    """:func:`continue_from_seeds` as a stream of :class:`~explorer_core.progress.Step` in ``orbits`` (the
    orbits found and continued, the current one by its own progress); the last one carries the result."""
    spec = spec_of(SeedsSpec, seeds_spec, spec, args, kw)
    return stoppable(lambda stop: _continue_from_seeds(spec, stop=stop, workers=workers), cancel)


def _continue_from_seeds(spec: SeedsSpec, *, stop: Cancel, workers: int | None = None) -> Iterator[Step[Continuation]]:
    """Every distinct orbit of ``spec.periods`` that Newton finds from the seeds at the range's first value,
    continued.

    For an orbit diagram: its initial conditions (or final states) as seeds; the branches of all the
    orbits found (stable and unstable, up to ``max_orbits``, lowest periods first) in one result, the last
    update's (in ``orbits``: as many as were found).
    """
    param, (a, b) = spec.param, spec.range
    start = spec.params.with_(**{param: a})
    found = find_orbits(start, spec.seeds, list(spec.periods), numerics=spec.numerics,
                        workers=workers).orbits[: spec.max_orbits]  # fmt: skip
    out = Continuation(spec.params, param, (a, b), spec.numerics, [], [])
    if not found:
        periods = ", ".join(map(str, spec.periods))
        out.messages.append(f"no orbit of period {periods} near the seeds at {param} = {a:g}")
    t0 = time.perf_counter()
    meter = _Meter("orbits", out)
    # (by position: an Orbit's == compares arrays, so found.index() raised for any but the first)
    for i, orb in enumerate(found):
        if stop():
            out.completed = False
            out.lost.append(Loss("orbits found but not continued", len(found) - i, "cancelled"))
            break
        if _on_a_branch(out, orb, a):
            continue  # already followed: the orbit is a point of a branch computed for an earlier seed
        orbit = _OrbitRun(spec.for_orbit(orb.points[0], orb.period), stop, workers)
        for upd in orbit:
            yield meter.at(i + upd.progress.fraction, len(found), upd.detail)
        res = orbit.result
        shift = len(out.branches)
        nb = len(out.bifurcations)
        out.branches += res.branches
        out.bifurcations += [replace(b, branch=b.branch + shift) for b in res.bifurcations]
        for br in res.branches:
            if br.parent is not None:
                br.parent += nb
        out.messages += res.messages
        out.lost += res.lost
        out.curves += res.curves
        out.param2, out.range2 = res.param2, res.range2
        out.completed = out.completed and res.completed
    out.elapsed_s = time.perf_counter() - t0
    yield meter.last(out.completed, len(found), out.elapsed_s, (out.n_points, None))


def _on_a_branch(cont: Continuation, orbit: Any, value: float) -> bool:
    """True if ``orbit`` (at the parameter ``value``) is a point of one of ``cont``'s branches."""
    tol = 1e-6 * (1.0 + float(np.abs(orbit.points).max()))
    for br in cont.branches:
        if br.period != orbit.period:
            continue
        for v, pts in zip(br.values, br.orbits, strict=True):
            if abs(v - value) <= 1e-9 * (1.0 + abs(value)):
                d = np.linalg.norm(pts[:, None, :] - orbit.points[None, 0, :], axis=-1)
                if d.min() <= tol:
                    return True
    return False


def chart_boundaries(
    spec: BoundariesSpec | Any,
    *args: Any,
    progress: Callable[[Step[Boundaries]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Boundaries:
    """The fold and period-doubling curves that bound a chart's regions of stable cycles: ``chart_boundaries(spec)``
    with a :class:`BoundariesSpec`, or ``chart_boundaries(chart, periods=, numerics=)`` (:func:`boundaries_spec`);
    ``progress`` gets every update of :func:`iter_chart_boundaries`."""
    return run(iter_chart_boundaries(spec, *args, cancel=cancel, workers=workers, **kw), progress)


def iter_chart_boundaries(
    spec: BoundariesSpec | Any,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[Boundaries]]:
    """:func:`chart_boundaries` as a stream of :class:`~explorer_core.progress.Step` in ``directions`` (each
    period's region continued towards both ends of the chart's ``x``); the last carries the result."""
    spec = spec_of(BoundariesSpec, boundaries_spec, spec, args, kw)
    return stoppable(lambda stop: _chart_boundaries(spec, stop=stop, workers=workers), cancel)


def _chart_boundaries(bspec: BoundariesSpec, *, stop: Cancel, workers: int | None = None) -> Iterator[Step[Boundaries]]:
    """The fold and period-doubling curves that bound a chart's regions of stable cycles.

    For each period ``p`` in ``periods`` present in the chart (:class:`explorer_core.analyses.regimes.Chart`),
    the pixel of period ``p`` nearest the region's centre: its trajectory is run through the chart's
    transient, Newton finds the period-``p`` orbit there, and that orbit is continued in the chart's ``x``
    towards both ends with every fold and period doubling followed as a curve in ``(x, y)`` over the
    chart. The last update's result holds one :class:`Continuation` per continued direction (their
    ``curves`` are the boundaries). ``numerics`` integrate the orbits and their continuation
    (:func:`boundaries_spec`'s default: the orbits' map as it follows the chart's tolerance).
    """
    from explorer_core.analyses.regimes import PERIODIC

    chart, periods, numerics = bspec.chart, bspec.periods, bspec.numerics
    spec = chart.spec
    xs, ys = np.asarray(spec.x_values, float), np.asarray(spec.y_values, float)
    xr, yr = (float(xs.min()), float(xs.max())), (float(ys.min()), float(ys.max()))
    out = Boundaries()
    total = 2 * len(periods)
    meter = _Meter("directions", out)
    for np_, p in enumerate(periods):
        yield meter.at(2 * np_, total)
        if stop():
            out.completed = False
            out._lost = [Loss("periods not continued", len(periods) - np_, "cancelled")]
            break
        js, is_, ks = np.nonzero((chart.regime == PERIODIC) & (chart.period == p) & chart.computed[..., None])
        if js.size == 0:
            continue
        cj, ci = js.mean(), is_.mean()
        n = int(np.argmin((js - cj) ** 2 + (is_ - ci) ** 2))
        j, i, k = int(js[n]), int(is_[n]), int(ks[n])
        params = spec.pixel_params(j, i)
        if isinstance(params, str):
            continue
        pmap = PoincareMap.of(params, spec.numerics, workers=1)
        batch = pmap.start(spec.ics[k : k + 1])
        pmap.advance(batch, spec.transient, store=False)
        found = find_orbits(params, batch.y, [p], numerics=numerics, workers=workers).orbits
        if not found:
            continue
        x0 = float(xs[i])
        for e, end in enumerate(xr):
            if end == x0:
                continue
            if stop():
                out.completed = False
                out._lost = [Loss("directions not continued", total - 2 * np_ - e, "cancelled")]
                break
            try:
                one = continuation_spec(params, spec.x_param, (x0, end), found[0].points[0], found[0].period,
                                        numerics=numerics, param2=spec.y_param, range2=yr,
                                        window1=xr)  # fmt: skip
                orbit = _OrbitRun(one, stop, workers)
                for upd in orbit:
                    yield meter.at(2 * np_ + e + upd.progress.fraction, total)
            except ParameterError:
                continue
            out.append(orbit.result)
            out.completed = out.completed and orbit.result.completed
        if not out.completed:
            break
    yield meter.last(out.completed, total, time.perf_counter() - meter.start)
