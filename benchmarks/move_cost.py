"""What one slider move costs the server: CPU (event loop and whole process) from the move to a settled scene.

    .venv/bin/python benchmarks/move_cost.py [--moves 20] [--settle 1.5] [--json F]

Serves the app (one process, warm), opens one tab the way a browser does (``load_test.Tab``), waits for the
first scene and its layers, then moves ``alpha`` ``--moves`` times. For each move it reads the server's CPU
before the move and ``--settle`` seconds after the full scene (the layers and series that follow it), so the
figure is the whole work one move causes: the event loop's own CPU (``/proc/<pid>/schedstat`` of the main
thread) and the process's (all threads). CPU seconds depend much less on other load than wall times do, so
an A/B of two trees (run this script from each tree) is meaningful on a shared machine; the wall time to the
full scene is printed too. This is the cost behind ``load_test.py``'s "move -> full scene" under 30 sessions.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
import load_test as lt
from harness import serve
from session_cost import loop_cpu_s


def _ms(xs: list[float]) -> dict[str, float]:
    s = sorted(xs)
    return {"n": len(s), "median": round(1e3 * statistics.median(s), 1), "max": round(1e3 * s[-1], 1)}


async def measure(server: Any, moves: int, settle: float) -> dict[str, Any]:
    pid = server.pid
    await lt._warm_up(server, 1)
    tab = lt.Tab(server, "m0")
    await tab.open(120)
    await asyncio.sleep(2 * settle)
    loop_s, proc_s, full_s = [], [], []
    for i in range(moves):
        value = lt.DEFAULT_ALPHA + (0.002 if i % 2 else -0.002) * (1 + i % 5)
        l0, c0 = loop_cpu_s(pid), lt.proc_status(pid)["cpu_s"]
        change = await tab.change("alpha", value)
        await asyncio.sleep(settle)
        loop_s.append(loop_cpu_s(pid) - l0)
        proc_s.append(lt.proc_status(pid)["cpu_s"] - c0)
        if change.full_s is not None:
            full_s.append(change.full_s)
    await tab.close()
    return {
        "moves": moves,
        "event_loop_cpu_ms": _ms(loop_s),
        "process_cpu_ms": _ms(proc_s),
        "wall_full_scene_ms": _ms(full_s) if full_s else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=20)
    ap.add_argument("--settle", type=float, default=1.5, help="seconds after the full scene counted with the move")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args()
    with serve("/tmp/move_cost_panel.log", session_lifetime=3000) as server:
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            t0 = time.perf_counter()
            report = pool.submit(asyncio.run, measure(server, args.moves, args.settle)).result()
            report["wall_s"] = round(time.perf_counter() - t0, 1)
    report["command"] = " ".join(sys.argv)
    text = json.dumps(report, indent=1)
    if args.json:
        Path(args.json).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
