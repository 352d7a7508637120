"""The figure download in the browser: the section's plot as a PNG of the size typed, sent by the server (no prompt)."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness import wait_finished
from test_app_browser import open_app

pytestmark = pytest.mark.browser


def test_the_figure_button_downloads_a_png_of_the_size_typed(page, app_url) -> None:
    """Fails on the old code (no figure button: Bokeh's save tool, a filename prompt, the plot's screen size)."""
    open_app(page, app_url, "?scene=fig8B&n=2&periods=50")
    wait_finished(page, timeout=240)  # a loaded machine compiles and runs slowly
    bar = page.locator(".pane-section .figure-bar")
    bar.locator(".fig-width").fill("900")
    bar.locator(".fig-height").fill("600")
    bar.locator(".fig-dpi").fill("120")
    with page.expect_download(timeout=60_000) as info:
        bar.locator(".btn-figure").click()
    download = info.value
    assert download.suggested_filename == "section.png"
    data = Path(download.path()).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    assert (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")) == (900, 600)
    assert not page.errors
