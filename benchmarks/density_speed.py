"""Speed and memory of million-point sections drawn as a density image (issue: the structure of the phase plane).

    .venv/bin/python benchmarks/density_speed.py [--repeat 3] [--skip-10m] [--json out.json]

* core: Fig. 8B, ``n`` random ICs x ``periods`` (after the scene's 100-period transient) binned into an
  800 x 600 image of the scene's window (``explorer_core.analyses.density``): time to the first image
  (the first chunk after the transient), to the whole image, and the growth of the process's peak RSS;
* in the browser: the served app opened at ``?scene=fig8B&n=N&periods=P&render=density`` in headless
  Chromium: time from navigation to the first density image in the page and to the finished run, and
  the server's resident memory (VmRSS) and peak (VmHWM) after it.

Medians of ``--repeat`` runs (core) after a warm-up; one browser run per size (a fresh server each).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time
from pathlib import Path

from explorer_core.analyses.density import iter_density
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import random_ics
from explorer_core.warm import warm_all

SIZES = {"1e6": (1000, 1000), "1e7": (10_000, 1000)}


def core_run(n: int, periods: int) -> tuple[float, float, int]:
    s = get_scene("fig8B")
    ics = random_ics(n, s.box, seed=1)
    t = time.perf_counter()
    first = None
    last = None
    for img, _ in iter_density(s.params, ics, periods, view=(*s.q_range, *s.r_range), pixels=(800, 600),
                               transient=s.transient, max_chunk=32):  # fmt: skip
        first = first if first is not None else time.perf_counter() - t
        last = img
    return first or 0.0, time.perf_counter() - t, last.points if last else 0


def vm(pid: int, key: str) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024
    return float("nan")


def browser_run(n: int, periods: int) -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
    from harness import CHROMIUM, CHROMIUM_ARGS, serve, wait_finished
    from playwright.sync_api import sync_playwright

    with serve("/tmp/density_speed_panel.log") as server, sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = b.new_page(viewport={"width": 1280, "height": 720})
        page.goto(server.url + "?scene=fig8B&tracks=0")  # the server's first page (templates, caches) first
        wait_finished(page, timeout=120)
        rss0 = vm(server.pid, "VmRSS")
        t = time.perf_counter()
        page.goto(server.url + f"?scene=fig8B&n={n}&periods={periods}&render=density&tracks=0")
        page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0 && "
                               "Bokeh.documents[0].get_model_by_name('density_source')?.get_length() > 0",
                               timeout=300_000)  # fmt: skip
        first = time.perf_counter() - t
        status = wait_finished(page, timeout=600)
        done = time.perf_counter() - t
        out = {"first_image_s": round(first, 3), "finished_s": round(done, 3), "status": status,
               "server_rss_before_mb": round(rss0, 1), "server_rss_after_mb": round(vm(server.pid, "VmRSS"), 1),
               "server_peak_mb": round(vm(server.pid, "VmHWM"), 1)}  # fmt: skip
        b.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-10m", action="store_true", help="only the 10^6-point runs")
    ap.add_argument("--json")
    args = ap.parse_args()
    warm_all()
    core_run(50, 20)
    sizes = {k: v for k, v in SIZES.items() if not (args.skip_10m and k == "1e7")}
    rows = {}
    print(f"load average {os.getloadavg()[0]:.2f}")
    for name, (n, periods) in sizes.items():
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        runs = [core_run(n, periods) for _ in range(1 if name == "1e7" else args.repeat)]
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - rss0
        first = statistics.median(r[0] for r in runs)
        total = statistics.median(r[1] for r in runs)
        rows[name] = {"n": n, "periods": periods, "points": runs[0][2], "core_first_image_s": round(first, 3),
                      "core_total_s": round(total, 3), "core_peak_rss_growth_mb": round(peak, 1)}  # fmt: skip
        print(f"core {name}: {runs[0][2]:,} points, first image {first:.2f} s, all {total:.2f} s, "
              f"peak RSS +{peak:.0f} MB")  # fmt: skip
    for name, (n, periods) in sizes.items():
        b = browser_run(n, periods)
        rows[name].update({f"browser_{k}": v for k, v in b.items()})
        print(
            f"browser {name}: first image {b['first_image_s']:.2f} s, finished {b['finished_s']:.2f} s, server RSS "
            f"{b['server_rss_before_mb']:.0f} -> {b['server_rss_after_mb']:.0f} MB (peak {b['server_peak_mb']:.0f})"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
