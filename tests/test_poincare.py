"""The map object and the one Newton: checked against solve_ivp and finite differences, and metamorphically."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from naive import fd_monodromy, ivp_map

from explorer_core.analyses.orbits import find_orbits, grid_seeds, orbit_from, same_orbit
from explorer_core.analyses.regimes import settled_cycles
from explorer_core.analyses.symmetry import check_symmetry
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import coefficients
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.poincare import PoincareMap, least_period, newton
from explorer_core.solve.section import section
from explorer_core.solve.tangent import Monodromy
from explorer_core.status import Status
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError

FIG8B = get_scene("fig8B")
FIG10 = get_scene("fig10").params
NUM = Numerics(rtol=1e-12, atol=1e-12)


def test_derivative_is_the_map_and_its_finite_differences() -> None:
    x = np.array([[-0.04, -2.4], [0.3, -1.0]])
    pmap = PoincareMap.of(FIG8B.params, NUM)
    mono = pmap.derivative(x, 2)
    for j in range(2):
        np.testing.assert_allclose(mono.end[j], ivp_map(FIG8B.params, x[j], 2), rtol=1e-8, atol=1e-9)
        fd = fd_monodromy(FIG8B.params, x[j], 2)
        np.testing.assert_allclose(mono.matrix[j], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    # The same points as members of a map with one system each, and as a chart's coefficient rows.
    per = PoincareMap.members([FIG8B.params, FIG8B.params], NUM).derivative(x, 2)
    coefs = coefficients([Model(FIG8B.params)], np.zeros(2, dtype=np.int64))
    rows = PoincareMap.rows(coefs, FIG8B.params.t0, FIG8B.params.period, NUM, block=1).derivative(x, 2)
    for other in (per, rows):
        np.testing.assert_allclose(other.end, mono.end, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(other.matrix, mono.matrix, rtol=1e-7, atol=1e-8 * np.abs(mono.matrix).max())


def test_iterate_streams_the_section() -> None:
    pmap = PoincareMap.of(FIG8B.params, NUM)
    chunks = list(pmap.iterate(np.array([[-0.04, -2.4]]), 7))
    pts = np.concatenate([c.points[0, : c.npts[0]] for c in chunks])
    ref = section(FIG8B.params, [[-0.04, -2.4]], 7, numerics=NUM).points[0]
    np.testing.assert_array_equal(pts, ref)
    with pytest.raises(ValueError, match="one system"):
        next(PoincareMap.members([FIG8B.params] * 2, NUM).iterate(np.zeros((2, 2)), 3))


def test_newton_reports_the_least_period_and_every_seed() -> None:
    # Newton for P^2 from near the flip saddle converges onto the fixed point: least period 1.
    pmap = PoincareMap.of(FIG8B.params, NUM)
    seeds = np.array([[-0.04, -2.4], [1e3, 1e3]])
    res = newton(pmap, seeds, np.array([2, 1]), ftol=1e-9, max_iter=40)
    assert [c.i for c in res.converged] == [0] and res.converged[0].least == 1
    assert [f.i for f in res.failures] == [1] and res.failures[0].reason  # nothing lost in silence
    # Cancelled before the first iteration: every seed is reported, as cancelled.
    res = newton(pmap, seeds, np.array([1, 1]), ftol=1e-9, max_iter=40, cancel=lambda: True)
    assert res.cancelled and sorted(f.i for f in res.failures) == [0, 1]
    assert all("cancelled" in f.reason for f in res.failures)


def test_least_period() -> None:
    chain = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    assert least_period(chain, 4, 1e-9) == 2
    assert least_period(chain, 3, 1e-9) == 3  # 2 does not divide 3


def test_charts_cycle_detection_goes_through_the_same_newton() -> None:
    # The period-1 focus of Fig. 10 at alpha = -0.35 is attracting: found from a nearby point with its least
    # period (Newton on P^2 too) and an exponent log|mu| / T < 0, the same point as find_orbits' orbit.
    params = FIG10.with_(alpha=-0.35)
    orbit = next(o for o in find_orbits(params, [[-0.0959, -1.962]], [1]).orbits)
    coefs = coefficients([Model(params)], np.zeros(1, dtype=np.int64))
    for p in (1, 2):
        (got,) = settled_cycles(coefs, orbit.points[0] + 1e-4, p, params.t0, params.period, near=0.1, same=1e-6)
        assert got is not None and got[0] == 1
        assert got[1] == pytest.approx(math.log(np.abs(orbit.multipliers).max()) / params.period, rel=1e-6)


def test_orbits_do_not_depend_on_the_order_of_the_seeds() -> None:
    seeds = grid_seeds(FIG8B.box, 5, 5)
    a = find_orbits(FIG8B.params, seeds, [1, 2])
    b = find_orbits(FIG8B.params, seeds[np.random.default_rng(7).permutation(len(seeds))], [2, 1])
    assert len(a.orbits) == len(b.orbits) > 0
    for o in a.orbits:
        assert any(same_orbit(o, p) for p in b.orbits), o.points


def test_unresolvable_times_are_refused_never_run_frozen() -> None:
    with pytest.raises(ParameterError, match=r"t0 = 1e\+20 cannot be resolved"):
        FIG8B.params.with_(t0=1e20)
    with pytest.raises(ParameterError, match="centre"):
        check_symmetry(FIG8B.params, [[0.1, 0.2]], 3, centre=1e20)
    # A t0 that is fine alone, with a horizon whose end is not: refused before any work.
    edge = 2.0**42  # above it doubles are 9.8e-4 apart, more than 1e-4 of a period 2 pi
    params = FIG8B.params.with_(omega=1.0, t0=edge - 100.0)
    with pytest.raises(ParameterError, match="horizon"):
        section(params, [[0.1, 0.2]], 1000)
    # Large but resolvable times still run and move.
    sec = section(FIG8B.params.with_(t0=1e6), [[-0.04, -2.4]], 3)
    assert sec.npts[0] == 3 and np.ptp(sec.points[0, :, 1]) > 1e-3


def test_determinant_of_a_strongly_contracting_orbit_is_liouvilles() -> None:
    # DP^n of rank ~1: det from the entries is rounding noise (here of the wrong sign); exp(int div) is not.
    mu1, v = -0.7, np.array([0.6, 0.8])
    a = mu1 * np.outer(v, v) + np.array([[0.0, 1e-17], [-1e-17, 0.0]])
    div = -60.0  # det = exp(-60) ~ 8.8e-27
    mono = Monodromy(np.zeros((1, 2)), a[None], np.array([div]), np.zeros((1, 1, 2)), np.zeros(1, np.int64),
                     np.zeros(1, np.int64))  # fmt: skip
    orb = orbit_from(FIG8B.params, np.zeros(2), 1, mono, 3, (0.0, 0.0))
    assert not orb.det_resolved
    assert orb.det == pytest.approx(math.exp(div)) and orb.det > 0
    assert orb.multipliers[1].real == pytest.approx(math.exp(div) / mu1)
    assert orb.kind == "stable node"


def test_orbits_csv_reads_back_as_numbers(tmp_path) -> None:
    res = find_orbits(FIG8B.params, grid_seeds(FIG8B.box, 3, 3), [1])
    path = tmp_path / "orbits.csv"
    rows = res.to_csv(str(path))
    text = path.read_text()
    assert "np." not in text
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert data.shape[0] == rows > 0
    for name in ("q", "r", "mu1_re", "mu1_im", "mu2_re", "mu2_im"):
        assert np.all(np.isfinite(data[name].astype(float)))
    with open(path, newline="") as fh:
        assert len(list(csv.DictReader(fh))) == rows


def test_every_long_analysis_reports_progress_in_one_shape() -> None:
    from explorer_core.analyses.lyapunov import lyapunov_spectrum
    from explorer_core.analyses.regimes import chart_spec, regime_chart
    from explorer_core.progress import Progress

    seen = []
    for chunk in PoincareMap.of(FIG8B.params, NUM).iterate(np.array([[-0.04, -2.4]]), 6):
        seen.append(chunk.progress)
    assert [p.done for p in seen][-1] == 6 and all(p.unit == "periods" and p.total == 6 for p in seen)
    lyap = []
    lyapunov_spectrum(FIG8B.params, [(-0.5, -1.0)], 40, progress=lyap.append, workers=1)
    assert lyap and isinstance(lyap[-1].progress, Progress) and lyap[-1].progress.total == lyap[-1].total_periods
    spec = chart_spec(FIG8B.params, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (3, 2), ics=[(-0.09, -2.0)],
                      transient=10, periods=40)  # fmt: skip
    ups = []
    regime_chart(spec, workers=1, progress=ups.append)
    assert ups[-1].progress.fraction == 1.0 and ups[-1].progress.unit == "tiles"
    assert "6/6 periods (100 %" in seen[-1].line()


def test_manifolds_say_what_they_lost() -> None:
    from explorer_core.analyses.manifolds import manifolds, saddle_orbit

    flip = saddle_orbit(FIG8B.params, (-0.04, -2.40), 1)
    view = (*FIG8B.q_range, *FIG8B.r_range)
    m = manifolds(FIG8B.params, flip, length=3.0, view=view, pixels=(200, 150), max_points=100)
    # A point budget far too small: branches stop short of the length, and say so.
    assert not m.complete and any("budget" in loss.why for loss in m.lost)
    assert m.summary()["lost"] == [loss.as_dict() for loss in m.lost]
    assert m.progress.fraction == 1.0  # the run is over: what it lacks is in lost


def test_shared_map_derivative_is_the_grouped_run_bit_for_bit() -> None:
    # A map of one system takes the tangent system's run directly (no grouping by section times): the same
    # batch, so the same numbers as monodromy_at's grouped run, at every member, failed ones' statuses included.
    from explorer_core.solve.tangent import monodromy_at

    p = get_scene("fig10").params
    pmap = PoincareMap.of(p, Numerics(bound=50.0))
    x = np.array([[-0.0959, -1.962], [0.3, -0.2], [0.0, 40.0], [np.nan, 0.0], [1.0, 1.0]])
    for n in (1, 3):
        got = pmap.derivative(x, n)
        ref = monodromy_at([p], x, n, pmap.numerics, block=pmap.block)
        ok = ref.status == Status.OK
        assert ok.sum() >= 3 and not ok.all()
        np.testing.assert_array_equal(got.status, ref.status)
        np.testing.assert_array_equal(got.nsteps, ref.nsteps)
        for name in ("end", "matrix", "div", "points"):
            np.testing.assert_array_equal(getattr(got, name)[ok], getattr(ref, name)[ok])
