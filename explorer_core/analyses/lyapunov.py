"""Lyapunov spectrum of the stroboscopic map and its Kaplan-Yorke dimension.

The paper (Figs. 4 and 8B) reports three exponents ``Lambda_1, Lambda_2,
Lambda_3 = 0`` of the autonomous 3-D form (eq-a3) ``q' = Q, r' = R, s' = 1``:
``Lambda_3 = 0`` belongs to the time direction ``s``; ``Lambda_1, Lambda_2``
are the exponents of the ``(q, r)`` flow. We compute them by the standard
method (Benettin et al. 1980; Parker & Chua 1989, ch. 8):

* the variational equations ``Phi' = J(q, r, t) Phi`` with the **exact**
  Jacobian (``Q``, ``R`` are quadratic in ``(q, r)``, so ``J`` is affine in
  ``(q, r)`` with the same time-dependent coefficient table as the field) are
  integrated together with the trajectory by the same embedded Runge-Kutta
  pair as sections (the method the default rule chooses for the tolerance), with error control on the state **and**
  on the tangent vectors, landing exactly on the section times ``t0 + k T``;
* at every section time ``Phi`` is re-orthonormalised (Gram-Schmidt, i.e. a QR
  factorisation ``Phi = Q R`` with ``R_ii > 0``) and ``log R_ii`` accumulated;
  inside a period only if the tangent vectors become nearly parallel (strong
  contraction, e.g. along the noncompact curves), which leaves the product of
  the ``R`` factors -- hence the per-period values -- unchanged;
* the divergence ``dQ/dq + dR/dr`` is integrated as an extra state. Liouville's
  formula ``det Phi = exp(int div dt)`` makes ``Lambda_1 + Lambda_2`` equal to
  its time average: a built-in consistency check of the tangent integration.

Units. Exponents are **per unit time** ``t`` (the paper's time; the period is
``T = 2 pi / omega``, ``2 pi`` for the paper's ``g = cos t``). The exponents of
the Poincare map *per iteration* are these times ``T``; both are reported.

The Kaplan-Yorke (Lyapunov) dimension of the section attractor is
``D = 1 + Lambda_1 / |Lambda_2|`` when ``Lambda_1 >= 0 > Lambda_1 + Lambda_2``
(the paper's formula); ``D = 0`` when ``Lambda_1 < 0`` (a stable cycle) and
``D = 2`` when the map does not contract area. The attractor of the 3-D flow
has dimension ``D + 1`` (the time direction adds one).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, run, stream
from explorer_core.solve import rk, tangent
from explorer_core.solve.integrators import tables
from explorer_core.solve.numerics import Numerics, check_ics, check_int
from explorer_core.solve.options import Arg, Check, declare, ics, integer, optional_of
from explorer_core.solve.options import seed as seed_check
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.rk import Status
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

_OK = int(Status.OK)
#: Default size of the random offsets of ensemble members (relative to 1 + |ic|).
ENSEMBLE_OFFSET = 1e-3
#: The measurement's numerics unless the caller gives its own (the defaults of :class:`Numerics`).
LYAPUNOV_NUMERICS = Numerics()


def qr_exponents(matrices: Any) -> np.ndarray:
    """Exponents per step of the product ``M_n ... M_2 M_1`` of 2x2 matrices.

    The same Gram-Schmidt accumulation the kernel applies at section times, on
    given one-step matrices (e.g. the Jacobians of a map along an orbit).

    Parameters
    ----------
    matrices : (n, 2, 2) array-like

    Returns
    -------
    (2,) array: ``sum log R_ii / n``, largest first.
    """
    mats = np.asarray(matrices, dtype=float)
    if mats.ndim != 3 or mats.shape[1:] != (2, 2) or mats.shape[0] == 0:
        raise ParameterError(f"matrices must have shape (n, 2, 2), got {mats.shape}")
    basis = np.eye(2)
    acc = np.zeros(2)
    for m in mats:
        new = m @ basis
        e1x, e1y, e2x, e2y, r11, r22 = rk.gram_schmidt(new[0, 0], new[1, 0], new[0, 1], new[1, 1])
        if r11 <= 0.0 or r22 <= 0.0:
            raise ParameterError("a matrix of the product is singular: exponents are -inf")
        basis = np.array([[e1x, e2x], [e1y, e2y]])
        acc += (math.log(r11), math.log(r22))
    return acc / mats.shape[0]


def kaplan_yorke(l1: float, l2: float) -> float:
    """Kaplan-Yorke dimension of a section attractor with exponents ``l1 >= l2``.

    ``1 + l1/|l2|`` if ``l1 >= 0 > l1 + l2`` (paper, after Figs. 4 and 8B);
    ``0`` for ``l1 < 0`` (a stable cycle), ``2`` if the map does not contract area.
    Units cancel: per time or per iteration give the same ``D``.
    """
    l1, l2 = max(l1, l2), min(l1, l2)
    if l1 < 0.0:
        return 0.0
    if l1 + l2 >= 0.0:
        return 2.0
    return 1.0 + l1 / abs(l2)


# ---------------------------------------------------------------------------
# Results and the public call.


@dataclass(frozen=True)
class LyapunovProgress:
    """Yielded by :func:`iter_lyapunov` (passed to ``progress``) after each chunk of periods; the last
    one carries the result."""

    phase: str  # "transient" or "measure"
    done_periods: int  # of this phase
    total_periods: int  # of this phase
    running: np.ndarray  # (n, 2) current estimates per unit time (0 where none yet)
    status: np.ndarray
    elapsed_s: float
    transient: int = 0  # periods of the transient (so that the progress counts both phases)
    result: LyapunovResult | None = None

    @property
    def progress(self) -> Progress:
        done = self.done_periods + (self.transient if self.phase == "measure" else 0)
        total = self.transient + (self.total_periods if self.phase == "measure" else 0)
        if self.phase == "transient":  # the measurement's periods are not known here: see periods_after
            total += self.periods_after
        return Progress(done, total, "periods", self.elapsed_s)

    #: measured periods that follow the transient (set on transient updates)
    periods_after: int = 0


@dataclass(frozen=True)
class LyapunovResult(Drawable):
    """Lyapunov exponents of one or several trajectories (an ensemble).

    All exponents are **per unit time**; multiply by :attr:`period` for the
    exponents of the Poincare map per iteration (:meth:`per_iteration`).

    Attributes
    ----------
    exponents : (M, 2) ``Lambda_1, Lambda_2`` of the ``(q, r)`` flow per member: the
        averages of ``log R_11``, ``log R_22`` over the ``npts[i]`` measured periods
        (0 where ``npts[i] == 0``). ``Lambda_1 >= Lambda_2`` holds asymptotically; a
        finite-time estimate of a degenerate pair may come out in either order.
    divergence_mean : (M,) time average of ``dQ/dq + dR/dr`` over the same periods.
    logs : (M, periods, 2) ``log R_ii`` of each period (the local stretching).
    divs : (M, periods) integral of the divergence over each period.
    points : (M, periods, 2) section points ``k = transient + 1, ...``.
    npts : (M,) measured periods per member (fewer than ``periods`` on failure).
    status : (M,) :class:`~explorer_core.solve.integrators.Status` codes.
    """

    params: Params
    numerics: Numerics
    ics: np.ndarray
    transient: int
    periods: int
    period: float
    exponents: np.ndarray
    divergence_mean: np.ndarray
    logs: np.ndarray
    divs: np.ndarray
    points: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    nsteps: np.ndarray
    elapsed_s: float
    completed: bool = True
    #: what the result lost: periods not measured (cancelled), members that failed
    lost: list[Loss] = field(default_factory=list)
    #: what was asked (None from :func:`lyapunov_tables`' raw fields)
    spec: LyapunovSpec | None = None

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def history(self) -> Iterator[tuple[int, int, float, float, float]]:
        """Rows ``member, k, L1, L2, divergence_mean``: every member's running estimates after each period."""
        for i in range(self.ics.shape[0]):
            est = self.running(i)
            m = est.shape[0]
            dmean = np.cumsum(self.divs[i, :m]) / (np.arange(1, m + 1) * self.period)
            for k in range(m):
                yield i, self.transient + k + 1, est[k, 0], est[k, 1], dmean[k]

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: the running estimates (:meth:`history`); ``.json``: the summary."""
        csv_ = lambda p: export.write_csv(p, ("member", "k", "L1", "L2", "divergence_mean"), self.history(),  # noqa: E731
                                          export.partial(self))  # fmt: skip
        return export.write_by_suffix(
            path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())}, "Lyapunov result"
        )

    @property
    def ok(self) -> np.ndarray:
        """Members that ran the whole measurement without failure."""
        return (self.status == _OK) & (self.npts == self.periods)

    def status_labels(self) -> list[str]:
        return [Status(int(s)).label for s in self.status]

    def running(self, i: int = 0) -> np.ndarray:
        """(npts[i], 2) running estimates per unit time after k = 1, 2, ... measured periods."""
        m = int(self.npts[i])
        k = np.arange(1, m + 1)[:, None]
        return np.cumsum(self.logs[i, :m], axis=0) / (k * self.period)

    def mean(self) -> np.ndarray:
        """Ensemble mean of ``(Lambda_1, Lambda_2)`` over the members that completed (0 if none)."""
        sel = self.exponents[self.ok]
        return sel.mean(axis=0) if sel.size else np.zeros(2)

    def spread(self) -> np.ndarray:
        """Ensemble standard deviation (ddof=1; 0 for fewer than two members)."""
        sel = self.exponents[self.ok]
        return sel.std(axis=0, ddof=1) if sel.shape[0] > 1 else np.zeros(2)

    def divergence(self) -> float:
        """Ensemble mean of the time-averaged divergence."""
        sel = self.divergence_mean[self.ok]
        return float(sel.mean()) if sel.size else 0.0

    def per_iteration(self) -> np.ndarray:
        """Mean exponents of the Poincare map per iteration: per-time values times ``T``."""
        return self.mean() * self.period

    def kaplan_yorke(self) -> float:
        """Kaplan-Yorke dimension of the section attractor from the mean exponents."""
        l1, l2 = self.mean()
        return kaplan_yorke(float(l1), float(l2))

    def convergence(self, n: int = 40) -> dict[str, list]:
        """Running estimate of member 0 at about ``n`` log-spaced ``k`` (for a convergence plot)."""
        run = self.running(0)
        if run.shape[0] == 0:
            return {"k": [], "L1": [], "L2": []}
        ks = np.unique(np.geomspace(1, run.shape[0], n).astype(int))
        return {
            "k": ks.tolist(),
            "L1": [float(v) for v in run[ks - 1, 0]],
            "L2": [float(v) for v in run[ks - 1, 1]],
        }

    def report(self) -> list[str]:
        """What the command line prints: the exponents with their spread, Kaplan-Yorke, the divergence check."""
        s = self.summary()
        if s["exponents"] is None:
            return [f"status {s['status']}: no member completed the measurement"]
        (l1, l2, _), (s1, s2, _), it = s["exponents"], s["spread"], s["per_iteration"]
        return [f"Lambda (per unit time) = {l1:.6f} +- {s1:.6f}, {l2:.6f} +- {s2:.6f}, 0",
                f"per iteration (x T = {self.period:.6g}): {it[0]:.6f}, {it[1]:.6f}",
                f"Kaplan-Yorke D = {s['kaplan_yorke']:.6f}; L1 + L2 = {l1 + l2:.6e}, "
                f"mean divergence = {s['divergence_mean']:.6e}; status {s['status']}"]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """JSON summary: mean exponents (with ``Lambda_3 = 0``), dimension, check, members."""
        n_ok = int(self.ok.sum())
        mean = self.mean()
        spread = self.spread()
        labels = self.status_labels()
        # The ensemble's status: ok, or what ended its first member that did not finish (a member ok but short of
        # its periods was cancelled); ``members_ok`` says how many the exponents average.
        short = [lab if lab != "ok" else Status.CANCELLED.label for lab, good in zip(labels, self.ok, strict=True)
                 if not good]  # fmt: skip
        status = short[0] if short else Status.OK.label
        div = self.divergence()
        return {
            "exponents": [float(mean[0]), float(mean[1]), 0.0] if n_ok else None,
            "spread": [float(spread[0]), float(spread[1]), 0.0] if n_ok else None,
            "per_iteration": [float(v) for v in self.per_iteration()] + [0.0] if n_ok else None,
            "units": f"exponents per unit time t; per_iteration = per time x T (T = {self.period:.12g})",
            "kaplan_yorke": self.kaplan_yorke() if n_ok else None,
            "divergence_mean": div if n_ok else None,
            "sum_minus_divergence": float(mean.sum() - div) if n_ok else None,
            "status": status,
            "members_ok": n_ok,
            "members": [
                {
                    "ic": [float(q), float(r)],
                    "status": lab,
                    "exponents": [float(e[0]), float(e[1])] if n else None,
                    "divergence_mean": float(d) if n else None,
                    "periods": int(n),
                    "steps": int(s),
                }
                for (q, r), lab, e, d, n, s in zip(
                    self.ics, labels, self.exponents, self.divergence_mean, self.npts, self.nsteps, strict=True
                )
            ],
            "ensemble": {"size": int(self.ics.shape[0]), "ok": n_ok},
            "convergence": self.convergence(),
            "transient": self.transient,
            "periods": self.periods,
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
            **({"spec": self.spec.as_dict()} if self.spec is not None else {}),  # what was asked (the ensemble's)
        }


def ensemble_ics(ic: Sequence[float], m: int, offset: float = ENSEMBLE_OFFSET, seed: int | None = 0) -> np.ndarray:
    """``m`` initial conditions: ``ic`` itself and ``m - 1`` seeded random offsets around it.

    Offsets are uniform in ``+-offset * (1 + |ic|)`` per coordinate; after the
    transient the members sit on the same attractor but (on a chaotic one)
    sample it independently.
    """
    ic = check_ics(ic)
    if ic.shape[0] != 1:
        raise ParameterError(f"ensemble_ics takes one initial condition, got {ic.shape[0]}")
    m = check_int("ensemble", m, 1, config.MAX_TRAJECTORIES)
    if not (math.isfinite(offset) and offset > 0):
        raise ParameterError(f"offset must be a positive number, got {offset!r}")
    rng = np.random.default_rng(seed)
    out = np.repeat(ic, m, axis=0)
    out[1:] += rng.uniform(-1.0, 1.0, (m - 1, 2)) * offset * (1.0 + np.abs(ic))
    return out


def attractor_ensemble(
    params: Params,
    ic: Sequence[float],
    m: int,
    *,
    transient: int,
    offset: float = 1e-6,
    seed: int | None = 0,
    numerics: Numerics | None = None,
) -> np.ndarray:
    """``m`` initial conditions on the attractor that ``ic`` goes to.

    ``ic`` is first run through ``transient`` periods; the members are the settled
    point and ``m - 1`` seeded offsets of relative size ``offset`` around it (see
    :func:`ensemble_ics`). Small offsets keep the members in the attractor's basin;
    on a chaotic attractor they decorrelate within a few dozen periods. If the
    settling run fails (e.g. escapes), the members are placed around ``ic`` itself
    and report the failure through their own status.
    """
    numerics = numerics or Numerics()
    start = check_ics(ic)
    transient = check_int("transient", transient, 0, config.MAX_PERIODS)
    if transient:
        pmap = PoincareMap.of(params, numerics, workers=1)
        batch = pmap.start(start)
        pmap.advance(batch, transient, store=False)
        if batch.status[0] == _OK:
            start = batch.y.copy()
    return ensemble_ics(start[0], m, offset=offset, seed=seed)


def lyapunov_tables(
    num: np.ndarray,
    gpc: np.ndarray,
    den: np.ndarray,
    forcing: np.ndarray,
    t0: float,
    period: float,
    ics: Any,
    periods: int,
    *,
    transient: int = 0,
    numerics: Numerics | None = None,
    progress: Callable[[LyapunovProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Low-level call on raw coefficient tables (see :func:`lyapunov_spectrum`).

    Returns the fields of :class:`LyapunovResult` that do not depend on ``Params``.
    """
    numerics = numerics or Numerics()
    ics = check_ics(ics)
    periods = check_int("periods", periods, 1, config.MAX_PERIODS)
    transient = check_int("transient", transient, 0, config.MAX_PERIODS)
    n = ics.shape[0]
    if n * periods > config.MAX_POINTS:
        raise ParameterError(f"{n} members x {periods} periods exceeds the limit {config.MAX_POINTS}")
    if not (math.isfinite(period) and period > 0):
        raise ParameterError(f"period must be positive, got {period!r}")
    # A raw quadratic field in the model's table format (any, e.g. a linear test field).
    coefs = tables(num, gpc, den, forcing, np.zeros(n, dtype=np.int64))
    batch = tangent.start(ics, t0, period)
    logs = np.zeros((n, periods, 2))
    divs = np.zeros((n, periods))
    pts = np.zeros((n, periods, 2))
    npts = np.zeros(n, dtype=np.int64)
    start = time.perf_counter()
    completed = True

    def chunks(total: int):
        done, size = 0, 8
        while done < total:
            step = min(size, total - done)
            yield step
            done += step
            size = min(2 * size, 256)

    def report(phase: str, done: int, total: int) -> None:
        if progress is None:
            return
        k = np.maximum(npts, 1)[:, None]
        running = logs.sum(axis=1) / (k * period)
        progress(LyapunovProgress(phase, done, total, running, batch.status.copy(), time.perf_counter() - start,
                                  transient, periods_after=periods if phase == "transient" else 0))  # fmt: skip

    done = 0
    for size in chunks(transient):
        if cancel is not None and cancel():
            completed = False
            break
        tangent.advance_lyapunov(coefs, batch, size, numerics, workers, store=False)
        done += size
        report("transient", done, transient)
    done = 0
    if completed:
        for size in chunks(periods):
            if cancel is not None and cancel():
                completed = False
                break
            lg, dv, pt, m = tangent.advance_lyapunov(coefs, batch, size, numerics, workers)
            for i in np.flatnonzero(m):
                # Trajectory i's periods stay contiguous: it contributes only while alive.
                a, b = npts[i], npts[i] + m[i]
                logs[i, a:b] = lg[i, : m[i]]
                divs[i, a:b] = dv[i, : m[i]]
                pts[i, a:b] = pt[i, : m[i]]
            npts += m
            done += size
            report("measure", done, periods)
            if not np.any(batch.status == _OK):
                break
    span = np.maximum(npts, 1) * period
    exps = np.where(npts[:, None] > 0, logs.sum(axis=1) / span[:, None], 0.0)
    divm = np.where(npts > 0, divs.sum(axis=1) / span, 0.0)
    return {
        "ics": ics,
        "transient": transient,
        "periods": periods,
        "period": float(period),
        "exponents": exps,
        "divergence_mean": divm,
        "logs": logs,
        "divs": divs,
        "points": pts,
        "npts": npts,
        "status": batch.status.copy(),
        "nsteps": batch.nsteps.copy(),
        "elapsed_s": time.perf_counter() - start,
        "completed": completed,
    }


