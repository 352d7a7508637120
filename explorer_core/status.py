"""The one status vocabulary: how a trajectory, a pixel, a sweep value, a seed or a branch ended.

Every per-member outcome in the package is a :class:`Status` (as diffrax's one ``RESULTS`` enum): the
engine's codes 0-4 (the compiled kernels write them, so they never change), then what the analyses add
on top (Newton and correctors that do not converge, budgets, cancellation, undecided classifications,
refused parameters, work never started). Files carry the stable lower-case name (``Status.label``:
``"escaped"``), never a bare integer in JSON or CSV; an NPZ integer array of codes is written with
``status_names`` (:func:`status_names`, the name of code ``c`` is ``status_names[c]``) so a reader can
decode it without this package. ``word`` is what the app and the CLI print, ``meaning`` one line for
documentation.

The name <-> code table is pinned by ``tests/test_status.py``: changing it is deliberate (files written
before would be read wrongly).
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import IntEnum
from typing import Any

import numpy as np


class Status(IntEnum):
    """Outcome of one member (trajectory, pixel, sweep value, Newton seed, branch); anything but OK ended it early
    or without a verdict. Codes 0-4 are written by the engine's kernels."""

    # code, word (printed), meaning (documentation)
    OK = 0, "ok", "ran to its end (and, where there is one, reached a verdict)"
    ESCAPED = 1, "escaped", "|q| or |r| left the escape bound: noncompact motion"
    STEP_COLLAPSED = 2, "step collapsed", "the adaptive step fell below the round-off floor"
    TOO_MANY_STEPS = 3, "too many steps", "the step budget of one period ran out"
    NONFINITE = 4, "non-finite", "the field or the state became inf or NaN"
    NOT_CONVERGED = 5, "not converged", "Newton or a corrector did not converge"
    BUDGET = 6, "budget spent", "a point, level or iteration budget ran out before the end"
    CANCELLED = 7, "cancelled", "stopped by a cancel request before its end"
    UNDECIDED = 8, "undecided", "ran to its end but could not be classified"
    INVALID = 9, "invalid parameters", "the parameters do not define a system (refused)"
    NOT_RUN = 10, "not run", "no outcome yet: never started (cancelled, not reached) or still running"

    word: str
    meaning: str

    def __new__(cls, code: int, word: str, meaning: str) -> Status:
        obj = int.__new__(cls, code)
        obj._value_ = code
        obj.word = word
        obj.meaning = meaning
        return obj

    @property
    def label(self) -> str:
        """The stable name written in every file: the member's name in lower case (``"step_collapsed"``)."""
        return self.name.lower()

    @property
    def engine(self) -> bool:
        """True for the codes the integration engine itself writes (0-4)."""
        return self.value <= 4

    @classmethod
    def of(cls, value: Any) -> Status:
        """The status named or numbered by ``value``: a :class:`Status`, a code (int or numpy integer), or a
        name (``"escaped"``, ``"ESCAPED"``) or word (``"step collapsed"``). Raises ValueError naming the value."""
        if isinstance(value, Status):
            return value
        if isinstance(value, int | np.integer) and not isinstance(value, bool):
            try:
                return cls(int(value))
            except ValueError:
                raise ValueError(f"no status has the code {value!r}; codes are {CODES}") from None
        if isinstance(value, str):
            key = value.strip().lower()
            for s in cls:
                if key in (s.label, s.word):
                    return s
        raise ValueError(f"no status is named {value!r}; names are {', '.join(CODES.values())}")


#: The documentation table ``{code: name}`` (also written into NPZ files as ``status_names``).
CODES: dict[int, str] = {int(s): s.label for s in Status}


def status_names() -> np.ndarray:
    """The names indexed by code (``status_names()[c]`` is the name of code ``c``), for NPZ files."""
    return np.array([CODES[c] for c in range(len(CODES))])


def names(codes: Any) -> Any:
    """The names of an array of codes, as nested lists of the same shape (a plain string for a scalar)."""
    arr = np.asarray(codes)
    ints = arr.astype(np.int64) if np.isrealobj(arr) and arr.dtype.kind in "biuf" else None
    if ints is None:
        raise ValueError(f"status codes must be integers, got {arr.dtype} values")
    bad = (ints != arr) | (ints < 0) | (ints >= len(CODES))
    if np.any(bad):
        raise ValueError(f"not a status code: {arr[bad].ravel()[0].item()!r}; codes are {CODES}")
    return status_names()[ints].tolist()


def count_names(codes: Iterable[Any]) -> dict[str, int]:
    """How many members have each status, by name, in code order (only the statuses present)."""
    arr = np.asarray(list(codes) if not isinstance(codes, np.ndarray) else codes).ravel()
    if arr.size == 0:
        return {}
    values, n = np.unique(arr.astype(np.int64), return_counts=True)
    return {Status.of(int(v)).label: int(k) for v, k in zip(values, n, strict=True)}


def describe(codes: Iterable[Any]) -> str:
    """The statuses of members in words, for people (the CLI's and the app's lines): ``"7 ok, 2 escaped"``."""
    return ", ".join(f"{n} {Status.of(name).word}" for name, n in count_names(codes).items()) or "no members"
