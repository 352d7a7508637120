"""Run a session's computations off the UI thread; the newest request always wins.

Each *channel* (the section, the layers under it, ...) has a generation number.
Starting a job bumps it; a job polls ``cancelled()`` between chunks and stops
once a newer job exists, the session closed or its browser disconnected, and
everything it emits is dropped on the document thread if it has become stale by
then. So moving a slider cancels the work in flight and no stale result
overwrites a newer one.

Jobs of all sessions share the machine through :class:`FairScheduler`: only
``slots`` jobs compute at a time. The next one is, in this order: the first
points of a section (a user just moved a control), the rest of a section, a
layer (equilibrium tracks, T' map, reliability check), a heavy analysis (chart,
bifurcation, Lyapunov, ...); a layer or heavy job that has waited
``max_wait`` seconds moves up to the rest-of-section tier, so nothing starves.
While a section's first points are being computed (or wait for a slot) no layer or
heavy job starts, unless it has waited ``max_wait``: the first period takes a few
milliseconds alone, but tens with a layer beside it holding the GIL.
Sessions without a running job go before a session that has ``per_session``
running; first points and heavy jobs take turns across sessions (least recently
served first), the rest of the sections and the layers go in the order of the
moves. A running job's ``cancelled()`` poll is also where it yields
its slot when another job is due first, so one session's big chart cannot
queue many tiles ahead of everyone's sections: the numerical kernels
(which split each chunk over both cores, ``explorer_core.solve.integrators``) only see
the chunks of the jobs holding a slot.

Why layers come after every section: they are mostly Python/numpy and hold the
GIL, which the server's event loop needs to send everybody's points
(docs/load.md). A played parameter's frame is the exception: drawn whole, its
section starts with ``first=False`` and its layers run beside it.
At most one layer and one heavy job run at a time, and heavy
jobs run in threads of low CPU priority (``HEAVY_NICE``): a chart's tiles
already started cannot be stopped at a poll, so they must not take the cores
from the sections either.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Mapping
from concurrent.futures import Executor, ThreadPoolExecutor

from explorer_core import config

log = logging.getLogger(__name__)

Emit = Callable[[Callable[[], None]], None]
Job = Callable[[Callable[[], bool], Emit], None]

#: Kinds of job, by channel: the points a user waits for after each move, the layers drawn with
#: them; every other channel (chart, bifurcation, lyapunov, bench, ...) is heavy. These are the defaults of
#: the scheduler; a session's layers declare their own channels' kinds (:meth:`Runner.declare`).
POINTS, LAYER, HEAVY = "points", "layer", "heavy"
POINT_CHANNELS = frozenset({"section", "orbit"})  # an orbit found from a click: waited for like points
LAYER_CHANNELS = frozenset({"tracks", "tprime", "reliability", "orbits", "manifolds", "basins", "ftle", "rotation"})


def job_kind(channel: str) -> str:
    return POINTS if channel in POINT_CHANNELS else LAYER if channel in LAYER_CHANNELS else HEAVY


#: Threads for jobs. A job waiting for its turn parks a thread, so this is sized for every live job
#: of a full classroom (a few per session), not for the cores; idle threads cost no CPU.
_POOL = ThreadPoolExecutor(
    max_workers=int(os.environ.get("BILIMOVICH_APP_JOB_THREADS", "128")), thread_name_prefix="explorer-job"
)

#: Nice value of heavy jobs' threads (and of the threads they start, which inherit it on Linux); 0: off.
HEAVY_NICE = int(os.environ.get("BILIMOVICH_APP_HEAVY_NICE", "10"))
#: Nice value of every other job's thread: the server's event loop (pages, messages, /liveness) goes
#: before any computation, so a class opening the page at once gets its pages first (docs/load.md).
JOB_NICE = int(os.environ.get("BILIMOVICH_APP_JOB_NICE", "5"))


def _niced(run: Callable[[], None], nice: int = HEAVY_NICE) -> None:
    # Per thread on Linux; a raise needs no privilege. Pool threads keep it (every pool job has the same).
    with contextlib.suppress(AttributeError, OSError):
        if os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) < nice:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    run()


#: BILIMOVICH_TRACE=1 logs, per job, how long its first result waited for a slot, to be computed and to be
#: delivered on the document thread (load work; see also app/controller.py).
TRACE = bool(os.environ.get("BILIMOVICH_TRACE"))

#: Set once the numba kernels are compiled/loaded (see app/warm.py).
WARM = threading.Event()


class InlineExecutor(Executor):
    """Runs a job in the caller's thread (unit tests, scripts)."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        fn(*args, **kwargs)


