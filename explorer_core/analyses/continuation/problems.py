"""The problems the engine follows the zeros of, each in scaled coordinates: a branch of period-``n`` orbits
(:class:`_BranchProblem`, ``P^n(x) - x = 0`` in ``(q, r, s)``) and a curve of folds or period doublings
(:class:`_CurveProblem`, the defining system in ``(q, r, s1, s2)``). A problem evaluates its equations, their
Jacobian and ``DP^n`` at a point, says when the corrector has converged, and names the box of its range
(``box``: the coordinates bounded to ``[0, 1]``)."""

from __future__ import annotations

import numpy as np

from explorer_core.analyses.continuation.system import ContinuationMap, _defining


class _BranchProblem:
    """``P^n(x) - x = 0`` in ``(q, r, s)``, ``s = (p - A) / (B - A)``: the range is ``s`` in ``[0, 1]``.

    The scaling makes one arclength unit comparable in state and parameter, so a step of ``ds_max``
    moves the parameter by at most ``ds_max`` of the range however fast the orbit moves.
    """

    def __init__(self, sys: ContinuationMap, rng: tuple[float, float], n: int, tol: float) -> None:
        self.sys, self.n, self.tol = sys, n, tol
        self.a, self.b = rng
        self.box = ((2, 0.0, 1.0),)

    def p(self, X: np.ndarray) -> float:
        return self.a + float(X[2]) * (self.b - self.a)

    def scaled(self, p: float) -> float:
        return (p - self.a) / (self.b - self.a)

    def fs(self, X: np.ndarray, a: np.ndarray) -> np.ndarray:
        amp = float(np.abs(a).max())
        return self.sys.fp(X[:2], [self.p(X)], self.n, amp)[:, 0] * (self.b - self.a)

    def evaluate(self, X: np.ndarray, chord: np.ndarray | None = None):
        """``F``, its Jacobian ``[DP^n - I | F_s]``, ``DP^n``, the orbit; ``chord``: its last column is ``F_s``."""
        n = self.n
        end, a, pts = self.sys.orbit(X[:2], [self.p(X)], n)
        fs = self.fs(X, a) if chord is None else chord[:, 2]
        return end - X[:2], np.column_stack([a - np.eye(2), fs]), a, np.vstack([X[None, :2], pts[: n - 1]])

    def fresh(self, X: np.ndarray, jac: np.ndarray) -> np.ndarray:
        return np.column_stack([jac[:, :2], self.fs(X, jac[:, :2] + np.eye(2))])

    def converged(self, f: np.ndarray, g: float, dX: np.ndarray, X: np.ndarray, a: np.ndarray) -> bool:
        # P^n is computed to ~rtol |x| and its error grows with |DP^n|: ask no more of the residual.
        scale = (1.0 + float(np.abs(X[:2]).max())) * max(1.0, float(np.abs(a).max()))
        return bool(np.linalg.norm(f) <= self.tol * scale and abs(g) <= self.tol)


class _CurveProblem:
    """A bifurcation's defining system ``(P^n(x) - x, phi(DP^n)) = 0`` in ``(q, r, s1, s2)``, each parameter
    scaled to its range: a step of ``curve_ds_max`` moves each parameter by at most that fraction of its range."""

    def __init__(self, sys: ContinuationMap, kind: str, n: int, origin: np.ndarray, width: np.ndarray,
                 tol: float) -> None:  # fmt: skip
        self.sys, self.kind, self.n, self.o, self.w, self.tol = sys, kind, n, origin, width, tol
        self.box = ((2, 0.0, 1.0), (3, 0.0, 1.0))

    def unscaled(self, Z: np.ndarray) -> np.ndarray:
        return self.o + self.w * Z

    def evaluate(self, Z: np.ndarray, chord: np.ndarray | None = None):
        Y = self.unscaled(Z)
        g, jac, a, pts = _defining(self.sys, self.kind, self.n, Y)
        return g, jac * self.w[None, :], a, np.vstack([Y[None, :2], pts[: self.n - 1]])

    def fresh(self, Z: np.ndarray, jac: np.ndarray) -> np.ndarray:
        return jac

    def converged(self, f: np.ndarray, g: float, dX: np.ndarray, Z: np.ndarray, a: np.ndarray) -> bool:
        # Converged when the Newton step is at the accuracy of the map (the test function's own
        # scale grows with the multipliers: no absolute bound on it means anything).
        scale = 1.0 + float(np.abs(Z[:2]).max())
        return bool(np.linalg.norm(f[:2]) <= self.tol * scale * 10 and np.abs(dX).max() <= 1e-9 * scale)
