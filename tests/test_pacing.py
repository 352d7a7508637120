"""Pages built one at a time on the server's event loop, with the loop free between them (app/pacing.py)."""

from __future__ import annotations

import asyncio
import itertools
import time

import pytest

from app import pacing


@pytest.fixture(autouse=True)
def _fresh(monkeypatch) -> None:
    monkeypatch.setattr(pacing, "_frozen", True)  # no gc.freeze() in the test process
    monkeypatch.setattr(pacing, "_building_since", None)
    monkeypatch.setattr(pacing, "_waiting", pacing.collections.deque())
    monkeypatch.setattr(pacing, "MAX_WAIT", 0.1)


async def _build(log: list, name: str, seconds: float, *, finish: bool = True) -> None:
    await pacing.take_turn()
    log.append(("start", name, time.monotonic()))
    time.sleep(seconds)  # a page build is synchronous: it holds the loop
    log.append(("end", name, time.monotonic()))
    if finish:
        pacing.page_built()


def _overlaps(log: list) -> int:
    building, worst = 0, 0
    for kind, _, _ in log:
        building += 1 if kind == "start" else -1
        worst = max(worst, building)
    return worst


def test_a_class_waiting_longer_than_max_wait_still_builds_one_page_at_a_time() -> None:
    """12 pages of 30 ms: the last waits ~0.36 s, over MAX_WAIT (0.1 s), and still goes in its turn."""

    async def main() -> tuple[list, list[float]]:
        log: list = []
        ticks: list[float] = []

        async def ticker() -> None:  # stands for /liveness: how long the loop goes without a turn
            while True:
                ticks.append(time.monotonic())
                await asyncio.sleep(0)

        t = asyncio.create_task(ticker())
        await asyncio.gather(*(_build(log, f"p{i}", 0.03) for i in range(12)))
        t.cancel()
        return log, ticks

    log, ticks = asyncio.run(main())
    assert _overlaps(log) == 1 and len(log) == 24
    assert [n for k, n, _ in log if k == "start"] == [f"p{i}" for i in range(12)]  # in arrival order
    gaps = [b - a for a, b in itertools.pairwise(ticks)]
    assert max(gaps) < 0.06  # the loop turned between every two pages (one page is 0.03 s)


def test_a_lost_build_lets_the_first_in_line_go_and_only_it() -> None:
    """A session that took its turn and never built (its tab closed): after MAX_WAIT the next goes, alone."""

    async def main() -> list:
        log: list = []
        lost = asyncio.create_task(_build(log, "lost", 0.0, finish=False))
        await asyncio.sleep(0)
        await asyncio.gather(lost, *(_build(log, f"p{i}", 0.03) for i in range(4)))
        return log

    t0 = time.monotonic()
    log = asyncio.run(main())
    starts = [(n, t) for k, n, t in log if k == "start"]
    assert [n for n, _ in starts] == ["lost", "p0", "p1", "p2", "p3"]
    assert starts[1][1] - t0 >= 0.1  # p0 waited for the lost one: MAX_WAIT
    assert _overlaps([e for e in log if e[1] != "lost"]) == 1  # then one at a time, not all at once


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

    log = asyncio.run(main())
    assert [n for k, n, _ in log if k == "start"] == ["first"]
    assert pacing._building_since is None  # nobody waits: the line is free
