"""Work-precision benchmark: error against an independent reference, and wall time, for our
integrators and for the tools a user would otherwise reach for, measured side by side in one run.

Cases
-----
Picked from ``scenes.json`` so that each stresses the integrators differently:

``regular``
    fig1C (compact motion), the scene's first seeded random initial condition
    ``(0.0709, -2.2595)``: a quasi-periodic orbit on an invariant curve (finite-time exponent
    ~0.0006 over 400 periods, separation of neighbours grows only linearly). Error grows linearly
    with k, so it is measured over 200 periods. This is the workload of the README's targets.
``chaotic``
    fig1C again (same field, same cost per step), its 4th seeded random IC ``(2.6919, 2.1991)``:
    it wanders over the chaotic sea around the islands (exponent ~0.057 per unit time).
``attractor``
    fig8B, the paper's strange attractor (exponents 0.082, -0.385): the scene's first seeded IC
    carried through the scene's 100-period transient (dop853, 1e-12), rounded to 6 digits, so the
    case starts on the attractor.
``drift``
    fig1A from ``(0, 8)``, the paper's Fig. 3 trajectory. Its first ~120 periods are transient chaos
    (neighbours separate by 1e11), which would leave a pointwise error nothing to measure; from
    k = 150 it rides the noncompact attractive curve (q -> -0.30, r falls by ~0.3 per period, so the
    rotation and the steps per period grow). The case starts at that point, ``(0.750728, -17.75087)``
    (dop853 1e-13, rounded), and runs 200 periods along the drift (r reaches ~ -81).

Reference and horizon
---------------------
The reference of one initial condition is ``scipy.integrate.solve_ivp(DOP853, rtol = atol = 3e-14)``
(near scipy's floor of 100 eps) integrated period by period so it lands exactly on every section
time. It is cross-checked against our DOP853 tableau at *fixed* steps (no error control; a different
step sequence and implementation) with ``N`` and ``2N`` steps per period, ``N`` ~ 3x the reference's
mean steps. The reference's error bound is ``max_k |ref - fixed_2N| + |fixed_N - fixed_2N|``: at
3x the steps DOP853's truncation error is ~3^8 times smaller than the reference's, so the check is
limited by round-off, which the second term measures. References are cached on disk
(``~/.cache/bilimovich/bench``, or ``$BILIMOVICH_CACHE_DIR/bench``, or ``cache_dir``).

Error is ``max_k |x_k - x_ref_k|`` (Euclidean in (q, r)) over section points k = 1..K. On chaotic
orbits any error is amplified like ``exp(lambda t)`` until it saturates at the size of the sea, after
which the number measures nothing. So K is the horizon: the largest k <= ``k_max`` at which the
amplification of an initial perturbation (two directions, delta = 1e-8, our dop853 at 1e-12)
stays below ``amp_max`` = 1e3 for every measured member. There errors of 1e-3 tolerances are not
yet saturated and the reference's bound (~1e-14 x amplification) is far below what we measure.
Regular and drifting orbits amplify only linearly and keep ``k_max`` = 200.

Timing
------
Medians of ``repeat`` runs (one run when a run takes longer than 2 s). *single*: each measured
initial condition alone, one worker and ``block=1`` (one step sequence each), like the peers.
*batch*: ``batch`` initial conditions in a small cloud around the case's one (measured members
first), the default lock-step block kernel on every core. Peers, each given the simplest field for the
scene, the form its user would write (:func:`peer_fields`; the closed form for a diagonal tensor, the
multiplier form otherwise): ``solve_ivp`` (RK45, DOP853, LSODA) with a plain Python function of
``(t, q, r)`` (:func:`user_field`), ``numbalsoda`` (LSODA, DOP853) with the same function as a numba
``cfunc``, both with ``t_eval`` at the section times, and ``heyoka`` (Taylor's method, LLVM JIT; optional
like numbalsoda) on the closed form, or the model's general tables for a full tensor, as expressions
(:func:`_heyoka_system`), compiled outside the timings,
``propagate_grid`` on the section times, one thread: ``heyoka:taylor`` one initial condition at a time,
``heyoka:batch`` the batch cloud in SIMD batches of :data:`HEYOKA_BATCH`;
a peer's tolerance ladder stops once a run costs more than ``peer_budget_s`` per
trajectory.

No UI imports here; pictures are drawn by ``explorer_core.reports.render.render_work_precision``.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import hashlib
import io
import json
import math
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import Any

import numba as nb
import numpy as np
from scipy.integrate import solve_ivp

from explorer_core import config, export
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Batch, Status, advance
from explorer_core.solve.numerics import random_ics
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

#: Bumped whenever the reference computation changes (invalidates the disk cache).
REFERENCE_VERSION = 1
#: The reference: solve_ivp DOP853 at this rtol = atol (scipy's floor is 100 eps = 2.2e-14).
REF_TOL = 3e-14
#: Tolerance of the runs that measure the amplification of perturbations (the horizon).
AMP_TOL = 1e-12
CASE_NAMES = ("regular", "chaotic", "attractor", "drift")
OUR_METHODS = ("rk4", "dp5", "dop853", "vern9", "taylor")
PEERS = (
    "scipy:RK45",
    "scipy:DOP853",
    "scipy:LSODA",
    "numbalsoda:lsoda",
    "numbalsoda:dop853",
    "heyoka:taylor",
    "heyoka:batch",
)
#: heyoka's batch mode: this many trajectories per SIMD integrator (8 doubles = one AVX-512 register; on
#: narrower hardware heyoka splits the batch, so the width is the same for every machine's report).
HEYOKA_BATCH = 8
#: Perturbation used to measure the amplification of errors (the horizon).
AMP_DELTA = 1e-8
#: A run longer than this is timed once, not ``repeat`` times.
LONG_RUN_S = 2.0


# ---------------------------------------------------------------------------
# Cases and settings.


@dataclass(frozen=True)
class Case:
    """One benchmark case: a system, an initial condition, the longest horizon and a batch cloud."""

    name: str
    params: Params
    ic: tuple[float, float]
    k_max: int = 200
    cloud: float = 0.01  # radius of the batch's cloud of initial conditions around ``ic``
    scene: str = ""
    why: str = ""

    def ics(self, n: int, seed: int = 0) -> np.ndarray:
        """``n`` initial conditions: ``ic`` first, then seeded points within ``cloud`` of it."""
        rng = np.random.default_rng(seed)
        rad = self.cloud * np.sqrt(rng.uniform(0.0, 1.0, n))
        ang = rng.uniform(0.0, 2.0 * math.pi, n)
        out = np.column_stack([self.ic[0] + rad * np.cos(ang), self.ic[1] + rad * np.sin(ang)])
        out[0] = self.ic
        return out


#: Colour of each line of a work-precision diagram, by (implementation, method): the PNG and the
#: app draw the same colours.
LINE_COLOURS = {
    ("ours", "rk4"): "#9467bd",
    ("ours", "dp5"): "#2ca02c",
    ("ours", "dop853"): "#1f77b4",
    ("ours", "vern9"): "#393b79",
    ("ours", "taylor"): "#bcbd22",
    ("scipy.solve_ivp", "RK45"): "#ff7f0e",
    ("scipy.solve_ivp", "DOP853"): "#d62728",
    ("scipy.solve_ivp", "LSODA"): "#8c564b",
    ("numbalsoda", "lsoda"): "#7f7f7f",
    ("numbalsoda", "dop853"): "#e377c2",
    ("heyoka", "taylor"): "#17becf",
}


def builtin_cases(k_max: int = 200) -> dict[str, Case]:
    """The four cases of the module docstring, with horizon at most ``k_max`` periods."""
    c1 = get_scene("fig1C")
    ics1 = c1.initial_conditions()
    return {
        "regular": Case(
            "regular", c1.params, (float(ics1[0, 0]), float(ics1[0, 1])), k_max, 0.02, "fig1C",
            "quasi-periodic orbit on an invariant curve: the scene's first seeded IC",
        ),
        "chaotic": Case(
            "chaotic", c1.params, (float(ics1[3, 0]), float(ics1[3, 1])), k_max, 0.01, "fig1C",
            "chaotic sea around the islands: the scene's 4th seeded IC (exponent ~0.057)",
        ),
        "attractor": Case(
            "attractor", get_scene("fig8B").params, (-1.193619, -1.609559), k_max, 0.01, "fig8B",
            "strange attractor: the scene's first seeded IC after its 100-period transient",
        ),
        "drift": Case(
            "drift", get_scene("fig1A").params, (0.750728, -17.75087), k_max, 0.01, "fig1A",
            "noncompact drift: the trajectory from (0, 8) at k = 150, after its chaotic transient",
        ),
    }  # fmt: skip


@dataclass(frozen=True)
class BenchConfig:
    """What to measure. :func:`full_config` and :func:`quick_config` are the two presets."""

    cases: tuple[str, ...] = CASE_NAMES
    k_max: int = 200
    amp_max: float = 1e3
    rk4_steps: tuple[int, ...] = (25, 50, 100, 200, 400, 800, 1600)
    dp5_tols: tuple[float, ...] = tuple(10.0**-e for e in range(3, 13))
    dop853_tols: tuple[float, ...] = tuple(10.0**-e for e in range(3, 13))
    vern9_tols: tuple[float, ...] = tuple(10.0**-e for e in range(6, 15))
    taylor_tols: tuple[float, ...] = tuple(10.0**-e for e in range(4, 16))
    modes: tuple[str, ...] = ("single", "batch")
    peers: tuple[str, ...] = PEERS
    peer_tols: tuple[float, ...] = tuple(10.0**-e for e in range(3, 13))
    peer_budget_s: float = 20.0
    measured: int = 3  # initial conditions per case with a reference
    batch: int = 64
    repeat: int = 3
    #: Throughput and the targets: ``target_ics`` x ``target_periods`` on regular orbits (fig1C central island),
    #: the loosest of ``target_tols`` whose error on ``target_check`` regular members is <= target_error.
    throughput: bool = True
    target_ics: int = 200
    target_periods: int = 1000
    target_error: float = 1e-6
    target_check: int = 6
    target_tols: tuple[float, ...] = (1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 3e-10, 1e-10)
    #: The table of issue 22 against heyoka (:func:`heyoka_table`): ``table_ics`` random ICs in [-1, 1]^2 x
    #: ``table_periods`` periods of :data:`TABLE_PARAMS` at each of ``table_tols``, ``table_methods`` on every core.
    table: bool = True
    table_ics: int = 200
    table_periods: int = 1000
    table_tols: tuple[float, ...] = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
    table_methods: tuple[str, ...] = ("dop853", "vern9", "taylor")
    #: The chaos indicators against a long Lyapunov run (issue 34, :mod:`explorer_core.studies.indicator_bench`'s
    #: small comparison: ``indicator_ics`` ICs a set, ``indicator_reference`` periods of reference).
    indicators: bool = True
    indicator_ics: int = 6
    indicator_reference: int = 1000
    label: str = "full"

    def as_dict(self) -> dict[str, Any]:
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def validate(self) -> None:
        """Raise ParameterError naming the first bad setting."""
        if not self.cases:
            raise ParameterError(f"no bench case chosen; choose from {', '.join(CASE_NAMES)}")
        bad = [c for c in self.cases if c not in CASE_NAMES]
        if bad:
            raise ParameterError(f"unknown bench case(s) {', '.join(bad)}; choose from {', '.join(CASE_NAMES)}")
        bad = [p for p in self.peers if p not in PEERS]
        if bad:
            raise ParameterError(f"unknown peer(s) {', '.join(bad)}; choose from {', '.join(PEERS)}")
        bad = [m for m in self.modes if m not in ("single", "batch")]
        if bad:
            raise ParameterError(f"unknown mode(s) {', '.join(bad)}; choose from single, batch")
        if not 1 <= self.k_max <= 100_000 or not 1 <= self.measured <= self.batch:
            raise ParameterError(f"need 1 <= k_max <= 100000 and 1 <= measured <= batch, got {self.k_max}, "
                                 f"{self.measured}, {self.batch}")  # fmt: skip
        for name in ("dp5_tols", "dop853_tols", "vern9_tols", "taylor_tols", "peer_tols", "target_tols"):
            if any(not (1e-15 <= t <= 1.0) for t in getattr(self, name)):
                raise ParameterError(f"{name} must lie in [1e-15, 1], got {getattr(self, name)}")
        if any(not 1 <= n <= 10_000_000 for n in self.rk4_steps):
            raise ParameterError(f"rk4_steps must lie in [1, 1e7], got {self.rk4_steps}")
        if any(not (1e-15 <= t <= 1.0) for t in self.table_tols):
            raise ParameterError(f"table_tols must lie in [1e-15, 1], got {self.table_tols}")
        bad = [m for m in self.table_methods if m not in OUR_METHODS or m == "rk4"]
        if bad:
            raise ParameterError(f"table_methods must be adaptive methods of ours, got {', '.join(bad)}")
        if not (1 <= self.indicator_ics <= 100 and 100 <= self.indicator_reference <= 100_000):
            raise ParameterError(f"need 1 <= indicator_ics <= 100 and 100 <= indicator_reference <= 100000, got "
                                 f"{self.indicator_ics}, {self.indicator_reference}")  # fmt: skip
        if not (1 <= self.table_ics <= 100_000 and 1 <= self.table_periods <= 100_000):
            raise ParameterError(f"need 1 <= table_ics, table_periods <= 100000, got {self.table_ics}, "
                                 f"{self.table_periods}")  # fmt: skip


def full_config() -> BenchConfig:
    """The full run (tens of minutes the first time, references cached afterwards)."""
    return BenchConfig()


def quick_config() -> BenchConfig:
    """A small run (well under a minute once the kernels are compiled): used by the tests."""
    return BenchConfig(
        k_max=20,
        rk4_steps=(50, 200, 800),
        dp5_tols=(1e-4, 1e-6, 1e-8),
        dop853_tols=(1e-4, 1e-6, 1e-8, 1e-10),
        vern9_tols=(1e-8, 1e-12),
        taylor_tols=(1e-6, 1e-10),
        peer_tols=(1e-4, 1e-6),
        peer_budget_s=2.0,
        measured=1,
        batch=16,
        repeat=1,
        target_ics=40,
        target_periods=100,
        target_check=2,
        target_tols=(1e-6, 1e-7, 1e-8, 1e-9, 1e-10),
        table_ics=16,
        table_periods=20,
        table_tols=(1e-6, 1e-10),
        indicators=False,
        label="quick",
    )


def app_config() -> BenchConfig:
    """What the app's *Measure* button runs: a few methods and tolerances, a short horizon."""
    return BenchConfig(
        k_max=50,
        rk4_steps=(50, 100, 200, 400),
        dp5_tols=(1e-4, 1e-6, 1e-8),
        dop853_tols=(1e-4, 1e-6, 1e-8, 1e-10),
        vern9_tols=(1e-8, 1e-12),
        taylor_tols=(1e-6, 1e-10),
        peers=("scipy:DOP853",),
        peer_tols=(1e-4, 1e-6, 1e-8),
        peer_budget_s=2.0,
        measured=1,
        batch=16,
        repeat=1,
        throughput=False,
        table=False,
        indicators=False,
        label="app",
    )


