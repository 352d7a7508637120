"""Two-parameter continuation of a fold or period-doubling point.

The curve of ``F = 0, phi = 0`` (``phi`` the test function, :func:`~.system._defining`) in ``(x, p1, p2)``, each
parameter scaled to its range (:class:`~.problems._CurveProblem`), followed both ways from the located bifurcation
by the same engine as the branches, each half to the edge of the box ``window1 x range2``.
"""

from __future__ import annotations

import numpy as np

from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.problems import _CurveProblem
from explorer_core.analyses.continuation.results import Bifurcation, Curve
from explorer_core.analyses.continuation.system import ContinuationMap, _Stop
from explorer_core.losses import Loss
from explorer_core.status import Status


def _follow_curve(eng: _Engine, branch: ContinuationMap, name2: str, bif: Bifurcation, rng1: tuple[float, float],
                  rng2: tuple[float, float]) -> tuple[Curve, list[Loss]]:  # fmt: skip
    """The curve of ``F = 0, phi = 0`` through ``bif`` (located on a branch of the map ``branch``) in
    ``(name1, name2)``, ``name1`` the branch's parameter, both ways, within ``rng1 x rng2``.

    Pseudo-arclength in ``(q, r, s1, s2)`` with each parameter scaled to its range (``rng1``: the window of the
    first parameter, ``rng2``), by the same engine as the branches; each half ends on the box's edge.
    """
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
    reasons, losses = [], []
    for sgn, way in ((1.0, "one way"), (-1.0, "the other way")):
        rows: list[tuple[float, float, float, float]] = []
        walk = eng.walk(_Point(Z0, pt0.A, pt0.J, sgn * pt0.t, None), eng.opts.curve_ds_max)
        try:
            for w in eng.follow(prob, walk):  # every point the engine accepts is one of the curve
                Y = prob.unscaled(w.new.X)
                rows.append((float(Y[2]), float(Y[3]), float(Y[0]), float(Y[1])))
            reason, lost, status = walk.reason, walk.lost, walk.status
        except _Stop as exc:
            reason, lost, status = str(exc), True, exc.status
        if curve.status == Status.OK:
            curve.status = status
        if lost:
            losses.append(Loss(f"{what} ({way})", 1, reason))
        halves.append(rows)
        reasons.append(reason)
    Y0 = prob.unscaled(Z0)
    curve.rows = [*reversed(halves[1]), (float(Y0[2]), float(Y0[3]), float(Y0[0]), float(Y0[1])), *halves[0]]
    curve.stop = "; ".join(reasons)
    return curve, losses
