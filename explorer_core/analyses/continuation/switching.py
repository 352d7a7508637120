"""Births and branch switching at period doublings.

At a period doubling the branch of period ``2n`` is switched onto (:func:`_switch`): it leaves the doubling point
tangent to the eigenvector ``v`` of ``mu = -1`` (a pitchfork of ``P^2n``), so the corrector from ``x* + h v`` with
``v . (x - x*) = h`` fixed lands on it. Followed to the next doubling, this is the cascade
``1 -> 2 -> 4 -> 8 -> 16``. Followed the other way, a period-``2n`` branch ends at its birth point
(:func:`_birth`), where it collapses onto the period-``n`` orbit (the parameter turns there, and the orbit's points
``x`` and ``P^n(x)`` meet): the branch stops there, it is not followed back through it.
"""

from __future__ import annotations

import numpy as np

from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.events import _locate, _refine
from explorer_core.analyses.continuation.problems import _BranchProblem
from explorer_core.analyses.continuation.system import _Stop
from explorer_core.analyses.orbits import eigenvector, ladder_seeds, minimal_period

#: A branch's birth point: at the turn of the parameter, ``|P^d(x) - x|`` is below this fraction of its value
#: at the neighbouring points (it vanishes like the square root of the distance to the birth).
BIRTH_RATIO = 0.1


def _separation(pt: _Point, d: int) -> float:
    """``|P^d(x) - x|`` relative to ``1 + |x|``."""
    x = pt.pts[0]
    return float(np.linalg.norm(pt.pts[d] - x) / (1.0 + np.linalg.norm(x)))


def _birth(eng: _Engine, prob: _BranchProblem, p0: _Point, p1: _Point) -> tuple[_Point, int] | None:
    """The birth point of a period-``n`` branch between ``p0`` and ``p1``, where the parameter turns, if there is one.

    At its birth (the period doubling of the period-``d`` orbit, ``n = 2d``) the branch is a parabola in the
    parameter through the period-``d`` orbit: the parameter turns there and ``|P^d(x) - x|`` vanishes like
    the square root of the distance. A fold of the period-``n`` orbit turns the parameter too, with the
    orbit's points apart.
    """
    n = prob.n
    divisors = [d for d in range(1, n) if n % d == 0]
    if not divisors or p0.t[2] * p1.t[2] >= 0:
        return None
    at, _ = _locate(eng, prob, lambda q: float(q.t[2]), p0, p1, sigma_tol=1e-9)
    for d in divisors:
        if _separation(at, d) <= BIRTH_RATIO * max(_separation(p0, d), _separation(p1, d)):
            return _birth_point(prob, at, d), d
    return None


def _birth_point(prob: _BranchProblem, at: _Point, d: int) -> _Point:
    """The birth point to the accuracy of the map: the period doubling of the period-``d`` orbit near ``at``.

    The branch's own points near it are ill-conditioned (its Jacobian is singular there, a pitchfork of
    ``P^n``); the doubling's defining system is regular. Falls back to ``at`` if its refinement fails.
    """
    Y0 = np.array([at.X[0], at.X[1], prob.p(at.X)])
    try:
        Y, _, _, _ = _refine(prob.sys, "period_doubling", d, Y0, final=False)
        if abs(Y[2] - Y0[2]) > 1e-4 * (1.0 + abs(Y0[2])) or np.linalg.norm(Y[:2] - Y0[:2]) > 1e-3:
            return at  # went elsewhere
        X = np.array([Y[0], Y[1], prob.scaled(Y[2])])
        _, jac, a, pts = prob.evaluate(X)
    except (_Stop, np.linalg.LinAlgError):
        return at
    return _Point(X, a, jac, at.t, pts, at.err)


def _switch(eng: _Engine, prob2: _BranchProblem, at: _Point) -> tuple[np.ndarray, float]:
    """A point of the period-``2n`` branch born at the period doubling ``at`` (a point of the period-``n`` branch)."""
    v = eigenvector(at.A, -1.0)
    x_star, s_star = at.X[:2], at.X[2]
    c = np.array([v[0], v[1], 0.0])
    for x in ladder_seeds(x_star, v):  # the one ladder (the app's following climbs it too)
        X_pred = np.array([*x, s_star])
        try:
            # Full Newton: at the pitchfork of P^2n the bordered Jacobian is singular, so F_s must be
            # taken at each iterate (off the doubling point), not frozen at it.
            new, _ = eng.correct(prob2, X_pred, c, c, max_iter=15)
        except _Stop:
            continue
        if minimal_period(new.pts, new.pts[0], prob2.n, 1e-6) == prob2.n:
            return new.X[:2], prob2.p(new.X)
    raise _Stop("could not switch onto the doubled branch")
