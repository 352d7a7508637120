"""Numerical settings in one place: defaults, limits and controller constants.

Everything a caller may want to change is an argument of the public functions;
these are only their defaults, kept here so the CLI, the app and the tests agree.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

#: Default integration method: ``"auto"`` is resolved by the tolerance when the settings are made
#: (:func:`explorer_core.solve.tableaus.resolve_method`): Verner 9(8) for VERN9_MIN_RTOL <= rtol <= VERN9_MAX_RTOL,
#: DOP853 elsewhere. Other names ("rk4", "dp5", "dop853", "vern9", "taylor") are used as given.
DEFAULT_METHOD = "auto"
#: Loosest tolerance at which "auto" takes vern9. Measured (benchmarks/method_choice.py, one process, methods
#: alternated, median of 5, load 1-4, 2026-11-25; vern9's time / DOP853's): plain sections 0.94 / 0.89 / 0.79 /
#: 0.67 at rtol 1e-7 / 1e-8 / 1e-9 / 1e-10; the tangent system loses at 1e-8 (chart of regimes 1.38, 1e-7: 1.10)
#: and wins from 1e-9 on (chart 0.74 / 0.88 at 1e-9 / 1e-10; Lyapunov spectrum 0.97 / 0.87 / 0.78 / 0.87 at
#: 1e-8 / 1e-9 / 1e-10 / 1e-12); continuation (1e-12) 0.77-0.80, periodic orbits about even (0.89-1.08, one
#: 17 ms case 1.24), manifolds (1e-10) 0.84-0.90, the Fig. 10 orbit diagram 0.72 / 0.82 at 1e-9 / 1e-10.
#: So vern9 from 1e-9 down; the charts and basins (1e-8) stay on DOP853.
VERN9_MAX_RTOL = 1e-9
#: Tightest tolerance at which "auto" takes vern9: below 1e-13 its error estimate picks up round-off and its
#: steps grow (solve/tableaus.py), DOP853 does not.
VERN9_MIN_RTOL = 1e-13
#: Default relative/absolute tolerance of the adaptive methods. Chosen so that
#: regular orbits are reproduced to ~1e-6 after 200 periods (see README).
DEFAULT_RTOL = 1e-10
DEFAULT_ATOL = 1e-10
#: Default number of fixed RK4 steps per forcing period.
DEFAULT_STEPS_PER_PERIOD = 400
#: A trajectory with |q| or |r| above this bound is flagged "escaped".
DEFAULT_ESCAPE_BOUND = 1.0e4
#: Accepted+rejected steps allowed per period before "too many steps".
DEFAULT_MAX_STEPS_PER_PERIOD = 200_000

#: Step-size controller (Hairer, Norsett & Wanner, Solving ODEs I, II.4).
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0

#: Hard limits that keep one request bounded (CLI, app, URL parameters).
MAX_TRAJECTORIES = 100_000
MAX_PERIODS = 10_000_000
MAX_GRID = 4096
#: Section points held in memory by one request (16 bytes each).
MAX_POINTS = 50_000_000
#: Basins of attraction (``bilimovich basins``): pixels per axis and in all.
MAX_BASIN_GRID = 2048
MAX_BASIN_PIXELS = 1_048_576

#: Trajectories integrated in lock-step by the adaptive batch kernel (1 = one step
#: sequence each). Measured trade-off in the README (performance).
BLOCK_SIZE = 32


def usable_cpus() -> int:
    """CPUs this process may use: its affinity mask, capped by a cgroup CPU quota (``docker run --cpus``)."""
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    quota = _cgroup_quota()
    if quota is not None:
        n = min(n, max(1, int(quota + 0.5)))
    return max(1, n)


def _cgroup_quota() -> float | None:
    """CPUs allowed by the cgroup (v2 ``cpu.max``, v1 ``cpu.cfs_quota_us``), None if unlimited or unknown."""
    with contextlib.suppress(OSError, ValueError):
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        return None if quota == "max" else int(quota) / int(period)
    with contextlib.suppress(OSError, ValueError):
        q = int(Path("/sys/fs/cgroup/cpu/cpu.cfs_quota_us").read_text())
        p = int(Path("/sys/fs/cgroup/cpu/cpu.cfs_period_us").read_text())
        return None if q <= 0 else q / p
    return None


def resolve_procs(text: str | int) -> int:
    """Server processes: ``auto`` (one per usable CPU) or a whole number 1..64; ValueError names a bad value."""
    t = str(text).strip().lower()
    if t == "auto":
        return usable_cpus()
    try:
        n = int(t)
    except ValueError:
        raise ValueError(f"--procs must be a whole number or 'auto', got {str(text)[:40]!r}") from None
    if not 1 <= n <= 64:
        raise ValueError(f"--procs must be between 1 and 64, got {n}")
    return n


#: Worker threads for batch kernels (the kernels release the GIL).
N_WORKERS = max(1, min(usable_cpus(), int(os.environ.get("BILIMOVICH_THREADS", "0")) or usable_cpus()))
