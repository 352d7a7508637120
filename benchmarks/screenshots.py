"""The screenshots in docs/: the explorer in headless Chromium at a projector's and a desktop's size.

    .venv/bin/python benchmarks/screenshots.py [--out docs]

Serves the app and saves ``app_1280x720.png`` (Fig. 8B, the default layout on a projector),
``app_1280x720_presentation.png`` (the same in presentation mode), ``app_1920x1080.png`` and
``app_chart_1280x720.png`` (a small chart of regimes of Fig. 11 with the current parameters marked) and
``app_manifolds_fig8B.png`` (Fig. 8B's attractor with the flip saddle's manifolds and homoclinic points,
1280x720), each after the scene, its layers and the k-series are drawn.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import CHROMIUM, CHROMIUM_ARGS, served_app, wait_finished

LAYERS_DRAWN = (
    "() => { const d = Bokeh.documents[0]; const n = (m) => d.get_model_by_name(m).get_length();"
    " return n('tprime_source') === 1 && n('tracks_source') > 0; }"
)


#: Fig. 8B with the flip saddle's manifolds to arc length 20 (the orbit layer finds the saddle from its seed).
MANIFOLDS = "?scene=fig8B&orb=-0.0377,-2.3979&orb_n=1&man=-0.0377,-2.3979,1&man_len=20&click=manifolds&tracks=0"
MANIFOLDS_DRAWN = (
    "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
    "/homoclinic points/.test(e.shadowRoot.querySelector('.manifold-status')?.textContent || ''))"
)


def shoot(
    browser,
    url: str,
    size: tuple[int, int],
    path: Path,
    *,
    present: bool = False,
    chart: bool = False,
    manifolds: bool = False,
) -> None:
    ctx = browser.new_context(viewport={"width": size[0], "height": size[1]})
    page = ctx.new_page()
    query = "?scene=fig11&n=4&periods=300&ch_grid=40,24&ch_n=200&ch_tr=200&tab=chart" if chart else "?scene=fig8B"
    query = MANIFOLDS if manifolds else query
    page.goto(url + query + ("&present=1" if present else ""))
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=120_000)
    wait_finished(page, timeout=120)
    if chart:
        page.locator(".chart-run").click()
        page.wait_for_function("() => /pixels:/.test(document.body.innerText) || Array.from("
                               "document.querySelectorAll('*')).some(e => e.shadowRoot && "
                               "/pixels:/.test(e.shadowRoot.textContent))", timeout=300_000)  # fmt: skip
    elif manifolds:
        page.wait_for_function(MANIFOLDS_DRAWN, timeout=120_000)
    else:
        page.wait_for_function(LAYERS_DRAWN, timeout=120_000)
    page.wait_for_timeout(1500)  # the last paint
    page.screenshot(path=str(path))
    ctx.close()
    print(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"))
    ap.add_argument("--only", choices=["manifolds"], help="only this screenshot")
    args = ap.parse_args()
    out = Path(args.out)
    from playwright.sync_api import sync_playwright

    with served_app("/tmp/screenshots_panel.log") as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        if not args.only:
            shoot(browser, url, (1280, 720), out / "app_1280x720.png")
            shoot(browser, url, (1280, 720), out / "app_1280x720_presentation.png", present=True)
            shoot(browser, url, (1920, 1080), out / "app_1920x1080.png")
            shoot(browser, url, (1280, 720), out / "app_chart_1280x720.png", chart=True)
        shoot(browser, url, (1280, 720), out / "app_manifolds_fig8B.png", manifolds=True)
        shoot(browser, url, (1920, 1080), Path("/tmp") / "app_manifolds_1920x1080.png", manifolds=True)
        browser.close()


if __name__ == "__main__":
    main()
