"""Continuation's findings do not depend on incidental inputs (where the range ends, the first step), and
nothing it loses goes unsaid (``complete``, ``lost``, plain numbers in every output)."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from clirun import run_cli

from explorer_core.analyses.continuation import ContinuationOptions, continue_orbit
from explorer_core.scenes import get_scene
from explorer_core.system.params import ParameterError

FIG10 = get_scene("fig10").params
FIXED_POINT_035 = (-0.0959, -1.962)  # the stable fixed point of Fig. 10 at alpha = -0.35
#: The doubling values read off the orbit diagram by bisection (tests/test_continuation.py): an independent check.
DIAGRAM = (-0.375263, -0.406667, -0.411689, -0.412429)
#: Range ends beyond the cascade's fifth doubling (16 -> 32 near alpha = -0.412576). Before this engine, the
#: doubled branch's first step overshot -0.4126 and the branch was dropped (3 doublings instead of 5).
ENDS = (-0.4126, -0.413, -0.42, -0.45)


def doublings(res) -> list[tuple[int, float]]:
    return [(b.period, b.value) for b in res.bifurcations if b.kind == "period_doubling"]


@pytest.fixture(scope="module")
def cascades():
    return {
        end: continue_orbit(FIG10, "alpha", (-0.35, end), FIXED_POINT_035, 1, switch=True, max_period=16)
        for end in ENDS
    }  # fmt: skip


def test_the_five_doublings_do_not_depend_on_where_the_range_ends(cascades) -> None:
    ref = doublings(cascades[-0.42])
    assert [p for p, _ in ref] == [1, 2, 4, 8, 16]
    np.testing.assert_allclose([v for _, v in ref][:4], DIAGRAM, atol=2e-4)
    for end, res in cascades.items():
        found = doublings(res)
        assert [p for p, _ in found] == [1, 2, 4, 8, 16], (end, found)
        np.testing.assert_allclose([v for _, v in found], [v for _, v in ref], rtol=0, atol=1e-8, err_msg=str(end))
        assert [b.kind for b in res.bifurcations] == ["period_doubling"] * 5, (end, res.bifurcations)
        assert [br.period for br in res.branches] == [1, 2, 4, 8, 16]
        # Every branch reaches the range's end (far into the chaotic band too, where the period-16 orbit's
        # multipliers pass 1e5: its branch used to crawl there, 5000 points in 150 s, and stop at -0.4258).
        assert [br.stop for br in res.branches] == ["range end"] * 5, (end, res.lost)
        assert res.complete and not res.lost and res.completed


def test_the_doublings_do_not_depend_on_the_first_step(cascades) -> None:
    ref = doublings(cascades[-0.413])
    for ds in (0.005, 0.06):
        res = continue_orbit(FIG10, "alpha", (-0.35, -0.413), FIXED_POINT_035, 1, switch=True, max_period=16, ds=ds)
        found = doublings(res)
        assert [p for p, _ in found] == [p for p, _ in ref], (ds, found)
        np.testing.assert_allclose([v for _, v in found], [v for _, v in ref], rtol=0, atol=1e-8)
        assert res.complete, res.lost


def test_a_period_two_branch_stops_at_its_birth_and_reports_each_doubling_once(cascades) -> None:
    # From the period-2 orbit at alpha = -0.42 towards -0.35: the branch meets its own doubling (2 -> 4) once,
    # then its birth point, where it collapses onto the period-1 orbit (the first doubling of the cascade).
    # Before this engine it went on through the birth point, along the same orbit back, and reported the
    # 2 -> 4 doubling twice and a fold at the birth point.
    two = cascades[-0.42].branches[1]
    assert two.period == 2 and two.values[-1] == -0.42
    res = continue_orbit(FIG10, "alpha", (-0.42, -0.35), two.states[-1], 2)
    first = doublings(cascades[-0.42])
    assert [(b.kind, b.period) for b in res.bifurcations] == [("period_doubling", 2)]
    assert res.bifurcations[0].value == pytest.approx(first[1][1], abs=1e-8)
    (br,) = res.branches
    assert "collapsed onto a period-1 orbit" in br.stop and "birth" in br.stop, br.stop
    assert br.values[-1] == pytest.approx(first[0][1], abs=1e-7)  # the birth point: the 1 -> 2 doubling
    assert min(br.values) >= -0.42 and max(br.values) <= first[0][1] + 1e-7  # not followed back through it
    assert res.complete and not res.lost


def test_a_branch_lost_to_its_corrector_is_listed() -> None:
    # A corrector asked for more than the map's accuracy fails at every step, down to ds_min.
    opts = ContinuationOptions(ds=0.02, ds_min=0.01, corrector_tol=1e-30, max_iter=3)
    res = continue_orbit(FIG10, "alpha", (-0.35, -0.36), FIXED_POINT_035, 1, options=opts)
    assert not res.complete and res.completed
    (loss,) = res.lost
    assert loss.what.startswith("branch 0 (period 1, from alpha = -0.35")
    assert "did not converge" in loss.why and "ds_min" in loss.why
    assert res.branches[0].stop == loss.why
    d = res.summary()
    assert d["complete"] is False and d["lost"] == [loss.as_dict()]


def test_cancel_returns_what_was_computed_marked_incomplete() -> None:
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 4

    res = continue_orbit(FIG10, "alpha", (-0.35, -0.42), FIXED_POINT_035, 1, switch=True, cancel=cancel)
    assert not res.completed and not res.complete
    assert res.branches and len(res.branches[0].values) >= 2
    assert any(loss.why == "cancelled" for loss in res.lost)


def test_outputs_hold_plain_numbers(tmp_path) -> None:
    out = tmp_path / "b.csv"
    rc, stdout, _ = run_cli("continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.38",
                            "--from=-0.0959,-1.962", "--period", "1", "--switch", "--max-period", "2", "--json",
                            "--out", str(out))  # fmt: skip
    assert rc == 0
    d = json.loads(stdout)
    assert d["complete"] is True and d["lost"] == []
    assert "np." not in stdout and "np." not in out.read_text()
    table = np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(10))  # the points' numbers ...
    assert np.isfinite(table).all()
    rows = [line.split(",")[10:] for line in out.read_text().splitlines()[1:]]  # ... and at a bifurcation its own
    assert sorted(r[0] for r in rows if any(r)) == ["period_doubling"] and all(len(r) == 4 for r in rows)
    assert all(np.isfinite(float(v)) for r in rows if any(r) for v in r[1:3])
    res = continue_orbit(FIG10, "alpha", (-0.35, -0.38), FIXED_POINT_035, 1)
    buf = io.StringIO()
    csv.writer(buf).writerows(res.csv_rows())
    text = json.dumps(res.summary()) + buf.getvalue() + repr(res.csv_rows()) + repr(res.branches[0].states)
    assert "np." not in text
    assert all(type(v) in (int, float) for row in res.csv_rows() for v in row[:10])
    assert all(type(v) in (type(None), str, float) for row in res.csv_rows() for v in row[10:])


@pytest.mark.parametrize(
    ("bad", "name"),
    [({"ds": -1.0}, "ds"), ({"ds_min": float("nan")}, "ds_min"), ({"ds": 0.5, "ds_max": 0.1}, "ds_max"),
     ({"growth": 0.5}, "growth"), ({"shrink": 1.5}, "shrink"), ({"max_points": 1}, "max_points"),
     ({"max_turn": 2.0}, "max_turn"), ({"contraction": "x"}, "contraction")],
)  # fmt: skip
def test_options_name_the_bad_value(bad: dict, name: str) -> None:
    with pytest.raises(ParameterError, match=name):
        ContinuationOptions(**bad)
    if set(bad) <= {"ds", "ds_min", "ds_max", "max_points"}:  # the old keywords of continue_orbit build the options
        with pytest.raises(ParameterError, match=name):
            continue_orbit(FIG10, "alpha", (-0.35, -0.36), FIXED_POINT_035, 1, **bad)


def test_a_two_parameter_curve_ends_on_the_box_even_when_it_starts_on_its_edge() -> None:
    # Fig. 10 has I11 = 1: with range2 = (1, 1.3) the doubling point is on the box's lower edge, and the half
    # of the curve that leaves the box must stop there (not run on outside it).
    for range2 in ((1.0, 1.3), (0.9, 1.3)):
        res = continue_orbit(FIG10, "alpha", (-0.35, -0.39), FIXED_POINT_035, 1, param2="I11", range2=range2)
        (curve,) = res.curves
        rows = np.array(curve.rows)
        assert curve.stop == "range end; range end" and res.complete, (curve.stop, res.lost)
        assert rows[:, 1].min() == range2[0] or rows[:, 0].min() == -0.39  # ends land exactly on an edge
        assert range2[0] <= rows[:, 1].min() and rows[:, 1].max() <= range2[1]
        assert -0.39 <= rows[:, 0].min() and rows[:, 0].max() <= -0.35
