"""A/B of the integration engine between two checkouts, in one run (issue: one engine, nothing >5 % slower).

    .venv/bin/python benchmarks/engine_ab.py --old /path/to/old/checkout [--rounds 5] [--out ab.json]
    .venv/bin/python benchmarks/engine_ab.py --old /path/to/old/checkout --suite analyses [--rounds 3 --repeat 3]

Runs the same cases alternately in the old and the new checkout (a child process each round, with
``PYTHONPATH`` pointing at the checkout), each case timed as the median of ``--repeat`` calls after a
warm-up, and reports the median over rounds and the new/old ratio. Every case also returns its
results, compared between the checkouts (bit-for-bit or the largest difference).

Cases: the per-trajectory section kernel (``block=1``), the lock-step block kernel, fixed-step RK4,
the Lyapunov spectrum and a small chart of regimes, all on one worker thread so the figures measure
the kernels and not the thread pool.

``--suite analyses`` times the analyses as a user runs them (default workers: both cores): periodic orbits
from a grid of seeds, the Fig. 10 continuation with branch switching, a chart of regimes, basins and the
Fig. 8B flip saddle's manifolds (the "nothing slower by more than 5 %" check of the one-contract issue), the
Fig. 10 orbit diagram and a Lyapunov spectrum at the default numerics (whose method the "auto" rule chooses).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]


def _imports():
    """The public calls under either layout (flat modules before the layered core, sub-packages after)."""
    try:
        from explorer_core.analyses.lyapunov import lyapunov_spectrum
        from explorer_core.analyses.regimes import chart_spec, regime_chart
        from explorer_core.solve.integrators import Batch, advance
        from explorer_core.solve.numerics import Numerics
        from explorer_core.system.model import Model
        from explorer_core.system.params import Params
    except ImportError:
        from explorer_core.integrators import Batch, advance
        from explorer_core.lyapunov import lyapunov_spectrum
        from explorer_core.model import Model, Params
        from explorer_core.regimes import chart_spec, regime_chart
        from explorer_core.section import Numerics
    return Batch, advance, lyapunov_spectrum, chart_spec, regime_chart, Numerics, Model, Params


def analyses_cases() -> dict:
    """The analyses as a user runs them (default workers), each returning numbers to compare."""
    from explorer_core.analyses.basins import basins
    from explorer_core.analyses.continuation import continue_orbit
    from explorer_core.analyses.manifolds import manifolds, saddle_orbit
    from explorer_core.analyses.orbits import find_orbits, grid_seeds
    from explorer_core.analyses.regimes import chart_spec, regime_chart
    from explorer_core.scenes import get_scene
    from explorer_core.solve.numerics import Numerics

    fig8b, fig10 = get_scene("fig8B"), get_scene("fig10")
    view = (*fig8b.q_range, *fig8b.r_range)
    flip = saddle_orbit(fig8b.params, (-0.04, -2.40), 1)

    def orbits():
        res = find_orbits(fig8b.params, grid_seeds(fig8b.box, 8, 8), [1, 2, 3])
        return sorted(float(o.points[0, 0]) for o in res.orbits)

    def cont():
        res = continue_orbit(fig10.params, "alpha", (-0.35, -0.42), (-0.0959, -1.962), 1, switch=True)
        return sorted(b.value for b in res.bifurcations)

    def chart():
        spec = chart_spec(fig8b.params, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (12, 8),
                          ics=((-0.09, -2.0), (-0.5, -1.0)), transient=200, periods=200,
                          numerics=Numerics(rtol=1e-8, atol=1e-8))  # fmt: skip
        return regime_chart(spec).regime

    def basin():
        return basins(fig8b.params.with_(alpha=-0.5, inertia=(1.6, 2, 4, 0.0, 0.5, 0.3)), (-1.7, 1.5, -3, 1),
                      (40, 40)).label  # fmt: skip

    def manifold():
        m = manifolds(fig8b.params, flip, length=10.0, view=view, pixels=(800, 600))
        return [sum(p.shape[0] for p in b.pieces) for b in m.branches]

    def diagram():
        from explorer_core.analyses.bifurcation import bifurcation_diagram
        from explorer_core.analyses.sweeps import sweep_values

        res = bifurcation_diagram(fig10.params, "alpha", sweep_values((-0.42, -0.35), 100), points=200, transient=500,
                                  ics=[(-0.0959, -1.962)])  # fmt: skip
        return res.npts

    def spectrum():
        from explorer_core.analyses.lyapunov import lyapunov_spectrum

        return lyapunov_spectrum(fig8b.params, [(-0.5, -1.0), (-0.4, -1.1)], 2000).exponents

    return {
        "orbits (fig8B, 8x8 seeds, periods 1-3)": orbits,
        "continuation (fig10, alpha -0.35..-0.42, switch)": cont,
        "chart (fig8B 12x8 px, 2 ICs, 200+200, rtol 1e-8)": chart,
        "basins (alpha -0.5, I11 1.6, 40x40)": basin,
        "manifolds (fig8B flip saddle, length 10, 800x600)": manifold,
        "orbit diagram (fig10, 100 values x (500 + 200), default numerics)": diagram,
        "Lyapunov spectrum (fig8B, 2 ICs x 2000, default numerics)": spectrum,
    }


def child(repeat: int, suite: str = "engine") -> dict:
    # The project's editable install maps explorer_core's sub-packages to its own checkout whatever
    # PYTHONPATH says: without its finder, the checkout on PYTHONPATH is the one imported.
    for finder in list(sys.meta_path):
        if "editable" in getattr(finder, "__name__", type(finder).__name__).lower():
            sys.meta_path.remove(finder)
    import explorer_core

    assert Path(explorer_core.__file__).resolve().is_relative_to(Path(os.environ["PYTHONPATH"]).resolve())
    Batch, advance, lyapunov_spectrum, chart_spec, regime_chart, Numerics, Model, Params = _imports()
    fig1c = Params(inertia=(1, 4, 2, 0, 0, 0), alpha=0.1)
    fig8b = Params(inertia=(1, 2, 4, 0.0, 0.5, 0.3), alpha=-0.45)
    ics = np.random.default_rng(1).uniform(-1.5, 1.5, (64, 2))

    def section(block: int, method: str = "dop853", **kw):
        b = Batch.start(ics, fig1c.t0, fig1c.period)
        out, npts = advance(Model(fig1c), b, 40, method=method, workers=1, block=block, **kw)
        return out

    cases = analyses_cases() if suite == "analyses" else {
        "section kernel (block=1, 64 ICs x 40 periods, dop853 1e-10)": lambda: section(1, rtol=1e-10, atol=1e-10),
        "block kernel (block=32, 64 ICs x 40 periods, dop853 1e-10)": lambda: section(32, rtol=1e-10, atol=1e-10),
        "rk4 (64 ICs x 40 periods x 400 steps)": lambda: section(32, "rk4", steps_per_period=400),
        "Lyapunov spectrum (fig8B, 2 ICs x 300 periods, dop853 1e-10)": lambda: lyapunov_spectrum(
            fig8b, [(-0.5, -1.0), (-0.4, -1.1)], 300, workers=1
        ).exponents,
        "chart (fig11 6x4 px, 2 ICs, 100+100 periods, rtol 1e-8)": lambda: regime_chart(
            chart_spec(fig8b, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (6, 4), ics=((-0.09, -2.0), (-0.5, -1.0)),
                       transient=100, periods=100, numerics=Numerics(rtol=1e-8, atol=1e-8)),
            workers=1,
        ).lyap,
    }  # fmt: skip
    out = {}
    for name, fn in cases.items():
        result = fn()  # warm-up (numba cache load) and the result to compare
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t)
        out[name] = {"median_s": statistics.median(times), "result": np.asarray(result).tolist()}
    return out


def run_child(tree: Path, repeat: int, suite: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, str(HERE / "benchmarks" / "engine_ab.py"), "--child", "--repeat", str(repeat),
           "--suite", suite]  # fmt: skip
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old", help="checkout to compare against")
    ap.add_argument("--new", default=str(HERE))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out")
    ap.add_argument("--suite", choices=("engine", "analyses"), default="engine")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args.repeat, args.suite)))
        return
    if not args.old:
        ap.error("--old is required")
    trees = {"old": Path(args.old).resolve(), "new": Path(args.new).resolve()}
    times: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
    results: dict[str, dict] = {}
    for rnd in range(args.rounds):
        for label in ("old", "new") if rnd % 2 == 0 else ("new", "old"):
            res = run_child(trees[label], args.repeat, args.suite)
            for case, v in res.items():
                times[label].setdefault(case, []).append(v["median_s"])
            results[label] = res
    report = {"suite": args.suite, "rounds": args.rounds, "repeat": args.repeat, "load": os.getloadavg()[0],
              "cases": {}}  # fmt: skip
    print(f"{'case':64s} {'old ms':>9s} {'new ms':>9s} {'new/old':>8s}  results")
    for case in times["old"]:
        old = statistics.median(times["old"][case])
        new = statistics.median(times["new"][case])
        a = np.asarray(results["old"][case]["result"], dtype=float)
        b = np.asarray(results["new"][case]["result"], dtype=float)
        if a.shape != b.shape:
            same = f"shapes differ {a.shape} vs {b.shape}"
        elif np.array_equal(a, b, equal_nan=True):
            same = "bit-for-bit"
        else:
            fin = np.isfinite(a) & np.isfinite(b)
            same = f"max |diff| {np.abs(a[fin] - b[fin]).max():.2e}" if fin.any() else "differ"
        report["cases"][case] = {"old_s": old, "new_s": new, "ratio": new / old, "results": same}
        print(f"{case:64s} {old * 1e3:9.1f} {new * 1e3:9.1f} {new / old:8.3f}  {same}")
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
