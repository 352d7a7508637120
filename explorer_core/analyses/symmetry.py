"""Reversibility of the reduced system: the involution ``t -> -t, q -> q, r -> -r``.

The paper (section "Two critical points") states that for an even ``g`` the
equations are invariant under ``t -> -t, q -> q, r -> -r``, so attractors and
repellers of the Poincare map come in symmetric pairs. For a centre ``s`` of
the involution (``t -> 2 s - t``) the field must satisfy::

    Q(q, -r, t) = -Q(q, r, 2 s - t),     R(q, -r, t) = R(q, r, 2 s - t).

Then the backward section from ``(q0, -r0)`` at ``s`` is the mirror image of the
forward section from ``(q0, r0)``: ``y_k = (q_k, -r_k)``. This module checks it
both ways:

* on the field (:func:`field_residual`: the two identities on sample points),
* on computed sections (:func:`check_symmetry`: the distance between the
  backward section and the reflected forward one),

and names what breaks it. Verified here (and in ``tests/test_symmetry.py``): it
holds for ``I13 = I23 = 0`` with any ``I12``; ``I13 != 0`` or ``I23 != 0`` (the
tensors of Figs. 4-11) break it. ``g = g0 + g1 cos(w t) + g2 sin(w t)`` is even
about ``phi = atan2(g2, g1) / w`` (and ``phi + T/2``), so ``g2 != 0`` breaks the
involution about ``t = 0`` only: about ``phi`` it holds again.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core.analyses.specs import Checking
from explorer_core.losses import Loss
from explorer_core.solve.numerics import Numerics, check_ics, check_int, random_ics
from explorer_core.solve.options import POSITIVE, Arg, declare, ics, integer, number, optional_of
from explorer_core.solve.options import box as box_check
from explorer_core.solve.options import seed as seed_check
from explorer_core.solve.section import section
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, check_time, reduce_time

#: A residual of the field identities below this (relative to the field's size) is rounding.
FIELD_TOL = 1e-12
#: A check's integration unless given: rtol = atol = 1e-12 (the "auto" method: vern9).
SYMMETRY_NUMERICS = Numerics(rtol=1e-12, atol=1e-12)


def symmetry_centres(params: Params) -> list[float]:
    """The times ``s`` in ``[0, T)`` about which ``g`` is even (all ``t`` if ``g`` is constant: ``[]``)."""
    if params.g1 == 0.0 and params.g2 == 0.0:
        return []
    phi = math.atan2(params.g2, params.g1) / params.omega
    T = params.period
    return sorted({phi % T, (phi + T / 2) % T})


def g_is_even_about(params: Params, s: float) -> bool:
    """``g(s + tau) == g(s - tau)`` for all ``tau``."""
    if params.g1 == 0.0 and params.g2 == 0.0:
        return True
    # g(s + tau) - g(s - tau) = -2 sin(w tau) (g1 sin(w s) - g2 cos(w s)), at s's phase (exact at any s).
    w = params.omega
    s = reduce_time(float(s), w)
    odd = params.g1 * math.sin(w * s) - params.g2 * math.cos(w * s)
    return abs(odd) <= 1e-12 * math.hypot(params.g1, params.g2)


def field_residual(params: Params, s: float, n: int = 64, seed: int = 0) -> float:
    """Largest relative violation of the field identities of the involution about ``s``.

    Sampled at ``n`` random ``(q, r, t)`` with ``|q|, |r| <= 3`` and ``t`` over a period.
    0 (to rounding) iff the field is reversible about ``s``.
    """
    model = Model(params)
    rng = np.random.default_rng(seed)
    s = reduce_time(float(s), params.omega)  # 2 s - t at s's phase: at s = 1e11 it would be rounded to 3e-5
    worst = 0.0
    for _ in range(n):
        q, r = rng.uniform(-3, 3, 2)
        t = s + rng.uniform(0, params.period)
        qa, ra = model.field(q, -r, t)
        qb, rb = model.field(q, r, 2 * s - t)
        scale = 1.0 + float(np.abs(model.field(q, r, t)).max())
        worst = max(worst, abs(float(qa + qb)) / scale, abs(float(ra - rb)) / scale)
    return worst


@dataclass(frozen=True)
class SymmetryCheck:
    """The involution about ``centre`` checked on a section.

    ``distance[i, k-1]`` is ``|y_k - (q_k, -r_k)|`` for initial condition ``i``
    (``y``: backward section from ``(q0, -r0)``), over the periods both runs completed.
    """

    params: Params
    centre: float
    ics: np.ndarray
    periods: int
    distance: np.ndarray
    npts: np.ndarray
    status: list[str]
    g_even: bool
    field_residual: float
    tol: float
    numerics: Numerics
    elapsed_s: float

    @property
    def lost(self) -> list[Loss]:
        """Initial conditions whose forward or backward run stopped before its last period (by status): their
        later points are not compared."""
        short = [i for i in range(self.ics.shape[0]) if self.npts[i] < self.periods]
        return [Loss("initial conditions", len(short), "a run stopped early: its later points are not compared")] \
            if short else []  # fmt: skip

    @property
    def complete(self) -> bool:
        return not self.lost

    @property
    def max_distance(self) -> float:
        vals = [self.distance[i, : self.npts[i]].max() for i in range(self.ics.shape[0]) if self.npts[i]]
        return float(max(vals)) if vals else 0.0

    @property
    def holds(self) -> bool:
        """The section is symmetric: every compared point within ``tol`` (and something was compared)."""
        return bool(self.npts.sum() > 0 and self.max_distance <= self.tol)

    def broken_by(self) -> list[str]:
        """What breaks the involution (empty if it holds)."""
        if self.holds:
            return []
        p = self.params
        out = []
        if not self.g_even:
            even = symmetry_centres(p)
            out.append(
                f"g is not even about t = {self.centre:.6g} (g2 = {p.g2:g}); it is even about "
                + (", ".join(f"{c:.6g}" for c in even) if even else "every t")
            )
        i13, i23 = p.inertia[4], p.inertia[5]
        if i13 != 0.0:
            out.append(f"I13 = {i13:g} != 0")
        if i23 != 0.0:
            out.append(f"I23 = {i23:g} != 0")
        if not out:
            out.append("numerical distance above tol (chaotic amplification or loose tolerance?)")
        return out

    def report(self) -> list[str]:
        """What the command line prints: the verdict and what breaks the involution."""
        verdict = "holds" if self.holds else "is broken"
        return [f"involution t -> {2 * self.centre:g} - t, r -> -r {verdict}: max distance {self.max_distance:.3g}",
                *(f"  broken by: {reason}" for reason in self.broken_by())]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        return {
            "holds": self.holds,
            "centre": self.centre,
            "g_even": self.g_even,
            "even_centres": symmetry_centres(self.params),
            "field_residual": self.field_residual,
            "max_distance": self.max_distance,
            "first_period_distance": float(self.distance[:, 0].max()) if self.npts.min() > 0 else None,
            "tol": self.tol,
            "broken_by": self.broken_by(),
            "trajectories": [
                {"ic": [float(q), float(r)], "status": st, "periods": int(n), "max_distance": float(d[:n].max())}
                if n
                else {"ic": [float(q), float(r)], "status": st, "periods": 0, "max_distance": None}
                for (q, r), st, n, d in zip(self.ics, self.status, self.npts, self.distance, strict=True)
            ],
            "periods": self.periods,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
        }


@dataclass(frozen=True)
class SymmetrySpec:
    """What defines a symmetry check (validated by :func:`symmetry_spec`; plain data)."""

    params: Params
    ics: tuple[tuple[float, float], ...]
    periods: int
    centre: float | None
    tol: float
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "ics": [list(x) for x in self.ics], "periods": self.periods,
                "centre": self.centre, "tol": self.tol, "numerics": self.numerics.as_dict()}  # fmt: skip


@declare(
    ics=Arg("initial condition (repeatable)", "points", flag="--ic", default=None, check=ics(optional=True)),
    periods=Arg("compared section points", "int", default=10, check=integer(1, 100_000)),
    random=Arg(
        "random initial conditions in --box (without --ic)", "int", metavar="N", default=4, checked_with=("ics",)
    ),
    box=Arg(
        "box of the random initial conditions",
        "box",
        metavar="QMIN,QMAX,RMIN,RMAX",
        default=(-1.0, 1.0, -1.0, 1.0),
        check=box_check(),
    ),
    seed=Arg("random seed of the initial conditions", "int", default=0, check=seed_check(optional=True)),
    centre=Arg("centre s of t -> 2s - t (default t0)", default=None, check=number(optional=True)),
    tol=Arg("largest distance counted as symmetric", default=1e-6, check=POSITIVE),
    numerics=Arg(
        "the integration", cli=False, default=SYMMETRY_NUMERICS, check=optional_of(Numerics, SYMMETRY_NUMERICS)
    ),
)
def symmetry_spec(
    params: Params,
    ics: np.ndarray | None,
    periods: int,
    *,
    random: int,
    box: tuple[float, float, float, float],
    seed: int,
    centre: float | None,
    tol: float,
    numerics: Numerics,
) -> SymmetrySpec:
    """A validated :class:`SymmetrySpec`: ``ics``, or ``random`` ones in ``box`` (``seed``) without them; the other
    options as :func:`check_symmetry`'s (a bad value raises ParameterError naming it, ``exc.option``: its keyword).
    The options are declared above: defaults, checks (run before this body), flags."""
    with Checking() as at:
        at("random")
        x = ics if ics is not None else random_ics(check_int("random", random, 1, 10_000), box, seed=seed)
    return SymmetrySpec(params, tuple((float(q), float(r)) for q, r in x), periods, centre, tol, numerics)


def check_symmetry(
    params: Params | SymmetrySpec,
    ics: Any = None,
    periods: int = 10,
    *,
    centre: float | None = None,
    tol: float = 1e-6,
    numerics: Numerics | None = None,
) -> SymmetryCheck:
    """Check ``t -> 2 s - t, q -> q, r -> -r`` on sections started at the centre ``s``.

    Parameters
    ----------
    params : the system (its ``t0`` is replaced by the centre).
    ics : (n, 2) initial conditions ``(q0, r0)`` at ``s``.
    periods : compared section points per trajectory; keep it short on chaotic orbits,
        where integration errors (~tolerance) grow like the Lyapunov exponent.
    centre : ``s``; default ``params.t0`` (the paper: ``t0 = 0``, ``g = cos t``).
    tol : largest distance still counted as symmetric.
    numerics : default rtol = atol = 1e-12 (the "auto" method: vern9).
    """
    start = time.perf_counter()
    if isinstance(params, SymmetrySpec):
        if ics is not None:
            raise TypeError(f"a SymmetrySpec comes alone, not with {ics!r}")
        sp = params
        params, ics, periods, centre, tol, numerics = sp.params, sp.ics, sp.periods, sp.centre, sp.tol, sp.numerics
    ics = check_ics(ics)
    s = float(params.t0 if centre is None else centre)
    if not math.isfinite(s):
        raise ParameterError(f"centre must be finite, got {centre!r}")
    check_time("centre", s, params.period)
    if not (isinstance(tol, int | float) and tol > 0):
        raise ParameterError(f"tol must be positive, got {tol!r}")
    numerics = numerics or SYMMETRY_NUMERICS
    p = params.with_(t0=s)
    fwd = section(p, ics, periods, numerics=numerics)
    mirrored = ics * np.array([1.0, -1.0])
    bwd = section(p, mirrored, periods, numerics=numerics, direction=-1)
    npts = np.minimum(fwd.npts, bwd.npts)
    dist = np.zeros((ics.shape[0], periods))
    refl = fwd.points * np.array([1.0, -1.0])
    for i in range(ics.shape[0]):
        m = int(npts[i])
        dist[i, :m] = np.hypot(*(bwd.points[i, :m] - refl[i, :m]).T)
    status = [
        a if a != "ok" else b for a, b in zip(fwd.status_labels(), bwd.status_labels(), strict=True)
    ]  # a failure in either direction
    return SymmetryCheck(
        params=p,
        centre=s,
        ics=ics,
        periods=int(periods),
        distance=dist,
        npts=npts,
        status=status,
        g_even=g_is_even_about(p, s),
        field_residual=field_residual(p, s),
        tol=float(tol),
        numerics=numerics,
        elapsed_s=time.perf_counter() - start,
    )
