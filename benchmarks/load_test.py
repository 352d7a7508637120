"""A classroom under load: N concurrent sessions on one server, driven through Bokeh's websocket protocol.

    .venv/bin/python benchmarks/load_test.py --sessions 30 --changes 5 --cycles 100 --chart [--procs 2] [--json F]

Serves the app warm (``python -m explorer_core.cli serve``, as the browser tests do) and opens
``--sessions`` tabs without a browser, **all at once** by default (``--stagger 0``). Each
:class:`Tab` does what a browser does: GET the page (``/main``), read the session token from
it, open the websocket with it (ACK, PULL-DOC, then PATCH-DOC both ways), send the
``document_ready`` event, and wait for the first section points and the full scene. It finds
the models by the names the app gives them (``section_source``; the page component, whose data
model carries ``values`` and ``view``). Per tab it times, from the GET: the page (the document
received), the first section points, the full scene. Meanwhile ``/liveness`` is asked every
0.1 s and its answer time recorded.

Then each tab moves ``alpha`` ``--changes`` times (the message a slider's release sends: a
``commit`` to the page component), pausing ``--think`` seconds between a finished scene and the
next move; per move it times, on the client, the first points of the new run (the section
source's data replaced and its generation tag bumped) and the full scene (the status reports a
finished run). With ``--chart`` tab 0 first starts a chart of regimes (the Chart tab's Run).
Then every tab closes and the server's CPU use is sampled (work must stop), and ``--cycles``
open/close cycles follow, with the server's RSS (summed over its worker processes, from
``/proc``) read at the start, every ``--every`` cycles and at the end, each time after waiting
for the server to discard the closed sessions (``--session-lifetime``, 15 s by default).

What this does not measure: the browser's own rendering (``benchmarks/app_latency.py`` and
``benchmarks/browser_class.py`` do). The client runs on the same machine as the server and takes
some CPU from it. Prints a Markdown table; ``--json`` writes every figure. :func:`run` is what the
tests call.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import contextlib
import itertools
import json
import os
import random
import re
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: ``bilimovich serve`` discards a closed session after --session-lifetime (15 s), checked every 5 s.
SESSION_LIFETIME_MS = 15000
DEFAULT_ALPHA = 0.1  # the default scene (fig1C)


def discard_wait(lifetime_ms: int) -> float:
    """Seconds after which the server has discarded every session closed before."""
    return lifetime_ms / 1000 + min(5.0, max(0.2, lifetime_ms / 3000)) + 2.0


# --- the server ------------------------------------------------------------------------------------

sys.path.insert(0, str(ROOT / "tests" / "browser"))
from harness import Server, serve, tree_pids  # noqa: E402  (one way to start the app for tests and benchmarks)

from explorer_core.config import resolve_procs  # noqa: E402


def proc_status(pid: int) -> dict[str, float]:
    """RSS (MB), threads and CPU seconds (user + system) of a process and its workers, from /proc."""
    out = {"rss_mb": 0.0, "threads": 0, "cpu_s": 0.0}
    for p in tree_pids(pid):
        with contextlib.suppress(OSError):
            with open(f"/proc/{p}/status") as fh:
                for line in fh:
                    if line.startswith("VmRSS:"):
                        out["rss_mb"] += int(line.split()[1]) / 1024
                    elif line.startswith("Threads:"):
                        out["threads"] += int(line.split()[1])
            with open(f"/proc/{p}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            out["cpu_s"] += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return out


# --- one tab -------------------------------------------------------------------------------------


def _models(doc: Any) -> dict[str, dict]:
    """Every model of a serialized document by id (Bokeh defines each once, then refers to it by id)."""
    found: dict[str, dict] = {}
    stack = [doc]
    while stack:
        o = stack.pop()
        if isinstance(o, dict):
            if o.get("type") == "object" and "id" in o:
                found[o["id"]] = o
            stack.extend(o.values())
        elif isinstance(o, list):
            stack.extend(o)
    return found


def _column_length(data: Any, name: str) -> int:
    """Length of one column in a serialized ``data`` map (ndarray reps carry their shape)."""
    if isinstance(data, dict) and data.get("type") == "map":
        data = {k: v for k, v in data["entries"]}
    col = data.get(name) if isinstance(data, dict) else None
    if isinstance(col, list):
        return len(col)
    if isinstance(col, dict) and col.get("type") == "ndarray":
        return int(col["shape"][0])
    return 0


def _ui_event(name: str, values: dict) -> dict:
    """A UI event (document ready, a page message) as a page sends it, inside a PATCH-DOC."""
    event = {"type": "event", "name": name, "values": values}
    return {"kind": "MessageSent", "msg_type": "bokeh_event", "msg_data": event}


def _plain(obj: Any) -> Any:
    """Bokeh's serialized maps ({"type": "map", "entries": ...}) as plain dicts, recursively."""
    if isinstance(obj, dict):
        if obj.get("type") == "map":
            return {k: _plain(v) for k, v in obj.get("entries", [])}
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj


