"""The contract of every long analysis (issue 20, item 4), checked analysis by analysis.

``iter_X(..., cancel=)`` yields updates with ``.progress`` (``done`` never decreasing, ending at ``total``)
and ``.result`` (the last one's is the result); ``X(..., progress=, cancel=)`` drives it with
:func:`explorer_core.progress.run` and returns the same result; a cancel after the first update returns
what was computed, marked incomplete with a :class:`~explorer_core.losses.Loss`, and never raises.
"""

from __future__ import annotations

import csv
import itertools
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from explorer_core import export
from explorer_core.analyses import (
    basins,
    bifurcation,
    continuation,
    density,
    drift,
    equilibria,
    lyapunov,
    manifolds,
    regimes,
)
from explorer_core.analyses.sweeps import sweep_values
from explorer_core.losses import Loss
from explorer_core.progress import ContractError, Progress, Step, run, stream
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import random_ics
from explorer_core.studies import reproduce

FIG10 = get_scene("fig10").params
FIG8B = get_scene("fig8B").params
FIG11 = get_scene("fig11").params.with_(I11=1.6, alpha=-0.5)
FIXED_POINT_035 = (-0.0959, -1.962)


def _chart_spec() -> regimes.ChartSpec:
    return regimes.chart_spec(get_scene("fig11").params, "alpha", (-0.6, -0.42), "I11", (1.0, 1.5), (4, 2),
                              ics=[(-0.1, -2.0)], transient=60, periods=64)  # fmt: skip


def _small_chart() -> regimes.Chart:
    spec = regimes.chart_spec(FIG10, "alpha", (-0.38, -0.36), "I11", (1.0, 1.002), (3, 2),
                              ics=[FIXED_POINT_035], transient=200, periods=64)  # fmt: skip
    return regimes.regime_chart(spec, workers=1)


@dataclass
class Case:
    """One long analysis: its ``iter_X`` and its ``X`` on the same small input."""

    name: str
    iterate: Callable[[Callable[[], bool] | None], Any]
    call: Callable[[Callable[[Any], None] | None, Callable[[], bool] | None], Any]


def _case(name: str, it: Callable[..., Any], fn: Callable[..., Any], *args: Any, **kw: Any) -> Case:
    return Case(name, lambda cancel: it(*args, cancel=cancel, **kw),
                lambda progress, cancel: fn(*args, progress=progress, cancel=cancel, **kw))  # fmt: skip


CASES = [
    _case("lyapunov", lyapunov.iter_lyapunov, lyapunov.lyapunov_spectrum, FIG8B, [(-1.0, -2.0), (-0.9, -2.1)], 64,
          transient=40),
    _case("bifurcation", bifurcation.iter_bifurcation_diagram, bifurcation.bifurcation_diagram, FIG10, "alpha",
          sweep_values((-0.4, -0.36), 6), points=8, transient=30, seeding="fixed", lockstep=False, workers=1),
    _case("bifurcation_sweeps", bifurcation.iter_bifurcation_diagram, bifurcation.bifurcation_diagram, FIG10, "alpha",
          sweep_values((-0.4, -0.36), 5), points=8, transient=30, workers=1),
    _case("continue_orbit", continuation.iter_continue_orbit, continuation.continue_orbit, FIG10, "alpha",
          (-0.35, -0.38), FIXED_POINT_035, 1, switch=True, max_period=2),
    _case("continue_from_seeds", continuation.iter_continue_from_seeds, continuation.continue_from_seeds, FIG10,
          "alpha", (-0.35, -0.36), [FIXED_POINT_035], periods=(1,), switch=False),
    # m = 6: two batches of draws (with m = 3 the first batch of 6 can hold all three: nothing left to cancel)
    _case("drift", drift.iter_drift_fit, drift.drift_fit, get_scene("fig3").params, (200, 300), degree=(0, 2), m=6,
          box=(-3, 3, 6, 10), seed=1),
    _case("equilibrium_tracks", equilibria.iter_equilibrium_tracks, equilibria.equilibrium_tracks, FIG10, 120),
    _case("reproduce", reproduce.iter_reproduce, reproduce.reproduce, "tiny", stages=("sections", "lyapunov")),
    Case("chart", lambda cancel: regimes.iter_chart(_chart_spec(), tile_pixels=2, workers=1, cancel=cancel),
         lambda progress, cancel: regimes.regime_chart(_chart_spec(), tile_pixels=2, workers=1, progress=progress,
                                                       cancel=cancel)),
    Case("basins", lambda cancel: basins.iter_basins(basins.basin_spec(FIG11, (-3, 3, -4, 2), (16, 12)), cancel=cancel,
                                                     update_s=0.0),
         lambda progress, cancel: basins.basins(FIG11, (-3, 3, -4, 2), (16, 12), progress=progress, cancel=cancel)),
    _case("density", density.iter_density, density.density, FIG8B, random_ics(4, (-2, 1, -4, 0), seed=1), 300,
          view=(-3, 2, -5, 1), pixels=(40, 30), max_chunk=32),
]  # fmt: skip


