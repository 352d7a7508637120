"""The one place files are written: CSV, JSON, NPZ/NPY, pictures, each at exactly the path given.

Every file reads back with ``csv``/``numpy``/``json``: numbers are written as numbers (``repr`` of a Python
float, the shortest text that reads back to the same double), never as ``np.float64(...)`` reprs.

CSV cells: ``None`` is an empty field; NaN is ``nan`` and infinities ``inf`` / ``-inf`` (both read back as
such by ``float`` and ``numpy.genfromtxt``, where an empty field reads as NaN too); booleans are ``0`` / ``1``.
JSON: numpy scalars and arrays become numbers and lists, dataclasses their fields (or ``as_dict()``), complex
numbers ``[re, im]``, and a NaN or infinite float ``null`` (JSON has no NaN).
NPZ/NPY: written through an open file, so numpy never appends a suffix of its own.

:func:`check_output` is called before any work starts: a path whose suffix does not match what will be
written, or that cannot be written, is refused with one line naming it.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
from collections.abc import Callable, Iterable, Sequence
from typing import Any, BinaryIO

import numpy as np


class OutputError(ValueError):
    """An output path that will not hold what is written (wrong suffix, missing folder, not writable)."""


def check_output(path: str, allowed_suffixes: Sequence[str], option: str = "--out") -> str:
    """Refuse ``path`` before any work if it does not end in one of ``allowed_suffixes`` or cannot be written.

    Writability is tried, not guessed: the file is opened for append (and removed again if this created it),
    which also catches read-only file systems and ``root`` writing into ``/proc``. Returns ``path``.
    """
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f"{option} must be a file name, got {text!r}")
    suffixes = tuple(s.lower() for s in allowed_suffixes)
    if suffixes and not text.lower().endswith(suffixes):
        raise OutputError(f"{option} must end in {' or '.join(suffixes)}, got {text!r}")
    folder = os.path.dirname(os.path.abspath(text))
    if not os.path.isdir(folder):
        raise OutputError(f"{option} {text}: the directory {folder} does not exist")
    if os.path.isdir(text):
        raise OutputError(f"{option} is a directory: {text}")
    existed = os.path.exists(text)
    try:
        with open(text, "ab"):
            pass
    except OSError as exc:
        raise OutputError(f"{option} cannot be written: {text} ({exc.strerror or exc})") from None
    if not existed:
        os.remove(text)
    return text


# --- plain values ----------------------------------------------------------------------------------------


def plain(obj: Any) -> Any:
    """``obj`` as plain Python data for JSON: numbers, strings, lists, dicts, None (NaN/inf -> None)."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (complex, np.complexfloating)):
        return [plain(obj.real), plain(obj.imag)]
    if isinstance(obj, np.ndarray):
        return [plain(v) for v in obj.tolist()] if obj.ndim else plain(obj.item())
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [plain(v) for v in obj]
    if hasattr(obj, "as_dict"):
        return plain(obj.as_dict())
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"cannot write a {type(obj).__name__} as JSON")


def dumps(obj: Any) -> str:
    """One line of strict JSON (no NaN), numpy and dataclasses converted by :func:`plain`."""
    return json.dumps(plain(obj), separators=(",", ": "), allow_nan=False)


def cell(value: Any) -> Any:
    """One CSV cell: a number as a number (round-trip ``repr``), None empty, text as text."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return repr(float(value))  # 'nan', 'inf', '-inf' for the non-finite
    if isinstance(value, (complex, np.complexfloating)):
        raise TypeError("write the real and imaginary parts of a complex number as two columns")
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return cell(value.item())
    return str(value)


# --- files -----------------------------------------------------------------------------------------------


def write_csv(path: str, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> int:
    """Write ``header`` and ``rows`` (cells by :func:`cell`) to exactly ``path``; returns the row count."""
    n = 0
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(header))
        for row in rows:
            if len(row) != len(header):
                raise ValueError(f"CSV row {n} has {len(row)} cells for {len(header)} columns")
            w.writerow([cell(v) for v in row])
            n += 1
    return n


def write_json(path: str, obj: Any) -> None:
    """``obj`` as indented strict JSON at exactly ``path``."""
    with open(path, "w") as fh:
        json.dump(plain(obj), fh, indent=1, allow_nan=False)
        fh.write("\n")


def write_npz(path: str, **arrays: Any) -> None:
    """A compressed ``.npz`` at exactly ``path`` (numpy appends ``.npz`` to a bare name; a file handle not)."""
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def write_npy(path: str, array: Any) -> None:
    """One array as ``.npy`` at exactly ``path``."""
    with open(path, "wb") as fh:
        np.save(fh, np.asarray(array))


def write_through(path: str, writer: Callable[[BinaryIO], Any]) -> Any:
    """Let a result's own ``to_npz``-style writer fill exactly ``path`` (it gets an open binary file)."""
    with open(path, "wb") as fh:
        return writer(fh)


def write_by_suffix(path: str, writers: dict[str, Callable[[str], Any]], what: str = "result") -> dict[str, Any]:
    """Write ``path`` with the writer of its suffix (``{".csv": fn, ".json": fn, ...}``, each ``fn(path)``).

    The one shape of a result's ``write(path)``: a suffix it has no writer for is refused with one line
    naming the ones it has (the command line refuses it before any work, :func:`check_output`). Returns
    what the CLI reports: ``{"path": path}``, with ``"rows"`` when the writer returns a row count.
    """
    text = os.fspath(path)
    for suffix, writer in writers.items():
        if text.lower().endswith(suffix):
            rows = writer(text)
            return (
                {"path": text, "rows": rows} if isinstance(rows, int) and not isinstance(rows, bool) else {"path": text}
            )
    raise OutputError(f"a {what} is written as {' or '.join(writers)}, got {text!r}")