@dataclass
class Change:
    """One slider move as the client saw it; times in seconds from sending the change."""

    session: str
    value: float
    first_s: float | None = None
    full_s: float | None = None
    points: int = 0
    t0: float = field(default=0.0, repr=False)
    gen0: int = field(default=0, repr=False)
    status_seq: int = field(default=-1, repr=False)


class Tab:
    """One simulated browser tab: the page over HTTP, then a Bokeh session over a websocket; it renders nothing."""

    def __init__(self, server: Server, name: str) -> None:
        self.server = server
        self.name = name
        self.ws: Any = None
        self.ids: dict[str, str] = {}
        self.gen = 0  # generation tag of the section source (bumped by each new run's first points)
        self.points = 0  # points of the current generation
        self.view: dict[str, Any] = {}
        self.status_seq = 0
        self.errors: list[str] = []
        self.probe: Change | None = None
        self.closed = False
        self.times: dict[str, float] = {}  # seconds from the GET: page (document in hand), first points, full scene
        self.document: dict[str, Any] = {}  # the document as pulled (its size and models are reported)
        self._changed = asyncio.Event()
        self._replies: dict[str, asyncio.Future] = {}
        self._arrived: dict[str, float] = {}
        self._reader: asyncio.Task | None = None
        self._receiver: Any = None
        self._msgid = itertools.count()

    @property
    def status(self) -> str:
        return str((self.view.get("section") or {}).get("status", ""))

    # --- protocol ---

    async def _send(self, msgtype: str, content: dict) -> None:
        header = {"msgid": f"{self.name}-{next(self._msgid)}", "msgtype": msgtype}
        for part in (header, {}, content):
            await self.ws.write_message(json.dumps(part))

    async def _read_loop(self) -> None:
        while True:
            frag = await self.ws.read_message()
            t = time.perf_counter()  # when it arrived, not when this client finished decoding it
            if frag is None:
                self.closed = True
                self._changed.set()
                for fut in self._replies.values():
                    if not fut.done():
                        fut.set_exception(ConnectionError(f"{self.name}: the server closed the connection"))
                return
            msg = await self._receiver.consume(frag)
            if msg is None:
                continue
            kind = msg.header["msgtype"]
            if kind == "PATCH-DOC":
                self._on_events(msg.content.get("events", []), t)
            elif kind in self._replies and not self._replies[kind].done():
                self._arrived[kind] = t
                self._replies[kind].set_result(msg.content)
            elif kind == "ERROR":
                self.errors.append(str(msg.content)[:300])

    def _expect(self, kind: str) -> asyncio.Future:
        self._replies[kind] = asyncio.get_running_loop().create_future()
        return self._replies[kind]

    def _on_events(self, events: list[dict], t: float) -> None:
        ids = self.ids
        for ev in events:
            mid = ev.get("model", {}).get("id") if isinstance(ev.get("model"), dict) else None
            kind, attr = ev.get("kind"), ev.get("attr")
            if mid is None:
                continue
            if mid == ids.get("section"):
                if kind == "ColumnDataChanged" or (kind == "ModelChanged" and attr == "data"):
                    self.points = _column_length(ev.get("data", ev.get("new")), "q")
                elif kind == "ColumnsStreamed":
                    self.points += _column_length(ev.get("data"), "q")
                elif kind == "ModelChanged" and attr == "tags":
                    self.gen = int(ev["new"][0]) if ev["new"] else 0
            elif mid == ids.get("data") and kind == "ModelChanged" and attr == "view":
                self.view = _plain(ev["new"])
                self.status_seq += 1
        p = self.probe
        if p is not None:
            if p.first_s is None and self.gen != p.gen0 and self.points > 0:
                p.first_s, p.status_seq = t - p.t0, self.status_seq
            # The status line reports the end of the run after its last points.
            finished = "trajectories" in self.status and "computing" not in self.status
            if p.first_s is not None and p.full_s is None and self.status_seq > p.status_seq and finished:
                p.full_s, p.points = t - p.t0, self.points
        self._changed.set()

    async def _until(self, pred: Callable[[], bool], timeout: float) -> bool:
        deadline = time.perf_counter() + timeout
        while not pred():
            if self.closed:
                return False
            self._changed.clear()
            if pred():
                break
            left = deadline - time.perf_counter()
            if left <= 0:
                return False
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._changed.wait(), left)
        return True

    # --- what a user does ---

    async def open(self, timeout: float = 180.0, query: str = "") -> float:
        """GET the page, connect with its token, load the document, say it is ready, wait for the first full
        scene; seconds taken. ``times`` gets the page, first points and full scene times from the GET."""
        from bokeh.protocol import Protocol
        from bokeh.protocol.receiver import Receiver
        from tornado.httpclient import AsyncHTTPClient, HTTPRequest
        from tornado.websocket import websocket_connect

        t0 = time.perf_counter()
        page = await AsyncHTTPClient().fetch(self.server.url + query, request_timeout=timeout)
        token = re.search(r'"token":"([^"]+)"', page.body.decode("utf-8", "replace"))
        if token is None:
            raise RuntimeError(f"{self.name}: no session token in the page")
        ws_url = self.server.url.replace("http://", "ws://") + "/ws"
        request = HTTPRequest(ws_url, connect_timeout=timeout, request_timeout=timeout)
        self._receiver = Receiver(Protocol())
        ack = self._expect("ACK")
        self.ws = await websocket_connect(request, subprotocols=["bokeh", token[1]], max_message_size=64 * 2**20)
        # As a browser's socket: Chromium and Firefox set TCP_NODELAY. Without it a message's frames after the first
        # wait for the server's delayed ACK (~40 ms): every "shown" of a played frame came 43 ms late.
        self.ws.protocol.set_nodelay(True)
        self._reader = asyncio.create_task(self._read_loop())
        await asyncio.wait_for(ack, timeout)  # the server builds the session's page first
        reply = self._expect("PULL-DOC-REPLY")
        await self._send("PULL-DOC-REQ", {})
        doc = (await asyncio.wait_for(reply, timeout))["doc"]
        self.times["page"] = self._arrived["PULL-DOC-REPLY"] - t0
        self.document = doc
        self._index(doc)
        self.probe = Change(self.name, DEFAULT_ALPHA, t0=t0, gen0=self.gen)
        await self._send("PATCH-DOC", {"events": [_ui_event("document_ready", {})]})
        if not await self._until(lambda: self.probe.full_s is not None, timeout):
            raise TimeoutError(f"{self.name}: no first scene after {timeout} s (status {self.status!r})")
        self.times["first_points"], self.times["full_scene"] = self.probe.first_s, self.probe.full_s
        return time.perf_counter() - t0

    def _index(self, doc: dict) -> None:
        models = _models(doc)
        for m in models.values():
            attrs = m.get("attributes", {})
            if attrs.get("name") == "section_source":
                self.ids["section"] = m["id"]
            if attrs.get("class_name") == "ExplorerUI":
                self.ids["ui"] = m["id"]
                self.ids["data"] = attrs["data"]["id"]
        data = models[self.ids["data"]]["attributes"]
        self.view = _plain(data.get("view", {}))

    async def message(self, data: dict) -> None:
        """What the page sends (model.send_msg): a typed value or an action."""
        event = _ui_event("data_event", {"model": {"id": self.ids["ui"]}, "data": data})
        await self._send("PATCH-DOC", {"events": [event]})

    async def show_tab(self, tab: str) -> None:
        """Open a tab of the page (as a click on it does)."""
        await self.message({"action": "tab", "tab": tab})

    async def change(self, name: str, value: float, timeout: float = 120.0) -> Change:
        """Commit a value (a slider's release); time the first new points and the full scene."""
        self.probe = p = Change(self.name, value, t0=time.perf_counter(), gen0=self.gen)
        await self.message({"commit": name, "text": repr(value)})
        await self._until(lambda: p.full_s is not None, timeout)
        return p

    async def start_chart(self, grid: tuple[int, int], periods: int, transient: int) -> None:
        """Open the Chart tab, fill it in and press Run."""
        await self.show_tab("chart")
        for name, text in (("chart_grid", f"{grid[0]},{grid[1]}"), ("chart_periods", str(periods)),
                           ("chart_transient", str(transient))):  # fmt: skip
            await self.message({"commit": name, "text": text})
        await self.message({"action": "run", "tab": "chart"})
        await asyncio.sleep(0.5)
        await self.show_tab("section")  # and back to the section, to move sliders meanwhile

    def chart_progress(self) -> tuple[int, int, bool]:
        """(tiles done, tiles, finished) from the Chart tab's view."""
        chart = self.view.get("chart") or {}
        m = re.search(r"(\d+)/(\d+) tiles", str(chart.get("message", "")))
        done, total = (int(m[1]), int(m[2])) if m else (0, 0)
        result = " ".join(chart.get("result") or [])
        return done, total, not chart.get("running") and ("pixels:" in result or "No pixel" in result)

    async def close(self) -> None:
        if self.ws is not None:
            self.ws.close()
        if self._reader is not None:
            self._reader.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._reader


