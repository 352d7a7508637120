"""Charts and bifurcation sweeps on a Dask cluster: identical to the local run, progressive, robust.

One ``LocalCluster`` of two single-threaded worker processes serves the whole
module (started once: process start-up dominates on a shared 2-core machine).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import threading
import time

import distributed
import numpy as np
import pytest
from clirun import run_cli

from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.regimes import chart_spec, iter_chart, plan_tiles, regime_chart
from explorer_core.parallel import cluster as dd
from explorer_core.scenes import get_scene
from explorer_core.status import Status
from explorer_core.system.params import ParameterError

# One xdist worker runs the whole module (./dev test uses --dist loadgroup): one cluster, not two.
pytestmark = pytest.mark.xdist_group("dask")

FIG11 = get_scene("fig11").params
IC = (-0.09, -2.0)
# Row I11 = 0 is not a positive-definite tensor: invalid pixels travel through the cluster too.
SPEC = chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (0.0, 2.0), (6, 5), ics=[IC, (-0.5, -1.0)], transient=60,
                  periods=40, p_max=8)  # fmt: skip
TILING = {"coarse": 2, "tile_pixels": 4}
ARRAYS = ("regime", "period", "lyap", "status", "computed")
DIAGRAM = ("sweeps", "points", "npts", "status", "final", "errors", "values")


@pytest.fixture(scope="module")
def cluster():
    """``tcp://`` address of a LocalCluster(n_workers=2, threads_per_worker=1, processes=True)."""
    lc = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                                  scheduler_kwargs={"dashboard": False})  # fmt: skip
    try:
        yield lc.scheduler_address
    finally:
        dd.close_clients()
        lc.close()


@pytest.fixture(scope="module")
def local_chart():
    return regime_chart(SPEC, workers=1, **TILING)


def assert_same_chart(a, b) -> None:
    for name in ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.errors == b.errors


def test_chart_equals_the_local_one_and_fills_in_tile_by_tile(cluster, local_chart) -> None:
    updates, computed = [], []

    def progress(u) -> None:
        updates.append(u)
        computed.append(int(u.chart.computed.sum()))

    chart = regime_chart(SPEC, executor=dd.DaskExecutor(cluster), progress=progress, **TILING)
    assert chart.completed and chart.computed.all()
    assert_same_chart(chart, local_chart)
    assert local_chart.errors and (0, 0) in chart.errors  # the invalid row came back with its reason
    # One progress call per tile, counting up, the coarse level first (as locally).
    tiles = plan_tiles(SPEC.shape, **TILING)
    assert [u.done_tiles for u in updates] == list(range(1, len(tiles) + 1))
    assert {u.total_tiles for u in updates} == {len(tiles)}
    assert updates[0].tile.tile.stride == 2
    sizes = [len(u.tile.tile.pixels()) for u in updates]
    assert np.cumsum(sizes).tolist() == computed  # the chart fills in as the tiles arrive
    assert sorted((t.j0, t.i0, t.stride) for t in tiles) == sorted(
        (u.tile.tile.j0, u.tile.tile.i0, u.tile.tile.stride) for u in updates
    )


def test_bifurcation_sweeps_equal_the_local_ones(cluster) -> None:
    """Continuation (chunks chained through their final states) and fixed seeding, with invalid holes."""
    alphas = np.linspace(-0.42, -0.36, 18)
    kw = {"points": 16, "transient": 40, "ics": [IC, (-0.5, -1.0)]}
    for param, values, seeding in (("alpha", alphas, "continuation"), ("alpha", alphas, "fixed"),
                                   ("I11", [0.0, 1.0, 0.05, 1.1, 1.2], "continuation")):  # fmt: skip
        # (Value by value, as the tasks run: fixed seeding in this process is otherwise in lock-step.)
        local = bifurcation_diagram(FIG11, param, values, seeding=seeding, workers=1, lockstep=False, **kw)
        two = bifurcation_diagram(FIG11, param, values, seeding=seeding, workers=2, lockstep=False, **kw)
        assert all(np.array_equal(getattr(local, name), getattr(two, name)) for name in DIAGRAM)
        calls = []
        remote = bifurcation_diagram(FIG11, param, values, seeding=seeding, executor=dd.DaskExecutor(cluster),
                                     progress=calls.append, **kw)  # fmt: skip
        for name in DIAGRAM:
            assert np.array_equal(getattr(local, name), getattr(remote, name)), (param, seeding, name)
        assert remote.completed
        valid = int(remote.valid.sum()) * remote.sweeps.size
        # (the last update, the one carrying the diagram, repeats the count: the contract of a long analysis)
        assert [c.done for c in calls[:-1]] == list(range(1, valid + 1)) and calls[-1].total == valid
        assert calls[-1].done == valid and calls[-1].result is remote


