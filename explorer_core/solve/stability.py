"""What limits an explicit step: the field's fastest rate and each method's real stability interval.

Used at run time (the reliability checks of :mod:`explorer_core.analyses.reliability`) and by the
failure study (:mod:`explorer_core.studies.failures`).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

from explorer_core.solve.tableaus import get_method
from explorer_core.system.model import Model
from explorer_core.system.params import Params


def relative_error(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``|x - ref| / (1 + |ref|)`` over the last axis (points of size O(1) and O(1000) alike)."""
    x = np.asarray(x, dtype=float)
    ref = np.asarray(ref, dtype=float)
    return np.linalg.norm(x - ref, axis=-1) / (1.0 + np.linalg.norm(ref, axis=-1))


def spectral_rate(params: Params, q: Any, r: Any, n_t: int = 64) -> np.ndarray:
    """Fastest rate of the field at frozen states: ``max_t`` of the Jacobian's spectral radius.

    The explicit methods' step limits scale with it (``rho h`` against the stability
    interval). For the drift of Fig. 1A at ``q = -0.3`` it is ``|r| / 3``. ``t`` runs
    over ``n_t`` samples of one period; the state is held fixed (only section points are known).
    """
    model = Model(params)
    q = np.atleast_1d(np.asarray(q, dtype=float))
    r = np.atleast_1d(np.asarray(r, dtype=float))
    out = np.zeros(np.broadcast(q, r).shape)
    for t in params.t0 + params.period * np.arange(n_t) / n_t:
        j = model.jacobian(q, r, float(t))
        tr = 0.5 * (j[..., 0, 0] + j[..., 1, 1])
        det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
        disc = tr * tr - det
        root = np.sqrt(np.abs(disc))
        real = np.maximum(np.abs(tr + root), np.abs(tr - root))
        out = np.maximum(out, np.where(disc >= 0.0, real, np.sqrt(np.abs(det))))
    return out


@cache
def stability_interval(method: str) -> float:
    """``beta``: the method is stable on ``[-beta, 0]`` of the real axis (``|R(z)| <= 1``).

    From its tableau: ``R(z) = 1 + sum_j z^j b^T A^(j-1) 1`` (explicit, so a polynomial):
    RK4 2.785, DP5 3.307, DOP853 6.39. An explicit step on a decaying mode of rate
    ``rho`` must satisfy ``rho h <= beta``.
    """
    meth = get_method(method)
    s = meth.b.shape[0]
    a = meth.a[:s, :s]
    coef = [1.0]
    v = np.ones(s)
    for _ in range(s):
        coef.append(float(meth.b @ v))
        v = a @ v
    x = -np.arange(1, 400_001) * 2.5e-5  # z on (0, -10]
    unstable = np.abs(np.polynomial.polynomial.polyval(x, coef)) > 1.0 + 1e-12
    return float(-x[np.argmax(unstable) - 1]) if unstable.any() else 10.0
