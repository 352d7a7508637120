"""One status vocabulary (issue 20, item 3): one enum, its names pinned, in every result and every file written."""

from __future__ import annotations

import ast
import csv
import json
from pathlib import Path

import numpy as np
import pytest
from clirun import run_cli
from test_cli_fuzz import VALID

from explorer_core.analyses.basins import ESCAPE, basins
from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.continuation import continue_orbit
from explorer_core.analyses.regimes import ESCAPED, FAILED, INVALID, Chart, chart_spec, regime_chart
from explorer_core.scenes import get_scene
from explorer_core.solve import integrators, poincare, rk
from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import Numerics
from explorer_core.status import CODES, Status, count_names, describe, names, status_names
from explorer_core.system.model import Model

ROOT = Path(__file__).resolve().parents[1]
FIG8B = get_scene("fig8B").params
FIG10 = get_scene("fig10").params
FIG11 = get_scene("fig11").params

#: The name <-> code table. Files written with these codes are read with it: change it deliberately only.
PINNED = {0: "ok", 1: "escaped", 2: "step_collapsed", 3: "too_many_steps", 4: "nonfinite", 5: "not_converged",
          6: "budget", 7: "cancelled", 8: "undecided", 9: "invalid", 10: "not_run"}  # fmt: skip


def test_the_name_code_table_is_pinned() -> None:
    assert CODES == PINNED
    assert status_names().tolist() == [PINNED[c] for c in range(len(PINNED))]
    for s in Status:
        assert Status.of(s.label) is s and Status.of(int(s)) is s and Status.of(np.int8(s)) is s
        assert Status.of(s.word) is s and Status.of(s.name) is s
        assert s.word and s.meaning and s.label == s.label.lower()
    assert [s for s in Status if s.engine] == [Status.OK, Status.ESCAPED, Status.STEP_COLLAPSED,
                                               Status.TOO_MANY_STEPS, Status.NONFINITE]  # fmt: skip


def test_helpers_decode_arrays_and_name_bad_values() -> None:
    codes = np.array([[0, 1], [9, 10]], dtype=np.int8)
    assert names(codes) == [["ok", "escaped"], ["invalid", "not_run"]]
    assert names(np.int64(3)) == "too_many_steps"
    assert count_names(np.array([1, 0, 1])) == {"ok": 1, "escaped": 2} and count_names([]) == {}
    assert describe(np.array([2, 0, 0, 9])) == "2 ok, 1 step collapsed, 1 invalid parameters"
    for bad, needle in ((11, "code 11"), ("exploded", "'exploded'"), (True, "True"), (1.5, "1.5")):
        with pytest.raises(ValueError, match=needle):
            Status.of(bad)
    with pytest.raises(ValueError, match="not a status code: -1"):
        names(np.array([0, -1]))


def test_the_engine_status_is_the_one_enum() -> None:
    from explorer_core.analyses import sweeps

    assert rk.Status is Status and integrators.Status is Status and poincare.Status is Status
    for old in ("INVALID_PARAMS", "NOT_RUN", "status_label"):
        assert not hasattr(sweeps, old)


# --- no second table --------------------------------------------------------------------------------------

#: Integer code tables that are NOT statuses, each with why it stays (a new one fails the test below: use
#: :class:`explorer_core.status.Status`, or add it here with a reason if it is no outcome).
NOT_STATUSES = {
    ("analyses/regimes.py", "NOT_COMPUTED"): "the chart's regime classification (pinned charts); why a pixel has "
    "no regime is its Chart.status",
    ("analyses/regimes.py", "REGIMES"): "the names of those regime codes",
    ("analyses/basins.py", "ESCAPE"): "basin labels (attractor ids >= 0); why a pixel has none is Basins.status",
    ("analyses/basins.py", "_SEARCH"): "phases of a member in the recurrence bookkeeping",
    ("solve/rk.py", "FIELD"): "the systems the engine integrates",
    ("system/model.py", "ROW_Q"): "rows of the coefficient tables",
    ("analyses/equilibria_kernels.py", "SADDLE"): "the types of an equilibrium (indices into equilibria.TYPES)",
    ("system/model.py", "GENERAL"): "the forms of the field (which monomials its tables hold: model.FORM_MASKS)",
    ("solve/rk.py", "_TB_NUM"): "offsets of a lock-step block's copied tables (rows of its scratch array)",
}


