"""Numerical settings and input checks shared by every call that integrates: the solving layer's boundary.

:class:`Numerics` (method, tolerances, budgets), validated on construction; the checks of initial
conditions, boxes and counts that the public functions, the CLI and the app apply to their inputs,
with messages that name the bad value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core import config
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

    def __post_init__(self) -> None:
        for name, lo, hi in (("rtol", 1e-15, 1.0), ("atol", 1e-300, 1e6)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi):
                raise ParameterError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        # "auto" becomes the concrete method here, so what is saved and shown says which method ran.
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


def random_ics(n: int, box: Sequence[float], seed: int | None = 0) -> np.ndarray:
    """``n`` initial conditions uniform in ``box = (qmin, qmax, rmin, rmax)``, reproducible by ``seed``."""
    n = check_int("random", n, 1, config.MAX_TRAJECTORIES)
    box = check_box(box)
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(box[0], box[1], n), rng.uniform(box[2], box[3], n)])


def check_box(box: Sequence[float], name: str = "box") -> tuple[float, float, float, float]:
    """Validate ``(qmin, qmax, rmin, rmax)``."""
    try:
        vals = tuple(float(v) for v in box)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be four numbers qmin,qmax,rmin,rmax, got {box!r}") from None
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise ParameterError(f"{name} must be four finite numbers qmin,qmax,rmin,rmax, got {box!r}")
    if not (vals[0] < vals[1] and vals[2] < vals[3]):
        raise ParameterError(f"{name} must have qmin < qmax and rmin < rmax, got {vals!r}")
    if not (math.isfinite(vals[1] - vals[0]) and math.isfinite(vals[3] - vals[2])):
        raise ParameterError(f"{name} is too wide: its width overflows, got {vals!r}")
    return vals  # type: ignore[return-value]


def check_int(name: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
        raise ParameterError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
    return int(v)


def check_ics(ics: Any) -> np.ndarray:
    """Initial conditions as a finite (n, 2) float array."""
    try:
        arr = np.asarray(ics, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"initial conditions must be real (q, r) pairs of equal shape, got {str(ics)[:60]}"
        ) from None
    if arr.ndim == 1 and arr.size == 2:
        arr = arr.reshape(1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
        raise ParameterError(f"initial conditions must be (q, r) pairs, got shape {arr.shape}")
    if arr.shape[0] > config.MAX_TRAJECTORIES:
        raise ParameterError(f"at most {config.MAX_TRAJECTORIES} initial conditions, got {arr.shape[0]}")
    bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
    if bad.size:
        raise ParameterError(f"initial condition {bad[0]} is not finite: {arr[bad[0]].tolist()}")
    return np.ascontiguousarray(arr)
