"""Warm a server process before its first visitor: the numba kernels in the background, one page now.

Used as ``panel serve --setup app/warm.py`` (so warming starts before the first visitor; with
``--num-procs`` in each worker) and called again by the app (idempotent). While the kernels load, the
page says the server is warming and jobs wait for :data:`app.runner.WARM`; :func:`warm_page` builds
one page at import, so the first visitor's does not pay for the imports and caches.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import signal
import threading

from app import memory, pacing
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


def _die_with_parent() -> None:
    """A worker of ``--num-procs`` ends when its parent does (even a parent killed without warning)."""
    import tornado.process

    if tornado.process.task_id() is not None:
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


_die_with_parent()
pacing.install()
start()


def warm_page() -> None:
    """Build and serialize one page with no visitor, before the server answers.

    The first page of a process costs ~1 s of the event loop more than the next ones (the app's
    modules and what they import, Bokeh's and Panel's per-class caches, the component's bundle):
    without this the first visitor of each worker waited for it, and every request with them.
    """
    from bokeh.document import Document

    from app.page import Page

    try:
        page = Page({}, lambda fn: fn())
        doc = Document()
        page.ui.server_doc(doc)
        doc.to_json()
        page.close()
    except Exception:  # a page that cannot be built fails again, visibly, for the visitor
        logging.getLogger(__name__).exception("warming a page failed")


warm_page()

memory.start()  # give freed memory back to the system; the diagnostic if asked (app/memory.py)
