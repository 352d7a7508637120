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
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numba as nb
import numpy as np
from numpy.polynomial import polynomial as P

#: Monomial order of the coefficient tables.
MONOMIALS = ("1", "q", "r", "q^2", "q r", "r^2")
#: Rows of the coefficient tables.
ROW_Q, ROW_R, ROW_LAMBDA = 0, 1, 2
#: Names of the six independent inertia entries, in the order used everywhere.
INERTIA_NAMES = ("I11", "I22", "I33", "I12", "I13", "I23")
_DEG = 5  # polynomial coefficients kept per table entry (degree <= 4 in g)


class ParameterError(ValueError):
    """A parameter set that does not define a valid Bilimovich system."""


def _check_finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        raise ParameterError(f"{name} must be a finite number, got {shown}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return v


@dataclass(frozen=True)
class Params:
    """One parameter set of the system.

    Parameters
    ----------
    inertia : (I11, I22, I33, I12, I13, I23)
        Entries of the symmetric positive-definite inertia tensor.
    alpha : float
        Inhomogeneity of the constraint ``p - g q = alpha``.
    g0, g1, g2, omega : float
        Forcing ``g(t) = g0 + g1 cos(omega t) + g2 sin(omega t)``, ``omega > 0``.
    t0 : float
        Section phase: Poincare points are taken at ``t0 + k T``.
    """

    inertia: tuple[float, float, float, float, float, float] = (1.0, 2.0, 4.0, 0.0, 0.0, 0.0)
    alpha: float = 0.1
    g0: float = 0.0
    g1: float = 1.0
    g2: float = 0.0
    omega: float = 1.0
    t0: float = 0.0

    def __post_init__(self) -> None:
        ent = self.inertia
        if isinstance(ent, str | bytes):
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got the string {ent[:40]!r}")
        if isinstance(ent, np.ndarray) and ent.shape == (3, 3):
            ent = inertia_entries(ent)
        try:
            ent = tuple(ent)
        except TypeError:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {self.inertia!r}") from None
        if len(ent) != 6:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {len(ent)}: {ent!r}")
        ent = tuple(_check_finite(n, v) for n, v in zip(INERTIA_NAMES, ent, strict=True))
        object.__setattr__(self, "inertia", ent)
        for f in ("alpha", "g0", "g1", "g2", "omega", "t0"):
            object.__setattr__(self, f, _check_finite(f, getattr(self, f)))
        if self.omega <= 0.0:
            raise ParameterError(f"omega must be > 0 (forcing frequency), got {self.omega!r}")
        _check_positive_definite(self.inertia_matrix, ent)

    @property
    def inertia_matrix(self) -> np.ndarray:
        """The 3x3 inertia tensor."""
        i11, i22, i33, i12, i13, i23 = self.inertia
        return np.array([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]], dtype=float)

    @property
    def period(self) -> float:
        """Forcing period ``T = 2 pi / omega``."""
        return 2.0 * math.pi / self.omega

    @property
    def forcing(self) -> np.ndarray:
        """``(g0, g1, g2, omega)`` as the array the kernels take."""
        return np.array([self.g0, self.g1, self.g2, self.omega], dtype=float)

    def with_(self, **changes: Any) -> Params:
        """A copy with some fields changed; accepts inertia entries by name (``I11=...``)."""
        new = changes.pop("inertia", self.inertia)
        if isinstance(new, str | bytes) or not hasattr(new, "__len__"):
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {new!r}")
        ent = list(new)
        if len(ent) != 6:
            raise ParameterError(f"inertia must be six numbers I11,I22,I33,I12,I13,I23, got {len(ent)}: {ent!r}")
        for i, n in enumerate(INERTIA_NAMES):
            if n in changes:
                ent[i] = changes.pop(n)
        return replace(self, inertia=tuple(ent), **changes)

    def as_dict(self) -> dict[str, Any]:
        """Plain-JSON form (inertia as a list)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["inertia"] = list(self.inertia)
        return d


def inertia_entries(matrix: Any, tol: float = 1e-12) -> tuple[float, ...]:
    """The six entries of a 3x3 tensor; rejects a non-symmetric one, naming the entry."""
    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3):
        raise ParameterError(f"inertia tensor must be 3x3, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ParameterError(f"inertia tensor must be finite, got {m.tolist()}")
    scale = max(1.0, float(np.max(np.abs(m))))
    for (i, j), name in (((0, 1), "I12"), ((0, 2), "I13"), ((1, 2), "I23")):
        if abs(m[i, j] - m[j, i]) > tol * scale:
            raise ParameterError(
                f"inertia tensor is not symmetric: {name}={float(m[i, j])!r} but I{j + 1}{i + 1}={float(m[j, i])!r}"
            )
    return (m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2])


def _check_positive_definite(m: np.ndarray, ent: tuple[float, ...]) -> None:
    eig = np.linalg.eigvalsh(m)
    # Relative threshold: a tensor this close to singular makes lambda's
    # denominator vanish and the reduced field meaningless.
    if eig[0] <= 1e-12 * max(1.0, float(np.max(np.abs(eig)))):
        txt = ", ".join(f"{n}={v:g}" for n, v in zip(INERTIA_NAMES, ent, strict=True))
        raise ParameterError(
            f"inertia tensor is not positive definite ({txt}; smallest eigenvalue {eig[0]:.6g}); "
            "off-diagonal entries are too large for the diagonal ones"
        )


# ---------------------------------------------------------------------------
# Exact construction of the coefficient tables (polynomials in g).


def _pvec_const(v: np.ndarray) -> list[np.ndarray]:
    return [np.array([float(x)]) for x in v]


def _pmat_vec(m: np.ndarray, v: list[np.ndarray]) -> list[np.ndarray]:
    return [P.polyadd(P.polyadd(m[i, 0] * v[0], m[i, 1] * v[1]), m[i, 2] * v[2]) for i in range(3)]


def _pcross(x: list[np.ndarray], y: list[np.ndarray]) -> list[np.ndarray]:
    return [
        P.polysub(P.polymul(x[1], y[2]), P.polymul(x[2], y[1])),
        P.polysub(P.polymul(x[2], y[0]), P.polymul(x[0], y[2])),
        P.polysub(P.polymul(x[0], y[1]), P.polymul(x[1], y[0])),
    ]


def _pdot(x: list[np.ndarray], y: list[np.ndarray]) -> np.ndarray:
    return P.polyadd(P.polyadd(P.polymul(x[0], y[0]), P.polymul(x[1], y[1])), P.polymul(x[2], y[2]))


def _pad(c: np.ndarray, n: int = _DEG) -> np.ndarray:
    c = np.trim_zeros(np.asarray(c, dtype=float), "b")
    if c.size > n:  # cannot happen for this system; guards the derivation
        raise AssertionError(f"polynomial of degree {c.size - 1} exceeds table size")
    out = np.zeros(n)
    out[: c.size] = c
    return out


def build_tables(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact coefficient tables of Q, R and lambda as polynomials in g.

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
    # omega = u0 + q u1 + r u2 on the constraint surface, as polynomial vectors in g.
    u = [
        _pvec_const(np.array([params.alpha, 0.0, 0.0])),
        [np.array([0.0, 1.0]), np.array([1.0]), np.array([0.0])],
        _pvec_const(np.array([0.0, 0.0, 1.0])),
    ]
    a = [np.array([1.0]), np.array([0.0, -1.0]), np.array([0.0])]
    ma = _pmat_vec(minv, a)
    den = _pdot(a, ma)

    def b(i: int, j: int) -> list[np.ndarray]:
        return _pmat_vec(minv, _pcross(_pmat_vec(inertia, u[i]), u[j]))

    def vadd(x: list[np.ndarray], y: list[np.ndarray]) -> list[np.ndarray]:
        return [P.polyadd(x[k], y[k]) for k in range(3)]

    # The quadratic form F(omega) = I^-1((I omega) x omega) split by monomial.
    fm = [
        b(0, 0),
        vadd(b(0, 1), b(1, 0)),
        vadd(b(0, 2), b(2, 0)),
        b(1, 1),
        vadd(b(1, 2), b(2, 1)),
        b(2, 2),
    ]
    num = np.zeros((3, 6, _DEG))
    for m, f in enumerate(fm):
        s = _pdot(a, f)  # (a, F_m)
        for row, comp in ((ROW_Q, 1), (ROW_R, 2)):
            # omega' = F - (a, F)/D I^-1 a  (+ the g' q term below), times D.
            num[row, m] = _pad(P.polysub(P.polymul(den, f[comp]), P.polymul(s, ma[comp])))
        num[ROW_LAMBDA, m] = _pad(-s)
    gpc = np.zeros((3, 2))
    gpc[ROW_Q] = _pad(ma[1], 2)
    gpc[ROW_R] = _pad(ma[2], 2)
    gpc[ROW_LAMBDA] = (1.0, 0.0)
    return num, gpc, _pad(den, 3)


@functools.lru_cache(maxsize=256)
def _tables(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # The exact polynomial algebra takes ~8 ms and one change of a slider builds the same model
    # for the section, the tracks, the T' map and the reliability check: build it once.
    # Read-only, so sharing them between models is safe.
    out = build_tables(params)
    for arr in out:
        arr.setflags(write=False)
    return out


# ---------------------------------------------------------------------------
# numba primitives shared by every kernel.

_jit = nb.njit(nogil=True, cache=True, fastmath=False, error_model="numpy")


@_jit
def forcing_g(forcing: np.ndarray, t: float) -> tuple[float, float]:
    """``g(t)`` and ``g'(t)`` for ``forcing = (g0, g1, g2, omega)``."""
    w = forcing[3]
    c = math.cos(w * t)
    s = math.sin(w * t)
    return forcing[0] + forcing[1] * c + forcing[2] * s, w * (forcing[2] * c - forcing[1] * s)


