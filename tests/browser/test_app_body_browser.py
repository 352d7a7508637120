"""The body in 3-D in the browser (issue 23, item 3; issue 36, item 4): the view draws, its frames advance while
playing and stop on pause, at >= 30 frames per second at every offered speed beside the default section's 30,000
points (>= 20 in the small scene: margin for a loaded machine), the section point of the period shown is highlighted
in the section plot, and the orientation the page holds after N periods matches an independent solve_ivp integration
of the naive field with R' = R [omega]_x (tests/test_app_body.py)."""

from __future__ import annotations

import importlib.util
import time
from pathlib import Path

import numpy as np
import pytest
from harness import wait_finished
from test_app_browser import open_app, query_of

pytestmark = pytest.mark.browser

BODY = "?scene=fig1C&n=6&periods=100&tracks=0&tprime=off&orbits=0&accuracy=high&body=1"
HOOK = "window.bilimovichBody"


def _reference():
    path = Path(__file__).resolve().parents[1] / "test_app_body.py"
    spec = importlib.util.spec_from_file_location("app_body_reference", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def body(page, expr: str):
    return page.evaluate(f"() => {HOOK}.{expr}")


def open_body(page, app_url: str, query: str = BODY) -> None:
    open_app(page, app_url, query)
    wait_finished(page, 120)
    page.wait_for_function(f"() => {HOOK} && {HOOK}.frames > 0", timeout=120_000)


def drawn_pixels(page) -> int:
    """Pixels of the body's canvas that are not the white background."""
    return page.evaluate(
        """() => {
          const host = Array.from(document.querySelectorAll('*')).find(e => e.shadowRoot &&
                       e.shadowRoot.querySelector('canvas.body-canvas'));
          const c = host.shadowRoot.querySelector('canvas.body-canvas');
          const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
          let n = 0;
          for (let i = 0; i < d.length; i += 4) if (d[i] < 235 || d[i + 1] < 235 || d[i + 2] < 235) n++;
          return n;
        }"""
    )


def click_body(page, css: str) -> None:
    page.locator(f".body-view {css}").first.click()


def test_the_body_view_draws_animates_at_30_fps_and_stops_on_pause(page, app_url) -> None:
    sent: list[str] = []  # messages from the page to the server
    page.on("websocket", lambda ws: ws.on("framesent", lambda payload: sent.append(str(payload)[:200])))
    open_body(page, app_url)
    assert query_of(page)["body"] == "1"
    assert drawn_pixels(page) > 5000  # the sphere, the body, the axes, omega, the trace, the labels
    assert body(page, "frames") == 20 * 48 + 1 and body(page, "playing")
    page.locator(".body-view .body-speed").first.select_option("1")  # a period a second (48 recorded frames)
    page.wait_for_function(f"() => {HOOK}.speed === 1", timeout=10_000)  # in use once the server has it
    time.sleep(0.5)
    before, f0, p0 = len(sent), body(page, "position"), body(page, "period")
    time.sleep(2.5)
    f1 = body(page, "position")
    assert f1 > f0  # frames advance while playing
    assert body(page, "period") > p0  # a new period: its section point moved in the plot...
    assert sent[before:] == []  # ... and nothing went to the server, per frame or per period
    fps = body(page, "fps")
    print(f"client frames per second: {fps:.1f}")
    assert fps >= 20
    click_body(page, ".body-play")  # Pause
    assert not body(page, "playing")
    paused = body(page, "position")
    time.sleep(1.0)
    assert body(page, "position") == paused
    click_body(page, ".body-step")
    assert body(page, "frame") == round(paused) + 1
    # Dragging turns the view (paused: the body's orientation stays, the picture changes).
    still = page.locator(".body-view canvas").first.screenshot()
    box = page.locator(".body-view canvas").first.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2 + 80, box["y"] + box["height"] / 2 + 30, steps=6)
    page.mouse.up()
    page.wait_for_timeout(200)
    assert page.locator(".body-view canvas").first.screenshot() != still
    assert body(page, "frame") == round(paused) + 1 and not body(page, "playing")
    assert not page.errors


