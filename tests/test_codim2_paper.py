"""The paper's scenes by brute force, independently of the normal forms (docs/continuation.md, "The paper's scenes
by brute force"; the pictures and the other points: docs/paper_scenes_check.py): what the orbit diagram and the
sections show near a bifurcation the continuation calls supercritical."""

from __future__ import annotations

import numpy as np
import pytest
from clirun import run_cli

from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.continuation import continue_orbit
from explorer_core.analyses.sections import poincare_section
from explorer_core.scenes import get_scene

FIG10 = get_scene("fig10").params
#: Fig. 10's period-1 orbit at alpha = -0.35 (README).
ORBIT = (-0.0959, -1.962)


def _exponent(d: np.ndarray, a: np.ndarray) -> float:
    """``e`` of ``a = c d^e`` by least squares in logs."""
    return float(np.polyfit(np.log(d), np.log(a), 1)[0])


def test_the_first_fig10_doubling_is_soft_by_brute_force_as_its_criticality_says() -> None:
    """The orbit diagram across the first doubling (continuation seeding, both sweeps): on the side where the
    period-1 orbit is unstable the doubled orbit's amplitude ``|x_k - x_k+1|`` grows like ``d^(1/2)`` (fitted
    exponent 0.5 +- 0.1), it vanishes on the other side, and the two sweeps agree (no hysteresis): a soft
    transition, which is what the continuation's "supercritical" (flip coefficient ``b > 0``) says. A
    subcritical doubling would show no small doubled orbit on the unstable side (a jump) and sweeps that
    differ."""
    cont = continue_orbit(FIG10, "alpha", (-0.35, -0.38), ORBIT, 1)
    (pd,) = [b for b in cont.bifurcations if b.kind == "period_doubling"]
    d = np.geomspace(2.5e-4, 4e-3, 6)
    values = np.concatenate([pd.value - d[::-1], pd.value + np.array([5e-4, 2e-3])])  # ascending
    diag = bifurcation_diagram(FIG10, "alpha", values, points=16, transient=4000, ics=[ORBIT],
                               seeding="continuation", sweeps=("forward", "backward"))  # fmt: skip
    assert (diag.status == 0).all()
    amp = np.linalg.norm(np.diff(diag.points[:, :, 0], axis=2), axis=3).max(axis=2)  # (sweep, value)
    unstable = amp[:, : d.size]
    assert np.abs(unstable[0] - unstable[1]).max() <= 1e-3 * unstable.max()  # no hysteresis
    assert amp[:, d.size :].max() < 1e-6  # the period-1 orbit on the stable side
    e = _exponent(d[::-1], unstable.mean(axis=0))
    assert abs(e - 0.5) < 0.1, e
    nf = pd.normal_form
    assert nf.criticality == "supercritical" and nf.coefficient > 0  # the sign the brute force agrees with


@pytest.mark.slow  # 10-20 s: eight sections of 30,000 periods
def test_the_fig10_neimark_sacker_point_in_g1_gives_birth_to_a_small_stable_curve() -> None:
    """Sections on both sides of the Neimark-Sacker point of Fig. 10's period-1 orbit in ``g1`` (alpha = -0.35):
    below it the trajectory settles on the fixed point, above it on a closed curve around it whose size grows
    like ``delta^(1/2)`` (fitted exponent 0.5 +- 0.1), reached from inside and from outside (a stable invariant
    curve born: the continuation's "supercritical", ``Re d < 0``)."""
    params = FIG10.with_(alpha=-0.35)
    cont = continue_orbit(params, "g1", (1.0, 2.2), ORBIT, 1)
    (ns,) = [b for b in cont.bifurcations if b.kind == "neimark_sacker"]
    x = np.array(ns.point)

    def size(delta: float, start: np.ndarray) -> float:
        sec = poincare_section(params.with_(g1=ns.value + delta), 300, ics=np.array([start]), transient=30000)
        p = sec.points[0, : sec.npts[0]]
        return 0.5 * float(np.max(np.linalg.norm(p[:, None] - p[None, :], axis=2)))

    deltas = np.array([2e-3, 4e-3, 8e-3, 1.6e-2])
    inside = np.array([size(dl, x + 0.01) for dl in deltas])
    outside = np.array([size(dl, x + 0.3) for dl in deltas])
    np.testing.assert_allclose(inside, outside, rtol=1e-2)  # one attracting curve
    assert 1e-3 < inside[0] < 0.1
    # Below: the fixed point attracts (slowly, |mu| = 1 - 3e-4 per period here): from 0.01 to far below the curve's
    # size at the same distance above.
    assert size(-4e-3, x + 0.01) < 0.01 * inside[1]
    e = _exponent(deltas, inside)
    assert abs(e - 0.5) < 0.1, e
    nf = ns.normal_form
    assert nf.criticality == "supercritical" and nf.coefficient < 0


def test_the_command_line_says_which_switch_is_not_offered_at_fig11_s_resonances() -> None:
    """``bilimovich continue --switch`` on Fig. 11's NS curve in ``(g1, I11)``: the R2 is switched at (the
    period-2 orbit's NS curve), the R3 and R4 are not, and the printed report says so with the point's kind; the
    points of the switched curve say that switching is not repeated."""
    rc, out, _ = run_cli("continue", "--scene", "fig11", "--inertia", "1.6,2,4,0,0.5,0.3", "--param", "g1",
                         "--range=1,4", "--from=-0.1744491259,-2.185453719", "--param2", "I11", "--range2=1,2",
                         "--switch")  # fmt: skip
    assert rc == 0
    lines = out.splitlines()
    said = {ln.split()[3]: ln for ln in lines if ln.startswith("no switching at ") and "period-1 orbit" in ln}
    assert set(said) == {"R3", "R4"}, said
    assert said["R3"].startswith("no switching at R3 (1:3 resonance) of the period-1 orbit at (g1, I11) = (1.8614")
    assert "not offered" in said["R3"] and "init_R3_NS3m" in said["R3"] and "init_R4_NS4m" in said["R4"]
    assert any(ln.startswith("R2 (1:2 resonance) of the period-2 orbit") for ln in lines)  # the switched curve's
    assert any("switching is not repeated" in ln for ln in lines)
