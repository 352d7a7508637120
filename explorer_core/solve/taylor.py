"""Taylor's method for the field: the engine's other arithmetic, for high accuracy.

The field is ``X = c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2`` with coefficients that depend on ``t``
alone (:mod:`explorer_core.system.model`), so the Taylor coefficients of a trajectory follow from
products of series (automatic differentiation, Jorba & Zou 2005, *Experimental Mathematics* 14):

* the **coefficient series** ``c_m(t_n + tau) = sum_k c_m[k] tau^k`` come from the series of
  ``cos(w t)``, ``sin(w t)`` (closed form), of ``g``, ``g'``, ``g^2 .. g^4`` (Cauchy products) and one
  division by the series of ``D(g)`` per coefficient. They depend on ``t`` only, so a lock-step block
  computes them **once per step** for all its members (one parameter set), or once per member;
* the **state series** ``q[k + 1] = Q[k] / (k + 1)`` with ``Q = c0 + q (c1 + c3 q + c4 r) + r (c2 + c5 r)``,
  the factors' series built order by order as the state's coefficients appear (10 products of series
  per order for both rows).

Order and step from the tolerance as in Jorba & Zou (and heyoka, Biscani & Izzo 2021, MNRAS 504):
order ``p = ceil(-ln(rtol) / 2 + 1)``; per member ``rho_k = (s / ||x[k]||_inf)^(1/k)`` for ``k = p - 1, p``
with ``s = max(atol / rtol, ||x[0]||_inf)`` (absolute control for small states, relative for large),
and step ``h = min(rho_{p-1}, rho_p) / e^2 * exp(-0.7 / (p - 1))``. No step is rejected. The block
takes the smallest of its members' steps; the step that would pass the section time ``t_base + k
period`` is shortened exactly to it (the polynomial is evaluated at the shorter step), so section
points carry no interpolation error.

Statuses exactly as the engine's (:class:`explorer_core.solve.rk.Status`): a member whose series is
not finite leaves as ``NONFINITE``, one that leaves the bound as ``ESCAPED``, one whose step falls below
the round-off floor ``10 eps max(|t|, period)`` as ``STEP_COLLAPSED``; a period that needs more than
``max_steps`` steps ends every live member as ``TOO_MANY_STEPS``. Each keeps its last section state.

Only the section system (:data:`explorer_core.solve.rk.FIELD`) so far: the tangent systems go
through the Runge-Kutta engine.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from explorer_core.solve.rk import FIELD, STATE_SIZE, Status
from explorer_core.system.params import ParameterError

_OK, _ESCAPED, _COLLAPSED, _TOO_MANY, _NONFINITE = (int(s) for s in Status if s.engine)
_EPS = float(np.finfo(float).eps)
_BIG = float(np.finfo(float).max)
#: The highest order (rtol 1e-15 needs 19; the bound only sizes the scratch arrays).
MAX_ORDER = 40
#: Jorba & Zou's safety factor ``exp(-0.7 / (p - 1)) / e^2`` without the exponential.
_INV_E2 = math.exp(-2.0)

_leaf = nb.njit(nogil=True, cache=True, error_model="numpy", _nrt=False)
_kernel = nb.njit(nogil=True, cache=True, error_model="numpy", _nrt=False)


def taylor_order(rtol: float) -> int:
    """Jorba & Zou's order for a relative tolerance: ``ceil(-ln(rtol) / 2 + 1)``, at least 2."""
    if not (isinstance(rtol, int | float) and math.isfinite(rtol) and 0.0 < rtol <= 1.0):
        raise ValueError(f"rtol must be a number in (0, 1], got {rtol!r}")
    p = max(2, math.ceil(-math.log(rtol) / 2.0 + 1.0))
    if p > MAX_ORDER:
        raise ValueError(f"rtol {rtol!r} needs Taylor order {p}, above the largest, {MAX_ORDER}")
    return p


# ---------------------------------------------------------------------------
# Series arithmetic.


@_leaf
def _cauchy(a, b, k) -> float:
    """Coefficient ``k`` of the product of the series ``a`` and ``b``."""
    total = 0.0
    for j in range(k + 1):
        total += a[j] * b[k - j]
    return total


