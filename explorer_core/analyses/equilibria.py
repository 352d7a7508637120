"""Equilibria of the frozen field: every finite real solution of ``Q = R = 0``.

At a frozen time ``t`` the reduced field (paper, eqs. (eq-m2), (eq-qr)) is a pair
of quadratic polynomials in ``(q, r)``, so its equilibria are the intersections
of two conics: at most four by Bezout, counted with multiplicity and including
points at infinity and complex points. They are found algebraically, never by
Newton from guesses:

1. rotate ``(q, r) -> (u, v)`` by an angle for which both conics keep a clearly
   non-zero ``v^2`` coefficient (a diagonal tensor's ``R`` does not depend on
   ``r`` at all, so ``v = r`` would lose a degree);
2. eliminate ``v`` with the Sylvester resultant, a polynomial of degree <= 4 in
   ``u``; leading coefficients at rounding-noise level (relative to the same
   formula evaluated on absolute values) are exact zeros: branches at infinity;
3. all roots of the resultant (companion eigenvalues); the near-real ones are
   candidates (a double root comes out as a near-real pair);
4. at each candidate ``u`` every real root ``v`` of either conic is tested; the
   points near both curves are polished by a few Newton steps with the exact
   Jacobian (polishing only: a step is kept only if it lowers the residual) and
   accepted if both ``Q`` and ``R`` vanish relative to the size of their terms;
   a cluster of k (nearly) equal real roots of the resultant yields at most k
   distinct points.

The arithmetic is compiled (:mod:`explorer_core.analyses.equilibria_kernels`, numba, no GIL held):
a track's whole grid of times is solved, classified and matched in one call each. ``tests/naive.py``
keeps the same algorithm in plain Python as the reference the kernels are tested against.

The energy identity explains the counts (see ``docs/equilibria.md``): since
``T' = alpha lambda`` is quadratic, the cubic part of ``(I omega, omega')``
vanishes, ``l1 Q2 + l3 R2 == 0`` for the quadratic parts ``Q2, R2`` and two
coprime linear forms ``l1, l3``. So ``Q2`` and ``R2`` share a linear factor and
the conics always meet at infinity: at most three finite equilibria, for any
tensor and any ``t`` (unless ``Q`` and ``R`` share a whole component).

:func:`equilibrium_tracks` follows the equilibria over one forcing period.
``python -m explorer_core.analyses.equilibria`` prints the counts for the paper's cases.
"""

from __future__ import annotations

import csv
import functools
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import export
from explorer_core.analyses import equilibria_kernels as ek
from explorer_core.analyses.specs import Checking
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, run
from explorer_core.solve.options import BOOL, Arg, declare, integer, number
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, reduce_time, reduce_times

#: Equilibrium types, as used in :attr:`Equilibria.types` and the CSV/JSON output.
TYPES = ("saddle", "stable node", "unstable node", "stable focus", "unstable focus", "centre", "degenerate")

# Jump accepted at the bisection limit (compactified plane; crossing infinity is ~2).
_LOOSE_JUMP = 0.5


# ---------------------------------------------------------------------------
# Results.


@dataclass(frozen=True, eq=False)
class Equilibria(Drawable):
    """Equilibria of the frozen field at one time ``t``.

    Attributes
    ----------
    t : float
        The frozen time.
    q, r : (n,) arrays
        Coordinates, sorted by ``q`` then ``r``.
    eigenvalues : (n, 2) complex array
        Eigenvalues of the Jacobian; larger real part first, ``+im`` first in a pair.
    types : tuple of str
        One of :data:`TYPES` per point.
    at_infinity : int
        Intersections of the two conics lost at infinity: Bezout's 4 minus the
        finite (real or complex) roots of the resultant, with multiplicity.
    n_complex : int
        Finite non-real intersections (roots of the resultant off the real axis).
    degenerate : bool
        ``Q`` and ``R`` share a common component (a whole curve of equilibria);
        no points are returned then.
    message : str
        Why the result is degenerate, or empty.
    """

    t: float
    q: np.ndarray
    r: np.ndarray
    eigenvalues: np.ndarray
    types: tuple[str, ...]
    at_infinity: int = 0
    n_complex: int = 0
    degenerate: bool = False
    message: str = ""

    def __len__(self) -> int:
        return int(self.q.size)

    @property
    def points(self) -> np.ndarray:
        """``(n, 2)`` array of ``(q, r)``."""
        return np.column_stack([self.q, self.r])

    def summary(self) -> dict[str, Any]:
        """What ``bilimovich critical`` prints: every equilibrium, and whether they form a curve (an empty list
        would say "none")."""
        out = self.to_dict()
        if self.degenerate:
            out.update(degenerate=True, message=self.message)
        return out

    def report(self) -> list[str]:
        """No lines: ``critical`` prints its JSON."""
        return []

    def write(self, path: str) -> dict[str, Any]:
        """Not written: the equilibria at one time are printed as JSON (``--track`` writes a CSV)."""
        raise export.OutputError("--out is written by --track only (the equilibria at one time are printed as JSON)")

    def to_dict(self, full: bool = False) -> dict[str, Any]:
        """JSON form ``{"t": t, "equilibria": [{"q", "r", "eigenvalues": [[re, im], [re, im]], "type"}]}``.

        With ``full=True`` also ``at_infinity``, ``n_complex``, ``degenerate`` and ``message``.
        """
        out: dict[str, Any] = {
            "t": float(self.t),
            "equilibria": [
                {
                    "q": float(self.q[i]),
                    "r": float(self.r[i]),
                    "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues[i]],
                    "type": self.types[i],
                }
                for i in range(len(self))
            ],
        }
        if full:
            out.update(
                at_infinity=self.at_infinity, n_complex=self.n_complex, degenerate=self.degenerate, message=self.message
            )
        return out


