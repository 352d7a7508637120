"""Continuation of periodic orbits of the Poincare map in a parameter, through their bifurcations.

A period-``n`` orbit is a zero of ``F(x, p) = P^n(x; p) - x``; its points ``(x, p)`` form curves
(branches). Pseudo-arclength continuation (Keller) follows a branch through folds: from a point ``X``
with unit tangent ``t`` (the null vector of ``[DP^n - I | F_p]``) the predictor ``X + ds t`` is corrected
by Newton on ``F = 0, t . (X - X_pred) = 0``. ``DP^n`` is the exact monodromy matrix (tangent system);
``F_p`` a central difference whose three members (``p``, ``p +- delta``) go in one lock-step batch, so
they share one step sequence and the difference is smooth in ``p``.

One engine (:class:`_Engine`) does the predictor, the corrector, the step control and the landing on
the range's ends for every curve followed here: the branches of one-parameter continuation, the
branches switched onto at period doublings, and the two-parameter curves of folds and doublings. Its
settings are one :class:`ContinuationOptions`. A refused step (the corrector failed or went too far
from the prediction, the tangent turned too much, the orbit lost its period) is retried shorter, down
to ``ds_min``; the step grows again after corrections that contract fast (Deuflhard's rule on the
Newton contraction, so a strongly unstable branch, whose corrector always needs a few iterations, is
not slowed down step after step).

Along a branch the test functions (Kuznetsov, *Elements of Applied Bifurcation Theory*, ch. 10; as in
MatContM) are ``det(A - I)`` (fold, ``mu = +1``), ``det(A + I)`` (period doubling, ``mu = -1``) and
``det A - 1`` on a complex pair (Neimark-Sacker, ``|mu| = 1``), ``A = DP^n``. A sign change between two
accepted points is located by bracketed secant steps in the arclength (each trial point corrected onto
the branch) to ``|delta p| <= 1e-12``; the error estimate adds the bracket to the shift of the located
value when the orbit is integrated ten times less accurately.

At a period doubling the branch of period ``2n`` is switched onto (``switch=True``): it leaves the
doubling point tangent to the eigenvector ``v`` of ``mu = -1`` (a pitchfork of ``P^2n``), so the
corrector from ``x* + h v`` with ``v . (x - x*) = h`` fixed lands on it. Followed to the next doubling,
this is the cascade ``1 -> 2 -> 4 -> 8 -> 16``. Followed the other way, a period-``2n`` branch ends at
its birth point, where it collapses onto the period-``n`` orbit (the parameter turns there, and the
orbit's points ``x`` and ``P^n(x)`` meet): the branch stops there, it is not followed back through it.

Two-parameter continuation follows a fold or period-doubling point in a second parameter: the curve of
``F = 0, phi = 0`` (``phi`` the test function) in ``(x, p1, p2)``, with ``phi``'s derivatives by central
differences of the monodromy (nine members in one lock-step batch).

Nothing is lost in silence: a branch or curve that stopped other than at a range end or at a located
bifurcation where it was meant to stop is a :class:`~explorer_core.losses.Loss` of the result.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from explorer_core import export
from explorer_core.analyses.orbits import ORBIT_NUMERICS, UNIT_TOL, classify, minimal_period, multipliers, newton
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.analyses.sweeps import check_param
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, run, stream
from explorer_core.solve.numerics import Numerics, check_ics, check_int
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.tangent import Monodromy, monodromy_at
from explorer_core.status import Status
from explorer_core.system.params import ParameterError, Params

#: Bifurcation types and their test functions.
KINDS = ("fold", "period_doubling", "neimark_sacker")
#: Relative size of the parameter step of the finite differences (divided by ``sqrt(|DP^n|)`` on a branch).
FD_STEP = 1e-7
#: The central differences integrate this many times less accurately than the orbit, at most at FD_RTOL_MAX,
#: and to a relative error ~FD_ACCURACY / 10 (see :meth:`_System.fd_numerics`).
FD_LOOSEN = 1e3
FD_RTOL_MAX = 1e-9
FD_ACCURACY = 1e-6
#: Newton on a corrected point stops when ``|F| <= CORRECTOR_TOL (1 + |x|)``.
CORRECTOR_TOL = 1e-10
#: A located bifurcation's bracket in the parameter.
LOCATE_TOL = 1e-12
#: The secant steps along the branch stop at this bracket (relative) when Newton on the bifurcation's defining
#: system takes over (it converges quadratically from there; each secant step is a corrected point of the branch).
REFINE_FROM = 1e-5
#: Newton on a bifurcation's defining system stops when its steps, below this (relative), no longer contract:
#: the map's noise (steps of ~1e-12 on Fig. 10's period 16 at rtol 1e-11).
REFINE_NOISE = 1e-10
MAX_POINTS = 5000
#: The longest period a cascade is followed to.
DEFAULT_MAX_PERIOD = 16
#: A branch's birth point: at the turn of the parameter, ``|P^d(x) - x|`` is below this fraction of its value
#: at the neighbouring points (it vanishes like the square root of the distance to the birth).
BIRTH_RATIO = 0.1


@dataclass(frozen=True)
class ContinuationOptions:
    """The settings of the continuation engine (one set for branches, switched branches and curves).

    Steps are arclengths in the scaled coordinates ``(q, r, s)``, ``s = (p - A) / (B - A)`` the
    parameter as a fraction of its range (two-parameter curves: each parameter scaled to its range).

    ds : the first step of every branch and curve.
    ds_min : the minimum step. A refused step (the corrector did not converge, went further than
        ``max_distance`` times the step from the prediction, the tangent turned by more than
        ``max_turn``, the orbit lost its period, a bifurcation could not be located) is retried with the
        step times ``shrink``, down to ``ds_min``; refused at ``ds_min``, the branch stops and is a loss.
    ds_max : the longest step on a branch (a step moves the parameter by at most this fraction of the range).
    curve_ds_max : the longest step on a two-parameter curve.
    growth : the largest factor the step grows by after an accepted step.
    shrink : the factor a refused step is shortened by.
    contraction : the target Newton contraction ``|dX_k+1| / |dX_k|`` of the corrector; the next step is
        scaled by ``sqrt(contraction / observed)``, within ``[shrink, growth]``.
    max_points : the most points of one branch (of each half of a curve).
    corrector_tol : Newton stops when ``|P^n(x) - x| <= corrector_tol (1 + |x|) max(1, |DP^n|)``.
    max_iter : corrector iterations per step.
    max_turn : the largest angle (radians) between the tangents at two successive points.
    max_distance : the largest distance of the corrected point from the prediction, relative to the step.
    period_tol : a point whose orbit has ``|P^d(x) - x| <= period_tol (1 + |x|)`` for a divisor ``d`` of
        the period has collapsed onto a period-``d`` orbit.
    """

    ds: float = 0.02
    ds_min: float = 1e-7
    ds_max: float = 0.1
    curve_ds_max: float = 0.05
    growth: float = 1.5
    shrink: float = 0.5
    contraction: float = 0.5
    max_points: int = MAX_POINTS
    corrector_tol: float = CORRECTOR_TOL
    max_iter: int = 8
    max_turn: float = 0.45
    max_distance: float = 0.5
    period_tol: float = 1e-6

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("max_points", "max_iter"):
                object.__setattr__(self, f.name, check_int(f.name, v, 2, 1_000_000))  # a plain int
                continue
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
                raise ParameterError(f"{f.name} must be a number, got {v!r}")
            v = float(v)
            object.__setattr__(self, f.name, v)  # plain floats (JSON, repr)
            if not (math.isfinite(v) and v > 0):
                raise ParameterError(f"{f.name} must be a positive finite number, got {v!r}")
        if not self.ds_min <= self.ds <= self.ds_max:
            raise ParameterError(
                f"the steps must satisfy ds_min <= ds <= ds_max, got ds_min = {self.ds_min!r}, ds = {self.ds!r}, "
                f"ds_max = {self.ds_max!r}"
            )
        if self.curve_ds_max < self.ds_min:
            raise ParameterError(f"curve_ds_max must be at least ds_min = {self.ds_min!r}, got {self.curve_ds_max!r}")
        if self.growth < 1.0:
            raise ParameterError(f"growth must be at least 1, got {self.growth!r}")
        for name in ("shrink", "contraction", "max_distance"):
            if getattr(self, name) >= 1.0:
                raise ParameterError(f"{name} must be below 1, got {getattr(self, name)!r}")
        if self.max_turn >= math.pi / 2:
            raise ParameterError(f"max_turn must be below pi/2 (radians), got {self.max_turn!r}")
        if self.corrector_tol >= 1e-3 or self.period_tol >= 1e-2:
            raise ParameterError(
                f"corrector_tol must be below 1e-3 and period_tol below 1e-2, got {self.corrector_tol!r}, "
                f"{self.period_tol!r}"
            )

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class ContinuationSpec:
    """Everything that defines a continuation (validated by :func:`continuation_spec`; plain data: picklable,
    comparable). ``params``: the system at the other parameters' values; ``seed`` a point near the
    period-``period`` orbit at ``range[0]``; ``window1``: ``param``'s range on the two-parameter curves
    (None: ``range``)."""

    params: Params
    param: str
    range: tuple[float, float]
    seed: tuple[float, float]
    period: int
    switch: bool = False
    max_period: int = DEFAULT_MAX_PERIOD
    options: ContinuationOptions = field(default_factory=ContinuationOptions)
    numerics: Numerics = ORBIT_NUMERICS
    param2: str | None = None
    range2: tuple[float, float] | None = None
    window1: tuple[float, float] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "param": self.param, "range": list(self.range),
                "seed": list(self.seed), "period": self.period, "switch": self.switch, "max_period": self.max_period,
                "options": self.options.as_dict(), "numerics": self.numerics.as_dict(), "param2": self.param2,
                "range2": None if self.range2 is None else list(self.range2),
                "window1": None if self.window1 is None else list(self.window1)}  # fmt: skip


def _two(name: str, value: Any, what: str) -> tuple[float, float]:
    """Two finite numbers (a range), or a ParameterError naming ``name`` and ``value``."""
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be two numbers {what}, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(b - a)):
        raise ParameterError(f"{name} must be two finite numbers {what} (a finite width), got {value!r}")
    return a, b


def continuation_spec(
    params: Params,
    param: str,
    value_range: Sequence[float],
    seed: Sequence[float],
    period: int,
    *,
    switch: bool = False,
    max_period: int = DEFAULT_MAX_PERIOD,
    options: ContinuationOptions | None = None,
    ds: float | None = None,
    ds_min: float | None = None,
    ds_max: float | None = None,
    max_points: int | None = None,
    numerics: Numerics | None = None,
    param2: str | None = None,
    range2: Sequence[float] | None = None,
    window1: Sequence[float] | None = None,
    check_end: bool = False,
) -> ContinuationSpec:
    """A validated :class:`ContinuationSpec`; every bad value raises :class:`ParameterError` naming it (and
    carrying the keyword as ``exc.option``, :mod:`explorer_core.analyses.specs`).

    Parameters
    ----------
    params : the system at the other parameters' values (``param`` is set to ``value_range[0]``).
    param : ``alpha``, an inertia entry, ``g0``, ``g1``, ``g2`` or ``omega``.
    value_range : ``(A, B)``, different and finite: from ``A`` (a valid system; where the orbit is seeded)
        to ``B``. A branch that leaves the valid systems stops there, a loss of the result; ``check_end=True``
        refuses a ``B`` that is no valid system instead (the CLI's check: positive-definite tensors are
        convex, so with both ends valid the whole range is).
    seed : one point ``(q, r)`` near the orbit at ``A``, inside the escape bound of ``numerics``.
    period : the orbit's period, in ``[1, 1024]``; ``max_period`` (``>= period``) caps a cascade.
    switch : at each period doubling, also follow the doubled branch (up to ``max_period``).
    options : the engine's settings (:class:`ContinuationOptions`); ``ds``, ``ds_min``, ``ds_max`` and
        ``max_points``, when given, replace theirs (``ds_max`` alone also bounds the first step).
    numerics : integration (default :data:`~explorer_core.analyses.orbits.ORBIT_NUMERICS`).
    param2, range2 : together or neither: also follow every fold and period doubling found as a curve in
        ``(param, param2)``, ``param2`` (not ``param``) over ``range2 = (C, D)``, ``C < D``, and ``param``
        over ``window1`` (default: the range).
    """
    with Checking() as at:
        at("param")
        param = check_param(param)
        at("value_range")
        a, b = _two("range", value_range, "A,B")
        if a == b:
            raise ParameterError(f"range must be two different numbers, got {value_range!r}")
        for end, v in (("first value", a), ("end", b))[: 2 if check_end else 1]:
            try:
                params.with_(**{param: v})
            except ParameterError as exc:
                raise ParameterError(f"the range's {end} {param} = {v:g} is not a valid system: {exc}") from None
        at("period")
        period = check_int("period", period, 1, 1024)
        at("max_period")
        max_period = check_int("max_period", max_period, period, 1024)
        at("options")
        if not isinstance(options, ContinuationOptions | None):
            raise ParameterError(f"options must be a ContinuationOptions, got {options!r}")
        opts = options or ContinuationOptions()
        given = {}
        for key, v in (("ds", ds), ("ds_min", ds_min), ("ds_max", ds_max), ("max_points", max_points)):
            if v is not None:
                at(key)
                given[key] = check_int(key, v, 2, 1_000_000) if key == "max_points" else _positive(key, v)
        if given:
            at("ds" if "ds" in given else next(iter(given)))
            if "ds" not in given and "ds_max" in given:  # an old-style ds_max alone bounds the default first step
                given["ds"] = min(float(opts.ds), float(given["ds_max"]))
            opts = ContinuationOptions(**{**asdict(opts), **given})
        at("numerics")
        numerics = ORBIT_NUMERICS if numerics is None else numerics
        if not isinstance(numerics, Numerics):
            raise ParameterError(f"numerics must be a Numerics, got {numerics!r}")
        at("seed")
        x0 = check_ics(seed)
        if x0.shape[0] != 1:
            raise ParameterError(f"seed must be one point (q, r), got {x0.shape[0]}")
        q, r = (float(v) for v in x0[0])
        if max(abs(q), abs(r)) > numerics.bound:
            raise ParameterError(f"seed {q:g},{r:g} is outside the escape bound {numerics.bound:g}")
        at("param2")
        if (param2 is None) != (range2 is None):
            raise ParameterError(f"param2 and range2 go together (both or neither), got {param2!r} and {range2!r}")
        rng2 = None
        if param2 is not None:
            param2 = check_param(param2)
            if param2 == param:
                raise ParameterError(f"param2 must differ from param, got {param2!r} twice")
            at("range2")
            c, d = _two("range2", range2, "C,D")
            if not c < d:
                raise ParameterError(f"range2 must have C < D, got {range2!r}")
            rng2 = (c, d)
        at("window1")
        w1 = None if window1 is None else _two("window1", window1, "A,B")
        w1 = None if w1 is None else (min(w1), max(w1))
    return ContinuationSpec(params, param, (a, b), (q, r), period, bool(switch), max_period, opts, numerics,
                            param2, rng2, w1)  # fmt: skip


def _positive(name: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) or not math.isfinite(v) \
            or v <= 0:  # fmt: skip
        raise ParameterError(f"{name} must be a positive finite number, got {v!r}")
    return float(v)


class _Stop(Exception):
    """A step is refused (or a branch ends) for the reason given; ``status`` says it in the one vocabulary."""

    def __init__(self, why: str, status: Status = Status.NOT_CONVERGED) -> None:
        super().__init__(why)
        self.status = status


@dataclass
class Branch:
    """Points of one branch: ``values`` (m,), ``states`` (m,) of ``(q, r)``, ``mults`` (m,) of 2 complex numbers.

    Plain Python numbers throughout (written to CSV and JSON as they are). ``status``: how the branch ended in the
    one vocabulary (``ok``: at the range's end, its birth point or a stop it meant; ``cancelled``; ``budget``:
    ``max_points``; ``not_converged``; ``invalid``: it left the valid parameters; an engine failure); ``stop``
    the detail in words.
    """

    period: int
    values: list[float] = field(default_factory=list)
    states: list[tuple[float, float]] = field(default_factory=list)
    mults: list[tuple[complex, complex]] = field(default_factory=list)
    orbits: list[np.ndarray] = field(default_factory=list)  # (n, 2) each: x, P(x), ..., P^(n-1)(x)
    stop: str = ""
    parent: int | None = None
    status: Status = Status.OK

    def add(self, p: float, pt: _Point) -> None:
        self.values.append(float(p))
        self.states.append((float(pt.X[0]), float(pt.X[1])))
        self.mults.append(tuple(complex(m) for m in multipliers(pt.A)))
        self.orbits.append(np.array(pt.pts, dtype=float))

    @property
    def stable(self) -> np.ndarray:
        return np.array([bool(np.all(np.abs(m) < 1.0 - UNIT_TOL)) for m in self.mults], dtype=bool)

    def as_dict(self) -> dict[str, Any]:
        return {
            "period": self.period,
            "status": self.status.label,
            "stop": self.stop,
            "parent": self.parent,
            "points": [
                {"value": v, "q": x[0], "r": x[1],
                 "multipliers": [[m.real, m.imag] for m in mu],
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
            "period": int(self.period),
            "point": [float(self.point[0]), float(self.point[1])],
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "branch": int(self.branch),
        }


@dataclass
class Curve:
    """A fold or period-doubling point followed in two parameters: rows ``(p1, p2, q, r)``; ``status`` as a
    branch's (the first half that did not end well decides), ``stop`` both halves' ends in words."""

    kind: str
    period: int
    rows: list[tuple[float, float, float, float]] = field(default_factory=list)
    stop: str = ""
    status: Status = Status.OK

    def as_dict(self, name1: str, name2: str) -> dict[str, Any]:
        return {
            "type": self.kind,
            "period": self.period,
            "status": self.status.label,
            "stop": self.stop,
            "points": [{name1: a, name2: b, "q": q, "r": r} for a, b, q, r in self.rows],
        }


@dataclass
class Continuation(Drawable):
    """Branches, the bifurcations on them and (two-parameter) curves.

    ``completed`` is False when the run was cancelled; ``complete`` is False when anything was lost
    (cancellation included): ``lost`` says what and why.
    """

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
    lost: list[Loss] = field(default_factory=list)
    options: ContinuationOptions = field(default_factory=ContinuationOptions)
    #: what was asked (None for the orbits of several seeds, :func:`continue_from_seeds`)
    spec: ContinuationSpec | None = None

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    @property
    def n_points(self) -> int:
        return sum(len(b.values) for b in self.branches)

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "param": self.param,
            "range": [float(v) for v in self.range],
            "branches": [b.as_dict() for b in self.branches],
            "bifurcations": [b.as_dict() for b in self.bifurcations],
            "points": self.n_points,
            "messages": list(self.messages),
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "elapsed_s": round(float(self.elapsed_s), 6),
            "options": self.options.as_dict(),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
        }
        if self.param2 is not None:
            out["param2"] = self.param2
            out["range2"] = [float(v) for v in self.range2 or ()]
            out["curves"] = [c.as_dict(self.param, self.param2) for c in self.curves]
        if self.spec is not None:  # what was asked: the seed, period, switching, ... (enough to run it again)
            out["spec"] = self.spec.as_dict()
        return out

    as_dict = summary

    #: the CSV's columns (:meth:`csv_rows`)
    CSV_HEADER = ("branch", "period", "value", "q", "r", "mu1_re", "mu1_im", "mu2_re", "mu2_im", "stable")

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: a row per point (:attr:`CSV_HEADER`); ``.json``: the summary."""
        csv_ = lambda p: export.write_csv(p, self.CSV_HEADER, self.csv_rows())  # noqa: E731
        return export.write_by_suffix(
            path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())}, "continuation"
        )

    def csv_rows(self) -> list[tuple[int, int, float, float, float, float, float, float, float, int]]:
        """``branch, period, value, q, r, mu1_re, mu1_im, mu2_re, mu2_im, stable`` per point, plain numbers."""
        rows = []
        for i, br in enumerate(self.branches):
            for v, x, mu, st in zip(br.values, br.states, br.mults, br.stable, strict=True):
                rows.append((i, br.period, v, x[0], x[1], mu[0].real, mu[0].imag, mu[1].real, mu[1].imag, int(st)))
        return rows


