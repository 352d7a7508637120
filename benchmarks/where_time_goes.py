"""Where the time goes against heyoka (issue 32): steps, evaluations, the cost of a step and of a member.

    .venv/bin/python benchmarks/where_time_goes.py [--case regular|attractor] [--ics 64] [--periods 200]
        [--tol 1e-12] [--repeat 5] [--blocks 1,4,8,16,32,64]

The cases and ICs are those of ``benchmarks/high_accuracy.py`` (regular: diag(1, 4, 2), alpha 0.1, random ICs in
[-1, 1]^2; attractor: Fig. 8B on its attractor), heyoka on the peers' field (``bench.peer_fields``: the closed
form for the diagonal tensor), everything on one thread in this process, interleaved, median of ``--repeat``.

Printed:

1. Counts, independent of the machine's load: steps per period (heyoka's from its scalar integrator, whose
   steps are those of each member of its batch; ours accepted + rejected per member), heyoka's Taylor order,
   right-hand-side evaluations per period (ours: stages x steps).
2. Cost per step and per evaluation: heyoka batch x8 and our lock-step blocks (vern9 and dop853, adaptive, blocks
   of 32 as by default and of 64), and our same kernel at fixed steps, the same number per period (no error
   control, no rejected steps: the arithmetic of the stages alone; fixed steps run in blocks of
   ``integrators.FIXED_BLOCK`` = 64, so they are compared with the adaptive blocks of 64). ns per member-step;
   ours also per member-evaluation (/ stages), heyoka per member-step per order (its Taylor coefficients are
   computed order by order).
3. The gap as a product: time(ours) / time(heyoka) = (steps ours / steps heyoka) x (ns per step ours / heyoka).
4. Per-member cost against the lock-step block size (vern9 at ``--tol``): members of a block share one step
   sequence, so a bigger block pays the coefficients less often per member but takes the smallest step any
   member needs.

``--command N`` instead times the issue's section as the user types it (``bilimovich section --inertia
1,4,2,0,0,0 --alpha 0.1 --random 200 --seed 1 --box=-1,1,-1,1 --periods 1000 --method auto --rtol TOL --json``)
as a whole process, N times after one untimed run (the warm worker started, if it is on), beside the same
command for one period (the fixed cost: start-up, spec, worker round trip, output), ``import explorer_core.cli``
alone (what a command run by this process loads) and ``import explorer_core.worker`` (what the console script's
client loads to hand a command to the worker), and heyoka's batch x8 on one thread in this process on the same 200
ICs x 1000 periods at the same tolerance (compiled outside the timing): medians, and our wall x cores over heyoka's
time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from high_accuracy import STAGES, attractor_ics, heyoka_points, heyoka_steps

from explorer_core import config
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import random_ics
from explorer_core.studies import bench
from explorer_core.system.model import Model
from explorer_core.system.params import Params


def ours(model: Model, ics: np.ndarray, periods: int, method: str, tol: float, block: int, fixed: int = 0) -> float:
    """Run ours on one thread; steps per period per member (accepted + rejected)."""
    p = model.params
    b = Batch.start(ics, p.t0, p.period)
    kw = {"adaptive": False, "steps_per_period": fixed} if fixed else {}
    advance(model, b, periods, method=method, rtol=tol, atol=tol, workers=1, block=block, store=False, **kw)
    return float(b.nsteps.mean()) / periods


def timed(runs: dict, repeat: int) -> dict[str, float]:
    """Median seconds of each run, interleaved (order reversed every other round); one untimed warm-up each."""
    for f in runs.values():
        f()
    times: dict[str, list[float]] = {k: [] for k in runs}
    for r in range(repeat):
        for k in list(runs) if r % 2 == 0 else list(runs)[::-1]:
            t0 = time.perf_counter()
            runs[k]()
            times[k].append(time.perf_counter() - t0)
    return {k: statistics.median(v) for k, v in times.items()}


SECTION = ["section", "--inertia", "1,4,2,0,0,0", "--alpha", "0.1", "--random", "200", "--seed", "1",
           "--box=-1,1,-1,1", "--method", "auto", "--json"]  # fmt: skip


def whole_command(runs: int, tol: float) -> None:
    """The section as typed, whole process, against heyoka on the same work (see the module docstring)."""

    def wall(cmd: list[str]) -> float:
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - t0

    # The console script as the user types it (``python -m explorer_core`` is the same entry where it is not
    # installed); ``python -m explorer_core.cli`` would load the command line before handing the command over.
    script = Path(sys.executable).with_name("bilimovich")
    cli = [str(script)] if script.exists() else [sys.executable, "-m", "explorer_core"]
    cmds = {"section 200 ICs x 1000 periods": [*cli, *SECTION, "--periods", "1000", "--rtol", f"{tol:g}"],
            "section 200 ICs x 1 period": [*cli, *SECTION, "--periods", "1", "--rtol", f"{tol:g}"],
            "import explorer_core.cli": [sys.executable, "-c", "import explorer_core.cli"],
            "import of the client": [sys.executable, "-c", "import explorer_core.worker"]}  # fmt: skip
    model = Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1))
    ics = random_ics(200, (-1.0, 1.0, -1.0, 1.0), seed=1)
    heyoka_points(model, ics[:8], 1, tol)  # compiled outside the timing
    times: dict[str, list[float]] = {k: [] for k in [*cmds, "heyoka batch x8, 1 thread"]}
    for cmd in cmds.values():
        wall(cmd)  # untimed: the kernels' cache, the warm worker
    for _ in range(runs):
        for name, cmd in cmds.items():
            times[name].append(wall(cmd))
        t0 = time.perf_counter()
        heyoka_points(model, ics, 1000, tol)
        times["heyoka batch x8, 1 thread"].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(
        f"whole command at tol {tol:g}, {runs} runs, medians; {config.N_WORKERS} cores; load {os.getloadavg()[0]:.2f}"
    )
    for k, v in med.items():
        print(f"  {k}: {v:.3f} s (runs {', '.join(f'{x:.3f}' for x in times[k])})")
    ours, fixed, hy = (med[k] for k in ("section 200 ICs x 1000 periods", "section 200 ICs x 1 period",
                                        "heyoka batch x8, 1 thread"))  # fmt: skip
    cores = config.N_WORKERS
    print(f"  ours wall x {cores} cores / heyoka: {ours * cores / hy:.2f}; without the one-period command's fixed "
          f"cost: {(ours - fixed) * cores / hy:.2f}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=("regular", "attractor"), default="regular")
    ap.add_argument("--ics", type=int, default=64)
    ap.add_argument("--periods", type=int, default=200)
    ap.add_argument("--tol", type=float, default=1e-12)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--blocks", default="1,4,8,16,32,64")
    ap.add_argument("--command", type=int, default=0, help="time the section command as typed this many times")
    a = ap.parse_args()
    if bench.heyoka_status()[0] is None:
        raise SystemExit(f"heyoka not available: {bench.heyoka_status()[1]}")
    if a.command:
        whole_command(a.command, a.tol)
        return
    if a.case == "regular":
        model = Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1))
        ics = random_ics(a.ics, (-1.0, 1.0, -1.0, 1.0), seed=0)
    else:
        scene = get_scene("fig8B")
        model = Model(scene.params)
        ics = attractor_ics(model, a.ics, scene.box)
    n, k, tol = a.ics, a.periods, a.tol
    print(f"{a.case}: {n} ICs x {k} periods at tol {tol:g}, one thread, median of {a.repeat} interleaved runs; "
          f"load {os.getloadavg()[0]:.2f}")  # fmt: skip
    for peer, text in bench.peer_fields(model.params).items():
        print(f"  {peer}: {text}")
    hy_spp, order = heyoka_steps(model, ics, k, tol)
    spp = {m: ours(model, ics, k, m, tol, 32) for m in ("vern9", "dop853")}
    spp64 = {m: ours(model, ics, k, m, tol, 64) for m in spp}
    runs = {"heyoka batch x8": lambda: heyoka_points(model, ics, k, tol)}
    for m in spp:
        runs[f"{m} block 32"] = lambda m=m: ours(model, ics, k, m, tol, 32)
        runs[f"{m} block 64"] = lambda m=m: ours(model, ics, k, m, tol, 64)
        runs[f"{m} fixed steps"] = lambda m=m: ours(model, ics, k, m, tol, 32, max(1, round(spp[m])))
    sec = timed(runs, a.repeat)
    member_steps = {"heyoka batch x8": hy_spp * n * k}
    for m in spp:
        member_steps[f"{m} block 32"] = spp[m] * n * k
        member_steps[f"{m} block 64"] = spp64[m] * n * k
        member_steps[f"{m} fixed steps"] = max(1, round(spp[m])) * n * k
    print(f"\nheyoka: order {order}, {hy_spp:.1f} steps / period; vern9 {spp['vern9']:.1f} steps / period "
          f"({STAGES['vern9'] * spp['vern9']:.0f} evaluations), dop853 {spp['dop853']:.1f} "
          f"({STAGES['dop853'] * spp['dop853']:.0f})\n")  # fmt: skip
    print("| run | time s | time / heyoka | ns per member-step | ns per member-evaluation (ours) or per order |")
    print("|---|---|---|---|---|")
    hy_ns = 1e9 * sec["heyoka batch x8"] / member_steps["heyoka batch x8"]
    for name, s in sec.items():
        ns = 1e9 * s / member_steps[name]
        per = ns / order if name.startswith("heyoka") else ns / STAGES[name.split()[0]]
        print(f"| {name} | {s:.3f} | {s / sec['heyoka batch x8']:.2f} | {ns:.0f} | {per:.1f} |")
    print()
    for m in spp:
        steps = spp[m] / hy_spp
        cost = 1e9 * sec[f"{m} block 32"] / member_steps[f"{m} block 32"] / hy_ns
        control = (
            sec[f"{m} block 64"]
            / member_steps[f"{m} block 64"]
            / (sec[f"{m} fixed steps"] / member_steps[f"{m} fixed steps"])
        )
        print(f"{m}: time / heyoka {sec[f'{m} block 32'] / sec['heyoka batch x8']:.2f} = steps {steps:.2f}x heyoka's "
              f"x cost per step {cost:.2f}x heyoka's (error control: x{control:.2f} per member-step, adaptive "
              "against fixed steps, both in blocks of 64)")  # fmt: skip
    print("\n| block | vern9 steps / period per member | ns per member-step | time s | time / block 32 |")
    print("|---|---|---|---|---|")
    blocks = [int(b) for b in a.blocks.split(",")]
    bspp = {b: ours(model, ics, k, "vern9", tol, b) for b in blocks}
    bsec = timed({b: lambda b=b: ours(model, ics, k, "vern9", tol, b) for b in [*blocks, 32]}, a.repeat)
    for b in blocks:
        print(f"| {b} | {bspp[b]:.1f} | {1e9 * bsec[b] / (bspp[b] * n * k):.0f} | {bsec[b]:.3f} | "
              f"{bsec[b] / bsec[32]:.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
