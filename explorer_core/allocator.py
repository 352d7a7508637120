"""Freed memory given back to the system (glibc), for every long-lived process: the app's server and the warm worker.

glibc keeps what the program frees in its arenas for the next allocation; it returns the top of an arena to the
system, not the free pages between blocks still in use, so a long-lived process that allocates and frees a lot
(a classroom's scenes, a worker's 10^7-point image) keeps its high-water mark while the blocks that stay pin the
pages around them. :func:`give_back` calls ``malloc_trim(0)``, which returns every free page of every arena
(glibc >= 2.8), when more than :data:`TRIM_ABOVE_MB` is kept; the pages come back on demand. Nothing here where the
C library is not glibc (musl, macOS): :func:`allocator` is None and :func:`give_back` returns 0.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os
import time
from typing import Any

#: Free memory kept by the allocator (MB) above which :func:`give_back` trims (below it a trim gains little).
TRIM_ABOVE_MB = 16.0


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()
    ]


@functools.cache
def _glibc() -> tuple[Any, Any]:
    """glibc's ``mallinfo2`` and ``malloc_trim`` (None each where the C library has none: musl, macOS)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None, None
    info, trim = getattr(libc, "mallinfo2", None), getattr(libc, "malloc_trim", None)
    if info is not None:
        info.restype, info.argtypes = _MallInfo2, []
    if trim is not None:
        trim.restype, trim.argtypes = ctypes.c_int, [ctypes.c_size_t]
    return info, trim


def allocator() -> dict[str, float] | None:
    """glibc's view in MB: ``in_use`` (allocated and not freed, heap and mapped), ``held_free`` (freed, kept in
    the arenas), ``mapped`` (large blocks mapped on their own); None where glibc has no ``mallinfo2``."""
    info = _glibc()[0]
    if info is None:
        return None
    m = info()
    mb = 1 / 2**20
    return {"in_use": (m.uordblks + m.hblkhd) * mb, "held_free": m.fordblks * mb, "mapped": m.hblkhd * mb}


#: What :func:`give_back` did in this process: trims, seconds spent, MB of RSS returned.
TRIMS = {"trims": 0, "seconds": 0.0, "returned_mb": 0.0}


def give_back(above_mb: float = TRIM_ABOVE_MB) -> float:
    """Return the allocator's free pages to the system if it keeps more than ``above_mb``; the RSS returned (MB).

    ctypes releases the GIL for the call: the event loop and the jobs go on (an allocation meanwhile waits for
    its arena's lock, a few ms)."""
    info, trim = _glibc()
    if trim is None:
        return 0.0
    if info is not None and info().fordblks < above_mb * 2**20:
        return 0.0
    t0, before = time.perf_counter(), rss_mb()
    trim(0)
    returned = max(0.0, before - rss_mb())
    TRIMS["trims"] += 1
    TRIMS["seconds"] += time.perf_counter() - t0
    TRIMS["returned_mb"] += returned
    return returned


def rss_mb(pid: int | str = "self") -> float:
    """The resident set of process ``pid`` (this one by default) in MB, from ``/proc`` (Linux)."""
    with open(f"/proc/{pid}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
