"""The command line's warm worker: same answers as a lone process, files where the caller is, busy and Ctrl-C;
a job stops with its caller, Ctrl-C within a second, a dead worker's socket recovered, every kernel warmed."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
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
    # The console script's client hands the command over without loading the command line (numpy, argparse's
    # tree: ~0.15 s of a command's start).
    script = ("import atexit, sys; atexit.register(lambda: print('loaded:', sorted({'numpy', 'explorer_core.cli'} & "
              f"set(sys.modules)), file=sys.stderr)); sys.argv = ['bilimovich', *{SMALL!r}]; "
              "from explorer_core.__main__ import entry; entry()")  # fmt: skip
    client = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=120)  # fmt: skip
    assert client.returncode == 0 and strip(client.stdout) == strip(alone.stdout)
    assert "served by the worker" in client.stderr and "loaded: []" in client.stderr


def long_job_in_worker(env: dict[str, str]) -> subprocess.Popen:
    """A worker left by a small command, then a long section sent to it (running after 3 s)."""
    bilimovich(SMALL, env, ROOT)
    wait_for_worker(env)
    long = subprocess.Popen([sys.executable, "-m", "explorer_core.cli", "section", "--scene", "fig1C", "--periods",
                             "100000", "--random", "20", "--quiet", "--json"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    time.sleep(3.0)  # the worker is running it
    return long


def test_busy_worker_and_ctrl_c(env: dict[str, str]) -> None:
    long = long_job_in_worker(env)
    meanwhile = bilimovich(SMALL, env, ROOT)
    assert meanwhile.returncode == 0 and "served by the worker" not in meanwhile.stderr  # ran by itself
    long.send_signal(signal.SIGINT)  # forwarded: the command stops and says so
    out, err = long.communicate(timeout=120)
    assert long.returncode == 130, err
    assert "interrupted" in err
    # The worker lives on. It frees itself just after the client has its exit status: under load a command sent
    # in that instant finds it busy and runs by itself (correctly), so wait until it says it is idle.
    deadline = time.time() + 30
    while "(" in (s := bilimovich(["worker", "status"], env, ROOT).stdout) and "idle" not in s:
        assert time.time() < deadline, s
        time.sleep(0.2)
    again = bilimovich(SMALL, env, ROOT)
    assert again.returncode == 0 and "served by the worker" in again.stderr


def test_command_of_and_what_stays_local() -> None:
    assert worker.command_of(["--version"]) is None
    assert worker.command_of(["section", "--scene", "fig1A"]) == "section"
    assert {"serve", "worker", "warmup"} <= worker.LOCAL


# --- a job never outlives its caller; a dead worker never blocks the next; every kernel warmed ---------------


def status_line(env: dict[str, str]) -> str:
    """What ``bilimovich worker status`` prints (``worker.status_text``), in the clients' environment."""
    code = "from explorer_core import worker; print(worker.status_text())"
    return subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True,
                          timeout=60).stdout  # fmt: skip


def wait_gone(pid: int, timeout: float = 30.0) -> None:
    deadline = time.time() + timeout
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        assert time.time() < deadline, f"process {pid} still alive"
        time.sleep(0.05)


def test_a_stale_socket_is_recovered_and_status_tells_the_truth(env: dict[str, str]) -> None:
    bilimovich(SMALL, env, ROOT)
    wait_for_worker(env)
    line = status_line(env)
    assert "listening at" in line and "(pid " in line, line
    pid = int(line.split("(pid ")[1].split(",")[0])
    os.kill(pid, signal.SIGKILL)  # dies without a word: its socket stays
    wait_gone(pid)
    (sock,) = Path(env["BILIMOVICH_WORKER_DIR"]).glob("*/worker-*.sock")
    assert sock.exists()
    line = status_line(env)
    assert "listening" not in line and "stale socket" in line, line
    # A command after the death runs by itself and leaves a new worker, which then serves.
    bilimovich(SMALL, env, ROOT)
    wait_for_worker(env)
    served = bilimovich(SMALL, env, ROOT)
    assert served.returncode == 0 and "served by the worker" in served.stderr, served.stderr
    new = status_line(env)
    assert "listening at" in new and f"(pid {pid}," not in new


