"""Lyapunov spectrum of the stroboscopic map and its Kaplan-Yorke dimension.

The paper (Figs. 4 and 8B) reports three exponents ``Lambda_1, Lambda_2,
Lambda_3 = 0`` of the autonomous 3-D form (eq-a3) ``q' = Q, r' = R, s' = 1``:
``Lambda_3 = 0`` belongs to the time direction ``s``; ``Lambda_1, Lambda_2``
are the exponents of the ``(q, r)`` flow. We compute them by the standard
method (Benettin et al. 1980; Parker & Chua 1989, ch. 8):

* the variational equations ``Phi' = J(q, r, t) Phi`` with the **exact**
  Jacobian (``Q``, ``R`` are quadratic in ``(q, r)``, so ``J`` is affine in
  ``(q, r)`` with the same time-dependent coefficient table as the field) are
  integrated together with the trajectory by the same embedded Runge-Kutta
  pair as sections (DOP853 by default), with error control on the state **and**
  on the tangent vectors, landing exactly on the section times ``t0 + k T``;
* at every section time ``Phi`` is re-orthonormalised (Gram-Schmidt, i.e. a QR
  factorisation ``Phi = Q R`` with ``R_ii > 0``) and ``log R_ii`` accumulated;
  inside a period only if the tangent vectors become nearly parallel (strong
  contraction, e.g. along the noncompact curves), which leaves the product of
  the ``R`` factors -- hence the per-period values -- unchanged;
* the divergence ``dQ/dq + dR/dr`` is integrated as an extra state. Liouville's
  formula ``det Phi = exp(int div dt)`` makes ``Lambda_1 + Lambda_2`` equal to
  its time average: a built-in consistency check of the tangent integration.

Units. Exponents are **per unit time** ``t`` (the paper's time; the period is
``T = 2 pi / omega``, ``2 pi`` for the paper's ``g = cos t``). The exponents of
the Poincare map *per iteration* are these times ``T``; both are reported.

The Kaplan-Yorke (Lyapunov) dimension of the section attractor is
``D = 1 + Lambda_1 / |Lambda_2|`` when ``Lambda_1 >= 0 > Lambda_1 + Lambda_2``
(the paper's formula); ``D = 0`` when ``Lambda_1 < 0`` (a stable cycle) and
``D = 2`` when the map does not contract area. The attractor of the 3-D flow
has dimension ``D + 1`` (the time direction adds one).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np

from explorer_core import config
from explorer_core.solve.integrators import Batch, Status, advance, get_method
from explorer_core.solve.section import Numerics, check_ics
from explorer_core.system.model import Model, ParameterError, Params, coefficients_at, eval_quadratic, forcing_g

#: Components of the integrated state: q, r, the 2x2 tangent matrix by columns
#: (v1 = (y2, y3), v2 = (y4, y5)) and the divergence integral over the period.
NSTATE = 7
_OK, _ESCAPED, _COLLAPSED, _TOO_MANY, _NONFINITE = (int(s) for s in Status)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = config.SAFETY, config.MIN_FACTOR, config.MAX_FACTOR
_EPS = float(np.finfo(float).eps)
#: Inside a period the basis is re-orthonormalised as well when the sine of the
#: angle between the tangent vectors drops below this (see ``_ill_conditioned``).
REORTHONORMALISE = 1e-2
#: Default size of the random offsets of ensemble members (relative to 1 + |ic|).
ENSEMBLE_OFFSET = 1e-3

_jit = nb.njit(nogil=True, cache=True, error_model="numpy")


@_jit
def variational_rhs(num, gpc, den, forcing, t, y, out, work) -> None:
    """Right-hand side of the state, the tangent matrix and the divergence integral.

    ``y = (q, r, Phi[:, 0], Phi[:, 1], s)``; ``out`` receives ``(Q, R, J Phi, div)``
    with the exact Jacobian ``J`` of the quadratic field (affine in ``(q, r)``).
    ``work`` is a (>= 2, 6) scratch array for the coefficients at ``t``.
    """
    g, gp = forcing_g(forcing, t)
    coefficients_at(num[:2], gpc[:2], den, g, gp, work)
    q = y[0]
    r = y[1]
    out[0] = eval_quadratic(work, 0, q, r)
    out[1] = eval_quadratic(work, 1, q, r)
    j00 = work[0, 1] + 2.0 * work[0, 3] * q + work[0, 4] * r
    j01 = work[0, 2] + work[0, 4] * q + 2.0 * work[0, 5] * r
    j10 = work[1, 1] + 2.0 * work[1, 3] * q + work[1, 4] * r
    j11 = work[1, 2] + work[1, 4] * q + 2.0 * work[1, 5] * r
    out[2] = j00 * y[2] + j01 * y[3]
    out[3] = j10 * y[2] + j11 * y[3]
    out[4] = j00 * y[4] + j01 * y[5]
    out[5] = j10 * y[4] + j11 * y[5]
    out[6] = j00 + j11


@_jit
def gram_schmidt(phi: np.ndarray) -> tuple[float, float]:
    """Orthonormalise the columns of the 2x2 tangent matrix in place (``Phi = Q R``).

    ``phi`` is ``(v1x, v1y, v2x, v2y)``; on return it holds ``Q`` and the
    function returns ``(R_11, R_22)`` (both >= 0; 0 signals a degenerate basis).
    """
    r11 = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1])
    if not (r11 > 0.0) or not math.isfinite(r11):
        return 0.0, 0.0
    e1x = phi[0] / r11
    e1y = phi[1] / r11
    r12 = e1x * phi[2] + e1y * phi[3]
    wx = phi[2] - r12 * e1x
    wy = phi[3] - r12 * e1y
    r22 = math.sqrt(wx * wx + wy * wy)
    if not (r22 > 0.0) or not math.isfinite(r22):
        return r11, 0.0
    phi[0] = e1x
    phi[1] = e1y
    phi[2] = wx / r22
    phi[3] = wy / r22
    return r11, r22


@_jit
def _ill_conditioned(y) -> bool:
    """True if the tangent basis ``y[2:6]`` is nearly degenerate or badly scaled.

    The perpendicular part of ``v2`` carries ``Lambda_2``; once it is below
    ``REORTHONORMALISE`` of ``|v2|`` its relative accuracy is about
    ``rtol / REORTHONORMALISE`` and falling.
    """
    n1 = math.sqrt(y[2] * y[2] + y[3] * y[3])
    n2 = math.sqrt(y[4] * y[4] + y[5] * y[5])
    det = y[2] * y[5] - y[3] * y[4]
    return abs(det) < REORTHONORMALISE * n1 * n2 or n1 > 1e100 or n2 > 1e100 or n1 < 1e-100 or n2 < 1e-100


@_jit
def _error_norm2(kst, e_vec, m_last, y, yn, rtol, atol, nc) -> float:
    """Sum over components of ``(sum_m e_m k_m / scale)^2`` (squared, not averaged)."""
    acc = 0.0
    for c in range(nc):
        e = 0.0
        for m in range(m_last):
            e += e_vec[m] * kst[m, c]
        sc = atol + rtol * max(abs(y[c]), abs(yn[c]))
        acc += (e / sc) ** 2
    return acc


@_jit
def _initial_step(num, gpc, den, forcing, t, y, f0, span, order, rtol, atol, work, tmp, f1) -> float:
    """Hairer's starting step (Solving ODEs I, II.4) on the whole variational state."""
    d0 = 0.0
    d1 = 0.0
    for c in range(NSTATE):
        sc = atol + abs(y[c]) * rtol
        d0 += (y[c] / sc) ** 2
        d1 += (f0[c] / sc) ** 2
    d0 = math.sqrt(d0 / NSTATE)
    d1 = math.sqrt(d1 / NSTATE)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, span)
    for c in range(NSTATE):
        tmp[c] = y[c] + h0 * f0[c]
    variational_rhs(num, gpc, den, forcing, t + h0, tmp, f1, work)
    d2 = 0.0
    for c in range(NSTATE):
        sc = atol + abs(y[c]) * rtol
        d2 += ((f1[c] - f0[c]) / sc) ** 2
    d2 = math.sqrt(d2 / NSTATE) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, span)


