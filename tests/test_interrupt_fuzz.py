"""Interrupts at random (issue 35, "the fuzz test extended to interrupts"): a random command with random small
sizes gets a random stop signal (SIGINT or SIGTERM) at a random time, from the interpreter's start to after
the run has ended, alone or through the warm worker. Seeded: a failure names its run's command line, signal
and time, and ``INTERRUPT_FUZZ_SEED`` / ``INTERRUPT_FUZZ_RUNS`` replay or widen it.

Whatever the moment, every file under its final name is whole (it reads back, ends with a newline, every row
as wide as its header) and says ``# partial`` exactly when the run was stopped with what it had computed, or
is absent; no temporary file is left; the exit status is 0, 128 + the signal, or :data:`cli.FAILED_STATUS`,
and stderr says the same (``interrupted`` for a stop, ``failed:`` for a total failure, nothing of either for
a run that ended). A signal before the command line has installed its handlers (the interpreter still
importing) is Python's own: the process dies of it (exit -signal, or SIGINT's ``KeyboardInterrupt``), nothing
written.
"""

from __future__ import annotations

import json
import os
import random
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from sigrun import check_csv, signalled, warm_worker

from explorer_core import cli

ROOT = Path(__file__).resolve().parents[1]
SEED = int(os.environ.get("INTERRUPT_FUZZ_SEED", "35001"))
RUNS = int(os.environ.get("INTERRUPT_FUZZ_RUNS", "40"))
#: Seconds after its start by which a signal is sent: lone runs take 1-10 s on a loaded machine (start included),
#: so some are signalled while importing, most while computing or writing, some after they ended.
LATEST_S = 4.0


