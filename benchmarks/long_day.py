"""A long day in the classroom: sessions opening, moving, playing, touring and closing at random, for an hour.

    .venv/bin/python benchmarks/long_day.py [--minutes 60] [--sessions 30] [--procs 1] [--sample 30] [--json F]

Serves the app warm (``python -m explorer_core.cli serve``, as the browser tests and ``load_test.py`` do) and runs
``--sessions`` students for ``--minutes``. Each student has one tab at a time (:class:`load_test.Tab`: a browser's
messages over Bokeh's websocket, nothing rendered) and, in a loop: opens the page (the default scene, or Fig. 10
with alpha ready to play), does 1-8 things at random with a pause of 1-6 s between them (moves alpha and waits for
the full scene; plays alpha for 5-15 s answering each frame as a page does, then pauses; starts a guided tour and
steps through it; opens the Lyapunov tab and comes back), closes the tab and comes back 0-5 s later.

Before the day, one tab does each of these once (what is built on first use is not growth). Watched meanwhile,
every ``--sample`` seconds: each server process's RSS, threads and CPU time (``/proc``), the tabs open, and
``/liveness`` (asked every 0.2 s from a separate process: p50 / p95 / max per interval). Before the day (after the
warm-up, every tab closed and discarded) and after it (the same), each process's RSS when idle. After the day's
first ``--warmup`` minutes (a third of it, at most 10) the RSS must not grow by more than ``--growth-bound`` MB
per process: neither its trend (Theil-Sen) nor the median of its last minutes over that of its first
(:func:`memory_growth`; one sample is a high or a low of the moment's work, a leak is what keeps rising).
Then the server's CPU over 10 s once every session is discarded (must be ~0), the protocol errors the tabs
received and the server log's errors and refusals (none for these polite clients). Prints a Markdown table;
``--json`` writes every sample.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import contextlib
import json
import os
import random
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from load_test import (  # the classroom's client and probes
    SESSION_LIFETIME_MS,
    Liveness,
    Tab,
    _summary,
    _warm_up,
    discard_wait,
    proc_status,
    serve,
    tree_pids,
)

from explorer_core.config import resolve_procs

#: The two pages a student opens: the default scene, or Fig. 10 with alpha ready to play (benchmarks/play_speed.py).
PAGES = {"default": ("", 0.1), "play": ("?scene=fig10&play=alpha&play_from=-0.42&play_to=-0.35&play_n=20", -0.4)}
TOURS = ("fig1C", "fig4A", "fig7", "fig8B", "fig10", "fig11")
#: Server log lines that are errors (benign: a write to a tab that had closed; see tests/browser/conftest.py).
ERROR_LINE = re.compile(r"Traceback|ERROR|Exception|refused|flood", re.I)
BENIGN = ("WebSocketClosedError", "Task exception was never retrieved", "write_message")


def worker_pids(pid: int) -> list[int]:
    """The processes that serve sessions: the server itself, or the workers of ``--procs N``."""
    pids = tree_pids(pid)
    return pids[1:] if len(pids) > 1 else pids


def per_process(pid: int) -> list[dict[str, float]]:
    return [{"pid": p, **proc_status(p)} for p in worker_pids(pid)]


class Student:
    """One student's tab, reopened again and again; counts what it did and what went wrong."""

    def __init__(self, server: Any, i: int, rng: random.Random) -> None:
        self.server, self.i, self.rng = server, i, rng
        self.tab: Tab | None = None
        self.done: dict[str, int] = {}
        self.failures: list[str] = []
        self.errors: list[str] = []
        self.opened = 0

    def _count(self, what: str) -> None:
        self.done[what] = self.done.get(what, 0) + 1

    async def day(self, until: float) -> None:
        while time.monotonic() < until:
            page = self.rng.choice(list(PAGES))
            query, alpha = PAGES[page]
            self.tab = tab = Tab(self.server, f"st{self.i}-{self.opened}")
            self.opened += 1
            try:
                await tab.open(180, query=query)
                self._count("open")
                for _ in range(self.rng.randint(1, 8)):
                    if time.monotonic() >= until:
                        break
                    await asyncio.sleep(self.rng.uniform(1.0, 6.0))
                    await self._act(tab, page, alpha)
            except Exception as exc:  # a tab that failed: counted, the student opens another
                self.failures.append(f"{tab.name}: {type(exc).__name__}: {str(exc)[:160]}")
            self.errors += tab.errors
            await tab.close()
            self.tab = None
            self._count("close")
            await asyncio.sleep(self.rng.uniform(0.0, 5.0))

    async def _act(self, tab: Tab, page: str, alpha: float, what: str | None = None) -> None:
        what = what or self.rng.choice(["move", "move", "play" if page == "play" else "move", "tour", "tab"])
        if what == "move":
            # A value other than the one in use (the same value starts no run: no scene to wait for): not the
            # last move's, and not a multiple of 0.01, which a tour's step or a scene may have set (Fig. 10's
            # tour sets alpha = -0.38 and a move there waited for a scene that never came).
            value = self.rng.choice([v for v in range(-20, 21) if v % 10 and v != getattr(tab, "moved", 0)])
            tab.moved = value  # type: ignore[attr-defined]
            c = await tab.change("alpha", round(alpha + 0.001 * value, 3), 120)
            if c.full_s is None:
                why = "its socket closed" if tab.closed else "in 120 s"
                raise TimeoutError(f"a move of alpha to {c.value} got no full scene ({why}, at "
                                   f"{time.strftime('%H:%M:%S')}: see the server log then)")  # fmt: skip
        elif what == "play":
            await self._play(tab, self.rng.uniform(5.0, 15.0))
        elif what == "tour":
            await tab.message({"action": "tour", "value": self.rng.choice(TOURS)})
            for _ in range(self.rng.randint(1, 3)):
                await asyncio.sleep(self.rng.uniform(1.0, 4.0))
                await tab.message({"action": "tour_step", "value": "next"})
        else:
            await tab.show_tab("lyapunov")
            await asyncio.sleep(self.rng.uniform(1.0, 4.0))
            await tab.show_tab("section")
        self._count(what)

    async def _play(self, tab: Tab, seconds: float) -> None:
        """Play, answering ``shown`` to each frame as a page does after drawing it, then pause."""

        def number() -> int:
            return int(((tab.view.get("section") or {}).get("play") or {}).get("number", -1) or -1)

        await tab.message({"action": "play"})
        deadline, last = time.perf_counter() + seconds, [-1]
        while (left := deadline - time.perf_counter()) > 0:
            if await tab._until(lambda: number() > last[0], left):
                last[0] = number()
                await tab.message({"action": "shown", "value": str(last[0])})
        await tab.message({"action": "pause"})


