"""Charts of regimes: classification on maps with known answers, tiles, progressive runs, outputs."""

from __future__ import annotations

import csv
import json
import math

import naive
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from explorer_core.analyses import regimes
from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.analyses.regimes import (
    CHAOTIC,
    ESCAPED,
    FAILED,
    INVALID,
    PERIODIC,
    QUASI_PERIODIC,
    REGIMES,
    TileSpec,
    chart_spec,
    classify,
    compute_tile,
    compute_tile_each,
    iter_chart,
    plan_tiles,
    regime_chart,
    settled_cycle,
)
from explorer_core.analyses.sweeps import detect_period
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Batch, Status, advance
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError

FIG11 = get_scene("fig11").params
IC = (-0.09, -2.0)
KW = {"p_max": 16, "tol": 1e-6, "lyap_threshold": 5e-3}


def logistic_orbit(r: float, n: int = 400, transient: int = 5000) -> tuple[np.ndarray, float]:
    """Points (x, 0) of the logistic map and its Lyapunov exponent mean log|r (1 - 2x)|."""
    x = 0.3
    for _ in range(transient):
        x = r * x * (1 - x)
    xs = np.empty(n)
    for k in range(n):
        x = r * x * (1 - x)
        xs[k] = x
    lyap = float(np.mean(np.log(np.abs(r * (1 - 2 * xs)))))
    return np.column_stack([xs, np.zeros(n)]), lyap


@pytest.mark.parametrize(
    ("r", "regime", "period"),
    [(2.8, PERIODIC, 1), (3.2, PERIODIC, 2), (3.5, PERIODIC, 4), (3.555, PERIODIC, 8), (3.83, PERIODIC, 3),
     (3.9, CHAOTIC, 0), (4.0, CHAOTIC, 0)],
)  # fmt: skip
def test_classify_logistic_map(r: float, regime: int, period: int) -> None:
    pts, lyap = logistic_orbit(r)
    assert classify(pts, pts.shape[0], Status.OK, lyap, **KW) == (regime, period)


def test_classify_quasi_periodic_rotation_escape_and_failure() -> None:
    """An irrational rotation of a circle: no period, zero exponent."""
    k = np.arange(400)
    theta = 2 * math.pi * k * (math.sqrt(5) - 1) / 2
    circle = np.column_stack([np.cos(theta), np.sin(theta)])
    assert classify(circle, 400, Status.OK, 0.0, **KW) == (QUASI_PERIODIC, 0)
    # A cycle longer than p_max is not a detected period either.
    assert classify(np.tile(circle[:20], (20, 1)), 400, Status.OK, 0.0, **KW) == (QUASI_PERIODIC, 0)
    assert classify(circle, 17, Status.ESCAPED, 0.0, **KW) == (ESCAPED, 0)
    assert classify(circle, 17, Status.STEP_COLLAPSED, 0.0, **KW) == (FAILED, 0)
    assert classify(circle, 399, Status.OK, 0.0, **KW) == (FAILED, 0)  # incomplete: cancelled


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 37), st.integers(1, 29), st.sampled_from([1, 2, 4, 8, 16]), st.integers(1, 80))
def test_tiles_cover_every_pixel_once_coarse_first(ny: int, nx: int, coarse: int, tile_pixels: int) -> None:
    tiles = plan_tiles((ny, nx), coarse, tile_pixels)
    seen = [p for t in tiles for p in t.pixels()]
    assert len(seen) == len(set(seen)) == ny * nx
    strides = [t.stride for t in tiles]
    assert strides == sorted(strides, reverse=True) and strides[0] <= coarse
    # Every pixel of the first level lies on the coarse lattice.
    assert all(j % coarse == 0 and i % coarse == 0 for t in tiles if t.stride == coarse for j, i in t.pixels())


