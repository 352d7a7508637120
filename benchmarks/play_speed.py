"""Play a parameter, measured through Bokeh's protocol: frames per second delivered and Play to the first frame.

    .venv/bin/python benchmarks/play_speed.py [--seconds 15] [--layers default|none] [--json F]
    .venv/bin/python benchmarks/play_speed.py --orbit-work   # the orbits layer's Newton work per frame, counted

Serves the app (as the browser tests do) and opens one session with :class:`load_test.Tab` (a browser's
messages over the websocket, nothing rendered) on Fig. 10 with alpha played across the figure's range
-0.42..-0.35 (``play_n`` frames, ``play_fps`` asked). The client acts as the page does: when a view says a
frame is computed (``play.number``), it answers ``shown`` at once (a browser would after its next paint).
Measured on the client: the time from the Play message to the first frame's view, and the frames delivered
per second over ``--seconds`` (distinct frame numbers received / time). ``--layers none`` turns the T′ map and
the frozen-field tracks off (the orbits layer is off in both: Fig. 10's scene has no orbit seeds).

``--sessions N`` (N > 1) opens N such sessions one after the other, then presses Play in all of them at once: a
class playing together. Meanwhile ``/liveness`` is asked every 0.1 s (``load_test.Liveness``, a separate process);
the report gives its answer times while they play and each session's frames per second (what a slow machine
gives every session: fewer frames, never a backlog).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from load_test import Tab

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "browser"))
from harness import serve

QUERY = "?scene=fig10&play=alpha&play_from=-0.42&play_to=-0.35&play_n={frames}&play_fps={fps}"


def _play(tab: Tab) -> dict[str, Any]:
    return (tab.view.get("section") or {}).get("play") or {}


async def measure(url: str, seconds: float, frames: int, fps: int, layers: str) -> dict[str, Any]:
    from load_test import Server

    tab = Tab(Server(url, 0, os.devnull), "play")
    await tab.open(query=_query(frames, fps, layers))
    await _idle(tab)
    return await _play_for(tab, seconds, frames, fps, layers)


async def _idle(tab: Tab, timeout: float = 60.0) -> None:
    """Wait until the page runs nothing (the still's last layer, e.g. its reliability check, is done), as a user
    would see the scene before pressing Play."""
    if not await tab._until(lambda: (tab.view.get("section") or {}).get("running") is False, timeout):
        raise TimeoutError(f"{tab.name}: the page still runs something after {timeout} s")
    await asyncio.sleep(0.2)


def _query(frames: int, fps: int, layers: str) -> str:
    return QUERY.format(frames=frames, fps=fps) + ("&tprime=off&tracks=0" if layers == "none" else "")


async def _play_for(tab: Tab, seconds: float, frames: int, fps: int, layers: str) -> dict[str, Any]:
    """Press Play in ``tab``, answer ``shown`` to every frame for ``seconds``, press Pause; what it saw."""
    t0 = time.perf_counter()
    await tab.message({"action": "play"})
    seen: dict[int, float] = {}
    first = None
    deadline = t0 + seconds
    while time.perf_counter() < deadline:
        ok = await tab._until(lambda: (_play(tab).get("number", -1) or -1) > max(seen, default=0), deadline -
                              time.perf_counter())  # fmt: skip
        if not ok:
            break
        n = int(_play(tab)["number"])
        now = time.perf_counter()
        seen[n] = now
        if first is None:
            first = now - t0
        await tab.message({"action": "shown", "value": str(n)})
    await tab.message({"action": "pause"})
    times = sorted(seen.values())
    rate = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0
    await tab.close()
    return {"first_frame_ms": None if first is None else round(1e3 * first, 1), "frames": len(times),
            "frames_per_s": round(rate, 2), "seconds": seconds, "play_n": frames, "play_fps": fps,
            "layers": layers, "server_first_ms": _play(tab).get("first_ms"),
            "load_1min": os.getloadavg()[0]}  # fmt: skip


async def measure_class(server: Any, sessions: int, seconds: float, frames: int, fps: int,
                        layers: str) -> dict[str, Any]:  # fmt: skip
    """``sessions`` tabs open (one after the other), then all play at once; /liveness while they play."""
    from load_test import Liveness

    tabs = [Tab(server, f"play{i}") for i in range(sessions)]
    for tab in tabs:
        await tab.open(timeout=300, query=_query(frames, fps, layers))
    for tab in tabs:
        await _idle(tab, timeout=300)
    probe = Liveness(server)
    probe.start()
    await asyncio.sleep(2.0)
    idle = probe.take()
    each = await asyncio.gather(*(_play_for(t, seconds, frames, fps, layers) for t in tabs))
    playing = probe.take()
    await probe.stop()
    rates = sorted(r["frames_per_s"] for r in each)
    firsts = sorted(r["first_frame_ms"] for r in each if r["first_frame_ms"] is not None)
    return {"sessions": sessions, "seconds": seconds, "layers": layers, "liveness_ms_idle": idle,
            "liveness_ms_playing": playing, "frames_per_s_per_session": {"min": rates[0],
            "median": rates[len(rates) // 2], "max": rates[-1]}, "frames_total": sum(r["frames"] for r in each),
            "first_frame_ms": {"median": firsts[len(firsts) // 2], "max": firsts[-1]} if firsts else None,
            "sessions_without_frames": sum(r["frames"] == 0 for r in each),
            "load_1min": os.getloadavg()[0]}  # fmt: skip


#: The plays whose orbit work ``--orbit-work`` counts: Fig. 10's alpha range with the orbits layer on (no fold:
#: nothing is added), and Fig. 11's 3-6-12 tongue (Fig. 10 at I11 = 1.8) across the fold at alpha = -0.4900859.
ORBIT_PLAYS = {
    "fig10": {"scene": "fig10", "n": "60", "periods": "300", "tracks": "0", "tprime": "off", "orbits": "1",
              "orb_all": "1", "orb_n": "4", "alpha": "-0.42", "play_from": "-0.42", "play_to": "-0.35",
              "play_n": "20"},
    "fold": {"scene": "fig10", "I11": "1.8", "n": "3", "ics": "-0.5,-1", "tracks": "0", "tprime": "off",
             "orbits": "1", "orb_all": "1", "orb_n": "3", "alpha": "-0.489", "play_from": "-0.489",
             "play_to": "-0.5", "play_n": "8"},
}  # fmt: skip


def orbit_work() -> dict[str, Any]:
    """The Newton work the orbits layer adds to following while playing (counts, not times: the same on a loaded
    machine), per frame: the follow job's searches, the seeds of orbits born at a doubling and of fold partners, and
    the searches from trajectories settled on an orbit not followed (app/layers/orbits.py). In one process, jobs
    run in order on this thread."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from jobs import Jobs

    from app.page import Page
    from app.runner import WARM

    WARM.set()
    out: dict[str, Any] = {}
    for name, query in ORBIT_PLAYS.items():
        jobs = Jobs()
        due: list[Any] = []
        page = Page(query, lambda fn: fn(), executor=jobs, schedule=lambda delay, fn, due=due: due.append(fn))
        page.start()
        jobs.drain()
        layer = page.session.layers["orbits"]
        page.handle({"action": "play"})
        frames = []
        for _ in range(int(query["play_n"])):
            jobs.drain()
            frames.append({"value": float(page.state.alpha), "work": list(layer.work),  # type: ignore[attr-defined]
                           "periods": sorted(o["period"] for o in page.session.orbits)})  # fmt: skip
            layer.work.clear()  # type: ignore[attr-defined]
            while due and not jobs.queue:
                due.pop(0)()
        out[name] = {"frames": frames, "settled_searches": list(page.player.settled_searches)}
        page.close()
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--fps", type=int, default=30, help="frames/s asked (the most the player sends)")
    ap.add_argument("--layers", choices=("default", "none"), default="default")
    ap.add_argument("--sessions", type=int, default=1, help="sessions playing at once (> 1: a class)")
    ap.add_argument("--json", default="")
    ap.add_argument("--orbit-work", action="store_true", help="count the orbits layer's Newton work per frame "
                    "while playing (in one process, no server; ORBIT_PLAYS)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.orbit_work:
        res = orbit_work()
        for name, r in res.items():
            print(name, "settled searches per frame:", r["settled_searches"])
            for f in r["frames"]:
                print(f"  {name} alpha = {f['value']:.5g}: periods shown {f['periods']}; jobs {f['work']}")
        if args.json:
            Path(args.json).write_text(json.dumps(res, indent=1))
        return
    with serve(session_lifetime=3000) as server:
        if args.sessions > 1:
            res = asyncio.run(measure_class(server, args.sessions, args.seconds, args.frames, args.fps, args.layers))
        else:
            res = asyncio.run(measure(server.url, args.seconds, args.frames, args.fps, args.layers))
    print(json.dumps(res))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
