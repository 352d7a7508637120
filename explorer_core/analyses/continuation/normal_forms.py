"""Normal-form coefficients of fold, period-doubling (flip) and Neimark-Sacker points of ``P^n``.

At a located bifurcation with ``A = DP^n``, its critical eigenvector ``q`` and adjoint eigenvector ``p``
(``A q = mu q``, ``A^T p = conj(mu) p``, ``<p, q> = conj(p) . q = 1``, ``<q, q> = 1``), and the multilinear forms of
the map's second and third derivatives ``B(u, v) = D^2 P^n [u, v]``, ``C(u, v, w) = D^3 P^n [u, v, w]``
(Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed., Sect. 5.4, the invariant formulas for maps in
``R^n``; MatContM's ``nf_LP``, ``nf_PD``, ``nf_NS`` for maps; BifurcationKit's ``period_doubling_normal_form``):

* fold (``mu = 1``), ``eta -> eta + beta + a eta^2``: ``a = 1/2 <p, B(q, q)>``. Its sign goes with ``q``'s, here
  oriented so that its largest component is positive: it says which way the branch turns, no criticality.
* flip (``mu = -1``), ``eta -> -(1 + beta) eta + b eta^3``:
  ``b = 1/6 <p, C(q, q, q)> + 1/2 <p, B(q, (I - A)^-1 B(q, q))>``. ``b > 0``: supercritical (the doubled orbit is
  born stable on the side where the orbit loses stability, a soft transition); ``b < 0``: subcritical (born
  unstable on the side where the orbit is stable: a jump, hysteresis).
* Neimark-Sacker (``mu = e^{i theta}``, ``0 < theta < pi``), ``z -> e^{i theta} z (1 + beta + d |z|^2)``:
  ``d = 1/2 e^{-i theta} [<p, C(q, q, conj q)> + 2 <p, B(q, (I - A)^-1 B(q, conj q))>
  + <p, B(conj q, (e^{2 i theta} I - A)^-1 B(q, q))>]``; the coefficient is ``Re d`` (the first Lyapunov
  coefficient): ``< 0`` supercritical (a stable invariant curve is born), ``> 0`` subcritical. Near a strong
  resonance ``e^{i k theta} = 1``, ``k = 1 .. 4`` (:data:`RESONANCE_TOL`), the normal form above does not hold
  (``k = 1, 3``: ``e^{2 i theta} I - A`` is singular): the point says so.

``B`` and ``C`` are central differences of the exact ``DP^n`` (the tangent system; one differentiation less than
differencing ``P^n``), in one lock-step batch (:meth:`~.system.ContinuationMap.jacobians`): at a fold or a flip
along ``q`` only (``x +- h q``: their forms all take ``q`` first), at a Neimark-Sacker point the whole tensors
(``x +- h e_k``, ``x +- h e_k +- h e_l``); for two steps ``h`` and ``h / 2``: the coefficient is their Richardson
extrapolation (the differences' error goes as ``h^2``), its error estimate the difference of the two (three times
the estimated error of the finer one: the noise of the map is in it too).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core.analyses.continuation.system import ContinuationMap

#: The larger step of the differences, relative to ``1 + |x|`` and divided by ``sqrt(|DP^n|)`` (the map bends on a
#: scale that shrinks with the orbit's instability, as for ``F_p``, :meth:`~.system._System.delta`).
NF_STEP = 1e-3
#: The least error of a coefficient, relative to ``1 + |DP^n|``: the rounding of its second differences of ``DP^n``
#: (``eps / NF_STEP^2``, with a margin), which the Richardson estimate misses where the map's third derivatives
#: vanish (an area-preserving map's ``Re d`` is 0 identically: rounding, no criticality).
NF_FLOOR = 1e-9
#: A Neimark-Sacker point is near the strong resonance 1:k when ``|k theta mod 2 pi| <`` this (radians).
RESONANCE_TOL = 1e-2


@dataclass(frozen=True)
class NormalForm:
    """A bifurcation's normal-form coefficient (fold ``a``, flip ``b``, Neimark-Sacker ``Re d``), its error estimate,
    its ``criticality`` (``supercritical``, ``subcritical``; ``""`` for a fold, or when the coefficient is not
    distinguishable from 0 within its error) and, at a Neimark-Sacker point, ``resonance`` (``"1:k"`` near a strong
    resonance, where the coefficient does not decide; else None)."""

    coefficient: float
    error: float
    criticality: str
    resonance: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"coefficient": self.coefficient, "coefficient_error": self.error, "criticality": self.criticality,
                "resonance": self.resonance}  # fmt: skip


def _stencil(kind: str, x: np.ndarray, q: np.ndarray, h: float) -> list[np.ndarray]:
    """Where ``DP^n`` is differenced with the step ``h``: a fold's and a flip's forms all take ``q`` first, so
    ``x +- h q`` give ``B(q, .)`` and ``C(q, q, .)``; a Neimark-Sacker point's take complex vectors: the whole
    tensors, from ``x +- h e_k`` and ``x +- h e_k +- h e_l``."""
    if kind != "neimark_sacker":
        return [x + h * q, x - h * q]
    e = np.eye(len(x))
    pts = [x + s * h * e[k] for k in range(len(x)) for s in (1.0, -1.0)]
    pairs = itertools.combinations(range(len(x)), 2)
    return pts + [x + h * (s * e[k] + t * e[j]) for k, j in pairs for s, t in ((1, 1), (1, -1), (-1, 1), (-1, -1))]


def derivatives(m: np.ndarray, a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The tensors ``T2[i, j, k] = d^2 P_i / dx_j dx_k`` and ``T3[i, j, k, l]``, symmetrised, from ``DP^n`` at the
    Neimark-Sacker :func:`_stencil` ``m`` (``a`` at its centre) with the step ``h``."""
    d = len(a)
    pairs = list(itertools.combinations(range(d), 2))
    t2 = np.stack([(m[2 * k] - m[2 * k + 1]) / (2 * h) for k in range(d)], axis=-1)
    t2 = 0.5 * (t2 + t2.transpose(0, 2, 1))
    t3 = np.empty((d, d, d, d))
    for k in range(d):
        t3[..., k, k] = (m[2 * k] - 2 * a + m[2 * k + 1]) / h**2
    for i, (k, j) in enumerate(pairs):
        pp, pm, mp, mm = m[2 * d + 4 * i : 2 * d + 4 * i + 4]
        t3[..., k, j] = t3[..., j, k] = (pp - pm - mp + mm) / (4 * h**2)
    t3 = sum(t3.transpose(0, *perm) for perm in itertools.permutations((1, 2, 3))) / 6.0
    return t2, t3


