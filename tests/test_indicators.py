"""Weighted Birkhoff averages and SALI/GALI_2 (issue 34, items 1 and 5): the core on maps with known answers (an
irrational rotation, Chirikov's standard map in its regular and chaotic regimes) and against plain-loop references
(tests/naive.py); the analyses on this system against the long Lyapunov exponent and an independent integration."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from naive import (
    naive_birkhoff_digits,
    naive_ftle,
    naive_rotation_number,
    naive_sali,
    naive_weighted_birkhoff,
    solve_ivp_section,
)

from explorer_core.analyses import indicators as ind
from explorer_core.analyses.lyapunov import lyapunov_spectrum, qr_exponents
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status
from explorer_core.system.params import ParameterError

TWO_PI = 2.0 * math.pi
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def standard_map(k: float):
    """Chirikov's standard map on (x, p): p' = p + K sin x, x' = x + p' (mod 2 pi), and its Jacobian."""

    def step(x: np.ndarray) -> np.ndarray:
        p = x[:, 1] + k * np.sin(x[:, 0])
        return np.column_stack([np.mod(x[:, 0] + p, TWO_PI), p])

    def jacobian(x: np.ndarray) -> np.ndarray:
        c = k * np.cos(x[:, 0])
        out = np.empty((x.shape[0], 2, 2))
        out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = 1.0 + c, 1.0, c, 1.0
        return out

    return step, jacobian


def rotation_map(rho: float):
    c, s = math.cos(TWO_PI * rho), math.sin(TWO_PI * rho)
    m = np.array([[c, -s], [s, c]])
    return (lambda x: x @ m.T), (lambda x: np.broadcast_to(m, (x.shape[0], 2, 2)).copy())


def orbit(step, x0, n: int) -> np.ndarray:
    x = np.asarray(x0, dtype=float).reshape(-1, 2)
    out = [x]
    for _ in range(n - 1):
        x = step(x)
        out.append(x)
    return np.stack(out, axis=1)


# Points of the standard map: K = 0.5 well below the last KAM torus' break-up (K ~ 0.9716), on invariant curves;
# K = 5 in the chaotic sea (its Lyapunov exponent is checked below, independently).
REGULAR_STD = [(0.0, 2.0), (3.0, 0.5), (0.0, 3.9)]
CHAOTIC_STD = [(0.5, 0.5), (1.0, 2.0), (2.0, 2.5), (0.3, 4.0)]


def test_the_kernels_equal_their_plain_loop_references() -> None:
    rng = np.random.default_rng(7)
    values = rng.normal(size=(3, 400))
    for v in values:
        assert ind.weighted_birkhoff(v) == pytest.approx(naive_weighted_birkhoff(v), rel=1e-12, abs=1e-15)
        assert float(ind.birkhoff_digits(v)) == pytest.approx(naive_birkhoff_digits(v), rel=1e-9)
    pts = orbit(standard_map(0.5)[0], [REGULAR_STD[1]], 300)[0]
    assert float(ind.rotation_number(pts)) == pytest.approx(naive_rotation_number(pts.tolist()), abs=1e-12)
    step, jac = standard_map(5.0)
    chain = orbit(step, [CHAOTIC_STD[0]], 40)[0]
    jacs = jac(chain)
    a = ind.alignment(lambda x, idx: (step(x), jac(x), np.zeros(len(idx), dtype=np.int64)), [CHAOTIC_STD[0]], 39,
                      sali_tol=0.0)  # fmt: skip
    sali, gali = naive_sali(jacs[:39].tolist())
    np.testing.assert_allclose(a.sali[0], sali, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(a.gali[0], gali, rtol=1e-9, atol=1e-15)
    assert np.mean(a.stretch[0]) == pytest.approx(naive_ftle(jacs[:39].tolist()), rel=1e-12)


def test_an_irrational_rotation_has_its_rotation_number_many_digits_and_a_finite_sali() -> None:
    step, jac = rotation_map(GOLDEN)
    pts = orbit(step, [(1.0, 0.0)], 2000)
    assert float(ind.rotation_number(pts)[0]) == pytest.approx(GOLDEN, abs=1e-13)
    assert float(ind.birkhoff_digits(pts[..., 0])[0]) >= 13
    # an off-centre circle: the centre found by the weighted average itself
    shifted = pts + np.array([3.0, -2.0])
    assert float(ind.rotation_number(shifted)[0]) == pytest.approx(GOLDEN, abs=1e-12)
    a = ind.alignment(ind.closed_map(step, jac), [(1.0, 0.0)], 500)
    assert a.verdict[0] == ind.REGULAR
    np.testing.assert_allclose(a.sali[0], math.sqrt(2.0), rtol=1e-12)  # the vectors stay orthogonal
    np.testing.assert_allclose(a.gali[0], 1.0, rtol=1e-12)


def test_the_standard_map_regular_at_k_half_chaotic_at_k_five() -> None:
    for k, x0, verdict in ((0.5, REGULAR_STD, ind.REGULAR), (5.0, CHAOTIC_STD, ind.CHAOTIC)):
        step, jac = standard_map(k)
        pts = orbit(step, x0, 2000)
        digits = ind.birkhoff_digits(np.sin(pts[..., 0]))
        assert np.all(ind.digits_verdict(digits, ind.REGULAR_DIGITS, ind.CHAOTIC_DIGITS, 1000) == verdict), digits
        # at the shortest run allowed to say chaos, no regular orbit is called chaotic
        short = ind.birkhoff_digits(np.sin(pts[:, : 2 * ind.MIN_CHAOTIC_PERIODS, 0]))
        got = ind.digits_verdict(short, ind.REGULAR_DIGITS, ind.CHAOTIC_DIGITS, ind.MIN_CHAOTIC_PERIODS)
        assert np.all((got == verdict) | (got == ind.NO_VERDICT)), short
        a = ind.alignment(ind.closed_map(step, jac), x0, 2000)
        assert np.all(a.verdict == verdict), (k, a.verdict)
        # the independent exponent agrees: ~0 on the curves, ~log(K/2) in the sea (Chirikov)
        lam = [qr_exponents(jac(pts[i]))[0] for i in range(len(x0))]
        if verdict == ind.CHAOTIC:
            assert min(lam) > 0.5 and np.all(a.npts <= 2 * ind.MIN_ALIGN_PERIODS)  # decided in a few dozen iterations
            print(f"\nstandard map K=5: SALI decided after {a.npts.tolist()} iterations; lambda {np.round(lam, 3)}")
        else:
            assert max(lam) < 0.01


def test_a_run_too_short_to_decide_says_undecided() -> None:
    step, _ = standard_map(0.5)
    pts = orbit(step, [REGULAR_STD[0]], 40)  # 20 iterates a half: far too few for 7 digits
    digits = ind.birkhoff_digits(np.sin(pts[..., 0]))
    assert ind.digits_verdict(digits, ind.REGULAR_DIGITS, ind.CHAOTIC_DIGITS, 20)[0] == ind.NO_VERDICT
    # a shear with a power-law decay faster than max_power is not called regular
    shear = lambda x: x @ np.array([[1.0, 0.0], [1.0, 1.0]]).T  # noqa: E731
    twist = lambda x: np.broadcast_to(np.array([[1.0, 0.0], [1.0, 1.0]]), (x.shape[0], 2, 2)).copy()  # noqa: E731
    a = ind.alignment(ind.closed_map(shear, twist), [(0.0, 1.0)], 200, max_power=0.5)  # it decays like 1/n
    assert a.verdict[0] == ind.NO_VERDICT
    assert ind.alignment(ind.closed_map(shear, twist), [(0.0, 1.0)], 200).verdict[0] == ind.REGULAR
    # fewer periods than min_regular without alignment: a slowly aligning chaotic orbit could look the same
    assert ind.alignment(ind.closed_map(shear, twist), [(0.0, 1.0)], ind.MIN_REGULAR_PERIODS - 1).verdict[0] == 0


# ---------------------------------------------------------------------------
# This system.

FIG5A = get_scene("fig5A").params  # islands of invariant curves about the centre (area preserved: div ~ 0)
FIG8B = get_scene("fig8B").params  # the strange attractor (positive Lyapunov exponent)
ISLANDS = [(0.4, 0.0), (-0.4, 0.0), (0.05, 0.02)]
ATTRACTOR = [(-1.0, -2.0), (-0.5, -1.0), (0.3, -3.0)]


def test_on_this_system_the_indicators_agree_with_the_long_lyapunov_exponent() -> None:
    lyap = {}
    for name, params, ics, transient in (("islands", FIG5A, ISLANDS, 0), ("attractor", FIG8B, ATTRACTOR, 100)):
        res = lyapunov_spectrum(params, ics, 2000, transient=transient)
        lyap[name] = res.exponents[:, 0] * params.period
        assert np.all(res.ok)
    assert np.all(lyap["islands"] < 0.005) and np.all(lyap["attractor"] > 0.3), lyap
    b = ind.birkhoff(FIG5A, ISLANDS, 500)
    s = ind.sali(FIG5A, ISLANDS, 1000)
    assert b.verdicts() == ["regular"] * 3 and np.all(s.verdict == ind.REGULAR), (b.digits, s.verdict)
    assert np.all(b.has_rotation) and b.complete and s.complete
    bc = ind.birkhoff(FIG8B, ATTRACTOR, 100, transient=100)
    sc = ind.sali(FIG8B, ATTRACTOR, 1000, transient=100)
    assert bc.verdicts() == ["chaotic"] * 3 and np.all(sc.verdict == ind.CHAOTIC), (bc.digits, sc.verdict)
    print(f"\nperiods: Lyapunov 2000 each; Birkhoff regular 2x500, chaotic 2x100; SALI regular {s.npts.tolist()}, "
          f"chaotic {sc.npts.tolist()}")  # fmt: skip
    assert np.all(sc.npts <= 2 * ind.MIN_ALIGN_PERIODS)


def test_the_rotation_number_of_an_island_curve_agrees_with_an_independent_integration() -> None:
    # 2 x 100 periods: 5 digits (the default 7 needs more), enough to compare the two integrations' estimates
    ours = ind.birkhoff(FIG5A, [ISLANDS[0]], 100, regular_digits=5.0, numerics=Numerics(rtol=1e-12, atol=1e-12))
    assert ours.verdicts() == ["regular"]
    pts = solve_ivp_section(FIG5A, ISLANDS[0], 200)  # P^1 .. P^200, as the analysis averages them
    assert ours.rotation[0] == pytest.approx(naive_rotation_number(pts.tolist()), abs=1e-8)
    assert ours.digits[0] == pytest.approx(naive_birkhoff_digits(pts[:, 0].tolist()), abs=0.5)


def test_escaped_orbits_are_undecided_with_their_status_and_lost() -> None:
    far = [(5000.0, 0.0), ATTRACTOR[0]]
    b = ind.birkhoff(FIG8B, far, 20)
    s = ind.sali(FIG8B, far, 20)
    for res in (b, s):
        assert Status(int(res.status[0])) == Status.ESCAPED and res.verdict[0] == ind.NO_VERDICT
        assert not res.complete and any("escaped" in loss.why for loss in res.lost)
        text = json.dumps(res.summary())  # no NaN anywhere
        assert "NaN" not in text and "Infinity" not in text


def test_a_cancelled_run_returns_what_it_had_marked_incomplete() -> None:
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 1

    s = ind.sali(FIG5A, ISLANDS, 500, cancel=cancel)
    assert not s.completed and not s.complete and np.all(s.npts < 500)
    assert any(loss.why.startswith("cancelled") for loss in s.lost)
    b = ind.birkhoff(FIG5A, ISLANDS, 2000, cancel=cancel)
    assert any(loss.why.startswith("cancelled") for loss in b.lost)
    assert not b.completed and np.all(b.verdict == ind.NO_VERDICT)


def test_specs_refuse_bad_values_naming_them() -> None:
    with pytest.raises(ParameterError, match="chaotic_digits") as exc:
        ind.birkhoff_spec(FIG5A, ISLANDS, 100, chaotic_digits=9.0, regular_digits=7.0)
    assert exc.value.option == "chaotic_digits"
    with pytest.raises(ParameterError, match="observable") as exc:
        ind.birkhoff_spec(FIG5A, ISLANDS, 100, observable="energy")
    with pytest.raises(ParameterError, match="sali_tol"):
        ind.sali_spec(FIG5A, ISLANDS, 100, sali_tol=-1.0)
    with pytest.raises(ParameterError, match="periods"):
        ind.sali_spec(FIG5A, ISLANDS, 2)


def test_results_write_their_files(tmp_path) -> None:
    b = ind.birkhoff(FIG5A, ISLANDS[:2], 100)
    s = ind.sali(FIG8B, ATTRACTOR[:2], 50, transient=20)
    assert b.write(str(tmp_path / "b.csv"))["rows"] == 2
    rows = np.genfromtxt(tmp_path / "b.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert list(rows["verdict"]) == b.verdicts()
    s.write(str(tmp_path / "s.npz"))
    with np.load(tmp_path / "s.npz") as z:
        assert z["sali"].shape == (2, 50) and json.loads(str(z["summary"]))["verdicts"]["chaotic"] == 2
    s.write(str(tmp_path / "s.json"))
    assert json.loads((tmp_path / "s.json").read_text())["spec"]["periods"] == 50


def test_the_commands_run_the_analyses_and_name_a_refused_flag(tmp_path) -> None:
    from tests.clirun import run_cli

    out = tmp_path / "b.csv"
    code, stdout, err = run_cli("birkhoff", "--scene", "fig5A", "--ic", "0.4,0", "--periods", "300", "--out", str(out),
                                "--json")  # fmt: skip
    assert code == 0, err
    d = json.loads(stdout)
    assert d["orbits"][0]["verdict"] == "regular" and d["out"] == [{"path": str(out), "rows": 1}]
    code, stdout, err = run_cli("sali", "--scene", "fig8B", "--ic", "-1,-2", "--transient", "50", "--json")
    assert code == 0, err
    assert json.loads(stdout)["orbits"][0]["verdict"] == "chaotic"
    code, _, err = run_cli("birkhoff", "--scene", "fig5A", "--ic", "0.4,0", "--chaotic-digits", "9")
    assert code == 2 and "--chaotic-digits" in err


def test_a_drifting_orbit_is_no_chaos_but_undecided_and_says_it_drifts() -> None:
    # Fig. 5A from (1.5, 0) drifts off (|x| from 1.3 to ~1400 in 1000 periods, growing every period of the second
    # half): its two halves' averages differ by ~70, "-1.9 digits", which the test read as chaos before.
    b = ind.birkhoff(FIG5A, [(1.5, 0.0), ISLANDS[0]], 500)
    assert b.verdicts() == ["undecided", "regular"] and b.drifting.tolist() == [True, False]
    assert Status(int(b.status[0])) == Status.UNDECIDED and b.digits[0] < 0 and not b.has_rotation[0]
    assert "drifting off" in b.report()[0] and "drifting" not in b.report()[1]
    assert [o["drifting"] for o in json.loads(json.dumps(b.summary()))["orbits"]] == [True, False]
