"""Continuation's work (issue 22: orbits and continuation faster at their accuracy), counted, not timed.

The central differences (``F_p``, the test function's derivatives) steer Newton and give the tangent only: they
run at a looser tolerance than the orbit, tightened with the orbit's instability; the located bifurcations'
secant steps are corrected by full Newton (a frozen ``F_p`` tripled their iterations). The answers are checked
against independent computations in tests/test_continuation.py and tests/test_continuation_metamorphic.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from enginework import count_engine
from naive import ivp_map

from explorer_core.analyses import continuation as co
from explorer_core.analyses.continuation import events
from explorer_core.analyses.orbits import ORBIT_NUMERICS
from explorer_core.scenes import get_scene
from explorer_core.solve import rk

FIG10 = get_scene("fig10").params
FIXED_POINT_035 = (-0.0959, -1.962)


def test_the_differences_run_looser_than_the_orbit_and_tighten_with_its_instability() -> None:
    sys = co._System(FIG10, ["alpha"], ORBIT_NUMERICS, 1)
    assert sys.fd_numerics(1.0).rtol == pytest.approx(1e-9)  # 1e-12 orbits: differences at 1e-9
    assert sys.fd_numerics(1e5).rtol == pytest.approx(1e-11)  # |DP^n| = 1e5: the error ~0.1 rtol |DP^n| stays 1e-7
    assert sys.fd_numerics(1e9).rtol == ORBIT_NUMERICS.rtol  # never tighter than the orbit
    loose = co._System(FIG10, ["alpha"], ORBIT_NUMERICS.__class__(rtol=1e-8, atol=1e-8), 1)
    assert loose.fd_numerics(1.0).rtol == 1e-8  # never looser than the orbit either


@pytest.mark.parametrize("n", [1, 2])
def test_f_p_at_the_looser_tolerance_matches_an_independent_difference(n: int) -> None:
    # The fixed point (n = 1) and the 2-cycle (n = 2) of Fig. 10 near alpha = -0.39 (after the first doubling).
    p = -0.39 if n == 2 else -0.36
    res = co.continue_orbit(FIG10, "alpha", (-0.35, p), FIXED_POINT_035, 1, switch=n == 2, max_period=2)
    br = res.branches[n - 1]
    x, value = np.array(br.states[-1]), br.values[-1]
    sys = co._System(FIG10, ["alpha"], ORBIT_NUMERICS, 1)
    amp = float(np.abs(np.array(br.mults[-1])).max())
    fp = sys.fp(x, [value], n, amp)[:, 0]
    h = 1e-5
    ref = (ivp_map(FIG10.with_(alpha=value + h), x, n) - ivp_map(FIG10.with_(alpha=value - h), x, n)) / (2 * h)
    np.testing.assert_allclose(fp, ref, rtol=1e-5, atol=1e-7)


def test_the_differences_take_fewer_steps_than_the_orbit(monkeypatch: pytest.MonkeyPatch) -> None:
    # Before: F_p's two members at the orbit's 1e-12 (alpha -0.35 .. -0.38), as many steps a period as the orbit.
    c = count_engine(monkeypatch)
    res = co.continue_orbit(FIG10, "alpha", (-0.35, -0.38), FIXED_POINT_035, 1)
    assert [b.kind for b in res.bifurcations] == ["period_doubling"]
    rate = {key[1:]: c[key] / c[("periods", *key[1:])] for key in c if key[0] == "steps"}
    field = [v for (s, _), v in rate.items() if s == rk.FIELD]
    assert field and max(field) < 0.75 * rate[(rk.TANGENT, ORBIT_NUMERICS.rtol)], rate


def count_evaluations(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts every evaluation of the branches' corrector (``_BranchProblem.evaluate``) while the test runs."""
    evals = {"n": 0}
    orig_eval = co._BranchProblem.evaluate

    def evaluate(self, X, chord=None):
        evals["n"] += 1
        return orig_eval(self, X, chord)

    monkeypatch.setattr(co._BranchProblem, "evaluate", evaluate)
    return evals