@_jit
def lyapunov_kernel(
    a_mat,
    b_vec,
    c_vec,
    e_vec,
    e3_vec,
    e5_vec,
    dop853_error,
    order,
    error_order,
    num,
    gpc,
    den,
    forcing,
    t_base,
    period,
    k_first,
    n_periods,
    y,
    h,
    status,
    nsteps,
    logs,
    divs,
    pts,
    npts,
    rtol,
    atol,
    max_steps,
    bound,
    fixed_steps,
    idx,
):
    """Advance trajectories ``idx`` and their tangent matrices by ``n_periods`` periods.

    Parameters
    ----------
    a_mat, b_vec, c_vec, e_vec, e3_vec, e5_vec, dop853_error, order, error_order
        The embedded pair, exactly as :func:`explorer_core.solve.integrators.advance_adaptive`.
    num, gpc, den, forcing
        Coefficient tables of the quadratic field (any quadratic field in this
        format works, e.g. a linear test field).
    t_base, period, k_first
        Section times are ``t_base + k * period``; the state is at ``k_first``.
    y : (n, 6) array
        ``q, r`` and the orthonormal tangent basis; updated in place.
    h, status, nsteps : (n,) arrays
        Step memory, :class:`~explorer_core.solve.integrators.Status` codes, step counts.
    logs : (n, n_periods, 2) array
        ``log R_11, log R_22`` of the QR factorisation at each section time.
    divs : (n, n_periods) array
        Integral of the divergence over each period.
    pts : (n, n_periods, 2) array
        Section points; ``npts[i]`` periods of trajectory ``i`` completed in this call.
    fixed_steps
        ``> 0``: that many equal steps per period, no error control.
    """
    s = b_vec.shape[0]
    kst = np.empty((s + 1, NSTATE))
    work = np.empty((2, 6))
    yc = np.empty(NSTATE)
    yn = np.empty(NSTATE)
    tmp = np.empty(NSTATE)
    f1 = np.empty(NSTATE)
    span = abs(period)
    expo = -1.0 / (error_order + 1.0)
    for ii in range(idx.shape[0]):
        i = idx[ii]
        npts[i] = 0
        if status[i] != _OK:
            continue
        for c in range(6):
            yc[c] = y[i, c]
        habs = h[i]
        for j in range(n_periods):
            ta = t_base + (k_first + j) * period
            tb = t_base + (k_first + j + 1) * period
            t = ta
            yc[6] = 0.0  # the divergence integral restarts every period
            log1 = 0.0
            log2 = 0.0
            variational_rhs(num, gpc, den, forcing, t, yc, tmp, work)
            for c in range(NSTATE):
                kst[0, c] = tmp[c]
            if not math.isfinite(tmp[0]) or not math.isfinite(tmp[1]):
                status[i] = _NONFINITE
                break
            if habs <= 0.0 and fixed_steps <= 0:
                habs = _initial_step(num, gpc, den, forcing, t, yc, tmp, span, order, rtol, atol, work, yn, f1)
            steps = 0
            saw_nonfinite = False
            while True:
                remaining = tb - t
                if remaining <= 0.0:
                    break
                hmin = 10.0 * _EPS * max(abs(t), span)
                if fixed_steps > 0:
                    hstep = span / fixed_steps
                    t = ta + steps * hstep  # step times from ta, not accumulated
                    last = steps + 1 == fixed_steps
                else:
                    hstep = habs
                    last = False
                    if hstep >= remaining - hmin:  # land exactly on the section time
                        hstep = remaining
                        last = True
                for st in range(1, s):
                    for c in range(NSTATE):
                        acc = 0.0
                        for m in range(st):
                            am = a_mat[st, m]
                            if am != 0.0:
                                acc += am * kst[m, c]
                        tmp[c] = yc[c] + hstep * acc
                    variational_rhs(num, gpc, den, forcing, t + c_vec[st] * hstep, tmp, f1, work)
                    for c in range(NSTATE):
                        kst[st, c] = f1[c]
                for c in range(NSTATE):
                    acc = 0.0
                    for m in range(s):
                        acc += b_vec[m] * kst[m, c]
                    yn[c] = yc[c] + hstep * acc
                tn = tb if last else t + hstep
                variational_rhs(num, gpc, den, forcing, tn, yn, f1, work)
                for c in range(NSTATE):
                    kst[s, c] = f1[c]
                if dop853_error:
                    n5 = _error_norm2(kst, e5_vec, s + 1, yc, yn, rtol, atol, NSTATE)
                    n3 = _error_norm2(kst, e3_vec, s + 1, yc, yn, rtol, atol, NSTATE)
                    if n5 == 0.0 and n3 == 0.0:
                        err = 0.0
                    else:
                        err = hstep * n5 / math.sqrt((n5 + 0.01 * n3) * NSTATE)
                else:
                    err = hstep * math.sqrt(_error_norm2(kst, e_vec, s + 1, yc, yn, rtol, atol, NSTATE) / NSTATE)
                steps += 1
                finite = math.isfinite(err)
                for c in range(NSTATE):
                    finite = finite and math.isfinite(f1[c]) and math.isfinite(yn[c])
                if fixed_steps > 0:
                    if not finite:
                        status[i] = _NONFINITE
                        break
                    err = 0.0
                if finite and err <= 1.0:
                    t = tn
                    for c in range(NSTATE):
                        yc[c] = yn[c]
                        kst[0, c] = f1[c]
                    factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err**expo)
                    # A clipped last step says little about the step size: keep the larger proposal.
                    habs = max(habs, hstep * factor) if last else hstep * factor
                    if abs(yc[0]) > bound or abs(yc[1]) > bound:
                        status[i] = _ESCAPED
                        break
                    if not last and _ill_conditioned(yc):
                        # Strong contraction within one period: the second vector would be
                        # lost to rounding before the section time. QR now (the product of
                        # the R factors is unchanged), restart the FSAL stage from the new basis.
                        r11, r22 = gram_schmidt(yc[2:6])
                        if r11 <= 0.0 or r22 <= 0.0:
                            status[i] = _NONFINITE
                            break
                        log1 += math.log(r11)
                        log2 += math.log(r22)
                        variational_rhs(num, gpc, den, forcing, t, yc, f1, work)
                        for c in range(NSTATE):
                            kst[0, c] = f1[c]
                else:
                    if not finite:
                        saw_nonfinite = True
                        habs = hstep * _MIN_FACTOR
                    else:
                        habs = hstep * max(_MIN_FACTOR, _SAFETY * err**expo)
                    if habs < hmin:
                        status[i] = _NONFINITE if saw_nonfinite else _COLLAPSED
                        break
                if steps >= max_steps:
                    status[i] = _TOO_MANY
                    break
            nsteps[i] += steps
            if status[i] != _OK:
                break
            r11, r22 = gram_schmidt(yc[2:6])
            if r11 <= 0.0 or r22 <= 0.0:
                # The tangent basis collapsed (under/overflow within one period).
                status[i] = _NONFINITE
                break
            logs[i, j, 0] = log1 + math.log(r11)
            logs[i, j, 1] = log2 + math.log(r22)
            divs[i, j] = yc[6]
            pts[i, j, 0] = yc[0]
            pts[i, j, 1] = yc[1]
            for c in range(6):
                y[i, c] = yc[c]
            npts[i] = j + 1
        h[i] = habs