# ---------------------------------------------------------------------------
# The map, its derivatives and the test functions at a point (x, p).


def _failed(code: int) -> _Stop:
    """The stop of an orbit whose trajectory the engine ended with ``code``."""
    st = Status.of(int(code))
    return _Stop(f"the orbit's trajectory failed: {st.label}", st)


class _System:
    """``P^n`` and its derivatives at ``(x, p...)`` for one or two continuation parameters."""

    def __init__(self, base: Params, names: Sequence[str], numerics: Numerics, workers: int | None) -> None:
        self.base = base
        self.names = list(names)
        self.numerics = numerics
        self.workers = workers
        self._fd: dict[tuple[float, float], Numerics] = {}

    def fd_numerics(self, amp: float) -> Numerics:
        """The integration of the central differences' members at an orbit with ``|DP^n| = amp``.

        The differences (``F_p``, the test function's derivatives) only steer Newton and give the tangent:
        members in lock-step share one step sequence, so their difference is smooth at any tolerance, and its
        relative error is ~0.1 ``rtol |DP^n|`` (measured on Fig. 10's period-16 orbit). They run up to
        ``FD_LOOSEN`` times looser than the orbit (at most ``FD_RTOL_MAX``), with that error below
        :data:`FD_ACCURACY` / 10, never more accurately than the orbit. ``P^n`` and ``DP^n`` at the point
        itself (the residual, the multipliers) keep the accuracy asked.
        """
        tol = {k: max(v, min(FD_RTOL_MAX, v * FD_LOOSEN, FD_ACCURACY / max(1.0, amp)))
               for k, v in (("rtol", self.numerics.rtol), ("atol", self.numerics.atol))}  # fmt: skip
        key = (tol["rtol"], tol["atol"])
        if key not in self._fd:
            self._fd[key] = Numerics(**{**self.numerics.as_dict(), **tol})
        return self._fd[key]

    def params(self, p: Sequence[float]) -> Params:
        try:
            return self.base.with_(**{n: float(v) for n, v in zip(self.names, p, strict=True)})
        except ParameterError as exc:
            raise _Stop(f"left the valid parameters ({exc})", Status.INVALID) from None

    def delta(self, p: float, amp: float = 1.0) -> float:
        """The parameter step of ``F_p``. ``P^n`` bends in ``p`` on a scale that shrinks with the orbit's
        instability ``amp = |DP^n|``: at ``|DP^16| ~ 4e3`` (Fig. 10, alpha = -0.423) ``FD_STEP`` alone puts
        the tangent 20 degrees off the branch, and every step is refused. Lock-step members keep the
        smaller difference smooth."""
        return FD_STEP * (1.0 + abs(p)) / math.sqrt(max(1.0, amp))

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P^n(x)``, ``A = DP^n(x)`` and the points ``P(x) .. P^n(x)`` at the parameters ``p``."""
        mono = monodromy_at([self.params(p)], x[None, :], n, self.numerics, workers=1, block=1)
        if mono.status[0] != Status.OK:
            raise _failed(mono.status[0])
        return mono.end[0], mono.matrix[0], mono.points[0]

    def fp(self, x: np.ndarray, p: Sequence[float], n: int, amp: float = 1.0) -> np.ndarray:
        """``dP^n/dp_k`` (2, k): central differences, ``p_k +- delta`` in one lock-step batch (one step sequence)."""
        prs = []
        for k in range(len(p)):
            for sgn in (1.0, -1.0):
                q = list(p)
                q[k] += sgn * self.delta(p[k], amp)
                prs.append(self.params(q))
        pmap = PoincareMap.members(prs, self.fd_numerics(amp), workers=1, block=len(prs))
        y, status = pmap.image(np.repeat(x[None, :], len(prs), axis=0), n)
        bad = np.flatnonzero(status != Status.OK)
        if bad.size:
            raise _failed(status[bad[0]])
        return np.column_stack([(y[2 * k] - y[2 * k + 1]) / (2 * self.delta(p[k], amp)) for k in range(len(p))])

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False):
        """``P^n(x)``, ``A = DP^n``, ``F_p`` (2, k) and, with ``dx``, ``A`` at ``x +- delta e_j`` and ``p +- delta``.

        The base point at the accuracy asked, then one lock-step batch (:meth:`fd_numerics`): ``p_k +- delta``
        for each parameter, then (``dx``) ``x +- delta e_j``.
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
        # The point at the accuracy asked; the differences' members (lock-step among themselves) looser.
        at = monodromy_at(prs[:1], np.array(pts[:1]), n, self.numerics, workers=1, block=1)
        if at.status[0] != Status.OK:
            raise _failed(at.status[0])
        fd = monodromy_at(prs[1:], np.array(pts[1:]), n, self.fd_numerics(float(np.abs(at.matrix[0]).max())),
                          workers=self.workers, block=len(prs) - 1)  # fmt: skip
        mono = Monodromy(*(np.concatenate([u, v]) for u, v in zip(_fields(at), _fields(fd), strict=True)))
        bad = np.flatnonzero(mono.status != Status.OK)
        if bad.size:
            raise _failed(mono.status[bad[0]])
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


