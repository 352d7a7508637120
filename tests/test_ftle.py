"""FTLE maps (issue 34, item 1 and 5): the logistic map's exponent log 2 through the same QR reduction, each pixel
against the Lyapunov analysis and an independent integration, the backward map against the inverse of the forward
derivative, escaped pixels lost with their reason, a cancelled map incomplete."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from naive import naive_ftle, solve_ivp_lyapunov, solve_ivp_section

from explorer_core.analyses import ftle
from explorer_core.analyses.lyapunov import lyapunov_spectrum, qr_exponents
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.poincare import PoincareMap
from explorer_core.status import Status

FIG8B = get_scene("fig8B").params
BOX = (-1.5, 0.5, -3.0, -1.0)


def test_the_logistic_maps_finite_time_exponent_tends_to_log_2() -> None:
    # x' = 4 x (1 - x) with a contracting second coordinate (y' = y / 2): the largest exponent is log 2 (Ulam).
    x, jacs = 0.1234, []
    for _ in range(20_000):
        jacs.append([[4.0 - 8.0 * x, 0.0], [0.0, 0.5]])
        x = 4.0 * x * (1.0 - x)
    top = qr_exponents(np.array(jacs))[0]
    assert top == pytest.approx(math.log(2.0), abs=0.02)
    assert top == pytest.approx(naive_ftle(jacs), rel=1e-10)  # one vector renormalised: the same number


def test_a_pixels_ftle_is_the_lyapunov_exponent_of_its_initial_condition() -> None:
    res = ftle.ftle_map(FIG8B, BOX, grid=(3, 2), periods=20)
    assert res.complete and res.forward.shape == (2, 3)
    ics = res.spec.ics()
    ly = lyapunov_spectrum(FIG8B, ics, 20)
    np.testing.assert_allclose(res.forward.ravel(), ly.exponents[:, 0], rtol=1e-12, atol=1e-14)
    # an independent integration (scipy on the naive field, complex-step Jacobian)
    for i in (0, 4):
        logs, _, _ = solve_ivp_lyapunov(FIG8B, ics[i], 20)
        assert res.forward.ravel()[i] == pytest.approx(logs[:, 0].sum() / (20 * FIG8B.period), rel=1e-6, abs=1e-9)


def test_the_backward_ftle_is_the_growth_under_the_inverse_of_the_forward_derivative() -> None:
    n = 6
    res = ftle.ftle_map(FIG8B, BOX, grid=(2, 2), periods=n, direction="both")
    assert res.backward is not None and res.complete
    pmap = PoincareMap.of(FIG8B, Numerics(rtol=1e-12, atol=1e-12))
    for i, x in enumerate(res.spec.ics()):
        y = solve_ivp_section(FIG8B, x, n, direction=-1)[-1]  # P^-n(x), independently
        mono = pmap.derivative(y[None, :], n)
        assert np.allclose(mono.end[0], x, atol=1e-7)
        inv = np.linalg.inv(mono.matrix[0])  # D P^-n (x) = (D P^n (y))^-1
        expect = math.log(np.linalg.norm(inv[:, 0])) / (n * FIG8B.period)  # growth of e_q, as the QR's R_11
        assert res.backward.ravel()[i] == pytest.approx(expect, rel=1e-6, abs=1e-9)


def test_pixels_that_escape_are_lost_with_their_reason_and_missing_values(tmp_path) -> None:
    # part of this box leaves along Fig. 8B's noncompact curve within 100 periods, part stays on the attractor
    res = ftle.ftle_map(FIG8B, (-0.2, 1.0, -1.0, 0.0), grid=(4, 3), periods=100)
    escaped = res.status_forward == Status.ESCAPED
    assert escaped.any() and (res.status_forward == Status.OK).any()
    # no value where there is none (a 0 would average silently): NaN beside the status that says why
    assert np.all(np.isnan(res.forward[escaped])) and np.all(np.isfinite(res.forward[~escaped]))
    assert not res.complete and any("escaped" in loss.why and "forward" in loss.what for loss in res.lost)
    res.write(str(tmp_path / "f.npz"))
    with np.load(tmp_path / "f.npz") as z:
        names = z["status_names"]
        assert "escaped" in {names[c] for c in z["status_forward"].ravel()}
        assert json.loads(str(z["summary"]))["complete"] is False
        assert np.array_equal(np.isnan(z["forward"]), escaped)
    assert res.write(str(tmp_path / "f.csv"))["rows"] == 12
    table = np.genfromtxt(tmp_path / "f.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert np.array_equal(np.isnan(table["ftle_forward"]), escaped.ravel())


def test_a_cancelled_map_keeps_its_tiles_and_says_what_was_not_computed(monkeypatch) -> None:
    monkeypatch.setattr(ftle, "TILE_PIXELS", 2)
    seen: list = []
    res = ftle.ftle_map(FIG8B, BOX, grid=(4, 4), periods=5, workers=1, progress=seen.append,
                        cancel=lambda: len(seen) >= 2)  # fmt: skip
    assert not res.completed and not res.complete
    not_run = res.status_forward == Status.NOT_RUN
    assert not_run.any() and (res.status_forward == Status.OK).any() and np.all(np.isnan(res.forward[not_run]))
    assert any(loss.why.startswith("cancelled") for loss in res.lost)


def test_the_command_writes_the_map_and_says_what_it_lost(tmp_path) -> None:
    from tests.clirun import run_cli

    out = tmp_path / "f.npz"
    code, stdout, err = run_cli("ftle", "--scene", "fig8B", "--box", "-0.2,1.0,-1.0,0.0", "--grid", "4,3",
                                "--periods", "100", "--out", str(out), "--json")  # fmt: skip
    assert code == 0, err
    d = json.loads(stdout)
    assert d["complete"] is False and d["forward"]["statuses"]["escaped"] == 3
    assert "lost: 3 pixels (forward): escaped" in err and "warning" not in err
    with np.load(out) as z:
        ok = z["status_forward"] == Status.OK
        assert z["forward"].shape == (3, 4) and np.all(np.isfinite(z["forward"]) == ok) and (~ok).sum() == 3
    code, _, err = run_cli("ftle", "--scene", "fig8B", "--grid", "4,3")
    assert code == 2 and "--out" in err  # nothing would be kept
