"""Compile (or load from the on-disk cache) every numba kernel of the package, so no user waits for it.

The engine (:mod:`explorer_core.solve.rk`) has one kernel per system (the field, the tangent system, the
Lyapunov basis, the body's orientation) and block kind (lock-step blocks, or a block of one: the system
and "one" are compile-time constants); every method and mode runs on them. Each is compiled here through the same
public calls the analyses make (so with the same argument types: a readonly or non-contiguous array
would be another compilation). The other kernels: the model's scalar helpers (equilibria, the
``solve_ivp`` cross-checks), the manifolds' crossings, the basins' recurrence tables, the frozen field's
equilibria (solved, classified, matched into tracks). (The benchmark's
numbalsoda ``cfunc`` is no dispatcher; ``bilimovich bench`` compiles it, with numbalsoda, whose import
alone takes 10-25 s.) ``tests/test_worker.py`` walks the package's modules and fails if a kernel has no compiled
signature after :func:`warm_all`, so a new kernel cannot be forgotten here.

Used by ``bilimovich warmup``, the warm worker, the app server at start-up and the Dask workers.
"""

from __future__ import annotations

import math
import threading

_lock = threading.Lock()
_warmed = False


def _engine() -> None:
    """Every (system, block kind) kernel of the engine, as the analyses call it."""
    import numpy as np

    from explorer_core.solve import rk, tangent
    from explorer_core.solve.integrators import Batch, advance, body_start, coefficients, run
    from explorer_core.solve.numerics import Numerics
    from explorer_core.system.model import Model
    from explorer_core.system.params import Params

    model = Model(Params())
    ics = np.array([[0.1, 0.2], [0.3, 0.1]])
    numerics = Numerics()
    for block in (2, 1):  # lock-step blocks, then one trajectory per block
        advance(model, Batch.start(ics, 0.0, 2 * math.pi), 1, workers=1, block=block)
        advance(model, Batch.start(ics, 0.0, 2 * math.pi), 1, workers=1, block=block, method="taylor")
        coefs = coefficients(model, n=ics.shape[0])
        tangent.monodromy(coefs, ics, 1, model.params.t0, model.params.period, numerics, workers=1, block=block)
        lyap = tangent.start(ics, model.params.t0, model.params.period)
        tangent.advance_lyapunov(coefs, lyap, 1, numerics, workers=1, block=block)
        body = body_start(model.params, ics)  # the body's orientation
        run(rk.BODY, coefs, body, 1, samples=4, workers=1, block=block, **numerics.kernel_kwargs())


def _model() -> None:
    """The model's scalar kernels (equilibria's coefficients, the right-hand side for ``solve_ivp``)."""
    import numpy as np

    from explorer_core.system.model import Model, rhs
    from explorer_core.system.params import Params

    model = Model(Params())
    model.coefficients(0.0)  # forcing_g and coefficients_at on the model's own (readonly) tables
    work = np.empty((2, 6))
    rhs(model.num, model.gpc, model.den, np.ascontiguousarray(model.forcing), 0.0, 0.1, 0.2, work)


def warm_all() -> None:
    """Compile or load every kernel, once per process (later calls return at once)."""
    global _warmed
    with _lock:
        if _warmed:
            return
        from explorer_core.analyses import basins, equilibria, manifolds

        _engine()
        _model()
        manifolds.warmup()  # the crossing kernel (the growth runs on the engine)
        basins.warmup()  # the recurrence bookkeeping
        equilibria.warmup()  # the frozen field's equilibria, classified and tracked
        _warmed = True
