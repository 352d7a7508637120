"""Where the time goes at high accuracy: counts that do not depend on the machine's load, and short
interleaved A/B ratios in one process (min of repeats), for our methods and heyoka's batch mode.

    .venv/bin/python benchmarks/high_accuracy.py [--ics 16] [--periods 200] [--repeat 3]
        [--tols 1e-8,1e-10,1e-12,1e-13] [--methods dop853,taylor]

The work of issue 22: the regular orbit of the diagonal tensor (1, 4, 2), alpha = 0.1, g = cos t; random ICs in
[-1, 1]^2 (the project's own ``random_ics``). Error: median over ICs of the largest distance from heyoka at
tol 1e-16 over the section points. Printed per method and tolerance: steps per period, right-hand-side
evaluations per period (RK: stages + FSAL; Taylor: order), the error, and the time per core relative to heyoka's
batch x8 on one thread, both run on one thread in the same process, interleaved, min of ``repeat``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import random_ics
from explorer_core.solve.taylor import taylor_order
from explorer_core.studies import bench
from explorer_core.system.model import Model
from explorer_core.system.params import Params

STAGES = {"dp5": 6, "dop853": 12, "vern9": 16}


def ours(model: Model, ics: np.ndarray, periods: int, method: str, tol: float, block: int) -> tuple[np.ndarray, float]:
    p = model.params
    b = Batch.start(ics, p.t0, p.period)
    out, _ = advance(model, b, periods, method=method, rtol=tol, atol=tol, workers=1, block=block)
    return out, float(b.nsteps.mean()) / periods


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ics", type=int, default=16)
    ap.add_argument("--periods", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tols", default="1e-8,1e-10,1e-12,1e-13")
    ap.add_argument("--methods", default="dop853,vern9,taylor")
    ap.add_argument("--block", type=int, default=32, help="lock-step block (1: one step sequence per IC)")
    a = ap.parse_args()
    model = Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1))
    ics = random_ics(a.ics, (-1.0, 1.0, -1.0, 1.0), seed=0)
    hy, why = bench.heyoka_status()
    if hy is None:
        raise SystemExit(f"heyoka not available: {why}")
    ref, ok, _, _ = bench._peer_heyoka(model, ics, a.periods, "batch", 1e-16)
    ref = np.array(ref)

    def err(pts: np.ndarray) -> float:
        return float(np.median(np.max(np.linalg.norm(np.asarray(pts) - ref, axis=2), axis=1)))

    print(f"{a.ics} ICs x {a.periods} periods, one thread each, min of {a.repeat} interleaved runs")
    print("| tol | method | steps/period | evals/period | error | time/heyoka |")
    print("|---|---|---|---|---|---|")
    for tol in (float(x) for x in a.tols.split(",")):
        runs = {"heyoka": lambda tol=tol: (np.array(bench._peer_heyoka(model, ics, a.periods, "batch", tol)[0]), 0.0)}
        for m in a.methods.split(","):
            runs[m] = lambda m=m, tol=tol: ours(model, ics, a.periods, m, tol, a.block)
        for f in runs.values():  # compile / warm
            f()
        best = {k: np.inf for k in runs}
        res = {}
        for _ in range(a.repeat):
            for k, f in runs.items():
                t0 = time.perf_counter()
                res[k] = f()
                best[k] = min(best[k], time.perf_counter() - t0)
        for k, (pts, spp) in res.items():
            evals = (
                ""
                if k == "heyoka"
                else (
                    f"{spp * taylor_order(tol):.0f} (order {taylor_order(tol)})"
                    if k == "taylor"
                    else f"{spp * STAGES[k]:.0f}"
                )
            )
            print(f"| {tol:.0e} | {k} | {spp:.1f} | {evals} | {err(pts):.2e} | {best[k] / best['heyoka']:.2f} |")


if __name__ == "__main__":
    main()
