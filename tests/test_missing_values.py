"""What was not measured is missing in every file (NaN in NPZ, ``nan`` or an empty field in CSV), never a number.

Before issue 35 the chart wrote an escaped pixel's exponent as 0.0 and a chaotic pixel's period as 0, and the
T' map an uncomputed cell's value as 0: a mean over the file took them in silently.
"""

from __future__ import annotations

import numpy as np
import pytest

from explorer_core.analyses import regimes as rg
from explorer_core.analyses.tprime import TPrimeMap
from explorer_core.scenes import get_scene
from explorer_core.status import Status
from explorer_core.system.params import Params

FIG11 = get_scene("fig11").params
IC = (-0.09, -2.0)


def _read_csv(path) -> np.ndarray:
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")


def _handmade_chart() -> rg.Chart:
    """A pixel of every regime in row 0 (row 1 not computed), one IC: what each file cell must say is known without
    running anything."""
    spec = rg.chart_spec(FIG11, "alpha", (-0.42, -0.36), "I11", (1.0, 2.0), (8, 2), ics=[IC], transient=10, periods=40)
    chart = rg.Chart.empty(spec)
    cells = [  # regime, period, lyap as computed (the engine's arrays hold 0 where nothing was measured), status
        (rg.PERIODIC, 3, -0.05, Status.OK),
        (rg.CHAOTIC, 0, 0.04, Status.OK),
        (rg.QUASI_PERIODIC, 0, 1e-4, Status.OK),
        (rg.ESCAPED, 0, 0.0, Status.ESCAPED),
        (rg.FAILED, 0, 0.0, Status.STEP_COLLAPSED),
        (rg.INVALID, 0, 0.0, Status.INVALID),
        (rg.PERIODIC, 2, -0.07, Status.OK),  # filled from its neighbour (a refined chart)
    ]
    for i, (regime, period, lyap, status) in enumerate(cells):
        chart.regime[0, i, 0], chart.period[0, i, 0], chart.lyap[0, i, 0] = regime, period, lyap
        chart.status[0, i, 0] = status
        chart.computed[0, i] = True
    chart.inferred[0, 6] = True  # pixel 7 (the last) is not computed: regime not_computed, status not_run
    chart.completed = True
    return chart


EXPECTED_PERIOD = [3, np.nan, np.nan, np.nan, np.nan, np.nan, 2, np.nan]
EXPECTED_LYAP = [-0.05, 0.04, 1e-4, np.nan, np.nan, np.nan, np.nan, np.nan]


def test_the_charts_npz_holds_nan_where_nothing_was_measured(tmp_path) -> None:
    chart = _handmade_chart()
    path = tmp_path / "c.npz"
    chart.write(str(path))
    with np.load(path) as z:
        np.testing.assert_array_equal(z["period"][0, :, 0], EXPECTED_PERIOD)
        np.testing.assert_array_equal(z["lyap"][0, :, 0], EXPECTED_LYAP)
        assert z["period"].dtype.kind == "f" and np.nanmin(z["period"]) >= 1  # never a period 0
    # The chart in memory is unchanged (the app draws from it).
    assert chart.period[0, 1, 0] == 0 and chart.lyap[0, 3, 0] == 0.0


def test_the_charts_csv_leaves_the_field_empty_where_nothing_was_measured(tmp_path) -> None:
    chart = _handmade_chart()
    path = tmp_path / "c.csv"
    assert chart.write(str(path))["rows"] == 7  # the computed pixels
    t = _read_csv(path)
    np.testing.assert_array_equal(t["period"], EXPECTED_PERIOD[:7])
    np.testing.assert_array_equal(t["lyap"], EXPECTED_LYAP[:7])
    assert t["inferred"].tolist() == [0, 0, 0, 0, 0, 0, 1]
    assert t["regime"].tolist()[3:6] == ["escaped", "failed", "invalid"]
    lines = path.read_text().splitlines()
    assert lines[4].split(",")[6:8] == ["nan", "nan"]  # the escaped pixel: no period, no exponent


