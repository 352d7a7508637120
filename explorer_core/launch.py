"""The stop signals handled from a program's first lines, before the heavy imports (the console script,
:mod:`explorer_core.__main__`, and ``python -m explorer_core.cli``: the warm worker, the tests).

The command line's own handlers (:func:`explorer_core.cli.entry`) are installed once ``explorer_core.cli`` and
numpy are imported, ~0.2-0.3 s after the start; a Ctrl-C or SIGTERM before then got Python's defaults (a
``KeyboardInterrupt`` traceback, a death by the signal). Here a signal in that window ends the process at once with
one line and ``128 + signal``, as :func:`explorer_core.cli.entry` does for a signal before the work begins:
nothing has run and no file is open. Only the interpreter's own start (~20 ms) comes before this module.
"""

from __future__ import annotations

import os
import signal
import sys

#: Signals that stop a command: Ctrl-C, SIGTERM (a process manager, ``kill``) and SIGHUP (a closed terminal). The
#: exit status is 128 plus the first one's number: 130, 143, 129 (the command line's handlers take the same).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def before_the_command(signum: int, frame: object) -> None:
    """End the process at once: one line and ``128 + signum`` (a stop signal before the command began)."""
    args = [a for a in sys.argv[1:] if not a.startswith("-")]
    os.write(2, f"bilimovich{f' {args[0]}' if args else ''}: interrupted\n".encode())
    os._exit(128 + signum)  # no file is written yet, and no exit handler has anything to do


def early() -> None:
    """Install the stop-signal handlers that hold until the command line's own replace them."""
    for s in STOP_SIGNALS:
        signal.signal(s, before_the_command)


#: Whether the command has begun in this process (None: not yet; a stop signal then ends it at once). Set by
#: :func:`explorer_core.worker.entry` while the worker has the command, and by ``explorer_core.cli.main`` when it
#: begins one.
began: bool | None = None

#: The hidden first argument of the worker process (``python -m explorer_core.cli _worker PATH``).
WORKER_ARG = "_worker"
