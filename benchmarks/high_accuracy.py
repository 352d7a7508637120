"""Where the time goes at high accuracy: counts that do not depend on the machine's load, and short
interleaved A/B ratios in one process (median of repeats), for our methods and heyoka's batch mode.

    .venv/bin/python benchmarks/high_accuracy.py [--case regular|attractor] [--ics 16] [--periods 200]
        [--repeat 5] [--tols 1e-8,1e-10,1e-12,1e-13] [--methods dop853,taylor] [--horizon 10]

``--case regular`` (issue 22's work): the regular orbit of the diagonal tensor (1, 4, 2), alpha = 0.1,
g = cos t; random ICs in [-1, 1]^2 (the project's own ``random_ics``). Error: median over ICs of the largest
distance from heyoka at tol 1e-16 over the section points.

``--case attractor``: the strange attractor of Fig. 8B (general tensor, alpha = -0.45; the paper's largest
exponent 0.082 per unit time, 0.52 per period). ICs: random in the scene's box, run for a transient of 300
periods (DOP853 at 1e-12), the first ``--ics`` still bounded are on the attractor. The time is that of
``--periods`` periods from there. On a chaotic orbit every error, the reference's rounding included, grows
like e^(0.52 k) after k periods, so the error is measured over the first ``--horizon`` periods only
(default 10: a growth of ~e^5 = 170, so heyoka's 1e-16 stays ~1e-14 off the true orbit, below every error
measured at tol >= 1e-13); the line "floor" gives heyoka at 1e-15 against 1e-16 over the same horizon, the
smallest error the reference can tell apart.

Printed per method and tolerance: steps per period, right-hand-side evaluations per period (RK: stages x steps;
heyoka and Taylor: order x steps, one Taylor coefficient per order), the error, and the time per core relative to
heyoka's batch x8 on one thread, both run on one thread in the same process, interleaved, median of ``repeat``.

Each peer is given the simplest field for the scene, the form its user would write (``bench.peer_fields``, the
one definition that ``bilimovich bench`` and the app's speed tab use too), and the fields are printed first.
heyoka: for a diagonal tensor (the regular case) the paper's closed form, ``R = (A - B)(g q + alpha) q / C`` with
no denominator (``bench._heyoka_diagonal``; on the regular case its trajectories are checked against heyoka on the
model's general tables at tol 1e-16 before the timings); otherwise the model's general field
(``bench._heyoka_tables``). Ours: the scene's own form, read off the model's tables
(:func:`~explorer_core.system.model.field_form`). heyoka compiles each integrator once, outside the timings (a
warm-up run of every peer precedes them).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import random_ics
from explorer_core.solve.taylor import taylor_order
from explorer_core.studies import bench
from explorer_core.system.model import FORM_MASKS, MONOMIALS, Model, field_form
from explorer_core.system.params import Params

STAGES = {"dp5": 6, "dop853": 12, "vern9": 16}


def print_fields(model: Model) -> None:
    """Each peer's field, as it is given to it (``bench.peer_fields``: the one definition), and ours."""
    print("fields:")
    for peer, text in bench.peer_fields(model.params).items():
        print(f"  {peer}: {text}")
    form = field_form(model.num, model.gpc)
    for row, name in enumerate(("Q", "R")):
        kept = [MONOMIALS[m] for m in range(6) if (FORM_MASKS[form][row] >> m) & 1]
        print(f"  ours {name} = sum of c_m(g, g') m over m in {{{', '.join(kept)}}} (the tables' form {form})")


def heyoka_points(model: Model, ics: np.ndarray, periods: int, tol: float, tables: bool = False) -> np.ndarray:
    """Section points (n, periods, 2) of heyoka's batch mode on the peers' field (``tables``: the general one)."""
    return np.array(bench._peer_heyoka(model, ics, periods, "batch", tol, tables)[0])


def heyoka_steps(model: Model, ics: np.ndarray, periods: int, tol: float) -> tuple[float, int]:
    """heyoka's steps per period per IC (its scalar integrator on the peers' field: the steps a member of its batch
    takes) and its Taylor order; run outside the timings."""
    p = model.params
    ta = bench._heyoka_integrator(p, float(tol), 0)
    grid = p.t0 + p.period * np.arange(periods + 1)
    steps = 0
    for ic in ics:
        ta.time = p.t0
        ta.state[:] = ic
        steps += ta.propagate_grid(grid)[3]
    return steps / ics.shape[0] / periods, int(ta.order)


def ours(model: Model, ics: np.ndarray, periods: int, method: str, tol: float, block: int) -> tuple[np.ndarray, float]:
    p = model.params
    b = Batch.start(ics, p.t0, p.period)
    out, _ = advance(model, b, periods, method=method, rtol=tol, atol=tol, workers=1, block=block)
    return out, float(b.nsteps.mean()) / periods


