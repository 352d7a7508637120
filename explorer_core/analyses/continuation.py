"""Continuation of periodic orbits of the Poincare map in a parameter, through their bifurcations.

A period-``n`` orbit is a zero of ``F(x, p) = P^n(x; p) - x``; its points ``(x, p)`` form curves
(branches). Pseudo-arclength continuation (Keller) follows a branch through folds: from a point ``X``
with unit tangent ``t`` (the null vector of ``[DP^n - I | F_p]``) the predictor ``X + ds t`` is corrected
by Newton on ``F = 0, t . (X - X_pred) = 0``. ``DP^n`` is the exact monodromy matrix (tangent system);
``F_p`` a central difference whose three members (``p``, ``p +- delta``) go in one lock-step batch, so
they share one step sequence and the difference is smooth in ``p``.

Along a branch the test functions (Kuznetsov, *Elements of Applied Bifurcation Theory*, ch. 10; as in
MatContM) are ``det(A - I)`` (fold, ``mu = +1``), ``det(A + I)`` (period doubling, ``mu = -1``) and
``det A - 1`` on a complex pair (Neimark-Sacker, ``|mu| = 1``), ``A = DP^n``. A sign change between two
points is located by bracketed secant steps in the arclength (each trial point corrected onto the
branch) to ``|delta p| <= 1e-12``; the error estimate adds the bracket to the shift of the located value
when the orbit is integrated ten times less accurately.

At a period doubling the branch of period ``2n`` is switched onto (``switch=True``): it leaves the
doubling point tangent to the eigenvector ``v`` of ``mu = -1`` (a pitchfork of ``P^2n``), so the
corrector from ``x* + h v`` with ``v . (x - x*) = h`` fixed lands on it. Followed to the next doubling,
this is the cascade ``1 -> 2 -> 4 -> 8 -> 16``.

Two-parameter continuation follows a fold or period-doubling point in a second parameter: the curve of
``F = 0, phi = 0`` (``phi`` the test function) in ``(x, p1, p2)``, with ``phi``'s derivatives by central
differences of the monodromy (nine members in one lock-step batch).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core.analyses.orbits import ORBIT_NUMERICS, UNIT_TOL, classify, minimal_period, multipliers, newton
from explorer_core.analyses.sweeps import check_param
from explorer_core.solve.integrators import run_at
from explorer_core.solve.numerics import Numerics, check_ics, check_int
from explorer_core.solve.rk import FIELD, Status
from explorer_core.solve.tangent import monodromy_at
from explorer_core.system.params import ParameterError, Params

#: Bifurcation types and their test functions.
KINDS = ("fold", "period_doubling", "neimark_sacker")
#: Relative size of the parameter step of the finite differences.
FD_STEP = 1e-7
#: Newton on a corrected point stops when ``|F| <= CORRECTOR_TOL (1 + |x|)``.
CORRECTOR_TOL = 1e-10
#: A located bifurcation's bracket in the parameter.
LOCATE_TOL = 1e-12
MAX_POINTS = 5000
#: The longest period a cascade is followed to.
DEFAULT_MAX_PERIOD = 16


class _Stop(Exception):
    """A branch ends here, for the reason given."""


@dataclass
class Branch:
    """Points of one branch: ``values`` (m,), ``states`` (m, 2), ``multipliers`` (m, 2) complex."""

    period: int
    values: list[float] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    mults: list[np.ndarray] = field(default_factory=list)
    orbits: list[np.ndarray] = field(default_factory=list)  # (n, 2) each: x, P(x), ..., P^(n-1)(x)
    stop: str = ""
    parent: int | None = None

    def add(self, p: float, pt: _Point) -> None:
        self.values.append(float(p))
        self.states.append(np.array(pt.X[:2], dtype=float))
        self.mults.append(multipliers(pt.A))
        self.orbits.append(np.array(pt.pts, dtype=float))

    @property
    def stable(self) -> np.ndarray:
        return np.array([bool(np.all(np.abs(m) < 1.0 - UNIT_TOL)) for m in self.mults], dtype=bool)

    def as_dict(self) -> dict[str, Any]:
        return {
            "period": self.period,
            "stop": self.stop,
            "parent": self.parent,
            "points": [
                {"value": v, "q": float(x[0]), "r": float(x[1]),
                 "multipliers": [[float(m.real), float(m.imag)] for m in mu],
                 "stable": bool(np.all(np.abs(mu) < 1.0 - UNIT_TOL))}
                for v, x, mu in zip(self.values, self.states, self.mults, strict=True)
            ],
        }  # fmt: skip


@dataclass(frozen=True)
class Bifurcation:
    """A located bifurcation on a branch."""

    kind: str
    value: float
    error: float
    period: int
    point: np.ndarray
    multipliers: np.ndarray
    branch: int

    def as_dict(self) -> dict[str, Any]:
        return {
            "type": self.kind,
            "value": float(self.value),
            "error": float(self.error),
            "period": self.period,
            "point": [float(self.point[0]), float(self.point[1])],
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "branch": self.branch,
        }


@dataclass
class Curve:
    """A fold or period-doubling point followed in two parameters: rows ``(p1, p2, q, r)``."""

    kind: str
    period: int
    rows: list[tuple[float, float, float, float]] = field(default_factory=list)
    stop: str = ""

    def as_dict(self, name1: str, name2: str) -> dict[str, Any]:
        return {
            "type": self.kind,
            "period": self.period,
            "stop": self.stop,
            "points": [{name1: a, name2: b, "q": q, "r": r} for a, b, q, r in self.rows],
        }


@dataclass
class Continuation:
    """Branches, the bifurcations on them and (two-parameter) curves."""

    params: Params
    param: str
    range: tuple[float, float]
    numerics: Numerics
    branches: list[Branch]
    bifurcations: list[Bifurcation]
    curves: list[Curve] = field(default_factory=list)
    param2: str | None = None
    range2: tuple[float, float] | None = None
    elapsed_s: float = 0.0
    completed: bool = True
    messages: list[str] = field(default_factory=list)

    @property
    def n_points(self) -> int:
        return sum(len(b.values) for b in self.branches)

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "param": self.param,
            "range": list(self.range),
            "branches": [b.as_dict() for b in self.branches],
            "bifurcations": [b.as_dict() for b in self.bifurcations],
            "points": self.n_points,
            "messages": self.messages,
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
        }
        if self.param2 is not None:
            out["param2"] = self.param2
            out["range2"] = list(self.range2 or ())
            out["curves"] = [c.as_dict(self.param, self.param2) for c in self.curves]
        return out


# ---------------------------------------------------------------------------
# The map, its derivatives and the test functions at a point (x, p).


class _System:
    """``P^n`` and its derivatives at ``(x, p...)`` for one or two continuation parameters."""

    def __init__(self, base: Params, names: Sequence[str], numerics: Numerics, workers: int | None) -> None:
        self.base = base
        self.names = list(names)
        self.numerics = numerics
        self.workers = workers

    def params(self, p: Sequence[float]) -> Params:
        try:
            return self.base.with_(**{n: float(v) for n, v in zip(self.names, p, strict=True)})
        except ParameterError as exc:
            raise _Stop(f"left the valid parameters ({exc})") from None

    def delta(self, p: float) -> float:
        return FD_STEP * (1.0 + abs(p))

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P^n(x)``, ``A = DP^n(x)`` and the points ``P(x) .. P^n(x)`` at the parameters ``p``."""
        mono = monodromy_at([self.params(p)], x[None, :], n, self.numerics, workers=1, block=1)
        if mono.status[0] != Status.OK:
            raise _Stop(f"the orbit's trajectory failed: {Status(int(mono.status[0])).label}")
        return mono.end[0], mono.matrix[0], mono.points[0]

    def fp(self, x: np.ndarray, p: Sequence[float], n: int) -> np.ndarray:
        """``dP^n/dp_k`` (2, k): central differences, ``p_k +- delta`` in one lock-step batch (one step sequence)."""
        prs = []
        for k in range(len(p)):
            for sgn in (1.0, -1.0):
                q = list(p)
                q[k] += sgn * self.delta(p[k])
                prs.append(self.params(q))
        y, _, status, _ = run_at(FIELD, prs, np.repeat(x[None, :], len(prs), axis=0), n, workers=1,
                                 block=len(prs), **self.numerics.kernel_kwargs())  # fmt: skip
        bad = np.flatnonzero(status != Status.OK)
        if bad.size:
            raise _Stop(f"the orbit's trajectory failed: {Status(int(status[bad[0]])).label}")
        return np.column_stack([(y[2 * k] - y[2 * k + 1]) / (2 * self.delta(p[k])) for k in range(len(p))])

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False):
        """``P^n(x)``, ``A = DP^n``, ``F_p`` (2, k) and, with ``dx``, ``A`` at ``x +- delta e_j`` and ``p +- delta``.

        One lock-step batch: the base point, then ``p_k +- delta`` for each parameter, then (``dx``)
        ``x +- delta e_j``.
        """
        p = list(p)
        pts, prs = [x], [self.params(p)]
        for k in range(len(p)):
            for sgn in (1.0, -1.0):
                q = list(p)
                q[k] += sgn * self.delta(p[k])
                pts.append(x)
                prs.append(self.params(q))
        hx = FD_STEP * (1.0 + float(np.abs(x).max()))
        if dx:
            for j in range(2):
                for sgn in (1.0, -1.0):
                    pts.append(x + sgn * hx * np.eye(2)[j])
                    prs.append(prs[0])
        mono = monodromy_at(prs, np.array(pts), n, self.numerics, workers=self.workers)
        bad = np.flatnonzero(mono.status != Status.OK)
        if bad.size:
            raise _Stop(f"the orbit's trajectory failed: {Status(int(mono.status[bad[0]])).label}")
        fp = np.column_stack([(mono.end[1 + 2 * k] - mono.end[2 + 2 * k]) / (2 * self.delta(p[k]))
                              for k in range(len(p))])  # fmt: skip
        extra = None
        if dx:
            o = 1 + 2 * len(p)
            extra = {
                "A_p": [(mono.matrix[1 + 2 * k], mono.matrix[2 + 2 * k], self.delta(p[k])) for k in range(len(p))],
                "A_x": [(mono.matrix[o + 2 * j], mono.matrix[o + 2 * j + 1], hx) for j in range(2)],
            }
        return mono.end[0], mono.matrix[0], fp, mono.div[0], mono.points[0], extra


