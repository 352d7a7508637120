"""Parallel efficiency: each analysis as typed, on one thread and on two, in separate processes (issue 32, item 2).

    .venv/bin/python benchmarks/parallel_efficiency.py [--rounds 3] [--only chart,basins] [--json out.json]

Every case is a ``bilimovich`` command run in-process (``explorer_core.cli.main``, output to a temporary folder,
the printed result discarded) by a child process started with ``BILIMOVICH_THREADS=n`` (the pool of the kernels
and of the analyses' tasks; ``NUMBA_NUM_THREADS=n`` is set too, though no kernel uses numba's own threads) and
``BILIMOVICH_WORKER=0``. The child runs the command once untimed (the kernels' cache loaded, the scene built),
then ``--repeat`` times timed: the median wall seconds and the process's CPU seconds over that wall (the cores
it kept busy). Rounds alternate 1 and 2 threads; the table gives the medians over rounds and ``speed-up =
wall(1) / wall(2)`` (2.0 is perfect on two cores). Process start-up (~1 s of imports) is not in the figures:
it is the same on one core or two. "In kernels" is the share of the one-thread wall time spent inside the
engines' block kernels (``rk.advance_blocks``, ``taylor.advance_blocks``: they release the GIL); the rest is
Python and numpy, one thread at a time, so "bound" = 1 / ((1 - share) + share / 2) is the speed-up two threads
could give if the kernels' work split perfectly (numpy releases the GIL in parts of the rest: a rough bound).
Each case takes well under 20 s on one thread; quote the machine load
printed beside the table. "Cores busy" with one thread well below 1.0 says the machine was shared (other work
took the cores): the speed-up is then contention, not the analysis' parallel efficiency; run it on a quiet
machine.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]

FIG11_CHART = ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.6,-0.4", "--y-param", "I11",
               "--y-range", "1,2", "--ic", "-0.09,-2", "--ic", "-0.5,-1", "--out", "ch.npz", "--quiet"]  # fmt: skip

#: name -> the command line (after ``bilimovich``); small but representative sizes.
CASES: dict[str, list[str]] = {
    "section (200 ICs x 1000 periods, auto, rtol 1e-12)": [
        "section", "--inertia", "1,4,2,0,0,0", "--alpha", "0.1", "--random", "200", "--seed", "1",
        "--box=-1,1,-1,1", "--periods", "1000", "--method", "auto", "--rtol", "1e-12", "--json"],
    "chart (fig11 20x20 px x 2 ICs, every pixel)": [*FIG11_CHART, "--grid", "20,20"],
    "basins (alpha -0.5, I11 1.6, 40x40)": [
        "basins", "--inertia", "1.6,2,4,0,0.5,0.3", "--alpha", "-0.5", "--box=-1.7,1.5,-3,1", "--grid", "40,40",
        "--out", "b.npz", "--quiet"],
    "orbit diagram (fig10, 100 values x (500 + 200))": [
        "bifurcation", "--scene", "fig10", "--param", "alpha", "--range", "-0.42,-0.35", "--n-values", "100",
        "--transient", "500", "--points", "200", "--out", "od.csv", "--quiet"],
    "continuation (fig10 period 1, switch)": [
        "continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.42", "--from=-0.0959,-1.962",
        "--period", "1", "--switch", "--json"],
}  # fmt: skip


def kernel_clock() -> list[float]:
    """Wrap the engines' block kernels (which release the GIL) so that their seconds add up in the returned list's
    one entry: with one thread, the rest of a command's wall time is Python and numpy holding (mostly) the GIL."""
    from explorer_core.solve import rk, taylor

    spent = [0.0]
    lock = threading.Lock()
    for mod in (rk, taylor):

        def timed(*args, _inner=mod.advance_blocks):
            t0 = time.perf_counter()
            try:
                return _inner(*args)
            finally:
                with lock:
                    spent[0] += time.perf_counter() - t0

        mod.advance_blocks = timed
    return spent


