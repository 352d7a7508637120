"""How many periods, and how much time, each chaos indicator needs to classify an orbit as a long Lyapunov run does.

    PYTHONPATH=. .venv/bin/python benchmarks/indicators_speed.py [--n 20] [--reference 5000] [--json out.json]

Two sets of ``--n`` initial conditions: **regular**, on the invariant curves of Fig. 5A's central island (a grid
about the centre, every orbit bounded), and **chaotic**, on Fig. 8B's strange attractor (points of one orbit after
a transient of 100 periods, seven periods apart). The reference is the Lyapunov exponent over ``--reference``
periods (:mod:`explorer_core.analyses.lyapunov`): chaotic when ``lambda_1 T > LYAP_TOL`` per period. Each indicator
runs on a ladder of lengths (every IC of a set in one batch per rung); an IC *needs* the first rung at which the
indicator's verdict equals the reference's (and every longer rung agrees). Reported per indicator and set: how many
ICs agree at the longest rung, the median and largest periods needed, and the seconds of the batch at the rung where
every IC (or, if never, the most) agreed, against the seconds of the reference batch (medians of ``--repeat``
runs each, in this process, one after the other). The indicators:

* Birkhoff: weighted Birkhoff averages of ``q``, ``2 N`` periods (:func:`~explorer_core.analyses.indicators.birkhoff`);
* SALI: at most ``N`` periods, a chaotic orbit stopping once decided (:func:`~explorer_core.analyses.indicators.sali`;
  its periods are those it used);
* FTLE: the finite-time exponent over ``N`` periods (:func:`~explorer_core.analyses.ftle.ftle_tile`), chaotic when
  above ``LYAP_TOL`` per period, as the reference.

The machine's load (``uptime``) is printed before and after: it is shared. The comparison itself is
:mod:`explorer_core.studies.indicator_bench` (``bilimovich bench`` runs a small one).
"""

from __future__ import annotations

import argparse
import json
import subprocess

from explorer_core.studies.indicator_bench import measure as _measure
from explorer_core.studies.indicator_bench import table
from explorer_core.warm import warm_all


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def measure(n: int, reference: int, repeat: int) -> dict:
    """:func:`explorer_core.studies.indicator_bench.measure` with the full ladders, and the load before and after."""
    before = uptime()
    report = _measure(n, reference, repeat)
    return {"load_before": before, **report, "load_after": uptime()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--reference", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each batch timed (median)")
    ap.add_argument("--json")
    args = ap.parse_args()
    warm_all()
    report = measure(args.n, args.reference, args.repeat)
    print(report["load_before"])
    print(table(report))
    for set_name, e in report["sets"].items():
        for name, d in e["indicators"].items():
            print(f"{set_name} {name}: (length, wrong, undecided) per rung {d['rungs']}")
            for miss in d["disagree_at_longest"]:
                print(f"{set_name} {name}: disagrees at the longest rung on {miss}")
    print(report["load_after"])
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
