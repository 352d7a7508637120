"""The one module of input checks: every boundary (specs, the CLI, the app, URLs) validates through these.

Each check takes the option's name and the value, returns the value in its canonical type (a plain ``int`` or
``float``, a tuple) and raises :class:`~explorer_core.system.params.ParameterError` with a message that names
the option and the value it refused (scipy's ``_ivp/common.py`` is the model: one validators module, every
solver calling it). The specs' fields name their check (:mod:`explorer_core.solve.options`), so a check is
written once and read by the builder, the command line's help and the app's widgets alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from explorer_core import config
from explorer_core.system.params import ParameterError

_REAL = (int, float, np.integer, np.floating)


def check_int(name: str, v: Any, lo: int, hi: int) -> int:
    """A whole number (not a bool, not a float) in ``[lo, hi]``, as a plain ``int``."""
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
        raise ParameterError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
    return int(v)


def check_optional_int(name: str, v: Any, lo: int, hi: int) -> int | None:
    """None, or :func:`check_int`."""
    return None if v is None else check_int(name, v, lo, hi)


def check_number(name: str, v: Any, lo: float = -math.inf, hi: float = math.inf) -> float:
    """A finite real number (not a bool) in ``[lo, hi]``, as a plain ``float``."""
    if isinstance(v, bool) or not isinstance(v, _REAL) or not math.isfinite(v) or not lo <= v <= hi:
        within = "" if (lo, hi) == (-math.inf, math.inf) else f" in [{lo:g}, {hi:g}]"
        raise ParameterError(f"{name} must be a finite number{within}, got {v!r}")
    return float(v)


def parse_finite(name: str, v: Any) -> float:
    """A finite number from a number or a text (a URL value, a time given as text), as a plain ``float``."""
    try:
        x = float(v)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{name} must be a number, got {str(v)[:40]!r}") from None
    if not math.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {str(v)[:40]!r}")
    return x


def check_positive(name: str, v: Any) -> float:
    """A positive finite number, as a plain ``float``."""
    if isinstance(v, bool) or not isinstance(v, _REAL) or not math.isfinite(v) or v <= 0:
        raise ParameterError(f"{name} must be a positive finite number, got {v!r}")
    return float(v)


def check_fraction(name: str, v: Any) -> float:
    """A number in the open interval ``(0, 1)`` (a relative tolerance, a ratio), as a plain ``float``."""
    if isinstance(v, bool) or not isinstance(v, _REAL) or not 0 < v < 1:
        raise ParameterError(f"{name} must be in (0, 1), got {v!r}")
    return float(v)


def check_choice(name: str, v: Any, choices: Sequence[str]) -> str:
    """One of ``choices`` (strings)."""
    if not isinstance(v, str) or v not in choices:
        raise ParameterError(f"{name} must be one of {', '.join(choices)}, got {v!r}")
    return v


def check_bool(name: str, v: Any) -> bool:
    """True or False (numpy's bool too); not 0/1, not a string."""
    if not isinstance(v, bool | np.bool_):
        raise ParameterError(f"{name} must be True or False, got {v!r}")
    return bool(v)


def check_range(name: str, value: Any, *, increasing: bool = True, what: str = "lo,hi") -> tuple[float, float]:
    """Two finite numbers with a finite width: ``lo < hi`` (``increasing``), or any two different numbers
    (a continuation's range runs either way, from where the orbit is seeded)."""
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be two numbers {what}, got {value!r}") from None
    if increasing:
        if not (math.isfinite(a) and math.isfinite(b) and a < b):
            raise ParameterError(f"{name} must be finite with lo < hi, got {value!r}")
    elif not (math.isfinite(a) and math.isfinite(b)):
        raise ParameterError(f"{name} must be two finite numbers {what} (a finite width), got {value!r}")
    if not math.isfinite(b - a):
        raise ParameterError(f"{name} is too wide: its width overflows, got {value!r}")
    if not increasing and a == b:
        raise ParameterError(f"{name} must be two different numbers, got {value!r}")
    return a, b


#: The largest seed a random draw takes (numpy's generators accept any non-negative integer; the command line's).
MAX_SEED = 2**63 - 1


def check_seed(v: Any, name: str = "seed") -> int:
    """A random draw's seed: a whole number in ``[0, MAX_SEED]``."""
    return check_int(name, v, 0, MAX_SEED)


def check_ints(name: str, value: Any, n: int, lo: int, hi: int, what: str = "NX,NY") -> tuple[int, ...]:
    """``n`` whole numbers each in ``[lo, hi]`` (a grid ``NX,NY``, a pixel size ``W,H``)."""
    try:
        vals = tuple(value)
    except TypeError:
        raise ParameterError(f"{name} must be {n} integers {what}, got {value!r}") from None
    if len(vals) != n or not all(not isinstance(v, bool) and isinstance(v, int | np.integer) for v in vals):
        raise ParameterError(f"{name} must be {n} integers {what}, got {value!r}")
    if not all(lo <= v <= hi for v in vals):
        raise ParameterError(f"{name} must be {n} integers {what} each in [{lo}, {hi}], got {value!r}")
    return tuple(int(v) for v in vals)


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


def check_optional_box(box: Any, name: str = "box") -> tuple[float, float, float, float] | None:
    """None, or :func:`check_box`."""
    return None if box is None else check_box(box, name)


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


def check_point(name: str, value: Any, bound: float = math.inf) -> tuple[float, float]:
    """One finite point ``(q, r)`` with ``|q|, |r| <= bound`` (a seed inside the escape bound)."""
    x = check_ics(value)
    if x.shape[0] != 1:
        raise ParameterError(f"{name} must be one point (q, r), got {x.shape[0]}")
    q, r = (float(v) for v in x[0])
    if max(abs(q), abs(r)) > bound:
        raise ParameterError(f"{name} {q:g},{r:g} is outside the escape bound {bound:g}")
    return q, r