def _without_times(obj: Any) -> Any:
    """A summary without its wall-clock times (the only thing two runs may differ in)."""
    if isinstance(obj, dict):
        return {k: _without_times(v) for k, v in obj.items() if "elapsed" not in k and "timings" not in k}
    if isinstance(obj, list):
        return [_without_times(v) for v in obj]
    return obj


def _summary(result: Any) -> Any:
    return _without_times(json.loads(export.dumps(result.summary())))


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_updates_progress_and_the_last_one_is_the_result(case: Case) -> None:
    updates = list(case.iterate(None))
    assert updates, "an iter_X yields at least its last update"
    done = [u.progress.done for u in updates]
    assert all(isinstance(u.progress, Progress) for u in updates)
    assert all(b >= a for a, b in itertools.pairwise(done)), done
    last = updates[-1]
    assert last.progress.done == last.progress.total, last.progress
    assert last.result is not None and last.result.complete is not None
    seen: list[Any] = []
    result = case.call(seen.append, None)
    assert seen and seen[-1].result is result  # progress gets every update, the last one too
    assert _summary(result) == _summary(last.result)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_cancel_after_the_first_update_returns_what_was_computed(case: Case) -> None:
    seen: list[Any] = []
    result = run(case.iterate(lambda: len(seen) >= 1), seen.append)
    assert result is not None and seen[-1].result is result
    assert result.complete is False
    assert result.lost and all(isinstance(loss, Loss) for loss in result.lost)
    assert any("cancel" in loss.why or "stopped" in loss.why for loss in result.lost), result.lost


def test_chart_boundaries_keep_the_contract() -> None:
    chart = _small_chart()
    ups = list(continuation.iter_chart_boundaries(chart, periods=(1,)))
    done = [u.progress.done for u in ups]
    assert all(b >= a for a, b in itertools.pairwise(done)) and done[-1] == ups[-1].progress.total
    res = ups[-1].result
    assert isinstance(res, list) and len(res) >= 1 and all(isinstance(c, continuation.Continuation) for c in res)
    seen: list[Any] = []
    cancelled = continuation.chart_boundaries(chart, periods=(1,), progress=seen.append, cancel=lambda: len(seen) >= 2)
    assert cancelled.complete is False and any("cancel" in loss.why for loss in cancelled.lost)


def test_manifolds_keep_the_contract() -> None:
    orbit = manifolds.saddle_orbit(FIG8B, (-0.04, -2.40), 1)
    ups = list(manifolds.iter_manifolds(FIG8B, orbit, length=2.0, view=(-3, 3, -5, 1), kinds=["unstable"]))
    done = [u.progress.done for u in ups]
    assert all(b >= a for a, b in itertools.pairwise(done)) and done[-1] == ups[-1].progress.total
    assert run(iter(ups)) is ups[-1].result


# --- every result writes its own files ------------------------------------------------------------------

#: The suffixes each result writes (``write`` refuses any other).
WRITES = {"lyapunov": (".csv", ".json"), "bifurcation": (".csv", ".json"), "bifurcation_sweeps": (".csv", ".json"),
          "continue_orbit": (".csv", ".json"), "continue_from_seeds": (".csv", ".json"), "drift": (".csv", ".json"),
          "equilibrium_tracks": (".csv", ".json"), "chart": (".npz", ".csv", ".json"), "basins": (".npz", ".json"),
          "density": (".npz", ".json")}  # fmt: skip


@pytest.mark.parametrize("case", [c for c in CASES if c.name in WRITES], ids=lambda c: c.name)
def test_every_result_writes_files_that_read_back(case: Case, tmp_path: Any) -> None:
    result = run(case.iterate(None))
    for suffix in WRITES[case.name]:
        path = str(tmp_path / f"out{suffix}")
        info = result.write(path)
        assert info["path"] == path
        if suffix == ".csv":
            with open(path, newline="") as fh:
                rows = list(csv.reader(fh))
            assert len(rows) >= 2 and "np.float64" not in open(path).read()
            assert info.get("rows", len(rows) - 1) == len(rows) - 1
            table = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding=None)
            assert any(np.issubdtype(table.dtype[k], np.number) for k in range(len(table.dtype))), table.dtype
        elif suffix == ".npz":
            with np.load(path) as data:
                assert data.files and all(data[k].size >= 0 for k in data.files)
        else:
            with open(path) as fh:
                back = json.load(fh)
            assert back["complete"] == result.complete and "lost" in back
    with pytest.raises(export.OutputError, match="written as"):
        result.write(str(tmp_path / "out.png"))


