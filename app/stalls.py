"""A watchdog for the server's event loop (diagnosis; ``BILIMOVICH_STALL_LOG=FILE`` turns it on).

A thread asks the loop to run a no-op every 50 ms; while the loop has not run it for longer than
:data:`THRESHOLD`, the thread samples the loop thread's stack every 10 ms. When the loop answers,
a stall longer than the threshold is written to the file with its duration and the stacks seen
most often: what held the loop (a page build, a message, a collection) is then named, not guessed.
"""

from __future__ import annotations

import asyncio
import collections
import os
import sys
import threading
import time
import traceback

#: A turn of the event loop longer than this (seconds) is reported.
THRESHOLD = 0.15

_started = False


def _stack(frame: object, depth: int = 14) -> str:
    lines = traceback.format_list(traceback.extract_stack(frame)[-depth:])  # type: ignore[arg-type]
    return "".join(line.split("\n", 1)[0] + "\n" for line in lines)


def _schedstat(native_id: int) -> tuple[float, float]:
    """Seconds a thread has run on a CPU and waited for one (Linux ``schedstat``)."""
    try:
        with open(f"/proc/self/task/{native_id}/schedstat") as fh:
            run, wait, _ = fh.read().split()
        return int(run) / 1e9, int(wait) / 1e9
    except (OSError, ValueError):
        return 0.0, 0.0


def _watch(loop: asyncio.AbstractEventLoop, ident: int, native_id: int, path: str) -> None:
    while not loop.is_closed():
        answered = threading.Event()
        ran0, waited0 = _schedstat(native_id)
        t0 = time.monotonic()
        try:
            loop.call_soon_threadsafe(answered.set)
        except RuntimeError:  # the loop closed
            return
        samples: collections.Counter[str] = collections.Counter()
        while not answered.wait(0.01):
            if time.monotonic() - t0 > THRESHOLD:
                frame = sys._current_frames().get(ident)
                if frame is not None:
                    samples[_stack(frame)] += 1
        stalled = time.monotonic() - t0
        if stalled > THRESHOLD:
            # Of the stall, the loop's thread ran (CPU), waited for a CPU (run queue) or for neither
            # (blocked: the GIL held by another thread, I/O).
            ran, waited = (b - a for a, b in zip((ran0, waited0), _schedstat(native_id), strict=True))
            with open(path, "a") as fh:
                fh.write(
                    f"=== pid {os.getpid()} at {time.strftime('%H:%M:%S')}: loop held {stalled * 1e3:.0f} ms: "
                    f"ran {ran * 1e3:.0f} ms, waited for a CPU {waited * 1e3:.0f} ms, blocked "
                    f"{(stalled - ran - waited) * 1e3:.0f} ms ({sum(samples.values())} samples)\n"
                )
                for stack, n in samples.most_common(3):
                    fh.write(f"--- {n} samples\n{stack}")
        time.sleep(0.05)


def start() -> None:
    """Start the watchdog for the running event loop, once per process, if ``BILIMOVICH_STALL_LOG`` names a file."""
    global _started
    path = os.environ.get("BILIMOVICH_STALL_LOG")
    if _started or not path:
        return
    _started = True
    loop = asyncio.get_running_loop()
    args = (loop, threading.get_ident(), threading.get_native_id(), path)
    threading.Thread(target=_watch, args=args, name="stall-watch", daemon=True).start()
