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

import asyncio
import contextlib
import functools
import json
import logging
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

from explorer_core.config import usable_cpus

HERE = Path(__file__).resolve().parent
log = logging.getLogger(__name__)

#: What one websocket may send. A page's largest message is an uploaded tours file (app/ui.py MAX_UPLOAD: 200,000
#: characters, at most ~1.2 MB as JSON); a message (its fragments and buffers together) beyond this closes the
#: connection before it is read whole.
MAX_MESSAGE_BYTES = 2 * 2**20
#: Events in one PATCH-DOC: a page sends one or a few; 20,000 clicks in one message would hold the event loop.
MAX_EVENTS = 200
#: Messages a connection may send per second (sustained, burst): a pan sends its ranges' changes every frame
#: (up to ~4 x 120 a second), a page's events (clicks, a slider's release, a played frame shown, a pan's end) a few
#: a second. Beyond that the server reads the socket slower (the client waits), so a flood costs the others no
#: more than a busy page does.
MESSAGE_RATE, MESSAGE_BURST = 1000.0, 2000.0
#: A page's events that make the server work (a value typed, a click in the plot, a pan's end, a button): a person
#: makes a few a second. A played frame's "shown" (up to the player's 30 frames/s) is cheap: only MESSAGE_RATE.
EVENT_RATE, EVENT_BURST = 10.0, 30.0
#: A connection whose socket holds more than FLOOD_BYTES unread for FLOOD_S seconds is closed, its session discarded
#: like a closed tab's: reading a flood at the rates above would keep its session alive, and working, for as long as
#: the socket's buffers last (2.3 MB of messages measured: minutes). A page's queue is empty whenever a message is read,
#: but for a message arriving behind it (an uploaded file: at most MAX_MESSAGE_BYTES, read in well under FLOOD_S).
FLOOD_BYTES, FLOOD_S = 256 * 1024, 3.0
#: Refusals logged per connection (then only counted): a hostile client must not fill the log.
LOGGED_REFUSALS = 3
#: Sessions one client address may hold in one server process (``bilimovich serve --max-sessions-per-address``).
MAX_SESSIONS_ENV = "BILIMOVICH_MAX_SESSIONS_PER_ADDRESS"
DEFAULT_MAX_SESSIONS = 50


def command(
    *,
    port: int,
    address: str,
    threads: int,
    origins: list[str],
    session_lifetime: int,
    procs: int,
    show: bool = False,
    max_sessions_per_address: int = DEFAULT_MAX_SESSIONS,
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
        "--websocket-max-message-size", str(MAX_MESSAGE_BYTES),  # one frame; whole messages: guard()
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
    env[MAX_SESSIONS_ENV] = str(max_sessions_per_address)  # read by guard() in the server process
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


#: Stands for the session token in a page's HTML rendered once (:func:`pages_once`); no token contains it.
TOKEN_SLOT = "@@bilimovich-session-token@@"


def pages_once() -> None:
    """Render the page's HTML once per template document, then only put each request's token into it.

    With ``--reuse-sessions`` every GET renders the HTML of the same template session: Panel walked its ~75 models
    four times for it (the stylesheets' URLs, MathJax, the extensions: ~17 ms of the event loop a page, a seventh
    of a new session's cost, docs/load.md) for a text in which only the session token (and the roots' element
    ids, unique within one page) differ. The HTML is rendered once per document, resources, template and path
    prefix, with a placeholder where the token goes.
    """
    import weakref

    import panel.io.server as panel_server
    from panel.io.state import state

    render = panel_server.server_html_page_for_session
    if getattr(render, "_once", False):
        return
    rendered: weakref.WeakKeyDictionary[Any, dict[tuple, str]] = weakref.WeakKeyDictionary()

    def page(session: Any, resources: Any, title: str, token: str | None = None, **kw: Any) -> str:
        token = token or session.token
        # Not the template variables: Panel's render sets two of them (the theme, the resources' URL) from the
        # configuration and the prefix, so the first render changes them.
        key = (title, resources.mode, resources.root_url, id(kw.get("template")), state.rel_path)
        pages = rendered.setdefault(session.document, {})
        if key not in pages:
            html = render(session, resources, title, token=TOKEN_SLOT, **kw)
            if html.count(TOKEN_SLOT) != 1:  # not a page this can fill in: rendered for every request
                return render(session, resources, title, token=token, **kw)
            pages[key] = html
        return pages[key].replace(TOKEN_SLOT, token)

    page._once = True  # type: ignore[attr-defined]
    panel_server.server_html_page_for_session = page


# --- hostile clients ------------------------------------------------------------------------------
#
# Bokeh's server applies whatever a client patches into its document (any property of any model, events with any
# values), answers errors with the traceback, logs whole messages, keeps a message's announced buffers in memory
# however many there are, and builds a session for any token a client makes up. guard() installs the limits above;
# tests/test_hostile_client.py is the client that found each.


class _Bucket:
    """A token bucket: how long to wait before spending ``n`` (the level may go below zero: the wait grows)."""

    def __init__(self, rate: float, burst: float) -> None:
        self.rate, self.burst, self.level, self.t = rate, burst, burst, time.monotonic()

    def wait(self, n: float) -> float:
        now = time.monotonic()
        self.level = min(self.burst, self.level + (now - self.t) * self.rate) - n
        self.t = now
        return max(0.0, -self.level / self.rate)


def _plain(v: Any, depth: int = 0) -> bool:
    """Whether a property value is one a widget or the plot sends: a finite number, a flag, a short text, a
    reference to an existing model, or a short list of those (never a new model, a NaN, a nested structure)."""
    if v is None or (isinstance(v, bool | str) and len(str(v)) <= 1000):
        return True
    if isinstance(v, int | float):
        return math.isfinite(v)
    if isinstance(v, dict):
        return set(v) == {"id"} and isinstance(v["id"], str)
    return isinstance(v, list) and depth == 0 and len(v) <= 1000 and all(_plain(x, 1) for x in v)


def _costly(event: Any) -> bool:
    """Whether an event of a PATCH-DOC makes the server work (every event but a played frame's "shown")."""
    if not isinstance(event, dict) or event.get("kind") != "MessageSent":
        return False
    values = event.get("msg_data", {}).get("values") if isinstance(event.get("msg_data"), dict) else None
    data = values.get("data") if isinstance(values, dict) else None
    return not (isinstance(data, dict) and data.get("action") == "shown")


def _unread(handler: Any) -> int:
    """Bytes a client sent that the server has not read yet (the socket's receive queue; 0 if unknown)."""
    import fcntl
    import struct
    import termios

    try:
        sock = handler.ws_connection.stream.socket
        return struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]
    except (AttributeError, OSError, ValueError):
        return 0


