"""Options declared once: a spec's fields carry their default, their check, their help and their flag.

An options class is a frozen dataclass whose fields are made by :func:`option`; :class:`Options` validates
every field on construction through the field's check (:mod:`explorer_core.solve.checks`), tags a refused
value with the option's name (``exc.option``), and lists its options (:meth:`Options.options`) for the
command line's flags, the app's controls and the docs. Nested options (a :class:`NewtonOptions` inside an
analysis' spec) are fields like any other, recorded in every result's JSON ``spec``.

:class:`NewtonOptions` are the settings of the one Newton on ``P^n(x) - x``
(:func:`explorer_core.solve.poincare.newton`), with named presets for its four uses (:data:`ORBITS`,
:data:`SETTLING`, :data:`JUMPS`, :data:`CORRECTOR`) and the one rule that derives the map Newton iterates
from the user's numerics (:meth:`NewtonOptions.at`), as BifurcationKit's ``ContinuationPar`` nests a
``NewtonPar`` that every corrector reads.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, TypeVar

from explorer_core import config
from explorer_core.solve import checks
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError

T = TypeVar("T", bound="Options")


@dataclass(frozen=True)
class Check:
    """A field's check: ``check(name, value)`` returns the canonical value or raises ParameterError;
    ``text`` says what it accepts (for the help)."""

    fn: Callable[[str, Any], Any]
    text: str
    #: How a command line's text becomes the value: "int", "float", "bool" (true/false); ``optional``: "none"
    #: is None.
    kind: str = "float"
    #: None is accepted: it stands for ``none_is`` (checked by ``fn`` unless None itself), never reaches ``fn``.
    optional: bool = False
    none_is: Any = None

    def __call__(self, name: str, value: Any) -> Any:
        if self.optional and value is None:
            return None if self.none_is is None else self.fn(name, self.none_is)
        return self.fn(name, value)

    def parse(self, name: str, text: str) -> Any:
        """The value of a command line's ``text`` (then checked), or ParameterError naming it."""
        t = str(text).strip().lower()
        if self.optional and t == "none":
            return self(name, None)
        try:
            if self.kind == "bool":
                value: Any = {"true": True, "false": False}[t]
            elif self.kind == "int":
                value = int(t)
            else:
                value = float(t)
        except (KeyError, ValueError):
            raise ParameterError(f"{name} must be {self.text}, got {str(text)[:40]!r}") from None
        return self(name, value)


def integer(lo: int, hi: int, optional: bool = False) -> Check:
    text = f"an integer in [{lo}, {hi}]" + (" or none" if optional else "")
    return Check(lambda n, v: checks.check_int(n, v, lo, hi), text, "int", optional)


POSITIVE = Check(checks.check_positive, "a positive number")
BOOL = Check(checks.check_bool, "true or false", "bool")
POSITIVE_OR_INF = Check(
    lambda n, v: math.inf if v == math.inf else checks.check_positive(n, v), "a positive number or inf"
)


def positive_or_none() -> Check:
    return Check(checks.check_positive, "a positive number or none", optional=True)


def instance(kind: type) -> Check:
    def fn(name: str, v: Any) -> Any:
        if not isinstance(v, kind):
            raise ParameterError(f"{name} must be a {kind.__name__}, got {v!r}")
        return v

    return Check(fn, f"a {kind.__name__}")


def number(lo: float = -math.inf, hi: float = math.inf, optional: bool = False) -> Check:
    """A finite number in ``[lo, hi]`` (``optional``: or None)."""
    within = "" if (lo, hi) == (-math.inf, math.inf) else f" in [{lo:g}, {hi:g}]"
    return Check(
        lambda n, v: checks.check_number(n, v, lo, hi),
        f"a finite number{within}" + (" or none" if optional else ""),
        optional=optional,
    )


def fraction() -> Check:
    return Check(checks.check_fraction, "a number in (0, 1)")


def choice(choices: tuple[str, ...]) -> Check:
    return Check(lambda n, v: checks.check_choice(n, v, choices), "one of " + ", ".join(choices), "str")


def seed(optional: bool = False) -> Check:
    """A random draw's seed (``optional``: or None, a fresh draw)."""
    text = f"an integer in [0, {checks.MAX_SEED}]" + (" or none" if optional else "")
    return Check(lambda n, v: checks.check_seed(v, n), text, "int", optional)


def span(increasing: bool = True, optional: bool = False, what: str = "lo,hi") -> Check:
    """Two finite numbers ``lo < hi`` (``increasing``) or two different ones (``optional``: or None)."""
    fn = functools.partial(checks.check_range, increasing=increasing, what=what)
    text = "two numbers " + ("lo < hi" if increasing else "A != B") + (" or none" if optional else "")
    return Check(fn, text, "str", optional)