def test_function(kind: str, a: np.ndarray) -> float:
    """``det(A - I)`` (fold), ``det(A + I)`` (period doubling), ``det A - 1`` (Neimark-Sacker)."""
    if kind == "fold":
        return float(np.linalg.det(a - np.eye(2)))
    if kind == "period_doubling":
        return float(np.linalg.det(a + np.eye(2)))
    return float(np.linalg.det(a) - 1.0)


def _complex_pair(a: np.ndarray) -> bool:
    tr, det = float(np.trace(a)), float(np.linalg.det(a))
    return tr * tr < 4.0 * det


def _null(j: np.ndarray) -> np.ndarray:
    """Unit null vector of a full-rank (k, k+1) matrix."""
    _, _, vt = np.linalg.svd(j)
    v = vt[-1]
    return v / np.linalg.norm(v)


# ---------------------------------------------------------------------------
# One-parameter continuation.


@dataclass
class _Point:
    X: np.ndarray  # (3,) q, r and s = (p - A) / (B - A): the range is s in [0, 1]
    A: np.ndarray  # DP^n
    fs: np.ndarray  # (2,) dP^n/ds
    t: np.ndarray  # unit tangent (3,)
    pts: np.ndarray  # (n, 2) the orbit: x, P(x), ..., P^(n-1)(x)


