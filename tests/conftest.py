"""Fixtures shared by every test directory."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest


def _harness():
    path = Path(__file__).resolve().parent / "browser" / "harness.py"
    spec = importlib.util.spec_from_file_location("browser_harness_shared", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def browser():
    """One headless Chromium per test process: Playwright's sync API cannot be started twice in one."""
    h = _harness()
    if not os.path.exists(h.CHROMIUM):
        pytest.fail(f"{h.CHROMIUM} is missing: ./dev setup installs Debian's chromium")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=h.CHROMIUM, args=h.CHROMIUM_ARGS)
        yield b
        b.close()
