"""How the app is served: processes, flags, messages from pages, and stopping (app/serve.py, app/ui.py)."""

from __future__ import annotations

import os
import signal
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from clirun import run_cli

from app.serve import command
from app.ui import check_message
from explorer_core.config import resolve_procs, usable_cpus

sys.path.insert(0, str(Path(__file__).resolve().parent / "browser"))
from harness import serve, tree_pids


def test_procs_is_a_count_or_auto() -> None:
    assert resolve_procs("auto") == usable_cpus() >= 1
    assert resolve_procs("3") == 3 and resolve_procs(" 1 ") == 1
    for bad, needle in (("0", "between 1 and 64, got 0"), ("65", "got 65"), ("two", "'two'"), ("", "''")):
        with pytest.raises(ValueError, match="--procs") as exc:
            resolve_procs(bad)
        assert needle in str(exc.value)


def test_serve_refuses_a_bad_process_count_in_one_line() -> None:
    rc, out, err = run_cli("serve", "--procs", "lots")
    assert rc == 2 and "--procs must be a whole number or 'auto', got 'lots'" in err and "Traceback" not in err


def test_the_server_command() -> None:
    cmd, env = command(port=5006, address="0.0.0.0", threads=4, origins=["a.example:443"], session_lifetime=15000,
                       procs=3)  # fmt: skip
    assert cmd[1:3] == ["-m", "app.serve"] and "--reuse-sessions" in cmd and "--liveness" in cmd
    assert cmd[cmd.index("--num-procs") + 1] == "3"
    assert cmd[cmd.index("--allow-websocket-origin") + 1] == "a.example:443"
    assert env["BOKEH_RESOURCES"] == "server"  # nothing from a CDN
    assert env["BOKEH_VALIDATE_DOC"] == "false"  # checked here instead: test_pages_pass_bokehs_checks
    assert env["MALLOC_ARENA_MAX"] == "2"  # no RSS growth over open/close cycles (docs/load.md)
    one, _ = command(port=5006, address="127.0.0.1", threads=4, origins=[], session_lifetime=15000, procs=1)
    assert "--num-procs" not in one
    # Hostile clients (tests/test_hostile_client.py): one frame at most 2 MB, sessions per address for guard().
    assert cmd[cmd.index("--websocket-max-message-size") + 1] == str(2 * 2**20)
    assert env["BILIMOVICH_MAX_SESSIONS_PER_ADDRESS"] == "50"
    _, capped = command(port=5006, address="127.0.0.1", threads=4, origins=[], session_lifetime=15000, procs=1,
                        max_sessions_per_address=7)  # fmt: skip
    assert capped["BILIMOVICH_MAX_SESSIONS_PER_ADDRESS"] == "7"


def test_serve_refuses_a_bad_session_cap_in_one_line() -> None:
    rc, _, err = run_cli("serve", "--max-sessions-per-address", "0")
    assert rc == 2 and "max-sessions-per-address must be between 1 and 100000, got 0" in err


def test_what_a_page_never_sends_is_refused() -> None:
    """app.serve.refusal: what a page sends passes (events, its plot's and tools' properties as numbers, flags,
    short texts, references); documents pushed, structure changes, server-owned models and odd values do not."""
    from bokeh.document import Document
    from bokeh.models import ColumnDataSource, Range1d

    from app.serve import MAX_EVENTS, refusal

    doc = Document()
    rng, src = Range1d(0, 1), ColumnDataSource({"q": [1.0]})
    doc.add_root(rng)
    doc.add_root(src)

    def change(model, attr: str, new) -> dict:
        return {"events": [{"kind": "ModelChanged", "model": {"id": model.id}, "attr": attr, "new": new}]}

    event = {"kind": "MessageSent", "msg_type": "bokeh_event", "msg_data": {"type": "event", "name": "tap"}}
    for ok in (change(rng, "start", -3.5), change(rng, "end", 2), change(rng, "name", "x"), change(rng, "tags", [1]),
               change(rng, "js_property_callbacks", None), {"events": [event]}, {"events": []}):  # fmt: skip
        assert refusal("PATCH-DOC", ok, doc) is None, ok
    assert refusal("PULL-DOC-REQ", {}, doc) is None
    nan = {"type": "number", "value": "nan"}
    bad = [
        (change(rng, "start", nan), "no widget sends"), (change(rng, "start", 1e400), "no widget sends"),
        (change(rng, "name", "x" * 1001), "no widget sends"), (change(rng, "tags", [[1]]), "no widget sends"),
        (change(rng, "tags", {"type": "object", "id": "n"}), "no widget sends"),
        (change(src, "data", {"q": [2.0]}), "ColumnDataSource.data (set by the server only)"),
        ({"events": [{"kind": "ModelChanged", "model": {"id": "p0"}, "attr": "x", "new": 1}]}, "unknown model"),
        ({"events": [{"kind": "RootRemoved", "model": {"id": rng.id}}]}, "'RootRemoved' event"),
        ({"events": [event] * (MAX_EVENTS + 1)}, f"{MAX_EVENTS + 1} events in one message"),
        ({"events": "all"}, "without a list"),
    ]  # fmt: skip
    for content, needle in bad:
        why = refusal("PATCH-DOC", content, doc)
        assert why is not None and needle in why, (content, why)
    assert "PUSH-DOC" in refusal("PUSH-DOC", {"doc": {}}, doc)


