"""The chart of regimes, old and new ways, in one run (issue: heavy analyses at the paper's resolution).

    .venv/bin/python benchmarks/chart_speed.py [--grid 60,30] [--modes reference,pixels,refined]
        [--old /path/to/old/checkout] [--rounds 1] [--ics 2] [--transient 500] [--periods 500] [--json out.json]

Fig. 11's chart (its scene's window, the two initial conditions of the paper's Fig. 11 discussion, 500
transient + 500 measured periods, today's classification; ``--ics 1 --transient 300 --periods 300``
is the app's preview), on both cores, in these modes (each in a
child process of its own, the modes alternating round by round; times are medians over rounds):

``reference``
    :func:`~explorer_core.analyses.regimes.compute_tile_each` tile by tile: every pixel and IC the whole
    way with the tangent system -- the classification every other mode is compared with;
``old``
    ``regime_chart`` of the checkout given by ``--old`` (e.g. ``git worktree add /tmp/ab-old main``);
``pixels``
    ``regime_chart``: every pixel computed, members stop early (cycles, escape, chaos);
``refined``
    ``regime_chart(refine=True)``: the coarse lattice, then only where neighbours differ.

Prints each mode's time and time per pixel-IC, and for each mode against the first one the fraction of
pixel-ICs with the same regime and period, and every difference with whether it lies on a boundary of
the first mode's chart (a neighbouring pixel has another regime or period for that IC) and whether the
refined chart inferred it.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]
ICS = [(-0.09, -2.0), (-0.5, -1.0)]


def child(mode: str, grid: tuple[int, int], out: str, ics: list, transient: int, periods: int) -> None:
    """Compute the chart one way in this process; write its arrays and time to ``out``."""
    if mode == "old":  # the checkout on PYTHONPATH, not the editable install's (see engine_ab.py)
        for finder in list(sys.meta_path):
            if "editable" in getattr(finder, "__name__", type(finder).__name__).lower():
                sys.meta_path.remove(finder)
    import time
    from concurrent.futures import ThreadPoolExecutor

    import explorer_core
    from explorer_core import config
    from explorer_core.analyses.regimes import Chart, chart_spec, compute_tile_each, plan_tiles, regime_chart
    from explorer_core.scenes import get_scene
    from explorer_core.warm import warm_all

    if mode == "old":
        assert Path(explorer_core.__file__).resolve().is_relative_to(Path(os.environ["PYTHONPATH"]).resolve())
    warm_all()
    scene = get_scene("fig11")
    c = scene.extra["chart"]
    spec = chart_spec(scene.params, c["x_param"], c["x_range"], c["y_param"], c["y_range"], grid, ics=ics,
                      transient=transient, periods=periods)  # fmt: skip
    inferred = np.zeros(spec.shape, dtype=bool)
    t = time.perf_counter()
    if mode == "reference":
        chart = Chart.empty(spec)
        with ThreadPoolExecutor(config.N_WORKERS) as pool:
            for res in pool.map(lambda tile: compute_tile_each(spec, tile), plan_tiles(spec.shape)):
                chart.add(res)
    elif mode == "refined":
        chart = regime_chart(spec, workers=config.N_WORKERS, refine=True)
        inferred = chart.inferred
    else:
        chart = regime_chart(spec, workers=config.N_WORKERS)
    elapsed = time.perf_counter() - t
    np.savez(out, regime=chart.regime, period=chart.period, lyap=chart.lyap, inferred=inferred, elapsed=elapsed,
             x=spec.x_values, y=spec.y_values)  # fmt: skip


def on_boundary(code: np.ndarray, j: int, i: int, k: int) -> bool:
    """True if a pixel next to ``(j, i)`` (8 neighbours) has another code for initial condition ``k``."""
    block = code[max(0, j - 1) : j + 2, max(0, i - 1) : i + 2, k]
    return bool(np.any(block != code[j, i, k]))


def describe(ch: dict, j: int, i: int, k: int) -> list:
    """``[regime name, period, exponent]`` of one pixel-IC."""
    from explorer_core.analyses.regimes import REGIMES

    return [REGIMES[int(ch["regime"][j, i, k])], int(ch["period"][j, i, k]), round(float(ch["lyap"][j, i, k]), 5)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", default="60,30")
    ap.add_argument("--modes", default="reference,pixels,refined")
    ap.add_argument("--old", help="checkout of the old code (mode 'old')")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--ics", type=int, default=2, choices=(1, 2), help="initial conditions per pixel")
    ap.add_argument("--transient", type=int, default=500)
    ap.add_argument("--periods", type=int, default=500)
    ap.add_argument("--json")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--child-out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    grid = tuple(int(v) for v in args.grid.split(","))
    ics = ICS[: args.ics]
    if args.child:
        child(args.child, grid, args.child_out, ics, args.transient, args.periods)
        return
    modes = args.modes.split(",")
    if "old" in modes and not args.old:
        ap.error("mode 'old' needs --old CHECKOUT")
    times: dict[str, list[float]] = {m: [] for m in modes}
    charts: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for mode in modes:
                out = os.path.join(tmp, f"{mode}.npz")
                env = dict(os.environ)
                if mode == "old":
                    env["PYTHONPATH"] = str(Path(args.old).resolve())
                cmd = [sys.executable, __file__, "--grid", args.grid, "--child", mode, "--child-out", out, "--ics",
                       str(args.ics), "--transient", str(args.transient), "--periods", str(args.periods)]  # fmt: skip
                subprocess.run(cmd, check=True, env=env)
                with np.load(out) as z:
                    charts[mode] = {k: z[k] for k in z.files}
                times[mode].append(float(charts[mode]["elapsed"]))
                print(f"round {r + 1} {mode}: {times[mode][-1]:.2f} s", flush=True)
    n = grid[0] * grid[1] * len(ics)
    base = modes[0]
    ref = charts[base]
    ref_code = np.where(ref["regime"] == 1, ref["period"].astype(np.int64), -ref["regime"].astype(np.int64))
    report: dict = {"grid": list(grid), "ics": ics, "transient": args.transient, "periods": args.periods,
                    "rounds": args.rounds, "modes": {}}  # fmt: skip
    for mode in modes:
        ch = charts[mode]
        med = statistics.median(times[mode])
        entry = {
            "s": round(med, 2),
            "all_s": [round(t, 2) for t in times[mode]],
            "ms_per_pixel_ic": round(1e3 * med / n, 3),
        }
        if mode != base:
            entry["speedup_vs_" + base] = round(statistics.median(times[base]) / med, 2)
            differ = np.argwhere((ch["regime"] != ref["regime"]) | (ch["period"] != ref["period"]))
            entry["identical_fraction"] = round(1 - len(differ) / n, 5)
            entry["inferred_pixels"] = int(ch["inferred"].sum())
            entry["differences"] = [
                {"j": int(j), "i": int(i), "ic": int(k), "x": float(ch["x"][i]), "y": float(ch["y"][j]),
                 base: describe(ref, j, i, k), mode: describe(ch, j, i, k),
                 "boundary": on_boundary(ref_code, int(j), int(i), int(k)), "inferred": bool(ch["inferred"][j, i])}
                for j, i, k in differ
            ]  # fmt: skip
            entry["differences_off_boundary"] = sum(not d["boundary"] for d in entry["differences"])
        report["modes"][mode] = entry
    for mode, e in report["modes"].items():
        print(mode, {k: v for k, v in e.items() if k != "differences"})
        for d in e.get("differences", []):
            print("  differs:", d)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