def test_a_worker_killed_mid_run_changes_nothing(cluster, local_chart) -> None:
    client = dd.get_client(cluster)
    pids = client.run(os.getpid)
    killed = []
    updates = []
    for upd in iter_chart(SPEC, executor=dd.DaskExecutor(cluster), **TILING):
        updates.append(upd)
        if not killed:  # the first tile is back, the others are queued or running on both workers
            busy = [w for w, keys in client.processing().items() if keys]
            victim = sorted(busy or pids)[0]
            os.kill(pids[victim], signal.SIGKILL)  # with its tile(s) in flight
            killed.append(victim)
    assert len(updates) == len(plan_tiles(SPEC.shape, **TILING))
    assert_same_chart(updates[-1].chart, local_chart)
    client.wait_for_workers(2, timeout=30)
    assert pids[killed[0]] not in client.run(os.getpid).values()  # the nanny started a new process


def test_cancel_drops_the_outstanding_tasks(cluster) -> None:
    client = dd.get_client(cluster)
    seen = []
    for upd in iter_chart(SPEC, executor=dd.DaskExecutor(cluster), cancel=lambda: bool(seen), **TILING):
        seen.append(upd)
    # Cancel is polled between batches of finished tiles: the first batch comes back, nothing after it.
    assert 1 <= len(seen) < len(plan_tiles(SPEC.shape, **TILING)) and not seen[-1].chart.completed
    deadline = time.monotonic() + 10
    while client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) == 0
    calls = []
    d = bifurcation_diagram(FIG11, "alpha", np.linspace(-0.42, -0.36, 18), points=8, transient=20, seeding="fixed",
                            executor=dd.DaskExecutor(cluster), progress=calls.append,
                            cancel=lambda: bool(calls))  # fmt: skip
    assert not d.completed and np.any(d.status == Status.NOT_RUN) and 0 < len(calls) < 18


def test_losing_the_scheduler_ends_the_run_with_a_clear_error() -> None:
    lc = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0",
                                  scheduler_kwargs={"dashboard": False})  # fmt: skip
    client = distributed.Client(lc, set_as_default=False, timeout=2)  # how long it tries to reconnect
    try:
        with pytest.raises(dd.SchedulerError, match="lost the Dask scheduler at"):
            for _ in iter_chart(SPEC, executor=dd.DaskExecutor(client), **TILING):
                lc.sync(lc.scheduler.close)
    finally:
        client.close()
        with contextlib.suppress(Exception):  # its scheduler is gone: do not wait 30 s for a clean shutdown
            lc.close(timeout=1)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_or_silent_scheduler_is_a_quick_clear_error() -> None:
    port = _free_port()  # nobody listens there: refused at once
    t = time.perf_counter()
    with pytest.raises(dd.SchedulerError, match=f"tcp://127.0.0.1:{port}.*refused"):
        regime_chart(SPEC, executor=dd.DaskExecutor(f"tcp://127.0.0.1:{port}"), **TILING)
    assert time.perf_counter() - t < 5
    # Something listens but never speaks the Dask protocol: a timeout, not a hang.
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        addr = f"tcp://127.0.0.1:{srv.getsockname()[1]}"
        t = time.perf_counter()
        with pytest.raises(dd.SchedulerError, match=f"{addr} accepts connections but does not answer"):
            dd.get_client(addr, timeout=1.0)
        assert time.perf_counter() - t < 15


@pytest.mark.parametrize(
    "address", ["127.0.0.1:8786", "tcp://127.0.0.1", "tcp://127.0.0.1:99999", "http://host:80", "local:0", "", None]
)
def test_bad_addresses_are_named(address) -> None:
    with pytest.raises(ParameterError, match="scheduler"):
        dd.parse_scheduler(address)


def test_addresses_and_the_environment_variable() -> None:
    assert dd.parse_scheduler(" tcp://node-1.lab:8786 ") == "tcp://node-1.lab:8786"
    assert dd.parse_scheduler("tcp://[::1]:8786") == "tcp://[::1]:8786"
    assert dd.parse_scheduler("local:3") == "local:3"
    assert dd.scheduler_from_env({}) is None and dd.scheduler_from_env({dd.ENV_VAR: " "}) is None
    assert dd.scheduler_from_env({dd.ENV_VAR: "tcp://h:1"}) == "tcp://h:1"
    with pytest.raises(ParameterError, match="BILIMOVICH_SCHEDULER: bad scheduler address 'h:1'"):
        dd.scheduler_from_env({dd.ENV_VAR: "h:1"})