def test_pages_pass_bokehs_checks() -> None:
    """What the server no longer checks on every page (BOKEH_VALIDATE_DOC=false): Bokeh's integrity
    checks of a page's document, with every layer drawn and every analysis tab opened."""
    from bokeh.core.validation.check import check_integrity
    from bokeh.document import Document

    from app.page import TAB_CLASSES, Page
    from app.runner import WARM

    WARM.set()
    page = Page({"scene": "fig8B"}, lambda fn: fn())
    doc = Document()
    page.ui.server_doc(doc)
    view = (-2.0, 1.5, -3.5, 0.5)
    page.fig.set_density(np.ones((4, 4)), view)
    page.fig.set_basins(np.zeros((4, 4), dtype=int), view, {0: "#1f77b4"})
    page.fig.set_manifolds([(np.array([0.0, 1.0]), np.array([0.0, 1.0]), "unstable")], [(0.5, 0.5, "homoclinic")])
    page.fig.set_ics(np.array([[0.1, -0.2]]))

    def errors() -> list:
        refs = set().union(*(root.references() for root in doc.roots))
        return check_integrity(refs).error

    assert errors() == []
    for name in TAB_CLASSES:
        page.handle({"action": "tab", "tab": name})
        assert errors() == [], name
    page.close()


def test_messages_from_a_page_are_checked() -> None:
    assert check_message({"commit": "alpha", "text": "0.2"}) == {"commit": "alpha", "text": "0.2"}
    assert check_message({"commit": "show_tracks", "text": False}) == {"commit": "show_tracks", "text": False}
    long = check_message({"commit": "alpha", "text": "9" * 5000})
    assert long is not None and len(long["text"]) == 201  # answered: refused as too long
    assert check_message({"action": "tab", "tab": "chart"}) == {"action": "tab", "tab": "chart"}
    assert check_message({"action": "presentation", "on": True}) == {"action": "presentation", "on": True}
    bad = [None, [], "stop", {"commit": "nope", "text": "1"}, {"commit": "alpha", "text": {"x": 1}},
           {"action": "rm -rf"}, {"action": "tab", "tab": 3}, {"action": "presentation", "on": "yes"}]  # fmt: skip
    for msg in bad:
        assert check_message(msg) is None, msg


def test_workers_share_the_port_and_stop_with_the_parent(tmp_path) -> None:
    """--procs 2: two workers answer pages; SIGTERM to the parent (docker stop) ends all of them."""
    with serve(str(tmp_path / "serve.log"), procs=2) as server:
        pids = tree_pids(server.pid)
        assert len(pids) == 3, pids  # the parent and two workers
        for _ in range(4):
            with urllib.request.urlopen(server.url, timeout=60) as r:
                assert r.status == 200 and b"Bilimovich Explorer" in r.read()
        os.kill(server.pid, signal.SIGTERM)
        deadline = time.monotonic() + 10
        while any(Path(f"/proc/{p}").exists() and "zombie" not in _state(p) for p in pids):
            assert time.monotonic() < deadline, f"still running 10 s after SIGTERM: {pids}"
            time.sleep(0.1)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/status").read_text().split("State:")[1].split("\n")[0]
    except (OSError, IndexError):
        return "zombie"


def test_the_servers_websockets_send_each_frame_at_once() -> None:
    """app.serve.no_delay (installed by ``python -m app.serve`` before Panel starts): every websocket Bokeh opens sets
    TCP_NODELAY before anything else, so a message's frames after the first never wait for a delayed ACK."""
    from bokeh.server.views.ws import WSHandler

    import app.serve as serve_mod

    calls: list[str] = []
    original = WSHandler.open

    def bokeh_open(self: object, *args: object) -> None:
        calls.append("open")

    class Handler:
        def set_nodelay(self, on: bool) -> None:
            calls.append(f"nodelay {on}")

    WSHandler.open = bokeh_open  # type: ignore[method-assign]
    try:
        serve_mod.no_delay()
        serve_mod.no_delay()  # once only
        WSHandler.open(Handler())  # type: ignore[arg-type]
    finally:
        WSHandler.open = original  # type: ignore[method-assign]
    assert calls == ["nodelay True", "open"]
    assert "no_delay()" in Path(serve_mod.__file__).read_text().split("def main(")[1]


