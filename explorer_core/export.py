"""The one place files are written: CSV, JSON, NPZ/NPY, pictures, each at exactly the path given.

Every file reads back with ``csv``/``numpy``/``json``: numbers are written as numbers (``repr`` of a Python
float, the shortest text that reads back to the same double), never as ``np.float64(...)`` reprs.

CSV cells: ``None`` is an empty field; NaN is ``nan`` and infinities ``inf`` / ``-inf`` (both read back as
such by ``float`` and ``numpy.genfromtxt``, where an empty field reads as NaN too); booleans are ``0`` / ``1``.
JSON: numpy scalars and arrays become numbers and lists, dataclasses their fields (or ``as_dict()``), complex
numbers ``[re, im]``, and a NaN or infinite float ``null`` (JSON has no NaN).
NPZ/NPY: written through an open file, so numpy never appends a suffix of its own.

Every file is written whole or not at all (:func:`atomic`): to a temporary name in the same folder, synced
to the disk, then renamed onto the final name (SQLite's and PostgreSQL's rule: a crash, a full disk or an
interrupt leaves the last complete state). A writer that fails or is interrupted midway removes its
temporary file and leaves the final name untouched: the previous file, or none; never a cut line. An
error of the file system names the final path (a full disk said "No space left on device: None").
A CSV written with ``comments`` has them as ``# `` lines right after its header (``numpy.genfromtxt`` with
``names=True`` and ``loadtxt`` skip them; before the header ``genfromtxt`` would take one for the names): a
result whose run was stopped says so there, with what it lost (:func:`partial`).

:func:`check_output` is called before any work starts: a path whose suffix does not match what will be
written, or that cannot be written, is refused with one line naming it.
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import dataclasses
import errno
import io
import json
import math
import os
import queue
import secrets
import shutil
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, BinaryIO

import numpy as np


class OutputError(ValueError):
    """An output path that will not hold what is written (wrong suffix, missing folder, not writable)."""


def check_output(path: str, allowed_suffixes: Sequence[str], option: str = "--out") -> str:
    """Refuse ``path`` before any work if it does not end in one of ``allowed_suffixes`` or cannot be written.

    Writability is tried, not guessed: the file is opened for append (and removed again if this created it),
    which also catches read-only file systems and ``root`` writing into ``/proc``. Returns ``path``.
    """
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f"{option} must be a file name, got {text!r}")
    suffixes = tuple(s.lower() for s in allowed_suffixes)
    if suffixes and not text.lower().endswith(suffixes):
        raise OutputError(f"{option} must end in {' or '.join(suffixes)}, got {text!r}")
    folder = os.path.dirname(os.path.abspath(text))
    if not os.path.isdir(folder):
        raise OutputError(f"{option} {text}: the directory {folder} does not exist")
    if os.path.isdir(text):
        raise OutputError(f"{option} is a directory: {text}")
    existed = os.path.exists(text)
    try:
        with open(text, "ab"):
            pass
        # The file is written beside its final name and renamed onto it: the folder must take a new file too.
        _release(_reserve(text), remove=True)
    except OSError as exc:
        raise OutputError(f"{option} cannot be written: {text} ({exc.strerror or exc})") from None
    finally:
        if not existed and os.path.exists(text):
            os.remove(text)
    return text


# --- whole files or none ------------------------------------------------------------------------------------

#: The temporary files being written by :func:`atomic` in this context: a writer inside another's (a result's
#: ``write`` calling :func:`write_csv`) writes the outer temporary file directly, renamed once.
_WRITING: contextvars.ContextVar[frozenset[str]] = contextvars.ContextVar("export_writing", default=frozenset())


#: The temporary files of this process not yet renamed or removed: what :func:`remove_temporaries` removes when
#: the process must end at once (``os._exit``: a job abandoned by the worker, a lone command's second signal).
_TEMPORARIES: set[str] = set()
_TEMPORARIES_LOCK = threading.Lock()


def _reserve(path: str) -> str:
    """A new empty file beside ``path``, named after it and ending in its suffix (matplotlib and numpy read the
    format from it), created with the mode a plain ``open(path, "w")`` would give (0666 less the umask); it is
    one of :data:`_TEMPORARIES` until :func:`_release`."""
    folder, base = os.path.split(os.path.abspath(path))
    suffix = os.path.splitext(base)[1]
    while True:
        tmp = os.path.join(folder, f".{base}.{secrets.token_hex(4)}.part{suffix}")
        try:
            with _TEMPORARIES_LOCK:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                _TEMPORARIES.add(tmp)
            return tmp
        except FileExistsError:
            continue


def _release(tmp: str, remove: bool) -> None:
    """``tmp`` is no longer a temporary of this process (renamed, or removed now if ``remove``)."""
    with _TEMPORARIES_LOCK:
        if remove:
            with contextlib.suppress(OSError):
                os.remove(tmp)
        _TEMPORARIES.discard(tmp)


def remove_temporaries() -> list[str]:
    """Remove every temporary file this process still holds (a file being written, a streamed CSV's rows): for a
    process about to end without unwinding (``os._exit``), so no ``.part`` file is left beside the results.
    Returns the paths removed."""
    with _TEMPORARIES_LOCK:
        gone = sorted(_TEMPORARIES)
        for tmp in gone:
            with contextlib.suppress(OSError):
                os.remove(tmp)
        _TEMPORARIES.clear()
    return gone


def _sync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic(path: str) -> Iterator[str]:
    """A temporary path to write ``path``'s content to: on leaving the block it is synced and renamed onto
    ``path`` (``os.replace``, atomic on one file system); on any exception, ``KeyboardInterrupt`` included, it
    is removed and ``path`` is left as it was. A symbolic link at ``path`` keeps pointing at the new file.
    An ``OSError`` without a file name (a write to a full disk) is raised again naming ``path``."""
    text = os.fspath(path)
    if text in _WRITING.get():  # inside another atomic write of this very file: it renames once
        yield text
        return
    final = os.path.realpath(text) if os.path.islink(text) else text
    try:
        tmp = _reserve(final)
    except OSError as exc:
        raise _named(exc, text) from None
    token = _WRITING.set(_WRITING.get() | {tmp})
    try:
        yield tmp
        _sync(tmp)
        with _TEMPORARIES_LOCK:  # renamed and released at once: remove_temporaries never sees it half-done
            os.replace(tmp, final)
            _TEMPORARIES.discard(tmp)
    except BaseException as exc:
        _release(tmp, remove=True)
        if isinstance(exc, OSError) and exc.filename in (None, tmp):
            raise _named(exc, text) from exc
        raise
    finally:
        _WRITING.reset(token)
    with contextlib.suppress(OSError):  # the rename itself on the disk (not every file system can sync a folder)
        _sync(os.path.dirname(os.path.abspath(final)))


def _named(exc: OSError, path: str) -> OSError:
    """``exc`` naming ``path`` (its subclass kept: ``OSError(ENOSPC, ...)`` is an ``OSError``, ``ENOENT`` a
    ``FileNotFoundError``)."""
    code = exc.errno if exc.errno is not None else errno.EIO
    return OSError(code, exc.strerror or os.strerror(code), path)


# --- plain values ----------------------------------------------------------------------------------------


def plain(obj: Any) -> Any:
    """``obj`` as plain Python data for JSON: numbers, strings, lists, dicts, None (NaN/inf -> None)."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (complex, np.complexfloating)):
        return [plain(obj.real), plain(obj.imag)]
    if isinstance(obj, np.ndarray):
        return [plain(v) for v in obj.tolist()] if obj.ndim else plain(obj.item())
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [plain(v) for v in obj]
    if hasattr(obj, "as_dict"):
        return plain(obj.as_dict())
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"cannot write a {type(obj).__name__} as JSON")