async def _warm_up_actions(server: Any) -> None:
    """Each thing a student does, once: what is built or imported on first use (the Lyapunov tab, the tours, the
    player) is then in the idle RSS before the day, and the day's growth is what sessions leave behind."""
    s = Student(server, -1, random.Random(1))
    for page, (query, alpha) in PAGES.items():
        tab = Tab(server, f"warm-{page}")
        await tab.open(300, query=query)
        for what in ("move", "tab", "tour", *(["play"] if page == "play" else [])):
            await s._act(tab, page, alpha, what)
        await tab.close()


async def _idle_rss(server: Any, lifetime_ms: int) -> list[dict[str, float]]:
    """Each process's RSS once every closed session is discarded."""
    await asyncio.sleep(discard_wait(lifetime_ms))
    return per_process(server.pid)


def _log_errors(path: str, start: int) -> list[str]:
    text = Path(path).read_text(errors="replace")[start:]
    lines = [ln for ln in text.splitlines() if ERROR_LINE.search(ln)]
    return [ln[:300] for ln in lines if not any(b in ln for b in BENIGN)]


async def long_day(server: Any, sessions: int, minutes: float, *, sample: float, lifetime_ms: int, seed: int,
                   procs: int, warmup: float) -> dict[str, Any]:  # fmt: skip
    pid = server.pid
    await _warm_up(server, procs)
    await _warm_up_actions(server)
    idle_before = await _idle_rss(server, lifetime_ms)
    log_start = Path(server.log_path).stat().st_size if os.path.exists(server.log_path) else 0
    rng = random.Random(seed)
    students = [Student(server, i, random.Random(rng.random())) for i in range(sessions)]
    probe = Liveness(server, period=0.2)
    probe.start()
    t0 = time.monotonic()
    until = t0 + 60.0 * minutes
    samples: list[dict[str, Any]] = []
    all_liveness: list[float] = []

    async def sampler() -> None:
        while time.monotonic() < until:
            await asyncio.sleep(min(sample, max(0.0, until - time.monotonic())))
            times = list(probe.times)
            all_liveness.extend(times)
            samples.append({
                "t_min": round((time.monotonic() - t0) / 60, 2),
                "processes": [{k: round(v, 1) for k, v in p.items()} for p in per_process(pid)],
                "tabs_open": sum(s.tab is not None for s in students),
                "liveness_ms": probe.take(),
                "load_1min": os.getloadavg()[0],
            })  # fmt: skip

    # Students start spread over the first minute (a class arriving), then come and go at random.
    async def start(s: Student) -> None:
        await asyncio.sleep(rng.uniform(0.0, min(60.0, 30.0 * minutes)))
        await s.day(until)

    await asyncio.gather(sampler(), *(start(s) for s in students))
    await probe.stop()
    cpu_3s = await _cpu(pid, 3.0)  # right after the last tab closed (its last jobs stop)
    idle_after = await _idle_rss(server, lifetime_ms)
    cpu_idle = await _cpu(pid, 10.0)  # once every session is discarded: nothing may run
    done: dict[str, int] = {}
    for s in students:
        for k, v in s.done.items():
            done[k] = done.get(k, 0) + v
    growth = [round(a["rss_mb"] - b["rss_mb"], 1) for a, b in zip(idle_after, idle_before, strict=True)]
    after_warmup = [
        memory_growth([x["t_min"] for x in samples], [x["processes"][i]["rss_mb"] for x in samples], warmup)
        for i in range(len(idle_before))
    ]
    return {
        "sessions": sessions,
        "minutes": minutes,
        "actions": done,
        "tab_failures": [f for s in students for f in s.failures][:20],
        "protocol_errors": [e for s in students for e in s.errors][:20],
        "server_log_errors": _log_errors(server.log_path, log_start)[:20],
        "liveness_ms": {**_summary(all_liveness), "failures": sum(x["liveness_ms"]["failures"] for x in samples)},
        "idle_rss_before_mb": [round(p["rss_mb"], 1) for p in idle_before],
        "idle_rss_after_mb": [round(p["rss_mb"], 1) for p in idle_after],
        "idle_rss_growth_mb": growth,
        "warmup_min": warmup,
        "rss_after_warmup": after_warmup,
        "rss_max_mb": [round(max(x["processes"][i]["rss_mb"] for x in samples), 1) for i in range(len(idle_before))]
        if samples
        else [],
        "server_cpu_s_in_3s_after_last_close": cpu_3s,
        "server_cpu_s_in_10s_once_discarded": cpu_idle,
        "samples": samples,
    }


