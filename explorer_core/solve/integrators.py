"""Stroboscopic integrators: numba kernels that advance batches period by period.

Every kernel advances each trajectory from one section time ``t0 + k T`` to the
next and lands on it exactly (the last step of a period is clipped to end at the
section time, which is computed as ``t0 + k T``, never accumulated), so section
points carry no interpolation error.

Methods
-------
``rk4``
    Classical fixed-step Runge-Kutta, ``steps_per_period`` steps per period.
``dp5``
    Dormand-Prince 5(4) with FSAL and standard error control.
``dop853``
    Hairer's DOP853, 8th order with the combined 5th/3rd-order error estimate.

The kernels release the GIL (``nogil=True``) and process a subset of the batch
given by an index array, so :func:`advance` splits a batch across threads and
both cores work at once. Failures are recorded per trajectory in ``status``
(see :class:`Status`); a failed trajectory keeps its last good section point and
is never advanced again.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from enum import IntEnum

import numba as nb
import numpy as np

from explorer_core import config
from explorer_core.solve import tableaus
from explorer_core.system.model import Model, coefficients_at, forcing_g, rhs


class Status(IntEnum):
    """Per-trajectory outcome; anything but OK ends the trajectory."""

    OK = 0
    ESCAPED = 1  # |q| or |r| left the bound: noncompact motion
    STEP_COLLAPSED = 2  # the adaptive step fell below the round-off floor
    TOO_MANY_STEPS = 3  # the per-period step budget ran out
    NONFINITE = 4  # the field or the state became inf/NaN

    @property
    def label(self) -> str:
        return self.name.lower()


_OK, _ESCAPED, _COLLAPSED, _TOO_MANY, _NONFINITE = (int(s) for s in Status)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = config.SAFETY, config.MIN_FACTOR, config.MAX_FACTOR
_EPS = float(np.finfo(float).eps)

_jit = nb.njit(nogil=True, cache=True, error_model="numpy")
#: Small pieces of the block kernel, inlined into it (numba IR inlining) so its loops stay fused and fast.
_jit_inline = nb.njit(nogil=True, cache=True, error_model="numpy", inline="always")


@_jit
def _rms_norm2(a: float, b: float, sa: float, sb: float) -> float:
    x = a / sa
    y = b / sb
    return math.sqrt(0.5 * (x * x + y * y))


@_jit
def _initial_step(num, gpc, den, forcing, t, q, r, fq, fr, d, span, order, rtol, atol, work) -> float:
    """Hairer's starting step (Solving ODEs I, II.4), as in scipy's select_initial_step."""
    sq = atol + abs(q) * rtol
    sr = atol + abs(r) * rtol
    d0 = _rms_norm2(q, r, sq, sr)
    d1 = _rms_norm2(fq, fr, sq, sr)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, span)
    f1q, f1r = rhs(num, gpc, den, forcing, t + d * h0, q + d * h0 * fq, r + d * h0 * fr, work)
    d2 = _rms_norm2(f1q - fq, f1r - fr, sq, sr) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, span)


@_jit
def advance_adaptive(
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
    out,
    npts,
    store,
    rtol,
    atol,
    max_steps,
    bound,
    fixed_steps,
    idx,
):
    """Advance trajectories ``idx`` by ``n_periods`` periods with an embedded RK pair.

    Parameters
    ----------
    a_mat, b_vec, c_vec : tableau (s x s, s, s).
    e_vec : (s+1,) error weights of a standard pair (DP5); unused for DOP853.
    e3_vec, e5_vec : (s+1,) DOP853 error weights; ``dop853_error`` selects them.
    t_base, period : section times are ``t_base + k * period`` (period < 0 runs backward).
    k_first : index k of the current state's section time.
    y : (n, 2) state, updated in place to the last completed section point.
    h : (n,) step-size memory (|h|, 0 = choose a starting step), updated.
    status, nsteps : (n,) updated in place.
    out : (n, n_periods, 2) section points written if ``store``; npts (n,) counts them.
    fixed_steps : if > 0, take exactly this many equal steps per period with no error
        control (the same stage arithmetic; used to measure the tableau's order).
    """
    s = b_vec.shape[0]
    k = np.empty((s + 1, 2))
    work = np.empty((2, 6))
    d = 1.0 if period > 0.0 else -1.0
    span = abs(period)
    expo = -1.0 / (error_order + 1.0)
    for ii in range(idx.shape[0]):
        i = idx[ii]
        npts[i] = 0
        if status[i] != _OK:
            continue
        q = y[i, 0]
        r = y[i, 1]
        habs = h[i]
        for j in range(n_periods):
            ta = t_base + (k_first + j) * period
            tb = t_base + (k_first + j + 1) * period
            t = ta
            fq, fr = rhs(num, gpc, den, forcing, t, q, r, work)
            if not (math.isfinite(fq) and math.isfinite(fr)):
                status[i] = _NONFINITE
                break
            if habs <= 0.0 and fixed_steps <= 0:
                habs = _initial_step(num, gpc, den, forcing, t, q, r, fq, fr, d, span, order, rtol, atol, work)
            steps = 0
            saw_nonfinite = False
            while True:
                remaining = (tb - t) * d
                if remaining <= 0.0:
                    break
                hmin = 10.0 * _EPS * max(abs(t), span)
                if fixed_steps > 0:
                    hstep = span / fixed_steps
                    t = ta + d * steps * hstep  # step times from ta, not accumulated
                    last = steps + 1 == fixed_steps
                else:
                    hstep = habs
                    last = False
                    # Clip to land exactly on the section time; absorb a sliver.
                    if hstep >= remaining - hmin:
                        hstep = remaining
                        last = True
                hs = d * hstep
                k[0, 0] = fq
                k[0, 1] = fr
                for st in range(1, s):
                    sq = 0.0
                    sr = 0.0
                    for m in range(st):
                        am = a_mat[st, m]
                        if am != 0.0:
                            sq += am * k[m, 0]
                            sr += am * k[m, 1]
                    k[st, 0], k[st, 1] = rhs(num, gpc, den, forcing, t + c_vec[st] * hs, q + hs * sq, r + hs * sr, work)
                bq = 0.0
                br = 0.0
                for m in range(s):
                    bq += b_vec[m] * k[m, 0]
                    br += b_vec[m] * k[m, 1]
                qn = q + hs * bq
                rn = r + hs * br
                tn = tb if last else t + hs
                k[s, 0], k[s, 1] = rhs(num, gpc, den, forcing, tn, qn, rn, work)
                scq = atol + rtol * max(abs(q), abs(qn))
                scr = atol + rtol * max(abs(r), abs(rn))
                if dop853_error:
                    e5q = 0.0
                    e5r = 0.0
                    e3q = 0.0
                    e3r = 0.0
                    for m in range(s + 1):
                        e5q += e5_vec[m] * k[m, 0]
                        e5r += e5_vec[m] * k[m, 1]
                        e3q += e3_vec[m] * k[m, 0]
                        e3r += e3_vec[m] * k[m, 1]
                    n5 = (e5q / scq) ** 2 + (e5r / scr) ** 2
                    n3 = (e3q / scq) ** 2 + (e3r / scr) ** 2
                    if n5 == 0.0 and n3 == 0.0:
                        err = 0.0
                    else:
                        err = hstep * n5 / math.sqrt((n5 + 0.01 * n3) * 2.0)
                else:
                    eq = 0.0
                    er = 0.0
                    for m in range(s + 1):
                        eq += e_vec[m] * k[m, 0]
                        er += e_vec[m] * k[m, 1]
                    err = hstep * _rms_norm2(eq, er, scq, scr)
                steps += 1
                finite = math.isfinite(err) and math.isfinite(k[s, 0]) and math.isfinite(k[s, 1])
                if fixed_steps > 0:
                    if not finite:
                        status[i] = _NONFINITE
                        break
                    err = 0.0
                if finite and err <= 1.0:
                    t = tn
                    q = qn
                    r = rn
                    fq = k[s, 0]
                    fr = k[s, 1]
                    factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err**expo)
                    # A clipped last step says little about the step size: keep the larger proposal.
                    habs = max(habs, hstep * factor) if last else hstep * factor
                    if abs(q) > bound or abs(r) > bound:
                        status[i] = _ESCAPED
                        break
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
            y[i, 0] = q
            y[i, 1] = r
            if store:
                out[i, j, 0] = q
                out[i, j, 1] = r
            npts[i] = j + 1
        h[i] = habs


@_jit
def _quad2(c, q, r) -> tuple[float, float]:
    return (
        c[0, 0] + q * (c[0, 1] + c[0, 3] * q + c[0, 4] * r) + r * (c[0, 2] + c[0, 5] * r),
        c[1, 0] + q * (c[1, 1] + c[1, 3] * q + c[1, 4] * r) + r * (c[1, 2] + c[1, 5] * r),
    )


@_jit
def _coefs(num, gpc, den, forcing, t, c) -> None:
    g, gp = forcing_g(forcing, t)
    coefficients_at(num[:2], gpc[:2], den, g, gp, c)


@_jit_inline
def _combine(w, row, scale, upto, kq, kr, n, sq, sr) -> None:
    # sq[p] = scale * sum_{mm < upto} w[row, mm] kq[mm, p] for the n packed members (zero weights skipped).
    for p in range(n):
        sq[p] = 0.0
        sr[p] = 0.0
    for mm in range(upto):
        wm = w[row, mm] * scale
        if wm != 0.0:
            for p in range(n):
                sq[p] += wm * kq[mm, p]
                sr[p] += wm * kr[mm, p]


@_jit_inline
def _field(c, yq, yr, dq, dr, n, kq, kr, st) -> None:
    # k[st] = f(y + d) for the n packed members at one time (coefficients c).
    c00, c01, c02, c03, c04, c05 = c[0, 0], c[0, 1], c[0, 2], c[0, 3], c[0, 4], c[0, 5]
    c10, c11, c12, c13, c14, c15 = c[1, 0], c[1, 1], c[1, 2], c[1, 3], c[1, 4], c[1, 5]
    for p in range(n):
        qq = yq[p] + dq[p]
        rr = yr[p] + dr[p]
        kq[st, p] = c00 + qq * (c01 + c03 * qq + c04 * rr) + rr * (c02 + c05 * rr)
        kr[st, p] = c10 + qq * (c11 + c13 * qq + c14 * rr) + rr * (c12 + c15 * rr)


@_jit_inline
def _scaled_norm2(eq, er, yq, yr, qn, rn, atol, rtol, n, out) -> None:
    # Squared error over the mixed absolute/relative scale of the old and new states.
    for p in range(n):
        a = eq[p] / (atol + rtol * max(abs(yq[p]), abs(qn[p])))
        b = er[p] / (atol + rtol * max(abs(yr[p]), abs(rn[p])))
        out[p] = a * a + b * b


@_jit
def _swap(p, last, slot, yq, yr, kq, kr) -> None:
    # Move a failed trajectory out of the packed live range [0, last).
    slot[p], slot[last] = slot[last], slot[p]
    yq[p], yq[last] = yq[last], yq[p]
    yr[p], yr[last] = yr[last], yr[p]
    for st in range(kq.shape[0]):
        kq[st, p], kq[st, last] = kq[st, last], kq[st, p]
        kr[st, p], kr[st, last] = kr[st, last], kr[st, p]


#: Trajectories RK4 advances together (fixed steps need no lock-step compromise; the
#: block only bounds the scratch arrays so they stay in cache).
RK4_BLOCK = 64


@_jit
def advance_rk4(
    num,
    gpc,
    den,
    forcing,
    t_base,
    period,
    k_first,
    n_periods,
    steps_per_period,
    y,
    status,
    nsteps,
    out,
    npts,
    store,
    bound,
    idx,
):
    """Advance trajectories ``idx`` by ``n_periods`` periods with fixed-step RK4.

    Same state/outputs as :func:`advance_adaptive`; the step is ``period / steps_per_period``
    and step times are ``ta + m h`` (not accumulated), the last one is the section time.
    Every trajectory takes the same steps, so blocks of :data:`RK4_BLOCK` go in lock-step:
    the field's coefficients (which depend on t only) are computed once per stage for the
    block, and the inner loops run over the packed live members and vectorise. The
    arithmetic per trajectory is that of the textbook loop (tests/naive.py), bit for bit.
    """
    hs = period / steps_per_period
    half = 0.5 * hs
    sixth = hs / 6.0
    c = np.empty((2, 6))
    nb_ = RK4_BLOCK
    kq = np.empty((4, nb_))
    kr = np.empty((4, nb_))
    yq = np.empty(nb_)
    yr = np.empty(nb_)
    slot = np.empty(nb_, dtype=np.int64)
    sq = np.empty(nb_)
    sr = np.empty(nb_)
    for b0 in range(0, idx.shape[0], nb_):
        n_live = 0
        for ii in range(b0, min(b0 + nb_, idx.shape[0])):
            i = idx[ii]
            npts[i] = 0
            if status[i] == _OK:
                slot[n_live] = i
                yq[n_live] = y[i, 0]
                yr[n_live] = y[i, 1]
                n_live += 1
        for j in range(n_periods):
            if n_live == 0:
                break
            ta = t_base + (k_first + j) * period
            for m in range(steps_per_period):
                t = ta + m * hs
                n = n_live
                _coefs(num, gpc, den, forcing, t, c)
                for p in range(n):
                    sq[p] = 0.0
                    sr[p] = 0.0
                _field(c, yq, yr, sq, sr, n, kq, kr, 0)
                _coefs(num, gpc, den, forcing, t + half, c)
                for p in range(n):
                    sq[p] = half * kq[0, p]
                    sr[p] = half * kr[0, p]
                _field(c, yq, yr, sq, sr, n, kq, kr, 1)
                for p in range(n):
                    sq[p] = half * kq[1, p]
                    sr[p] = half * kr[1, p]
                _field(c, yq, yr, sq, sr, n, kq, kr, 2)
                _coefs(num, gpc, den, forcing, t + hs, c)
                for p in range(n):
                    sq[p] = hs * kq[2, p]
                    sr[p] = hs * kr[2, p]
                _field(c, yq, yr, sq, sr, n, kq, kr, 3)
                for p in range(n):
                    yq[p] = yq[p] + sixth * (kq[0, p] + 2.0 * kq[1, p] + 2.0 * kq[2, p] + kq[3, p])
                    yr[p] = yr[p] + sixth * (kr[0, p] + 2.0 * kr[1, p] + 2.0 * kr[2, p] + kr[3, p])
                p = 0
                while p < n_live:
                    q = yq[p]
                    r = yr[p]
                    code = _OK
                    if not (math.isfinite(q) and math.isfinite(r)):
                        code = _NONFINITE
                    elif abs(q) > bound or abs(r) > bound:
                        code = _ESCAPED
                    if code == _OK:
                        p += 1
                        continue
                    # Leaves the block: it keeps its last section point and its steps so far
                    # (counted per period, as a period is the unit of work).
                    status[slot[p]] = code
                    nsteps[slot[p]] += steps_per_period
                    n_live -= 1
                    _swap(p, n_live, slot, yq, yr, kq, kr)
                if n_live == 0:
                    break
            for p in range(n_live):
                i = slot[p]
                nsteps[i] += steps_per_period
                y[i, 0] = yq[p]
                y[i, 1] = yr[p]
                if store:
                    out[i, j, 0] = yq[p]
                    out[i, j, 1] = yr[p]
                npts[i] = j + 1


@_jit
def advance_adaptive_block(
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
    out,
    npts,
    store,
    rtol,
    atol,
    max_steps,
    bound,
    idx,
):
    """Advance the trajectories ``idx`` together, in lock-step, with one adaptive step sequence.

    Same arguments and outputs as :func:`advance_adaptive`. The step is accepted only if
    every trajectory's own error norm is <= 1, so each meets its tolerance; the field's
    coefficients are computed once per stage for the whole block (they depend on t
    only), which is what makes this faster. A trajectory that fails (escapes, overflows,
    or alone forces the step below the round-off floor) leaves the block; the others go on.

    Layout, for speed: live trajectories are kept packed at the front (a failed one is
    swapped with the last live one) and stages are stored as ``(stage, trajectory)``
    rows, so every inner loop runs over a contiguous, branch-free range and vectorises.
    """
    s = b_vec.shape[0]
    m = idx.shape[0]
    kq = np.empty((s + 1, m))
    kr = np.empty((s + 1, m))
    yq = np.empty(m)
    yr = np.empty(m)
    qn = np.empty(m)
    rn = np.empty(m)
    sq = np.empty(m)
    sr = np.empty(m)
    errp = np.empty(m)
    err3 = np.empty(m)
    # Weights as rows of 2-D arrays, so _combine sees one array type for all of them.
    b_mat = b_vec.reshape(1, s)
    e_mat = np.empty((3, s + 1))
    e_mat[0] = e_vec[: s + 1]
    e_mat[1] = e5_vec[: s + 1]
    e_mat[2] = e3_vec[: s + 1]
    slot = np.empty(m, dtype=np.int64)
    c = np.empty((2, 6))
    work = np.empty((2, 6))
    d = 1.0 if period > 0.0 else -1.0
    span = abs(period)
    expo = -1.0 / (error_order + 1.0)
    n_live = 0
    habs = 0.0
    for p in range(m):
        i = idx[p]
        npts[i] = 0
        if status[i] == _OK:
            slot[n_live] = i
            yq[n_live] = y[i, 0]
            yr[n_live] = y[i, 1]
            n_live += 1
            if h[i] > 0.0 and (habs == 0.0 or h[i] < habs):
                habs = h[i]
    if n_live == 0:
        return
    for j in range(n_periods):
        ta = t_base + (k_first + j) * period
        tb = t_base + (k_first + j + 1) * period
        t = ta
        _coefs(num, gpc, den, forcing, t, c)
        p = 0
        while p < n_live:
            qq = yq[p]
            rr = yr[p]
            fq = c[0, 0] + qq * (c[0, 1] + c[0, 3] * qq + c[0, 4] * rr) + rr * (c[0, 2] + c[0, 5] * rr)
            fr = c[1, 0] + qq * (c[1, 1] + c[1, 3] * qq + c[1, 4] * rr) + rr * (c[1, 2] + c[1, 5] * rr)
            kq[0, p] = fq
            kr[0, p] = fr
            if not (math.isfinite(fq) and math.isfinite(fr)):
                status[slot[p]] = _NONFINITE
                n_live -= 1
                _swap(p, n_live, slot, yq, yr, kq, kr)
            else:
                p += 1
        if n_live == 0:
            break
        if habs <= 0.0:
            habs = span
            for p in range(n_live):
                hp = _initial_step(
                    num, gpc, den, forcing, t, yq[p], yr[p], kq[0, p], kr[0, p], d, span, order, rtol, atol, work
                )
                habs = min(habs, hp)
        steps = 0
        saw_nonfinite = False
        while n_live > 0:
            remaining = (tb - t) * d
            if remaining <= 0.0:
                break
            hmin = 10.0 * _EPS * max(abs(t), span)
            hstep = habs
            last = False
            if hstep >= remaining - hmin:
                hstep = remaining
                last = True
            hs = d * hstep
            n = n_live
            for st in range(1, s):
                _coefs(num, gpc, den, forcing, t + c_vec[st] * hs, c)
                _combine(a_mat, st, hs, st, kq, kr, n, sq, sr)
                _field(c, yq, yr, sq, sr, n, kq, kr, st)
            tn = tb if last else t + hs
            _coefs(num, gpc, den, forcing, tn, c)
            _combine(b_mat, 0, hs, s, kq, kr, n, sq, sr)
            for p in range(n):
                qn[p] = yq[p] + sq[p]
                rn[p] = yr[p] + sr[p]
            _field(c, yq, yr, sq, sr, n, kq, kr, s)  # FSAL: f at the new state
            if dop853_error:
                # Hairer's combined estimate from the 5th- and 3rd-order embedded solutions.
                _combine(e_mat, 1, 1.0, s + 1, kq, kr, n, sq, sr)
                _scaled_norm2(sq, sr, yq, yr, qn, rn, atol, rtol, n, errp)
                _combine(e_mat, 2, 1.0, s + 1, kq, kr, n, sq, sr)
                _scaled_norm2(sq, sr, yq, yr, qn, rn, atol, rtol, n, err3)
                for p in range(n):
                    den2 = (errp[p] + 0.01 * err3[p]) * 2.0
                    errp[p] = hstep * errp[p] / math.sqrt(den2) if den2 > 0.0 else 0.0
            else:
                _combine(e_mat, 0, 1.0, s + 1, kq, kr, n, sq, sr)
                _scaled_norm2(sq, sr, yq, yr, qn, rn, atol, rtol, n, errp)
                for p in range(n):
                    errp[p] = hstep * math.sqrt(0.5 * errp[p])
            err = 0.0
            worst = -1
            any_nonfinite = False
            for p in range(n):
                ep = errp[p]
                if not (math.isfinite(ep) and math.isfinite(kq[s, p]) and math.isfinite(kr[s, p])):
                    any_nonfinite = True
                    ep = math.inf
                if ep > err:
                    err = ep
                    worst = p
            steps += 1
            if err <= 1.0:
                t = tn
                p = 0
                while p < n_live:
                    yq[p] = qn[p]
                    yr[p] = rn[p]
                    kq[0, p] = kq[s, p]
                    kr[0, p] = kr[s, p]
                    if abs(qn[p]) > bound or abs(rn[p]) > bound:
                        status[slot[p]] = _ESCAPED
                        nsteps[slot[p]] += steps
                        n_live -= 1
                        _swap(p, n_live, slot, yq, yr, kq, kr)
                        qn[p], qn[n_live] = qn[n_live], qn[p]
                        rn[p], rn[n_live] = rn[n_live], rn[p]
                    else:
                        p += 1
                factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err**expo)
                habs = max(habs, hstep * factor) if last else hstep * factor
            else:
                if any_nonfinite:
                    saw_nonfinite = True
                    habs = hstep * _MIN_FACTOR
                else:
                    habs = hstep * max(_MIN_FACTOR, _SAFETY * err**expo)
                if habs < hmin:
                    status[slot[worst]] = _NONFINITE if saw_nonfinite else _COLLAPSED
                    nsteps[slot[worst]] += steps
                    n_live -= 1
                    _swap(worst, n_live, slot, yq, yr, kq, kr)
                    saw_nonfinite = False
                    habs = hstep
            if steps >= max_steps:
                for p in range(n_live):
                    status[slot[p]] = _TOO_MANY
                    nsteps[slot[p]] += steps
                n_live = 0
        for p in range(n_live):
            i = slot[p]
            nsteps[i] += steps
            y[i, 0] = yq[p]
            y[i, 1] = yr[p]
            if store:
                out[i, j, 0] = yq[p]
                out[i, j, 1] = yr[p]
            npts[i] = j + 1
        if n_live == 0:
            break
    for p in range(m):
        h[idx[p]] = habs


# ---------------------------------------------------------------------------
# Methods as data, and the batch driver.


@dataclass(frozen=True)
class Method:
    """An integration method: its name, order and (for adaptive ones) tableau."""

    name: str
    order: int
    adaptive: bool
    error_order: int = 0
    stages: int = 4
    a: np.ndarray | None = None
    b: np.ndarray | None = None
    c: np.ndarray | None = None
    e: np.ndarray | None = None
    e3: np.ndarray | None = None
    e5: np.ndarray | None = None


def _square(a: np.ndarray) -> np.ndarray:
    s = a.shape[0]
    out = np.zeros((s, s))
    out[:, : a.shape[1]] = a
    return np.ascontiguousarray(out)


_EMPTY = np.zeros(1)
METHODS: dict[str, Method] = {
    "rk4": Method("rk4", 4, False),
    # RK4 as a tableau for the generic kernel (cross-checks the hand-written one).
    "rk4-tableau": Method(
        "rk4-tableau",
        4,
        False,
        3,
        4,
        tableaus.RK4_A.copy(),
        tableaus.RK4_B.copy(),
        tableaus.RK4_C.copy(),
        np.zeros(5),
        np.zeros(5),
        np.zeros(5),
    ),
    "dp5": Method(
        "dp5",
        tableaus.DP5_ORDER,
        True,
        tableaus.DP5_ERROR_ORDER,
        6,
        _square(tableaus.DP5_A),
        tableaus.DP5_B.copy(),
        tableaus.DP5_C.copy(),
        tableaus.DP5_E.copy(),
        np.zeros(7),
        np.zeros(7),
    ),
    "dop853": Method(
        "dop853",
        tableaus.DOP853_ORDER,
        True,
        tableaus.DOP853_ERROR_ORDER,
        12,
        _square(tableaus.DOP853_A),
        tableaus.DOP853_B.copy(),
        tableaus.DOP853_C.copy(),
        np.zeros(13),
        tableaus.DOP853_E3.copy(),
        tableaus.DOP853_E5.copy(),
    ),
}


def get_method(name: str) -> Method:
    """The method called ``name``; a ValueError names the bad value and the choices."""
    try:
        return METHODS[str(name).lower()]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}") from None


@dataclass
class Batch:
    """Mutable state of a batch of trajectories between section times.

    ``k`` is the section index of the current state (time ``t0 + k * period``;
    ``period`` is negative for backward integration).
    """

    y: np.ndarray  # (n, 2)
    h: np.ndarray  # (n,) adaptive step memory
    status: np.ndarray  # (n,) int64, Status codes
    nsteps: np.ndarray  # (n,) int64, steps taken (accepted + rejected)
    k: int
    t0: float
    period: float

    @classmethod
    def start(cls, ics: np.ndarray, t0: float, period: float, k: int = 0) -> Batch:
        ics = np.ascontiguousarray(np.asarray(ics, dtype=float).reshape(-1, 2))
        n = ics.shape[0]
        status = np.zeros(n, dtype=np.int64)
        status[~np.all(np.isfinite(ics), axis=1)] = _NONFINITE
        return cls(ics.copy(), np.zeros(n), status, np.zeros(n, dtype=np.int64), k, float(t0), float(period))

    @property
    def n(self) -> int:
        return self.y.shape[0]


_executor_lock = threading.Lock()
_executor: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    global _executor
    with _executor_lock:
        if _executor is None:
            _executor = ThreadPoolExecutor(max_workers=config.N_WORKERS, thread_name_prefix="bilimovich-kernel")
        return _executor


def _split(n: int, parts: int) -> list[np.ndarray]:
    # Interleaved split balances cost: drifting (expensive) trajectories tend to cluster.
    return [np.arange(w, n, parts, dtype=np.int64) for w in range(parts) if w < n]


def advance(
    model: Model,
    batch: Batch,
    n_periods: int,
    *,
    method: str = config.DEFAULT_METHOD,
    rtol: float = config.DEFAULT_RTOL,
    atol: float = config.DEFAULT_ATOL,
    steps_per_period: int = config.DEFAULT_STEPS_PER_PERIOD,
    bound: float = config.DEFAULT_ESCAPE_BOUND,
    max_steps: int = config.DEFAULT_MAX_STEPS_PER_PERIOD,
    adaptive: bool = True,
    store: bool = True,
    workers: int | None = None,
    block: int = config.BLOCK_SIZE,
) -> tuple[np.ndarray, np.ndarray]:
    """Advance every live trajectory of ``batch`` by ``n_periods`` periods.

    ``adaptive=False`` runs an embedded pair (dp5, dop853) at ``steps_per_period``
    fixed steps; rk4 is always fixed-step. With ``block > 1`` the adaptive methods
    integrate blocks of up to ``block`` trajectories in lock-step
    (:func:`advance_adaptive_block`): trajectories are grouped by the size of their
    state (a proxy for how fast they rotate), deterministically, so results do not
    depend on the number of workers. ``block=1`` uses one step sequence per trajectory.

    Returns
    -------
    points : (n, n_periods, 2) array
        Section points; only ``points[i, :npts[i]]`` are data (the rest is unset).
    npts : (n,) int array
        Number of valid section points each trajectory produced in this call.
    """
    meth = get_method(method)
    n = batch.n
    n_periods = int(n_periods)
    out = np.empty((n, n_periods if store else 1, 2))
    npts = np.zeros(n, dtype=np.int64)
    if n == 0 or n_periods <= 0:
        return out[:, :0], npts
    args_common = (model.num, model.gpc, model.den, np.ascontiguousarray(model.forcing))
    run: Callable[[np.ndarray], None]
    if meth.a is not None:

        def run(idx: np.ndarray) -> None:
            advance_adaptive(
                meth.a,
                meth.b,
                meth.c,
                meth.e,
                meth.e3,
                meth.e5,
                meth.name == "dop853",
                float(meth.order),
                float(meth.error_order),
                *args_common,
                batch.t0,
                batch.period,
                batch.k,
                n_periods,
                batch.y,
                batch.h,
                batch.status,
                batch.nsteps,
                out,
                npts,
                store,
                float(rtol),
                float(atol),
                int(max_steps),
                float(bound),
                0 if (adaptive and meth.adaptive) else int(steps_per_period),
                idx,
            )

    else:

        def run(idx: np.ndarray) -> None:
            advance_rk4(
                *args_common,
                batch.t0,
                batch.period,
                batch.k,
                n_periods,
                int(steps_per_period),
                batch.y,
                batch.status,
                batch.nsteps,
                out,
                npts,
                store,
                float(bound),
                idx,
            )

    parts = max(1, min(workers or config.N_WORKERS, n))
    lockstep = meth.adaptive and adaptive and block > 1
    if lockstep:
        kernel_args = (meth.a, meth.b, meth.c, meth.e, meth.e3, meth.e5, meth.name == "dop853", float(meth.order),
                       float(meth.error_order), *args_common, batch.t0, batch.period, batch.k, n_periods, batch.y,
                       batch.h, batch.status, batch.nsteps, out, npts, store, float(rtol), float(atol),
                       int(max_steps), float(bound))  # fmt: skip
        alive = np.flatnonzero(batch.status == Status.OK)
        speed = np.max(np.abs(batch.y[alive]), axis=1)
        order = alive[np.argsort(speed, kind="stable")]
        blocks = [order[i : i + block] for i in range(0, order.size, block)]
        npts[:] = 0

        # Workers pull the next block when they finish one: block costs differ a lot
        # (drifting trajectories need many more steps), so a fixed share would idle a core.
        # The blocks are sorted by state size; the costly (large) ones go first.
        queue = iter(blocks[::-1])
        queue_lock = threading.Lock()

        def run_blocks() -> None:
            while True:
                with queue_lock:
                    b = next(queue, None)
                if b is None:
                    return
                advance_adaptive_block(*kernel_args, np.ascontiguousarray(b, dtype=np.int64))

        if parts <= 1 or len(blocks) <= 1:
            run_blocks()
        else:
            futures = [_pool().submit(run_blocks) for _ in range(min(parts, len(blocks)))]
            for f in futures:
                f.result()
    elif parts <= 1:
        run(np.arange(n, dtype=np.int64))
    else:
        # Each worker touches only its own rows of the shared arrays.
        futures = [_pool().submit(run, idx) for idx in _split(n, parts)]
        for f in futures:
            f.result()
    batch.k += n_periods
    return out, npts


def warmup() -> None:
    """Compile (or load from the on-disk cache) every kernel, so no user waits for it."""
    from explorer_core.system.model import Params

    model = Model(Params())
    for name in METHODS:
        for block in (1, config.BLOCK_SIZE):
            batch = Batch.start(np.array([[0.1, 0.2], [0.3, 0.1]]), 0.0, 2 * math.pi)
            advance(model, batch, 1, method=name, steps_per_period=8, workers=1, block=block)


def warmup_all() -> None:
    """Compile every numba kernel of the package: sections and the variational (Lyapunov) one."""
    from explorer_core.analyses import lyapunov

    warmup()
    lyapunov.warmup()