# --- the scenarios -------------------------------------------------------------------------------


_PRIVATE = ("t0", "gen0", "status_seq")


def _pct(xs: list[float], q: float) -> float | None:
    if not xs:
        return None
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q * (len(s) - 1))))]


def _summary(xs: list[float], scale: float = 1e3, digits: int = 0) -> dict[str, float | None]:
    r = {"n": len(xs)}
    for label, q in (("p50", 0.5), ("p95", 0.95), ("max", 1.0)):
        v = _pct(xs, q)
        r[label] = None if v is None else round(v * scale, digits)
    return r


#: The /liveness prober, run in a process of its own: the tabs' client is busy decoding pages and
#: points, and its event loop (or its GIL) would delay the timing of the answers, not the server.
_PROBE = """
import sys, time, urllib.request
url, period = sys.argv[1], float(sys.argv[2])
while True:
    t0 = time.perf_counter()
    try:
        urllib.request.urlopen(url, timeout=30).read()
        ok = 1
    except Exception:
        ok = 0
    dt = time.perf_counter() - t0
    print(f"{dt:.6f} {ok}", flush=True)
    time.sleep(max(0.0, period - dt))
"""


def _server_priority() -> None:
    # The prober asks as an outside monitor would, at the server's priority, not the tabs' (needs privilege).
    with contextlib.suppress(OSError):
        os.setpriority(os.PRIO_PROCESS, 0, 0)


