"""Where the methods fail: a measured map of the failure regimes (issue 5, "Where methods fail").

Each study returns data (a dataclass of arrays) and a JSON-ready ``summary()``;
pictures are drawn elsewhere (``app/failure_render.py``) and
:mod:`explorer_core.analyses.reliability` turns the measured thresholds into warnings.

* :func:`rk4_on_drift` -- fixed-step RK4 on the noncompact drift of Fig. 1A
  (``diag(1, 2, 4)``, ``alpha = 0.1``; the curve ``q -> -0.3``, ``|r|`` growing like
  ``k^2``). Along the drift ``r`` flips sign twice per period and the field's fastest
  rate is ``rho = |r| / 3`` (the spectral radius of the Jacobian, maximised over the
  period), so ``|r| h`` (``h = T / N``) is ``3 rho h``. A long run from a point on the
  curve against a reference gives error and cost against ``k``; a *local map* (one
  period of RK4 from points on the curve, against ``solve_ivp(DOP853, 1e-13)`` on the
  model's coefficients) gives error, drift step and status against ``|r| h``.
* :func:`adaptive_cost` -- DP5/DOP853 steps per period against ``|r|`` along the
  drift, the fitted growth law, the stability floor ``rho T / beta`` of each tableau,
  the global error per period relative to the tolerance on regular orbits, and how a
  section's wall time scales with periods and initial conditions.
* :func:`status_scenarios` -- each :class:`~explorer_core.solve.integrators.Status` produced
  by a realistic setting and reported by :func:`~explorer_core.solve.section.section`,
  plus where the step collapsed against the size of ``t`` (nowhere since ``t0`` is reduced exactly).
* :func:`float_precision` -- the kernels are float64 only; an RK4 in numpy run in
  float32 against float64 shows what single precision would cost.
* :func:`lyapunov_sensitivity` -- the exponents of Fig. 8B against method and tolerance.

:func:`failure_map` runs them all at a :class:`Size`.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from explorer_core.analyses.lyapunov import LyapunovResult, attractor_ensemble, lyapunov_spectrum
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Status
from explorer_core.solve.numerics import Numerics, random_ics
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.section import section
from explorer_core.solve.stability import relative_error, spectral_rate, stability_interval
from explorer_core.studies.reproduce import check_stages, run_stages
from explorer_core.system.model import Model, rhs
from explorer_core.system.params import TIME_RESOLUTION, ParameterError, Params

#: The drift scene: Fig. 1A (the same system as Fig. 3), whose curve has q -> -0.3.
DRIFT_SCENE = "fig1A"
DRIFT_Q = -0.3
#: Reference tolerance (rtol = atol) of the tight integrations.
REF_TOL = 1e-13
#: Relative error ``|x - x_ref| / (1 + |x_ref|)``: thresholds reported by the studies.
ERROR_LEVELS = (1e-9, 1e-6, 1e-3)
#: A drift step (r_{k+1} - r_k) off by more than this fraction counts as "drift lost".
DRIFT_STEP_TOLERANCE = 0.1
#: A run whose |r_{k+1} - r_k| over its last tenth is below this fraction of the reference's has stalled.
STALL_FRACTION = 0.05
#: Regular (island) orbits of Fig. 1A used to calibrate global error against the tolerance.
ISLAND_ICS = ((0.3, 0.3), (0.6, 0.0), (0.0, 1.0), (1.0, 1.0), (1.5, 0.0), (0.0, 2.0))
#: The strange attractor of Fig. 8B (IC of the reproduction, README table).
ATTRACTOR_SCENE = "fig8B"
ATTRACTOR_IC = (-0.3181, -2.178)

Progress = Callable[[str, float], None]
Cancel = Callable[[], bool]


@dataclass(frozen=True)
class Size:
    """How much to measure: ``full`` for the documented map, ``quick`` in about 30 s, ``tiny`` for tests."""

    name: str
    drift_periods: int  # long RK4 run along the drift, from |r| = 20
    drift_steps: tuple[int, ...]  # RK4 steps per period of the long runs
    ivp_periods: int  # periods of the long-run reference checked against solve_ivp
    local_r: tuple[float, ...]  # |r| of the local-map start points
    local_steps: tuple[int, ...]  # RK4 steps per period of the local map
    local_reference: str  # "ivp" (solve_ivp DOP853 1e-13) or "dop853" (ours at 1e-13)
    cost_tols: tuple[float, ...]
    scaling_periods: tuple[int, ...]
    scaling_ics: tuple[int, ...]
    repeat: int
    calib_periods: int
    float_periods: int
    float_steps: int
    float_chaos_periods: int
    lyap_members: int
    lyap_periods: int
    lyap_transient: int
    lyap_rk4: tuple[int, ...]
    lyap_dp5: tuple[float, ...]
    lyap_dop853: tuple[float, ...]


SIZES = {
    "full": Size(
        "full", 3000, (25, 50, 100, 200, 400, 800, 1600, 3200), 100,
        (10, 20, 40, 80, 160, 320, 640, 1280, 2560), tuple(2**j for j in range(3, 14)), "ivp",
        (1e-6, 1e-8, 1e-10, 1e-12, 1e-13), (100, 200, 400, 800, 1600), (10, 20, 40, 80, 160), 3, 400,
        1000, 200, 60, 8, 10_000, 200, (8, 12, 25, 50, 100, 400), (1e-3, 1e-5, 1e-8), (1e-4, 1e-6, 1e-8, 1e-10, 1e-12),
    ),
    "quick": Size(
        "quick", 600, (25, 50, 100, 200, 400, 800), 20,
        (10, 40, 160, 640), tuple(2**j for j in range(3, 12)), "ivp",
        (1e-6, 1e-10), (100, 200, 400), (10, 40, 160), 1, 200,
        300, 200, 40, 4, 1500, 100, (12, 50, 200), (1e-5,), (1e-6, 1e-10),
    ),
    "tiny": Size(
        "tiny", 120, (25, 200), 3,
        (10, 80), (8, 32, 128, 512), "dop853",
        (1e-6, 1e-10), (20, 40), (4, 8), 1, 40,
        20, 200, 20, 2, 100, 20, (12,), (1e-5,), (1e-8,),
    ),
}  # fmt: skip


def get_size(size: str | Size) -> Size:
    """A :class:`Size` by name (``tiny``, ``quick``, ``full``) or as given."""
    if isinstance(size, Size):
        return size
    try:
        return SIZES[str(size)]
    except KeyError:
        raise ParameterError(f"size must be one of {', '.join(SIZES)}, got {size!r}") from None


# ---------------------------------------------------------------------------
# Shared measurements.


def _ivp_points(params: Params, y0: Sequence[float], periods: int, tol: float = REF_TOL) -> tuple[np.ndarray, int]:
    """``solve_ivp(DOP853)`` section points ``k = 1..periods`` from ``y0`` at ``t0``, on the model's coefficients.

    The same right-hand side as the kernels (the model's coefficient tables) through
    scipy's own DOP853, at ``rtol = atol = tol``: an independent integrator.
    """
    model = Model(params)
    num, gpc, den, forcing = model.num, model.gpc, model.den, np.ascontiguousarray(model.forcing)
    work = np.empty((2, 6))

    def f(t: float, y: np.ndarray) -> tuple[float, float]:
        return rhs(num, gpc, den, forcing, t, y[0], y[1], work)

    t_eval = params.t0 + params.period * np.arange(1, periods + 1)
    sol = solve_ivp(f, (params.t0, t_eval[-1]), np.asarray(y0, float), method="DOP853", rtol=tol, atol=tol,
                    t_eval=t_eval)  # fmt: skip
    pts = np.full((periods, 2), np.nan)
    pts[: sol.y.shape[1]] = sol.y.T
    return pts, int(sol.nfev)


def _run(
    params: Params, y0: Any, periods: int, numerics: Numerics, per_period: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Integrate ``y0`` (n, 2) for ``periods``: points (n, periods, 2) with NaN after failure, status, steps, time.

    ``per_period`` advances one period at a time and returns steps per period (n, periods).
    """
    pmap = PoincareMap.of(params, numerics, workers=1)
    ics = np.asarray(y0, dtype=float).reshape(-1, 2)
    batch = pmap.start(ics)
    out = np.full((ics.shape[0], periods, 2), np.nan)
    start = time.perf_counter()
    if per_period:
        steps = np.zeros((ics.shape[0], periods), dtype=np.int64)
        for k in range(periods):
            before = batch.nsteps.copy()
            pts, npts = pmap.advance(batch, 1, block=1)
            steps[:, k] = batch.nsteps - before
            ok = npts > 0
            out[ok, k] = pts[ok, 0]
            if not np.any(batch.status == Status.OK):
                break
    else:
        pts, npts = pmap.advance(batch, periods, block=1)
        for i, m in enumerate(npts):
            out[i, :m] = pts[i, :m]
        steps = batch.nsteps.copy()
    return out, batch.status.copy(), steps, time.perf_counter() - start


def drift_state(r_abs: float, params: Params | None = None) -> np.ndarray:
    """A point of the drift curve of Fig. 1A with ``|r|`` about ``r_abs``, at the section phase.

    ``(-0.3, -r_abs)`` is one period of DOP853 (1e-13) away from the curve: the
    transverse rate is ``|r| / 3``, so after one period the point is on it.
    """
    params = params or get_scene(DRIFT_SCENE).params
    pts, status, _, _ = _run(
        params, [(DRIFT_Q, -float(r_abs))], 1, Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL, bound=1e300)
    )
    if status[0] != Status.OK:
        raise ParameterError(f"the drift start at |r| = {r_abs} failed ({Status(int(status[0])).label})")
    return pts[0, 0].copy()


