"""Bifurcation diagrams: the sweep engine on maps with known bifurcations, then the ODE."""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest
from clirun import run_cli

from explorer_core.analyses.bifurcation import bifurcation_diagram, bilimovich_orbits, sweep_orbits
from explorer_core.analyses.sweeps import check_param, detect_period, sweep_values
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Status
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError

FIG10 = get_scene("fig10").params


def map_orbits(step, values, transient: int, n: int):
    """An OrbitFn for a 1-D map ``x -> step(x, value)``; points are ``(x, 0)``."""

    def orbits(v: int, seed: np.ndarray, threads: int):
        x = seed[:, 0].copy()
        for _ in range(transient):
            x = step(x, values[v])
        pts = np.empty((x.size, n, 2))
        pts[..., 1] = 0.0
        for j in range(n):
            x = step(x, values[v])
            pts[:, j, 0] = x
        final = np.column_stack([x, np.zeros_like(x)])
        return pts, np.full(x.size, n), np.zeros(x.size, dtype=np.int64), final

    return orbits


def logistic(x, r):
    return r * x * (1.0 - x)


def test_logistic_map_period_doubling_points() -> None:
    """Periods 1, 2, 4, 8 and the period-3 window; doublings at r = 3 and 1 + sqrt(6)."""
    rs = np.concatenate([np.linspace(2.9, 3.6, 141), [3.83]])
    out = sweep_orbits(map_orbits(logistic, rs, 4000, 64), rs.size, np.array([[0.3, 0.0]]), 64, seeding="fixed")
    per = np.array([detect_period(out["points"][0, v, 0], 16, 1e-7) for v in range(rs.size)])
    assert per[-1] == 3
    first_2 = rs[np.argmax(per == 2)]
    first_4 = rs[np.argmax(per == 4)]
    first_8 = rs[np.argmax(per == 8)]
    # Slow convergence right at a doubling (multiplier -1) shifts the detected onset by a grid step or two.
    assert 3.0 - 0.005 <= first_2 <= 3.0 + 0.015
    assert 1 + math.sqrt(6) - 0.005 <= first_4 <= 1 + math.sqrt(6) + 0.015
    assert 3.5441 - 0.005 <= first_8 <= 3.5441 + 0.015  # r3 = 3.54409...
    assert set(per[(rs > 3.02) & (rs < 3.44)]) == {2}
    assert np.all(per[:-1][rs[:-1] > 3.575] == 0)  # chaos beyond the accumulation point (r = 3.5699...)


def test_continuation_exposes_hysteresis_of_a_bistable_map() -> None:
    """x -> x + 0.1 (c + x - x^3): two stable fixed points for |c| < 2/(3 sqrt 3); folds at +-0.3849."""
    cs = np.linspace(-0.6, 0.6, 121)
    fold = 2 / (3 * math.sqrt(3))
    out = sweep_orbits(
        map_orbits(lambda x, c: x + 0.1 * (c + x - x**3), cs, 500, 4),
        cs.size,
        np.array([[-1.5, 0.0]]),
        4,
        seeding="continuation",
    )
    assert out["sweeps"].tolist() == ["forward", "backward"]
    fwd = out["points"][0, :, 0, -1, 0]
    bwd = out["points"][1, :, 0, -1, 0]
    # Forward stays on the lower branch until the upper fold, backward on the upper until the lower fold.
    jump_up = cs[np.argmax(fwd > 0)]
    jump_down = cs[::-1][np.argmax(bwd[::-1] < 0)]
    assert fold - 0.011 <= jump_up <= fold + 0.011
    assert -fold - 0.011 <= jump_down <= -fold + 0.011
    inside = np.abs(cs) < fold - 0.02
    assert np.all(fwd[inside] < 0) and np.all(bwd[inside] > 0)
    # Fixed seeding from x = -1.5 never sees the upper branch below the fold.
    fixed = sweep_orbits(
        map_orbits(lambda x, c: x + 0.1 * (c + x - x**3), cs, 500, 4), cs.size, np.array([[-1.5, 0.0]]), 4,
        seeding="fixed",
    )  # fmt: skip
    np.testing.assert_allclose(fixed["points"][0, inside], out["points"][0, inside], atol=1e-9)


