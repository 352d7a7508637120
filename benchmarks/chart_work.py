"""Where a chart's work goes, in load-independent counts (no timings): periods integrated, engine steps, Newton.

    .venv/bin/python benchmarks/chart_work.py [--grid 40,40] [--ics 2] [--reference] [--npz out.npz] [--json out.json]

Fig. 11's chart (its scene's window; the two initial conditions of ``chart_speed.py``; 500 transient + 500
measured periods), every tile of :func:`~explorer_core.analyses.regimes.plan_tiles` computed with
:func:`~explorer_core.analyses.regimes.compute_tile` on two threads (the counts do not depend on the threads).
Prints, per final regime (periodic by period, quasi-periodic, chaotic, escaped, failed): the members, the
periods they integrated (in the transient / the measurement) and the tangent system's steps; Newton's calls on
settled cycles, the periods and steps it integrated; and the tail of the run: tiles scheduled on two workers
in plan order with their steps as the cost (the makespan against half the total).

``--reference`` also computes :func:`~explorer_core.analyses.regimes.compute_tile_each` (every member the whole
way) and prints the pixel-ICs whose regime or period differ, with whether each lies on a boundary of the
reference chart (a neighbouring pixel has another regime or period for that IC).
"""

from __future__ import annotations

import argparse
import heapq
import json
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ICS = [(-0.09, -2.0), (-0.5, -1.0)]