def _is_int(node: ast.AST) -> bool:
    try:
        return type(ast.literal_eval(node)) is int
    except ValueError:
        return False


def _code_tables() -> set[tuple[str, str]]:
    """Enums, several names bound to integers at once, and tuples of names indexed by code, in explorer_core."""
    labels = set(CODES.values())
    found = set()
    for path in sorted((ROOT / "explorer_core").rglob("*.py")):
        rel = path.relative_to(ROOT / "explorer_core").as_posix()
        if rel == "status.py":
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                for b in node.bases:
                    if any(w in ast.unparse(b) for w in ("Enum", "Flag")):
                        found.add((rel, node.name))
            if not isinstance(node, ast.Assign):
                continue
            first = node.targets[0]
            names_ = [e.id for e in first.elts if isinstance(e, ast.Name)] if isinstance(first, ast.Tuple) else (
                [first.id] if isinstance(first, ast.Name) else [])  # fmt: skip
            if not names_:
                continue
            v = node.value
            ints = isinstance(v, ast.Tuple) and all(_is_int(e) for e in v.elts)
            by_range = isinstance(v, ast.Call) and ast.unparse(v.func) == "range"
            if len(names_) >= 3 and (ints or by_range):
                found.add((rel, names_[0]))
            if len(names_) == 1 and ints is False and isinstance(v, ast.Tuple | ast.List):
                words = {e.value for e in v.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)}
                if len(words & labels) >= 2:
                    found.add((rel, names_[0]))
            if len(names_) == 1 and isinstance(v, ast.Dict):
                keys = [k for k in v.keys if k is not None]
                if keys and all(isinstance(k, ast.Constant) and isinstance(k.value, int) for k in keys):
                    found.add((rel, names_[0]))
            statusy = {s.name for s in Status} | {"INVALID_PARAMS", "FAILED"}
            if len(names_) == 1 and names_[0].lstrip("_") in statusy and _is_int(v):  # a code by hand
                found.add((rel, names_[0]))
    return found


def test_no_second_status_table() -> None:
    """A new IntEnum or code table of outcomes in explorer_core fails here (it failed on the old code: rk.Status,
    sweeps' INVALID_PARAMS/NOT_RUN, basins' OUTCOMES and fates)."""
    extra = _code_tables() - set(NOT_STATUSES)
    assert not extra, f"a second status vocabulary: {sorted(extra)}; use explorer_core.status.Status"


# --- per-member statuses agree with the engine --------------------------------------------------------------


def _engine_status(p, ic, periods: int, **kw) -> Status:
    batch = Batch.start(np.array([ic]), p.t0, p.period)
    advance(Model(p), batch, periods, workers=1, block=1, **kw)
    return Status.of(int(batch.status[0]))


