"""How a streaming section job paces its updates and when it starts the layers that follow it."""

from __future__ import annotations

import time
from collections.abc import Callable

#: Longest chunk streamed to the browser: bounds how long a cancel waits.
MAX_CHUNK = 32
#: Time between point updates sent to the browser: starts here, doubles up to the max (seconds).
EMIT_INTERVAL = 0.5
MAX_EMIT_INTERVAL = 1.0
#: The layers (T' map, tracks) of a new setting are computed once the section is done, or
#: this long (seconds) into a longer run: computed alongside, they would take CPU (and the
#: GIL: the tracks are Python) from the section's first points, and every update they send
#: makes the browser redraw the whole plot while the points are still coming.
LAYER_DELAY = 1.0


class Cadence:
    """When a streaming section job sends an update, and when it starts the layers.

    The first update goes out at once; later ones back off (EMIT_INTERVAL doubling up to MAX_EMIT_INTERVAL):
    each makes the browser redraw every point, which costs more than the data. The layers start
    LAYER_DELAY into a long run, or at the end of a shorter one that was not cancelled.
    """

    def __init__(self, start_layers: Callable[[], None] | None) -> None:
        self._first = True
        self._last = 0.0
        self._interval = EMIT_INTERVAL
        self._t0 = time.perf_counter()
        self._layers = start_layers

    def due(self) -> bool:
        return self._first or time.perf_counter() - self._last >= self._interval

    def sent(self) -> bool:
        """An update goes out now; whether it is the run's first (it replaces the picture on screen)."""
        first, self._first = self._first, False
        self._last = time.perf_counter()
        if not first:
            self._interval = min(2 * self._interval, MAX_EMIT_INTERVAL)
        return first

    def layers_if_late(self) -> None:
        if self._layers is not None and time.perf_counter() - self._t0 >= LAYER_DELAY:
            self._start_layers()  # a long run: the layers need not wait for its end

    def layers_at_end(self, done: bool) -> None:
        if self._layers is not None and done:
            self._start_layers()  # stale runs start none: the newer run starts its own

    def _start_layers(self) -> None:
        start, self._layers = self._layers, None
        start()  # type: ignore[misc]
