"""The system at a point ``(x, p)``: ``P^n``, its derivatives, the test functions and a bifurcation's defining system.

A period-``n`` orbit is a zero of ``F(x, p) = P^n(x; p) - x``. ``DP^n`` is the exact monodromy matrix (tangent
system); ``F_p`` a central difference whose three members (``p``, ``p +- delta``) go in one lock-step batch, so
they share one step sequence and the difference is smooth in ``p`` (:class:`_System`).

The test functions (Kuznetsov, *Elements of Applied Bifurcation Theory*, ch. 10; as in MatContM) are
``det(A - I)`` (fold, ``mu = +1``), ``det(A + I)`` (period doubling, ``mu = -1``) and ``det A - 1`` on a complex
pair (Neimark-Sacker, ``|mu| = 1``), ``A = DP^n`` (:func:`test_function`). A fold or a period doubling is a zero
of its defining system ``G = (P^n(x) - x, phi(DP^n))`` (:func:`_defining`), ``phi`` the test function, with
``phi``'s derivatives by central differences of the monodromy (up to nine members in one lock-step batch).

The engine, the events, the normal forms and the two-parameter curves ask a map for no more than
:class:`ContinuationMap` says (``P^n``, ``DP^n``, ``F_p`` at ``(x, p)``); :class:`_System` is this system's
(the Poincare map, integrated), :mod:`.testmaps` has maps in closed form (Henon, the delayed logistic map) that
test the engine against exact bifurcation sets.

:class:`_Stop` is how anything here or in the engine refuses a step or ends a branch, with its status.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from explorer_core.solve.numerics import Numerics
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.tangent import Monodromy, monodromy_at
from explorer_core.status import Status
from explorer_core.system.params import ParameterError, Params

#: Bifurcation types and their test functions.
KINDS = ("fold", "period_doubling", "neimark_sacker")
#: Relative size of the parameter step of the finite differences (divided by ``sqrt(|DP^n|)`` on a branch).
FD_STEP = 1e-7
#: The central differences integrate this many times less accurately than the orbit, at most at FD_RTOL_MAX,
#: and to a relative error ~FD_ACCURACY / 10 (see :meth:`_System.fd_numerics`).
FD_LOOSEN = 1e3
FD_RTOL_MAX = 1e-9
FD_ACCURACY = 1e-6


class _Stop(Exception):
    """A step is refused (or a branch ends) for the reason given; ``status`` says it in the one vocabulary."""

    def __init__(self, why: str, status: Status = Status.NOT_CONVERGED) -> None:
        super().__init__(why)
        self.status = status


def _failed(code: int) -> _Stop:
    """The stop of an orbit whose trajectory the engine ended with ``code``."""
    st = Status.of(int(code))
    return _Stop(f"the orbit's trajectory failed: {st.label}", st)


#: The inertia's components, parameters that are not attributes of :class:`Params`.
_INERTIA = ("I11", "I22", "I33", "I12", "I13", "I23")


class ContinuationMap(Protocol):
    """What the continuation asks of a map ``x -> P(x; p)`` of the plane: its ``n``-th iterate and derivatives at
    ``(x, p)``, ``p`` the values of the continuation parameters ``names`` (one on a branch, two on a curve).

    Branches and located bifurcations need :meth:`orbit`, :meth:`fp` and :meth:`evaluate`; the error estimate of
    a located value :meth:`coarse`; the normal forms :meth:`jacobians`; the two-parameter curves :meth:`over`
    and :meth:`value`. Failures (the orbit escaped, the parameters left the valid ones) raise :class:`_Stop`.
    """

    names: list[str]

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P^n(x)``, ``A = DP^n(x)`` (2, 2) and the points ``P(x) .. P^n(x)`` (n, 2)."""
        ...

    def fp(self, x: np.ndarray, p: Sequence[float], n: int, amp: float = 1.0) -> np.ndarray:
        """``dP^n/dp_k`` (2, k); ``amp = |DP^n|`` may set the step of a finite difference."""
        ...

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False) -> tuple[Any, ...]:
        """``(P^n(x), DP^n, F_p, div, points, extra)``: ``div`` anything (unused by the engine); with ``dx``,
        ``extra = {"A_p": [(A(p_k + d), A(p_k - d), d), ...], "A_x": [(A(x + h e_j), A(x - h e_j), h), ...]}``
        (the derivatives of a test function by central differences), else None."""
        ...

    def jacobians(self, xs: np.ndarray, p: Sequence[float], n: int) -> np.ndarray:
        """``DP^n`` at the points ``xs`` (m, 2), (m, 2, 2), to the accuracy of :meth:`orbit` and smooth in ``x``
        (the normal forms difference them)."""
        ...

    def coarse(self) -> ContinuationMap:
        """The same map computed less accurately (ten times, for an integrated one): the shift of a located
        value under it is the value's error estimate. A map in closed form is its own."""
        ...

    def over(self, names: Sequence[str]) -> ContinuationMap:
        """The same map (the same values of every parameter) with ``names`` as its continuation parameters."""
        ...

    def value(self, name: str) -> float:
        """The value of the parameter ``name`` (at the point the map was made at)."""
        ...