def attractor_ics(model: Model, n: int, box: tuple[float, float, float, float]) -> np.ndarray:
    """``n`` points on the attractor: random ICs in ``box`` after 300 periods, those that stayed bounded."""
    p = model.params
    start = random_ics(8 * n, box, seed=0)
    b = Batch.start(start, p.t0, p.period)
    advance(model, b, 300, method="dop853", rtol=1e-12, atol=1e-12, bound=1e3, store=False)
    kept = b.y[(b.status == 0) & np.all(np.abs(b.y) < 10.0, axis=1)]
    if kept.shape[0] < n:
        raise SystemExit(f"only {kept.shape[0]} of {8 * n} ICs stayed on the attractor; ask for fewer --ics")
    return np.ascontiguousarray(kept[:n])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=("regular", "attractor"), default="regular")
    ap.add_argument("--ics", type=int, default=16)
    ap.add_argument("--periods", type=int, default=200)
    ap.add_argument("--horizon", type=int, default=10, help="attractor: periods over which the error is measured")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--tols", default="1e-8,1e-10,1e-12,1e-13")
    ap.add_argument("--methods", default="dop853,vern9,taylor")
    ap.add_argument("--block", type=int, default=32, help="lock-step block (1: one step sequence per IC)")
    a = ap.parse_args()
    hy, why = bench.heyoka_status()
    if hy is None:
        raise SystemExit(f"heyoka not available: {why}")
    if a.case == "regular":
        model = Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1))
        ics = random_ics(a.ics, (-1.0, 1.0, -1.0, 1.0), seed=0)
        horizon = a.periods
    else:
        scene = get_scene("fig8B")
        model = Model(scene.params)
        ics = attractor_ics(model, a.ics, scene.box)
        horizon = min(a.horizon, a.periods)
    print_fields(model)
    ref = heyoka_points(model, ics, horizon, 1e-16)
    if bench.is_diagonal(model.params):
        # heyoka's closed form against the general tables, both at 1e-16: the same trajectories to ~rounding
        dev = np.max(np.abs(heyoka_points(model, ics, horizon, 1e-16, tables=True) - ref) / np.max(np.abs(ref)))
        print(f"heyoka's simple field vs the general one at tol 1e-16: largest relative difference {dev:.1e}")

    def err(pts: np.ndarray) -> float:
        dev = np.asarray(pts)[:, :horizon] - ref
        return float(np.median(np.max(np.linalg.norm(dev, axis=2), axis=1)))

    if a.case == "attractor":
        floor = err(heyoka_points(model, ics, horizon, 1e-15))
        print(f"attractor of fig8B, error over the first {horizon} periods; floor (heyoka 1e-15 vs 1e-16) {floor:.1e}")

    print(f"{a.ics} ICs x {a.periods} periods, one thread each, median of {a.repeat} interleaved runs;",
          f"load {os.getloadavg()}")  # fmt: skip
    print("| tol | method | steps/period | evals/period | error | time s | time/heyoka |")
    print("|---|---|---|---|---|---|---|")
    curves: dict[str, list[tuple[float, float]]] = {}
    for tol in (float(x) for x in a.tols.split(",")):
        runs = {"heyoka": lambda tol=tol: (heyoka_points(model, ics, a.periods, tol), 0.0)}
        for m in a.methods.split(","):
            runs[m] = lambda m=m, tol=tol: ours(model, ics, a.periods, m, tol, a.block)
        for f in runs.values():  # compile / warm
            f()
        times: dict[str, list[float]] = {k: [] for k in runs}
        res = {}
        for r in range(a.repeat):
            for k in list(runs) if r % 2 == 0 else list(runs)[::-1]:
                t0 = time.perf_counter()
                res[k] = runs[k]()
                times[k].append(time.perf_counter() - t0)
        best = {k: statistics.median(v) for k, v in times.items()}
        hy_spp, hy_order = heyoka_steps(model, ics, a.periods, tol)
        res["heyoka"] = (res["heyoka"][0], hy_spp)
        for k, (pts, spp) in res.items():
            evals = (
                f"{spp * hy_order:.0f} (order {hy_order})"
                if k == "heyoka"
                else (
                    f"{spp * taylor_order(tol):.0f} (order {taylor_order(tol)})"
                    if k == "taylor"
                    else f"{spp * STAGES[k]:.0f}"
                )
            )
            e = err(pts)
            curves.setdefault(k, []).append((e, best[k]))
            print(
                f"| {tol:.0e} | {k} | {spp:.1f} | {evals} | {e:.2e} | {best[k]:.3f} | {best[k] / best['heyoka']:.2f} |"
            )
    equal_error(curves)


def equal_error(curves: dict[str, list[tuple[float, float]]]) -> None:
    """At each of heyoka's errors, each method's time for the same error (log-log interpolation between its
    tolerances; blank outside the errors it reached) over heyoka's: the comparison at equal accuracy."""
    ours_ = [k for k in curves if k != "heyoka"]
    print("\n| heyoka error | heyoka s | " + " | ".join(f"{k} at that error / heyoka" for k in ours_) + " |")
    print("|---|---|" + "---|" * len(ours_))
    for e_h, t_h in curves["heyoka"]:
        cols = []
        for k in ours_:
            pts = sorted(curves[k])
            le, lt = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
            x = np.log(e_h)
            cols.append(f"{np.exp(np.interp(x, le, lt)) / t_h:.2f}" if le[0] <= x <= le[-1] else "")
        print(f"| {e_h:.2e} | {t_h:.3f} | " + " | ".join(cols) + " |")


if __name__ == "__main__":
    main()