@functools.cache
def _server_owned() -> tuple[type, ...]:
    """Models whose properties only the server sets: the data it draws and the page component's state."""
    from bokeh.model import DataModel
    from bokeh.models import ColumnarDataSource
    from panel.models.esm import ReactiveESM

    return (ColumnarDataSource, DataModel, ReactiveESM)


def refusal(msgtype: str, content: Any, document: Any) -> str | None:
    """Why a message from a client is refused (None: it is one a page sends). A page reads the document, sends
    events and changes the properties of its plot and tools; it never replaces the document, adds or removes
    models, streams data or sets what the server computes."""
    if msgtype == "PUSH-DOC":
        return "PUSH-DOC (a page never replaces its document)"
    if msgtype != "PATCH-DOC":
        return None
    events = content.get("events") if isinstance(content, dict) else None
    if not isinstance(events, list):
        return "a PATCH-DOC without a list of events"
    if len(events) > MAX_EVENTS:
        return f"{len(events)} events in one message (at most {MAX_EVENTS})"
    owned = _server_owned()
    for ev in events:
        kind = ev.get("kind") if isinstance(ev, dict) else None
        if kind == "MessageSent":
            continue  # an event: the app's handlers check its values
        if kind != "ModelChanged":
            return f"a {str(kind)[:40]!r} event (a page only changes properties and sends events)"
        ref, attr = ev.get("model"), str(ev.get("attr"))[:40]
        model = document.get_model_by_id(ref.get("id")) if isinstance(ref, dict) and "id" in ref else None
        if model is None:
            return f"a change of an unknown model {str(ref)[:60]}"
        if isinstance(model, owned):
            return f"a change of {type(model).__name__}.{attr} (set by the server only)"
        if not _plain(ev.get("new")):
            return f"a value of {type(model).__name__}.{attr} that no widget sends"
    return None


def _refuse(connection: Any, message: Any, why: str) -> Any:
    """The ERROR answer (a short text, no traceback); the first few per connection are logged."""
    n = connection.refused = getattr(connection, "refused", 0) + 1
    if n <= LOGGED_REFUSALS:
        where = getattr(getattr(connection, "_socket", None), "request", None)
        last = " (further refusals on this connection are not logged)" if n == LOGGED_REFUSALS else ""
        log.warning("refused a %s from %s: %s%s", message.msgtype, getattr(where, "remote_ip", "?"), why[:200], last)
    return connection.error(message, why[:200])