def qr_exponents(matrices: Any) -> np.ndarray:
    """Exponents per step of the product ``M_n ... M_2 M_1`` of 2x2 matrices.

    The same Gram-Schmidt accumulation the kernel applies at section times, on
    given one-step matrices (e.g. the Jacobians of a map along an orbit).

    Parameters
    ----------
    matrices : (n, 2, 2) array-like

    Returns
    -------
    (2,) array: ``sum log R_ii / n``, largest first.
    """
    mats = np.asarray(matrices, dtype=float)
    if mats.ndim != 3 or mats.shape[1:] != (2, 2) or mats.shape[0] == 0:
        raise ParameterError(f"matrices must have shape (n, 2, 2), got {mats.shape}")
    phi = np.array([1.0, 0.0, 0.0, 1.0])
    acc = np.zeros(2)
    for m in mats:
        basis = np.array([[phi[0], phi[2]], [phi[1], phi[3]]])
        new = m @ basis
        phi = np.array([new[0, 0], new[1, 0], new[0, 1], new[1, 1]])
        r11, r22 = gram_schmidt(phi)
        if r11 <= 0.0 or r22 <= 0.0:
            raise ParameterError("a matrix of the product is singular: exponents are -inf")
        acc += (math.log(r11), math.log(r22))
    return acc / mats.shape[0]


