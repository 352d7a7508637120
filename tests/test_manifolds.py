"""Stable and unstable manifolds of saddles: checked against solve_ivp, finite differences and brute force."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from clirun import run_cli
from naive import fd_monodromy, ivp_manifold_points, ivp_map, naive_segment_crossings

from explorer_core.analyses.manifolds import (
    Manifolds,
    crossings,
    iter_manifolds,
    manifolds,
    saddle_eigenvectors,
    saddle_orbit,
    segment_crossings,
)
from explorer_core.scenes import get_scene
from explorer_core.system.params import ParameterError

SCENE = get_scene("fig8B")
FIG8B = SCENE.params
VIEW = (*SCENE.q_range, *SCENE.r_range)
PIXELS = (800, 600)


@pytest.fixture(scope="module")
def flip() -> Manifolds:
    """The flip saddle of Fig. 8B, whose unstable manifold is the strange attractor's skeleton."""
    orbit = saddle_orbit(FIG8B, (-0.04, -2.40), 1)
    return manifolds(FIG8B, orbit, length=8.0, view=VIEW, pixels=PIXELS)


def _on(branch_pieces: list[np.ndarray], s: float) -> np.ndarray:
    """The computed point nearest to arc length ``s`` (a vertex: a chord between vertices is off the curve)."""
    p = branch_pieces[0]
    return p[int(np.argmin(np.abs(p[:, 0] - s))), 1:].copy()


