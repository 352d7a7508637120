"""A warm worker for the command line: small jobs answer without paying numba's start-up again.

A ``bilimovich`` process spends ~0.75 s before a small job's first step: importing numba and loading
the cached kernels (numba's target context imports ~250 modules on the first load), ten times the
job itself. After a command that loaded the kernels, ``bilimovich`` leaves a worker process behind
(one per user, per version of this package and per ``BILIMOVICH_*``/``NUMBA_*`` environment): later
commands send it their arguments and working directory over a Unix socket (a 0700 directory of the
user's) and print what it writes; the worker runs them one at a time in its main thread exactly as
``bilimovich`` would (same parser, same outputs, files written relative to the caller's directory,
Ctrl-C forwarded). A command that finds the worker busy runs by itself. The worker exits after
:data:`IDLE_S` idle seconds, or on ``bilimovich worker stop``; ``BILIMOVICH_WORKER=0`` turns it off.

Frames on the socket: a 1-byte kind and a 4-byte big-endian length, then the payload. The client sends
``h`` (the request as JSON) and ``i`` (Ctrl-C); the worker sends ``o``/``e`` (stdout/stderr bytes),
``x`` (the exit status as text) or ``b`` (busy: run it yourself).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import queue
import signal
import socket
import struct
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

#: Seconds without a request after which the worker exits.
IDLE_S = float(os.environ.get("BILIMOVICH_WORKER_IDLE", "900"))
#: Commands never sent to the worker: they exec another program, manage the worker or compile.
LOCAL = frozenset({"serve", "worker", "warmup"})
#: How long a client waits for a worker to accept and say whether it is free.
CONNECT_S = 0.5


def enabled() -> bool:
    return os.environ.get("BILIMOVICH_WORKER", "1") != "0"


def _key() -> str:
    """This package's version of the code (its files' sizes and times), the interpreter and the environment."""
    h = hashlib.sha256(sys.executable.encode())
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")) + sorted(root.glob("*.json")):
        st = path.stat()
        h.update(f"{path.relative_to(root)}:{st.st_size}:{st.st_mtime_ns};".encode())
    for k in sorted(os.environ):
        if k.startswith(("BILIMOVICH_", "NUMBA_", "OPENBLAS_")) and not k.startswith("BILIMOVICH_WORKER"):
            h.update(f"{k}={os.environ[k]};".encode())
    return h.hexdigest()[:16]


def socket_dir() -> Path:
    base = os.environ.get("BILIMOVICH_WORKER_DIR") or os.environ.get("XDG_RUNTIME_DIR") or "/tmp"
    return Path(base) / f"bilimovich-{os.getuid()}"


def socket_path() -> Path:
    return socket_dir() / f"worker-{_key()}.sock"


def _private_dir() -> Path:
    d = socket_dir()
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = d.stat()
    if st.st_uid != os.getuid() or st.st_mode & 0o077:
        raise PermissionError(f"{d} must be a directory of this user's alone (mode 0700)")
    return d


# --- frames ---------------------------------------------------------------------------------------


def _send(sock: socket.socket, kind: bytes, payload: bytes) -> None:
    sock.sendall(kind + struct.pack(">I", len(payload)) + payload)


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        part = sock.recv(n - len(buf))
        if not part:
            raise ConnectionError("the other side closed the socket")
        buf += part
    return buf


def _recv(sock: socket.socket) -> tuple[bytes, bytes]:
    head = _recv_exact(sock, 5)
    (n,) = struct.unpack(">I", head[1:])
    return head[:1], _recv_exact(sock, n)


# --- the client -----------------------------------------------------------------------------------


def command_of(argv: Sequence[str]) -> str | None:
    """The subcommand of ``argv`` (its first word that is not an option), or None."""
    return next((a for a in argv if not a.startswith("-")), None)


def run_in_worker(argv: Sequence[str]) -> int | None:
    """Run ``bilimovich argv`` in the worker and return its exit status; None if no free worker answered."""
    path = socket_path()
    if not path.exists():
        return None
    try:  # only a worker in a directory of this user's alone (nobody else could have put a socket there)
        st = path.parent.stat()
        if st.st_uid != os.getuid() or st.st_mode & 0o077 or path.stat().st_uid != os.getuid():
            return None
    except OSError:
        return None
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(CONNECT_S)
    try:
        sock.connect(str(path))
        request = {"argv": list(argv), "cwd": os.getcwd(), "tty": [sys.stdout.isatty(), sys.stderr.isatty()]}
        _send(sock, b"h", json.dumps(request).encode())
        kind, payload = _recv(sock)  # "a" (accepted) or "b" (busy), at once
    except (OSError, ConnectionError):
        sock.close()
        return None
    if kind != b"a":
        sock.close()
        return None
    sock.settimeout(None)
    old = signal.getsignal(signal.SIGINT)

    def interrupt(signum: int, frame: Any) -> None:
        with contextlib.suppress(OSError):
            _send(sock, b"i", b"")

    signal.signal(signal.SIGINT, interrupt)
    try:
        while True:
            try:
                kind, payload = _recv(sock)
            except (OSError, ConnectionError):
                sys.stderr.write("bilimovich: the worker stopped before the command ended\n")
                return 1
            if kind == b"o":
                sys.stdout.buffer.write(payload)
                sys.stdout.flush()
            elif kind == b"e":
                sys.stderr.buffer.write(payload)
                sys.stderr.flush()
            elif kind == b"x":
                if os.environ.get("BILIMOVICH_WORKER_TRACE"):
                    sys.stderr.write(f"bilimovich: served by the worker at {path}\n")
                return int(payload)
    finally:
        signal.signal(signal.SIGINT, old)
        sock.close()


def spawn(command: Sequence[str]) -> None:
    """Start ``command + [socket path]`` in the background as the worker (it warms up, then listens; a
    second one finds the socket taken and exits)."""
    try:
        path = _private_dir() / f"worker-{_key()}.sock"
    except OSError:
        return
    if path.exists() or len(os.fsencode(path)) > 107:  # a Unix socket's path has at most 107 bytes
        return
    subprocess.Popen(  # this interpreter and our own command line
        [*command, str(path)],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # not in the terminal's process group: Ctrl-C there does not reach it
        close_fds=True,
    )


def stop_all() -> list[str]:
    """Ask every worker of this user to exit; returns the sockets that answered."""
    stopped = []
    d = socket_dir()
    for path in sorted(d.glob("worker-*.sock")) if d.is_dir() else []:
        with contextlib.suppress(OSError, ConnectionError), socket.socket(socket.AF_UNIX) as sock:
            sock.settimeout(CONNECT_S)
            sock.connect(str(path))
            _send(sock, b"h", json.dumps({"stop": True}).encode())
            _recv(sock)
            stopped.append(str(path))
    return stopped


# --- the worker -----------------------------------------------------------------------------------


class _Stream(io.TextIOBase):
    """A text stream that sends what is written to the client as frames of one kind."""

    def __init__(self, sock: socket.socket, kind: bytes, tty: bool) -> None:
        self._sock, self._kind, self._tty = sock, kind, tty
        self.buffer = self  # type: ignore[assignment]  # for code that writes bytes

    def write(self, text: Any) -> int:
        data = text if isinstance(text, bytes) else str(text).encode()
        if data:
            with contextlib.suppress(OSError):
                _send(self._sock, self._kind, data)
        return len(text)

    def isatty(self) -> bool:
        return self._tty

    def writable(self) -> bool:
        return True


def serve(path: str, run: Callable[[list[str]], int], idle_s: float = IDLE_S) -> None:
    """The worker's loop: warm up, listen on ``path``, run each request with ``run(argv)`` (the command
    line's ``main``), one at a time, until idle for ``idle_s`` seconds or asked to stop."""
    from explorer_core.warm import warm_all

    warm_all()
    p = Path(path)
    if p.exists():  # a worker that died left its socket: take it over unless one still answers
        with contextlib.suppress(OSError), socket.socket(socket.AF_UNIX) as probe:
            probe.settimeout(CONNECT_S)
            probe.connect(path)
            return
        p.unlink(missing_ok=True)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        server.bind(path)
    except OSError:
        return  # another worker just took it
    os.chmod(path, 0o600)
    server.listen(8)
    jobs: queue.Queue = queue.Queue(maxsize=1)
    busy = threading.Event()
    done = threading.Event()

    def accept() -> None:
        # Answers every connection at once: the first while idle gets the worker, later ones "busy".
        while not done.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                return
            try:
                conn.settimeout(CONNECT_S)
                kind, payload = _recv(conn)
                request = json.loads(payload)
                if request.get("stop"):
                    _send(conn, b"x", b"0")
                    conn.close()
                    done.set()
                    with contextlib.suppress(queue.Full):
                        jobs.put_nowait(None)
                    return
                if busy.is_set():
                    _send(conn, b"b", b"")
                    conn.close()
                    continue
                busy.set()
                _send(conn, b"a", b"")
                conn.settimeout(None)
                jobs.put((conn, request))
            except (OSError, ConnectionError, ValueError):
                conn.close()

    threading.Thread(target=accept, daemon=True, name="worker-accept").start()
    try:
        while not done.is_set():
            try:
                item = jobs.get(timeout=idle_s)
            except queue.Empty:
                return  # idle
            if item is None:
                return
            conn, request = item
            try:
                _run_one(conn, request, run)
            finally:
                conn.close()
                busy.clear()
    finally:
        done.set()
        server.close()
        with contextlib.suppress(OSError):
            if p.exists():
                p.unlink()