def kaplan_yorke(l1: float, l2: float) -> float:
    """Kaplan-Yorke dimension of a section attractor with exponents ``l1 >= l2``.

    ``1 + l1/|l2|`` if ``l1 >= 0 > l1 + l2`` (paper, after Figs. 4 and 8B);
    ``0`` for ``l1 < 0`` (a stable cycle), ``2`` if the map does not contract area.
    Units cancel: per time or per iteration give the same ``D``.
    """
    l1, l2 = max(l1, l2), min(l1, l2)
    if l1 < 0.0:
        return 0.0
    if l1 + l2 >= 0.0:
        return 2.0
    return 1.0 + l1 / abs(l2)


# ---------------------------------------------------------------------------
# Driver: batches, threads, chunks.


@dataclass
class TangentBatch:
    """State of a batch of trajectories with their tangent bases, between section times."""

    y: np.ndarray  # (n, 6): q, r, orthonormal tangent basis
    h: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    k: int
    t0: float
    period: float

    @classmethod
    def start(cls, ics: np.ndarray, t0: float, period: float) -> TangentBatch:
        ics = np.asarray(ics, dtype=float).reshape(-1, 2)
        n = ics.shape[0]
        y = np.zeros((n, 6))
        y[:, :2] = ics
        y[:, 2] = 1.0  # identity: v1 = e_q, v2 = e_r
        y[:, 5] = 1.0
        status = np.zeros(n, dtype=np.int64)
        status[~np.all(np.isfinite(ics), axis=1)] = _NONFINITE
        return cls(y, np.zeros(n), status, np.zeros(n, dtype=np.int64), 0, float(t0), float(period))

    @property
    def n(self) -> int:
        return self.y.shape[0]


