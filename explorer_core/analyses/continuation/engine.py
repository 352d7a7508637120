"""The continuation engine: predictor, corrector, step control and the landing on the range's ends.

Pseudo-arclength continuation (Keller) follows a curve of zeros of a problem (:mod:`.problems`) through folds:
from a point ``X`` with unit tangent ``t`` (the null vector of the problem's Jacobian, ``[DP^n - I | F_p]`` on a
branch) the predictor ``X + ds t`` is corrected by Newton on ``F = 0, t . (X - X_pred) = 0``. One engine
(:class:`_Engine`) does it for every curve followed here: the branches of one-parameter continuation, the
branches switched onto at period doublings, and the two-parameter curves of folds and doublings. Its settings
are one :class:`~.options.ContinuationOptions`. A refused step (the corrector failed or went too far from the
prediction, the tangent turned too much, or the driver refused the point: the orbit lost its period, a
bifurcation could not be located) is retried shorter, down to ``ds_min``; the step grows again after
corrections that contract fast (Deuflhard's rule on the Newton contraction, so a strongly unstable branch,
whose corrector always needs a few iterations, is not slowed down step after step).

Continuation is an iterator (BifurcationKit's ``ContIterable`` over a ``ContState``): the state of a curve
being followed is explicit (:class:`_Walk`: its last point, the next step, the refusals), and
:meth:`_Engine.follow` is a generator that yields that state at every point the engine accepts. The driver
looks at the point (``walk.new``) between two steps and decides: go on, end the curve there
(``walk.stop``), or refuse the point (``walk.refusal``, retried shorter); it locates bifurcations and queues
switched branches itself. When the generator returns, the state says how the curve ended.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.options import ContinuationOptions
from explorer_core.analyses.continuation.system import _Stop
from explorer_core.status import Status


def _null(j: np.ndarray) -> np.ndarray:
    """Unit null vector of a full-rank (k, k+1) matrix."""
    _, _, vt = np.linalg.svd(j)
    v = vt[-1]
    return v / np.linalg.norm(v)


@dataclass
class _Point:
    """A point of a curve in its scaled coordinates, with what the corrector computed there."""

    X: np.ndarray  # branch: (q, r, s); curve: (q, r, s1, s2); each s a parameter scaled to its range
    A: np.ndarray  # DP^n
    J: np.ndarray  # (k, k+1): the Jacobian of the defining equations (its null vector is the tangent)
    t: np.ndarray  # unit tangent
    pts: np.ndarray | None  # branch: (n, 2) the orbit x, P(x), ..., P^(n-1)(x)
    err: float = 0.0  # the corrector's last step: how far the point may be from the curve
    #: dt/ds, the tangent's change per arclength since the previous point of the curve (None: no previous point)
    curv: np.ndarray | None = None


@dataclass
class _Walk:
    """The state of one curve being followed (BifurcationKit's ``ContState``), made by :meth:`_Engine.walk` and
    advanced by :meth:`_Engine.follow`.

    Between two steps, ``new`` is the point the engine just accepted (``at_end``: on an end of the range) and ``pt``
    the one before it; the driver may set ``stop`` (end the curve at ``new``: a stop it meant, nothing lost) or
    ``refusal`` (``new`` is refused: the step is retried shorter, as when the corrector fails). When ``follow``
    returns, ``pt`` is the curve's last point, ``reason`` says why it ended, ``lost`` is True unless it reached an
    end of its range or a stop the driver meant (then ``status`` is ok).
    """

    pt: _Point
    ds_max: float  # the longest step of this curve
    h: float  # the next step
    #: Newton's contraction per unit error of the prediction (see :meth:`_Engine._trial`); None until measured
    kappa: float | None = None
    count: int = 1  # the points accepted so far, the first included
    first_refusal: str = ""  # since the last accepted point: the longer step may have failed for a telling reason
    new: _Point | None = None
    at_end: bool = False
    stop: str | None = None
    refusal: _Stop | None = None
    reason: str = ""
    lost: bool = False
    status: Status = Status.OK

    def end(self, reason: str, lost: bool, status: Status, last: _Point | None = None) -> None:
        self.reason, self.lost, self.status = reason, lost, status
        if last is not None:
            self.pt = last


class _Refused(_Stop):
    """A trial step refused; ``used`` is the step it took (the next one is shorter than that)."""

    def __init__(self, why: str, used: float, status: Status = Status.NOT_CONVERGED) -> None:
        super().__init__(why, status)
        self.used = used


class _Engine:
    """Pseudo-arclength continuation of the zeros of a problem (:class:`_BranchProblem`, :class:`_CurveProblem`)."""

    def __init__(self, options: ContinuationOptions, cancel: Callable[[], bool] | None) -> None:
        self.opts = options
        self.cancel = cancel
        self.min_cos = math.cos(options.max_turn)

    def first(self, prob: Any, X: np.ndarray, orient: np.ndarray) -> _Point:
        """The point ``X`` (on the curve already) and its tangent, oriented along ``orient``."""
        f, jac, a, pts = prob.evaluate(X)
        t = _null(jac)
        return _Point(X, a, jac, t if t @ orient >= 0 else -t, pts)

    def correct(self, prob: Any, X_pred: np.ndarray, c: np.ndarray, orient: np.ndarray,
                chord: np.ndarray | None = None, max_iter: int | None = None) -> tuple[_Point, float]:  # fmt: skip
        """Newton on ``F = 0, c . (X - X_pred) = 0``; the point and the worst contraction ``|dX_k+1| / |dX_k|``.

        ``chord``: a Jacobian whose parameter columns are kept throughout (one trajectory less per
        iteration), refreshed at the solution for its tangent.
        """
        max_iter = self.opts.corrector.max_iter if max_iter is None else max_iter
        X = X_pred.copy()
        norms: list[float] = []
        for _ in range(max_iter):
            f, jac, a, pts = prob.evaluate(X, chord)
            g = float(c @ (X - X_pred))
            try:
                dX = np.linalg.solve(np.vstack([jac, c[None, :]]), -np.concatenate([f, [g]]))
            except np.linalg.LinAlgError:
                raise _Stop("singular corrector") from None
            if prob.converged(f, g, dX, X, a):
                if chord is not None:
                    jac = prob.fresh(X, jac)
                t = _null(jac)
                err = float(np.linalg.norm(dX))
                # Newton's first contraction, unless its second step is already at the accuracy of the map
                # (then the ratio measures rounding, not the predictor's error).
                theta = norms[1] / norms[0] if len(norms) > 1 and norms[1] > 10 * err else 0.0
                return _Point(X, a, jac, t if t @ orient >= 0 else -t, pts, err), theta
            norms.append(float(np.linalg.norm(dX)))
            X = X + dX
            if not np.all(np.isfinite(X)):
                raise _Stop("the corrector overflowed")
        raise _Stop(f"the corrector did not converge in {max_iter} iterations")

    def at(self, prob: Any, pt: _Point, sigma: float, end: _Point | None = None) -> _Point:
        """The point at arclength ``sigma`` from ``pt`` along its tangent (locating bifurcations), on the plane
        ``pt.t . (X - pt.X) = sigma``. Predicted on the cubic through ``pt`` and ``end`` (the bracket's far end)
        with their tangents, whose error goes as the bracket's length to the fourth, not the tangent line
        (second power): one or two Newton steps instead of three to six on Fig. 10's period-8 branch. Full
        Newton: with ``F_p`` frozen at ``pt`` the corrector of an unstable orbit took 3-4 times the iterations
        (Fig. 10's period 16), each more than the central difference it saved."""
        X_pred = pt.X + sigma * pt.t
        if end is not None:
            chord = end.X - pt.X
            span, length = float(pt.t @ chord), float(np.linalg.norm(chord))
            if span > 0.0 and float(end.t @ pt.t) > 0.0:
                u = sigma / span
                h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
                cubic = h00 * pt.X + h10 * length * pt.t + h01 * end.X + h11 * length * end.t
                X_pred = cubic + (sigma - float(pt.t @ (cubic - pt.X))) * pt.t  # onto the plane
        return self.correct(prob, X_pred, pt.t, pt.t, max_iter=self.opts.corrector.max_iter + 4)[0]

    def _check(self, pt: _Point, new: _Point, X_pred: np.ndarray, h: float) -> None:
        d = float(np.linalg.norm(new.X - X_pred))
        # The points are on the curve to the corrector's accuracy only (large with |DP^n|).
        if d > self.opts.max_distance * h + 4.0 * (pt.err + new.err):
            raise _Stop(f"the corrector went {d:.3g} from the prediction, more than {self.opts.max_distance:g} "
                        f"times the step {h:.3g}")  # fmt: skip
        if float(new.t @ pt.t) < self.min_cos and h > self.opts.ds_min * (1 + 1e-9):
            raise _Stop(f"the tangent turned by {math.degrees(math.acos(max(-1.0, float(new.t @ pt.t)))):.3g} deg")

    @staticmethod
    def _exit(box: Sequence[tuple[int, float, float]], X0: np.ndarray, X1: np.ndarray):
        """The first bound of ``box`` the segment ``X0 -> X1`` crosses: ``(coordinate, bound, fraction)`` or None."""
        first = None
        for k, lo, hi in box:
            for bound in (lo, hi):
                outward = X1[k] < lo if bound == lo else X1[k] > hi
                if (X1[k] - bound) * (X0[k] - bound) < 0 or (X1[k] == bound != X0[k]) or (X0[k] == bound and outward):
                    lam = (bound - X0[k]) / (X1[k] - X0[k])
                    if first is None or lam < first[2]:
                        first = (k, bound, float(lam))
        return first

    def _land(self, prob: Any, pt: _Point, X_pred: np.ndarray, k: int, bound: float) -> tuple[_Point, float]:
        """The point of the curve on ``X_k = bound`` near ``X_pred`` (an end of a range)."""
        X_pred = X_pred.copy()
        X_pred[k] = bound
        c = np.zeros_like(X_pred)
        c[k] = 1.0
        new, theta = self.correct(prob, X_pred, c, pt.t, max_iter=self.opts.corrector.max_iter + 4)
        new.X[k] = bound  # exact: the constraint is linear
        self._check(pt, new, X_pred, float(np.linalg.norm(X_pred - pt.X)))
        for j, lo, hi in prob.box:
            if not lo - 1e-12 <= new.X[j] <= hi + 1e-12:
                raise _Stop("the end point is outside the other range")
        return new, theta

    def _trial(self, prob: Any, walk: _Walk) -> tuple[_Point, float, bool]:
        """One step of length ``walk.h`` from ``walk.pt``: the new point, the contraction, and whether it is on an end.

        The corrector starts from the second-order prediction ``X + h t + h^2/2 dt/ds`` (``dt/ds`` from the
        previous point; error ~ ``h^3``): fewer Newton steps. The steps stay those of the first-order rule:
        Newton's contraction is ``kappa`` times the prediction's error, ``kappa`` measured at every step
        (the first of a curve from the tangent line), and the contraction returned is ``kappa`` times the
        tangent line's error ``|X_new - (X + h t)|``. Longer steps would save more, but through a chaotic band
        they jump between the many nearby orbits of one period (Fig. 10's period 16 beyond alpha = -0.413).
        """
        pt, h = walk.pt, walk.h
        X_pred = pt.X + h * pt.t
        ex = self._exit(prob.box, pt.X, X_pred)
        used = h
        try:
            if ex is not None and ex[2] <= 0.0:
                return pt, 0.0, True  # on an end already, and leaving the range: done
            if ex is not None:  # the step would pass the end: shortened to land on it
                k, bound, lam = ex
                used = lam * h
                new, theta = self._land(prob, pt, pt.X + used * pt.t, k, bound)
                return new, theta, True
            second = pt.curv is not None and walk.kappa is not None
            start = X_pred + 0.5 * h * h * pt.curv if second else X_pred
            new, theta = self.correct(prob, start, pt.t, pt.t)
            self._check(pt, new, X_pred, h)
            line, off = float(np.linalg.norm(new.X - X_pred)), float(np.linalg.norm(new.X - start))
            if theta > 0.0 and off > 0.0:
                walk.kappa = theta / off
            if second:
                theta = walk.kappa * line
            ex = self._exit(prob.box, pt.X, new.X)
            if ex is not None:  # corrected beyond the end: the end point along the chord
                k, bound, lam = ex
                used = lam * h
                new, theta = self._land(prob, pt, pt.X + lam * (new.X - pt.X), k, bound)
                return new, theta, True
            return new, theta, False
        except _Refused:
            raise
        except _Stop as exc:
            raise _Refused(str(exc), used, exc.status) from None

    def walk(self, pt: _Point, ds_max: float) -> _Walk:
        """The state of a curve to follow from ``pt`` (its tangent oriented the way to go), steps up to ``ds_max``."""
        return _Walk(pt, ds_max, min(self.opts.ds, ds_max))

    def follow(self, prob: Any, walk: _Walk) -> Iterator[_Walk]:
        """Steps from ``walk.pt`` until an end, a stop the driver sets, or a refusal at ``ds_min``; yields ``walk``
        at every point accepted (``walk.new``), for the driver to judge (see :class:`_Walk`). ``cancel`` is polled
        before every step."""
        o = self.opts
        while True:
            if self.cancel is not None and self.cancel():
                walk.end("cancelled", True, Status.CANCELLED)
                return
            if walk.count >= o.max_points:
                walk.end(f"stopped after max_points = {o.max_points} points", True, Status.BUDGET)
                return
            try:
                new, theta, at_end = self._trial(prob, walk)
                if new is walk.pt:
                    walk.end("range end", False, Status.OK)
                    return
                walk.new, walk.at_end, walk.stop, walk.refusal = new, at_end, None, None
                yield walk
                if walk.refusal is not None:
                    raise walk.refusal
            except _Stop as exc:
                used = exc.used if isinstance(exc, _Refused) else walk.h
                walk.first_refusal = walk.first_refusal or str(exc)
                if used <= o.ds_min * (1 + 1e-9):
                    why = f"{exc} (at the minimum step ds_min = {o.ds_min:g})"
                    if walk.first_refusal != str(exc):
                        why += f"; with longer steps: {walk.first_refusal}"
                    walk.end(why, True, exc.status)
                    return
                walk.h = max(o.ds_min, used * o.shrink)
                continue
            walk.first_refusal = ""
            walk.count += 1
            if walk.stop is not None:
                walk.end(walk.stop, False, Status.OK, new)
                return
            if at_end:
                walk.end("range end", False, Status.OK, new)
                return
            new.curv = (new.t - walk.pt.t) / max(float(np.linalg.norm(new.X - walk.pt.X)), 1e-300)
            walk.pt = new
            # Deuflhard's rule: the predictor's error, hence the corrector's contraction, goes as h^2.
            factor = o.growth if theta <= 0.0 else min(o.growth, max(o.shrink, math.sqrt(o.contraction / theta)))
            walk.h = min(walk.ds_max, max(o.ds_min, walk.h * factor))
