"""Where a long analysis is (one shape for every progress line), and the contract every long analysis keeps.

Every update a long analysis yields or passes to its ``progress`` callback (``SectionChunk``, ``Density``,
``SweepProgress``, ``LyapunovProgress``, ``ChartUpdate``, ``Manifolds`` as grown so far, ...) has a
``progress`` property of this type, so the command line's progress line and the app's status read them
all alike.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar, runtime_checkable


@dataclass(frozen=True)
class Progress:
    """``done`` of ``total`` ``unit`` (e.g. 120 of 700 periods), after ``elapsed_s`` seconds."""

    done: float
    total: float
    unit: str
    elapsed_s: float = 0.0

    @property
    def fraction(self) -> float:
        return min(1.0, max(0.0, self.done / self.total)) if self.total > 0 else 0.0

    def line(self) -> str:
        def num(v: float) -> str:
            return f"{v:.4g}" if v != int(v) else str(int(v))

        return f"{num(self.done)}/{num(self.total)} {self.unit} ({100 * self.fraction:.0f} %, {self.elapsed_s:.1f} s)"


# --- the contract of a long analysis ---------------------------------------------------------------------
#
# ``iter_X(..., cancel=None)`` yields updates; every update has ``.progress`` (a :class:`Progress`, its
# ``done`` never decreasing) and ``.result``. THE RULE: the last update's ``result`` is the final result
# (earlier updates may carry the live, partial result, or None). ``X(..., progress=None, cancel=None)`` is
# ``run(iter_X(..., cancel=cancel), progress)``. Cancelling never raises: the analysis stops at its next
# poll and the last update still carries what was computed, marked incomplete (``complete`` False, a
# ``Loss`` saying what was not computed).

R = TypeVar("R")


@runtime_checkable
class Update(Protocol):
    """What every ``iter_X`` yields and every ``progress`` callback receives."""

    @property
    def progress(self) -> Progress: ...

    @property
    def result(self) -> Any: ...


#: The one signature of a ``progress`` callback.
ProgressCallback = Callable[[Any], None]
#: Polled by a long analysis; True stops it (it then returns what it computed).
Cancel = Callable[[], bool]


@dataclass(frozen=True)
class Step(Generic[R]):
    """An update of an analysis without an update type of its own: where it is, what it is doing, and
    (on the last update) the result."""

    progress: Progress
    detail: Any = None
    result: R | None = None


class ContractError(RuntimeError):
    """An ``iter_X`` that broke the contract (yielded nothing, or no result on its last update)."""


def run(updates: Iterable[Any], progress: ProgressCallback | None = None) -> Any:
    """Drive ``updates`` (an ``iter_X``) to its end, passing each update to ``progress``; the last one's result."""
    last = None
    for last in updates:
        if progress is not None:
            progress(last)
    result = getattr(last, "result", None)
    if result is None:
        raise ContractError(f"the analysis ended without a result (last update: {last!r})")
    return result


def stoppable(body: Callable[[Cancel], Iterable[Any]], cancel: Cancel | None = None) -> Iterator[Any]:
    """The updates of ``body(stop)``, an analysis written as a generator that polls ``stop()`` where it may stop,
    as an ``iter_X``: no thread (the generator counterpart of :func:`stream`).

    ``stop()`` is ``cancel()``: the analysis runs only while the consumer asks for its next update, so a
    ``progress`` callback that sets ``cancel`` is seen at the analysis's next poll. Closing the iterator early
    (``break``, ``close()``, Ctrl-C) makes ``stop()`` True and runs ``body`` on to that poll, where it ends as a
    cancelled run does, its remaining updates dropped: the live result that earlier updates carried is left
    marked incomplete, with its ``Loss``, exactly as a cancel leaves it.
    """
    closed = False

    def stop() -> bool:
        return closed or (cancel is not None and bool(cancel()))

    for update in body(stop):
        if closed:
            continue
        try:
            yield update
        except GeneratorExit:  # closed by the consumer: the analysis stops at its next poll
            closed = True


_DONE = object()


def stream(work: Callable[[ProgressCallback, Cancel], Any], cancel: Cancel | None = None) -> Iterator[Any]:
    """The updates of ``work(emit, stop)``, an analysis written with a callback, as an ``iter_X``.

    ``work`` calls ``emit(update)`` where it reports, polls ``stop()`` where it may stop, and returns its
    last update (the one carrying the result). It runs on a thread of its own in lock-step with the
    consumer: ``emit`` returns only when the consumer asks for the next update, so a ``progress``
    callback that sets ``cancel`` is seen by the analysis's next poll, exactly as a callback would be.
    Closing the iterator early (``break``, Ctrl-C) stops the analysis and waits for it. An exception of
    ``work`` is raised in the consumer.
    """
    handoff: queue.Queue = queue.Queue(maxsize=1)
    resume = threading.Semaphore(0)
    closed = threading.Event()

    def stop() -> bool:
        return closed.is_set() or (cancel is not None and bool(cancel()))

    def emit(update: Any) -> None:
        if closed.is_set():
            return
        handoff.put((update, None))
        resume.acquire()

    def body() -> None:
        try:
            handoff.put((work(emit, stop), _DONE))
        except BaseException as exc:  # handed to the consumer, raised there
            handoff.put((None, exc))

    thread = threading.Thread(target=body, name="analysis", daemon=True)
    thread.start()
    try:
        while True:
            update, flag = handoff.get()
            if flag is _DONE:
                yield update
                return
            if flag is not None:
                raise flag
            yield update
            resume.release()
    finally:
        closed.set()
        resume.release()  # an emit waiting for the consumer returns (and the analysis sees stop())
        while thread.is_alive():
            try:  # drain so that the thread's last put does not block
                handoff.get(timeout=0.05)
            except queue.Empty:
                pass
        thread.join()