CHART_ARGS = ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.42,-0.36", "--y-param", "I11",
              "--y-range", "1,1.2", "--grid", "3,2", "--ic", "-0.09,-2", "--transient", "50", "--periods", "40",
              "--p-max", "8", "--coarse", "2", "--quiet"]  # fmt: skip
BIF_ARGS = ["bifurcation", "--scene", "fig10", "--param", "alpha", "--range", "-0.42,-0.36", "--n-values", "6",
            "--points", "8", "--transient", "20", "--quiet"]  # fmt: skip


def test_cli_with_a_scheduler_writes_the_same_files(cluster, tmp_path) -> None:
    a, b = tmp_path / "local.npz", tmp_path / "dask.npz"
    assert run_cli(*CHART_ARGS, "--out", str(a))[0] == 0
    assert run_cli(*CHART_ARGS, "--out", str(b), "--scheduler", cluster)[0] == 0
    with np.load(a) as za, np.load(b) as zb:
        assert sorted(za.files) == sorted(zb.files)
        for name in za.files:
            assert np.array_equal(za[name], zb[name], equal_nan=za[name].dtype.kind == "f"), name
    c, d = tmp_path / "local.csv", tmp_path / "dask.csv"
    assert run_cli(*BIF_ARGS, "--out", str(c))[0] == 0
    assert run_cli(*BIF_ARGS, "--out", str(d), "--scheduler", cluster)[0] == 0
    assert c.read_bytes() == d.read_bytes()
    rc, _, err = run_cli(*CHART_ARGS, "--json", "--scheduler", f"tcp://127.0.0.1:{_free_port()}")
    assert rc == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:" in err and "Traceback" not in err
    rc, _, err = run_cli(*BIF_ARGS, "--json", "--scheduler", "localhost:8786")
    assert rc == 2 and "bad scheduler address 'localhost:8786'" in err


def test_workers_running_other_code_are_refused(cluster, monkeypatch) -> None:
    client = distributed.Client(cluster, set_as_default=False)
    try:
        edited = {**dd.fingerprint(), "explorer_core": "0" * 16}  # as if this process's numerics had changed
        monkeypatch.setattr(dd, "fingerprint", lambda: edited)
        with pytest.raises(dd.SchedulerError, match=r"runs different code than this process \(explorer_core "):
            dd.get_client(client)
    finally:
        client.close()


def test_app_tabs_use_the_configured_scheduler(cluster, monkeypatch) -> None:
    from app.analyses import BifurcationTab, ChartTab
    from app.controller import ExplorerSession
    from app.runner import WARM, InlineExecutor, Runner
    from app.state import ExplorerState

    WARM.set()

    def tab() -> ChartTab:
        st = ExplorerState(scene="fig11")
        st.param.update(chart_grid=(3, 2), chart_periods=30, chart_transient=30)
        return ChartTab(ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor())))

    local = tab()
    local.run()
    monkeypatch.setenv(dd.ENV_VAR, cluster)
    remote = tab()
    remote.run()
    assert not remote.view["error"] and remote.chart.completed
    assert_same_chart(remote.chart, local.chart)
    sweeps = []
    for env in ("", cluster):
        monkeypatch.setenv(dd.ENV_VAR, env)
        runner = Runner(lambda fn: fn(), executor=InlineExecutor())
        st = ExplorerState(scene="fig10")
        st.param.update(bif_values=4, bif_points=5, bif_transient=20)
        b = BifurcationTab(ExplorerSession(st, runner))
        b.run()
        sweeps.append(b._data)
    for name in DIAGRAM:
        assert np.array_equal(getattr(sweeps[0], name), getattr(sweeps[1], name)), name
    monkeypatch.setenv(dd.ENV_VAR, "my-cluster")
    bad = tab()
    bad.run()
    assert "BILIMOVICH_SCHEDULER" in bad.view["error"] and "my-cluster" in bad.view["error"]
    monkeypatch.setenv(dd.ENV_VAR, f"tcp://127.0.0.1:{_free_port()}")
    down = tab()
    down.run()
    assert "cannot reach the Dask scheduler" in down.view["error"]


def test_local_n_starts_a_cluster_once_and_reuses_it() -> None:
    """``local:N`` (the single-big-machine case) runs the same chart; threads share one cached client."""
    spec = chart_spec(FIG11, "alpha", (-0.42, -0.36), "I11", (1.0, 1.2), (2, 2), ics=[IC], transient=30, periods=20,
                      p_max=4)  # fmt: skip
    clients = []
    threads = [threading.Thread(target=lambda: clients.append(dd.get_client("local:1"))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert clients[0] is clients[1]
    assert_same_chart(regime_chart(spec, executor=dd.DaskExecutor("local:1")), regime_chart(spec, workers=1))
