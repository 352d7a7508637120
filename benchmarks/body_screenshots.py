"""Screenshots of the body in 3-D in presentation mode (docs/), and what the page measures while it plays:

    .venv/bin/python benchmarks/body_screenshots.py [--out docs] [--scene fig8B]

``lesson_body_1280x720.png`` and ``lesson_body_1920x1080.png``: the scene's section with the body view open
(``body=1&present=1``), taken after the body has turned for a few seconds (the trace of the largest axis drawn so
far, the section point of the period shown starred). Prints the client's frames per second and the payload's size
(the status line under the view).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, served_app, text, wait_finished

SIZES = ((1280, 720), (1920, 1080))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs")
    ap.add_argument("--scene", default="fig8B")
    ap.add_argument("--seconds", type=float, default=6.0, help="how long the body turns before the picture")
    args = ap.parse_args(argv)
    out = Path(args.out)
    from playwright.sync_api import sync_playwright

    with served_app() as url, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        for w, h in SIZES:
            page = browser.new_page(viewport={"width": w, "height": h})
            page.goto(f"{url}?scene={args.scene}&body=1&present=1")
            page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)
            wait_finished(page, 180)
            page.wait_for_function("() => window.bilimovichBody && bilimovichBody.frames > 0", timeout=120_000)
            page.evaluate("() => bilimovichBody.seek(0)")
            time.sleep(args.seconds)
            hook = "() => [bilimovichBody.fps, bilimovichBody.frame, bilimovichBody.frames]"
            fps, frame, frames = page.evaluate(hook)
            path = out / f"lesson_body_{w}x{h}.png"
            page.screenshot(path=str(path))
            print(f"saved {path}: frame {frame}/{frames}, {fps:.1f} frames/s in the client;",
                  text(page, ".body-status"))  # fmt: skip
            page.close()
        browser.close()


if __name__ == "__main__":
    main()
