"""Two-parameter continuation of a fold, period-doubling or Neimark-Sacker point, and its codimension-two points.

The curve of ``F = 0, phi = 0`` (``phi`` the test function, :func:`~.system._defining`) in ``(x, p1, p2)``, each
parameter scaled to its range (:class:`~.problems._CurveProblem`), followed both ways from the located bifurcation
by the same engine as the branches, each half to the edge of the box ``window1 x range2``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.codim2 import ENDS_NS, _changed, _crossings, _Tests
from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.events import _crossed, _located, _refine
from explorer_core.analyses.continuation.problems import _BranchProblem, _CurveProblem
from explorer_core.analyses.continuation.results import CODIM2_NAMES, Bifurcation, Codim2Point, Curve
from explorer_core.analyses.continuation.switching import _switch
from explorer_core.analyses.continuation.system import ContinuationMap, _Stop
from explorer_core.analyses.orbits import minimal_period
from explorer_core.losses import Loss
from explorer_core.status import Status


def _collapsed(pt: _Point, new: _Point, n: int, tol: float) -> int:
    """The divisor ``d`` of ``n`` the period-``n`` orbit collapsed onto between two points of a curve (``n``: none):
    ``P^d(x) = x`` at ``new``, or ``P^d(x) - x`` reversed (the orbit passed through the collapse between them, where
    the curve of the period-``n`` system goes on as the period-``d`` orbit's, the orbit's points swapped)."""
    if n == 1 or pt.pts is None:
        return n
    for d in (d for d in range(1, n) if n % d == 0):
        if minimal_period(new.pts, new.pts[0], n, tol) <= d:
            return d
        # not a return distance (the one rule is minimal_period's): the sign of P^d(x) - x between the two points
        if float(_displacement(pt.pts, d) @ _displacement(new.pts, d)) < 0.0:
            return d
    return n


def _displacement(pts: np.ndarray, d: int) -> np.ndarray:
    """``P^d(x) - x`` of the orbit's points ``pts`` (``x = pts[0]``)."""
    return pts[d] - pts[0]


def _follow_curve(eng: _Engine, branch: ContinuationMap, name2: str, bif: Bifurcation, rng1: tuple[float, float],
                  rng2: tuple[float, float], nf: bool = False,
                  messages: list[str] | None = None) -> tuple[Curve, list[Loss]]:  # fmt: skip
    """The curve of ``F = 0, phi = 0`` through ``bif`` (located on a branch of the map ``branch``) in
    ``(name1, name2)``, ``name1`` the branch's parameter, both ways, within ``rng1 x rng2``.

    Pseudo-arclength in ``(q, r, s1, s2)`` with each parameter scaled to its range (``rng1``: the window of the
    first parameter, ``rng2``), by the same engine as the branches; each half ends on the box's edge, or (a
    Neimark-Sacker curve) at R1 or R2, or where its orbit collapses onto one of a divisor period. The
    codimension-two points crossed are located (:mod:`.codim2`; those a normal-form coefficient gives, CP, GPD, CH,
    only with ``nf``) and are points of the curve; why a sign change was not kept goes to ``messages``.
    """
    messages = [] if messages is None else messages
    name1 = branch.names[0]
    p2_0 = branch.value(name2)
    sys = branch.over([name1, name2])
    n, kind = bif.period, bif.kind
    curve = Curve(kind, n)
    what = f"the {kind} curve of the period-{n} orbit from {name1} = {bif.value:.12g}"
    lo, hi = rng2
    if not lo <= p2_0 <= hi:
        curve.stop = f"{name2} = {p2_0} at the bifurcation is outside the range"
        curve.status = Status.NOT_RUN
        return curve, [Loss(what, 1, curve.stop)]
    origin = np.array([0.0, 0.0, min(rng1), lo])
    width = np.array([1.0, 1.0, abs(rng1[1] - rng1[0]), hi - lo])
    prob = _CurveProblem(sys, kind, n, origin, width, eng.opts.corrector.ftol)
    Z0 = (np.array([bif.point[0], bif.point[1], bif.value, p2_0]) - origin) / width
    try:
        pt0 = eng.first(prob, Z0, np.zeros(4))
    except _Stop as exc:
        curve.stop, curve.status = str(exc), exc.status
        return curve, [Loss(what, 1, curve.stop)]
    halves: list[list[tuple[float, float, float, float]]] = []
    found: list[list[Codim2Point]] = []
    reasons, losses = [], []
    tests = _Tests(prob, nf)
    f0 = tests.values(pt0)
    row = lambda Y: (float(Y[2]), float(Y[3]), float(Y[0]), float(Y[1]))  # noqa: E731
    for sgn, way in ((1.0, "one way"), (-1.0, "the other way")):
        rows: list[tuple[float, float, float, float]] = []
        points: list[Codim2Point] = []
        walk = eng.walk(_Point(Z0, pt0.A, pt0.J, sgn * pt0.t, None), eng.opts.curve_ds_max)
        f_pt = f0
        try:
            for w in eng.follow(prob, walk):  # every point the engine accepts is one of the curve
                d = _collapsed(w.pt, w.new, n, eng.opts.period_tol)
                if d < n:  # beyond, the curve is the period-d orbit's, traced as period n (and back)
                    w.stop = f"the period-{n} orbit collapsed onto a period-{d} orbit"
                    continue
                f_new = tests.values(w.new)
                located, why = _crossings(eng, prob, tests, w.pt, w.new, f_pt, f_new)
                messages += [f"{what} ({way}): {m}" for m in why]
                for c, at in located:
                    points.append(c)
                    rows.append(row(prob.unscaled(at.X)))
                    if kind == "neimark_sacker" and c.kind in ENDS_NS:  # the pair turns real: the curve ends
                        w.stop = f"{c.kind} ({CODIM2_NAMES[c.kind]}): the Neimark-Sacker pair turns real"
                        break
                ended = [e for e in ENDS_NS if kind == "neimark_sacker" and _changed(e, f_pt[e], f_new[e])]
                if ended and w.stop is None:  # crossed, though not located
                    w.stop = f"{ended[0]} ({CODIM2_NAMES[ended[0]]}, not located): the Neimark-Sacker pair turns real"
                f_pt = f_new
                if w.stop is not None:
                    continue
                rows.append(row(prob.unscaled(w.new.X)))
            reason, lost, status = walk.reason, walk.lost, walk.status
        except _Stop as exc:
            reason, lost, status = str(exc), True, exc.status
        if curve.status == Status.OK:
            curve.status = status
        if lost:
            losses.append(Loss(f"{what} ({way})", 1, reason))
        halves.append(rows)
        found.append(points)
        reasons.append(reason)
    curve.rows = [*reversed(halves[1]), row(prob.unscaled(Z0)), *halves[0]]
    curve.codim2 = [*reversed(found[1]), *found[0]]
    curve.stop = "; ".join(reasons)
    return curve, losses