#: The page a class opens (the default scene's 30,000 section points) with the body view open.
FULL = "?body=1"
#: Frames per second over a few seconds at each speed: the wall clock's rate of the page's animation frames.
JS_RATE = """(secs) => new Promise((done) => {
  const hook = window.bilimovichBody, t = [], d0 = hook.draws, k0 = hook.period
  let moves = 0, k = k0
  const tick = (now) => {
    t.push(now)
    if (hook.period !== k) { moves++; k = hook.period }
    if (now - t[0] < secs * 1000) { requestAnimationFrame(tick); return }
    const gaps = t.slice(1).map((x, i) => x - t[i]).sort((a, b) => a - b)
    done({fps: 1000 * (t.length - 1) / (t[t.length - 1] - t[0]), draws: hook.draws - d0, moves,
          longest: gaps[gaps.length - 1], hookFps: hook.fps})
  }
  requestAnimationFrame(tick)
})"""


def test_the_body_runs_at_30_fps_at_every_offered_speed_beside_a_full_section(page, app_url) -> None:
    # Issue 36, item 4. The highlighted section point moves each period; it was on the section's glyph level, so
    # each move repainted the plot's 30,000 points (0.5-1.2 s in headless Chromium): 2-3 frames/s at 2 and 4
    # periods/s (13-16 at 1) on the code before, 55-60 with the point on the overlay level (load 7-10 on 2 cores).
    # The machine is shared: a speed under 30 frames/s is measured once more (a neighbour's burst can stall the
    # browser for a second; the old code's stall comes every period, and fails both times).
    open_body(page, app_url, FULL)
    assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('section_source').get_length()") >= 30_000
    speeds = [float(v) for v in page.locator(".body-view .body-speed option").evaluate_all(
        "(os) => os.map((o) => o.value)")]  # fmt: skip
    assert speeds == [0.05, 0.1, 0.25, 0.5, 1, 2, 4]  # every speed offered (app/body.js's SPEEDS)
    rates = {}
    for v in speeds:
        page.locator(".body-view .body-speed").first.select_option(f"{v:g}")
        page.wait_for_function(f"() => {HOOK}.speed === {v}", timeout=10_000)
        for _ in range(2):
            page.wait_for_timeout(300)
            r = page.evaluate(JS_RATE, 3)
            if r["fps"] >= 30:
                break
        rates[v] = r
        print(f"{v:g} periods/s: {r['fps']:.1f} frames/s, {r['draws']} drawn, longest frame {r['longest']:.0f} ms, "
              f"{r['moves']} moves of the section point")  # fmt: skip
        assert body(page, "playing")
        # The section point still follows the period shown (not bought by moving it less).
        if v >= 0.5:
            assert r["moves"] >= 1
        page.wait_for_function(
            f"() => {{ const p = {HOOK}.point(), d = Bokeh.documents[0].get_model_by_name('body_source').data;"
            " return p !== null && d.q.length === 1 && d.q[0] === p[0] && d.r[0] === p[1] }",
            timeout=10_000,
        )
    slow = {v: round(r["fps"], 1) for v, r in rates.items() if r["fps"] < 30}
    assert not slow, f"under 30 frames/s at (periods/s: frames/s) {slow}"
    assert not page.errors


def test_the_period_shown_is_highlighted_on_the_section_and_the_orientation_matches_an_independent_integration(
    page, app_url
) -> None:
    open_body(page, app_url)
    click_body(page, ".body-play")  # Pause, then go to the start of the 10th period of the series
    n = 10
    samples = body(page, "samples")
    page.evaluate(f"() => {HOOK}.seek({n * samples})")
    page.wait_for_function(f"() => {HOOK}.period === {n}", timeout=10_000)
    q, r, k = body(page, "point()")
    k0 = body(page, "k0")
    assert k == k0 + n
    # The highlighted point is in the section plot (the page wrote it there, no message to the server), and it is
    # the selected trajectory's point k of the section (the body computed at 1e-10, the section at 1e-12).
    src = page.evaluate("() => { const d = Bokeh.documents[0].get_model_by_name('body_source').data;"
                        " return [Array.from(d.q), Array.from(d.r)] }")  # fmt: skip
    assert src == [[q], [r]]
    sel = int(query_of(page)["sel"])
    pts = page.evaluate(
        """([sel, k]) => { const d = Bokeh.documents[0].get_model_by_name('section_source').data;
           const out = []; for (let i = 0; i < d.q.length; i++) if (d.traj[i] === sel && d.k[i] === k)
           out.push([d.q[i], d.r[i]]); return out }""",
        [sel, k0],
    )
    assert len(pts) == 1
    start = page.evaluate(f"() => [{HOOK}.quaternion(0), {HOOK}.quaternion({n * samples})]")
    assert np.allclose(start[0], [1, 0, 0, 0], atol=1e-7)  # the identity at the series' start
    ref = _reference()
    from app.state import state_from_query

    params = state_from_query({"scene": "fig1C"})[0].system()
    qr, rot = ref.ivp_orientation(params, tuple(pts[0]), n)
    err = np.max(np.abs(ref.rotation_of(np.array(start[1])) - rot[-1]))
    print(f"orientation after {n} periods: max |R_page - R_solve_ivp| = {err:.2e}")
    assert err < 1e-6
    assert abs(q - qr[-1][0]) < 1e-6 and abs(r - qr[-1][1]) < 1e-6
    assert not page.errors


