"""Numerical settings and input checks shared by every call that integrates: the solving layer's boundary.

:class:`Numerics` (method, tolerances, budgets), validated on construction; the checks of initial
conditions, boxes and counts that the public functions, the CLI and the app apply to their inputs,
with messages that name the bad value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config

# The input checks live in solve.checks; these names are imported from here by the analyses and the CLI.
from explorer_core.solve.checks import check_box, check_choice, check_ics, check_int  # noqa: F401
from explorer_core.solve.tableaus import get_method, resolve_method
from explorer_core.system.params import ParameterError


@dataclass(frozen=True)
class Numerics:
    """How to integrate: method, tolerances, budgets. Validated on construction.

    ``method="auto"`` (the default, ``config.DEFAULT_METHOD``) is replaced on construction by the method that
    wins at ``rtol`` (:func:`~explorer_core.solve.tableaus.resolve_method`: vern9 at 1e-9..1e-13, else dop853).
    """

    method: str = config.DEFAULT_METHOD
    rtol: float = config.DEFAULT_RTOL
    atol: float = config.DEFAULT_ATOL
    steps_per_period: int = config.DEFAULT_STEPS_PER_PERIOD
    bound: float = config.DEFAULT_ESCAPE_BOUND
    max_steps: int = config.DEFAULT_MAX_STEPS_PER_PERIOD
    #: False runs dp5/dop853 at ``steps_per_period`` fixed steps (rk4 is always fixed).
    adaptive: bool = True
    #: Whether ``method`` was chosen by the "auto" rule (set on construction; not part of the value: two
    #: settings that run the same method compare equal): :meth:`loosened` chooses again only then.
    by_rule: bool = field(default=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        for name, lo, hi in (("rtol", 1e-15, 1.0), ("atol", 1e-300, 1e6)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi):
                raise ParameterError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        # "auto" becomes the concrete method here, so what is saved and shown says which method ran.
        if self.method == "auto":
            object.__setattr__(self, "by_rule", True)
        try:
            object.__setattr__(self, "method", resolve_method(self.method, self.rtol, bool(self.adaptive)))
        except ValueError as exc:
            raise ParameterError(str(exc)) from None
        for name, lo, hi in (("steps_per_period", 1, 10_000_000), ("max_steps", 10, 1_000_000_000)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
                raise ParameterError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
            object.__setattr__(self, name, int(v))
        b = self.bound
        if not (isinstance(b, int | float) and b > 0 and not math.isnan(b)):
            raise ParameterError(f"bound must be a positive number, got {b!r}")
        object.__setattr__(self, "bound", float(b))

    def kernel_kwargs(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "rtol": self.rtol,
            "atol": self.atol,
            "steps_per_period": self.steps_per_period,
            "bound": self.bound,
            "max_steps": self.max_steps,
            "adaptive": bool(self.adaptive) and get_method(self.method).adaptive,
        }

    def as_dict(self) -> dict[str, Any]:
        return dict(self.kernel_kwargs())

    def loosened(self, rtol: float, atol: float | None = None) -> Numerics:
        """These settings at another tolerance (``atol`` default: ``rtol``), the method chosen again by the
        "auto" rule if it chose this one (a map loosened from vern9 at 1e-12 to 1e-8 runs DOP853, as a user
        asking 1e-8 gets), else kept. The one way an analysis derives inner numerics from the user's."""
        return Numerics(
            method="auto" if self.by_rule else self.method,
            rtol=rtol,
            atol=rtol if atol is None else atol,
            steps_per_period=self.steps_per_period,
            bound=self.bound,
            max_steps=self.max_steps,
            adaptive=self.adaptive,
        )


def random_ics(n: int, box: Sequence[float], seed: int | None = 0) -> np.ndarray:
    """``n`` initial conditions uniform in ``box = (qmin, qmax, rmin, rmax)``, reproducible by ``seed``."""
    n = check_int("random", n, 1, config.MAX_TRAJECTORIES)
    box = check_box(box)
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(box[0], box[1], n), rng.uniform(box[2], box[3], n)])


#: The app's Accuracy control: "plot" (a picture's tolerance) or "high" (:data:`HIGH_RTOL` everywhere).
ACCURACIES = ("plot", "high")
HIGH_RTOL = 1e-12


def chosen_numerics(
    method: str,
    accuracy: str,
    own: Numerics | None = None,
    *,
    plot_rtol: float | None = None,
    bound: float | None = None,
    steps_per_period: int | None = None,
) -> tuple[Numerics, str]:
    """The numerics a computation runs with when the user chose ``method`` and ``accuracy``, and why: the one
    rule that takes the app's Method and Accuracy controls to every computation.

    ``own`` is the computation's default (its spec's; None: :class:`Numerics`' defaults). The method is the
    user's (``"auto"``: the rule at the tolerance). ``accuracy="high"``: rtol = atol = :data:`HIGH_RTOL`.
    ``"plot"``: ``plot_rtol`` for a picture of points (a section, a density image, an orbit diagram: the
    tolerance their pixels need), else ``own``'s tolerance (an exponent, an orbit, a manifold is a number or a
    curve, not pixels). ``bound`` and ``steps_per_period``: the page's, else ``own``'s. Returns the numerics and
    one line saying what ran and why.
    """
    check_choice("accuracy", accuracy, ACCURACIES)
    own = own or Numerics()
    if accuracy == "high":
        tol, why = HIGH_RTOL, "Accuracy high"
    elif plot_rtol is not None:
        tol, why = plot_rtol, "plot: the picture's tolerance"
    else:
        tol, why = own.rtol, "plot: its own tolerance, no picture's"
    numerics = Numerics(
        method=method,
        rtol=tol,
        atol=tol,
        steps_per_period=own.steps_per_period if steps_per_period is None else steps_per_period,
        bound=own.bound if bound is None else bound,
        max_steps=own.max_steps,
    )
    return numerics, f"{numerics.method} at rtol {numerics.rtol:.3g} ({why})"