def _fit_power(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``y = a x^p`` by least squares in log-log: ``(a, p)``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if np.count_nonzero(ok) < 2:
        return math.nan, math.nan
    p, loga = np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)
    return float(math.exp(loga)), float(p)


def _r(v: float, digits: int = 4) -> float | None:
    """Rounded to ``digits`` significant digits for JSON (None for NaN/inf)."""
    if v is None or not math.isfinite(v):
        return None
    return float(f"{v:.{digits}g}")


# ---------------------------------------------------------------------------
# 1. Fixed-step RK4 on the drift.


@dataclass(frozen=True)
class LocalMap:
    """One period of RK4 from points on the drift curve, against a tight reference.

    Arrays are ``(len(r0), len(steps))``: ``rh = |r| h``, ``z = rho h`` (``rho`` the
    field's fastest rate at the start point), ``error`` the relative error after one
    period, ``step_ratio`` RK4's drift step ``r_1 - r_0`` over the reference's,
    ``richardson`` the error estimated from ``N`` against ``2N`` steps (what
    :func:`explorer_core.analyses.reliability.rk4_probe` computes), and ``status`` the kernel's
    status code (NaN error where it failed).
    """

    r0: np.ndarray  # (n_r,) |r| of the start points
    starts: np.ndarray  # (n_r, 2)
    reference: np.ndarray  # (n_r, 2) one period later
    rho: np.ndarray  # (n_r,)
    steps: np.ndarray  # (n_s,)
    rh: np.ndarray
    z: np.ndarray
    error: np.ndarray
    step_ratio: np.ndarray
    richardson: np.ndarray
    status: np.ndarray
    reference_kind: str
    reference_s: float

    def thresholds(self) -> dict[str, Any]:
        """Where RK4 goes unstable and where it loses the drift, in ``|r| h`` and ``rho h``."""
        finite = self.status == Status.OK
        failed = ~finite
        out: dict[str, Any] = {}
        for name, val in (("rh", self.rh), ("z", self.z)):
            out[f"{name}_unstable_min"] = _r(float(val[failed].min())) if failed.any() else None
            out[f"{name}_stable_max"] = _r(float(val[finite].max())) if finite.any() else None
            lost = finite & (np.abs(self.step_ratio - 1.0) > DRIFT_STEP_TOLERANCE)
            out[f"{name}_drift_lost_min"] = _r(float(val[lost].min())) if lost.any() else None
            for level in ERROR_LEVELS:
                bad = failed | (self.error > level)
                # Largest value below which every measured cell met the level.
                good_below = float(val[bad].min()) if bad.any() else math.inf
                ok_vals = val[~bad & (val < good_below)]
                out[f"{name}_error_{level:.0e}"] = _r(float(ok_vals.max())) if ok_vals.size else None
        # How well the N-vs-2N estimate tracks the true error where RK4 still gets the drift right.
        good = finite & (np.abs(self.step_ratio - 1.0) <= DRIFT_STEP_TOLERANCE) & (self.error > 1e-11)
        ratio = (self.richardson / self.error)[good & np.isfinite(self.richardson)]
        if ratio.size:
            out["richardson_over_error"] = {
                "median": _r(float(np.median(ratio)), 3),
                "min": _r(float(ratio.min()), 3),
                "max": _r(float(ratio.max()), 3),
            }
        return out

    def summary(self) -> dict[str, Any]:
        return {
            "reference": self.reference_kind,
            "reference_s": round(self.reference_s, 2),
            "r0": [_r(v) for v in self.r0],
            "rho": [_r(v) for v in self.rho],
            "steps": self.steps.tolist(),
            "rh": [[_r(v) for v in row] for row in self.rh],
            "error": [[_r(v, 3) for v in row] for row in self.error],
            "step_ratio": [[_r(v, 3) for v in row] for row in self.step_ratio],
            "richardson": [[_r(v, 3) for v in row] for row in self.richardson],
            "status": [[Status(int(s)).label for s in row] for row in self.status],
            "thresholds": self.thresholds(),
        }


