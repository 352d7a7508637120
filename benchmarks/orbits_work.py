"""Work counts of the periodic-orbit tools, independent of the machine's load (issue 22: orbits and continuation).

    .venv/bin/python benchmarks/orbits_work.py [--cases click,grid,fig10grid,cascade,fine] [--json out.json]

For each case of ``benchmarks/orbits_speed.py`` (a click, the 15 x 15 grid of Fig. 8B to period 8, the Fig. 10
cascade 1 -> 16 with default steps and with ``ds_max = 0.01``) and the Fig. 10 10 x 10-seed period-1 search
(``bilimovich orbits --scene fig10``), counts what the engine integrates: member-periods of the tangent system
and of the field alone, their steps (accepted + rejected, summed over members: the field evaluations divided by
the stages), engine calls; Newton iterations (``derivative_points``: seed-iterations), continuation points,
corrector iterations (``corrector_iterations``: branch evaluations), central differences of ``F_p``
(``fp_evaluations``) and Jacobians of a bifurcation's defining system (``defining_evaluations``). Keys ending
``_loose`` count integrations at rtol above 1e-9 (Newton's rough maps, the looser differences), the others at
1e-9 and below. The engine does not report rejected steps apart: they are in the steps. One process, no
timing: run it on a loaded machine too.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from contextlib import contextmanager
from typing import Any

import numpy as np

from explorer_core.solve import integrators, poincare, rk, tangent

NAMES = {rk.FIELD: "field", rk.TANGENT: "tangent", rk.LYAPUNOV: "lyapunov", rk.BODY: "body"}


@contextmanager
def counting() -> Any:
    """Count every engine call (``integrators.run``, however imported) and every Newton iteration."""
    c: Counter = Counter()
    orig_run = integrators.run
    orig_deriv = poincare.PoincareMap.derivative

    def run(system: int, coefs: Any, batch: Any, n_periods: int, **kw: Any) -> Any:
        before = batch.nsteps.copy()
        out = orig_run(system, coefs, batch, n_periods, **kw)
        name = NAMES[system]
        tight = "" if kw.get("rtol", 1.0) <= 1e-9 else "_loose"
        c[f"{name}{tight}_calls"] += 1
        c[f"{name}{tight}_member_periods"] += int(batch.n) * int(n_periods)
        c[f"{name}{tight}_steps"] += int((batch.nsteps - before).sum())
        return out

    def derivative(self: Any, x: np.ndarray, n: int, *a: Any, **k: Any) -> Any:
        c["derivative_points"] += int(np.asarray(x).reshape(-1, 2).shape[0])
        return orig_deriv(self, x, n, *a, **k)

    mods = (integrators, poincare, tangent)
    saved = [(m, m.__dict__.get("run")) for m in mods]
    for m in mods:
        if "run" in m.__dict__:
            m.run = run
    poincare.PoincareMap.derivative = derivative
    try:
        yield c
    finally:
        for m, f in saved:
            if f is not None:
                m.run = f
        poincare.PoincareMap.derivative = orig_deriv


def cases() -> dict[str, Any]:
    from explorer_core.analyses.continuation import continue_orbit
    from explorer_core.analyses.orbits import find_orbits, grid_seeds
    from explorer_core.scenes import get_scene

    fig8b = get_scene("fig8B")
    fig10s = get_scene("fig10")
    fig10 = fig10s.params.with_(alpha=-0.35)
    clicks = [(-0.03, -2.39), (-1.45, -4.12), (-0.02, 0.07)]

    def click() -> dict[str, Any]:
        out = [find_orbits(fig8b.params, [c], [1]) for c in clicks]
        return {"orbits": [len(r.orbits) for r in out]}

    def grid() -> dict[str, Any]:
        res = find_orbits(fig8b.params, grid_seeds(fig8b.box, 15, 15), list(range(1, 9)))
        return {"orbits": len(res.orbits), "periods": sorted(Counter(o.period for o in res.orbits).items())}

    def fig10grid() -> dict[str, Any]:
        res = find_orbits(fig10s.params, grid_seeds(fig10s.box, 10, 10), [1])
        return {"orbits": len(res.orbits), "failures": len(res.failures)}

    def cascade(**kw: Any) -> dict[str, Any]:
        res = continue_orbit(fig10, "alpha", (-0.35, -0.42), (-0.0959, -1.962), 1, switch=True, max_period=16, **kw)
        return {
            "points": res.n_points,
            "doublings": [round(b.value, 10) for b in res.bifurcations if b.kind == "period_doubling"],
            "complete": res.complete,
        }

    return {
        "click": click,
        "grid": grid,
        "fig10grid": fig10grid,
        "cascade": cascade,
        "fine": lambda: cascade(ds_max=0.01),
    }


def corrector_counts() -> tuple[Any, Any]:
    """Count the continuation's corrector iterations (branch problem evaluations)."""
    from explorer_core.analyses import continuation as co

    c: Counter = Counter()
    orig_eval, orig_fp = co._BranchProblem.evaluate, co._System.fp
    orig_sys_eval = co._System.evaluate

    def evaluate(self: Any, X: Any, chord: Any = None) -> Any:
        c["corrector_iterations"] += 1
        return orig_eval(self, X, chord)

    def fp(self: Any, *a: Any, **k: Any) -> Any:
        c["fp_evaluations"] += 1
        return orig_fp(self, *a, **k)

    def sys_eval(self: Any, *a: Any, **k: Any) -> Any:
        c["defining_evaluations"] += 1
        return orig_sys_eval(self, *a, **k)

    co._BranchProblem.evaluate, co._System.fp, co._System.evaluate = evaluate, fp, sys_eval

    def restore() -> None:
        co._BranchProblem.evaluate, co._System.fp, co._System.evaluate = orig_eval, orig_fp, orig_sys_eval

    return c, restore


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="click,grid,fig10grid,cascade,fine")
    ap.add_argument("--json")
    args = ap.parse_args()
    todo = cases()
    report = {}
    for name in args.cases.split(","):
        extra, restore = corrector_counts()
        try:
            with counting() as c:
                result = todo[name]()
        finally:
            restore()
        c.update(extra)
        report[name] = {"result": result, **dict(sorted(c.items()))}
        print(name, json.dumps(report[name]), flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
