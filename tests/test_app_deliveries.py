"""The server's one queue of deliveries to the pages (app/pacing.py): it never stops draining."""

from __future__ import annotations

import asyncio
import threading
from types import SimpleNamespace

from app.pacing import Deliveries


class _Session:
    destroyed = False

    def __init__(self, fail_first: bool) -> None:
        self.fail_first = fail_first

    async def with_document_locked(self, fn, *args):
        if self.fail_first:
            self.fail_first = False
            raise asyncio.CancelledError  # the task running the drain was cancelled mid-way
        return fn(*args)


class _Doc:
    def __init__(self, session: _Session) -> None:
        self.session_context = SimpleNamespace(_session=session)


def _doc(session: _Session) -> _Doc:
    return _Doc(session)


class _Loop:
    """Tornado's IOLoop.add_callback on an asyncio loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.tasks: list[asyncio.Task] = []

    def add_callback(self, fn) -> None:
        self.tasks.append(self.loop.create_task(fn()))


def test_a_drain_that_dies_leaves_the_queue_drainable() -> None:
    async def main() -> list[str]:
        d = Deliveries()
        d._loop = _Loop(asyncio.get_running_loop())
        got: list[str] = []
        doc = _doc(_Session(fail_first=True))
        d.put(doc, lambda: got.append("lost with the cancelled drain"))
        d.put(doc, lambda: got.append("second"))
        for _ in range(50):
            await asyncio.sleep(0.01)
            if got:
                break
        d.put(doc, lambda: got.append("third"))
        for _ in range(50):
            await asyncio.sleep(0.01)
            if "third" in got:
                break
        return got

    # In a thread of its own: a test before this one may leave an event loop marked as running in this thread.
    out: list[list[str]] = []
    t = threading.Thread(target=lambda: out.append(asyncio.run(main())))
    t.start()
    t.join(30)
    assert out == [["second", "third"]]
