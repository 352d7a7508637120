"""The app in headless Chromium: what a user does, and what they must see."""

from __future__ import annotations

import time
import urllib.parse

import pytest
from harness import JS_COUNT, box_value, drag_slider, section_q, set_number, text, wait_finished, wait_points, wait_text

pytestmark = pytest.mark.browser
DEFAULT_POINTS = 60 * 500  # fig1C: 60 random ICs x 500 periods
JS_SOURCE = "(name) => Bokeh.documents[0].get_model_by_name(name)"


def open_app(page, url: str, query: str = "") -> None:
    page.goto(url + query)
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=60_000)


def count(page, name: str = "section_source") -> int:
    return page.evaluate(f"(n) => ({JS_SOURCE})(n).get_length()", name)


def query_of(page) -> dict[str, str]:
    return {k: v[-1] for k, v in urllib.parse.parse_qs(urllib.parse.urlparse(page.url).query).items()}


def wait_query(page, key: str, value: str, timeout: float = 30.0) -> None:
    page.wait_for_function(f"() => new URLSearchParams(location.search).get({key!r}) === {value!r}",
                           timeout=timeout * 1000)  # fmt: skip


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
    drag_slider(page, "alpha", 0.6)
    page.wait_for_function(f"() => ({JS_COUNT})() >= {DEFAULT_POINTS} && "
                           "Bokeh.documents[0].get_model_by_name('section_source').data.q[0] !== "
                           f"{before[0]!r}", timeout=60_000)  # fmt: skip
    alpha = float(box_value(page, "alpha"))
    assert alpha > 0.1
    wait_query(page, "scene", "custom")
    assert abs(float(query_of(page)["alpha"]) - alpha) < 1e-9
    assert section_q(page)[:200] != before


def test_click_adds_a_trajectory_selects_and_rings_it(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&n=3&periods=40")
    wait_points(page, 120)
    wait_finished(page)
    canvas = max(page.locator(".plot-section canvas").all(), key=lambda c: c.bounding_box()["width"])
    box = canvas.bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.55, box["y"] + box["height"] * 0.45)
    wait_points(page, 160)
    assert count(page, "ics_source") == 1
    page.wait_for_function("() => (new URLSearchParams(location.search).get('ics') || '').includes(',')")
    status = wait_finished(page)
    assert status.startswith("160 points · 4 trajectories")  # the clicked one counted
    assert box_value(page, "selected") == "3"  # numbered after the 3 random ones (they keep their numbers)
    wait_query(page, "sel", "3")
    page.wait_for_function(f"() => ({JS_SOURCE})('selected_source').get_length() === 40")


def test_choosing_a_scene_sets_the_sliders(page, app_url) -> None:
    open_app(page, app_url)
    wait_points(page, 1)
    page.locator(".ctl-scene select").select_option("fig8B")
    wait_query(page, "scene", "fig8B")
    assert float(box_value(page, "alpha")) == pytest.approx(-0.45)
    assert float(box_value(page, "I13")) == pytest.approx(0.5)
    assert float(box_value(page, "I23")) == pytest.approx(0.3)
    assert int(box_value(page, "transient")) == 100
    assert "Strange attractor" in text(page, ".scene-info")