def box(optional: bool = False) -> Check:
    """``qmin,qmax,rmin,rmax`` with ``qmin < qmax``, ``rmin < rmax`` (``optional``: or None)."""
    return Check(
        lambda n, v: checks.check_box(v, n),
        "four numbers qmin < qmax, rmin < rmax" + (" or none" if optional else ""),
        "str",
        optional,
    )


def ints(count: int, lo: int, hi: int, what: str = "NX,NY", optional: bool = False) -> Check:
    """``count`` whole numbers each in ``[lo, hi]`` (``optional``: or None)."""
    return Check(
        lambda n, v: checks.check_ints(n, v, count, lo, hi, what),
        f"{count} integers {what} in [{lo}, {hi}]" + (" or none" if optional else ""),
        "str",
        optional,
    )


def ics(optional: bool = False, none_is: Any = None) -> Check:
    """Initial conditions (or seeds) as a finite ``(n, 2)`` array (:func:`~explorer_core.solve.checks.check_ics`'
    messages); ``optional``: or None, which stands for ``none_is`` (the option's default; None: none given)."""
    text = "finite (q, r) pairs" + (" or none" if optional else "")
    return Check(lambda n, v: checks.check_ics(v), text, "str", optional, none_is)


def optional_of(kind: type, none_is: Any = None) -> Check:
    """An instance of ``kind``, or None: ``none_is`` (the option's default, e.g. an analysis' own numerics: a caller
    passing None asks for the default)."""
    return Check(instance(kind).fn, f"a {kind.__name__} or none", optional=True, none_is=none_is)


def option(default: Any, check: Check, help: str, *, flag: str | None = None, metavar: str | None = None) -> Any:
    """A spec field: its ``default``, its ``check``, one line of ``help`` and the command line's ``flag``
    (default: ``--`` and the field's name with dashes; ``""``: no flag)."""
    return field(default=default, metadata={"check": check, "help": help, "flag": flag, "metavar": metavar})


@dataclass(frozen=True)
class OptionInfo:
    """One option as the command line, the app and the docs show it."""

    name: str
    default: Any
    help: str
    check: Check
    flag: str | None
    metavar: str | None

    @property
    def accepts(self) -> str:
        return self.check.text


