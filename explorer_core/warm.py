"""Compile (or load from the on-disk cache) every numba kernel of the package, so no user waits for it.

The engine (:mod:`explorer_core.solve.rk`) is one kernel for every method, system (sections, the
tangent system, the Lyapunov basis) and mode (adaptive, fixed, lock-step, per-member parameters): one
call compiles it; the other kernels find crossings of manifolds and keep the basins' recurrence
tables. Used by ``bilimovich warmup``, the app server at start-up and the Dask workers.
"""

from __future__ import annotations

import threading

_lock = threading.Lock()
_warmed = False


def warm_all() -> None:
    """Compile or load every kernel, once per process (later calls return at once)."""
    global _warmed
    with _lock:
        if _warmed:
            return
        from explorer_core.analyses import basins, manifolds
        from explorer_core.solve.integrators import warmup

        warmup()
        manifolds.warmup()  # the crossing kernel (the growth runs on the engine)
        basins.warmup()  # the recurrence bookkeeping
        _warmed = True