@dataclass
class Row:
    """One measured point of a work-precision diagram."""

    case: str
    method: str
    implementation: str
    setting: str
    mode: str
    n_traj: int
    periods: int
    error: float | None  # None: some measured trajectory did not reach the horizon (see status)
    time_per_traj_s: float
    total_s: float
    steps_per_period: float | None = None
    evals_per_period: float | None = None
    status: str = "ok"
    tol: float | None = None
    steps: int | None = None

    @property
    def series(self) -> str:
        """The line of the diagram this point belongs to."""
        return f"{self.implementation} {self.method}" + (" batch" if self.mode == "batch" else "")

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["series"] = self.series
        return {k: _jsonable(v) for k, v in d.items()}


@dataclass
class BenchProgress:
    """Reported after each measurement."""

    text: str
    done: int
    total: int
    elapsed_s: float


# ---------------------------------------------------------------------------
# The peers' fields: one definition for every peer of `bilimovich bench`, the app's speed tab and
# benchmarks/high_accuracy.py. Each peer is given the simplest field for the scene, the form its user
# would write from the equations (PHYSICS.md), not the model's coefficient tables: for a diagonal tensor
# the paper's closed form, otherwise the multiplier form with the tensor and its inverse. The constants
# are the parameters' own numbers and ``g = g0 + g1 cos(omega t) + g2 sin(omega t)`` is taken at ``t``
# as given (a user does not reduce ``t`` to the period).


def is_diagonal(params: Params) -> bool:
    """Whether the tensor is diagonal, so the closed form of :func:`diagonal_field` applies."""
    return not any(params.inertia[3:])


def peer_constants(params: Params) -> tuple[float, ...]:
    """What the peers' fields read: ``(A, B, C, alpha, g0, g1, g2, omega)`` for a diagonal tensor; otherwise
    ``(I11, I22, I33, I12, I13, I23, J11, J22, J33, J12, J13, J23, alpha, g0, g1, g2, omega)``, ``J = I^-1``."""
    p = params
    forcing = (p.alpha, p.g0, p.g1, p.g2, p.omega)
    if is_diagonal(p):
        return tuple(float(v) for v in (*p.inertia[:3], *forcing))
    j = np.linalg.inv(p.inertia_matrix)
    inverse = (j[0, 0], j[1, 1], j[2, 2], j[0, 1], j[0, 2], j[1, 2])
    return tuple(float(v) for v in (*p.inertia, *inverse, *forcing))


def diagonal_field(t: float, q: float, r: float, k: Any) -> tuple[float, float]:
    """``(q', r')`` for ``diag(A, B, C)``: ``q' = -[alpha (A - C) r + g (A - B) q r + A g g' q] / (g^2 A + B)``,
    ``r' = (A - B)(g q + alpha) q / C`` (PHYSICS.md); ``k`` from :func:`peer_constants`."""
    a, b, c, al, g0, g1, g2, w = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7]
    cw, sw = math.cos(w * t), math.sin(w * t)
    g = g0 + g1 * cw + g2 * sw
    gp = w * (g2 * cw - g1 * sw)
    qdot = -(al * (a - c) * r + g * (a - b) * q * r + a * g * gp * q) / (g * g * a + b)
    return qdot, (a - b) * (g * q + al) * q / c


def general_field(t: float, q: float, r: float, k: Any) -> tuple[float, float]:
    """``(q', r')`` from ``I omega' = M + lambda a`` with ``omega = (alpha + g q, q, r)``, ``M = (I omega) x omega``,
    ``a = (1, -g, 0)`` and ``lambda = -[(a, J M) - g' q] / (a, J a)``, ``J = I^-1`` (PHYSICS.md); ``k`` from
    :func:`peer_constants`."""
    i11, i22, i33, i12, i13, i23 = k[0], k[1], k[2], k[3], k[4], k[5]
    j11, j22, j33, j12, j13, j23 = k[6], k[7], k[8], k[9], k[10], k[11]
    al, g0, g1, g2, w = k[12], k[13], k[14], k[15], k[16]
    cw, sw = math.cos(w * t), math.sin(w * t)
    g = g0 + g1 * cw + g2 * sw
    gp = w * (g2 * cw - g1 * sw)
    p = al + g * q
    l1, l2, l3 = i11 * p + i12 * q + i13 * r, i12 * p + i22 * q + i23 * r, i13 * p + i23 * q + i33 * r
    m1, m2, m3 = l2 * r - l3 * q, l3 * p - l1 * r, l1 * q - l2 * p
    jm1, jm2, jm3 = j11 * m1 + j12 * m2 + j13 * m3, j12 * m1 + j22 * m2 + j23 * m3, j13 * m1 + j23 * m2 + j33 * m3
    ja1, ja2, ja3 = j11 - g * j12, j12 - g * j22, j13 - g * j23
    lam = -(jm1 - g * jm2 - gp * q) / (ja1 - g * ja2)
    return jm2 + lam * ja2, jm3 + lam * ja3