@dataclass(frozen=True)
class Options:
    """Base of options classes: every field made by :func:`option` is checked on construction."""

    #: Prefix of the fields' flags when the class is nested in a spec (``newton`` -> ``--newton-ftol``).
    prefix: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for f in fields(self):
            check = f.metadata.get("check")
            if check is None:
                continue
            try:
                value = check(f.name, getattr(self, f.name))
            except ParameterError as exc:
                if getattr(exc, "option", None) is None:
                    exc.option = f.name  # type: ignore[attr-defined]
                raise
            object.__setattr__(self, f.name, value)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float) and math.isinf(v):
                v = "inf" if v > 0 else "-inf"  # JSON has no infinity (the writers make it null: no information)
            out[f.name] = v.as_dict() if hasattr(v, "as_dict") else v
        return out

    def replace(self: T, **changes: Any) -> T:
        """A copy with ``changes`` (checked); an unknown name is refused, never ignored."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            have = ", ".join(self.names())
            raise ParameterError(f"{type(self).__name__} has no option {unknown[0]!r} (it has {have})")
        return dataclasses.replace(self, **changes)

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    @classmethod
    def options(cls) -> list[OptionInfo]:
        """The declared options, in order, with the flags they take when nested under :attr:`prefix`."""
        out = []
        for f in fields(cls):
            if "check" not in f.metadata:
                continue
            flag = f.metadata["flag"]
            if flag is None:
                flag = "--" + "-".join(p for p in (cls.prefix, f.name.replace("_", "-")) if p)
            out.append(OptionInfo(f.name, f.default, f.metadata["help"], f.metadata["check"], flag or None,
                                  f.metadata["metavar"]))  # fmt: skip
        return out


@dataclass(frozen=True)
class NewtonOptions(Options):
    """Settings of the one Newton on ``P^n(x) - x`` (:func:`explorer_core.solve.poincare.newton`).

    ``rtol`` is the tolerance of the map Newton iterates *when the analysis runs at its default tolerance*;
    with ``follow`` (default) it moves with the user's: :meth:`at` is the one rule.
    """

    prefix: ClassVar[str] = "newton"

    ftol: float = option(1e-9, POSITIVE, "converged when |P^n(x) - x| <= ftol (1 + |x|)")
    max_iter: int = option(40, integer(1, 10_000), "iterations per seed")
    max_step: float = option(1.0, POSITIVE_OR_INF, "trust region: the longest step (inf: plain Newton)")
    patience: int | None = option(
        6, integer(1, 10_000, optional=True), "give up after this many iterations without halving the residual"
    )
    coarse: bool = option(True, BOOL, "iterate with a less accurate map far from the orbit")
    rtol: float | None = option(
        None, positive_or_none(), "tolerance of the map Newton iterates at the analysis' default tolerance "
        "(none: the analysis' own map, as it is)")  # fmt: skip
    follow: bool = option(True, BOOL, "the map's tolerance and ftol follow the user's tolerance (false: as set)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.rtol is not None and not 1e-15 <= self.rtol <= 1.0:
            raise ParameterError(f"newton rtol must be in [1e-15, 1], got {self.rtol!r}")

    def at(self, user: Numerics, reference_rtol: float) -> tuple[Numerics, float]:
        """The map Newton iterates and its ``ftol`` for an analysis run with ``user`` numerics whose default
        tolerance is ``reference_rtol``: the rule, documented once.

        With ``factor = user.rtol / reference_rtol``: the map's tolerances are ``rtol * factor`` (atol alike),
        clipped to [1e-13, 1e-6]; ``ftol`` grows with a looser user (``ftol * max(1, factor)``: a residual
        cannot be smaller than the map is accurate); the method is the user's, or the "auto" rule's when the
        rule chose the user's or the user's cannot integrate the tangent system (taylor); step budgets are the
        user's, the escape bound the larger of the user's and the sections' default (Newton's iterates may
        wander farther than the trajectory they start from before they converge). At the default tolerance
        this is the preset exactly. ``rtol=None``: the user's numerics themselves (``ftol`` following them).
        ``follow=False``: ``rtol`` and ``ftol`` as set.
        """
        factor = user.rtol / reference_rtol if self.follow else 1.0

        def scale(v: float, by: float, lo: float = 1e-13, hi: float = 1e-6) -> float:
            # 12 digits: a decade times a decade is that decade (1e-10 * 100 is 1e-8, not 1.0000000000000001e-08).
            return min(hi, max(lo, v if by == 1.0 else float(f"{v * by:.12g}")))

        ftol = scale(self.ftol, max(1.0, factor), 0.0, 1e-2) if self.follow else self.ftol
        if self.rtol is None:
            return user, ftol

        rtol = scale(self.rtol, factor) if self.follow else self.rtol
        method = "auto" if user.by_rule or user.method == "taylor" else user.method
        bound = max(user.bound, config.DEFAULT_ESCAPE_BOUND)
        numerics = Numerics(method=method, rtol=rtol, atol=rtol, steps_per_period=user.steps_per_period,
                            bound=bound, max_steps=user.max_steps, adaptive=user.adaptive)  # fmt: skip
        return numerics, ftol

    def newton_kwargs(self) -> dict[str, Any]:
        """The keywords of :func:`~explorer_core.solve.poincare.newton` these options set (not ``ftol``:
        :meth:`at` gives it)."""
        return {"max_iter": self.max_iter, "max_step": self.max_step, "patience": self.patience,
                "coarse": self.coarse}  # fmt: skip


#: Periodic orbits from seeds (orbits, basins' cycles, manifolds' saddles): the map at 1e-12 (vern9).
ORBITS = NewtonOptions(ftol=1e-9, max_iter=40, max_step=1.0, patience=6, coarse=True, rtol=1e-12)
#: A chart pixel's settled cycle: a few plain Newton steps on a map at 1e-10, no patience.
SETTLING = NewtonOptions(ftol=1e-8, max_iter=8, max_step=math.inf, patience=None, coarse=True, rtol=1e-10)
#: The orbit diagram's jump onto an attracting cycle: the diagram's own map, 6 plain steps to a tenth of the
#: diagram's SETTLE_TOL (written as the product, the float the diagram has always used).
JUMPS = NewtonOptions(ftol=0.1 * 1e-9, max_iter=6, max_step=math.inf, patience=None, coarse=False, rtol=None)
#: Continuation's corrector (Newton on F = 0 and the arclength condition) on the continuation's own map.
CORRECTOR = NewtonOptions(ftol=1e-10, max_iter=8, max_step=math.inf, patience=None, coarse=False, rtol=None)
PRESETS = {"orbits": ORBITS, "settling": SETTLING, "jumps": JUMPS, "corrector": CORRECTOR}


# ---------------------------------------------------------------------------
# A builder's options, each declared once: default, check, help, and how the command line and a scene give it.

#: An option with no default: the call must give it.
REQUIRED: Any = inspect.Parameter.empty


@dataclass(frozen=True)
class Arg:
    """One option of a builder (or a runner), declared once beside it (:func:`declare`): the call's ``default``, the
    ``check`` that validates it, its ``help``, and how the command line gives it. The builder's signature, the
    command line's flags and help, and the validation are all generated from these declarations.

    default : the call's default (:data:`REQUIRED`: none, the call must give it).
    check : validates one value and returns its canonical form (:class:`Check`); None only with ``checked_with``.
    checked_with : the options the body checks this one with (its check depends on them: a seed inside the escape
        bound of ``numerics``); a declaration says where its check is.
    parse : how the text becomes the value: ``"int"``, ``"float"``, ``"str"``, ``"switch"`` (a flag without a
        value: True), ``"range"`` (``A,B``), ``"ints"`` (``NX,NY``), ``"box"`` (``Q0,Q1,R0,R1``), ``"points"``
        (``Q,R``, repeatable), ``"point"``, ``"list"`` (comma-separated words).
    flag : default ``--`` and the keyword with dashes; ``""``: taken from the scene only.
    cli : False: a keyword of calls only (numerics, nested options, internal sizes), no flag.
    scene : under ``--scene``, the default is this attribute of the scene (``box``, ``points``, ``view``,
        ``transient``, ``periods``, ``initial_conditions``) when the flag is not given.
    unless : the scene's value is not taken when one of these options is given (``--random`` instead of the
        scene's initial conditions).
    positional : passed to the builder by position (in the declared order), not by keyword.
    cli_default : the command line's default where it differs from the call's (a command runs a transient that
        the call leaves to its caller); the help shows it.
    """

    help: str = ""
    parse: str = "float"
    flag: str | None = None
    metavar: str | None = None
    required: bool = False
    scene: str | None = None
    choices: tuple[str, ...] | None = None
    positional: bool = False
    cli_default: Any = None
    unless: tuple[str, ...] = ()
    default: Any = REQUIRED
    check: Check | None = None
    checked_with: tuple[str, ...] = ()
    cli: bool = True

    def flag_of(self, name: str) -> str:
        return self.flag or "--" + name.replace("_", "-")


def declare(**args: Arg) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Declare a builder's (or a runner's) options once (:class:`Arg`) and validate them generically.

    The function's own parameters carry no default for a declared option (a second place would drift): the
    returned builder's signature takes the declarations' defaults, every value given or defaulted goes through its
    option's ``check`` (a refusal is tagged with the option's name, ``exc.option``) before the body runs, and the
    body does only what needs several options at once (cross-checks, derived values). ``builder.__options__`` has
    every declaration, ``builder.__cli__`` those with a flag.
    """

    def attach(fn: Callable[..., Any]) -> Callable[..., Any]:
        sig = inspect.signature(fn)
        for name, arg in args.items():
            p = sig.parameters.get(name)
            if p is None:
                raise TypeError(f"{fn.__name__} declares {name!r}, which it does not take")
            if p.default is not inspect.Parameter.empty:
                raise TypeError(f"{fn.__name__}: the default of {name!r} belongs in its declaration, not the signature")
            if (arg.check is None) == (not arg.checked_with):
                raise TypeError(f"{fn.__name__}: {name!r} needs a check, or checked_with naming what the body "
                                "checks it with (not both)")  # fmt: skip
        # Raises if a defaulted positional option precedes one without a default (the declarations' order).
        full = sig.replace(parameters=[p.replace(default=args[p.name].default) if p.name in args else p
                                       for p in sig.parameters.values()])  # fmt: skip

        kinds = {p.kind for p in full.parameters.values()}
        plain = not kinds & {inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.VAR_POSITIONAL,
                             inspect.Parameter.VAR_KEYWORD}  # fmt: skip
        positional = [n for n, p in full.parameters.items() if p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD]
        defaults = {n: p.default for n, p in full.parameters.items() if p.default is not inspect.Parameter.empty}
        checked = [(n, a.check) for n, a in args.items() if a.check is not None]
        every = full.parameters.keys()

        def bind(a: tuple, kw: dict[str, Any]) -> dict[str, Any]:
            # Signature.bind's answer without its cost (a builder runs on every slider move): plain
            # parameters only; anything unusual (a missing or unknown name) goes to bind for its TypeError.
            if plain and len(a) <= len(positional) and not kw.keys() & positional[: len(a)]:
                values = {**defaults, **dict(zip(positional, a, strict=False)), **kw}
                if values.keys() == every:
                    return values
            bound = full.bind(*a, **kw)
            bound.apply_defaults()
            return dict(bound.arguments)

        @functools.wraps(fn)
        def build(*a: Any, **kw: Any) -> Any:
            values = bind(a, kw)
            for name, check in checked:
                try:
                    values[name] = check(name, values[name])
                except ParameterError as exc:
                    if getattr(exc, "option", None) is None:
                        exc.option = name  # type: ignore[attr-defined]
                    raise
            if plain:
                return fn(**values)
            bound = full.bind_partial()
            bound.arguments.update(values)
            return fn(*bound.args, **bound.kwargs)

        build.__signature__ = full  # type: ignore[attr-defined]
        build.__options__ = dict(args)  # type: ignore[attr-defined]
        build.__cli__ = {n: a for n, a in args.items() if a.cli}  # type: ignore[attr-defined]
        return build

    return attach