def test_a_write_to_a_tab_that_closed_is_not_logged_as_an_error(caplog) -> None:
    """asyncio logs a task's unretrieved WebSocketClosedError (Panel's update to a tab that had closed) as an error
    with its traceback: the long day's server log had two such in an hour. A real error is still logged."""
    import asyncio

    from tornado.iostream import StreamClosedError
    from tornado.websocket import WebSocketClosedError

    from app.serve import quiet_client_leaving

    quiet_client_leaving()
    quiet_client_leaving()  # once: a second call adds no second filter
    loop = asyncio.new_event_loop()
    try:
        for exc in (WebSocketClosedError(), StreamClosedError(), RuntimeError("a bug")):
            loop.default_exception_handler({"message": "Task exception was never retrieved", "exception": exc})
    finally:
        loop.close()
    logged = [r for r in caplog.records if r.name == "asyncio"]
    assert [type(r.exc_info[1]) for r in logged] == [RuntimeError]


def test_a_pages_html_is_rendered_once_and_carries_each_requests_token(monkeypatch) -> None:
    """app.serve.pages_once: the template document's HTML is rendered once (Panel walked its models for every
    GET); each request gets it with its own token, and a new document, title or prefix is rendered anew."""
    import panel.io.server as panel_server

    import app.serve as serve_mod

    rendered: list[tuple[str, str]] = []

    def render(session: object, resources: object, title: str, token: str | None = None, **kw: object) -> str:
        rendered.append((title, str(token)))
        return f'<html><title>{title}</title><script>[{{"token":"{token}"}}]</script></html>'

    class Doc:  # a document (weakly referenced by the cache)
        pass

    class Session:
        def __init__(self, doc: Doc, token: str) -> None:
            self.document, self.token = doc, token

    class Resources:
        mode, root_url = "server", "/"

    monkeypatch.setattr(panel_server, "server_html_page_for_session", render)
    serve_mod.pages_once()
    serve_mod.pages_once()  # once only
    page = panel_server.server_html_page_for_session
    template = Doc()
    first = page(Session(template, "t0"), Resources(), "Explorer", token="token-a", template=None)
    second = page(Session(template, "t0"), Resources(), "Explorer", token="token-b", template=None)
    assert '"token":"token-a"' in first and '"token":"token-b"' in second
    assert first.replace("token-a", "token-b") == second
    assert rendered == [("Explorer", serve_mod.TOKEN_SLOT)]  # one render for both
    page(Session(template, "t0"), Resources(), "Other", token="token-c", template=None)
    page(Session(Doc(), "t1"), Resources(), "Explorer", template=None)  # the session's own token
    assert [r[0] for r in rendered] == ["Explorer", "Other", "Explorer"]
    assert '"token":"t1"' in page(Session(Doc(), "t1"), Resources(), "Explorer", template=None)
    assert "pages_once()" in Path(serve_mod.__file__).read_text().split("def main(")[1]


def test_every_page_of_a_served_app_has_a_token_of_its_own(tmp_path) -> None:
    """The HTML rendered once (pages_once) still gives each visitor a session of their own: two GETs differ in
    their token only, and each token opens a session whose document comes back."""
    import asyncio
    import concurrent.futures
    import re

    from bokeh.protocol import Protocol
    from bokeh.protocol.receiver import Receiver
    from tornado.websocket import websocket_connect

    with serve(str(tmp_path / "serve.log")) as server:
        pages = [urllib.request.urlopen(server.url, timeout=60).read().decode() for _ in range(2)]
        tokens = [re.search(r'"token":"([^"]+)"', p)[1] for p in pages]
        assert tokens[0] != tokens[1] and pages[0].replace(tokens[0], tokens[1]) == pages[1]

        async def pull(token: str) -> dict:
            ws = await websocket_connect(server.url.replace("http://", "ws://") + "/ws", subprotocols=["bokeh", token])
            receiver, protocol = Receiver(Protocol()), Protocol()
            try:
                while True:  # ACK, then the document on request
                    msg = await receiver.consume(await ws.read_message())
                    if msg is None:
                        continue
                    if msg.header["msgtype"] == "ACK":
                        req = protocol.create("PULL-DOC-REQ")
                        for part in (req.header_json, req.metadata_json, req.content_json):
                            await ws.write_message(part)
                    elif msg.header["msgtype"] == "PULL-DOC-REPLY":
                        return msg.content["doc"]
            finally:
                ws.close()

        # A loop of its own in a thread: an earlier test in this worker may leave one marked running here.
        with concurrent.futures.ThreadPoolExecutor(1) as own:
            docs = [own.submit(asyncio.run, asyncio.wait_for(pull(t), 120)).result() for t in tokens]
        assert all(any("ExplorerUI" in str(r) for r in d["roots"]) for d in docs)
