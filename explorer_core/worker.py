"""A warm worker for the command line: small jobs answer without paying numba's start-up again.

A ``bilimovich`` process spends ~0.75 s before a small job's first step: importing numba and loading
the cached kernels (numba's target context imports ~250 modules on the first load), ten times the
job itself. After a command that loaded the kernels, ``bilimovich`` leaves a worker process behind
(one per user, per version of this package and per ``BILIMOVICH_*``/``NUMBA_*`` environment): later
commands send it their arguments and working directory over a Unix socket (a 0700 directory of the
user's) and print what it writes; the worker runs them one at a time in its main thread exactly as
``bilimovich`` would (same parser, same outputs, files written relative to the caller's directory).
A command that finds the worker busy runs by itself. The worker exits after :data:`IDLE_S` idle
seconds, or on ``bilimovich worker stop``; ``BILIMOVICH_WORKER=0`` turns it off.

A job never outlives its caller: Ctrl-C, SIGTERM and SIGHUP of the client are forwarded, and a client
that disappears (its socket closed, or a write to it fails) cancels its job the same way. The client
waits until the job has stopped and written what it computed, prints what the job printed (its ``lost:``
lines, its summary) and exits with ``128 +`` its first signal (130, 143, 129): nothing computed is lost.
An analysis polls its ``cancel`` between kernels (numba kernels run without the GIL and cannot be
interrupted): a job not back within :data:`CANCEL_GRACE_S` says it is finishing its current step; one
still computing :data:`CANCEL_STOP_S` after the cancel (:data:`CANCEL_HARD_S` while it writes) is
abandoned: the worker exits, which stops the kernels, and the client says that nothing more was written;
the next command starts a new worker. A second signal leaves at once (the job then stops in the worker,
writing what it computed). :func:`run_here` gives a command run without the worker the same rules.

The worker's log records every job: its start (arguments, folder), a cancel and why, its end (exit status,
time, the ``lost:``, ``failed:`` and ``error:`` lines it printed), a traceback, an abandonment.

The worker holds an exclusive lock on ``worker-KEY.lock`` (beside its socket, holding its pid) from
before it compiles until it exits; the system drops the lock when the process dies, even by SIGKILL.
A socket nobody listens on whose lock is free is stale: the next command removes it and a new worker
starts; :func:`status` probes the socket with a ping and reports the pid.

Frames on the socket: a 1-byte kind and a 4-byte big-endian length, then the payload. The client sends
``h`` (the request as JSON: a command, ``{"ping": true}`` or ``{"stop": true}``) and ``i`` (cancel);
the worker sends ``a`` (accepted) or ``b`` (busy: run it yourself), then ``o``/``e`` (stdout/stderr
bytes) and ``x`` (the exit status as text); ``p`` answers a ping (JSON: ``pid``, ``busy``).
"""

from __future__ import annotations

import contextlib
import errno
import faulthandler
import fcntl
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
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, NamedTuple

from explorer_core import launch


def _remove_temporaries() -> list[str]:
    """The temporary files of the writes under way, removed (``explorer_core.export``'s, if it is loaded: a
    process that never imported it wrote nothing)."""
    export = sys.modules.get("explorer_core.export")
    return export.remove_temporaries() if export is not None else []


#: Seconds without a request after which the worker exits.
IDLE_S = float(os.environ.get("BILIMOVICH_WORKER_IDLE", "900"))
#: Commands never sent to the worker: they exec another program, manage the worker or compile.
LOCAL = frozenset({"serve", "worker", "warmup"})
#: How long a client waits for a worker to accept and say whether it is free.
CONNECT_S = 0.5
#: Seconds after a cancel when a command not back yet says it is finishing its current step.
CANCEL_GRACE_S = 0.8
#: Seconds a cancelled command may go on computing (its current kernel) before it is abandoned with what it
#: computed (``BILIMOVICH_CANCEL_STOP`` overrides it: the tests' bound).
CANCEL_STOP_S = float(os.environ.get("BILIMOVICH_CANCEL_STOP", "30"))
#: Seconds a cancelled command has to return whatever it is doing (writing what it computed so far).
CANCEL_HARD_S = max(120.0, CANCEL_STOP_S)
#: What a command that is not back within :data:`CANCEL_GRACE_S` of a cancel says (once).
FINISHING = ("\nbilimovich: stopping: the current step ends first, then what was computed is written "
             "(a second signal leaves at once without it)\n")  # fmt: skip
