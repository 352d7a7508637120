"""Is the "plot" accuracy what it says? Section points of regular orbits against solve_ivp, in pixels.

    .venv/bin/python benchmarks/plot_accuracy.py [--scenes fig1A,fig1B] [--ics 16] [--json out.json]
        [--per-period C]

For every section scene of the paper (or those given): of the scene's first ``--ics`` seeded
initial conditions, the first ``--max-orbits`` on regular orbits (a perturbation grows less than
1000-fold over the scene's periods, ``explorer_core.studies.bench.amplification``) are integrated at the
scene's "plot" tolerance (``explorer_core.scenes.plot_tolerance``; ``--per-period C`` tries another calibration) and
compared, point by point, with ``explorer_core.studies.bench.reference`` (scipy's ``solve_ivp`` DOP853 at
1e-13, cached on disk). Prints, per scene, the largest and the median error in pixels of the
scene's plot window (800 across): the promise is under a quarter pixel.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from explorer_core import scenes
from explorer_core.solve.section import section
from explorer_core.studies.bench import amplification, reference, regular_members


def measure(scene_id: str, n_ics: int, cache_dir: str | None, max_orbits: int = 6) -> dict:
    sc = scenes.get_scene(scene_id)
    n = sc.periods + sc.transient
    ics = sc.initial_conditions()[:n_ics]
    px = sc.pixel_size()
    num = sc.numerics()
    amp = amplification(sc.params, ics, n)
    regular = regular_members(amp)[:max_orbits]
    row = {"scene": scene_id, "periods": n, "tol": num.rtol, "pixel": px, "ics": len(ics), "regular": len(regular)}
    if not regular:
        return row
    t = time.perf_counter()
    sec = section(sc.params, ics[regular], sc.periods, transient=sc.transient, numerics=num)
    row["ours_s"] = round(time.perf_counter() - t, 3)
    errs = []
    for j, i in enumerate(regular):
        ref = reference(sc.params, ics[i], n, cache_dir_=cache_dir)
        if ref.periods < n or sec.npts[j] < sc.periods:
            continue
        e = np.linalg.norm(sec.points[j, : sc.periods] - ref.points[sc.transient : n], axis=1)
        errs.append({"ic": ics[i].tolist(), "max_px": float(e.max() / px), "ref_bound_px": float(ref.bound / px)})
    row["orbits"] = errs
    if errs:
        row["max_px"] = max(e["max_px"] for e in errs)
        row["median_px"] = float(np.median([e["max_px"] for e in errs]))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", help="comma-separated scene ids (default: every scene with a section)")
    ap.add_argument("--ics", type=int, default=16, help="seeded initial conditions tried per scene")
    ap.add_argument("--max-orbits", type=int, default=6, help="regular orbits compared per scene (references are slow)")
    ap.add_argument("--per-period", type=float, help="another PLOT_ERROR_PER_PERIOD to try")
    ap.add_argument("--cache-dir", help="reference cache (default: the bench cache)")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args()
    if args.per_period is not None:
        scenes.PLOT_ERROR_PER_PERIOD = args.per_period
    ids = args.scenes.split(",") if args.scenes else [s.id for s in scenes.list_scenes() if "section" in s.views]
    rows = []
    print(f"PLOT_ERROR_PER_PERIOD = {scenes.PLOT_ERROR_PER_PERIOD}")
    print("| scene | periods | tol | regular / tried | max error (px) | median of the orbits' max (px) | ours (s) |")
    print("|---|---|---|---|---|---|---|")
    for sid in ids:
        r = measure(sid, args.ics, args.cache_dir, args.max_orbits)
        rows.append(r)
        if "max_px" in r:
            print(f"| {sid} | {r['periods']} | {r['tol']:.1e} | {r['regular']} / {r['ics']} | {r['max_px']:.3f} | "
                  f"{r['median_px']:.3f} | {r['ours_s']} |", flush=True)  # fmt: skip
        else:
            print(f"| {sid} | {r['periods']} | {r['tol']:.1e} | {r['regular']} / {r['ics']} | - | - | - |", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"per_period": scenes.PLOT_ERROR_PER_PERIOD, "scenes": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