def test_a_stale_socket_left_before_any_status_is_removed_by_the_next_command(env: dict[str, str]) -> None:
    bilimovich(SMALL, env, ROOT)
    wait_for_worker(env)
    pid = int(status_line(env).split("(pid ")[1].split(",")[0])
    os.kill(pid, signal.SIGKILL)
    wait_gone(pid)
    first = bilimovich(SMALL, env, ROOT)  # meets the dead socket: runs here, removes it, leaves a worker
    assert first.returncode == 0 and "served by the worker" not in first.stderr
    deadline = time.time() + 120
    while "listening at" not in status_line(env):
        assert time.time() < deadline, "no new worker after a stale socket"
        time.sleep(0.5)
    assert "served by the worker" in bilimovich(SMALL, env, ROOT).stderr


# A job that writes a line every 0.1 s and stops when its Ctrl-C flag is set (as the commands' _Interrupt
# does), served by the real worker loop: the side effect tells whether the job still runs.
FAKE_SERVE = """
import os, signal, sys, time
from explorer_core import worker

KEPT = []

def run(argv):
    mode, path = argv
    if mode == "quick":
        return 0
    if mode == "fragments":  # ~430 MB freed between blocks that stay: glibc keeps those pages by itself
        import numpy as np
        blocks = [np.ones(2000) for _ in range(30000)]
        KEPT.extend(blocks[::20])
        return 0
    flag = []
    signal.signal(signal.SIGINT, lambda *a: flag.append(1))
    if mode == "ignores":  # a CSV streamed while it runs: its rows in a temporary file beside the result
        from explorer_core import export
        export.StreamedCsv(path + ".csv", ["x"], str, lambda piece: 1).feed("1\\n")
    with open(path, "a") as fh:
        for _ in range(3000):
            if flag and mode == "polls":
                print("interrupted", file=sys.stderr)
                return 130
            fh.write("tick\\n")
            fh.flush()
            print("tick", flush=True)
            time.sleep(0.1)
    return 0

worker.serve(str(worker._private_dir() / ("worker-" + worker._key() + ".sock")), run, idle_s=120)
"""
FAKE_CLIENT = "import sys; from explorer_core import worker; sys.exit(worker.run_in_worker(sys.argv[1:]))"
# A command whose handlers take the stop signals (as the CLI's main does) and never look at them again.
FAKE_HERE = """
import signal, sys, time
from explorer_core import worker

def run(argv):
    for s in worker.FORWARDED:
        signal.signal(s, lambda *a: None)
    time.sleep(120)
    return 0

sys.exit(worker.run_here(run, []))
"""


def serve_fake(env: dict[str, str]):
    """The fake worker's process, running until the test ends."""
    proc = subprocess.Popen([sys.executable, "-c", FAKE_SERVE], env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    try:
        wait_for_worker(env)
        yield proc
    finally:
        proc.kill()
        proc.wait(timeout=30)


@pytest.fixture
def fake_worker(env: dict[str, str]):
    yield from serve_fake(env)


def lines(path: Path) -> int:
    return len(path.read_text().splitlines()) if path.exists() else 0


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL, signal.SIGHUP])
def test_a_job_whose_caller_is_killed_stops(env: dict[str, str], fake_worker, tmp_path: Path, how: int) -> None:
    side = tmp_path / "side.txt"
    client = subprocess.Popen([sys.executable, "-c", FAKE_CLIENT, "polls", str(side)], env=env, cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    deadline = time.time() + 60
    while lines(side) < 5:
        assert time.time() < deadline and client.poll() is None, "the job did not start in the worker"
        time.sleep(0.05)
    client.send_signal(how)
    client.communicate(timeout=30)
    if how != signal.SIGKILL:  # forwarded, answered: 128 + the signal, as a lone process
        assert client.returncode == 128 + how
    time.sleep(1.5)  # the cancel reaches the job within one tick
    stopped_at = lines(side)
    time.sleep(1.5)
    assert lines(side) == stopped_at, "the job went on writing after its caller was killed"
    assert fake_worker.poll() is None  # it stopped by itself: the worker lives on, free
    assert "idle" in status_line(env)


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL])
def test_a_command_whose_client_is_killed_frees_the_worker(env: dict[str, str], how: int) -> None:
    long = long_job_in_worker(env)
    long.send_signal(how)
    long.communicate(timeout=60)
    if how == signal.SIGTERM:
        assert long.returncode == 128 + how
    deadline = time.time() + 15  # the command stops at its next look at Ctrl-C's flag: the worker is free
    while "served by the worker" not in bilimovich(SMALL, env, ROOT).stderr:
        assert time.time() < deadline, "the job went on after its client was killed"
        time.sleep(0.2)


