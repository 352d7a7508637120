"""Tabs of a real browser opening the explorer together: time to the page and to the first points.

    .venv/bin/python benchmarks/browser_class.py [--tabs 10] [--procs 2] [--single 5] [--json out.json]

Serves the app warm, then (1) a single visitor: ``--single`` times, a fresh headless-Chromium
context navigates to the page, alone; (2) a class: ``--tabs`` contexts navigate at the same moment.
Each tab reports, in the page's own clock (milliseconds since its navigation started): when the
Bokeh document is there (the page is built and sent), and when the section's first points are in
its data. The browser runs on the same cores as the server (here: two), so a class of tabs also
measures the browsers' own work; the websocket benchmark (``load_test.py``) takes the browsers out.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, serve

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from explorer_core.config import resolve_procs

#: Returns performance.now() (ms since navigation) once the condition holds.
DOC_READY = "() => (window.Bokeh && Bokeh.documents.length > 0) ? performance.now() : false"
FIRST_POINTS = (
    "() => { const d = window.Bokeh && Bokeh.documents[0];"
    " const s = d && d.get_model_by_name('section_source');"
    " return (s && s.get_length() > 0) ? performance.now() : false; }"
)


async def visit(browser: Any, url: str, timeout_s: float = 180.0) -> dict[str, float]:
    ctx = await browser.new_context(viewport={"width": 1280, "height": 720})
    try:
        page = await ctx.new_page()
        await page.goto(url, wait_until="commit", timeout=timeout_s * 1000)
        doc = await (await page.wait_for_function(DOC_READY, timeout=timeout_s * 1000)).json_value()
        first = await (await page.wait_for_function(FIRST_POINTS, timeout=timeout_s * 1000)).json_value()
        return {"page_ms": float(doc), "first_points_ms": float(first)}
    finally:
        await ctx.close()


def _stats(xs: list[float]) -> dict[str, float]:
    s = sorted(xs)
    p95 = s[min(len(s) - 1, round(0.95 * (len(s) - 1)))]
    return {"n": len(s), "p50": round(statistics.median(s)), "p95": round(p95), "max": round(s[-1])}


async def measure(url: str, tabs: int, single: int) -> dict[str, Any]:
    from playwright.async_api import async_playwright

    async with async_playwright() as p:
        browser = await p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        for _ in range(3):  # warm: kernels, each worker's template page, the browser's caches
            await asyncio.gather(*(visit(browser, url) for _ in range(2)))
        alone = [await visit(browser, url) for _ in range(single)]
        await asyncio.sleep(2.0)
        together = await asyncio.gather(*(visit(browser, url) for _ in range(tabs)))
        await browser.close()
    return {
        "single_visitor": {k: _stats([r[k] for r in alone]) for k in ("page_ms", "first_points_ms")},
        f"{tabs}_tabs_together": {k: _stats([r[k] for r in together]) for k in ("page_ms", "first_points_ms")},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tabs", type=int, default=10)
    ap.add_argument("--single", type=int, default=5, help="single-visitor navigations")
    ap.add_argument("--procs", default="1", help="server processes (bilimovich serve --procs; 'auto')")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args()
    procs = resolve_procs(args.procs)
    with serve("/tmp/browser_class_panel.log", procs=procs) as server:
        report = asyncio.run(measure(server.url, args.tabs, args.single))
    report.update(procs=procs, command=" ".join(sys.argv))
    text = json.dumps(report, indent=1)
    if args.json:
        Path(args.json).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
