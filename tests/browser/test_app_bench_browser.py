"""The speed tab in the browser: a bench run that compared the chaos indicators offers their chart (issue 34), which
replaces the work-precision diagram when chosen. A 1280x720 screenshot is saved for the docs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from harness import new_page, served_app
from test_app_browser import count, open_app

pytestmark = pytest.mark.browser
ROOT = Path(__file__).resolve().parents[2]
#: The full comparison (benchmarks/indicators_speed.py --n 20 --reference 5000), as docs/indicators.md draws it.
REPORT = ROOT / "docs" / "figures" / "indicators.json"
SHOT = ROOT / "docs" / "screenshots" / "bench-indicators-1280x720.png"
JS_VISIBLE = "(name) => Bokeh.documents[0].get_model_by_name(name).visible"
JS_SHADOW = ("(css) => Array.from(document.querySelectorAll('*')).map((e) => e.shadowRoot?.querySelector(css))"
             ".find((x) => x)?.textContent || ''")  # fmt: skip


def test_the_indicators_chart_is_offered_and_drawn(browser, tmp_path) -> None:
    report = json.loads(REPORT.read_text())
    path = tmp_path / "bench.json"
    path.write_text(json.dumps({"cases": {}, "rows": [], "config": {"label": "docs"}, "indicators": report}))
    with served_app(str(tmp_path / "panel.log"), env={"BILIMOVICH_BENCH_RESULTS": str(path)}) as url:
        page = new_page(browser, 1280, 720)
        try:
            open_app(page, url, "?tab=bench")
            choice = page.locator(".bench-choice").first
            choice.wait_for(state="visible", timeout=60_000)
            page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('bench_indicator_lines')",
                                   timeout=60_000)  # fmt: skip
            choice.select_option("latest bench run (docs): chaos indicators")
            page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('bench_indicator_lines').get_length()"
                                   " === 6", timeout=60_000)  # fmt: skip
            # per set: every rung of every indicator and the reference
            rungs = sum(len(v) for v in report["ladders"].values())
            assert count(page, "bench_indicator_points") == len(report["sets"]) * (rungs + 1)
            assert page.evaluate(JS_VISIBLE, "bench_indicators") and not page.evaluate(
                JS_VISIBLE, "bench_work_precision"
            )
            page.wait_for_timeout(800)
            said = page.evaluate(JS_SHADOW, ".analysis-result")
            assert "Chaos indicators against a Lyapunov exponent over 5000 periods" in said, said
            SHOT.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(SHOT))
            assert page.errors == []
        finally:
            page.context.close()