class Liveness:
    """Asks ``/liveness`` every ``period`` seconds (one request at a time, from a separate process) and
    records how long each answer took."""

    def __init__(self, server: Server, period: float = 0.1) -> None:
        self.url = server.url.rsplit("/", 1)[0] + "/liveness"
        self.period = period
        self.times: list[float] = []
        self.failures = 0
        self._proc: Any = None
        self._task: asyncio.Task | None = None

    def start(self) -> None:
        self._task = asyncio.create_task(self._loop())

    async def _loop(self) -> None:
        self._proc = await asyncio.create_subprocess_exec(
            sys.executable, "-c", _PROBE, self.url, str(self.period), stdout=asyncio.subprocess.PIPE,
            preexec_fn=_server_priority,
        )  # fmt: skip
        while True:
            line = await self._proc.stdout.readline()
            if not line:
                return
            dt, ok = line.split()
            self.times.append(float(dt))
            self.failures += ok == b"0"

    def take(self) -> dict[str, Any]:
        """Answer times (ms) since the last call: p50 / p95 / max, and how many."""
        out = {**_summary(self.times), "failures": self.failures}
        self.times, self.failures = [], 0
        return out

    async def stop(self) -> None:
        if self._proc is not None and self._proc.returncode is None:
            self._proc.kill()
            await self._proc.wait()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task