@dataclass(frozen=True)
class LyapunovSpec:
    """Everything that defines a Lyapunov measurement (validated by :func:`lyapunov_spec`; plain data:
    picklable, comparable). With ``ensemble > 1`` the members are placed on the attractor of the one
    initial condition (:func:`attractor_ensemble`, through ``transient`` periods, offsets ``offset``
    seeded by ``seed``) when the measurement runs."""

    params: Params
    ics: tuple[tuple[float, float], ...]
    periods: int
    transient: int
    numerics: Numerics
    ensemble: int
    offset: float
    seed: int | None

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "ics": [list(x) for x in self.ics], "periods": self.periods,
                "transient": self.transient, "numerics": self.numerics.as_dict(), "ensemble": self.ensemble,
                "offset": self.offset, "seed": self.seed}  # fmt: skip


def _offset(n: str, v: Any) -> float:
    # More than 1 (relative to 1 + |x|) is not "near the attractor".
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) or not 0 < v <= 1:
        raise ParameterError(f"{n} must be in (0, 1] (relative to 1 + |x|), got {v!r}")
    return float(v)


@declare(
    ics=Arg(
        "initial condition (repeatable: one member each)",
        "points",
        flag="--ic",
        scene="points",
        positional=True,
        check=ics(),
    ),
    periods=Arg("measured periods", "int", positional=True, cli_default=2000, check=integer(1, config.MAX_PERIODS)),
    transient=Arg(
        "periods dropped first",
        "int",
        scene="transient",
        cli_default=100,
        default=0,
        check=integer(0, config.MAX_PERIODS),
    ),
    numerics=Arg(
        "method and tolerances", cli=False, default=LYAPUNOV_NUMERICS, check=optional_of(Numerics, LYAPUNOV_NUMERICS)
    ),
    ensemble=Arg(
        "members placed on the attractor of the one initial condition",
        "int",
        metavar="M",
        default=1,
        check=integer(1, config.MAX_TRAJECTORIES),
    ),
    offset=Arg("relative offset of the ensemble's members", default=1e-6, check=Check(_offset, "a number in (0, 1]")),
    seed=Arg("the offsets' random seed", "int", default=0, check=seed_check(optional=True)),
)
def lyapunov_spec(
    params: Params,
    ics: np.ndarray,
    periods: int,
    *,
    transient: int,
    numerics: Numerics,
    ensemble: int,
    offset: float,
    seed: int | None,
) -> LyapunovSpec:
    """A validated :class:`LyapunovSpec`; every bad value raises :class:`ParameterError` naming it (and
    carrying the keyword as ``exc.option``, :mod:`explorer_core.analyses.specs`). The options are declared above
    (defaults, checks run before this body, flags); the body checks what needs several of them.

    Parameters
    ----------
    params : the system.
    ics : (M, 2) finite initial conditions at ``t0`` (several on one attractor form an ensemble).
    periods : measured periods after the transient, in ``[1, config.MAX_PERIODS]``; members x periods at
        most ``config.MAX_POINTS``.
    transient : periods integrated first and not counted, in ``[0, config.MAX_PERIODS]``.
    numerics : method and tolerances (default :data:`LYAPUNOV_NUMERICS`; None: the default).
    ensemble : members placed on the attractor of the one initial condition (1: the ``ics`` as given).
    offset : the members' offsets relative to ``1 + |x|``, in ``(0, 1]`` (more is not "near the attractor").
    seed : the offsets' random seed (an integer >= 0, or None).
    """
    with Checking() as at:
        at("ensemble")
        if ensemble > 1 and ics.shape[0] != 1:
            raise ParameterError(f"an ensemble of {ensemble} takes one initial condition (the members are placed "
                                 f"on its attractor), got {ics.shape[0]}")  # fmt: skip
        at("periods")
        members = max(ensemble, ics.shape[0])
        if members * periods > config.MAX_POINTS:
            raise ParameterError(f"{members} members x {periods} periods exceeds the limit {config.MAX_POINTS}")
    ics_ = tuple((float(q), float(r)) for q, r in ics)
    return LyapunovSpec(params, ics_, periods, transient, numerics, ensemble, offset, seed)


