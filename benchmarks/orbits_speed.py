"""Speed of the periodic-orbit tools (issue: periodic orbits of the Poincare map), in one run.

    .venv/bin/python benchmarks/orbits_speed.py [--repeat 5] [--json out.json]

* a click: the period-1 orbit Newton finds from one seed near each period-1 orbit of Fig. 8B (core time);
* a grid: every orbit of period <= 8 from a 15 x 15 grid of seeds over Fig. 8B's box (and, once, the
  same search without the early stop of stalled seeds, for what the early stop loses);
* Fig. 10's period-1 orbits from its 10 x 10 grid (``bilimovich orbits --scene fig10``);
* a cascade: the Fig. 10 continuation from alpha = -0.35 to -0.42 with branch switching, 1 -> 16
  (default steps, and steps of at most 0.01 for ~300 points).

Medians of ``--repeat`` runs after a warm-up (kernels loaded from the on-disk cache). The same cases' work,
independent of the machine's load: ``benchmarks/orbits_work.py``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from explorer_core.analyses.continuation import continue_orbit
from explorer_core.analyses.orbits import find_orbits, grid_seeds
from explorer_core.scenes import get_scene
from explorer_core.warm import warm_all


def timed(fn, repeat: int) -> tuple[float, object]:
    out = fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json")
    args = ap.parse_args()
    warm_all()
    fig8b = get_scene("fig8B")
    report: dict[str, object] = {}

    clicks = [(-0.03, -2.39), (-1.45, -4.12), (-0.02, 0.07)]
    t_click, _ = timed(lambda: [find_orbits(fig8b.params, [c], [1]) for c in clicks], args.repeat)
    report["click_period1_ms"] = round(1e3 * t_click / len(clicks), 1)

    seeds = grid_seeds(fig8b.box, 15, 15)
    t_grid, res = timed(lambda: find_orbits(fig8b.params, seeds, list(range(1, 9))), args.repeat)
    t0 = time.perf_counter()
    thorough = find_orbits(fig8b.params, seeds, list(range(1, 9)), patience=None)
    t_thorough = time.perf_counter() - t0
    report["grid_15x15_periods_1_8_s"] = round(t_grid, 3)
    report["grid_orbits"] = len(res.orbits)
    report["grid_thorough_s"] = round(t_thorough, 3)
    report["grid_thorough_orbits"] = len(thorough.orbits)

    fig10s = get_scene("fig10")
    seeds10 = grid_seeds(fig10s.box, 10, 10)
    t_g10, res10 = timed(lambda: find_orbits(fig10s.params, seeds10, [1]), args.repeat)
    report["fig10_grid_10x10_period1_s"] = round(t_g10, 3)
    report["fig10_grid_orbits"] = len(res10.orbits)

    fig10 = get_scene("fig10").params.with_(alpha=-0.35)
    t_cas, cas = timed(
        lambda: continue_orbit(fig10, "alpha", (-0.35, -0.42), (-0.0959, -1.962), 1, switch=True, max_period=16),
        args.repeat,
    )
    report["cascade_s"] = round(t_cas, 3)
    report["cascade_points"] = cas.n_points
    report["cascade_branches"] = [br.period for br in cas.branches]
    report["cascade_doublings"] = [b.value for b in cas.bifurcations if b.kind == "period_doubling"]
    # The size: ~300 points through the same cascade (arclength steps at most 0.01).
    t_fine, fine = timed(
        lambda: continue_orbit(
            fig10, "alpha", (-0.35, -0.42), (-0.0959, -1.962), 1, switch=True, max_period=16, ds_max=0.01
        ),
        args.repeat,
    )
    report["cascade_ds_max_0.01_s"] = round(t_fine, 3)
    report["cascade_ds_max_0.01_points"] = fine.n_points
    for k, v in report.items():
        print(f"{k:28s} {v}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)
    assert np.isfinite(t_grid)


if __name__ == "__main__":
    main()