def test_line_of_the_chart_agrees_with_the_bifurcation_diagram_and_lyapunov() -> None:
    """Along I11 = 1 the chart sees chaos, period 4, 2, 1 (as Fig. 10's diagram does, computed independently)."""
    alphas = [-0.42, -0.409, -0.39, -0.36]
    # The Lyapunov bound's early decision is what this test pins (the SALI's: tests/test_regimes_chaos_test.py).
    spec = chart_spec(FIG11, "alpha", (-0.42, -0.36), "I11", (1.0, 2.0), (4, 1), ics=[IC], transient=400, periods=128,
                      chaos_test="lyapunov")  # fmt: skip
    spec = spec.__class__(**{**spec.__dict__, "x_values": np.array(alphas)})
    chart = regime_chart(spec, workers=1)
    assert chart.completed and chart.computed.all()
    assert chart.regime[0, :, 0].tolist() == [CHAOTIC, PERIODIC, PERIODIC, PERIODIC]
    assert chart.period[0, :, 0].tolist() == [0, 4, 2, 1]
    d = bifurcation_diagram(FIG11.with_(I11=1.0), "alpha", alphas, points=128, transient=400, ics=[IC], seeding="fixed")
    assert d.periods(tol=1e-5)[0, 1:, 0].tolist() == [4, 2, 1]
    # Chaos was decided early (before CHAOS_MIN_PERIODS measured periods), as soon as the early bound held over
    # the second half of the run so far: the exponent is the mean log R_11 over those periods, the spectrum's own
    # (an independent driver). Here it is a close call: the bound held at 300 periods, with the margin that
    # applies from CHAOS_LATER_PERIODS on (at 420 with the first margin alone).
    at = FIG11.with_(I11=1.0, alpha=-0.42)
    whole = lyapunov_spectrum(at, [IC], 528, transient=0, numerics=spec.numerics)
    per = whole.logs[0, :, 0]

    def holds(n: int) -> bool:
        margin = regimes.CHAOS_LATER_MARGIN if n >= regimes.CHAOS_LATER_PERIODS else regimes.CHAOS_EARLY_MARGIN
        mean, err = regimes.chaos_bound(per[n // 2 // 10 * 10 : n])
        return mean - regimes.CHAOS_EARLY_Z * err > margin * spec.lyap_threshold * at.period

    n = next(n for n in range(regimes.CHAOS_EARLY_PERIODS, 400 + regimes.CHAOS_MIN_PERIODS, 10) if holds(n))
    assert n == 300
    assert chart.lyap[0, 0, 0] == pytest.approx(per[n // 2 // 10 * 10 : n].mean() / at.period, rel=1e-12)
    assert lyapunov_spectrum(at, [IC], 128, transient=400, numerics=spec.numerics).exponents[0, 0] > 0.02


def _small_spec(**kw):
    base = {"ics": [IC], "transient": 60, "periods": 40, "p_max": 8}
    base.update(kw)
    return chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (1.0, 2.0), (6, 5), **base)


def test_tile_is_a_pure_function_and_threads_do_not_change_the_chart() -> None:
    spec = _small_spec()
    tile = plan_tiles(spec.shape, 2, 4)[0]
    a, b = compute_tile(spec, tile), compute_tile(spec, tile)
    for name in ("regime", "period", "lyap", "status"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    one = regime_chart(spec, workers=1, coarse=2, tile_pixels=4)
    two = regime_chart(spec, workers=2, coarse=2, tile_pixels=4)
    np.testing.assert_array_equal(one.regime, two.regime)
    np.testing.assert_array_equal(one.lyap, two.lyap)
    # The chart equals its tiles computed one by one.
    for t in plan_tiles(spec.shape, 2, 4):
        res = compute_tile(spec, t)
        np.testing.assert_array_equal(one.regime[res.jj, res.ii], res.regime)


def test_progressive_coarse_picture_first_then_cancel() -> None:
    spec = _small_spec()
    updates = []
    for u in iter_chart(spec, coarse=4, tile_pixels=4, workers=1):
        updates.append((u.tile.tile.stride, int(u.chart.computed.sum()), u.chart.filled().computed.all()))
    assert updates[0][0] == 4 and updates[-1][1] == 30
    # Once the coarse level is done, the filled picture already covers every pixel.
    n_coarse = sum(1 for s, _, _ in updates if s == 4)
    assert updates[n_coarse - 1][2]
    calls = []
    part = regime_chart(spec, coarse=4, tile_pixels=4, workers=1, progress=calls.append, cancel=lambda: len(calls) >= 2)
    assert not part.completed and 0 < part.computed.sum() < 30 and len(calls) == 2
    filled = part.filled()
    assert filled.computed.all()
    np.testing.assert_array_equal(filled.regime[part.computed], part.regime[part.computed])


def test_invalid_pixels_and_several_initial_conditions(tmp_path) -> None:
    spec = chart_spec(
        FIG11, "alpha", (-0.4, -0.36), "I11", (0.0, 1.0), (2, 3), ics=[IC, (-0.5, -1.0)], transient=300, periods=64,
    )  # fmt: skip
    chart = regime_chart(spec, workers=2)
    assert chart.regime.shape == (3, 2, 2)
    assert np.all(chart.regime[0] == INVALID) and "positive definite" in chart.errors[(0, 0)]
    assert np.all(chart.regime[1:] != INVALID)
    s = chart.summary()
    assert s["invalid_pixels"] == 2 and s["computed"] == 6
    # At alpha = -0.36, I11 = 1 the second initial condition finds the coexisting period-4 cycle.
    assert chart.period[2, 1].tolist() == [1, 4] and chart.multistable()[2, 1]
    npz = tmp_path / "c.npz"
    chart.to_npz(str(npz))
    with np.load(npz) as z:
        np.testing.assert_array_equal(z["regime"], chart.regime)
        assert json.loads(str(z["spec"]))["y_param"] == "I11" and list(z["regimes"]) == list(REGIMES)
    path = tmp_path / "c.csv"
    assert chart.to_csv(str(path)) == 12
    rows = list(csv.reader(path.open()))
    assert rows[0] == ["i", "j", "alpha", "I11", "ic", "regime", "period", "lyap", "status", "inferred"]
    assert {r[5] for r in rows[1:3]} == {"invalid"}


def test_png_with_legend(tmp_path) -> None:
    pytest.importorskip("matplotlib")
    from explorer_core.reports.render import render_chart

    chart = regime_chart(_small_spec(), workers=2, coarse=2)
    path = tmp_path / "c.png"
    render_chart(chart, str(path))
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"x_param": "beta"}, "cannot sweep"),
        ({"y_param": "alpha"}, "must differ"),
        ({"grid": (0, 3)}, "grid must be"),
        ({"p_max": 40}, "p_max"),
        ({"tol": 0.0}, "tol must be"),
        ({"periods": 2}, "periods must be"),
    ],
)
def test_bad_input_named(kw, needle: str) -> None:
    args = {"x_param": "alpha", "y_param": "I11", "grid": (3, 3), "p_max": 8, "tol": 1e-5, "periods": 40}
    args.update(kw)
    with pytest.raises(ParameterError, match=needle):
        chart_spec(FIG11, args.pop("x_param"), (-0.6, -0.4), args.pop("y_param"), (1, 2), args.pop("grid"), **args)
    with pytest.raises(ParameterError, match="power of two"):
        plan_tiles((4, 4), 3)


