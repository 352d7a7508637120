"""The chart of regimes before and after early stops on settled cycles, in one run (issue: heavy analyses).

    .venv/bin/python benchmarks/chart_speed.py [--grid 60,30] [--json out.json]

Fig. 11's chart (its scene's window, the two initial conditions of the paper's Fig. 11 discussion, 500
transient + 500 measured periods, today's classification) computed twice on both cores: tile by tile
as before (:func:`~explorer_core.analyses.regimes.compute_tile_each`: every pixel and IC the whole
way with the tangent system) and as now (:func:`~explorer_core.analyses.regimes.regime_chart`:
members on an attracting cycle stop early). Prints both times, the time per pixel-IC, and every
pixel-IC whose regime or period differs, with the old and new period and the new exponent (a
difference is expected only where the old finite-time tail had not converged: near a bifurcation,
where the cycle's exponent is close to 0).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from explorer_core import config
from explorer_core.analyses.regimes import REGIMES, Chart, chart_spec, compute_tile_each, plan_tiles, regime_chart
from explorer_core.scenes import get_scene
from explorer_core.warm import warm_all

ICS = [(-0.09, -2.0), (-0.5, -1.0)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", default="60,30")
    ap.add_argument("--json")
    args = ap.parse_args()
    nx, ny = (int(v) for v in args.grid.split(","))
    warm_all()
    scene = get_scene("fig11")
    c = scene.extra["chart"]
    spec = chart_spec(scene.params, c["x_param"], c["x_range"], c["y_param"], c["y_range"], (nx, ny), ics=ICS)
    n = nx * ny * len(ICS)

    t = time.perf_counter()
    after = regime_chart(spec, workers=config.N_WORKERS)
    t_after = time.perf_counter() - t

    t = time.perf_counter()
    before = Chart.empty(spec)
    with ThreadPoolExecutor(config.N_WORKERS) as pool:
        for res in pool.map(lambda tile: compute_tile_each(spec, tile), plan_tiles(spec.shape)):
            before.add(res)
    t_before = time.perf_counter() - t

    differ = np.argwhere((before.regime != after.regime) | (before.period != after.period))
    rows = [
        {"j": int(j), "i": int(i), "ic": int(k), spec.x_param: float(spec.x_values[i]),
         spec.y_param: float(spec.y_values[j]),
         "before": [REGIMES[before.regime[j, i, k]], int(before.period[j, i, k]), float(before.lyap[j, i, k])],
         "after": [REGIMES[after.regime[j, i, k]], int(after.period[j, i, k]), float(after.lyap[j, i, k])]}
        for j, i, k in differ
    ]  # fmt: skip
    report = {
        "grid": [nx, ny],
        "ics": ICS,
        "workers": config.N_WORKERS,
        "before_s": round(t_before, 2),
        "after_s": round(t_after, 2),
        "speedup": round(t_before / t_after, 2),
        "before_ms_per_pixel_ic": round(1e3 * t_before / n, 2),
        "after_ms_per_pixel_ic": round(1e3 * t_after / n, 2),
        "identical_fraction": round(1 - len(rows) / n, 5),
        "counts_after": after.counts(0),
        "differences": rows,
    }
    for k, v in report.items():
        if k != "differences":
            print(f"{k}: {v}")
    for r in rows:
        print("differs:", r)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
