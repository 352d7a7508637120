"""How many periods, and how much time, each chaos indicator needs to classify an orbit as a long Lyapunov run does.

Issue 34's comparison (docs/indicators.md): two sets of ``n`` initial conditions, **regular** on the invariant curves
of Fig. 5A's central island (a grid about the centre, every orbit bounded) and **chaotic** on Fig. 8B's strange
attractor (points of one orbit after a transient of 100 periods, seven periods apart). The reference is the
Lyapunov exponent over ``reference`` periods (:mod:`explorer_core.analyses.lyapunov`): chaotic when
``lambda_1 T > LYAP_TOL`` per period. Each indicator runs on a ladder of lengths (every IC of a set in one batch per
rung); an IC *needs* the first rung from which every longer rung's verdict equals the reference's. Reported per
indicator and set: how many ICs agree at the longest rung, the median and largest periods needed, and the seconds
of the batch at the rung where every IC (or, if never, the most) agreed, against the seconds of the reference batch
(medians of ``repeat`` runs each, one after the other in this process). The indicators:

* Birkhoff: weighted Birkhoff averages of ``q``, ``2 N`` periods (:func:`~explorer_core.analyses.indicators.birkhoff`);
* SALI: at most ``N`` periods, a chaotic orbit stopping once decided (:func:`~explorer_core.analyses.indicators.sali`;
  its periods are those it used);
* FTLE: the finite-time exponent over ``N`` periods (:func:`~explorer_core.analyses.ftle.ftle_tile`), chaotic when
  above ``LYAP_TOL`` per period, as the reference.

``benchmarks/indicators_speed.py`` runs the full comparison (20 ICs a set, 5,000 periods of reference);
``bilimovich bench`` a small one (:class:`~explorer_core.studies.bench.BenchConfig`'s ``indicator_*``).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from explorer_core.analyses import indicators as ind
from explorer_core.analyses.ftle import ftle_tile
from explorer_core.analyses.lyapunov import LYAPUNOV_NUMERICS, lyapunov_spectrum
from explorer_core.scenes import get_scene
from explorer_core.solve.section import section
from explorer_core.system.params import Params

#: Largest exponent per period (lambda_1 T) above which the reference calls an orbit chaotic.
LYAP_TOL = 0.01
#: Ladders of lengths per indicator: the full comparison's.
LADDERS = {
    "birkhoff": (50, 100, 200, 400, 800, 1600),  # N: 2 N periods
    "sali": (25, 50, 100, 200, 500, 1000, 2000),
    "ftle": (25, 50, 100, 200, 500, 1000, 2000),
}


def sets(n: int) -> dict[str, tuple[Params, np.ndarray]]:
    """``name -> (params, ics (n, 2))``: the island's grid and points of the attractor."""
    island = get_scene("fig5A").params
    side = int(np.ceil(np.sqrt(n)))
    g = np.linspace(-0.45, 0.45, side)
    qq, rr = np.meshgrid(g, g * 0.8)
    regular = np.column_stack([qq.ravel(), rr.ravel()])[:n]
    strange = get_scene("fig8B").params
    orbit = section(strange, [(-1.0, -2.0)], 100 + 7 * n).points[0]
    chaotic = orbit[100::7][:n]
    return {"regular": (island, regular), "chaotic": (strange, chaotic)}


