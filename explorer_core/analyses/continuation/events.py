"""Bifurcations on a branch: crossing, location and refinement.

Along a branch a bifurcation is a sign change of its test function (:func:`~.system.test_function`) between two
accepted points (:func:`_crossed`). It is located by bracketed secant steps in the arclength (each trial point
corrected onto the branch, :func:`_locate`) to within :data:`REFINE_FROM`, then refined by Newton on its defining
system to the accuracy of the map (:func:`_refine`; if that fails, the secant steps go on to ``|delta p| <=``
:data:`LOCATE_TOL`). The error estimate is the shift of the located value when the orbit is integrated ten
times less accurately (plus the bracket, if the refinement failed) (:func:`_located`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.engine import _Engine, _Point
from explorer_core.analyses.continuation.normal_forms import normal_form
from explorer_core.analyses.continuation.problems import _BranchProblem
from explorer_core.analyses.continuation.results import Bifurcation
from explorer_core.analyses.continuation.system import (
    KINDS,
    ContinuationMap,
    _complex_pair,
    _defining,
    _residual,
    _Stop,
    test_function,
)
from explorer_core.analyses.orbits import multipliers

#: A located bifurcation's bracket in the parameter.
LOCATE_TOL = 1e-12
#: The secant steps along the branch stop at this bracket (relative) when Newton on the bifurcation's defining
#: system takes over (it converges quadratically from there; each secant step is a corrected point of the branch).
REFINE_FROM = 1e-5
#: Newton on a bifurcation's defining system stops when its steps, below this (relative), no longer contract:
#: the map's noise (steps of ~1e-12 on Fig. 10's period 16 at rtol 1e-11).
REFINE_NOISE = 1e-10


def _crossed(p0: _Point, p1: _Point) -> list[str]:
    """The test functions that change sign between two points of a branch."""
    out = []
    for kind in KINDS:
        f0, f1 = test_function(kind, p0.A), test_function(kind, p1.A)
        if f0 == 0.0 or (f0 > 0) == (f1 > 0):
            continue
        if kind == "neimark_sacker" and not (_complex_pair(p0.A) and _complex_pair(p1.A)):
            continue  # det A = 1 with real multipliers mu, 1/mu: a neutral saddle, no bifurcation
        out.append(kind)
    return out


def _regula_falsi(
    eng: _Engine,
    prob: Any,
    fn: Callable[[_Point], float],
    p0: _Point,
    p1: _Point,
    f0: float,
    f1: float,
    close: Callable[[_Point, _Point, float], bool],
) -> tuple[_Point, float, _Point, _Point]:
    """The zero of ``fn`` (``f0``, ``f1`` at ``p0``, ``p1``, of opposite signs) along the curve of ``prob`` between
    ``p0`` and ``p1``: Illinois regula falsi in the arclength along ``p0.t``, each trial corrected onto the curve
    (:meth:`~.engine._Engine.at`), until ``close(lo, hi, sigma_width)`` says the bracket is small enough (at most 60
    steps). Returns the last trial point, its value and the bracket's two ends."""
    lo, hi = 0.0, float(p0.t @ (p1.X - p0.X))
    flo, fhi = f0, f1
    plo, phi_ = p0, p1
    best, fbest = (p1, f1) if abs(f1) < abs(f0) else (p0, f0)
    side = 0
    for _ in range(60):
        if close(plo, phi_, hi - lo):
            break
        # Illinois regula falsi: secant steps that keep the bracket
        s = hi - fhi * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not (lo < s < hi):
            s = 0.5 * (lo + hi)
        mid = eng.at(prob, p0, s, p1)
        fm = fn(mid)
        best, fbest = mid, fm
        if fm == 0.0:
            return mid, 0.0, mid, mid
        if (fm > 0) == (fhi > 0):
            hi, fhi, phi_ = s, fm, mid
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo, plo = s, fm, mid
            if side == -1:
                fhi *= 0.5
            side = -1
    return best, fbest, plo, phi_


def _locate(eng: _Engine, prob: _BranchProblem, fn: Callable[[_Point], float], p0: _Point, p1: _Point,
            sigma_tol: float = 0.0, ptol: float = LOCATE_TOL) -> tuple[_Point, float]:  # fmt: skip
    """The zero of ``fn`` between ``p0`` and ``p1``: the point and its bracket in p.

    Stops when the bracket is below ``ptol`` (relative) in the parameter or ``sigma_tol`` in the arclength (at a
    turn of the parameter the parameter's bracket says nothing about the point's).
    """

    def close(a: _Point, b: _Point, width: float) -> bool:
        plo = prob.p(a.X)
        return abs(prob.p(b.X) - plo) <= ptol * (1.0 + abs(plo)) and abs(width) <= sigma_tol

    best, fbest, a, b = _regula_falsi(eng, prob, fn, p0, p1, fn(p0), fn(p1), close)
    return best, (0.0 if fbest == 0.0 and a is b else abs(prob.p(b.X) - prob.p(a.X)))