def _fields(m: Monodromy) -> tuple[np.ndarray, ...]:
    return m.end, m.matrix, m.div, m.points, m.status, m.nsteps


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
# The engine: predictor, corrector, step control, landing on the range's ends.


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


class _BranchProblem:
    """``P^n(x) - x = 0`` in ``(q, r, s)``, ``s = (p - A) / (B - A)``: the range is ``s`` in ``[0, 1]``.

    The scaling makes one arclength unit comparable in state and parameter, so a step of ``ds_max``
    moves the parameter by at most ``ds_max`` of the range however fast the orbit moves.
    """

    def __init__(self, sys: _System, rng: tuple[float, float], n: int, tol: float) -> None:
        self.sys, self.n, self.tol = sys, n, tol
        self.a, self.b = rng
        self.box = ((2, 0.0, 1.0),)

    def p(self, X: np.ndarray) -> float:
        return self.a + float(X[2]) * (self.b - self.a)

    def scaled(self, p: float) -> float:
        return (p - self.a) / (self.b - self.a)

    def fs(self, X: np.ndarray, a: np.ndarray) -> np.ndarray:
        amp = float(np.abs(a).max())
        return self.sys.fp(X[:2], [self.p(X)], self.n, amp)[:, 0] * (self.b - self.a)

    def evaluate(self, X: np.ndarray, chord: np.ndarray | None = None):
        """``F``, its Jacobian ``[DP^n - I | F_s]``, ``DP^n``, the orbit; ``chord``: its last column is ``F_s``."""
        n = self.n
        end, a, pts = self.sys.orbit(X[:2], [self.p(X)], n)
        fs = self.fs(X, a) if chord is None else chord[:, 2]
        return end - X[:2], np.column_stack([a - np.eye(2), fs]), a, np.vstack([X[None, :2], pts[: n - 1]])

    def fresh(self, X: np.ndarray, jac: np.ndarray) -> np.ndarray:
        return np.column_stack([jac[:, :2], self.fs(X, jac[:, :2] + np.eye(2))])

    def converged(self, f: np.ndarray, g: float, dX: np.ndarray, X: np.ndarray, a: np.ndarray) -> bool:
        # P^n is computed to ~rtol |x| and its error grows with |DP^n|: ask no more of the residual.
        scale = (1.0 + float(np.abs(X[:2]).max())) * max(1.0, float(np.abs(a).max()))
        return bool(np.linalg.norm(f) <= self.tol * scale and abs(g) <= self.tol)


