"""Lyapunov spectrum: known answers on linear fields, the slow reference, consistency, status."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from clirun import run_cli
from naive import solve_ivp_lyapunov

from explorer_core.analyses.lyapunov import (
    attractor_ensemble,
    ensemble_ics,
    kaplan_yorke,
    lyapunov_spectrum,
    lyapunov_tables,
    qr_exponents,
)
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Status
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError, Params

TIGHT = Numerics(rtol=1e-11, atol=1e-11)
FIG8B = get_scene("fig8B").params
FIG8B_IC = (-0.5, -1.0)


def linear_tables(a: np.ndarray, gq: float = 0.0, gqr: float = 0.0) -> tuple[np.ndarray, ...]:
    """Coefficient tables of the linear field ``x' = A x`` plus forcing terms.

    ``gq``: adds ``gq * g'(t) * q`` to ``Q`` (through the ``g'`` table);
    ``gqr``: adds ``gqr * g(t) * r`` to ``Q``. Denominator 1.
    """
    num = np.zeros((3, 6, 5))
    num[0, 1, 0], num[0, 2, 0] = a[0]
    num[1, 1, 0], num[1, 2, 0] = a[1]
    num[0, 2, 1] = gqr
    gpc = np.zeros((3, 2))
    gpc[0, 0] = gq
    den = np.array([1.0, 0.0, 0.0])
    return num, gpc, den


def run_linear(tables, periods: int, forcing=(0.0, 1.0, 0.0, 1.0), ic=(0.0, 0.0), **kw):
    # The state sits at the equilibrium 0 (never escapes); the tangent matrix is what moves.
    return lyapunov_tables(*tables, np.array(forcing), 0.0, 2 * math.pi / forcing[3], [ic], periods, **kw)


@pytest.mark.parametrize(
    "a",
    [
        np.array([[0.05, 0.7], [0.1, -0.2]]),
        # Contraction e^-17 per period: exercises the re-orthonormalisation inside a period.
        np.array([[0.3, 0.7], [0.4, -2.5]]),
    ],
)
def test_constant_non_normal_linear_field_matches_expm(a: np.ndarray) -> None:
    """Exponents of x' = A x equal log diag R of expm(A t) = QR, at every t (QR accumulation is exact)."""
    for periods in (1, 7):
        out = run_linear(linear_tables(a), periods, numerics=TIGHT)
        t = periods * 2 * math.pi
        _, rm = np.linalg.qr(scipy.linalg.expm(a * t))
        l1 = math.log(abs(rm[0, 0])) / t
        # R_22 of a nearly singular product loses digits; det = e^{tr A t} does not.
        expected = [l1, np.trace(a) - l1]
        np.testing.assert_allclose(out["exponents"][0], expected, rtol=0, atol=1e-9)
    assert out["divergence_mean"][0] == pytest.approx(np.trace(a), abs=1e-12)
    assert out["status"].tolist() == [Status.OK]
    # Asymptotically the exponents are the real parts of the eigenvalues.
    eig = np.sort(np.linalg.eigvals(a).real)[::-1]
    out = run_linear(linear_tables(a), 200, numerics=TIGHT)
    assert out["status"].tolist() == [Status.OK] and out["npts"].tolist() == [200]
    np.testing.assert_allclose(out["exponents"][0], eig, atol=2e-3)


@pytest.mark.parametrize("omega", [1.0, 1.7])
def test_forced_triangular_field_has_exact_exponents_every_period(omega: float) -> None:
    """q' = (a + k g'(t)) q + c g(t) r, r' = b r: R_11 = e^{a T}, R_22 = e^{b T} each period.

    The forcing rotates the second tangent vector within the period, so the
    Gram-Schmidt step is exercised; the answer is exact because e_q is invariant.
    """
    a_, b_ = 0.03, -0.11
    tables = linear_tables(np.array([[a_, 0.0], [0.0, b_]]), gq=0.8, gqr=1.5)
    forcing = (0.2, 0.9, -0.4, omega)
    out = run_linear(tables, 12, forcing=forcing, numerics=TIGHT)
    T = 2 * math.pi / omega
    np.testing.assert_allclose(out["logs"][0], np.tile([a_ * T, b_ * T], (12, 1)), atol=1e-10)
    np.testing.assert_allclose(out["divs"][0], (a_ + b_) * T, atol=1e-10)
    np.testing.assert_allclose(out["exponents"][0], [a_, b_], atol=1e-11)