def eigenpair(a: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray, complex]:
    """``q``, ``p`` and ``mu`` of a bifurcation of ``kind``: ``A q = mu q``, ``A^T p = conj(mu) p``, ``<q, q> = 1``,
    ``<p, q> = 1``; real for a fold (``mu`` nearest 1) or a flip (nearest -1), ``q``'s largest component positive;
    at a Neimark-Sacker point ``mu`` the multiplier with ``Im mu > 0``."""
    w, v = np.linalg.eig(a)
    wl, vl = np.linalg.eig(a.T)
    if kind == "neimark_sacker":
        i = int(np.argmax(w.imag))
        mu = complex(w[i])
        q = v[:, i].astype(complex)
        p = vl[:, int(np.argmin(np.abs(wl - np.conj(mu))))].astype(complex)
    else:
        target = 1.0 if kind == "fold" else -1.0
        i = int(np.argmin(np.abs(w - target)))
        mu = complex(w[i].real)
        q = np.real(v[:, i])
        p = np.real(vl[:, int(np.argmin(np.abs(wl - target)))])
    q = q / np.linalg.norm(q)
    if kind != "neimark_sacker":
        q = q if q[int(np.argmax(np.abs(q)))] > 0 else -q
    p = p / np.conj(np.vdot(p, q))
    return q, p, mu


