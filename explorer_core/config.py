"""Numerical settings in one place: defaults, limits and controller constants.

Everything a caller may want to change is an argument of the public functions;
these are only their defaults, kept here so the CLI, the app and the tests agree.
"""

from __future__ import annotations

import os

#: Default integration method for sections ("rk4", "dp5" or "dop853").
DEFAULT_METHOD = "dop853"
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

#: Trajectories integrated in lock-step by the adaptive batch kernel (1 = one step
#: sequence each). Measured trade-off in the README (performance).
BLOCK_SIZE = 32

#: Worker threads for batch kernels (the kernels release the GIL).
N_WORKERS = max(1, min(os.cpu_count() or 1, int(os.environ.get("BILIMOVICH_THREADS", "0")) or (os.cpu_count() or 1)))
