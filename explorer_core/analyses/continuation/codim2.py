"""Codimension-two points on the two-parameter curves of folds, period doublings (flips) and Neimark-Sacker points.

Along a curve of ``P^n`` (``A = DP^n`` at each point, one multiplier ``mu1`` critical) a codimension-two point is a
zero of a test function (MatContM's for maps, Kuznetsov & Meijer, *Numerical Bifurcation Analysis of Maps*, 2019,
ch. 4; ``limitpointmap.m``, ``perioddoublingmap.m``, ``neimarksackermap.m``), which on a map of the plane reduce to
the second multiplier ``mu2`` and the normal-form coefficient of the curve's bifurcation (:mod:`.normal_forms`):

* fold curve (``mu1 = 1``, ``mu2 = tr A - 1``): **CP** (cusp) the fold coefficient ``a = 0``; **R1** (1:1
  resonance) ``mu2 = 1``: ``tr A - 2``; **LPPD** (fold-flip) ``mu2 = -1``: ``det(A + I)``.
* flip curve (``mu1 = -1``, ``mu2 = tr A + 1``): **GPD** (generalised flip) the flip coefficient ``b = 0``;
  **LPPD** ``mu2 = 1``: ``det(A - I)``; **R2** (1:2 resonance) ``mu2 = -1``: ``tr A + 2``.
* Neimark-Sacker curve (``det A = 1``, ``mu = e^{+-i theta}``, ``kappa = cos theta = tr A / 2``, MatContM's ``k``):
  **R1** ``kappa - 1`` (``theta -> 0``), **R2** ``kappa + 1`` (``theta -> pi``), **R3** ``kappa + 1/2``
  (``theta = 2 pi / 3``), **R4** ``kappa`` (``theta = pi / 2``), **CH** (Chenciner) ``Re d = 0``. At R1 and R2 the
  pair turns real (``det A = 1`` then holds on a neutral saddle, no bifurcation): the curve ends there.

**LPNS, PDNS, NSNS** (a fold, a flip or a second Neimark-Sacker pair beside a Neimark-Sacker pair) need three or
four multipliers, so a map of the plane (this system's Poincare map, the test maps) has none: they are not
looked for (:data:`NOT_IN_THE_PLANE`).

A sign change of a test function between two accepted points of a curve is located by bracketed secant steps
(Illinois) in the arclength along the curve, each trial point corrected onto the curve (as a bifurcation on a branch,
:func:`~.events._locate`), until the bracket in both parameters is below :data:`LOCATE_TOL`. The error estimate is
that bracket, plus the corrector's last step, plus (for CP, GPD, CH) the coefficient's own error estimate turned
into a shift along the curve by the test function's slope. A normal-form coefficient changes sign through a pole
too (its resolvent singular near R1, R3 or LPPD): a zero is kept only if the test function is smaller there than
at both ends of the bracket, and only where the coefficient is larger than its error estimate at both ends.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.events import _regula_falsi
from explorer_core.analyses.continuation.normal_forms import NF_FLOOR, normal_form
from explorer_core.analyses.continuation.problems import _CurveProblem
from explorer_core.analyses.continuation.results import Codim2Point
from explorer_core.analyses.continuation.system import _Stop
from explorer_core.analyses.orbits import multipliers

#: The codimension-two points looked for on each kind of curve, in the order they are tested.
ON_CURVE: dict[str, tuple[str, ...]] = {
    "fold": ("CP", "R1", "LPPD"),
    "period_doubling": ("GPD", "LPPD", "R2"),
    "neimark_sacker": ("CH", "R1", "R2", "R3", "R4"),
}
#: Codimension-two points that need a map of dimension three or more: never on a map of the plane.
NOT_IN_THE_PLANE = ("LPNS", "PDNS", "NSNS")
#: Where a Neimark-Sacker curve ends: the complex pair turns real.
ENDS_NS = ("R1", "R2")
#: The located point's bracket in each parameter (relative to ``1 + |p|``).
LOCATE_TOL = 1e-13
#: The test functions given by a normal-form coefficient (the others by ``A`` alone).
BY_NORMAL_FORM = {"CP": "fold", "GPD": "period_doubling", "CH": "neimark_sacker"}


def _by_multipliers(kind: str, name: str, a: np.ndarray) -> float:
    """A test function given by ``A = DP^n`` alone (module docstring)."""
    tr = float(np.trace(a))
    if kind == "neimark_sacker":
        k = 0.5 * tr
        return {"R1": k - 1.0, "R2": k + 1.0, "R3": k + 0.5, "R4": k}[name]
    if name == "R1":
        return tr - 2.0
    if name == "R2":
        return tr + 2.0
    # LPPD: the other multiplier -1 on a fold curve, +1 on a flip curve
    return float(np.linalg.det(a + np.eye(2) if kind == "fold" else a - np.eye(2)))


class _Tests:
    """The test functions of one curve at its points: ``values(pt)`` maps each name to ``(value, error)``
    (``None`` where a normal form could not be computed). Those of ``A`` alone cost nothing; those a normal-form
    coefficient gives (``nf``) a normal form at every point (about half the curve's own cost)."""

    def __init__(self, prob: _CurveProblem, nf: bool) -> None:
        self.prob = prob
        self.names = tuple(k for k in ON_CURVE[prob.kind] if nf or k not in BY_NORMAL_FORM)

    def one(self, name: str, pt: _Point) -> tuple[float, float] | None:
        kind = self.prob.kind
        if name not in BY_NORMAL_FORM:
            return _by_multipliers(kind, name, pt.A), 0.0
        if kind == "neimark_sacker" and not float(np.trace(pt.A)) ** 2 < 4.0 * float(np.linalg.det(pt.A)):
            return None  # no complex pair: no Neimark-Sacker coefficient
        Y = self.prob.unscaled(pt.X)
        try:
            nf = normal_form(self.prob.sys, kind, Y[:2], [float(Y[2]), float(Y[3])], self.prob.n, pt.A)
        except (_Stop, np.linalg.LinAlgError):
            return None
        # A coefficient that vanishes identically (an area-preserving map's Re d) is rounding: no sign to compare
        # (NF_FLOOR).
        return nf.coefficient, max(nf.error, NF_FLOOR * (1.0 + float(np.abs(pt.A).max())))

    def values(self, pt: _Point) -> dict[str, tuple[float, float] | None]:
        return {name: self.one(name, pt) for name in self.names}


def _changed(name: str, f0: tuple[float, float] | None, f1: tuple[float, float] | None) -> bool:
    """A sign change of a test function between two points, each value beyond its error estimate."""
    if f0 is None or f1 is None or f0[0] == 0.0:
        return False
    if name in BY_NORMAL_FORM and not (abs(f0[0]) > f0[1] and abs(f1[0]) > f1[1]):
        return False  # not distinguishable from 0 at an end: no sign to compare
    return (f0[0] > 0) != (f1[0] > 0)


def _locate(eng: _Engine, prob: _CurveProblem, fn: Callable[[_Point], tuple[float, float] | None], p0: _Point,
            p1: _Point, f0: float, f1: float) -> tuple[_Point, float, float, float]:  # fmt: skip
    """The zero of ``fn`` between the curve's points ``p0`` and ``p1``: the point, its test value, the bracket in
    the parameters (the larger of the two, unscaled) and the slope of the test function per unit of the parameters.

    Illinois regula falsi in the arclength along the curve (:func:`~.events._regula_falsi`, as a bifurcation on a
    branch), to :data:`LOCATE_TOL` in both parameters."""

    def value(q: _Point) -> float:
        val = fn(q)
        if val is None:
            raise _Stop("the test function could not be computed inside the bracket")
        return val[0]

    def params(q: _Point) -> np.ndarray:
        return prob.unscaled(q.X)[2:]

    def close(a: _Point, b: _Point, width: float) -> bool:
        return bool(np.all(np.abs(params(b) - params(a)) <= LOCATE_TOL * (1.0 + np.abs(params(a)))))

    slope = abs(f1 - f0) / max(float(np.abs(params(p1) - params(p0)).max()), 1e-300)
    best, fbest, a, b = _regula_falsi(eng, prob, value, p0, p1, f0, f1, close)
    return best, fbest, float(np.abs(params(b) - params(a)).max()), slope


def _off_curve(prob: _CurveProblem, name: str, at: _Point, val: float, slope: float) -> float:
    """How far the located point ``at`` may be from the codimension-two point because it is off the curve: the
    corrector stops once its step is below its tolerance (``1e-9`` of the box), and that step, not taken, moves
    the test function too. Here: the shortest step onto the curve from ``at`` (the defining system's minimum-norm
    Newton step), its length in the parameters plus the change of the test function along it over its slope; and
    the test function's own error (twice its spread over ``DP^n`` started from the orbit's other points) over the
    slope.
    The Henon 8-cycle's R2 on its flip curve was ``7e-9`` off (the step's ``1.6e-9`` in ``b``, ``tr A`` steep in
    ``a``) against an estimate of ``3.7e-9`` without this; on its Neimark-Sacker curve it is ``4e-12`` off."""
    try:
        f, jac, _, _ = prob.evaluate(at.X)
        dX = -np.linalg.pinv(jac) @ f
        Y0, Y1 = prob.unscaled(at.X), prob.unscaled(at.X + dX)
        p1 = [float(Y1[2]), float(Y1[3])]
        _, a1, pts1 = prob.sys.orbit(Y1[:2], p1, prob.n)
        # The test function's own error: DP^n from the orbit's other points has the same multipliers through
        # other products (their rounding); twice their spread, a margin (a few samples of a rounding error). On
        # the Henon 16-cycle's flip curve, where tr A + 2 = 1 - b^16 is flat, that is the R2's error (1.2e-11 in a).
        others = [prob.sys.orbit(x, p1, prob.n)[1] for x in pts1[: prob.n - 1]]
    except (_Stop, np.linalg.LinAlgError):
        return 0.0  # the bracket and the corrector's step stand alone
    f1 = _by_multipliers(prob.kind, name, a1)
    spread = max((abs(_by_multipliers(prob.kind, name, a) - f1) for a in others), default=0.0)
    shift = (abs(f1 - val) + 2.0 * spread) / max(slope, 1e-300)
    return float(np.abs(Y1[2:] - Y0[2:]).max()) + shift


def _crossings(eng: _Engine, prob: _CurveProblem, tests: _Tests, pt: _Point, new: _Point, f_pt: dict[str, Any],
               f_new: dict[str, Any]) -> tuple[list[tuple[Codim2Point, _Point]], list[str]]:  # fmt: skip
    """The codimension-two points between two accepted points of a curve, located, in the curve's order, and why
    a sign change was not kept (a pole of a coefficient, a failed location)."""
    found, why = [], []
    for name in tests.names:
        if not _changed(name, f_pt[name], f_new[name]):
            continue
        fn = lambda q, name=name: tests.one(name, q)  # noqa: E731
        try:
            at, val, bracket, slope = _locate(eng, prob, fn, pt, new, f_pt[name][0], f_new[name][0])
        except (_Stop, np.linalg.LinAlgError) as exc:
            why.append(f"{name}: not located ({exc})")
            continue
        if abs(val) >= min(abs(f_pt[name][0]), abs(f_new[name][0])):
            why.append(f"{name}: a pole of its test function, not a zero")
            continue
        own = fn(at)
        Y = prob.unscaled(at.X)
        # The bracket, the corrector's last step (not taken: the point is that far from the curve, in the state too,
        # which the test function turns into a shift along it; four times, a margin), and the parameters' rounding.
        err = (bracket + 4.0 * float(at.err * max(1.0, np.abs(prob.w[2:]).max()))
               + LOCATE_TOL * (1.0 + float(np.abs(Y[2:]).max())))  # fmt: skip
        if name in BY_NORMAL_FORM and own is not None:
            err += own[1] / max(slope, 1e-300)
        elif name not in BY_NORMAL_FORM:
            err += _off_curve(prob, name, at, val, slope)
            # The map's own error, as for a bifurcation of a branch: the test function of the ten times less
            # accurate map at the point, turned into a shift along the curve (0 on a map in closed form).
            coarse = prob.sys.coarse()
            if coarse is not prob.sys:
                a2 = coarse.orbit(Y[:2], [float(Y[2]), float(Y[3])], prob.n)[1]
                err += abs(_by_multipliers(prob.kind, name, a2) - val) / max(slope, 1e-300)
        along = float(pt.t @ (at.X - pt.X))
        found.append((along, Codim2Point(name, prob.kind, prob.n, (float(Y[2]), float(Y[3])), float(err),
                                         (float(Y[0]), float(Y[1])), tuple(complex(m) for m in multipliers(at.A))),
                      at))  # fmt: skip
    found.sort(key=lambda f: f[0])
    return [(c, at) for _, c, at in found], why