async def _idle_cpu(pid: int, seconds: float) -> float:
    """Server CPU seconds used over ``seconds`` of wall time (after the tabs closed: should be ~0)."""
    before = proc_status(pid)["cpu_s"]
    await asyncio.sleep(seconds)
    return round(proc_status(pid)["cpu_s"] - before, 2)


def _alpha(session: int, k: int) -> float:
    # Small distinct moves around the default scene's alpha (0.1), never the current value.
    return round(DEFAULT_ALPHA + 0.001 * (1 + (7 * session + 13 * k) % 40) * (1 if k % 2 == 0 else -1), 3)


async def classroom(
    server: Server,
    sessions: int,
    changes: int,
    *,
    chart: tuple[int, int] | None = None,
    chart_periods: int = 300,
    chart_transient: int = 300,
    chart_timeout: float = 600.0,
    think: float = 3.0,
    stagger: float = 0.0,
    timeout: float = 180.0,
    seed: int = 0,
    settle: float = 3.0,
) -> dict[str, Any]:
    """Open ``sessions`` tabs (together), move alpha ``changes`` times in each, close them; what every user saw."""
    rng = random.Random(seed)
    pid = server.pid
    base = proc_status(pid)
    tabs = [Tab(server, f"s{i:02d}") for i in range(sessions)]
    probe = Liveness(server)
    probe.start()

    async def opener(i: int) -> float:
        await asyncio.sleep(i * stagger)
        return await tabs[i].open(timeout)

    t_open = time.perf_counter()
    open_s = await asyncio.gather(*(opener(i) for i in range(sessions)))
    all_open_s = time.perf_counter() - t_open
    liveness_open = probe.take()
    # Idle sessions: every first scene and its layers done, nothing moving.
    await asyncio.sleep(settle)
    opened = proc_status(pid)
    peak = [opened["rss_mb"]]
    stop = asyncio.Event()

    async def sampler() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], proc_status(pid)["rss_mb"])
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(stop.wait(), 0.5)

    sampling = asyncio.create_task(sampler())
    results: list[Change] = []
    chart_t0 = time.perf_counter()
    if chart is not None:
        await tabs[0].start_chart(chart, chart_periods, chart_transient)

    async def student(i: int) -> None:
        await asyncio.sleep(rng.uniform(0, think))
        for k in range(changes):
            results.append(await tabs[i].change("alpha", _alpha(i, k), timeout))
            await asyncio.sleep(rng.uniform(0.5, 1.5) * think)

    t_changes = time.perf_counter()
    await asyncio.gather(*(student(i) for i in range(sessions)))
    changes_s = time.perf_counter() - t_changes
    liveness_changes = probe.take()
    await probe.stop()
    chart_report = None
    if chart is not None:
        await asyncio.sleep(1.0)
        done_during, total, _ = tabs[0].chart_progress()
        finished = await tabs[0]._until(lambda: tabs[0].chart_progress()[2], chart_timeout)
        chart_report = {
            "grid": list(chart),
            "periods": chart_periods,
            "transient": chart_transient,
            "tiles": total,
            "tiles_done_while_others_moved": done_during,
            "finished": finished,
            "total_s": round(time.perf_counter() - chart_t0, 1) if finished else None,
        }
    stop.set()
    await sampling
    errors = [e for t in tabs for e in t.errors]
    for t in tabs:
        await t.close()
    cpu_after_close = await _idle_cpu(pid, 3.0)
    after = proc_status(pid)

    first = [c.first_s for c in results if c.first_s is not None]
    full = [c.full_s for c in results if c.full_s is not None]
    per_session: dict[str, list[Change]] = {t.name: [] for t in tabs}
    for c in results:
        per_session[c.session].append(c)
    return {
        "sessions": sessions,
        "changes_per_session": changes,
        "open_s": _summary(open_s, 1.0, 2),
        "open_stagger_s": stagger,
        "document": {"models": len(_models(tabs[0].document)), "kB": round(len(json.dumps(tabs[0].document)) / 1e3, 1)},
        "open_page_s": _summary([t.times["page"] for t in tabs], 1.0, 2),
        "open_first_points_s": _summary([t.times["first_points"] for t in tabs], 1.0, 2),
        "open_full_scene_s": _summary([t.times["full_scene"] for t in tabs], 1.0, 2),
        "liveness_ms": {"while_opening": liveness_open, "while_moving": liveness_changes},
        "all_open_s": round(all_open_s, 1),
        "changes_phase_s": round(changes_s, 1),
        "first_points_ms": _summary(first),
        "full_scene_ms": _summary(full),
        "starvation": {
            "changes": len(results),
            "without_new_points": sum(c.first_s is None for c in results),
            "without_full_scene": sum(c.full_s is None for c in results),
            "sessions_with_every_change_answered": sum(
                all(c.first_s is not None for c in cs) and len(cs) == changes for cs in per_session.values()
            ),
            "max_first_ms_per_session": {
                name: round(1e3 * max(c.first_s for c in cs if c.first_s is not None), 0)
                if any(c.first_s is not None for c in cs)
                else None
                for name, cs in per_session.items()
            },
        },
        "memory": {
            "rss_before_mb": round(base["rss_mb"], 1),
            "rss_all_open_mb": round(opened["rss_mb"], 1),
            "per_session_mb": round((opened["rss_mb"] - base["rss_mb"]) / sessions, 2),
            "procs": len(tree_pids(pid)) - (1 if len(tree_pids(pid)) > 1 else 0),
            "rss_peak_mb": round(peak[0], 1),
            "threads_before": base["threads"],
            "threads_all_open": opened["threads"],
            "threads_after_close": after["threads"],
        },
        "server_cpu_s_in_3s_after_close": cpu_after_close,
        "chart": chart_report,
        "protocol_errors": errors[:5],
        "changes": [
            {"at_s": round(c.t0 - t_changes, 2), **{k: v for k, v in asdict(c).items() if k not in _PRIVATE}}
            for c in results
        ],
    }


