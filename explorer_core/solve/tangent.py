"""The tangent system: the field with its variational equations, a derived system run by the one engine.

State ``(q, r, Phi[:, 0], Phi[:, 1], s)``: ``q' = Q``, ``r' = R``, ``Phi' = J(q, r, t) Phi`` with the
**exact** Jacobian (``Q``, ``R`` are quadratic in ``(q, r)``, so ``J`` is affine in them) and
``s' = dQ/dq + dR/dr``. The engine (:mod:`explorer_core.solve.rk`) integrates it exactly like the field,
with error control on every component, landing exactly on the section times; analyses only ask it for
what they need (as DynamicalSystemsBase's ``TangentDynamicalSystem``):

* :func:`monodromy`: ``P^n(x)``, the derivative ``DP^n(x) = Phi(t0 + n T)`` from ``Phi = I``, and
  ``int div dt`` over the ``n`` periods (Liouville: ``det DP^n = exp(int div dt)``) -- Newton on the
  map, multipliers of periodic orbits, continuation;
* :func:`advance_lyapunov`: the basis re-orthonormalised at every section time (and inside a period when
  it becomes ill-conditioned), with ``log R_ii`` and ``int div`` per period -- the Lyapunov spectrum.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from explorer_core.solve import rk
from explorer_core.solve.integrators import Batch, run, run_at
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.rk import LYAPUNOV, TANGENT, Status
from explorer_core.system.params import Params

#: Components of the tangent state: q, r, the 2x2 matrix Phi by columns (v1 = (y2, y3), v2 = (y4, y5)), int div.
NSTATE = rk.STATE_SIZE[TANGENT]


def start(ics: np.ndarray, t0: float, period: float, k: int = 0) -> Batch:
    """A batch of tangent states at ``ics`` with ``Phi = I`` and ``int div = 0``."""
    batch = Batch.start(ics, t0, period, k=k, dim=NSTATE)
    batch.y[:, 2] = 1.0  # v1 = e_q, v2 = e_r
    batch.y[:, 5] = 1.0
    return batch


def advance_lyapunov(
    coefs: rk.Coefficients,
    batch: Batch,
    n_periods: int,
    numerics: Numerics,
    workers: int | None = None,
    block: int = 1,
    store: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Advance a tangent batch by ``n_periods`` periods, re-orthonormalising ``Phi`` (Lyapunov spectrum).

    ``block = 1`` (the default) gives every member its own step sequence.

    Returns
    -------
    logs : (n, n_periods, 2) ``log R_11, log R_22`` of the QR factorisation of each period's ``Phi``
    divs : (n, n_periods) the divergence integral over each period
    points : (n, n_periods, 2) section points
    npts : (n,) periods completed by each trajectory in this call
    """
    rec, npts = run(LYAPUNOV, coefs, batch, n_periods, workers=workers, block=block, store=store,
                    **numerics.kernel_kwargs())  # fmt: skip
    return rec[..., 2:4], rec[..., 4], rec[..., :2], npts


@dataclass(frozen=True)
class Monodromy:
    """``P^n`` and its derivative at a batch of points (see :func:`monodromy`).

    ``end`` (m, 2) ``P^n(x)``; ``matrix`` (m, 2, 2) ``DP^n(x)``; ``div`` (m,) ``int div dt`` over the ``n``
    periods; ``points`` (m, n, 2) the section points ``P(x) ... P^n(x)``; ``status`` (m,)
    :class:`~explorer_core.solve.rk.Status` (anything but OK: the values are not data); ``nsteps`` (m,).
    """

    end: np.ndarray
    matrix: np.ndarray
    div: np.ndarray
    points: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return self.status == Status.OK

    def member(self, j: int) -> Monodromy:
        """Point ``j`` alone (arrays of length one, copied)."""
        s = slice(j, j + 1)
        return Monodromy(*(np.array(a[s]) for a in (self.end, self.matrix, self.div, self.points, self.status,
                                                     self.nsteps)))  # fmt: skip


def monodromy(
    coefs: rk.Coefficients,
    x: np.ndarray,
    n_periods: int,
    t0: float,
    period: float,
    numerics: Numerics,
    *,
    workers: int | None = None,
    block: int = 1,
) -> Monodromy:
    """``P^n(x)``, ``DP^n(x)`` and ``int div dt`` for every row of ``x`` (m, 2), by the tangent system.

    ``coefs`` holds one parameter set for all points or one row per point (``coefs.row``), e.g. the
    points of a continuation at different parameter values. ``block > 1`` integrates that many points
    in lock-step (each still meets the tolerance).
    """
    batch = start(np.asarray(x, dtype=float).reshape(-1, 2), t0, period)
    rec, npts = run(TANGENT, coefs, batch, int(n_periods), workers=workers, block=block, **numerics.kernel_kwargs())
    y = batch.y
    return Monodromy(y[:, :2].copy(), _matrix(y), y[:, 6].copy(), rec[..., :2].copy(), batch.status.copy(),
                     batch.nsteps.copy())  # fmt: skip


def monodromy_at(
    params: Sequence[Params],
    x: np.ndarray,
    n_periods: int,
    numerics: Numerics,
    *,
    workers: int | None = None,
    block: int = 32,
) -> Monodromy:
    """:func:`monodromy` of point ``x[i]`` under ``params[i]`` (one parameter set each, or one for all).

    Grouped and batched as :func:`explorer_core.solve.integrators.run_at`: members that share the section
    times go in lock-step blocks with per-member coefficients (finite differences in a parameter see one
    step sequence).
    """
    x = np.asarray(x, dtype=float).reshape(-1, 2)
    y0 = start(x, 0.0, 1.0).y
    y, rec, status, nsteps = run_at(TANGENT, params, y0, int(n_periods), workers=workers, block=block,
                                    **numerics.kernel_kwargs())  # fmt: skip
    return Monodromy(y[:, :2].copy(), _matrix(y), y[:, 6].copy(), rec[..., :2].copy(), status, nsteps)


def _matrix(y: np.ndarray) -> np.ndarray:
    # Phi with columns v1 = (y2, y3), v2 = (y4, y5), shape (m, 2, 2): rows (y2, y4) and (y3, y5), a new array
    return y[:, _PHI_ROWS].reshape(-1, 2, 2)


_PHI_ROWS = np.array([2, 4, 3, 5])
