"""Manifolds in the browser: a click on the flip saddle's cross draws its manifolds and homoclinic points."""

from __future__ import annotations

import pytest
from harness import text, wait_finished
from test_app_browser import count, open_app, query_of
from test_app_orbits_browser import click_frame_centre

pytestmark = pytest.mark.browser

#: Fig. 8B's flip saddle at the centre of the view, found from the URL's orbit seed; clicks draw manifolds.
CENTRED = ("?scene=fig8B&n=2&periods=50&orb=-0.0377,-2.3979&orb_n=1&click=manifolds&man_len=6"
           "&qr=-0.5377,0.4623&rr=-2.8979,-1.8979")  # fmt: skip


def test_a_click_on_the_saddle_draws_its_manifolds(page, app_url) -> None:
    open_app(page, app_url, CENTRED)
    wait_finished(page)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('orbits_saddle')?.get_length() === 1",
                           timeout=30_000)  # fmt: skip
    click_frame_centre(page)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('manifolds_source')?.get_length() >= 4",
                           timeout=60_000)  # fmt: skip
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/homoclinic points/.test(e.shadowRoot.querySelector('.manifold-status')?.textContent || ''))",
        timeout=60_000,
    )
    assert count(page, "crossings_source") > 0
    kinds = page.evaluate("() => Bokeh.documents[0].get_model_by_name('manifolds_source').data.kind")
    assert set(kinds) == {"stable", "unstable"}
    assert text(page, ".manifold-status").startswith("flip saddle (period 1)")
    page.wait_for_function("() => (new URLSearchParams(location.search).get('man') || '').endsWith(',1')")
    assert query_of(page)["click"] == "manifolds"
    assert page.errors == []