def test_tile_spec_pixels_skip_coarser_levels() -> None:
    t = TileSpec(stride=1, coarsest=2, j0=0, j1=2, i0=0, i1=3)
    assert t.pixels() == [(0, 1), (1, 0), (1, 1), (1, 2)]


def test_cli(capsys, tmp_path) -> None:
    from explorer_core.cli import main

    out = tmp_path / "c.npz"
    args = ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.42,-0.36", "--y-param", "I11",
            "--y-range", "1,1.2", "--grid", "2,2", "--ic", "-0.09,-2", "--transient", "50", "--periods", "40",
            "--p-max", "8", "--out", str(out), "--json"]  # fmt: skip
    assert main(args) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["computed"] == 4 and s["grid"] == [2, 2] and s["numerics"]["rtol"] == 1e-8 and out.exists()
    assert main([*args[:-3], "--out", str(tmp_path / "c.txt")]) == 2
    assert "--out must end" in capsys.readouterr().err
    assert main([*args, "--refine", "--coarse", "1"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["computed"] == 4 and s["inferred_pixels"] == 0  # a coarse lattice of stride 1 is every pixel


def _long_period(spec, j: int, i: int, k: int, periods: int = 3000) -> int:
    """Period detected over the last 250 of ``periods`` section points at rtol 1e-10 (0: none)."""
    p = spec.pixel_params(int(j), int(i))
    batch = Batch.start(spec.ics[k : k + 1], p.t0, p.period)
    pts, _ = advance(Model(p), batch, periods, rtol=1e-10, atol=1e-10, workers=1, block=1)
    tail = pts[0, -250:]
    return detect_period(tail, spec.p_max, spec.tol * (1 + np.abs(tail).max()))


def _same_or_confirmed(spec, a, b) -> np.ndarray:
    """Where tiles ``a`` (early stops) and ``b`` (the whole way) differ, ``a`` found a cycle a long run confirms.

    Newton confirms an attracting cycle that the reference's short measurement had not converged on yet;
    a long integration at another tolerance settles on it. Returns the mask of differences.
    """
    differ = (a.regime != b.regime) | (a.period != b.period)
    for pix, k in zip(*np.nonzero(differ), strict=True):
        assert a.regime[pix, k] == PERIODIC
        assert _long_period(spec, a.jj[pix], a.ii[pix], k) == a.period[pix, k]
    return differ


def _settle_spec():
    return chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (1.0, 2.0), (8, 5), ics=[IC, (-0.5, -1.0)],
                      transient=150, periods=100, chaos_test="lyapunov")  # fmt: skip


def test_members_on_an_attracting_cycle_stop_early_the_others_are_the_per_pixel_chart(monkeypatch) -> None:
    """Early stops change no regime and no period here (but cycles the reference had not converged on); every
    member that runs to the end is computed as before, to the bit (escaped members stop at ESCAPE_BOUND)."""
    spec = _settle_spec()
    calls = []
    real = regimes.settled_cycles
    monkeypatch.setattr(regimes, "settled_cycles", lambda *a, **kw: calls.extend(real(*a, **kw)) or calls[-len(a[1]) :])
    n_periodic, n_differ = 0, 0
    for t in plan_tiles(spec.shape, 4, 16):
        a, b = compute_tile(spec, t), compute_tile_each(spec, t)
        differ = _same_or_confirmed(spec, a, b)
        n_differ += int(differ.sum())
        np.testing.assert_array_equal(a.status, b.status)
        # Members run to the end: bit for bit. Chaos may be decided early (200 periods): a finite-time estimate.
        other = (a.regime != PERIODIC) & (a.regime != ESCAPED) & (a.regime != CHAOTIC) & ~differ
        np.testing.assert_array_equal(a.lyap[other], b.lyap[other])
        chaos = (a.regime == CHAOTIC) & ~differ
        assert np.all(a.lyap[chaos] > regimes.CHAOS_MARGIN * spec.lyap_threshold) and np.all(b.lyap[chaos] > 0)
        per = a.regime == PERIODIC
        n_periodic += int(per.sum())
        # A cycle's exponent is its own: negative, and what the finite-time average approaches.
        assert np.all(a.lyap[per] < 0)
        np.testing.assert_allclose(a.lyap[per], b.lyap[per], atol=5e-3)
    assert {CHAOTIC, ESCAPED} <= {
        int(r) for t in plan_tiles(spec.shape, 4, 16) for r in compute_tile(spec, t).regime.ravel()
    }
    # Every periodic member stopped early, on a cycle Newton found.
    assert n_periodic > 20 and sum(c is not None for c in calls) >= n_periodic
    assert n_differ <= 2


def test_a_settled_cycle_has_its_least_period_its_own_exponent_and_must_attract() -> None:
    fig10 = get_scene("fig10").params
    seed = np.array([-0.0959, -1.962])
    at = fig10.with_(alpha=-0.35)
    # A stable fixed point returns after 2 and 3 iterations as well: the least period is 1.
    for p in (1, 2, 3):
        period, lam = settled_cycle(at, seed, p)
        assert period == 1
    # Its exponent from the multipliers of an independent solve_ivp Newton (finite-difference-free variational).
    _, mono = naive.ivp_fixed_point(at, seed, 1)
    assert lam == pytest.approx(math.log(np.abs(np.linalg.eigvals(mono)).max()) / at.period, rel=1e-7)
    # Past the first period doubling (alpha = -0.37534) the same orbit is a flip saddle: no early stop.
    assert settled_cycle(fig10.with_(alpha=-0.385), seed, 1) is None


@pytest.mark.slow
def test_early_stopped_periods_agree_with_long_independent_integrations() -> None:
    spec = _settle_spec()
    seen: dict[int, tuple[int, int, int]] = {}
    for t in plan_tiles(spec.shape, 4, 16):
        res = compute_tile(spec, t)
        for pix, k in zip(*np.nonzero(res.regime == PERIODIC), strict=True):
            seen.setdefault(int(res.period[pix, k]), (int(res.jj[pix]), int(res.ii[pix]), int(k)))
    assert len(seen) >= 2
    for p, (j, i, k) in sorted(seen.items())[:3]:
        pts = naive.solve_ivp_section(spec.pixel_params(j, i), spec.ics[k], 250, rtol=1e-10, atol=1e-10)[150:]
        assert detect_period(pts, spec.p_max, spec.tol * (1 + np.abs(pts).max())) == p, (j, i, k)


@pytest.mark.slow
def test_early_escape_agrees_with_an_independent_integration() -> None:
    """A sampled member stopped at ESCAPE_BOUND: solve_ivp on the naive field leaves that bound too, and 1e3."""
    from scipy.integrate import solve_ivp

    spec = _settle_spec()
    res = compute_tile(spec, plan_tiles(spec.shape, 4, 16)[0])
    pix, k = (int(v[0]) for v in np.nonzero(res.regime == ESCAPED))
    p = spec.pixel_params(int(res.jj[pix]), int(res.ii[pix]))
    field = naive.NaiveField(p)
    for bound in (regimes.ESCAPE_BOUND, 1e3):
        leave = lambda t, y, b=bound: max(abs(y[0]), abs(y[1])) - b  # noqa: E731
        leave.terminal = True
        sol = solve_ivp(field.rhs, (p.t0, p.t0 + (spec.transient + spec.periods) * p.period), spec.ics[k],
                        method="DOP853", rtol=1e-10, atol=1e-10, events=leave)  # fmt: skip
        assert sol.status == 1 and sol.t_events[0].size == 1, bound


def _chaos_spec():
    return chart_spec(FIG11, "alpha", (-0.6, -0.42), "I11", (1.0, 1.5), (6, 3), ics=[IC], transient=100, periods=250,
                      chaos_test="lyapunov")  # fmt: skip


def _early_chaos(spec) -> list[tuple[int, int, int, float, float]]:
    """``(j, i, ic, early exponent, reference exponent)`` of every member decided chaotic before the end."""
    out = []
    for t in plan_tiles(spec.shape, 2, 64):
        a, b = compute_tile(spec, t), compute_tile_each(spec, t)
        # Regimes and periods as the whole computation's (this window has no long chaotic transient).
        assert _same_or_confirmed(spec, a, b).sum() <= 1
        for pix, k in zip(*np.nonzero((a.regime == CHAOTIC) & (a.lyap != b.lyap)), strict=True):
            out.append((int(a.jj[pix]), int(a.ii[pix]), int(k), float(a.lyap[pix, k]), float(b.lyap[pix, k])))
    return out


def test_chaos_is_decided_early_when_the_bound_on_the_exponent_holds() -> None:
    spec = _chaos_spec()
    early = _early_chaos(spec)
    assert len(early) >= 3
    for j, i, k, lam, ref in early:
        # The exponent over the first CHAOS_MIN_PERIODS.. measured periods, the same computation cut short.
        assert lam > regimes.CHAOS_MARGIN * spec.lyap_threshold and ref > spec.lyap_threshold
        p = spec.pixel_params(j, i)
        short = lyapunov_spectrum(p, [spec.ics[k]], regimes.CHAOS_MIN_PERIODS, transient=spec.transient,
                                  numerics=spec.numerics)  # fmt: skip
        assert lam == pytest.approx(short.exponents[0, 0], rel=1e-12)
    # The bound: block means of a chaotic orbit's log R_11.
    rng = np.random.default_rng(0)
    mean, err = regimes.chaos_bound(0.3 + rng.normal(0, 1, 400))
    assert abs(mean - 0.3) < 4 * err and 0.03 < err < 0.07
    assert math.isinf(regimes.chaos_bound(np.ones(15))[1])  # fewer than two blocks: no bound


@pytest.mark.slow
def test_early_chaos_agrees_with_long_independent_integrations() -> None:
    """A sampled early-decided member of each kind (after 100 measured periods; in the transient at 200 periods):
    solve_ivp's exponent over the whole measurement is chaos, and no cycle."""
    sampled = []
    for spec in (_chaos_spec(), _settle_spec()):
        early = _early_chaos(spec)
        sampled.append((spec, *early[len(early) // 2][:3]))
    for spec, j, i, k in sampled:
        p = spec.pixel_params(j, i)
        logs, _, pts = naive.solve_ivp_lyapunov(p, spec.ics[k], spec.transient + spec.periods, rtol=1e-9, atol=1e-9)
        lam = logs[spec.transient :, 0].mean() / p.period
        tail = pts[-spec.periods // 2 :]
        assert lam > spec.lyap_threshold, (j, i, k, lam)
        assert detect_period(tail, spec.p_max, spec.tol * (1 + np.abs(tail).max())) == 0


def _simulate_refinement(true: np.ndarray, coarse: int) -> tuple[np.ndarray, int]:
    """Refine a known picture of codes ``[j, i, ic]`` as iter_chart(refine=True) does; (picture, pixels computed)."""
    ny, nx, _ = true.shape
    code = np.zeros_like(true)
    ys, xs = regimes.lattice(ny, coarse), regimes.lattice(nx, coarse)
    code[np.ix_(ys, xs)] = true[np.ix_(ys, xs)]
    n = ys.size * xs.size
    s = coarse // 2
    while s >= 1:
        compute, fill = regimes.refine_level(code, (ny, nx), s, regimes.REFINE_RING)
        for j, i in compute:
            code[j, i] = true[j, i]
        for j, i, sj, si in fill:
            code[j, i] = code[sj, si]
        n += len(compute)
        s //= 2
    return code, n


def test_refinement_reproduces_regions_and_computes_only_near_boundaries() -> None:
    assert regimes.lattice(10, 4).tolist() == [0, 4, 8, 9] and regimes.lattice(9, 4).tolist() == [0, 4, 8]
    jj, ii = np.mgrid[0:61, 0:83]
    disc = (jj - 30) ** 2 + (ii - 40) ** 2 < 18**2
    band = (ii > 2 * jj) & (ii < 2 * jj + 9)  # a band 9 pixels wide: wider than a coarse cell's half-diagonal
    true = np.stack([disc * 1 + band * 2, disc * 1], axis=-1)
    for coarse in (4, 8):
        picture, n = _simulate_refinement(true, coarse)
        np.testing.assert_array_equal(picture, true)
        assert n < 0.5 * true[..., 0].size
    # A feature smaller than the coarse cells and away from every other is not seen: the price of refining.
    dot = np.zeros((33, 33, 1), dtype=np.int64)
    dot[13, 13] = 5
    assert not np.any(_simulate_refinement(dot, 8)[0] == 5)


def test_refined_chart_computes_pixels_as_the_full_chart_and_fills_the_rest() -> None:
    spec = chart_spec(FIG11, "alpha", (-0.6, -0.4), "I11", (0.0, 2.0), (13, 11), ics=[IC], transient=60, periods=40,
                      p_max=8)  # fmt: skip
    full = regime_chart(spec, workers=2)
    refined = regime_chart(spec, workers=2, coarse=4, refine=True)
    assert refined.completed and refined.computed.all() and 0 < refined.inferred.sum() < refined.inferred.size
    own = ~refined.inferred
    for name in ("regime", "period", "lyap", "status"):
        np.testing.assert_array_equal(getattr(refined, name)[own], getattr(full, name)[own])
    # I11 = 0 is not positive definite: never inferred, computed, with its reason.
    assert np.all(refined.regime[0] == INVALID) and not refined.inferred[0].any() and (0, 5) in refined.errors
    assert refined.summary()["inferred_pixels"] == int(refined.inferred.sum())
    # A cancelled refinement is a partial chart.
    calls = []
    part = regime_chart(spec, workers=1, coarse=4, refine=True, progress=calls.append, cancel=lambda: len(calls) >= 2)
    assert not part.completed and len(calls) == 2

    # Nothing lost in silence: every pixel not computed is a loss with its count and reason.
    def count(start: str) -> int:
        return sum(loss.count for loss in refined.lost if loss.why.startswith(start))

    assert count("not computed: filled from computed neighbours") == int(refined.inferred.sum())
    assert count("not a valid system") == len(refined.errors) and refined.errors[(0, 5)] in str(refined.lost)
    assert not refined.complete and not any("not computed" in loss.why for loss in full.lost)
    assert refined.summary()["lost"] == [loss.as_dict() for loss in refined.lost]
    missing = {loss.why: loss.count for loss in part.lost if "stopped" in loss.why}
    assert sum(missing.values()) == int((~part.computed).sum()) > 0
