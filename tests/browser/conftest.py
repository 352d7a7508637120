"""Fixtures for the browser tests: one served app per test session (Chromium: tests/conftest.py)."""

from __future__ import annotations

import itertools
import re

import pytest
from harness import new_page, served_app


@pytest.fixture(scope="session")
def app_url(tmp_path_factory) -> str:
    log = tmp_path_factory.mktemp("serve") / "panel.log"
    # The runner traces its jobs into the log (slot waits, spans): a wait that times out quotes it.
    with served_app(str(log), env={"BILIMOVICH_TRACE": "1"}) as url:
        yield url
    # An exception on the server (e.g. a model changed off the document's thread) can leave the page
    # looking fine while a step after it never ran: none may be logged.
    text = server_exceptions(log.read_text(errors="replace"))
    assert "Traceback" not in text, f"the server logged an exception:\n{text[text.index('Traceback') :][:3000]}"


#: A log record starts with its time stamp.
RECORD = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d+ ", re.M)


def server_exceptions(text: str) -> str:
    """The server's log without tornado's report of a write to a websocket the browser had closed: a tab
    that closes while an update is on its way (a density image is ~2 MB) is a client leaving, not a fault
    of the server (asyncio logs the write's unretrieved WebSocketClosedError)."""
    starts = sorted({0, len(text), *(m.start() for m in RECORD.finditer(text))})
    records = [text[a:b] for a, b in itertools.pairwise(starts)]
    benign = ("Task exception was never retrieved", "write_message", "tornado.websocket.WebSocketClosedError")
    return "".join(r for r in records if not all(b in r for b in benign))


@pytest.fixture
def page(browser):
    pg = new_page(browser, 1400, 1000)
    yield pg
    pg.context.close()