def user_field(params: Params) -> Callable[[float, float, float], tuple[float, float]]:
    """``f(t, q, r) -> (q', r')`` in plain Python, the field a user writes for ``solve_ivp``: the scene's closed
    form for a diagonal tensor, the multiplier form otherwise, on the parameters' numbers."""
    fn = diagonal_field if is_diagonal(params) else general_field
    k = peer_constants(params)
    return lambda t, q, r: fn(t, q, r, k)


def scipy_rhs(model: Model) -> Callable[[float, np.ndarray], tuple[float, float]]:
    """``f(t, y)`` for ``solve_ivp``: :func:`user_field` on ``y = (q, r)`` (scipy makes the array itself)."""
    f = user_field(model.params)
    return lambda t, y: f(t, y[0], y[1])


def peer_fields(params: Params) -> dict[str, str]:
    """Each peer's field as it is given to it, by peer (what the benchmarks print)."""
    diag = is_diagonal(params)
    doc = (diagonal_field if diag else general_field).__doc__ or ""
    formula = " ".join(doc.split("(PHYSICS.md)")[0].replace("``", "").split()).strip(" ,")
    k = ", ".join(f"{v:.6g}" for v in peer_constants(params))
    plain = f"{'diagonal' if diag else 'general'}_field(t, q, r, k) in plain Python, k = ({k}): {formula}"
    out = {"scipy": plain, "numbalsoda": plain.replace("in plain Python", "as a numba cfunc")}
    hy, _ = heyoka_status()
    if hy is not None:
        sys_ = _heyoka_system(hy, params)
        out["heyoka"] = f"q' = {sys_[0][1]}; r' = {sys_[1][1]}"
    return out


def cfunc_data(model: Model) -> np.ndarray:
    """The constants of the numbalsoda ``cfunc`` (:func:`peer_constants`), as its ``data`` array."""
    return np.array(peer_constants(model.params), dtype=float)


@cache
def compiled_field(diagonal: bool) -> Any:
    """:func:`diagonal_field` or :func:`general_field` compiled by numba (numbalsoda's cfunc calls it), built on
    first use: the plain functions are the peers' fields (solve_ivp's too), and no module-level dispatcher is left
    for warm_all to compile (the benchmark's peers are not the app's kernels)."""
    return nb.njit(nogil=True, cache=True)(diagonal_field if diagonal else general_field)


@cache
def _cfunc_rhs(diagonal: bool) -> int:
    """Address of a numba ``cfunc`` with numbalsoda's signature ``(t, u, du, p)`` calling :func:`diagonal_field`
    or :func:`general_field` on ``p`` = :func:`cfunc_data`. Compiled lazily (cached on disk) so importing this
    module stays cheap."""
    dbl = nb.types.double
    sig = nb.types.void(dbl, nb.types.CPointer(dbl), nb.types.CPointer(dbl), nb.types.CPointer(dbl))
    field = compiled_field(diagonal)

    @nb.cfunc(sig, cache=True, error_model="numpy")
    def rhs(t, u, du, p):  # pragma: no cover - runs inside numbalsoda
        du[0], du[1] = field(t, u[0], u[1], p)

    return rhs.address


def numbalsoda_status() -> tuple[Any, str]:
    """``(module or None, description)``: numbalsoda is optional (sdist only, needs gfortran)."""
    try:
        import numbalsoda  # type: ignore[import-not-found]
    except Exception as exc:  # ImportError, or a broken shared library
        reason = "not installed" if isinstance(exc, ImportError) else f"{type(exc).__name__}: {exc}"
        return None, f"not available ({reason}; pip install numbalsoda builds it from source with gfortran)"
    try:
        from importlib.metadata import version

        ver = version("numbalsoda")
    except Exception:
        ver = "?"
    return numbalsoda, f"available ({ver})"


def heyoka_status() -> tuple[Any, str]:
    """``(module or None, description)``: heyoka is optional (``pip install heyoka`` has wheels)."""
    try:
        import heyoka  # type: ignore[import-not-found]
    except Exception as exc:  # ImportError, or a broken shared library (LLVM)
        reason = "not installed" if isinstance(exc, ImportError) else f"{type(exc).__name__}: {exc}"
        return None, f"not available ({reason}; pip install heyoka)"
    return heyoka, f"available ({getattr(heyoka, '__version__', '?')}, batch {HEYOKA_BATCH})"


def _heyoka_system(hy: Any, params: Params) -> list[tuple[Any, Any]]:
    """heyoka's field for ``params``: :func:`_heyoka_diagonal` for a diagonal tensor, :func:`_heyoka_tables`
    otherwise (with a full tensor the general form is the simplest)."""
    return _heyoka_diagonal(hy, params) if is_diagonal(params) else _heyoka_tables(hy, Model(params))


def _heyoka_sum(terms: list[Any]) -> Any:
    """A sum of heyoka expressions (None when there is none)."""
    return functools.reduce(lambda a, b: a + b, terms) if terms else None


def _heyoka_diagonal(hy: Any, p: Params) -> list[tuple[Any, Any]]:
    """The closed form of :func:`diagonal_field` as heyoka expressions, zero terms and unit factors left out as a
    user would: ``r' = (A - B)(g q + alpha) q / C`` has no denominator at all."""
    a, b, c = (float(v) for v in p.inertia[:3])
    q, r = hy.make_vars("q", "r")
    w = float(p.omega)
    wt = hy.time if w == 1.0 else w * hy.time
    cw, sw = hy.cos(wt), hy.sin(wt)

    def lin(*pairs: tuple[float, Any]) -> Any:
        return _heyoka_sum([e if k == 1.0 else (-e if k == -1.0 else k * e) for k, e in pairs if k != 0.0])

    g = lin((p.g1, cw), (p.g2, sw))
    g = g if p.g0 == 0.0 else (p.g0 if g is None else g + p.g0)
    gp = lin((w * p.g2, cw), (-w * p.g1, sw))
    al = float(p.alpha)
    num = _heyoka_sum([t for t in ((al * (a - c)) * r if al * (a - c) != 0.0 else None, (a - b) * g * q * r,
                                   (a * g * gp) * q if gp is not None else None) if t is not None])  # fmt: skip
    qdot = -num / (a * g * g + b)
    rdot = ((a - b) / c) * ((g * q + al) if al != 0.0 else g * q) * q
    return [(q, qdot), (r, rdot)]


def _heyoka_tables(hy: Any, model: Model) -> list[tuple[Any, Any]]:
    """The field as heyoka expressions, ``c_m = [N_m(g) + g' G_m(g)] / D(g)`` on the model's own tables.

    The table entries are numbers in the expressions (as a user writes a field for heyoka), so heyoka's
    compiler folds the zero entries away: one compiled integrator per model, tolerance and batch width.
    """
    q, r = hy.make_vars("q", "r")
    f = [float(v) for v in model.forcing]
    w = f[3]
    cw, sw = hy.cos(w * hy.time), hy.sin(w * hy.time)

    def lin(a: float, x: Any, b: float, y: Any) -> Any:
        terms = [c * e for c, e in ((a, x), (b, y)) if c != 0.0]
        return sum(terms[1:], terms[0]) if terms else None

    g = lin(f[1], cw, f[2], sw)
    g = f[0] if g is None else (g + f[0] if f[0] != 0.0 else g)
    gp = lin(w * f[2], cw, -w * f[1], sw)

    def poly(coefs: Sequence[float]) -> Any:
        # sum_j coefs[j] g^j by Horner, zero coefficients skipped
        out: Any = 0.0
        for c in reversed([float(v) for v in coefs]):
            out = out * g if not (isinstance(out, float) and out == 0.0) else out
            if c != 0.0:
                out = out + c if not (isinstance(out, float) and out == 0.0) else hy.expression(c)
        return out

    den = poly(model.den)
    mono = (None, q, r, q * q, q * r, r * r)
    rhs = []
    for row in range(2):
        total: Any = 0.0
        for m in range(6):
            c = poly(model.num[row, m])
            if m == 1 and gp is not None and (model.gpc[row, 0] != 0.0 or model.gpc[row, 1] != 0.0):
                c = c + gp * poly(model.gpc[row])
            if isinstance(c, float) and c == 0.0:
                continue
            term = c if mono[m] is None else c * mono[m]
            total = term if isinstance(total, float) else total + term
        rhs.append(total / den)
    return [(q, rhs[0]), (r, rhs[1])]


@functools.lru_cache(maxsize=128)
def _heyoka_integrator(params: Params, tol: float, batch: int, tables: bool = False) -> Any:
    """One compiled heyoka integrator per model, tolerance and batch width (0: scalar) on :func:`_heyoka_system`
    (``tables``: on the model's general tables, :func:`_heyoka_tables`); compiled outside the timings."""
    hy, _ = heyoka_status()
    sys_ = _heyoka_tables(hy, Model(params)) if tables else _heyoka_system(hy, params)
    if batch == 0:
        return hy.taylor_adaptive(sys_, [0.0, 0.0], tol=tol)
    return hy.taylor_adaptive_batch(sys_, np.zeros((2, batch)), tol=tol)


def _peer_heyoka(model: Model, ics: np.ndarray, periods: int, mode: str, tol: float, tables: bool = False):
    """heyoka at ``tol``: each IC alone (``single``) or SIMD batches of :data:`HEYOKA_BATCH` (``batch``), one thread.

    ``propagate_grid`` on the section times (heyoka's dense output lands on them); the rhs of :func:`_heyoka_system`
    (``tables``: of :func:`_heyoka_tables`, the general form, for checks).
    """
    p = model.params
    grid = p.t0 + p.period * np.arange(0, periods + 1)
    pts, ok, msgs = [], [], []
    if mode == "single":
        ta = _heyoka_integrator(p, float(tol), 0, tables)
        for ic in ics:
            ta.time = p.t0
            ta.state[:] = ic
            oc, *_, states = ta.propagate_grid(grid)
            good = "time_limit" in str(oc) and states.shape[0] == grid.size and bool(np.all(np.isfinite(states)))
            ok.append(good)
            if not good:
                msgs.append(f"heyoka: {oc}")
            pts.append(states[1:])
        return pts, ok, None, msgs
    nb_ = HEYOKA_BATCH
    tb = _heyoka_integrator(p, float(tol), nb_, tables)
    bgrid = np.ascontiguousarray(np.repeat(grid[:, None], nb_, axis=1))
    for b0 in range(0, ics.shape[0], nb_):
        chunk = ics[b0 : b0 + nb_]
        state = np.repeat(chunk[-1:], nb_, axis=0)  # a partial last batch repeats its last member
        state[: chunk.shape[0]] = chunk
        tb.set_time(np.full(nb_, p.t0))
        tb.state[:] = state.T
        _, states = tb.propagate_grid(bgrid)
        outcomes = [str(res[0]) for res in tb.propagate_res]
        for i in range(chunk.shape[0]):
            good = "time_limit" in outcomes[i] and bool(np.all(np.isfinite(states[:, :, i])))
            ok.append(good)
            if not good:
                msgs.append(f"heyoka: {outcomes[i]}")
            pts.append(states[1:, :, i])
    return pts, ok, None, msgs


