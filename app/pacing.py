"""The server's event loop kept responsive: pages built one at a time, deliveries in slices.

When a class opens the link together, the websockets of many tabs arrive in the same instant;
Bokeh then builds their pages one after the other in a single turn of the event loop (each is
synchronous work, ~0.1 s), and nothing else, ``/liveness`` included, is answered until all of
them are built (0.9 s measured with 15 pages per worker). Here each new session waits for the
previous page to be built and for one more turn of the loop (:func:`take_turn`, from Panel's
session-created hook), so requests that arrived meanwhile are served between two pages. The pages
are built as fast as before; a page build that never comes (a tab closed first) holds the line
for at most :data:`MAX_WAIT` seconds.
"""

from __future__ import annotations

import asyncio
import collections
import gc
import logging
import os
import threading
import time
from typing import Any

from app import stalls

log = logging.getLogger(__name__)

#: A page build not finished this long after it began (seconds) is taken as lost (its tab closed
#: first): the next in line goes.
MAX_WAIT = 1.0

_waiting: collections.deque[asyncio.Future] = collections.deque()
_building_since: float | None = None


def _stuck() -> bool:
    return _building_since is None or time.monotonic() - _building_since >= MAX_WAIT


async def take_turn() -> None:
    """Wait until no other page is being built (called before a session's page is built)."""
    global _building_since
    stalls.start()
    if not _stuck():
        fut = asyncio.get_running_loop().create_future()
        _waiting.append(fut)
        try:
            while not fut.done():
                try:
                    await asyncio.wait_for(asyncio.shield(fut), MAX_WAIT)
                except TimeoutError:
                    # Only the first in line takes over a lost build: every waiter timing out at
                    # once and building together is the stall this module prevents (a class of
                    # 15 pages per worker waits longer than MAX_WAIT in line, and progresses).
                    if _waiting and _waiting[0] is fut and _stuck():
                        _waiting.popleft()
                        break
        except asyncio.CancelledError:  # the tab went away while waiting
            if fut in _waiting:
                _waiting.remove(fut)
            raise
    _building_since = time.monotonic()


_frozen = False


def page_built() -> None:
    """The page is built: let the next one go after the event loop has had a turn."""
    global _frozen
    if not _frozen:
        # Everything loaded so far (numba, Panel, the template page: ~300 MB of objects) stays for
        # the process's life: out of the garbage collector's full passes, which otherwise walk it
        # all every few pages (~50-100 ms of the event loop each time).
        _frozen = True
        gc.freeze()
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:  # no server (tests, scripts)
        _release()
        return
    loop.call_soon(_after_turns, loop, 1)


#: Turns of the event loop between two pages: at least MIN_TURNS, then until nothing else is ready
#: (at most MAX_TURNS). A request needs a few turns (accept, read, handler, write); with one turn
#: between pages a /liveness request could wait for three pages (0.4-0.9 s measured in a class).
MIN_TURNS, MAX_TURNS = 4, 64


def _after_turns(loop: asyncio.AbstractEventLoop, turns: int) -> None:
    # CPython's loop keeps its ready callbacks in ``_ready``: the loop is idle when it is empty.
    if turns < MAX_TURNS and (turns < MIN_TURNS or getattr(loop, "_ready", None)):
        loop.call_soon(_after_turns, loop, turns + 1)
        return
    _release()


def _release() -> None:
    global _building_since
    from app.runner import SCHEDULER

    while _waiting:
        fut = _waiting.popleft()
        if not fut.done():
            fut.set_result(None)
            _building_since = time.monotonic()
            if SCHEDULER is not None:
                SCHEDULER.poke()  # jobs held back longer than the scheduler's max_wait go, pages or not
            return
    _building_since = None
    if SCHEDULER is not None:
        SCHEDULER.poke()  # the first points and layers held back while pages were built may start
    _fill_spares()


def _fill_spares() -> None:
    """No page in line: build the next pages' section figures while the server is idle (app/views.py: SPARES):
    no page due, no delivery waiting and no job computing (a figure holds the GIL ~25 ms: after a class opened,
    the first scenes go first)."""
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:  # no server (tests, scripts)
        return
    from app.runner import SCHEDULER
    from app.views import SPARES

    def idle() -> bool:
        jobs = SCHEDULER.stats() if SCHEDULER is not None else {"running": 0, "waiting": 0}
        return not (pages_due() or DELIVERIES.busy() or jobs["running"] or jobs["waiting"])

    SPARES.fill(loop, idle)