def test_a_refused_value_shows_the_value_in_use_and_why(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&n=4&periods=50")
    wait_points(page, 200)
    wait_finished(page)
    before = section_q(page)
    set_number(page, "I12", 3)
    msg = page.locator(".ctl-I12 .ctl-msg")
    msg.wait_for(state="visible", timeout=30_000)
    assert "not positive definite" in msg.inner_text() and "I12=3" in msg.inner_text()
    assert "still using I12 = 0" in msg.inner_text()
    assert box_value(page, "I12") == "0"  # the box shows the value in use, not the refused one
    assert "not positive definite" in text(page, ".main-error")  # and the main area says it too
    for field, typed, kept, needle in [("periods", "", "50", "Periods is empty"), ("I11", "nan", "1", "finite"),
                                       ("n_random", "20000", "4", "between 0 and 10000")]:  # fmt: skip
        set_number(page, field, typed)
        page.locator(f".ctl-{field} .ctl-msg").wait_for(state="visible", timeout=30_000)
        assert needle in page.locator(f".ctl-{field} .ctl-msg").inner_text()
        assert box_value(page, field) == kept
    time.sleep(1.0)
    assert section_q(page) == before and "computing" not in text(page, ".status-line")
    assert page.locator(".btn-stop").is_disabled()  # nothing runs
    assert "Traceback" not in page.content()
    set_number(page, "I12", 0.1)
    page.locator(".ctl-I12 .ctl-msg").wait_for(state="hidden", timeout=30_000)
    wait_query(page, "I12", "0.1")


def test_stop_is_enabled_only_while_something_runs(page, app_url) -> None:
    # A long transient at tolerance 1e-12: seconds of work, few points for the browser to draw.
    open_app(page, app_url, "?scene=fig1C&n=40&periods=50&transient=5000&accuracy=high")
    stop = page.locator(".btn-stop")
    page.wait_for_selector(".btn-stop:not([disabled])", timeout=60_000)
    # Stop and the status line are two updates of the page (a layer's job may enable Stop a moment first).
    wait_text(page, ".status-line", "computing", timeout=10)
    stop.click()
    status = wait_finished(page, timeout=30)
    assert "stopped" in status and "computing" not in status
    page.wait_for_selector(".btn-stop[disabled]", timeout=10_000)
    # Nothing is left running: Stop stays disabled, the status stays "stopped".
    page.wait_for_timeout(1500)
    assert stop.is_disabled() and "stopped" in text(page, ".status-line")


def test_shared_url_restores_the_state(page, app_url) -> None:
    q = "?scene=custom&I11=1&I22=2&I33=4&I12=0&I13=0.5&I23=0.3&alpha=-0.4"
    q += "&n=5&periods=50&ics=0.1,-1&seed=3&tprime=period&sel=2"
    open_app(page, app_url, q)
    status = wait_finished(page)
    assert float(box_value(page, "alpha")) == pytest.approx(-0.4)
    assert float(box_value(page, "I13")) == pytest.approx(0.5)
    assert int(box_value(page, "seed")) == 3 and box_value(page, "selected") == "2"
    assert count(page, "ics_source") == 1
    assert "6 trajectories" in status  # 5 random + 1 from the URL
    # Some of these drift off (noncompact motion): listed, and only their valid points drawn.
    assert count(page) == int(status.split(" points")[0].replace(",", ""))
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('tprime_source').get_length() === 1")


def test_bad_url_values_are_reported_as_text(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig1C&alpha=nan&I11=%3Cimg%20src%3Dx%20onerror%3Dalert(1)%3E&n=2&periods=5&I12=9")
    dialogs: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
    page.locator(".main-error").wait_for(state="visible", timeout=30_000)
    msg = text(page, ".main-error")
    assert "URL parameter alpha: α must be finite" in msg and "I11 must be a number" in msg
    assert "not positive definite" in msg
    assert page.locator(".main-error img").count() == 0 and dialogs == []
    wait_points(page, 10)  # the rest of the URL applies


def test_chart_click_sets_the_two_parameters_to_the_pixel_centre(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig11&n=3&periods=30")
    wait_finished(page)
    page.locator(".tab-btn[data-tab=chart]").click()
    wait_query(page, "tab", "chart")
    assert page.locator(".btn-npz").is_disabled()  # no chart yet: nothing to download
    for field, value in (("chart_grid", "6,4"), ("chart_periods", "60"), ("chart_transient", "60")):
        set_number(page, field, value)
    wait_query(page, "ch_grid", "6,4")
    page.locator(".chart-run").click()
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('chart_source').get_length() === 1",
                           timeout=120_000)  # fmt: skip
    canvas = max((c for c in page.locator(".plot-analysis canvas").all() if c.is_visible()),
                 key=lambda c: c.bounding_box()["width"])  # fmt: skip
    box = canvas.bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.3, box["y"] + box["height"] * 0.5)
    wait_query(page, "scene", "custom")
    q = query_of(page)
    alphas = [-0.6 + i * 0.2 / 5 for i in range(6)]  # the chart's 6 x values: a click lands on one
    assert min(abs(float(q["alpha"]) - a) for a in alphas) < 1e-9
    assert 1.0 <= float(q["I11"]) <= 2.0
    page.wait_for_function(f"() => ({JS_SOURCE})('chart_current').data.x[0] === {float(q['alpha'])!r}")
    assert page.locator(".btn-npz").is_enabled()
    page.locator(".tab-btn[data-tab=section]").click()
    assert abs(float(box_value(page, "alpha")) - float(q["alpha"])) < 1e-9


def test_projector_layout_offline_and_quiet(browser, app_url) -> None:
    """1280x720: the section and the k-series in view without scrolling; every request to this server;
    no console error; the wheel scrolls unless the zoom tool is picked; presentation mode in one click."""
    ctx = browser.new_context(viewport={"width": 1280, "height": 720})
    page = ctx.new_page()
    requests: list[str] = []
    problems: list[str] = []
    page.on("request", lambda r: requests.append(r.url))
    page.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(str(e)))
    try:
        open_app(page, app_url)
        wait_points(page, DEFAULT_POINTS)
        wait_finished(page)
        page.locator(".series-q polyline").wait_for(state="attached", timeout=30_000)  # the k-series drawn
        page.wait_for_timeout(500)
        host = urllib.parse.urlparse(app_url).netloc
        # blob: URLs are the page's own in-memory modules, not requests to anywhere.
        outside = [
            u for u in requests if not u.startswith(("blob:", "data:")) and urllib.parse.urlparse(u).netloc != host
        ]
        assert outside == [], outside
        assert problems == [], problems
        # The plots sit inside the viewport, nothing to scroll to.
        for css in (".plot-section", ".plot-series"):
            b = page.locator(css).bounding_box()
            assert b["y"] >= 0 and b["y"] + b["height"] <= 720 and b["height"] > 250, (css, b)
        for key in "qrT":
            b = page.locator(f".series-{key}").bounding_box()
            assert b["y"] + b["height"] <= 720 and b["height"] > 70, (key, b)
        assert page.evaluate("() => document.scrollingElement.scrollHeight <= window.innerHeight + 1")
        # The wheel over the plot does not zoom it (no active scroll tool).
        x0 = page.evaluate("() => Bokeh.documents[0].get_model_by_name('q_range').start")
        b = page.locator(".plot-section").bounding_box()
        page.mouse.move(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2)
        page.mouse.wheel(0, 400)
        page.wait_for_timeout(300)
        assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('q_range').start") == x0
        # Presentation mode: one click, larger fonts, the controls out of the way; and back.
        page.locator(".btn-present").click()
        wait_query(page, "present", "1")
        assert page.locator(".side").evaluate("e => e.getBoundingClientRect().width") < 1
        assert page.locator(".app").evaluate("e => parseFloat(getComputedStyle(e).fontSize)") >= 18
        page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('section_figure')"
                               ".below[0].axis_label_text_font_size === '16pt'")  # fmt: skip
        page.locator(".btn-present").click()
        page.wait_for_function("() => !new URLSearchParams(location.search).has('present')")
        assert page.locator(".side").evaluate("e => e.getBoundingClientRect().width") > 200
    finally:
        ctx.close()