async def open_close_cycles(
    server: Server,
    cycles: int,
    *,
    per_cycle: int = 1,
    every: int = 10,
    discard_wait: float = discard_wait(SESSION_LIFETIME_MS),
    timeout: float = 180.0,
) -> dict[str, Any]:
    """Open ``per_cycle`` tabs (each draws its first scene), close them; RSS once the server discarded them."""
    pid = server.pid
    await asyncio.sleep(discard_wait)
    rss = [(0, round(proc_status(pid)["rss_mb"], 1))]
    cpu_after: list[float] = []
    t0 = time.perf_counter()
    for c in range(1, cycles + 1):
        tabs = [Tab(server, f"c{c}-{j}") for j in range(per_cycle)]
        await asyncio.gather(*(t.open(timeout) for t in tabs))
        for t in tabs:
            await t.close()
        if c % every == 0 or c == cycles:
            cpu_after.append(await _idle_cpu(pid, 2.0))
            await asyncio.sleep(max(0.0, discard_wait - 2.0))
            rss.append((c, round(proc_status(pid)["rss_mb"], 1)))
    return {
        "cycles": cycles,
        "tabs_per_cycle": per_cycle,
        "rss_mb": rss,
        "growth_mb": round(rss[-1][1] - rss[0][1], 1),
        "max_growth_mb": round(max(r for _, r in rss) - rss[0][1], 1),
        "server_cpu_s_in_2s_after_close": cpu_after,
        "elapsed_s": round(time.perf_counter() - t0, 1),
    }