@dataclass(frozen=True)
class Rk4Drift:
    """RK4 along the drift: long runs from ``start`` against a reference, and the local map.

    ``points[j]`` is the run with ``steps[j]`` steps per period (NaN after a failure),
    ``error[j]`` its relative error against ``reference``; ``adaptive`` holds DOP853
    runs at the CLI default and a plot tolerance for comparison (points, error, steps
    per period). ``ref_steps`` are the reference's steps per period (cost against k).
    """

    params: Params
    start: np.ndarray
    k: np.ndarray  # (K,) section indices 1..K counted from the start point
    reference: np.ndarray  # (K, 2) DOP853 at 1e-13
    ref_steps: np.ndarray  # (K,)
    ivp_check: dict[str, Any]
    steps: np.ndarray  # (n_N,)
    points: np.ndarray  # (n_N, K, 2)
    error: np.ndarray  # (n_N, K)
    status: np.ndarray  # (n_N,)
    seconds: np.ndarray  # (n_N,)
    adaptive: dict[str, dict[str, Any]]
    local: LocalMap

    def run_summary(self, j: int) -> dict[str, Any]:
        """What happened to the run with ``steps[j]`` steps per period."""
        n = int(self.steps[j])
        h = self.params.period / n
        err = self.error[j]
        valid = np.isfinite(err)
        m = int(np.count_nonzero(valid))
        out: dict[str, Any] = {
            "steps_per_period": n,
            "h": _r(h),
            "status": Status(int(self.status[j])).label,
            "k_fail": int(self.k[m]) if m < self.k.size else None,
            "seconds": round(float(self.seconds[j]), 3),
            "final_r": _r(float(self.points[j, m - 1, 1]), 6) if m else None,
            "reference_final_r": _r(float(self.reference[-1, 1]), 6),
            "final_error": _r(float(err[m - 1]), 3) if m else None,
        }
        for level in ERROR_LEVELS:
            over = np.flatnonzero(valid & (err > level))
            k_at = int(self.k[over[0]]) if over.size else None
            out[f"k_error_{level:.0e}"] = k_at
            out[f"rh_error_{level:.0e}"] = _r(abs(float(self.reference[over[0], 1])) * h) if over.size else None
        stall = self.stall(j)
        out.update(stall)
        return out

    def stall(self, j: int) -> dict[str, Any]:
        """Whether run ``j`` stopped drifting (a spurious fixed point of the RK4 map)."""
        x = self.points[j]
        valid = np.isfinite(x[:, 1])
        m = int(np.count_nonzero(valid))
        tail = max(3, m // 10)
        if m < 2 * tail:
            return {"stalled": False}
        own = np.mean(np.abs(np.diff(x[m - tail : m, 1])))
        ref = np.mean(np.abs(np.diff(self.reference[m - tail : m, 1])))
        if not own < STALL_FRACTION * ref:
            return {"stalled": False}
        r_end = float(x[m - 1, 1])
        k_stall = int(self.k[np.argmax(np.abs(x[:m, 1] - r_end) <= 0.01 * abs(r_end))])
        h = self.params.period / float(self.steps[j])
        rho = float(spectral_rate(self.params, x[m - 1, 0], r_end)[0])
        return {"stalled": True, "k_stall": k_stall, "r_stall": _r(r_end, 6), "rh_stall": _r(abs(r_end) * h),
                "z_stall": _r(rho * h)}  # fmt: skip

    def cost_growth(self) -> dict[str, Any]:
        """How steps per period and the section's total steps grow along the drift (second half of the run).

        ``steps/period ~ k^g`` and ``|r| ~ k^m`` are fitted; then ``steps/period ~ |r|^(g/m)`` and the
        total to period ``K`` grows like ``K^(g+1)``.
        """
        half = self.k >= self.k.size // 2
        _, m = _fit_power(self.k[half], np.abs(self.reference[half, 1]))
        out: dict[str, Any] = {"r_exponent_in_k": _r(m, 3)}
        runs = {f"dop853 {REF_TOL:g} (reference)": self.ref_steps}
        runs.update({name: d["steps_per_period"] for name, d in self.adaptive.items()})
        for name, sp in runs.items():
            _, g = _fit_power(self.k[half], sp[half])
            out[name] = {"steps_exponent_in_k": _r(g, 3), "steps_exponent_in_r": _r(g / m, 3),
                         "total_exponent_in_K": _r(g + 1, 3), "total_steps": int(sp.sum()),
                         "steps_first_period": int(sp[0]), "steps_last_period": int(sp[-1])}  # fmt: skip
        return out

    def summary(self) -> dict[str, Any]:
        sample = np.unique(np.geomspace(1, self.k.size, 24).astype(int)) - 1
        return {
            "scene": DRIFT_SCENE,
            "start": [float(v) for v in self.start],
            "periods": int(self.k.size),
            "reference": f"DOP853 rtol=atol={REF_TOL:g} (ours), checked against solve_ivp(DOP853) {REF_TOL:g}",
            "ivp_check": self.ivp_check,
            "reference_r": {"k": self.k[sample].tolist(), "r": [_r(float(v), 6) for v in self.reference[sample, 1]]},
            "reference_steps_per_period": {"k": self.k[sample].tolist(), "steps": self.ref_steps[sample].tolist()},
            "runs": [self.run_summary(j) for j in range(self.steps.size)],
            "adaptive": {
                name: {kk: v for kk, v in d.items() if kk not in ("points", "error", "steps_per_period")}
                for name, d in self.adaptive.items()
            },
            "cost_growth": self.cost_growth(),
            "local_map": self.local.summary(),
        }


def local_map(
    r0: Sequence[float], steps: Sequence[int], reference: str = "ivp", cancel: Cancel | None = None
) -> LocalMap:
    """One period of RK4 at ``steps`` from drift points with ``|r| = r0`` (see :class:`LocalMap`)."""
    params = get_scene(DRIFT_SCENE).params
    r0 = np.asarray(r0, dtype=float)
    steps = np.asarray(steps, dtype=int)
    starts = np.array([drift_state(v, params) for v in r0])
    t = time.perf_counter()
    if reference == "ivp":
        ref = np.array([_ivp_points(params, y, 1)[0][0] for y in starts])
    elif reference == "dop853":
        ref = _run(params, starts, 1, Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL, bound=1e300))[0][:, 0]
    else:
        raise ParameterError(f"reference must be 'ivp' or 'dop853', got {reference!r}")
    ref_s = time.perf_counter() - t
    rho = spectral_rate(params, starts[:, 0], starts[:, 1])
    shape = (r0.size, steps.size)
    error, ratio, richardson = np.full(shape, np.nan), np.full(shape, np.nan), np.full(shape, np.nan)
    status = np.zeros(shape, dtype=np.int64)
    for j, n in enumerate(steps):
        if cancel is not None and cancel():
            break
        # bound = 1e300: an instability shows as "nonfinite", not as a fake escape.
        pts, st, _, _ = _run(params, starts, 1, Numerics(method="rk4", steps_per_period=int(n), bound=1e300))
        status[:, j] = st
        ok = st == Status.OK
        error[ok, j] = relative_error(pts[ok, 0], ref[ok])
        ratio[ok, j] = (pts[ok, 0, 1] - starts[ok, 1]) / (ref[ok, 1] - starts[ok, 1])
        # The error estimate reliability.rk4_probe uses: N against 2N steps (Richardson, 4th order).
        pts2, st2, _, _ = _run(params, starts, 1, Numerics(method="rk4", steps_per_period=2 * int(n), bound=1e300))
        both = ok & (st2 == Status.OK)
        richardson[both, j] = relative_error(pts[both, 0], pts2[both, 0]) * 16.0 / 15.0
    h = params.period / steps
    return LocalMap(
        r0=np.abs(starts[:, 1]),
        starts=starts,
        reference=ref,
        rho=rho,
        steps=steps,
        rh=np.abs(starts[:, 1])[:, None] * h[None, :],
        z=rho[:, None] * h[None, :],
        error=error,
        step_ratio=ratio,
        richardson=richardson,
        status=status,
        reference_kind="solve_ivp DOP853 1e-13" if reference == "ivp" else "ours DOP853 1e-13",
        reference_s=ref_s,
    )


