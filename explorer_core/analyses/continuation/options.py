"""What a continuation is asked: the engine's settings (:class:`ContinuationOptions`, one set for branches,
switched branches and two-parameter curves) and the run's definition (:class:`ContinuationSpec`, validated by
:func:`continuation_spec`: every bad value raises :class:`~explorer_core.system.params.ParameterError`
naming it)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from explorer_core.analyses.orbits import ORBIT_NUMERICS
from explorer_core.analyses.regimes import DEFAULT_CHART_TOL, SWEEP_PARAM
from explorer_core.analyses.specs import Checking
from explorer_core.solve.checks import check_point
from explorer_core.solve.numerics import Numerics, check_int
from explorer_core.solve.options import (
    BOOL,
    CORRECTOR,
    ORBITS,
    Arg,
    Check,
    NewtonOptions,
    declare,
    ics,
    integer,
    optional_of,
    positive_or_none,
)
from explorer_core.system.params import ParameterError, Params

#: Newton on a corrected point stops when ``|F| <= CORRECTOR_TOL (1 + |x|)`` (the ``CORRECTOR`` preset's ftol).
CORRECTOR_TOL = CORRECTOR.ftol
MAX_POINTS = 5000
#: The longest period a cascade is followed to.
DEFAULT_MAX_PERIOD = 16


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
    max_iter: int = CORRECTOR.max_iter
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

    @property
    def corrector(self) -> NewtonOptions:
        """The corrector's Newton (what the engine reads): the ``CORRECTOR`` preset with these ``corrector_tol`` and
        ``max_iter`` (plain Newton steps on the continuation's own map, no trust region)."""
        return CORRECTOR.replace(ftol=self.corrector_tol, max_iter=self.max_iter)

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
    switch: bool
    max_period: int
    options: ContinuationOptions
    numerics: Numerics
    param2: str | None
    range2: tuple[float, float] | None
    window1: tuple[float, float] | None
    #: on the curves, also the codimension-two points a normal-form coefficient gives (CP, GPD, CH)
    codim2_nf: bool

    def as_dict(self) -> dict[str, Any]:
        """Every field in order, as plain data (``params``, ``options``, ``numerics`` by their ``as_dict``)."""
        plain = lambda v: v.as_dict() if hasattr(v, "as_dict") else list(v) if isinstance(v, tuple) else v  # noqa: E731
        return {f.name: plain(getattr(self, f.name)) for f in fields(self)}


#: The engine's settings when a call gives none.
DEFAULT_OPTIONS = ContinuationOptions()


def _two(name: str, value: Any, what: str) -> tuple[float, float]:
    """Two finite numbers (a range), or a ParameterError naming ``name`` and ``value``."""
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be two numbers {what}, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(b - a)):
        raise ParameterError(f"{name} must be two finite numbers {what} (a finite width), got {value!r}")
    return a, b


def _value_range(name: str, value: Any) -> tuple[float, float]:
    """``(A, B)``, different and finite (either way: from where the orbit is seeded), refused as "range"."""
    a, b = _two("range", value, "A,B")
    if a == b:
        raise ParameterError(f"range must be two different numbers, got {value!r}")
    return a, b