def test_a_command_sent_as_the_last_one_ends_finds_the_worker_free(env: dict[str, str], fake_worker) -> None:
    """The worker is free before a job's exit status goes out: commands sent back to back are all served by it
    (before, one sent in the instant between the status and the worker freeing itself met "busy" and ran by
    itself: correct, only slower; CI under load met it once)."""
    code = ("import sys; from explorer_core import worker\n"
            "print(sum(worker.run_in_worker(['quick', 'x']) is None for _ in range(50)))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "0", out.stdout + out.stderr


def test_a_worker_whose_start_directory_is_removed_goes_on(env: dict[str, str], tmp_path: Path) -> None:
    """A worker started from a directory that is then removed (a script's temporary directory: the first command
    there leaves the worker) serves the next command from elsewhere; it used to fail to return there when the job
    began and die, and that command exited 1 ("the worker stopped before the command ended")."""
    start = tmp_path / "gone"
    start.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", FAKE_SERVE], env=env, cwd=start, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    try:
        wait_for_worker(env)
        start.rmdir()
        for _ in range(2):
            done = subprocess.run([sys.executable, "-c", FAKE_CLIENT, "quick", "x"], env=env, cwd=ROOT,
                                  capture_output=True, text=True, timeout=60)  # fmt: skip
            assert done.returncode == 0 and "served by the worker" in done.stderr, done.stderr
        assert proc.poll() is None
    finally:
        proc.kill()
        proc.wait(timeout=30)


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="Linux's /proc")
def test_the_worker_gives_a_jobs_freed_memory_back(env: dict[str, str], fake_worker, tmp_path: Path) -> None:
    """A job that frees ~430 MB between blocks it keeps: the worker's RSS comes back near what it was before the
    job (+ the ~22 MB kept), not ~450 MB up until the worker exits 15 minutes later."""
    from explorer_core.allocator import allocator, rss_mb

    if allocator() is None:
        pytest.skip("glibc's mallinfo2 / malloc_trim only")
    before = rss_mb(fake_worker.pid)
    done = subprocess.run([sys.executable, "-c", FAKE_CLIENT, "fragments", str(tmp_path / "x")], env=env, cwd=ROOT,
                          timeout=120)  # fmt: skip
    assert done.returncode == 0
    deadline = time.monotonic() + 20
    while (after := rss_mb(fake_worker.pid)) > before + 150 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert after < before + 150, (before, after)


def test_a_job_frees_the_worker_before_its_exit_status_goes_out() -> None:
    """The order that closes the race above, deterministically: ``free`` before the ``x`` message."""
    import socket as sk

    worker_end, client_end = sk.socketpair()
    events: list[str] = []
    request = {"argv": [], "cwd": os.getcwd(), "tty": [False, False]}
    old = signal.getsignal(signal.SIGINT)
    try:

        def free() -> None:
            try:
                client_end.recv(1, sk.MSG_PEEK | sk.MSG_DONTWAIT)
                events.append("free after the status was sent")
            except BlockingIOError:
                events.append("free")

        worker._run_one(worker_end, request, lambda argv: 3, lambda: None, free)
    finally:
        signal.signal(signal.SIGINT, old)
    assert events == ["free"]
    client_end.settimeout(10)
    kind, payload = worker._recv(client_end)  # sent after free() was called (the job's status)
    assert (kind, payload) == (b"x", b"3")
    worker_end.close()
    client_end.close()


def read_lines(stream) -> list[str]:
    """The lines of ``stream`` as they come (a thread appends them)."""
    got: list[str] = []
    threading.Thread(target=lambda: got.extend(iter(stream.readline, "")), daemon=True).start()
    return got


def wait_for(got: list[str], text: str, timeout: float) -> float:
    """Seconds until a line containing ``text`` is in ``got``."""
    start = time.monotonic()
    while not any(text in line for line in got):
        assert time.monotonic() - start < timeout, f"no {text!r} within {timeout} s: {got}"
        time.sleep(0.02)
    return time.monotonic() - start