class _Follower:
    """Pseudo-arclength steps along one branch in ``(q, r, s)``, ``s`` the parameter scaled to the range.

    The scaling makes one arclength unit comparable in state and parameter, so a step of ``ds_max``
    moves the parameter by at most ``ds_max`` of the range however fast the orbit moves.
    """

    def __init__(self, sys: _System, rng: tuple[float, float], ds: float, ds_min: float, ds_max: float,
                 max_points: int) -> None:  # fmt: skip
        self.sys = sys
        self.a, self.b = rng
        self.ds0, self.ds_min, self.ds_max = ds, ds_min, ds_max
        self.max_points = max_points

    def p(self, X: np.ndarray) -> float:
        return self.a + float(X[2]) * (self.b - self.a)

    def correct(self, n: int, X_pred: np.ndarray, t: np.ndarray, fs: np.ndarray | None, max_iter: int = 8):
        """Newton on ``F = 0, t . (X - X_pred) = 0`` with the exact ``DP^n``; ``F_s`` is ``fs`` throughout (a chord
        method: one trajectory per iteration) or, with ``fs=None``, recomputed at every iterate.

        Returns the point, ``A``, ``F_s`` there (fresh) and the iterations.
        """
        X = X_pred.copy()
        for it in range(1, max_iter + 1):
            end, a, pts = self.sys.orbit(X[:2], [self.p(X)], n)
            fs_it = self.sys.fp(X[:2], [self.p(X)], n)[:, 0] * (self.b - self.a) if fs is None else fs
            f = end - X[:2]
            g = float(t @ (X - X_pred))
            # P^n is computed to ~rtol |x| and its error grows with |DP^n|: ask no more of the residual.
            scale = (1.0 + float(np.abs(X[:2]).max())) * max(1.0, float(np.abs(a).max()))
            if np.linalg.norm(f) <= CORRECTOR_TOL * scale and abs(g) <= CORRECTOR_TOL:
                fs_new = self.sys.fp(X[:2], [self.p(X)], n)[:, 0] * (self.b - self.a)
                return X, a, fs_new, it, np.vstack([X[None, :2], pts[: n - 1]])
            jac = np.vstack([np.column_stack([a - np.eye(2), fs_it]), t[None, :]])
            try:
                step = np.linalg.solve(jac, -np.concatenate([f, [g]]))
            except np.linalg.LinAlgError:
                raise _Stop("singular corrector") from None
            X = X + step
            if not np.all(np.isfinite(X)):
                raise _Stop("the corrector overflowed")
        raise _Stop(f"the corrector did not converge in {max_iter} iterations")

    def tangent(self, a: np.ndarray, fs: np.ndarray, prev: np.ndarray | None, direction: float) -> np.ndarray:
        t = _null(np.column_stack([a - np.eye(2), fs]))
        if prev is not None:
            return t if t @ prev >= 0 else -t
        return t if t[2] * direction >= 0 else -t

    def first(self, n: int, x: np.ndarray, p: float, direction: float) -> _Point:
        _, a, pts = self.sys.orbit(x, [p], n)
        fs = self.sys.fp(x, [p], n)[:, 0] * (self.b - self.a)
        X = np.array([x[0], x[1], (p - self.a) / (self.b - self.a)])
        return _Point(X, a, fs, self.tangent(a, fs, None, direction), np.vstack([x[None, :], pts[: n - 1]]))

    def step(self, n: int, pt: _Point, ds: float) -> tuple[_Point, int]:
        X_pred = pt.X + ds * pt.t
        X, a, fs, it, pts = self.correct(n, X_pred, pt.t, None)
        return _Point(X, a, fs, self.tangent(a, fs, pt.t, 1.0), pts), it

    def end(self, n: int, pt: _Point, s_end: float) -> _Point | None:
        """The branch point at ``s = s_end`` (an end of the range) from ``pt``; None if the branch turns before it."""
        if (s_end - pt.X[2]) * pt.t[2] <= 0.0:
            return None
        X_pred = pt.X + ((s_end - pt.X[2]) / pt.t[2]) * pt.t
        X, a, fs, _, pts = self.correct(n, X_pred, np.array([0.0, 0.0, 1.0]), None, max_iter=12)
        return _Point(X, a, fs, self.tangent(a, fs, pt.t, 1.0), pts)

    def at(self, n: int, pt: _Point, sigma: float) -> _Point:
        """The branch point at arclength ``sigma`` from ``pt`` along its tangent (predictor-corrector)."""
        X_pred = pt.X + sigma * pt.t
        X, a, fs, _, pts = self.correct(n, X_pred, pt.t, pt.fs, max_iter=12)
        return _Point(X, a, fs, pt.t, pts)


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