@_leaf
def coefficient_series(num, gpc, den, forcing, s, t, order, w, cs, o) -> None:
    """``cs[o, row, m, k]``, ``k = 0..order``: the Taylor coefficients in ``tau`` of the field's coefficient
    ``c_m(t + tau)`` of row ``row`` (Q, R) for parameter set ``s`` (stacked tables, as the engine's).

    ``w`` (8, order + 2) is scratch: the series of cos, sin, g, g', g^2, g^3, g^4 and D(g).
    """
    om = forcing[s, 3]
    cw = math.cos(om * t)
    sw = math.sin(om * t)
    # cos(om (t + tau)) = sum_k cos(om t + k pi/2) (om tau)^k / k!, and the same for sin.
    fac = 1.0
    for k in range(order + 2):
        ph = k % 4
        cc = cw if ph == 0 else (-sw if ph == 1 else (-cw if ph == 2 else sw))
        ss = sw if ph == 0 else (cw if ph == 1 else (-sw if ph == 2 else -cw))
        w[0, k] = cc * fac
        w[1, k] = ss * fac
        fac *= om / (k + 1)
    for k in range(order + 2):
        w[2, k] = forcing[s, 1] * w[0, k] + forcing[s, 2] * w[1, k]
    w[2, 0] += forcing[s, 0]
    for k in range(order + 1):
        w[3, k] = (k + 1) * w[2, k + 1]  # g'
    for k in range(order + 1):
        w[4, k] = _cauchy(w[2], w[2], k)  # g^2
    for k in range(order + 1):
        w[5, k] = _cauchy(w[4], w[2], k)  # g^3
    for k in range(order + 1):
        w[6, k] = _cauchy(w[4], w[4], k)  # g^4
    for k in range(order + 1):
        w[7, k] = den[s, 1] * w[2, k] + den[s, 2] * w[4, k]  # D(g)
    w[7, 0] += den[s, 0]
    d0 = 1.0 / w[7, 0]
    for row in range(2):
        for m in range(6):
            for k in range(order + 1):
                # numerator N_m(g) (+ g' (G0 + G1 g) on the q monomial), then divided by D(g)
                x = num[s, row, m, 1] * w[2, k] + num[s, row, m, 2] * w[4, k] + num[s, row, m, 3] * w[5, k]
                x += num[s, row, m, 4] * w[6, k]
                if k == 0:
                    x += num[s, row, m, 0]
                if m == 1:
                    x += gpc[s, row, 0] * w[3, k] + gpc[s, row, 1] * _cauchy(w[3], w[2], k)
                for j in range(1, k + 1):
                    x -= w[7, j] * cs[o, row, m, k - j]
                cs[o, row, m, k] = x * d0


@_leaf
def state_series(cs, shared, order, x, a, f, n) -> None:
    """The Taylor coefficients ``x[comp, k, p]`` (``k = 1..order``) of the ``n`` members from ``x[:, 0, p]``.

    ``cs`` (1 or n, 2, 6, order + 1) the coefficient series (``shared``: row 0 for all); ``a`` (4, order + 1, n)
    the series of ``c1 + c3 q + c4 r`` and ``c2 + c5 r`` of each row, so ``X = c0 + q (c1 + c3 q + c4 r) +
    r (c2 + c5 r)`` costs 10 products of series per order (13 with the monomials ``q^2, q r, r^2``); ``f`` (2, n)
    scratch. Members innermost: the loops run over contiguous members and vectorise.
    """
    for k in range(order):
        # the factors' coefficient k (they need the state's up to k, known now)
        for p in range(n):
            o = 0 if shared else p
            a[0, k, p] = cs[o, 0, 1, k]
            a[1, k, p] = cs[o, 0, 2, k]
            a[2, k, p] = cs[o, 1, 1, k]
            a[3, k, p] = cs[o, 1, 2, k]
        for j in range(k + 1):
            i = k - j
            if shared:
                a3, a4, a5 = cs[0, 0, 3, j], cs[0, 0, 4, j], cs[0, 0, 5, j]
                b3, b4, b5 = cs[0, 1, 3, j], cs[0, 1, 4, j], cs[0, 1, 5, j]
                for p in range(n):
                    qi = x[0, i, p]
                    ri = x[1, i, p]
                    a[0, k, p] += a3 * qi + a4 * ri
                    a[1, k, p] += a5 * ri
                    a[2, k, p] += b3 * qi + b4 * ri
                    a[3, k, p] += b5 * ri
            else:
                for p in range(n):
                    qi = x[0, i, p]
                    ri = x[1, i, p]
                    a[0, k, p] += cs[p, 0, 3, j] * qi + cs[p, 0, 4, j] * ri
                    a[1, k, p] += cs[p, 0, 5, j] * ri
                    a[2, k, p] += cs[p, 1, 3, j] * qi + cs[p, 1, 4, j] * ri
                    a[3, k, p] += cs[p, 1, 5, j] * ri
        for p in range(n):
            o = 0 if shared else p
            f[0, p] = cs[o, 0, 0, k]
            f[1, p] = cs[o, 1, 0, k]
        for j in range(k + 1):
            i = k - j
            for p in range(n):
                qj = x[0, j, p]
                rj = x[1, j, p]
                f[0, p] += qj * a[0, i, p] + rj * a[1, i, p]
                f[1, p] += qj * a[2, i, p] + rj * a[3, i, p]
        inv = 1.0 / (k + 1)
        for p in range(n):
            x[0, k + 1, p] = f[0, p] * inv
            x[1, k + 1, p] = f[1, p] * inv