def test_a_computed_chart_writes_no_zero_for_its_escaped_and_chaotic_pixels(tmp_path) -> None:
    spec = rg.chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (1.0, 2.0), (6, 5), ics=[IC], transient=60, periods=40,
                      p_max=8)  # fmt: skip
    chart = rg.regime_chart(spec, workers=1)
    escaped, chaotic = chart.regime == rg.ESCAPED, chart.regime == rg.CHAOTIC
    assert escaped.any() and chaotic.any()
    chart.write(str(tmp_path / "c.npz"))
    chart.write(str(tmp_path / "c.csv"))
    with np.load(tmp_path / "c.npz") as z:
        assert np.all(np.isnan(z["lyap"][escaped])) and np.all(np.isnan(z["period"][~(chart.regime == rg.PERIODIC)]))
        np.testing.assert_array_equal(z["lyap"][chaotic], chart.lyap[chaotic])
        np.testing.assert_array_equal(
            z["period"][chart.regime == rg.PERIODIC], chart.period[chart.regime == rg.PERIODIC]
        )
    t = _read_csv(tmp_path / "c.csv")
    assert np.all(np.isnan(t["lyap"][t["regime"] == "escaped"])) and np.all(
        np.isnan(t["period"][t["regime"] != "periodic"])
    )
    assert np.all(np.isfinite(t["lyap"][t["regime"] == "chaotic"]))


def test_the_tprime_npz_holds_nan_where_no_value_was_computed(tmp_path) -> None:
    values = np.array([[0.5, 0.0], [-0.25, 0.0]])
    ok = np.array([[True, True], [True, False]])
    status = np.where(ok, int(Status.OK), int(Status.ESCAPED)).astype(np.int8)
    tmap = TPrimeMap("per-period", 0.0, np.array([0.0, 1.0]), np.array([0.0, 1.0]), values, ok, status, Params(), 0.0)
    tmap.write(str(tmp_path / "t.npz"))
    with np.load(tmp_path / "t.npz") as z:
        np.testing.assert_array_equal(z["values"], [[0.5, 0.0], [-0.25, np.nan]])  # a true 0 stays 0
        np.testing.assert_array_equal(z["sign"], [[1, 0], [-1, np.nan]])


@pytest.mark.parametrize("name", ["period", "lyap"])
def test_the_app_shows_missing_values_as_missing(name: str) -> None:
    pytest.importorskip("holoviews")
    from app.holo import draw_chart

    img = draw_chart(_handmade_chart())
    col = {"period": "period", "lyap": "Λ1"}[name]
    got = np.asarray(img.dimension_values(col), dtype=float)
    want = np.asarray({"period": EXPECTED_PERIOD, "lyap": EXPECTED_LYAP}[name], dtype=float)
    np.testing.assert_array_equal(np.sort(got[np.isfinite(got)]), np.sort(want[np.isfinite(want)]))
    assert np.isnan(got).sum() == got.size - np.isfinite(want).sum()  # row 1 (not computed) too


# --- reproduce's table: numbers in their own columns, and error bars that cover -----------------------------


def _tricky_reproduction():
    from explorer_core.studies.reproduce import SIZES, Reproduction, Row

    rep = Reproduction(SIZES["tiny"])
    rep.rows += [
        Row("Fig. 4A", "Lambda_1", 0.022, 0.0213, 8.2e-4, "2 members, 300 periods", "per unit time, (x 2 pi)"),
        Row("Fig. 10", "period doubling 1 -> 2: alpha", ours=-0.375344, uncertainty=4.6e-7, paper_text="figure only"),
        Row("Fig. 11", "cascade 1-2-4-8", paper_text="present", ours_text='only 1-2, "4"', note="# of px: 3"),
        Row("Fig. 4A", "Lambda_1", 0.022, ours_text="no chaotic IC found", settings="a, b"),
    ]
    return rep