def coefficient(kind: str, a: np.ndarray, m: np.ndarray, h: float) -> float:
    """The normal-form coefficient of ``kind`` (fold ``a``, flip ``b``, Neimark-Sacker ``Re d``) from ``A = DP^n``
    and ``DP^n`` at the :func:`_stencil` ``m`` of the step ``h`` (module docstring)."""
    q, p, mu = eigenpair(a, kind)
    eye = np.eye(len(q))
    if kind != "neimark_sacker":
        b_q, c_qq = (m[0] - m[1]) / (2 * h), (m[0] - 2 * a + m[1]) / h**2  # B(q, .), C(q, q, .)
        if kind == "fold":
            return float(0.5 * p @ b_q @ q)
        h2 = np.linalg.solve(eye - a, b_q @ q)
        return float(p @ c_qq @ q / 6.0 + 0.5 * p @ b_q @ h2)
    t2, t3 = derivatives(m, a, h)
    b = lambda u, v: np.einsum("ijk,j,k->i", t2, u, v)  # noqa: E731
    c = lambda u, v, w: np.einsum("ijkl,j,k,l->i", t3, u, v, w)  # noqa: E731
    qb = np.conj(q)
    e = mu / abs(mu)
    h11 = np.linalg.solve(eye - a, b(q, qb))
    h20 = np.linalg.solve(e * e * eye - a, b(q, q))
    d = 0.5 / e * (np.vdot(p, c(q, q, qb)) + 2.0 * np.vdot(p, b(q, h11)) + np.vdot(p, b(qb, h20)))
    return float(d.real)


def resonance(mu: complex) -> str | None:
    """``"1:k"`` if ``mu = e^{i theta}`` is within :data:`RESONANCE_TOL` of a strong resonance (``k = 1 .. 4``)."""
    theta = abs(math.atan2(mu.imag, mu.real))
    for k in range(1, 5):
        r = (k * theta) % (2 * math.pi)
        if min(r, 2 * math.pi - r) < RESONANCE_TOL:
            return f"1:{k}"
    return None


def normal_form(sys: ContinuationMap, kind: str, x: np.ndarray, p: list[float], n: int,
                a: np.ndarray) -> NormalForm:  # fmt: skip
    """The normal-form coefficient of the bifurcation ``kind`` of ``P^n`` at ``(x, p)`` (``a = DP^n`` there), with
    its error estimate and criticality (module docstring; none near a strong resonance). Raises
    :class:`numpy.linalg.LinAlgError` where a resolvent is singular (at a strong resonance 1:1 or 1:3, or a
    multiplier 1 beside a flip), :class:`~.system._Stop` if the map fails at a point of the differences."""
    x = np.asarray(x, dtype=float)
    h = NF_STEP * (1.0 + float(np.abs(x).max())) / math.sqrt(max(1.0, float(np.abs(a).max())))
    q = eigenpair(a, kind)[0]
    steps = (h, 0.5 * h)
    stencils = [_stencil(kind, x, q, s) for s in steps]
    m = sys.jacobians(np.array([pt for st in stencils for pt in st]), p, n)  # one lock-step batch
    c1, c2 = (coefficient(kind, a, m[i * len(stencils[0]) : (i + 1) * len(stencils[0])], s)
              for i, s in enumerate(steps))  # fmt: skip
    value, error = c2 + (c2 - c1) / 3.0, abs(c2 - c1)
    res = resonance(eigenpair(a, kind)[2]) if kind == "neimark_sacker" else None
    crit = ""
    if kind != "fold" and abs(value) > max(error, NF_FLOOR * (1.0 + float(np.abs(a).max()))) and res is None:
        sign = value if kind == "period_doubling" else -value
        crit = "supercritical" if sign > 0 else "subcritical"
    return NormalForm(value, error, crit, res)
