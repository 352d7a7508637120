"""Play a parameter and the guided tours in the browser (issue 23): frames advance while playing and stop on
Pause; a tour's steps change the settings and the URL, with the buttons and the arrow keys."""

from __future__ import annotations

import time

import pytest
from harness import text, wait_finished
from test_app_browser import open_app, query_of, wait_query

pytestmark = pytest.mark.browser

PLAY = "?scene=fig10&n=20&periods=100&tracks=0&tprime=off&play_from=-0.42&play_to=-0.35&play_n=15&play_fps=8"


def click(page, css: str) -> None:
    page.locator(css).first.click()


def alpha_box(page) -> float:
    return float(page.locator("#c-alpha").first.input_value())


def test_frames_advance_while_playing_and_stop_on_pause(page, app_url) -> None:
    open_app(page, app_url, PLAY)
    wait_finished(page)
    start = alpha_box(page)
    click(page, ".btn-play")
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/frames\\/s/.test(e.shadowRoot.querySelector('.play-status')?.textContent || ''))",
        timeout=60_000,
    )
    seen = set()
    deadline = time.time() + 20
    while time.time() < deadline and len(seen) < 4:
        seen.add(round(alpha_box(page), 6))
        time.sleep(0.05)
    assert len(seen) >= 4, seen  # the slider follows the frames
    assert "Pause" in text(page, ".btn-play")
    click(page, ".btn-play")  # Pause
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/Play/.test(e.shadowRoot.querySelector('.btn-play')?.textContent || ''))",
        timeout=30_000,
    )
    time.sleep(0.5)
    paused = alpha_box(page)
    time.sleep(1.5)
    assert alpha_box(page) == paused  # stopped
    assert float(query_of(page)["alpha"]) == paused and len(seen | {start}) >= 4
    assert not page.errors


def test_a_tours_steps_change_the_settings_and_the_url(page, app_url) -> None:
    open_app(page, app_url, "?tour=fig8B&step=1&n=10&periods=100")
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/strange attractor/.test(e.shadowRoot.querySelector('.tour-text')?.textContent || ''))",
        timeout=60_000,
    )
    click(page, ".btn-tour-next")
    wait_query(page, "step", "2")
    assert query_of(page)["orb_all"] == "1" and query_of(page)["tour"] == "fig8B"
    page.wait_for_function(
        "() => (Bokeh.documents[0].get_model_by_name('marks_source')?.get_length() || 0) === 2", timeout=30_000
    )
    page.locator("body").click(position={"x": 5, "y": 5})  # the keys go to the page, not a box
    page.keyboard.press("ArrowRight")
    wait_query(page, "step", "3")
    assert query_of(page)["man"].startswith("-0.03766")
    page.keyboard.press("ArrowLeft")
    page.keyboard.press("ArrowLeft")
    wait_query(page, "step", "1")
    assert "orb_all" not in query_of(page)
    assert not page.errors
