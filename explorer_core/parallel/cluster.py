"""The Dask executor: an analysis's tasks on a Dask cluster (``dask.distributed``).

A *scheduler* is ``"tcp://HOST:PORT"`` (a running ``dask scheduler``), ``"local:N"`` (a
:class:`distributed.LocalCluster` of ``N`` single-threaded worker processes, started on first use and
kept for the life of this process) or a ``distributed.Client``. :class:`DaskExecutor` implements the
executor protocol of :mod:`explorer_core.parallel.executor`: the analysis hands it its tasks (a chart's
tiles, the chunks of a sweep), pure functions of plain data, and gets their results back as they
complete (``as_completed``), so charts fill in and progress is reported exactly as locally. Tasks run
single-threaded with the same kernels, so the results are identical to a local run whatever the number
of workers. A lost worker's tasks are rescheduled by the scheduler; ``retries`` re-runs a task that
raised; ``cancel`` is polled while waiting and cancels every outstanding task.

Connecting checks that the scheduler answers, that it has a worker and that the workers run the same
numeric code (:func:`fingerprint`); every failure is a :class:`SchedulerError` naming the address.
Nothing here imports an analysis: the command line and the app make the executor and pass it in.
``dask`` is imported only when a scheduler is used.
"""

from __future__ import annotations

import asyncio
import atexit
import hashlib
import os
import re
import socket
import threading
import time
import warnings
import weakref
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from explorer_core.system.params import ParameterError

#: Environment variable the app reads its scheduler from (unset or empty: local).
ENV_VAR = "BILIMOVICH_SCHEDULER"
#: Seconds to wait for a scheduler to answer (and for it to have a worker).
DEFAULT_TIMEOUT = 10.0
#: Re-runs of a task that raised (a lost worker is handled by the scheduler itself).
RETRIES = 2
#: How often ``cancel`` is polled while tasks run (seconds).
POLL_S = 0.05
#: Tasks queued per worker thread: enough to keep workers busy, few enough that cancel is cheap.
TASKS_PER_THREAD = 2
MAX_LOCAL_WORKERS = 256
#: The code that decides the numbers, every module of these floors of the core: workers must run the same.
NUMERIC_PACKAGES = ("system", "solve", "analyses")


class SchedulerError(ConnectionError):
    """A Dask scheduler that cannot be reached or used; the message names its address."""


_TCP = re.compile(r"tcp://(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(?P<port>[0-9]{1,5})")
_LOCAL = re.compile(r"local(?::(?P<n>[0-9]{1,4}))?")


def parse_scheduler(address: Any) -> str:
    """Canonical scheduler address: ``tcp://HOST:PORT`` or ``local:N``.

    ``local`` alone means one worker per core. Anything else is a
    :class:`~explorer_core.system.model.ParameterError` that names the bad value.
    """
    text = str(address).strip() if isinstance(address, str) else None
    hint = "use tcp://HOST:PORT (a running `dask scheduler`) or local:N (N worker processes on this machine)"
    if not text:
        raise ParameterError(f"scheduler address must be a non-empty string, got {address!r}; {hint}")
    if m := _LOCAL.fullmatch(text):
        n = int(m["n"]) if m["n"] is not None else (os.cpu_count() or 1)
        if not 1 <= n <= MAX_LOCAL_WORKERS:
            raise ParameterError(f"scheduler {text!r}: N must be in [1, {MAX_LOCAL_WORKERS}]")
        return f"local:{n}"
    m = _TCP.fullmatch(text)
    if m is None:
        raise ParameterError(f"bad scheduler address {text[:80]!r}; {hint}")
    if not 1 <= int(m["port"]) <= 65535:
        raise ParameterError(f"bad scheduler address {text!r}: port must be in [1, 65535]")
    return f"tcp://{m['host']}:{int(m['port'])}"


def scheduler_from_env(environ: dict[str, str] | None = None) -> str | None:
    """The scheduler configured in ``BILIMOVICH_SCHEDULER`` (``None`` if unset or empty), validated."""
    value = (os.environ if environ is None else environ).get(ENV_VAR, "").strip()
    if not value:
        return None
    try:
        return parse_scheduler(value)
    except ParameterError as exc:
        raise ParameterError(f"{ENV_VAR}: {exc}") from None


# ---------------------------------------------------------------------------
# What the workers must share with us for identical results.


@cache
def fingerprint() -> dict[str, str]:
    """Versions that decide the numbers: the numeric modules' source and the numerical libraries."""
    import llvmlite
    import numba

    core = Path(__file__).resolve().parents[1]
    h = hashlib.sha256((core / "config.py").read_bytes())
    for pkg in NUMERIC_PACKAGES:
        for path in sorted((core / pkg).glob("*.py")):
            h.update(path.name.encode() + path.read_bytes())
    return {
        "explorer_core": h.hexdigest()[:16],
        "numpy": np.__version__,
        "numba": numba.__version__,
        "llvmlite": llvmlite.__version__,
    }


def host_cpu() -> str:
    """The CPU numba compiles for (kernels compiled for different CPUs may differ in the last bits)."""
    import llvmlite.binding

    return str(llvmlite.binding.get_host_cpu_name())


