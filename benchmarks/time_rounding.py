"""The same 100-period map, early and late: how the absolute time in a double costs accuracy and steps.

    .venv/bin/python benchmarks/time_rounding.py [--ics 16] [--periods 100] [--starts 0,1000,10000]
        [--runs dop853:1e-13,vern9:1e-13,dop853:1e-12]

The forcing is periodic, so ``P^n`` from a state at section time ``t0 + k T`` is the same map for every ``k``.
Each run starts the same random ICs in [-1, 1]^2 at section ``k`` (the batch's ``k``, so the engine's times are
``t0 + k T + ...``) and compares the ``n`` section points with heyoka at tol 1e-16 started at ``k = 0``
(heyoka keeps time in double-length arithmetic). Printed: the median over ICs of the largest deviation, and
the steps per period. If the error or the steps grow with ``k`` for the same map, the stage times ``t + c h``
(rounded to ulp(t) ~ 1e-12 at t ~ 6000) limit the accuracy, not the method.
"""

from __future__ import annotations

import argparse

import numpy as np

from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import random_ics
from explorer_core.studies import bench


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ics", type=int, default=16)
    ap.add_argument("--periods", type=int, default=100)
    ap.add_argument("--starts", default="0,1000,10000")
    ap.add_argument("--runs", default="dop853:1e-13,vern9:1e-13,dop853:1e-12")
    a = ap.parse_args()
    model = bench.Model(bench.TABLE_PARAMS)
    p = model.params
    ics = random_ics(a.ics, (-1.0, 1.0, -1.0, 1.0), seed=0)
    ref = np.array(bench._peer_heyoka(model, ics, a.periods, "batch", bench.TABLE_REF_TOL)[0])
    print("| method | tol | start k | t at start | error (median over ICs) | steps / period |")
    print("|---|---|---|---|---|---|")
    for run in a.runs.split(","):
        method, tol = run.split(":")
        for k0 in (int(k) for k in a.starts.split(",")):
            b = Batch.start(ics, p.t0, p.period)
            b.k = k0
            out, _ = advance(model, b, a.periods, method=method, rtol=float(tol), atol=float(tol), block=1)
            err = np.median(np.max(np.linalg.norm(out - ref, axis=2), axis=1))
            print(f"| {method} | {tol} | {k0} | {p.t0 + k0 * p.period:.0f} | {err:.1e} | "
                  f"{b.nsteps.mean() / a.periods:.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()