def _range2(name: str, value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    c, d = _two(name, value, "C,D")
    if not c < d:
        raise ParameterError(f"{name} must have C < D, got {value!r}")
    return c, d


def _window(name: str, value: Any) -> tuple[float, float] | None:
    """None, or a range in increasing order."""
    w = None if value is None else _two(name, value, "A,B")
    return None if w is None else (min(w), max(w))


def _options_default(name: str) -> str:
    """``(default X)``: a :class:`ContinuationOptions` field's own default, for the help of the keyword that sets it
    (its declared default is None: the options' own)."""
    value = next(f.default for f in fields(ContinuationOptions) if f.name == name)
    return f"(default {value:g})"


#: The continuation's options that continue_from_seeds passes on as they are (one declaration for both builders).
_BRANCH = {
    "param": Arg("the parameter followed", "str", required=True, positional=True, check=SWEEP_PARAM),
    "value_range": Arg(
        "from A (where the orbit is seeded) to B",
        "range",
        flag="--range",
        metavar="A,B",
        required=True,
        positional=True,
        check=Check(_value_range, "two different numbers A,B", "str"),
    ),
    "options": Arg(
        "the engine's settings",
        cli=False,
        default=DEFAULT_OPTIONS,
        check=optional_of(ContinuationOptions, DEFAULT_OPTIONS),
    ),
    "numerics": Arg("integration", cli=False, default=ORBIT_NUMERICS, check=optional_of(Numerics, ORBIT_NUMERICS)),
    "param2": Arg(
        "also follow each fold / period doubling in (PARAM, PARAM2)",
        "str",
        default=None,
        check=Check(SWEEP_PARAM.fn, f"{SWEEP_PARAM.text} or none", "str", optional=True),
    ),
    "range2": Arg(
        "the range of PARAM2",
        "range",
        metavar="C,D",
        default=None,
        check=Check(_range2, "two numbers C < D or none", "str", optional=True),
    ),
    "window1": Arg(
        "PARAM's range on the curves (default: the range)",
        cli=False,
        default=None,
        check=Check(_window, "two numbers A,B or none", "str", optional=True),
    ),
    "codim2_nf": Arg(
        "on the curves, also look for the codimension-two points a normal-form coefficient gives (cusp, generalised "
        "flip, Chenciner): a normal form at every point of every curve, about 1.5 times the curves' time",
        "switch",
        default=False,
        check=BOOL,
    ),
}
#: The options continuation_spec and map_spec share by meaning (one declaration for both builders).
_ORBIT = {
    "period": Arg("the orbit's period", "int", positional=True, cli_default=1, check=integer(1, 1024)),
    "switch": Arg(
        "at each period doubling, follow the doubled orbit too (and at each R2, LPPD and GPD point of a curve, the "
        "doubled orbit's curve that emanates)",
        "switch",
        default=False,
        check=BOOL,
    ),
    "max_period": Arg("cap of a cascade", "int", default=DEFAULT_MAX_PERIOD, checked_with=("period",)),
}


def _check_param2(param: str, param2: str | None, range2: tuple[float, float] | None) -> None:
    """``param2`` and ``range2`` go together, and ``param2`` is not ``param``."""
    if (param2 is None) != (range2 is None):
        raise ParameterError(f"param2 and range2 go together (both or neither), got {param2!r} and {range2!r}")
    if param2 is not None and param2 == param:
        raise ParameterError(f"param2 must differ from param, got {param2!r} twice")


@declare(
    param=_BRANCH["param"],
    value_range=_BRANCH["value_range"],
    seed=Arg(
        "a point near the period-N orbit at A",
        "point",
        flag="--from",
        metavar="Q,R",
        positional=True,
        checked_with=("numerics",),
    ),
    period=_ORBIT["period"],
    switch=_ORBIT["switch"],
    max_period=_ORBIT["max_period"],
    max_points=Arg(
        f"points per branch {_options_default('max_points')}",
        "int",
        default=None,
        check=integer(2, 1_000_000, optional=True),
    ),
    ds=Arg(
        f"first arclength step in (q, r, (p - A) / (B - A)) {_options_default('ds')}",
        default=None,
        check=positive_or_none(),
    ),
    ds_min=Arg(
        f"smallest step before a branch gives up {_options_default('ds_min')}",
        default=None,
        check=positive_or_none(),
    ),
    ds_max=Arg(f"largest step {_options_default('ds_max')}", default=None, check=positive_or_none()),
    param2=_BRANCH["param2"],
    range2=_BRANCH["range2"],
    options=_BRANCH["options"],
    numerics=_BRANCH["numerics"],
    window1=_BRANCH["window1"],
    codim2_nf=_BRANCH["codim2_nf"],
    check_end=Arg("refuse a range's end that is no valid system", cli=False, default=False, check=BOOL),
)
def continuation_spec(
    params: Params,
    param: str,
    value_range: tuple[float, float],
    seed: Sequence[float],
    period: int,
    *,
    switch: bool,
    max_period: int,
    options: ContinuationOptions,
    ds: float | None,
    ds_min: float | None,
    ds_max: float | None,
    max_points: int | None,
    numerics: Numerics,
    param2: str | None,
    range2: tuple[float, float] | None,
    window1: tuple[float, float] | None,
    codim2_nf: bool,
    check_end: bool,
) -> ContinuationSpec:
    """A validated :class:`ContinuationSpec`; every bad value raises :class:`ParameterError` naming it (and
    carrying the keyword as ``exc.option``, :mod:`explorer_core.analyses.specs`). The options are declared above:
    defaults, checks (run before this body), flags; the body checks what needs several of them.

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
    options : the engine's settings (:class:`ContinuationOptions`, default :data:`DEFAULT_OPTIONS`); ``ds``,
        ``ds_min``, ``ds_max`` and ``max_points``, when given, replace theirs (``ds_max`` alone also bounds the
        first step).
    numerics : integration (default :data:`~explorer_core.analyses.orbits.ORBIT_NUMERICS`).
    param2, range2 : together or neither: also follow every fold and period doubling found as a curve in
        ``(param, param2)``, ``param2`` (not ``param``) over ``range2 = (C, D)``, ``C < D``, and ``param``
        over ``window1`` (default: the range); their codimension-two points are located (:mod:`.codim2`), those a
        normal-form coefficient gives (CP, GPD, CH) only with ``codim2_nf``.
    """
    with Checking() as at:
        at("value_range")
        a, b = value_range
        for end, v in (("first value", a), ("end", b))[: 2 if check_end else 1]:
            try:
                params.with_(**{param: v})
            except ParameterError as exc:
                raise ParameterError(f"the range's {end} {param} = {v:g} is not a valid system: {exc}") from None
        at("max_period")
        max_period = check_int("max_period", max_period, period, 1024)
        opts = options
        given = {k: v for k, v in (("ds", ds), ("ds_min", ds_min), ("ds_max", ds_max), ("max_points", max_points))
                 if v is not None}  # fmt: skip
        if given:
            at("ds" if "ds" in given else next(iter(given)))
            if "ds" not in given and "ds_max" in given:  # an old-style ds_max alone bounds the default first step
                given["ds"] = min(float(opts.ds), float(given["ds_max"]))
            opts = ContinuationOptions(**{**asdict(opts), **given})
        at("seed")
        q, r = check_point("seed", seed, numerics.bound)
        at("param2")
        _check_param2(param, param2, range2)
    return ContinuationSpec(params, param, (a, b), (q, r), period, switch, max_period, opts, numerics,
                            param2, range2, window1, codim2_nf)  # fmt: skip


@dataclass(frozen=True)
class MapSpec(ContinuationSpec):
    """A continuation on a map given in closed form (:class:`~.testmaps.ClosedFormMap`, any
    :class:`~.system.ContinuationMap` with ``as_dict``) rather than this system: ``params`` is the map, ``numerics``
    None (the map is exact). Made by :func:`map_spec`."""


def _a_map(name: str, value: Any) -> Any:
    if not isinstance(getattr(value, "values", None), dict) or not hasattr(value, "over"):
        raise ParameterError(f"{name} must be a map with its parameters' values (a ClosedFormMap), got {value!r}")
    return value


def _any_point(name: str, value: Any) -> tuple[float, float]:
    """One finite point (a map in closed form has no escape bound)."""
    return check_point(name, value, math.inf)


def _map_param(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise ParameterError(f"{name} must be the name of a parameter of the map, got {value!r}")
    return value


@declare(
    cmap=Arg(
        "the map (a ClosedFormMap, or any ContinuationMap with values and as_dict)",
        cli=False,
        check=Check(_a_map, "a map with its parameters' values", "str"),
    ),
    param=Arg("the parameter followed", "str", checked_with=("cmap",)),
    value_range=_BRANCH["value_range"],
    seed=Arg("a point near the period-N orbit at A", "point", check=Check(_any_point, "a finite point Q,R", "str")),
    period=_ORBIT["period"],
    switch=_ORBIT["switch"],
    max_period=_ORBIT["max_period"],
    options=_BRANCH["options"],
    param2=Arg("the second parameter of the curves", "str", default=None, checked_with=("cmap",)),
    range2=_BRANCH["range2"],
    window1=_BRANCH["window1"],
    codim2_nf=_BRANCH["codim2_nf"],
)
def map_spec(
    cmap: Any,
    param: str,
    value_range: tuple[float, float],
    seed: Sequence[float],
    period: int,
    *,
    switch: bool,
    max_period: int,
    options: ContinuationOptions,
    param2: str | None,
    range2: tuple[float, float] | None,
    window1: tuple[float, float] | None,
    codim2_nf: bool,
) -> MapSpec:
    """A validated :class:`MapSpec`: the options declared above as :func:`continuation_spec`'s (the same
    declarations where they mean the same: range, period, switching, the cap, the engine's settings, range2, the
    window, codim2_nf); ``param`` and ``param2`` among the map's ``values``, ``seed`` any finite point (the map has no
    escape bound). Every bad value raises :class:`ParameterError` naming it."""
    with Checking() as at:
        for key, name in (("param", param), ("param2", param2)):
            at(key)
            if name is not None and _map_param(key, name) not in cmap.values:
                raise ParameterError(f"the map has no parameter {name!r} (it has {', '.join(cmap.values)})")
        at("max_period")
        max_period = check_int("max_period", max_period, period, 1024)
        at("param2")
        _check_param2(param, param2, range2)
    return MapSpec(cmap, param, value_range, seed, period, switch, max_period, options, None, param2, range2,
                   window1, codim2_nf)  # fmt: skip


@dataclass(frozen=True)
class SeedsSpec:
    """:func:`~explorer_core.analyses.continuation.continue_from_seeds`: every distinct orbit of ``periods`` that
    Newton finds from ``seeds`` at the range's first value (up to ``max_orbits``, lowest periods first), each
    continued as ``branch`` says (its own point and period set by :meth:`for_orbit`). Made by :func:`seeds_spec`."""

    seeds: np.ndarray = field(repr=False, compare=False)
    periods: tuple[int, ...]
    max_orbits: int
    #: The continuation every orbit found gets (``switch``, ``options``, ``numerics``, curves), at a placeholder
    #: point and the largest period; ``max_period``: the cascade's cap asked (at least the orbit's own).
    branch: ContinuationSpec
    max_period: int

    @property
    def params(self) -> Params:
        return self.branch.params

    @property
    def param(self) -> str:
        return self.branch.param

    @property
    def range(self) -> tuple[float, float]:
        return self.branch.range

    @property
    def numerics(self) -> Numerics:
        return self.branch.numerics

    def for_orbit(self, point: Sequence[float], period: int) -> ContinuationSpec:
        """The continuation of one orbit found (through ``point``, of ``period``), checked as every spec is."""
        b = self.branch
        return continuation_spec(b.params, b.param, b.range, point, period, switch=b.switch,
                                 max_period=max(self.max_period, period), options=b.options, numerics=b.numerics,
                                 param2=b.param2, range2=b.range2, window1=b.window1,
                                 codim2_nf=b.codim2_nf)  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        own = {"seeds": self.seeds.tolist(), "periods": list(self.periods), "max_orbits": self.max_orbits,
               "max_period": self.max_period}  # fmt: skip
        return {**self.branch.as_dict(), "seed": None, "period": None, **own}


#: Periods to look for: at least one, each a whole number in ``[1, 1024]``.
_PERIODS = Check(lambda n, v: _periods(v), "periods in [1, 1024]", "str")


# No command runs it (the app does): its own options are keywords of calls only; the shared ones keep the flags of
# `continue`.
@declare(
    param=_BRANCH["param"],
    value_range=_BRANCH["value_range"],
    seeds=Arg("points near the orbits at A", cli=False, check=ics()),
    periods=Arg("the periods Newton looks for", cli=False, default=(1, 2, 3, 4), check=_PERIODS),
    max_orbits=Arg("orbits continued at most (lowest periods first)", cli=False, default=6, check=integer(1, 1000)),
    switch=Arg("at each period doubling, follow the doubled orbit too", cli=False, default=True, check=BOOL),
    max_period=Arg("cap of a cascade", cli=False, default=DEFAULT_MAX_PERIOD, check=integer(1, 1024)),
    options=_BRANCH["options"],
    numerics=_BRANCH["numerics"],
    param2=_BRANCH["param2"],
    range2=_BRANCH["range2"],
    window1=_BRANCH["window1"],
)
def seeds_spec(
    params: Params,
    param: str,
    value_range: tuple[float, float],
    seeds: np.ndarray,
    *,
    periods: tuple[int, ...],
    max_orbits: int,
    switch: bool,
    max_period: int,
    options: ContinuationOptions,
    numerics: Numerics,
    param2: str | None,
    range2: tuple[float, float] | None,
    window1: tuple[float, float] | None,
) -> SeedsSpec:
    """A validated :class:`SeedsSpec`: the seeds (n, 2), the periods Newton looks for (each in ``[1, 1024]``),
    ``max_orbits`` in ``[1, 1000]``; the rest as :func:`continuation_spec` checks it (the orbit's own seed and
    period are Newton's, found when it runs). The options are declared above (defaults, checks)."""
    branch = continuation_spec(params, param, value_range, (0.0, 0.0), max(periods), switch=switch,
                               max_period=max(max_period, *periods), options=options, numerics=numerics,
                               param2=param2, range2=range2, window1=window1)  # fmt: skip
    return SeedsSpec(seeds, periods, max_orbits, branch, max_period)


@dataclass(frozen=True)
class BoundariesSpec:
    """:func:`~explorer_core.analyses.continuation.chart_boundaries`: the fold and period-doubling curves that
    bound ``chart``'s regions of stable cycles of ``periods``, continued with ``numerics`` (validated by
    :func:`boundaries_spec`)."""

    chart: Any = field(repr=False, compare=False)
    periods: tuple[int, ...]
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return {"chart": self.chart.spec.as_dict(), "periods": list(self.periods), "numerics": self.numerics.as_dict()}


def _computed_chart(name: str, chart: Any) -> Any:
    if getattr(chart, "spec", None) is None or not hasattr(chart, "regime"):
        raise ParameterError(f"{name} must be a computed chart of regimes, got {type(chart).__name__}")
    return chart


@declare(
    chart=Arg("a computed chart of regimes", cli=False, check=Check(_computed_chart, "a computed chart", "str")),
    periods=Arg("the periods whose regions are bounded", cli=False, default=(1, 2, 3), check=_PERIODS),
    numerics=Arg(
        "the continuation's integration (none: following the chart's)",
        cli=False,
        default=None,
        check=optional_of(Numerics),
    ),
)
def boundaries_spec(chart: Any, *, periods: tuple[int, ...], numerics: Numerics | None) -> BoundariesSpec:
    """A validated :class:`BoundariesSpec`. ``numerics`` default: the orbits' map as it follows the chart's
    tolerance (:meth:`~explorer_core.solve.options.NewtonOptions.at` of
    :data:`~explorer_core.solve.options.ORBITS`: vern9 at 1e-12 for a chart at its default 1e-8, 1e-10 for a
    chart at 1e-6). The options are declared above (defaults, checks)."""
    if numerics is None:
        numerics = ORBITS.at(chart.spec.numerics, DEFAULT_CHART_TOL)[0]
    return BoundariesSpec(chart, periods, numerics)


def _periods(periods: Any) -> tuple[int, ...]:
    """Periods to look for: at least one, each a whole number in ``[1, 1024]``."""
    try:
        out = tuple(check_int("periods", p, 1, 1024) for p in periods)
    except TypeError:
        raise ParameterError(f"periods must be whole numbers in [1, 1024], got {periods!r}") from None
    if not out:
        raise ParameterError("periods must name at least one period, got none")
    return out