def test_closing_the_view_drops_the_series_and_its_point(page, app_url) -> None:
    open_body(page, app_url)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('body_source').get_length() === 1")
    page.locator(".series-head .ctl-show_body input").first.click()
    page.wait_for_function(f"() => {HOOK}.frames === 0", timeout=30_000)
    assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('body_source').get_length()") == 0
    page.wait_for_function("() => !new URLSearchParams(location.search).has('body')", timeout=30_000)
    # The k-series are back in its place, drawn.
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "e.shadowRoot.querySelector('.series-q polyline'))",
        timeout=30_000,
    )
    assert not page.errors


def test_a_link_with_the_body_views_settings_opens_the_view_with_them(page, app_url) -> None:
    # A system a box has (moments 1, 3, 3), drawn as the ellipsoid, at 2 periods a second, tracing axis 1.
    query = BODY.replace("scene=fig1C", "scene=fig1C&I22=3&I33=3") + "&body_v=2&body_axis=1&body_shape=ellipsoid"
    open_body(page, app_url, query)
    assert (body(page, "speed"), body(page, "traceAxis"), body(page, "shape")) == (2, 1, "ellipsoid")
    bar = page.locator(".body-view .body-bar").first
    shown = [bar.locator(f"select.{c}").input_value() for c in ("body-speed", "body-trace-axis", "body-shape")]
    assert shown == ["2", "0", "ellipsoid"]  # the trace's select counts axes from 0 (its option 'axis 1')
    assert {k: query_of(page).get(k) for k in ("body_v", "body_axis", "body_shape")} == {
        "body_v": "2", "body_axis": "1", "body_shape": "ellipsoid"}  # fmt: skip
    # Chosen in the bar: in use once the server has it, and in the URL.
    bar.locator("select.body-shape").select_option("box")
    page.wait_for_function(f"() => {HOOK}.shape === 'box'", timeout=10_000)
    page.wait_for_function("() => !new URLSearchParams(location.search).has('body_shape')", timeout=10_000)
    bar.locator("select.body-trace-axis").select_option("2")
    page.wait_for_function(f"() => {HOOK}.traceAxis === 3", timeout=10_000)
    page.wait_for_function("() => !new URLSearchParams(location.search).has('body_axis')", timeout=10_000)
    assert not page.errors


def test_a_box_no_body_has_is_refused_under_the_bar_and_the_ellipsoid_stays(page, app_url) -> None:
    open_body(page, app_url)  # fig1C: moments 1, 2, 4, no box
    bar = page.locator(".body-view .body-bar").first
    assert bar.locator("select.body-shape").input_value() == "ellipsoid" and body(page, "shape") == "ellipsoid"
    bar.locator("select.body-shape").select_option("box")
    msg = page.locator(".body-view .body-msg").filter(has_text="no uniform box").first
    msg.wait_for(timeout=10_000)
    assert "no uniform box has the principal moments 1, 2, 4" in msg.inner_text()
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "e.shadowRoot.querySelector('select.body-shape')?.value === 'ellipsoid')",
        timeout=10_000,
    )  # the select shows the drawing in use again
    assert body(page, "shape") == "ellipsoid" and "body_shape" not in query_of(page)
    assert not page.errors