def test_rotating_field_gives_equal_exponents() -> None:
    """x' = a x + w(t) J x: a rotation times e^{a t}, both exponents a."""
    a_ = -0.04
    num, gpc, den = linear_tables(np.array([[a_, -1.0], [1.0, a_]]))
    num[0, 2, 1], num[1, 1, 1] = -0.5, 0.5  # w(t) = 1 + 0.5 g(t)
    out = run_linear((num, gpc, den), 10, numerics=TIGHT)
    np.testing.assert_allclose(out["logs"][0], a_ * 2 * math.pi, atol=1e-10)


def test_qr_accumulation_on_linear_maps() -> None:
    tri = np.tile([[2.0, 1.0], [0.0, 0.5]], (50, 1, 1))
    np.testing.assert_allclose(qr_exponents(tri), [math.log(2.0), math.log(0.5)], atol=1e-14)
    cat = np.tile([[2.0, 1.0], [1.0, 1.0]], (3000, 1, 1))  # Arnold's cat map: +-log golden^2
    lam = math.log((3 + math.sqrt(5)) / 2)
    ex = qr_exponents(cat)
    np.testing.assert_allclose(ex, [lam, -lam], atol=1e-3)
    assert ex.sum() == pytest.approx(0.0, abs=1e-12)  # det = 1
    rng = np.random.default_rng(4)
    mats = rng.normal(size=(200, 2, 2))
    ex = qr_exponents(mats)
    assert ex.sum() == pytest.approx(np.mean(np.log(np.abs(np.linalg.det(mats)))), abs=1e-12)
    with pytest.raises(ParameterError, match="singular"):
        qr_exponents([[[1.0, 2.0], [0.0, 0.0]]])


@pytest.mark.parametrize(
    ("params", "ic", "periods", "atol"),
    [
        (FIG8B, FIG8B_IC, 20, 1e-7),  # chaotic: short, before the trajectories separate
        (Params(inertia=(1, 4, 2, 0, 0, 0), alpha=0.1), (0.32, 0.688), 40, 1e-8),  # regular (Fig. 1C)
        (Params(inertia=(2.0, 3.0, 1.5, 0.2, -0.3, 0.25), alpha=0.15, g0=-0.1, g2=-0.5, omega=0.8, t0=-1.1),
         (0.9, -0.7), 15, 1e-8),
    ],
)  # fmt: skip
def test_kernel_matches_solve_ivp_reference(params: Params, ic, periods: int, atol: float) -> None:
    ref_logs, ref_divs, ref_pts = solve_ivp_lyapunov(params, ic, periods)
    res = lyapunov_spectrum(params, [ic], periods, numerics=Numerics(rtol=1e-12, atol=1e-12), workers=1)
    assert res.status_labels() == ["ok"]
    np.testing.assert_allclose(res.points[0], ref_pts, atol=atol)
    np.testing.assert_allclose(res.logs[0], ref_logs, atol=atol)
    np.testing.assert_allclose(res.divs[0], ref_divs, atol=atol)


@pytest.mark.parametrize("scene", ["fig8B", "fig4A"])
def test_sum_of_exponents_equals_mean_divergence(scene: str) -> None:
    """Liouville: Lambda_1 + Lambda_2 is the time average of dQ/dq + dR/dr on the same trajectory."""
    p = get_scene(scene).params
    res = lyapunov_spectrum(p, [(-0.5, -1.0), (1.1, 1.6)], 300, transient=50)
    assert res.ok.all()
    np.testing.assert_allclose(res.exponents.sum(axis=1), res.divergence_mean, atol=1e-9)
    assert np.all(res.exponents[:, 0] >= res.exponents[:, 1])


def test_strange_attractor_has_one_positive_exponent_and_running_history() -> None:
    ics = attractor_ensemble(FIG8B, FIG8B_IC, 3, transient=100, seed=1)
    res = lyapunov_spectrum(FIG8B, ics, 400, transient=100)
    assert res.ok.all()
    assert np.all(res.spread() > 0)
    l1, l2 = res.mean()
    assert l1 > 0.03 and l2 < -0.2  # chaotic and dissipative
    run = res.running(0)
    assert run.shape == (400, 2)
    np.testing.assert_allclose(run[-1], res.exponents[0], rtol=1e-12)
    np.testing.assert_allclose(res.per_iteration(), res.mean() * 2 * math.pi)
    assert 1.0 < res.kaplan_yorke() < 2.0
    s = res.summary()
    assert s["status"] == "ok" and s["exponents"][2] == 0.0
    assert s["kaplan_yorke"] == pytest.approx(1 + l1 / abs(l2))
    assert abs(s["sum_minus_divergence"]) < 1e-9
    assert s["convergence"]["k"][-1] == 400