#: The curve switched onto at a codimension-two point (MatContM's ``init_R2_NS2m``, ``init_LPPD_NS2m``,
#: ``init_GPD_LP2m``): the Neimark-Sacker curve of the doubled orbit at R2 and LPPD, its fold curve at GPD.
SWITCHES = {"R2": "neimark_sacker", "LPPD": "neimark_sacker", "GPD": "fold"}
#: The switchings MatContM offers that this package does not, and why: said in ``messages`` (with ``switch``)
#: for every such point met, so that asking for a switch is never answered by silence.
NOT_OFFERED = {
    "R1": "the Neimark-Sacker curve of the same orbit that MatContM switches onto (init_R1_NSm) is reached from "
          "its Neimark-Sacker points on the branches instead",
    "R3": "the period-3n orbit's Neimark-Sacker curve (MatContM's init_R3_NS3m) is not switched onto",
    "R4": "the period-4n orbit's fold and Neimark-Sacker curves (MatContM's init_R4_LP4m, init_R4_NS4m) are "
          "not switched onto",
    "CH": "the curve of folds of invariant curves (MatContM's init_CH_LPCm) needs invariant curves, which this "
          "package does not compute",
}  # fmt: skip
#: Switching looks for the doubled orbit's bifurcation on lines this far (a fraction of the box) from the point ...
SWITCH_OFFSET = 1e-3
#: ... along this much of them (a fraction of the box) from the flip curve.
SWITCH_REACH = 0.02
#: The switched curve must come this close to the point (a fraction of the box).
SWITCH_NEAR = 5e-3


class _Fixed:
    """A map of two continuation parameters with the ``k``-th held at ``value``: a one-parameter
    :class:`~.system.ContinuationMap` in the other (lines through a codimension-two point, :func:`_switch_codim2`)."""

    def __init__(self, sys2: ContinuationMap, k: int, value: float) -> None:
        self.sys2, self.k, self.fixed = sys2, k, float(value)
        self.j = 1 - k
        self.names = [sys2.names[self.j]]

    def _p(self, p: Sequence[float]) -> list[float]:
        q = [0.0, 0.0]
        q[self.j], q[self.k] = float(p[0]), self.fixed
        return q

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.sys2.orbit(x, self._p(p), n)

    def fp(self, x: np.ndarray, p: Sequence[float], n: int, amp: float = 1.0) -> np.ndarray:
        return self.sys2.fp(x, self._p(p), n, amp)[:, [self.j]]

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False) -> tuple[Any, ...]:
        end, a, fp, div, pts, extra = self.sys2.evaluate(x, self._p(p), n, dx)
        if extra is not None:
            extra = {**extra, "A_p": [extra["A_p"][self.j]]}
        return end, a, fp[:, [self.j]], div, pts, extra

    def jacobians(self, xs: np.ndarray, p: Sequence[float], n: int) -> np.ndarray:
        return self.sys2.jacobians(xs, self._p(p), n)

    def coarse(self) -> _Fixed:
        return _Fixed(self.sys2.coarse(), self.k, self.fixed)

    def over(self, names: Sequence[str]) -> ContinuationMap:
        return self.sys2.over(names)  # the curves pass both parameters' values at every point

    def value(self, name: str) -> float:
        return self.fixed if name == self.sys2.names[self.k] else self.sys2.value(name)