def memory_growth(t_min: list[float], rss_mb: list[float], warmup: float, window: float = 5.0) -> dict[str, Any]:
    """How one process's RSS grew after the warm-up, judged on its trend, not on one sample.

    With the allocator's trim (app/memory.py) the RSS follows the memory in use, which rises and falls by tens of
    MB with the moment's work; one sample is a high or a low of that. A leak is what keeps rising, so growth is:
    ``trend``, the Theil-Sen slope (the median of the slopes between every pair of samples: one outlier cannot
    move it) times the minutes after the warm-up; ``end``, the median of the last ``window`` minutes less the
    median of the first ``window`` after the warm-up (``level``). ``highest`` (the highest sample less the level)
    is the moment's work on top and is reported, not judged. ``growth_mb`` (the larger of trend and end) is what
    the bound applies to.
    """
    warm = [(t, v) for t, v in zip(t_min, rss_mb, strict=True) if t >= warmup]
    if len(warm) < 2:
        raise ValueError(f"{len(warm)} samples after the {warmup:g}-min warm-up: the day is too short to judge")
    t0, t1 = warm[0][0], warm[-1][0]
    w = min(window, (t1 - t0) / 4)
    level = _median([v for t, v in warm if t <= t0 + w])
    end = _median([v for t, v in warm if t >= t1 - w])
    slopes = [(b - a) / (tb - ta) for i, (ta, a) in enumerate(warm) for tb, b in warm[i + 1 :] if tb > ta]
    trend = _median(slopes) * (t1 - t0) if slopes else 0.0
    return {
        "minutes": round(t1 - t0, 1),
        "window_min": round(w, 1),
        "level_mb": level,
        "trend_mb": round(trend, 1),
        "end_mb": round(end - level, 1),
        "highest_mb": round(max(v for _, v in warm) - level, 1),
        "growth_mb": round(max(trend, end - level), 1),
    }


