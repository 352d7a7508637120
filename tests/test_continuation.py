"""Continuation of periodic orbits: the Fig. 10 cascade, a fold, two-parameter curves, checked independently."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from clirun import run_cli
from naive import fd_monodromy, ivp_fixed_point, ivp_map

from explorer_core.analyses.continuation import KINDS, continue_orbit
from explorer_core.analyses.continuation import test_function as phi
from explorer_core.analyses.regimes import PERIODIC, chart_spec, regime_chart
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError

FIG10 = get_scene("fig10").params
FIXED_POINT_035 = (-0.0959, -1.962)  # the stable fixed point of Fig. 10 at alpha = -0.35
#: The doubling values read off the orbit diagram by bisection (README, previous sessions).
DIAGRAM = (-0.375263, -0.406667, -0.411689, -0.412429)


@pytest.fixture(scope="module")
def cascade():
    return continue_orbit(FIG10, "alpha", (-0.35, -0.42), FIXED_POINT_035, 1, switch=True, max_period=16)


def test_the_cascade_1_2_4_8_16_is_followed_with_branch_switching(cascade) -> None:
    pds = [b for b in cascade.bifurcations if b.kind == "period_doubling"]
    assert [b.period for b in pds] == [1, 2, 4, 8, 16]
    assert [br.period for br in cascade.branches] == [1, 2, 4, 8, 16]
    values = [b.value for b in pds]
    assert all(a > b for a, b in itertools.pairwise(values))  # towards the accumulation point
    for b in pds:
        assert b.error < 1e-9, b
        np.testing.assert_allclose(min(b.multipliers, key=lambda m: abs(m + 1)), -1.0, atol=1e-9)
    # The orbit diagram's bisection is off in the 4th-5th digit (slow transients near mu = -1).
    np.testing.assert_allclose(values[:4], DIAGRAM, atol=2e-4)
    # The stable part: the period-1 branch is stable before its doubling, unstable after.
    br = cascade.branches[0]
    before = np.array(br.values) > values[0]
    assert br.stable[before].all() and not br.stable[~before].any()
    # Feigenbaum ratios of the first intervals, between the dissipative 4.67 and the conservative 8.72
    d = np.diff(values)
    ratios = d[:-1] / d[1:]
    assert np.all((ratios > 4.0) & (ratios < 9.0)), ratios


def test_each_doubling_point_is_one_for_an_independent_integrator(cascade) -> None:
    for b in [b for b in cascade.bifurcations if b.kind == "period_doubling"][:3]:
        p = FIG10.with_(alpha=b.value)
        x = b.point
        assert np.linalg.norm(ivp_map(p, x, b.period) - x) < 1e-7
        mu = np.linalg.eigvals(fd_monodromy(p, x, b.period))
        assert np.min(np.abs(mu + 1.0)) < 1e-5, mu


@pytest.mark.slow
def test_the_first_doubling_is_located_to_2e_9_by_an_independent_computation(cascade) -> None:
    # On both sides of the located value, 2e-9 away, the fixed point and its monodromy matrix from scipy's
    # DOP853 on the naive field (variational equations with complex-step Jacobians): det(A + I) changes sign.
    b = next(b for b in cascade.bifurcations if b.kind == "period_doubling")
    signs = []
    for off in (-2e-9, 2e-9):
        x, a = ivp_fixed_point(FIG10.with_(alpha=b.value + off), b.point, 1)
        signs.append(np.sign(phi("period_doubling", a)))
    assert signs[0] != signs[1]


def test_a_fold_of_the_period_three_orbit() -> None:
    # Fig. 11's 3-6-12 tongue: the period-3 saddle meets the node at a fold; the branch turns back.
    res = continue_orbit(FIG10.with_(I11=1.8, alpha=-0.5), "alpha", (-0.5, -0.4), (-0.9833, -1.5180), 3)
    (fold,) = [b for b in res.bifurcations if b.kind == "fold"]
    assert -0.5 < fold.value < -0.4 and fold.error < 1e-9
    assert "after a fold" in res.branches[0].stop
    mu = np.linalg.eigvals(fd_monodromy(FIG10.with_(I11=1.8, alpha=fold.value), fold.point, 3))
    assert np.min(np.abs(mu - 1.0)) < 1e-5, mu
    values = np.array(res.branches[0].values)
    assert values.max() == pytest.approx(fold.value, abs=2e-3)  # the branch's furthest point is the fold


def test_a_neimark_sacker_point_in_the_fig7_family() -> None:
    # The focus near the origin: unstable for alpha < 0 (Fig. 7), a complex pair crosses |mu| = 1 near alpha = 0.
    p = get_scene("fig7B").params
    res = continue_orbit(p, "alpha", (-0.01, 0.01), (-0.000426, 0.001717), 1)
    (ns,) = [b for b in res.bifurcations if b.kind == "neimark_sacker"]
    assert abs(ns.value) < 1e-6
    assert abs(ns.multipliers[0].imag) > 0 and np.abs(ns.multipliers) == pytest.approx([1, 1], abs=1e-8)


def test_the_period_doubling_curve_bounds_the_period_one_region_of_the_chart() -> None:
    res = continue_orbit(FIG10, "alpha", (-0.35, -0.42), FIXED_POINT_035, 1, param2="I11", range2=(0.9, 1.3))
    (curve,) = res.curves
    assert curve.kind == "period_doubling" and len(curve.rows) >= 5
    rows = np.array(curve.rows)
    assert rows[:, 1].min() >= 0.9 and rows[:, 1].max() <= 1.3
    # Independently, by brute force: the chart's classification (long transients, the period read off the
    # section) is period 1 on one side of the curve and 2 on the other.
    pick = rows[[1, len(rows) // 2, -2]]
    for a, i11, q, r in pick:
        spec = chart_spec(FIG10.with_(I11=i11), "alpha", (a - 0.004, a + 0.004), "I11", (i11, i11 + 1e-9), (2, 1),
                          ics=[(q + 1e-3, r)], transient=3000, periods=200,
                          numerics=Numerics(rtol=1e-10, atol=1e-10))  # fmt: skip
        chart = regime_chart(spec, workers=1)
        assert chart.regime[0, :, 0].tolist() == [PERIODIC, PERIODIC]
        assert chart.period[0, :, 0].tolist() == [2, 1], (a, i11, chart.period)  # alpha below the curve: doubled


def test_stops_are_reported() -> None:
    # I12 grows until the tensor is no longer positive definite: the branch stops and says why.
    base = FIG10.with_(alpha=-0.35)
    res = continue_orbit(base, "I12", (0.0, 3.0), FIXED_POINT_035, 1, max_points=200)
    assert "left the valid parameters" in res.branches[0].stop or "failed" in res.branches[0].stop
    # ... and it is a loss of the result, not a silent stop
    assert not res.complete and [loss.what.split(",")[0] for loss in res.lost] == ["branch 0 (period 1"]
    assert res.lost[0].why == res.branches[0].stop
    with pytest.raises(ParameterError, match="no period-1 orbit"):
        continue_orbit(base, "alpha", (-0.35, -0.3), (0.0, 8000.0), 1)
    with pytest.raises(ParameterError, match="cannot sweep"):
        continue_orbit(base, "I99", (0.0, 1.0), FIXED_POINT_035, 1)
    with pytest.raises(ParameterError, match="range"):
        continue_orbit(base, "alpha", (-0.35, -0.35), FIXED_POINT_035, 1)
    assert set(KINDS) == {"fold", "period_doubling", "neimark_sacker"}


def test_cli_continue_json_and_errors(tmp_path) -> None:
    out = tmp_path / "b.csv"
    rc, stdout, _ = run_cli("continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.39",
                            "--from=-0.0959,-1.962", "--period", "1", "--switch", "--max-period", "2",
                            "--param2", "I11", "--range2", "0.95,1.05", "--json", "--out", str(out))  # fmt: skip
    assert rc == 0
    d = json.loads(stdout)
    assert [b["period"] for b in d["branches"]] == [1, 2]
    pt = d["branches"][0]["points"][0]
    assert set(pt) == {"value", "q", "r", "multipliers", "stable"}
    (bif,) = d["bifurcations"]
    assert set(bif) >= {"type", "value", "error", "period", "point", "multipliers"}
    assert bif["type"] == "period_doubling" and bif["error"] < 1e-9
    # Its normal form (tests/test_normal_forms.py: b = 7.4152, supercritical by brute force).
    assert bif["criticality"] == "supercritical" and abs(bif["coefficient"] - 7.4152) < 1e-3
    assert 0 < bif["coefficient_error"] < 1e-3 and bif["resonance"] is None
    (curve,) = d["curves"]
    assert set(curve["points"][0]) == {"alpha", "I11", "q", "r"}
    assert d["params"] and d["numerics"]
    lines = out.read_text().splitlines()
    assert lines[0] == ("branch,period,value,q,r,mu1_re,mu1_im,mu2_re,mu2_im,stable,bifurcation,coefficient,"
                        "coefficient_error,criticality")  # fmt: skip
    (row,) = [line.split(",") for line in lines[1:] if "period_doubling" in line]
    assert float(row[2]) == bif["value"] and float(row[11]) == bif["coefficient"] and row[13] == "supercritical"
    assert sum(line.endswith(",,,,") for line in lines[1:]) == len(lines) - 2  # the other points: no bifurcation
    assert "supercritical period_doubling" not in stdout
    base = ("continue", "--scene", "fig10", "--period", "1", "--json")
    for args, msg in (
        (("--param", "I99", "--range", "0,1", "--from", "0,0"), "cannot sweep"),
        (("--param", "I12", "--range", "0,5", "--from", "0,0"), "not a valid system"),
        (("--param", "alpha", "--range=-0.35,-0.4", "--from", "1e9,0"), "outside the escape bound"),
        (("--param", "alpha", "--range=-0.35,-0.4"), "--from"),
        (("--param", "alpha", "--range=-0.35,-0.4", "--from=-0.0959,-1.962", "--param2", "I11"), "go together"),
    ):
        rc, _, err = run_cli(*base, *args)
        assert rc == 2 and msg in err and "Traceback" not in err, (args, err)