def _switch_codim2(eng: _Engine, sys2: ContinuationMap, c: Codim2Point, rng1: tuple[float, float],
                   rng2: tuple[float, float], messages: list[str],
                   nf: bool = False) -> tuple[Curve | None, list[Loss]]:  # fmt: skip
    """The curve of the doubled orbit that emanates from the codimension-two point ``c`` (R2, LPPD: its
    Neimark-Sacker curve; GPD: its fold curve) in the box ``rng1 x rng2`` of ``sys2``'s two parameters, or None.

    MatContM starts it from the point's normal form (an asymptotic predictor); here it is found by continuation
    instead: on a line of one parameter held :data:`SWITCH_OFFSET` of the box from the point (each parameter, each
    side), the flip of the period-``n`` orbit is refined, the period-``2n`` branch born there is switched onto
    (:func:`~.switching._switch`) and followed up to :data:`SWITCH_REACH` of the box; the first bifurcation of the
    sought kind on it is located and followed as a curve (:func:`_follow_curve`). Why it failed goes to
    ``messages``."""
    target, n = SWITCHES[c.kind], c.period
    boxes = (rng1, rng2)
    tol = eng.opts.corrector.ftol
    what = f"{c.kind} at ({c.values[0]:.12g}, {c.values[1]:.12g})"
    for k, sgn in ((1, 1.0), (1, -1.0), (0, 1.0), (0, -1.0)):
        j = 1 - k
        lo_k, hi_k = boxes[k]
        fixed = c.values[k] + sgn * SWITCH_OFFSET * (hi_k - lo_k)
        if not lo_k <= fixed <= hi_k:
            continue
        fmap = _Fixed(sys2, k, fixed)
        lo_j, hi_j = boxes[j]
        reach = SWITCH_REACH * (hi_j - lo_j)
        try:
            Y, _, _, _ = _refine(fmap, "period_doubling", n, np.array([*c.point, c.values[j]]), final=False)
            rng = (max(lo_j, Y[2] - reach), min(hi_j, Y[2] + reach))
            prob = _BranchProblem(fmap, rng, n, tol)
            at = eng.first(prob, np.array([Y[0], Y[1], prob.scaled(Y[2])]), np.array([0.0, 0.0, 1.0]))
            prob2 = _BranchProblem(fmap, rng, 2 * n, tol)
            xs, ps = _switch(eng, prob2, at)
            away = np.sign(prob2.scaled(ps) - prob2.scaled(Y[2])) or 1.0
            walk = eng.walk(eng.first(prob2, np.array([*xs, prob2.scaled(ps)]), np.array([0.0, 0.0, away])),
                            eng.opts.ds_max)  # fmt: skip
            for w in eng.follow(prob2, walk):
                if minimal_period(w.new.pts, w.new.pts[0], 2 * n, eng.opts.period_tol) < 2 * n:
                    w.stop = "collapsed"
                    continue
                if target not in _crossed(w.pt, w.new):
                    continue
                bif, _, _ = _located(eng, prob2, target, w.pt, w.new, 0)
                curve, losses = _follow_curve(eng, fmap, sys2.names[k], bif, boxes[j], boxes[k], nf, messages)
                if j == 1:  # followed in (p2, p1): back to (p1, p2)
                    curve.rows = [(b, a, q, r) for a, b, q, r in curve.rows]
                    curve.codim2 = [replace(p, values=p.values[::-1]) for p in curve.codim2]
                # The curve that emanates from c passes by it (another one of the doubled orbit may be met first).
                scale = np.array([rng1[1] - rng1[0], rng2[1] - rng2[0]])
                gap = min(float(np.abs((np.array(r[:2]) - c.values) / scale).max()) for r in curve.rows)
                if gap > SWITCH_NEAR:
                    raise _Stop(f"the {target.replace('_', '-')} curve met does not pass by it ({gap:.2g} of the box)")
                return replace(curve, origin=c), losses
            last = prob2.p(walk.pt.X)
            messages.append(f"{what}: no {target.replace('_', '-')} point of the period-{2 * n} orbit on the line "
                            f"{sys2.names[k]} = {fixed:.12g}, {sys2.names[j]} from {ps:.12g} to {last:.12g} "
                            f"({walk.reason})")  # fmt: skip
        except (_Stop, np.linalg.LinAlgError) as exc:
            messages.append(f"{what}: no switch on the line {sys2.names[k]} = {fixed:.12g} ({exc})")
    messages.append(f"{what}: no {target.replace('_', '-')} point of the period-{2 * n} orbit found nearby")
    return None, []
