"""The section as an analysis: its spec (the initial conditions, periods, numerics and the window it is drawn in),
and the run that says when the method is unreliable for it.

The engine is :mod:`explorer_core.solve.section` (``section(params, ics, periods, ...)``, ``iter_section``): this
module is its boundary for the command line and the registry, where the options are declared once
(:func:`section_spec`): the initial conditions given, drawn at random in a box, or the scene's; the numerics a
picture of the window needs (:func:`~explorer_core.scenes.plot_numerics`) unless given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from explorer_core import config
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.scenes import pixel_size, plot_numerics
from explorer_core.solve.numerics import Numerics, random_ics
from explorer_core.solve.options import BOOL, Arg, declare, ics, integer, optional_of
from explorer_core.solve.options import box as box_check
from explorer_core.solve.options import seed as seed_check
from explorer_core.solve.section import Section, SectionChunk, section
from explorer_core.system.params import ParameterError, Params

#: ``--random`` without a box (and no scene to take one from).
DEFAULT_RANDOM_BOX = (-2.0, 2.0, -2.0, 2.0)


@dataclass(frozen=True)
class SectionSpec:
    """A section to compute: ``periods`` points per initial condition after ``transient``, forward or backward
    (``direction``), with ``numerics``; ``view`` the window it is drawn in (the reliability checks' pixel), and
    ``origin`` how the initial conditions were made (recorded: ``{"random": n, "box": ..., "seed": ...}``)."""

    params: Params
    ics: np.ndarray = field(repr=False)
    periods: int
    transient: int
    numerics: Numerics
    direction: int
    view: tuple[float, float, float, float] | None
    origin: dict[str, Any] | None

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "ics": self.origin or {"given": self.ics.tolist()},
                "periods": self.periods, "transient": self.transient, "numerics": self.numerics.as_dict(),
                "direction": self.direction, "view": None if self.view is None else list(self.view)}  # fmt: skip


#: Options a section's builder and a density image's (:func:`~explorer_core.analyses.density.density_spec`) share.
PERIODS_ARG = Arg(
    "section points per trajectory", "int", scene="periods", positional=True, metavar="N",
    check=integer(1, config.MAX_PERIODS),
)  # fmt: skip
SEED_ARG = Arg("seed of --random", "int", default=0, check=seed_check())
TRANSIENT_ARG = Arg("periods dropped first", "int", scene="transient", default=0, check=integer(0, config.MAX_PERIODS))


@declare(
    periods=PERIODS_ARG,
    ics=Arg(
        "initial condition (repeatable)",
        "points",
        flag="--ic",
        scene="initial_conditions",
        unless=("random",),
        default=None,
        check=ics(optional=True),
    ),
    random=Arg(
        "random initial conditions in --box",
        "int",
        metavar="N",
        default=None,
        check=integer(1, config.MAX_TRAJECTORIES, optional=True),
    ),
    seed=SEED_ARG,
    box=Arg("box for --random", "box", scene="box", default=DEFAULT_RANDOM_BOX, check=box_check(optional=True)),
    transient=TRANSIENT_ARG,
    backward=Arg("integrate backward in time (points at t0 - k T)", "switch", default=False, check=BOOL),
    view=Arg("", scene="view", flag="", default=None, check=box_check(optional=True)),
    bound=Arg("", scene="bound", flag="", default=None, checked_with=("numerics",)),
    numerics=Arg("default: a picture's of the view", cli=False, default=None, check=optional_of(Numerics)),
)
def section_spec(
    params: Params,
    periods: int,
    *,
    ics: np.ndarray | None,
    random: int | None,
    seed: int,
    box: tuple[float, float, float, float] | None,
    transient: int,
    backward: bool,
    view: tuple[float, float, float, float] | None,
    bound: float | None,
    numerics: Numerics | None,
) -> SectionSpec:
    """A validated :class:`SectionSpec` (a bad value raises ParameterError naming it, ``exc.option``: its keyword).

    The initial conditions: ``random`` of them uniform in ``box`` (None: :data:`DEFAULT_RANDOM_BOX`) from
    ``seed``, then the given ``ics`` (n, 2) (as a scene's: its random ones, then its points). ``numerics``
    default: a picture's of ``view`` over the whole run (:func:`~explorer_core.scenes.plot_numerics`) escaping at
    ``bound``, or :class:`Numerics` (with ``bound``) when there is no view. The options are declared above:
    defaults, checks (run before this body), flags.
    """
    with Checking() as at:
        direction = -1 if backward else 1
        given = np.empty((0, 2)) if ics is None else ics
        origin = None
        if random is not None:
            box = box or DEFAULT_RANDOM_BOX
            origin = {"random": random, "box": list(box), "seed": seed, "points": given.tolist()}
            given = np.concatenate([random_ics(random, box, seed=seed), given])  # as a scene's: random ones first
        at("ics")
        if given.shape[0] == 0:
            raise ParameterError("give initial conditions: --ic Q,R (repeatable) or --random N")
        ics = given
        if ics.shape[0] * periods > config.MAX_POINTS:
            raise ParameterError(f"{ics.shape[0]} trajectories x {periods} periods = {ics.shape[0] * periods} "
                                 f"points exceeds the limit {config.MAX_POINTS}")  # fmt: skip
        at("numerics")
        if numerics is None:  # the bound is checked where it is used (Numerics), only without numerics
            bound = config.DEFAULT_ESCAPE_BOUND if bound is None else float(bound)
            numerics = plot_numerics(view, periods + transient, bound) if view else Numerics(bound=bound)
    return SectionSpec(params, ics, periods, transient, numerics, direction, view, origin)  # type: ignore[arg-type]


@dataclass
class AssessedSection(Section):
    """A :class:`~explorer_core.solve.section.Section` with the warnings of
    :func:`~explorer_core.analyses.reliability.assess_section`: where the method is unreliable for this run."""

    reliability: list = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        return {**super().summary(), "reliability": [w.as_dict() for w in self.reliability]}

    def report(self) -> list[str]:
        from explorer_core.status import describe

        points = int(self.npts.sum())
        return [f"{self.n} trajectories, {points} points, {self.elapsed_s:.3f} s, {describe(self.status)}"]

    def notes(self) -> list[str]:
        """The reliability warnings, one line each (stderr; ``--quiet`` silences them)."""
        return [w.line() for w in self.reliability]


def poincare_section(
    spec: SectionSpec | Params,
    *args: Any,
    progress: Callable[[SectionChunk], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> AssessedSection:
    """The section of ``spec`` (or of :func:`section_spec`'s keywords), with its reliability warnings."""
    from explorer_core.analyses.reliability import assess_section

    spec = spec_of(SectionSpec, section_spec, spec, args, kw)
    sec = section(spec.params, spec.ics, spec.periods, transient=spec.transient, numerics=spec.numerics,
                  direction=spec.direction, progress=progress, cancel=cancel, workers=workers)  # fmt: skip
    pixel = None if spec.view is None else pixel_size(spec.view)
    warnings = assess_section(sec, pixel=pixel, window=spec.view)
    return AssessedSection(**{f.name: getattr(sec, f.name) for f in fields(sec)}, reliability=warnings)