def test_detect_period() -> None:
    cyc = np.array([[0.0, 1.0], [1.0, 0.0], [2.0, 2.0]])
    pts = np.tile(cyc, (10, 1))
    assert detect_period(pts, 8, 1e-12) == 3
    assert detect_period(pts[:, ::-1] * 0 + 1.0, 8, 0.0) == 1
    assert detect_period(pts + np.arange(30)[:, None] * 1e-3, 8, 1e-6) == 0
    assert detect_period(pts, 2, 1e-12) == 0


def test_period_doubling_cascade_in_fig10_range() -> None:
    """Fig. 10: a period-1 cycle at alpha = -0.36 doubles to 2 and 4 as alpha decreases; chaos by -0.42.

    At -0.36 a period-4 cycle coexists with the fixed point (multistability): the
    second initial condition finds it.
    """
    vals = np.array([-0.42, -0.409, -0.39, -0.36])
    ics = [(-0.09, -2.0), (-0.5, -1.0)]
    d = bifurcation_diagram(FIG10, "alpha", vals, points=64, transient=400, ics=ics, seeding="fixed")
    assert d.status_counts() == {"ok": 8}
    per = d.periods()[0]
    assert per[:, 0].tolist() == [0, 4, 2, 1]
    assert per[3, 1] == 4


def test_continuation_seeds_each_value_from_the_previous_final_state() -> None:
    vals = sweep_values((-0.40, -0.38), 3)
    num = Numerics(rtol=1e-9, atol=1e-9)
    d = bifurcation_diagram(FIG10, "alpha", vals, points=20, transient=30, ics=[(-0.5, -1.0)], numerics=num)
    assert d.sweeps.tolist() == ["forward", "backward"]
    # Forward value 1 starts where value 0 ended; backward value 1 where value 2 ended.
    for s, src in ((0, 0), (1, 2)):
        pts, npts, st, fin, _ = bilimovich_orbits(FIG10.with_(alpha=vals[1]), d.final[s, src], 30, 20, num)
        np.testing.assert_array_equal(pts, d.points[s, 1])
        np.testing.assert_array_equal(fin, d.final[s, 1])


def test_invalid_values_are_marked_and_skipped() -> None:
    """I11 below ~0.066 makes the fig. 8 tensor indefinite: marked invalid, the rest computed."""
    vals = np.array([0.0, 0.05, 1.0, 1.2])
    d = bifurcation_diagram(FIG10, "I11", vals, points=5, transient=5, ics=[(-0.5, -1.0)])
    assert d.status[:, :2].ravel().tolist() == [Status.INVALID] * 4
    assert d.valid.tolist() == [False, False, True, True]
    assert "positive definite" in d.errors[0]
    assert np.all(d.status[:, 2:] == Status.OK)
    assert d.summary()["invalid_values"][0]["value"] == 0.0


def test_escaped_trajectories_are_not_drawn(tmp_path) -> None:
    d = bifurcation_diagram(
        FIG10, "alpha", [-0.6, -0.36], points=10, transient=50, ics=[(0.0, 3.0), (-0.5, -1.0)], seeding="fixed",
        numerics=Numerics(bound=50.0),
    )  # fmt: skip
    assert d.status[0, 0, 0] == Status.ESCAPED and d.status[0, 1, 1] == Status.OK
    s, v, val, i, k, q, r = d.long()
    assert not np.any((v == 0) & (i == 0))
    assert np.all(np.isfinite(q)) and k.min() == 51 and k.max() == 60
    path = tmp_path / "b.csv"
    rows = d.to_csv(str(path))
    lines = list(csv.reader(path.open()))
    assert lines[0] == ["sweep", "value_index", "value", "ic", "k", "q", "r", "status"]
    assert len(lines) == rows + 1
    escaped = [row for row in lines[1:] if row[7] == "escaped"]
    assert escaped and all(row[4:7] == ["", "", ""] for row in escaped)
    assert sum(row[7] == "ok" for row in lines[1:]) == q.size