# ---------------------------------------------------------------------------
# The ceiling: the engine's lock-step arithmetic with nothing else.


def run_ceiling(model: Model, ics: np.ndarray, periods: int, steps_per_period: int, block: int = 0) -> np.ndarray:
    """DOP853's stages at fixed steps on blocks of ``block`` trajectories in lock-step; returns the end states.

    The engine (:mod:`explorer_core.solve.rk`) with no error control, step rejection or stored points and an
    infinite escape bound: the arithmetic of the lock-step block and its bookkeeping of live members only,
    on one thread -- the speed the adaptive sections could reach if they needed no error control.
    """
    batch = Batch.start(np.asarray(ics, dtype=float), model.params.t0, model.params.period)
    advance(model, batch, int(periods), method="dop853", adaptive=False, steps_per_period=int(steps_per_period),
            bound=math.inf, store=False, workers=1, block=int(block or config.BLOCK_SIZE))  # fmt: skip
    return batch.y


def warmup() -> None:
    """Compile (or load from the cache) the engine and, if numbalsoda is there, the cfunc rhs."""
    model = Model(Params())
    run_ceiling(model, np.array([[0.1, 0.2], [0.2, 0.1]]), 1, 4)
    mod, _ = numbalsoda_status()
    if mod is not None:
        _cfunc_rhs(True)
        _cfunc_rhs(False)


# ---------------------------------------------------------------------------
# References, amplification, horizon.


def cache_dir(path: str | os.PathLike[str] | None = None) -> str:
    """Where references are cached: ``path``, or ``$BILIMOVICH_CACHE_DIR/bench``, or ``~/.cache/bilimovich/bench``."""
    if path:
        return os.fspath(path)
    root = os.environ.get("BILIMOVICH_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "bilimovich")
    return os.path.join(root, "bench")


@dataclass
class Reference:
    """The reference section points of one initial condition, with its error bound."""

    ic: np.ndarray
    periods: int  # section points available (may be fewer than asked if the orbit escapes)
    points: np.ndarray  # (periods, 2): solve_ivp DOP853 at REF_TOL, period by period
    check: np.ndarray  # (periods, 2): our DOP853 tableau at 2N fixed steps per period
    check_half: np.ndarray  # (periods, 2): the same at N steps
    fixed_steps: int  # 2N
    ref_steps_per_period: float
    bound: float  # max_k |points - check| + |check_half - check|
    elapsed_s: float
    cache_hit: bool = False
    status: str = "ok"

    def bound_k(self) -> np.ndarray:
        """The bound per section point (running maximum)."""
        b = np.linalg.norm(self.points - self.check, axis=1) + np.linalg.norm(self.check_half - self.check, axis=1)
        return np.maximum.accumulate(b) if b.size else b


def _ref_key(params: Params, ic: np.ndarray, periods: int, bound: float) -> str:
    blob = json.dumps(
        {"v": REFERENCE_VERSION, "params": params.as_dict(), "ic": [float(v).hex() for v in ic],
         "periods": int(periods), "tol": REF_TOL, "bound": bound},
        sort_keys=True,
    )  # fmt: skip
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def reference(
    params: Params,
    ic: Sequence[float],
    periods: int,
    *,
    cache_dir_: str | os.PathLike[str] | None = None,
    use_cache: bool = True,
    bound: float = config.DEFAULT_ESCAPE_BOUND,
) -> Reference:
    """The reference of ``ic`` over ``periods`` periods, from the disk cache if it is there."""
    ic = np.asarray(ic, dtype=float).reshape(2)
    key = _ref_key(params, ic, periods, bound)
    directory = cache_dir(cache_dir_)
    path = os.path.join(directory, f"{key}.npz")
    if use_cache and os.path.exists(path):
        try:
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
                return Reference(ic=ic, points=z["points"], check=z["check"], check_half=z["check_half"],
                                 cache_hit=True, **meta)  # fmt: skip
        except Exception:  # a truncated or foreign file: recompute and overwrite
            pass
    ref = _compute_reference(params, ic, periods, bound)
    if use_cache:
        os.makedirs(directory, exist_ok=True)
        meta = {k: getattr(ref, k) for k in ("periods", "fixed_steps", "ref_steps_per_period", "bound", "elapsed_s",
                                             "status")}  # fmt: skip
        # Write then rename: a concurrent reader never sees half a file.
        fd, tmp = tempfile.mkstemp(dir=directory, suffix=".npz.tmp")
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, points=ref.points, check=ref.check, check_half=ref.check_half, meta=json.dumps(meta))
        os.replace(tmp, path)
    return ref


def _compute_reference(params: Params, ic: np.ndarray, periods: int, bound: float) -> Reference:
    start = time.perf_counter()
    model = Model(params)
    f = scipy_rhs(model)
    pts = np.empty((periods, 2))
    y = ic.copy()
    nfev = 0
    got = 0
    status = "ok"
    for k in range(periods):
        ta = params.t0 + k * params.period
        tb = params.t0 + (k + 1) * params.period
        sol = solve_ivp(f, (ta, tb), y, method="DOP853", rtol=REF_TOL, atol=REF_TOL)
        nfev += sol.nfev
        if sol.status != 0 or not np.all(np.isfinite(sol.y[:, -1])):
            status = f"reference failed at k = {k + 1}: {sol.message}"
            break
        y = sol.y[:, -1].copy()
        if np.max(np.abs(y)) > bound:
            status = f"escaped at k = {k + 1}"
            break
        pts[k] = y
        got = k + 1
    pts = pts[:got]
    mean_steps = nfev / 12.0 / max(1, got)
    n_half = int(8 * math.ceil(3.0 * max(8.0, mean_steps) / 8))
    checks = []
    for n in (n_half, 2 * n_half):
        b = Batch.start(ic.reshape(1, 2), params.t0, params.period)
        out, npts = advance(model, b, max(1, got), method="dop853", adaptive=False, steps_per_period=n, workers=1,
                            block=1, bound=math.inf)  # fmt: skip
        c = np.full((got, 2), np.nan)
        m = min(got, int(npts[0]))
        c[:m] = out[0, :m]
        checks.append(c)
    ref = Reference(ic=ic, periods=got, points=pts, check=checks[1], check_half=checks[0], fixed_steps=2 * n_half,
                    ref_steps_per_period=round(mean_steps, 2), bound=0.0, elapsed_s=0.0, status=status)  # fmt: skip
    bk = ref.bound_k()
    ref.bound = float(bk[-1]) if bk.size and np.isfinite(bk[-1]) else math.inf
    ref.elapsed_s = round(time.perf_counter() - start, 3)
    return ref


def amplification(params: Params, ics: np.ndarray, periods: int, delta: float = AMP_DELTA) -> np.ndarray:
    """``A[i, k]``: growth of a perturbation of size ``delta`` of ``ics[i]`` after k + 1 periods.

    Two perturbation directions (q and r), the larger kept; our dop853 at ``AMP_TOL``, one step
    sequence each. NaN after a trajectory fails (escapes).
    """
    ics = np.asarray(ics, dtype=float).reshape(-1, 2)
    n = ics.shape[0]
    all_ics = np.concatenate([ics, ics + np.array([delta, 0.0]), ics + np.array([0.0, delta])])
    b = Batch.start(all_ics, params.t0, params.period)
    out, npts = advance(Model(params), b, periods, method="dop853", rtol=AMP_TOL, atol=AMP_TOL, workers=None, block=1)
    amp = np.full((n, periods), np.nan)
    for i in range(n):
        m = int(min(npts[i], npts[n + i], npts[2 * n + i]))
        d1 = np.linalg.norm(out[n + i, :m] - out[i, :m], axis=1)
        d2 = np.linalg.norm(out[2 * n + i, :m] - out[i, :m], axis=1)
        amp[i, :m] = np.maximum(d1, d2) / delta
    return amp


def regular_members(amp: np.ndarray, amp_max: float = 1e3) -> list[int]:
    """Rows of :func:`amplification` whose perturbation never failed and stayed below ``amp_max`` (regular orbits)."""
    return [i for i in range(amp.shape[0]) if np.all(np.isfinite(amp[i])) and np.max(amp[i]) < amp_max]


def horizon(amp: np.ndarray, amp_max: float, k_max: int) -> int:
    """Largest K <= k_max such that every member's amplification stays <= amp_max up to K (at least 1)."""
    a = np.atleast_2d(amp)[:, :k_max]
    worst = np.max(np.where(np.isnan(a), np.inf, a), axis=0)
    above = np.flatnonzero(np.maximum.accumulate(worst) > amp_max)
    return max(1, int(above[0]) if above.size else int(a.shape[1]))


# ---------------------------------------------------------------------------
# Measurements.


def _error(points: np.ndarray, npts: int, ref: np.ndarray) -> float | None:
    k = ref.shape[0]
    if npts < k:
        return None
    return float(np.max(np.linalg.norm(points[:k] - ref, axis=1)))