#: Signals of the client that cancel its job in the worker (as Ctrl-C does).
FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


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


def lock_path(sock: Path) -> Path:
    """The lock a live worker of socket ``sock`` holds (it contains the worker's pid)."""
    return sock.with_suffix(".lock")


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


# --- liveness: the worker's lock ------------------------------------------------------------------


def _take_lock(sock: Path, tries: int = 10) -> int | None:
    """An open descriptor holding ``sock``'s lock exclusively, or None if a live worker holds it.

    Retried for a moment: a client that checks the lock holds it for microseconds.
    """
    fd = os.open(lock_path(sock), os.O_RDWR | os.O_CREAT, 0o600)
    for i in range(tries):
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return fd
        except BlockingIOError:
            if i + 1 < tries:
                time.sleep(0.05)
    os.close(fd)
    return None


def holder(sock: Path) -> int | None:
    """The pid of the live worker of socket ``sock`` (0 if it has not written it yet), or None if none lives."""
    try:
        fd = os.open(lock_path(sock), os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            text = os.read(fd, 32).decode(errors="replace").strip()
            return int(text) if text.isdigit() else 0
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _remove_if_stale(sock: Path) -> bool:
    """Remove ``sock`` if no live worker holds its lock (under the lock: a worker starting now waits)."""
    try:
        fd = _take_lock(sock, tries=1)
    except OSError:
        return False
    if fd is None:
        return False
    try:
        sock.unlink(missing_ok=True)
        return True
    finally:
        os.close(fd)


def _connect(sock: Path) -> socket.socket:
    conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    conn.settimeout(CONNECT_S)
    try:
        conn.connect(str(sock))
    except BaseException:
        conn.close()
        raise
    return conn


def _refused(exc: OSError) -> bool:
    # Nobody listens on the socket (ECONNREFUSED), or it vanished meanwhile.
    return exc.errno in (errno.ECONNREFUSED, errno.ENOENT)


def _owned(sock: Path) -> bool:
    """Only a socket in a directory of this user's alone (nobody else could have put it there)."""
    try:
        st = sock.parent.stat()
        return not (st.st_uid != os.getuid() or st.st_mode & 0o077 or sock.stat().st_uid != os.getuid())
    except OSError:
        return False


# --- the client -----------------------------------------------------------------------------------


def command_of(argv: Sequence[str]) -> str | None:
    """The subcommand of ``argv`` (its first word that is not an option), or None."""
    return next((a for a in argv if not a.startswith("-")), None)


class _Leave(Exception):
    """A second signal: the client leaves without waiting for the worker."""


def run_in_worker(argv: Sequence[str]) -> int | None:
    """Run ``bilimovich argv`` in the worker and return its exit status; None if no free worker answered.

    A stale socket (a worker that died) is removed on the way, so the caller's run leaves a new worker.
    SIGINT, SIGTERM and SIGHUP cancel the job (forwarded); a second one returns at once (the worker then
    sees the socket close, which cancels the job too). Exit status after a forwarded SIGTERM/SIGHUP:
    128 + the signal's number.
    """
    path = socket_path()
    if not path.exists() or not _owned(path):
        return None
    try:
        sock = _connect(path)
    except OSError as exc:
        if _refused(exc):
            _remove_if_stale(path)
        return None
    received: list[int] = []
    accepted = False

    def tell(signum: int) -> None:
        with contextlib.suppress(OSError):
            _send(sock, b"i", str(int(signum)).encode())
        # The worker answers when the job has written what it computed, or abandons it (and exits, which
        # closes the socket) after CANCEL_HARD_S at the latest.
        sock.settimeout(CANCEL_HARD_S + 10.0)

    def forward(signum: int, frame: FrameType | None) -> None:
        received.append(signum)
        if len(received) > 1:
            raise _Leave
        if accepted:  # before, the job is told as soon as the worker has taken it
            tell(signum)

    def cancelled(status: int) -> int:
        # 128 + the first signal, as a lone process: an interrupted job (130) or one that had ended (0).
        return 128 + int(received[0]) if status in (0, 130) else status

    # The handlers before the request: a signal while the worker takes the job cancels it as any other (it
    # killed the client there, and the job went on to write a partial file after the client's exit).
    old = {s: signal.signal(s, forward) for s in FORWARDED}
    try:
        try:
            request = {"argv": list(argv), "cwd": os.getcwd(), "tty": [sys.stdout.isatty(), sys.stderr.isatty()]}
            _send(sock, b"h", json.dumps(request).encode())
            kind, payload = _recv(sock)  # "a" (accepted) or "b" (busy), at once
        except (OSError, ConnectionError):
            kind = b""
        if kind != b"a":  # no job: run here, unless a signal came (then nothing runs)
            if received:
                sys.stderr.write(f"bilimovich {command_of(argv) or ''}: interrupted\n")
                return 128 + int(received[0])
            return None
        sock.settimeout(None)
        accepted = True
        if received:
            tell(received[0])
        while True:
            try:
                kind, payload = _recv(sock)
            except (OSError, ConnectionError):
                if received:
                    return cancelled(130)
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
                return cancelled(int(payload)) if received else int(payload)
    except _Leave:  # wherever the second signal found us
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.write("\nbilimovich: left without waiting: the command stops in the worker, writing what it "
                             "computed so far\n")  # fmt: skip
        return cancelled(130)
    except BrokenPipeError:  # our reader left (``| head``): closing the socket cancels the job
        return 0
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        sock.close()


#: The worker's own log (its start, its end and why, a command's traceback, a fatal error's stacks) is started
#: afresh once it is larger than this.
LOG_BYTES = 1 << 20


def log_path(sock: Path) -> Path:
    """The worker's log beside its socket (``worker-KEY.log``, in the user's 0700 directory)."""
    return sock.with_name(sock.stem + ".log")


def _open_log(sock: Path) -> Any:
    """The log file a new worker's stderr goes to (appended to; started afresh past :data:`LOG_BYTES`)."""
    path = log_path(sock)
    try:
        big = path.stat().st_size > LOG_BYTES
    except OSError:
        big = False
    fh = open(path, "wb" if big else "ab")  # handed to the child as its stderr, closed by spawn
    os.chmod(path, 0o600)
    return fh


def _log(text: str) -> None:
    """A line in the worker's log (its stderr), stamped."""
    with contextlib.suppress(OSError, ValueError):
        sys.__stderr__.write(f"{time.strftime('%Y-%m-%d %H:%M:%S')} worker {os.getpid()}: {text}\n")
        sys.__stderr__.flush()


def spawn(command: Sequence[str]) -> None:
    """Start ``command + [socket path]`` in the background as the worker (it takes the lock, warms up,
    then listens; a second one finds the lock taken and exits). Not while a worker lives or starts; a
    stale socket is removed first."""
    try:
        path = _private_dir() / f"worker-{_key()}.sock"
    except OSError:
        return
    if len(os.fsencode(path)) > 107 or holder(path) is not None:  # a Unix socket's path has at most 107 bytes
        return
    if path.exists() and not _remove_if_stale(path):
        return
    try:
        log = _open_log(path)
    except OSError:
        log = None
    try:
        subprocess.Popen(  # this interpreter and our own command line
            [*command, str(path)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=log if log is not None else subprocess.DEVNULL,  # its own errors: a worker that died says why
            start_new_session=True,  # not in the terminal's process group: Ctrl-C there does not reach it
            close_fds=True,
        )
    finally:
        if log is not None:
            log.close()


class WorkerStatus(NamedTuple):
    """What :func:`status` found at ``path``.

    ``state``: ``listening`` (it answered a ping), ``starting`` (its lock is held, no socket yet: it is
    compiling), ``not answering`` (a live worker that did not answer within :data:`CONNECT_S`),
    ``stale`` (the socket of a worker that died: removed now) or ``none``.
    """

    state: str
    path: Path
    pid: int | None = None
    busy: bool | None = None

    def describe(self) -> str:
        pid = f"pid {self.pid}" if self.pid else "pid unknown"
        if self.state == "listening":
            return f"listening at {self.path} ({pid}, {'busy' if self.busy else 'idle'})"
        if self.state == "starting":
            return f"starting ({pid}, compiling the kernels; no socket yet at {self.path})"
        if self.state == "not answering":
            return f"not answering at {self.path} ({pid})"
        if self.state == "stale":
            return f"none running (removed the stale socket {self.path} of a worker that died)"
        return "none running"


def ping(path: Path) -> dict[str, Any]:
    """The worker's answer to a ping at ``path`` (``pid``, ``busy``); raises OSError/ConnectionError."""
    with _connect(path) as conn:
        _send(conn, b"h", json.dumps({"ping": True}).encode())
        kind, payload = _recv(conn)
    if kind != b"p":
        raise ConnectionError(f"the worker answered a ping with frame {kind!r}")
    return json.loads(payload)


def status(path: Path | None = None) -> WorkerStatus:
    """The truth about the worker of this code and environment (or of socket ``path``): the socket is
    probed, a stale one removed."""
    path = socket_path() if path is None else path
    pid = holder(path)
    if not path.exists():
        return WorkerStatus("starting" if pid is not None else "none", path, pid)
    try:
        answer = ping(path)
        return WorkerStatus("listening", path, int(answer.get("pid") or 0) or pid, bool(answer.get("busy")))
    except OSError as exc:
        if _refused(exc) and pid is None and _remove_if_stale(path):
            return WorkerStatus("stale", path)
        return WorkerStatus("not answering" if pid is not None or not _refused(exc) else "none", path, pid)
    except (ConnectionError, ValueError):
        return WorkerStatus("not answering", path, pid)


def status_text() -> str:
    """The line ``bilimovich worker status`` prints (and where the worker's log is, once there is one)."""
    state = "on" if enabled() else "off (BILIMOVICH_WORKER=0)"
    found = status()
    log = log_path(found.path)
    where = f"; its log: {log}" if log.exists() else ""
    return f"worker: {state}; for this code and environment: {found.describe()}{where}"


def stop_all() -> list[str]:
    """Ask every worker of this user to exit; returns the sockets that answered (stale ones are removed)."""
    stopped = []
    d = socket_dir()
    for path in sorted(d.glob("worker-*.sock")) if d.is_dir() else []:
        try:
            with _connect(path) as sock:
                _send(sock, b"h", json.dumps({"stop": True}).encode())
                _recv(sock)
                stopped.append(str(path))
        except OSError as exc:
            if _refused(exc):
                _remove_if_stale(path)
        except ConnectionError:
            pass
    return stopped


# --- cancelling: every job returns within a bound ---------------------------------------------------


#: Functions that write results: a cancelled command inside one gets :data:`CANCEL_HARD_S` to finish it.
_WRITERS = ("write", "to_csv", "to_npz", "save", "render", "dump")


def _writing(thread_id: int) -> bool:
    """Whether thread ``thread_id`` is writing results (a function of :data:`_WRITERS` or the reports on its
    stack) rather than computing (kernels run without the GIL and cannot be interrupted)."""
    frame = sys._current_frames().get(thread_id)
    while frame is not None:
        name = frame.f_code.co_name.lower()
        if any(w in name for w in _WRITERS) or "/explorer_core/reports/" in frame.f_code.co_filename:
            return True
        frame = frame.f_back
    return False


class _Watchdog:
    """After a cancel: ``late()`` once the job has not returned within :data:`CANCEL_GRACE_S`, then
    ``abandon()`` once it is still computing ``stop_s`` after the cancel (or, while it writes what it
    computed so far, :data:`CANCEL_HARD_S`)."""

    def __init__(self, late: Callable[[str], None], abandon: Callable[[str], None], stop_s: float) -> None:
        self._late, self._abandon, self._stop_s = late, abandon, stop_s
        self._main = threading.main_thread().ident or 0
        self.finished = threading.Event()
        self._cancelled = threading.Event()
        self._lock = threading.Lock()

    @property
    def cancelled(self) -> bool:
        return self._cancelled.is_set()

    def cancel(self) -> bool:
        """Start the clock (once); True the first time."""
        with self._lock:
            if self._cancelled.is_set() or self.finished.is_set():
                return False
            self._cancelled.set()
        threading.Thread(target=self._watch, daemon=True, name="bilimovich-cancel").start()
        return True

    def _watch(self) -> None:
        start = time.monotonic()
        told = False
        while not self.finished.wait(0.05):
            waited = time.monotonic() - start
            why = f"the command did not stop within {waited:.1f} s of the cancel"
            if not told and waited >= CANCEL_GRACE_S:
                told = True
                self._late(why)
            if (waited >= self._stop_s and not _writing(self._main)) or waited >= CANCEL_HARD_S:
                if not self.finished.is_set():
                    self._abandon(why)
                return

    def finish(self) -> None:
        self.finished.set()


def run_here(run: Callable[[list[str]], int], argv: Sequence[str]) -> int:
    """``run(argv)`` in this process with a stop signal (:data:`FORWARDED`) honoured as in the worker: the
    command's own handler is told (it stops, writes what it computed so far and returns); one not back
    within :data:`CANCEL_GRACE_S` says it is finishing its current step; one still computing
    :data:`CANCEL_STOP_S` after the signal (:data:`CANCEL_HARD_S` while it writes its results), or a second
    signal, ends the process with status ``128 +`` the first signal. The command must install Python
    handlers for these signals (the CLI's ``main`` does): only then does the interpreter report them here.
    For ``bilimovich``'s ``entry``: ``status = worker.run_here(main, argv)``."""
    if threading.current_thread() is not threading.main_thread():
        return run(list(argv))
    # The interpreter writes each signal's number to this socket the moment it arrives, whichever Python
    # handler the command installs and even while the main thread is inside a kernel.
    reader, writer = socket.socketpair()
    writer.setblocking(False)
    try:
        previous = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
    except ValueError:
        reader.close()
        writer.close()
        return run(list(argv))
    if previous != -1:  # someone else's (an event loop's): leave it alone
        signal.set_wakeup_fd(previous)
        reader.close()
        writer.close()
        return run(list(argv))

    first: list[int] = []

    def abandon(why: str) -> None:
        _remove_temporaries()  # the exit below unwinds nothing: no .part file left beside the results
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        os.write(2, f"\nbilimovich: interrupted; {why}: stopped, nothing more written\n".encode())
        os._exit(128 + (first[0] if first else int(signal.SIGINT)))

    def late(why: str) -> None:
        with contextlib.suppress(OSError):
            os.write(2, FINISHING.encode())

    dog = _Watchdog(late, abandon, CANCEL_STOP_S)
    stops = {int(s) for s in FORWARDED}

    def listen() -> None:
        while True:
            try:
                data = reader.recv(64)
            except OSError:
                return
            if not data:
                return
            for signum in (b for b in data if b in stops):
                first.append(signum)
                if not dog.finished.is_set() and not dog.cancel():
                    abandon(f"a second signal ({signal.Signals(signum).name})")

    threading.Thread(target=listen, daemon=True, name="bilimovich-signals").start()
    try:
        return run(list(argv))
    finally:
        dog.finish()
        signal.set_wakeup_fd(-1)
        writer.close()
        with contextlib.suppress(OSError):
            reader.shutdown(socket.SHUT_RDWR)  # wakes the listener (a close alone would not)
        reader.close()


# --- the worker -----------------------------------------------------------------------------------


class _Stream(io.TextIOBase):
    """A text stream that sends what is written to the client as frames of one kind; a failed write
    means the client is gone (``gone`` is called)."""

    #: The lines of a command's stderr the worker's log keeps (what it lost, why it failed, was interrupted).
    KEEP = (": lost: ", ": failed: ", ": error: ", ": interrupted", "internal error")

    def __init__(self, sock: socket.socket, kind: bytes, tty: bool, gone: Callable[[], None], keep: bool = False):
        self._sock, self._kind, self._tty, self._gone = sock, kind, tty, gone
        self.buffer = self  # type: ignore[assignment]  # for code that writes bytes
        self._text: list[str] | None = [] if keep else None
        self._size = 0

    def kept(self, most: int = 50) -> list[str]:
        """The lines of :data:`KEEP` written so far (at most ``most``: the log stays small)."""
        if self._text is None:
            return []
        lines = [ln.strip() for ln in "".join(self._text).splitlines() if any(k in ln for k in self.KEEP)]
        return lines[:most] + ([f"... {len(lines) - most} more"] if len(lines) > most else [])

    def write(self, text: Any) -> int:
        data = text if isinstance(text, bytes) else str(text).encode()
        if self._text is not None and self._size < LOG_BYTES:  # what the log may keep of it, bounded
            self._text.append(data.decode(errors="replace"))
            self._size += len(data)
        if data:
            try:
                _send(self._sock, self._kind, data)
            except OSError:
                self._gone()
        return len(text)

    def isatty(self) -> bool:
        return self._tty

    def writable(self) -> bool:
        return True


def serve(path: str, run: Callable[[list[str]], int], idle_s: float = IDLE_S) -> None:
    """The worker's loop: take the lock, warm up, listen on ``path``, run each request with ``run(argv)``
    (the command line's ``main``), one at a time, until idle for ``idle_s`` seconds or asked to stop."""
    p = Path(path)
    try:
        lock = _take_lock(p)
    except OSError:
        return
    if lock is None:
        return  # another worker of this code lives (or is starting)
    os.ftruncate(lock, 0)
    os.write(lock, f"{os.getpid()}\n".encode())
    # Between jobs the worker stays in its own directory, not in the one it was started from: that one can be
    # removed while the worker lives (a script's temporary directory), and a job's return to it then failed and
    # ended the worker.
    os.chdir(p.parent)
    # A fatal error (a crash in a kernel, an abort) writes every thread's stack to the log (stderr, see spawn).
    with contextlib.suppress(OSError, ValueError, AttributeError, io.UnsupportedOperation):
        faulthandler.enable(sys.__stderr__)
    _log(f"started for {path}")
    why = "stopped: an error in the worker's loop"
    # A stray SIGINT between jobs must not end the worker (a job installs its own handler).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from explorer_core.allocator import give_back  # here: a client imports this module and needs neither
    from explorer_core.warm import warm_all

    warm_all()
    if p.exists():  # a worker that died left its socket (we hold the lock: nobody else listens on it)
        p.unlink(missing_ok=True)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        server.bind(path)
    except OSError:
        os.close(lock)
        return
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
                if request.get("ping"):
                    _send(conn, b"p", json.dumps({"pid": os.getpid(), "busy": busy.is_set()}).encode())
                    conn.close()
                    continue
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
                try:
                    _send(conn, b"a", b"")
                    conn.settimeout(None)
                except OSError:
                    busy.clear()  # the client left before its job started
                    raise
                jobs.put((conn, request))
            except (OSError, ConnectionError, ValueError):
                conn.close()

    def leave() -> None:
        # Abandoning a job: the socket goes first, so no client meets a worker about to vanish.
        done.set()
        with contextlib.suppress(OSError):
            p.unlink()
        server.close()

    threading.Thread(target=accept, daemon=True, name="worker-accept").start()
    try:
        while not done.is_set():
            try:
                item = jobs.get(timeout=idle_s)
            except queue.Empty:
                why = f"idle for {idle_s:g} s"
                return
            if item is None:
                why = "asked to stop"
                return
            conn, request = item
            freed = threading.Event()

            def free(freed: threading.Event = freed) -> None:
                # Once per job: the job frees the worker just before its exit status goes out, so a command sent
                # the instant its caller has the status finds the worker free (it waits in ``jobs`` for this
                # job's last clean-up); before, it could meet "busy" and run by itself.
                if not freed.is_set():
                    freed.set()
                    busy.clear()

            try:
                _run_one(conn, request, run, leave, free)
            except KeyboardInterrupt:  # a cancel that arrived as the job ended: the worker goes on
                pass
            finally:
                conn.close()
                free()
            # What the job freed goes back to the system now, not when the worker exits (up to IDLE_S later):
            # glibc keeps a big job's high-water mark (a 10^7-point image: ~1 GB) otherwise.
            returned = give_back()
            if returned:
                _log(f"gave {returned:.0f} MB back to the system after the job")
    finally:
        done.set()
        server.close()
        with contextlib.suppress(OSError):
            if p.exists():
                p.unlink()
        _log(f"exits: {why}")
        os.close(lock)


def _run_one(
    conn: socket.socket,
    request: dict[str, Any],
    run: Callable[[list[str]], int],
    leave: Callable[[], None],
    free: Callable[[], None] = lambda: None,
) -> None:
    """One command, in this (the main) thread: its own streams and directory; a cancel (Ctrl-C, SIGTERM or
    SIGHUP of the client, or the client gone) is a SIGINT here, which the command's handler (or Python)
    takes. A command that has not returned :data:`CANCEL_GRACE_S` after a cancel: the client gets status
    130 at once (and the job's later output is dropped); one still computing :data:`CANCEL_STOP_S` after
    it is abandoned: this process exits (``leave`` first withdraws the socket). ``free`` is called when the
    command has returned, before its exit status is sent."""
    send_lock = threading.Lock()
    client_gone = threading.Event()
    answered = threading.Event()

    def answer(message: str, status: int) -> None:
        # The exit status goes to the client once; nothing after it.
        with send_lock:
            if answered.is_set() or client_gone.is_set():
                return
            answered.set()
            with contextlib.suppress(OSError):
                if message:
                    _send(conn, b"e", message.encode())
                _send(conn, b"x", str(status).encode())

    argv = list(request["argv"])
    job = f"job {argv} in {request.get('cwd')}"

    def late(why: str) -> None:
        with send_lock:
            if not (answered.is_set() or client_gone.is_set()):
                with contextlib.suppress(OSError):
                    _send(conn, b"e", FINISHING.encode())

    def abandon(why: str) -> None:
        gone = _remove_temporaries()  # the exit below unwinds nothing: no .part file left behind
        _log(f"{job}: abandoned ({why}, still computing); the worker exits"
             + (f"; removed {len(gone)} temporary files" if gone else ""))  # fmt: skip
        leave()
        answer(f"\nbilimovich: interrupted; {why}: stopped, nothing more written\n", 130)
        os._exit(130)

    dog = _Watchdog(late, abandon, CANCEL_STOP_S)

    def cancel(why: str) -> None:
        if not dog.finished.is_set() and dog.cancel():
            _log(f"{job}: cancelled ({why})")
            os.kill(os.getpid(), signal.SIGINT)

    def gone() -> None:
        client_gone.set()
        if not dog.cancelled:
            cancel("its client is gone")

    tty = request.get("tty", [False, False])
    out, err = _Stream(conn, b"o", bool(tty[0]), gone), _Stream(conn, b"e", bool(tty[1]), gone, keep=True)

    def listen() -> None:
        # A cancel from the client, or its socket closing: the caller is gone, the job with it.
        while not dog.finished.is_set():
            try:
                kind, payload = _recv(conn)
            except (OSError, ConnectionError):
                if not dog.finished.is_set():
                    gone()
                return
            if kind == b"i":
                name = signal.Signals(int(payload)).name if payload.isdigit() else "a signal"
                cancel(f"the client's {name}")

    try:
        home = os.getcwd()
    except OSError:  # removed under us: the job's directory is absolute, and afterwards the root will do
        home = "/"
    status = 1
    start = time.monotonic()
    _log(f"{job}: started")
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a lone process
    threading.Thread(target=listen, daemon=True, name="worker-listen").start()
    try:
        os.chdir(request["cwd"])
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):  # type: ignore[type-var]
            try:
                status = run(list(request["argv"]))
            except SystemExit as exc:  # argparse: usage errors and --help
                status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            except KeyboardInterrupt:
                status = 130
            except Exception:  # a command that raised (the CLI's main reports its own): as a lone process would
                traceback.print_exc()
                _log(f"{job} raised:\n{traceback.format_exc()}")
                status = 1
    except KeyboardInterrupt:
        status = 130
    except OSError as exc:
        err.write(f"bilimovich: {exc}\n")
    finally:
        dog.finish()
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            os.chdir(home)
        except OSError:
            os.chdir("/")
    said = "".join(f"\n  {line}" for line in err.kept())
    gone_ = ", its client gone" if client_gone.is_set() else ""
    _log(f"{job}: ended, exit status {status}, {time.monotonic() - start:.2f} s"
         f"{', cancelled' if dog.cancelled else ''}{gone_}{said}")  # fmt: skip
    free()
    answer("", int(status or 0))


# --- the console script ------------------------------------------------------------------------------------
# Here, not in explorer_core.cli: the command line (numpy, argparse's tree: ~0.15 s) is imported only when this
# process runs the command itself; a command the worker runs costs its client the interpreter and this module
# (~50 ms in all, 0.12 s before).

Main = Callable[[Sequence[str]], int]


def entry(load_main: Callable[[], Main]) -> None:
    """The ``bilimovich`` console script: a free warm worker runs the command if there is one, else this process
    does (``load_main()`` is the command line's ``main``: imported only then) and leaves a worker for the next
    command."""
    argv = sys.argv[1:]
    if argv[:1] == [launch.WORKER_ARG] and len(argv) == 2:
        serve(argv[1], load_main())
        return
    cmd = command_of(argv)
    # Outside the command's own handlers (main's, or the worker client's) a stop signal is no traceback and no
    # death by the signal: before the command it ends the process at once (nothing ran); after it, the files
    # are written and the exit status says the signal came (as a signal at the very end of the work does).
    late: list[int] = []

    def outside(signum: int, frame: Any) -> None:
        late.append(int(signum))
        if launch.began is None:
            # Nothing has run: end at once. Not by raising: the signal can land in a callback Python runs from C
            # (an import's module-lock weakref callback), which prints the exception as "ignored" with its
            # traceback and goes on with the command.
            launch.before_the_command(signum, frame)

    for s in launch.STOP_SIGNALS:
        signal.signal(s, outside)
    try:
        status = _entry(argv, cmd, load_main)
    except KeyboardInterrupt:
        sys.stderr.write(f"bilimovich{f' {cmd}' if cmd else ''}: interrupted\n")
        status = 128 + late[0] if late else 130
    if late and status == 0:
        sys.stderr.write(f"bilimovich{f' {cmd}' if cmd else ''}: interrupted ({signal.Signals(late[0]).name}) as "
                         "its work ended; what it wrote is complete\n")  # fmt: skip
        status = 128 + late[0]
    for s in launch.STOP_SIGNALS:  # the work is over: a signal now is ignored (Python's exit would die of it)
        signal.signal(s, signal.SIG_IGN)
    sys.exit(status)


def _entry(argv: list[str], cmd: str | None, load_main: Callable[[], Main]) -> int:
    """The command's exit status, run by a free warm worker if there is one, else here (then leaving a worker)."""
    use = enabled() and cmd is not None and cmd not in LOCAL and not {"-h", "--help"} & set(argv)
    if use:
        launch.began = True  # the client's handlers from here (a job may start: it runs to its end or is cancelled)
        status = run_in_worker(argv)
        launch.began = status is not None or None
        if status is not None:
            return status
    # A stop signal is honoured as in the worker, even inside a kernel.
    status = run_here(load_main(), argv)
    if use and "numba" in sys.modules:  # this run paid for the kernels: the next one need not
        with contextlib.suppress(OSError):
            spawn([sys.executable, "-m", "explorer_core.cli", launch.WORKER_ARG])
    return status
