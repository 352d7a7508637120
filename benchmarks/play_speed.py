"""Play a parameter, measured through Bokeh's protocol: frames per second delivered and Play to the first frame.

    .venv/bin/python benchmarks/play_speed.py [--seconds 15] [--layers default|none] [--json F]

Serves the app (as the browser tests do) and opens one session with :class:`load_test.Tab` (a browser's
messages over the websocket, nothing rendered) on Fig. 10 with alpha played across the figure's range
-0.42..-0.35 (``play_n`` frames, ``play_fps`` asked). The client acts as the page does: when a view says a
frame is computed (``play.number``), it answers ``shown`` at once (a browser would after its next paint).
Measured on the client: the time from the Play message to the first frame's view, and the frames delivered
per second over ``--seconds`` (distinct frame numbers received / time). ``--layers none`` turns the T′ map and
the frozen-field tracks off (the orbits layer is off in both: Fig. 10's scene has no orbit seeds).
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
    query = QUERY.format(frames=frames, fps=fps) + ("&tprime=off&tracks=0" if layers == "none" else "")
    await tab.open(query=query)
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


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--fps", type=int, default=30, help="frames/s asked (the most the player sends)")
    ap.add_argument("--layers", choices=("default", "none"), default="default")
    ap.add_argument("--json", default="")
    args = ap.parse_args(argv)
    with serve() as server:
        res = asyncio.run(measure(server.url, args.seconds, args.frames, args.fps, args.layers))
    print(json.dumps(res))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
