"""The body's orientation (engine system BODY, analyses.body) against independent computations.

The reference (tests/naive.py ``ivp_body``) integrates the full 3-D Lagrange-d'Alembert equations (all three
components of omega, the multiplier from the current omega) with the orientation as a 3x3 matrix,
``R' = R [omega]_x``, by scipy's DOP853 at 1e-12: no quaternion, no coefficient tables, no engine.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from naive import NaiveField, ivp_body

from explorer_core.analyses.body import BodySeries, body_series, iter_body_series, principal_axes
from explorer_core.scenes import get_scene
from explorer_core.solve import rk
from explorer_core.solve.integrators import Batch, coefficients, run
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import section
from explorer_core.status import Status
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

TIGHT = Numerics(rtol=1e-12, atol=1e-12)
#: A period-1 orbit of Fig. 10's tensor (regular) and Fig. 8B's strange attractor (chaotic).
REGULAR = (get_scene("fig10").params.with_(alpha=-0.35), (-0.0959, -1.962))
CHAOTIC = (get_scene("fig8B").params, (-0.318, -2.178))  # on the attractor after ~100 periods
FIG1A = Params(inertia=(1, 2, 4, 0, 0, 0), alpha=0.1)


def _derivative(v: np.ndarray, dt: float) -> np.ndarray:
    """``v'`` at the frames 2 .. F-3 by central differences with Richardson's extrapolation (error ~ dt^4)."""
    d1 = (v[3:-1] - v[1:-3]) / (2 * dt)
    d2 = (v[4:] - v[:-4]) / (4 * dt)
    return (4 * d1 - d2) / 3


def _reference(s: BodySeries) -> tuple[np.ndarray, np.ndarray]:
    return ivp_body(s.params, s.ic, float(s.t[0]), s.t)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("case", "periods", "k0"), [(REGULAR, 10, 0), (REGULAR, 50, 0), (CHAOTIC, 10, 0), (CHAOTIC, 5, 100)]
)
def test_orientation_after_n_periods_matches_the_3x3_rotation_of_the_full_system(case, periods, k0) -> None:
    # On the strange attractor (k0 = 100) a short run: over 10 periods there the reference at 1e-12 differs from
    # itself at 1e-13 by 1.5e-8 (over 5: 2.4e-10), so it can no longer tell 1e-8.
    params, ic = case
    s = body_series(params, ic, periods, samples=16, k0=k0, numerics=TIGHT)
    assert s.complete and s.status == Status.OK and s.lost == []
    assert s.frames == periods * 16 + 1
    omega, rot = _reference(s)
    np.testing.assert_allclose(s.rotation()[-1], rot[-1], rtol=0, atol=1e-8)  # after N periods
    np.testing.assert_allclose(s.rotation(), rot, rtol=0, atol=1e-8)  # and at every frame
    np.testing.assert_allclose(s.omega, omega, rtol=0, atol=1e-9 * (1 + np.abs(omega).max()))
    # The reference keeps R orthogonal by itself (a check of the reference), the series' |Q| stays 1.
    np.testing.assert_allclose(np.einsum("fij,fkj->fik", rot, rot), np.broadcast_to(np.eye(3), rot.shape), atol=1e-9)
    assert s.norm_drift < 1e-9
    np.testing.assert_allclose(np.einsum("fij,fkj->fik", *(s.rotation(),) * 2), np.broadcast_to(np.eye(3), rot.shape),
                               atol=1e-13)  # fmt: skip
    # Energy T = (I omega, omega)/2 of the reference's omega (p integrated, not taken from the constraint).
    energy = 0.5 * np.einsum("fi,ij,fj->f", omega, params.inertia_matrix, omega)
    np.testing.assert_allclose(s.energy, energy, rtol=1e-9)


def test_energy_rate_is_alpha_times_the_multiplier() -> None:
    """``T' = alpha lambda`` (PHYSICS.md) by central differences of the series' energy at alpha != 0."""
    params, ic = CHAOTIC
    s = body_series(params, ic, 3, samples=512, numerics=TIGHT)
    rate = _derivative(s.energy, params.period / s.samples)
    f = NaiveField(params)
    lam = np.array([f.omega_dot(t, q, r)[1] for t, (q, r) in zip(s.t[2:-2], s.omega[2:-2, 1:], strict=True)])
    scale = np.abs(params.alpha * lam).max()
    assert scale > 1e-2  # the energy changes: the check has something to see
    np.testing.assert_allclose(rate, params.alpha * lam, rtol=0, atol=1e-7 * scale)


def test_space_omega_is_the_rotation_rate_of_the_series() -> None:
    """``R' R^T = [R omega]_x`` by central differences of the rotations: the quaternion turns body -> space."""
    params, ic = REGULAR
    s = body_series(params, ic, 2, samples=512, numerics=TIGHT)
    rot = s.rotation()
    skew = np.einsum("fij,fkj->fik", _derivative(rot, params.period / s.samples), rot[2:-2])
    w = s.space_omega()[2:-2]
    got = np.column_stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]])
    np.testing.assert_allclose(got, w, rtol=0, atol=1e-6 * np.abs(w).max())
    np.testing.assert_allclose(skew + skew.transpose(0, 2, 1), 0.0, atol=1e-6 * np.abs(w).max())