async def _warm_up(server: Server, procs: int) -> None:
    # The first page of each worker builds its template session, and the first session pays for the
    # kernels and lazy imports: keep them out of the figures. Which worker answers is the kernel's
    # choice, so ask a few times per worker.
    for _ in range(2):
        tabs = [Tab(server, f"warm-up-{i}") for i in range(3 * procs)]
        await asyncio.gather(*(t.open(300) for t in tabs))
        await tabs[0].change("alpha", 0.101)
        for t in tabs:
            await t.close()


def run(
    sessions: int = 30,
    changes: int = 5,
    cycles: int = 100,
    *,
    chart: tuple[int, int] | None = (60, 40),
    env: dict[str, str] | None = None,
    log_path: str | None = None,
    session_lifetime: int = SESSION_LIFETIME_MS,
    procs: int = 1,
    client_nice: int = 5,
    **kw: Any,
) -> dict[str, Any]:
    """Serve the app, run the classroom then the open/close cycles; the report as a dict.

    The simulated tabs run at nice ``client_nice`` (the server at 0): they stand for browsers on the
    students' machines and should take their CPU from the computations, not from the server's event loop.
    """
    cycle_kw = {k: kw.pop(k) for k in ("per_cycle", "every") if k in kw}
    cycle_kw["discard_wait"] = discard_wait(session_lifetime)
    load0 = os.getloadavg()
    with serve(log_path, env=env, session_lifetime=session_lifetime, procs=procs) as server:

        async def main() -> dict[str, Any]:
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), client_nice)
            await _warm_up(server, procs)
            report: dict[str, Any] = {"classroom": await classroom(server, sessions, changes, chart=chart, **kw)}
            if cycles:
                report["cycles"] = await open_close_cycles(server, cycles, **cycle_kw)
            return report

        # In a thread of its own: the caller may already run an event loop (pytest with the
        # session's Playwright browser open does), and asyncio.run refuses to nest.
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            report = pool.submit(asyncio.run, main()).result()
    report["machine"] = {"cpus": os.cpu_count(), "loadavg_before": load0, "loadavg_after": os.getloadavg()}
    report["env"] = env or {}
    report["session_lifetime_ms"] = session_lifetime
    report["procs"] = procs
    report["client_nice"] = client_nice
    return report


