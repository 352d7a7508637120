"""The parameters of the inhomogeneous Bilimovich system: inertia tensor, ``alpha`` and the forcing ``g(t)``.

:class:`Params` is validated on construction (finite values, a positive-definite tensor, a positive
forcing frequency); every boundary (command line, app, URL) builds one and reports its
:class:`ParameterError`, which names the bad value. Pure numpy: importing it costs no compiler.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields, replace
from fractions import Fraction
from typing import Any

import numpy as np

#: Names of the six independent inertia entries, in the order used everywhere.
INERTIA_NAMES = ("I11", "I22", "I33", "I12", "I13", "I23")


class ParameterError(ValueError):
    """A parameter set that does not define a valid Bilimovich system."""


#: The forcing phase must be resolved to this fraction of a period: beyond, doubles near ``t`` are so far
#: apart that the forcing is a staircase (a fixed-step or loose run returns it with status ok), and far
#: beyond, ``t + h == t`` and the integration freezes (t0 = 1e20: every point the initial one, status ok).
#: Below it an adaptive run that needs a step under the round-off floor says so (``step_collapsed``).
TIME_RESOLUTION = 1e-4


def check_time(name: str, t: float, period: float) -> None:
    """Refuse a time ``t`` whose doubles do not resolve the forcing phase (``ulp(t) > TIME_RESOLUTION T``)."""
    if not math.isfinite(t):  # t0 + (k + n) T overflowed
        raise ParameterError(f"{name} overflows double precision ({t}): ask for fewer periods or a smaller t0")
    spacing = math.ulp(abs(t))
    if spacing > TIME_RESOLUTION * abs(period):
        # the largest |t| whose doubles are TIME_RESOLUTION T apart
        limit = 2.0 ** (math.floor(52 + math.log2(TIME_RESOLUTION * abs(period))) + 1)
        raise ParameterError(
            f"{name} = {t:.6g} cannot be resolved in double precision: doubles there are {spacing:.3g} apart, "
            f"more than {TIME_RESOLUTION:g} of the forcing period {abs(period):.6g}; keep |{name}| below {limit:.3g}"
        )


#: pi to 90 digits, for :func:`reduce_time`: the forcing period ``2 pi / omega`` is irrational, and the ~1e12
#: periods in a resolvable ``t`` multiply the error of any pi they are subtracted with (a double's pi: 1e-4).
_PI = Fraction("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899862803482534211")


def reduce_time(t: float, omega: float) -> float:
    """``t`` less a whole number of forcing periods ``T = 2 pi / omega``: the same phase of ``g``, near 0.

    The remainder of the truncated division by the exact ``T`` (``t`` itself when ``|t| < T``), computed in
    exact rational arithmetic on the double ``t`` and rounded once: the engine's stage times ``t + c h`` then
    keep their digits whatever ``t`` (at ``t0 = 1e11`` they were rounded to 1.5e-5, an error of 1e-5 in the
    section for a tolerance of 1e-10, or a step collapse). A non-positive or non-finite ``omega`` (a constant
    forcing, a test's table) has no period: ``t`` is returned unchanged.
    """
    if t == 0.0 or not (math.isfinite(t) and math.isfinite(omega) and omega > 0.0):
        return t  # (0.0 and -0.0 are one key of the cache)
    if abs(t) * omega < _INSIDE:
        return t  # inside the first period (the model evaluated at a user's time: no rational arithmetic)
    return _reduce_time(t, omega)


#: ``|t| omega`` below this is inside the first period whatever the rounding of the product (2 pi less 1e-14).
_INSIDE = 2.0 * math.pi * (1.0 - 1e-14)


def reduce_times(ts: np.ndarray, omega: float) -> np.ndarray:
    """:func:`reduce_time` for times near one another (a grid over a period): each less the whole periods of
    the first, ``m T`` taken exactly (rational) and subtracted as a double-double, so each phase is exact to
    its last bit or two however large ``t`` and one rational reduction serves the whole array. The phases may
    reach past ``T`` (a grid over more than a period keeps its order)."""
    ts = np.asarray(ts, dtype=float)
    if ts.size == 0 or not (math.isfinite(omega) and omega > 0.0):
        return ts
    first = float(ts.flat[0])
    if not math.isfinite(first) or abs(first) * omega < _INSIDE:
        return ts
    m = math.trunc(Fraction(first) * Fraction(omega) / (2 * _PI))
    whole = m * 2 * _PI / Fraction(omega)
    hi = float(whole)
    lo = float(whole - Fraction(hi))
    return (ts - hi) - lo


@functools.lru_cache(maxsize=256)
def _reduce_time(t: float, omega: float) -> float:
    exact_t, period = Fraction(t), 2 * _PI / Fraction(omega)
    m = math.trunc(exact_t / period)
    return t if m == 0 else float(exact_t - m * period)


def _check_finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        raise ParameterError(f"{name} must be a finite number, got {shown}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return v


@dataclass(frozen=True)
class Params:
    """One parameter set of the system.

    Parameters
    ----------
    inertia : (I11, I22, I33, I12, I13, I23)
        Entries of the symmetric positive-definite inertia tensor.
    alpha : float
        Inhomogeneity of the constraint ``p - g q = alpha``.
    g0, g1, g2, omega : float
        Forcing ``g(t) = g0 + g1 cos(omega t) + g2 sin(omega t)``, ``omega > 0``.
    t0 : float
        Section phase: Poincare points are taken at ``t0 + k T``.
    """

    inertia: tuple[float, float, float, float, float, float] = (1.0, 2.0, 4.0, 0.0, 0.0, 0.0)
    alpha: float = 0.1
    g0: float = 0.0
    g1: float = 1.0
    g2: float = 0.0
    omega: float = 1.0
    t0: float = 0.0

    def __post_init__(self) -> None:
        ent = self.inertia
        if isinstance(ent, str | bytes):
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got the string {ent[:40]!r}")
        if isinstance(ent, np.ndarray) and ent.shape == (3, 3):
            ent = inertia_entries(ent)
        try:
            ent = tuple(ent)
        except TypeError:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {self.inertia!r}") from None
        if len(ent) != 6:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {len(ent)}: {ent!r}")
        ent = tuple(_check_finite(n, v) for n, v in zip(INERTIA_NAMES, ent, strict=True))
        object.__setattr__(self, "inertia", ent)
        for f in ("alpha", "g0", "g1", "g2", "omega", "t0"):
            object.__setattr__(self, f, _check_finite(f, getattr(self, f)))
        if self.omega <= 0.0:
            raise ParameterError(f"omega must be > 0 (forcing frequency), got {self.omega!r}")
        check_time("t0", self.t0, self.period)
        _check_positive_definite(self.inertia_matrix, ent)

    @property
    def inertia_matrix(self) -> np.ndarray:
        """The 3x3 inertia tensor."""
        i11, i22, i33, i12, i13, i23 = self.inertia
        return np.array([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]], dtype=float)

    @property
    def period(self) -> float:
        """Forcing period ``T = 2 pi / omega``."""
        return 2.0 * math.pi / self.omega

    @property
    def phase(self) -> float:
        """The section phase ``t0`` less a whole number of periods, exactly (:func:`reduce_time`): the same
        section times, where the engine's clock starts."""
        return reduce_time(self.t0, self.omega)

    @property
    def forcing(self) -> np.ndarray:
        """``(g0, g1, g2, omega)`` as the array the kernels take."""
        return np.array([self.g0, self.g1, self.g2, self.omega], dtype=float)

    def with_(self, **changes: Any) -> Params:
        """A copy with some fields changed; accepts inertia entries by name (``I11=...``)."""
        new = changes.pop("inertia", self.inertia)
        if isinstance(new, str | bytes) or not hasattr(new, "__len__"):
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {new!r}")
        ent = list(new)
        if len(ent) != 6:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {len(ent)}: {ent!r}")
        for i, n in enumerate(INERTIA_NAMES):
            if n in changes:
                ent[i] = changes.pop(n)
        return replace(self, inertia=tuple(ent), **changes)

    def as_dict(self) -> dict[str, Any]:
        """Plain-JSON form (inertia as a list)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["inertia"] = list(self.inertia)
        return d


def inertia_entries(matrix: Any, tol: float = 1e-12) -> tuple[float, ...]:
    """The six entries of a 3x3 tensor; rejects a non-symmetric one, naming the entry."""
    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3):
        raise ParameterError(f"inertia tensor must be 3x3, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ParameterError(f"inertia tensor must be finite, got {m.tolist()}")
    scale = max(1.0, float(np.max(np.abs(m))))
    for (i, j), name in (((0, 1), "I12"), ((0, 2), "I13"), ((1, 2), "I23")):
        if abs(m[i, j] - m[j, i]) > tol * scale:
            raise ParameterError(
                f"inertia tensor is not symmetric: {name}={float(m[i, j])!r} but I{j + 1}{i + 1}={float(m[j, i])!r}"
            )
    return (m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2])


def _check_positive_definite(m: np.ndarray, ent: tuple[float, ...]) -> None:
    eig = _eigenvalues(ent)
    # Relative threshold: a tensor this close to singular makes lambda's
    # denominator vanish and the reduced field meaningless.
    top = max(1.0, float(np.max(np.abs(eig))))
    if eig[0] <= 1e-12 * top:
        txt = ", ".join(f"{n}={v:g}" for n, v in zip(INERTIA_NAMES, ent, strict=True))
        if eig[0] > 0:  # positive definite, but the smallest moment is lost in the rounding of the largest
            why = f"its moments span more than 12 orders of magnitude (largest {top:.6g}): numerically singular"
            raise ParameterError(
                f"inertia tensor is too ill-conditioned ({txt}; smallest eigenvalue {eig[0]:.6g}); {why}"
            )
        bad = [n for n, v in zip(INERTIA_NAMES[:3], ent[:3], strict=True) if v <= 0]
        why = (f"a principal moment must be positive: {', '.join(bad)} <= 0" if bad
               else "off-diagonal entries are too large for the diagonal ones")  # fmt: skip
        raise ParameterError(
            f"inertia tensor is not positive definite ({txt}; smallest eigenvalue {eig[0]:.6g}); {why}"
        )


@functools.lru_cache(maxsize=1024)
def _eigenvalues(ent: tuple[float, ...]) -> np.ndarray:
    # A continuation in alpha or the forcing builds thousands of Params with one tensor.
    i11, i22, i33, i12, i13, i23 = ent
    out = np.linalg.eigvalsh(np.array([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]], dtype=float))
    out.setflags(write=False)
    return out