# ---------------------------------------------------------------------------
# Algebra on two conics given as coefficient rows (1, q, r, q^2, q r, r^2).


@functools.lru_cache(maxsize=16)
def _model_of(params: Params) -> Model:
    # Building the coefficient tables costs ~2 ms, ~70x a solve: reuse them per Params.
    return Model(params)


def _as_model(model_or_params: Model | Params) -> Model:
    if isinstance(model_or_params, Model):
        return model_or_params
    if isinstance(model_or_params, Params):
        return _model_of(model_or_params)
    raise ParameterError(f"expected a Model or Params, got {type(model_or_params).__name__}: {model_or_params!r}")


def _check_t(name: str, t: Any) -> float:
    try:
        v = float(t)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {t!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {t!r}")
    return v


def _check_positive(name: str, v: Any, allow_zero: bool = False) -> None:
    ok = isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or v < 0 or (v == 0 and not allow_zero):
        raise ParameterError(f"{name} must be a {'non-negative' if allow_zero else 'positive'} number, got {v!r}")


@dataclass(frozen=True, eq=False)
class ConicSolution:
    """Finite real intersections of two conics, see :func:`solve_conics`."""

    q: np.ndarray
    r: np.ndarray
    at_infinity: int
    n_complex: int
    degenerate: bool
    message: str


#: Why a solve is degenerate, by the kernel's code (a non-zero constant conic is not: it has no zeros).
_MESSAGES = {
    ek.Q_ZERO: "Q vanishes identically: every point on the other curve is an equilibrium",
    ek.R_ZERO: "R vanishes identically: every point on the other curve is an equilibrium",
    ek.COMMON: "Q and R have a common factor (their resultant vanishes identically): "
    "a whole curve of equilibria, not isolated points",
}


def _eig_failed(where: str) -> np.linalg.LinAlgError:
    # As np.linalg.eigvals did: LAPACK's QR iteration on a 4x4 companion matrix practically always converges.
    return np.linalg.LinAlgError(f"the companion matrix's eigenvalues did not converge ({where})")


def _conic(name: str, c: Any) -> np.ndarray:
    try:
        arr = np.array(c, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be 6 numbers (1, q, r, q^2, q r, r^2), got {c!r}") from None
    if arr.shape != (6,) or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be 6 finite numbers (1, q, r, q^2, q r, r^2), got {c!r}")
    return arr


def solve_conics(
    cq: Any,
    cr: Any,
    *,
    inf_norm: float = 1e8,
    imag_tol: float = 1e-5,
    accept_tol: float = 1e-9,
    dedupe_tol: float = 1e-7,
) -> ConicSolution:
    """All finite real intersections of two conics ``c0 + c1 q + c2 r + c3 q^2 + c4 q r + c5 r^2 = 0``.

    The arithmetic is :func:`explorer_core.analyses.equilibria_kernels.solve_pairs` (the module's
    docstring gives the algorithm; ``tests/naive.py`` keeps it in plain Python as the reference).

    Parameters
    ----------
    cq, cr : sequences of 6 finite floats
        Monomial coefficients in the order ``(1, q, r, q^2, q r, r^2)`` (:data:`explorer_core.system.model.MONOMIALS`).
    inf_norm : float
        Points with ``|(q, r)| > inf_norm`` are counted as at infinity.
    imag_tol : float
        A resultant root ``u`` is a real candidate if ``|Im u| <= imag_tol (|u| + max_k |u_k|)``.
        Generous on purpose (a double root splits into a near-real pair): the residual test decides.
    accept_tol : float
        Largest residual ``max(|Q| / scale_Q, |R| / scale_R)`` of an accepted, polished point, with
        ``scale = sum_k |c_k| rho^deg_k``, ``rho = |x| + 1e-12``.
    dedupe_tol : float
        Points closer than ``dedupe_tol (1 + |x|)`` are one point (a double root).

    Returns
    -------
    ConicSolution
        Points sorted by ``q`` then ``r``; ``at_infinity = 4 -`` (finite roots of the
        resultant, real or not, with multiplicity); ``degenerate`` when the conics
        share a component (the resultant vanishes identically).
    """
    coef = np.empty((1, 2, 6))
    coef[0, 0] = _conic("cq", cq)
    coef[0, 1] = _conic("cr", cr)
    _check_positive("inf_norm", inf_norm)
    for name, v in (("imag_tol", imag_tol), ("accept_tol", accept_tol), ("dedupe_tol", dedupe_tol)):
        _check_positive(name, v, allow_zero=True)
    points = np.zeros((1, ek.MAX_POINTS, 2))
    info = np.zeros((1, 4), np.int64)
    ek.solve_pairs(coef, float(inf_norm), float(imag_tol), float(accept_tol), float(dedupe_tol), points, info)
    code, n, at_infinity, n_complex = info[0].tolist()
    if code == ek.EIG_FAILED:
        raise _eig_failed(f"Q = {coef[0, 0].tolist()}, R = {coef[0, 1].tolist()}")
    message = _MESSAGES.get(code, "")
    return ConicSolution(
        points[0, :n, 0].copy(), points[0, :n, 1].copy(), at_infinity, n_complex, bool(message), message
    )


# ---------------------------------------------------------------------------
# Classification.


def classify(jacobian: Any, rtol: float = 1e-12) -> tuple[np.ndarray, tuple[str, ...]]:
    """Eigenvalues and type of each 2x2 Jacobian of a ``(n, 2, 2)`` stack.

    Types (:data:`TYPES`): ``|det| <= rtol |J|^2``: degenerate; ``det < 0``: saddle;
    ``det > 0`` and ``|tr| <= rtol |J|``: centre (the linearisation cannot decide,
    e.g. the origin at ``g' = 0`` in the diagonal case); otherwise node if
    ``tr^2 >= 4 det`` else focus, stable if ``tr < 0``. ``|J|`` is the Frobenius norm.
    Eigenvalues: larger real part first, ``+im`` first in a pair.
    """
    _check_positive("rtol", rtol, allow_zero=True)
    jac = np.array(jacobian, dtype=float).reshape(-1, 2, 2)  # a fresh C array: one kernel signature
    eig = np.zeros((jac.shape[0], 2), dtype=complex)
    kinds = np.zeros(jac.shape[0], dtype=np.int64)
    ek.classify_stack(jac, float(rtol), eig, kinds)
    return eig, tuple(TYPES[k] for k in kinds.tolist())


# ---------------------------------------------------------------------------
# Public entry points.


def check_tables(model: Model) -> None:
    """ParameterError when the frozen field's coefficient tables overflow in double precision (alpha = 1e300:
    alpha^2 is inf, and the resultant of overflowed conics "vanishes identically": a whole curve of equilibria
    would be claimed that is no property of the system)."""
    if not all(np.isfinite(a).all() for a in (model.num, model.gpc, model.den)):
        p = model.params
        raise ParameterError(f"the frozen field's coefficients overflow in double precision (alpha = {p.alpha:g}, "
                             f"inertia {', '.join(f'{v:g}' for v in p.inertia)}): its equilibria cannot be "
                             "computed; scale the system down")  # fmt: skip


class _Samples:
    """The equilibria of one model at many frozen times, row by row in arrays that grow (a row per time).

    Rows as :func:`~explorer_core.analyses.equilibria_kernels.equilibria_at` fills them: ``t``,
    ``points`` (up to 4), ``info`` (code, count, at infinity, complex), ``eig``, ``kinds``;
    ``link[s, i] = (s', j)``: point ``i`` of row ``s`` continues as point ``j`` of row ``s'`` (tracks).
    """

    def __init__(self, model: Model, capacity: int, inf_norm: float, rtol: float) -> None:
        check_tables(model)
        self.model = model
        self.forcing = model.forcing
        self.inf_norm = float(inf_norm)
        self.rtol = float(rtol)
        self.n = 0
        self._allocate(max(1, capacity))

    def _allocate(self, cap: int) -> None:
        fresh = {
            "t": np.zeros(cap),
            "points": np.zeros((cap, ek.MAX_POINTS, 2)),
            "info": np.zeros((cap, 4), np.int64),
            "eig": np.zeros((cap, ek.MAX_POINTS, 2), dtype=complex),
            "kinds": np.zeros((cap, ek.MAX_POINTS), np.int64),
            "link": np.full((cap, ek.MAX_POINTS, 2), -1, np.int64),
        }
        for name, arr in fresh.items():
            if self.n:  # growing: keep the rows solved
                arr[: self.n] = getattr(self, name)[: self.n]
            setattr(self, name, arr)

    def add(self, ts: np.ndarray) -> int:
        """Solve at the times ``ts`` (a float array); returns the row of the first."""
        first = self.n
        if first + ts.size > self.t.size:
            self._allocate(2 * (first + ts.size))
        m = self.model
        self.t[first : first + ts.size] = ts
        # The kernel's g(t) at the times less whole periods taken exactly: the same phases, with their digits.
        phases = reduce_times(ts, m.params.omega)
        ek.equilibria_at(m.num, m.gpc, m.den, self.forcing, phases, first, self.inf_norm, self.rtol,
                         self.points, self.info, self.eig, self.kinds)  # fmt: skip
        self.n += ts.size
        failed = self.info[first : self.n, 0] == ek.EIG_FAILED
        if failed.any():
            raise _eig_failed(f"t = {float(ts[np.argmax(failed)])!r}")
        return first

    def equilibria(self, s: int) -> Equilibria:
        """Row ``s`` as :class:`Equilibria`."""
        code, n, at_infinity, n_complex = self.info[s].tolist()
        q = self.points[s, :n, 0].copy()
        r = self.points[s, :n, 1].copy()
        eig = self.eig[s, :n].copy()
        for arr in (q, r, eig):
            arr.setflags(write=False)
        message = _MESSAGES.get(code, "")
        return Equilibria(
            t=float(self.t[s]),
            q=q,
            r=r,
            eigenvalues=eig,
            types=tuple(TYPES[k] for k in self.kinds[s, :n].tolist()),
            at_infinity=at_infinity,
            n_complex=n_complex,
            degenerate=bool(message),
            message=message,
        )


def equilibria(
    model_or_params: Model | Params,
    t: float,
    *,
    inf_norm: float = 1e8,
    rtol: float = 1e-12,
) -> Equilibria:
    """Every finite real equilibrium of the frozen field at time ``t`` (paper, eq. (eq-qr)).

    Parameters
    ----------
    model_or_params : Model or Params
        The system; a :class:`Params` is turned into a :class:`Model` (cached for
        the last 16 parameter sets: building one takes ~2 ms, a call ~0.03 ms).
    t : float
        Frozen time.
    inf_norm : float
        Intersections farther than this from the origin count as at infinity.
    rtol : float
        Relative tolerance of the classification (see :func:`classify`).

    Returns
    -------
    Equilibria
        Points, Jacobian eigenvalues and types. ``degenerate=True`` (and no
        points) when ``Q`` and ``R`` share a component, e.g. ``alpha = 0`` with a
        diagonal tensor, where the whole line ``q = 0`` is at rest.
    """
    t = _check_t("t", t)
    _check_positive("inf_norm", inf_norm)
    _check_positive("rtol", rtol, allow_zero=True)
    samples = _Samples(_as_model(model_or_params), 1, inf_norm, rtol)
    return samples.equilibria(samples.add(np.array([t])))


# ---------------------------------------------------------------------------
# Tracks over one period.


@dataclass(frozen=True, eq=False)
class Tracks(Drawable):
    """Equilibria followed continuously over one forcing period.

    Rows are sorted by branch, then time. A branch ends where its point is born
    or dies with a partner (the count changes), runs off to infinity, or jumps
    by more than the continuity tolerance even after bisection: branches are
    never joined across infinity.

    Attributes
    ----------
    model : Model
        The system tracked.
    branch, t, q, r : (m,) arrays
        One row per (sample time, equilibrium); branch ids are numbered by first appearance.
    types : tuple of str
        Type of each row.
    eigenvalues : (m, 2) complex array
    sample_t, sample_count : arrays
        Every time evaluated (grid and bisection points, sorted) and the number of
        equilibria there; ``sample_degenerate`` flags a common component.
    t_start, period : float
        The covered interval ``[t_start, t_start + period]``.
    """

    model: Model = field(repr=False)
    t_start: float
    period: float
    branch: np.ndarray
    t: np.ndarray
    q: np.ndarray
    r: np.ndarray
    types: tuple[str, ...]
    eigenvalues: np.ndarray
    sample_t: np.ndarray
    sample_count: np.ndarray
    sample_degenerate: np.ndarray
    #: False when cancelled: the tracks then cover only the start of the period (``lost`` says how much).
    completed: bool = True
    lost: tuple[Loss, ...] = ()

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    @property
    def n_branches(self) -> int:
        return int(self.branch.max()) + 1 if self.branch.size else 0

    def branches(self) -> Iterator[dict[str, Any]]:
        """Per-branch arrays: ``{"branch", "t", "q", "r", "types", "eigenvalues"}``."""
        bounds = np.flatnonzero(np.diff(self.branch)) + 1
        for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, self.branch.size], strict=True):
            if hi > lo:
                yield {
                    "branch": int(self.branch[lo]),
                    "t": self.t[lo:hi],
                    "q": self.q[lo:hi],
                    "r": self.r[lo:hi],
                    "types": self.types[lo:hi],
                    "eigenvalues": self.eigenvalues[lo:hi],
                }

    def section(self) -> Equilibria:
        """Equilibria at the section phase ``params.t0`` (the frozen field the Poincare map starts from).

        With the default ``t_start = t0`` the same points are the rows ``rows_at(t_start)``,
        which also carry their branch ids.
        """
        return equilibria(self.model, self.model.params.t0)

    def report(self) -> list[str]:
        """No lines: ``critical --track`` writes its CSV and prints its JSON with ``--json``."""
        return []

    def summary(self) -> dict[str, Any]:
        """Plain-JSON overview: the interval, the counts per sample, and each branch's ends."""

        def end(b: dict[str, Any], k: int) -> dict[str, Any]:
            return {"t": float(b["t"][k]), "q": float(b["q"][k]), "r": float(b["r"][k]), "type": b["types"][k]}

        counts, freq = np.unique(self.sample_count, return_counts=True)
        return {
            "t_start": self.t_start,
            "period": self.period,
            "n_samples": int(self.sample_t.size),
            "count_samples": {str(int(c)): int(f) for c, f in zip(counts, freq, strict=True)},
            "n_branches": self.n_branches,
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "branches": [
                {"branch": b["branch"], "n": int(b["t"].size), "start": end(b, 0), "end": end(b, -1)}
                for b in self.branches()
            ],
        }

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "set of tracks"
        )

    def rows_at(self, t: float) -> np.ndarray:
        """Indices of the rows at sample time ``t`` (exact match), e.g. ``rows_at(tracks.t_start)``."""
        return np.flatnonzero(self.t == t)

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write ``branch,t,q,r,type,eig1_re,eig1_im,eig2_re,eig2_im`` rows, whole or not at all."""
        with export.atomic(os.fspath(path)) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["branch", "t", "q", "r", "type", "eig1_re", "eig1_im", "eig2_re", "eig2_im"])
            for i in range(self.branch.size):
                e = self.eigenvalues[i]
                w.writerow(
                    [int(self.branch[i])]
                    + [repr(float(x)) for x in (self.t[i], self.q[i], self.r[i])]
                    + [self.types[i]]
                    + [repr(float(x)) for x in (e[0].real, e[0].imag, e[1].real, e[1].imag)]
                )


Point = tuple[float, float]


def _compact(x: Point) -> Point:
    """``x / (1 + |x|)``: the plane squeezed into the unit disc, infinity on its rim."""
    s = 1.0 / (1.0 + math.hypot(x[0], x[1]))
    return x[0] * s, x[1] * s


def equilibrium_tracks(
    model_or_params: Model | Params,
    n_t: int = 400,
    t_start: float | None = None,
    *,
    progress: Callable[[Step[Tracks]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> Tracks:
    """Equilibria of the frozen field followed over one period (:func:`iter_equilibrium_tracks`'s
    arguments); ``progress`` gets each of its updates."""
    return run(iter_equilibrium_tracks(model_or_params, n_t, t_start, cancel=cancel, **kw), progress)


#: Updates :func:`iter_equilibrium_tracks` yields over a period (at most; one per grid interval if fewer).
TRACK_UPDATES = 100


def iter_equilibrium_tracks(
    model_or_params: Model | Params,
    n_t: int = 400,
    t_start: float | None = None,
    *,
    jump: float = 0.05,
    max_depth: int = 12,
    max_refine: int | None = None,
    inf_norm: float = 1e8,
    rtol: float = 1e-12,
    cancel: Callable[[], bool] | None = None,
) -> Iterator[Step[Tracks]]:
    """Equilibria of the frozen field followed over one period ``[t_start, t_start + T]``.

    Yields a :class:`~explorer_core.progress.Step` (grid intervals done of ``n_t - 1``) about
    :data:`TRACK_UPDATES` times; the last one's ``result`` is the :class:`Tracks`.

    Parameters
    ----------
    model_or_params : Model or Params
    n_t : int
        Grid samples over the period (both ends included), ``2 <= n_t <= 1e6``.
    t_start : float, optional
        Start of the period; default ``params.t0`` (the section phase).
    jump : float
        Consecutive points of a branch are at most ``jump`` apart on the compactified
        plane ``x / (1 + |x|)`` (about ``|dx| <= jump (1 + |x|)`` for a sideways
        move; a point running off to infinity stays continuous up to the rim).
    max_depth, max_refine : int
        A grid interval whose match is not clearly continuous (count change, large
        or ambiguous jump) is bisected, at most ``max_depth`` levels deep and with
        at most ``max_refine`` extra evaluations in total (default ``4 n_t``).
        Where it is still unclear at the limit, pairs closer than 0.5 on the
        compactified plane are joined and the others cut: so a branch through
        infinity (``g -> 0`` in the diagonal case, where ``x2* = (-alpha/g,
        I11 g'/(I22 - I33))``) ends and a new one starts.
    inf_norm, rtol : float
        As in :func:`equilibria`.
    cancel : callable, optional
        Polled between grid intervals; once it returns True the work stops and the tracks
        computed so far come back with ``completed=False`` and the rest of the period in ``lost``.

    Yields
    ------
    Step[Tracks]
    """
    model = _as_model(model_or_params)
    if isinstance(n_t, bool) or not isinstance(n_t, int | np.integer):
        raise ParameterError(f"n_t must be an integer, got {n_t!r}")
    if not 2 <= n_t <= 1_000_000:
        raise ParameterError(f"n_t must be between 2 and 1000000, got {n_t!r}")
    t_user = model.params.t0 if t_start is None else _check_t("t_start", t_start)
    # Tracked at the phase (t less whole periods, exactly): the grid and the bisection keep their digits at any
    # t (at t = 1e11 doubles are 1.5e-5 apart); the rows say the user's times.
    t_start = reduce_time(t_user, model.params.omega)
    shift = t_user - t_start

    def user_t(t: np.ndarray) -> np.ndarray:
        return np.where(t == t_start, t_user, t + shift)

    _check_positive("jump", jump)
    jump = float(jump)  # one kernel signature for the matching
    _check_positive("inf_norm", inf_norm)
    _check_positive("rtol", rtol, allow_zero=True)
    for name, v in (("max_depth", max_depth), ("max_refine", max_refine)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0):
            raise ParameterError(f"{name} must be a non-negative integer, got {v!r}")
    if max_refine is None:
        max_refine = 4 * n_t
    period = model.params.period

    grid = (t_start + period * np.linspace(0.0, 1.0, n_t)).tolist()
    grid[-1] = t_start + period
    # Every grid time at once, in one kernel call; bisection points one by one as the matching asks.
    samples = _Samples(model, n_t + min(max_refine, 16 + n_t // 8), inf_norm, rtol)  # grows if need be
    samples.add(np.array(grid))
    row: dict[float, int] = {}  # frozen time -> its row (a time met twice is solved once)
    for k, t in enumerate(grid):
        row.setdefault(t, k)

    def solve(t: float) -> int:
        s = row.get(t)
        if s is None:
            s = row[t] = samples.add(np.array([t]))
        return s

    # Points of consecutive grid times matched in one call; only unclear intervals are matched again.
    grid_pairs = np.zeros((n_t - 1, ek.MAX_POINTS, 2), np.int64)
    grid_npairs = np.zeros(n_t - 1, np.int64)
    grid_clear = np.zeros(n_t - 1, np.bool_)
    ek.match_chain(samples.points, samples.info, n_t, jump, grid_pairs, grid_npairs, grid_clear)
    pairs = np.zeros((ek.MAX_POINTS, 2), np.int64)
    budget = max_refine
    lost: tuple[Loss, ...] = ()
    start = time.perf_counter()
    every = max(1, (n_t - 1) // TRACK_UPDATES)
    done = 0
    for k in range(n_t - 1):
        if k and k % every == 0:
            yield Step(Progress(k, n_t - 1, "intervals", time.perf_counter() - start))
        done = k
        if cancel is not None and cancel():
            t_a, t_k, t_b = (t_user + (x - t_start) for x in (grid[0], grid[k], grid[-1]))
            why = f"cancelled: the tracks cover t in [{t_a:.6g}, {t_k:.6g}] of [{t_a:.6g}, {t_b:.6g}]"
            lost = (Loss("grid intervals", n_t - 1 - k, why),)
            # The grid beyond the intervals done was solved ahead: those samples are not part of the tracks.
            row = {t: s for t, s in row.items() if k > 0 and t <= grid[k]}
            break
        if grid_clear[k]:
            sa, sb = row[grid[k]], row[grid[k + 1]]
            for i, j in grid_pairs[k, : grid_npairs[k]].tolist():
                samples.link[sa, i] = sb, j
            done = k + 1
            continue
        stack = [(grid[k], grid[k + 1], 0)]
        while stack:
            ta, tb, depth = stack.pop()
            sa, sb = solve(ta), solve(tb)
            npairs, clear = ek.match(samples.points, samples.info, sa, sb, jump, pairs)
            tm = 0.5 * (ta + tb)
            if not clear and depth < max_depth and budget > 0 and ta < tm < tb:
                budget -= 1
                stack.append((tm, tb, depth + 1))
                stack.append((ta, tm, depth + 1))
                continue
            if not clear:
                # Still unclear at the limit: the interval is tiny, so accept any pair that
                # does not cross infinity (an antipodal jump of ~2 on the compactified plane).
                npairs, _ = ek.match(samples.points, samples.info, sa, sb, max(jump, _LOOSE_JUMP), pairs)
            for i, j in pairs[:npairs].tolist():
                samples.link[sa, i] = sb, j
        done = k + 1

    times = sorted(row)
    order = np.array([row[t] for t in times], dtype=np.int64)
    branch_at = np.full((samples.n, ek.MAX_POINTS), -1, np.int64)
    ek.number_branches(order, samples.info, samples.link, branch_at)
    count = samples.info[order, 1]
    s_of = np.repeat(order, count)  # (sample row, point) of every row of the tracks
    i_of = np.arange(s_of.size) - np.repeat(np.cumsum(count) - count, count)
    b_of = branch_at[s_of, i_of]
    t_of = samples.t[s_of]
    rows = np.lexsort((i_of, t_of, b_of))  # by branch, then time
    s_of, i_of = s_of[rows], i_of[rows]
    tracks = Tracks(
        model=model,
        t_start=float(t_user),
        period=float(period),
        branch=b_of[rows],
        t=user_t(t_of[rows]),
        q=samples.points[s_of, i_of, 0],
        r=samples.points[s_of, i_of, 1],
        types=tuple(TYPES[k] for k in samples.kinds[s_of, i_of].tolist()),
        eigenvalues=samples.eig[s_of, i_of],
        sample_t=user_t(np.array(times)),
        sample_count=count,
        sample_degenerate=np.isin(samples.info[order, 0], list(_MESSAGES)),
        completed=not lost,
        lost=lost,
    )
    yield Step(Progress(done, n_t - 1, "intervals", time.perf_counter() - start), None, tracks)


def warmup() -> None:
    """Compile (or load from the on-disk cache) the kernels, through the calls the analyses make."""
    # The diagonal case's far point passes through infinity at g = 0: unclear intervals, bisected.
    equilibrium_tracks(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1), n_t=8, max_refine=4)
    solve_conics([-1.0, 0.0, 0.0, 1.0, 0.0, 1.0], [-1.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    classify(np.eye(2))


# ---------------------------------------------------------------------------
# The counts for the paper's cases (docs/equilibria.md).

#: The paper's tensors and alphas with g = cos t.
PAPER_CASES: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...] = (
    ("diag(1,2,4)", (1.0, 2.0, 4.0, 0.0, 0.0, 0.0), (0.1,)),
    ("diag(4,2,1)", (4.0, 2.0, 1.0, 0.0, 0.0, 0.0), (0.1,)),
    ("diag(1,4,2)", (1.0, 4.0, 2.0, 0.0, 0.0, 0.0), (0.1, 0.4)),
    ("diag(4,1,2)", (4.0, 1.0, 2.0, 0.0, 0.0, 0.0), (0.1, 0.4)),
    ("[[1,0,.1],[0,2,0],[.1,0,4]]", (1.0, 2.0, 4.0, 0.0, 0.1, 0.0), (0.1, -0.1, 0.4, -0.4)),
    ("[[1,0,.5],[0,2,.3],[.5,.3,4]]", (1.0, 2.0, 4.0, 0.0, 0.5, 0.3), (-0.001, -0.01, -0.05, -0.37, -0.45, -0.5)),
)


def count_survey(params: Params, n_t: int = 20000, n_track: int = 1000) -> dict[str, Any]:
    """How many equilibria there are over one period, and where they go.

    Parameters
    ----------
    params : Params
    n_t : int
        Grid for the counts: midpoints ``t0 + T (k + 1/2) / n_t``, so that an exact
        singular instant such as ``g = 0`` is not sampled by accident.
    n_track : int
        Grid of the :func:`equilibrium_tracks` run that locates the events.

    Returns
    -------
    dict
        ``fraction``: share of the grid with each number of real equilibria;
        ``changes``: ``(t, before, after)`` where that number changes between grid
        points; ``n_complex``, ``at_infinity``: their (min, max) over the grid;
        ``through_infinity``: times where a tracked point passes through infinity
        (its branch is cut and continues from the opposite direction);
        ``pair_events``: other times where a branch ends or starts inside the
        period (a pair is born or dies).
    """
    model = Model(params)
    ts = params.t0 + params.period * (np.arange(n_t) + 0.5) / n_t
    samples = _Samples(model, n_t, 1e8, 1e-12)  # equilibria()'s defaults, every time in one call
    samples.add(ts)
    n_real_a, n_inf, n_cx = samples.info[:n_t, 1], samples.info[:n_t, 2].tolist(), samples.info[:n_t, 3].tolist()
    change = np.flatnonzero(np.diff(n_real_a)) + 1
    values, freq = np.unique(n_real_a, return_counts=True)
    tracks = equilibrium_tracks(model, n_track)
    t_end = tracks.t_start + tracks.period
    starts = [(float(b["t"][0]), _compact((b["q"][0], b["r"][0]))) for b in tracks.branches()]
    reappear: set[int] = set()
    through_inf: list[float] = []
    pair_events: list[float] = []
    h = tracks.period / (n_track - 1)  # one grid step: the bisection stays inside it
    for b in tracks.branches():
        te = float(b["t"][-1])
        if te >= t_end:
            continue
        x = _compact((b["q"][-1], b["r"][-1]))
        # A branch cut where another one starts within a grid step on the opposite
        # side of the rim of the compactified plane is a passage through infinity.
        far = [
            (math.hypot(x[0] - y[0], x[1] - y[1]), k)
            for k, (t, y) in enumerate(starts)
            if te < t <= te + h and k not in reappear
        ]
        dist, k = max(far, default=(0.0, -1))
        if dist > 1.0:
            reappear.add(k)
            through_inf.append(te)
        else:
            pair_events.append(te)
    pair_events += [t for k, (t, _) in enumerate(starts) if t > tracks.t_start and k not in reappear]
    return {
        "fraction": {int(v): float(f) / n_t for v, f in zip(values, freq, strict=True)},
        "changes": [(float(ts[i]), int(n_real_a[i - 1]), int(n_real_a[i])) for i in change],
        "n_complex": (min(n_cx), max(n_cx)),
        "at_infinity": (min(n_inf), max(n_inf)),
        "through_infinity": sorted({round(t, 4) for t in through_inf}),
        "pair_events": sorted({round(t, 4) for t in pair_events}),
    }


def main() -> None:
    """Print :func:`count_survey` for :data:`PAPER_CASES` (``python -m explorer_core.analyses.equilibria``)."""
    for name, inertia, alphas in PAPER_CASES:
        for alpha in alphas:
            s = count_survey(Params(inertia=inertia, alpha=alpha))
            frac = ", ".join(f"{k}: {v:.4f}" for k, v in s["fraction"].items())
            ch = "; ".join(f"{t:.4f} {a}->{b}" for t, a, b in s["changes"]) or "none"
            inf = ", ".join(f"{t:.4f}" for t in s["through_infinity"]) or "none"
            pair = ", ".join(f"{t:.4f}" for t in s["pair_events"]) or "none"
            print(
                f"{name} alpha={alpha:+g}: real count (share of period) {{{frac}}}, "
                f"complex {s['n_complex']}, at infinity {s['at_infinity']}\n"
                f"    count changes at t = {ch}\n    a point passes through infinity at t = {inf}\n"
                f"    a pair is born or dies at t = {pair}"
            )


if __name__ == "__main__":
    main()


# ---------------------------------------------------------------------------
# As a spec (``bilimovich critical``): the equilibria at one frozen time, or tracked over one period.


@dataclass(frozen=True)
class CriticalSpec:
    """What ``bilimovich critical`` computes (made by :func:`critical_spec`): the equilibria of the frozen field at
    ``t``, or (``track``) followed over one period at ``n_t`` times."""

    params: Params
    t: float
    track: bool
    n_t: int
    #: Bisections allowed where the equilibria's count changes (None: 4 per sample).
    max_refine: int | None

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "t": self.t, "track": self.track, "n_t": self.n_t,
                "max_refine": self.max_refine}  # fmt: skip


@declare(
    t=Arg("frozen time (default t0)", default=None, check=number(optional=True)),
    track=Arg("track them over one period", "switch", default=False, check=BOOL),
    n_t=Arg("time samples for --track", "int", cli_default=721, default=400, check=integer(2, 1_000_000)),
    max_refine=Arg(
        "bisections for --track where the equilibria's count changes (default 4 per sample)",
        "int",
        default=None,
        check=integer(0, 100_000_000, optional=True),
    ),
)
def critical_spec(params: Params, t: float | None, *, track: bool, n_t: int, max_refine: int | None) -> CriticalSpec:
    """A validated :class:`CriticalSpec` (a bad value raises ParameterError naming it); ``t`` default ``t0``. The
    options are declared above (defaults, checks run before this body, flags)."""
    with Checking() as at:
        at("params")
        check_tables(_as_model(params))
    return CriticalSpec(params, params.t0 if t is None else t, track, n_t, max_refine)


def critical_points(spec: CriticalSpec, progress: Callable[[Any], None] | None = None,
                    cancel: Callable[[], bool] | None = None) -> Equilibria | Tracks:  # fmt: skip
    """The equilibria of ``spec``: :func:`equilibria` at ``spec.t``, or :func:`equilibrium_tracks` (``track``)."""
    if spec.track:
        return equilibrium_tracks(spec.params, n_t=spec.n_t, max_refine=spec.max_refine, progress=progress,
                                  cancel=cancel)  # fmt: skip
    return equilibria(spec.params, spec.t)
