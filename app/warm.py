"""Warm the numba kernels in the background, once per server process.

Used as ``panel serve --setup app/warm.py`` (so warming starts before the first
visitor) and called again by the app (idempotent). While it runs, the page says
the server is warming and jobs wait for :data:`app.runner.WARM`.
"""

from __future__ import annotations

import threading

from app.runner import WARM

_started = threading.Lock()
_thread: threading.Thread | None = None


def _warm() -> None:
    from explorer_core.warm import warm_all as warmup

    try:
        warmup()
    finally:
        WARM.set()


def start() -> None:
    """Start warming (no-op if already started)."""
    global _thread
    with _started:
        if _thread is None:
            _thread = threading.Thread(target=_warm, name="explorer-warmup", daemon=True)
            _thread.start()


start()