# --- fair scheduling across sessions ---------------------------------------------------------------

_WAITING, _RUNNING, _DONE, _DROPPED = "waiting", "running", "done", "dropped"


class Ticket:
    """One job's place in the :class:`FairScheduler` (created by :meth:`FairScheduler.ticket`)."""

    __slots__ = ("channel", "event", "fresh", "kind", "seq", "session", "since", "stale", "state")

    def __init__(
        self, session: int, channel: str, seq: int, stale: Callable[[], bool], kind: str | None = None
    ) -> None:
        self.session = session
        self.channel = channel
        self.kind = kind or job_kind(channel)
        self.seq = seq
        self.since = 0.0
        self.stale = stale
        self.state = _DONE
        self.event = threading.Event()
        self.fresh = True  # nothing shown yet: the user is waiting for this job's first result

    def __repr__(self) -> str:
        return f"Ticket(session={self.session}, channel={self.channel!r}, state={self.state})"


class FairScheduler:
    """Which job computes next (see the module's docstring for the order).

    Parameters
    ----------
    slots : jobs computing at the same time (the rest wait, parked in their threads).
    per_session : running jobs per session while another session's job waits (a lone
        session may use every slot: the cap never leaves a slot idle).
    layer_slots, heavy_slots : running layer / heavy jobs at most.
    max_wait : seconds after which a waiting layer or heavy job is served like the rest of
        a section, so a chart still advances (a tile at a time) under a steady stream of moves.
    heavy_extra : heavy jobs that may run beside the ``slots`` (the server's: 1). A chart's tiles,
        once started, cannot be stopped at a poll; with one slot per process they would hold it and
        the first points of every session of that process would wait for them. They run at a low
        CPU priority, so the sections still get the cores.
    """

    def __init__(
        self,
        slots: int = 2,
        per_session: int = 1,
        layer_slots: int = 1,
        heavy_slots: int = 1,
        max_wait: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
        heavy_extra: int = 0,
    ) -> None:
        if min(slots, per_session, layer_slots, heavy_slots) < 1:
            raise ValueError("slots, per_session, layer_slots and heavy_slots must be >= 1")
        self.slots = slots
        self.heavy_extra = heavy_extra
        self.per_session = per_session
        self.max_wait = max_wait
        self._caps = {POINTS: slots, LAYER: layer_slots, HEAVY: heavy_slots}
        self._clock = clock
        self._lock = threading.Lock()
        self._waiting: list[Ticket] = []
        self._running: dict[str, int] = {POINTS: 0, LAYER: 0, HEAVY: 0}
        self._active: set[Ticket] = set()  # running tickets
        self._by_session: dict[int, int] = {}  # running jobs per session
        self._live: dict[int, int] = {}  # waiting + running tickets per session
        self._last: dict[int, float] = {}  # when each session was last given a slot
        self._seq = itertools.count()
        self.granted = 0  # slots given out (for tests)
        #: Whether new pages are being built in this process (set by app/pacing.py; never in tests).
        self.pages_due: Callable[[], bool] = lambda: False

    # --- used by Runner ---------------------------------------------------------------

    def ticket(self, session: int, channel: str, stale: Callable[[], bool], kind: str | None = None) -> Ticket:
        return Ticket(session, channel, next(self._seq), stale, kind)

    def acquire(self, t: Ticket) -> bool:
        """Wait for a slot; False if the job became stale meanwhile (it must not run)."""
        with self._lock:
            self._live[t.session] = self._live.get(t.session, 0) + 1
            self._enqueue(t)
            self._dispatch()
        t.event.wait()
        return t.state == _RUNNING

    def checkpoint(self, t: Ticket) -> bool:
        """Called at a job's poll: give the slot up if another job is due, wait for it back.

        Returns False if the job became stale while waiting. Several threads of one job
        (a bifurcation's two sweeps) may call this; all of them wait while the job waits.
        """
        with self._lock:
            if t.state == _RUNNING:
                if not self._waiting:
                    return True  # nobody else wants a slot: no bookkeeping
                self._free(t)
                self._enqueue(t)
                self._dispatch()
                if t.state == _RUNNING:
                    return True  # still the job due
        t.event.wait()
        return t.state == _RUNNING

    def shown(self, t: Ticket) -> None:
        """The job's first result is out: it stops going first, and holds nothing back any more."""
        with self._lock:
            t.fresh = False
            if self._waiting:
                self._dispatch()

    def release(self, t: Ticket) -> None:
        """The job ended (normally, cancelled or failed)."""
        with self._lock:
            if t.state == _RUNNING:
                self._free(t)
            elif t.state == _WAITING:
                self._waiting.remove(t)
            if t.state in (_RUNNING, _WAITING):  # a dropped ticket was forgotten when dropped
                self._forget(t.session)
            t.state = _DONE
            self._dispatch()

    def poke(self) -> None:
        """Wake waiting jobs that became stale (a cancel or a closed session) so they exit now."""
        with self._lock:
            self._dispatch()

    def stats(self) -> dict[str, int]:
        with self._lock:
            return {
                "running": sum(self._running.values()),
                "waiting": len(self._waiting),
                "sessions": len(self._live),
                "granted": self.granted,
            }

    # --- internals (lock held) -----------------------------------------------------------

    def _enqueue(self, t: Ticket) -> None:
        t.state = _WAITING
        t.since = self._clock()
        t.event.clear()
        self._waiting.append(t)

    def _free(self, t: Ticket) -> None:
        self._running[t.kind] -= 1
        self._active.discard(t)
        self._by_session[t.session] -= 1
        if not self._by_session[t.session]:
            del self._by_session[t.session]

    def _forget(self, session: int) -> None:
        self._live[session] -= 1
        if not self._live[session]:
            del self._live[session]
            self._last.pop(session, None)

    def _key(self, t: Ticket, now: float) -> tuple:
        if t.kind == POINTS:
            tier = 0 if t.fresh else 1
        else:
            tier = 1 if now - t.since >= self.max_wait else 2 if t.kind == LAYER else 3
        capped = self._by_session.get(t.session, 0) >= self.per_session
        # First points and heavy jobs round-robin across sessions (least recently served first);
        # the rest of the sections and the layers in the order of the moves, which finishes
        # scenes sooner than taking turns would.
        rr = self._last.get(t.session, 0.0) if tier == 0 or t.kind == HEAVY else 0.0
        return (tier, capped, rr, t.seq)

    def _used(self) -> int:
        """Slots in use; up to ``heavy_extra`` heavy jobs run beside the slots (at a low CPU priority)."""
        r = self._running
        return r[POINTS] + r[LAYER] + max(0, r[HEAVY] - self.heavy_extra)

    def _dispatch(self) -> None:
        stale = [t for t in self._waiting if t.stale()]
        for t in stale:
            # Woken to exit at once: a cancelled job must not hold a thread until its turn.
            self._waiting.remove(t)
            self._forget(t.session)
            t.state = _DROPPED
            t.event.set()
        now = self._clock()
        while self._used() < self.slots and self._waiting:
            # New pages being built count as first points due: the layers and analyses (Python, they
            # hold the GIL the event loop needs) wait for them too (app/pacing.py), and so do first points:
            # a class opening together had the first scenes of the pages built first computed and delivered
            # between the next pages (page p95 3.3-3.6 s; a page is ~60 ms, a first scene's points more).
            pages = self.pages_due()
            first_due = pages or any(t.kind == POINTS and t.fresh for t in (*self._waiting, *self._active))
            ready = [
                t for t in self._waiting
                if self._running[t.kind] < self._caps[t.kind]
                and ((t.kind == POINTS and not pages) or not first_due or now - t.since >= self.max_wait)
            ]  # fmt: skip
            if not ready:
                return
            t = min(ready, key=lambda t: self._key(t, now))
            self._waiting.remove(t)
            self._running[t.kind] += 1
            self._active.add(t)
            self._by_session[t.session] = self._by_session.get(t.session, 0) + 1
            # Strictly increasing, so sessions rotate even when the clock does not tick between grants.
            self._last[t.session] = max(now, max(self._last.values(), default=0.0) + 1e-9)
            self.granted += 1
            t.state = _RUNNING
            t.event.set()


