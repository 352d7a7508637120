"""How ``bilimovich serve`` runs the app: Panel's server with the project's flags, on N processes.

``python -m app.serve ARGS`` is ``panel serve ARGS`` with a parent process that stops its
workers on SIGTERM (``docker stop``): with ``--num-procs N`` Tornado forks N workers that share
the listening socket (the kernel hands each new connection to one of them) and the parent only
waits for them, so without this it would die alone on SIGTERM and leave the workers running (or,
as PID 1 in a container, ignore the signal).

Why several processes and no proxy: a Bokeh server runs every session's page build, websocket
messages and callbacks on one event loop per process, so one process uses one core for all of
that. With ``--reuse-sessions`` the page's HTML comes from a template session built once per
process, and a session is built only when its websocket connects: a page and its websocket may
land in different workers without building anything twice, so no session affinity (sticky
sessions) is needed between the workers. Behind a reverse proxy (TLS, a public name) one
upstream is enough: the workers share one port (docs/deployment.md).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import time
from pathlib import Path

from explorer_core.config import usable_cpus

HERE = Path(__file__).resolve().parent


def command(
    *,
    port: int,
    address: str,
    threads: int,
    origins: list[str],
    session_lifetime: int,
    procs: int,
    show: bool = False,
) -> tuple[list[str], dict[str, str]]:
    """The command line and environment of the server process."""
    cmd = [
        sys.executable, "-m", "app.serve", str(HERE / "main.py"),
        "--port", str(port), "--address", address,
        "--setup", str(HERE / "warm.py"),  # compile/load the kernels before the first visitor (in each worker)
        "--num-threads", str(threads),
        "--liveness",
        # The page's HTML from one template session per process; a session is built when its
        # websocket connects (docs/load.md).
        "--reuse-sessions",
        # A closed tab's session (its document, figures, data) is freed this long after it closed;
        # its jobs stop at once (app/main.py). A page must connect its websocket within it.
        "--check-unused-sessions", str(min(5000, max(200, session_lifetime // 3))),
        "--unused-session-lifetime", str(session_lifetime),
    ]  # fmt: skip
    if procs > 1:
        cmd += ["--num-procs", str(procs)]
    for origin in origins:
        cmd += ["--allow-websocket-origin", origin]
    if show:
        cmd.append("--show")
    env = dict(os.environ)
    # BokehJS, Panel's CSS and every other resource from this server: nothing from a CDN (a
    # classroom network may have no internet, and a page must not depend on it).
    env["BOKEH_RESOURCES"] = "server"
    # Bokeh's integrity checks of every new page walk all its models (~25 ms of the event loop a
    # page, a sixth of it); the same checks run once in the tests (test_app_serve.py).
    env.setdefault("BOKEH_VALIDATE_DOC", "false")
    # glibc gives each thread that allocates its own arena (up to 8 per core); the job threads take
    # turns, and the server's RSS grew ~0.3 MB per opened-and-closed tab with no object left alive
    # (+34 MB over 100 cycles; with 2 arenas +5 MB, no trend: docs/load.md).
    env.setdefault("MALLOC_ARENA_MAX", "2")
    if procs > 1:
        # Each worker computes on its share of the cores (job slots and the kernels' threads): the
        # workers' schedulers do not see each other, and two workers each running two jobs on every
        # core would share the CPU between all of them and finish every scene later (docs/load.md).
        share = str(max(1, usable_cpus() // procs))
        env.setdefault("BILIMOVICH_APP_SLOTS", share)
        env.setdefault("BILIMOVICH_THREADS", share)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(HERE.parent), env.get("PYTHONPATH", "")) if p)
    return cmd, env


def _children() -> list[int]:
    pids: list[int] = []
    me = os.getpid()
    with contextlib.suppress(OSError):
        for task in os.listdir(f"/proc/{me}/task"):
            with contextlib.suppress(OSError, ValueError):
                pids += [int(p) for p in Path(f"/proc/{me}/task/{task}/children").read_text().split()]
    return pids


def _stop_workers(signum: int, frame: object) -> None:
    """The parent on SIGTERM/SIGINT: stop the workers (Bokeh shuts each down cleanly), then leave."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    for pid in _children():
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + 8.0
    while time.monotonic() < deadline:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            break
        if pid == 0:
            time.sleep(0.05)
    os._exit(0)


def launch(spec: dict) -> None:
    """Exec the server for the settings ``bilimovich serve`` checked (``python -m app.serve --launch JSON``)."""
    cmd, env = command(**spec)
    os.execve(sys.executable, cmd, env)


def no_delay() -> None:
    """Send each websocket frame at once (TCP_NODELAY), as browsers do on their side.

    Bokeh sends a message as several frames (header, metadata, content, buffers). With Nagle's algorithm on, a
    frame after the first waits for the peer's ACK, which a delayed ACK holds up to 40 ms: measured on a played
    parameter, every frame's answer from a client without it came 43 ms late (benchmarks/play_speed.py).
    """
    from bokeh.server.views.ws import WSHandler

    if getattr(WSHandler.open, "_no_delay", False):
        return
    original = WSHandler.open

    def open(self: WSHandler, *args: object, **kwargs: object) -> object:
        self.set_nodelay(True)
        return original(self, *args, **kwargs)

    open._no_delay = True  # type: ignore[attr-defined]
    WSHandler.open = open  # type: ignore[method-assign]


def main(argv: list[str]) -> None:
    if argv[:1] == ["--launch"]:
        launch(json.loads(argv[1]))
        return
    no_delay()
    if "--num-procs" in argv:
        signal.signal(signal.SIGTERM, _stop_workers)  # the workers replace it with Bokeh's own
        signal.signal(signal.SIGINT, _stop_workers)
    from panel.command import main as panel_main

    sys.argv = ["panel", "serve", *argv]
    panel_main()


if __name__ == "__main__":
    main(sys.argv[1:])