def _locate(fol: _Follower, n: int, kind: str, p0: _Point, p1: _Point) -> tuple[_Point, float, float]:
    """The zero of the test function between ``p0`` and ``p1``: the point, its bracket in p, and d(test)/dp."""
    lo, hi = 0.0, float(p0.t @ (p1.X - p0.X))
    flo, fhi = test_function(kind, p0.A), test_function(kind, p1.A)
    plo, phi_ = fol.p(p0.X), fol.p(p1.X)
    slope = (fhi - flo) / (phi_ - plo) if phi_ != plo else math.inf
    best = p1 if abs(fhi) < abs(flo) else p0
    side = 0
    for _ in range(60):
        if abs(phi_ - plo) <= LOCATE_TOL * (1.0 + abs(plo)):
            break
        # Illinois regula falsi: secant steps that keep the bracket
        s = hi - fhi * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not (lo < s < hi):
            s = 0.5 * (lo + hi)
        mid = fol.at(n, p0, s)
        fm = test_function(kind, mid.A)
        best = mid
        if fm == 0.0:
            return mid, 0.0, slope
        if (fm > 0) == (fhi > 0):
            hi, fhi, phi_ = s, fm, fol.p(mid.X)
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo, plo = s, fm, fol.p(mid.X)
            if side == -1:
                fhi *= 0.5
            side = -1
    return best, abs(phi_ - plo), slope


def _switch(fol: _Follower, n: int, at: _Point) -> tuple[np.ndarray, float]:
    """A point of the period-``2n`` branch born at the period doubling ``at``."""
    mu, vecs = np.linalg.eig(at.A)
    v = np.real(vecs[:, int(np.argmin(np.abs(mu + 1.0)))])
    v /= np.linalg.norm(v)
    x_star, s_star = at.X[:2], at.X[2]
    for h in (1e-3, 3e-3, 1e-2, 3e-2):
        hh = h * (1.0 + float(np.abs(x_star).max()))
        X_pred = np.array([*(x_star + hh * v), s_star])
        t = np.array([v[0], v[1], 0.0])
        try:
            # Full Newton: at the pitchfork of P^2n the bordered Jacobian is singular, so F_s must be
            # taken at each iterate (off the doubling point), not frozen at it.
            X, _, _, _, _ = fol.correct(2 * n, X_pred, t, None, max_iter=15)
        except _Stop:
            continue
        end, _, pts = fol.sys.orbit(X[:2], [fol.p(X)], 2 * n)
        chain = np.vstack([X[None, :2], pts])
        if minimal_period(chain, end, 2 * n, 1e-6) == 2 * n:
            return X[:2], fol.p(X)
    raise _Stop("could not switch onto the doubled branch")