@pytest.fixture
def quick_stop_worker(env: dict[str, str]):
    """The fake worker, abandoning a cancelled job that does not stop after 3 s (instead of CANCEL_STOP_S)."""
    env["BILIMOVICH_CANCEL_STOP"] = "3"
    yield from serve_fake(env)


def test_a_job_that_does_not_stop_is_waited_for_then_left(env: dict[str, str], quick_stop_worker, tmp_path) -> None:
    """The client waits for its job to stop and write what it computed (the job's lines reach it): one that does
    not stop says so within a second; a second Ctrl-C leaves at once; the worker abandons the job after its
    bound (BILIMOVICH_CANCEL_STOP) and exits (kernels cannot be stopped otherwise)."""
    side = tmp_path / "side.txt"
    client = subprocess.Popen([sys.executable, "-c", FAKE_CLIENT, "ignores", str(side)], env=env, cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    err = read_lines(client.stderr)
    deadline = time.time() + 60
    while lines(side) < 5:
        assert time.time() < deadline and client.poll() is None, "the job did not start in the worker"
        time.sleep(0.05)
    assert len(list(tmp_path.glob(".side.txt.csv.*.part.csv"))) == 1  # the streamed CSV's rows, under way
    client.send_signal(signal.SIGINT)  # the job never looks at its flag
    assert wait_for(err, "stopping: the current step ends first", 1.5) < 1.5
    assert client.poll() is None  # still waiting for its job
    start = time.monotonic()
    client.send_signal(signal.SIGINT)
    client.wait(timeout=30)
    assert time.monotonic() - start < 1.5 and client.returncode == 130
    wait_for(err, "left without waiting", 5)
    quick_stop_worker.wait(timeout=3 + 10)
    stopped_at = lines(side)
    time.sleep(0.5)
    assert lines(side) == stopped_at
    assert "listening" not in status_line(env)  # no stale socket left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["side.txt"]  # nor a temporary file


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_in_a_lone_process_is_honoured(how: int) -> None:
    """Without the worker the same rules: the command is told, says within a second that it finishes its step,
    a second signal ends the process at once, and one that never stops is ended after the bound, exit 128 + the
    first signal."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "BILIMOVICH_CANCEL_STOP": "3"}
    for second in (True, False):
        proc = subprocess.Popen([sys.executable, "-c", FAKE_HERE], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)  # fmt: skip
        err = read_lines(proc.stderr)
        time.sleep(3.0)  # imported and running
        proc.send_signal(how)
        wait_for(err, "stopping: the current step ends first", 1.5)
        start = time.monotonic()
        if second:
            proc.send_signal(how)
        proc.wait(timeout=30)
        took = time.monotonic() - start
        assert proc.returncode == 128 + how, err
        assert took < (1.5 if second else 3 + 1.5), f"took {took:.2f} s"
        wait_for(err, "nothing more written", 5)


FIND_KERNELS = """
import importlib, json, pkgutil, sys
import explorer_core
from numba.core.dispatcher import Dispatcher
from explorer_core.warm import warm_all

warm_all()
found = {}
def visit(obj, where):
    if isinstance(obj, Dispatcher):
        found.setdefault(id(obj), (obj, where))
    elif isinstance(obj, (tuple, list)):
        for i, o in enumerate(obj):
            visit(o, f"{where}[{i}]")
for info in pkgutil.walk_packages(explorer_core.__path__, "explorer_core."):
    mod = importlib.import_module(info.name)
    for name, value in vars(mod).items():
        visit(value, f"{info.name}.{name}")

# A kernel compiled inside another (a leaf it calls, or one inlined) is loaded with its caller from the
# cache and then has no signature of its own: covered are the kernels compiled and those they reach.
def callees(d):
    names, codes = set(), [d.py_func.__code__]
    while codes:
        code = codes.pop()
        names.update(code.co_names)
        codes.extend(c for c in code.co_consts if hasattr(c, "co_names"))
    out = [d.py_func.__globals__.get(n) for n in names]
    out += [c.cell_contents for c in d.py_func.__closure__ or ()]
    return [o for o in out if isinstance(o, Dispatcher)]
covered = {i for i, (d, _) in found.items() if d.signatures}
todo = [d for d, _ in found.values() if d.signatures]
while todo:
    for c in callees(todo.pop()):
        if id(c) not in covered:
            covered.add(id(c))
            todo.append(c)
missing = sorted(w for i, (d, w) in found.items() if i not in covered)

# The analyses then meet only the signatures warmed (another argument type would compile again).
import contextlib, io
from explorer_core.cli import main
before = {i: len(d.signatures) for i, (d, _) in found.items()}
for argv in COMMANDS:
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(argv) == 0, argv
recompiled = sorted(w for i, (d, w) in found.items() if len(d.signatures) != before[i])
print(json.dumps({"all": len(found), "missing": missing, "recompiled": recompiled}))
"""
#: Small commands over the engine's systems and block kinds, the tangent system and the model's kernels.
COMMANDS = [
    ["continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.355", "--from=-0.0959,-1.962",
     "--period", "1", "--switch", "--json"],
    ["lyapunov", "--scene", "fig8B", "--ic", "0.1,0.2", "--transient", "10", "--periods", "20", "--json", "--quiet"],
    ["orbits", "--scene", "fig10", "--period", "1", "--seed=-0.0959,-1.962", "--json", "--quiet"],
    ["critical", "--scene", "fig1A", "--json"],
    SMALL,
]  # fmt: skip


def test_warm_all_compiles_every_kernel() -> None:
    """Every numba dispatcher of the package is compiled by warm_all (or inside one it compiles), with the
    argument types the analyses use."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "BILIMOVICH_WORKER": "0"}
    code = f"COMMANDS = {COMMANDS!r}\n{FIND_KERNELS}"
    proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True,
                          timeout=900)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["all"] >= 30  # the walk finds the kernels (the engine's six among them)
    assert report["missing"] == [], f"kernels warm_all does not compile: {report['missing']}"
    assert report["recompiled"] == [], f"kernels compiled again by the analyses: {report['recompiled']}"


