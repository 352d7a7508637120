"""From a click in "finds a periodic orbit" mode to the orbit drawn, in headless Chromium.

    .venv/bin/python benchmarks/orbit_click_latency.py [--repeat 15]

Serves the app warm, opens Fig. 8B with its flip saddle at the centre of the view, and repeats: clear
the orbits, click the centre of the plot's frame, and time in the page from ``pointerup`` to the
animation frame that holds the orbit's marker (Newton from the click for period 1, on the server).
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, served_app, wait_finished
from playwright.sync_api import sync_playwright
from test_app_orbits_browser import CENTRED, JS_ORBIT_PROBE, click_frame_centre


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    times = []
    with served_app() as url, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 720})
        page.goto(url + CENTRED)
        page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=120_000)
        wait_finished(page, timeout=120)
        for _ in range(args.repeat + 1):  # the first is a warm-up
            if page.evaluate("() => Bokeh.documents[0].get_model_by_name('orbits_saddle')?.get_length() > 0"):
                page.locator(".btn-clear-orbits").click()  # enabled only while orbits are shown
            page.wait_for_function(
                "() => (Bokeh.documents[0].get_model_by_name('orbits_saddle')?.get_length() ?? 0) === 0"
            )
            page.wait_for_timeout(300)
            page.evaluate(JS_ORBIT_PROBE)
            click_frame_centre(page)
            page.wait_for_function("() => window.__orbit.drawn !== null", timeout=30_000)
            times.append(page.evaluate("() => window.__orbit.drawn - window.__orbit.t0"))
        browser.close()
    t = sorted(times[1:])
    p90 = t[min(len(t) - 1, int(0.9 * len(t)))]
    print(f"click -> orbit drawn: median {statistics.median(t):.0f} ms, p90 {p90:.0f} ms, max {t[-1]:.0f} ms "
          f"({len(t)} clicks)")  # fmt: skip


if __name__ == "__main__":
    main()
