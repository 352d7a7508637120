"""Fixtures for the browser tests: one served app per test session (Chromium: tests/conftest.py)."""

from __future__ import annotations

import pytest
from harness import served_app


@pytest.fixture(scope="session")
def app_url(tmp_path_factory) -> str:
    log = tmp_path_factory.mktemp("serve") / "panel.log"
    with served_app(str(log)) as url:
        yield url
    # An exception on the server (e.g. a model changed off the document's thread) can leave the page
    # looking fine while a step after it never ran: none may be logged.
    text = log.read_text(errors="replace")
    assert "Traceback" not in text, f"the server logged an exception:\n{text[text.index('Traceback') :][:3000]}"


@pytest.fixture
def page(browser):
    ctx = browser.new_context(viewport={"width": 1400, "height": 1000})
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.errors = errors
    yield pg
    ctx.close()
