"""The FTLE layer in the browser: turned on from its control, drawn under the section points with its colour bar, in
the URL; the selected trajectory's Birkhoff verdict after its caption. A 1280x720 screenshot is saved for the docs."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness import new_page, wait_finished
from test_app_browser import count, open_app, query_of

pytestmark = pytest.mark.browser
SHOT = Path(__file__).resolve().parents[2] / "docs" / "screenshots" / "ftle-1280x720.png"
#: Names of the section plot's renderers, bottom to top.
JS_RENDERERS = "() => Bokeh.documents[0].get_model_by_name('section_figure').renderers.map((r) => r.name)"
JS_SHADOW = ("(css) => Array.from(document.querySelectorAll('*')).map((e) => e.shadowRoot?.querySelector(css))"
             ".find((x) => x)?.textContent || ''")  # fmt: skip


def test_the_ftle_layer_is_drawn_under_the_points_from_its_control(browser, app_url) -> None:
    page = new_page(browser, 1280, 720)
    try:
        open_app(page, app_url, "?scene=fig8B&n=20&periods=200&transient=50&ics=-1,-2&sel=20")
        wait_finished(page, timeout=120)
        assert "ftle_image" not in page.evaluate(JS_RENDERERS) and "ftle" not in query_of(page)  # off at first
        page.locator(".ctl-ftle select").first.select_option("forward")
        page.wait_for_function(f"() => /FTLE forward over 20 periods on 40 x 40 pixels: .* s/.test(({JS_SHADOW})"
                               "('.ftle-status'))", timeout=180_000)  # fmt: skip
        assert count(page, "ftle_source") == 1
        names = page.evaluate(JS_RENDERERS)
        assert names.index("ftle_image") < names.index("section_points")  # the image under the points
        assert query_of(page)["ftle"] == "forward"
        assert page.locator(".btn-ftle-npz").first.is_visible()
        # the colour key spans the values the status line gives (the final map's, not a partial one's)
        low, high = page.evaluate("() => { const m = Bokeh.documents[0].get_model_by_name('ftle_mapper');"
                                  " return [m.low, m.high] }")  # fmt: skip
        words = page.evaluate(JS_SHADOW, ".ftle-status").split("pixels: ")[1].split(" per unit time")[0]
        assert [f"{v:.3g}" for v in (low, high)] == words.split(" to "), (low, high, words)
        # the verdict on the selected trajectory (the clicked one, on the attractor: chaotic) after its caption
        page.wait_for_function(f"() => /chaotic \\(Birkhoff/.test(({JS_SHADOW})('.series-caption'))",
                               timeout=120_000)  # fmt: skip
        page.wait_for_timeout(500)  # the image painted
        SHOT.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SHOT))
        assert page.errors == []
    finally:
        page.context.close()
