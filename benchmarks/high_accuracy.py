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

Printed per method and tolerance: steps per period, right-hand-side evaluations per period (RK: stages + FSAL;
Taylor: order), the error, and the time per core relative to heyoka's batch x8 on one thread, both run on one
thread in the same process, interleaved, median of ``repeat``.

Each peer is given the simplest field for the scene, the form its user would write, and the fields are printed
first. heyoka: for a diagonal tensor (the regular case) the paper's closed form, ``R = (A - B)(g q + alpha) q / C``
with no denominator (:func:`simple_system`; it agrees with the model's general field, checked at tol 1e-16 before
the timings); otherwise the model's general field (``bench._heyoka_system``). Ours: the scene's own form, read off
the model's tables (:func:`~explorer_core.system.model.field_form`). heyoka compiles each integrator once, outside
the timings (a warm-up run of every peer precedes them).
"""

from __future__ import annotations

import argparse
import functools
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


def _sum(terms: list) -> object:
    """A sum of heyoka expressions (None when there is none)."""
    return functools.reduce(lambda a, b: a + b, terms) if terms else None


def simple_system(hy: object, p: Params) -> list[tuple[object, object]]:
    """The field a heyoka user writes for a diagonal tensor ``diag(A, B, C)`` (PHYSICS.md):
    ``q' = -[alpha (A - C) r + g (A - B) q r + A g g' q] / (g^2 A + B)``, ``r' = (A - B)(g q + alpha) q / C``, with
    ``g = g0 + g1 cos(omega t) + g2 sin(omega t)``; zero terms and unit factors left out, as a user would."""
    a, b, c = (float(v) for v in p.inertia[:3])
    q, r = hy.make_vars("q", "r")
    w = float(p.omega)
    wt = hy.time if w == 1.0 else w * hy.time
    cw, sw = hy.cos(wt), hy.sin(wt)

    def lin(*pairs: tuple[float, object]) -> object:
        return _sum([e if k == 1.0 else (-e if k == -1.0 else k * e) for k, e in pairs if k != 0.0])

    g = lin((p.g1, cw), (p.g2, sw))
    g = g if p.g0 == 0.0 else (p.g0 if g is None else g + p.g0)
    gp = lin((w * p.g2, cw), (-w * p.g1, sw))
    al = float(p.alpha)
    num = _sum([t for t in ((al * (a - c)) * r if al * (a - c) != 0.0 else None, (a - b) * g * q * r,
                            (a * g * gp) * q if gp is not None else None) if t is not None])  # fmt: skip
    qdot = -num / (a * g * g + b)
    rdot = ((a - b) / c) * ((g * q + al) if al != 0.0 else g * q) * q
    return [(q, qdot), (r, rdot)]


@functools.lru_cache(maxsize=32)
def _simple_integrator(p: Params, tol: float) -> object:
    """heyoka's batch integrator (``bench.HEYOKA_BATCH`` wide) on :func:`simple_system`, compiled once."""
    hy, _ = bench.heyoka_status()
    return hy.taylor_adaptive_batch(simple_system(hy, p), np.zeros((2, bench.HEYOKA_BATCH)), tol=tol)


def heyoka_simple(p: Params, ics: np.ndarray, periods: int, tol: float) -> np.ndarray:
    """Section points (n, periods, 2) of heyoka's batch mode on :func:`simple_system`, one thread; ``ics`` fill
    whole batches (a multiple of ``bench.HEYOKA_BATCH``)."""
    tb = _simple_integrator(p, float(tol))
    nb_ = bench.HEYOKA_BATCH
    if ics.shape[0] % nb_:
        raise SystemExit(f"--ics must be a multiple of {nb_} for heyoka's batches")
    grid = np.ascontiguousarray(np.repeat((p.t0 + p.period * np.arange(periods + 1))[:, None], nb_, axis=1))
    out = []
    for b0 in range(0, ics.shape[0], nb_):
        tb.set_time(np.full(nb_, p.t0))
        tb.state[:] = ics[b0 : b0 + nb_].T
        _, states = tb.propagate_grid(grid)
        out.append(np.moveaxis(states[1:], 2, 0))
    return np.concatenate(out)


def print_fields(model: Model, simple: bool) -> None:
    """Each peer's field, as it is given to it."""
    hy, _ = bench.heyoka_status()
    sys_ = simple_system(hy, model.params) if simple else bench._heyoka_system(hy, model)
    print("fields:")
    for name, (_, rhs) in zip(("q'", "r'"), sys_, strict=True):
        print(f"  heyoka {name} = {rhs}")
    form = field_form(model.num, model.gpc)
    for row, name in enumerate(("Q", "R")):
        kept = [MONOMIALS[m] for m in range(6) if (FORM_MASKS[form][row] >> m) & 1]
        print(f"  ours   {name} = sum of c_m(g, g') m over m in {{{', '.join(kept)}}} (the tables' form {form})")


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
    simple = a.case == "regular" and not any(model.params.inertia[3:])
    print_fields(model, simple)
    ref = np.array(bench._peer_heyoka(model, ics, horizon, "batch", 1e-16)[0])
    if simple:
        # heyoka's simple field against its general one, both at 1e-16: the same trajectories to ~rounding
        dev = np.max(np.abs(heyoka_simple(model.params, ics, horizon, 1e-16) - ref) / np.max(np.abs(ref)))
        print(f"heyoka's simple field vs the general one at tol 1e-16: largest relative difference {dev:.1e}")

    def err(pts: np.ndarray) -> float:
        dev = np.asarray(pts)[:, :horizon] - ref
        return float(np.median(np.max(np.linalg.norm(dev, axis=2), axis=1)))

    if a.case == "attractor":
        floor = err(np.array(bench._peer_heyoka(model, ics, horizon, "batch", 1e-15)[0]))
        print(f"attractor of fig8B, error over the first {horizon} periods; floor (heyoka 1e-15 vs 1e-16) {floor:.1e}")

    def heyoka_points(tol: float) -> np.ndarray:
        if simple:
            return heyoka_simple(model.params, ics, a.periods, tol)
        return np.array(bench._peer_heyoka(model, ics, a.periods, "batch", tol)[0])

    print(f"{a.ics} ICs x {a.periods} periods, one thread each, median of {a.repeat} interleaved runs;",
          f"load {os.getloadavg()}")  # fmt: skip
    print("| tol | method | steps/period | evals/period | error | time s | time/heyoka |")
    print("|---|---|---|---|---|---|---|")
    curves: dict[str, list[tuple[float, float]]] = {}
    for tol in (float(x) for x in a.tols.split(",")):
        runs = {"heyoka": lambda tol=tol: (heyoka_points(tol), 0.0)}
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
        for k, (pts, spp) in res.items():
            evals = (
                ""
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