def continue_orbit(
    params: Params,
    param: str,
    value_range: Sequence[float],
    seed: Sequence[float],
    period: int,
    *,
    switch: bool = False,
    max_period: int = DEFAULT_MAX_PERIOD,
    ds: float | None = None,
    ds_min: float | None = None,
    ds_max: float | None = None,
    max_points: int = MAX_POINTS,
    numerics: Numerics | None = None,
    param2: str | None = None,
    range2: Sequence[float] | None = None,
    window1: Sequence[float] | None = None,
    progress: Callable[[int, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Continuation:
    """Follow the period-``period`` orbit near ``seed`` over ``param`` from ``value_range[0]`` to ``value_range[1]``.

    Parameters
    ----------
    params : the system at the other parameters' values (``param`` is set to ``value_range[0]``).
    param : ``alpha``, an inertia entry, ``g0``, ``g1``, ``g2`` or ``omega``.
    seed : a point near the orbit at the first value (Newton converges from it).
    switch : at each period doubling, also follow the doubled branch (up to ``max_period``).
    ds, ds_min, ds_max : arclength steps in ``(q, r, (p - A) / (B - A))`` (default 0.02, 1e-7, 0.1: at
        least ten points over the range).
    param2, range2 : also follow every fold and period doubling found as a curve in ``(param, param2)``
        with ``param2`` over ``range2`` and ``param`` over ``window1`` (default: the range).
    progress : called with (points so far, current value); cancel: polled at every point.

    Every branch stops at the range's end, on escape or integration failure, on leaving the valid
    parameters (e.g. a tensor that is not positive definite), after ``max_points``, or where the step
    falls below ``ds_min``; its ``stop`` says which.
    """
    start = time.perf_counter()
    param = check_param(param)
    try:
        a, b = (float(v) for v in value_range)
    except (TypeError, ValueError):
        raise ParameterError(f"range must be two numbers A,B, got {value_range!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and a != b):
        raise ParameterError(f"range must be two different finite numbers, got {value_range!r}")
    period = check_int("period", period, 1, 1024)
    max_period = check_int("max_period", max_period, period, 1024)
    check_int("max_points", max_points, 2, 1_000_000)
    x0 = check_ics(seed)[0]
    numerics = numerics or ORBIT_NUMERICS
    ds = 0.02 if ds is None else float(ds)
    ds_min = 1e-7 if ds_min is None else float(ds_min)
    ds_max = 0.1 if ds_max is None else float(ds_max)
    for name, v in (("ds", ds), ("ds_min", ds_min), ("ds_max", ds_max)):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"{name} must be a positive number, got {v!r}")
    try:
        base = params.with_(**{param: a})
    except ParameterError as exc:
        raise ParameterError(f"the range's first value {param} = {a} is not a valid system: {exc}") from None
    sys = _System(base, [param], numerics, workers)
    fol = _Follower(sys, (a, b), ds, ds_min, ds_max, max_points)

    conv, failures = newton(base, x0[None, :], np.array([period]), numerics=numerics, workers=workers)
    if not conv:
        raise ParameterError(
            f"no period-{period} orbit found from {x0.tolist()} at {param} = {a}: {failures[0].reason}"
        )
    _, x_start, mono, _ = conv[0]
    chain = np.vstack([x_start[None, :], mono.points[0]])
    if minimal_period(chain, mono.end[0], period, 1e-6) != period:
        d = minimal_period(chain, mono.end[0], period, 1e-6)
        raise ParameterError(f"the orbit found from {x0.tolist()} has period {d}, not {period}: ask for --period {d}")

    res = Continuation(params, param, (a, b), numerics, [], [])
    queue: list[tuple[int, np.ndarray, float, int | None]] = [(period, x_start, a, None)]
    stopped = False
    while queue and not stopped:
        n, x, p, parent = queue.pop(0)
        br = Branch(n, parent=parent)
        res.branches.append(br)
        k = len(res.branches) - 1
        try:
            # A doubled branch leaves its doubling point on the side where it exists.
            away = p - res.bifurcations[parent].value if parent is not None else 0.0
            pt = fol.first(n, x, p, math.copysign(1.0, away / (b - a)) if abs(away) > 1e-14 * (1 + abs(p)) else 1.0)
            br.add(fol.p(pt.X), pt)
            h = ds
            while True:
                if cancel is not None and cancel():
                    br.stop = "cancelled"
                    stopped = True
                    break
                if len(br.values) >= max_points:
                    raise _Stop(f"{max_points} points")
                try:
                    new, it = fol.step(n, pt, h)
                except _Stop:
                    h *= 0.5
                    if h < ds_min:
                        raise
                    continue
                # a big turn of the tangent: the step was too long for the curvature
                if float(new.t @ pt.t) < 0.9 and h > ds_min:
                    h *= 0.5
                    continue
                end = not 0.0 <= new.X[2] <= 1.0
                if end:  # the last point lands on the range's end (or, after a fold, its start) exactly
                    new = fol.end(n, pt, 1.0 if new.X[2] > 1.0 else 0.0)
                    if new is None:
                        br.stop = "range end"
                        break
                try:
                    found = [(kind, *_located(fol, n, kind, pt, new, k)) for kind in _crossed(pt, new)]
                except _Stop:
                    if h > 4 * ds_min:  # locating failed in a long step: take a shorter one
                        h *= 0.5
                        continue
                    raise
                # In branch order, each bifurcation is a point of the branch (where its stability changes).
                found.sort(key=lambda f: float(pt.t @ (f[2].X - pt.X)))
                for kind, bif, at in found:
                    res.bifurcations.append(bif)
                    br.add(bif.value, at)
                    if kind == "period_doubling" and switch and 2 * n <= max_period:
                        try:
                            xs, ps = _switch(fol, n, at)
                            queue.append((2 * n, xs, ps, len(res.bifurcations) - 1))
                        except _Stop as exc:
                            res.messages.append(f"period doubling at {param} = {bif.value:.12g}: {exc}")
                br.add(fol.p(new.X), new)
                if progress is not None:
                    progress(res.n_points, fol.p(new.X))
                if end:
                    br.stop = "range end" if new.X[2] >= 0.5 else "back at the range's start (after a fold)"
                    break
                pt = new
                h = min(ds_max, h * 1.5) if it <= 3 else (h * 0.6 if it >= 6 else h)
        except _Stop as exc:
            br.stop = (br.stop + str(exc)).strip()
    if param2 is not None and not stopped:
        res.param2 = check_param(param2)
        if res.param2 == param:
            raise ParameterError(f"param2 must differ from param, got {param2!r} twice")
        try:
            c, d = (float(v) for v in (range2 or ()))
        except (TypeError, ValueError):
            raise ParameterError(f"range2 must be two numbers C,D, got {range2!r}") from None
        if not (math.isfinite(c) and math.isfinite(d) and c < d):
            raise ParameterError(f"range2 must be finite with C < D, got {range2!r}")
        res.range2 = (c, d)
        for bif in list(res.bifurcations):
            if bif.kind in ("fold", "period_doubling"):
                w1 = (a, b) if window1 is None else (float(min(window1)), float(max(window1)))
                res.curves.append(_follow_curve(base, param, res.param2, bif, w1, (c, d), numerics, max_points,
                                                cancel, workers))  # fmt: skip
    res.elapsed_s = time.perf_counter() - start
    res.completed = not stopped
    return res


def _defining(sys: _System, kind: str, n: int, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bifurcation's defining system at ``Y = (q, r, p_1, ...)``: ``G = (P^n(x) - x, test(A))`` and its Jacobian.

    ``DP^n`` exact; the derivatives of the test function and ``F_p`` by central differences of one
    lock-step batch (base, ``p_k +- delta``, ``x +- delta e_j``).
    """
    end, a, fp, _, _, ex = sys.evaluate(Y[:2], list(Y[2:]), n, dx=True)
    dphi_x = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_x"]]
    dphi_p = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_p"]]
    g = np.concatenate([end - Y[:2], [test_function(kind, a)]])
    jac = np.vstack([np.column_stack([a - np.eye(2), fp]), np.array([*dphi_x, *dphi_p])[None, :]])
    return g, jac, a


def _refine(sys: _System, kind: str, n: int, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Newton on the defining system from a located point: the bifurcation to the accuracy of ``P^n``."""
    for _ in range(8):
        g, jac, a = _defining(sys, kind, n, Y)
        step = np.linalg.solve(jac, -g)
        Y = Y + step
        if not np.all(np.isfinite(Y)):
            raise _Stop("the refinement of a bifurcation overflowed")
        if np.abs(step).max() <= 1e-13 * (1.0 + float(np.abs(Y).max())):
            break
    _, _, a = _defining(sys, kind, n, Y)
    return Y, a


def _located(fol: _Follower, n: int, kind: str, p0: _Point, p1: _Point, branch: int) -> tuple[Bifurcation, _Point]:
    """Locate the bifurcation between two points of a branch.

    Bracketed secant steps along the branch find the test function's zero; Newton on the defining system
    ``(P^n(x) - x, test(DP^n)) = 0`` then refines it to the accuracy of the integration. The error
    estimate is the shift of the refined value when ``P^n`` is integrated ten times less accurately
    (plus the secant bracket, if the refinement failed).
    """
    at, bracket, _ = _locate(fol, n, kind, p0, p1)
    Y0 = np.array([at.X[0], at.X[1], fol.p(at.X)])
    loose = Numerics(**{**fol.sys.numerics.as_dict(), "rtol": fol.sys.numerics.rtol * 10,
                        "atol": fol.sys.numerics.atol * 10})  # fmt: skip
    try:
        Y, a = _refine(fol.sys, kind, n, Y0)
        Y2, _ = _refine(_System(fol.sys.base, fol.sys.names, loose, 1), kind, n, Y)
        error = abs(Y2[2] - Y[2])
        if abs(Y[2] - Y0[2]) > 1e3 * (bracket + 1e-9 * (1 + abs(Y0[2]))):
            raise _Stop("the refinement went elsewhere")  # keep the bracketed value
    except (_Stop, np.linalg.LinAlgError):
        Y, a, error = Y0, at.A, bracket
    X = np.array([Y[0], Y[1], (Y[2] - fol.a) / (fol.b - fol.a)])
    at = _Point(X, a, at.fs, at.t, at.pts)
    bif = Bifurcation(kind, float(Y[2]), float(error), n, Y[:2].copy(), multipliers(a), branch)
    return bif, at


# ---------------------------------------------------------------------------
# Two-parameter continuation of a fold or period-doubling point.


def _follow_curve(base: Params, name1: str, name2: str, bif: Bifurcation, rng1: tuple[float, float],
                  rng2: tuple[float, float], numerics: Numerics, max_points: int, cancel: Callable[[], bool] | None,
                  workers: int | None) -> Curve:  # fmt: skip
    """The curve of ``F = 0, phi = 0`` through ``bif`` in ``(name1, name2)``, both ways, within ``rng1 x rng2``.

    Pseudo-arclength in ``(q, r, s1, s2)`` with each parameter scaled to its range (``rng1``: the window of the
    first parameter, ``rng2``): a step moves each parameter by at most ``0.05`` of its range.
    """
    p2_0 = float(getattr(base, name2) if name2 not in ("I11", "I22", "I33", "I12", "I13", "I23")
                 else base.inertia[("I11", "I22", "I33", "I12", "I13", "I23").index(name2)])  # fmt: skip
    sys = _System(base, [name1, name2], numerics, workers)
    n, kind = bif.period, bif.kind
    curve = Curve(kind, n)
    lo, hi = rng2
    if not lo <= p2_0 <= hi:
        curve.stop = f"{name2} = {p2_0} at the bifurcation is outside the range"
        return curve
    # Scaled coordinates Z = (q, r, (p1 - o1) / w1, (p2 - o2) / w2).
    o = np.array([0.0, 0.0, min(rng1), lo])
    w = np.array([1.0, 1.0, abs(rng1[1] - rng1[0]), hi - lo])

    def unscaled(Z: np.ndarray) -> np.ndarray:
        return o + w * Z

    def residual_and_jac(Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, jac, _ = _defining(sys, kind, n, unscaled(Z))
        return g, jac * w[None, :]

    def correct(Z_pred: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        Z = Z_pred.copy()
        for it in range(1, 11):
            g, jac = residual_and_jac(Z)
            c = float(t @ (Z - Z_pred))
            scale = 1.0 + float(np.abs(Z[:2]).max())
            try:
                step = np.linalg.solve(np.vstack([jac, t[None, :]]), -np.concatenate([g, [c]]))
            except np.linalg.LinAlgError:
                raise _Stop("singular corrector") from None
            # Converged when the Newton step is at the accuracy of the map (the test function's own
            # scale grows with the multipliers: no absolute bound on it means anything).
            if np.linalg.norm(g[:2]) <= CORRECTOR_TOL * scale * 10 and np.abs(step).max() <= 1e-9 * scale:
                return Z, jac, it
            Z = Z + step
            if not np.all(np.isfinite(Z)):
                raise _Stop("the corrector overflowed")
        raise _Stop("the corrector did not converge")

    Z0 = (np.array([bif.point[0], bif.point[1], bif.value, p2_0]) - o) / w
    try:
        _, jac0 = residual_and_jac(Z0)
    except _Stop as exc:
        curve.stop = str(exc)
        return curve
    t0 = _null(jac0)
    halves: list[list[tuple[float, float, float, float]]] = []
    reasons = []
    for sgn in (1.0, -1.0):
        rows: list[tuple[float, float, float, float]] = []
        Z, t, h = Z0.copy(), sgn * t0, 0.01
        reason = f"{max_points} points"
        try:
            while len(rows) < max_points:
                if cancel is not None and cancel():
                    reason = "cancelled"
                    break
                try:
                    Z_new, jac, it = correct(Z + h * t, t)
                except _Stop:
                    h *= 0.5
                    if h < 1e-7:
                        raise
                    continue
                t_new = _null(jac)
                t_new = t_new if t_new @ t >= 0 else -t_new
                Y = unscaled(Z_new)
                if not (lo <= Y[3] <= hi and min(rng1) <= Y[2] <= max(rng1)):
                    reason = "range end"
                    break
                rows.append((float(Y[2]), float(Y[3]), float(Y[0]), float(Y[1])))
                Z, t = Z_new, t_new
                h = min(0.05, h * 1.5) if it <= 3 else (h * 0.6 if it >= 6 else h)
        except _Stop as exc:
            reason = str(exc)
        halves.append(rows)
        reasons.append(reason)
    Y0 = unscaled(Z0)
    curve.rows = [*reversed(halves[1]), (float(Y0[2]), float(Y0[3]), float(Y0[0]), float(Y0[1])), *halves[0]]
    curve.stop = "; ".join(reasons)
    return curve


def classify_branch(br: Branch) -> list[str]:
    """The type of every point of a branch (see :func:`explorer_core.analyses.orbits.classify`)."""
    return [classify(m) for m in br.mults]


def continue_from_seeds(
    params: Params,
    param: str,
    value_range: Sequence[float],
    seeds: Any,
    *,
    periods: Sequence[int] = (1, 2, 3, 4),
    switch: bool = True,
    max_period: int = DEFAULT_MAX_PERIOD,
    max_orbits: int = 6,
    numerics: Numerics | None = None,
    param2: str | None = None,
    range2: Sequence[float] | None = None,
    window1: Sequence[float] | None = None,
    progress: Callable[[int, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Continuation:
    """Every distinct orbit of ``periods`` that Newton finds from ``seeds`` at the range's first value, continued.

    For an orbit diagram: its initial conditions (or final states) as seeds; the branches of all the
    orbits found (stable and unstable, up to ``max_orbits``, lowest periods first) in one result.
    """
    from explorer_core.analyses.orbits import find_orbits

    param = check_param(param)
    a = float(value_range[0])
    start = params.with_(**{param: a})
    found = find_orbits(start, seeds, list(periods), numerics=numerics, workers=workers).orbits[:max_orbits]
    out = Continuation(params, param, (a, float(value_range[1])), numerics or ORBIT_NUMERICS, [], [])
    if not found:
        out.messages.append(f"no orbit of period {', '.join(map(str, periods))} near the seeds at {param} = {a:g}")
    t0 = time.perf_counter()
    for orb in found:
        if cancel is not None and cancel():
            out.completed = False
            break
        if _on_a_branch(out, orb, a):
            continue  # already followed: the orbit is a point of a branch computed for an earlier seed
        done = out.n_points
        step = None if progress is None else (lambda n, v, d=done: progress(d + n, v))
        res = continue_orbit(params, param, value_range, orb.points[0], orb.period, switch=switch,
                             max_period=max(max_period, orb.period), numerics=numerics, cancel=cancel, workers=workers,
                             progress=step, param2=param2, range2=range2, window1=window1)  # fmt: skip
        shift = len(out.branches)
        nb = len(out.bifurcations)
        out.branches += res.branches
        out.bifurcations += [Bifurcation(b.kind, b.value, b.error, b.period, b.point, b.multipliers, b.branch + shift)
                             for b in res.bifurcations]  # fmt: skip
        for br in res.branches:
            if br.parent is not None:
                br.parent += nb
        out.messages += res.messages
        out.curves += res.curves
        out.param2, out.range2 = res.param2, res.range2
        out.completed = out.completed and res.completed
    out.elapsed_s = time.perf_counter() - t0
    return out


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
    chart: Any,
    *,
    periods: Sequence[int] = (1, 2, 3),
    numerics: Numerics | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> list[Continuation]:
    """The fold and period-doubling curves that bound a chart's regions of stable cycles.

    For each period ``p`` in ``periods`` present in the chart (:class:`explorer_core.analyses.regimes.Chart`),
    the pixel of period ``p`` nearest the region's centre: its trajectory is run through the chart's
    transient, Newton finds the period-``p`` orbit there, and that orbit is continued in the chart's ``x``
    towards both ends with every fold and period doubling followed as a curve in ``(x, y)`` over the
    chart. Returns one :class:`Continuation` per continued direction (their ``curves`` are the boundaries).
    """
    from explorer_core.analyses.orbits import find_orbits
    from explorer_core.analyses.regimes import PERIODIC
    from explorer_core.solve.integrators import Batch, advance
    from explorer_core.system.model import Model

    spec = chart.spec
    xs, ys = np.asarray(spec.x_values, float), np.asarray(spec.y_values, float)
    xr, yr = (float(xs.min()), float(xs.max())), (float(ys.min()), float(ys.max()))
    out: list[Continuation] = []
    for p in periods:
        js, is_, ks = np.nonzero((chart.regime == PERIODIC) & (chart.period == p) & chart.computed[..., None])
        if js.size == 0 or (cancel is not None and cancel()):
            continue
        cj, ci = js.mean(), is_.mean()
        n = int(np.argmin((js - cj) ** 2 + (is_ - ci) ** 2))
        j, i, k = int(js[n]), int(is_[n]), int(ks[n])
        params = spec.pixel_params(j, i)
        if isinstance(params, str):
            continue
        batch = Batch.start(spec.ics[k : k + 1], params.t0, params.period)
        advance(Model(params), batch, spec.transient, store=False, workers=1, **spec.numerics.kernel_kwargs())
        found = find_orbits(params, batch.y, [p], numerics=numerics, workers=workers).orbits
        if not found:
            continue
        x0 = float(xs[i])
        for end in xr:
            if end == x0 or (cancel is not None and cancel()):
                continue
            try:
                out.append(continue_orbit(params, spec.x_param, (x0, end), found[0].points[0], found[0].period,
                                          numerics=numerics, param2=spec.y_param, range2=yr, window1=xr,
                                          cancel=cancel, workers=workers))  # fmt: skip
            except ParameterError:
                continue
    return out