def rk4_on_drift(size: str | Size = "full", cancel: Cancel | None = None) -> Rk4Drift:
    """RK4 at several steps per period along the drift of Fig. 1A, against a tight reference.

    The long runs start on the curve at ``|r| = 20`` (the approach from ``(0, 8)`` is a
    chaotic transient: even two 1e-13 integrators part after ~50 periods, so pointwise
    error from there measures nothing). The reference is our DOP853 at 1e-13, checked
    against ``solve_ivp(DOP853, 1e-13)`` over the first ``ivp_periods`` periods.
    """
    sz = get_size(size)
    params = get_scene(DRIFT_SCENE).params
    start = drift_state(20.0, params)
    big = 1e300  # no escape bound: failures show as themselves
    ref_num = Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL, bound=big)
    ref_pts, _, ref_steps, _ = _run(params, start, sz.drift_periods, ref_num, per_period=True)
    reference = ref_pts[0]
    ivp, nfev = _ivp_points(params, start, sz.ivp_periods)
    diff = relative_error(reference[: sz.ivp_periods], ivp)
    ivp_check = {"periods": sz.ivp_periods, "max_relative_difference": _r(float(np.nanmax(diff)), 3), "nfev": nfev}
    steps = np.asarray(sz.drift_steps, dtype=int)
    points = np.full((steps.size, sz.drift_periods, 2), np.nan)
    status = np.zeros(steps.size, dtype=np.int64)
    seconds = np.zeros(steps.size)
    for j, n in enumerate(steps):
        if cancel is not None and cancel():
            break
        pts, st, _, el = _run(
            params, start, sz.drift_periods, Numerics(method="rk4", steps_per_period=int(n), bound=big)
        )
        points[j], status[j], seconds[j] = pts[0], st[0], el
    adaptive: dict[str, dict[str, Any]] = {}
    for name, tol in (("dop853 1e-10", 1e-10), ("dop853 1e-6", 1e-6)):
        pts, st, sp, el = _run(
            params, start, sz.drift_periods, Numerics(method="dop853", rtol=tol, atol=tol, bound=big), per_period=True
        )
        err = relative_error(pts[0], reference)
        adaptive[name] = {
            "points": pts[0],
            "error": err,
            "steps_per_period": sp[0],
            "status": Status(int(st[0])).label,
            "seconds": round(el, 3),
            "total_steps": int(sp[0].sum()),
            "final_error": _r(float(err[np.isfinite(err)][-1]), 3),
            "max_error": _r(float(np.nanmax(err)), 3),
        }
    lm = local_map(sz.local_r, sz.local_steps, sz.local_reference, cancel)
    return Rk4Drift(
        params=params,
        start=start,
        k=np.arange(1, sz.drift_periods + 1),
        reference=reference,
        ref_steps=ref_steps[0],
        ivp_check=ivp_check,
        steps=steps,
        points=points,
        error=relative_error(points, reference[None]),
        status=status,
        seconds=seconds,
        adaptive=adaptive,
        local=lm,
    )


# ---------------------------------------------------------------------------
# 2. Cost of the adaptive methods along the drift; how a section's cost scales.


@dataclass(frozen=True)
class AdaptiveCost:
    """Steps per period of DP5/DOP853 against ``|r|`` on the drift, and section cost scaling.

    ``steps[(method, tol)]`` is ``(n_r,)`` steps per period at the points ``r0``;
    ``floor[method]`` the stability floor ``rho T / beta``. ``calibration`` holds the
    global error after ``P`` periods over ``tol * P`` on regular orbits; ``scaling`` the
    wall time of sections against periods and initial conditions.
    """

    r0: np.ndarray
    rho: np.ndarray
    period: float
    steps: dict[tuple[str, float], np.ndarray]
    beta: dict[str, float]
    calibration: dict[str, Any]
    scaling: dict[str, Any]

    def floor(self, method: str) -> np.ndarray:
        return self.rho * self.period / self.beta[method]

    def fits(self, r_min: float = 40.0) -> dict[str, dict[str, float | None]]:
        """``steps = a |r|^p`` over ``|r| >= r_min``, and the ratio to the stability floor at the largest ``|r|``."""
        out = {}
        sel = self.r0 >= r_min
        for (method, tol), s in self.steps.items():
            a, p = _fit_power(self.r0[sel], s[sel])
            out[f"{method} {tol:g}"] = {
                "a": _r(a),
                "p": _r(p, 3),
                "steps_at_max_r": int(s[-1]),
                "over_stability_floor_at_max_r": _r(float(s[-1] / self.floor(method)[-1]), 3),
            }
        return out

    def summary(self) -> dict[str, Any]:
        return {
            "r0": [_r(v) for v in self.r0],
            "rho": [_r(v) for v in self.rho],
            "steps_per_period": {f"{m} {t:g}": s.tolist() for (m, t), s in self.steps.items()},
            "stability_interval": {m: _r(b) for m, b in self.beta.items()},
            "stability_floor": {m: [_r(v) for v in self.floor(m)] for m in self.beta},
            "fits": self.fits(),
            "calibration": self.calibration,
            "scaling": self.scaling,
        }


