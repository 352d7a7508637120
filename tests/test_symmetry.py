"""The involution t -> 2s - t, q -> q, r -> -r: where it holds, what breaks it, against solve_ivp."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from naive import solve_ivp_section

from explorer_core.analyses.symmetry import check_symmetry, field_residual, g_is_even_about, symmetry_centres
from explorer_core.system.params import ParameterError, Params

BASE = Params(inertia=(1, 4, 2, 0, 0, 0), alpha=0.1, g0=0.3, g1=0.9)
ICS = [(0.4, 0.7), (0.1, -0.3)]


@pytest.mark.parametrize("change", [{}, {"I12": 0.3}, {"I12": -0.2, "I11": 3.0, "alpha": -0.4}])
def test_holds_for_i13_i23_zero_and_even_g(change) -> None:
    c = check_symmetry(BASE.with_(**change), ICS, 10)
    assert c.holds and c.broken_by() == []
    assert c.max_distance < 1e-9 and c.field_residual < 1e-12
    assert c.summary()["holds"] is True


@pytest.mark.parametrize(("change", "reason"), [({"I13": 0.3}, "I13"), ({"I23": 0.3}, "I23"), ({"g2": 0.4}, "g2")])
def test_broken_and_named(change, reason: str) -> None:
    c = check_symmetry(BASE.with_(**change), ICS, 10)
    assert not c.holds and c.max_distance > 1e-3 and c.field_residual > 1e-3
    assert any(reason in b for b in c.broken_by())


def test_distances_agree_with_solve_ivp_reference() -> None:
    """Backward section from (q0, -r0) vs reflected forward one, both by scipy on the naive field."""
    p = BASE.with_(I13=0.3, I23=-0.1)
    c = check_symmetry(p, ICS[:1], 6)
    fwd = solve_ivp_section(p, ICS[0], 6)
    bwd = solve_ivp_section(p, (ICS[0][0], -ICS[0][1]), 6, direction=-1)
    ref = np.hypot(bwd[:, 0] - fwd[:, 0], bwd[:, 1] + fwd[:, 1])
    np.testing.assert_allclose(c.distance[0], ref, atol=1e-8)


def test_odd_forcing_is_even_about_its_phase_and_the_involution_holds_there() -> None:
    """g = g0 + g1 cos t + g2 sin t is even about phi = atan2(g2, g1): g2 != 0 only moves the centre."""
    p = BASE.with_(g2=0.4)
    phi = math.atan2(0.4, 0.9)
    np.testing.assert_allclose(symmetry_centres(p), [phi, phi + math.pi])
    assert not g_is_even_about(p, 0.0) and g_is_even_about(p, phi) and g_is_even_about(p, phi + math.pi)
    for s in (phi, phi + math.pi):
        c = check_symmetry(p, ICS, 10, centre=s)
        assert c.holds and c.centre == s and field_residual(p, s) < 1e-12
    assert symmetry_centres(Params(g1=0.0, g0=0.5)) == []  # constant g: even about every t


def test_failed_runs_are_reported() -> None:
    from explorer_core.solve.numerics import Numerics

    p = Params(inertia=(1, 2, 4, 0, 0, 0), alpha=0.1)
    c = check_symmetry(p, [(0.0, 8.0)], 300, numerics=Numerics(rtol=1e-10, atol=1e-10, bound=30.0))
    assert c.status == ["escaped"] and c.npts[0] < 300
    assert c.summary()["trajectories"][0]["status"] == "escaped"
    with pytest.raises(ParameterError, match="tol must be positive"):
        check_symmetry(p, ICS, 3, tol=0)


def test_cli(capsys) -> None:
    from explorer_core.cli import main

    assert main(["symmetry", "--scene", "fig1C", "--periods", "5", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["holds"] is True and s["centre"] == 0.0 and len(s["trajectories"]) == 4
    assert main(["symmetry", "--scene", "fig8B", "--ic", "-0.5,-1", "--periods", "5", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["holds"] is False and s["broken_by"] == ["I13 = 0.5 != 0", "I23 = 0.3 != 0"]
    assert main(["symmetry", "--scene", "fig1C", "--periods", "3"]) == 0
    assert "holds" in capsys.readouterr().out
