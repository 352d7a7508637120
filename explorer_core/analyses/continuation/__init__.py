"""Continuation of periodic orbits of the Poincare map in a parameter, through their bifurcations.

A period-``n`` orbit is a zero of ``F(x, p) = P^n(x; p) - x``; its points ``(x, p)`` form curves (branches),
followed by pseudo-arclength continuation (Keller) through folds. Along a branch the folds, period doublings and
Neimark-Sacker points are located where their test functions change sign; at a period doubling the doubled
branch is switched onto (``switch=True``: the cascade ``1 -> 2 -> 4 -> 8 -> 16``); folds, doublings and
Neimark-Sacker points can be followed as curves in a second parameter, with their codimension-two points. Nothing
is lost in silence: a branch or curve that stopped other than at a range end or at a located bifurcation where it
was meant to stop is a :class:`~explorer_core.losses.Loss` of the result.

Continuation is an iterator, as BifurcationKit's ``ContIterable`` over a ``ContState``: the engine's
:meth:`~.engine._Engine.follow` is a generator over an explicit state, the drivers are generators over it, and
``iter_continue_orbit`` streams the points with a plain ``for`` loop, no thread.

The modules, bottom to top:

* :mod:`.options`: :class:`ContinuationOptions` (the engine's settings), :class:`ContinuationSpec` and its
  builder :func:`continuation_spec`;
* :mod:`.system`: what the engine asks of a map (:class:`ContinuationMap`) and this system's (``_System``: ``P^n``,
  ``DP^n``, ``F_p`` by lock-step central differences), the test
  functions (:func:`test_function`) and a bifurcation's defining system;
* :mod:`.engine`: predictor, corrector, step control, landing on the range's ends (:class:`_Engine`), the state
  of a curve being followed (:class:`_Walk`) and the generator :meth:`_Engine.follow`;
* :mod:`.results`: :class:`Branch`, :class:`Bifurcation`, :class:`Curve`, :class:`Continuation`,
  :class:`Boundaries` and their writers;
* :mod:`.problems`: the branch and curve problems the engine follows (:class:`_BranchProblem`,
  :class:`_CurveProblem`);
* :mod:`.events`: crossing, location and refinement of bifurcations on a branch;
* :mod:`.switching`: births and switching at period doublings;
* :mod:`.codim2`: the codimension-two points on the curves (test functions, location; CP, R1-R4, LPPD, GPD, CH);
* :mod:`.curves`: two-parameter curves of folds, doublings and Neimark-Sacker points, and the switching at their
  R2, LPPD and GPD points onto the doubled orbit's curves;
* :mod:`.drivers`: :func:`continue_orbit` / :func:`iter_continue_orbit`, :func:`continue_from_seeds` /
  :func:`iter_continue_from_seeds`, :func:`chart_boundaries` / :func:`iter_chart_boundaries`, and
  :func:`continue_map` (the same on any :class:`~.system.ContinuationMap` with ``as_dict``);
* :mod:`.testmaps`: maps in closed form with exact bifurcation sets (Henon, the delayed logistic map).
"""

from explorer_core.analyses.continuation.drivers import (
    chart_boundaries,
    continue_from_seeds,
    continue_map,
    continue_orbit,
    iter_chart_boundaries,
    iter_continue_from_seeds,
    iter_continue_orbit,
)
from explorer_core.analyses.continuation.engine import _Engine, _Point, _Walk
from explorer_core.analyses.continuation.events import LOCATE_TOL, REFINE_FROM, REFINE_NOISE
from explorer_core.analyses.continuation.options import (
    CORRECTOR_TOL,
    DEFAULT_MAX_PERIOD,
    MAX_POINTS,
    BoundariesSpec,
    ContinuationOptions,
    ContinuationSpec,
    MapSpec,
    SeedsSpec,
    boundaries_spec,
    continuation_spec,
    map_spec,
    seeds_spec,
)
from explorer_core.analyses.continuation.problems import _BranchProblem, _CurveProblem
from explorer_core.analyses.continuation.results import (
    Bifurcation,
    Boundaries,
    Branch,
    Codim2Point,
    Continuation,
    Curve,
    classify_branch,
)
from explorer_core.analyses.continuation.switching import BIRTH_RATIO
from explorer_core.analyses.continuation.system import (
    FD_ACCURACY,
    FD_LOOSEN,
    FD_RTOL_MAX,
    FD_STEP,
    KINDS,
    ContinuationMap,
    _defining,
    _Stop,
    _System,
    test_function,
)

# The private names are for the tests and benchmarks that count the engine's work (tests/test_continuation_work.py,
# benchmarks/orbits_work.py): a class's method is patched here (it is the one class), a function in the module that
# looks it up (e.g. ``continuation.events._defining``, which the refinement calls).
__all__ = [
    "BIRTH_RATIO",
    "CORRECTOR_TOL",
    "DEFAULT_MAX_PERIOD",
    "FD_ACCURACY",
    "FD_LOOSEN",
    "FD_RTOL_MAX",
    "FD_STEP",
    "KINDS",
    "LOCATE_TOL",
    "MAX_POINTS",
    "REFINE_FROM",
    "REFINE_NOISE",
    "Bifurcation",
    "Boundaries",
    "BoundariesSpec",
    "Branch",
    "Codim2Point",
    "Continuation",
    "ContinuationMap",
    "ContinuationOptions",
    "ContinuationSpec",
    "Curve",
    "MapSpec",
    "SeedsSpec",
    "_BranchProblem",
    "_CurveProblem",
    "_Engine",
    "_Point",
    "_Stop",
    "_System",
    "_Walk",
    "_defining",
    "boundaries_spec",
    "chart_boundaries",
    "classify_branch",
    "continuation_spec",
    "continue_from_seeds",
    "continue_map",
    "continue_orbit",
    "iter_chart_boundaries",
    "iter_continue_from_seeds",
    "iter_continue_orbit",
    "map_spec",
    "seeds_spec",
    "test_function",
]