def verdicts(name: str, params: Params, ics: np.ndarray, n: int, repeat: int) -> tuple[np.ndarray, np.ndarray, float]:
    """The indicator's verdicts (1 chaotic, 0 regular, -1 undecided) on ``ics`` at rung ``n``, the periods each
    used, and the batch's median seconds over ``repeat`` runs."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        v, used = _run(name, params, ics, n)
        times.append(time.perf_counter() - t)
    out = np.where(v == ind.CHAOTIC, 1, np.where(v == ind.REGULAR, 0, -1))
    return out, used, statistics.median(times)


def _run(name: str, params: Params, ics: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    if name == "birkhoff":
        res = ind.birkhoff(params, ics, n)
        v, used = res.verdict, np.full(len(ics), 2 * n)
    elif name == "sali":
        res = ind.sali(params, ics, n)
        v, used = res.verdict, res.npts.copy()
    else:
        ftle, status, _ = ftle_tile(params, LYAPUNOV_NUMERICS, ics, n, 1)
        v = np.where(status != 0, ind.NO_VERDICT, np.where(ftle * params.period > LYAP_TOL, ind.CHAOTIC, ind.REGULAR))
        used = np.full(len(ics), n)
    return v, used


def measure(
    n: int,
    reference: int,
    repeat: int,
    ladders: dict[str, tuple[int, ...]] | None = None,
    tick: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The comparison as a JSON-able dict: ``sets -> {reference_s, reference_chaotic, reference_ok, indicators ->
    name -> {agree_at_longest, periods_median, periods_max, never, all_agree_at, seconds_at_that_rung, speedup,
    rungs [(length, wrong, undecided)], disagree_at_longest}, seconds -> name -> [the batch's seconds per rung]}``
    (the seconds per rung draw the speed tab's chart against time). ``tick(text)`` is called after each batch."""
    ladders = LADDERS if ladders is None else ladders
    report: dict[str, Any] = {"n": n, "reference_periods": reference, "lyap_tol": LYAP_TOL, "repeat": repeat,
                              "ladders": {k: list(v) for k, v in ladders.items()}, "sets": {}}  # fmt: skip
    for set_name, (params, ics) in sets(n).items():
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            ly = lyapunov_spectrum(params, ics, reference)
            times.append(time.perf_counter() - t)
        ref_s = statistics.median(times)
        if tick is not None:
            tick(f"indicators: {set_name} reference")
        ref = (ly.exponents[:, 0] * params.period > LYAP_TOL).astype(int)
        entry = {"reference_s": round(ref_s, 3), "reference_chaotic": int(ref.sum()), "reference_ok": int(ly.ok.sum()),
                 "indicators": {}, "seconds": {}}  # fmt: skip
        for name, ladder in ladders.items():
            rungs = [verdicts(name, params, ics, k, repeat) for k in ladder]
            if tick is not None:
                tick(f"indicators: {set_name} {name}")
            agree = np.array([v == ref for v, _, _ in rungs])  # (rungs, n)
            entry["seconds"][name] = [round(t, 4) for _, _, t in rungs]
            # the first rung from which every longer rung agrees
            settled = np.array([np.all(agree[j:], axis=0) for j in range(len(ladder))])
            first = np.where(settled.any(axis=0), settled.argmax(axis=0), -1)
            used = np.array([rungs[j][1][i] if j >= 0 else -1 for i, j in enumerate(first)])
            best = int(np.argmax(agree.sum(axis=1) == n)) if (agree.sum(axis=1) == n).any() else int(
                np.argmax(agree.sum(axis=1)))  # fmt: skip
            entry["indicators"][name] = {
                "agree_at_longest": int(agree[-1].sum()),
                "periods_median": float(np.median(used[used >= 0])) if (used >= 0).any() else None,
                "periods_max": int(used.max()) if (used >= 0).all() else None,
                "never": int((used < 0).sum()),
                "all_agree_at": ladder[best] if agree[best].all() else None,
                "seconds_at_that_rung": round(rungs[best][2], 3),
                "speedup": round(ref_s / max(rungs[best][2], 1e-9), 1),
                # per rung: (length, verdicts opposite to the reference's, undecided)
                "rungs": [(k, int(((v >= 0) & (v != ref)).sum()), int((v < 0).sum()))
                          for k, (v, _, _) in zip(ladder, rungs, strict=True)],
                "disagree_at_longest": [
                    {"ic": ics[i].round(4).tolist(), "lambda1_T": round(float(ly.exponents[i, 0] * params.period), 5),
                     "verdict": int(rungs[-1][0][i])}
                    for i in np.flatnonzero(~agree[-1])
                ],
            }  # fmt: skip
        report["sets"][set_name] = entry
    return report


def table(report: dict[str, Any]) -> str:
    """The comparison as a Markdown table (a work-precision table: agreement, periods, seconds)."""
    lines = [f"reference: Lyapunov over {report['reference_periods']} periods, chaotic when lambda_1 T > "
             f"{report['lyap_tol']}; {report['n']} ICs a set",
             "| set | indicator | agree (longest rung) | periods needed: median / max | all agree at | s at that rung "
             "| Lyapunov s | speed-up |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for set_name, e in report["sets"].items():
        for name, d in e["indicators"].items():
            lines.append(f"| {set_name} | {name} | {d['agree_at_longest']}/{report['n']} | {d['periods_median']} / "
                         f"{d['periods_max']} | {d['all_agree_at']} | {d['seconds_at_that_rung']} | "
                         f"{e['reference_s']} | {d['speedup']}x |")  # fmt: skip
    return "\n".join(lines)
