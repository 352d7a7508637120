"""The inhomogeneous Bilimovich system reduced to the (q, r) plane.

A rigid body with inertia tensor ``I`` and angular velocity ``omega = (p, q, r)``
obeys the Lagrange-d'Alembert equations (paper, eq. (eq-g))::

    I omega' = (I omega) x omega + lambda a,      a = df/domega = (1, -g, 0),

under the rheonomic constraint ``f = p - g(t) q - alpha = 0``. Requiring
``df/dt = 0`` gives the multiplier::

    lambda = [ -(a, I^-1 ((I omega) x omega)) + g' q ] / (a, I^-1 a).

On the constraint surface ``p = alpha + g q`` (the paper prints ``g r``: a typo)
the 2nd and 3rd components of ``omega'`` are ``Q(q, r, t)`` and ``R(q, r, t)``.

Structure used everywhere in this package: ``omega`` is affine in ``(q, r)``,
``(I omega) x omega`` is a quadratic form, and ``(a, I^-1 a)`` depends on ``t``
only. So ``Q``, ``R`` and ``lambda`` are quadratic polynomials in ``(q, r)``::

    X = c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2,

whose coefficients are ``c_m(t) = [N_m(g) + g' G_m(g)] / D(g)`` with ``N_m`` a
polynomial of degree <= 4 in ``g``, ``D(g) = (a, I^-1 a)`` of degree 2 and the
``g'`` term present on the ``q`` monomial only. :class:`Model` builds these
polynomial tables once, exactly, by polynomial arithmetic in ``g``; the numba
kernels only evaluate them (Horner), and every trajectory at the same time
shares the same coefficients.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numba as nb
import numpy as np

from explorer_core.system.params import Params, reduce_time

#: Monomial order of the coefficient tables.
MONOMIALS = ("1", "q", "r", "q^2", "q r", "r^2")
#: Rows of the coefficient tables.
ROW_Q, ROW_R, ROW_LAMBDA = 0, 1, 2
_DEG = 5  # polynomial coefficients kept per table entry (degree <= 4 in g)


_WORK = 9  # coefficients kept while deriving (degree <= 8: no product here is truncated)


#: ``_CONV[i, j, k] = 1`` where ``i + j = k``: the product of coefficient arrays as one contraction.
_CONV = np.zeros((_WORK, _WORK, _WORK))
for _i in range(_WORK):
    _CONV[_i, np.arange(_WORK - _i), np.arange(_i, _WORK)] = 1.0


def _pmul(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Product of polynomials in ``g`` stored as coefficient arrays ``(..., _WORK)`` (ascending powers)."""
    return np.einsum("...i,...j,ijk->...k", x, y, _CONV)


