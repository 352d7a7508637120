"""Which method wins for each analysis at the tolerance it runs at: DOP853 against Verner 9(8), A/B in one process.

    .venv/bin/python benchmarks/method_choice.py [--repeat 5] [--cases orbits,continuation,...] [--methods dop853,vern9]

The measurement behind ``config.VERN9_MAX_RTOL`` (the ``"auto"`` method's rule). Each case is an analysis as
the user meets it (default workers) with its own tolerance, run with each method in turn (alternated, after one
warm-up each), timed as the median of ``--repeat`` runs; printed with the time ratio against the first method
and what the two results differ by (the more accurate method moves the answers at the level of the error).
Ratios only: the machine's load moves absolute times; say ``uptime`` with the figures.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import numpy as np


def cases() -> dict[str, Callable[[str], np.ndarray]]:
    from explorer_core.analyses.bifurcation import bifurcation_diagram
    from explorer_core.analyses.continuation import continue_orbit
    from explorer_core.analyses.lyapunov import lyapunov_spectrum
    from explorer_core.analyses.manifolds import manifolds, saddle_orbit
    from explorer_core.analyses.orbits import find_orbits, grid_seeds
    from explorer_core.analyses.regimes import chart_spec, regime_chart
    from explorer_core.analyses.sweeps import sweep_values
    from explorer_core.scenes import get_scene
    from explorer_core.solve.integrators import Batch, advance
    from explorer_core.solve.numerics import Numerics, random_ics
    from explorer_core.system.model import Model
    from explorer_core.system.params import Params

    fig8b, fig10 = get_scene("fig8B"), get_scene("fig10")
    view = (*fig8b.q_range, *fig8b.r_range)
    flip = saddle_orbit(fig8b.params, (-0.04, -2.40), 1)
    fig1c = Params(inertia=(1, 4, 2, 0, 0, 0), alpha=0.1)
    ics = random_ics(200, (-1, 1, -1, 1), seed=0)

    def num(method: str, tol: float) -> Numerics:
        return Numerics(method=method, rtol=tol, atol=tol)

    def orbits(m: str) -> np.ndarray:
        res = find_orbits(fig8b.params, grid_seeds(fig8b.box, 8, 8), [1, 2, 3], numerics=num(m, 1e-12))
        return np.array(sorted(float(o.points[0, 0]) for o in res.orbits))

    def cont(m: str) -> np.ndarray:
        res = continue_orbit(fig10.params, "alpha", (-0.35, -0.4126), (-0.0959, -1.962), 1, switch=True,
                             numerics=num(m, 1e-12))  # fmt: skip
        return np.array(sorted(b.value for b in res.bifurcations))

    def lyap(m: str, tol: float) -> np.ndarray:
        return lyapunov_spectrum(fig8b.params, [(-0.5, -1.0), (-0.4, -1.1)], 2000, numerics=num(m, tol)).exponents

    def manifold(m: str) -> np.ndarray:
        res = manifolds(fig8b.params, flip, length=10.0, view=view, pixels=(800, 600), numerics=num(m, 1e-10))
        return np.array([sum(p.shape[0] for p in b.pieces) for b in res.branches], float)

    def sec(m: str, tol: float) -> np.ndarray:
        b = Batch.start(ics, fig1c.t0, fig1c.period)
        out, _ = advance(Model(fig1c), b, 200, method=m, rtol=tol, atol=tol)
        return np.asarray(out)

    def chart(m: str, tol: float) -> np.ndarray:
        spec = chart_spec(fig8b.params, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (12, 8),
                          ics=((-0.09, -2.0), (-0.5, -1.0)), transient=200, periods=200,
                          numerics=num(m, tol))  # fmt: skip
        return np.asarray(regime_chart(spec).lyap, float)

    def diagram(m: str, tol: float) -> np.ndarray:
        res = bifurcation_diagram(fig10.params, "alpha", sweep_values((-0.42, -0.35), 100), seeding="continuation",
                                  points=200, transient=500, ics=[(-0.0959, -1.962)], numerics=num(m, tol))  # fmt: skip
        return np.asarray(res.points, float)[..., -8:, :]

    return {
        "orbit diagram (fig10, 100 values x (500 + 200), 1e-10)": lambda m: diagram(m, 1e-10),
        "orbit diagram (fig10, 100 values x (500 + 200), 1e-9)": lambda m: diagram(m, 1e-9),
        "orbits (fig8B 8x8 seeds, periods 1-3, 1e-12)": orbits,
        "continuation (fig10 cascade, switch, 1e-12)": cont,
        **{f"lyapunov (fig8B 2 ICs x 2000, {t:g})": (lambda m, t=t: lyap(m, t)) for t in (1e-8, 1e-9, 1e-10, 1e-12)},
        "manifolds (fig8B flip saddle, length 10, 1e-10)": manifold,
        "section (fig1C 200 ICs x 200, 1e-7)": lambda m: sec(m, 1e-7),
        "section (fig1C 200 ICs x 200, 1e-8)": lambda m: sec(m, 1e-8),
        "section (fig1C 200 ICs x 200, 1e-9)": lambda m: sec(m, 1e-9),
        "section (fig1C 200 ICs x 200, 1e-10)": lambda m: sec(m, 1e-10),
        **{
            f"chart (fig8B 12x8 px, 2 ICs, 200+200, {t:g})": (lambda m, t=t: chart(m, t))
            for t in (1e-7, 1e-8, 1e-9, 1e-10)
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--methods", default="dop853,vern9")
    ap.add_argument("--cases", default="", help="comma-separated substrings of the case names (default: all)")
    a = ap.parse_args()
    methods = a.methods.split(",")
    want = [w for w in a.cases.split(",") if w]
    print(f"load at start {os.getloadavg()}; median of {a.repeat}, methods alternated")
    print(f"| case | {' | '.join(methods)} (s) | {methods[-1]}/{methods[0]} | results differ by |")
    print("|---|" + "---|" * (len(methods) + 2))
    for name, fn in cases().items():
        if want and not any(w in name for w in want):
            continue
        res = {m: np.asarray(fn(m), float) for m in methods}  # warm-up, and the answers
        times: dict[str, list[float]] = {m: [] for m in methods}
        for r in range(a.repeat):
            for m in methods if r % 2 == 0 else methods[::-1]:
                t = time.perf_counter()
                fn(m)
                times[m].append(time.perf_counter() - t)
        med = {m: statistics.median(times[m]) for m in methods}
        x, y = res[methods[0]], res[methods[-1]]
        if x.shape != y.shape:
            diff = f"shapes {x.shape} vs {y.shape}"
        else:
            fin = np.isfinite(x) & np.isfinite(y)
            diff = f"{np.abs(x[fin] - y[fin]).max():.1e}" if fin.any() else "-"
        cols = " | ".join(f"{med[m]:.3f}" for m in methods)
        print(f"| {name} | {cols} | {med[methods[-1]] / med[methods[0]]:.2f} | {diff} |", flush=True)
    print(f"load at end {os.getloadavg()}")


if __name__ == "__main__":
    main()