def test_cancel_and_progress() -> None:
    seen = []
    d = bifurcation_diagram(
        FIG10, "alpha", sweep_values((-0.4, -0.36), 40), points=5, transient=5, seeding="fixed",
        progress=seen.append, cancel=lambda: len(seen) >= 3, workers=1, lockstep=False,
    )  # fmt: skip
    # (the contract: progress also gets the last update, the one that carries the diagram)
    assert not d.completed and len(seen) == 4 and seen[-1].total == 40 and seen[-1].result is d
    assert d.status_counts()["not_run"] == 37 and not d.complete and d.lost[0].count == 37
    # In lock-step every value advances together: progress by periods, a cancel leaves nothing drawn.
    seen.clear()
    d = bifurcation_diagram(
        FIG10, "alpha", sweep_values((-0.4, -0.36), 40), points=5, transient=250, seeding="fixed",
        progress=seen.append, cancel=lambda: len(seen) >= 2,
    )  # fmt: skip
    assert not d.completed and len(seen) == 3 and seen[0].done < seen[1].done < 40 and seen[2].result is d
    assert d.status_counts() == {"not_run": 40}


def test_fixed_seeding_in_lockstep_is_the_value_by_value_diagram() -> None:
    """Lock-step blocks of neighbouring values: the same periods and, on cycles, the same points (to 1e-6)."""
    vals = sweep_values((-0.42, -0.35), 24)
    kw = {"points": 64, "transient": 400, "ics": [(-0.09, -2.0), (-0.5, -1.0)], "seeding": "fixed"}
    a = bifurcation_diagram(FIG10, "alpha", vals, lockstep=False, **kw)
    b = bifurcation_diagram(FIG10, "alpha", vals, **kw)
    one = bifurcation_diagram(FIG10, "alpha", vals, workers=1, **kw)  # the blocks do not depend on the threads
    assert np.array_equal(one.points, b.points) and np.array_equal(one.final, b.final)
    assert b.completed and b.status_counts() == a.status_counts() == {"ok": 48}
    pa, pb = a.periods(tol=1e-5), b.periods(tol=1e-5)
    # Other step sequences: a transient that ends within the 400 periods on one of them has not ended on the
    # other (its 64 points show no period yet): at one value with DOP853 (alpha = -0.4017), at two with vern9.
    # Where both show a period it is the same.
    differ = pa != pb
    assert differ.sum() <= 2 and np.all((pa[differ] == 0) | (pb[differ] == 0))
    assert {0, 1, 2, 4} <= set(pa.ravel().tolist())
    for s, v, i in zip(*np.nonzero((pa > 0) & (pa == pb)), strict=True):
        p = int(pa[s, v, i])
        ca, cb = a.points[s, v, i, -p:], b.points[s, v, i, -p:]  # the same cycle, in any phase
        assert np.abs(cb[:, None, :] - ca[None, :, :]).max(axis=2).min(axis=1).max() < 1e-6, (v, i)


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: check_param("beta"), "cannot sweep 'beta'"),
        (lambda: sweep_values((1, 0), 5), "lo < hi"),
        (lambda: sweep_values((0, 1), 0), "n_values"),
        (lambda: bifurcation_diagram(FIG10, "alpha", [0.1], seeding="random"), "seeding must be"),
        (lambda: bifurcation_diagram(FIG10, "alpha", [0.1], sweeps=("up",)), "sweeps must be"),
        (lambda: bifurcation_diagram(FIG10, "alpha", [np.nan]), "finite"),
        (lambda: bifurcation_diagram(FIG10, "alpha", [0.1], points=0), "points must be"),
    ],
)
def test_bad_input_named(call, needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        call()


def test_omega_is_accepted_in_any_case() -> None:
    assert check_param("Omega") == "omega" and check_param("i13") == "I13"


def test_cli(tmp_path) -> None:
    path = tmp_path / "b.csv"
    rc, out, err = run_cli(
        "bifurcation", "--scene", "fig10", "--param", "alpha", "--range", "-0.40,-0.36", "--n-values", "3",
        "--points", "8", "--transient", "20", "--ic", "-0.5,-1", "--out", str(path), "--json",
    )  # fmt: skip
    assert rc == 0, err
    s = json.loads(out)
    assert s["param"] == "alpha" and s["n_values"] == 3 and s["sweeps"] == ["forward", "backward"]
    assert s["status"] == {"ok": 6} and s["out"][0]["rows"] == 6 * 8
    assert len(list(csv.reader(path.open()))) == 1 + 48
    rc, _, err = run_cli("bifurcation", "--param", "beta", "--range", "0,1", "--n-values", "3", "--out", "x.csv")
    assert rc == 2 and "beta" in err


@pytest.mark.parametrize("alpha", [-0.36, -0.39, -0.41, -0.418])
def test_a_settled_transient_gives_the_same_orbit_and_phase(alpha: float) -> None:
    """Continuation sweeps end a transient once the members repeat a cycle (to 1e-9): the recorded points
    are those of the whole transient (the same cycle and phase), and a chaotic orbit runs it all (bit for bit)."""
    p = get_scene("fig10").params.with_(alpha=alpha)
    ics = np.array([[-0.0959, -1.962]])
    num = Numerics(rtol=1e-9, atol=1e-9)
    full = bilimovich_orbits(p, ics, 500, 100, num)
    settled = bilimovich_orbits(p, ics, 500, 100, num, settle=True)
    period = detect_period(full[0][0, 50:], 16, 1e-7)
    if period:
        np.testing.assert_allclose(settled[0], full[0], rtol=0, atol=1e-7)
    else:
        np.testing.assert_array_equal(settled[0], full[0])


def test_repeat_period_is_the_least_period_a_member_repeats() -> None:
    """Each member settles on its own (an escaped or chaotic member no longer holds the others back): the least
    period its last 8 points repeat after (the rule DIAGRAM), at the tolerance asked."""
    from explorer_core.solve.recurrence import DIAGRAM, recurrence

    def repeat_period(x: np.ndarray, tol: float) -> int:
        return int(recurrence(x, DIAGRAM, tol=tol).period)

    cyc2 = np.tile([[0.1, 0.2], [0.3, 0.4]], (16, 1))  # (32, 2)
    cyc3 = np.tile([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]], (11, 1))[:32]
    drift = np.cumsum(np.full((32, 2), 1e-6), axis=0)
    assert repeat_period(cyc2, 1e-9) == 2 and repeat_period(cyc3, 1e-9) == 3
    assert repeat_period(drift, 1e-9) == 0  # still moving: not settled
    assert repeat_period(drift, 1e-3) == 1  # to a loose tolerance it is (Newton's cycle may then be tried)
    assert repeat_period(cyc2[:9], 1e-9) == 0  # fewer than p + 8 points: not yet looked at
    # In a batch, a member that escapes does not keep the other from settling (it did: the batch settled as one).
    p, num = FIG10.with_(alpha=-0.36), Numerics(rtol=1e-10, atol=1e-10)
    alone = bilimovich_orbits(p, np.array([[-0.0959, -1.962]]), 300, 50, num, settle=True)
    pair = bilimovich_orbits(p, np.array([[-0.0959, -1.962], [5.0, 5.0]]), 300, 50, num, settle=True)
    assert pair[2].tolist() == [Status.OK, Status.ESCAPED] and pair[1].tolist() == [50, 0]
    assert pair[4][0].tolist() == alone[4][0].tolist() and pair[4][0, 0] == 1 and pair[4][1].tolist() == [0, 0, 0]
    np.testing.assert_allclose(pair[0][0], alone[0][0], rtol=0, atol=1e-9)