@_leaf
def _member_step(x, order, p, scale) -> float:
    """Jorba & Zou's step for member ``p`` from its last two Taylor coefficients (inf if both vanish, NaN if
    not finite)."""
    s = max(scale, abs(x[0, 0, p]), abs(x[1, 0, p]))
    n1 = max(abs(x[0, order - 1, p]), abs(x[1, order - 1, p]))
    n2 = max(abs(x[0, order, p]), abs(x[1, order, p]))
    if not (math.isfinite(n1) and math.isfinite(n2)):
        return math.nan
    rho = math.inf
    if n1 > 0.0:
        rho = (s / n1) ** (1.0 / (order - 1))
    if n2 > 0.0:
        rho = min(rho, (s / n2) ** (1.0 / order))
    return rho * _INV_E2 * math.exp(-0.7 / (order - 1))


@_leaf
def _swap(p, last, slot, x) -> None:
    # Move member p out of the packed live range [0, last): exchange its state with the last live one's.
    slot[p], slot[last] = slot[last], slot[p]
    for comp in range(2):
        x[comp, 0, p], x[comp, 0, last] = x[comp, 0, last], x[comp, 0, p]


@_leaf
def _series_into(num, gpc, den, forcing, row, shared, t, order, w, slot, n, cs) -> None:
    # The coefficient series at t: once for the block, or once per live member's parameter set.
    if shared:
        coefficient_series(num, gpc, den, forcing, 0, t, order, w, cs, 0)
    else:
        for p in range(n):
            coefficient_series(num, gpc, den, forcing, row[slot[p]], t, order, w, cs, p)


@_kernel
def taylor_blocks(co, clock, ctl, arr, idx, block, order, w, cs, x, a, f, hp, slot) -> None:
    """Advance the trajectories ``idx`` of the field by ``clock.n_periods`` periods, ``block`` at a time in lock-step.

    The engine's structures (:mod:`explorer_core.solve.rk`: ``Coefficients``, ``Clock``, ``Control``,
    ``Arrays``); ``ctl.fixed_steps`` is ignored (the order and step come from ``rtol``/``atol``).
    Scratch: ``w`` (8, order + 2), ``cs`` (1 or block, 2, 6, order + 1), ``x`` (2, order + 1, block),
    ``a`` (4, order + 1, block), ``f`` (2, block), ``hp`` (block,), ``slot`` (block,) int64.
    """
    num, gpc, den, forcing, row = co.num, co.gpc, co.den, co.forcing, co.row
    y, h, status, nsteps, rec, npts = arr.y, arr.h, arr.status, arr.nsteps, arr.rec, arr.npts
    rtol, atol, bound = ctl.rtol, ctl.atol, ctl.bound
    lim = min(bound, _BIG)
    t_base, period, k_first, store = clock.t_base, clock.period, clock.k_first, clock.store
    shared = num.shape[0] == 1
    scale = atol / rtol
    d = 1.0 if period > 0.0 else -1.0
    span = abs(period)
    for b0 in range(0, idx.shape[0], block):
        members = idx[b0 : b0 + block]
        m = members.shape[0]
        n_live = 0
        for p in range(m):
            i = members[p]
            npts[i] = 0
            if status[i] == _OK:
                slot[n_live] = i
                x[0, 0, n_live] = y[i, 0]
                x[1, 0, n_live] = y[i, 1]
                n_live += 1
        h_last = 0.0
        for j in range(clock.n_periods):
            if n_live == 0:
                break
            ta = t_base + (k_first + j) * period
            tb = t_base + (k_first + j + 1) * period
            t = ta
            steps = 0
            while n_live > 0:
                remaining = (tb - t) * d
                if remaining <= 0.0:
                    break
                if steps >= ctl.max_steps:
                    for p in range(n_live):
                        status[slot[p]] = _TOO_MANY
                        nsteps[slot[p]] += steps
                    n_live = 0
                    break
                hmin = 10.0 * _EPS * max(abs(t), span)
                _series_into(num, gpc, den, forcing, row, shared, t, order, w, slot, n_live, cs)
                state_series(cs, shared, order, x, a, f, n_live)
                # Each member's step; a member with a non-finite series or a collapsed step leaves.
                hstep = remaining
                p = 0
                while p < n_live:
                    hm = _member_step(x, order, p, scale)
                    if not math.isnan(hm) and hm >= hmin:
                        hp[p] = hm
                        hstep = min(hstep, hm)
                        p += 1
                        continue
                    status[slot[p]] = _NONFINITE if math.isnan(hm) else _COLLAPSED
                    nsteps[slot[p]] += steps
                    n_live -= 1
                    _swap(p, n_live, slot, x)
                    # its series moved too: recompute it for the member now at p on the next step; this step
                    # uses the others' series, which _swap left in place for members before p
                    for comp in range(2):
                        for k in range(1, order + 1):
                            x[comp, k, p] = x[comp, k, n_live]
                    if not shared:
                        for r_ in range(2):
                            for mm in range(6):
                                for k in range(order + 1):
                                    cs[p, r_, mm, k] = cs[n_live, r_, mm, k]
                if n_live == 0:
                    break
                last = hstep >= remaining - hmin  # land exactly on the section time; absorb a sliver
                if last:
                    hstep = remaining
                else:
                    h_last = hstep
                hs = d * hstep
                for p in range(n_live):
                    for comp in range(2):
                        v = x[comp, order, p]
                        for k in range(order - 1, -1, -1):
                            v = v * hs + x[comp, k, p]
                        x[comp, 0, p] = v
                t = tb if last else t + hs
                steps += 1
                p = 0
                while p < n_live:
                    qn = x[0, 0, p]
                    rn = x[1, 0, p]
                    if abs(qn) <= lim and abs(rn) <= lim:
                        p += 1
                        continue
                    finite = math.isfinite(qn) and math.isfinite(rn)
                    status[slot[p]] = _ESCAPED if finite else _NONFINITE
                    nsteps[slot[p]] += steps
                    n_live -= 1
                    _swap(p, n_live, slot, x)
            for p in range(n_live):
                i = slot[p]
                if store:
                    rec[i, j, 0] = x[0, 0, p]
                    rec[i, j, 1] = x[1, 0, p]
                nsteps[i] += steps
                y[i, 0] = x[0, 0, p]
                y[i, 1] = x[1, 0, p]
                npts[i] = j + 1
        for p in range(m):
            h[members[p]] = h_last


