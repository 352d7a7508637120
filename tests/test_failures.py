"""Where the methods fail: failures are produced, detected and reported, not only good cases passing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clirun import run_cli

from app.controller import ExplorerSession
from app.runner import WARM, InlineExecutor, Runner
from app.state import ExplorerState
from explorer_core.analyses.reliability import (
    RK4_Z_DRIFT_LOST,
    RK4_Z_UNSTABLE,
    ReliabilityWarning,
    assess,
    assess_section,
)
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Status
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import section
from explorer_core.studies import failures as F

FIG1A = get_scene("fig1A")
WINDOW_1A = (*FIG1A.q_range, *FIG1A.r_range)


def codes(warnings: list[ReliabilityWarning]) -> set[str]:
    return {w.code for w in warnings}


# --- measurements the thresholds rest on ----------------------------------------------------------


def test_stability_intervals_of_the_tableaus() -> None:
    # Known real-axis stability limits: RK4 2.7853, DP5 3.3066 (Hairer & Wanner), DOP853 about 6.4.
    assert F.stability_interval("rk4") == pytest.approx(2.7853, abs=1e-3)
    assert F.stability_interval("dp5") == pytest.approx(3.3066, abs=1e-3)
    assert 6.0 < F.stability_interval("dop853") < 6.6


def test_fastest_rate_on_the_drift_is_a_third_of_r() -> None:
    # diag(1, 2, 4): dQ/dq = g r / (g^2 + 2) dominates, largest at |g| = 1.
    rho = F.spectral_rate(FIG1A.params, [-0.3, -0.3], [-600.0, 1500.0])
    np.testing.assert_allclose(rho, [200.0, 500.0], rtol=2e-3)


def test_local_map_finds_the_instability_and_the_lost_drift() -> None:
    lm = F.local_map((20.0, 80.0, 320.0), tuple(2**j for j in range(3, 11)), reference="dop853")
    assert np.any(lm.status == Status.NONFINITE), "coarse RK4 on the drift must overflow"
    th = lm.thresholds()
    # The overflow sets in at rho h ~ 2.6 (linear theory: 2.785), the drift is lost well before.
    assert 2.0 < th["z_unstable_min"] < 3.2
    assert th["z_drift_lost_min"] < th["z_unstable_min"]
    assert RK4_Z_DRIFT_LOST <= th["z_drift_lost_min"] + 0.05
    assert RK4_Z_UNSTABLE <= th["z_unstable_min"] + 0.05
    # The N-vs-2N estimate reliability uses tracks the true one-period error.
    ratio = th["richardson_over_error"]
    assert 0.5 < ratio["median"] < 2.0


def test_float32_costs_accuracy_that_float64_does_not() -> None:
    params = FIG1A.params
    ics = np.array(F.ISLAND_ICS[:3])
    periods, steps = 15, 200
    ref = section(params, ics, periods, numerics=Numerics(rtol=1e-13, atol=1e-13)).points.transpose(1, 0, 2)
    x64 = F.rk4_numpy(params, ics, periods, steps, np.float64)
    x32 = F.rk4_numpy(params, ics, periods, steps, np.float32)
    assert x64.dtype == np.float64 and x32.dtype == np.float32
    e64 = F.relative_error(x64, ref).max()
    e32 = F.relative_error(x32.astype(float), ref).max()
    assert e32 > 30 * e64 and e32 > 1e-6
    # The numpy reference is the kernels' RK4: same steps, same points to round-off.
    kern = section(params, ics, periods, numerics=Numerics(method="rk4", steps_per_period=steps))
    np.testing.assert_allclose(x64, kern.points.transpose(1, 0, 2), rtol=0, atol=1e-11)


def test_adaptive_cost_grows_along_the_drift_and_respects_the_stability_floor() -> None:
    starts = np.array([F.drift_state(v) for v in (20.0, 640.0)])
    _, status, steps, _ = F._run(FIG1A.params, starts, 2, Numerics(rtol=1e-6, atol=1e-6, bound=1e300), per_period=True)
    assert np.all(status == Status.OK)
    per = steps[:, 1]
    assert per[1] > 3 * per[0]
    floor = F.spectral_rate(FIG1A.params, starts[:, 0], starts[:, 1]) * FIG1A.params.period
    assert np.all(per >= floor / F.stability_interval("dop853"))


# --- every status is produced and reported ----------------------------------------------------------


def test_each_status_scenario_produces_its_status_and_a_warning() -> None:
    rows = F.status_scenarios()
    assert [r.status for r in rows] == [r.expected for r in rows]
    assert {r.status for r in rows} == {"ok", "escaped", "too_many_steps", "step_collapsed", "nonfinite"}
    for r in rows:
        if r.status == "ok":
            # The silent failure: RK4 stalls with status ok; only the reliability check sees it.
            assert "warning:rk4_drift_lost" in r.warnings, r
        else:
            assert any(w.endswith(":" + r.status) for w in r.warnings), r
            assert r.k_fail is not None and r.points == r.k_fail - 1


def test_no_step_collapse_at_large_t() -> None:
    # t0 is reduced exactly to its phase before the engine's clock starts (it collapsed at 1e12 before).
    c = F.collapse_onset(tols=(1e-10,), exponents=(6, 12))
    assert c["by_tol"]["1e-10"]["status"] == ["ok", "ok"] and c["by_tol"]["1e-10"]["first_collapse_exponent"] is None


# --- reliability.assess ---------------------------------------------------------------------------


def test_rk4_with_few_steps_on_the_drift_is_an_error_and_overflows() -> None:
    num = Numerics(method="rk4", steps_per_period=16, bound=1e300)
    found = assess(FIG1A.params, num, periods=10, ics=[(-0.3, -100.0)])
    assert [w.level for w in found if w.code == "rk4_unstable"] == ["error"]
    assert "rho*h = " in found[0].message and "16 steps" in found[0].message
    sec = section(FIG1A.params, [(-0.3, -100.0)], 10, numerics=num)
    assert sec.status_labels() == ["nonfinite"]
    after = codes(assess_section(sec))
    assert {"rk4_unstable", "nonfinite"} <= after


def test_rk4_stall_is_silent_in_the_status_but_warned() -> None:
    sec = section(FIG1A.params, [(-0.3, -20.0)], 800, numerics=Numerics(method="rk4", steps_per_period=100))
    ref = section(FIG1A.params, [(-0.3, -20.0)], 800, numerics=Numerics())
    assert sec.status_labels() == ["ok"]
    _, _, r = sec.trajectory(0)
    _, _, r_ref = ref.trajectory(0)
    assert abs(r[-1] - r[-2]) < 1e-6 and abs(r_ref[-1]) > 3 * abs(r[-1])  # stalled, the true drift went on
    found = assess_section(sec, pixel=FIG1A.pixel_size(), window=WINDOW_1A)
    assert "rk4_drift_lost" in codes(found)


def test_dop853_at_tight_tolerance_on_regular_orbits_gives_no_warning() -> None:
    sec = section(FIG1A.params, F.ISLAND_ICS[:4], 200, numerics=Numerics(rtol=1e-10, atol=1e-10))
    assert sec.status_labels() == ["ok"] * 4
    assert assess_section(sec, pixel=FIG1A.pixel_size(), window=WINDOW_1A) == []
    c = get_scene("fig1C")
    sec = section(c.params, c.initial_conditions()[:10], 100, numerics=c.numerics(100))
    assert assess_section(sec, pixel=c.pixel_size(), window=(*c.q_range, *c.r_range)) == []


def test_loose_tolerance_budget_and_chaotic_horizon_are_warned() -> None:
    c = get_scene("fig1C")
    found = assess(c.params, Numerics(rtol=1e-4, atol=1e-4), periods=500, ics=c.initial_conditions(),
                   pixel=c.pixel_size())  # fmt: skip
    assert "tolerance_loose" in codes(found)
    found = assess(FIG1A.params, Numerics(max_steps=100), periods=10, ics=[(-0.3, -2000.0)])
    assert [w.level for w in found if w.code == "step_budget"] == ["error"]
    b = get_scene("fig8B")
    high = assess(b.params, Numerics(rtol=1e-12, atol=1e-12), periods=500, ics=b.initial_conditions()[:3],
                  pixel=b.pixel_size())  # fmt: skip
    assert "chaotic_horizon" in codes(high)
    plot = assess(b.params, b.numerics(500), periods=500, ics=b.initial_conditions()[:3], pixel=b.pixel_size())
    assert "chaotic_horizon" not in codes(plot)


def test_drift_and_escapes_are_reported() -> None:
    sec = section(FIG1A.params, [(-0.3, -20.0), (0.3, 0.3)], 400, numerics=Numerics(bound=100.0))
    assert sec.status_labels() == ["escaped", "ok"]
    found = {w.code: w for w in assess_section(sec, window=WINDOW_1A)}
    assert "1 of 2 trajectories escaped" in found["escaped"].message
    assert found["drift"].message.startswith("1 trajectory leaves the plot window")


# --- the command line and the app -----------------------------------------------------------------


def test_cli_failures_writes_json_and_pictures(tmp_path) -> None:
    out = tmp_path / "f"
    rc, _, err = run_cli("failures", "--out", str(out), "--size", "tiny", "--quiet")
    assert rc == 0, err
    d = json.loads((out / "failures.json").read_text())
    assert d["size"] == "tiny" and d["completed"]
    assert {r["status"] for r in d["status_scenarios"]} >= {"escaped", "nonfinite", "step_collapsed"}
    assert d["rk4_on_drift"]["local_map"]["thresholds"]["z_unstable_min"] is not None
    pngs = sorted(p.name for p in out.glob("failure_*.png"))
    assert len(pngs) == 6 and all((out / p).stat().st_size > 10_000 for p in pngs)


def test_cli_section_prints_reliability_warnings() -> None:
    args = ("section", "--scene", "fig1A", "--ic=-0.3,-20", "--periods", "600", "--method", "rk4",
            "--steps-per-period", "100")  # fmt: skip
    rc, _, err = run_cli(*args)
    assert rc == 0
    lines = [ln for ln in err.splitlines() if "rk4_drift_lost" in ln]
    assert len(lines) == 1 and lines[0].startswith("bilimovich section: warning [rk4_drift_lost]")
    rc, out, err = run_cli(*args, "--json", "--quiet")
    assert rc == 0 and err == ""
    assert "rk4_drift_lost" in {w["code"] for w in json.loads(out)["reliability"]}


@pytest.fixture
def session() -> ExplorerSession:
    WARM.set()
    return ExplorerSession(ExplorerState(scene="fig1A"), Runner(lambda fn: fn(), executor=InlineExecutor()))


def test_app_warns_for_rk4_at_low_steps_on_the_drift(session: ExplorerSession) -> None:
    session.state.param.update(n_random=0, clicked=[(-0.3, -20.0)], periods=600, method="rk4", steps_per_period=100)
    assert "1 trajectory ·" in session.status and not session.failed  # the status says nothing is wrong
    found = {w["code"]: w for w in session.reliability}
    lost = found["rk4_drift_lost"]
    assert lost["level"] == "warning" and "100 steps per period" in lost["message"]
    session.state.steps_per_period = 8
    assert session.reliability[0]["level"] == "error" and session.reliability[0]["code"] == "rk4_unstable"
    session.state.method = "dop853"
    assert not any(w["code"].startswith("rk4") for w in session.reliability)
