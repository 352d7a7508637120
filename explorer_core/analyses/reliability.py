"""Is the chosen method reliable for this scene? Warnings from the measured failure map.

:func:`assess` looks at the system, the numerics and what is known of the states
(initial conditions, the section's points, each trajectory's status) and returns
plain-text :class:`ReliabilityWarning` s naming the values involved. Every
threshold is a measured constant of :mod:`explorer_core.studies.failures` (``bilimovich
failures --out DIR``, full size; ``docs/failures.md``):

* fixed-step RK4 is judged by ``z = rho h``, the field's fastest rate ``rho`` (the
  Jacobian's spectral radius, maximised over a period, at the largest states seen)
  times the step ``h = T / N``. On the drift of Fig. 1A (``rho = |r| / 3``) one period
  of RK4 overflows above :data:`RK4_Z_UNSTABLE` and gets the drift step wrong by more
  than 10 % above :data:`RK4_Z_DRIFT_LOST`, where the RK4 map has spurious fixed points
  (the drift stalls with status ``ok``). Below that, one period at ``N`` and ``2N``
  steps from the fastest states in view estimates the error (Richardson), which, times
  the periods, is checked against a pixel;
* adaptive methods: the measured global error per period relative to the tolerance on
  regular orbits, times the periods, against a pixel; the stability floor
  ``rho T / beta`` of the tableau against the step budget;
* statuses in a result (escaped, step_collapsed, too_many_steps, nonfinite), points
  leaving the plot window (drift);
* chaos: a high-accuracy tolerance claims nothing past the Lyapunov horizon.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core.scenes import list_scenes
from explorer_core.solve.integrators import Batch, Status, advance
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import Section
from explorer_core.solve.stability import relative_error, spectral_rate, stability_interval
from explorer_core.system.model import Model
from explorer_core.system.params import Params

LEVELS = ("warning", "error")

# --- measured constants (bilimovich failures --out DIR, full size; docs/failures.md) -----------------

#: rho h from which one period of RK4 from the drift of Fig. 1A overflows (local map: the smallest rho h
#: that overflowed is 2.58, the largest that did not 2.63; RK4's linear stability limit on the real axis
#: is 2.785).
RK4_Z_UNSTABLE = 2.55
#: rho h above which RK4's drift step r_{k+1} - r_k is off by more than 10 % (local map:
#: ``z_drift_lost_min`` = 0.646); long runs stall at spurious fixed points at rho h = 1.1 ... 2.5.
RK4_Z_DRIFT_LOST = 0.65
#: Global error after P periods over (tol_eff P), tol_eff = atol + rtol |x|, on regular orbits (the island
#: orbits of Fig. 1A, rtol = atol = 1e-6 ... 1e-10, 400 periods; ``adaptive_cost.calibration``, median; the
#: 90th percentiles, 2.8 and 15, come from orbits whose phase error grows like P^2).
#: vern9 (the "auto" default at 1e-9..1e-13) is given DOP853's figure, an upper bound: at the same tolerance its
#: errors are 1.2-5x smaller than DOP853's (benchmarks/high_accuracy.py, regular and attractor cases).
TOL_ERROR_PER_PERIOD = {"dp5": 0.24, "dop853": 0.076, "vern9": 0.076}
#: The tolerance is called loose when the expected error exceeds this many pixels (visible in the plot).
LOOSE_PIXELS = 1.0
#: Steps per period of DOP853 (1e-10) along the drift grow like |r|^p (``rk4_on_drift.cost_growth``).
DRIFT_COST_EXPONENT = 0.67
#: A trajectory drifts if it ends outside the plot window beyond this factor times the largest |x| of the
#: first half of its points (an escaping drift passes the bound within a flip, at ~1.8 x on Fig. 1A).
DRIFT_GROWTH = 1.5
#: ... and if |x| grew in this fraction of the steps of the second half (settling orbits go back and forth).
DRIFT_MONOTONE = 0.9
MIN_DRIFT_POINTS = 8
#: Largest Lyapunov exponent (per unit time) of the paper's chaotic scenes (README, reproduction).
KNOWN_LYAPUNOV = {"fig4A": 0.0153, "fig4B": 0.0156, "fig8B": 0.0811}
#: A tolerance at or below this is a high-accuracy claim (the app's "high" is 1e-12).
HIGH_ACCURACY_TOL = 1e-10
#: States probed: the largest by size plus a seeded sample of the rest.
N_PROBE_LARGEST = 64
N_PROBE_SAMPLE = 64
#: States integrated for the RK4 error probe.
N_RICHARDSON = 8


@dataclass(frozen=True)
class ReliabilityWarning:
    """One finding: ``level`` ``"warning"`` (results may be wrong) or ``"error"`` (they are, or will fail)."""

    level: str
    code: str
    message: str

    def __post_init__(self) -> None:
        if self.level not in LEVELS:
            raise ValueError(f"level must be one of {LEVELS}, got {self.level!r}")

    def as_dict(self) -> dict[str, str]:
        return {"level": self.level, "code": self.code, "message": self.message}

    def line(self) -> str:
        """One line for a terminal: ``warning [code]: message``, or ``unreliable [code]: ...`` for an ``"error"``
        (the run itself went on: its exit status is not an error's, and the words on stderr say no more)."""
        return f"{'unreliable' if self.level == 'error' else self.level} [{self.code}]: {self.message}"


def known_lyapunov(params: Params) -> float | None:
    """The measured largest exponent if ``params`` is one of the paper's chaotic scenes."""
    for scene in list_scenes():
        if scene.id in KNOWN_LYAPUNOV and scene.params == params:
            return KNOWN_LYAPUNOV[scene.id]
    return None


def _statuses(status: Any, section_summary: Mapping[str, Any] | None) -> list[str]:
    if status is not None:
        return [s if isinstance(s, str) else Status(int(s)).label for s in np.asarray(status).ravel().tolist()]
    if section_summary is not None:
        return [str(t.get("status", "ok")) for t in section_summary.get("trajectories", [])]
    return []


def _states(points: Any, ics: Any, box: Sequence[float] | None) -> np.ndarray:
    parts = []
    for arr in (points, ics):
        if arr is not None:
            a = np.asarray(arr, dtype=float).reshape(-1, 2)
            parts.append(a[np.all(np.isfinite(a), axis=1)])
    if box is not None:
        q0, q1, r0, r1 = (float(v) for v in box)
        parts.append(np.array([(q0, r0), (q0, r1), (q1, r0), (q1, r1)]))
    if not parts:
        return np.zeros((0, 2))
    x = np.concatenate(parts)
    if x.shape[0] <= N_PROBE_LARGEST + N_PROBE_SAMPLE:
        return x
    size = np.max(np.abs(x), axis=1)
    largest = np.argsort(size)[-N_PROBE_LARGEST:]
    keep = np.ones(x.shape[0], dtype=bool)  # the others, in order (setdiff1d's sorting took a second for 1e6)
    keep[largest] = False
    rest = np.flatnonzero(keep)
    sample = np.random.default_rng(0).choice(rest, N_PROBE_SAMPLE, replace=False)
    return x[np.concatenate([largest, sample])]


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def _inside(pts: np.ndarray, window: Sequence[float]) -> np.ndarray:
    q0, q1, r0, r1 = (float(v) for v in window)
    return (pts[:, 0] >= q0) & (pts[:, 0] <= q1) & (pts[:, 1] >= r0) & (pts[:, 1] <= r1)


def _size_inside(states: np.ndarray, window: Sequence[float]) -> float:
    inside = states[_inside(states, window)]
    return float(np.max(np.abs(inside))) if inside.size else 0.0


def escaping(norm: np.ndarray) -> bool:
    """True if the distances ``norm`` (n,) of one orbit's points from the origin, in order, are those of an escaping
    drift: growing in :data:`DRIFT_MONOTONE` of the steps of the second half and ending beyond :data:`DRIFT_GROWTH`
    times the largest of the first half (a bounded orbit goes back and forth)."""
    half = norm.size // 2
    growing = np.mean(np.diff(norm[half:]) > 0) >= DRIFT_MONOTONE if norm.size > 2 else False
    further = norm[-1] >= DRIFT_GROWTH * max(float(norm[:half].max(initial=0.0)), 1e-300)
    return bool(growing and further)


def _drifting(
    pts: np.ndarray, traj: Any, window: Sequence[float], escaped: set[int]
) -> tuple[int, tuple[float, float]]:
    """Trajectories that end outside ``window`` and are escaping: ``escaped`` ones, or ``|x|`` growing in
    :data:`DRIFT_MONOTONE` of the steps of the second half of their points and ending beyond
    :data:`DRIFT_GROWTH` times the largest ``|x|`` of the first half. An orbit settling onto a compact
    attractor partly outside the window goes back and forth and does not count.

    ``pts`` are in increasing ``k`` per trajectory (as :meth:`Section.long` and the app give them).
    """
    ids = np.zeros(pts.shape[0], dtype=np.int64) if traj is None else np.asarray(traj)
    norm = np.hypot(pts[:, 0], pts[:, 1])
    out = ~_inside(pts, window)
    n, big = 0, (0.0, 0.0)
    # Each trajectory's points in their order, from one stable sort (not a scan of every point per trajectory).
    order = np.argsort(ids, kind="stable")
    grouped, seen = ids[order], np.unique(ids[out])
    starts, ends = np.searchsorted(grouped, seen, side="left"), np.searchsorted(grouped, seen, side="right")
    for t, lo, hi in zip(seen, starts, ends, strict=True):
        sel = order[lo:hi]
        if not out[sel[-1]] or (int(t) not in escaped and sel.size < MIN_DRIFT_POINTS):
            continue
        if int(t) in escaped or escaping(norm[sel]):
            n += 1
            big = (max(big[0], float(np.abs(pts[sel, 0]).max())), max(big[1], float(np.abs(pts[sel, 1]).max())))
    return n, big


def rk4_probe(params: Params, states: np.ndarray, steps: int) -> tuple[float, int]:
    """Estimated relative error of one RK4 period at ``steps`` from ``states`` (Richardson, ``N`` vs ``2N``).

    Returns ``(largest estimate, number of states that failed at N)``; the estimate is
    ``|x_N - x_2N| 16/15 / (1 + |x|)``, the leading error term of a 4th-order method.
    """
    model = Model(params)
    out = []
    for n in (steps, 2 * steps):
        batch = Batch.start(states, params.t0, params.period)
        pts, npts = advance(model, batch, 1, method="rk4", steps_per_period=n, bound=1e300, workers=1)
        out.append((pts[:, 0].copy(), batch.status.copy()))
    (x1, s1), (x2, s2) = out
    ok = (s1 == Status.OK) & (s2 == Status.OK)
    est = relative_error(x1[ok], x2[ok]) * 16.0 / 15.0 if ok.any() else np.zeros(0)
    return (float(est.max()) if est.size else 0.0), int(np.count_nonzero(s1 != Status.OK))


def assess(
    params: Params,
    numerics: Numerics,
    *,
    periods: int,
    transient: int = 0,
    ics: Any = None,
    box: Sequence[float] | None = None,
    points: Any = None,
    traj: Any = None,
    status: Any = None,
    section_summary: Mapping[str, Any] | None = None,
    window: Sequence[float] | None = None,
    pixel: float | None = None,
    lyapunov_max: float | None = None,
) -> list[ReliabilityWarning]:
    """Warnings for ``numerics`` on ``params`` given what is known of the states.

    Parameters
    ----------
    params, numerics : the system and how it is (to be) integrated.
    periods, transient : section points per trajectory and the periods before them.
    ics : (n, 2) initial conditions; ``box`` ``(qmin, qmax, rmin, rmax)`` of random ones.
    points : (m, 2) section points seen (any subset); ``traj`` (m,) their trajectory ids.
    status : per-trajectory status codes or labels of a result, or ``section_summary``
        (the dict of :meth:`Section.summary`) to read them from.
    window : the plot window ``(qmin, qmax, rmin, rmax)``: points leaving it are drift.
    pixel : data units per pixel; accuracy is judged against a quarter pixel (else 1e-6
        relative per period for RK4, and no tolerance check).
    lyapunov_max : largest Lyapunov exponent per unit time, if known (else the paper's
        chaotic scenes are recognised by their parameters).

    Returns
    -------
    list of :class:`ReliabilityWarning`, errors first.
    """
    out: list[ReliabilityWarning] = []
    total = int(periods) + int(transient)
    states = _states(points, ics, box)
    period = params.period
    if states.shape[0]:
        rho_all = spectral_rate(params, states[:, 0], states[:, 1])
        i_max = int(np.argmax(rho_all))
        rho, x_big = float(rho_all[i_max]), states[i_max]
        size = float(np.max(np.abs(states)))
    else:
        rho, x_big, size = 0.0, np.zeros(2), 0.0
    where = f"(|q|, |r|) = ({_fmt(abs(x_big[0]))}, {_fmt(abs(x_big[1]))})"
    fixed = numerics.method == "rk4" or not numerics.adaptive

    if fixed and states.shape[0]:
        n = numerics.steps_per_period
        h = period / n
        # Thresholds are RK4's; another tableau at fixed steps scales with its stability interval.
        scale = stability_interval(numerics.method) / stability_interval("rk4")
        z = rho * h
        name = numerics.method if numerics.method == "rk4" else f"fixed-step {numerics.method}"
        need = math.ceil(rho * period / (RK4_Z_DRIFT_LOST * scale))
        if z >= RK4_Z_UNSTABLE * scale:
            out.append(ReliabilityWarning("error", "rk4_unstable", (
                f"{name} with {n} steps per period is unstable at the largest states seen {where}: "
                f"rho*h = {_fmt(z)} (|r|*h = {_fmt(abs(x_big[1]) * h)}) is above {_fmt(RK4_Z_UNSTABLE * scale)}, "
                f"where one period overflowed in the measured failure map; expect 'nonfinite' (or a false "
                f"'escaped'). Use at least {need} steps per period, or dop853."
            )))  # fmt: skip
        elif z >= RK4_Z_DRIFT_LOST * scale:
            out.append(ReliabilityWarning("warning", "rk4_drift_lost", (
                f"{name} with {n} steps per period is too coarse at the largest states seen {where}: "
                f"rho*h = {_fmt(z)} (|r|*h = {_fmt(abs(x_big[1]) * h)}) is above {_fmt(RK4_Z_DRIFT_LOST * scale)}, "
                f"where the measured RK4 drift step is off by more than 10 % and the drift can stop at a "
                f"spurious fixed point while the status stays 'ok'. Use at least {need} steps per period, or dop853 "
                f"(on a noncompact drift |r| keeps growing and no fixed step stays adequate)."
            )))  # fmt: skip
        elif numerics.method == "rk4":
            # Only what is drawn needs pixel accuracy: probe the fastest states inside the window.
            shown = states if window is None else states[_inside(states, window)]
            if shown.shape[0] == 0:
                shown = states
            rho_shown = spectral_rate(params, shown[:, 0], shown[:, 1])
            est, _ = rk4_probe(params, shown[np.argsort(rho_shown)[-N_RICHARDSON:]], n)
            size_scale = 1.0 + float(np.max(np.abs(shown)))
            if pixel is not None and pixel > 0:
                expected = est * size_scale * total
                if expected > LOOSE_PIXELS * pixel:
                    out.append(ReliabilityWarning("warning", "rk4_inaccurate", (
                        f"rk4 with {n} steps per period: one period from the fastest states in view has an "
                        f"estimated error of {_fmt(est * size_scale)} (N against 2N steps), about {_fmt(expected)} "
                        f"after {total} periods: {_fmt(expected / pixel)} pixels of {_fmt(pixel)}. "
                        f"Use more steps or dop853."
                    )))  # fmt: skip
            elif est > 1e-6:
                out.append(ReliabilityWarning("warning", "rk4_inaccurate", (
                    f"rk4 with {n} steps per period: one period from the largest states has an estimated "
                    f"relative error of {_fmt(est)} (N vs 2N steps), above 1e-6."
                )))  # fmt: skip

    if not fixed and states.shape[0]:
        beta = stability_interval(numerics.method)
        floor = rho * period / beta
        if floor > numerics.max_steps:
            steps = math.ceil(floor) if math.isfinite(floor) else "infinitely many"  # rho overflows at omega = 1e300
            out.append(ReliabilityWarning("error", "step_budget", (
                f"{numerics.method} needs at least {steps} steps per period at {where} "
                f"(stability: rho*T/beta = {_fmt(rho)}*{_fmt(period)}/{_fmt(beta)}), more than the budget "
                f"max_steps = {numerics.max_steps}: expect 'too_many_steps'."
            )))  # fmt: skip
        if pixel is not None and pixel > 0:
            # Only what is drawn needs pixel accuracy: the size of the states inside the window.
            shown = size if window is None else _size_inside(states, window)
            tol_eff = numerics.atol + numerics.rtol * shown
            c = TOL_ERROR_PER_PERIOD.get(numerics.method, max(TOL_ERROR_PER_PERIOD.values()))
            expected = c * tol_eff * total
            if expected > LOOSE_PIXELS * pixel:
                out.append(ReliabilityWarning("warning", "tolerance_loose", (
                    f"tolerance rtol = {numerics.rtol:g}, atol = {numerics.atol:g} is loose for this plot: the "
                    f"expected error after {total} periods is about {_fmt(expected)} (measured: {c:g} x "
                    f"(atol + rtol |x|) per period on regular orbits, |x| up to {_fmt(shown)} here), "
                    f"{_fmt(expected / pixel)} pixels of {_fmt(pixel)}. Tighten the tolerance."
                )))  # fmt: skip

    labels = _statuses(status, section_summary)
    n_traj = len(labels)
    counts = {lab: labels.count(lab) for lab in set(labels)}
    if counts.get("nonfinite"):
        hint = "increase the steps per period" if fixed else "the field overflowed: check the parameters"
        out.append(ReliabilityWarning("error", "nonfinite", (
            f"{counts['nonfinite']} of {n_traj} trajectories became nonfinite (inf/NaN) and stopped; {hint}."
        )))  # fmt: skip
    if counts.get("step_collapsed"):
        t_end = abs(params.t0) + total * period
        floor_h = 10.0 * np.finfo(float).eps * max(t_end, period)
        out.append(ReliabilityWarning("error", "step_collapsed", (
            f"{counts['step_collapsed']} of {n_traj} trajectories stopped with 'step_collapsed': the step needed "
            f"for rtol = {numerics.rtol:g} fell below the round-off floor 10*eps*|t| = {_fmt(floor_h)} at "
            f"t up to {_fmt(t_end)}. Loosen the tolerance or move t0 nearer 0."
        )))  # fmt: skip
    if counts.get("too_many_steps"):
        out.append(ReliabilityWarning("error", "too_many_steps", (
            f"{counts['too_many_steps']} of {n_traj} trajectories ran out of the step budget (max_steps = "
            f"{numerics.max_steps} per period); along a drift the steps per period grow like |r|^"
            f"{DRIFT_COST_EXPONENT:g}. Raise max_steps or compute fewer periods."
        )))  # fmt: skip
    if counts.get("escaped"):
        extra = ""
        if fixed and any(w.code == "rk4_unstable" for w in out):
            extra = " With this rk4 step an escape may be a numerical blow-up, not drift."
        out.append(ReliabilityWarning("warning", "escaped", (
            f"{counts['escaped']} of {n_traj} trajectories escaped (|q| or |r| passed the bound "
            f"{numerics.bound:g}): noncompact drift; their points stop there.{extra}"
        )))  # fmt: skip

    if window is not None and points is not None:
        escaped_ids = {i for i, lab in enumerate(labels) if lab == "escaped"}
        drifting, big = _drifting(np.asarray(points, dtype=float).reshape(-1, 2), traj, window, escaped_ids)
        if drifting:
            out.append(ReliabilityWarning("warning", "drift", (
                f"{drifting} {'trajectory leaves' if drifting == 1 else 'trajectories leave'} the plot window with "
                f"growing |x| (up to |q| = {_fmt(big[0])}, "
                f"|r| = {_fmt(big[1])}): noncompact drift. The cost per period grows with |r| (DOP853 steps "
                f"~ |r|^{DRIFT_COST_EXPONENT:g}) and fixed-step rk4 loses the drift."
            )))  # fmt: skip

    lam = lyapunov_max if lyapunov_max is not None else known_lyapunov(params)
    if lam is not None and lam > 0 and not fixed and numerics.rtol <= HIGH_ACCURACY_TOL:
        target = 0.25 * pixel if pixel else 1e-3
        tol_eff = numerics.atol + numerics.rtol * max(size, 1.0)
        horizon = math.log(max(target / tol_eff, 1.0)) / (lam * period)
        if total > horizon:
            out.append(ReliabilityWarning("warning", "chaotic_horizon", (
                f"chaotic dynamics (largest exponent {lam:g} per unit time): an error of {tol_eff:.1g} grows past "
                f"{_fmt(target)} after about {horizon:.0f} periods, fewer than the {total} computed. Beyond that "
                f"the tolerance does not make individual orbits accurate; the picture of the attractor is still right."
            )))  # fmt: skip
    return sorted(out, key=lambda w: LEVELS.index(w.level), reverse=True)


def assess_section(
    sec: Section,
    *,
    pixel: float | None = None,
    window: Sequence[float] | None = None,
    lyapunov_max: float | None = None,
) -> list[ReliabilityWarning]:
    """:func:`assess` for a computed :class:`~explorer_core.solve.section.Section` (states, statuses)."""
    traj, _, q, r = sec.long()
    return assess(
        sec.params,
        sec.numerics,
        periods=sec.periods,
        transient=sec.transient,
        ics=sec.ics,
        points=np.column_stack([q, r]),
        traj=traj,
        status=sec.status,
        window=window,
        pixel=pixel,
        lyapunov_max=lyapunov_max,
    )