def _median(xs: list[float]) -> float:
    s = sorted(xs)
    return round((s[(len(s) - 1) // 2] + s[len(s) // 2]) / 2, 1)


async def _cpu(pid: int, seconds: float) -> float:
    before = sum(p["cpu_s"] for p in per_process(pid))
    await asyncio.sleep(seconds)
    return round(sum(p["cpu_s"] for p in per_process(pid)) - before, 2)


def run(
    sessions: int = 30, minutes: float = 60.0, *, procs: int = 1, sample: float = 30.0, seed: int = 0,
    log_path: str | None = None, lifetime_ms: int = SESSION_LIFETIME_MS, client_nice: int = 5,
    warmup: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Serve the app and run the day; the report as a dict."""
    # Every student comes from this machine's address, and a closed tab's session lives on for lifetime_ms.
    env = {"BILIMOVICH_MAX_SESSIONS_PER_ADDRESS": str(4 * sessions + 20)}
    load0 = os.getloadavg()
    with serve(log_path, env=env, session_lifetime=lifetime_ms, procs=procs) as server:

        async def main() -> dict[str, Any]:
            with contextlib.suppress(OSError):  # the tabs stand for browsers on other machines: below the server
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), client_nice)
            return await long_day(server, sessions, minutes, sample=sample, lifetime_ms=lifetime_ms, seed=seed,
                                  procs=procs, warmup=min(10.0, minutes / 3) if warmup is None else warmup)  # fmt: skip

        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            report = pool.submit(asyncio.run, main()).result()
    report.update(procs=procs, machine={"cpus": os.cpu_count(), "loadavg_before": load0,
                                        "loadavg_after": os.getloadavg()})  # fmt: skip
    return report


def markdown(r: dict[str, Any], bound: float) -> str:
    live = r["liveness_ms"]
    loads = [s["load_1min"] for s in r["samples"]]
    trail = "; ".join(
        f"{s['t_min']:.0f} min: " + "/".join(f"{p['rss_mb']:.0f}" for p in s["processes"])
        for s in r["samples"][:: max(1, len(r["samples"]) // 8)]
    )
    rows = [
        ("students (one tab each) x minutes (server processes)", f"{r['sessions']} x {r['minutes']:g} ({r['procs']})"),
        ("done", ", ".join(f"{k} {v}" for k, v in sorted(r["actions"].items()))),
        ("/liveness p50 / p95 / max (failures)",
         f"{live['p50']:.0f} / {live['p95']:.0f} / {live['max']:.0f} ms ({live['failures']})"),
        ("RSS per process over the day (MB)", trail),
        ("RSS per process, peak (MB)", " / ".join(f"{v:.0f}" for v in r["rss_max_mb"])),
        ("idle RSS before -> after the day (MB)",
         ", ".join(f"{a} -> {b}" for a, b in zip(r["idle_rss_before_mb"], r["idle_rss_after_mb"], strict=True))),
        ("idle RSS growth over the day (the allocator keeps a full class's high-water mark)",
         " / ".join(f"{g:+.1f} MB" for g in r["idle_rss_growth_mb"])),
        (f"RSS after the {r['warmup_min']:g}-min warm-up: level (median of its first minutes, MB)",
         " / ".join(f"{g['level_mb']:.0f}" for g in r["rss_after_warmup"])),
        (f"RSS growth after the warm-up: trend (Theil-Sen) / last minutes' median (bound {bound:g} MB per process)",
         " / ".join(f"{g['trend_mb']:+.1f} / {g['end_mb']:+.1f} MB" for g in r["rss_after_warmup"])),
        ("RSS above the level at its highest (the moment's work, not judged)",
         " / ".join(f"{g['highest_mb']:+.1f} MB" for g in r["rss_after_warmup"])),
        ("server CPU in the 3 s after the last tab closed", f"{r['server_cpu_s_in_3s_after_last_close']} s"),
        ("server CPU in 10 s once every session was discarded", f"{r['server_cpu_s_in_10s_once_discarded']} s"),
        ("tabs that failed / protocol errors / server log errors",
         f"{len(r['tab_failures'])} / {len(r['protocol_errors'])} / {len(r['server_log_errors'])}"),
        ("machine load (1 min) during the day, min-max", f"{min(loads, default=0):.1f}-{max(loads, default=0):.1f}"),
    ]  # fmt: skip
    return "\n".join(["| measure | value |", "|---|---|", *(f"| {a} | {b} |" for a, b in rows)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0, help="length of the day")
    ap.add_argument("--sessions", type=int, default=30, help="students, each with one tab at a time")
    ap.add_argument("--procs", default="1", help="server processes (bilimovich serve --procs; 'auto')")
    ap.add_argument("--sample", type=float, default=30.0, help="seconds between two samples")
    ap.add_argument("--growth-bound", type=float, default=50.0,
                    help="RSS growth allowed per process after the warm-up: trend and last minutes (MB)")  # fmt: skip
    ap.add_argument("--warmup", type=float, help="minutes of the day before memory counts (default: a third, <= 10)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--log", default="/tmp/long_day_panel.log", help="server log")
    ap.add_argument("--json", metavar="FILE", help="write the whole report here")
    args = ap.parse_args()
    report = run(args.sessions, args.minutes, procs=resolve_procs(args.procs), sample=args.sample, seed=args.seed,
                 log_path=args.log, warmup=args.warmup)  # fmt: skip
    report["command"] = " ".join(sys.argv)
    ok = (
        max((g["growth_mb"] for g in report["rss_after_warmup"]), default=0.0) <= args.growth_bound
        and not report["server_log_errors"]
        and not report["protocol_errors"]
        and report["server_cpu_s_in_10s_once_discarded"] < 0.5
    )
    report["within_bounds"] = ok
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    print(markdown(report, args.growth_bound))
    print("within bounds" if ok else "NOT within bounds: see the report")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
