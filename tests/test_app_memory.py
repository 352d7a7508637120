"""The server gives the memory it freed back to the system (app/memory.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from app import memory

ROOT = Path(__file__).resolve().parents[1]
glibc = pytest.mark.skipif(memory.allocator() is None, reason="glibc's mallinfo2 / malloc_trim only")


def _run(code: str, **env: str) -> str:
    full = {**os.environ, "PYTHONPATH": str(ROOT), "MALLOC_ARENA_MAX": "2", **env}
    cmd = [sys.executable, "-c", textwrap.dedent(code)]
    out = subprocess.run(cmd, env=full, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout


@glibc
def test_freed_pages_between_live_blocks_are_given_back() -> None:
    # One block in 20 stays: glibc cannot return the pages between them by itself; the RSS stays up until trimmed.
    out = _run(
        """
        import numpy as np
        from app import memory
        blocks = [np.ones(2000) for _ in range(30000)]
        kept = blocks[::20]
        del blocks
        held, before = memory.allocator()["held_free"], memory.rss_mb()
        returned = memory.give_back()
        print(held, before, returned, memory.rss_mb(), memory.TRIMS["trims"], memory.give_back())
        """
    )
    held, before, returned, after, trims, again = map(float, out.split())
    assert held > 300  # ~430 MB freed and kept
    assert returned > 0.8 * held and after < before - 0.8 * held
    assert trims == 1
    assert again == 0.0  # nothing kept any more: no second trim


@glibc
def test_little_kept_is_not_trimmed() -> None:
    assert memory.give_back(above_mb=1e9) == 0.0


def test_started_once_per_process_and_off_with_zero() -> None:
    # warm.py runs as the server's setup script and again as a module: one thread each, not two.
    out = _run(
        """
        import threading
        from app import memory
        memory.start(); memory.start()
        print(sorted(t.name for t in threading.enumerate() if t.name.startswith("memory")))
        """,
        BILIMOVICH_TRIM_EVERY="30",
        BILIMOVICH_MEMORY_LOG="",
    )
    assert out.strip() == ("['memory-give-back']" if memory.allocator() is not None else "[]")
    out = _run(
        """
        import threading
        from app import memory
        memory.start()
        print(sorted(t.name for t in threading.enumerate() if t.name.startswith("memory")))
        """,
        BILIMOVICH_TRIM_EVERY="0",
    )
    assert out.strip() == "[]"


def test_the_diagnostic_writes_a_line_per_sample(tmp_path: Path) -> None:
    log = tmp_path / "mem"
    _run(
        """
        import time
        from app import memory
        memory.start()
        time.sleep(1.5)
        """,
        BILIMOVICH_MEMORY_LOG=str(log),
        BILIMOVICH_MEMORY_EVERY="0.5",
        BILIMOVICH_TRACEMALLOC="2",
    )
    import json

    (path,) = tmp_path.glob("mem.*")
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert len(lines) >= 2
    assert {"rss", "allocator", "objects", "types", "classes", "threads", "trims", "traced_mb"} <= set(lines[0])
    assert "grew" in lines[-1]  # compared with the first sample's snapshot


def test_the_app_file_defines_no_class_of_its_own() -> None:
    # Bokeh runs app/main.py as a new module for every session: a class defined there is a new class per session,
    # and the page's location class stayed alive, one per session (1,300 in an hour: app/memory.py found it).
    import runpy

    name = "app_main_as_a_module"  # not "bokeh_app...": the page itself is not built
    ns = runpy.run_path(str(ROOT / "app" / "main.py"), run_name=name)
    assert [k for k, v in ns.items() if isinstance(v, type) and v.__module__ == name] == []