def pages_due() -> bool:
    """Whether a new page is being built or waits to be (the other work of this process waits)."""
    return _building_since is not None and time.monotonic() - _building_since < MAX_WAIT


def install() -> None:
    """Hook :func:`take_turn` into Panel's session creation (once per server process)."""
    from panel.io.application import Application

    if os.environ.get("BILIMOVICH_PAGE_PACING", "1") == "0":  # off (measurements)
        return
    if getattr(Application.on_session_created, "_paced", False):
        return
    original = Application.on_session_created

    async def on_session_created(self: Any, session_context: Any) -> None:
        await take_turn()
        await original(self, session_context)

    on_session_created._paced = True  # type: ignore[attr-defined]
    Application.on_session_created = on_session_created  # type: ignore[method-assign]
    from app.runner import SCHEDULER

    if SCHEDULER is not None:
        SCHEDULER.pages_due = pages_due


class Deliveries:
    """Work for the sessions' documents (new points, statuses, answers to the page), run on the
    server's event loop in slices of at most :attr:`budget` seconds, with the loop free in between.

    Bokeh's ``add_next_tick_callback`` puts each callback in the loop's ready queue; when many
    sessions' jobs emit at once, one turn of the loop runs them all back to back (0.6 s measured)
    and a request that arrived meanwhile (``/liveness``, a page) waits for the whole turn. Here one
    queue per process keeps the order of every document's callbacks, and the loop polls its
    sockets at least every ``budget`` seconds.
    """

    def __init__(self, budget: float = 0.03) -> None:
        self.budget = budget
        self._queue: collections.deque[tuple[Any, Any]] = collections.deque()
        self._urgent: collections.deque[tuple[Any, Any]] = collections.deque()
        self._lock = threading.Lock()
        self._scheduled = False
        self._loop: Any = None

    def put(self, doc: Any, fn: Any) -> None:
        """Run ``fn`` on the event loop with ``doc`` as the current document, its changes sent as one message.

        A callable marked ``urgent`` (what a user just did, a run's first points) goes before the backlog
        of other sessions' streaming points; results of runs it replaces are dropped anyway (app/runner.py).
        """
        with self._lock:
            (self._urgent if getattr(fn, "urgent", False) else self._queue).append((doc, fn))
            if self._scheduled:
                return
            self._scheduled = True
        self._loop.add_callback(self._drain)  # thread-safe

    def busy(self) -> bool:
        """Whether deliveries wait to be run."""
        return self._scheduled

    def bind(self) -> None:
        """Remember the server's event loop (called on it, when a session is built)."""
        if self._loop is None:
            from tornado.ioloop import IOLoop

            self._loop = IOLoop.current()

    async def _drain(self) -> None:
        try:
            await self._drain_queue()
        except BaseException:
            # The loop is ending (a cancelled task) or a bug: never leave the queue marked as drained by a
            # coroutine that is gone, or every later delivery of every session would wait for ever.
            with self._lock:
                self._scheduled = False
                again = bool(self._urgent or self._queue)
            if again:
                self._schedule()
            raise

    def _schedule(self) -> None:
        with self._lock:
            if self._scheduled:
                return
            self._scheduled = True
        self._loop.add_callback(self._drain)

    async def _drain_queue(self) -> None:
        from panel.io.document import unlocked
        from panel.io.state import set_curdoc

        def run(doc: Any, fn: Any) -> None:
            # One websocket message for everything fn changes (points, status, series...): the
            # browser then applies, lays out and paints once, not once per model change.
            with set_curdoc(doc), unlocked():
                fn()

        t0 = time.perf_counter()
        while True:
            with self._lock:
                if not (self._urgent or self._queue):
                    self._scheduled = False
                    return
                doc, fn = (self._urgent or self._queue).popleft()
            session = getattr(doc.session_context, "_session", None) if doc.session_context else None
            if session is None or session.destroyed:  # the session is gone
                continue
            try:
                # Under the session's document lock, as Bokeh runs its own next-tick callbacks.
                await session.with_document_locked(run, doc, fn)
            except Exception:
                log.exception("a delivery to a page failed")
            if pages_due():  # new pages first: one delivery between two of them
                await asyncio.sleep(0.01)
                t0 = time.perf_counter()
            elif time.perf_counter() - t0 > self.budget:
                await asyncio.sleep(0.001)  # a turn of the loop for sockets first
                t0 = time.perf_counter()


DELIVERIES = Deliveries()


def urgent(fn: Any) -> Any:
    """Mark a delivery as one a user waits for (:meth:`Deliveries.put`)."""
    fn.urgent = True
    return fn
