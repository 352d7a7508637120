"""The work-precision harness: rows, references and their cache, the horizon, the CLI and the app tab.

Wall times are reported by the harness, never asserted (the machines are noisy).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os

import numpy as np
import pytest
from clirun import run_cli
from scipy.integrate import solve_ivp

from app.bench_tab import MEASURED, BenchTab
from app.controller import ExplorerSession
from app.runner import WARM, InlineExecutor, Runner
from app.state import ExplorerState
from explorer_core.solve.integrators import Batch, advance
from explorer_core.studies import bench
from explorer_core.system.model import Model
from explorer_core.system.params import Params


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> str:
    return str(tmp_path_factory.mktemp("bench_cache"))


@pytest.fixture(scope="module")
def quick(cache: str) -> bench.BenchResult:
    return bench.run_bench(bench.quick_config(), cache_dir_=cache)


def test_quick_run_has_finite_errors_for_every_method_and_case(quick: bench.BenchResult) -> None:
    cfg = quick.config
    have_nbs = quick.peers["numbalsoda"].startswith("available")
    expected = {f"ours {m}{' batch' if mode == 'batch' else ''}" for m in bench.OUR_METHODS for mode in cfg.modes}
    expected |= {f"scipy.solve_ivp {p.split(':')[1]}" for p in cfg.peers if p.startswith("scipy")}
    if have_nbs:
        expected |= {f"numbalsoda {p.split(':')[1]}" for p in cfg.peers if p.startswith("numbalsoda")}
    if quick.peers["heyoka"].startswith("available"):
        expected |= {{"heyoka:taylor": "heyoka taylor", "heyoka:batch": "heyoka taylor batch"}[p] for p in cfg.peers
                     if p.startswith("heyoka")}  # fmt: skip
    assert quick.completed
    for case in cfg.cases:
        lines = quick.series(case)
        assert set(lines) == expected, case
        for name, rows in lines.items():
            for r in rows:
                assert r.status == "ok", (case, name, r.setting, r.status)
                assert r.error is not None and math.isfinite(r.error) and r.error > 0, (case, name, r.setting)
                assert r.time_per_traj_s > 0 and r.periods == quick.cases[case].horizon
    # The files' contents agree with the rows.
    data = quick.as_dict()
    assert len(data["rows"]) == len(quick.rows) and json.loads(json.dumps(data)) == data
    assert quick.csv_text().count("\n") == len(quick.rows) + 1
    assert "| regular |" in quick.markdown()


def test_dop853_error_falls_with_the_tolerance_on_the_regular_orbit(quick: bench.BenchResult) -> None:
    for line in ("ours dop853", "ours dop853 batch"):
        rows = quick.series("regular")[line]
        tols = [r.tol for r in rows]
        assert tols == sorted(tols, reverse=True)
        errors = [r.error for r in rows]
        assert all(a > b for a, b in itertools.pairwise(errors)), errors
        # Work grows as the tolerance tightens.
        steps = [r.steps_per_period for r in rows]
        assert steps == sorted(steps)


def test_horizon_is_cut_on_chaotic_orbits_only(quick: bench.BenchResult) -> None:
    cases = quick.cases
    for name in ("regular", "drift"):
        assert cases[name].horizon == cases[name].k_max
    for name in ("chaotic", "attractor"):
        assert 2 <= cases[name].horizon < cases[name].k_max
        assert cases[name].amp_at_horizon <= quick.config.amp_max < cases[name].amp_at_k_max
    for c in cases.values():
        assert 0 < c.reference_bound < 1e-9  # far below every error measured


def test_horizon_rule() -> None:
    amp = np.array([[1.0, 5.0, 50.0, 2e3, 10.0], [1.0, 2.0, 3.0, 4.0, 5.0]])
    assert bench.horizon(amp, 1e3, 5) == 3  # the first member crosses at k = 4; no coming back below
    assert bench.horizon(amp[1:], 1e3, 5) == 5
    assert bench.horizon(amp[1:], 1e3, 2) == 2
    assert bench.horizon(np.array([[np.nan, 1.0]]), 1e3, 2) == 1  # a failed member counts as above


def test_time_at_error_interpolates_along_a_line() -> None:
    line = [(1e-2, 1.0), (1e-4, 10.0), (1e-8, 100.0)]
    t, how = bench.time_at_error(line, 1e-6)
    assert how == "interpolated" and t == pytest.approx(math.sqrt(10.0 * 100.0))
    assert bench.time_at_error(line, 1e-1) == (1.0, "at most")
    assert bench.time_at_error(line, 1e-9) == (None, "not reached")
    assert bench.time_at_error([(None, 1.0), (1e-7, 2.0)], 1e-6) == (2.0, "at most")


def test_reference_cache_is_hit_the_second_time(tmp_path) -> None:
    case = bench.builtin_cases()["regular"]
    first = bench.reference(case.params, case.ic, 3, cache_dir_=tmp_path)
    assert not first.cache_hit and len(os.listdir(tmp_path)) == 1
    second = bench.reference(case.params, case.ic, 3, cache_dir_=tmp_path)
    assert second.cache_hit
    np.testing.assert_array_equal(first.points, second.points)
    assert second.bound == first.bound and second.periods == 3
    other = bench.reference(case.params, case.ic, 4, cache_dir_=tmp_path)  # other horizon, other file
    assert not other.cache_hit and len(os.listdir(tmp_path)) == 2


def test_cache_dir_follows_the_environment(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("BILIMOVICH_CACHE_DIR", str(tmp_path))
    assert bench.cache_dir() == os.path.join(str(tmp_path), "bench")
    assert bench.cache_dir(tmp_path / "x") == str(tmp_path / "x")


def test_reference_agrees_with_independent_solvers_within_its_bound(cache: str) -> None:
    case = bench.builtin_cases()["regular"]
    model = Model(case.params)
    f = bench.scipy_rhs(model)
    period = case.params.period
    # Radau (implicit collocation: nothing shared with DOP853) over two periods, and scipy's DOP853
    # in one call with dense output (another step sequence) over the quick horizon; each one's own
    # error is estimated by the difference of two tolerances.
    for method, k in (("Radau", 2), ("DOP853", 20)):
        ref = bench.reference(case.params, case.ic, k, cache_dir_=cache)
        t_eval = period * np.arange(1, k + 1)
        runs = {tol: solve_ivp(f, (0.0, k * period), case.ic, method=method, rtol=tol, atol=tol, t_eval=t_eval).y.T
                for tol in (1e-12, 1e-13)}  # fmt: skip
        own = np.linalg.norm(runs[1e-12] - runs[1e-13], axis=1)
        diff = np.linalg.norm(runs[1e-13] - ref.points, axis=1)
        assert np.all(diff <= ref.bound_k() + own), (method, diff, ref.bound_k(), own)
    assert ref.bound < 1e-11


def test_ceiling_kernel_is_the_dop853_arithmetic() -> None:
    case = bench.builtin_cases()["attractor"]
    model = Model(case.params)
    ics = case.ics(37)  # more than one block, the last one partial
    end = bench.run_ceiling(model, ics, 2, 30)
    b = Batch.start(ics, case.params.t0, case.params.period)
    out, _ = advance(model, b, 2, method="dop853", adaptive=False, steps_per_period=30, workers=1, block=1)
    np.testing.assert_allclose(end, out[:, -1], rtol=0, atol=1e-12)


def test_numbalsoda_absence_is_reported_and_skipped(monkeypatch, tmp_path) -> None:
    monkeypatch.setattr(bench, "numbalsoda_status", lambda: (None, "not available (no Fortran compiler)"))
    cfg = dataclasses.replace(bench.quick_config(), cases=("regular",), k_max=3, rk4_steps=(50,), dp5_tols=(),
                              dop853_tols=(1e-6,), modes=("single",), peers=("numbalsoda:lsoda", "scipy:DOP853"),
                              peer_tols=(1e-6,), throughput=False)  # fmt: skip
    res = bench.run_bench(cfg, cache_dir_=tmp_path)
    assert res.peers["numbalsoda"] == "not available (no Fortran compiler)"
    assert {r.implementation for r in res.rows} == {"ours", "scipy.solve_ivp"}
    assert "numbalsoda: not available (no Fortran compiler)" in res.markdown()


def test_heyoka_is_a_peer_single_and_batch(tmp_path) -> None:
    pytest.importorskip("heyoka")
    cfg = dataclasses.replace(bench.quick_config(), cases=("regular", "attractor"), k_max=5, rk4_steps=(), dp5_tols=(),
                              dop853_tols=(1e-8,), modes=("single",), peers=("heyoka:taylor", "heyoka:batch"),
                              peer_tols=(1e-6, 1e-10), batch=10, throughput=False)  # fmt: skip
    res = bench.run_bench(cfg, cache_dir_=tmp_path)
    assert res.peers["heyoka"].startswith("available")
    for case in cfg.cases:
        lines = res.series(case)
        assert {"heyoka taylor", "heyoka taylor batch"} <= set(lines)
        # The batch runs the case's cloud (10: one full SIMD batch of 8 and a partial one), single the measured IC.
        assert [r.n_traj for r in lines["heyoka taylor batch"]] == [10, 10]
        for single, batch in zip(lines["heyoka taylor"], lines["heyoka taylor batch"], strict=True):
            assert single.status == batch.status == "ok"
            # Against the independent reference, and the same integrator whether alone or in a SIMD batch.
            assert single.error < 100 * single.tol and batch.error == pytest.approx(single.error, rel=1e-3, abs=1e-13)
    assert "heyoka taylor / ours dop853" in res.ratios
    assert "heyoka: available" in res.markdown()
    # Each peer's field is printed: the closed form for fig1C's diagonal tensor, the general one for fig8B's.
    assert "regular, heyoka: q' = " in res.markdown() and "  heyoka's field: q' = " in res.headline()
    assert "/" not in res.cases["regular"].peer_fields["heyoka"].split("r' = ")[1]


def test_heyoka_table_has_the_issue_columns_and_an_independent_reference() -> None:
    pytest.importorskip("heyoka")
    cfg = dataclasses.replace(bench.quick_config(), table_ics=9, table_periods=10, table_tols=(1e-6, 1e-12), repeat=1)
    table = bench.heyoka_table(cfg)
    assert table["available"] and table["workers"] >= 1
    rows = table["rows"]
    assert [(r["tol"], r["method"]) for r in rows] == [(t, m) for t in cfg.table_tols for m in cfg.table_methods]
    for r in rows:
        assert r["complete"] == cfg.table_ics and r["error_median"] <= r["error_max"]
        assert r["ratio_per_core"] == pytest.approx(r["time_s"] * table["workers"] / r["heyoka_time_s"])
        assert r["ratio_1_thread"] > 0
    tight = {r["method"]: r for r in rows if r["tol"] == 1e-12}
    loose = {r["method"]: r for r in rows if r["tol"] == 1e-6}
    for m in cfg.table_methods:
        assert tight[m]["error_max"] < 1e-9 and tight[m]["error_max"] < loose[m]["error_max"]
    assert tight["dop853"]["heyoka_error_max"] < 1e-9
    md = bench.heyoka_table_markdown(table)
    assert "| tol | ours | error (median / max) | time (s) |" in md and "ratio per core" in md
    # The table's reference (heyoka at 1e-16) against solve_ivp at 1e-13 on one IC, section by section.
    p = bench.TABLE_PARAMS
    model = Model(p)
    ic = bench.random_ics(1, (-1.0, 1.0, -1.0, 1.0), seed=0)
    ref, _, _, _ = bench._peer_heyoka(model, ic, 10, "batch", bench.TABLE_REF_TOL)
    rhs = bench.scipy_rhs(model)
    sol = solve_ivp(rhs, (p.t0, p.t0 + 10 * p.period), ic[0], method="DOP853", rtol=1e-13, atol=1e-13,
                    t_eval=p.t0 + p.period * np.arange(1, 11))  # fmt: skip
    assert np.max(np.abs(sol.y.T - ref[0])) < 1e-10


def test_heyoka_absence_is_reported_and_skipped(monkeypatch, tmp_path) -> None:
    import builtins

    real_import = builtins.__import__

    def no_heyoka(name, *args, **kw):
        if name == "heyoka" or name.startswith("heyoka."):
            raise ImportError("No module named 'heyoka'")
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_heyoka)
    mod, text = bench.heyoka_status()
    assert mod is None and text.startswith("not available (not installed")
    cfg = dataclasses.replace(bench.quick_config(), cases=("regular",), k_max=3, rk4_steps=(50,), dp5_tols=(),
                              dop853_tols=(1e-6,), modes=("single",), peers=("heyoka:taylor", "heyoka:batch",
                              "scipy:DOP853"), peer_tols=(1e-6,), throughput=False)  # fmt: skip
    res = bench.run_bench(cfg, cache_dir_=tmp_path)
    assert res.peers["heyoka"] == text
    assert {r.implementation for r in res.rows} == {"ours", "scipy.solve_ivp"}
    assert f"heyoka: {text}" in res.markdown()
    assert not any(k.startswith("heyoka") for k in res.ratios)
    assert f"heyoka table: {text}" in res.markdown()


def test_bad_settings_are_rejected() -> None:
    for bad in ({"cases": ("nope",)}, {"peers": ("julia:Tsit5",)}, {"dop853_tols": (0.0,)}, {"measured": 0}):
        with pytest.raises(ValueError):
            bench.run_bench(dataclasses.replace(bench.quick_config(), **bad))


def test_cli_bench_quick_writes_every_file(tmp_path, cache: str, quick: bench.BenchResult) -> None:
    out = tmp_path / "bench"
    rc, stdout, err = run_cli("bench", "--quick", "--out", str(out), "--cache-dir", cache, "--json")
    assert rc == 0, err
    names = {"bench.json", "bench.csv", "bench.md", "throughput.json", "work_precision.png"}
    assert names <= set(os.listdir(out))
    assert (out / "work_precision.png").read_bytes()[:4] == b"\x89PNG"
    summary = json.loads(stdout)
    assert summary["completed"] and set(summary["horizons"]) == set(bench.CASE_NAMES)
    data = bench.load_result(str(out / "bench.json"))
    # The fixture's run computed the references: this one reads them all from the cache.
    assert all(c["cache_misses"] == 0 and c["cache_hits"] >= 1 for c in data["cases"].values())
    assert "target" in data["throughput"] and "kernel" in data["throughput"]
    assert "[1/" in err and "horizon" in err  # progress lines on stderr
    assert os.path.exists(bench.latest_path(cache))


def test_cli_bench_indicators_prints_and_writes_the_comparison(tmp_path, cache: str) -> None:
    """Issue 34: ``bench --indicators`` compares the chaos indicators with a long Lyapunov run: a table printed and
    in bench.json / bench.md (structure; the agreement on the attractor, whose answer does not depend on the load)."""
    out = tmp_path / "bench"
    rc, stdout, err = run_cli("bench", "--quick", "--cases", "regular", "--no-peers", "--no-throughput",
                              "--indicators", "--out", str(out), "--cache-dir", cache)  # fmt: skip
    assert rc == 0, err
    assert "| chaotic | sali |" in stdout and "Lyapunov over 1000 periods" in stdout
    data = bench.load_result(str(out / "bench.json"))
    ind = data["indicators"]
    assert ind["n"] == 6 and ind["reference_periods"] == 1000 and set(ind["sets"]) == {"regular", "chaotic"}
    keys = {"agree_at_longest", "periods_median", "periods_max", "never", "all_agree_at", "seconds_at_that_rung",
            "speedup", "rungs", "disagree_at_longest"}  # fmt: skip
    for entry in ind["sets"].values():
        assert entry["reference_s"] > 0 and entry["reference_ok"] == 6
        assert set(entry["indicators"]) == set(bench.INDICATOR_LADDERS)
        for ind_name, d in entry["indicators"].items():
            assert set(d) == keys
            assert [r[0] for r in d["rungs"]] == list(bench.INDICATOR_LADDERS[ind_name])
            assert all(0 <= wrong + undecided <= 6 for _, wrong, undecided in d["rungs"])
    assert ind["sets"]["chaotic"]["reference_chaotic"] == 6
    sali = ind["sets"]["chaotic"]["indicators"]["sali"]
    assert sali["agree_at_longest"] == 6 and sali["periods_max"] <= 25  # decided in tens of periods, not 1000
    assert "## Chaos indicators" in (out / "bench.md").read_text()
    # Off by default in a quick run (the tests' and the app's): no indicators in its JSON.
    assert bench.quick_config().indicators is False and bench.full_config().indicators is True


def test_cli_bench_bad_input_is_one_line(tmp_path) -> None:
    rc, _, err = run_cli("bench", "--quick", "--out", str(tmp_path / "b"), "--cases", "regular,bogus")
    assert rc == 2 and err.count("\n") == 1 and "bogus" in err
    rc, _, err = run_cli("bench", "--quick", "--out", str(tmp_path / "missing" / "b"))
    assert rc == 2 and "does not exist" in err


# --- the app tab, without a browser ----------------------------------------------------------------


@pytest.fixture
def _warm() -> None:
    WARM.set()


def _session(scene: str = "fig1C") -> ExplorerSession:
    st = ExplorerState(scene=scene)
    st.param.update(n_random=2, periods=10)
    return ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor()))


def test_bench_tab_measures_the_current_system(_warm, tmp_path) -> None:
    sess = _session()
    tab = BenchTab(sess, results_path=str(tmp_path / "none.json"), cache_dir=str(tmp_path))
    assert tab.view["options"] == []  # no full run yet
    sess.state.bench_periods = 4
    tab.figure()
    tab.run()
    assert not tab.view["error"], tab.view["error"]
    assert tab.view["choice"] == MEASURED
    labels = set(tab.solid.data["label"]) | set(tab.dashed.data["label"])
    assert {"ours rk4", "ours dp5", "ours dop853", "ours dop853 batch", "scipy.solve_ivp DOP853"} <= labels
    ys = np.asarray(tab.points.data["y"])
    assert ys.size > 10 and np.all(np.isfinite(ys)) and np.all(ys > 0)
    assert "K = 4" in tab.view["result"][0] and tab.floor.visible
    assert "measurements" in tab.view["message"]


def test_bench_tab_shows_the_latest_full_run(_warm, tmp_path, quick: bench.BenchResult) -> None:
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(quick.as_dict()))
    tab = BenchTab(_session(), results_path=str(path), cache_dir=str(tmp_path))
    assert len(tab.view["options"]) == len(quick.cases)
    chaotic = next(o for o in tab.view["options"] if o.endswith("chaotic"))
    assert tab.choose(chaotic) is None
    assert "chaos horizon" in tab.view["result"][0]
    assert len(tab.solid.data["xs"]) == len([s for s in quick.series("chaotic") if not s.endswith("batch")])
    assert "no diagram" in tab.choose("nonsense") and tab.view["choice"] == chaotic


def test_bench_tab_rejects_bad_input(_warm, tmp_path) -> None:
    sess = _session()
    sess.state.param.update(n_random=0, clicked=[])
    tab = BenchTab(sess, results_path=str(tmp_path / "none.json"), cache_dir=str(tmp_path))
    tab.run()
    assert "no initial condition" in tab.view["error"]
    tab.load_results()
    assert "bilimovich bench" in tab.view["error"]


def _random_scenes(n: int) -> list[Params]:
    """Seeded random scenes: diagonal and full tensors (zero, tiny and ordinary off-diagonal entries), alpha zero or
    not, forcings with one or all three terms and omega != 1."""
    rng = np.random.default_rng(7)
    out = [bench.TABLE_PARAMS, Params(inertia=(1.6, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=-0.45)]
    while len(out) < n:
        diag = rng.uniform(1.0, 5.0, 3)
        off = rng.choice([0.0, 1e-300, 1e-9, 0.3], 3) * rng.choice([-1.0, 1.0], 3)
        g = rng.uniform(-1.0, 1.0, 3) * rng.integers(0, 2, 3)
        try:
            out.append(Params(inertia=(*diag, *off), alpha=float(rng.choice([0.0, rng.uniform(-1, 1)])), g0=g[0],
                              g1=g[1] or 1.0, g2=g[2], omega=float(rng.uniform(0.5, 3.0))))  # fmt: skip
        except bench.ParameterError:  # not positive definite
            continue
    return out


def test_every_peer_is_given_the_scenes_simplest_field_and_it_is_the_models_field(monkeypatch) -> None:
    """The one peer definition (solve_ivp's plain function, numbalsoda's cfunc, heyoka's expressions) against the
    model's general field from its tables, at a few units of rounding, on random scenes."""
    hy = None
    try:
        import heyoka as hy
    except ImportError:
        pass
    rng = np.random.default_rng(3)
    pts = rng.uniform(-3.0, 3.0, (50, 3)) * np.array([3.0, 1.0, 1.0]) + np.array([3.0, 0.0, 0.0])
    for p in _random_scenes(12):
        model = Model(p)
        diag = not any(p.inertia[3:])
        assert bench.is_diagonal(p) is diag  # 1e-300 off the diagonal is a full tensor
        f = bench.user_field(p)
        jit = bench.compiled_field(diag)
        k = np.array(bench.peer_constants(p))
        cf = None
        if hy is not None:
            sys_ = bench._heyoka_system(hy, p)
            cf = hy.cfunc([sys_[0][1], sys_[1][1]], [sys_[0][0], sys_[1][0]])
            if diag:  # the closed form: no denominator in r'
                assert "/" not in str(sys_[1][1])
        for t, q, r in pts:
            want = np.array(model.field(q, r, t), dtype=float)
            scale = (1.0 + abs(q) + abs(r)) ** 2  # the size of the field's terms (quadratic in q, r)
            got = {"python": f(t, q, r), "numba": jit(t, q, r, k)}
            if cf is not None:
                got["heyoka"] = cf(np.array([q, r]), time=t)
            for name, v in got.items():
                assert np.max(np.abs(np.asarray(v) - want)) <= 2e-15 * scale, (p, name, t, q, r, v, want)
    # solve_ivp's right-hand side is that plain function, not the model's tables.
    monkeypatch.setattr(Model, "coefficients", lambda *a: pytest.fail("the peer read the model's tables"))
    rhs = bench.scipy_rhs(Model(bench.TABLE_PARAMS))
    assert np.allclose(rhs(0.3, np.array([0.2, -0.4])), bench.user_field(bench.TABLE_PARAMS)(0.3, 0.2, -0.4), rtol=0)
    text = bench.peer_fields(bench.TABLE_PARAMS)
    assert "diagonal_field" in text["scipy"] and "(A - B)(g q + alpha) q / C" in text["scipy"]


def test_numbalsoda_peer_runs_the_plain_field() -> None:
    nbs = pytest.importorskip("numbalsoda")
    for p in (bench.TABLE_PARAMS, Params(inertia=(1.6, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=-0.45)):
        model = Model(p)
        ic = np.array([[0.3, -0.4]])
        pts, ok, _, _ = bench._peer_numbalsoda(nbs, model, ic, 5, "dop853", 1e-12)
        sol = solve_ivp(lambda t, y, model=model: model.field(y[0], y[1], t), (p.t0, p.t0 + 5 * p.period), ic[0],
                        method="DOP853", rtol=1e-13, atol=1e-13, t_eval=p.t0 + p.period * np.arange(1, 6))  # fmt: skip
        assert ok == [True] and np.max(np.abs(pts[0] - sol.y.T)) < 1e-9