def _run_one(conn: socket.socket, request: dict[str, Any], run: Callable[[list[str]], int]) -> None:
    """One command, in this (the main) thread: its own streams and directory, Ctrl-C as SIGINT."""
    tty = request.get("tty", [False, False])
    out, err = _Stream(conn, b"o", bool(tty[0])), _Stream(conn, b"e", bool(tty[1]))
    finished = threading.Event()

    def listen() -> None:
        # Ctrl-C from the client: a SIGINT to this process, which the command's handler (or Python) takes.
        while not finished.is_set():
            try:
                kind, _ = _recv(conn)
            except (OSError, ConnectionError):
                return
            if kind == b"i" and not finished.is_set():
                os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=listen, daemon=True, name="worker-listen").start()
    cwd = os.getcwd()
    status = 1
    try:
        os.chdir(request["cwd"])
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):  # type: ignore[type-var]
            try:
                status = run(list(request["argv"]))
            except SystemExit as exc:  # argparse: usage errors and --help
                status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            except KeyboardInterrupt:
                status = 130
    except OSError as exc:
        err.write(f"bilimovich: {exc}\n")
    finally:
        finished.set()
        os.chdir(cwd)
    with contextlib.suppress(OSError):
        _send(conn, b"x", str(int(status or 0)).encode())