class _Owners:
    """Which client address opened which session (in this process), to cap the sessions of one address."""

    def __init__(self) -> None:
        self.by_id: dict[str, tuple[str, float, bool]] = {}  # session id -> (address, opened at, seen alive)

    def count(self, address: str, live: set[str]) -> int:
        n, now = 0, time.monotonic()
        for sid, (addr, t, seen) in list(self.by_id.items()):
            if sid in live:
                self.by_id[sid] = (addr, t, True)
            elif seen or now - t > 60.0:  # discarded (or never built: its page never connected)
                del self.by_id[sid]
                continue
            n += addr == address
        return n


OWNERS = _Owners()
_CAP_LOGGED: dict[str, float] = {}

CAP_PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>Bilimovich Explorer: too many sessions</title>
</head><body style="font-family: sans-serif; max-width: 40em; margin: 3em auto">
<h1>Too many open sessions</h1>
<p>Your address ({address}) already has {count} open sessions of the Bilimovich Explorer on this server (at most
{cap}). Close some of its tabs, wait {wait:.0f} seconds and reload this page.</p>
<p>A classroom behind one address (NAT): the server's operator raises the limit with
<code>bilimovich serve --max-sessions-per-address N</code>.</p></body></html>
"""


def _live(application_context: Any) -> set[str]:
    # Not the template session of --reuse-sessions (Panel keeps it, expiration blocked, for every page's HTML).
    return {s.id for s in application_context.sessions if not s.expiration_blocked}


def guard(cap: int, lifetime_s: float = 15.0) -> None:
    """Install the limits on what clients send and on the sessions of one address (idempotent)."""
    from bokeh.server.protocol_handler import ProtocolHandler
    from bokeh.server.views.ws import WSHandler
    from bokeh.util.token import get_session_id
    from panel.io.server import DocHandler as PanelDocHandler  # the page's handler (its get() is Panel's own)

    if getattr(ProtocolHandler.handle, "_guarded", False):
        return

    async def handle(self: ProtocolHandler, message: Any, connection: Any) -> Any:
        handler = self._handlers.get(message.msgtype)
        if handler is None:  # not a message a client sends: Bokeh closes the connection
            from bokeh.protocol.exceptions import ProtocolError

            raise ProtocolError(f"a {str(message.msgtype)[:40]!r} message is not expected on the server")
        why = refusal(message.msgtype, message.content, connection.session.document)
        if why is None:
            try:
                return await handler(message, connection)
            except Exception as exc:  # a value Bokeh's or the app's checks refused: the session goes on
                why = f"{type(exc).__name__}: {exc}"
        return _refuse(connection, message, why)  # outside the except: the answer carries no traceback

    handle._guarded = True  # type: ignore[attr-defined]
    ProtocolHandler.handle = handle  # type: ignore[method-assign]

    receive, handle_ws, async_open = WSHandler._receive, WSHandler._handle, WSHandler._async_open
    get = PanelDocHandler.get

    async def _receive(self: WSHandler, fragment: str | bytes) -> Any:
        if self.ws_connection is None or self.ws_connection.is_closing():  # refused: the rest is not read
            return None
        pending = getattr(self, "_pending_bytes", 0) + len(fragment)
        if pending > MAX_MESSAGE_BYTES:
            self._protocol_error(f"a message of more than {MAX_MESSAGE_BYTES} bytes")
            return None
        message = await receive(self, fragment)
        self._pending_bytes = 0 if message is not None else pending
        return message

    async def _handle(self: WSHandler, message: Any) -> Any:
        if not hasattr(self, "_buckets"):
            self._buckets = (_Bucket(MESSAGE_RATE, MESSAGE_BURST), _Bucket(EVENT_RATE, EVENT_BURST))
        events = message.content.get("events") if isinstance(message.content, dict) else None
        sent = sum(_costly(e) for e in events or ())
        sent = sent if sent <= MAX_EVENTS else 1  # refused whole (refusal()): nothing of it is run
        delay = max(self._buckets[0].wait(1.0), self._buckets[1].wait(sent) if sent else 0.0)
        # A flood: the client keeps the socket's queue full (a page's messages are small and few, so its queue is
        # empty whenever one is read); a connection whose queue stays above FLOOD_BYTES for FLOOD_S is closed.
        now = time.monotonic()
        if _unread(self) <= FLOOD_BYTES:
            self._flood_since = None
        elif now - (getattr(self, "_flood_since", None) or now) > FLOOD_S:
            log.warning("closed a connection from %s: a flood of messages", self.request.remote_ip)
            self.close(1008, "a flood of messages")
            return None
        else:
            self._flood_since = getattr(self, "_flood_since", None) or now
        if delay > 0:
            await asyncio.sleep(delay)  # the socket is read slower: the client waits, the others do not
        return await handle_ws(self, message)

    async def _async_open(self: WSHandler, token: str) -> None:
        sid, address = get_session_id(token), self.request.remote_ip
        live = _live(self.application_context)
        if sid not in live and OWNERS.count(address, live) >= cap:
            if time.monotonic() - _CAP_LOGGED.get(address, -60.0) >= 60.0:  # once a minute per address
                _CAP_LOGGED[address] = time.monotonic()
                log.warning("refused a session to %s: it has %d (--max-sessions-per-address)", address, cap)
            self.close(4029, "too many sessions from this address")
            return
        OWNERS.by_id.setdefault(sid, (address, time.monotonic(), False))  # counted while it is built
        try:
            await async_open(self, token)
        finally:
            if sid in _live(self.application_context):  # built: counted until it is discarded
                OWNERS.by_id[sid] = (address, OWNERS.by_id[sid][1], True)
            else:  # not built, or Panel's template session (the first page's): not counted
                OWNERS.by_id.pop(sid, None)

    async def get_page(self: PanelDocHandler, *args: Any, **kwargs: Any) -> None:
        address = self.request.remote_ip
        n = OWNERS.count(address, _live(self.application_context))
        if n >= cap:
            self.set_status(429)
            self.set_header("Content-Type", "text/html; charset=utf-8")
            self.set_header("Retry-After", str(int(lifetime_s) + 5))
            self.finish(CAP_PAGE.format(address=address, count=n, cap=cap, wait=lifetime_s + 5))
            return
        await get(self, *args, **kwargs)

    WSHandler._receive, WSHandler._handle, WSHandler._async_open = _receive, _handle, _async_open  # type: ignore
    PanelDocHandler.get = get_page  # type: ignore[method-assign]
    _short_server_logs()
    quiet_client_leaving()


class _ClientLeft(logging.Filter):
    """asyncio's report of a write to a websocket that its tab had closed (Panel dispatches an update in a task
    nobody awaits; the tab closed while it was on its way): a client leaving, not a fault of the server. The long
    day logged two such tracebacks in an hour of 30 students (benchmarks/long_day.py)."""

    def filter(self, record: logging.LogRecord) -> bool:
        from tornado.iostream import StreamClosedError
        from tornado.websocket import WebSocketClosedError

        exc = record.exc_info[1] if record.exc_info else None
        return not isinstance(exc, (WebSocketClosedError, StreamClosedError))


def quiet_client_leaving() -> None:
    """Drop asyncio's reports of writes to closed tabs (:class:`_ClientLeft`) from the server's log; once."""
    log = logging.getLogger("asyncio")
    if not any(isinstance(f, _ClientLeft) for f in log.filters):
        log.addFilter(_ClientLeft())


def _short_server_logs() -> None:
    """Records of Bokeh's server and Tornado cut to 500 characters, without the traceback of what a client sent:
    Bokeh logs a refused message whole (a 2 MB patch, one line of 2 MB)."""
    make = logging.getLogRecordFactory()

    def factory(*args: Any, **kwargs: Any) -> logging.LogRecord:
        record = make(*args, **kwargs)
        if record.name.startswith(("bokeh.server", "tornado")):
            text = record.getMessage()
            if len(text) > 500:
                record.msg, record.args = text[:500] + " [cut]", ()
            if record.name.startswith("bokeh.server.views.ws"):
                record.exc_info = None
        return record

    logging.setLogRecordFactory(factory)


def main(argv: list[str]) -> None:
    if argv[:1] == ["--launch"]:
        launch(json.loads(argv[1]))
        return
    no_delay()
    pages_once()
    lifetime = argv[argv.index("--unused-session-lifetime") + 1] if "--unused-session-lifetime" in argv else "15000"
    guard(int(os.environ.get(MAX_SESSIONS_ENV, DEFAULT_MAX_SESSIONS)), int(lifetime) / 1000)
    if "--num-procs" in argv:
        signal.signal(signal.SIGTERM, _stop_workers)  # the workers replace it with Bokeh's own
        signal.signal(signal.SIGINT, _stop_workers)
    from panel.command import main as panel_main

    sys.argv = ["panel", "serve", *argv]
    panel_main()


if __name__ == "__main__":
    main(sys.argv[1:])
