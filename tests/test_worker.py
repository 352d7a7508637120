"""The command line's warm worker: same answers as a lone process, files where the caller is, busy and Ctrl-C."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from explorer_core import worker

ROOT = Path(__file__).resolve().parents[1]
SMALL = ["section", "--scene", "fig1A", "--ic", "0.1,0.2", "--periods", "10", "--quiet", "--json"]


def bilimovich(args: list[str], env: dict[str, str], cwd: Path, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "explorer_core.cli", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300, **kw)  # fmt: skip


@pytest.fixture
def env():
    # A short directory: a Unix socket's path must fit in 107 bytes (pytest's tmp_path may not).
    sock_dir = tempfile.mkdtemp(prefix="bw-", dir="/tmp")
    e = {**os.environ, "BILIMOVICH_WORKER": "1", "BILIMOVICH_WORKER_DIR": sock_dir,
         "BILIMOVICH_WORKER_TRACE": "1", "PYTHONPATH": str(ROOT)}  # fmt: skip
    yield e
    subprocess.run([sys.executable, "-m", "explorer_core.cli", "worker", "stop"], env=e, cwd=ROOT, timeout=60,
                   capture_output=True)  # fmt: skip
    shutil.rmtree(sock_dir, ignore_errors=True)


def wait_for_worker(env: dict[str, str], timeout: float = 120.0) -> None:
    d = Path(env["BILIMOVICH_WORKER_DIR"])
    deadline = time.time() + timeout
    while not list(d.glob("*/worker-*.sock")):
        assert time.time() < deadline, "no worker started"
        time.sleep(0.2)


def test_a_worker_answers_like_a_lone_process(env: dict[str, str], tmp_path: Path) -> None:
    alone = bilimovich(SMALL, {**env, "BILIMOVICH_WORKER": "0"}, ROOT)
    first = bilimovich(SMALL, env, ROOT)  # runs here, then leaves a worker
    assert first.returncode == 0 and "served by the worker" not in first.stderr
    wait_for_worker(env)
    served = bilimovich(SMALL, env, ROOT)
    assert served.returncode == 0 and "served by the worker" in served.stderr
    strip = lambda out: out.split('"elapsed_s"')[0]  # noqa: E731 - the timings differ
    assert strip(served.stdout) == strip(alone.stdout) == strip(first.stdout)
    # Files go where the caller is; bad input is refused the same way.
    work = tmp_path / "here"
    work.mkdir()
    out = bilimovich([*SMALL[:-1], "--out", "s.csv"], env, work)
    assert out.returncode == 0 and (work / "s.csv").read_text().startswith("traj,k,q,r")
    bad = bilimovich(["section", "--scene", "nope"], env, ROOT)
    assert bad.returncode == 2 and "unknown scene" in bad.stderr and "served by the worker" in bad.stderr
    status = bilimovich(["worker", "status"], env, ROOT)
    assert "listening at" in status.stdout


def test_busy_worker_and_ctrl_c(env: dict[str, str]) -> None:
    bilimovich(SMALL, env, ROOT)
    wait_for_worker(env)
    long = subprocess.Popen([sys.executable, "-m", "explorer_core.cli", "section", "--scene", "fig1C", "--periods",
                             "100000", "--random", "20", "--quiet", "--json"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    time.sleep(3.0)  # the worker is running it
    meanwhile = bilimovich(SMALL, env, ROOT)
    assert meanwhile.returncode == 0 and "served by the worker" not in meanwhile.stderr  # ran by itself
    long.send_signal(signal.SIGINT)  # forwarded: the command stops and says so
    out, err = long.communicate(timeout=120)
    assert long.returncode == 130, err
    assert "interrupted" in err
    again = bilimovich(SMALL, env, ROOT)  # the worker lives on
    assert again.returncode == 0 and "served by the worker" in again.stderr


def test_command_of_and_what_stays_local() -> None:
    assert worker.command_of(["--version"]) is None
    assert worker.command_of(["section", "--scene", "fig1A"]) == "section"
    assert {"serve", "worker", "warmup"} <= worker.LOCAL
