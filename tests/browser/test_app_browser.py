"""The app in headless Chromium: what a user does, and what they must see."""

from __future__ import annotations

import time
import urllib.parse

import pytest
from harness import JS_COUNT, section_q, set_number, text, wait_finished, wait_points

pytestmark = pytest.mark.browser
DEFAULT_POINTS = 60 * 500  # fig1C: 60 random ICs x 500 periods


def open_app(page, url: str, query: str = "") -> None:
    page.goto(url + query)
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)


def count(page) -> int:
    return page.evaluate(JS_COUNT)


def query_of(page) -> dict[str, str]:
    return {k: v[-1] for k, v in urllib.parse.parse_qs(urllib.parse.urlparse(page.url).query).items()}


def test_page_loads_and_shows_points(page, app_url) -> None:
    open_app(page, app_url)
    wait_points(page, DEFAULT_POINTS)
    page.wait_for_function("() => !document.title.includes('Loading')")
    page.wait_for_timeout(500)
    assert text(page, ".status-line").startswith("30,000 points · 60 trajectories")
    assert "Traceback" not in page.content()
    assert query_of(page)["scene"] == "fig1C"
    assert page.errors == []


def test_moving_alpha_changes_points_and_url(page, app_url) -> None:
    open_app(page, app_url)
    wait_points(page, DEFAULT_POINTS)
    before = section_q(page)[:200]
    handle = page.locator(".ctl-alpha .noUi-handle").first
    box = handle.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + 40, box["y"] + box["height"] / 2, steps=6)
    page.mouse.up()
    page.wait_for_function(f"() => ({JS_COUNT})() >= {DEFAULT_POINTS} && "
                           "Bokeh.documents[0].get_model_by_name('section_source').data.q[0] !== "
                           f"{before[0]!r}", timeout=60_000)  # fmt: skip
    alpha = float(page.locator(".ctl-alpha input").first.input_value())
    assert alpha > 0.1
    page.wait_for_function("() => new URLSearchParams(location.search).get('scene') === 'custom'")
    assert abs(float(query_of(page)["alpha"]) - alpha) < 1e-9
    assert section_q(page)[:200] != before


def test_click_adds_a_trajectory(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&n=3&periods=40")
    wait_points(page, 120)
    canvas = max(
        page.locator(".bk-Canvas canvas, canvas").all(),
        key=lambda c: c.bounding_box()["width"] * c.bounding_box()["height"],
    )
    box = canvas.bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.55, box["y"] + box["height"] * 0.45)
    wait_points(page, 160)
    assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('ics_source').get_length()") == 1
    page.wait_for_function("() => (new URLSearchParams(location.search).get('ics') || '').includes(',')")
    assert int(page.locator(".ctl-selected input").first.input_value()) == 3


def test_choosing_a_scene_sets_the_sliders(page, app_url) -> None:
    open_app(page, app_url)
    wait_points(page, 1)
    page.locator(".ctl-scene select").select_option("fig8B")
    page.wait_for_function("() => new URLSearchParams(location.search).get('scene') === 'fig8B'", timeout=30_000)
    assert float(page.locator(".ctl-alpha input").first.input_value()) == pytest.approx(-0.45)
    assert float(page.locator(".ctl-I13 input").first.input_value()) == pytest.approx(0.5)
    assert float(page.locator(".ctl-I23 input").first.input_value()) == pytest.approx(0.3)
    assert int(page.locator(".ctl-transient input").first.input_value()) == 100
    assert "Strange attractor" in text(page, ".scene-info")


def test_invalid_tensor_shows_message_and_keeps_last_picture(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&n=4&periods=50")
    wait_points(page, 200)
    before = section_q(page)
    set_number(page, "I12", 3)
    page.locator(".error-box").wait_for(state="visible", timeout=30_000)
    msg = text(page, ".error-box")
    assert "not positive definite" in msg and "I12=3" in msg
    time.sleep(1.0)
    assert section_q(page) == before
    assert "Traceback" not in page.content()
    set_number(page, "I12", 0)
    page.locator(".error-box").wait_for(state="hidden", timeout=30_000)


def test_shared_url_restores_the_state(page, app_url) -> None:
    q = "?scene=custom&I11=1&I22=2&I33=4&I12=0&I13=0.5&I23=0.3&alpha=-0.4"
    q += "&n=5&periods=50&ics=0.1,-1&seed=3&tprime=period"
    open_app(page, app_url, q)
    status = wait_finished(page)
    assert float(page.locator(".ctl-alpha input").first.input_value()) == pytest.approx(-0.4)
    assert float(page.locator(".ctl-I13 input").first.input_value()) == pytest.approx(0.5)
    assert int(page.locator(".ctl-seed input").first.input_value()) == 3
    assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('ics_source').get_length()") == 1
    assert "6 trajectories" in status  # 5 random + 1 from the URL
    # Some of these drift off (noncompact motion): listed, and only their valid points drawn.
    assert count(page) == int(status.split(" points")[0].replace(",", ""))
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('tprime_source').get_length() === 1")


def test_bad_url_values_are_reported_as_text(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&alpha=nan&I11=%3Cimg%20src%3Dx%20onerror%3Dalert(1)%3E&n=2&periods=5")
    dialogs: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
    page.locator(".error-box").wait_for(state="visible", timeout=30_000)
    msg = text(page, ".error-box")
    assert "alpha must be finite" in msg and "I11 must be a number" in msg
    assert page.locator(".error-box img").count() == 0 and dialogs == []
    wait_points(page, 10)


def test_chart_click_sets_the_two_parameters_and_the_section(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig11&n=3&periods=30")
    wait_finished(page)
    page.locator(".bk-tab", has_text="Chart of regimes").first.click()
    for css, value in ((".chart-grid", "6,4"), (".chart-periods", "60"), (".chart-transient", "60")):
        box = page.locator(f"{css} input").first
        box.fill(value)
        box.press("Enter")
    page.locator(".chart-run button").first.click()
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('chart_source').get_length() === 1",
                           timeout=120_000)  # fmt: skip
    visible = [c for c in page.locator("canvas").all() if c.is_visible()]
    canvas = max(visible, key=lambda c: c.bounding_box()["width"] * c.bounding_box()["height"])
    box = canvas.bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.3, box["y"] + box["height"] * 0.5)
    page.wait_for_function("() => new URLSearchParams(location.search).get('scene') === 'custom'", timeout=30_000)
    q = query_of(page)
    assert -0.6 < float(q["alpha"]) < -0.4 and float(q["alpha"]) != -0.5
    assert 1.0 < float(q["I11"]) < 2.0 and float(q["I11"]) != 1.0
    page.locator(".bk-tab", has_text="Poincaré section").first.click()
    assert abs(float(page.locator(".ctl-alpha input").first.input_value()) - float(q["alpha"])) < 1e-3
