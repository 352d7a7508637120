"""Screenshots of the tours and of the picture the paper shows (issue 36, items 2 and 4) in docs/screenshots/:

    .venv/bin/python benchmarks/tour_picture_screenshots.py [--out docs/screenshots] [--only tour|picture]

``tour-fig10-step1-bifurcation-1280x720.png`` (Fig. 10's tour at step 1: the orbit diagram its step computed, the
step's text over the tab), ``tour-fig11-step1-chart-presentation-1280x720.png`` (Fig. 11's step 1: the chart its
step computed, presentation mode), ``tour-fig10-step99-presentation-1920x1080.png`` (``step=99``: step 4 and the
message saying so), ``tour-missing-file-1280x720.png`` (``tour_url`` naming no file: the message naming it);
``picture-fig8B-1920x1080.png`` (Fig. 8B with the selected trajectory's thin rings: the attractor visible),
``picture-no-selection-1280x720.png`` (``sel=none``: nothing ringed, the k-series saying why) and
``picture-paused-orbits-1280x720.png`` (Fig. 10's alpha played backward from -0.36, paused once orbits are drawn:
the orbits found while playing kept by the still).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, served_app, wait_finished

#: In-page test: an element ``css`` of the page (in its shadow roots) for which ``test`` (JS of ``e``) holds.
ANY = ("Array.from(document.querySelectorAll('*')).some((h) => {{ const e = h.shadowRoot?.querySelector('{css}');"
       " return !!e && ({test}) }})")  # fmt: skip
#: An analysis tab's run is done and its results are shown.
ANALYSIS_DONE = "() => " + ANY.format(css=".btn-stop-analysis", test="e.disabled") + " && " + ANY.format(
    css=".analysis-result", test="e.children.length > 0")  # fmt: skip
MESSAGE = "() => " + ANY.format(css=".tour-message", test="e.getClientRects().length && e.textContent.trim() !== ''")
#: Periodic orbits drawn: every point of every orbit (the three kinds' sources; none before the layer is built).
JS_ORBITS = """() => ['stable', 'unstable', 'saddle'].reduce((n, k) => {
  const s = Bokeh.documents[0].get_model_by_name('orbits_' + k); return n + (s ? s.get_length() : 0) }, 0)"""
#: Fig. 10's alpha played backward from -0.35 to -0.42 in 8 frames, a frame a second (the orbits layer on).
PLAY = "?scene=fig10&alpha=-0.36&play_from=-0.42&play_to=-0.35&play_n=8&play_fps=1&play_dir=backward"


def _open(browser, url: str, w: int, h: int):
    page = browser.new_page(viewport={"width": w, "height": h})
    page.goto(url)
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)
    return page


def _save(page, out: Path, name: str) -> None:
    time.sleep(1.0)  # a few frames: the figures laid out and drawn
    path = out / name
    page.screenshot(path=str(path))
    print("saved", path)
    page.close()


def tours(browser, url: str, out: Path) -> None:
    for query, (w, h), name in [
        ("?tour=fig10&step=1", (1280, 720), "tour-fig10-step1-bifurcation-1280x720.png"),
        ("?tour=fig11&step=1&present=1", (1280, 720), "tour-fig11-step1-chart-presentation-1280x720.png"),
    ]:
        page = _open(browser, url + query, w, h)
        page.wait_for_function(ANALYSIS_DONE, timeout=600_000)
        _save(page, out, name)
    page = _open(browser, url + "?tour=fig10&step=99&present=1", 1920, 1080)
    page.wait_for_function(MESSAGE, timeout=60_000)
    wait_finished(page, 180)
    _save(page, out, "tour-fig10-step99-presentation-1920x1080.png")
    page = _open(browser, url + "?tour_url=/tours/nope.json&tour=mine", 1280, 720)
    page.wait_for_function(MESSAGE, timeout=60_000)
    wait_finished(page, 180)
    _save(page, out, "tour-missing-file-1280x720.png")


def pictures(browser, url: str, out: Path) -> None:
    for query, (w, h), name in [
        ("?scene=fig8B", (1920, 1080), "picture-fig8B-1920x1080.png"),
        ("?scene=fig8B&sel=none", (1280, 720), "picture-no-selection-1280x720.png"),
    ]:
        page = _open(browser, url + query, w, h)
        wait_finished(page, 180)
        _save(page, out, name)
    page = _open(browser, url + PLAY, 1280, 720)
    wait_finished(page, 180)
    page.locator(".btn-play").first.click()
    page.wait_for_function(f"() => ({JS_ORBITS})() > 0", timeout=180_000)
    # Pause once a frame is drawn whole (Stop disabled), as tests/browser/test_app_picture_browser.py pauses.
    paused = False
    deadline = time.time() + 120
    while not paused and time.time() < deadline:
        paused = page.evaluate(
            """() => { const find = (c) => Array.from(document.querySelectorAll('*'))
                         .map(e => e.shadowRoot?.querySelector(c)).find(b => b);
               if (!find('.btn-stop').disabled) return false; find('.btn-play').click(); return true }"""
        )
        time.sleep(0.02)
    page.wait_for_function("() => " + ANY.format(css=".btn-play", test="/Play/.test(e.textContent)"), timeout=60_000)
    wait_finished(page, 180)
    time.sleep(2.0)  # the still's orbits job (Newton from the orbits shown) has ended and been drawn
    _save(page, out, "picture-paused-orbits-1280x720.png")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/screenshots")
    ap.add_argument("--only", choices=("tour", "picture"), default=None)
    args = ap.parse_args(argv)
    out = Path(args.out)
    from playwright.sync_api import sync_playwright

    with served_app() as url, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        if args.only in (None, "tour"):
            tours(browser, url, out)
        if args.only in (None, "picture"):
            pictures(browser, url, out)
        browser.close()


if __name__ == "__main__":
    main()