def test_settled_members_agree_with_the_whole_integration_from_the_same_seed() -> None:
    """A continuation sweep stops integrating a member once it is on an attracting cycle (repeated to 1e-9, or
    Newton's cycle that the rest of the transient would reach): from each value's own seed, its points and final
    state are those of the whole integration to 1e-8, and a chaotic member is integrated bit for bit."""
    from explorer_core.analyses.bifurcation import NEWTON_CYCLE, REPEATED

    vals = sweep_values((-0.38, -0.374), 7)
    d = bifurcation_diagram(FIG10, "alpha", vals, points=100, transient=300, ics=[(-0.0959, -1.962)],
                            sweeps=("forward",), numerics=Numerics(rtol=1e-10, atol=1e-10))  # fmt: skip
    how = d.settled[0, :, 0, 2]
    assert NEWTON_CYCLE in how  # started near the previous value's cycle: Newton ends the transient early
    summary = d.summary()["settled"]
    assert summary["newton"] == int(np.count_nonzero(how == NEWTON_CYCLE))
    assert summary["repeated"] == int(np.count_nonzero(how == REPEATED)) and summary["periods_copied"] > 0
    for v in range(1, vals.size):
        p, seed = FIG10.with_(alpha=vals[v]), d.final[0, v - 1]
        full = bilimovich_orbits(p, seed, 300, 100, d.numerics)
        np.testing.assert_array_equal(d.status[0, v], full[2])
        if how[v]:
            np.testing.assert_allclose(d.points[0, v], full[0], rtol=0, atol=1e-8)
            np.testing.assert_allclose(d.final[0, v], full[3], rtol=0, atol=1e-8)
        else:
            np.testing.assert_array_equal(d.points[0, v], full[0])


