"""Pages built one at a time on the server's event loop, with the loop free between them (app/pacing.py)."""

from __future__ import annotations

import asyncio
import concurrent.futures
import time

import pytest

from app import pacing


@pytest.fixture(autouse=True)
def _fresh(monkeypatch) -> None:
    monkeypatch.setattr(pacing, "_frozen", True)  # no gc.freeze() in the test process
    monkeypatch.setattr(pacing, "_building_since", None)
    monkeypatch.setattr(pacing, "_waiting", pacing.collections.deque())
    monkeypatch.setattr(pacing, "MAX_WAIT", 0.1)


#: Turns of the event loop seen by a ticker task (test 1): a page build that starts with no tick since
#: the previous one ended was built in the same turn of the loop.
_ticks: list[int] = [0]


async def _build(log: list, name: str, seconds: float, *, finish: bool = True) -> None:
    await pacing.take_turn()
    log.append(("start", name, time.monotonic(), _ticks[0]))
    time.sleep(seconds)  # a page build is synchronous: it holds the loop
    log.append(("end", name, time.monotonic(), _ticks[0]))
    if finish:
        pacing.page_built()


def _run(coro):
    # In a thread of its own: a test process with Playwright's browser open already runs an event
    # loop in this thread, and asyncio.run refuses to nest.
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coro).result()


async def _class(log: list, *builds) -> None:
    """Run page builds together beside a task that counts the loop's turns (as /liveness would be answered)."""
    _ticks[0] = 0

    async def ticker() -> None:
        while True:
            _ticks[0] += 1
            await asyncio.sleep(0)

    t = asyncio.create_task(ticker())
    await asyncio.gather(*builds)
    t.cancel()


def _one_per_turn(log: list) -> bool:
    """Every page began after the one before it ended, with a turn of the loop between them.

    (A build is synchronous, so two never overlap in time: what the old line did wrong was build
    several in one turn of the loop, the ticker not running between them.)
    """
    starts = [e for e in log if e[0] == "start"]
    ends = [e for e in log if e[0] == "end"]
    return len(starts) == len(ends) and all(s[3] > e[3] for e, s in zip(ends, starts[1:], strict=False))


def test_a_class_waiting_longer_than_max_wait_still_builds_one_page_at_a_time() -> None:
    """12 pages of 30 ms: the last waits ~0.36 s, over MAX_WAIT (0.1 s), and still goes in its turn."""

    async def main() -> list:
        log: list = []
        await _class(log, *(_build(log, f"p{i}", 0.03) for i in range(12)))
        return log

    log = _run(main())
    assert len(log) == 24
    assert [e[1] for e in log if e[0] == "start"] == [f"p{i}" for i in range(12)]  # in arrival order
    assert _one_per_turn(log)  # the old line built the ones past MAX_WAIT together


def test_a_lost_build_lets_the_first_in_line_go_and_only_it() -> None:
    """A session that took its turn and never built (its tab closed): after MAX_WAIT the next goes, alone."""

    async def main() -> list:
        log: list = []
        lost = asyncio.create_task(_build(log, "lost", 0.0, finish=False))
        await asyncio.sleep(0)
        await _class(log, lost, *(_build(log, f"p{i}", 0.03) for i in range(4)))
        return log

    t0 = time.monotonic()
    log = _run(main())
    starts = [(e[1], e[2]) for e in log if e[0] == "start"]
    assert [n for n, _ in starts] == ["lost", "p0", "p1", "p2", "p3"]
    assert starts[1][1] - t0 >= 0.1  # p0 waited for the lost one: MAX_WAIT
    assert _one_per_turn([e for e in log if e[1] != "lost"])  # then one at a time, not all at once


def test_a_tab_closed_while_waiting_leaves_the_line() -> None:
    async def main() -> list:
        log: list = []
        first = asyncio.create_task(_build(log, "first", 0.0, finish=False))
        await asyncio.sleep(0)
        waiter = asyncio.create_task(_build(log, "gone", 0.0))
        await asyncio.sleep(0.01)
        assert len(pacing._waiting) == 1
        waiter.cancel()
        await asyncio.gather(first, waiter, return_exceptions=True)
        assert not pacing._waiting
        pacing.page_built()
        await asyncio.sleep(0.01)
        return log

    log = _run(main())
    assert [e[1] for e in log if e[0] == "start"] == ["first"]
    assert pacing._building_since is None  # nobody waits: the line is free


def _normalised(fig) -> str:
    """A figure as a page receives it, its models' ids numbered in order of appearance."""
    import json
    import re

    from bokeh.document import Document
    from bokeh.protocol import Protocol

    doc = Document()
    doc.add_root(fig.fig)
    text = json.dumps(json.loads(Protocol().create("PULL-DOC-REPLY", "x", doc).content_json), sort_keys=True)
    ids: dict[str, str] = {}
    return re.sub(r'"(p\d+)"', lambda m: f'"m{ids.setdefault(m[1], len(ids))}"', text)


def test_spare_figures_are_built_while_the_loop_is_idle_and_taken_with_the_pages_view() -> None:
    """app.views.SpareFigures: built one at a time only while the server is idle, up to their number; a page takes
    one with its own view, the same figure a page built then would have; none left: built then."""
    from app.views import SectionFigure, SpareFigures

    spares = SpareFigures(size=3, every=0.005)
    idle = [False]

    async def scenario() -> list[int]:
        seen = []
        spares.fill(asyncio.get_running_loop(), lambda: idle[0])
        await asyncio.sleep(0.1)
        seen.append(len(spares))  # busy: none built
        idle[0] = True
        for _ in range(200):
            await asyncio.sleep(0.01)
            if len(spares) == 3:
                break
        await asyncio.sleep(0.1)
        seen.append(len(spares))  # full: no more
        return seen

    assert _run(scenario()) == [0, 3]
    fig = spares.take((-2.0, 1.5), (-3.5, 0.5))
    assert len(spares) == 2
    assert (fig.x_range.start, fig.x_range.end, fig.y_range.start, fig.y_range.end) == (-2.0, 1.5, -3.5, 0.5)
    assert _normalised(fig) == _normalised(SectionFigure((-2.0, 1.5), (-3.5, 0.5)))
    spares.take((0, 1), (0, 1)), spares.take((0, 1), (0, 1))
    built = spares.take((-1.0, 1.0), (-2.0, 2.0))  # none left
    assert len(spares) == 0 and (built.x_range.start, built.y_range.end) == (-1.0, 2.0)
    idle[0] = False
    assert _run(scenario()) == [0, 3]  # a new loop (a new server) fills them again


def test_the_spares_are_filled_when_no_page_waits(monkeypatch) -> None:
    """The line of pages empty (pacing._release), the server builds the next pages' figures, not before."""
    import app.views as views

    spares = views.SpareFigures(size=2, every=0.005)
    monkeypatch.setattr(views, "SPARES", spares)

    async def scenario() -> list[int]:
        log: list = []
        await asyncio.gather(_build(log, "a", 0.02), _build(log, "b", 0.02))
        for _ in range(200):
            await asyncio.sleep(0.01)
            if len(spares) == 2:
                break
        return [len(spares)]

    assert _run(scenario()) == [2]
