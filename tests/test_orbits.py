"""Periodic orbits of the Poincare map: checked against solve_ivp, finite differences and closed forms."""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp
from clirun import run_cli
from naive import fd_monodromy, ivp_map

from explorer_core.analyses.orbits import (
    UNIT_TOL,
    classify,
    find_orbits,
    grid_seeds,
    minimal_period,
    multipliers,
    return_seeds,
)
from explorer_core.scenes import get_scene
from explorer_core.solve.section import section
from explorer_core.system.params import ParameterError

FIG8B = get_scene("fig8B").params


@pytest.fixture(scope="module")
def fig8b_period1():
    return find_orbits(FIG8B, grid_seeds(get_scene("fig8B").box, 6, 6), [1])


def test_fig8b_period_one_orbits_against_solve_ivp_and_finite_differences(fig8b_period1) -> None:
    orbits = fig8b_period1.orbits
    kinds = sorted(o.kind for o in orbits)
    assert kinds == ["flip saddle", "saddle", "unstable focus"], kinds
    flip = next(o for o in orbits if o.kind == "flip saddle")
    # The skeleton of the strange attractor (the phase-plane issue): near (-0.04, -2.40).
    np.testing.assert_allclose(flip.points[0], (-0.0377, -2.3979), atol=1e-3)
    for o in orbits:
        x = o.points[0]
        # An independent integrator (scipy's DOP853 on the naive 3x3 field) returns to the point.
        assert np.linalg.norm(ivp_map(FIG8B, x, 1) - x) < 1e-8 * (1 + np.linalg.norm(x))
        # The monodromy matrix from the variational equations equals finite differences of that map.
        fd = fd_monodromy(FIG8B, x, 1)
        np.testing.assert_allclose(o.matrix, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
        mu_fd = multipliers(fd)
        np.testing.assert_allclose(np.sort_complex(o.multipliers), np.sort_complex(mu_fd), rtol=1e-5, atol=1e-7)
        # Liouville: det DP = exp(int div dt) over the period.
        assert o.det == pytest.approx(o.liouville, rel=1e-9)
        assert o.residual < 1e-8


def test_fig4_steady_rotations_are_the_closed_form_fixed_points() -> None:
    # On q = 0 (p = alpha whatever g is) a point is fixed for all t iff lambda = 0 and (I w) x w = 0:
    # w = (alpha, 0, r) is an eigenvector of I. Solved here with sympy, independently of the tables.
    params = get_scene("fig4A").params
    i11, _, i33, _, i13, _ = (sp.nsimplify(v) for v in params.inertia)
    alpha, r = sp.nsimplify(params.alpha), sp.symbols("r")
    inertia = sp.Matrix([[i11, 0, i13], [0, sp.nsimplify(params.inertia[1]), 0], [i13, 0, i33]])
    w = sp.Matrix([alpha, 0, r])
    roots = [float(v) for v in sp.solve((inertia * w).cross(w)[1], r)]
    assert len(roots) == 2
    res = find_orbits(params, [(0.01, rr + 0.02) for rr in roots], [1])
    found = sorted(float(o.points[0, 1]) for o in res.orbits)
    np.testing.assert_allclose(found, sorted(roots), atol=1e-10)
    for o in res.orbits:
        assert abs(o.points[0, 0]) < 1e-10


def test_a_reversible_scene_has_an_elliptic_fixed_point() -> None:
    # Fig. 1A: a diagonal tensor, g even: reversible, so a symmetric fixed point has mu, 1/mu.
    res = find_orbits(get_scene("fig1A").params, [(0.05, 0.05)], [1])
    (o,) = res.orbits
    assert o.kind == "elliptic" and not o.stable
    np.testing.assert_allclose(np.abs(o.multipliers), 1.0, atol=1e-9)
    assert o.det == pytest.approx(1.0, abs=1e-9)


def test_a_fixed_point_is_not_reported_as_a_two_cycle(fig8b_period1) -> None:
    flip = next(o for o in fig8b_period1.orbits if o.kind == "flip saddle")
    res = find_orbits(FIG8B, [flip.points[0] + 1e-4], [2])
    assert [o.period for o in res.orbits] == [1]
    np.testing.assert_allclose(res.orbits[0].points[0], flip.points[0], atol=1e-9)


def test_cyclic_shifts_are_one_orbit() -> None:
    res = find_orbits(FIG8B, [(-0.96, -1.86)], [2])
    (two,) = [o for o in res.orbits if o.period == 2]
    both = find_orbits(FIG8B, [two.points[0] + 1e-4, two.points[1] - 1e-4], [2])
    assert len([o for o in both.orbits if o.period == 2]) == 1
    # the points are listed from the lexicographically smallest, each the image of the one before
    assert tuple(two.points[0]) <= tuple(two.points[1])
    np.testing.assert_allclose(ivp_map(FIG8B, two.points[0], 1), two.points[1], atol=1e-8)


def test_failed_seeds_are_reported_with_their_reason_and_never_as_orbits() -> None:
    # Fig. 3's drift from (0, 8): no period-1 orbit nearby, the trajectory leaves any bound.
    res = find_orbits(get_scene("fig3").params.with_(), [(0.0, 8.0)], [1], max_iter=6)
    assert res.orbits == []
    (f,) = res.failures
    assert f.period == 1 and f.reason and f.iterations >= 1


def test_bad_input_names_the_bad_value() -> None:
    with pytest.raises(ParameterError, match="period"):
        find_orbits(FIG8B, [(0.0, 0.0)], [0])
    with pytest.raises(ParameterError, match="initial condition"):
        find_orbits(FIG8B, [(np.nan, 0.0)], [1])
    with pytest.raises(ParameterError, match="ftol"):
        find_orbits(FIG8B, [(0.0, 0.0)], [1], ftol=2.0)


@pytest.mark.parametrize(
    ("mu", "kind"),
    [
        ((0.5, 0.2), "stable node"),
        ((-0.5, 0.2), "stable node"),
        ((0.5 + 0.3j, 0.5 - 0.3j), "stable focus"),
        ((1.5, 1.2), "unstable node"),
        ((1.5 + 1j, 1.5 - 1j), "unstable focus"),
        ((3.0, 0.2), "saddle"),
        ((-3.0, 0.2), "flip saddle"),
        ((np.exp(0.3j), np.exp(-0.3j)), "elliptic"),
        ((1.0, 0.4), "neutral"),
        ((-1.0, 0.4), "neutral"),
    ],
)
def test_classification(mu, kind) -> None:
    assert classify(np.array(mu, dtype=complex)) == kind


def test_minimal_period_and_returns() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1e-12], [1.0, 0.0], [0.0, 0.0]])
    assert minimal_period(pts, pts[-1], 4, 1e-9) == 2
    assert minimal_period(pts[:3], pts[2], 2, 1e-15) == 2
    sec = section(FIG8B, [(-0.0377, -2.3979)], 40, transient=0)
    seeds = return_seeds(sec.points, sec.npts, 2, 0.05)
    assert seeds and all(n in (1, 2) for _, n in seeds)
    assert UNIT_TOL > 0


def test_cli_orbits_json_and_errors(tmp_path) -> None:
    out = tmp_path / "o.csv"
    rc, stdout, _ = run_cli("orbits", "--scene", "fig8B", "--max-period", "2", "--seeds", "4,4", "--json", "--out",
                            str(out))  # fmt: skip
    assert rc == 0
    d = json.loads(stdout)
    assert set(d) >= {"orbits", "failures", "params", "numerics"}
    o = d["orbits"][0]
    assert set(o) >= {"period", "points", "multipliers", "type", "stable", "det", "liouville", "residual"}
    assert len(o["points"]) == o["period"] and len(o["multipliers"]) == 2
    assert out.read_text().splitlines()[0].startswith("orbit,period,type,stable,j,q,r")
    for args, msg in (
        (("--period", "999"), "--period: period must be an integer in [1, 64], got 999"),
        (("--seed", "1e9,0"), "outside the escape bound"),
        (("--period", "1", "--max-period", "2"), "not both"),
        (("--seeds", "0,3"), "--seeds"),
    ):
        rc, _, err = run_cli("orbits", "--scene", "fig8B", *args, "--json")
        assert rc == 2 and msg in err and "Traceback" not in err, (args, err)
