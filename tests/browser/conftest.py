"""Fixtures for the browser tests: one served app and one Chromium per test session."""

from __future__ import annotations

import os

import pytest
from harness import CHROMIUM, CHROMIUM_ARGS, served_app


@pytest.fixture(scope="session")
def app_url(tmp_path_factory) -> str:
    log = tmp_path_factory.mktemp("serve") / "panel.log"
    with served_app(str(log)) as url:
        yield url


@pytest.fixture(scope="session")
def browser():
    if not os.path.exists(CHROMIUM):
        pytest.fail(f"{CHROMIUM} is missing: ./dev setup installs Debian's chromium")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    ctx = browser.new_context(viewport={"width": 1400, "height": 1000})
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.errors = errors
    yield pg
    ctx.close()