@pytest.mark.parametrize(("numerics", "tol"), [(Numerics(), 1e-6), (TIGHT, 1e-8)])
@pytest.mark.parametrize("k0", [0, 7])
def test_the_field_part_is_the_section_at_the_section_frames(k0: int, numerics: Numerics, tol: float) -> None:
    """The same trajectory as the field's, to the tolerance (the frames change the step sequence; the chaotic
    scene's stretching takes a 1e-10 difference to ~4e-8 in 10 periods)."""
    params, ic = CHAOTIC
    periods = 10
    s = body_series(params, ic, periods, samples=8, k0=k0, numerics=numerics)
    sec = section(params, [ic], k0 + periods, numerics=numerics)
    pts = sec.points[0, : k0 + periods]
    frames = s.section_frames()
    assert frames.tolist() == list(range(0, periods * 8 + 1, 8))
    # Frame 0 is section()'s k0-th point exactly (the same map), later ones agree to the tolerance.
    start = np.asarray(ic) if k0 == 0 else pts[k0 - 1]
    np.testing.assert_array_equal(s.omega[0, 1:], start)
    np.testing.assert_array_equal(s.ic, start)
    np.testing.assert_allclose(s.omega[frames[1:], 1:], pts[k0:], rtol=0, atol=tol)
    np.testing.assert_array_equal(s.quaternion[0], [1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(s.t[frames], params.t0 + (k0 + np.arange(periods + 1)) * params.period, rtol=1e-15)


def test_under_fixed_steps_the_field_part_is_the_section_bit_for_bit() -> None:
    """The body's (q, r) is the field's own computation: the same coefficients, the same stages (rk4 steps agree)."""
    params, ic = REGULAR
    rk4 = Numerics(method="rk4", steps_per_period=480)
    s = body_series(params, ic, 5, samples=16, numerics=rk4)
    sec = section(params, [ic], 5, numerics=rk4)
    np.testing.assert_array_equal(s.omega[s.section_frames()[1:], 1:], sec.points[0])
    ref = body_series(params, ic, 5, samples=16, numerics=TIGHT)
    np.testing.assert_allclose(s.rotation(), ref.rotation(), atol=1e-7)  # rk4 at 480 steps a period: ~h^4


def test_frames_do_not_depend_on_the_number_of_frames_or_periods_asked() -> None:
    """Metamorphic: a frame is the state at its time, whatever else was asked (frames per period, periods)."""
    params, ic = CHAOTIC
    a = body_series(params, ic, 12, samples=8, numerics=TIGHT)
    b = body_series(params, ic, 12, samples=24, numerics=TIGHT)
    np.testing.assert_allclose(b.t[::3], a.t, rtol=1e-15)
    np.testing.assert_allclose(b.quaternion[::3], a.quaternion, atol=1e-10)
    np.testing.assert_allclose(b.omega[::3], a.omega, atol=1e-10)
    c = body_series(params, ic, 100, samples=8, numerics=TIGHT)  # two chunks of periods
    np.testing.assert_array_equal(c.quaternion[: a.frames], a.quaternion)


def test_a_later_start_is_the_same_motion_seen_from_the_body_at_that_start() -> None:
    """Metamorphic: the series from period k0 is the full one's, rotated back by its orientation at k0."""
    params, ic = REGULAR
    full = body_series(params, ic, 10, samples=8, numerics=TIGHT)
    late = body_series(params, ic, 4, samples=8, k0=6, numerics=TIGHT)
    f0 = 6 * 8
    np.testing.assert_allclose(late.omega, full.omega[f0:], atol=1e-10)
    rel = np.einsum("ji,fjk->fik", full.rotation()[f0], full.rotation()[f0:])
    np.testing.assert_allclose(late.rotation(), rel, atol=1e-9)


def test_principal_axes_and_the_box() -> None:
    params = get_scene("fig8B").params
    moments, axes = principal_axes(params)
    assert np.all(np.diff(moments) > 0)
    np.testing.assert_allclose(axes @ np.diag(moments) @ axes.T, params.inertia_matrix, atol=1e-13)
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-14)
    assert np.linalg.det(axes) == pytest.approx(1.0)
    # A uniform box of sides (a, b, c) has I_x = (b^2 + c^2)/12 ...: the sides come back from the moments.
    sides = np.array([1.0, 0.6, 0.3])
    box = Params(inertia=(*(((sides**2).sum() - sides**2) / 12), 0, 0, 0))
    s = body_series(box, (0.1, 0.2), 1, samples=4)
    np.testing.assert_allclose(s.box_sides()[np.argsort(s.moments)], np.sort(sides)[::-1] / sides.max(), rtol=1e-12)
    assert s.box_exists
    trace = s.axis_trace(2)
    np.testing.assert_allclose(np.linalg.norm(trace, axis=1), 1.0, atol=1e-12)
    fig1a = body_series(FIG1A, (0.1, 0.2), 1, samples=4)
    assert not fig1a.box_exists and fig1a.box_sides().min() == 0.0  # diag(1, 2, 4): 1 + 2 < 4
    np.testing.assert_allclose(fig1a.ellipsoid_axes(), [1.0, 1 / math.sqrt(2), 0.5])
    with pytest.raises(ParameterError, match="principal axis must be 0, 1 or 2, got 3"):
        s.axis_trace(3)


def test_an_escape_ends_the_series_with_its_status_and_a_loss() -> None:
    s = body_series(FIG1A, (0.0, 13.5), 30, samples=8, numerics=Numerics(bound=20.0))
    assert s.status == Status.ESCAPED and not s.complete
    assert 1 < s.frames < 30 * 8 + 1
    assert s.frames % 8 != 1  # the frames inside the period of the escape are kept, up to it
    (loss,) = s.lost
    assert loss.what == "frames" and loss.count == 30 * 8 + 1 - s.frames and "escaped" in loss.why
    assert np.all(np.isfinite(s.quaternion)) and np.abs(s.omega[:, 1:]).max() <= 20.0
    summary = s.summary()
    assert summary["status"] == "escaped" and summary["complete"] is False and summary["lost"][0]["count"] == loss.count
    early = body_series(FIG1A, (0.0, 13.5), 5, samples=8, k0=40, numerics=Numerics(bound=20.0))
    assert early.frames == 0 and early.status == Status.ESCAPED and "before period 40" in early.lost[0].why
    assert np.all(np.isnan(early.ic)) and early.summary()["frames"] == 0


def test_cancel_keeps_what_was_computed_and_says_so() -> None:
    params, ic = REGULAR
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 1  # after the first chunk of periods

    s = body_series(params, ic, 200, samples=4, cancel=cancel)
    assert s.status == Status.CANCELLED and not s.complete
    assert s.frames == 64 * 4 + 1
    assert s.lost[0].why == "cancelled" and s.lost[0].count == 200 * 4 + 1 - s.frames
    before = body_series(params, ic, 5, samples=4, k0=3, cancel=lambda: True)
    assert before.frames == 0 and before.status == Status.CANCELLED


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"periods": 0}, r"periods must be an integer in \[1, 10000\], got 0"),
        ({"periods": 10_001}, "got 10001"),
        ({"samples": 3}, r"samples must be an integer in \[4, 512\], got 3"),
        ({"samples": 513}, "got 513"),
        ({"periods": 10_000, "samples": 48}, "480001 frames exceeds the limit 200000"),
        ({"ic": (math.nan, 0.0)}, "not finite"),
        ({"ic": (0.0, 2e4)}, r"initial condition \[0.0, 20000.0\] lies outside the escape bound 10000"),
        ({"ic": [(0.1, 0.2), (0.2, 0.1)]}, "one trajectory: give one"),
        ({"k0": -1}, "k0 must be an integer"),
        ({"numerics": Numerics(method="taylor")}, "method taylor"),
        (
            {"numerics": Numerics(method="rk4", steps_per_period=400)},
            r"\(400\) is a multiple of samples",
        ),
    ],
)
def test_inputs_are_refused_with_the_bad_value_named(kw, match) -> None:
    args = {"ic": (0.1, 0.2), "periods": 5, **kw}
    with pytest.raises(ParameterError, match=match):
        body_series(FIG1A, args.pop("ic"), args.pop("periods"), **args)


