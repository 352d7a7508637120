"""Run a session's computations off the UI thread; the newest request always wins.

Each *channel* (the section, the layers under it, ...) has a generation number.
Starting a job bumps it; a job polls ``cancelled()`` between chunks and stops
once a newer job exists or the session closed, and everything it emits is
dropped on the document thread if it has become stale by then. So moving a
slider cancels the work in flight and no stale result overwrites a newer one.

Jobs run on a thread pool shared by all sessions; the numerical kernels release
the GIL and split their batches over both cores (``explorer_core.integrators``),
whose FIFO pool interleaves the chunks of concurrent sessions.
"""

from __future__ import annotations

import logging
import os
import threading
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import Executor, ThreadPoolExecutor

log = logging.getLogger(__name__)

Emit = Callable[[Callable[[], None]], None]
Job = Callable[[Callable[[], bool], Emit], None]

_POOL = ThreadPoolExecutor(
    max_workers=int(os.environ.get("BILIMOVICH_APP_JOB_THREADS", "32")), thread_name_prefix="explorer-job"
)

#: Set once the numba kernels are compiled/loaded (see app/warm.py).
WARM = threading.Event()


class InlineExecutor(Executor):
    """Runs a job in the caller's thread (unit tests, scripts)."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        fn(*args, **kwargs)


class Runner:
    """Per-session job starter with newest-wins cancellation.

    Parameters
    ----------
    deliver : schedules a callable on the session's document thread
        (``doc.add_next_tick_callback`` in a server; call-through in tests).
    on_error : called on the document thread with a job's exception.
    """

    def __init__(
        self,
        deliver: Callable[[Callable[[], None]], None],
        on_error: Callable[[str, BaseException], None] | None = None,
        executor: Executor | None = None,
    ) -> None:
        self._deliver = deliver
        self._on_error = on_error
        self._executor = executor or _POOL
        self._gen: dict[str, int] = defaultdict(int)
        self._lock = threading.Lock()
        self.closed = False

    def ui(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on the document thread (figure updates from widget callbacks)."""
        self._deliver(fn)

    def generation(self, channel: str) -> int:
        return self._gen[channel]

    def start(self, channel: str, job: Job, *, bump: bool = True) -> int:
        """Run ``job(cancelled, emit)``; ``bump=False`` joins the current generation (no cancel)."""
        with self._lock:
            if bump:
                self._gen[channel] += 1
            gen = self._gen[channel]

        def cancelled() -> bool:
            return self.closed or self._gen[channel] != gen

        def emit(fn: Callable[[], None]) -> None:
            if cancelled():
                return

            def guarded() -> None:
                if not cancelled():
                    fn()

            self._deliver(guarded)

        def run() -> None:
            try:
                WARM.wait()
                if not cancelled():
                    job(cancelled, emit)
            except Exception as exc:  # reported to the session, never a traceback in the page
                log.exception("job on channel %s failed", channel)
                if self._on_error is not None:
                    emit(lambda err=exc: self._on_error(channel, err))

        self._executor.submit(run)
        return gen

    def cancel(self, channel: str) -> None:
        with self._lock:
            self._gen[channel] += 1

    def close(self) -> None:
        """Stop every job of this session (called when the browser tab closes)."""
        self.closed = True
