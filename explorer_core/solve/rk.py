"""The Runge-Kutta engine: the one place where the package does Runge-Kutta arithmetic.

Every trajectory the package integrates goes through :func:`advance_blocks`: sections (one step
sequence per trajectory, or blocks in lock-step), fixed-step RK4, the tangent system behind the
Lyapunov spectrum and the monodromy matrix of the Poincare map, and the lock-step ceiling of the
benchmark. What varies is data:

* the **method** is a :class:`Tableau` (``a, b, c`` and the embedded error weights, from
  :mod:`explorer_core.solve.tableaus`); ``Control.fixed_steps > 0`` takes that many equal steps per
  period with no error control (RK4 always does);
* the **system** is a code: :data:`FIELD` ``(q, r)`` with ``q' = Q, r' = R``; :data:`TANGENT`, the field
  with its variational matrix ``Phi' = J Phi`` and ``s' = div = tr J`` (the derived system of
  DynamicalSystemsBase's ``TangentDynamicalSystem``), whose record is the whole state (the monodromy
  matrix of the map is ``Phi`` after ``n`` periods from ``Phi = I``); :data:`LYAPUNOV`, the same with
  ``Phi`` re-orthonormalised at every section time (and inside a period when it becomes ill-conditioned),
  recording ``log R_11, log R_22`` and ``int div`` of each period; :data:`BODY`, the field with the body's
  orientation as a unit quaternion ``(w, x, y, z)`` (body -> space), ``Q' = 1/2 Q (x) (0, omega)`` with
  ``omega = (alpha + g q, q, r)``, recording the state at ``Clock.samples`` equally spaced times inside
  each period (the steps land on them exactly, as on section times), so an animation has frames;
* the **parameters** are :class:`Coefficients`: one row of coefficient tables per parameter set, and
  the row of every trajectory, so the members of one lock-step block may have different parameters
  (charts, continuation); with a single row the coefficients are computed once per stage for the whole
  block, which is what makes lock-step fast.

Members of a block share one step sequence; a step is accepted only if every member's own error norm
is <= 1, so each meets its tolerance (a block of one is an ordinary adaptive integrator). Every
period ends exactly on the section time ``t_base + k period`` (computed, never accumulated): the last
step is clipped to it. Time is kept inside the period (0 to ``period``) and the coefficients are taken at
``t_base`` plus it, the same phase of the periodic forcing: a stage time keeps its digits however many
periods in (as ``t0 + k T + t`` it was rounded to ulp(t), the error floor of long runs), and the map from
section ``k`` is the same computation for every ``k``. Failures are data: a member that escapes, overflows,
or alone forces the step below the round-off floor gets its :class:`Status` and leaves the block, keeping its
last section state; the others go on.

Layout, for speed: live members are kept packed at the front of the block (a failed one is swapped
with the last live one) and stages are stored as ``(stage, component, member)``, so every inner loop
runs over a contiguous, branch-free range of members and vectorises.

Controller: Hairer, Norsett & Wanner, *Solving ODEs I*, II.4 (the error norm, the starting step and
the step-size factor, as in scipy's ``solve_ivp``); DOP853's combined 5th/3rd-order error estimate
(ibid. II.10).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from explorer_core import config
from explorer_core.status import Status  # the one vocabulary; the kernels write its codes 0-4
from explorer_core.system.model import (
    DIAGONAL,
    DIAGONAL_HOMOGENEOUS,
    FORM_MASKS,
    GENERAL,
    HOMOGENEOUS,
    forcing_at,
    forcing_of,
    form_coefficients,
    form_gradient,
    form_value,
)

_OK, _ESCAPED, _COLLAPSED, _TOO_MANY, _NONFINITE = (int(s) for s in Status if s.engine)

#: Systems the engine integrates (see the module docstring).
FIELD, TANGENT, LYAPUNOV, BODY = 0, 1, 2, 3
#: State components per system: ``(q, r)``; ``(q, r, Phi[:, 0], Phi[:, 1], int div)``; ``(q, r, w, x, y, z)``.
STATE_SIZE = (2, 7, 7, 6)
#: Values recorded at each section time: ``(q, r)``; the whole state; ``(q, r, log R11, log R22, int div)``;
#: BODY: the whole state at each of the ``samples`` frames of a period (its records are frames, not periods).
RECORD_SIZE = (2, 7, 5, 6)
#: Columns of a coefficient row in the kernels: the six monomials of Q (row 0) and R (row 1); BODY keeps
#: ``g(t)`` and ``alpha`` beside them in row 0 (columns 6 and 7), for ``p = alpha + g q``.
COEF_COLUMNS = (6, 6, 6, 8)
_G, _ALPHA = 6, 7
#: Rows of a block's own copy of its members' tables (``Work.tb``, one column per packed member; blocks with a
#: parameter set per member): ``num`` by (row, monomial, power), ``gpc``, ``den``, ``(g0, g1, g2)``, then scratch
#: ``g``, ``g'`` and ``1 / D(g)`` of the last stage. A stage's coefficients are then one loop over the members
#: per monomial, contiguous and vectorised, with ``cos, sin`` once for the block (the forcings share omega).
_TB_NUM, _TB_GPC, _TB_DEN, _TB_FORCING, _TB_G, _TB_GP, _TB_DINV = 0, 60, 64, 67, 70, 71, 72
TB_ROWS = 73
#: Up to this many live members, a block with a parameter set per member computes each member's coefficients
#: straight from the tables instead (loops over so few members vectorise nothing: continuation's blocks of 2 were
#: ~15% slower over the copied tables).
FEW_MEMBERS = 4
#: Inside a period the Lyapunov basis is re-orthonormalised when the sine of the angle between the
#: tangent vectors drops below this: the perpendicular part of ``v2`` carries ``Lambda_2``, and below
#: it its relative accuracy (about ``rtol / REORTHONORMALISE``) falls.
REORTHONORMALISE = 1e-2

_SAFETY, _MIN_FACTOR, _MAX_FACTOR = config.SAFETY, config.MIN_FACTOR, config.MAX_FACTOR
_EPS = float(np.finfo(float).eps)
_BIG = float(np.finfo(float).max)

#: The pieces of a step: no reference counting (the kernels allocate nothing; an update is an atomic
#: instruction, and passing arrays between pieces would cost two per array); LLVM inlines them, so the
#: kernel's constants (system, state size, block of one) reach inside and their loops unroll and vectorise.
_leaf = nb.njit(nogil=True, cache=True, error_model="numpy", _nrt=False)
#: The step loop itself, inlined once into each kernel (numba IR inlining), where the system is a constant.
_jit_inline = nb.njit(nogil=True, cache=True, error_model="numpy", _nrt=False, inline="always")


class Tableau(NamedTuple):
    """A Runge-Kutta method as the kernel reads it (built by :meth:`explorer_core.solve.tableaus.Method.tableau`).

    ``a`` (s, s), ``b`` (1, s) (a row, so the same combination code serves ``a`` and ``b``), ``c`` (s,);
    ``e`` (3, s + 1): error weights on the stages and the FSAL stage ``f(t + h, y_new)`` -- row 0 a
    standard embedded pair, rows 1 and 2 DOP853's 5th- and 3rd-order estimates (``dop853``).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    e: np.ndarray
    order: float
    error_order: float
    dop853: bool


