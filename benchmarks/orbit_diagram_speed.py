"""The Fig. 10 orbit diagram at 400 values x (500 transient + 200 points): seedings and lock-step, in one run.

    .venv/bin/python benchmarks/orbit_diagram_speed.py [--values 400] [--rounds 3] [--json out.json]

Modes, alternating round by round in this process after a warm-up (medians over rounds), both cores:
``continuation`` (forward and backward sweeps side by side, the command line's default), ``fixed``
(every value from the same IC, values one by one in threads: ``lockstep=False``) and ``lockstep``
(fixed seeding, every value at once in lock-step blocks with per-member coefficients, the default for
fixed seeding). The lock-step diagram is compared with the value-by-value one: the period detected at
each value (``OrbitDiagram.periods``, tol 1e-5) and, where both see the same period, the largest
distance from a point of one cycle to the nearest point of the other (the phase may differ).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.sweeps import sweep_values
from explorer_core.scenes import get_scene
from explorer_core.warm import warm_all

IC = (-0.0959, -1.962)


def cycle_distance(x: np.ndarray, y: np.ndarray, p: int) -> float:
    """Largest distance from a point of ``y``'s last cycle of ``p`` points to the nearest of ``x``'s (any phase)."""
    cx, cy = x[-p:], y[-p:]
    return float(np.abs(cy[:, None, :] - cx[None, :, :]).max(axis=2).min(axis=1).max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--values", type=int, default=400)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json")
    args = ap.parse_args()
    warm_all()
    params = get_scene("fig10").params
    values = sweep_values((-0.42, -0.35), args.values)
    kw = {"points": 200, "transient": 500, "ics": [IC]}
    modes = {
        "continuation": lambda: bifurcation_diagram(params, "alpha", values, seeding="continuation", **kw),
        "fixed": lambda: bifurcation_diagram(params, "alpha", values, seeding="fixed", lockstep=False, **kw),
        "lockstep": lambda: bifurcation_diagram(params, "alpha", values, seeding="fixed", **kw),
    }
    times: dict[str, list[float]] = {m: [] for m in modes}
    last = {}
    for r in range(args.rounds):
        for name, fn in modes.items():
            t = time.perf_counter()
            last[name] = fn()
            times[name].append(time.perf_counter() - t)
            print(f"round {r + 1} {name}: {times[name][-1]:.2f} s", flush=True)
    a, b = last["fixed"], last["lockstep"]
    pa, pb = a.periods(tol=1e-5)[0, :, 0], b.periods(tol=1e-5)[0, :, 0]
    both = (pa > 0) & (pa == pb)
    dist = [cycle_distance(a.points[0, v, 0], b.points[0, v, 0], int(pa[v])) for v in np.flatnonzero(both)]
    report = {
        "values": args.values,
        "rounds": args.rounds,
        "s": {m: round(statistics.median(t), 2) for m, t in times.items()},
        "all_s": {m: [round(x, 2) for x in t] for m, t in times.items()},
        "same_period_fraction": round(float(np.mean(pa == pb)), 4),
        "differing_values": [(float(values[v]), int(pa[v]), int(pb[v])) for v in np.flatnonzero(pa != pb)],
        "cycles_max_point_distance": max(dist) if dist else None,
        "cycles_compared": len(dist),
    }
    for k, v in report.items():
        print(f"{k}: {v}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