class _System:
    """``P^n`` and its derivatives at ``(x, p...)`` for one or two continuation parameters: this system's
    :class:`ContinuationMap` (the Poincare map, ``DP^n`` by the tangent system)."""

    def __init__(self, base: Params, names: Sequence[str], numerics: Numerics, workers: int | None) -> None:
        self.base = base
        self.names = list(names)
        self.numerics = numerics
        self.workers = workers
        self._fd: dict[tuple[float, float], Numerics] = {}

    def fd_numerics(self, amp: float) -> Numerics:
        """The integration of the central differences' members at an orbit with ``|DP^n| = amp``.

        The differences (``F_p``, the test function's derivatives) only steer Newton and give the tangent:
        members in lock-step share one step sequence, so their difference is smooth at any tolerance, and its
        relative error is ~0.1 ``rtol |DP^n|`` (measured on Fig. 10's period-16 orbit). They run up to
        ``FD_LOOSEN`` times looser than the orbit (at most ``FD_RTOL_MAX``), with that error below
        :data:`FD_ACCURACY` / 10, never more accurately than the orbit. ``P^n`` and ``DP^n`` at the point
        itself (the residual, the multipliers) keep the accuracy asked.
        """
        tol = {k: max(v, min(FD_RTOL_MAX, v * FD_LOOSEN, FD_ACCURACY / max(1.0, amp)))
               for k, v in (("rtol", self.numerics.rtol), ("atol", self.numerics.atol))}  # fmt: skip
        key = (tol["rtol"], tol["atol"])
        if key not in self._fd:
            self._fd[key] = self.numerics.loosened(tol["rtol"], tol["atol"])  # the method chosen again if auto chose
        return self._fd[key]

    def coarse(self) -> _System:
        loose = self.numerics.loosened(self.numerics.rtol * 10, self.numerics.atol * 10)
        return _System(self.base, self.names, loose, 1)

    def over(self, names: Sequence[str]) -> _System:
        return _System(self.base, names, self.numerics, self.workers)

    def value(self, name: str) -> float:
        return float(getattr(self.base, name) if name not in _INERTIA else self.base.inertia[_INERTIA.index(name)])

    def jacobians(self, xs: np.ndarray, p: Sequence[float], n: int) -> np.ndarray:
        """``DP^n`` at the points ``xs``: one lock-step batch (one step sequence, so differences of the matrices
        are smooth) at the accuracy asked."""
        prs = [self.params(p)] * len(xs)
        mono = monodromy_at(prs, np.asarray(xs, dtype=float), n, self.numerics, workers=1, block=len(xs))
        bad = np.flatnonzero(mono.status != Status.OK)
        if bad.size:
            raise _failed(mono.status[bad[0]])
        return mono.matrix

    def params(self, p: Sequence[float]) -> Params:
        try:
            return self.base.with_(**{n: float(v) for n, v in zip(self.names, p, strict=True)})
        except ParameterError as exc:
            raise _Stop(f"left the valid parameters ({exc})", Status.INVALID) from None

    def delta(self, p: float, amp: float = 1.0) -> float:
        """The parameter step of ``F_p``. ``P^n`` bends in ``p`` on a scale that shrinks with the orbit's
        instability ``amp = |DP^n|``: at ``|DP^16| ~ 4e3`` (Fig. 10, alpha = -0.423) ``FD_STEP`` alone puts
        the tangent 20 degrees off the branch, and every step is refused. Lock-step members keep the
        smaller difference smooth."""
        return FD_STEP * (1.0 + abs(p)) / math.sqrt(max(1.0, amp))

    def orbit(self, x: np.ndarray, p: Sequence[float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P^n(x)``, ``A = DP^n(x)`` and the points ``P(x) .. P^n(x)`` at the parameters ``p``."""
        mono = monodromy_at([self.params(p)], x[None, :], n, self.numerics, workers=1, block=1)
        if mono.status[0] != Status.OK:
            raise _failed(mono.status[0])
        return mono.end[0], mono.matrix[0], mono.points[0]

    def fp(self, x: np.ndarray, p: Sequence[float], n: int, amp: float = 1.0) -> np.ndarray:
        """``dP^n/dp_k`` (2, k): central differences, ``p_k +- delta`` in one lock-step batch (one step sequence)."""
        prs = []
        for k in range(len(p)):
            for sgn in (1.0, -1.0):
                q = list(p)
                q[k] += sgn * self.delta(p[k], amp)
                prs.append(self.params(q))
        pmap = PoincareMap.members(prs, self.fd_numerics(amp), workers=1, block=len(prs))
        y, status = pmap.image(np.repeat(x[None, :], len(prs), axis=0), n)
        bad = np.flatnonzero(status != Status.OK)
        if bad.size:
            raise _failed(status[bad[0]])
        return np.column_stack([(y[2 * k] - y[2 * k + 1]) / (2 * self.delta(p[k], amp)) for k in range(len(p))])

    def evaluate(self, x: np.ndarray, p: Sequence[float], n: int, dx: bool = False):
        """``P^n(x)``, ``A = DP^n``, ``F_p`` (2, k) and, with ``dx``, ``A`` at ``x +- delta e_j`` and ``p +- delta``.

        The base point at the accuracy asked, then one lock-step batch (:meth:`fd_numerics`): ``p_k +- delta``
        for each parameter, then (``dx``) ``x +- delta e_j``.
        """
        p = list(p)
        pts, prs = [x], [self.params(p)]
        for k in range(len(p)):
            for sgn in (1.0, -1.0):
                q = list(p)
                q[k] += sgn * self.delta(p[k])
                pts.append(x)
                prs.append(self.params(q))
        hx = FD_STEP * (1.0 + float(np.abs(x).max()))
        if dx:
            for j in range(2):
                for sgn in (1.0, -1.0):
                    pts.append(x + sgn * hx * np.eye(2)[j])
                    prs.append(prs[0])
        # The point at the accuracy asked; the differences' members (lock-step among themselves) looser.
        at = monodromy_at(prs[:1], np.array(pts[:1]), n, self.numerics, workers=1, block=1)
        if at.status[0] != Status.OK:
            raise _failed(at.status[0])
        fd = monodromy_at(prs[1:], np.array(pts[1:]), n, self.fd_numerics(float(np.abs(at.matrix[0]).max())),
                          workers=self.workers, block=len(prs) - 1)  # fmt: skip
        mono = Monodromy(*(np.concatenate([u, v]) for u, v in zip(_fields(at), _fields(fd), strict=True)))
        bad = np.flatnonzero(mono.status != Status.OK)
        if bad.size:
            raise _failed(mono.status[bad[0]])
        fp = np.column_stack([(mono.end[1 + 2 * k] - mono.end[2 + 2 * k]) / (2 * self.delta(p[k]))
                              for k in range(len(p))])  # fmt: skip
        extra = None
        if dx:
            o = 1 + 2 * len(p)
            extra = {
                "A_p": [(mono.matrix[1 + 2 * k], mono.matrix[2 + 2 * k], self.delta(p[k])) for k in range(len(p))],
                "A_x": [(mono.matrix[o + 2 * j], mono.matrix[o + 2 * j + 1], hx) for j in range(2)],
            }
        return mono.end[0], mono.matrix[0], fp, mono.div[0], mono.points[0], extra


def _fields(m: Monodromy) -> tuple[np.ndarray, ...]:
    return m.end, m.matrix, m.div, m.points, m.status, m.nsteps


def test_function(kind: str, a: np.ndarray) -> float:
    """``det(A - I)`` (fold), ``det(A + I)`` (period doubling), ``det A - 1`` (Neimark-Sacker)."""
    if kind == "fold":
        return float(np.linalg.det(a - np.eye(2)))
    if kind == "period_doubling":
        return float(np.linalg.det(a + np.eye(2)))
    return float(np.linalg.det(a) - 1.0)


def _complex_pair(a: np.ndarray) -> bool:
    tr, det = float(np.trace(a)), float(np.linalg.det(a))
    return tr * tr < 4.0 * det


def _defining(sys: ContinuationMap, kind: str, n: int,
              Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The bifurcation's defining system at ``Y = (q, r, p_1, ...)``: ``G = (P^n(x) - x, test(A))``, its Jacobian,
    ``A`` and the section points ``P(x) .. P^n(x)``.

    ``DP^n`` exact; the derivatives of the test function and ``F_p`` by central differences of one
    lock-step batch (base, ``p_k +- delta``, ``x +- delta e_j``).
    """
    end, a, fp, _, pts, ex = sys.evaluate(Y[:2], list(Y[2:]), n, dx=True)
    dphi_x = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_x"]]
    dphi_p = [(test_function(kind, ap) - test_function(kind, am)) / (2 * h) for ap, am, h in ex["A_p"]]
    g = np.concatenate([end - Y[:2], [test_function(kind, a)]])
    jac = np.vstack([np.column_stack([a - np.eye(2), fp]), np.array([*dphi_x, *dphi_p])[None, :]])
    return g, jac, a, pts


def _residual(sys: ContinuationMap, kind: str, n: int, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The defining system's ``G`` alone at ``Y``, with ``A`` and the orbit ``x, P(x), ..., P^(n-1)(x)``: one
    integration of the tangent system (no central differences)."""
    end, a, pts = sys.orbit(Y[:2], list(Y[2:]), n)
    return np.concatenate([end - Y[:2], [test_function(kind, a)]]), a, np.vstack([Y[None, :2], pts[: n - 1]])