def _tolerance_calibration(periods: int) -> dict[str, Any]:
    """Global error after ``P`` periods over ``tol (1 + |x|) P`` on the island orbits of Fig. 1A (rtol = atol)."""
    params = get_scene(DRIFT_SCENE).params
    ref = section(params, ISLAND_ICS, periods, numerics=Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL))
    size = np.max(np.abs(ref.points), axis=(1, 2))
    out: dict[str, Any] = {
        "ics": [list(p) for p in ISLAND_ICS],
        "periods": periods,
        "orbit_size": size.round(3).tolist(),
    }
    for method in ("dp5", "dop853"):
        ratios = []
        for tol in (1e-6, 1e-8, 1e-10):
            s = section(params, ISLAND_ICS, periods, numerics=Numerics(method=method, rtol=tol, atol=tol))
            err = np.max(np.abs(s.points[:, -1] - ref.points[:, -1]), axis=1)
            # Per unit of tol_eff = atol + rtol |x| (the orbit's size), as reliability.assess uses it.
            ratios.extend((err / (tol * (1.0 + size) * periods)).tolist())
        arr = np.array(ratios)
        out[method] = {
            "median": _r(float(np.median(arr)), 3),
            "p90": _r(float(np.quantile(arr, 0.9)), 3),
            "max": _r(float(arr.max()), 3),
        }
    return out


def _timed_section(
    params: Params, ics: np.ndarray, periods: int, numerics: Numerics, repeat: int, workers: int | None = None
) -> tuple[float, float, int]:
    """Medians over ``repeat`` runs of wall and CPU seconds (all threads), and the steps taken."""
    wall, cpu = [], []
    steps = 0
    for _ in range(repeat):
        c0 = time.process_time()
        sec = section(params, ics, periods, numerics=numerics, workers=workers)
        cpu.append(time.process_time() - c0)
        wall.append(sec.elapsed_s)
        steps = int(sec.nsteps.sum())
    return statistics.median(wall), statistics.median(cpu), steps