def advance_blocks(system: int, co, clock, ctl, arr, idx: np.ndarray, block: int) -> None:
    """Taylor's method on the trajectories ``idx`` (the engine's :func:`explorer_core.solve.rk.advance_blocks`).

    ``block = 1`` gives every trajectory its own step sequence. The kernel releases the GIL.
    """
    if system != FIELD:
        raise ParameterError(
            "method taylor integrates sections only for now (not the tangent system of orbits, continuation, "
            "manifolds or Lyapunov spectra): choose dop853 there"
        )
    if arr.y.shape[1] != STATE_SIZE[FIELD]:
        raise ValueError(f"the field has {STATE_SIZE[FIELD]} state components, the batch {arr.y.shape[1]}")
    order = taylor_order(ctl.rtol)
    m = max(1, min(int(block), idx.shape[0]))
    shared = co.num.shape[0] == 1
    taylor_blocks(co, clock, ctl, arr, idx, m, order, np.empty((8, order + 2)),
                  np.empty((1 if shared else m, 2, 6, order + 1)), np.empty((2, order + 1, m)),
                  np.empty((4, order + 1, m)), np.empty((2, m)), np.empty(m), np.empty(m, dtype=np.int64))  # fmt: skip


def series_at(co, s: int, t: float, q: float, r: float, order: int) -> np.ndarray:
    """The Taylor coefficients ``(2, order + 1)`` of the trajectory through ``(q, r)`` at time ``t`` (parameter set
    ``s`` of ``co``): the kernel's own arithmetic, for tests and diagnostics."""
    if not 2 <= order <= MAX_ORDER:
        raise ValueError(f"order must be an integer in [2, {MAX_ORDER}], got {order!r}")
    cs = np.empty((1, 2, 6, order + 1))
    coefficient_series(co.num, co.gpc, co.den, co.forcing, int(s), float(t), order, np.empty((8, order + 2)), cs, 0)
    x = np.zeros((2, order + 1, 1))
    x[0, 0, 0], x[1, 0, 0] = q, r
    state_series(cs, True, order, x, np.empty((4, order + 1, 1)), np.empty((2, 1)), 1)
    return x[:, :, 0]