def markdown(report: dict[str, Any]) -> str:
    """The headline figures as a Markdown table."""
    c = report["classroom"]
    s, m = c["starvation"], c["memory"]
    when = "together" if not c["open_stagger_s"] else f"{c['open_stagger_s']} s apart"
    rows = [
        (
            "sessions x slider moves (server processes)",
            f"{c['sessions']} x {c['changes_per_session']} ({report.get('procs', 1)})",
        ),
        ("a new page's document: Bokeh models, JSON", f"{c['document']['models']}, {c['document']['kB']} kB"),
        (f"opened {when}: GET -> page (document), p50 / p95 / max", _s(c["open_page_s"])),
        ("GET -> first section points, p50 / p95 / max", _s(c["open_first_points_s"])),
        ("GET -> full first scene, p50 / p95 / max", _s(c["open_full_scene_s"])),
        ("/liveness answer while opening, p50 / p95 / max", _ms(c["liveness_ms"]["while_opening"])),
        ("/liveness answer while moving, p50 / p95 / max", _ms(c["liveness_ms"]["while_moving"])),
        ("move -> first new points, p50 / p95 / max", _ms(c["first_points_ms"])),
        ("move -> full scene (30,000 points), p50 / p95 / max", _ms(c["full_scene_ms"])),
        ("moves without new points / without full scene", f"{s['without_new_points']} / {s['without_full_scene']}"),
        ("worst session's slowest first points", f"{max(v or 0 for v in s['max_first_ms_per_session'].values())} ms"),
        (
            "server RSS (MB): before / all open / peak",
            " / ".join(str(m[k]) for k in ("rss_before_mb", "rss_all_open_mb", "rss_peak_mb")),
        ),
        ("server RSS per idle session", f"{m['per_session_mb']} MB"),
        ("server CPU in the 3 s after every tab closed", f"{c['server_cpu_s_in_3s_after_close']} s"),
    ]
    if c.get("chart"):
        ch = c["chart"]
        done = f"finished in {ch['total_s']} s" if ch["finished"] else "not finished"
        tiles = f"{ch['tiles_done_while_others_moved']}/{ch['tiles']} tiles while the others moved; {done}"
        rows.append((f"chart {ch['grid'][0]}x{ch['grid'][1]} in session 0", tiles))
    if "cycles" in report:
        cy = report["cycles"]
        trail = ", ".join(f"{n}: {r}" for n, r in cy["rss_mb"])
        rows.append((f"RSS over {cy['cycles']} open/close cycles (MB)", trail))
        rows.append(("RSS growth, end - start (max)", f"{cy['growth_mb']} MB ({cy['max_growth_mb']} MB)"))
    lines = ["| measure | value |", "|---|---|", *(f"| {a} | {b} |" for a, b in rows)]
    return "\n".join(lines)


def _ms(d: dict[str, Any]) -> str:
    return " / ".join("–" if d[k] is None else f"{d[k]:.0f} ms" for k in ("p50", "p95", "max"))


def _s(d: dict[str, Any]) -> str:
    return " / ".join("–" if d[k] is None else f"{d[k]:.2f} s" for k in ("p50", "p95", "max"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=30)
    ap.add_argument("--changes", type=int, default=5, help="slider moves per session")
    ap.add_argument("--think", type=float, default=3.0, help="mean pause between a full scene and the next move (s)")
    ap.add_argument("--stagger", type=float, default=0.0, help="seconds between two tabs opening (0: together)")
    ap.add_argument("--procs", default="1", help="server processes (bilimovich serve --procs; 'auto': one per CPU)")
    ap.add_argument("--chart", action="store_true", help="session 0 runs a chart of regimes meanwhile")
    ap.add_argument("--chart-grid", default="60,40", help="NX,NY of that chart")
    ap.add_argument("--chart-periods", type=int, default=300)
    ap.add_argument("--cycles", type=int, default=100, help="open/close cycles after the classroom (0: none)")
    ap.add_argument("--per-cycle", type=int, default=1, help="tabs opened and closed per cycle")
    ap.add_argument("--every", type=int, default=10, help="read the RSS every this many cycles")
    ap.add_argument("--session-lifetime", type=int, default=SESSION_LIFETIME_MS, help="the server's (ms)")
    ap.add_argument("--slots", type=int, help="BILIMOVICH_APP_SLOTS of the server (0: no fair scheduler)")
    ap.add_argument("--client-nice", type=int, default=5, help="nice value of the simulated tabs (server: 0)")
    ap.add_argument("--log", default="/tmp/load_test_panel.log", help="server log")
    ap.add_argument("--json", metavar="FILE", help="write the whole report here")
    args = ap.parse_args()
    grid = tuple(int(v) for v in args.chart_grid.split(","))
    env = {"BILIMOVICH_APP_SLOTS": str(args.slots)} if args.slots is not None else None
    report = run(
        args.sessions, args.changes, args.cycles, chart=grid if args.chart else None, env=env, log_path=args.log,
        think=args.think, stagger=args.stagger, chart_periods=args.chart_periods, per_cycle=args.per_cycle,
        every=args.every, session_lifetime=args.session_lifetime, procs=resolve_procs(args.procs),
        client_nice=args.client_nice,
    )  # fmt: skip
    report["command"] = " ".join(sys.argv)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)
    print(markdown(report))


if __name__ == "__main__":
    main()
