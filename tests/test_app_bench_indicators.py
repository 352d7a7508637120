"""The speed tab's chart of the chaos indicators (issue 34): each indicator's agreement with a long Lyapunov run
against the periods it was given, drawn from a bench run's ``indicators``
(:mod:`explorer_core.studies.indicator_bench`).
"""

from __future__ import annotations

import json

import pytest

from app.bench_tab import (
    FOOTNOTE,
    INDICATOR_COLOURS,
    INDICATOR_FOOTNOTE,
    INDICATORS,
    LATEST,
    MEASURED,
    SET_DASH,
    BenchTab,
)
from app.controller import ExplorerSession
from app.runner import WARM, InlineExecutor, Runner
from app.state import ExplorerState
from explorer_core.studies import bench
from explorer_core.studies.indicator_bench import measure

#: A small comparison: 3 ICs a set, a 300-period reference, two rungs per indicator.
LADDERS = {"birkhoff": (50, 100), "sali": (25, 50), "ftle": (25, 100)}


@pytest.fixture(scope="module")
def report() -> dict:
    return json.loads(json.dumps(measure(3, 300, 1, LADDERS)))  # as bench.json holds it


def _tab(tmp_path) -> BenchTab:
    WARM.set()
    st = ExplorerState(scene="fig1C")
    st.param.update(n_random=2, periods=10)
    sess = ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor()))
    return BenchTab(sess, results_path=str(tmp_path / "none.json"), cache_dir=str(tmp_path))


def test_the_chart_is_drawn_from_the_comparisons_numbers(tmp_path, report: dict) -> None:
    tab = _tab(tmp_path)
    tab.figure()
    labels = tab.add_dataset({"cases": {}, "rows": [], "indicators": report}, LATEST)
    assert labels == [f"{LATEST}: {INDICATORS}"]
    assert tab.choose(labels[0]) is None
    assert tab.indicators.visible and not tab.work_precision.visible
    assert tab.view["footnote"] == INDICATOR_FOOTNOTE  # not the work-precision diagram's line styles
    lines, pts = tab.indicator_lines.data, tab.indicator_points.data
    n = report["n"]
    assert len(lines["xs"]) == len(report["sets"]) * len(LADDERS)
    for set_name, entry in report["sets"].items():
        for name, ladder in LADDERS.items():
            label = f"{name} ({set_name})"
            i = lines["label"].index(label)
            # periods an orbit was given: Birkhoff averages two halves of each rung's length
            assert lines["xs"][i] == [(2 if name == "birkhoff" else 1) * k for k in ladder]
            rungs = entry["indicators"][name]["rungs"]
            assert lines["ys"][i] == [100.0 * (n - wrong - undecided) / n for _, wrong, undecided in rungs]
            assert lines["color"][i] == INDICATOR_COLOURS[name] and lines["dash"][i] == SET_DASH[set_name]
            at = [j for j, lab in enumerate(pts["label"]) if lab == label]
            assert [pts["seconds"][j] for j in at] == entry["seconds"][name] and all(
                s > 0 for s in entry["seconds"][name]
            )
            assert [pts["wrong"][j] for j in at] == [w for _, w, _ in rungs]
        ref = pts["label"].index(f"Lyapunov reference ({set_name})")
        assert (pts["x"][ref], pts["y"][ref], pts["seconds"][ref]) == (300, 100.0, entry["reference_s"])
    # SALI decides Fig. 8B's attractor in 10-13 periods (docs/indicators.md): every IC agrees at its first rung
    assert lines["ys"][lines["label"].index("sali (chaotic)")][0] == 100.0
    said = tab.view["result"]
    assert said[0].startswith("Chaos indicators against a Lyapunov exponent over 300 periods")
    assert any(line.startswith("chaotic (reference ") and "sali all from 25 periods" in line for line in said)


def test_the_work_precision_diagram_comes_back_and_a_run_without_indicators_offers_no_chart(tmp_path, report) -> None:
    tab = _tab(tmp_path)
    tab.figure()
    data = {"cases": {"regular": {"ic": [0.1, 0.2], "horizon": 5, "k_max": 5, "reference_bound": 1e-12}},
            "rows": [], "indicators": report}  # fmt: skip
    labels = tab.add_dataset(data, LATEST)
    assert labels == [f"{LATEST}: regular", f"{LATEST}: {INDICATORS}"]
    tab.choose(labels[1])
    tab.choose(labels[0])
    assert tab.work_precision.visible and not tab.indicators.visible and tab.view["footnote"] == FOOTNOTE
    assert tab.view["result"][0].startswith("regular (custom), IC (0.1, 0.2)")
    assert tab.add_dataset({**data, "indicators": {}}, MEASURED) == [MEASURED]
    assert bench.app_config().indicators is False  # the tab's own Measure never runs the comparison
