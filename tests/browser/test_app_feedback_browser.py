"""Feedback that stays in view: the plot's toolbar and legend, the orbit table, refusals that go away."""

from __future__ import annotations

import pytest
from harness import set_number, text, wait_finished

pytestmark = pytest.mark.browser

#: Where the section plot's frame (the data area), toolbar and legend are, in page coordinates.
JS_PLOT_BOXES = """() => {
  const find = (v) => v.model.name === 'section_figure' ? v
                      : Array.from(v.child_views || []).map(find).find((x) => x) || null;
  const plot = Object.values(Bokeh.index).map(find).find((x) => x);
  const c = plot.canvas_view.el.getBoundingClientRect();
  const f = plot.frame.bbox;
  const all = [];
  const walk = (root) => {
    for (const e of root.querySelectorAll('*')) { all.push(e); if (e.shadowRoot) walk(e.shadowRoot) }
  };
  walk(document);
  const box = (sel) => all.filter((e) => e.matches(sel)).map((e) => {
    const b = e.getBoundingClientRect(); return {x: b.left, y: b.top, w: b.width, h: b.height} });
  return {frame: {x: c.left + f.left, y: c.top + f.top, w: f.width, h: f.height},
          section: box('.plot-section')[0], toolbar: box('.bk-Toolbar'), legend: box('.bk-Legend')}
}"""


def open_app(page, url: str, query: str = "") -> None:
    page.goto(url + query)
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)


def inside(inner: dict, outer: dict, slack: float = 1.0) -> bool:
    return (inner["x"] >= outer["x"] - slack and inner["y"] >= outer["y"] - slack
            and inner["x"] + inner["w"] <= outer["x"] + outer["w"] + slack
            and inner["y"] + inner["h"] <= outer["y"] + outer["h"] + slack)  # fmt: skip


@pytest.mark.parametrize(("width", "height"), [(1280, 720), (1920, 1080)])
def test_with_orbits_drawn_the_toolbar_legend_and_orbit_table_stay_in_view(browser, app_url, width, height) -> None:
    """Drawing the orbits adds a hover tool to the plot; BokehJS then rebuilt the toolbar below the page and put
    the legend at the canvas corner (8 of 10 loads), and the orbit table was squeezed to 1 px at 1280x720.
    Three loads at each size: every time, the toolbar and the legend are inside the plot and the viewport, and
    the table shows its header and at least three rows."""
    viewport = {"x": 0, "y": 0, "w": width, "h": height}
    for _ in range(3):
        ctx = browser.new_context(viewport={"width": width, "height": height})
        page = ctx.new_page()
        try:
            open_app(page, app_url, "?scene=fig8B&n=20&periods=200&orb_all=1&orb_n=2")
            page.locator(".orbit-table tr").nth(3).wait_for(state="attached", timeout=90_000)
            wait_finished(page)
            page.wait_for_timeout(800)  # a few frames: the plot's layout after the new tools
            boxes = page.evaluate(JS_PLOT_BOXES)
            assert len(boxes["toolbar"]) == 1 and len(boxes["legend"]) == 1, boxes
            toolbar, legend, section = boxes["toolbar"][0], boxes["legend"][0], boxes["section"]
            assert inside(toolbar, section) and inside(toolbar, viewport), boxes
            assert toolbar["h"] > 100, boxes  # its buttons (pan, zoom, reset, save, hover) shown
            assert inside(legend, boxes["frame"]) and inside(legend, viewport), boxes  # in the data area
            table = page.locator(".orbits").bounding_box()
            rows = page.locator(".orbit-table tr").nth(3).bounding_box()
            # The header and three rows at least: the third orbit's row ends inside the table's (scrolled) box. The
            # rows' heights differ in the side column (the multipliers on their own line, wrapped when long).
            assert rows["y"] + rows["height"] <= table["y"] + table["height"] + 1, (table, rows)
            assert inside({"x": table["x"], "y": table["y"], "w": table["width"], "h": table["height"]}, viewport)
        finally:
            ctx.close()


def test_retyping_the_value_in_use_clears_its_refusal(page, app_url) -> None:
    """A refused value puts the value in use back in its box; typing that value again (Enter) answers the
    refusal. The old page sent nothing (the box "had not changed"), so the refusals piled up in the main
    error box."""
    open_app(page, app_url, "?scene=fig1C&n=4&periods=50")
    wait_finished(page)
    refusals = (("I11", "0", "1"), ("n_random", "20000", "4"), ("periods", "", "50"))
    for field, bad, _ in refusals:
        set_number(page, field, bad)
        page.locator(f".ctl-{field} .ctl-msg").wait_for(state="visible", timeout=30_000)
    assert len(text(page, ".main-error").strip().splitlines()) == 3
    for field, _, kept in refusals:  # the values in use, typed again
        set_number(page, field, kept)
        page.locator(f".ctl-{field} .ctl-msg").wait_for(state="hidden", timeout=30_000)
    page.locator(".main-error").wait_for(state="hidden", timeout=30_000)


HOSTILE_QUERIES = (
    "?n=%C2%B2&periods=5",
    "?periods=" + "9" * 5000 + "&n=3",
    "?ics=%5B1,2%5D&n=3&periods=5",
    "?alpha=%7B%22a%22:1%7D&n=3&periods=5",
)


@pytest.mark.parametrize("query", HOSTILE_QUERIES)
def test_a_hostile_url_value_gives_the_normal_page_and_names_its_key(page, app_url, query) -> None:
    """Panel's query parsing raised on these (a blank page and a server traceback; the session fixture fails on
    any traceback in the server's log) or changed their type (``[1,2]`` became a list)."""
    key = query[1:].split("=", 1)[0]
    open_app(page, app_url, query)
    status = wait_finished(page)
    assert "trajectories" in status
    page.locator(".main-error").wait_for(state="visible", timeout=30_000)
    assert f"URL parameter {key}:" in text(page, ".main-error")


def test_in_presentation_mode_at_1280x720_the_orbit_table_shows_without_scrolling(browser, app_url) -> None:
    """The table sat below the fold in presentation mode (its top at y = 775 of 720: the main area had to be
    scrolled). Now it follows the plot directly: its header and three orbits are in the viewport, unscrolled."""
    ctx = browser.new_context(viewport={"width": 1280, "height": 720})
    page = ctx.new_page()
    try:
        open_app(page, app_url, "?scene=fig8B&n=20&periods=200&orb_all=1&orb_n=2&present=1")
        page.locator(".orbit-table tr").nth(3).wait_for(state="attached", timeout=90_000)
        wait_finished(page)
        page.wait_for_timeout(800)
        assert page.locator(".main").evaluate("(e) => e.scrollTop") == 0
        viewport = {"x": 0, "y": 0, "w": 1280, "h": 720}
        for i in range(4):  # the header and three orbits
            b = page.locator(".orbit-table tr").nth(i).bounding_box()
            assert inside({"x": b["x"], "y": b["y"], "w": b["width"], "h": b["height"]}, viewport), (i, b)
        # The plot's legend names the map's orbits apart from the frozen field's equilibria.
        legend = page.evaluate(JS_PLOT_BOXES)["legend"]
        assert len(legend) == 1 and inside(legend[0], viewport)
    finally:
        ctx.close()
