"""Latency a user feels: release the alpha slider on the default scene, time the new points in the browser.

    .venv/bin/python benchmarks/app_latency.py [--repeat 15]

Serves the app (warm, as `bilimovich serve` does), opens it in headless Chromium and
drags the alpha slider repeatedly, pausing --settle-ms between releases. For each release it
measures, in the page, from the
`pointerup` event to the first animation frame that holds new section points, and to the
frame that holds the full default scene (60 ICs x 500 periods). Prints medians and p90.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))

from harness import (
    CHROMIUM,
    CHROMIUM_ARGS,
    JS_INSTALL_PROBE,
    JS_READ_PROBE,
    drag_slider,
    served_app,
    wait_finished,
    wait_points,
)

DEFAULT_POINTS = 30_000


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--settle-ms", type=int, default=1500, help="pause between releases")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    first, full = [], []
    with served_app("/tmp/app_latency_panel.log") as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        wait_points(page, DEFAULT_POINTS, timeout=120)
        wait_finished(page)
        for i in range(args.repeat):
            # A person looks at the result before moving the slider again; the late layers
            # (T' map, tracks) finish drawing meanwhile.
            page.wait_for_timeout(args.settle_ms)
            page.evaluate(JS_INSTALL_PROBE, DEFAULT_POINTS)
            drag_slider(page, "alpha", 0.53 + 0.04 * (i % 5))
            page.wait_for_function("() => window.__probe.full !== null", timeout=60_000)
            pr = page.evaluate(JS_READ_PROBE)
            first.append(pr["first"] - pr["t0"])
            full.append(pr["full"] - pr["t0"])
            wait_finished(page)
        browser.close()

    def q(xs: list[float], f: float) -> float:
        return sorted(xs)[min(len(xs) - 1, int(f * len(xs)))]

    out = {
        "repeats": args.repeat,
        "settle_ms": args.settle_ms,
        "first_points_ms": {"median": round(statistics.median(first), 1), "p90": round(q(first, 0.9), 1)},
        "full_scene_ms": {"median": round(statistics.median(full), 1), "p90": round(q(full, 0.9), 1)},
        "all_first_ms": [round(x, 1) for x in first],
        "all_full_ms": [round(x, 1) for x in full],
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
