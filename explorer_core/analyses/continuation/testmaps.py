"""Maps of the plane in closed form that the continuation engine runs on (:class:`~.system.ContinuationMap`):
their bifurcation sets are known exactly, so they test the engine, the location of bifurcations, the normal-form
coefficients and the two-parameter curves without an integrator's error.

* :class:`Henon`: ``(x, y) -> (1 - a x^2 + y, b x)``. Its fixed points solve ``a x^2 + (1 - b) x - 1 = 0``: a
  fold at ``a = -(1 - b)^2 / 4`` (``x = 2 / (1 - b)``), a period doubling at ``a = 3 (1 - b)^2 / 4``
  (``det(DP + I) = 1 - b - 2 a x = 0``, ``x = (1 - b) / (2 a)``); the period-2 orbit doubles at
  ``a = (1 - b)^2 + (1 + b)^2 / 4`` (``1 + tr + det = 0`` of ``DP^2``, with ``x1 + x2 = (1 - b) / a``).
* :class:`DelayedLogistic`: ``(x, y) -> (a x (1 - y), x)``. The fixed point ``x = y = 1 - 1/a`` has
  ``DP = [[1, 1 - a], [1, 0]]``: a Neimark-Sacker point at ``a = 2`` (``det = a - 1``), multipliers
  ``exp(+-i pi/3)``.

``P^n``, ``DP^n`` and ``dP^n/dp`` are exact (the chain rule along the orbit); the derivatives of a test function
(:func:`~.system._defining`) are central differences of the exact ``DP^n``, as for the integrated map.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.system import FD_STEP, _Stop
from explorer_core.status import Status
from explorer_core.system.params import ParameterError


class ClosedFormMap(ABC):
    """A map of the plane ``P(x; values)`` given by :meth:`step` (its value, Jacobian and parameter derivatives);
    ``names`` are the continuation parameters (the point ``p`` of :class:`~.system.ContinuationMap`'s methods
    overrides their values). Subclasses name their parameters and defaults in ``DEFAULTS``."""

    DEFAULTS: Mapping[str, float] = {}

    def __init__(self, names: Sequence[str] = (), **values: float) -> None:
        unknown = [k for k in (*values, *names) if k not in self.DEFAULTS]
        if unknown:
            raise ParameterError(f"{type(self).__name__} has no parameter {unknown[0]!r} (it has "
                                 f"{', '.join(self.DEFAULTS)})")  # fmt: skip
        self.values = {k: float(values.get(k, v)) for k, v in self.DEFAULTS.items()}
        self.names = list(names)

    @abstractmethod
    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """``P(x)``, ``DP(x)`` and ``dP/dv_k`` for each parameter, at the values ``v``."""

    def as_dict(self) -> dict[str, Any]:
        return {"map": type(self).__name__, **self.values}

    def _at(self, p: Sequence[float]) -> dict[str, float]:
        v = dict(self.values)
        v.update({k: float(q) for k, q in zip(self.names, p, strict=True)})
        return v

    def _iterate(self, x: np.ndarray, v: Mapping[str, float], n: int, names: Sequence[str] = ()):
        """``P^n(x)``, ``DP^n``, the points ``P(x) .. P^n(x)`` and ``dP^n/dv_k`` for ``names`` (chain rule)."""
        x = np.asarray(x, dtype=float)
        a = np.eye(2)
        d = np.zeros((2, len(names)))
        pts = np.empty((n, 2))
        for i in range(n):
            y, j, dv = self.step(x, v)
            if not np.all(np.isfinite(y)) or not np.all(np.isfinite(j)):
                raise _Stop("the orbit of the map became non-finite", Status.NONFINITE)
            a = j @ a
            if names:
                d = j @ d + np.column_stack([dv[k] for k in names])
            x = y
            pts[i] = x
        return x, a, pts, d

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        end, a, pts, _ = self._iterate(x, self._at(p), n)
        return end, a, pts

    def fp(self, x: np.ndarray, p: Sequence[float], n: int, amp: float = 1.0) -> np.ndarray:
        return self._iterate(x, self._at(p), n, self.names)[3]

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False) -> tuple[Any, ...]:
        end, a, pts, fp = self._iterate(x, self._at(p), n, self.names)
        extra = None
        if dx:
            a_p = []
            for k in range(len(p)):
                delta = FD_STEP * (1.0 + abs(p[k]))
                q = [list(p), list(p)]
                q[0][k] += delta
                q[1][k] -= delta
                a_p.append((self.orbit(x, q[0], n)[1], self.orbit(x, q[1], n)[1], delta))
            hx = FD_STEP * (1.0 + float(np.abs(x).max()))
            a_x = [(self.orbit(x + hx * e, p, n)[1], self.orbit(x - hx * e, p, n)[1], hx) for e in np.eye(2)]
            extra = {"A_p": a_p, "A_x": a_x}
        return end, a, fp, None, pts, extra

    def jacobians(self, xs: np.ndarray, p: Sequence[float], n: int) -> np.ndarray:
        return np.array([self.orbit(x, p, n)[1] for x in np.asarray(xs, dtype=float)])

    def coarse(self) -> ClosedFormMap:
        return self  # exact: no less accurate version

    def over(self, names: Sequence[str]) -> ClosedFormMap:
        return type(self)(names, **self.values)

    def value(self, name: str) -> float:
        return self.values[name]


class Henon(ClosedFormMap):
    """``(x, y) -> (1 - a x^2 + y, b x)``: fold at ``a = -(1 - b)^2 / 4``, period doubling at ``a = 3 (1 - b)^2 / 4``,
    the period-2 orbit's at ``a = (1 - b)^2 + (1 + b)^2 / 4``."""

    DEFAULTS: Mapping[str, float] = {"a": 1.4, "b": 0.3}

    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        a, b = v["a"], v["b"]
        y = np.array([1.0 - a * x[0] ** 2 + x[1], b * x[0]])
        jac = np.array([[-2.0 * a * x[0], 1.0], [b, 0.0]])
        return y, jac, {"a": np.array([-(x[0] ** 2), 0.0]), "b": np.array([0.0, x[0]])}

    @staticmethod
    def fixed_point(a: float, b: float, sign: float = 1.0) -> np.ndarray:
        """The fixed point ``x = (-(1 - b) + sign sqrt((1 - b)^2 + 4 a)) / (2 a)``, ``y = b x``."""
        x = (-(1.0 - b) + sign * math.sqrt((1.0 - b) ** 2 + 4.0 * a)) / (2.0 * a)
        return np.array([x, b * x])


class DelayedLogistic(ClosedFormMap):
    """``(x, y) -> (a x (1 - y), x)``: the fixed point ``x = y = 1 - 1/a`` has a Neimark-Sacker point at ``a = 2``."""

    DEFAULTS: Mapping[str, float] = {"a": 1.5}

    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        a = v["a"]
        y = np.array([a * x[0] * (1.0 - x[1]), x[0]])
        jac = np.array([[a * (1.0 - x[1]), -a * x[0]], [1.0, 0.0]])
        return y, jac, {"a": np.array([x[0] * (1.0 - x[1]), 0.0])}
