"""A long section in the browser: drawn as a density image, recomputed for a zoomed view."""

from __future__ import annotations

import pytest
from harness import frame_centre, text, wait_finished
from test_app_browser import count, open_app, query_of

pytestmark = pytest.mark.browser


def test_a_long_section_is_a_density_image_that_a_zoom_recomputes(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig8B&n=600&periods=800&tracks=0")  # 480,000 points: auto -> density
    wait_finished(page, timeout=120)
    assert count(page, "density_source") == 1 and count(page, "section_source") == 0
    assert "points as a density image" in text(page, ".status-line")
    before = page.evaluate("() => Bokeh.documents[0].get_model_by_name('density_source').data.x[0]")
    # Pan by dragging (the default tool): the new ranges reach the server, which recomputes the image for them.
    f = frame_centre(page)
    page.mouse.move(f["x"], f["y"])
    page.mouse.down()
    page.mouse.move(f["x"] + 60, f["y"] + 40, steps=8)
    page.mouse.up()
    page.wait_for_function(f"() => Bokeh.documents[0].get_model_by_name('density_source').data.x[0] !== {before!r}",
                           timeout=60_000)  # fmt: skip
    wait_finished(page, timeout=120)
    x0 = page.evaluate("() => Bokeh.documents[0].get_model_by_name('density_source').data.x[0]")
    start = page.evaluate("() => Bokeh.documents[0].get_model_by_name('q_range').start")
    assert x0 == pytest.approx(start) and x0 < before  # dragged right: the view moved left
    assert "points as a density image" in text(page, ".status-line")
    assert float(query_of(page)["qr"].split(",")[0]) == pytest.approx(start)
    assert page.errors == []