def test_newtons_cycle_is_taken_only_where_the_transient_would_bring_the_member() -> None:
    """The jump's test: an attracting cycle whose linearised pull over the turns left brings the member within
    SETTLE_TOL / JUMP_SAFETY; not with no turns left, and never a cycle that does not attract."""
    from explorer_core.analyses.bifurcation import _newton_cycles
    from explorer_core.solve.poincare import PoincareMap

    num = Numerics(rtol=1e-10, atol=1e-10)
    on = FIG10.with_(alpha=-0.36)  # period 1, attracting
    pts = bilimovich_orbits(on, np.array([[-0.0959, -1.962]]), 400, 4, num)[0][0]
    assert detect_period(pts, 4, 1e-9) == 1
    x = pts[-1:] + 1e-4
    pmap = PoincareMap.of(on, num)
    near, none_left = _newton_cycles(pmap, np.vstack([x, x]), np.array([1, 1]), np.array([400, 0]))
    assert none_left is None  # 1e-4 away and no turns left: the transient would not have reached it
    np.testing.assert_allclose(near[0], pts[-1], rtol=0, atol=1e-8)
    # Past the first doubling the period-1 orbit repels along the flip direction: Newton finds it, no jump.
    past = FIG10.with_(alpha=-0.38)
    two = bilimovich_orbits(past, np.array([[-0.0959, -1.962]]), 400, 4, num)[0][0]
    assert detect_period(two, 4, 1e-9) == 2
    mid = two[-2:].mean(axis=0, keepdims=True)  # between the two points: near the period-1 saddle
    (repelled,) = _newton_cycles(PoincareMap.of(past, num), mid, np.array([1]), np.array([400]))
    assert repelled is None


def _csv_rows_of_long(d) -> str:
    """The rows of every drawn point from :meth:`OrbitDiagram.long`, each float as its repr (what csv.writer wrote)."""
    s, v, val, i, k, q, r = d.long()
    cols = zip(d.sweeps[s], v.tolist(), val.tolist(), i.tolist(), k.tolist(), q.tolist(), r.tolist(), strict=True)
    return "".join(",".join([a, str(b), repr(c), str(e), str(f), repr(g), repr(h), "ok"]) + "\r\n"
                   for a, b, c, e, f, g, h in cols)  # fmt: skip


def test_csv_formats_each_point_as_before_and_keeps_the_sign_of_zero(tmp_path) -> None:
    # Continuation sweeps settle on cycles (their points repeat: formatted once each); a value of the chaotic band
    # does not. Then 0.0 and -0.0 (equal as floats, not as text) in one trajectory.
    d = bifurcation_diagram(FIG10, "alpha", sweep_values((-0.4, -0.355), 4), points=40, transient=300,
                            ics=[(-0.0959, -1.962), (0.1, 0.1)])  # fmt: skip
    assert d.settled_summary()["periods_copied"] > 0 and d.drawn().all()
    points = d.points.copy()
    points[0, 0, 0, :4] = [[0.0, 1.5], [-0.0, 1.5], [0.0, -0.0], [-0.0, 1.5]]
    d = dataclasses.replace(d, points=points)
    path = tmp_path / "b.csv"
    rows = d.to_csv(str(path))
    text = path.read_bytes().decode()
    assert rows == d.drawn().sum() * d.n_points
    assert text == "sweep,value_index,value,ic,k,q,r,status\r\n" + _csv_rows_of_long(d)
    first = [f"forward,0,-0.4,0,{k},{qr},ok" for k, qr in ((301, "0.0,1.5"), (302, "-0.0,1.5"), (303, "0.0,-0.0"),
                                                            (304, "-0.0,1.5"))]  # fmt: skip
    assert text.split("\r\n")[1:5] == first