def _worker_info() -> tuple[dict[str, str], str]:
    return fingerprint(), host_cpu()


# ---------------------------------------------------------------------------
# Clients.

_clients: dict[str, Any] = {}
_clusters: dict[str, Any] = {}
_checked: weakref.WeakSet = weakref.WeakSet()
_clients_lock = threading.Lock()


def get_client(scheduler: Any, *, timeout: float = DEFAULT_TIMEOUT, warm: Callable[[], None] | None = None) -> Any:
    """A ready ``distributed.Client`` for ``scheduler``, cached per address for the life of the process.

    Connecting checks that the scheduler answers within ``timeout`` seconds, that
    it has at least one worker and that the workers run the same numeric code and
    libraries (:func:`fingerprint`); every failure is a :class:`SchedulerError`
    naming the address. ``warm`` (e.g. :func:`explorer_core.warm.warm_all`) runs once on every
    worker before the first task.
    """
    from distributed import Client

    if isinstance(scheduler, Client):
        with _clients_lock:
            if scheduler not in _checked:
                _prepare(scheduler, str(scheduler.scheduler.address), timeout, warm)
                _checked.add(scheduler)
        return scheduler
    address = parse_scheduler(scheduler)
    with _clients_lock:
        client = _clients.get(address)
        if client is not None and client.status == "running":
            return client
        client = _connect(address, timeout)
        try:
            _prepare(client, address, timeout, warm)
        except BaseException:
            client.close()
            raise
        _clients[address] = client
        return client


def close_clients() -> None:
    """Close every cached client and the local clusters this process started."""
    with _clients_lock:
        for client in _clients.values():
            try:
                client.close()
            except Exception:  # closing at exit: nothing useful to do about it
                pass
        for cluster in _clusters.values():
            try:
                cluster.close()
            except Exception:
                pass
        _clients.clear()
        _clusters.clear()


atexit.register(close_clients)


def _connect(address: str, timeout: float) -> Any:
    from distributed import Client, LocalCluster

    if address.startswith("local:"):
        cluster = _clusters.get(address)
        if cluster is None:
            # Processes: numba kernels release the GIL, but separate processes are what a real cluster is.
            # No dashboard (its HTTP port would collide with other clusters); the scheduler listens on localhost.
            try:
                cluster = LocalCluster(
                    n_workers=int(address.split(":")[1]),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address="127.0.0.1:0",
                    scheduler_kwargs={"dashboard": False},
                )
            except Exception as exc:  # e.g. a script without `if __name__ == "__main__":` re-running itself
                raise SchedulerError(f"could not start a local Dask cluster ({address}): {exc}") from None
            _clusters[address] = cluster
        return Client(cluster, set_as_default=False)
    host, port = address[len("tcp://") :].rsplit(":", 1)
    # A plain TCP probe first: a refused or unroutable address fails at once with the OS's reason,
    # instead of dask's retry loop and a half-built Client.
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise SchedulerError(
            f"cannot reach the Dask scheduler at {address}: {reason} (timeout {timeout:g} s)"
        ) from None
    # Then the Dask handshake, bounded by our own timeout: Client() itself can wait forever on a peer
    # that accepts connections but never answers, and fails with odd errors (even MemoryError) on
    # one that speaks another protocol. A thread of its own: the caller may be inside an event loop.
    with ThreadPoolExecutor(1) as pool:
        try:
            reply = pool.submit(asyncio.run, _identity(address, timeout)).result()
        except Exception as exc:
            reply = f"{type(exc).__name__}: {str(exc)[:200]}" if str(exc) else type(exc).__name__
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise SchedulerError(
            f"{address} accepts connections but does not answer as a Dask scheduler within {timeout:g} s ({reply})"
        )
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except Exception as exc:
        raise SchedulerError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None


async def _identity(address: str, timeout: float) -> Any:
    from distributed.comm import connect

    comm = await asyncio.wait_for(connect(address, timeout=timeout), timeout)
    try:
        await asyncio.wait_for(comm.write({"op": "identity", "reply": True}), timeout)
        return await asyncio.wait_for(comm.read(), timeout)
    finally:
        comm.abort()


def _prepare(client: Any, address: str, timeout: float, warm: Callable[[], None] | None) -> None:
    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:
        raise SchedulerError(
            f"the Dask scheduler at {address} has no workers after {timeout:g} s; start some with "
            f"`dask worker {address}` on machines where this package is installed"
        ) from None
    try:
        info = client.run(_worker_info)
    except Exception as exc:
        raise SchedulerError(
            f"the workers of {address} cannot run explorer_core ({type(exc).__name__}: {str(exc)[:200]}); "
            "install the same bilimovich-explorer on every worker"
        ) from None
    mine = fingerprint()
    for worker, (theirs, _) in info.items():
        if theirs != mine:
            diff = ", ".join(f"{k} {theirs.get(k)} (here {v})" for k, v in mine.items() if theirs.get(k) != v)
            raise SchedulerError(
                f"worker {worker} of {address} runs different code than this process ({diff}); results would "
                "not be identical: install the same version of bilimovich-explorer and its libraries there"
            )
    if warm is not None:
        # Compile or load the kernels on every worker now (in a task thread, not the worker's event loop),
        # so the first tasks do not pay for it; a worker that joins later compiles in its first task.
        client.gather([client.submit(warm, workers=[w], pure=False) for w in info])
    cpus = {cpu for _, cpu in info.values()}
    if cpus != {host_cpu()}:
        warnings.warn(
            f"the workers of {address} have CPUs {sorted(cpus)} and this machine {host_cpu()}: numba compiles for "
            "each CPU, so results may differ in the last bits (set NUMBA_CPU_NAME=generic everywhere to avoid it)",
            stacklevel=3,
        )


