"""Executors: where the independent tasks of an analysis run (chart tiles, chunks of a sweep, Newton seeds).

One protocol, :class:`Executor`: :meth:`~Executor.stream` takes a queue of ``(tag, function, args)``
tasks -- the caller may append to it while iterating, e.g. the next chunk of a continuation sweep once
the previous one is done -- and yields batches of ``(tag, result)`` as tasks finish. Analyses take an
executor as an argument and never import a particular one: :class:`LocalExecutor` (threads of this
process; the default) is here, the Dask executor in :mod:`explorer_core.parallel.cluster` is made by
the command line or the app from a scheduler address and passed in. Tasks are module-level functions
of picklable data, so the same task runs in a thread or on a cluster with identical results.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from typing import Any, Protocol

from explorer_core import config

#: A task: ``(tag, function, args)``; the result comes back with its tag.
Task = tuple[Any, Callable[..., Any], tuple]


class Executor(Protocol):
    """Runs tasks and streams their results back."""

    #: Shown in summaries ("local", "tcp://host:8786", ...).
    label: str

    def threads(self) -> int:
        """How many tasks run at once (for sizing chunks)."""
        ...

    def stream(self, todo: deque[Task], cancel: Callable[[], bool] | None = None) -> Iterator[list[tuple[Any, Any]]]:
        """Run ``todo`` (in order; the caller may append while iterating), yielding ``(tag, result)`` batches.

        ``cancel`` is polled between tasks; once it returns True no new task starts and the stream ends
        after the running ones (a cluster cancels its queued tasks). A task's exception propagates.
        """
        ...


class LocalExecutor:
    """Tasks in ``workers`` threads of this process (default: every core); the kernels release the GIL.

    At most ``workers`` tasks run at once, taken from the queue in order, so the first tasks (a chart's
    coarse levels) finish first.
    """

    label = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, int(workers or config.N_WORKERS))

    def threads(self) -> int:
        return self.workers

    def stream(self, todo: deque[Task], cancel: Callable[[], bool] | None = None) -> Iterator[list[tuple[Any, Any]]]:
        if self.workers == 1:
            while todo and not (cancel is not None and cancel()):
                tag, fn, args = todo.popleft()
                yield [(tag, fn(*args))]
            return
        with ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix="bilimovich-task") as pool:
            running: dict[Future, Any] = {}
            try:
                while True:
                    while todo and len(running) < self.workers and not (cancel is not None and cancel()):
                        tag, fn, args = todo.popleft()
                        running[pool.submit(fn, *args)] = tag
                    if not running:
                        return
                    finished, _ = wait(running, return_when=FIRST_COMPLETED)
                    yield [(running.pop(f), f.result()) for f in finished]
            finally:
                for f in running:  # the caller stopped iterating: nothing new starts, running tasks end
                    f.cancel()


def local_executor(executor: Executor | None, workers: int | None = None) -> Executor:
    """``executor`` itself, or threads of this process when it is None."""
    return executor if executor is not None else LocalExecutor(workers)