class Coefficients(NamedTuple):
    """The field's exact coefficient tables (:class:`explorer_core.system.model.Model`), one row per parameter set.

    ``num`` (P, 2, 6, 5), ``gpc`` (P, 2, 2), ``den`` (P, 3), ``forcing`` (P, 4); ``row`` (n,) the parameter
    set of each trajectory; ``alpha`` (P,) the constraint's inhomogeneity of each set, read by BODY only (for
    ``p = alpha + g q``; the field's tables hold alpha already); ``form`` the field's structure
    (:data:`explorer_core.system.model.FORM_MASKS`): the kernels compute and evaluate only its monomials, so it
    must hold every nonzero entry of every row. All rows share the section times (``t0`` and the forcing period).
    """

    num: np.ndarray
    gpc: np.ndarray
    den: np.ndarray
    forcing: np.ndarray
    row: np.ndarray
    alpha: np.ndarray = np.zeros(0)  # none: only BODY reads it (integrators.run checks it has a row per set)
    form: int = GENERAL  # the smallest form that holds every row's tables (model.field_form)


class Control(NamedTuple):
    """Tolerances and budgets: ``fixed_steps > 0`` takes that many equal steps per period, no error control."""

    rtol: float
    atol: float
    max_steps: int
    bound: float
    fixed_steps: int


class Clock(NamedTuple):
    """Section times ``t_base + k period`` (``period < 0`` runs backward); the state is at ``k_first``.

    ``samples``: BODY's frames per period, at ``t_base + k period + period (s / samples)``, ``s = 1 .. samples``
    (the last is the section time); the other systems record at section times only.
    """

    t_base: float
    period: float
    k_first: int
    n_periods: int
    store: bool
    samples: int = 1


class Arrays(NamedTuple):
    """A batch, updated in place: ``y`` (n, STATE_SIZE) the state at the last completed section time;
    ``h`` (n,) step memory (0 = choose a starting step); ``status``, ``nsteps`` (n,); ``rec``
    (n, n_periods, RECORD_SIZE) the records of this call if ``store``; ``npts`` (n,) periods completed in it.
    BODY records frames: ``rec`` (n, n_periods samples, 6) and ``npts`` the frames recorded (a member that fails
    inside a period keeps the frames it reached).
    """

    y: np.ndarray
    h: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    rec: np.ndarray
    npts: np.ndarray


class Work(NamedTuple):
    """Scratch space of one block (made by :func:`work_arrays`): the kernels allocate nothing.

    They run without numba's reference counting (``_nrt=False``): every array they touch is passed in,
    so passing arrays between the inlined pieces of a step costs no atomic reference-count update
    (with it, a block of one trajectory spent 60 % of its time on them).
    """

    k: np.ndarray  # (s + 1, dim, m) the stages and the FSAL stage
    ys: np.ndarray  # (dim, m) the states of the packed live members
    yn: np.ndarray  # (dim, m) the proposed new states
    acc: np.ndarray  # (dim, m) stage sums
    err: np.ndarray  # (m,) error norms
    err3: np.ndarray  # (m,) DOP853's 3rd-order estimate
    lg: np.ndarray  # (2, m) log R_ii of the re-orthonormalisations inside a period
    slot: np.ndarray  # (m,) int64: the batch row of each packed member
    c: np.ndarray  # the coefficients: the block's one set (1, 2, COEF_COLUMNS), or each member's (2, COEF_COLUMNS, m)
    cw: np.ndarray  # (1, 2, COEF_COLUMNS) the coefficients of a starting-step trial
    tb: np.ndarray  # (TB_ROWS, 1 or m) the packed members' tables (unused with one set)