class _CurveProblem:
    """A bifurcation's defining system ``(P^n(x) - x, phi(DP^n)) = 0`` in ``(q, r, s1, s2)``, each parameter
    scaled to its range: a step of ``curve_ds_max`` moves each parameter by at most that fraction of its range."""

    def __init__(self, sys: _System, kind: str, n: int, origin: np.ndarray, width: np.ndarray, tol: float) -> None:
        self.sys, self.kind, self.n, self.o, self.w, self.tol = sys, kind, n, origin, width, tol
        self.box = ((2, 0.0, 1.0), (3, 0.0, 1.0))

    def unscaled(self, Z: np.ndarray) -> np.ndarray:
        return self.o + self.w * Z

    def evaluate(self, Z: np.ndarray, chord: np.ndarray | None = None):
        g, jac, a, _ = _defining(self.sys, self.kind, self.n, self.unscaled(Z))
        return g, jac * self.w[None, :], a, None

    def fresh(self, Z: np.ndarray, jac: np.ndarray) -> np.ndarray:
        return jac

    def converged(self, f: np.ndarray, g: float, dX: np.ndarray, Z: np.ndarray, a: np.ndarray) -> bool:
        # Converged when the Newton step is at the accuracy of the map (the test function's own
        # scale grows with the multipliers: no absolute bound on it means anything).
        scale = 1.0 + float(np.abs(Z[:2]).max())
        return bool(np.linalg.norm(f[:2]) <= self.tol * scale * 10 and np.abs(dX).max() <= 1e-9 * scale)


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
        max_iter = self.opts.max_iter if max_iter is None else max_iter
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
        return self.correct(prob, X_pred, pt.t, pt.t, max_iter=self.opts.max_iter + 4)[0]

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
        new, theta = self.correct(prob, X_pred, c, pt.t, max_iter=self.opts.max_iter + 4)
        new.X[k] = bound  # exact: the constraint is linear
        self._check(pt, new, X_pred, float(np.linalg.norm(X_pred - pt.X)))
        for j, lo, hi in prob.box:
            if not lo - 1e-12 <= new.X[j] <= hi + 1e-12:
                raise _Stop("the end point is outside the other range")
        return new, theta

    def _trial(self, prob: Any, pt: _Point, h: float) -> tuple[_Point, float, bool]:
        """One step of length ``h`` from ``pt``: the new point, the contraction, and whether it is on an end.

        The corrector starts from the second-order prediction ``X + h t + h^2/2 dt/ds`` (``dt/ds`` from the
        previous point; error ~ ``h^3``): fewer Newton steps. The steps stay those of the first-order rule:
        Newton's contraction is ``kappa`` times the prediction's error, ``kappa`` measured at every step
        (the first of a curve from the tangent line), and the contraction returned is ``kappa`` times the
        tangent line's error ``|X_new - (X + h t)|``. Longer steps would save more, but through a chaotic band
        they jump between the many nearby orbits of one period (Fig. 10's period 16 beyond alpha = -0.413).
        """
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
            second = pt.curv is not None and self._kappa is not None
            start = X_pred + 0.5 * h * h * pt.curv if second else X_pred
            new, theta = self.correct(prob, start, pt.t, pt.t)
            self._check(pt, new, X_pred, h)
            line, off = float(np.linalg.norm(new.X - X_pred)), float(np.linalg.norm(new.X - start))
            if theta > 0.0 and off > 0.0:
                self._kappa = theta / off
            if second:
                theta = self._kappa * line
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

    def follow(self, prob: Any, pt: _Point, accept: Callable[[_Point, _Point], str | None],
               ds_max: float) -> tuple[str, bool, _Point, Status]:  # fmt: skip
        """Steps from ``pt`` until an end, a stop ``accept`` returns, or a refusal at ``ds_min``.

        ``accept(pt, new)`` records an accepted point; it raises :class:`_Stop` to refuse it, or returns a
        reason to stop there. Returns ``(reason, lost, last point, status)``: ``lost`` unless the curve reached
        an end of its range or a stop ``accept`` meant (then ``status`` is ok).
        """
        o = self.opts
        h = min(o.ds, ds_max)
        self._kappa: float | None = None  # Newton's contraction per unit error of the prediction (see _trial)
        count = 1
        first_refusal = ""  # since the last accepted point: the longer step may have failed for a telling reason
        while True:
            if self.cancel is not None and self.cancel():
                return "cancelled", True, pt, Status.CANCELLED
            if count >= o.max_points:
                return f"stopped after max_points = {o.max_points} points", True, pt, Status.BUDGET
            try:
                new, theta, at_end = self._trial(prob, pt, h)
                if new is pt:
                    return "range end", False, pt, Status.OK
                verdict = accept(pt, new)
            except _Stop as exc:
                used = exc.used if isinstance(exc, _Refused) else h
                first_refusal = first_refusal or str(exc)
                if used <= o.ds_min * (1 + 1e-9):
                    why = f"{exc} (at the minimum step ds_min = {o.ds_min:g})"
                    if first_refusal != str(exc):
                        why += f"; with longer steps: {first_refusal}"
                    return why, True, pt, exc.status
                h = max(o.ds_min, used * o.shrink)
                continue
            first_refusal = ""
            count += 1
            if verdict is not None:
                return verdict, False, new, Status.OK
            if at_end:
                return "range end", False, new, Status.OK
            new.curv = (new.t - pt.t) / max(float(np.linalg.norm(new.X - pt.X)), 1e-300)
            pt = new
            # Deuflhard's rule: the predictor's error, hence the corrector's contraction, goes as h^2.
            factor = o.growth if theta <= 0.0 else min(o.growth, max(o.shrink, math.sqrt(o.contraction / theta)))
            h = min(ds_max, max(o.ds_min, h * factor))


