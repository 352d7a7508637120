"""Drift fits: synthetic drifts with known polynomials, the implied map, a field with an exact drift."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from naive import solve_ivp_section

from explorer_core.analyses.drift import (
    Tables,
    drift_fit,
    drift_fit_tables,
    fit_polynomial,
    implied_map,
    on_drift,
    poly_text,
    quadratic_map,
    to_time,
)
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError


@pytest.mark.parametrize("degree", [0, 1, 2, 6])
def test_fit_recovers_a_known_polynomial(degree: int) -> None:
    rng = np.random.default_rng(degree)
    coef = rng.normal(size=degree + 1) * 10.0 ** -np.arange(degree + 1)  # sensible scale up to k = 900
    k = np.arange(200, 901)
    x = np.polynomial.polynomial.polyval(k, coef)
    got, res = fit_polynomial(k, x, degree)
    np.testing.assert_allclose(np.polynomial.polynomial.polyval(k, got), x, rtol=1e-9, atol=1e-9 * np.abs(x).max())
    assert np.abs(res).max() <= 1e-8 * max(1.0, np.abs(x).max())
    noisy, res = fit_polynomial(k, x + rng.normal(scale=1e-3, size=k.size), degree)
    assert np.sqrt(np.mean(res**2)) == pytest.approx(1e-3, rel=0.1)


def test_to_time_and_poly_text() -> None:
    coef_k = np.array([26.779718, -0.2386278, -0.0002545])
    t0, T = 0.3, 2 * math.pi
    coef_t = to_time(coef_k, t0, T)
    k = np.arange(0, 50)
    np.testing.assert_allclose(
        np.polynomial.polynomial.polyval(t0 + k * T, coef_t), np.polynomial.polynomial.polyval(k, coef_k), rtol=1e-12
    )
    assert poly_text(coef_k) == "-0.0002545 k^2 - 0.2386278 k + 26.77972"
    assert poly_text(coef_k, "t", digits=8) == "-0.0002545 t^2 - 0.2386278 t + 26.779718"


def test_quadratic_map_is_exact_on_its_curve_and_the_paper_formula_needs_time_and_sign() -> None:
    a, b, c = -0.0002545, -0.2386278, 26.779718  # the paper's Fig. 3 coefficients
    k = np.arange(200, 900)
    r = a * k**2 + b * k + c
    # In k, on the branch dr/dk < 0 (sign -1), the map reproduces the sequence exactly.
    np.testing.assert_allclose(quadratic_map(a, b, c, r[:-1], 1.0, -1.0), r[1:], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(implied_map(np.array([c, b, a]), r[:-1], k[:-1]), r[1:], rtol=1e-12, atol=1e-9)
    # The paper's formula (step 2 pi, sign +) is exact only for a curve in t with dr/dt > 0.
    t = 2 * math.pi * k
    rt = 1e-6 * t**2 + 0.3 * t + 1.0
    np.testing.assert_allclose(quadratic_map(1e-6, 0.3, 1.0, rt[:-1], 2 * math.pi, 1.0), rt[1:], rtol=1e-12)
    assert np.abs(quadratic_map(a, b, c, r[:-1], 2 * math.pi, 1.0) - r[1:]).min() > 1.0


def test_implied_map_of_a_cubic() -> None:
    coef = np.array([3.0, -2.0, 0.01, -1e-4])
    k = np.arange(0, 60, dtype=float)
    x = np.polynomial.polynomial.polyval(k, coef)
    np.testing.assert_allclose(implied_map(coef, x[:-1], k[:-1] + 0.3), x[1:], rtol=1e-9)


def test_on_drift_criteria() -> None:
    k = np.arange(200, 901)
    drift = np.column_stack([-0.3 + 0 * k, -0.00025 * k**2 - 0.24 * k + 27])
    assert on_drift(drift)
    theta = 0.7 * np.arange(300)
    assert not on_drift(np.column_stack([np.cos(theta), np.sin(theta)]))
    # Still sliding onto the curve: the direction of the steps turns by ~90 degrees.
    s = np.linspace(0, 1, 200)
    arc = np.column_stack([10 * np.cos(s * math.pi / 2), -10 - 50 * s**2])
    assert not on_drift(arc)
    assert on_drift(arc, "leaves") is False and on_drift(drift, "leaves") is True
    with pytest.raises(ParameterError, match="criterion"):
        on_drift(drift, "sometimes")


def exact_drift_field(c0: float, d0: float, d1: float) -> Tables:
    """q' = c0, r' = d0 + d1 q: q = q0 + c0 t, r = r0 + d0 t + d1 (q0 t + c0 t^2 / 2) (t from 0)."""
    num = np.zeros((3, 6, 5))
    num[0, 0, 0] = c0
    num[1, 0, 0], num[1, 1, 0] = d0, d1
    return Tables(num, np.zeros((3, 2)), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0, 1.0]), 0.0, 2 * math.pi)


def test_fit_through_the_integrator_recovers_an_exact_quadratic_drift() -> None:
    c0, d0, d1 = -0.01, -0.2, 0.05
    field = exact_drift_field(c0, d0, d1)
    ics = [(0.5, 1.0), (-0.2, 3.0), (0.1, -1.0)]
    fit = drift_fit_tables(field, (20, 120), degree=(1, 2), ics=ics)
    assert fit.members.shape[0] == 3 and fit.rejected == 0
    T = 2 * math.pi
    for (q0, r0), cq, cr in zip(ics, fit.coef_q, fit.coef_r, strict=True):
        np.testing.assert_allclose(cq, [q0, c0 * T], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(cr, [r0, (d0 + d1 * q0) * T, d1 * c0 * T**2 / 2], rtol=1e-8, atol=1e-9)
    assert fit.rms_r.max() < 1e-8
    mq, mr = fit.mean()
    np.testing.assert_allclose(mr[2], d1 * c0 * T**2 / 2, rtol=1e-9)
    # In time t the same curve has the textbook coefficients.
    np.testing.assert_allclose(fit.mean_in_time()[1][2], d1 * c0 / 2, rtol=1e-9)
    # One member: its own curve read as a map reproduces its data; the paper's 2 pi steps do not.
    err = drift_fit_tables(field, (20, 120), degree=(1, 2), ics=ics[:1]).map_error()
    assert err["implied"] < 1e-8 and err["quadratic_in_k"] < 1e-8
    assert err["paper_formula"] > err["mean_step"]


def test_fig3_members_are_on_the_curve_and_q_settles_near_minus_0_3() -> None:
    """Fig. 3 (paper: q = -0.300263 from ten ICs over k = 200..900); two members keep this test short.

    Members reach the curve after chaotic transients of ~200 periods, so which are drawn and how settled they
    are at k = 200 follows the method's digits: q is checked where it has settled (k = 300..400), and the
    series there against solve_ivp started from the member's own point at k = 300 (the drift is regular).
    """
    p = get_scene("fig3").params
    fit = drift_fit(p, (200, 400), degree=(0, 2), m=2, box=(-3, 3, 6, 10), seed=1)
    assert fit.members.shape[0] == 2
    np.testing.assert_allclose(fit.series[:, 300:401, 0], -0.300, atol=0.003)
    assert fit.mean()[0][0] == pytest.approx(fit.series[:, 200:401, 0].mean(), abs=1e-9)
    for member in fit.series:
        ref = solve_ivp_section(p, member[300], 100, rtol=1e-12, atol=1e-12)
        assert np.abs(ref - member[301:401]).max() < 1e-5
    r = fit.series[:, 200:401, 1]
    assert np.all(np.diff(r, axis=1) < 0)  # r decreases monotonically along the curve
    s = fit.summary()
    assert s["members"] == 2 and s["variable"].startswith("k")
    assert s["map_error"]["quadratic_in_k"] < 0.1 * s["map_error"]["mean_step"]
    assert s["map_error"]["paper_formula"] > 3 * s["map_error"]["mean_step"]


def test_no_member_on_the_drift_is_an_error_naming_the_counts() -> None:
    p = get_scene("fig1C").params  # compact: nothing drifts
    with pytest.raises(ParameterError, match=r"no trajectory is on the drift over k = 10..60: 6 tried"):
        drift_fit(p, (10, 60), m=3, box=(-1, 1, -1, 1), max_draws=6)
    with pytest.raises(ParameterError, match="escaped"):
        drift_fit(get_scene("fig3").params, (10, 300), ics=[(0.0, 8.0)], numerics=Numerics(bound=20.0))


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"window": (5, 5)}, "window must satisfy"),
        ({"window": (0, 10), "degree": (11, 1)}, "degree must be"),
        ({"window": (0, 10), "criterion": "x"}, "criterion"),
        ({"window": (0, 10), "box": None}, "give initial conditions"),
    ],
)
def test_bad_input_named(kw, needle: str) -> None:
    args = {"box": (-1, 1, -1, 1)}
    args.update(kw)
    with pytest.raises(ParameterError, match=needle):
        drift_fit(get_scene("fig3").params, args.pop("window"), **args)


def test_cli(capsys, tmp_path) -> None:
    from explorer_core.cli import main

    out = tmp_path / "s.csv"
    rc = main(
        # The method is pinned: (0, 8) is captured by the drift near k = 200 after a chaotic transient, before
        # k = 200 with DOP853's digits at 1e-10, after it with vern9's (as with solve_ivp at 1e-12).
        ["fit", "--scene", "fig3", "--window", "200,300", "--degree", "0,2", "--ic", "0,8", "--out", str(out), "--json",
         "--method", "dop853"]
    )  # fmt: skip
    assert rc == 0
    s = json.loads(capsys.readouterr().out)
    assert s["members"] == 1 and len(s["r"]["coef"]) == 3 and s["q"]["coef"][0] == pytest.approx(-0.29, abs=0.03)
    assert out.read_text().splitlines()[0] == "member,k,q,r" and len(out.read_text().splitlines()) == 302
    assert main(["fit", "--window", "1,5"]) == 2
    assert "--box" in capsys.readouterr().err