def _log_uniform(rng: random.Random, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def random_run(rng: random.Random) -> list[str]:
    """One valid command line with small random sizes (``{d}``: the run's folder)."""
    kind = rng.choice(["section", "manifolds", "chart", "orbits", "basins", "bifurcation", "lyapunov", "density"])
    if kind == "section":
        n = rng.randint(1, 300)
        periods = max(2, min(int(_log_uniform(rng, 5, 20_000)), 1_000_000 // n))
        return ["section", "--scene", rng.choice(["fig1A", "fig1C", "fig8B"]), "--random", str(n), "--periods",
                str(periods), "--out", "{d}/s.csv"]  # fmt: skip
    if kind == "manifolds":
        return ["manifolds", "--scene", "fig8B", "--orbit=-0.04,-2.4", "--length", f"{_log_uniform(rng, 0.5, 1e5):.3g}",
                "--max-points", "1000000", "--out", "{d}/m.csv"]  # fmt: skip
    if kind == "chart":
        g, periods = rng.randint(2, 24), rng.randint(20, 1500)
        return ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range=-0.6,-0.5", "--y-param", "I11",
                "--y-range", "1,2", "--grid", f"{g},{g}", "--ic=-0.09,-2", "--periods", str(periods), "--p-max", "4",
                "--transient", str(rng.randint(4, 1500)), "--out", "{d}/c.csv", "--out", "{d}/c.npz"]  # fmt: skip
    if kind == "orbits":
        s = rng.randint(2, 8)
        return ["orbits", "--scene", "fig8B", "--max-period", str(rng.randint(1, 4)), "--seeds", f"{s},{s}",
                "--out", "{d}/o.csv"]  # fmt: skip
    if kind == "basins":
        g = rng.randint(3, 24)
        return ["basins", "--scene", "fig11", "--box", "-1,1,-1,1", "--grid", f"{g},{g}", "--max-periods",
                str(rng.randint(20, 1000)), "--cells", "8,8", "--out", "{d}/b.npz"]  # fmt: skip
    if kind == "bifurcation":
        return ["bifurcation", "--scene", "fig10", "--param", "alpha", "--range=-0.40,-0.39", "--n-values",
                str(rng.randint(2, 80)), "--points", str(rng.randint(3, 300)), "--transient", str(rng.randint(2, 300)),
                "--ic=-0.5,-1", "--out", "{d}/b.csv"]  # fmt: skip
    if kind == "lyapunov":
        return ["lyapunov", "--scene", "fig8B", "--ic=-0.5,-1", "--periods", str(int(_log_uniform(rng, 5, 20_000))),
                "--transient", "2", "--history", "{d}/h.csv"]  # fmt: skip
    return ["density", "--scene", "fig8B", "--random", str(rng.randint(5, 500)), "--periods",
            str(int(_log_uniform(rng, 4, 20_000))), "--pixels", "8,6", "--box", "-1,1,-3,-1",
            "--out", "{d}/d.npz"]  # fmt: skip


def check_run(argv: list[str], sig: int, rc: int, err: str, d: Path) -> str:
    """The contract above for one run; returns how it ended (for the summary)."""
    name = argv[0]
    names = sorted(p.name for p in d.iterdir())
    assert not [n for n in names if n.startswith(".")], f"temporary files left: {names}"
    assert "Traceback" not in err or (rc in (-sig, 1) and err.rstrip().endswith("KeyboardInterrupt")), err
    expected = sorted(Path(a).name for a in argv if "{d}" in a)
    stopped = "computed so far were written" in err
    if rc == -sig or (rc == 1 and err.rstrip().endswith("KeyboardInterrupt")):
        # Python's own handling, before the command installed its handlers or after it restored them: killed at
        # the start (nothing written) or at the end (everything written, complete).
        assert names in ([], expected) and not stopped, (names, err)
        if not names:
            return "killed at start"
    if rc in (0, -sig, 1):
        assert "interrupted" not in err and "failed:" not in err and not stopped, err
        how = "ended" if rc == 0 else "killed at the end"
    elif rc == 128 + sig:
        assert f"bilimovich {name}: interrupted" in err, err
        how = "stopped" if stopped else "interrupted as it ended" if "as its work ended" in err else "before work"
        if how == "before work":
            assert names == [], (names, err)
    else:
        assert rc == cli.FAILED_STATUS and "failed: every member failed" in err and "interrupted" not in err, err
        how = "failed"
    if how != "before work":
        assert names == expected, (names, expected, err)
    for path in (d / n for n in names):
        if path.suffix == ".csv":
            partial = check_csv(path)
            # A stopped run's file says so; one that ended (or ended as the signal came) does not.
            assert partial is stopped, (path.name, path.read_text()[:400], err)
        elif path.suffix == ".npz":
            with np.load(path) as z:
                assert z.files, path
        elif path.suffix == ".json":
            json.loads(path.read_text())
    return how


@pytest.fixture(scope="module")
def worker_env():
    with warm_worker() as env:
        yield env


def _job_ended(env: dict[str, str], d: Path, timeout: float = 60.0) -> None:
    """Wait until the worker's log says the job of folder ``d`` ended (or that it never started)."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        lines = [ln for log in Path(env["BILIMOVICH_WORKER_DIR"]).glob("*/worker-*.log")
                 for ln in log.read_text().splitlines() if str(d) in ln]  # fmt: skip
        if any("ended" in ln for ln in lines) or (not lines and time.monotonic() - start > 3):
            return
        time.sleep(0.1)
    raise AssertionError(f"the worker's job in {d} did not end within {timeout} s")


@pytest.mark.slow
def test_a_random_signal_at_a_random_time_leaves_whole_files_or_none(tmp_path: Path, worker_env) -> None:
    lone = {**os.environ, "BILIMOVICH_WORKER": "0", "PYTHONPATH": str(ROOT)}
    seen: dict[str, int] = {}
    started = time.monotonic()
    for i in range(RUNS):
        rng = random.Random(SEED + i)
        argv = random_run(rng)
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        at = rng.uniform(0.0, LATEST_S)
        through_worker = rng.random() < 0.3
        d = tmp_path / f"run{i}"
        d.mkdir()
        line = [a.replace("{d}", str(d)) for a in argv]
        where = f"run {i} (seed {SEED + i}): {' '.join(line)} / {signal.Signals(sig).name} at {at:.2f} s" + (
            " through the worker" if through_worker else ""
        )
        env = worker_env if through_worker else lone
        rc, err, _ = signalled(line, sig, env, tmp_path, at=at)
        if through_worker:  # a client killed at its start leaves a job that ends on its own: wait for its files
            _job_ended(env, d)
        try:
            how = check_run(argv, sig, rc, err, d)
        except AssertionError as exc:
            raise AssertionError(f"{where}: exit {rc}\n{exc}") from None
        seen[how] = seen.get(how, 0) + 1
        if how.startswith("killed"):
            print(f"\n{where}: exit {rc}, {how}: {err[-300:]!r}")
    print(f"\n{RUNS} runs in {time.monotonic() - started:.0f} s: {seen}")
    assert len(seen) >= 3, seen  # the times drawn reach several moments of a run