@_jit
def coefficients_at(num: np.ndarray, gpc: np.ndarray, den: np.ndarray, g: float, gp: float, out: np.ndarray) -> None:
    """Fill ``out[row, m]`` with the monomial coefficients of Q, R, lambda at (g, g')."""
    dinv = 1.0 / (den[0] + g * (den[1] + g * den[2]))
    nrow = out.shape[0]
    for row in range(nrow):
        for m in range(6):
            c = num[row, m]
            v = c[0] + g * (c[1] + g * (c[2] + g * (c[3] + g * c[4])))
            if m == 1:
                v += gp * (gpc[row, 0] + g * gpc[row, 1])
            out[row, m] = v * dinv


@_jit
def eval_quadratic(c: np.ndarray, row: int, q: float, r: float) -> float:
    """``c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2`` for one row of coefficients."""
    return c[row, 0] + q * (c[row, 1] + c[row, 3] * q + c[row, 4] * r) + r * (c[row, 2] + c[row, 5] * r)


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
    """``(Q, R)`` at ``(q, r, t)``; ``work`` is a (>=2, 6) scratch array."""
    g, gp = forcing_g(forcing, t)
    coefficients_at(num[:2], gpc[:2], den, g, gp, work)
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
    def forcing(self) -> np.ndarray:
        return self.params.forcing

    def g(self, t: float) -> tuple[float, float]:
        """``g(t), g'(t)``."""
        return forcing_g(self.forcing, float(t))

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
