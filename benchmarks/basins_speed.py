"""Speed of the basins of attraction (issue 14: 200x200 <= 20 s, a 50x50 preview <= 2 s).

    .venv/bin/python benchmarks/basins_speed.py [--repeat 5] [--fig8b] [--json out.json]

Fig. 11's tensor at ``alpha = -0.5, I11 = 1.6`` over Fig. 11's box of initial conditions
``(-1.7, 1.5, -3, 1)``, the defaults of :func:`~explorer_core.analyses.basins.basins` (DOP853 at 1e-8,
both cores): the whole 200x200 computation and a 50x50 preview, each ``--repeat`` times in this process
after the kernels are warm (the first call, which also loads the orbits' and Lyapunov kernels, is timed
apart), and the time to the first coarse level (every 4th pixel) of the 200x200 run. ``--fig8b`` adds
Fig. 8B (a strange attractor and escape) at 200x200. The machine's load before and after is printed:
the numbers are only comparable with the same load.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import time

from explorer_core import config
from explorer_core.analyses.basins import basin_spec, basins, iter_basins
from explorer_core.scenes import get_scene
from explorer_core.warm import warm_all

BOX = (-1.7, 1.5, -3.0, 1.0)


def load() -> str:
    """``uptime`` and the busiest processes (the machine is shared)."""
    up = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    ps = subprocess.run(["ps", "-eo", "pcpu,etime,comm", "--sort=-pcpu"], capture_output=True, text=True).stdout
    return up + "\n" + "\n".join(ps.splitlines()[:6])


def timed(params, grid, repeat: int) -> tuple[list[float], list[float], object]:
    """Wall and CPU seconds (this process, all threads: less sensitive to a shared machine) of each run."""
    times, cpu, res = [], [], None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        res = basins(params, BOX, grid)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return times, cpu, res


def first_level(params, grid) -> tuple[float, float]:
    """Seconds to the first coarse level and to the end, from :func:`iter_basins`."""
    t = time.perf_counter()
    first = None
    for upd in iter_basins(basin_spec(params, BOX, grid)):
        if upd.level_done and first is None:
            first = time.perf_counter() - t
    return float(first or 0.0), time.perf_counter() - t


def describe(res) -> dict:
    s = res.summary()
    n = res.label.size
    return {
        "attractors": [(a["id"], a["kind"], a["period"], round(a["fraction"], 4)) for a in s["attractors"]],
        "statuses": s["statuses"],
        "periods_per_pixel": round(s["periods"] / n, 2),
        "steps_per_pixel": round(s["steps"] / n, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fig8b", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M:%S %Z')}, {config.N_WORKERS} worker threads, pid {os.getpid()}")
    print("load before:\n" + load())
    warm_all()
    params = get_scene("fig11").params.with_(alpha=-0.5, I11=1.6)
    t = time.perf_counter()
    basins(params, BOX, (50, 50))
    cold = time.perf_counter() - t
    out: dict = {"first_call_50x50_s": round(cold, 3)}
    for name, grid in (("50x50", (50, 50)), ("200x200", (200, 200))):
        times, cpu, res = timed(params, grid, args.repeat)
        out[name] = {"median_s": round(statistics.median(times), 3), "min_s": round(min(times), 3),
                     "max_s": round(max(times), 3), "cpu_median_s": round(statistics.median(cpu), 3),
                     "runs": len(times), **describe(res)}  # fmt: skip
        print(f"fig11 tensor {name}: median {out[name]['median_s']} s (min {out[name]['min_s']}, "
              f"max {out[name]['max_s']}, {len(times)} runs; CPU {out[name]['cpu_median_s']} s) "
              f"{describe(res)}")  # fmt: skip
    firsts = [first_level(params, (200, 200)) for _ in range(args.repeat)]
    out["200x200_first_level_s"] = round(statistics.median(f for f, _ in firsts), 3)
    print(f"200x200: first level (every 4th pixel) after {out['200x200_first_level_s']} s (median)")
    if args.fig8b:
        times, cpu, res = timed(get_scene("fig8B").params, (200, 200), max(1, args.repeat // 2))
        out["fig8B_200x200"] = {"median_s": round(statistics.median(times), 3),
                                "cpu_median_s": round(statistics.median(cpu), 3), "runs": len(times),
                                **describe(res)}  # fmt: skip
        print(f"fig8B 200x200: median {out['fig8B_200x200']['median_s']} s (CPU "
              f"{out['fig8B_200x200']['cpu_median_s']} s) {describe(res)}")  # fmt: skip
    print(f"first call in the process (50x50, loads the orbit/Lyapunov kernels): {cold:.2f} s")
    after = load()
    print("load after:\n" + after)
    out["load_after"] = after
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
