"""Sweeping a parameter: which parameters can be swept, their values, and reading a period off section points.

Shared by the orbit diagrams (:mod:`explorer_core.analyses.bifurcation`), the charts of regimes
(:mod:`explorer_core.analyses.regimes`) and the continuation of periodic orbits.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from explorer_core import config
from explorer_core.solve.checks import check_int, check_range
from explorer_core.solve.recurrence import SWEEP, recurrence
from explorer_core.system.params import INERTIA_NAMES, ParameterError, Params

#: Parameters a diagram (or a chart of regimes) can sweep.
SWEEP_PARAMS = ("alpha", *INERTIA_NAMES, "g0", "g1", "g2", "omega")


def check_param(name: str) -> str:
    """Canonical name of a sweepable parameter (case-insensitive: ``Omega`` is ``omega``)."""
    for p in SWEEP_PARAMS:
        if str(name).strip().lower() == p.lower():
            return p
    raise ParameterError(f"cannot sweep {name!r}; choose one of {', '.join(SWEEP_PARAMS)}")


def sweep_values(rng: Sequence[float], n: int) -> np.ndarray:
    """``n`` equally spaced values over ``rng = (lo, hi)`` (both ends included)."""
    lo, hi = check_range("range", rng)
    n = check_int("n_values", n, 1, config.MAX_GRID * 16)
    return np.linspace(lo, hi, n) if n > 1 else np.array([lo])


def params_at(base: Params, name: str, value: float) -> Params | str:
    """``base`` with ``name = value``, or the reason the result is not a valid system."""
    try:
        return base.with_(**{name: float(value)})
    except ParameterError as exc:
        return str(exc)


def detect_period(points: np.ndarray, p_max: int, tol: float) -> int:
    """Smallest ``p <= p_max`` with ``|x_{k+p} - x_k| <= tol`` for every ``k`` of ``points``; 0 if none.

    ``points`` are consecutive section points after a transient, shape (m, 2); ``tol`` is absolute (in units of
    ``q``, ``r``): the rule :data:`~explorer_core.solve.recurrence.SWEEP` (``CHART`` for a tolerance relative
    to the points' largest ``|x|``).
    """
    return int(recurrence(points, SWEEP, tol=tol, p_max=p_max).period)