def work_arrays(stages: int, dim: int, m: int, shared: bool, columns: int = 6) -> Work:
    """Scratch space for blocks of up to ``m`` members of a system with ``dim`` state components; ``shared``: each
    block has one parameter set (one set in the tables, or blocks of one member)."""
    each = 1 if shared else m
    return Work(
        np.empty((stages + 1, dim, m)),
        np.empty((dim, m)),
        np.empty((dim, m)),
        np.empty((dim, m)),
        np.empty(m),
        np.empty(m),
        np.zeros((2, m)),
        np.empty(m, dtype=np.int64),
        np.empty((1, 2, columns)) if shared else np.empty((2, columns, m)),
        np.empty((1, 2, columns)),
        np.empty((TB_ROWS, each)),
    )


# ---------------------------------------------------------------------------
# The field and its tangent at one member, in the scene's form (the model's `form_value`, `form_gradient`).
# No array views in the loops: a view costs two atomic reference-count updates, which in a block of
# one trajectory was most of the time.


@_leaf
def _point(system, form, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, g, al, ys, acc, p, k, st) -> None:
    """``k[st, :, p] = f(ys[:, p] + acc[:, p])`` with the coefficients ``a`` (row Q) and ``b`` (row R) in ``form``;
    BODY also reads ``g`` and ``al`` (alpha), the other systems ignore them."""
    q = ys[0, p] + acc[0, p]
    r = ys[1, p] + acc[1, p]
    k[st, 0, p] = form_value(form, 0, a0, a1, a2, a3, a4, a5, q, r)
    k[st, 1, p] = form_value(form, 1, b0, b1, b2, b3, b4, b5, q, r)
    if system == BODY:
        # Q' = 1/2 Q (x) (0, omega), omega = (p, q, r) in the body frame: R(Q)' = R(Q) [omega]_x.
        pb = al + g * q
        w = ys[2, p] + acc[2, p]
        x = ys[3, p] + acc[3, p]
        y = ys[4, p] + acc[4, p]
        z = ys[5, p] + acc[5, p]
        k[st, 2, p] = -0.5 * (x * pb + y * q + z * r)
        k[st, 3, p] = 0.5 * (w * pb + y * r - z * q)
        k[st, 4, p] = 0.5 * (w * q + z * pb - x * r)
        k[st, 5, p] = 0.5 * (w * r + x * q - y * pb)
    elif system != FIELD:
        # The exact Jacobian: the field is quadratic, so J is affine in (q, r).
        j00, j01 = form_gradient(form, 0, a0, a1, a2, a3, a4, a5, q, r)
        j10, j11 = form_gradient(form, 1, b0, b1, b2, b3, b4, b5, q, r)
        v1x = ys[2, p] + acc[2, p]
        v1y = ys[3, p] + acc[3, p]
        v2x = ys[4, p] + acc[4, p]
        v2y = ys[5, p] + acc[5, p]
        no_r = form == DIAGONAL or form == DIAGONAL_HOMOGENEOUS  # dR/dr = 0: the same sums without its terms
        k[st, 2, p] = j00 * v1x + j01 * v1y
        k[st, 3, p] = j10 * v1x if no_r else j10 * v1x + j11 * v1y
        k[st, 4, p] = j00 * v2x + j01 * v2y
        k[st, 5, p] = j10 * v2x if no_r else j10 * v2x + j11 * v2y
        k[st, 6, p] = j00 if no_r else j00 + j11


@_leaf
def _eval_form(system, form, shared, c, ys, acc, lo, hi, k, st) -> None:
    """Stage ``st`` of the members ``lo <= p < hi``: coefficients ``c[0]`` shared, or ``c[:, :, p]`` each member's
    (members last, so the coefficients of a stage are written and read contiguously, see :class:`Work`)."""
    if shared:
        a0, a1, a2, a3, a4, a5 = c[0, 0, 0], c[0, 0, 1], c[0, 0, 2], c[0, 0, 3], c[0, 0, 4], c[0, 0, 5]
        b0, b1, b2, b3, b4, b5 = c[0, 1, 0], c[0, 1, 1], c[0, 1, 2], c[0, 1, 3], c[0, 1, 4], c[0, 1, 5]
        g = c[0, 0, _G] if system == BODY else 0.0  # (only BODY's rows have these columns)
        al = c[0, 0, _ALPHA] if system == BODY else 0.0
        for p in range(lo, hi):
            _point(system, form, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, g, al, ys, acc, p, k, st)
    else:
        for p in range(lo, hi):
            q0, q1, q2, q3, q4, q5 = c[0, 0, p], c[0, 1, p], c[0, 2, p], c[0, 3, p], c[0, 4, p], c[0, 5, p]
            r0, r1, r2, r3, r4, r5 = c[1, 0, p], c[1, 1, p], c[1, 2, p], c[1, 3, p], c[1, 4, p], c[1, 5, p]
            g = c[0, _G, p] if system == BODY else 0.0
            al = c[0, _ALPHA, p] if system == BODY else 0.0
            _point(system, form, q0, q1, q2, q3, q4, q5, r0, r1, r2, r3, r4, r5, g, al, ys, acc, p, k, st)


@_jit_inline
def _eval(system, form, shared, c, ys, acc, lo, hi, k, st) -> None:
    """:func:`_eval_form` with the form a constant in each branch (one test per stage, none per member: the member
    loops stay branch-free and vectorise). Entries outside the form are never read (they may be unset)."""
    if form == DIAGONAL:
        _eval_form(system, DIAGONAL, shared, c, ys, acc, lo, hi, k, st)
    elif form == DIAGONAL_HOMOGENEOUS:
        _eval_form(system, DIAGONAL_HOMOGENEOUS, shared, c, ys, acc, lo, hi, k, st)
    elif form == HOMOGENEOUS:
        _eval_form(system, HOMOGENEOUS, shared, c, ys, acc, lo, hi, k, st)
    else:
        _eval_form(system, GENERAL, shared, c, ys, acc, lo, hi, k, st)


