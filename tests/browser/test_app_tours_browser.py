"""Guided tours on a projector's 1280x720 screen (issue 36, item 2): every step of every tour shows its text, the
tour's title, "step i of n", Back, Next and the close button in the viewport, on top and above the plot of whatever
tab the step opens (Fig. 10's and Fig. 11's first steps open an analysis tab, where none of it was shown), in normal
and presentation mode; a link's step the tour does not have, and a tours file that is not there, are said on the
page (naming the value, the file)."""

from __future__ import annotations

import json

import pytest
from harness import ROOT, new_page, text, wait_finished
from test_app_browser import open_app, query_of

pytestmark = pytest.mark.browser

TOURS = json.loads((ROOT / "app" / "tours.json").read_text(encoding="utf-8"))["tours"]
#: Small analyses for the steps that press Run (a tour's scene sets their ranges; these stay from the link).
SMALL = "&bif_n=6&bif_pts=5&bif_tr=20&bif_orb=0&ch_grid=4,3&ch_n=20&ch_tr=20&ch_curves=0"
VIEWPORT = {"width": 1280, "height": 720}

#: The tour's parts in the page (one shadow root): each one's box, whether it is the element on top at its centre
#: (nothing covers it), its text; the open tab's plot box, the tour box's bottom, and the main area's scroll.
JS_TOUR_BOXES = """() => {
  const host = Array.from(document.querySelectorAll('*')).find((e) => e.shadowRoot &&
                                                               e.shadowRoot.querySelector('.tour'))
  const root = host.shadowRoot
  const box = (e) => { const b = e.getBoundingClientRect(); return {x: b.left, y: b.top, w: b.width, h: b.height} }
  const parts = {}
  for (const sel of ['.tour-text', '.tour-count', '.tour .tour-choice', '.btn-tour-back', '.btn-tour-next',
                     '.btn-tour-close']) {
    const e = root.querySelector(sel)
    if (!e) { parts[sel] = null; continue }
    const b = box(e)
    const hit = root.elementFromPoint(b.x + b.w / 2, b.y + b.h / 2)
    parts[sel] = {...b, top: !!hit && (hit === e || e.contains(hit)), text: e.tagName === 'SELECT' ?
                  e.options[e.selectedIndex]?.text : e.textContent, hidden: !e.getClientRects().length}
  }
  const tab = root.querySelector('.tab-btn[aria-selected="true"]').dataset.tab
  return {parts, tab, tour: box(root.querySelector('.tour')), scroll: root.querySelector('.main').scrollTop,
          plot: box(root.querySelector(tab === 'section' ? '.plot-section' : '.plot-analysis'))}
}"""


def in_view(b: dict, slack: float = 1.0) -> bool:
    """Whether a box (x, y, w, h) is not empty and inside the viewport."""
    right, bottom = b["x"] + b["w"], b["y"] + b["h"]
    inside = b["x"] >= -slack and b["y"] >= -slack and right <= VIEWPORT["width"] + slack
    return inside and bottom <= VIEWPORT["height"] + slack and b["w"] > 0 and b["h"] > 0


def wait_step(page, i: int, n: int, words: str) -> None:
    """Wait until the page shows step ``i`` of ``n`` with the step's text."""
    page.wait_for_function(
        """([count, words]) => Array.from(document.querySelectorAll('*')).some((e) => e.shadowRoot &&
             e.shadowRoot.querySelector('.tour-count')?.textContent === count &&
             e.shadowRoot.querySelector('.tour-text')?.textContent === words)""",
        arg=[f"step {i} of {n}", words],
        timeout=60_000,
    )


@pytest.fixture
def screen(browser):
    """A page at a projector's 1280x720."""
    pg = new_page(browser, VIEWPORT["width"], VIEWPORT["height"])
    yield pg
    pg.context.close()


