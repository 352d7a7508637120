"""The screenshots in docs/: the explorer in headless Chromium at a projector's and a desktop's size.

    .venv/bin/python benchmarks/screenshots.py [--out docs]

Serves the app and saves ``app_1280x720.png`` (Fig. 8B, the default layout on a projector),
``app_1280x720_presentation.png`` (the same in presentation mode), ``app_1920x1080.png`` and
``app_chart_1280x720.png`` (a small chart of regimes of Fig. 11 with the current parameters marked) and
the phase-plane layers at 1280x720: ``app_manifolds_fig8B.png`` (Fig. 8B's attractor with the flip
saddle's manifolds and homoclinic points), ``app_basins_fig11.png`` (the basins of Fig. 11's coexisting
cycles at alpha = -0.5, I11 = 1.6) and ``app_density_fig8B.png`` (10^6 points of Fig. 8B as a density
image), each after the scene, its layers and the k-series are drawn (``--only layers``: just these).
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


def _says(css: str, pattern: str) -> str:
    """In-page probe: the component's element ``css`` shows text matching ``pattern``."""
    return ("() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
            f"/{pattern}/.test(e.shadowRoot.querySelector('{css}')?.textContent || ''))")  # fmt: skip


MANIFOLDS_DRAWN = _says(".manifold-status", "homoclinic points")
BASINS = "?scene=fig11&alpha=-0.5&I11=1.6&n=4&periods=300&basins=1&bas_n=120&tprime=off&tracks=0"
BASINS_DRAWN = _says(".basin-status", "basins on")
DENSITY = "?scene=fig8B&n=1000&periods=1000&render=density&tprime=off&tracks=0"
DENSITY_DRAWN = _says(".status-line", "density image")
#: The phase-plane layers: (query, what to wait for).
LAYERS = {
    "manifolds": (MANIFOLDS, MANIFOLDS_DRAWN),
    "basins": (BASINS, BASINS_DRAWN),
    "density": (DENSITY, DENSITY_DRAWN),
}


def shoot(
    browser,
    url: str,
    size: tuple[int, int],
    path: Path,
    *,
    present: bool = False,
    chart: bool = False,
    layer: str | None = None,
) -> None:
    ctx = browser.new_context(viewport={"width": size[0], "height": size[1]})
    page = ctx.new_page()
    query = "?scene=fig11&n=4&periods=300&ch_grid=40,24&ch_n=200&ch_tr=200&tab=chart" if chart else "?scene=fig8B"
    query = LAYERS[layer][0] if layer else query
    page.goto(url + query + ("&present=1" if present else ""))
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=120_000)
    wait_finished(page, timeout=300)
    if chart:
        page.locator(".chart-run").click()
        page.wait_for_function("() => /pixels:/.test(document.body.innerText) || Array.from("
                               "document.querySelectorAll('*')).some(e => e.shadowRoot && "
                               "/pixels:/.test(e.shadowRoot.textContent))", timeout=300_000)  # fmt: skip
    elif layer:
        page.wait_for_function(LAYERS[layer][1], timeout=300_000)
    else:
        page.wait_for_function(LAYERS_DRAWN, timeout=120_000)
    page.wait_for_timeout(1500)  # the last paint
    page.screenshot(path=str(path))
    ctx.close()
    print(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"))
    ap.add_argument("--only", choices=["layers"], help="only the phase-plane layers' screenshots")
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
        shoot(browser, url, (1280, 720), out / "app_manifolds_fig8B.png", layer="manifolds")
        shoot(browser, url, (1280, 720), out / "app_basins_fig11.png", layer="basins")
        shoot(browser, url, (1280, 720), out / "app_density_fig8B.png", layer="density")
        browser.close()


if __name__ == "__main__":
    main()