def _timed(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Median wall time of ``repeat`` calls (one if a call is long) and the last result."""
    times = []
    out = None
    for _ in range(max(1, repeat)):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
        if times[-1] > LONG_RUN_S:
            break
    return statistics.median(times), out


def _status_text(codes: Sequence[int]) -> str:
    labels = [Status(int(s)).label for s in codes]
    counts = {lab: labels.count(lab) for lab in sorted(set(labels))}
    if list(counts) == ["ok"]:
        return "ok"
    return ", ".join(f"{k} {v}" for k, v in counts.items())


#: Right-hand-side evaluations per step (Taylor's method has none: a step costs O(order^2) series products).
_STAGES = {"rk4": 4, "dp5": 6, "dop853": 12, "vern9": 16, "taylor": None}


def _ours(
    model: Model, ics: np.ndarray, periods: int, method: str, setting: float, mode: str, repeat: int
) -> tuple[float, list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """Time our method; returns (median seconds, per-IC points, npts, status, nsteps)."""
    kw: dict[str, Any] = {"method": method}
    if method == "rk4":
        kw["steps_per_period"] = int(setting)
    else:
        kw["rtol"] = kw["atol"] = float(setting)
    p = model.params
    if mode == "single":

        def run() -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
            pts, npts, st, ns = [], [], [], []
            for ic in ics:
                b = Batch.start(ic.reshape(1, 2), p.t0, p.period)
                out, n = advance(model, b, periods, workers=1, block=1, **kw)
                pts.append(out[0])
                npts.append(int(n[0]))
                st.append(int(b.status[0]))
                ns.append(int(b.nsteps[0]))
            return pts, np.array(npts), np.array(st), np.array(ns)

    else:

        def run() -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
            b = Batch.start(ics, p.t0, p.period)
            out, n = advance(model, b, periods, **kw)  # default block kernel, every worker
            return list(out), n, b.status.copy(), b.nsteps.copy()

    sec, (pts, npts, st, ns) = _timed(run, repeat)
    return sec, pts, npts, st, ns


def _peer_scipy(model: Model, ics: np.ndarray, periods: int, method: str, tol: float):
    p = model.params
    f = scipy_rhs(model)
    t_eval = p.t0 + p.period * np.arange(1, periods + 1)
    pts, ok, nfev, msgs = [], [], 0, []
    for ic in ics:
        sol = solve_ivp(f, (p.t0, t_eval[-1]), ic, method=method, rtol=tol, atol=tol, t_eval=t_eval)
        nfev += sol.nfev
        good = sol.status == 0 and sol.y.shape[1] == periods
        ok.append(good)
        if not good:
            msgs.append(str(sol.message)[:80])
        y = np.full((periods, 2), np.nan)
        y[: sol.y.shape[1]] = sol.y.T
        pts.append(y)
    return pts, ok, nfev, msgs


def _peer_numbalsoda(mod: Any, model: Model, ics: np.ndarray, periods: int, method: str, tol: float):
    p = model.params
    t_eval = p.t0 + p.period * np.arange(0, periods + 1)
    data = cfunc_data(model)
    addr = _cfunc_rhs(is_diagonal(p))
    solver = mod.lsoda if method == "lsoda" else mod.dop853
    pts, ok, msgs = [], [], []
    for ic in ics:
        usol, success = solver(addr, np.array(ic, dtype=float), t_eval, data=data, rtol=tol, atol=tol,
                               mxstep=10_000_000)  # fmt: skip
        good = bool(success) and np.all(np.isfinite(usol))
        ok.append(good)
        if not good:
            msgs.append("failed")
        pts.append(usol[1:])
    return pts, ok, None, msgs


def _fmt_setting(method: str, v: float) -> str:
    return f"steps={int(v)}" if method == "rk4" else f"tol={v:.0e}"


@dataclass
class CaseInfo:
    """What a case measured against: the horizon and the reference."""

    name: str
    scene: str
    why: str
    ic: tuple[float, float]
    k_max: int
    horizon: int
    amp_at_horizon: float
    amp_at_k_max: float
    measured_ics: list[list[float]]
    batch: int
    reference_bound: float
    reference_steps_per_period: float
    reference_fixed_steps: int
    reference_elapsed_s: float
    cache_hits: int
    cache_misses: int
    notes: list[str] = field(default_factory=list)
    #: Each peer's field as it is given to it (:func:`peer_fields`).
    peer_fields: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {k: _jsonable(v) for k, v in dataclasses.asdict(self).items()}


@dataclass
class BenchResult:
    """Rows, per-case horizon and reference information, throughput and ratios."""

    config: BenchConfig
    rows: list[Row] = field(default_factory=list)
    cases: dict[str, CaseInfo] = field(default_factory=dict)
    throughput: dict[str, Any] = field(default_factory=dict)
    ratios: dict[str, Any] = field(default_factory=dict)
    peers: dict[str, str] = field(default_factory=dict)
    machine: dict[str, Any] = field(default_factory=dict)
    #: The chaos indicators' comparison (:func:`explorer_core.studies.indicator_bench.measure`), if it ran.
    indicators: dict[str, Any] = field(default_factory=dict)
    elapsed_s: float = 0.0
    completed: bool = True

    def rows_for(self, case: str) -> list[Row]:
        return [r for r in self.rows if r.case == case]

    def series(self, case: str) -> dict[str, list[Row]]:
        """Rows of one case grouped into diagram lines, in the order of their settings (loose to tight)."""
        out: dict[str, list[Row]] = {}
        for r in self.rows_for(case):
            out.setdefault(r.series, []).append(r)
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "version": 1,
            "config": self.config.as_dict(),
            "machine": self.machine,
            "peers": self.peers,
            "cases": {k: v.as_dict() for k, v in self.cases.items()},
            "rows": [r.as_dict() for r in self.rows],
            "throughput": _jsonable(self.throughput),
            "ratios": _jsonable(self.ratios),
            "indicators": _jsonable(self.indicators),
            "elapsed_s": round(self.elapsed_s, 2),
            "completed": self.completed,
        }

    def headline(self) -> str:
        """A few lines for the terminal: horizons, the targets and the ratios."""
        out = []
        for c in self.cases.values():
            out.append(f"{c.name}: horizon {c.horizon}/{c.k_max} periods, reference bound {c.reference_bound:.1e}")
            peers = {p.split(":")[0] for p in self.config.peers}
            out += [f"  {peer}'s field: {text}" for peer, text in c.peer_fields.items() if peer in peers]
        tgt = self.throughput.get("target", {})
        if tgt.get("wall_s") is not None:
            out.append(f"target: {tgt['what']}: {tgt['wall_s']:.3f} s at tol {tgt['tol']:g} "
                       f"(error {tgt['error_on_regular_members']:.1e} on regular members; goal 0.5 s)")  # fmt: skip
        par = self.throughput.get("parallel", {})
        if par:
            out.append(f"parallel efficiency: {par['efficiency']:.0%} (speedup {par['speedup']:.2f})")
        ker = self.throughput.get("kernel", {})
        if ker:
            out.append(f"batch kernel: {ker['percent_of_ceiling_1_worker']:.0f}% of the lock-step ceiling (goal 30%)")
        for k, v in self.ratios.items():
            if " / " in k:
                out.append(f"{k} at the same error: {'n/a' if v is None else f'{v:g}x'}")
        if "heyoka_table" in self.throughput:
            out.append(heyoka_table_markdown(self.throughput["heyoka_table"]).rstrip("\n"))
        if self.indicators:
            from explorer_core.studies.indicator_bench import table

            out.append(table(self.indicators))
        return "\n".join(out)

    def csv_text(self) -> str:
        cols = ["case", "method", "implementation", "setting", "mode", "n_traj", "periods", "error",
                "time_per_traj_s", "total_s", "steps_per_period", "evals_per_period", "status"]  # fmt: skip
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for r in self.rows:
            d = r.as_dict()
            w.writerow(["" if d[c] is None else d[c] for c in cols])
        return buf.getvalue()

    def markdown(self) -> str:
        """The report as Markdown (see :func:`markdown_report`)."""
        return markdown_report(self.as_dict())

    def write(self, outdir: str) -> list[str]:
        """bench.json, bench.csv, bench.md and throughput.json in ``outdir`` (the PNG: explorer_core.reports.render)."""
        os.makedirs(outdir, exist_ok=True)
        names = ("bench.json", "bench.csv", "bench.md", "throughput.json")
        paths = {name: os.path.join(outdir, name) for name in names}
        export.write_text(paths["bench.json"], json.dumps(self.as_dict(), indent=1))
        export.write_text(paths["bench.csv"], self.csv_text())
        export.write_text(paths["bench.md"], self.markdown())
        export.write_text(paths["throughput.json"], json.dumps({"throughput": _jsonable(self.throughput),
                          "ratios": _jsonable(self.ratios), "machine": self.machine}, indent=1))  # fmt: skip
        return list(paths.values())


def markdown_report(data: dict[str, Any], rows: bool = True) -> str:
    """Markdown of a bench.json dict: cases, time to reach the target error, ratios, throughput, rows."""
    cfg = data.get("config", {})
    mach = data.get("machine", {})
    target = float(cfg.get("target_error", 1e-6))
    out = [f"# Work-precision benchmark ({cfg.get('label', '?')})", ""]
    out += [f"Machine: {mach.get('cpus')} cores, load average at start {mach.get('load_start')}, at end "
            f"{mach.get('load_end')}. numbalsoda: {data.get('peers', {}).get('numbalsoda', '?')}. "
            f"heyoka: {data.get('peers', {}).get('heyoka', '?')}. "
            f"Total {data.get('elapsed_s', 0):.0f} s.", ""]  # fmt: skip
    out += ["| case | scene | IC | horizon K (periods) | amplification at K | reference bound | refs cached |",
            "|---|---|---|---|---|---|---|"]  # fmt: skip
    for c in data["cases"].values():
        amp = "" if c["amp_at_horizon"] is None else f"{c['amp_at_horizon']:.3g}"
        out.append(f"| {c['name']} | {c['scene']} | ({c['ic'][0]:.6g}, {c['ic'][1]:.6g}) | {c['horizon']} of "
                   f"{c['k_max']} | {amp} | {c['reference_bound']:.1e} | {c['cache_hits']}/"
                   f"{c['cache_hits'] + c['cache_misses']} |")  # fmt: skip
    notes = [f"{c['name']}: {n}" for c in data["cases"].values() for n in c.get("notes", [])]
    out += ["", *(f"* {n}" for n in notes), ""] if notes else [""]
    fields = [f"* {c['name']}, {peer}: {text}" for c in data["cases"].values()
              for peer, text in c.get("peer_fields", {}).items()]  # fmt: skip
    out += ["Each peer's field, as it is given to it:", "", *fields, ""] if fields else []
    # Time per trajectory to reach the target error, per line and case.
    names = list(data["cases"])
    series: dict[str, dict[str, list[tuple[float | None, float]]]] = {}
    for r in data["rows"]:
        series.setdefault(r["series"], {}).setdefault(r["case"], []).append((r["error"], r["time_per_traj_s"]))
    out += [f"## Time per trajectory to reach error {target:g} (ms; log-log interpolation along each line)", "",
            "| line | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]  # fmt: skip
    for line, per_case in series.items():
        cells = []
        for name in names:
            t, how = time_at_error(per_case.get(name, []), target)
            cells.append("—" if t is None else f"{'≤ ' if how == 'at most' else ''}{1e3 * t:.3g}")
        out.append(f"| {line} | " + " | ".join(cells) + " |")
    out.append("")
    ratios = data.get("ratios") or {}
    if ratios:
        out += ["## Ratios (per trajectory, at the same error, regular orbit)", ""]
        out += [f"* {k}: {'n/a' if v is None else f'{v:g}x'}" for k, v in ratios.items() if " / " in k]
        out.append("")
    if data.get("throughput"):
        out += ["## Throughput and targets", ""]
        out += [f"* {k}: {_fmt_value(v)}" for k, v in data["throughput"].items() if k != "heyoka_table"]
        out.append("")
    if "heyoka_table" in (data.get("throughput") or {}):
        out += [
            "## Against heyoka at every tolerance (issue 22)",
            "",
            heyoka_table_markdown(data["throughput"]["heyoka_table"]),
        ]
    if data.get("indicators"):
        from explorer_core.studies.indicator_bench import table

        out += ["## Chaos indicators against a long Lyapunov run (issue 34)", "", table(data["indicators"]), ""]
    if rows:
        out += ["## Rows", "",
                "| case | implementation | method | setting | mode | n | periods | error | time / traj (s) | "
                "total (s) | steps / period | status |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in data["rows"]:
            err = "—" if r["error"] is None else f"{r['error']:.2e}"
            spp = "" if r["steps_per_period"] is None else f"{r['steps_per_period']:.1f}"
            out.append(f"| {r['case']} | {r['implementation']} | {r['method']} | {r['setting']} | {r['mode']} | "
                       f"{r['n_traj']} | {r['periods']} | {err} | {r['time_per_traj_s']:.3g} | {r['total_s']:.3g} | "
                       f"{spp} | {r['status']} |")  # fmt: skip
    return "\n".join(out) + "\n"


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_fmt_value(x)}" for k, x in v.items())
    if isinstance(v, list | tuple):
        return "[" + "; ".join(_fmt_value(x) for x in v) + "]"
    return str(v)


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        v = float(v)
        return v if math.isfinite(v) else None
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    return v


def latest_path(cache_dir_: str | os.PathLike[str] | None = None) -> str:
    """Where :func:`save_latest` keeps the most recent ``bilimovich bench`` result."""
    return os.path.join(cache_dir(cache_dir_), "latest_bench.json")


def save_latest(data: dict[str, Any], cache_dir_: str | os.PathLike[str] | None = None) -> str:
    """Keep ``data`` (a bench.json dict) as the latest result, for the app's speed-vs-accuracy tab."""
    path = latest_path(cache_dir_)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".json.tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh)
    os.replace(tmp, path)
    return path


def load_result(path: str) -> dict[str, Any]:
    """A ``bench.json`` written by :meth:`BenchResult.write` (as plain data)."""
    with open(path) as fh:
        data = json.load(fh)
    if not isinstance(data, dict) or "rows" not in data or "cases" not in data:
        raise ValueError(f"{path} is not a bench.json (no rows/cases)")
    return data


def time_at_error(points: Sequence[tuple[float | None, float]], target: float) -> tuple[float | None, str]:
    """Time to reach ``target`` error along a work-precision line of ``(error, time)`` points.

    ``points`` go from the loosest setting to the tightest. The first point at or below the target
    and the one before it are interpolated in log-log; ``how`` is ``"interpolated"``, ``"at most"``
    (the loosest point already meets it, or there is nothing to interpolate) or ``"not reached"``.
    """
    prev: tuple[float, float] | None = None
    for e, t in points:
        if e is None or not (e > 0 and t > 0):
            prev = None  # a failed point breaks the line
            continue
        if e <= target:
            if prev is None or prev[0] <= target or prev[1] <= 0:
                return t, "at most"
            e0, t0 = prev
            w = (math.log(target) - math.log(e0)) / (math.log(e) - math.log(e0))
            return math.exp(math.log(t0) + w * (math.log(t) - math.log(t0))), "interpolated"
        prev = (e, t)
    return None, "not reached"


# ---------------------------------------------------------------------------
# The driver.


class _Cancelled(Exception):
    pass


def run_bench(
    cfg: BenchConfig | None = None,
    *,
    cases: Sequence[Case] | None = None,
    cache_dir_: str | os.PathLike[str] | None = None,
    progress: Callable[[BenchProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> BenchResult:
    """Measure every case of ``cfg`` (or the given ``cases``): rows, horizons, throughput, ratios.

    ``progress`` is called after each measurement; ``cancel`` is polled between measurements and
    stops the run (``completed=False``, what was measured is kept).
    """
    cfg = cfg or full_config()
    cfg.validate()
    if cases is None:
        known = builtin_cases(cfg.k_max)
        cases = [known[c] for c in cfg.cases]
    start = time.perf_counter()
    res = BenchResult(config=cfg)
    res.machine = {"cpus": os.cpu_count(), "workers": config.N_WORKERS, "platform": platform.platform(),
                   "python": platform.python_version(), "numpy": np.__version__, "numba": nb.__version__,
                   "load_start": _load()}  # fmt: skip
    nbs, nbs_text = numbalsoda_status()
    hy, hy_text = heyoka_status()
    res.peers = {"numbalsoda": nbs_text, "heyoka": hy_text}
    peers = [p for p in cfg.peers if (nbs is not None or not p.startswith("numbalsoda"))
             and (hy is not None or not p.startswith("heyoka"))]  # fmt: skip
    n_ours = len(cfg.modes) * (len(cfg.rk4_steps) + len(cfg.dp5_tols) + len(cfg.dop853_tols) + len(cfg.vern9_tols)
                               + len(cfg.taylor_tols))  # fmt: skip
    total = len(cases) * (1 + n_ours + len(peers) * len(cfg.peer_tols)) + (3 if cfg.throughput else 0)
    table = cfg.table and any(p.startswith("heyoka") for p in cfg.peers)  # --no-peers: no table either
    total += (1 + len(cfg.table_tols)) if table and hy is not None else 0
    total += 2 * (1 + len(INDICATOR_LADDERS)) if cfg.indicators else 0
    done = [0]

    def tick(text: str) -> None:
        done[0] += 1
        if progress is not None:
            progress(BenchProgress(text, min(done[0], total), total, time.perf_counter() - start))
        if cancel is not None and cancel():
            raise _Cancelled

    try:
        if progress is not None:
            progress(BenchProgress("warming up the kernels", 0, total, 0.0))
        _warm(cfg, nbs if any(p.startswith("numbalsoda") for p in peers) else None)
        for case in cases:
            _run_case(res, case, cfg, peers, nbs, cache_dir_, tick)
        if cfg.throughput:
            _run_throughput(res, cfg, cache_dir_, tick)
        if table:
            res.throughput["heyoka_table"] = heyoka_table(cfg, tick)
        if cfg.indicators:
            res.indicators = _run_indicators(cfg, tick)
    except _Cancelled:
        res.completed = False
    res.ratios = _ratios(res, cfg, nbs is not None, hy is not None) if res.completed or res.rows else {}
    res.machine["load_end"] = _load()
    res.elapsed_s = time.perf_counter() - start
    return res


#: The ladders of lengths of bench's indicator comparison (the small one: the full one is
#: ``benchmarks/indicators_speed.py``'s).
INDICATOR_LADDERS = {"birkhoff": (50, 100, 200), "sali": (25, 50, 100, 200, 500), "ftle": (25, 50, 100, 200, 500)}


def _run_indicators(cfg: BenchConfig, tick: Callable[[str], None]) -> dict[str, Any]:
    """The small comparison of the chaos indicators (:func:`explorer_core.studies.indicator_bench.measure`)."""
    from explorer_core.studies.indicator_bench import measure  # the analyses only when asked for

    return measure(cfg.indicator_ics, cfg.indicator_reference, cfg.repeat, INDICATOR_LADDERS, tick)


def _load() -> list[float] | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return None


def _warm(cfg: BenchConfig, nbs: Any) -> None:
    """Compile/load every kernel and start the thread pool, so no timing includes either (heyoka: per case)."""
    model = Model(Params())
    ics = np.array([[0.1, 0.2], [0.3, 0.1], [0.2, 0.2]])
    for method in OUR_METHODS:
        for block, workers in ((1, 1), (config.BLOCK_SIZE, None)):
            b = Batch.start(ics, 0.0, model.params.period)
            advance(model, b, 1, method=method, steps_per_period=8, workers=workers, block=block)
    if cfg.throughput:
        run_ceiling(model, ics, 1, 4)
    if nbs is not None:  # numbalsoda's drivers are jitted without a disk cache: compiled in every process
        _cfunc_rhs(is_diagonal(model.params))
        for method in ("lsoda", "dop853"):
            _peer_numbalsoda(nbs, model, ics[:1], 1, method, 1e-6)


def _run_case(
    res: BenchResult,
    case: Case,
    cfg: BenchConfig,
    peers: list[str],
    nbs: Any,
    cache_dir_: str | os.PathLike[str] | None,
    tick: Callable[[str], None],
) -> None:
    model = Model(case.params)
    batch_ics = case.ics(max(cfg.batch, cfg.measured))
    measured = batch_ics[: cfg.measured]
    amp = amplification(case.params, measured, case.k_max)
    k = horizon(amp, cfg.amp_max, case.k_max)
    refs = [reference(case.params, ic, k, cache_dir_=cache_dir_) for ic in measured]
    notes = [r.status for r in refs if r.status != "ok"]
    k = min([k, *(r.periods for r in refs)])
    if k < 1:
        raise ParameterError(f"case {case.name}: the reference fails in the first period ({'; '.join(notes)})")
    ref_pts = [r.points[:k] for r in refs]
    bounds = [float(r.bound_k()[k - 1]) for r in refs]
    worst = np.nanmax(np.where(np.isnan(amp[:, :k]), np.inf, amp[:, :k]))
    info = CaseInfo(
        name=case.name, scene=case.scene, why=case.why, ic=case.ic, k_max=case.k_max, horizon=k,
        amp_at_horizon=float(worst), amp_at_k_max=float(np.nanmax(amp[:, -1])) if np.isfinite(amp[:, -1]).any()
        else math.inf, measured_ics=measured.tolist(), batch=int(batch_ics.shape[0]), reference_bound=max(bounds),
        reference_steps_per_period=max(r.ref_steps_per_period for r in refs),
        reference_fixed_steps=max(r.fixed_steps for r in refs),
        reference_elapsed_s=round(sum(r.elapsed_s for r in refs), 2), cache_hits=sum(r.cache_hit for r in refs),
        cache_misses=sum(not r.cache_hit for r in refs), notes=notes, peer_fields=peer_fields(case.params),
    )  # fmt: skip
    res.cases[case.name] = info
    tick(f"{case.name}: horizon {k} periods, reference bound {info.reference_bound:.1e} "
         f"({info.cache_hits} cached, {info.cache_misses} computed)")  # fmt: skip
    m = len(refs)
    for mode in cfg.modes:
        ics = measured if mode == "single" else batch_ics
        for method, settings in (("rk4", cfg.rk4_steps), ("dp5", cfg.dp5_tols), ("dop853", cfg.dop853_tols),
                                 ("vern9", cfg.vern9_tols), ("taylor", cfg.taylor_tols)):  # fmt: skip
            for s in settings:
                sec, pts, npts, st, ns = _ours(model, ics, k, method, s, mode, cfg.repeat)
                errs = [_error(pts[i], int(npts[i]), ref_pts[i]) for i in range(m)]
                n = ics.shape[0]
                spp = float(np.mean(ns)) / k
                res.rows.append(
                    Row(case.name, method, "ours", _fmt_setting(method, s), mode, n, k,
                        None if any(e is None for e in errs) else max(errs), sec / n, sec, round(spp, 2),
                        None if _STAGES[method] is None else round(spp * _STAGES[method], 1), _status_text(st),
                        None if method == "rk4" else float(s), int(s) if method == "rk4" else None)
                )  # fmt: skip
                tick(f"{case.name}: ours {method} {_fmt_setting(method, s)} {mode}")
    for peer in peers:
        lib, method = peer.split(":")
        last: list[float] = []
        for tol in cfg.peer_tols:
            growth = last[-1] / last[-2] if len(last) >= 2 and last[-2] > 0 else 1.0
            if last and last[-1] * max(1.0, growth) > cfg.peer_budget_s:
                info.notes.append(f"{peer}: tolerances from {tol:.0e} on skipped (over {cfg.peer_budget_s:g} s "
                                  "per trajectory)")  # fmt: skip
                tick(f"{case.name}: {peer} tol={tol:.0e} skipped")
                for _ in cfg.peer_tols[cfg.peer_tols.index(tol) + 1 :]:
                    tick(f"{case.name}: {peer} skipped")
                break

            # heyoka's batch mode runs the case's batch cloud (like ours batch), everything else the measured ICs.
            mode = "batch" if peer == "heyoka:batch" else "single"
            ics = batch_ics if mode == "batch" else measured

            def run(lib: str = lib, method: str = method, tol: float = tol, mode: str = mode, ics=ics):
                if lib == "scipy":
                    return _peer_scipy(model, ics, k, method, tol)
                if lib == "heyoka":
                    return _peer_heyoka(model, ics, k, mode, tol)
                return _peer_numbalsoda(nbs, model, ics, k, method, tol)

            if lib == "heyoka":  # heyoka compiles per model and tolerance, on first use: outside the timing
                _peer_heyoka(model, ics[:1], 1, mode, tol)
            sec, (pts, ok, nfev, msgs) = _timed(run, cfg.repeat)
            errs = [_error(pts[i], k if ok[i] else 0, ref_pts[i]) for i in range(m)]
            impl = {"scipy": "scipy.solve_ivp"}.get(lib, lib)
            name = "taylor" if lib == "heyoka" else method
            n = ics.shape[0]
            res.rows.append(
                Row(case.name, name, impl, f"tol={tol:.0e}", mode, n, k,
                    None if any(e is None for e in errs) else max(errs), sec / n, sec, None,
                    None if nfev is None else round(nfev / n / k, 1), "ok" if all(ok) else "; ".join(msgs[:3]), tol,
                    None)
            )  # fmt: skip
            last.append(sec / n)
            tick(f"{case.name}: {impl} {name}{' batch' if mode == 'batch' else ''} tol={tol:.0e}")


def _target_case() -> Case:
    return builtin_cases()["regular"]


#: The central island of Fig. 1C (diag(1, 4, 2), alpha = 0.1), where every orbit is regular: an
#: ellipse of semi-axes 0.9 (q) and 1.2 (r) around the origin, scaled by 0.05 ... 0.6 (docs/figures/fig1.png).
ISLAND_AXES = (0.9, 1.2)
ISLAND_RADII = (0.05, 0.6)


def island_ics(n: int, seed: int = 0) -> np.ndarray:
    """``n`` seeded initial conditions on regular orbits: area-uniform in Fig. 1C's central island."""
    rng = np.random.default_rng(seed)
    lo, hi = ISLAND_RADII
    rad = np.sqrt(rng.uniform(lo * lo, hi * hi, n))
    ang = rng.uniform(0.0, 2.0 * math.pi, n)
    return np.column_stack([ISLAND_AXES[0] * rad * np.cos(ang), ISLAND_AXES[1] * rad * np.sin(ang)])


def _run_throughput(
    res: BenchResult, cfg: BenchConfig, cache_dir_: str | os.PathLike[str] | None, tick: Callable[[str], None]
) -> None:
    """Targets (c) 200 ICs x 1000 periods at 1e-6, (b) parallel efficiency, (a) throughput vs the ceiling."""
    scene = get_scene("fig1C")
    params = scene.params
    model = Model(params)
    # "A section of regular orbits": seeded ICs in the central island, where perturbations grow
    # linearly, not exponentially (most of fig1C's box is chaotic sea: 3 of its first 18 seeded ICs
    # are regular; the box's cost at the chosen tolerance is reported next to it).
    ics = island_ics(cfg.target_ics, seed=0)
    periods = cfg.target_periods
    repeat = max(3, cfg.repeat)  # short runs on a shared machine: always a median
    cand = ics[: 2 * cfg.target_check]
    amp = amplification(params, cand, periods)
    regular = regular_members(amp, cfg.amp_max)
    check = regular[: cfg.target_check]
    refs = [reference(params, ics[i], periods, cache_dir_=cache_dir_) for i in check]
    tick(f"target: {len(check)} regular members with references ({sum(r.cache_hit for r in refs)} cached)")
    chosen: tuple[float, float, float, Batch] | None = None
    ladder = []
    for tol in cfg.target_tols:
        wall, (batch, out, npts) = _timed(lambda tol=tol: _batch_run(model, ics, periods, tol, None), repeat)
        errs = [_error(out[i], int(npts[i]), r.points) for i, r in zip(check, refs, strict=True)]
        err = None if not errs or any(e is None for e in errs) else max(errs)  # type: ignore[type-var]
        ladder.append({"tol": tol, "wall_s": round(wall, 4), "error_regular": err})
        if err is not None and err <= cfg.target_error:
            chosen = (tol, wall, err, batch)
            break
    if chosen is None:
        res.throughput["target"] = {"reached": False, "ladder": ladder}
        tick("target: error not reached")
        tick("parallel efficiency skipped")
        return
    tol, wall2, err, batch = chosen
    steps2 = int(batch.nsteps.sum())
    workers = config.N_WORKERS
    res.throughput["target"] = {
        "what": f"{cfg.target_ics} ICs on regular orbits (fig1C central island, seed 0) x {periods} periods, "
        f"dop853, default block kernel, {workers} workers",
        "tol": tol,
        "error_on_regular_members": err,
        "regular_members_checked": len(check),
        "regular_among_candidates": f"{len(regular)} of {cand.shape[0]}",
        "reference_bound": max(r.bound for r in refs),
        "wall_s": round(wall2, 4),
        "goal_s": 0.5,
        "steps_per_period_per_traj": round(steps2 / cfg.target_ics / periods, 2),
        "status": _status_text(batch.status),
        "ladder": ladder,
    }
    tick(f"target: tol {tol:g}, {wall2:.3f} s on {workers} workers")
    # For comparison: the whole box (mostly chaotic sea: larger states, more steps) at the same tolerance.
    box_ics = random_ics(cfg.target_ics, scene.box, seed=0)
    wall_box, (batch_box, _, _) = _timed(lambda: _batch_run(model, box_ics, periods, tol, None), repeat)
    res.throughput["target"]["whole_box"] = {
        "what": f"{cfg.target_ics} ICs uniform in fig1C's box (seed 0), same tolerance and periods",
        "wall_s": round(wall_box, 4),
        "steps_per_period_per_traj": round(int(batch_box.nsteps.sum()) / cfg.target_ics / periods, 2),
    }
    tick(f"target: whole box at tol {tol:g}, {wall_box:.3f} s")
    wall1, (batch1, _, _) = _timed(lambda: _batch_run(model, ics, periods, tol, 1), repeat)
    res.throughput["parallel"] = {
        "wall_1_worker_s": round(wall1, 4),
        f"wall_{workers}_workers_s": round(wall2, 4),
        "speedup": round(wall1 / wall2, 3),
        "efficiency": round(wall1 / (workers * wall2), 3),
    }
    tick(f"parallel: 1 worker {wall1:.3f} s, efficiency {wall1 / (workers * wall2):.0%}")
    # The ceiling: the same ICs and periods at the mean step count, fixed steps, one thread.
    n_fixed = max(1, round(steps2 / cfg.target_ics / periods))
    sec_c, _ = _timed(lambda: run_ceiling(model, ics, periods, n_fixed), repeat)
    ceiling = cfg.target_ics * periods * n_fixed / sec_c
    ours1 = int(batch1.nsteps.sum()) / wall1
    ours2 = steps2 / wall2 / workers
    res.throughput["kernel"] = {
        "what": "trajectory RK steps (accepted + rejected) per second per core; ceiling = minimal lock-step "
        "DOP853 kernel (fixed steps, same coefficient evaluation, no error control), one thread",
        "ours_1_worker": round(ours1),
        f"ours_{workers}_workers_per_core": round(ours2),
        "ceiling_1_thread": round(ceiling),
        "ceiling_steps_per_period": n_fixed,
        "block": config.BLOCK_SIZE,
        "percent_of_ceiling_1_worker": round(100.0 * ours1 / ceiling, 1),
        f"percent_of_ceiling_{workers}_workers": round(100.0 * ours2 / ceiling, 1),
        "goal_percent": 30,
    }
    tick(f"throughput: {100 * ours1 / ceiling:.0f}% of the ceiling")


#: The work of issue 22's table: a regular orbit family of the diagonal tensor (1, 4, 2), alpha = 0.1, g = cos t.
TABLE_PARAMS = Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1)
#: heyoka's tolerance for the table's reference.
TABLE_REF_TOL = 1e-16


def heyoka_table(
    cfg: BenchConfig, tick: Callable[[str], None] = lambda _: None, params: Params = TABLE_PARAMS
) -> dict[str, Any]:
    """Issue 22's table: at each tolerance, heyoka's batch mode (x :data:`HEYOKA_BATCH`, one thread) beside ours.

    ``cfg.table_ics`` random ICs in [-1, 1]^2 (seed 0) x ``cfg.table_periods`` periods of ``params``. Error of a
    run: per IC the largest distance from heyoka at :data:`TABLE_REF_TOL` over the section points; the table
    gives the median and the largest over ICs. Ours: ``cfg.table_methods``, the default lock-step block kernel
    on every worker (:data:`explorer_core.config.N_WORKERS`). Times: heyoka and ours interleaved, the fastest of
    ``max(3, cfg.repeat)`` rounds (short runs on a shared machine). ``ratio_per_core`` = our core-seconds (wall x
    workers) over heyoka's one-thread seconds: above 1, heyoka does the work with less CPU.
    """
    hy, text = heyoka_status()
    if hy is None:
        return {"available": False, "heyoka": text}
    model = Model(params)
    ics = random_ics(cfg.table_ics, (-1.0, 1.0, -1.0, 1.0), seed=0)
    periods = cfg.table_periods
    workers = config.N_WORKERS
    ref_pts, ref_ok, _, _ = _peer_heyoka(model, ics, periods, "batch", TABLE_REF_TOL)
    ref = np.array(ref_pts)
    good = np.asarray(ref_ok, bool)
    tick(f"heyoka table: reference at tol {TABLE_REF_TOL:g} ({int(good.sum())} of {good.size} ICs complete)")

    def errors(pts: np.ndarray, ok: np.ndarray) -> tuple[float | None, float | None]:
        use = good & ok
        if not use.any():
            return None, None
        dev = np.max(np.linalg.norm(pts[use] - ref[use], axis=2), axis=1)
        return float(np.median(dev)), float(np.max(dev))

    def ours(method: str, tol: float, workers_: int | None) -> tuple[np.ndarray, np.ndarray, float]:
        b = Batch.start(ics, params.t0, params.period)
        out, npts = advance(model, b, periods, method=method, rtol=tol, atol=tol, workers=workers_)
        return out, (b.status == Status.OK) & (npts == periods), float(b.nsteps.mean()) / periods

    def peer(tol: float) -> tuple[np.ndarray, np.ndarray, None]:
        pts, ok, _, _ = _peer_heyoka(model, ics, periods, "batch", tol)
        return np.array(pts), np.asarray(ok, bool), None

    rows = []
    for tol in cfg.table_tols:
        runs: dict[str, Callable[[], Any]] = {"heyoka": lambda tol=tol: peer(tol)}
        for m in cfg.table_methods:
            runs[m] = lambda m=m, tol=tol: ours(m, tol, None)
            if workers > 1:  # per core without the parallel efficiency (and the machine's load) in it
                runs[f"{m} 1"] = lambda m=m, tol=tol: ours(m, tol, 1)
        best = dict.fromkeys(runs, math.inf)
        got: dict[str, Any] = {}
        for _ in range(max(3, cfg.repeat)):
            for name, fn in runs.items():
                t0 = time.perf_counter()
                got[name] = fn()
                best[name] = min(best[name], time.perf_counter() - t0)
        hy_med, hy_max = errors(got["heyoka"][0], got["heyoka"][1])
        for m in cfg.table_methods:
            med, mx = errors(got[m][0], got[m][1])
            rows.append({"tol": tol, "method": m, "error_median": med, "error_max": mx, "time_s": best[m],
                         "steps_per_period": got[m][2], "heyoka_error_median": hy_med, "heyoka_error_max": hy_max,
                         "heyoka_time_s": best["heyoka"], "ratio_per_core": best[m] * workers / best["heyoka"],
                         "ratio_1_thread": best.get(f"{m} 1", best[m]) / best["heyoka"],
                         "complete": int(got[m][1].sum())})  # fmt: skip
        tick(f"heyoka table: tol {tol:g}")
    return {
        "available": True,
        "what": f"{cfg.table_ics} random ICs in [-1, 1]^2 x {periods} periods, tensor diag(1, 4, 2), alpha 0.1, "
        f"g = cos t; error = per IC the largest distance from heyoka at tol {TABLE_REF_TOL:g} (median, max over "
        f"ICs); ours on {workers} workers (default block kernel), heyoka batch x{HEYOKA_BATCH} on one thread on "
        f"the peers' field ({peer_fields(params).get('heyoka', '')}); "
        "ratio per core = ours wall x workers / heyoka wall; ratio 1 thread = ours on one worker / heyoka; "
        'fastest of interleaved rounds. The default method ("auto") is vern9 at rtol '
        f"{config.VERN9_MIN_RTOL:g}..{config.VERN9_MAX_RTOL:g} and dop853 elsewhere",
        "workers": workers,
        "rows": rows,
    }


def heyoka_table_markdown(table: dict[str, Any]) -> str:
    """The table of :func:`heyoka_table` as Markdown (one line if heyoka is not available)."""
    if not table.get("available"):
        return f"heyoka table: {table.get('heyoka', 'not measured')}\n"

    def e(v: float | None) -> str:
        return "—" if v is None else f"{v:.1e}"

    out = [table["what"], "",
           "| tol | ours | error (median / max) | time (s) | steps / period | heyoka error (median / max) | "
           "heyoka time (s) | ratio per core | ratio 1 thread |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in table["rows"]:
        out.append(f"| {r['tol']:.0e} | {r['method']} | {e(r['error_median'])} / {e(r['error_max'])} | "
                   f"{r['time_s']:.3f} | {r['steps_per_period']:.1f} | {e(r['heyoka_error_median'])} / "
                   f"{e(r['heyoka_error_max'])} | {r['heyoka_time_s']:.3f} | {r['ratio_per_core']:.2f} | "
                   f"{r['ratio_1_thread']:.2f} |")  # fmt: skip
    return "\n".join(out) + "\n"


def _batch_run(
    model: Model, ics: np.ndarray, periods: int, tol: float, workers: int | None
) -> tuple[Batch, np.ndarray, np.ndarray]:
    p = model.params
    b = Batch.start(ics, p.t0, p.period)
    out, npts = advance(model, b, periods, method="dop853", rtol=tol, atol=tol, workers=workers)
    return b, out, npts


def _ratios(res: BenchResult, cfg: BenchConfig, have_nbs: bool, have_hy: bool = False) -> dict[str, Any]:
    """Per-trajectory speed ratios at ``target_error`` on the regular case, from its diagram lines."""
    if "regular" not in res.cases:
        return {}
    target = cfg.target_error
    lines = res.series("regular")
    at: dict[str, Any] = {}
    for name, rows in lines.items():
        t, how = time_at_error([(r.error, r.time_per_traj_s) for r in rows], target)
        at[name] = {"time_per_traj_s": t, "how": how}
    out: dict[str, Any] = {
        "what": f"time per trajectory to reach error {target:g} after {res.cases['regular'].horizon} periods "
        "on the regular orbit (log-log interpolation on each line)",
        "time_at_error": at,
    }

    def ratio(num: str, den: str) -> float | None:
        a = at.get(num, {}).get("time_per_traj_s")
        b = at.get(den, {}).get("time_per_traj_s")
        return round(a / b, 1) if a and b else None

    for ours in ("ours dop853 batch", "ours dop853"):
        for peer in ("scipy.solve_ivp DOP853", "scipy.solve_ivp RK45", "scipy.solve_ivp LSODA", "numbalsoda dop853",
                     "numbalsoda lsoda"):  # fmt: skip
            if peer.startswith("numbalsoda") and not have_nbs:
                continue
            out[f"{peer} / {ours}"] = ratio(peer, ours)
    if have_hy:
        for peer, ours in (
            ("heyoka taylor", "ours dop853"),
            ("heyoka taylor batch", "ours dop853 batch"),
            ("heyoka taylor", "ours vern9"),
            ("heyoka taylor batch", "ours vern9 batch"),
            ("heyoka taylor", "ours taylor"),
            ("heyoka taylor batch", "ours taylor batch"),
        ):
            out[f"{peer} / {ours}"] = ratio(peer, ours)
    return out