@pytest.mark.parametrize("present", [False, True], ids=["normal", "presentation"])
def test_every_step_of_every_tour_shows_its_text_and_buttons_in_view(screen, app_url, present: bool) -> None:
    """One page walks every tour (chosen in the tour's menu) with Next; at each step the text, title, count, Back,
    Next and close are inside the 1280x720 viewport, unscrolled and uncovered, above the open tab's plot."""
    page = screen
    open_app(page, app_url, f"?tour={TOURS[0]['id']}&step=1{'&present=1' if present else ''}{SMALL}")
    for t, tour in enumerate(TOURS):
        if t:
            page.locator(".tour .tour-choice").select_option(tour["id"])
        steps = tour["steps"]
        for i, step in enumerate(steps, 1):
            wait_step(page, i, len(steps), step["text"])
            tab = step["settings"].get("tab", "section")
            page.wait_for_function(  # the step's tab is the one shown
                f"""() => Array.from(document.querySelectorAll('*')).some((e) => e.shadowRoot &&
                      e.shadowRoot.querySelector('.tab-btn[aria-selected="true"]')?.dataset.tab === {tab!r})"""
            )
            got = page.evaluate(JS_TOUR_BOXES)
            where = (tour["id"], i, "presentation" if present else "normal")
            assert got["tab"] == tab and got["scroll"] == 0, (where, got["tab"], got["scroll"])
            for sel, part in got["parts"].items():
                assert part and not part["hidden"] and in_view(part) and part["top"], (where, sel, part)
            assert got["parts"][".tour .tour-choice"]["text"] == tour["title"], where
            # The tour's box is above the tab's plot, not over it.
            assert got["tour"]["y"] + got["tour"]["h"] <= got["plot"]["y"] + 1, (where, got["tour"], got["plot"])
            assert page.locator(".btn-tour-back").is_disabled() == (i == 1), where
            assert page.locator(".btn-tour-next").is_disabled() == (i == len(steps)), where
            if i < len(steps):
                page.locator(".btn-tour-next").click()
    assert query_of(page)["tour"] == TOURS[-1]["id"] and query_of(page)["step"] == str(len(TOURS[-1]["steps"]))
    assert not page.errors


@pytest.mark.parametrize(
    ("step", "shown", "words", "present"),
    [("99", 4, "there is no step 99", False), ("0", 1, "there is no step 0", True),
     ("abc", 1, "'abc' is not a step number", False)],
)  # fmt: skip
def test_a_step_the_tour_does_not_have_opens_the_nearest_and_says_so(screen, app_url, step, shown, words,
                                                                     present) -> None:  # fmt: skip
    page = screen
    open_app(page, app_url, f"?tour=fig10&step={step}{'&present=1' if present else ''}{SMALL}")
    fig10 = next(t for t in TOURS if t["id"] == "fig10")
    wait_step(page, shown, 4, fig10["steps"][shown - 1]["text"])
    msg = page.locator(".tour-message")
    msg.wait_for(state="visible", timeout=30_000)
    said = text(page, ".tour-message")
    assert f"URL parameter step: {words}" in said and f"showing step {shown}" in said, said
    b = msg.bounding_box()
    assert in_view({"x": b["x"], "y": b["y"], "w": b["width"], "h": b["height"]}), b
    assert query_of(page)["step"] == str(shown)
    assert not page.errors


def test_a_missing_tours_file_is_named_not_taken_for_a_missing_tour(screen, app_url) -> None:
    page = screen
    open_app(page, app_url, "?tour_url=/tours/nope.json&tour=mine&present=1")
    msg = page.locator(".tour-message")
    msg.wait_for(state="visible", timeout=30_000)
    said = text(page, ".tour-message")
    assert "no tours file '/tours/nope.json'" in said and "no tour 'mine'" not in said, said
    b = msg.bounding_box()
    assert in_view({"x": b["x"], "y": b["y"], "w": b["width"], "h": b["height"]}), b
    # The page works on, with the paper's tours (and nothing computes when the server stops after the last test).
    assert "trajectories" in wait_finished(page, timeout=120)
    assert page.locator("header .tour-choice option[value=fig8B]").count() == 1
    assert not page.errors