_pool_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None


def run_threads(fn: Callable[[np.ndarray], None], n: int, workers: int | None = None) -> None:
    """Call ``fn(idx)`` on interleaved index subsets of ``range(n)`` in worker threads.

    The kernels release the GIL, so the threads share both cores. Callers that
    are themselves running in a worker (chart tiles) pass ``workers=1``.
    """
    global _pool
    parts = min(workers or config.N_WORKERS, n)
    if parts <= 1:
        fn(np.arange(n, dtype=np.int64))
        return
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=config.N_WORKERS, thread_name_prefix="bilimovich-lyapunov")
    futures = [_pool.submit(fn, np.arange(w, n, parts, dtype=np.int64)) for w in range(parts)]
    for f in futures:
        f.result()


def advance_tangent(
    num: np.ndarray,
    gpc: np.ndarray,
    den: np.ndarray,
    forcing: np.ndarray,
    batch: TangentBatch,
    n_periods: int,
    numerics: Numerics,
    workers: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Advance a :class:`TangentBatch` by ``n_periods`` periods (low-level call).

    Takes raw coefficient tables so any quadratic field in the model's format
    (including a linear test field) can be used.

    Returns
    -------
    logs : (n, n_periods, 2) ``log R_ii`` per period
    divs : (n, n_periods) divergence integral per period
    pts : (n, n_periods, 2) section points
    npts : (n,) periods completed by each trajectory in this call
    """
    meth = get_method(numerics.method)
    if meth.name == "rk4":
        meth = get_method("rk4-tableau")
    fixed = 0 if (numerics.adaptive and meth.adaptive) else int(numerics.steps_per_period)
    n = batch.n
    logs = np.zeros((n, n_periods, 2))
    divs = np.zeros((n, n_periods))
    pts = np.zeros((n, n_periods, 2))
    npts = np.zeros(n, dtype=np.int64)
    if n == 0 or n_periods <= 0:
        return logs, divs, pts, npts
    forcing = np.ascontiguousarray(forcing, dtype=float)

    def run(idx: np.ndarray) -> None:
        lyapunov_kernel(
            meth.a,
            meth.b,
            meth.c,
            meth.e,
            meth.e3,
            meth.e5,
            meth.name == "dop853",
            float(meth.order),
            float(meth.error_order),
            num,
            gpc,
            den,
            forcing,
            batch.t0,
            batch.period,
            batch.k,
            n_periods,
            batch.y,
            batch.h,
            batch.status,
            batch.nsteps,
            logs,
            divs,
            pts,
            npts,
            numerics.rtol,
            numerics.atol,
            numerics.max_steps,
            numerics.bound,
            fixed,
            idx,
        )

    run_threads(run, n, workers)
    batch.k += n_periods
    return logs, divs, pts, npts


# ---------------------------------------------------------------------------
# Results and the public call.


@dataclass(frozen=True)
class LyapunovProgress:
    """Passed to the ``progress`` callback after each chunk of periods."""

    phase: str  # "transient" or "measure"
    done_periods: int
    total_periods: int
    running: np.ndarray  # (n, 2) current estimates per unit time (0 where none yet)
    status: np.ndarray
    elapsed_s: float


@dataclass(frozen=True)
class LyapunovResult:
    """Lyapunov exponents of one or several trajectories (an ensemble).

    All exponents are **per unit time**; multiply by :attr:`period` for the
    exponents of the Poincare map per iteration (:meth:`per_iteration`).

    Attributes
    ----------
    exponents : (M, 2) ``Lambda_1, Lambda_2`` of the ``(q, r)`` flow per member: the
        averages of ``log R_11``, ``log R_22`` over the ``npts[i]`` measured periods
        (0 where ``npts[i] == 0``). ``Lambda_1 >= Lambda_2`` holds asymptotically; a
        finite-time estimate of a degenerate pair may come out in either order.
    divergence_mean : (M,) time average of ``dQ/dq + dR/dr`` over the same periods.
    logs : (M, periods, 2) ``log R_ii`` of each period (the local stretching).
    divs : (M, periods) integral of the divergence over each period.
    points : (M, periods, 2) section points ``k = transient + 1, ...``.
    npts : (M,) measured periods per member (fewer than ``periods`` on failure).
    status : (M,) :class:`~explorer_core.solve.integrators.Status` codes.
    """

    params: Params
    numerics: Numerics
    ics: np.ndarray
    transient: int
    periods: int
    period: float
    exponents: np.ndarray
    divergence_mean: np.ndarray
    logs: np.ndarray
    divs: np.ndarray
    points: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    elapsed_s: float
    completed: bool = True

    @property
    def ok(self) -> np.ndarray:
        """Members that ran the whole measurement without failure."""
        return (self.status == _OK) & (self.npts == self.periods)

    def status_labels(self) -> list[str]:
        return [Status(int(s)).label for s in self.status]

    def running(self, i: int = 0) -> np.ndarray:
        """(npts[i], 2) running estimates per unit time after k = 1, 2, ... measured periods."""
        m = int(self.npts[i])
        k = np.arange(1, m + 1)[:, None]
        return np.cumsum(self.logs[i, :m], axis=0) / (k * self.period)

    def mean(self) -> np.ndarray:
        """Ensemble mean of ``(Lambda_1, Lambda_2)`` over the members that completed (0 if none)."""
        sel = self.exponents[self.ok]
        return sel.mean(axis=0) if sel.size else np.zeros(2)

    def spread(self) -> np.ndarray:
        """Ensemble standard deviation (ddof=1; 0 for fewer than two members)."""
        sel = self.exponents[self.ok]
        return sel.std(axis=0, ddof=1) if sel.shape[0] > 1 else np.zeros(2)

    def divergence(self) -> float:
        """Ensemble mean of the time-averaged divergence."""
        sel = self.divergence_mean[self.ok]
        return float(sel.mean()) if sel.size else 0.0

    def per_iteration(self) -> np.ndarray:
        """Mean exponents of the Poincare map per iteration: per-time values times ``T``."""
        return self.mean() * self.period

    def kaplan_yorke(self) -> float:
        """Kaplan-Yorke dimension of the section attractor from the mean exponents."""
        l1, l2 = self.mean()
        return kaplan_yorke(float(l1), float(l2))

    def convergence(self, n: int = 40) -> dict[str, list]:
        """Running estimate of member 0 at about ``n`` log-spaced ``k`` (for a convergence plot)."""
        run = self.running(0)
        if run.shape[0] == 0:
            return {"k": [], "L1": [], "L2": []}
        ks = np.unique(np.geomspace(1, run.shape[0], n).astype(int))
        return {
            "k": ks.tolist(),
            "L1": [float(v) for v in run[ks - 1, 0]],
            "L2": [float(v) for v in run[ks - 1, 1]],
        }

    def summary(self) -> dict[str, Any]:
        """JSON summary: mean exponents (with ``Lambda_3 = 0``), dimension, check, members."""
        n_ok = int(self.ok.sum())
        mean = self.mean()
        spread = self.spread()
        labels = self.status_labels()
        if n_ok == self.ics.shape[0]:
            status = "ok"
        elif n_ok:
            status = "partial"
        else:
            status = next((lab for lab in labels if lab != "ok"), "incomplete")
        div = self.divergence()
        return {
            "exponents": [float(mean[0]), float(mean[1]), 0.0] if n_ok else None,
            "spread": [float(spread[0]), float(spread[1]), 0.0] if n_ok else None,
            "per_iteration": [float(v) for v in self.per_iteration()] + [0.0] if n_ok else None,
            "units": f"exponents per unit time t; per_iteration = per time x T (T = {self.period:.12g})",
            "kaplan_yorke": self.kaplan_yorke() if n_ok else None,
            "divergence_mean": div if n_ok else None,
            "sum_minus_divergence": float(mean.sum() - div) if n_ok else None,
            "status": status,
            "members": [
                {
                    "ic": [float(q), float(r)],
                    "status": lab,
                    "exponents": [float(e[0]), float(e[1])] if n else None,
                    "divergence_mean": float(d) if n else None,
                    "periods": int(n),
                    "steps": int(s),
                }
                for (q, r), lab, e, d, n, s in zip(
                    self.ics, labels, self.exponents, self.divergence_mean, self.npts, self.nsteps, strict=True
                )
            ],
            "ensemble": {"size": int(self.ics.shape[0]), "ok": n_ok},
            "convergence": self.convergence(),
            "transient": self.transient,
            "periods": self.periods,
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
        }


def _check_count(name: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
        raise ParameterError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
    return int(v)


def ensemble_ics(ic: Sequence[float], m: int, offset: float = ENSEMBLE_OFFSET, seed: int | None = 0) -> np.ndarray:
    """``m`` initial conditions: ``ic`` itself and ``m - 1`` seeded random offsets around it.

    Offsets are uniform in ``+-offset * (1 + |ic|)`` per coordinate; after the
    transient the members sit on the same attractor but (on a chaotic one)
    sample it independently.
    """
    ic = check_ics(ic)
    if ic.shape[0] != 1:
        raise ParameterError(f"ensemble_ics takes one initial condition, got {ic.shape[0]}")
    m = _check_count("ensemble", m, 1, config.MAX_TRAJECTORIES)
    if not (math.isfinite(offset) and offset > 0):
        raise ParameterError(f"offset must be a positive number, got {offset!r}")
    rng = np.random.default_rng(seed)
    out = np.repeat(ic, m, axis=0)
    out[1:] += rng.uniform(-1.0, 1.0, (m - 1, 2)) * offset * (1.0 + np.abs(ic))
    return out


def attractor_ensemble(
    params: Params,
    ic: Sequence[float],
    m: int,
    *,
    transient: int,
    offset: float = 1e-6,
    seed: int | None = 0,
    numerics: Numerics | None = None,
) -> np.ndarray:
    """``m`` initial conditions on the attractor that ``ic`` goes to.

    ``ic`` is first run through ``transient`` periods; the members are the settled
    point and ``m - 1`` seeded offsets of relative size ``offset`` around it (see
    :func:`ensemble_ics`). Small offsets keep the members in the attractor's basin;
    on a chaotic attractor they decorrelate within a few dozen periods. If the
    settling run fails (e.g. escapes), the members are placed around ``ic`` itself
    and report the failure through their own status.
    """
    numerics = numerics or Numerics()
    start = check_ics(ic)
    transient = _check_count("transient", transient, 0, config.MAX_PERIODS)
    if transient:
        batch = Batch.start(start, params.t0, params.period)
        advance(Model(params), batch, transient, store=False, workers=1, **numerics.kernel_kwargs())
        if batch.status[0] == _OK:
            start = batch.y.copy()
    return ensemble_ics(start[0], m, offset=offset, seed=seed)


def lyapunov_tables(
    num: np.ndarray,
    gpc: np.ndarray,
    den: np.ndarray,
    forcing: np.ndarray,
    t0: float,
    period: float,
    ics: Any,
    periods: int,
    *,
    transient: int = 0,
    numerics: Numerics | None = None,
    progress: Callable[[LyapunovProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Low-level call on raw coefficient tables (see :func:`lyapunov_spectrum`).

    Returns the fields of :class:`LyapunovResult` that do not depend on ``Params``.
    """
    numerics = numerics or Numerics()
    ics = check_ics(ics)
    periods = _check_count("periods", periods, 1, config.MAX_PERIODS)
    transient = _check_count("transient", transient, 0, config.MAX_PERIODS)
    n = ics.shape[0]
    if n * periods > config.MAX_POINTS:
        raise ParameterError(f"{n} members x {periods} periods exceeds the limit {config.MAX_POINTS}")
    if not (math.isfinite(period) and period > 0):
        raise ParameterError(f"period must be positive, got {period!r}")
    batch = TangentBatch.start(ics, t0, period)
    logs = np.zeros((n, periods, 2))
    divs = np.zeros((n, periods))
    pts = np.zeros((n, periods, 2))
    npts = np.zeros(n, dtype=np.int64)
    start = time.perf_counter()
    completed = True

    def chunks(total: int):
        done, size = 0, 8
        while done < total:
            step = min(size, total - done)
            yield step
            done += step
            size = min(2 * size, 256)

    def report(phase: str, done: int, total: int) -> None:
        if progress is None:
            return
        k = np.maximum(npts, 1)[:, None]
        running = logs.sum(axis=1) / (k * period)
        progress(LyapunovProgress(phase, done, total, running, batch.status.copy(), time.perf_counter() - start))

    done = 0
    for size in chunks(transient):
        if cancel is not None and cancel():
            completed = False
            break
        advance_tangent(num, gpc, den, forcing, batch, size, numerics, workers)
        done += size
        report("transient", done, transient)
    done = 0
    if completed:
        for size in chunks(periods):
            if cancel is not None and cancel():
                completed = False
                break
            lg, dv, pt, m = advance_tangent(num, gpc, den, forcing, batch, size, numerics, workers)
            for i in np.flatnonzero(m):
                # Trajectory i's periods stay contiguous: it contributes only while alive.
                a, b = npts[i], npts[i] + m[i]
                logs[i, a:b] = lg[i, : m[i]]
                divs[i, a:b] = dv[i, : m[i]]
                pts[i, a:b] = pt[i, : m[i]]
            npts += m
            done += size
            report("measure", done, periods)
            if not np.any(batch.status == _OK):
                break
    span = np.maximum(npts, 1) * period
    exps = np.where(npts[:, None] > 0, logs.sum(axis=1) / span[:, None], 0.0)
    divm = np.where(npts > 0, divs.sum(axis=1) / span, 0.0)
    return {
        "ics": ics,
        "transient": transient,
        "periods": periods,
        "period": float(period),
        "exponents": exps,
        "divergence_mean": divm,
        "logs": logs,
        "divs": divs,
        "points": pts,
        "npts": npts,
        "status": batch.status.copy(),
        "nsteps": batch.nsteps.copy(),
        "elapsed_s": time.perf_counter() - start,
        "completed": completed,
    }


def lyapunov_spectrum(
    params: Params,
    ics: Any,
    periods: int,
    *,
    transient: int = 0,
    numerics: Numerics | None = None,
    progress: Callable[[LyapunovProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> LyapunovResult:
    """Lyapunov exponents ``Lambda_1 >= Lambda_2`` (per unit time) for each initial condition.

    Parameters
    ----------
    params : the system.
    ics : (M, 2) initial conditions at ``t0``; several on one attractor form an
        ensemble (see :func:`ensemble_ics`), whose mean and spread the result gives.
    periods : measured periods after the transient (the averaging time is ``periods * T``).
    transient : periods integrated first (the tangent basis aligns meanwhile) and not counted.
    numerics : method and tolerances (error control covers the tangent vectors too).
    progress : called after each chunk of periods with a :class:`LyapunovProgress`.
    cancel : polled between chunks; True stops and returns what was measured (``completed=False``).
    workers : threads (default: both cores).

    Returns
    -------
    LyapunovResult
    """
    numerics = numerics or Numerics()
    model = Model(params)
    out = lyapunov_tables(
        model.num,
        model.gpc,
        model.den,
        model.forcing,
        params.t0,
        params.period,
        ics,
        periods,
        transient=transient,
        numerics=numerics,
        progress=progress,
        cancel=cancel,
        workers=workers,
    )
    return LyapunovResult(params=params, numerics=numerics, **out)


def warmup() -> None:
    """Compile (or load from the on-disk cache) the variational kernel."""
    lyapunov_spectrum(Params(), [(0.1, 0.2)], 1, workers=1)