def test_a_doubling_is_located_with_a_few_newton_steps_per_secant_step(monkeypatch: pytest.MonkeyPatch) -> None:
    # Before: the secant steps' corrector froze F_p at the bracket's end and started on the tangent line: 6
    # evaluations each on the period-2 branch (10-11 on the period-4 one); now 1-2 (full Newton, from the cubic).
    evals = count_evaluations(monkeypatch)
    counts: list[tuple[int, int]] = []
    orig_at = co._Engine.at

    def at(self, prob, pt, sigma, end=None):
        before = evals["n"]
        try:
            return orig_at(self, prob, pt, sigma, end)
        finally:
            counts.append((prob.n, evals["n"] - before))

    monkeypatch.setattr(co._Engine, "at", at)
    res = co.continue_orbit(FIG10, "alpha", (-0.35, -0.41), FIXED_POINT_035, 1, switch=True, max_period=2)
    assert [b.period for b in res.bifurcations] == [1, 2]
    assert counts and max(k for _, k in counts) <= 3, counts


def test_the_doublings_do_not_depend_on_the_longest_step() -> None:
    # ds_max = 0.01 (the issue's ~300 points) against the default steps: the same five doublings, to their stated
    # error. (A refinement that stopped at the map's noise once fell back to the secant value, 5e-11 off the
    # refined one with a stated error of 4e-14.)
    runs = [
        co.continue_orbit(FIG10, "alpha", (-0.35, -0.4126), FIXED_POINT_035, 1, switch=True, max_period=16, **kw)
        for kw in ({}, {"ds_max": 0.01})
    ]
    pds = [[b for b in r.bifurcations if b.kind == "period_doubling"] for r in runs]
    assert [b.period for b in pds[0]] == [b.period for b in pds[1]] == [1, 2, 4, 8, 16]
    for a, b in zip(*pds, strict=True):
        assert abs(a.value - b.value) <= 10 * (a.error + b.error) + 1e-13, (a, b)


def test_the_cascade_takes_few_corrector_evaluations_a_point(monkeypatch: pytest.MonkeyPatch) -> None:
    # Everything the branches' corrector evaluates (steps, refused steps, secant steps, landings) per point of the
    # cascade 1 -> 16: main took 613 for 95 points (6.5); the looser differences, the cubic secant predictions and
    # the second-order prediction of the steps bring it to ~3.4.
    evals = count_evaluations(monkeypatch)
    res = co.continue_orbit(FIG10, "alpha", (-0.35, -0.42), FIXED_POINT_035, 1, switch=True, max_period=16)
    assert [b.period for b in res.bifurcations] == [1, 2, 4, 8, 16] and res.complete
    assert evals["n"] <= 4.5 * res.n_points, (evals["n"], res.n_points)


def test_a_doubling_is_refined_with_few_central_differences(monkeypatch: pytest.MonkeyPatch) -> None:
    # Newton on the defining system (P^n(x) - x, det(A + I)) = 0 keeps its Jacobian (six members of central
    # differences) while the steps contract tenfold; main took a fresh one at every step, and again for the
    # error estimate's refinement: 6 per doubling here.
    calls = {"n": 0}
    orig = co._defining

    def defining(*a, **k):
        calls["n"] += 1
        return orig(*a, **k)

    monkeypatch.setattr(events, "_defining", defining)  # where the refinement looks it up (co re-exports it)
    res = co.continue_orbit(FIG10, "alpha", (-0.35, -0.4118), FIXED_POINT_035, 1, switch=True, max_period=4)
    pds = [b for b in res.bifurcations if b.kind == "period_doubling"]
    assert [b.period for b in pds] == [1, 2, 4]
    assert 0 < calls["n"] <= 3 * len(pds), calls  # (0: the patch missed the module that calls it)
    for b in pds:  # the refined points are doublings: mu = -1 to the map's accuracy
        assert np.min(np.abs(b.multipliers + 1.0)) < 1e-9, b
