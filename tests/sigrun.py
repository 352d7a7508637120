"""Run the ``bilimovich`` command as a user does (its own process, stderr on a terminal) and signal it; read its
files back (tests/test_interrupts.py, tests/test_interrupt_fuzz.py)."""

from __future__ import annotations

import contextlib
import csv
import os
import pty
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def signalled(argv: list[str], sig: int, env: dict[str, str], cwd: Path, after: float = 0.5,
              at: float | None = None) -> tuple[int, str, float]:  # fmt: skip
    """Run ``bilimovich argv`` with stderr on a terminal, send ``sig`` ``after`` seconds once its progress shows
    (or ``at`` seconds after its start, whatever it is doing then; not at all if it has ended), and return the
    exit status, what it wrote on stderr and the seconds from the signal to its exit."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "explorer_core.cli", *argv], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=slave, text=True)  # fmt: skip
    os.close(slave)
    chunks: list[bytes] = []

    def read() -> None:
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    if at is None:
        deadline = time.monotonic() + 240
        # The work runs: a progress line (\r) or a stage's time, not only the worker's greeting.
        while not any(m in b"".join(chunks) for m in (b"\r", b"sections: ")):
            assert proc.poll() is None, b"".join(chunks).decode(errors="replace")
            assert time.monotonic() < deadline, "no progress within 240 s"
            time.sleep(0.05)
        time.sleep(after)
    else:
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=at)
    start = time.monotonic()
    if proc.poll() is None:
        proc.send_signal(sig)
    proc.communicate(timeout=180)
    took = time.monotonic() - start
    reader.join(timeout=10)
    os.close(master)
    return proc.returncode, b"".join(chunks).decode(errors="replace").replace("\r\n", "\n"), took


def check_csv(path: Path, numbers: bool = True) -> bool:
    """The CSV reads back whole (every row as wide as its header, the last line ended; with ``numbers``, by
    numpy too); True if it says it is partial (its run was stopped)."""
    text = path.read_text()
    assert text.endswith("\n"), f"{path} ends in a cut line"
    lines = text.splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.reader(ln for ln in lines if not ln.startswith("#")))
    assert rows and all(len(r) == len(rows[0]) for r in rows), f"{path} has a cut row"
    if numbers and len(rows) > 1:
        # (the first 100000 rows: genfromtxt takes a minute for millions; csv read every row above)
        np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8", max_rows=100_000)
    return bool(head) and lines[1].startswith("# partial: the run was stopped")


@contextlib.contextmanager
def warm_worker() -> Iterator[dict[str, str]]:
    """The environment of commands served by a warm worker of their own (started here, stopped after)."""
    # A short directory: a Unix socket's path must fit in 107 bytes (pytest's tmp_path may not).
    sock_dir = tempfile.mkdtemp(prefix="bwi-", dir="/tmp")
    env = {**os.environ, "BILIMOVICH_WORKER": "1", "BILIMOVICH_WORKER_DIR": sock_dir, "BILIMOVICH_WORKER_TRACE": "1",
           "PYTHONPATH": str(ROOT)}  # fmt: skip
    try:
        small = ["section", "--scene", "fig1A", "--ic", "0.1,0.2", "--periods", "3", "--quiet"]
        subprocess.run([sys.executable, "-m", "explorer_core.cli", *small], env=env, cwd=ROOT, timeout=300, check=True)
        deadline = time.monotonic() + 240
        while not list(Path(sock_dir).glob("*/worker-*.sock")):
            assert time.monotonic() < deadline, "no worker started"
            time.sleep(0.2)
        yield env
    finally:
        subprocess.run([sys.executable, "-m", "explorer_core.cli", "worker", "stop"], env=env, cwd=ROOT, timeout=60,
                       capture_output=True)  # fmt: skip
        shutil.rmtree(sock_dir, ignore_errors=True)
