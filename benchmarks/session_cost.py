"""What one new session costs the server: CPU to build and send its page, memory while it sits idle.

    .venv/bin/python benchmarks/session_cost.py [--sessions 30] [--json out.json]

Serves the app (one process), warms it up, then opens ``--sessions`` tabs one after the other
the way a browser does (GET the page, websocket with its token, ACK, PULL-DOC) and measures, per
tab, the server CPU it took until the document was in the client's hands (in all, and per step: the
page's HTML, the session built, the document sent), the document's size and models; the event loop's own
CPU (``/proc/<pid>/schedstat`` of the main thread, nanoseconds) and the whole process's (all
threads, ``/proc/<pid>/stat``, 10 ms ticks). The tabs never say ``document_ready``, so nothing
is computed: this is the page alone, what a class opening the link at once queues on the event
loop. The server builds no spare section figures here (``BILIMOVICH_SPARE_FIGURES=0``): the figures are
what a page costs in all (spares move a part of it to before the class arrives, app/views.py). Then, with
every tab open and idle, the RSS per session.

A second pass opens the same number of tabs that do say ``document_ready`` (the first scene is
computed and its first points, layers and series sent), and reports the CPU per session with
the first view complete, and the RSS per idle session afterwards.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import json
import re
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
import load_test as lt
from harness import serve


def loop_cpu_s(pid: int) -> float:
    """CPU time of the process's main thread (the server's event loop), from schedstat (ns)."""
    with open(f"/proc/{pid}/schedstat") as fh:
        return int(fh.read().split()[0]) / 1e9


class PageOnly(lt.Tab):
    """A tab that loads the page and its document, and stops there (no ``document_ready``)."""

    async def page_only(self, timeout: float = 120.0, mark: Any = None) -> dict:
        """The page's three steps; ``mark(step)`` is called after each (the HTML, the session built, the
        document received). Returns the document."""
        from bokeh.protocol import Protocol
        from bokeh.protocol.receiver import Receiver
        from tornado.httpclient import AsyncHTTPClient, HTTPRequest
        from tornado.websocket import websocket_connect

        mark = mark or (lambda step: None)
        page = await AsyncHTTPClient().fetch(self.server.url, request_timeout=timeout)
        await mark("html")
        token = re.search(r'"token":"([^"]+)"', page.body.decode())[1]
        request = HTTPRequest(self.server.url.replace("http://", "ws://") + "/ws", request_timeout=timeout)
        self._receiver = Receiver(Protocol())
        ack = self._expect("ACK")
        self.ws = await websocket_connect(request, subprotocols=["bokeh", token], max_message_size=64 * 2**20)
        self._reader = asyncio.create_task(self._read_loop())
        await asyncio.wait_for(ack, timeout)
        await mark("session")
        reply = self._expect("PULL-DOC-REPLY")
        await self._send("PULL-DOC-REQ", {})
        doc = (await asyncio.wait_for(reply, timeout))["doc"]
        await mark("document")
        return doc


def _ms(xs: list[float]) -> dict[str, float]:
    s = sorted(xs)
    return {"n": len(s), "median": round(1e3 * statistics.median(s), 1),
            "p95": round(1e3 * s[min(len(s) - 1, round(0.95 * (len(s) - 1)))], 1),
            "max": round(1e3 * s[-1], 1)}  # fmt: skip


async def measure(server: Any, sessions: int) -> dict[str, Any]:
    pid = server.pid
    await lt._warm_up(server, 1)
    await asyncio.sleep(2.0)
    out: dict[str, Any] = {}

    # Pass 1: the page alone.
    base = lt.proc_status(pid)
    tabs, loop_s, proc_s, wall_s = [], [], [], []
    steps: dict[str, list[float]] = {"html": [], "session": [], "document": []}
    for i in range(sessions):
        t = PageOnly(server, f"p{i}")
        l0, c0, w0 = loop_cpu_s(pid), lt.proc_status(pid)["cpu_s"], time.perf_counter()
        last = [l0]

        async def mark(step: str, last: list[float] = last) -> None:
            # The event loop's CPU per step: the GET's HTML, the session built (app/main.py), the document sent.
            await asyncio.sleep(0.05)  # let the server finish the step
            now = loop_cpu_s(pid)
            steps[step].append(now - last[0])
            last[0] = now

        doc = await t.page_only(mark=mark)
        loop_s.append(loop_cpu_s(pid) - l0)
        proc_s.append(lt.proc_status(pid)["cpu_s"] - c0)
        wall_s.append(time.perf_counter() - w0)
        tabs.append(t)
    await asyncio.sleep(1.0)
    idle = lt.proc_status(pid)
    out["page_only"] = {
        "event_loop_cpu_ms": _ms(loop_s),
        "event_loop_cpu_ms_per_step": {k: _ms(v) for k, v in steps.items()},
        "document": {"models": len(lt._models(doc)), "kB": round(len(json.dumps(doc)) / 1e3, 1)},
        "process_cpu_ms_mean": round(1e3 * sum(proc_s) / sessions, 1),
        "wall_ms": _ms(wall_s),
        "rss_per_session_mb": round((idle["rss_mb"] - base["rss_mb"]) / sessions, 2),
    }
    for t in tabs:
        await t.close()
    await asyncio.sleep(lt.discard_wait(3000))

    # Pass 2: the first view complete (first scene, layers, series).
    base = lt.proc_status(pid)
    tabs, loop_s, proc_s = [], [], []
    for i in range(sessions):
        t = lt.Tab(server, f"v{i}")
        l0, c0 = loop_cpu_s(pid), lt.proc_status(pid)["cpu_s"]
        await t.open(120)
        await asyncio.sleep(1.5)  # the layers and the series after the first scene
        loop_s.append(loop_cpu_s(pid) - l0)
        proc_s.append(lt.proc_status(pid)["cpu_s"] - c0)
        tabs.append(t)
    await asyncio.sleep(2.0)
    idle = lt.proc_status(pid)
    out["first_view"] = {
        "event_loop_cpu_ms": _ms(loop_s),
        "process_cpu_ms_mean": round(1e3 * sum(proc_s) / sessions, 1),
        "rss_per_idle_session_mb": round((idle["rss_mb"] - base["rss_mb"]) / sessions, 2),
    }
    for t in tabs:
        await t.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=30)
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args()
    env = {"BILIMOVICH_SPARE_FIGURES": "0"}
    with serve("/tmp/session_cost_panel.log", session_lifetime=3000, env=env) as server:
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            report = pool.submit(asyncio.run, measure(server, args.sessions)).result()
    report["command"] = " ".join(sys.argv)
    text = json.dumps(report, indent=1)
    if args.json:
        Path(args.json).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
