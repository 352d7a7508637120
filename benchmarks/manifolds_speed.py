"""Speed of the invariant manifolds (issue: the structure of the phase plane), in one run.

    .venv/bin/python benchmarks/manifolds_speed.py [--repeat 5] [--json out.json]

* the Fig. 8B flip saddle near (-0.04, -2.40): both manifolds, both branches, to arc length 10 and 50 in
  the scene's window at 800 x 600 pixels (target: 50 in <= 1 s), with the homoclinic crossings;
* the same at 1920 x 1440 pixels (finer view: more points, to show the cost follows the view);
* the Fig. 8B saddle near (-1.46, -4.13) (mu_u = 1.48: slow growth, many levels) to arc length 10.

Medians of ``--repeat`` runs after a warm-up (kernels loaded from the on-disk cache), on every core.
"""

from __future__ import annotations

import argparse
import json
import os

from orbits_speed import timed  # the same medians as the orbits' benchmark (this folder is on the path)

from explorer_core.analyses.manifolds import manifolds, saddle_orbit
from explorer_core.scenes import get_scene
from explorer_core.warm import warm_all


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    warm_all()
    scene = get_scene("fig8B")
    view = (*scene.q_range, *scene.r_range)
    flip = saddle_orbit(scene.params, (-0.04, -2.40), 1)
    slow = saddle_orbit(scene.params, (-1.457, -4.13), 1)
    cases = [
        ("flip saddle, length 10, 800x600", flip, 10.0, view, (800, 600)),
        ("flip saddle, length 50, 800x600", flip, 50.0, view, (800, 600)),
        ("flip saddle, length 50, 1920x1440", flip, 50.0, view, (1920, 1440)),
        ("saddle mu=1.48, length 10, 800x600", slow, 10.0, (-3.0, 0.5, -5.5, -2.0), (800, 600)),
    ]
    rows = []
    print(f"load average {os.getloadavg()[0]:.2f}; medians of {args.repeat}")
    for name, orbit, length, box, px in cases:
        t, m = timed(lambda o=orbit, L=length, b=box, p=px: manifolds(scene.params, o, length=L, view=b, pixels=p),
                     args.repeat)  # fmt: skip
        points = sum(p.shape[0] for b in m.branches for p in b.pieces)
        members = sum(b.members for b in m.branches)
        status = sorted({b.status for b in m.branches})
        rows.append({"case": name, "median_s": round(t, 4), "points": points, "members": members,
                     "crossings": len(m.crossings), "status": status})  # fmt: skip
        print(f"{name:38s} {t * 1e3:8.1f} ms  {points:6d} points  {members:6d} members  "
              f"{len(m.crossings):4d} crossings  {status}")  # fmt: skip
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