# ---------------------------------------------------------------------------
# The task stream.


def _threads(client: Any) -> int:
    return max(1, sum(client.nthreads().values()))


def _stream(
    client: Any, todo: deque, cancel: Callable[[], bool] | None, address: str
) -> Iterator[list[tuple[Any, Any]]]:
    """Run ``todo``'s ``(tag, func, args)`` as tasks, yielding batches of ``(tag, result)`` as they complete.

    About :data:`TASKS_PER_THREAD` tasks per worker thread are queued at a time, in
    ``todo`` order (earlier first, also by priority); the caller may append to
    ``todo`` while iterating. ``cancel`` is polled every :data:`POLL_S` seconds; once
    it is True, and whenever the caller stops iterating, outstanding tasks are
    cancelled on the cluster.
    """
    from distributed import as_completed

    tags: dict[Any, Any] = {}
    done = as_completed(loop=client.loop)
    submitted = 0
    window, window_at = 0, 0.0

    def top_up() -> None:
        nonlocal submitted, window, window_at
        now = time.monotonic()
        if now - window_at > 2.0:  # workers may come and go; nthreads() is a round trip to the scheduler
            window, window_at = TASKS_PER_THREAD * _threads(client), now
        while todo and len(tags) < window:
            tag, func, args = todo.popleft()
            fut = client.submit(func, *args, retries=RETRIES, priority=-submitted, pure=False)
            submitted += 1
            tags[fut] = tag
            done.add(fut)

    lost = _LostScheduler(address)
    try:
        with lost:
            top_up()
        while tags:
            if cancel is not None and cancel():
                return
            ready = done.next_batch(block=False)
            if not ready:
                if client.status in ("closing", "closed"):  # the client gave up reconnecting
                    raise SchedulerError(f"lost the Dask scheduler at {address}")
                time.sleep(POLL_S)
                continue
            if any(f.status == "error" for f in ready):
                client.gather(ready)  # raises the task's own error (after RETRIES re-runs)
            with lost:
                results = client.gather(ready)
            batch = [(tags.pop(f), r) for f, r in zip(ready, results, strict=True)]
            yield batch
            with lost:
                top_up()
    finally:
        if tags and client.status == "running":
            with suppress(Exception):  # a client that is going away has nothing left to cancel
                client.cancel(list(tags))


class _LostScheduler:
    """Turns any failure of a call to the scheduler (not of a task) into a :class:`SchedulerError`."""

    def __init__(self, address: str) -> None:
        self.address = address

    def __enter__(self) -> None:
        return None

    def __exit__(self, typ: Any, exc: BaseException | None, tb: Any) -> None:
        if isinstance(exc, Exception) and not isinstance(exc, SchedulerError):
            raise SchedulerError(f"lost the Dask scheduler at {self.address} ({type(exc).__name__}: {exc})") from None


class DaskExecutor:
    """Tasks on the Dask cluster of ``scheduler`` (see the module docstring); connects on first use.

    ``warm`` runs once on every worker before its first task (the kernels compiled or loaded there).
    """

    def __init__(self, scheduler: Any, *, timeout: float = DEFAULT_TIMEOUT, warm: Callable[[], None] | None = None):
        # An address is checked now (a clear error before any work); a distributed.Client is used as it is.
        self.scheduler = parse_scheduler(scheduler) if isinstance(scheduler, str) else scheduler
        self.timeout = timeout
        self.warm = warm
        self._client: Any = None

    @property
    def label(self) -> str:
        return self.scheduler if isinstance(self.scheduler, str) else str(self.scheduler.scheduler.address)

    def client(self) -> Any:
        if self._client is None or self._client.status != "running":
            self._client = get_client(self.scheduler, timeout=self.timeout, warm=self.warm)
        return self._client

    def threads(self) -> int:
        return _threads(self.client())

    def stream(self, todo: deque, cancel: Callable[[], bool] | None = None) -> Iterator[list[tuple[Any, Any]]]:
        yield from _stream(self.client(), todo, cancel, self.label)


def executor_for(scheduler: Any, warm: Callable[[], None] | None = None) -> DaskExecutor | None:
    """A :class:`DaskExecutor` for ``scheduler``, or ``None`` (run in this process) when it is ``None``."""
    return None if scheduler is None else DaskExecutor(scheduler, warm=warm)