def test_chart_pixels_carry_the_status_of_their_member(tmp_path) -> None:
    num = Numerics(rtol=1e-8, atol=1e-8, bound=3.0)  # a low bound: some members escape
    spec = chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (0.0, 2.0), (3, 3), ics=[(-0.09, -2.0)], transient=20,
                      periods=40, numerics=num)  # fmt: skip
    assert (Chart.empty(spec).status == Status.NOT_RUN).all()
    chart = regime_chart(spec, workers=1)
    assert np.array_equal(chart.regime == INVALID, chart.status == Status.INVALID) and (chart.regime == INVALID).any()
    assert np.array_equal(chart.regime == ESCAPED, chart.status == Status.ESCAPED) and (chart.regime == ESCAPED).any()
    classified = (chart.regime > 0) & (chart.regime < ESCAPED)
    assert np.array_equal(classified, chart.status == Status.OK)
    for j, i, k in zip(*np.nonzero((chart.regime == ESCAPED) | (chart.regime == FAILED)), strict=True):
        p = spec.pixel_params(int(j), int(i))
        engine = _engine_status(p, spec.ics[k], spec.transient + spec.periods, rtol=1e-8, atol=1e-8, bound=3.0)
        assert engine == Status.of(int(chart.status[j, i, k])), (j, i, k)
    assert chart.summary()["statuses"] == count_names(chart.status[chart.computed])
    chart.to_npz(str(tmp_path / "c.npz"))
    with np.load(tmp_path / "c.npz") as z:
        assert z["status_names"][z["status"]].tolist() == names(chart.status)
    chart.to_csv(str(tmp_path / "c.csv"))
    rows = list(csv.DictReader((tmp_path / "c.csv").open()))
    assert {r["status"] for r in rows} == {"ok", "escaped", "invalid"} & set(count_names(chart.status))


def test_basin_pixels_carry_the_status_of_their_member(tmp_path) -> None:
    box = (-1.7, 1.5, -3.0, 1.0)
    b = basins(FIG8B, box, (5, 5))
    esc = np.argwhere(b.status == Status.ESCAPED)
    assert np.array_equal(b.status == Status.ESCAPED, b.label == ESCAPE) and esc.size
    bound = b.extra["escape_bound"]
    for j, i in esc[:3]:
        st = _engine_status(FIG8B, (b.q[i], b.r[j]), b.spec.max_periods, rtol=b.spec.numerics.rtol,
                            atol=b.spec.numerics.atol, bound=bound)  # fmt: skip
        assert st == Status.ESCAPED
    assert np.array_equal(b.status[b.label >= 0] == Status.OK, np.ones(int((b.label >= 0).sum()), bool))
    assert b.summary()["statuses"] == count_names(b.status)
    b.to_npz(str(tmp_path / "b.npz"))
    with np.load(tmp_path / "b.npz") as z:
        assert z["status_names"][z["status"]].tolist() == names(b.status)


def test_sweep_values_carry_the_status_of_their_member(tmp_path) -> None:
    d = bifurcation_diagram(FIG10, "I11", [0.0, 1.0], points=5, transient=5, ics=[(-0.5, -1.0), (0.0, 3.0)],
                            seeding="fixed", numerics=Numerics(bound=50.0))  # fmt: skip
    assert (d.status[:, 0] == Status.INVALID).all()
    for i, ic in enumerate(d.ics):
        engine = _engine_status(FIG10.with_(I11=1.0), ic, 10, bound=50.0)
        assert Status.of(int(d.status[0, 1, i])) == engine
    d.to_csv(str(tmp_path / "d.csv"))
    words = {r["status"] for r in csv.DictReader((tmp_path / "d.csv").open())}
    assert words <= set(CODES.values()) and "invalid" in words


def test_branches_and_newton_failures_say_why_in_the_vocabulary() -> None:
    res = continue_orbit(FIG10, "alpha", (-0.35, -0.36), (-0.0959, -1.962), period=1, max_points=3)
    br = res.branches[0]
    assert br.status == Status.BUDGET and "max_points" in br.stop
    assert json.loads(json.dumps(br.as_dict()))["status"] == "budget"
    pmap = poincare.PoincareMap.of(FIG8B, Numerics(bound=5.0))
    out = poincare.newton(pmap, np.array([[0.0, 4.9], [-0.04, -2.4]]), np.array([1, 1]), ftol=1e-10, max_iter=1)
    by_seed = {f.i: f.status for f in out.failures}
    assert by_seed[0] == Status.ESCAPED  # the seed's own trajectory escapes
    assert by_seed.get(1, Status.OK) in (Status.OK, Status.NOT_CONVERGED)
    cancelled = poincare.newton(pmap, np.array([[-0.04, -2.4]]), np.array([1]), ftol=1e-10, max_iter=5,
                                cancel=lambda: True)  # fmt: skip
    assert [f.status for f in cancelled.failures] == [Status.CANCELLED]