def child(names: list[str], repeat: int) -> dict:
    """Time ``names`` in this process (threads from the environment): median wall and CPU seconds of each, and
    the seconds inside the engines' kernels (summed over threads)."""
    from explorer_core import cli, config

    kernels = kernel_clock()
    out = {"threads": config.N_WORKERS}
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        for name in names:
            argv = CASES[name]
            walls, cpus, kern = [], [], []
            for i in range(repeat + 1):
                w, c, k = time.perf_counter(), time.process_time(), kernels[0]
                with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                    status = cli.main(argv)
                if status:
                    raise SystemExit(f"{name}: exit status {status}")
                if i:  # the first run loads the kernels and builds the scene
                    walls.append(time.perf_counter() - w)
                    cpus.append(time.process_time() - c)
                    kern.append(kernels[0] - k)
            out[name] = {"wall": statistics.median(walls), "cpu": statistics.median(cpus),
                         "kernel": statistics.median(kern)}  # fmt: skip
    return out


def run_child(threads: int, names: list[str], repeat: int) -> dict:
    env = {**os.environ, "BILIMOVICH_THREADS": str(threads), "NUMBA_NUM_THREADS": str(threads),
           "BILIMOVICH_WORKER": "0", "PYTHONPATH": str(HERE)}  # fmt: skip
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--repeat", str(repeat), "--only", ",".join(names)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if proc.returncode:
        raise SystemExit(proc.stderr[-2000:])
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    if res["threads"] != threads:
        raise SystemExit(f"asked for {threads} threads, the child has {res['threads']} (usable CPUs?)")
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="child processes per thread count (alternating)")
    ap.add_argument("--repeat", type=int, default=1, help="timed runs per case in each child")
    ap.add_argument("--only", help="comma-separated prefixes of case names (section, chart, basins, orbit, cont)")
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    names = list(CASES)
    if args.only:
        names = [n for n in CASES if any(n.startswith(p) for p in args.only.split(","))]
    if args.child:
        print(json.dumps(child(names, args.repeat)))
        return
    load0 = os.getloadavg()
    figs: dict[int, dict[str, dict[str, list[float]]]] = {1: {}, 2: {}}
    for rnd in range(args.rounds):
        for threads in (1, 2) if rnd % 2 == 0 else (2, 1):
            res = run_child(threads, names, args.repeat)
            for name in names:
                for key in ("wall", "cpu", "kernel"):
                    figs[threads].setdefault(name, {}).setdefault(key, []).append(res[name][key])
    report = {"load": [load0[0], os.getloadavg()[0]], "rounds": args.rounds, "cases": table(figs)}
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    print(f"load average before {report['load'][0]:.2f} / after {report['load'][1]:.2f} (1 min); {args.rounds} "
          "rounds, medians")  # fmt: skip


def table(figs: dict[int, dict[str, dict[str, list[float]]]]) -> dict[str, dict[str, float]]:
    """Print the table of the medians over rounds (``figs[threads][case][wall or cpu]``); its rows as a dict."""
    print(f"{'case':52s} {'1 thread s':>10s} {'2 threads s':>11s} {'speed-up':>8s} {'cores busy 1 / 2':>16s} "
          f"{'in kernels 1 thread':>19s} {'bound':>5s}")  # fmt: skip
    rows = {}
    for name, one in figs[1].items():
        w1, w2 = statistics.median(one["wall"]), statistics.median(figs[2][name]["wall"])
        busy1, busy2 = statistics.median(one["cpu"]) / w1, statistics.median(figs[2][name]["cpu"]) / w2
        share = min(1.0, statistics.median(one["kernel"]) / w1)
        # Amdahl with the GIL: the time outside the kernels runs one thread at a time, the kernels' time halves
        bound = 1.0 / ((1.0 - share) + share / 2.0)
        rows[name] = {"wall_1": w1, "wall_2": w2, "speedup": w1 / w2, "cores_busy_1": busy1, "cores_busy_2": busy2,
                      "kernel_share_1": share, "speedup_bound": bound}  # fmt: skip
        print(f"{name:52s} {w1:10.2f} {w2:11.2f} {w1 / w2:8.2f} {busy1:8.2f} / {busy2:5.2f} {share:19.2f} "
              f"{bound:5.2f}")  # fmt: skip
    return rows


if __name__ == "__main__":
    main()