def test_the_reproduction_table_reads_back_with_numeric_columns(tmp_path) -> None:
    rep = _tricky_reproduction()
    rep.write_table(str(tmp_path / "t.md"), str(tmp_path / "t.csv"))
    t = np.genfromtxt(tmp_path / "t.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert t.shape == (4,)
    for name in ("paper", "ours", "uncertainty"):
        assert t[name].dtype.kind == "f", name
    np.testing.assert_array_equal(t["paper"], [0.022, np.nan, np.nan, 0.022])
    np.testing.assert_array_equal(t["ours"], [0.0213, -0.375344, np.nan, np.nan])
    np.testing.assert_array_equal(t["uncertainty"], [8.2e-4, 4.6e-7, np.nan, np.nan])
    assert t["ours_text"][2] == "only 1-2; '4'" and t["settings"][3] == "a; b"
    assert "+-" not in (tmp_path / "t.csv").read_text()
    md = (tmp_path / "t.md").read_text()  # the Markdown table is for reading: +- and the words
    assert "| 0.022 | 0.0213 | +-8.2e-04 |" in md and "| figure only | -0.3753 | +-4.6e-07 |" in md


def test_every_stages_rows_are_numbers(tmp_path) -> None:
    from explorer_core.studies.reproduce import reproduce

    rep = reproduce("tiny", stages=("lyapunov",))
    rep.write_table(str(tmp_path / "t.md"), str(tmp_path / "t.csv"))
    t = np.genfromtxt(tmp_path / "t.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert t.shape == (len(rep.rows),) and all(t[n].dtype.kind == "f" for n in ("paper", "ours", "uncertainty"))
    l1 = t[(t["figure"] == "Fig. 8B") & (t["quantity"] == "Lambda_1")][0]
    assert l1["paper"] == 0.082 and l1["ours"] > 0 and l1["uncertainty"] > 0


@pytest.mark.parametrize(
    ("p", "seed_alpha", "lo", "hi"),
    [(1, -0.37, -0.3745, -0.3760), (2, -0.40, -0.4064, -0.4072), (1, -0.37, -0.3740, -0.3750)],
    ids=["1->2", "2->4", "1->2, both ends before the doubling"],
)
def test_the_bisected_doubling_brackets_the_continuations(p: int, seed_alpha: float, lo: float, hi: float) -> None:
    """The bisection's error bar covers the doubling found by continuation (pseudo-arclength, the test function
    ``det(DP^p + I)``: another algorithm). Before, its verdict was the period read off a finite transient and it
    stopped short of the doubling (here by 2e-4 after 400 periods), and a starting bracket from the orbit
    diagram's periods (read the same way) that did not contain the doubling was taken as it was."""
    from explorer_core.analyses.bifurcation import bilimovich_orbits
    from explorer_core.analyses.continuation import continue_orbit
    from explorer_core.analyses.orbits import find_orbits
    from explorer_core.solve.numerics import Numerics
    from explorer_core.studies.reproduce import FIG10_IC, _doubling

    fig10 = get_scene("fig10").params
    start = fig10.with_(alpha=seed_alpha)
    orbit = next(o for o in find_orbits(start, [FIG10_IC, (-0.2, -2.0)], [p]).orbits if o.period == p and o.stable)
    cont = continue_orbit(start, "alpha", (seed_alpha, hi - 0.002), orbit.points[0], p, switch=False, max_period=p)
    flip = next(b for b in cont.bifurcations if b.kind == "period_doubling" and b.period == p)
    num = Numerics(rtol=1e-10, atol=1e-10)
    seed = bilimovich_orbits(fig10.with_(alpha=lo), orbit.points[:1], 400, 1, num)[3]
    a, b = _doubling(fig10, lo, hi, seed, p, 10, 400, num)
    assert min(a, b) <= flip.value <= max(a, b)
    assert abs(b - a) == pytest.approx(abs(hi - lo) / 2**10)  # and tight: ten halvings of the start's width