def _distance_to(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline ``poly`` (m, 2)."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    out = []
    for x in points:
        t = np.clip(np.einsum("ij,ij->i", x - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1)
        out.append(np.min(np.linalg.norm(a + t[:, None] * ab - x, axis=1)))
    return np.array(out)


def test_flip_saddle_branches_complete(flip: Manifolds) -> None:
    assert flip.orbit.kind == "flip saddle"
    assert flip.completed
    assert {(b.kind, b.label) for b in flip.branches} == {(k, s) for k in ("unstable", "stable") for s in ("0+", "0-")}
    for b in flip.branches:
        assert b.end == "complete" and b.status == "ok", b.as_dict()
        assert b.length == pytest.approx(8.0)
        assert len(b.pieces) == 1 and b.escaped == 0 and b.failed == 0
        s = b.pieces[0][:, 0]
        assert s[0] == 0.0 and np.all(np.diff(s) > 0)
        np.testing.assert_allclose(b.pieces[0][0, 1:], flip.orbit.points[0])


def test_tangent_at_the_saddle_is_the_eigenvector_of_finite_differences(flip: Manifolds) -> None:
    x = flip.orbit.points[0]
    mu_u, vu, mu_s, vs = saddle_eigenvectors(fd_monodromy(FIG8B, x, 1))
    assert mu_u == pytest.approx(flip.orbit.multipliers[0].real, rel=1e-6)
    # Zoomed in on the saddle: the view's pixels are 5e-6 wide, so the curve is kept that fine.
    zoom = manifolds(FIG8B, flip.orbit, length=1e-3, view=(x[0] - 2e-3, x[0] + 2e-3, x[1] - 1.5e-3, x[1] + 1.5e-3))
    for b in zoom.branches:
        p = b.pieces[0]
        assert 0 < p[1, 0] < 1e-5  # the first point after the saddle, a pixel or two away
        d = p[1, 1:] - x
        v = vu if b.kind == "unstable" else vs
        sine = abs(d[0] * v[1] - d[1] * v[0]) / np.linalg.norm(d)
        assert sine < 1e-4, (b.kind, b.label, sine)
        assert np.sign(d @ v) == b.sign


@pytest.mark.parametrize("kind", ["unstable", "stable"])
def test_points_converge_to_the_saddle_at_the_rate_of_the_multiplier(flip: Manifolds, kind: str) -> None:
    """solve_ivp backwards (unstable) or forwards (stable) from points of the branches: the distance to the
    saddle shrinks by 1/|mu_u| (or |mu_s|) per period."""
    x = flip.orbit.points[0]
    mu = np.abs(flip.orbit.multipliers.real)
    rate = 1.0 / mu[0] if kind == "unstable" else mu[1]
    step = -1 if kind == "unstable" else 1
    for b in (b for b in flip.branches if b.kind == kind):
        y = _on(b.pieces, 0.4)
        dist = [np.linalg.norm(y - x)]
        for _ in range(6):
            y = ivp_map(FIG8B, y, step, rtol=1e-12, atol=1e-12)
            dist.append(np.linalg.norm(y - x))
        ratios = np.array(dist[1:]) / np.array(dist[:-1])
        assert dist[-1] < 2e-3 * dist[0], dist
        np.testing.assert_allclose(ratios[-3:], rate, rtol=0.03, err_msg=f"{kind} {b.label}: {ratios}")


def test_brute_force_images_of_the_fundamental_domain_lie_on_the_curve(flip: Manifolds) -> None:
    """Points of the linear fundamental domain, mapped by solve_ivp, are within a pixel of the grown curve."""
    x = flip.orbit.points[0]
    pixel = min((VIEW[1] - VIEW[0]) / PIXELS[0], (VIEW[3] - VIEW[2]) / PIXELS[1])
    delta = flip.extra["delta"]
    for b in flip.branches:
        mu = b.multiplier if b.kind == "unstable" else 1.0 / b.multiplier
        n = 2 if b.kind == "unstable" else -2  # a flip saddle: G = F^2 (or F^-2) keeps each branch on its side
        pts = ivp_manifold_points(FIG8B, x, b.eigenvector, mu**2, n, 3, 12, delta, b.sign)
        flat = pts.reshape(-1, 2)
        inside = (flat[:, 0] > VIEW[0]) & (flat[:, 0] < VIEW[1]) & (flat[:, 1] > VIEW[2]) & (flat[:, 1] < VIEW[3])
        far = np.linalg.norm(flat - x, axis=1) < 0.9 * 8.0  # within the grown length (a chord is shorter)
        d = _distance_to(flat[inside & far], b.pieces[0][:, 1:])
        assert d.size >= 6
        assert d.max() < pixel, (b.kind, b.label, d.max() / pixel)


def test_homoclinic_points_of_the_flip_saddle(flip: Manifolds) -> None:
    """The tangle behind the strange attractor: the unstable and stable manifolds cross."""
    assert len(flip.crossings) > 10
    assert {c.kind for c in flip.crossings} == {"homoclinic"}
    x = flip.orbit.points[0]
    for c in flip.crossings:
        assert c.s_unstable > 0 and c.s_stable > 0
        assert np.hypot(c.q - x[0], c.r - x[1]) > 1e-3  # never the saddle itself


def test_crossing_kernel_against_brute_force() -> None:
    rng = np.random.default_rng(3)
    for trial in range(20):
        a = np.cumsum(rng.normal(size=(rng.integers(2, 200), 2)) * 0.1, axis=0)
        b = np.cumsum(rng.normal(size=(rng.integers(2, 200), 2)) * 0.1, axis=0)
        if trial % 3 == 0:  # long segments among short ones
            a[rng.integers(0, len(a))] += 5.0
            b[rng.integers(0, len(b))] -= 4.0
        cell = float(rng.choice([0.01, 0.1, 1.0]))
        fast = sorted((int(i), int(j)) for i, j, _, _ in segment_crossings(a, b, cell))
        slow = sorted((i, j) for i, j, _, _ in naive_segment_crossings(a, b))
        assert fast == slow, trial


def test_heteroclinic_crossings_between_two_orbits(flip: Manifolds) -> None:
    """Crossings of one saddle's unstable with another's stable pieces are heteroclinic."""
    from dataclasses import replace

    shifted = replace(flip, branches=[replace(b, pieces=[p + np.array([0.0, 0.05, 0.0]) for p in b.pieces])
                                      for b in flip.branches])  # fmt: skip
    found = crossings([flip, shifted])
    assert {c.kind for c in found} == {"homoclinic", "heteroclinic"}
    assert any(c.unstable.startswith("A:") and c.stable.startswith("1:") for c in found)


def test_partial_results_stream_and_cancel() -> None:
    orbit = saddle_orbit(FIG8B, (-0.04, -2.40), 1)
    parts = list(iter_manifolds(FIG8B, orbit, length=5.0, view=VIEW, kinds=["unstable"]))
    assert len(parts) >= 2 and not parts[0].completed and parts[-1].completed
    assert {(b.end, b.status) for b in parts[0].branches} == {("growing", "not_run")}
    lengths = [sum(b.length for b in p.branches) for p in parts]
    assert lengths == sorted(lengths)
    calls = []
    stopped = manifolds(FIG8B, orbit, length=50.0, view=VIEW, cancel=lambda: calls.append(1) or len(calls) > 3)
    assert not stopped.completed or {b.end for b in stopped.branches} == {"cancelled"}
    assert "cancelled" in {b.status for b in stopped.branches} & {b.end for b in stopped.branches}
    # Cancelled: no crossings computed (they take seconds on a large run), and the result says so.
    assert not stopped.complete and stopped.crossings == []
    assert {loss.what for loss in stopped.lost} >= {"crossings"}
    assert all(loss.why == "cancelled" for loss in stopped.lost if loss.what.startswith("branch"))


def test_a_branch_that_ends_on_an_attractor_or_off_view() -> None:
    """The Fig. 8B saddle near (-1.46, -4.13): a slow unstable branch (mu = 1.48) grown level after level."""
    orbit = saddle_orbit(FIG8B, (-1.457, -4.13), 1)
    assert orbit.kind == "saddle"
    m = manifolds(FIG8B, orbit, length=3.0, kinds=["unstable"], view=(-3.0, 0.0, -5.5, -2.5))
    for b in m.branches:
        assert b.end in ("complete", "ends", "escaped") and b.status in ("ok", "escaped"), b.as_dict()
        assert b.levels > 10  # mu = 1.48: many levels from the fundamental domain


def test_bad_input_is_refused_with_the_value() -> None:
    orbit = saddle_orbit(FIG8B, (-0.04, -2.40), 1)
    with pytest.raises(ParameterError, match="unstable focus"):
        saddle_orbit(FIG8B, (-0.02, 0.077), 1)
    with pytest.raises(ParameterError, match="length"):
        manifolds(FIG8B, orbit, length=float("nan"))
    with pytest.raises(ParameterError, match="kinds"):
        manifolds(FIG8B, orbit, kinds=["sideways"])
    with pytest.raises(ParameterError, match="view"):
        manifolds(FIG8B, orbit, view=(1.0, 0.0, 0.0, 1.0))
    with pytest.raises(ParameterError, match="delta_px"):
        manifolds(FIG8B, orbit, delta_px=0.0)
    with pytest.raises(ParameterError, match="not a saddle"):
        saddle_eigenvectors(np.array([[0.5, 0.0], [0.0, 0.2]]))


def test_cli_manifolds_csv_and_json(tmp_path) -> None:
    out = tmp_path / "m.csv"
    rc, stdout, err = run_cli("manifolds", "--scene", "fig8B", "--orbit", "-0.04,-2.4", "--period", "1",
                              "--length", "3", "--out", str(out), "--json")  # fmt: skip
    assert rc == 0, err
    data = json.loads(stdout)
    assert data["orbit"]["type"] == "flip saddle"
    assert {b["kind"] for b in data["branches"]} == {"stable", "unstable"}
    assert data["out"][0]["rows"] > 100
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["branch", "kind", "s", "q", "r"]
    assert {r[1] for r in rows[1:]} == {"stable", "unstable"}
    assert {r[0] for r in rows[1:]} == {"0+", "0-"}
    assert len(rows) - 1 == data["out"][0]["rows"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--orbit", "0,x"], "--orbit"),
        (["--orbit", "-0.02,0.077"], "not a saddle"),
        (["--orbit", "-0.04,-2.4", "--kinds", "up"], "--kinds"),
        (["--orbit", "-0.04,-2.4", "--view", "1,0,0,1"], "--view"),
        (["--orbit", "-0.04,-2.4", "--length", "0"], "length"),
        (["--orbit", "-0.04,-2.4", "--period", "0"], "period"),
    ],
)
def test_cli_manifolds_bad_input(args: list[str], message: str) -> None:
    rc, _, err = run_cli("manifolds", "--scene", "fig8B", *args)
    assert rc == 2
    assert message in err and "Traceback" not in err