LOGGED_SERVE = """
import os, sys
from explorer_core import worker

def run(argv):
    if argv == ["boom"]:
        raise RuntimeError("a bug in a command")
    if argv == ["crash"]:
        os.abort()  # a fatal error (as a crash in a kernel would be)
    return 0

worker.serve(sys.argv[1], run, idle_s=120)
"""


def test_a_worker_that_dies_says_why_in_its_log_and_a_command_that_raises_does_not_kill_it(env) -> None:
    """The worker's own stderr goes to ``worker-KEY.log`` beside its socket (it was /dev/null: a worker that died
    left no trace). A command that raises gets its traceback and status 1, as a lone process would, and the worker
    lives on (before: the exception left the worker's loop and the worker died, the caller got "the worker stopped
    before the command ended"). A fatal error writes the threads' stacks to the log; ``worker status`` names it."""
    script = Path(env["BILIMOVICH_WORKER_DIR"]) / "serve.py"
    script.write_text(LOGGED_SERVE)
    spawn = "import sys; from explorer_core import worker; worker.spawn([sys.executable, sys.argv[1]])"
    subprocess.run([sys.executable, "-c", spawn, str(script)], env=env, cwd=ROOT, timeout=60, check=True)
    wait_for_worker(env)
    (path,) = Path(env["BILIMOVICH_WORKER_DIR"]).glob("*/worker-*.sock")
    log = worker.log_path(path)

    def client(*argv: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", FAKE_CLIENT, *argv], env=env, cwd=ROOT, capture_output=True,
                              text=True, timeout=60)  # fmt: skip

    boom = client("boom")
    assert boom.returncode == 1 and "RuntimeError: a bug in a command" in boom.stderr
    assert client("fine").returncode == 0  # the same worker, alive
    assert "started for" in log.read_text() and "a bug in a command" in log.read_text()
    crash = client("crash")
    assert crash.returncode != 0
    deadline = time.time() + 30
    while "Fatal Python error" not in log.read_text():
        assert time.time() < deadline, log.read_text()
        time.sleep(0.2)
    status = subprocess.run([sys.executable, "-m", "explorer_core.cli", "worker", "status"], env=env, cwd=ROOT,
                            capture_output=True, text=True, timeout=60)  # fmt: skip
    assert f"its log: {log}" in status.stdout
