"""The tests' job executor: jobs queue up and run when the test drains them, on the test's thread."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class Jobs:
    """Stands in for the runner's thread pool: ``submit`` queues, ``drain`` runs everything queued (and what
    those jobs queue) in order, so a test decides when background work happens."""

    def __init__(self) -> None:
        self.queue: list[Callable[[], Any]] = []

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> None:
        self.queue.append(lambda: fn(*args, **kwargs))

    def drain(self) -> None:
        while self.queue:
            self.queue.pop(0)()