def test_files_read_back_as_numbers(tmp_path) -> None:
    s = body_series(FIG1A, (0.3, 0.2), 2, samples=4)
    out = s.write(str(tmp_path / "body.csv"))
    assert out["rows"] == s.frames == 9
    with open(tmp_path / "body.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["frame", "k", "t", "p", "q", "r", "w", "x", "y", "z", "T"]
    table = np.array([[float(v) for v in r] for r in rows[1:]])
    np.testing.assert_array_equal(table[:, 2], s.t)
    np.testing.assert_array_equal(table[:, 6:10], s.quaternion)
    np.testing.assert_array_equal(table[:, 10], s.energy)
    assert rows[5][:2] == ["4", "1"]
    s.write(str(tmp_path / "body.npz"))
    with np.load(tmp_path / "body.npz") as z:
        np.testing.assert_array_equal(z["quaternion"], s.quaternion)
        np.testing.assert_array_equal(z["section_frames"], [0, 4, 8])
        assert json.loads(str(z["summary"]))["frames"] == 9
    s.write(str(tmp_path / "body.json"))
    summary = json.loads((tmp_path / "body.json").read_text())
    assert summary["status"] == "ok" and summary["complete"] is True and summary["lost"] == []
    assert summary["samples"] == 4 and len(summary["axes"]) == 3


def test_a_lock_step_block_of_bodies_with_different_parameters_meets_each_ones_series() -> None:
    """The block kernel: members with their own alpha and forcing rows (g, alpha beside each member's coefficients),
    one escaping mid-run (it leaves the packed block, the others go on), each as its own series."""
    p1, ic1 = REGULAR
    p2 = p1.with_(alpha=-0.42, g0=0.1)
    members = [(p1, ic1), (p2, (0.2, -1.5)), (FIG1A, (0.0, 13.5)), (p1.with_(alpha=0.3), (0.4, 0.1))]
    rows = np.array([0, 1, 2, 3])
    coefs = coefficients([Model(p) for p, _ in members], rows)
    batch = Batch.start(np.array([ic for _, ic in members]), p1.t0, p1.period, dim=rk.STATE_SIZE[rk.BODY])
    batch.y[:, 2] = 1.0
    numerics = Numerics(rtol=1e-12, atol=1e-12, bound=20.0)
    frames, nframes = run(rk.BODY, coefs, batch, 30, samples=8, block=4, workers=1, **numerics.kernel_kwargs())
    assert batch.status.tolist() == [Status.OK, Status.OK, Status.ESCAPED, Status.OK]
    for i, (p, ic) in enumerate(members):
        s = body_series(p, ic, 30, samples=8, numerics=numerics)
        assert nframes[i] == s.frames - 1
        np.testing.assert_allclose(frames[i, : nframes[i], :2], s.omega[1:, 1:], atol=1e-9)
        np.testing.assert_allclose(frames[i, : nframes[i], 2:], s.quaternion[1:], atol=1e-9)


def test_at_alpha_zero_the_energy_is_conserved() -> None:
    """``T' = alpha lambda = 0``: the constraint does no work (PHYSICS.md), while the body turns."""
    params = REGULAR[0].with_(alpha=0.0)
    s = body_series(params, (0.3, -0.8), 20, samples=16, numerics=TIGHT)
    assert s.complete
    np.testing.assert_allclose(s.energy, s.energy[0], rtol=1e-10)
    assert np.abs(s.rotation()[-1] - np.eye(3)).max() > 0.1


def test_a_series_does_not_depend_on_which_period_the_section_phase_is_counted_from() -> None:
    """Metamorphic: ``t0`` one forcing period later is the same system (``g`` is periodic) and the same series."""
    params, ic = REGULAR
    a = body_series(params, ic, 10, samples=8, numerics=TIGHT)
    b = body_series(params.with_(t0=params.t0 + params.period), ic, 10, samples=8, numerics=TIGHT)
    np.testing.assert_allclose(b.t - params.period, a.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.quaternion, a.quaternion, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.omega, a.omega, rtol=0, atol=1e-10)


def test_the_series_streams_its_progress_under_the_contract() -> None:
    params, ic = REGULAR
    seen = []
    s = body_series(params, ic, 150, samples=4, k0=10, progress=seen.append)
    done = [u.progress.done for u in seen]
    assert done == [10, 74, 138, 160] and all(u.progress.total == 160 for u in seen)
    assert [u.result is None for u in seen] == [True, True, True, False] and seen[-1].result is s and s.complete
    stop = []
    cut = body_series(
        params, ic, 150, samples=4, k0=10, progress=lambda u: stop.append(u), cancel=lambda: len(stop) >= 2
    )
    assert not cut.complete and cut.status == Status.CANCELLED and cut.frames == 64 * 4 + 1
    assert stop[-1].progress.done == 74 and stop[-1].result is cut
    with pytest.raises(ParameterError, match="samples must be"):
        iter_body_series(params, ic, 5, samples=2)  # checked at once, before the first update