def test_chart_boundaries_write_their_points(tmp_path: Any) -> None:
    res = continuation.chart_boundaries(_small_chart(), periods=(1,))
    info = res.write(str(tmp_path / "b.csv"))
    with open(info["path"], newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:2] == ["continuation", "branch"] and len(rows) - 1 == info["rows"] > 0
    assert json.loads(export.dumps(res.summary()))["continuations"]


# --- the driver and the thread adapter -------------------------------------------------------------------


def test_run_refuses_a_stream_without_a_result() -> None:
    with pytest.raises(ContractError):
        run(iter([]))
    with pytest.raises(ContractError):
        run(iter([Step(Progress(1, 2, "x"))]))


def test_stream_hands_updates_over_in_lock_step_and_stops_when_closed() -> None:
    polls: list[int] = []

    def work(emit: Callable[[Any], None], stop: Callable[[], bool]) -> Step[str]:
        k = 0
        for k in range(1000):
            if stop():
                break
            polls.append(k)
            emit(Step(Progress(k + 1, 1000, "items")))
        return Step(Progress(k, 1000, "items"), None, "stopped" if stop() else "done")

    # the consumer's cancel is seen by the analysis's next poll (as with a callback)
    seen: list[Any] = []
    assert run(stream(work, lambda: len(seen) >= 3), seen.append) == "stopped"
    assert polls == [0, 1, 2]
    # closing the iterator early stops the analysis too (and waits for it)
    polls.clear()
    it = stream(work)
    next(it)
    it.close()
    assert polls == [0]


def test_stream_raises_the_analysis_error_in_the_consumer() -> None:
    def work(emit: Callable[[Any], None], stop: Callable[[], bool]) -> Any:
        emit(Step(Progress(0, 1, "x")))
        raise ValueError("bad input 42")

    with pytest.raises(ValueError, match="bad input 42"):
        run(stream(work))


def test_a_drift_fit_cancelled_before_any_member_returns_an_empty_fit() -> None:
    """On the old code this raised ParameterError ('no trajectory is on the drift'): a cancel must not."""
    fit = drift.drift_fit(get_scene("fig3").params, (200, 300), degree=(0, 2), m=3, box=(-3, 3, 6, 10),
                          cancel=lambda: True)  # fmt: skip
    assert fit.members.shape == (0, 2) and not fit.completed and not fit.complete
    assert fit.lost == [Loss("members not found", 3, "cancelled")]
    assert json.loads(export.dumps(fit.summary()))["members"] == 0


def test_section_orbits_and_tprime_write_their_own_files(tmp_path: Any) -> None:
    """The results the CLI used to write inline (section, orbit search, T' map) write themselves too."""
    from explorer_core.analyses.orbits import find_orbits
    from explorer_core.analyses.tprime import tprime_map
    from explorer_core.solve.section import section

    sec = section(FIG8B, np.array([[-0.04, -2.4], [0.1, -2.0]]), 5)
    orbits = find_orbits(FIG8B, np.array([[-0.04, -2.4]]), [1])
    tmap = tprime_map(FIG8B, 0.0, (-1.0, 1.0), (-3.0, -1.0), 8)
    for result, suffixes in ((sec, (".csv", ".json")), (orbits, (".csv", ".json")), (tmap, (".npz",))):
        for suffix in suffixes:
            path = str(tmp_path / f"{type(result).__name__}{suffix}")
            assert result.write(path)["path"] == path
            if suffix == ".csv":
                table = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding=None)
                assert table.size >= 1 and "np.float64" not in open(path).read()
                assert np.issubdtype(table.dtype["q"], np.floating)
            elif suffix == ".npz":
                with np.load(path) as data:
                    assert np.allclose(data["values"], tmap.values, equal_nan=True)
            else:
                with open(path) as fh:
                    assert json.load(fh)
        with pytest.raises(export.OutputError, match="written as"):
            result.write(str(tmp_path / "out.png"))


def test_continuation_from_seeds_continues_every_orbit_found() -> None:
    """Three period-1 orbits of Fig. 8B (saddle, flip saddle, unstable focus): each continued. Fails on 2cce8ac,
    where the second orbit's position was looked up with list.index, whose == compared arrays: ValueError (the
    app's orbit diagram with 'follow the orbits' logged it)."""
    seeds = np.array([[-1.457, -4.130], [-0.0377, -2.398], [-0.019, 0.077]])
    res = continuation.continue_from_seeds(FIG8B, "alpha", (-0.45, -0.44), seeds, periods=(1,), max_orbits=4)
    starts = [b.states[0] for b in res.branches if b.parent is None]
    assert len(starts) == 3, starts
    assert res.complete