def _cross(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    # cross product of polynomial 3-vectors (..., 3, _DEG)
    return np.stack(
        [
            _pmul(x[..., 1, :], y[..., 2, :]) - _pmul(x[..., 2, :], y[..., 1, :]),
            _pmul(x[..., 2, :], y[..., 0, :]) - _pmul(x[..., 0, :], y[..., 2, :]),
            _pmul(x[..., 0, :], y[..., 1, :]) - _pmul(x[..., 1, :], y[..., 0, :]),
        ],
        axis=-2,
    )


#: The power of ``alpha`` in each monomial's coefficient: ``omega = (alpha, 0, 0) + q u1 + r u2`` enters the
#: field bilinearly, so the constant monomial goes with ``alpha^2``, ``q`` and ``r`` with ``alpha``.
ALPHA_POWER = np.array([2, 1, 1, 0, 0, 0])


def build_tables(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact coefficient tables of Q, R and lambda as polynomials in g (see :func:`tensor_tables`).

    The tables of ``alpha = 1`` (one build per tensor, cached) with each monomial scaled by its power of
    ``alpha`` (:data:`ALPHA_POWER`): a few microseconds, so a continuation in ``alpha`` builds nothing.
    """
    num, gpc, den = _tensor_tables(params.inertia)
    # |alpha| beyond ~1e154 overflows alpha^2: the tables hold inf (and 0 * inf = nan), which every computation
    # then reports as a status (nonfinite, degenerate), not as numpy's RuntimeWarning once per process.
    with np.errstate(over="ignore", invalid="ignore"):
        scale = float(params.alpha) ** ALPHA_POWER
        return np.ascontiguousarray(num * scale[None, :, None]), gpc.copy(), den.copy()


@functools.lru_cache(maxsize=256)
def _tensor_tables(inertia: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    out = tensor_tables(Params(inertia=inertia, alpha=1.0))
    for arr in out:
        arr.setflags(write=False)
    return out


def tensor_tables(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact coefficient tables of Q, R and lambda as polynomials in g, built for ``params`` as given.

    Polynomial arithmetic in ``g`` on coefficient arrays, all monomials at once (~0.2 ms: continuation
    in an inertia entry builds a model per point).

    Returns
    -------
    num : (3, 6, 5) array
        ``num[row, m, j]``: coefficient of ``g**j`` in the numerator of monomial
        ``m`` (see :data:`MONOMIALS`) of row ``Q``, ``R`` or ``lambda``.
    gpc : (3, 2) array
        ``g' * (gpc[row, 0] + gpc[row, 1] g)`` is added to the ``q``-monomial numerator.
    den : (3,) array
        ``D(g) = (a, I^-1 a)`` coefficients; every row shares this denominator.
    """
    inertia = params.inertia_matrix
    minv = np.linalg.inv(inertia)
    # omega = u0 + q u1 + r u2 on the constraint surface, as polynomial 3-vectors in g: (3 terms, 3, _DEG).
    u = np.zeros((3, 3, _WORK))
    u[0, 0, 0] = params.alpha
    u[1, 0, 1] = 1.0  # p = alpha + g q
    u[1, 1, 0] = 1.0
    u[2, 2, 0] = 1.0
    a = np.zeros((3, _WORK))
    a[0, 0], a[1, 1] = 1.0, -1.0
    ma = np.einsum("kl,lc->kc", minv, a)
    den = _pmul(a, ma).sum(axis=0)
    # F(omega) = I^-1 ((I omega) x omega): the term of u_i and u_j, then split by monomial.
    iu = np.einsum("kl,ilc->ikc", inertia, u)
    b = np.einsum("kl,ijlc->ijkc", minv, _cross(iu[:, None], u[None, :]))
    fm = np.stack([b[0, 0], b[0, 1] + b[1, 0], b[0, 2] + b[2, 0], b[1, 1], b[1, 2] + b[2, 1], b[2, 2]])  # (6, 3, _DEG)
    s = _pmul(a[None], fm).sum(axis=1)  # (a, F_m), (6, _DEG)
    num = np.zeros((3, 6, _WORK))
    # omega' = F - (a, F)/D I^-1 a (+ the g' q term below), times D.
    num[ROW_Q] = _pmul(den[None], fm[:, 1]) - _pmul(s, ma[1][None])
    num[ROW_R] = _pmul(den[None], fm[:, 2]) - _pmul(s, ma[2][None])
    num[ROW_LAMBDA] = -s
    # D has degree 2 in g, (a, F) 3, so the numerators 4: the tables hold them exactly.
    high = num[..., _DEG:]
    # (entries that overflowed, for absurd parameters, are not finite anyway: the kernels flag them)
    if np.any(den[3:]) or np.any(np.isfinite(high) & (high != 0.0)):  # pragma: no cover - guards the derivation
        raise AssertionError("a polynomial degree exceeds the table size")
    gpc = np.zeros((3, 2))
    gpc[ROW_Q] = ma[1, :2]
    gpc[ROW_R] = ma[2, :2]
    gpc[ROW_LAMBDA] = (1.0, 0.0)
    return np.ascontiguousarray(num[..., :_DEG]), gpc, den[:3].copy()


def _tables(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # The tables depend on the tensor and alpha only (the forcing enters when they are evaluated).
    return _tables_of(params.inertia, params.alpha)


@functools.lru_cache(maxsize=256)
def _tables_of(inertia: tuple[float, ...], alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # One change of a slider builds the same model
    # for the section, the tracks, the T' map and the reliability check: build it once.
    # Read-only, so sharing them between models is safe.
    out = build_tables(Params(inertia=inertia, alpha=alpha))
    for arr in out:
        arr.setflags(write=False)
    return out


# ---------------------------------------------------------------------------
# The field's structure: the monomials a scene's tables hold.

#: Forms of the field: ``FORM_MASKS[form][row]`` has bit ``m`` set for each monomial (:data:`MONOMIALS`) of
#: ``Q`` (row 0) or ``R`` (row 1) that the form keeps. A diagonal tensor has ``Q`` in ``{q, r, q r}`` and ``R``
#: in ``{q, q^2}``; ``alpha = 0`` drops the monomials of ``alpha`` (1 and ``r``, :data:`ALPHA_POWER`), not the
#: ``g'`` term on ``q``. The kernels evaluate a scene's smallest form (:func:`field_form`): the general sums
#: without their zero terms, so the same numbers (``x + 0 y == x`` for finite ``y``) from fewer operations.
GENERAL, HOMOGENEOUS, DIAGONAL, DIAGONAL_HOMOGENEOUS = 0, 1, 2, 3
FORM_MASKS = ((0b111111, 0b111111), (0b111010, 0b111010), (0b010110, 0b001010), (0b010010, 0b001000))
#: The forms from the fewest monomials to the most (GENERAL, which holds every table, last).
_FORMS_BY_SIZE = tuple(sorted(range(len(FORM_MASKS)), key=lambda f: sum(bin(m).count("1") for m in FORM_MASKS[f])))
_MONOMIAL_BITS = 1 << np.arange(6)


def used_monomials(num: np.ndarray, gpc: np.ndarray) -> tuple[int, int]:
    """Bits (``1 << m``, :data:`MONOMIALS`) of the monomials ``Q`` and ``R`` hold: their nonzero table entries.

    ``num`` (..., rows, 6, 5) and ``gpc`` (..., rows, 2), one model's or stacked (a monomial any set holds); rows
    ``Q`` and ``R`` are read. An entry counts as zero only if it is exactly 0.0 (1e-300 is a term like any other);
    NaN is not zero.
    """
    num = np.asarray(num, dtype=float)
    gpc = np.asarray(gpc, dtype=float)
    nonzero = (num[..., :2, :, :] != 0.0).reshape(-1, 2, 6, num.shape[-1]).any(axis=(0, 3))  # (2, 6)
    nonzero[:, 1] |= (gpc[..., :2, :] != 0.0).reshape(-1, 2, gpc.shape[-1]).any(axis=(0, 2))  # g' sits on q
    used_q, used_r = (int(u) for u in nonzero @ _MONOMIAL_BITS)
    return used_q, used_r


def form_of(used_q: int, used_r: int) -> int:
    """The smallest form (:data:`FORM_MASKS`) that holds the monomials ``used_q``, ``used_r``
    (:func:`used_monomials`), or :data:`GENERAL`."""
    return next(f for f in _FORMS_BY_SIZE if not (used_q & ~FORM_MASKS[f][0] or used_r & ~FORM_MASKS[f][1]))


def field_form(num: np.ndarray, gpc: np.ndarray) -> int:
    """The smallest form (:data:`FORM_MASKS`) that holds every nonzero entry of coefficient tables (one model's or
    stacked, see :func:`used_monomials`)."""
    return form_of(*used_monomials(num, gpc))


@functools.lru_cache(maxsize=256)
def _used_of(inertia: tuple[float, ...], alpha: float) -> tuple[int, int]:
    # With the tables (cached the same way): every engine call reads its form, and Newton makes hundreds.
    num, gpc, _ = _tables_of(inertia, alpha)
    return used_monomials(num, gpc)


# ---------------------------------------------------------------------------
# numba primitives shared by every kernel.

_jit = nb.njit(nogil=True, cache=True, fastmath=False, error_model="numpy")
#: The pieces of the engine's inner loops: no reference counting (``_nrt=False``: they allocate nothing,
#: and a reference-count update is an atomic instruction), small enough for LLVM to inline them.
_leaf = nb.njit(nogil=True, cache=True, fastmath=False, error_model="numpy", _nrt=False)


@_leaf
def forcing_at(forcing: np.ndarray, s: int, c: float, sn: float) -> tuple[float, float]:
    """``g`` and ``g'`` for row ``s`` of stacked forcings ``(P, 4)`` from ``cos(omega t)``, ``sin(omega t)``.

    Members with one ``omega`` (a lock-step block's) share the trigonometry, the costliest part.
    """
    w = forcing[s, 3]
    return forcing[s, 0] + forcing[s, 1] * c + forcing[s, 2] * sn, w * (forcing[s, 2] * c - forcing[s, 1] * sn)


@_leaf
def forcing_of(forcing: np.ndarray, s: int, t: float) -> tuple[float, float]:
    """``g(t)`` and ``g'(t)`` for row ``s`` of stacked forcings ``(P, 4)``, each ``(g0, g1, g2, omega)``."""
    w = forcing[s, 3]
    return forcing_at(forcing, s, math.cos(w * t), math.sin(w * t))


@_leaf
def _horner4(num, s: int, row: int, m: int, g: float) -> float:
    """``N(g)`` of monomial ``m`` of row ``row`` from set ``s`` (degree 4, Horner)."""
    return num[s, row, m, 0] + g * (
        num[s, row, m, 1] + g * (num[s, row, m, 2] + g * (num[s, row, m, 3] + g * num[s, row, m, 4]))
    )


@_leaf
def _put(out, last: bool, o: int, row: int, m: int, v: float) -> None:
    # member o's coefficient: out[o, row, m], or out[row, m, o] with the members last (lock-step blocks)
    if last:
        out[row, m, o] = v
    else:
        out[o, row, m] = v


@_leaf
def form_coefficients(form: int, num, gpc, den, s: int, g: float, gp: float, out, o: int, last: bool = False) -> None:
    """``out[o, row, m]``: the monomial coefficients of row ``row`` (Q, R, lambda) at ``(g, g')`` from set ``s``.

    Stacked tables: ``num`` (P, rows, 6, 5), ``gpc`` (P, rows, 2), ``den`` (P, 3); ``out`` (., rows', 6) with
    ``rows' <= rows`` (the kernels need only Q and R), or with ``last`` ``out[row, m, o]`` (rows', columns, .).
    ``[N(g) + g' G(g)] / D(g)``, Horner in ``g``. Rows Q and R get only the monomials of ``form``
    (:data:`FORM_MASKS`; the others are not written: the form's evaluation never reads them), with the same numbers.
    """
    dinv = 1.0 / (den[s, 0] + g * (den[s, 1] + g * den[s, 2]))
    rows = out.shape[0] if last else out.shape[1]
    if form == GENERAL:
        for row in range(rows):
            # The q-monomial (m = 1) apart, so the loop over the others has no branch (~25% faster).
            _put(out, last, o, row, 0, _horner4(num, s, row, 0, g) * dinv)
            vq = _horner4(num, s, row, 1, g) + gp * (gpc[s, row, 0] + g * gpc[s, row, 1])
            _put(out, last, o, row, 1, vq * dinv)
            for m in range(2, 6):
                _put(out, last, o, row, m, _horner4(num, s, row, m, g) * dinv)
        return
    for row in range(rows):
        mask = FORM_MASKS[form][row] if row < 2 else 0b111111
        _put(out, last, o, row, 1, (_horner4(num, s, row, 1, g) + gp * (gpc[s, row, 0] + g * gpc[s, row, 1])) * dinv)
        for m in (0, 2, 3, 4, 5):
            if (mask >> m) & 1:
                _put(out, last, o, row, m, _horner4(num, s, row, m, g) * dinv)


@_jit
def forcing_g(forcing: np.ndarray, t: float) -> tuple[float, float]:
    """``g(t)`` and ``g'(t)`` for ``forcing = (g0, g1, g2, omega)``."""
    return forcing_of(forcing.reshape((1, 4)), 0, t)


@_jit
def coefficients_at(num: np.ndarray, gpc: np.ndarray, den: np.ndarray, g: float, gp: float, out: np.ndarray) -> None:
    """Fill ``out[row, m]`` with the monomial coefficients of Q, R, lambda at (g, g') (one model's tables)."""
    form_coefficients(GENERAL, num.reshape((1, *num.shape)), gpc.reshape((1, *gpc.shape)), den.reshape((1, 3)), 0, g,
                      gp, out.reshape((1, *out.shape)), 0)  # fmt: skip


@_leaf
def quadratic(c0: float, c1: float, c2: float, c3: float, c4: float, c5: float, q: float, r: float) -> float:
    """``c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2`` (:data:`MONOMIALS`): every kernel evaluates the field so."""
    return c0 + q * (c1 + c3 * q + c4 * r) + r * (c2 + c5 * r)


@_leaf
def form_value(form: int, row: int, c0, c1, c2, c3, c4, c5, q: float, r: float) -> float:
    """Row ``row`` (0: ``Q``, 1: ``R``) of the field in ``form``: :func:`quadratic` without the form's zero terms."""
    if form == DIAGONAL:
        return q * (c1 + c4 * r) + c2 * r if row == 0 else q * (c1 + c3 * q)
    if form == DIAGONAL_HOMOGENEOUS:
        return q * (c1 + c4 * r) if row == 0 else q * (c3 * q)
    if form == HOMOGENEOUS:
        return q * (c1 + c3 * q + c4 * r) + r * (c5 * r)
    return quadratic(c0, c1, c2, c3, c4, c5, q, r)


@_leaf
def form_gradient(form: int, row: int, c0, c1, c2, c3, c4, c5, q: float, r: float) -> tuple[float, float]:
    """``(d/dq, d/dr)`` of :func:`form_value` (affine in ``(q, r)``); ``R`` of a diagonal form has no ``r``."""
    if form == GENERAL:
        return c1 + 2.0 * c3 * q + c4 * r, c2 + c4 * q + 2.0 * c5 * r
    if form == HOMOGENEOUS:
        return c1 + 2.0 * c3 * q + c4 * r, c4 * q + 2.0 * c5 * r
    if row == 0:
        return c1 + c4 * r, (c2 + c4 * q if form == DIAGONAL else c4 * q)
    return (c1 + 2.0 * c3 * q if form == DIAGONAL else 2.0 * c3 * q), 0.0


@_jit
def eval_quadratic(c: np.ndarray, row: int, q: float, r: float) -> float:
    """:func:`quadratic` with one row of a coefficient table."""
    return quadratic(c[row, 0], c[row, 1], c[row, 2], c[row, 3], c[row, 4], c[row, 5], q, r)


@_jit
def rhs(
    num: np.ndarray,
    gpc: np.ndarray,
    den: np.ndarray,
    forcing: np.ndarray,
    t: float,
    q: float,
    r: float,
    work: np.ndarray,
) -> tuple[float, float]:
    """``(Q, R)`` at ``(q, r, t)`` from one model's tables; ``work`` is a (2, 6) scratch array."""
    g, gp = forcing_g(forcing, t)
    coefficients_at(num, gpc, den, g, gp, work)
    return eval_quadratic(work, 0, q, r), eval_quadratic(work, 1, q, r)


# ---------------------------------------------------------------------------
# The public, vectorised model (numpy; used for grids, equilibria and tests).


@dataclass(frozen=True)
class Model:
    """The reduced field of one parameter set, with its coefficient tables.

    All methods broadcast over array arguments ``q``, ``r``; ``t`` is a scalar.
    """

    params: Params
    num: np.ndarray = field(init=False, repr=False)
    gpc: np.ndarray = field(init=False, repr=False)
    den: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        num, gpc, den = _tables(self.params)
        for name, arr in (("num", num), ("gpc", gpc), ("den", den)):
            object.__setattr__(self, name, arr)

    @property
    def used(self) -> tuple[int, int]:
        """The monomials ``Q`` and ``R`` hold (:func:`used_monomials` of its tables), cached with the tables."""
        return _used_of(self.params.inertia, self.params.alpha)

    @property
    def forcing(self) -> np.ndarray:
        return self.params.forcing

    def g(self, t: float) -> tuple[float, float]:
        """``g(t), g'(t)``, at ``t`` less whole forcing periods taken exactly (:func:`reduce_time`): the same
        phase, with its digits at any ``t`` (``cos(omega t)`` at ``t = 1e11`` would carry an error of 1e-5)."""
        return forcing_g(self.forcing, reduce_time(float(t), self.params.omega))

    def coefficients(self, t: float) -> np.ndarray:
        """(3, 6) monomial coefficients of ``Q, R, lambda`` at time ``t`` (order :data:`MONOMIALS`)."""
        g, gp = self.g(t)
        out = np.empty((3, 6))
        coefficients_at(self.num, self.gpc, self.den, g, gp, out)
        return out

    @staticmethod
    def _poly(c: np.ndarray, q: Any, r: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        r = np.asarray(r, dtype=float)
        return c[0] + c[1] * q + c[2] * r + c[3] * q * q + c[4] * q * r + c[5] * r * r

    def field(self, q: Any, r: Any, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Q, R)``: the right-hand side of ``q' = Q, r' = R``."""
        c = self.coefficients(t)
        return self._poly(c[ROW_Q], q, r), self._poly(c[ROW_R], q, r)

    def jacobian(self, q: Any, r: Any, t: float) -> np.ndarray:
        """Exact Jacobian ``[[dQ/dq, dQ/dr], [dR/dq, dR/dr]]``, shape ``(..., 2, 2)``."""
        c = self.coefficients(t)
        q = np.asarray(q, dtype=float)
        r = np.asarray(r, dtype=float)
        out = np.empty((*np.broadcast(q, r).shape, 2, 2))
        for i, row in enumerate((ROW_Q, ROW_R)):
            k = c[row]
            out[..., i, 0] = k[1] + 2.0 * k[3] * q + k[4] * r
            out[..., i, 1] = k[2] + k[4] * q + 2.0 * k[5] * r
        return out

    def divergence(self, q: Any, r: Any, t: float) -> np.ndarray:
        """``dQ/dq + dR/dr``: the phase-area contraction rate."""
        j = self.jacobian(q, r, t)
        return j[..., 0, 0] + j[..., 1, 1]

    def multiplier(self, q: Any, r: Any, t: float) -> np.ndarray:
        """The Lagrange multiplier ``lambda``."""
        return self._poly(self.coefficients(t)[ROW_LAMBDA], q, r)

    def tprime(self, q: Any, r: Any, t: float) -> np.ndarray:
        """``T' = dT/dt = alpha * lambda``: power of the constraint reaction."""
        return self.params.alpha * self.multiplier(q, r, t)

    def omega_vector(self, q: Any, r: Any, t: float) -> np.ndarray:
        """``(p, q, r)`` with ``p = alpha + g q``, stacked on the last axis."""
        g, _ = self.g(t)
        q = np.asarray(q, dtype=float)
        r = np.asarray(r, dtype=float)
        q, r = np.broadcast_arrays(q, r)
        return np.stack([self.params.alpha + g * q, q, r], axis=-1)

    def energy(self, q: Any, r: Any, t: float) -> np.ndarray:
        """Kinetic energy ``T = (I omega, omega) / 2``."""
        w = self.omega_vector(q, r, t)
        return 0.5 * np.einsum("...i,ij,...j->...", w, self.params.inertia_matrix, w)