@_leaf
def _coefs_set(form, num, gpc, den, forcing, s, t, c, o) -> None:
    g, gp = forcing_of(forcing, s, t)
    form_coefficients(form, num, gpc, den, s, g, gp, c, o)


@_leaf
def _load_tables(num, gpc, den, forcing, row, slot, n, tb) -> None:
    """Copy the tables of the ``n`` packed members (parameter set ``row[slot[p]]``) into their columns of ``tb``."""
    for p in range(n):
        s = row[slot[p]]
        for rr in range(2):
            for m in range(6):
                for j in range(5):
                    tb[_TB_NUM + 5 * (6 * rr + m) + j, p] = num[s, rr, m, j]
            for j in range(2):
                tb[_TB_GPC + 2 * rr + j, p] = gpc[s, rr, j]
        for j in range(3):
            tb[_TB_DEN + j, p] = den[s, j]
            tb[_TB_FORCING + j, p] = forcing[s, j]


@_leaf
def _block_coefficients(form, tb, cw, sw, w, n, c) -> None:
    """``c[row, m, p]`` for the ``n`` packed members from their tables in ``tb``, at ``cos(w t) = cw``, ``sin = sw``.

    The arithmetic of :func:`~explorer_core.system.model.forcing_at` and
    :func:`~explorer_core.system.model.form_coefficients` (the same numbers), one monomial at a time over the members.
    """
    for p in range(n):
        g = tb[_TB_FORCING, p] + tb[_TB_FORCING + 1, p] * cw + tb[_TB_FORCING + 2, p] * sw
        tb[_TB_G, p] = g
        tb[_TB_GP, p] = w * (tb[_TB_FORCING + 2, p] * cw - tb[_TB_FORCING + 1, p] * sw)
        tb[_TB_DINV, p] = 1.0 / (tb[_TB_DEN, p] + g * (tb[_TB_DEN + 1, p] + g * tb[_TB_DEN + 2, p]))
    for rr in range(2):
        mask = FORM_MASKS[form][rr]
        e = _TB_NUM + 5 * (6 * rr + 1)
        x = _TB_GPC + 2 * rr
        for p in range(n):  # q: every form has it, with the g' term
            g = tb[_TB_G, p]
            v = tb[e, p] + g * (tb[e + 1, p] + g * (tb[e + 2, p] + g * (tb[e + 3, p] + g * tb[e + 4, p])))
            c[rr, 1, p] = (v + tb[_TB_GP, p] * (tb[x, p] + g * tb[x + 1, p])) * tb[_TB_DINV, p]
        for m in (0, 2, 3, 4, 5):
            if (mask >> m) & 1:
                e = _TB_NUM + 5 * (6 * rr + m)
                for p in range(n):
                    g = tb[_TB_G, p]
                    v = tb[e, p] + g * (tb[e + 1, p] + g * (tb[e + 2, p] + g * (tb[e + 3, p] + g * tb[e + 4, p])))
                    c[rr, m, p] = v * tb[_TB_DINV, p]


@_leaf
def _block_set(num, row, slot, n) -> int:
    """The parameter set of a block with one: the tables' only set, or that of its one live member."""
    return row[slot[0]] if num.shape[0] > 1 and n > 0 else 0


@_leaf
def _coefs(form, num, gpc, den, forcing, row, shared, t, slot, n, c, tb) -> None:
    """The coefficients at time ``t`` into ``c``: once for the block (its one parameter set: the tables' only one,
    or its one member's), or for each of the ``n`` live members (from their tables in ``tb``)."""
    if shared:
        _coefs_set(form, num, gpc, den, forcing, _block_set(num, row, slot, n), t, c, 0)
    elif n > 0:
        # A block's members share omega (the section times): cos and sin once, not once per member.
        w = forcing[row[slot[0]], 3]
        cw, sw = math.cos(w * t), math.sin(w * t)
        if n <= FEW_MEMBERS:
            for p in range(n):
                s = row[slot[p]]
                g, gp = forcing_at(forcing, s, cw, sw)
                form_coefficients(form, num, gpc, den, s, g, gp, c, p, True)
        else:
            _block_coefficients(form, tb, cw, sw, w, n, c)


@_leaf
def _body_columns(forcing, al, s, t, c, o, shared) -> None:
    """BODY's row ``o`` also holds ``g(t)`` and alpha (``p = alpha + g q``) beside the field's coefficients."""
    g, _ = forcing_of(forcing, s, t)  # bit for bit the g of the coefficients (forcing_at on the same cos, sin)
    if shared:
        c[o, 0, _G] = g
        c[o, 0, _ALPHA] = al
    else:
        c[0, _G, o] = g
        c[0, _ALPHA, o] = al


@_leaf
def _coefs_set_body(form, num, gpc, den, forcing, al, s, t, c, o) -> None:
    _coefs_set(form, num, gpc, den, forcing, s, t, c, o)
    _body_columns(forcing, al, s, t, c, o, True)


@_leaf
def _coefs_body(form, num, gpc, den, forcing, alpha, row, shared, t, slot, n, c, tb) -> None:
    """:func:`_coefs` for BODY: the same coefficients, and ``g(t)``, ``alpha`` in columns ``_G``, ``_ALPHA``."""
    _coefs(form, num, gpc, den, forcing, row, shared, t, slot, n, c, tb)
    for p in range(1 if shared else n):
        s = _block_set(num, row, slot, n) if shared else row[slot[p]]
        _body_columns(forcing, alpha[s], s, t, c, p, shared)