# ---------------------------------------------------------------------------
# One-parameter continuation.


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


def _locate(eng: _Engine, prob: _BranchProblem, fn: Callable[[_Point], float], p0: _Point, p1: _Point,
            sigma_tol: float = 0.0, ptol: float = LOCATE_TOL) -> tuple[_Point, float]:  # fmt: skip
    """The zero of ``fn`` between ``p0`` and ``p1``: the point and its bracket in p.

    Stops when the bracket is below ``ptol`` (relative) in the parameter or ``sigma_tol`` in the arclength (at a
    turn of the parameter the parameter's bracket says nothing about the point's).
    """
    lo, hi = 0.0, float(p0.t @ (p1.X - p0.X))
    flo, fhi = fn(p0), fn(p1)
    plo, phi_ = prob.p(p0.X), prob.p(p1.X)
    best = p1 if abs(fhi) < abs(flo) else p0
    side = 0
    for _ in range(60):
        if abs(phi_ - plo) <= ptol * (1.0 + abs(plo)) and abs(hi - lo) <= sigma_tol:
            break
        # Illinois regula falsi: secant steps that keep the bracket
        s = hi - fhi * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not (lo < s < hi):
            s = 0.5 * (lo + hi)
        mid = eng.at(prob, p0, s, p1)
        fm = fn(mid)
        best = mid
        if fm == 0.0:
            return mid, 0.0
        if (fm > 0) == (fhi > 0):
            hi, fhi, phi_ = s, fm, prob.p(mid.X)
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo, plo = s, fm, prob.p(mid.X)
            if side == -1:
                fhi *= 0.5
            side = -1
    return best, abs(phi_ - plo)


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
    mu, vecs = np.linalg.eig(at.A)
    v = np.real(vecs[:, int(np.argmin(np.abs(mu + 1.0)))])
    v /= np.linalg.norm(v)
    x_star, s_star = at.X[:2], at.X[2]
    for h in (1e-3, 3e-3, 1e-2, 3e-2):
        hh = h * (1.0 + float(np.abs(x_star).max()))
        X_pred = np.array([*(x_star + hh * v), s_star])
        c = np.array([v[0], v[1], 0.0])
        try:
            # Full Newton: at the pitchfork of P^2n the bordered Jacobian is singular, so F_s must be
            # taken at each iterate (off the doubling point), not frozen at it.
            new, _ = eng.correct(prob2, X_pred, c, c, max_iter=15)
        except _Stop:
            continue
        if minimal_period(new.pts, new.pts[0], prob2.n, 1e-6) == prob2.n:
            return new.X[:2], prob2.p(new.X)
    raise _Stop("could not switch onto the doubled branch")