def dumps(obj: Any) -> str:
    """One line of strict JSON (no NaN), numpy and dataclasses converted by :func:`plain`."""
    return json.dumps(plain(obj), separators=(",", ": "), allow_nan=False)


def cell(value: Any) -> Any:
    """One CSV cell: a number as a number (round-trip ``repr``), None empty, text as text."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return repr(float(value))  # 'nan', 'inf', '-inf' for the non-finite
    if isinstance(value, (complex, np.complexfloating)):
        raise TypeError("write the real and imaginary parts of a complex number as two columns")
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return cell(value.item())
    return str(value)


# --- files -----------------------------------------------------------------------------------------------


def write_csv(path: str, header: Sequence[str], rows: Iterable[Sequence[Any]], comments: Sequence[str] = ()) -> int:
    """Write ``header``, ``comments`` (``# `` lines) and ``rows`` (cells by :func:`cell`) to exactly ``path``,
    whole or not at all (:func:`atomic`); returns the row count."""
    n = 0
    with atomic(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(header))
        fh.writelines(comment_lines(comments))
        for row in rows:
            if len(row) != len(header):
                raise ValueError(f"CSV row {n} has {len(row)} cells for {len(header)} columns")
            w.writerow([cell(v) for v in row])
            n += 1
    return n


def csv_head(header: Sequence[str], comments: Sequence[str] = ()) -> str:
    """A CSV's first lines: ``header`` as :func:`write_csv` writes it (``csv`` quoting, ``\\r\\n``) and the
    ``comments`` (:func:`comment_lines`)."""
    buf = io.StringIO()
    csv.writer(buf).writerow(list(header))
    return buf.getvalue() + "".join(comment_lines(comments))


def comment_lines(comments: Sequence[str]) -> list[str]:
    """``# text`` lines for a CSV's head, after its header line (one per line of each comment)."""
    return [f"# {line}\n" for text in comments for line in str(text).splitlines() or [""]]


def partial(result: Any) -> list[str]:
    """The CSV head comments of a result whose run was stopped before its end (a cancel, a stop signal:
    ``completed`` false, or a loss ``cancelled``, as the crossings of manifolds grown to their end): that it is
    partial, and each of its losses. Nothing for a run that ended (members that failed are ``lost:`` lines and
    ``complete: false`` in JSON, not a partial file)."""
    losses = list(getattr(result, "lost", None) or ())
    if bool(getattr(result, "completed", True)) and not any("cancel" in loss.why for loss in losses):
        return []
    lost = [loss.line() for loss in losses]
    return ["partial: the run was stopped before its end; this file holds what it had computed (complete: false)",
            *lost]  # fmt: skip


def write_json(path: str, obj: Any) -> None:
    """``obj`` as indented strict JSON at exactly ``path``, whole or not at all."""
    with atomic(path) as tmp, open(tmp, "w") as fh:
        json.dump(plain(obj), fh, indent=1, allow_nan=False)
        fh.write("\n")


def write_npz(path: str, **arrays: Any) -> None:
    """A compressed ``.npz`` at exactly ``path`` (numpy appends ``.npz`` to a bare name; a file handle not)."""
    with atomic(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def write_npy(path: str, array: Any) -> None:
    """One array as ``.npy`` at exactly ``path``."""
    with atomic(path) as tmp, open(tmp, "wb") as fh:
        np.save(fh, np.asarray(array))


def write_through(path: str, writer: Callable[[BinaryIO], Any]) -> Any:
    """Let a result's own ``to_npz``-style writer fill exactly ``path`` (it gets an open binary file)."""
    with atomic(path) as tmp, open(tmp, "wb") as fh:
        return writer(fh)


def write_text(path: str, text: str) -> None:
    """``text`` at exactly ``path``, whole or not at all."""
    with atomic(path) as tmp, open(tmp, "w") as fh:
        fh.write(text)


def save_figure(fig: Any, path: str, **kw: Any) -> None:
    """A matplotlib figure at exactly ``path`` in the format of its suffix, whole or not at all."""
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or None
    with atomic(path) as tmp:
        fig.savefig(tmp, format=fmt, **kw)


def write_by_suffix(path: str, writers: dict[str, Callable[[str], Any]], what: str = "result") -> dict[str, Any]:
    """Write ``path`` with the writer of its suffix (``{".csv": fn, ".json": fn, ...}``, each ``fn(path)``).

    The one shape of a result's ``write(path)``: a suffix it has no writer for is refused with one line
    naming the ones it has (the command line refuses it before any work, :func:`check_output`). The
    writer fills a temporary file renamed onto ``path`` when it returns (:func:`atomic`: whatever it
    opens itself is whole or absent too). Returns what the CLI reports: ``{"path": path}``, with
    ``"rows"`` when the writer returns a row count.
    """
    text = os.fspath(path)
    for suffix, writer in writers.items():
        if text.lower().endswith(suffix):
            with atomic(text) as tmp:
                rows = writer(tmp)
            return (
                {"path": text, "rows": rows} if isinstance(rows, int) and not isinstance(rows, bool) else {"path": text}
            )
    raise OutputError(f"a {what} is written as {' or '.join(writers)}, got {text!r}")


# --- a CSV written while its run goes ---------------------------------------------------------------------

#: Rows a :class:`StreamedCsv` may hold not yet written: the run waits for its writer beyond this, so a stop
#: waits for at most about this many rows (~0.1-0.5 s of formatting) before the file is whole.
STREAM_BACKLOG_ROWS = 200_000


class StreamedCsv:
    """A CSV whose rows are written while its run computes them, so that the end of the run (a stop signal
    included) only adds a head and renames: millions of rows no longer take seconds after the stop.

    A thread turns each piece :meth:`put` (or :meth:`feed`) gives it into text (``lines(piece)``: whole
    ``\\r\\n``-ended rows, as :func:`write_csv` writes them) and appends it to a temporary rows file beside
    ``path``; :meth:`write` then writes the final file as :func:`atomic` does: a temporary file with the
    header, the comments known only then (a stopped run's :func:`partial` lines) and the rows copied in the
    kernel, synced, renamed onto ``path``. :meth:`discard` (or leaving a ``with`` block by an exception)
    removes the temporary files and leaves ``path`` untouched. The writer keeps at most
    :data:`STREAM_BACKLOG_ROWS` rows behind: the run waits for it beyond that (never slower than writing after
    the run, which it overlaps).
    """

    def __init__(self, path: str, header: Sequence[str], lines: Callable[[Any], str], count: Callable[[Any], int],
                 backlog: int = STREAM_BACKLOG_ROWS) -> None:  # fmt: skip
        self.path = os.fspath(path)
        self._header, self._lines, self._count, self._backlog = list(header), lines, count, backlog
        final = os.path.realpath(self.path) if os.path.islink(self.path) else self.path
        try:
            self._rows_path = _reserve(final)
            self._fh = open(self._rows_path, "wb")  # closed when the thread ends (write, discard)
        except OSError as exc:
            raise _named(exc, self.path) from None
        self.rows = 0
        self._pending = 0
        self._error: BaseException | None = None
        self._room = threading.Condition()
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._drain, daemon=True, name="bilimovich-csv")
        self._thread.start()

    def __enter__(self) -> StreamedCsv:
        return self

    def __exit__(self, kind: Any, *exc: Any) -> None:
        if kind is not None:
            self.discard()

    _END = object()

    def feed(self, piece: Any) -> None:
        """Queue one piece of rows (``count(piece)`` of them): a run's progress update."""
        self.put(piece, self._count(piece))

    def put(self, piece: Any, rows: int) -> None:
        """Queue ``piece`` (``rows`` rows once written); waits while the writer is more than the backlog behind."""
        with self._room:
            self._room.wait_for(lambda: self._pending <= self._backlog or self._error is not None)
            self._pending += rows
        self._queue.put((piece, rows))

    def _drain(self) -> None:
        while True:
            item = self._queue.get()
            if item is self._END:
                return
            piece, rows = item
            try:
                if self._error is None:
                    self._fh.write(self._lines(piece).encode())
                    self.rows += rows
            except BaseException as exc:  # a full disk: said by write()
                self._error = exc
            with self._room:
                self._pending -= rows
                self._room.notify_all()

    def _stop_thread(self) -> None:
        if self._thread.is_alive():
            self._queue.put(self._END)
            self._thread.join()
        self._fh.close()

    def write(self, comments: Sequence[str] = ()) -> int:
        """The final file: the header, ``comments`` and every row put, whole at ``path`` (:func:`atomic`);
        returns the row count. The temporary rows file is removed whatever happens."""
        try:
            self._stop_thread()
            if self._error is not None:
                exc = self._error
                raise _named(exc, self.path) if isinstance(exc, OSError) else exc
            with atomic(self.path) as tmp, open(tmp, "wb") as out, open(self._rows_path, "rb") as rows:
                out.write(csv_head(self._header, comments).encode())
                out.flush()
                _copy(rows, out)
        finally:
            _release(self._rows_path, remove=True)
        return self.rows

    def write_result(self, result: Any) -> dict[str, Any]:
        """:meth:`write` with ``result``'s :func:`partial` lines (a stopped run says so); what a result's
        ``write`` returns: ``{"path", "rows"}``."""
        return {"path": self.path, "rows": self.write(partial(result))}

    def discard(self) -> None:
        """Nothing written: the temporary rows file removed, ``path`` as it was."""
        with contextlib.suppress(OSError):
            self._stop_thread()
        _release(self._rows_path, remove=True)


def _copy(src: BinaryIO, dst: BinaryIO) -> None:
    """``src`` from its position appended to ``dst``: in the kernel where it can (``copy_file_range``), else
    through a buffer."""
    size = os.fstat(src.fileno()).st_size - src.tell()
    try:
        while size > 0:
            done = os.copy_file_range(src.fileno(), dst.fileno(), size)
            if done == 0:
                break
            size -= done
    except (AttributeError, OSError) as exc:
        if isinstance(exc, OSError) and exc.errno not in (errno.EXDEV, errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP):
            raise
        shutil.copyfileobj(src, dst, 1 << 20)
