"""Periodic orbits in the browser: a click finds one and draws it; the orbit diagram gets its continued branches."""

from __future__ import annotations

import pytest
from harness import frame_centre, text, wait_finished
from test_app_browser import count, open_app, query_of

pytestmark = pytest.mark.browser

#: Fig. 8B's flip saddle at the centre of the view, so a click at the frame's centre lands near it.
CENTRED = "?scene=fig8B&n=2&periods=50&click=orbit&orb_n=1&qr=-0.5377,0.4623&rr=-2.8979,-1.8979"
#: In-page probe: time from the pointerup to the animation frame that draws the first orbit point.
JS_ORBIT_PROBE = """
() => {
  // The orbits layer joins the plot with its first orbit: look its sources up on every frame.
  const srcs = () => ['orbits_saddle', 'orbits_stable', 'orbits_unstable'].map(
      (n) => Bokeh.documents[0].get_model_by_name(n));
  const p = {t0: null, drawn: null};
  window.__orbit = p;
  window.addEventListener('pointerup', () => { p.t0 = performance.now(); }, {capture: true, once: true});
  const tick = () => {
    if (p.t0 !== null && srcs().some((s) => s?.get_length() > 0)) { p.drawn = performance.now(); return; }
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
}
"""


def click_frame_centre(page) -> None:
    """Click the centre of the section plot's frame (the data area, between the axes)."""
    f = frame_centre(page)
    page.mouse.click(f["x"], f["y"])


def test_a_click_finds_the_orbit_and_draws_it(page, app_url) -> None:
    open_app(page, app_url, CENTRED)
    wait_finished(page)
    page.evaluate(JS_ORBIT_PROBE)
    click_frame_centre(page)
    page.wait_for_function("() => window.__orbit.drawn !== null", timeout=30_000)
    assert count(page, "orbits_saddle") == 1
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/flip saddle/.test(e.shadowRoot.querySelector('.orbit-table')?.textContent || ''))",
        timeout=30_000,
    )
    assert "flip saddle" in text(page, ".orbit-status")
    page.wait_for_function("() => (new URLSearchParams(location.search).get('orb') || '').includes(',')")
    assert query_of(page)["click"] == "orbit"
    assert page.errors == []


def test_the_orbit_diagram_gets_its_continued_branches(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig10&n=2&periods=40&tab=bifurcation&bif_n=12&bif_pts=10&bif_tr=60")
    page.wait_for_timeout(1000)
    page.locator(".bifurcation-run").click()
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/period doubling of the period-1 orbit at alpha = -0.3753448/.test(e.shadowRoot.textContent))",
        timeout=180_000,
    )
    assert count(page, "branches_stable") > 0 and count(page, "branches_unstable") > 0
    assert count(page, "bif_points") >= 1
    assert page.errors == []


#: The text of every hover tooltip shown on the page (Bokeh draws them in shadow roots).
JS_TOOLTIPS = """() => {
  const out = [];
  const walk = (root) => {
    for (const e of root.querySelectorAll('*')) {
      if (e.classList && e.classList.contains('bk-tooltip-content') && e.offsetParent !== null) out.push(e.innerText);
      if (e.shadowRoot) walk(e.shadowRoot);
    }
  };
  walk(document);
  return out.filter((t) => t.trim());
}"""


def test_hovering_the_flip_saddle_shows_its_multipliers_first_and_few_points(page, app_url) -> None:
    """Hover on Fig. 8B's flip saddle, section points all around it: the orbit's tooltip starts with its
    multipliers, the points' tooltip lists at most 3 points, and no tooltip shows 'frozen-field equilibrium: ???'
    (one hover over the points and the diamonds showed it on every point; dozens of point entries buried the
    multipliers)."""
    open_app(page, app_url, "?scene=fig8B&n=60&periods=400&orb=-0.0377,-2.3979&orb_n=1"
                            "&qr=-0.5377,0.4623&rr=-2.8979,-1.8979")  # fmt: skip
    wait_finished(page)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('orbits_saddle')?.get_length() > 0",
                           timeout=60_000)  # fmt: skip
    page.wait_for_timeout(800)
    f = frame_centre(page)
    # The saddle is at the view's centre: move onto it in small steps (a hover needs mouse moves).
    page.mouse.move(f["x"] + 30, f["y"] + 30)
    for i in range(10, -1, -1):
        page.mouse.move(f["x"] + 3 * i, f["y"] + 3 * i)
        page.wait_for_timeout(60)
    page.wait_for_function(f"() => ({JS_TOOLTIPS})().some((t) => t.includes('multipliers'))", timeout=10_000)
    tips = page.evaluate(JS_TOOLTIPS)
    orbit = [t for t in tips if "multipliers" in t]
    assert orbit and orbit[0].lstrip().startswith("multipliers"), tips
    assert "-3.028" in orbit[0] and orbit[0].count("multipliers") == 1, tips  # one orbit point described
    assert not any("???" in t for t in tips), tips
    assert sum(t.count("trajectory") for t in tips) <= 3, tips