@_jit_inline
def _coefs_of(system, form, num, gpc, den, forcing, alpha, row, shared, t, slot, n, c, tb) -> None:
    # The system is a constant where this is inlined: the other systems call _coefs as before.
    if system == BODY:
        _coefs_body(form, num, gpc, den, forcing, alpha, row, shared, t, slot, n, c, tb)
    else:
        _coefs(form, num, gpc, den, forcing, row, shared, t, slot, n, c, tb)


# ---------------------------------------------------------------------------
# Stage sums, error norm, step-size factor, starting step: written once.


@_leaf
def _combine(w, row, scale, upto, k, dim, n, acc) -> None:
    """``acc[:, p] = sum_{m < upto} (scale w[row, m]) k[m, :, p]`` for the ``n`` packed members (zeros skipped)."""
    for p in range(n):
        for comp in range(dim):
            acc[comp, p] = 0.0
    for mm in range(upto):
        wm = w[row, mm] * scale
        if wm != 0.0:
            for p in range(n):
                for comp in range(dim):
                    acc[comp, p] += wm * k[mm, comp, p]


@_leaf
def _scaled_sq(e, ys, yn, rtol, atol, dim, n, out) -> None:
    # sum over components of (e / scale)^2, the scale mixing absolute and relative, old and new state
    for p in range(n):
        total = 0.0
        for comp in range(dim):
            x = e[comp, p] / (atol + rtol * max(abs(ys[comp, p]), abs(yn[comp, p])))
            total += x * x
        out[p] = total


@_leaf
def _error_norms(e, dop853, k, s, ys, yn, rtol, atol, hstep, dim, n, acc, err, err3) -> None:
    """``err[p]``: the step's scaled error norm of member ``p`` (accept if <= 1).

    The RMS over the components of ``e / (atol + rtol max(|y|, |y_new|))``, times ``h``; DOP853 combines
    its 5th- and 3rd-order estimates as Hairer's code does.
    """
    if dop853:
        _combine(e, 1, 1.0, s + 1, k, dim, n, acc)
        _scaled_sq(acc, ys, yn, rtol, atol, dim, n, err)
        _combine(e, 2, 1.0, s + 1, k, dim, n, acc)
        _scaled_sq(acc, ys, yn, rtol, atol, dim, n, err3)
        for p in range(n):
            den = (err[p] + 0.01 * err3[p]) * dim
            err[p] = hstep * err[p] / math.sqrt(den) if den > 0.0 else 0.0
    else:
        _combine(e, 0, 1.0, s + 1, k, dim, n, acc)
        _scaled_sq(acc, ys, yn, rtol, atol, dim, n, err)
        for p in range(n):
            err[p] = hstep * math.sqrt(err[p] / dim)


@_leaf
def _factor(err, expo) -> float:
    """Step-size factor after a step with error norm ``err``: grow after acceptance, shrink after rejection."""
    if err == 0.0:
        return _MAX_FACTOR
    return min(_MAX_FACTOR, max(_MIN_FACTOR, _SAFETY * err**expo))


@_leaf
def _rms(v, row, p, ys, rtol, atol, dim) -> float:
    # RMS of v[row, :, p] over the components, scaled by the state ys[:, p]
    total = 0.0
    for comp in range(dim):
        x = v[row, comp, p] / (atol + abs(ys[comp, p]) * rtol)
        total += x * x
    return math.sqrt(total / dim)


@_leaf
def _initial_step(system, form, dim, order, num, gpc, den, forcing, al, r, t, d, span, ys, k, s, p, rtol, atol,
                  cw) -> float:  # fmt: skip
    """Hairer's starting step for member ``p`` (``k[0, :, p]`` holds ``f`` at ``t``; parameter set ``r``, whose alpha
    is ``al``: BODY reads it).

    Uses ``k[s, :, p]``, ``k[s - 1, :, p]`` and ``cw`` (1, 2, COEF_COLUMNS) as scratch (no stage is live yet).
    """
    for comp in range(dim):
        k[s - 1, comp, p] = ys[comp, p]  # the state as a "stage", so one _rms serves y, f and f1 - f0
    d0 = _rms(k, s - 1, p, ys, rtol, atol, dim)
    d1 = _rms(k, 0, p, ys, rtol, atol, dim)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, span)
    for comp in range(dim):
        k[s - 1, comp, p] = d * h0 * k[0, comp, p]  # the offset of the trial point from ys
    if system == BODY:
        _coefs_set_body(form, num, gpc, den, forcing, al, r, t + d * h0, cw, 0)
    else:
        _coefs_set(form, num, gpc, den, forcing, r, t + d * h0, cw, 0)
    _eval(system, form, True, cw, ys, k[s - 1], p, p + 1, k, s)
    for comp in range(dim):
        k[s, comp, p] -= k[0, comp, p]
    d2 = _rms(k, s, p, ys, rtol, atol, dim) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, span)


# ---------------------------------------------------------------------------
# The tangent basis.