def _section_scaling(sz: Size) -> dict[str, Any]:
    """Time of fig1C sections (DOP853 1e-10) against periods, initial conditions and cores.

    CPU seconds (all threads) are the work and hardly change when other processes share
    the machine; wall seconds are what a user waits for.
    """
    params = get_scene("fig1C").params
    box = get_scene("fig1C").box
    num = Numerics(method="dop853")  # the study measures DOP853 (its labels say so)
    n_fixed = sz.scaling_ics[len(sz.scaling_ics) // 2]
    p_fixed = sz.scaling_periods[len(sz.scaling_periods) // 2]
    ics = random_ics(n_fixed, box, seed=0)
    section(params, ics, 2, numerics=num)  # warm
    by_p = [_timed_section(params, ics, p, num, sz.repeat) for p in sz.scaling_periods]
    by_n = [_timed_section(params, random_ics(n, box, seed=0), p_fixed, num, sz.repeat) for n in sz.scaling_ics]
    both = _timed_section(params, ics, p_fixed, num, sz.repeat)
    one = _timed_section(params, ics, p_fixed, num, sz.repeat, workers=1)

    def table(xs: Sequence[int], rows: list[tuple[float, float, int]]) -> dict[str, Any]:
        x = np.array(xs, dtype=float)
        return {
            "wall_s": [_r(w) for w, _, _ in rows],
            "cpu_s": [_r(c) for _, c, _ in rows],
            "steps": [n for _, _, n in rows],
            "cpu_exponent": _r(_fit_power(x, np.array([c for _, c, _ in rows]))[1], 3),
            "steps_exponent": _r(_fit_power(x, np.array([n for _, _, n in rows], dtype=float))[1], 3),
        }

    return {
        "scene": "fig1C",
        "numerics": "dop853 1e-10",
        "repeat": sz.repeat,
        "vs_periods": {"ics": n_fixed, "periods": list(sz.scaling_periods), **table(sz.scaling_periods, by_p)},
        "vs_ics": {"periods": p_fixed, "ics": list(sz.scaling_ics), **table(sz.scaling_ics, by_n)},
        "parallel": {"ics": n_fixed, "periods": p_fixed, "one_core_wall_s": _r(one[0]),
                     "all_cores_wall_s": _r(both[0]), "speedup": _r(one[0] / both[0], 3)},
    }  # fmt: skip


def adaptive_cost(size: str | Size = "full", cancel: Cancel | None = None) -> AdaptiveCost:
    """DP5/DOP853 steps per period at drift points of growing ``|r|``, and section cost scaling."""
    sz = get_size(size)
    params = get_scene(DRIFT_SCENE).params
    r0 = np.asarray(sz.local_r, dtype=float)
    starts = np.array([drift_state(v, params) for v in r0])
    rho = spectral_rate(params, starts[:, 0], starts[:, 1])
    steps: dict[tuple[str, float], np.ndarray] = {}
    for method in ("dp5", "dop853"):
        for tol in sz.cost_tols:
            if cancel is not None and cancel():
                break
            num = Numerics(method=method, rtol=tol, atol=tol, bound=1e300, max_steps=10**9)
            # One period first so the step-size memory is settled, then the mean of three.
            _, _, sp, _ = _run(params, starts, 4, num, per_period=True)
            steps[(method, tol)] = sp[:, 1:].mean(axis=1)
    return AdaptiveCost(
        r0=np.abs(starts[:, 1]),
        rho=rho,
        period=params.period,
        steps=steps,
        beta={m: stability_interval(m) for m in ("rk4", "dp5", "dop853")},
        calibration=_tolerance_calibration(sz.calib_periods),
        scaling=_section_scaling(sz),
    )


# ---------------------------------------------------------------------------
# 3. Every status, produced and reported.


@dataclass(frozen=True)
class Scenario:
    """One failure scenario: what was run, the status it produced and when."""

    name: str
    expected: str
    setting: str
    status: str
    k_fail: int | None
    points: int
    note: str
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.name,
            "expected": self.expected,
            "setting": self.setting,
            "status": self.status,
            "k_fail": self.k_fail,
            "points": self.points,
            "note": self.note,
            "warnings": list(self.warnings),
        }


#: (name, expected status, scene, parameter changes, ICs, periods, numerics, note)
SCENARIOS: tuple[tuple[str, str, str, dict[str, float], tuple[tuple[float, float], ...], int, dict[str, Any], str], ...]
SCENARIOS = (
    ("drift leaves the bound", "escaped", "fig1A", {}, ((-0.3, -20.0),), 2000, {"bound": 100.0},
     "noncompact drift: |r| passes the escape bound"),
    ("exponential escape (Fig. 9)", "escaped", "fig9", {}, ((0.8663, -2.1588),), 400, {},
     "leaves the attractor along r ~ 5 q, |x_k| ~ e^(0.178 k)"),
    ("step budget on the drift", "too_many_steps", "fig1A", {}, ((-0.3, -20.0),), 2000, {"max_steps": 400},
     "steps per period grow with |r| until the per-period budget runs out"),
    ("step budget too small", "too_many_steps", "fig8B", {}, ((-0.3181, -2.178),), 10, {"max_steps": 10},
     "max_steps below what one period needs"),
    ("huge state, no bound", "step_collapsed", "fig1C", {}, ((1e13, 1e13),), 10,
     {"bound": math.inf, "method": "dop853"},
     "a state of 1e13 turns so fast that the step it needs is below the round-off floor of the time (a huge "
     "t0 no longer does: the clock starts at t0's phase, reduced exactly)"),
    ("rk4 too coarse on the drift", "nonfinite", "fig1A", {}, ((-0.3, -100.0),), 10,
     {"method": "rk4", "steps_per_period": 16, "bound": 1e300}, "|r| h = 39 >> 8.4: RK4 is unstable and overflows"),
    ("rk4 too coarse, finite bound", "escaped", "fig1A", {}, ((-0.3, -100.0),), 10,
     {"method": "rk4", "steps_per_period": 16}, "the same blow-up passes the bound first: reported as an escape"),
    ("rk4 stalls on the drift", "ok", "fig1A", {}, ((-0.3, -20.0),), 2000, {"method": "rk4", "steps_per_period": 100},
     "silent: a spurious fixed point of the RK4 map; only the reliability check flags it"),
)  # fmt: skip


def status_scenarios(cancel: Cancel | None = None) -> list[Scenario]:
    """Run every scenario of :data:`SCENARIOS` through :func:`~explorer_core.solve.section.section`."""
    from explorer_core.analyses.reliability import assess_section  # reliability imports this module's constants

    out = []
    for name, expected, sid, changes, ics, periods, nkw, note in SCENARIOS:
        if cancel is not None and cancel():
            break
        params = get_scene(sid).params.with_(**changes)
        scene = get_scene(sid)
        num = Numerics(**{"bound": scene.bound, **nkw})
        sec = section(params, ics, periods, numerics=num)
        st = int(sec.status[0])
        m = int(sec.npts[0])
        warnings = assess_section(sec, pixel=scene.pixel_size())
        setting = f"{sid} {changes or ''} ic {ics[0]} {num.method} " + (
            f"N={num.steps_per_period}" if num.method == "rk4" else f"tol {num.rtol:g}"
        )
        setting += f", bound {num.bound:g}, max_steps {num.max_steps}"
        out.append(
            Scenario(
                name=name,
                expected=expected,
                setting=" ".join(setting.split()),
                status=Status(st).label,
                k_fail=int(sec.k_first + m) if st != Status.OK else None,
                points=m,
                note=note,
                warnings=tuple(f"{w.level}:{w.code}" for w in warnings),
            )
        )
    return out


def collapse_onset(
    tols: Sequence[float] = (1e-6, 1e-10, 1e-13), exponents: Sequence[int] = tuple(range(4, 17))
) -> dict[str, Any]:
    """Smallest ``t0 = 10^e`` at which one period of DOP853 on Fig. 1C reports ``step_collapsed`` (None: none).

    The engine's clock starts at ``t0`` reduced exactly to its phase (:func:`~explorer_core.system.params.
    reduce_time`), so no resolvable ``t0`` collapses any more (before: from 1e10 at tol 1e-13, 1e13 at 1e-6).

    From the ``t0`` whose doubles no longer resolve the forcing phase (:data:`TIME_RESOLUTION` of a period)
    the system is refused before any work: those exponents are labelled ``refused``.
    """
    base = get_scene("fig1C").params
    out: dict[str, Any] = {"scene": "fig1C", "ic": [0.5, 0.5], "t0_exponents": list(exponents), "by_tol": {},
                           "time_resolution": TIME_RESOLUTION}  # fmt: skip
    for tol in tols:
        first = None
        labels = []
        for e in exponents:
            try:
                params = base.with_(t0=10.0**e)
            except ParameterError:
                labels.append("refused")
                continue
            sec = section(params, [(0.5, 0.5)], 1, numerics=Numerics(method="dop853", rtol=tol, atol=tol))
            lab = Status(int(sec.status[0])).label
            labels.append(lab)
            if first is None and lab == "step_collapsed":
                first = e
        out["by_tol"][f"{tol:g}"] = {"first_collapse_exponent": first, "status": labels}
    return out


# ---------------------------------------------------------------------------
# 4. float32 against float64.


def rk4_numpy(
    params: Params,
    ics: Any,
    periods: int,
    steps: int,
    dtype: Any = np.float64,
    clock_dtype: Any | None = None,
) -> np.ndarray:
    """Section points of classical RK4 in numpy with the state and all arithmetic in ``dtype``.

    A plain reference implementation (not a kernel): the coefficient tables, the
    forcing, the time and the state are all held in ``dtype`` (float32 or float64);
    ``clock_dtype`` (default ``dtype``) is the type of the time ``t`` and of ``g(t)``,
    ``g'(t)``, which are rounded to ``dtype`` before use. Section times are
    ``t0 + k T`` rounded once, step times ``t_k + m h`` (as the kernels do).

    Returns
    -------
    (periods, n, 2) array in ``dtype``; NaN once a trajectory is not finite.
    """
    ft = np.dtype(dtype).type
    ct = np.dtype(clock_dtype or dtype).type
    model = Model(params)
    num = model.num[:2].astype(ft)  # (2, 6, 5)
    gpc = model.gpc[:2].astype(ft)
    den = model.den.astype(ft)
    g0, g1, g2, w = (ct(v) for v in params.forcing)
    y = np.asarray(ics, dtype=ft).reshape(-1, 2).T.copy()  # (2, n)
    h = ct(params.period / steps)
    half = ct(0.5) * h
    hs, hh, sixth, two = ft(h), ft(half), ft(1.0 / 6.0), ft(2.0)
    out = np.empty((periods, y.shape[1], 2), dtype=ft)
    mono = np.empty((6, y.shape[1]), dtype=ft)

    def tables(ta: Any) -> np.ndarray:
        # The coefficients depend on t only: one (2, 6) table per stage time of the period.
        t = ta + np.arange(2 * steps + 1, dtype=ct) * half
        c, s = np.cos(w * t), np.sin(w * t)
        g = (g0 + g1 * c + g2 * s).astype(ft)
        gp = (w * (g2 * c - g1 * s)).astype(ft)
        gg = g[:, None, None]
        v = num[..., 0] + gg * (num[..., 1] + gg * (num[..., 2] + gg * (num[..., 3] + gg * num[..., 4])))
        v[:, :, 1] += gp[:, None] * (gpc[:, 0] + g[:, None] * gpc[:, 1])
        return v / (den[0] + g * (den[1] + g * den[2]))[:, None, None]

    def f(c: np.ndarray, yy: np.ndarray) -> np.ndarray:
        q, r = yy[0], yy[1]
        mono[0] = 1
        mono[1], mono[2], mono[3], mono[4], mono[5] = q, r, q * q, q * r, r * r
        return c @ mono

    for k in range(periods):
        tab = tables(ct(params.t0 + k * params.period))
        for m in range(steps):
            c0, c1, c2 = tab[2 * m], tab[2 * m + 1], tab[2 * m + 2]
            k1 = f(c0, y)
            k2 = f(c1, y + hh * k1)
            k3 = f(c1, y + hh * k2)
            k4 = f(c2, y + hs * k3)
            y = y + hs * sixth * (k1 + two * (k2 + k3) + k4)
        out[k] = y.T
    bad = ~np.isfinite(out).all(axis=2)
    out[np.maximum.accumulate(bad, axis=0)] = np.nan
    return out


@dataclass(frozen=True)
class FloatStudy:
    """Section error against ``k`` of RK4 in float64, float32 and float32 with a float64 clock.

    ``error[variant]`` is ``(periods,)``: the largest relative error over the ICs
    against a float64 DOP853 reference at 1e-13, on regular orbits and on the chaotic
    attractor of Fig. 8B (``chaotic_error``: there the question is how soon it diverges;
    ``chaos_steps`` = 4 ``steps``, so that RK4's truncation is below float32's rounding).
    """

    regular_ics: np.ndarray
    steps: int
    chaos_steps: int
    error: dict[str, np.ndarray]
    chaotic_error: dict[str, np.ndarray]
    seconds: dict[str, float]

    def summary(self) -> dict[str, Any]:
        def at(arr: np.ndarray, k: int) -> float | None:
            return _r(float(arr[min(k, arr.size) - 1]), 3)

        def growth(arr: np.ndarray) -> float | None:
            k = np.arange(1, arr.size + 1)
            sel = k >= max(2, arr.size // 10)
            return _r(_fit_power(k[sel], arr[sel])[1], 3)

        n = next(iter(self.error.values())).size
        marks = sorted({1, 10, max(1, n // 10), n})
        return {
            "scene": DRIFT_SCENE + " islands",
            "ics": self.regular_ics.tolist(),
            "steps_per_period": self.steps,
            "periods": n,
            "regular": {
                name: {"error_at": {str(k): at(e, k) for k in marks}, "growth_exponent": growth(e)}
                for name, e in self.error.items()
            },
            "chaotic": {
                "scene": ATTRACTOR_SCENE,
                "reference": f"float64 DOP853 {REF_TOL:g}",
                "steps_per_period": self.chaos_steps,
                "periods_to_error_1e-3": {
                    name: (int(np.argmax(e > 1e-3)) + 1 if np.any(e > 1e-3) else None)
                    for name, e in self.chaotic_error.items()
                },
            },
            "seconds": {k: round(v, 2) for k, v in self.seconds.items()},
            "kernels_use": "float64 only",
        }


FLOAT_VARIANTS = {
    "float64": (np.float64, None),
    "float32": (np.float32, None),
    "float32, float64 clock": (np.float32, np.float64),
}


def float_precision(size: str | Size = "full", cancel: Cancel | None = None) -> FloatStudy:
    """What float32 would cost: RK4 in numpy, float32 against float64, regular and chaotic orbits."""
    sz = get_size(size)
    params = get_scene(DRIFT_SCENE).params
    ics = np.array(ISLAND_ICS[:4])
    ref = section(params, ics, sz.float_periods, numerics=Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL))
    ref_pts = np.transpose(ref.points, (1, 0, 2))  # (periods, n, 2)
    err, chaotic, secs = {}, {}, {}
    cparams = get_scene(ATTRACTOR_SCENE).params
    cics = attractor_ensemble(cparams, ATTRACTOR_IC, 4, transient=100, offset=1e-3)
    cref = section(
        cparams, cics, sz.float_chaos_periods, numerics=Numerics(method="dop853", rtol=REF_TOL, atol=REF_TOL)
    )
    cref_pts = np.transpose(cref.points, (1, 0, 2))
    for name, (dt, clock) in FLOAT_VARIANTS.items():
        if cancel is not None and cancel():
            break
        t = time.perf_counter()
        pts = rk4_numpy(params, ics, sz.float_periods, sz.float_steps, dt, clock).astype(float)
        secs[name] = time.perf_counter() - t
        err[name] = np.max(relative_error(pts, ref_pts), axis=1)
        cp = rk4_numpy(cparams, cics, sz.float_chaos_periods, 4 * sz.float_steps, dt, clock).astype(float)
        chaotic[name] = np.nan_to_num(np.max(relative_error(cp, cref_pts), axis=1), nan=np.inf)
    return FloatStudy(ics, sz.float_steps, 4 * sz.float_steps, err, chaotic, secs)


# ---------------------------------------------------------------------------
# 5. Lyapunov exponents against method and tolerance.


@dataclass(frozen=True)
class LyapunovSensitivity:
    """Exponents of Fig. 8B for each numerical setting, with the ensemble's standard error."""

    settings: list[str]
    results: list[LyapunovResult]
    reference: str

    def rows(self) -> list[dict[str, Any]]:
        ref = self.results[self.settings.index(self.reference)]
        rm, rs = ref.mean(), _sem(ref)
        out = []
        for name, res in zip(self.settings, self.results, strict=True):
            m, s = res.mean(), _sem(res)
            ok = int(res.ok.sum())
            labels = res.status_labels()
            comb = np.sqrt(s**2 + rs**2)
            dev = (m - rm) / np.where(comb > 0, comb, np.inf)
            out.append(
                {
                    "setting": name,
                    "L1": _r(float(m[0]), 5) if ok else None,
                    "L1_sem": _r(float(s[0]), 2) if ok else None,
                    "L2": _r(float(m[1]), 5) if ok else None,
                    "L2_sem": _r(float(s[1]), 2) if ok else None,
                    "L1_minus_ref_in_sigma": _r(float(dev[0]), 2) if ok else None,
                    "L2_minus_ref_in_sigma": _r(float(dev[1]), 2) if ok else None,
                    "sum_minus_divergence": _r(float(m.sum() - res.divergence()), 2) if ok else None,
                    "kaplan_yorke": _r(res.kaplan_yorke(), 4) if ok else None,
                    "members_ok": ok,
                    "statuses": {lab: labels.count(lab) for lab in sorted(set(labels))},
                    "steps_per_period": _r(float(res.nsteps.mean()) / (res.periods + res.transient), 3),
                    "seconds": round(res.elapsed_s, 2),
                }
            )
        return out

    def summary(self) -> dict[str, Any]:
        rows = self.rows()
        l1 = [r["L1"] for r in rows if r["L1"] is not None]
        ref = self.results[self.settings.index(self.reference)]
        return {
            "scene": ATTRACTOR_SCENE,
            "ic": list(ATTRACTOR_IC),
            "members": int(ref.ics.shape[0]),
            "periods": ref.periods,
            "transient": ref.transient,
            "reference": self.reference,
            "rows": rows,
            "L1_spread": {"min": min(l1), "max": max(l1)} if l1 else None,
        }


def _sem(res: LyapunovResult) -> np.ndarray:
    n = int(res.ok.sum())
    return res.spread() / math.sqrt(n) if n > 1 else np.zeros(2)


def lyapunov_settings(sz: Size) -> list[tuple[str, Numerics]]:
    out = [(f"rk4 N={n}", Numerics(method="rk4", steps_per_period=n)) for n in sz.lyap_rk4]
    out += [(f"dp5 {t:g}", Numerics(method="dp5", rtol=t, atol=t)) for t in sz.lyap_dp5]
    out += [(f"dop853 {t:g}", Numerics(method="dop853", rtol=t, atol=t)) for t in sz.lyap_dop853]
    return out


def lyapunov_sensitivity(size: str | Size = "full", cancel: Cancel | None = None) -> LyapunovSensitivity:
    """Exponents of the strange attractor of Fig. 8B for RK4 at several steps, DP5/DOP853 at several tolerances.

    Every setting starts from the same ensemble on the attractor (placed by DOP853 at
    1e-12); the exponents are finite-time averages, so settings differ by the
    ensemble's standard error at least -- deviations are reported in those units.
    """
    sz = get_size(size)
    params = get_scene(ATTRACTOR_SCENE).params
    ics = attractor_ensemble(params, ATTRACTOR_IC, sz.lyap_members, transient=1000, offset=1e-3,
                             numerics=Numerics(method="dop853", rtol=1e-12, atol=1e-12))  # fmt: skip
    settings = lyapunov_settings(sz)
    names, results = [], []
    for name, num in settings:
        if cancel is not None and cancel():
            break
        res = lyapunov_spectrum(params, ics, sz.lyap_periods, transient=sz.lyap_transient, numerics=num)
        names.append(name)
        results.append(res)
    tightest = [n for n in names if n.startswith("dop853")]
    return LyapunovSensitivity(names, results, tightest[-1] if tightest else names[-1])


# ---------------------------------------------------------------------------
# Everything.


@dataclass
class FailureMap:
    """All the studies at one size, with timings."""

    size: str
    rk4: Rk4Drift | None = None
    cost: AdaptiveCost | None = None
    scenarios: list[Scenario] = field(default_factory=list)
    collapse: dict[str, Any] = field(default_factory=dict)
    floats: FloatStudy | None = None
    lyapunov: LyapunovSensitivity | None = None
    timings: dict[str, float] = field(default_factory=dict)
    completed: bool = True

    def summary(self) -> dict[str, Any]:
        return {
            "size": self.size,
            "rk4_on_drift": self.rk4.summary() if self.rk4 else None,
            "adaptive_cost": self.cost.summary() if self.cost else None,
            "status_scenarios": [s.as_dict() for s in self.scenarios],
            "step_collapse_onset": self.collapse or None,
            "float_precision": self.floats.summary() if self.floats else None,
            "lyapunov_sensitivity": self.lyapunov.summary() if self.lyapunov else None,
            "timings_s": {k: round(v, 2) for k, v in self.timings.items()},
            "completed": self.completed,
        }


STAGES = ("rk4", "cost", "scenarios", "floats", "lyapunov")


def failure_map(
    size: str | Size = "full",
    *,
    stages: Sequence[str] | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> FailureMap:
    """Run the studies (all, or ``stages`` of :data:`STAGES`) at ``size``; ``progress(stage, seconds)`` after each."""
    sz = get_size(size)
    stages = check_stages(stages or None, STAGES)
    fm = FailureMap(sz.name)

    def stop() -> bool:
        return cancel is not None and bool(cancel())

    runs: dict[str, Callable[[], None]] = {
        "rk4": lambda: setattr(fm, "rk4", rk4_on_drift(sz, stop)),
        "cost": lambda: setattr(fm, "cost", adaptive_cost(sz, stop)),
        "scenarios": lambda: fm.__dict__.update(scenarios=status_scenarios(stop), collapse=collapse_onset()),
        "floats": lambda: setattr(fm, "floats", float_precision(sz, stop)),
        "lyapunov": lambda: setattr(fm, "lyapunov", lyapunov_sensitivity(sz, stop)),
    }
    fm.completed = run_stages([(name, runs[name]) for name in stages], fm.timings, progress, stop)
    return fm
