"""A server process's memory: freed memory given back to the system, and where the memory goes (a diagnostic).

**Giving back.** glibc keeps what the program frees in its arenas for the next allocation; it returns the top of
an arena to the system, not the free pages between blocks still in use. A classroom allocates and frees a few
hundred MB a minute (scenes, figures, documents) and the blocks that stay (a session's page, a cache) pin the pages
around them: in a long day (``benchmarks/long_day.py``, 30 students) the memory in use stayed at ~200 MB while the
freed-but-kept memory grew from 13 to 107 MB in 8 minutes and the RSS with it (+152 MB in an hour). :func:`start`
runs :func:`~explorer_core.allocator.give_back` every ``BILIMOVICH_TRIM_EVERY`` seconds (30; 0: never):
``malloc_trim(0)`` returns every free page of every arena (glibc >= 2.8), when more than :data:`TRIM_ABOVE_MB` is
kept. The pages come back on demand. (The command line's warm worker gives back after each job.)

**Where it goes.** Enabled by ``BILIMOVICH_MEMORY_LOG=FILE``: every ``BILIMOVICH_MEMORY_EVERY`` seconds (30) a
JSON line is appended to ``FILE.<pid>``: the RSS, what glibc's allocator holds (in use by the program, free but
kept, mapped), the objects the garbage collector tracks that were made after the page's first build
(``gc.freeze`` keeps the rest out of sight: :func:`app.pacing.page_built`) counted by type, the threads and the
trims. With ``BILIMOVICH_TRACEMALLOC=N`` (frames per trace) the lines also name the source lines whose
allocations grew most since the first sample. Nothing of this runs unless asked: it walks every object
(~50-200 ms held GIL), and on Python < 3.12 ``gc.get_objects()`` can hand out a tuple another thread is still
building (``tuple(generator)``), which then fails in that thread with "SystemError: ... bad argument to internal
function" (CPython gh-107137, fixed in 3.12): seen once in an hour-long day with this diagnostic on. A diagnostic,
never for a class.
"""

from __future__ import annotations

import collections
import gc
import json
import os
import threading
import time
from typing import Any

from explorer_core.allocator import TRIM_ABOVE_MB, TRIMS, _glibc, allocator, give_back, rss_mb

__all__ = ["TRIMS", "TRIM_ABOVE_MB", "allocator", "give_back", "objects_by_type", "rss_mb", "sample", "start"]

LOG_ENV, EVERY_ENV, TRACE_ENV = "BILIMOVICH_MEMORY_LOG", "BILIMOVICH_MEMORY_EVERY", "BILIMOVICH_TRACEMALLOC"
TRIM_ENV = "BILIMOVICH_TRIM_EVERY"
#: Seconds after the server's start before the allocations' baseline is taken (after the warm-up).
BASELINE_ENV = "BILIMOVICH_MEMORY_BASELINE"


def _module(cls: type) -> str:
    # Bokeh runs the app's file as a new module for each session (bokeh_app_<uuid>): one name for them all.
    name = str(getattr(cls, "__module__", "?"))
    return "bokeh_app_*" if name.startswith("bokeh_app_") else name


def objects_by_type(top: int = 25) -> tuple[int, list[tuple[str, int]], list[tuple[str, int]]]:
    """The garbage collector's unfrozen objects: how many, the ``top`` types by count, and the classes made more
    than once (by module and name: a class made again for each session is a leak's sign)."""
    objs = gc.get_objects()
    counts = collections.Counter(f"{type(o).__module__}.{type(o).__qualname__}" for o in objs)
    classes = collections.Counter(f"{_module(o)}.{o.__qualname__}" for o in objs if isinstance(o, type))
    n = len(objs)
    del objs
    return n, counts.most_common(top), [(k, c) for k, c in classes.most_common(top) if c > 1]


def sample(baseline: Any = None) -> dict[str, Any]:
    """One sample of the diagnostic (see the module's docstring); ``baseline``: a tracemalloc snapshot."""
    n, top, classes = objects_by_type()
    out: dict[str, Any] = {"t": time.time(), "rss": rss_mb(), "allocator": allocator(), "objects": n, "types": top}
    out["classes"] = classes
    out["threads"] = threading.active_count()
    out["trims"] = dict(TRIMS)
    try:
        import tracemalloc

        if tracemalloc.is_tracing():
            snap = tracemalloc.take_snapshot()
            out["traced_mb"] = tracemalloc.get_traced_memory()[0] / 2**20
            if baseline is not None:
                diff = snap.compare_to(baseline, "traceback" if tracemalloc.get_traceback_limit() > 1 else "lineno")
                out["grew"] = [
                    {"kb": round(d.size_diff / 1024, 1), "n": d.count_diff, "where": [str(f) for f in d.traceback]}
                    for d in diff[:15]
                ]
            out["_snapshot"] = snap
    except Exception as e:  # a diagnostic must never stop the server
        out["trace_error"] = repr(e)
    return out


_started = threading.Lock()


def start() -> None:
    """In this process, once: give freed memory back every ``BILIMOVICH_TRIM_EVERY`` s, and sample the diagnostic
    if ``BILIMOVICH_MEMORY_LOG`` is set (see the module's docstring)."""
    if not _started.acquire(blocking=False):
        return
    trim_every = float(os.environ.get(TRIM_ENV, "30") or 0)
    if trim_every > 0 and _glibc()[1] is not None:

        def trimming() -> None:
            while True:
                time.sleep(trim_every)
                give_back()

        threading.Thread(target=trimming, name="memory-give-back", daemon=True).start()
    path = os.environ.get(LOG_ENV)
    if not path:
        return
    every = float(os.environ.get(EVERY_ENV, "30"))
    frames = int(os.environ.get(TRACE_ENV, "0") or 0)
    if frames > 0:
        import tracemalloc

        tracemalloc.start(frames)
    after = time.monotonic() + float(os.environ.get(BASELINE_ENV, "0"))

    def sampling() -> None:
        baseline = None
        out = f"{path}.{os.getpid()}"
        while True:
            time.sleep(every)
            s = sample(baseline)
            snap = s.pop("_snapshot", None)
            if baseline is None and time.monotonic() >= after:
                baseline = snap
            with open(out, "a") as f:
                f.write(json.dumps(s) + "\n")

    threading.Thread(target=sampling, name="memory-log", daemon=True).start()