def test_method_and_tolerance_do_not_change_short_time_stretching() -> None:
    a = lyapunov_spectrum(FIG8B, [FIG8B_IC], 10, numerics=Numerics(method="dp5", rtol=1e-11, atol=1e-11))
    b = lyapunov_spectrum(FIG8B, [FIG8B_IC], 10, numerics=Numerics(method="rk4", steps_per_period=2000))
    c = lyapunov_spectrum(FIG8B, [FIG8B_IC], 10, numerics=TIGHT)
    np.testing.assert_allclose(a.logs, c.logs, atol=1e-7)
    np.testing.assert_allclose(b.logs, c.logs, atol=1e-7)


def test_escape_is_reported_and_excluded_from_the_ensemble() -> None:
    p = get_scene("fig3").params
    res = lyapunov_spectrum(p, [(0.0, 8.0), (0.2, 0.1)], 300, numerics=Numerics(bound=30.0))
    assert res.status_labels() == ["escaped", "ok"]
    assert 0 < res.npts[0] < 300 and res.npts[1] == 300
    assert res.ok.tolist() == [False, True]
    np.testing.assert_array_equal(res.mean(), res.exponents[1])
    s = res.summary()
    assert s["status"] == "escaped" and s["members_ok"] == 1 and s["members"][0]["status"] == "escaped"
    only = lyapunov_spectrum(p, [(0.0, 8.0)], 300, numerics=Numerics(bound=30.0)).summary()
    assert only["status"] == "escaped" and only["exponents"] is None
    assert all(np.isfinite(res.exponents.ravel()))


def test_cancel_and_progress() -> None:
    seen = []
    res = lyapunov_spectrum(FIG8B, [FIG8B_IC], 10_000, progress=seen.append, cancel=lambda: len(seen) >= 3, workers=1)
    assert not res.completed and res.npts[0] == seen[-1].done_periods < 10_000
    assert seen[-1].phase == "measure" and np.all(np.isfinite(seen[-1].running))
    assert np.isfinite(res.exponents).all()


def test_kaplan_yorke_cases() -> None:
    assert kaplan_yorke(0.082, -0.385) == pytest.approx(1.2129870)
    assert kaplan_yorke(-0.1, -0.3) == 0.0
    assert kaplan_yorke(0.1, 0.05) == 2.0
    assert kaplan_yorke(0.0, -0.2) == 1.0


def test_ensemble_ics() -> None:
    e = ensemble_ics((0.5, -1.0), 5, offset=1e-3, seed=2)
    assert e.shape == (5, 2) and tuple(e[0]) == (0.5, -1.0)
    assert np.all(np.abs(e[1:] - e[0]) <= 1e-3 * 2.0) and len({tuple(x) for x in e}) == 5


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: lyapunov_spectrum(FIG8B, [(0, 0)], 0), "periods must be"),
        (lambda: lyapunov_spectrum(FIG8B, [(0, 0)], 5, transient=-2), "transient must be"),
        (lambda: lyapunov_spectrum(FIG8B, [(np.inf, 0)], 5), "not finite"),
        (lambda: ensemble_ics((0, 0), 0), "ensemble must be"),
        (lambda: ensemble_ics([(0, 0), (1, 1)], 3), "one initial condition"),
    ],
)
def test_bad_input_named(call, needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        call()


def test_cli_json_and_history(tmp_path) -> None:
    import csv
    import json

    hist = tmp_path / "h.csv"
    rc, out, err = run_cli(
        "lyapunov", "--scene", "fig8B", "--ic", "-0.5,-1", "--transient", "20", "--periods", "60",
        "--ensemble", "2", "--history", str(hist), "--json",
    )  # fmt: skip
    assert rc == 0, err
    s = json.loads(out)
    assert set(s) >= {"exponents", "kaplan_yorke", "divergence_mean", "status", "per_iteration", "spread"}
    assert len(s["exponents"]) == 3 and s["exponents"][2] == 0.0 and s["status"] == "ok"
    assert s["ensemble"] == {"size": 2, "ok": 2}
    assert s["exponents"][0] + s["exponents"][1] == pytest.approx(s["divergence_mean"], abs=1e-9)
    rows = list(csv.reader(hist.open()))
    assert rows[0] == ["member", "k", "L1", "L2", "divergence_mean"] and len(rows) == 1 + 2 * 60
    assert rows[1][1] == "21"


def test_cli_errors_are_one_line() -> None:
    rc, _, err = run_cli("lyapunov", "--scene", "fig8B", "--periods", "5")
    assert rc == 2 and "--ic" in err and err.count("\n") == 1
    rc, _, err = run_cli("lyapunov", "--ic", "0,1", "--ic", "1,1", "--ensemble", "3", "--periods", "5")
    assert rc == 2 and "--ensemble" in err
    rc, _, err = run_cli("lyapunov", "--ic", "0,1", "--I11", "-1", "--periods", "5")
    assert rc == 2 and "positive definite" in err