def continue_orbit(
    spec: ContinuationSpec | Params,
    *args: Any,
    progress: Callable[[Step[Continuation]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Continuation:
    """Follow the period-``period`` orbit near ``seed`` over ``param`` (:func:`_continue_orbit`);
    ``progress`` gets every update of :func:`iter_continue_orbit`.

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
    furthest point covers, of those started or queued); ``detail`` is ``(points, value)``. The last
    update's ``result`` is the continuation. The spec (or the keyword form's) is checked at the call."""
    spec = spec_of(ContinuationSpec, continuation_spec, spec, args, kw)

    def work(emit: Callable[[Step[Continuation]], None], stop: Callable[[], bool]) -> Step[Continuation]:
        last = _Last(emit)
        res = _continue_orbit(spec, progress=last, cancel=stop, workers=workers)
        return last.step(res, "branches", len(res.branches) + len(res.curves))

    return stream(work, cancel)


class _Last:
    """Passes a continuation's updates on and remembers the last, for the progress of the final update."""

    def __init__(self, emit: Callable[[Step[Continuation]], None]) -> None:
        self.emit, self.done = emit, 0.0

    def __call__(self, update: Step[Continuation]) -> None:
        self.done = update.progress.done
        self.emit(update)

    def step(self, res: Continuation, unit: str, total: float) -> Step[Continuation]:
        """The last update: ``total`` done when the run reached its end, as far as it came if cancelled."""
        done = total if res.completed else min(self.done, total)
        return Step(Progress(done, total, unit, res.elapsed_s), (res.n_points, None), res)


class _Meter:
    """The progress of a continuation in branches (and curves): monotone, the current one by its range share."""

    def __init__(self, report: Callable[[Step[Continuation]], None] | None, a: float, b: float) -> None:
        self.report, self.a, self.b = report, a, b
        self.start = time.perf_counter()
        self.done = 0.0

    def __call__(self, res: Continuation, finished: int, total: int, value: float | None) -> None:
        if self.report is None:
            return
        share = 0.0 if value is None else min(1.0, max(0.0, (value - self.a) / (self.b - self.a)))
        self.done = max(self.done, min(finished + share, total))
        elapsed = time.perf_counter() - self.start
        self.report(Step(Progress(self.done, total, "branches", elapsed), (res.n_points, value)))


def _continue_orbit(
    spec: ContinuationSpec,
    *,
    progress: Callable[[int, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Continuation:
    """Follow the period-``spec.period`` orbit near ``spec.seed`` over ``spec.param`` from ``spec.range[0]`` to
    ``spec.range[1]`` (see :func:`continuation_spec` for the settings).

    ``progress`` is called with a :class:`~explorer_core.progress.Step` after every point (see
    :func:`iter_continue_orbit`); ``cancel`` is polled at every point. A cancelled run returns what it
    computed, with ``completed`` False and the rest in ``lost``.

    Every branch stops at the range's end, at its birth point (a doubled orbit collapsing onto the orbit it
    was born from), on escape or integration failure, on leaving the valid parameters (e.g. a tensor
    that is not positive definite), after ``max_points``, or where a step is refused at ``ds_min``; its
    ``stop`` says which, and every stop but the first two is in ``lost``.
    """
    start = time.perf_counter()
    params, param, (a, b), period, opts, numerics = spec.params, spec.param, spec.range, spec.period, spec.options, \
        spec.numerics  # fmt: skip
    switch, max_period, x0 = spec.switch, spec.max_period, np.array(spec.seed, dtype=float)
    base = params.with_(**{param: a})
    sys = _System(base, [param], numerics, workers)
    eng = _Engine(opts, cancel)

    conv, failures = newton(base, x0[None, :], np.array([period]), numerics=numerics, workers=workers)
    if not conv:
        raise ParameterError(
            f"no period-{period} orbit found from {x0.tolist()} at {param} = {a}: {failures[0].reason}"
        )
    _, x_start, mono, _ = conv[0]
    chain = np.vstack([x_start[None, :], mono.points[0]])
    d = minimal_period(chain, mono.end[0], period, 1e-6)
    if d != period:
        raise ParameterError(f"the orbit found from {x0.tolist()} has period {d}, not {period}: ask for --period {d}")

    res = Continuation(params, param, (a, b), numerics, [], [], options=opts, spec=spec)
    queue: list[tuple[int, np.ndarray, float, int | None]] = [(period, x_start, a, None)]
    meter = _Meter(progress, a, b)
    stopped = False
    while queue and not stopped:
        n, x, p, parent = queue.pop(0)
        br = Branch(n, parent=parent)
        res.branches.append(br)
        k = len(res.branches) - 1
        prob = _BranchProblem(sys, (a, b), n, opts.corrector_tol)
        what = f"branch {k} (period {n}, from {param} = {p:.12g})"

        def accept(pt: _Point, new: _Point, prob: _BranchProblem = prob, br: Branch = br, k: int = k) -> str | None:
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
            for kind, bif, at in found:
                res.bifurcations.append(bif)
                br.add(bif.value, at)
                if kind == "period_doubling" and switch and 2 * n <= max_period:
                    try:
                        xs, ps = _switch(eng, _BranchProblem(sys, (a, b), 2 * n, opts.corrector_tol), at)
                        queue.append((2 * n, xs, ps, len(res.bifurcations) - 1))
                    except _Stop as exc:
                        res.messages.append(f"period doubling at {param} = {bif.value:.12g}: {exc}")
                        res.lost.append(Loss(f"the period-{2 * n} branch born at {param} = {bif.value:.12g}", 1,
                                             str(exc)))  # fmt: skip
            last = new if birth is None else birth[0]
            br.add(prob.p(last.X), last)
            meter(res, k, len(res.branches) + len(queue), prob.p(last.X))
            if birth is not None:
                return (f"the period-{n} orbit collapsed onto a period-{birth[1]} orbit at {param} = "
                        f"{prob.p(birth[0].X):.12g} (its birth point)")  # fmt: skip
            return None

        try:
            # A doubled branch leaves its doubling point on the side where it exists.
            away = p - res.bifurcations[parent].value if parent is not None else 0.0
            direction = math.copysign(1.0, away / (b - a)) if abs(away) > 1e-14 * (1 + abs(p)) else 1.0
            pt = eng.first(prob, np.array([x[0], x[1], prob.scaled(p)]), np.array([0.0, 0.0, direction]))
            br.add(p, pt)
            reason, lost, last, br.status = eng.follow(prob, pt, accept, opts.ds_max)
            if reason == "range end":
                reason = "range end" if last.X[2] >= 0.5 else "back at the range's start (after a fold)"
        except _Stop as exc:
            reason, lost, br.status = str(exc), True, exc.status
        br.stop = reason
        if lost:
            res.lost.append(Loss(what, 1, reason))
        if reason == "cancelled":
            stopped = True
    if stopped:
        if queue:
            res.lost.append(Loss("branches not started", len(queue), "cancelled"))
        if spec.param2 is not None:
            res.lost.append(Loss("two-parameter curves", 1, "cancelled before they were followed"))
    if spec.param2 is not None and not stopped:
        res.param2, res.range2 = spec.param2, spec.range2
        c, d = spec.range2  # type: ignore[misc]
        todo = [bif for bif in res.bifurcations if bif.kind in ("fold", "period_doubling")]
        for bif in list(res.bifurcations):
            if bif.kind in ("fold", "period_doubling"):
                meter(res, len(res.branches) + len(res.curves), len(res.branches) + len(todo), None)
                if cancel is not None and cancel():
                    stopped = True
                    res.lost.append(Loss(f"the {bif.kind} curve from {param} = {bif.value:.12g}", 1, "cancelled"))
                    continue
                w1 = (a, b) if spec.window1 is None else spec.window1
                curve, losses = _follow_curve(eng, base, param, res.param2, bif, w1, (c, d), numerics, workers)
                res.curves.append(curve)
                res.lost += losses
                stopped = stopped or "cancelled" in curve.stop
    res.elapsed_s = time.perf_counter() - start
    res.completed = not stopped
    return res


def _defining(sys: _System, kind: str, n: int, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The bifurcation's defining system at ``Y = (q, r, p_1, ...)``: ``G = (P^n(x) - x, test(A))``, its Jacobian,
    ``A`` and the section points ``P(x) .. P^n(x)``.

    ``DP^n`` exact; the derivatives of the test function and ``F_p`` by central differences of one
    lock-step batch (base, ``p_k +- delta``, ``x +- delta e_j``).
    """
    end, a, fp, _, pts, ex = sys.evaluate(Y[:2], list(Y[2:]), n, dx=True)
    dphi_x = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_x"]]
    dphi_p = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_p"]]
    g = np.concatenate([end - Y[:2], [test_function(kind, a)]])
    jac = np.vstack([np.column_stack([a - np.eye(2), fp]), np.array([*dphi_x, *dphi_p])[None, :]])
    return g, jac, a, pts


def _residual(sys: _System, kind: str, n: int, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The defining system's ``G`` alone at ``Y``, with ``A`` and the orbit ``x, P(x), ..., P^(n-1)(x)``: one
    integration of the tangent system (no central differences)."""
    end, a, pts = sys.orbit(Y[:2], list(Y[2:]), n)
    return np.concatenate([end - Y[:2], [test_function(kind, a)]]), a, np.vstack([Y[None, :2], pts[: n - 1]])


def _refine(
    sys: _System, kind: str, n: int, Y: np.ndarray, final: bool = True, jac: np.ndarray | None = None
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
             branch: int) -> tuple[Bifurcation, _Point]:  # fmt: skip
    """Locate the bifurcation between two points of a branch.

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
    loose = Numerics(**{**sys.numerics.as_dict(), "rtol": sys.numerics.rtol * 10,
                        "atol": sys.numerics.atol * 10})  # fmt: skip
    try:
        Y, a, pts, jac = _refine(sys, kind, n, Y0)
        # The error estimate: the same zero of the less accurate map, from Y with the same Jacobian.
        Y2, _, _, _ = _refine(_System(sys.base, sys.names, loose, 1), kind, n, Y, final=False, jac=jac)
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
    bif = Bifurcation(kind, float(Y[2]), float(error), n, Y[:2].copy(), multipliers(a), branch)
    return bif, at


# ---------------------------------------------------------------------------
# Two-parameter continuation of a fold or period-doubling point.


def _follow_curve(eng: _Engine, base: Params, name1: str, name2: str, bif: Bifurcation, rng1: tuple[float, float],
                  rng2: tuple[float, float], numerics: Numerics,
                  workers: int | None) -> tuple[Curve, list[Loss]]:  # fmt: skip
    """The curve of ``F = 0, phi = 0`` through ``bif`` in ``(name1, name2)``, both ways, within ``rng1 x rng2``.

    Pseudo-arclength in ``(q, r, s1, s2)`` with each parameter scaled to its range (``rng1``: the window of the
    first parameter, ``rng2``), by the same engine as the branches; each half ends on the box's edge.
    """
    p2_0 = float(getattr(base, name2) if name2 not in ("I11", "I22", "I33", "I12", "I13", "I23")
                 else base.inertia[("I11", "I22", "I33", "I12", "I13", "I23").index(name2)])  # fmt: skip
    sys = _System(base, [name1, name2], numerics, workers)
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
    prob = _CurveProblem(sys, kind, n, origin, width, eng.opts.corrector_tol)
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

        def accept(pt: _Point, new: _Point, rows: list = rows) -> None:
            Y = prob.unscaled(new.X)
            rows.append((float(Y[2]), float(Y[3]), float(Y[0]), float(Y[1])))

        try:
            reason, lost, _, status = eng.follow(prob, _Point(Z0, pt0.A, pt0.J, sgn * pt0.t, None), accept,
                                                 eng.opts.curve_ds_max)  # fmt: skip
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


def classify_branch(br: Branch) -> list[str]:
    """The type of every point of a branch (see :func:`explorer_core.analyses.orbits.classify`)."""
    return [classify(m) for m in br.mults]


def continue_from_seeds(
    params: Params,
    param: str,
    value_range: Sequence[float],
    seeds: Any,
    *,
    progress: Callable[[Step[Continuation]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> Continuation:
    """Every distinct orbit Newton finds from ``seeds``, continued (:func:`_continue_from_seeds`'s
    arguments); ``progress`` gets every update of :func:`iter_continue_from_seeds`."""
    return run(iter_continue_from_seeds(params, param, value_range, seeds, cancel=cancel, **kw), progress)


def iter_continue_from_seeds(
    params: Params,
    param: str,
    value_range: Sequence[float],
    seeds: Any,
    *,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> Iterator[Step[Continuation]]:
    """:func:`continue_from_seeds` as a stream of :class:`~explorer_core.progress.Step` in ``orbits`` (the
    orbits found and continued, the current one by its own progress); the last one carries the result."""

    def work(emit: Callable[[Step[Continuation]], None], stop: Callable[[], bool]) -> Step[Continuation]:
        last = _Last(emit)
        res, n = _continue_from_seeds(params, param, value_range, seeds, progress=last, cancel=stop, **kw)
        return last.step(res, "orbits", n)

    return stream(work, cancel)


def _continue_from_seeds(
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
    options: ContinuationOptions | None = None,
    progress: Callable[[Step[Continuation]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> tuple[Continuation, int]:
    """Every distinct orbit of ``periods`` that Newton finds from ``seeds`` at the range's first value, continued.

    For an orbit diagram: its initial conditions (or final states) as seeds; the branches of all the
    orbits found (stable and unstable, up to ``max_orbits``, lowest periods first) in one result.
    Returns it and the number of orbits found.
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
    seen = [0.0]  # orbits done so far, monotone

    def step(upd: Step[Continuation], i: int) -> None:
        seen[0] = max(seen[0], i + upd.progress.fraction)
        p = Progress(seen[0], len(found), "orbits", time.perf_counter() - t0)
        progress(Step(p, upd.detail))  # type: ignore[misc]

    # (by position: an Orbit's == compares arrays, so found.index() raised for any but the first)
    for i, orb in enumerate(found):
        if cancel is not None and cancel():
            out.completed = False
            out.lost.append(Loss("orbits found but not continued", len(found) - i, "cancelled"))
            break
        if _on_a_branch(out, orb, a):
            continue  # already followed: the orbit is a point of a branch computed for an earlier seed
        one = continuation_spec(params, param, value_range, orb.points[0], orb.period, switch=switch,
                                max_period=max(max_period, orb.period), numerics=numerics, param2=param2,
                                range2=range2, window1=window1, options=options)  # fmt: skip
        res = _continue_orbit(one, cancel=cancel, workers=workers,
                              progress=None if progress is None else (lambda u, i=i: step(u, i)))  # fmt: skip
        shift = len(out.branches)
        nb = len(out.bifurcations)
        out.branches += res.branches
        out.bifurcations += [Bifurcation(b.kind, b.value, b.error, b.period, b.point, b.multipliers, b.branch + shift)
                             for b in res.bifurcations]  # fmt: skip
        for br in res.branches:
            if br.parent is not None:
                br.parent += nb
        out.messages += res.messages
        out.lost += res.lost
        out.curves += res.curves
        out.param2, out.range2 = res.param2, res.range2
        out.completed = out.completed and res.completed
    out.elapsed_s = time.perf_counter() - t0
    return out, len(found)


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


class Boundaries(list):
    """The continuations of :func:`chart_boundaries` (a list of :class:`Continuation`), with what was lost:
    directions not continued because cancelled, and every loss of the continuations themselves."""

    completed: bool = True

    @property
    def lost(self) -> list[Loss]:
        own = getattr(self, "_lost", [])
        return own + [loss for c in self for loss in c.lost]

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def summary(self) -> dict[str, Any]:
        return {"continuations": [c.summary() for c in self], "completed": self.completed,
                "complete": self.complete, "lost": [loss.as_dict() for loss in self.lost]}  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: the continuations' points, a column ``continuation`` first; ``.json``: the summary."""

        def csv_(p: str) -> int:
            rows = ((k, *row) for k, c in enumerate(self) for row in c.csv_rows())
            return export.write_csv(p, ("continuation", *Continuation.CSV_HEADER), rows)

        return export.write_by_suffix(
            path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())}, "set of boundaries"
        )


def chart_boundaries(
    chart: Any,
    *,
    progress: Callable[[Step[Boundaries]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> Boundaries:
    """The fold and period-doubling curves that bound a chart's regions of stable cycles
    (:func:`_chart_boundaries`); ``progress`` gets every update of :func:`iter_chart_boundaries`."""
    return run(iter_chart_boundaries(chart, cancel=cancel, **kw), progress)


def iter_chart_boundaries(
    chart: Any, *, cancel: Callable[[], bool] | None = None, **kw: Any
) -> Iterator[Step[Boundaries]]:
    """:func:`chart_boundaries` as a stream of :class:`~explorer_core.progress.Step` in ``directions`` (each
    period's region continued towards both ends of the chart's ``x``); the last carries the result."""
    return stream(lambda emit, stop: _chart_boundaries(chart, progress=emit, cancel=stop, **kw), cancel)


def _chart_boundaries(
    chart: Any,
    *,
    periods: Sequence[int] = (1, 2, 3),
    numerics: Numerics | None = None,
    progress: Callable[[Step[Boundaries]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Step[Boundaries]:
    """The fold and period-doubling curves that bound a chart's regions of stable cycles.

    For each period ``p`` in ``periods`` present in the chart (:class:`explorer_core.analyses.regimes.Chart`),
    the pixel of period ``p`` nearest the region's centre: its trajectory is run through the chart's
    transient, Newton finds the period-``p`` orbit there, and that orbit is continued in the chart's ``x``
    towards both ends with every fold and period doubling followed as a curve in ``(x, y)`` over the
    chart. Returns the last update, whose result holds one :class:`Continuation` per continued direction
    (their ``curves`` are the boundaries).
    """
    from explorer_core.analyses.orbits import find_orbits
    from explorer_core.analyses.regimes import PERIODIC

    spec = chart.spec
    xs, ys = np.asarray(spec.x_values, float), np.asarray(spec.y_values, float)
    xr, yr = (float(xs.min()), float(xs.max())), (float(ys.min()), float(ys.max()))
    out = Boundaries()
    start = time.perf_counter()
    total = 2 * len(periods)
    done = [0.0]

    def stopped() -> bool:
        return cancel is not None and bool(cancel())

    def meter(slots: int, upd: Step[Continuation] | None = None) -> None:
        done[0] = max(done[0], slots + (upd.progress.fraction if upd is not None else 0.0))
        if progress is not None:
            progress(Step(Progress(done[0], total, "directions", time.perf_counter() - start)))

    for np_, p in enumerate(periods):
        meter(2 * np_)
        if stopped():
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
            if stopped():
                out.completed = False
                out._lost = [Loss("directions not continued", total - 2 * np_ - e, "cancelled")]
                break
            step = None if progress is None else (lambda u, s=2 * np_ + e: meter(s, u))
            try:
                one = continuation_spec(params, spec.x_param, (x0, end), found[0].points[0], found[0].period,
                                        numerics=numerics, param2=spec.y_param, range2=yr,
                                        window1=xr)  # fmt: skip
                res = _continue_orbit(one, cancel=cancel, workers=workers, progress=step)
            except ParameterError:
                continue
            out.append(res)
            out.completed = out.completed and res.completed
        if not out.completed:
            break
    elapsed = time.perf_counter() - start
    return Step(Progress(total if out.completed else done[0], total, "directions", elapsed), None, out)