# --- every file and JSON the CLI writes ------------------------------------------------------------------------


def _check_names(obj, where: str) -> None:
    """Every ``status`` in a JSON document is a name of the enum (or a count of names); never a bare int."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k == "status":
                if isinstance(v, dict):
                    assert set(v) <= set(CODES.values()), (where, v)
                else:
                    assert isinstance(v, str) and v in CODES.values(), (where, k, v)
            if k == "statuses":
                assert set(v) <= set(CODES.values()), (where, v)
            _check_names(v, where)
    elif isinstance(obj, list):
        for v in obj:
            _check_names(v, where)


CLI_RUNS = {
    "section": ["section", "--scene", "fig8B", "--ic", "-0.1,0.2", "--ic=0,40", "--periods", "3", "--bound", "30",
                "--out", "{d}/s.csv", "--json"],
    "tprime": ["tprime", "--scene", "fig1A", "--grid", "4", "--per-period", "--out", "{d}/t.npz", "--json"],
    "lyapunov": ["lyapunov", "--scene", "fig8B", "--ic", "-0.5,-1", "--ic", "0,40", "--bound", "30", "--periods",
                 "5", "--transient", "2", "--history", "{d}/h.csv", "--json"],
    "bifurcation": ["bifurcation", "--scene", "fig10", "--param", "I11", "--range", "0,1", "--n-values", "2",
                    "--points", "3", "--transient", "2", "--ic", "-0.5,-1", "--out", "{d}/b.csv", "--json"],
    "orbits": ["orbits", "--scene", "fig8B", "--seed", "-0.04,-2.4", "--seed", "0,4.9", "--bound", "5", "--period",
               "1", "--out", "{d}/o.csv", "--json"],
    "chart": ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.6,-0.5", "--y-param", "I11",
              "--y-range", "0,2", "--grid", "2,2", "--ic", "-0.09,-2", "--periods", "10", "--p-max", "2",
              "--transient", "4", "--out", "{d}/c.npz", "--out", "{d}/c.csv", "--json"],
    "basins": ["basins", "--scene", "fig8B", "--box", "-1.7,1.5,-3,1", "--grid", "3,3", "--max-periods", "60",
               "--out", "{d}/b.npz", "--json"],
    **{name: VALID[name] for name in ("manifolds", "continue", "symmetry", "density")},  # the fuzzer's small runs
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CLI_RUNS))
def test_cli_outputs_carry_names_and_read_back(name: str, tmp_path) -> None:
    argv = [a.replace("{d}", str(tmp_path)) for a in CLI_RUNS[name]]
    rc, out, err = run_cli(*argv)
    assert rc == 0, err
    summary = json.loads(out)
    _check_names(summary, name)
    # One completeness vocabulary (README, "What a result lost"): `completed` (the run reached its end) and
    # `complete` (completed and nothing lost), both booleans, in every command's JSON.
    assert isinstance(summary["completed"], bool) and isinstance(summary["complete"], bool), name
    assert summary["completed"] or not summary["complete"]
    assert summary["complete"] == (summary["completed"] and not summary["lost"])
    for path in sorted(tmp_path.iterdir()):
        if path.suffix == ".csv":
            with path.open() as fh:
                rows = list(csv.DictReader(fh))
            for r in rows:
                if "status" in r:
                    assert r["status"] in CODES.values(), (path.name, r)
        elif path.suffix == ".npz":
            with np.load(path) as z:
                if "status" in z.files:
                    assert "status_names" in z.files, path.name
                    assert z["status_names"].tolist() == list(CODES.values())
                    assert set(z["status_names"][z["status"]].ravel()) <= set(CODES.values())
