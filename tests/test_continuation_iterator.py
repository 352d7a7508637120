"""Continuation is an iterator (issue 31, item 6; BifurcationKit's ``ContIterable``): ``iter_continue_orbit`` and its
siblings are plain generators over the engine's generator, with no thread, and closing one early leaves its live
result as a cancel leaves it (the contract of a long analysis, explorer_core/progress.py).

Both tests fail on c3075ef, whose ``iter_X`` ran the work on a thread (``progress.stream``) and whose updates before
the last carried no result.
"""

from __future__ import annotations

import itertools
import json
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from explorer_core import export
from explorer_core.analyses import continuation, regimes
from explorer_core.progress import Progress, Step, run, stoppable
from explorer_core.scenes import get_scene

FIG10 = get_scene("fig10").params
FIG8B = get_scene("fig8B").params
FIXED_POINT_035 = (-0.0959, -1.962)
SEEDS_8B = [(-1.457, -4.130), (-0.0377, -2.398), (-0.019, 0.077)]


def _chart() -> regimes.Chart:
    spec = regimes.chart_spec(FIG10, "alpha", (-0.38, -0.36), "I11", (1.0, 1.002), (3, 2),
                              ics=[FIXED_POINT_035], transient=200, periods=64)  # fmt: skip
    return regimes.regime_chart(spec, workers=1)


#: Each iter_X on a small case, as ``iterate(cancel)``.
ITERATORS: dict[str, Callable[[Callable[[], bool] | None], Iterator[Any]]] = {
    "continue_orbit": lambda cancel: continuation.iter_continue_orbit(
        FIG10, "alpha", (-0.35, -0.42), FIXED_POINT_035, 1, switch=True, max_period=16, workers=1, cancel=cancel
    ),
    "continue_from_seeds": lambda cancel: continuation.iter_continue_from_seeds(
        FIG8B, "alpha", (-0.45, -0.44), SEEDS_8B, periods=(1,), max_orbits=4, workers=1, cancel=cancel
    ),
    "chart_boundaries": lambda cancel: continuation.iter_chart_boundaries(
        _chart(), periods=(1,), workers=1, cancel=cancel
    ),
}


def _summary(result: Any) -> Any:
    """A result's summary without its wall-clock times."""

    def strip(obj: Any) -> Any:
        if isinstance(obj, dict):
            return {k: strip(v) for k, v in obj.items() if "elapsed" not in k}
        if isinstance(obj, list):
            return [strip(v) for v in obj]
        return obj

    return strip(json.loads(export.dumps(result.summary())))


def test_iterating_a_continuation_starts_no_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    started: list[str] = []
    start = threading.Thread.start

    def counted(self: threading.Thread) -> None:
        started.append(self.name)
        start(self)

    monkeypatch.setattr(threading.Thread, "start", counted)
    before = threading.active_count()
    ups, alive = [], []
    for upd in ITERATORS["continue_orbit"](None):
        ups.append(upd)
        alive.append(threading.active_count())
    assert started == [] and set(alive) == {before}, (started, set(alive), before)
    last = ups[-1]
    assert last.result.complete and len(ups) > 10  # the whole cascade, point by point
    assert [b.period for b in last.result.bifurcations if b.kind == "period_doubling"] == [1, 2, 4, 8, 16]


@pytest.mark.parametrize("name", list(ITERATORS))
def test_closing_the_iterator_early_leaves_the_result_cancelled(name: str) -> None:
    """Every update carries the live result; closed after its third update, the generator stops at its next poll
    and that result ends marked incomplete, with a ``cancelled`` loss: the same result as a cancel set by the
    progress callback at the third update."""
    it = ITERATORS[name](None)
    ups = list(itertools.islice(it, 3))
    live = ups[-1].result
    assert len(ups) == 3 and live is not None and all(u.result is live for u in ups)
    it.close()
    assert live.completed is False and live.complete is False
    assert any("cancel" in loss.why for loss in live.lost), live.lost
    seen: list[Any] = []
    cancelled = run(ITERATORS[name](lambda: len(seen) >= 3), seen.append)
    assert len(seen) == 4 and seen[-1].result is cancelled  # three updates, then the last one
    assert _summary(live) == _summary(cancelled)


def test_stoppable_polls_cancel_in_lock_step_and_a_close_runs_the_body_to_its_next_poll() -> None:
    """:func:`explorer_core.progress.stoppable`, the generator counterpart of ``progress.stream``."""
    polls: list[int] = []
    ended: list[str] = []

    def body(stop: Callable[[], bool]) -> Iterator[Step[str]]:
        k = 0
        for k in range(1000):
            if stop():
                break
            polls.append(k)
            yield Step(Progress(k + 1, 1000, "items"))
        ended.append("stopped" if stop() else "done")
        yield Step(Progress(k, 1000, "items"), None, ended[-1])

    seen: list[Any] = []
    assert run(stoppable(body, lambda: len(seen) >= 3), seen.append) == "stopped"
    assert polls == [0, 1, 2] and len(seen) == 4
    polls.clear()
    it = stoppable(body)
    next(it)
    it.close()  # the body saw stop() at its next poll and ended, its last update dropped
    assert polls == [0] and ended[-1] == "stopped"
