"""Time a section with this project's kernels and with scipy's solve_ivp, same RHS, same tolerance.

    .venv/bin/python benchmarks/section_vs_solve_ivp.py [--scene fig1C] [--random 100] [--periods 1000]
        [--ivp-trajectories 5] [--repeat 3]

solve_ivp is run on a subset of the trajectories (it is slow) and its time per
trajectory is reported next to ours; both see the same initial conditions,
right-hand side (the model's coefficients) and rtol = atol. Medians of --repeat runs.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
from scipy.integrate import solve_ivp

from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import warmup
from explorer_core.solve.numerics import Numerics, random_ics
from explorer_core.solve.section import section
from explorer_core.system.model import Model


def ivp_section(model: Model, ic, periods: int, tol: float) -> np.ndarray:
    p = model.params

    def f(t, y):
        c = model.coefficients(t)
        q, r = y
        mon = (1.0, q, r, q * q, q * r, r * r)
        return [sum(a * b for a, b in zip(c[0], mon, strict=True)), sum(a * b for a, b in zip(c[1], mon, strict=True))]

    t_eval = p.t0 + p.period * np.arange(1, periods + 1)
    sol = solve_ivp(f, (p.t0, t_eval[-1]), ic, method="DOP853", rtol=tol, atol=tol, t_eval=t_eval)
    return sol.y.T


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="fig1C")
    ap.add_argument("--random", type=int, default=100)
    ap.add_argument("--periods", type=int, default=1000)
    ap.add_argument("--ivp-trajectories", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    scene = get_scene(args.scene)
    ics = random_ics(args.random, scene.box, seed=0)
    warmup()
    rows = []
    for label, num in (("scene plot accuracy", scene.numerics(args.periods)), ("rtol 1e-10", Numerics())):
        times = []
        for _ in range(args.repeat):
            sec = section(scene.params, ics, args.periods, numerics=num)
            times.append(sec.elapsed_s)
        ours = statistics.median(times)
        ours1 = []
        for _ in range(args.repeat):
            s1 = section(scene.params, ics, args.periods, numerics=num, workers=1)
            ours1.append(s1.elapsed_s)
        m = Model(scene.params)
        t0 = time.perf_counter()
        for ic in ics[: args.ivp_trajectories]:
            ivp_section(m, ic, args.periods, num.rtol)
        ivp_per = (time.perf_counter() - t0) / args.ivp_trajectories
        rows.append(
            {
                "settings": label,
                "rtol": num.rtol,
                "ours_s_2cores": round(ours, 4),
                "ours_s_1core": round(statistics.median(ours1), 4),
                "ours_per_traj_ms": round(1e3 * ours / args.random, 3),
                "steps_per_period_mean": round(float(sec.nsteps.mean()) / args.periods, 1),
                "solve_ivp_per_traj_s": round(ivp_per, 3),
                "solve_ivp_est_total_s": round(ivp_per * args.random, 1),
                "speedup_per_traj_vs_2core": round(ivp_per * args.random / ours, 0),
                "escaped": int(np.count_nonzero(sec.status == 1)),
            }
        )
        print(json.dumps(rows[-1]), flush=True)


if __name__ == "__main__":
    main()