#: The scheduler of every session's jobs; BILIMOVICH_APP_SLOTS=0 turns fair scheduling off (measurements).
_SLOTS = int(os.environ.get("BILIMOVICH_APP_SLOTS", str(config.N_WORKERS)))
_HEAVY_EXTRA = int(os.environ.get("BILIMOVICH_APP_HEAVY_EXTRA", "1"))
SCHEDULER: FairScheduler | None = FairScheduler(slots=_SLOTS, heavy_extra=_HEAVY_EXTRA) if _SLOTS > 0 else None
_session_ids = itertools.count(1)


class Runner:
    """Per-session job starter with newest-wins cancellation.

    Parameters
    ----------
    deliver : schedules a callable on the session's document thread
        (``doc.add_next_tick_callback`` in a server; call-through in tests).
    on_error : called on the document thread with a job's exception.
    executor : where jobs run; default the shared job pool, scheduled by :data:`SCHEDULER`.
        With an explicit executor (e.g. :class:`InlineExecutor`) jobs are not scheduled
        unless ``scheduler`` is given too.
    alive : polled with ``cancelled()``; False (the browser disconnected) stops the jobs
        long before the server discards the session.
    on_busy : called on the document thread with a channel's name whenever that channel may have
        started or stopped running (:meth:`busy` says which). What a page shows as "computing"
        is derived from it, so it cannot outlive the work: a job that ends, fails or is
        cancelled (a newer job, Stop, a closed tab) always ends its channel's busy state.
    """

    def __init__(
        self,
        deliver: Callable[[Callable[[], None]], None],
        on_error: Callable[[str, BaseException], None] | None = None,
        executor: Executor | None = None,
        *,
        scheduler: FairScheduler | None = None,
        alive: Callable[[], bool] | None = None,
        on_busy: Callable[[str], None] | None = None,
    ) -> None:
        self._deliver = deliver
        self._on_busy = on_busy
        self._live: dict[str, dict[int, int]] = defaultdict(dict)  # channel -> generation -> unfinished jobs
        self._on_error = on_error
        self._executor = executor or _POOL
        self._scheduler = scheduler if scheduler is not None or executor is not None else SCHEDULER
        self._alive = alive
        self._gen: dict[str, int] = defaultdict(int)
        self._lock = threading.Lock()
        self._id = next(_session_ids)
        self._kinds: dict[str, str] = {}
        self.closed = False

    def declare(self, kinds: Mapping[str, str]) -> None:
        """The kind of job (POINTS, LAYER, HEAVY) of channels (a layer's): how the scheduler ranks them."""
        self._kinds.update(kinds)

    def kind(self, channel: str) -> str:
        return self._kinds.get(channel) or job_kind(channel)

    def set_on_busy(self, on_busy: Callable[[str], None], *, replace: bool = False) -> None:
        """Who is told when a channel may have started or stopped (the controller, unless the page is)."""
        if replace or self._on_busy is None:
            self._on_busy = on_busy

    def ui(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on the document thread (figure updates from widget callbacks)."""
        self._deliver(fn)

    def generation(self, channel: str) -> int:
        return self._gen[channel]

    def busy(self, channel: str) -> bool:
        """Whether a job of the channel's current generation has not finished yet."""
        with self._lock:
            return not self.closed and self._live[channel].get(self._gen[channel], 0) > 0

    def _notify(self, channel: str) -> None:
        if self._on_busy is not None and not self.closed:
            self._deliver(lambda: self._on_busy(channel))

    def _one_less(self, channel: str, gen: int) -> bool:
        """One job of ``channel``'s generation ``gen`` fewer (lock held); whether none is left."""
        left = self._live[channel].get(gen, 0) - 1
        if left > 0:
            self._live[channel][gen] = left
        else:
            self._live[channel].pop(gen, None)
        return left <= 0

    def _ended(self, channel: str, gen: int) -> None:
        """A job is over (document thread): delivered after everything it emitted, so a channel is
        busy until its results are on the page, not only until its thread is done."""
        with self._lock:
            notify = self._one_less(channel, gen) and gen == self._gen[channel]
        if notify and self._on_busy is not None and not self.closed:
            self._on_busy(channel)

    def start(self, channel: str, job: Job, *, bump: bool = True, first: bool = True) -> int:
        """Run ``job(cancelled, emit)``; ``bump=False`` joins the current generation (no cancel). ``first=False``: the
        job's first result is not what a user waits for alone (a played parameter's frame, drawn once its layers are
        done too), so the layers need not wait for it (:class:`FairScheduler`)."""
        with self._lock:
            if bump:
                self._gen[channel] += 1
            gen = self._gen[channel]
            self._live[channel][gen] = self._live[channel].get(gen, 0) + 1
        self._notify(channel)
        alive = self._alive

        def stale() -> bool:
            return self.closed or self._gen[channel] != gen or (alive is not None and not alive())

        sched = self._scheduler
        kind = self.kind(channel)
        ticket = sched.ticket(self._id, channel, stale, kind) if sched is not None else None
        if ticket is not None and not first:
            ticket.fresh = False
        stamps = [time.perf_counter()] if TRACE else None  # started, given a slot, first result out

        def cancelled(wait: bool = True) -> bool:
            """Whether the job is stale; ``wait`` (a poll between chunks of work): also where it yields its slot
            to a job due first, and waits for its turn back. After its last chunk a job asks with ``wait=False``:
            its results are computed, and waiting for a turn would only hold them back."""
            if stale():
                return True
            return wait and ticket is not None and not sched.checkpoint(ticket)

        first = [True]

        def emit(fn: Callable[[], None]) -> None:
            if stale():
                return
            urgent = first[0] and kind == POINTS  # a user waits for exactly this
            first[0] = False
            if ticket is not None and ticket.fresh:
                sched.shown(ticket)  # its first points are out: the rest waits behind others' first points
            if stamps is not None and len(stamps) == 2:
                stamps.append(time.perf_counter())
                self._trace_later(channel, stamps)

            def guarded() -> None:
                if not stale():
                    fn()

            guarded.urgent = urgent  # type: ignore[attr-defined]  # delivered before the backlog (app/pacing.py)
            self._deliver(guarded)

        def run() -> None:
            try:
                WARM.wait()
                if ticket is None:
                    if not stale():
                        job(cancelled, emit)
                elif sched.acquire(ticket):
                    if stamps is not None:
                        stamps.append(time.perf_counter())
                    job(cancelled, emit)
            except Exception as exc:  # reported to the session, never a traceback in the page
                log.exception("job on channel %s failed", channel)
                if self._on_error is not None:
                    emit(lambda err=exc: self._on_error(channel, err))
            finally:
                if stamps is not None and len(stamps) >= 2:  # the job's span on the shared clock (a frame's timeline)
                    log.warning("trace job %d %s: ran %.4f to %.4f", self._id, channel, stamps[1], time.perf_counter())
                if ticket is not None:
                    sched.release(ticket)
                if not self.closed:  # a closed session's document is gone; nothing to tell it
                    self._deliver(lambda: self._ended(channel, gen))

        if bump and sched is not None:
            sched.poke()  # the job this one replaces may be waiting: let it go now
        try:
            if self._executor is _POOL and HEAVY_NICE and kind == HEAVY:
                # A heavy job's tiles run in threads of its own that no poll can stop once started:
                # they inherit a low CPU priority from this thread, so sections still get the cores.
                threading.Thread(target=_niced, args=(run,), name=f"explorer-{channel}", daemon=True).start()
            elif self._executor is _POOL and JOB_NICE:
                self._executor.submit(_niced, run, JOB_NICE)
            else:
                self._executor.submit(run)
        except RuntimeError:
            # The server is shutting down (its pool takes no new job): a section that ends now starts no layers.
            log.info("job on channel %s not started: the server is shutting down", channel)
            if ticket is not None:
                sched.release(ticket)
            with self._lock:
                self._one_less(channel, gen)
        return gen

    def _trace_later(self, channel: str, stamps: list[float]) -> None:
        # Where a job's first result waited: for a slot, for the computation, for the document thread.
        def on_document_thread() -> None:
            started, granted, emitted = stamps
            waited, computed, delivered = granted - started, emitted - granted, time.perf_counter() - emitted
            log.warning("trace job %d %s: slot after %.0f ms, first result %.0f ms later, on the document thread "
                        "%.0f ms later", self._id, channel, 1e3 * waited, 1e3 * computed, 1e3 * delivered)  # fmt: skip

        self._deliver(on_document_thread)

    def cancel(self, channel: str) -> None:
        with self._lock:
            was = self._live[channel].get(self._gen[channel], 0) > 0
            self._gen[channel] += 1
        if was:
            self._notify(channel)
        if self._scheduler is not None:
            self._scheduler.poke()

    def close(self) -> None:
        """Stop every job of this session (called when the session is destroyed)."""
        self.closed = True
        if self._scheduler is not None:
            self._scheduler.poke()
