"""Maps of the plane in closed form that the continuation engine runs on (:class:`~.system.ContinuationMap`):
their bifurcation sets are known exactly, so they test the engine, the location of bifurcations, the normal-form
coefficients and the two-parameter curves without an integrator's error.

* :class:`Henon`: ``(x, y) -> (1 - a x^2 + y, b x)``. Its fixed points solve ``a x^2 + (1 - b) x - 1 = 0``: a
  fold at ``a = -(1 - b)^2 / 4`` (``x = 2 / (1 - b)``), a period doubling at ``a = 3 (1 - b)^2 / 4``
  (``det(DP + I) = 1 - b - 2 a x = 0``, ``x = (1 - b) / (2 a)``); the period-2 orbit doubles at
  ``a = (1 - b)^2 + (1 + b)^2 / 4`` (``1 + tr + det = 0`` of ``DP^2``, with ``x1 + x2 = (1 - b) / a``).
* :class:`DelayedLogistic`: ``(x, y) -> (a x (1 - y), (1 - c) x + c y)`` (``c = 0``: the delayed logistic map).
  The fixed point ``x = y = 1 - 1/a`` has at ``c = 0`` ``DP = [[1, 1 - a], [1, 0]]``: a Neimark-Sacker point at
  ``a = 2`` (``det = a - 1``), multipliers ``exp(+-i pi/3)``; in ``(a, c)`` the Neimark-Sacker curve ``a = 2``.
* :class:`FoldFlip`: an unfolding of the fold-flip point with a cusp, a generalised flip and a 1:2 resonance.
* :class:`NeimarkSacker`: a Neimark-Sacker normal form with its strong resonances and a Chenciner point.

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
    """``(x, y) -> (a x (1 - y), (1 - c) x + c y)`` (``c = 0``: the delayed logistic map): the fixed point
    ``x = y = 1 - 1/a`` has ``DP = [[1, 1 - a], [1 - c, c]]``, ``det = c + (a - 1)(1 - c)``, ``tr = 1 + c``: the
    Neimark-Sacker curve is ``a = 2`` for every ``c < 1``, with ``cos theta = (1 + c) / 2`` (R4 at ``c = -1``, R3
    at ``c = -2``, R2 at ``c = -3``, R1 at ``c = 1``)."""

    DEFAULTS: Mapping[str, float] = {"a": 1.5, "c": 0.0}

    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        a, c = v["a"], v["c"]
        y = np.array([a * x[0] * (1.0 - x[1]), (1.0 - c) * x[0] + c * x[1]])
        jac = np.array([[a * (1.0 - x[1]), -a * x[0]], [1.0 - c, c]])
        return y, jac, {"a": np.array([x[0] * (1.0 - x[1]), 0.0]), "c": np.array([0.0, x[1] - x[0]])}


class FoldFlip(ClosedFormMap):
    """``(x, y) -> (-(1 + a) x + x y + d x^3, y + b + c y^2 + y^3 + x^2)``, an unfolding of the fold-flip
    interaction (Kuznetsov, *Elements*, Sect. 9.6): the fixed points ``(0, y)``, ``b + c y^2 + y^3 = 0``, have the
    multipliers ``y - (1 + a)`` (a flip where ``y = a``: the curve ``b = -c a^2 - a^3``) and ``1 + 2 c y + 3 y^2``
    (a fold where ``y (2 c + 3 y) = 0``). Its codimension-two points: LPPD at ``a = b = 0``; on the flip curve R2
    where ``3 a^2 + 2 c a + 2 = 0`` and GPD where the flip coefficient ``d + 1 / (1 - mu2)`` vanishes; on the fold
    curve in ``(c, b)`` at ``y = -2 c / 3`` a cusp at ``c = 0``."""

    DEFAULTS: Mapping[str, float] = {"a": 0.5, "b": 0.0, "c": 1.0, "d": 0.0}

    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        a, b, c, d = v["a"], v["b"], v["c"], v["d"]
        p, q = x
        y = np.array([-(1.0 + a) * p + p * q + d * p**3, q + b + c * q**2 + q**3 + p**2])
        jac = np.array([[-(1.0 + a) + q + 3.0 * d * p**2, p], [2.0 * p, 1.0 + 2.0 * c * q + 3.0 * q**2]])
        return y, jac, {"a": np.array([-p, 0.0]), "b": np.array([0.0, 1.0]), "c": np.array([0.0, q**2]),
                        "d": np.array([p**3, 0.0])}  # fmt: skip


class NeimarkSacker(ClosedFormMap):
    """``z -> e^{i theta} z (1 + a + c |z|^2) + conj(z)^2`` in ``z = x + i y`` (Kuznetsov, *Elements*, Sect. 4.7, with
    a resonant-free quadratic term): the fixed point 0 has ``DP = (1 + a) R(theta)``, a Neimark-Sacker curve
    ``a = 0`` with the angle ``theta`` (strong resonances at ``theta = 0, pi, 2 pi / 3, pi / 2``) and the
    coefficient ``Re d = c - 1`` (``g21 = 2 e^{i theta} c``, ``g02 = 2``): a Chenciner point at ``c = 1``."""

    DEFAULTS: Mapping[str, float] = {"a": -0.1, "c": 0.5, "theta": 1.0}

    def step(self, x: np.ndarray, v: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        a, c, th = v["a"], v["c"], v["theta"]
        p, q = x
        co, si = math.cos(th), math.sin(th)
        m = 1.0 + a + c * (p * p + q * q)
        u, w = co * p - si * q, si * p + co * q
        y = np.array([m * u + p * p - q * q, m * w - 2.0 * p * q])
        jac = np.array([[2 * c * p * u + m * co + 2 * p, 2 * c * q * u - m * si - 2 * q],
                        [2 * c * p * w + m * si - 2 * q, 2 * c * q * w + m * co - 2 * p]])  # fmt: skip
        r2 = p * p + q * q
        return y, jac, {"a": np.array([u, w]), "c": np.array([r2 * u, r2 * w]), "theta": np.array([-m * w, m * u])}