def iter_lyapunov(
    spec: LyapunovSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[LyapunovProgress]:
    """:func:`lyapunov_spectrum` as a stream of :class:`LyapunovProgress` (after each chunk of periods,
    the transient's counted with the measurement's); the last update's ``result`` is the result.
    ``iter_lyapunov(spec)``, or the keyword form ``iter_lyapunov(params, ics, periods, transient=,
    numerics=)`` (the spec built by :func:`lyapunov_spec`, checked at the call)."""
    spec = spec_of(LyapunovSpec, lyapunov_spec, spec, args, kw)
    params, numerics = spec.params, spec.numerics

    def work(emit: Callable[[LyapunovProgress], None], stop: Callable[[], bool]) -> LyapunovProgress:
        ics = np.array(spec.ics, dtype=float)
        if spec.ensemble > 1:
            ics = attractor_ensemble(params, ics[0], spec.ensemble, transient=spec.transient, offset=spec.offset,
                                     seed=spec.seed, numerics=numerics)  # fmt: skip
        model = Model(params)
        out = lyapunov_tables(model.num, model.gpc, model.den, model.forcing, params.t0, params.period, ics,
                              spec.periods, transient=spec.transient, numerics=numerics, progress=emit, cancel=stop,
                              workers=workers)  # fmt: skip
        res = LyapunovResult(params=params, numerics=numerics, **out, lost=_losses(out), spec=spec)
        k = np.maximum(res.npts, 1)[:, None]
        measured = int(res.periods) if res.completed else int(res.npts.max(initial=0))
        return LyapunovProgress("measure", measured, res.periods, res.logs.sum(axis=1) / (k * res.period),
                                res.status, res.elapsed_s, res.transient, result=res)  # fmt: skip

    return stream(work, cancel)


def _losses(out: dict[str, Any]) -> list[Loss]:
    """What a measurement lost: members the integrator stopped, periods not measured when cancelled."""
    lost = []
    status = out["status"]
    for code in np.unique(status[status != _OK]):
        why = f"the integrator stopped ({Status(int(code)).label}) before the measurement's end"
        lost.append(Loss("members", int(np.count_nonzero(status == code)), why))
    if not out["completed"]:
        left = int(np.sum(out["periods"] - out["npts"][status == _OK]))
        lost.append(Loss("periods not measured", left, "cancelled"))
    return lost


def lyapunov_spectrum(
    spec: LyapunovSpec | Params,
    *args: Any,
    progress: Callable[[LyapunovProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> LyapunovResult:
    """Lyapunov exponents ``Lambda_1 >= Lambda_2`` (per unit time) for each initial condition.

    ``lyapunov_spectrum(spec)`` with a :class:`LyapunovSpec`, or the keyword form
    ``lyapunov_spectrum(params, ics, periods, transient=0, numerics=None)``, which builds the spec with
    :func:`lyapunov_spec` (its parameters: the system, the (M, 2) initial conditions at ``t0`` -- several on
    one attractor form an ensemble, see :func:`ensemble_ics` --, the measured periods after the transient,
    the transient's periods, integrated first while the tangent basis aligns, and the numerics, whose error
    control covers the tangent vectors too).

    progress : called with every update of :func:`iter_lyapunov` (a :class:`LyapunovProgress`).
    cancel : polled between chunks; True stops and returns what was measured (``completed=False``,
        the periods not measured in ``lost``).
    workers : threads (default: both cores).

    Returns
    -------
    LyapunovResult
    """
    return run(iter_lyapunov(spec, *args, cancel=cancel, workers=workers, **kw), progress)