class NewtonWork:
    """Counts of :meth:`PoincareMap.derivative` calls made for settled cycles (thread-safe)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.calls = self.points = self.periods = self.steps = 0
        self.cycles_asked = self.cycles_found = self.batches = 0


def install_counters(work: NewtonWork) -> None:
    """Wrap the map's derivative and the chart's Newton hand-over so they count their work."""
    from explorer_core.analyses import regimes
    from explorer_core.solve.poincare import PoincareMap

    derivative = PoincareMap.derivative

    def counted(self, x, n, members=None):
        mono = derivative(self, x, n, members)
        with work.lock:
            work.calls += 1
            work.points += int(np.asarray(x).reshape(-1, 2).shape[0])
            work.periods += int(n) * int(np.asarray(x).reshape(-1, 2).shape[0])
            work.steps += int(mono.nsteps.sum())
        return mono

    PoincareMap.derivative = counted
    settled = regimes.settled_cycles

    def asked(coefs, x, *a, **kw):
        with work.lock:
            work.batches += 1
            work.cycles_asked += int(np.asarray(x).reshape(-1, 2).shape[0])
        found = settled(coefs, x, *a, **kw)
        with work.lock:
            work.cycles_found += sum(c is not None for c in found)
        return found

    regimes.settled_cycles = asked


def run(spec, fn, threads: int = 2) -> tuple[dict, list]:
    """``fn`` over every tile; the chart's arrays ``[j, i, ic]`` and the tiles' results in plan order."""
    from explorer_core.analyses.regimes import plan_tiles

    tiles = plan_tiles(spec.shape)
    with ThreadPoolExecutor(threads) as pool:
        results = list(pool.map(lambda t: fn(spec, t), tiles))
    ny, nx = spec.shape
    n = spec.ics.shape[0]
    out = {
        name: np.zeros((ny, nx, n), dtype=dt)
        for name, dt in (("regime", np.int8), ("period", np.int16), ("lyap", float), ("status", np.int8),
                         ("periods_run", np.int64), ("steps", np.int64))
    }  # fmt: skip
    for res in results:
        for name in out:
            out[name][res.jj, res.ii] = getattr(res, name)
    return out, results


def kind(regime: int, period: int) -> str:
    from explorer_core.analyses.regimes import REGIMES

    return f"period_{period}" if regime == 1 else REGIMES[regime]


def profile(ch: dict, transient: int) -> dict:
    """Members, periods (transient / measurement) and steps per final regime."""
    rows: dict[str, dict] = {}
    for r, p, ran, st in zip(ch["regime"].ravel(), ch["period"].ravel(), ch["periods_run"].ravel(),
                             ch["steps"].ravel(), strict=True):  # fmt: skip
        e = rows.setdefault(kind(int(r), int(p)), {"members": 0, "transient": 0, "measure": 0, "steps": 0})
        e["members"] += 1
        e["transient"] += int(min(ran, transient))
        e["measure"] += int(max(ran - transient, 0))
        e["steps"] += int(st)
    total = {k: sum(e[k] for e in rows.values()) for k in ("members", "transient", "measure", "steps")}
    for e in rows.values():
        e["periods_per_member"] = round((e["transient"] + e["measure"]) / e["members"], 1)
        e["steps_share"] = round(e["steps"] / max(total["steps"], 1), 3)
    return {"by_regime": dict(sorted(rows.items())), "total": total}


def tail(results: list, newton_steps_by_tile: list | None = None, workers: int = 2) -> dict:
    """Tiles given to ``workers`` in plan order (each to the first free worker), steps as their cost."""
    costs = [int(r.steps.sum()) for r in results]
    free = [(0, w) for w in range(workers)]
    end = 0
    for c in costs:
        t, w = heapq.heappop(free)
        heapq.heappush(free, (t + c, w))
        end = max(end, t + c)
    return {
        "tiles": len(costs),
        "largest_tile_steps": max(costs),
        "makespan_steps": end,
        "half_total_steps": sum(costs) // workers,
        "idle_fraction": round(1 - sum(costs) / (workers * end), 3),
    }


def on_boundary(code: np.ndarray, j: int, i: int, k: int) -> bool:
    block = code[max(0, j - 1) : j + 2, max(0, i - 1) : i + 2, k]
    return bool(np.any(block != code[j, i, k]))


def differences(ch: dict, ref: dict) -> list[dict]:
    code = np.where(ref["regime"] == 1, ref["period"].astype(np.int64), -ref["regime"].astype(np.int64))
    out = []
    for j, i, k in np.argwhere((ch["regime"] != ref["regime"]) | (ch["period"] != ref["period"])):
        out.append({"j": int(j), "i": int(i), "ic": int(k),
                    "reference": [kind(int(ref["regime"][j, i, k]), int(ref["period"][j, i, k])),
                                  round(float(ref["lyap"][j, i, k]), 5)],
                    "chart": [kind(int(ch["regime"][j, i, k]), int(ch["period"][j, i, k])),
                              round(float(ch["lyap"][j, i, k]), 5), int(ch["periods_run"][j, i, k])],
                    "boundary": on_boundary(code, int(j), int(i), int(k))})  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", default="40,40")
    ap.add_argument("--ics", type=int, default=2, choices=(1, 2))
    ap.add_argument("--transient", type=int, default=500)
    ap.add_argument("--periods", type=int, default=500)
    ap.add_argument("--reference", action="store_true", help="also every member the whole way, and compare")
    ap.add_argument("--npz", help="write the per-member arrays here")
    ap.add_argument("--compare", help="a reference's arrays written by --reference --npz (its *_ref.npz)")
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a constant of regimes (e.g. SETTLE_TOL=0.05) to measure its effect",
    )
    ap.add_argument("--json")
    args = ap.parse_args()

    from explorer_core.analyses import regimes
    from explorer_core.analyses.regimes import chart_spec, compute_tile, compute_tile_each
    from explorer_core.scenes import get_scene

    for item in args.set:
        name, value = item.split("=", 1)
        old = getattr(regimes, name)  # only existing constants
        setattr(regimes, name, type(old)(value))

    grid = tuple(int(v) for v in args.grid.split(","))
    scene = get_scene("fig11")
    c = scene.extra["chart"]
    spec = chart_spec(scene.params, c["x_param"], c["x_range"], c["y_param"], c["y_range"], grid,
                      ics=ICS[: args.ics], transient=args.transient, periods=args.periods)  # fmt: skip
    newton = NewtonWork()
    install_counters(newton)
    ch, results = run(spec, compute_tile)
    report = {"grid": list(grid), "ics": args.ics, "transient": args.transient, "periods": args.periods,
              **profile(ch, args.transient),
              "newton": {"hand_overs": newton.cycles_asked, "cycles_found": newton.cycles_found,
                         "batches": newton.batches, "derivative_calls": newton.calls, "points": newton.points,
                         "periods": newton.periods, "steps": newton.steps},
              "tail": tail(results)}  # fmt: skip
    report["total"]["steps_with_newton"] = report["total"]["steps"] + newton.steps
    ref = None
    if args.compare:
        with np.load(args.compare) as z:
            ref = {k: z[k] for k in z.files}
    elif args.reference:
        ref, _ = run(spec, compute_tile_each)
    if ref is not None:
        report["reference_total"] = profile(ref, args.transient)["total"]
        diff = differences(ch, ref)
        report["differences"] = {"count": len(diff), "off_boundary": sum(not d["boundary"] for d in diff),
                                 "list": diff}  # fmt: skip
        if args.npz and args.reference:
            np.savez(args.npz.replace(".npz", "_ref.npz"), **ref)
    if args.npz:
        np.savez(args.npz, **ch)
    for key, val in report.items():
        if key == "by_regime":
            for k, e in val.items():
                print(f"  {k:16s} {e}")
        elif key == "differences":
            print("differences", {k: v for k, v in val.items() if k != "list"})
            for d in val["list"]:
                print("  differs:", d)
        else:
            print(key, val)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
