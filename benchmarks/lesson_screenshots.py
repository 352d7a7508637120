"""Screenshots of the lesson features at a projector's size, in presentation mode (docs/):

    .venv/bin/python benchmarks/lesson_screenshots.py [--out docs]

``lesson_tour_WxH.png``: Fig. 8B's tour at step 2 (the flip saddles ringed and labelled, the step's text
over the plot); ``lesson_play_WxH.png``: Fig. 10's alpha played from -0.42 to -0.35, taken while playing; each at
1280x720 and 1920x1080.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, served_app, wait_finished

TOUR = "?tour=fig8B&step=2&present=1"
PLAY = ("?scene=fig10&present=1&orbits=1&orb_all=1&orb_n=2&play_from=-0.42&play_to=-0.35&play_n=30&play_fps=8"
        "&tracks=0")  # fmt: skip


def _says(css: str, pattern: str) -> str:
    return ("() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
            f"/{pattern}/.test(e.shadowRoot.querySelector('{css}')?.textContent || ''))")  # fmt: skip


SIZES = ((1280, 720), (1920, 1080))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs")
    args = ap.parse_args(argv)
    out = Path(args.out)
    from playwright.sync_api import sync_playwright

    with served_app() as url, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        for w, h in SIZES:
            page = browser.new_page(viewport={"width": w, "height": h})
            page.goto(url + TOUR)
            page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)
            wait_finished(page, 120)
            page.wait_for_function(_says(".orbit-status", "periodic orbits of period"), timeout=120_000)
            page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('marks_source')?.get_length() === 2")
            time.sleep(1.5)
            path = out / f"lesson_tour_{w}x{h}.png"
            page.screenshot(path=str(path))
            print("saved", path)

            page.goto(url + PLAY)
            page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)
            wait_finished(page, 120)
            page.wait_for_function(_says(".orbit-status", "periodic orbits of period"), timeout=120_000)
            page.locator(".btn-play").first.click()
            page.wait_for_function(_says(".status-line", r"frame [0-9]+\/30.*frames\/s"), timeout=60_000)
            time.sleep(3.0)
            path = out / f"lesson_play_{w}x{h}.png"
            page.screenshot(path=str(path))
            print("saved", path, page.locator(".status-line").first.inner_text()[:120])
            page.locator(".btn-play").first.click()
            page.close()
        browser.close()


if __name__ == "__main__":
    main()