@_leaf
def gram_schmidt(v1x, v1y, v2x, v2y):
    """QR of the 2x2 matrix with columns ``v1, v2``: ``(e1x, e1y, e2x, e2y, R11, R22)``, ``R_ii >= 0``.

    ``R11 = 0`` or ``R22 = 0`` (with the input returned) signals a degenerate basis.
    """
    r11 = math.sqrt(v1x * v1x + v1y * v1y)
    if not (r11 > 0.0) or not math.isfinite(r11):
        return v1x, v1y, v2x, v2y, 0.0, 0.0
    e1x = v1x / r11
    e1y = v1y / r11
    r12 = e1x * v2x + e1y * v2y
    wx = v2x - r12 * e1x
    wy = v2y - r12 * e1y
    r22 = math.sqrt(wx * wx + wy * wy)
    if not (r22 > 0.0) or not math.isfinite(r22):
        return v1x, v1y, v2x, v2y, r11, 0.0
    return e1x, e1y, wx / r22, wy / r22, r11, r22


@_leaf
def _orthonormalise(ys, p) -> tuple[float, float]:
    # Phi = Q R in place for member p; returns (R11, R22), a zero if degenerate.
    e1x, e1y, e2x, e2y, r11, r22 = gram_schmidt(ys[2, p], ys[3, p], ys[4, p], ys[5, p])
    ys[2, p] = e1x
    ys[3, p] = e1y
    ys[4, p] = e2x
    ys[5, p] = e2y
    return r11, r22


@_leaf
def _ill_conditioned(ys, p) -> bool:
    """True if the tangent basis of member ``p`` is nearly degenerate or badly scaled (see REORTHONORMALISE)."""
    n1 = math.sqrt(ys[2, p] * ys[2, p] + ys[3, p] * ys[3, p])
    n2 = math.sqrt(ys[4, p] * ys[4, p] + ys[5, p] * ys[5, p])
    det = ys[2, p] * ys[5, p] - ys[3, p] * ys[4, p]
    return abs(det) < REORTHONORMALISE * n1 * n2 or n1 > 1e100 or n2 > 1e100 or n1 < 1e-100 or n2 < 1e-100


# ---------------------------------------------------------------------------
# The kernel.


@_leaf
def _swap(p, last, slot, ys, yn, k, lg, c, tb, shared) -> None:
    # Move member p out of the packed live range [0, last): exchange it with the last live one.
    slot[p], slot[last] = slot[last], slot[p]
    for comp in range(ys.shape[0]):
        ys[comp, p], ys[comp, last] = ys[comp, last], ys[comp, p]
        yn[comp, p], yn[comp, last] = yn[comp, last], yn[comp, p]
        for st in range(k.shape[0]):
            k[st, comp, p], k[st, comp, last] = k[st, comp, last], k[st, comp, p]
    lg[0, p], lg[0, last] = lg[0, last], lg[0, p]
    lg[1, p], lg[1, last] = lg[1, last], lg[1, p]
    if not shared:
        for a in range(2):
            for b in range(c.shape[1]):
                c[a, b, p], c[a, b, last] = c[a, b, last], c[a, b, p]
        for a in range(TB_ROWS):
            tb[a, p], tb[a, last] = tb[a, last], tb[a, p]


@_leaf
def _finite(v, p, dim) -> bool:
    for comp in range(dim):
        if not math.isfinite(v[comp, p]):
            return False
    return True


@_leaf
def _all_inside(ys, n, dim, lim, every) -> bool:
    # |q|, |r| <= lim for all n members (NaN fails), and with ``every`` all components finite.
    out = 0
    for p in range(n):
        ok = (abs(ys[0, p]) <= lim) & (abs(ys[1, p]) <= lim)
        if every:
            for comp in range(2, dim):
                ok = ok & (abs(ys[comp, p]) <= _BIG)
        out += 0 if ok else 1
    return out == 0