def _refine(
    sys: ContinuationMap, kind: str, n: int, Y: np.ndarray, final: bool = True, jac: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
    """Newton on the defining system from a located point: the bifurcation to the accuracy of ``P^n``, with ``A``
    and the orbit ``x, P(x), ..., P^(n-1)(x)`` there (``final=False``: the point alone, one integration less),
    and the Jacobian used.

    A chord method: the Jacobian (central differences, six members) is taken at the start (or given: ``jac``)
    and kept while the steps contract tenfold; each step then costs one integration of the tangent system
    instead of seven. The point is the zero of ``G``, whichever Jacobian steered Newton there.
    """
    last = math.inf
    for _ in range(8):
        if jac is None:
            g, jac, _, _ = _defining(sys, kind, n, Y)
        else:
            g, _, _ = _residual(sys, kind, n, Y)
        step = np.linalg.solve(jac, -g)
        size = float(np.abs(step).max())
        scale = 1.0 + float(np.abs(Y).max())
        noise = size <= REFINE_NOISE * scale
        if size > 0.1 * last and not noise:  # slow: a fresh Jacobian here (the step from the stale one is not taken)
            g, jac, _, _ = _defining(sys, kind, n, Y)
            step = np.linalg.solve(jac, -g)
            size = float(np.abs(step).max())
        Y = Y + step
        if not np.all(np.isfinite(Y)):
            raise _Stop("the refinement of a bifurcation overflowed")
        # Converged; or the steps stopped contracting at the map's noise (no Jacobian does better there).
        if size <= 1e-13 * scale or (noise and size > 0.1 * last):
            break
        last = size
    if not final:
        return Y, None, None, jac
    _, a, pts = _residual(sys, kind, n, Y)
    return Y, a, pts, jac


def _located(eng: _Engine, prob: _BranchProblem, kind: str, p0: _Point, p1: _Point,
             branch: int) -> tuple[Bifurcation, _Point, str]:  # fmt: skip
    """Locate the bifurcation between two points of a branch, with its normal form (:mod:`.normal_forms`), and
    why there is none ("" if there is).

    Bracketed secant steps along the branch bring the test function's zero to within :data:`REFINE_FROM`;
    Newton on the defining system ``(P^n(x) - x, test(DP^n)) = 0`` then refines it to the accuracy of the
    integration (if it fails, the secant steps go on to :data:`LOCATE_TOL`). The error
    estimate is the shift of the refined value when ``P^n`` is integrated ten times less accurately
    (plus the secant bracket, if the refinement failed).
    """
    test = lambda q: test_function(kind, q.A)  # noqa: E731
    at, bracket = _locate(eng, prob, test, p0, p1, sigma_tol=math.inf, ptol=REFINE_FROM)
    n, sys = prob.n, prob.sys
    Y0 = np.array([at.X[0], at.X[1], prob.p(at.X)])
    try:
        Y, a, pts, jac = _refine(sys, kind, n, Y0)
        # The error estimate: the same zero of the less accurate map, from Y with the same Jacobian.
        Y2, _, _, _ = _refine(sys.coarse(), kind, n, Y, final=False, jac=jac)
        error = abs(Y2[2] - Y[2])
        # The zero is inside the bracket: a refinement further than that (and the map's accuracy) went elsewhere.
        if abs(Y[2] - Y0[2]) > bracket + 1e3 * (LOCATE_TOL + 1e-9) * (1 + abs(Y0[2])):
            raise _Stop("the refinement went elsewhere")  # keep the bracketed value
    except (_Stop, np.linalg.LinAlgError):
        # No refinement: the secant steps locate the zero to LOCATE_TOL themselves.
        at, bracket = _locate(eng, prob, test, p0, p1, sigma_tol=math.inf)
        Y, a, pts, error = np.array([at.X[0], at.X[1], prob.p(at.X)]), at.A, at.pts, bracket
    X = np.array([Y[0], Y[1], prob.scaled(Y[2])])
    at = _Point(X, a, at.J, at.t, pts)
    nf, why = None, ""
    try:
        nf = normal_form(sys, kind, Y[:2], [float(Y[2])], n, a)
    except (_Stop, np.linalg.LinAlgError) as exc:
        why = f"{kind} at {sys.names[0]} = {Y[2]:.12g}: no normal form ({exc})"
    bif = Bifurcation(kind, float(Y[2]), float(error), n, Y[:2].copy(), multipliers(a), branch, nf)
    return bif, at, why
