"""The basins layer in the browser: coexisting attractors of Fig. 11's tensor, coloured and listed."""

from __future__ import annotations

import pytest
from harness import text, wait_finished
from test_app_browser import count, open_app, query_of

pytestmark = pytest.mark.browser


def test_the_basins_layer_draws_and_lists_the_coexisting_attractors(page, app_url) -> None:
    open_app(page, app_url, "?scene=fig11&alpha=-0.5&I11=1.6&n=4&periods=50&basins=1&bas_n=40")
    wait_finished(page)
    page.wait_for_function(
        "() => Array.from(document.querySelectorAll('*')).some(e => e.shadowRoot && "
        "/basins on 40 x 40/.test(e.shadowRoot.querySelector('.basin-status')?.textContent || ''))",
        timeout=120_000,
    )
    assert count(page, "basins_source") == 1
    legend = text(page, ".basin-legend")
    assert legend.count("cycle") >= 2 and "%" in legend, legend  # the period-3 and the period-1 cycles
    assert query_of(page)["basins"] == "1"
    assert page.errors == []