@_jit_inline
def _run_block(system, dim, one, tab, co, clock, ctl, arr, idx, block, work) -> None:
    """Advance the trajectories ``idx`` by ``clock.n_periods`` periods, ``block`` of them at a time in lock-step."""
    # Everything out of the structures once: the loops see plain arrays and scalars.
    a_mat, b_row, c_vec, e_mat, dop853 = tab.a, tab.b, tab.c, tab.e, tab.dop853
    num, gpc, den, forcing, row, alpha, form = co.num, co.gpc, co.den, co.forcing, co.row, co.alpha, co.form
    y, h, status, nsteps, rec, npts = arr.y, arr.h, arr.status, arr.nsteps, arr.rec, arr.npts
    rtol, atol, bound, fixed = ctl.rtol, ctl.atol, ctl.bound, ctl.fixed_steps
    lim = min(bound, _BIG)  # inf is never inside, whatever the bound
    t_base, period, k_first, store = clock.t_base, clock.period, clock.k_first, clock.store
    samples = clock.samples
    k, ys, yn, acc, err, err3, lg, slot, c, cw, mtab = work
    for b0 in range(0, idx.shape[0], block):
        members = idx[b0 : b0 + block]
        s = b_row.shape[1]
        m = members.shape[0]
        # One parameter set for the block (the tables' only one, or a block of one member's): its coefficients once per
        # stage into c[0], straight from the tables (a copy of one member's tables cost blocks of one ~25%); else each
        # member's, from their tables copied into mtab (members last: the stage's coefficients vectorise).
        shared = one or num.shape[0] == 1
        c_time = math.nan  # the time of the coefficients in c (stages at equal times share them)
        for p in range(m):
            lg[0, p] = 0.0
            lg[1, p] = 0.0
        d = 1.0 if period > 0.0 else -1.0
        span = abs(period)
        expo = -1.0 / (tab.error_order + 1.0)
        n_live = 0
        habs = 0.0
        for p in range(m):
            i = members[p]
            npts[i] = 0
            if status[i] == _OK:
                slot[n_live] = i
                for comp in range(dim):
                    ys[comp, n_live] = y[i, comp]
                n_live += 1
                if h[i] > 0.0 and (habs == 0.0 or h[i] < habs):
                    habs = h[i]
        if not shared:
            _load_tables(num, gpc, den, forcing, row, slot, n_live, mtab)
        for j in range(clock.n_periods):
            if n_live == 0:
                break
            # Time inside the period, from 0 to ``period``: the forcing's phase at t_base + (k_first + j) period
            # + t is that at t_base + t, and a stage time t + c h then keeps its digits (at t ~ 6000, 1000
            # periods in, ulp(t) ~ 1e-12 jittered every coefficient evaluation: the error floor of long runs).
            # BODY lands on each frame time period (frame / samples) in turn (frame / samples is 1.0 exactly
            # at the last: the section time); the other systems on the section time only.
            frame = 1
            tb = period * (frame / samples) if system == BODY else period
            t = 0.0
            if system == LYAPUNOV:
                for p in range(n_live):
                    ys[6, p] = 0.0  # the divergence integral restarts every period
                    lg[0, p] = 0.0
                    lg[1, p] = 0.0
            if t != c_time:
                _coefs_of(system, form, num, gpc, den, forcing, alpha, row, shared, t_base + t, slot, n_live, c, mtab)
                c_time = t
            for p in range(n_live):
                for comp in range(dim):
                    acc[comp, p] = 0.0
            _eval(system, form, shared, c, ys, acc, 0, n_live, k, 0)
            p = 0
            while p < n_live:
                if math.isfinite(k[0, 0, p]) and math.isfinite(k[0, 1, p]):
                    p += 1
                else:
                    status[slot[p]] = _NONFINITE
                    n_live -= 1
                    _swap(p, n_live, slot, ys, yn, k, lg, c, mtab, shared)
            if n_live == 0:
                break
            if habs <= 0.0 and fixed <= 0:
                habs = span
                for p in range(n_live):
                    r = row[slot[p]]
                    al = alpha[r] if system == BODY else 0.0  # (only BODY's coefficients carry alpha)
                    hp = _initial_step(system, form, dim, tab.order, num, gpc, den, forcing, al, r, t_base + t, d, span,
                                       ys, k, s, p, rtol, atol, cw)  # fmt: skip
                    habs = min(habs, hp)
            steps = 0
            saw_nonfinite = False
            # The smallest step this period resolves (a constant of the period: computed once, not per step).
            hmin = 10.0 * _EPS * max(abs(t_base + (k_first + j) * period), span)
            while n_live > 0:
                if fixed > 0:
                    if steps == fixed:
                        break
                    hstep = span / fixed
                    t = d * steps * hstep  # step times from the period's start, not accumulated
                    last = steps + 1 == fixed
                else:
                    remaining = (tb - t) * d
                    if remaining <= 0.0:
                        break
                    hstep = habs
                    last = False
                    if hstep >= remaining - hmin:  # land exactly on the section time; absorb a sliver
                        hstep = remaining
                        last = True
                hs = d * hstep
                n = 1 if one else n_live  # a block of one: every member loop below folds to straight-line code
                for st in range(1, s):
                    ts = t + c_vec[st] * hs
                    if ts != c_time:
                        _coefs_of(
                            system, form, num, gpc, den, forcing, alpha, row, shared, t_base + ts, slot, n, c, mtab
                        )
                        c_time = ts
                    _combine(a_mat, st, hs, st, k, dim, n, acc)
                    _eval(system, form, shared, c, ys, acc, 0, n, k, st)
                tn = tb if last else t + hs
                if tn != c_time:
                    _coefs_of(system, form, num, gpc, den, forcing, alpha, row, shared, t_base + tn, slot, n, c, mtab)
                    c_time = tn
                _combine(b_row, 0, hs, s, k, dim, n, acc)
                if fixed <= 0:  # the error estimate needs the new state beside the old one
                    for p in range(n):
                        for comp in range(dim):
                            yn[comp, p] = ys[comp, p] + acc[comp, p]
                _eval(system, form, shared, c, ys, acc, 0, n, k, s)  # FSAL: f at the new state
                steps += 1
                worst = -1
                e_max = 0.0
                any_nonfinite = False
                if fixed <= 0:
                    _error_norms(e_mat, dop853, k, s, ys, yn, rtol, atol, hstep, dim, n, acc, err, err3)
                    for p in range(n):
                        ep = err[p]
                        if not math.isfinite(ep):
                            ep = math.inf
                        else:
                            for comp in range(dim):
                                if not math.isfinite(k[s, comp, p]):
                                    ep = math.inf
                        if ep > e_max:
                            e_max = ep
                            worst = p
                    any_nonfinite = e_max == math.inf
                if e_max <= 1.0:
                    t = tn
                    for p in range(n):
                        for comp in range(dim):
                            # ys + acc is yn to the bit (the same addition); fixed steps never formed yn
                            ys[comp, p] = yn[comp, p] if fixed <= 0 else ys[comp, p] + acc[comp, p]
                            k[0, comp, p] = k[s, comp, p]
                    # Members that left the bound, or (fixed steps: no error control) overflowed, leave: a
                    # branch-free test of the block first, the members one by one only if one did.
                    p = n_live if _all_inside(ys, n, dim, lim, fixed > 0) else 0
                    while p < n_live:
                        if abs(ys[0, p]) <= bound and abs(ys[1, p]) <= bound and (fixed <= 0 or _finite(ys, p, dim)):
                            p += 1
                            continue
                        status[slot[p]] = _ESCAPED if _finite(ys, p, dim) else _NONFINITE
                        nsteps[slot[p]] += steps
                        n_live -= 1
                        _swap(p, n_live, slot, ys, yn, k, lg, c, mtab, shared)
                    if fixed <= 0:
                        # A clipped last step says little about the step size: keep the larger proposal.
                        factor = _factor(e_max, expo)
                        habs = max(habs, hstep * factor) if last else hstep * factor
                    # BODY: a frame reached (adaptive: the step landed on it; fixed: every fixed / samples steps)
                    if system == BODY and (last if fixed <= 0 else (steps * samples) % fixed == 0):
                        f = j * samples + (frame if fixed <= 0 else (steps * samples) // fixed) - 1
                        for p in range(n_live):
                            i = slot[p]
                            if store:
                                for comp in range(dim):
                                    rec[i, f, comp] = ys[comp, p]
                            npts[i] = f + 1
                        if fixed <= 0 and frame < samples:
                            frame += 1
                            tb = period * (frame / samples)
                    if system == LYAPUNOV and not last:
                        # Strong contraction within one period would lose the second vector to rounding
                        # before the section time: QR now (the product of the R factors is unchanged) and
                        # restart the FSAL stage from the new basis (the coefficients at t are still in c).
                        p = 0
                        while p < n_live:
                            if _ill_conditioned(ys, p):
                                r11, r22 = _orthonormalise(ys, p)
                                if r11 <= 0.0 or r22 <= 0.0:
                                    status[slot[p]] = _NONFINITE
                                    nsteps[slot[p]] += steps
                                    n_live -= 1
                                    _swap(p, n_live, slot, ys, yn, k, lg, c, mtab, shared)
                                    continue
                                lg[0, p] += math.log(r11)
                                lg[1, p] += math.log(r22)
                                for comp in range(dim):
                                    acc[comp, p] = 0.0
                                _eval(system, form, shared, c, ys, acc, p, p + 1, k, 0)
                            p += 1
                else:
                    if any_nonfinite:
                        saw_nonfinite = True
                        habs = hstep * _MIN_FACTOR
                    else:
                        habs = hstep * _factor(e_max, expo)
                    if habs < hmin:
                        # The member that forces the step below the round-off floor leaves; the others go on.
                        status[slot[worst]] = _NONFINITE if saw_nonfinite else _COLLAPSED
                        nsteps[slot[worst]] += steps
                        n_live -= 1
                        _swap(worst, n_live, slot, ys, yn, k, lg, c, mtab, shared)
                        saw_nonfinite = False
                        habs = hstep
                if fixed <= 0 and steps >= ctl.max_steps:
                    for p in range(n_live):
                        status[slot[p]] = _TOO_MANY
                        nsteps[slot[p]] += steps
                    n_live = 0
            p = 0
            while p < n_live:
                i = slot[p]
                if system == LYAPUNOV:
                    r11, r22 = _orthonormalise(ys, p)
                    if r11 <= 0.0 or r22 <= 0.0:  # the basis collapsed (under/overflow within one period)
                        status[i] = _NONFINITE
                        nsteps[i] += steps
                        n_live -= 1
                        _swap(p, n_live, slot, ys, yn, k, lg, c, mtab, shared)
                        continue
                    if store:
                        rec[i, j, 0] = ys[0, p]
                        rec[i, j, 1] = ys[1, p]
                        rec[i, j, 2] = lg[0, p] + math.log(r11)
                        rec[i, j, 3] = lg[1, p] + math.log(r22)
                        rec[i, j, 4] = ys[6, p]
                elif store and system != BODY:  # (BODY recorded its frames as it landed on them)
                    for comp in range(dim):
                        rec[i, j, comp] = ys[comp, p]
                nsteps[i] += steps
                for comp in range(dim):
                    y[i, comp] = ys[comp, p]
                npts[i] = (j + 1) * samples if system == BODY else j + 1
                p += 1
        for p in range(m):
            h[members[p]] = habs


# One compiled kernel per system and block kind: the system, its state size and "a block of one" are
# constants in each (closure variables are compile-time constants), so the system's branches fold away,
# the component loops unroll and, for one trajectory, the member loops vanish. (Runtime switches there
# cost the field 2-3x: no vectorisation.) Each is cached on disk under its own constants.
_kernel = nb.njit(nogil=True, cache=True, error_model="numpy", _nrt=False)


def _specialise(system: int, one: bool):
    dim = STATE_SIZE[system]

    def kernel(tab, co, clock, ctl, arr, idx, block, work):
        _run_block(system, dim, one, tab, co, clock, ctl, arr, idx, 1 if one else block, work)

    return _kernel(kernel)


#: ``KERNELS[system][block == 1]``
KERNELS = tuple((_specialise(system, False), _specialise(system, True)) for system in (FIELD, TANGENT, LYAPUNOV, BODY))


def advance_blocks(system: int, tab, co, clock, ctl, arr, idx, block) -> None:
    """Advance the trajectories ``idx`` by ``clock.n_periods`` periods, ``block`` of them at a time in lock-step.

    ``block = 1`` gives every trajectory its own step sequence; with fixed steps lock-step costs
    nothing in accuracy (every member takes the same steps anyway). The kernels release the GIL:
    callers run disjoint index sets in threads (each touches only its own rows).
    """
    work = work_arrays(tab.b.shape[1], STATE_SIZE[system], min(block, idx.shape[0]), co.num.shape[0] == 1 or block == 1,
                       COEF_COLUMNS[system])  # fmt: skip
    KERNELS[system][block == 1](tab, co, clock, ctl, arr, idx, block, work)
