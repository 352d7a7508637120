"""Options declared once: the validators, NewtonOptions and its presets, the rule that derives inner numerics from
the user's tolerance, and the app's Method and Accuracy reaching the computations through the core's rule."""

from __future__ import annotations

import inspect
import json
import math
import pathlib
import re

import numpy as np
import pytest

from explorer_core.analyses import basins as basins_mod
from explorer_core.analyses import regimes
from explorer_core.analyses.basins import basin_spec
from explorer_core.analyses.bifurcation import DIAGRAM_RTOL, diagram_spec
from explorer_core.analyses.orbits import FTOL, MAX_ITER, ORBIT_NUMERICS
from explorer_core.analyses.regimes import DEFAULT_CHART_TOL, chart_numerics, chart_spec
from explorer_core.scenes import get_scene
from explorer_core.solve import checks
from explorer_core.solve.numerics import Numerics, chosen_numerics
from explorer_core.solve.options import CORRECTOR, JUMPS, ORBITS, PRESETS, SETTLING, NewtonOptions
from explorer_core.solve.poincare import PATIENCE
from explorer_core.system.params import ParameterError

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIG8B = get_scene("fig8B").params


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: checks.check_int("periods", 2.0, 1, 10), "periods must be an integer in [1, 10], got 2.0"),
        (lambda: checks.check_int("periods", True, 0, 10), "got True"),
        (lambda: checks.check_positive("ds", -1e-3), "ds must be a positive finite number, got -0.001"),
        (lambda: checks.check_positive("ds", math.nan), "ds must be a positive finite number, got nan"),
        (lambda: checks.check_fraction("tol", 1.0), "tol must be in (0, 1), got 1.0"),
        (lambda: checks.check_number("g0", math.inf), "g0 must be a finite number, got inf"),
        (lambda: checks.check_choice("seeding", "both", ("fixed", "continuation")), "got 'both'"),
        (lambda: checks.check_bool("switch", 1), "switch must be True or False, got 1"),
        (lambda: checks.check_range("q_range", (1, 0)), "q_range must be finite with lo < hi"),
        (lambda: checks.check_range("range", (1, 1), increasing=False), "range must be two different numbers"),
        (lambda: checks.check_range("range", (-1e308, 1e308)), "range is too wide"),
        (lambda: checks.check_range("range", "ab"), "range must be two numbers lo,hi, got 'ab'"),
        (lambda: checks.check_ints("grid", (3, 0), 2, 1, 10), "grid must be 2 integers NX,NY each in [1, 10]"),
        (lambda: checks.check_point("seed", (5.0, 0.0), 1.0), "seed 5,0 is outside the escape bound 1"),
        (lambda: checks.check_box((0, 1, 1, 0)), "box must have qmin < qmax and rmin < rmax"),
    ],
)
def test_a_check_names_the_option_and_the_value_it_refused(call, words) -> None:
    with pytest.raises(ParameterError) as err:
        call()
    assert words in str(err.value)


def test_checks_return_plain_python_values() -> None:
    assert type(checks.check_int("n", np.int64(3), 0, 5)) is int
    assert type(checks.check_positive("x", np.float32(0.5))) is float
    assert checks.check_range("range", (0.5, -1), increasing=False) == (0.5, -1.0)
    assert checks.check_optional_int("hit", None, 1, 3) is None


def test_the_presets_are_todays_settings() -> None:
    # Declared once in solve.options; the analyses' module names read them.
    assert (FTOL, MAX_ITER, ORBITS.patience, ORBITS.max_step, ORBITS.coarse) == (1e-9, 40, PATIENCE, 1.0, True)
    assert ORBIT_NUMERICS == Numerics(rtol=1e-12, atol=1e-12) and ORBIT_NUMERICS.method == "vern9"
    assert (SETTLING.ftol, SETTLING.max_iter, SETTLING.max_step, SETTLING.patience) == (1e-8, 8, math.inf, None)
    assert JUMPS.ftol == 0.1 * 1e-9 and JUMPS.rtol is None and not JUMPS.coarse
    assert set(PRESETS) == {"orbits", "settling", "jumps", "corrector"} and CORRECTOR.ftol == 1e-10


def test_at_the_default_tolerance_the_inner_numerics_are_the_presets_exactly() -> None:
    inner, ftol = SETTLING.at(chart_numerics(), DEFAULT_CHART_TOL)
    assert inner == Numerics(rtol=1e-10, atol=1e-10) and inner.method == "vern9" and ftol == 1e-8
    spec = basin_spec(FIG8B, (-1, 1, -1, 1), (8, 8))
    assert spec.newton_map() == (ORBIT_NUMERICS, FTOL) and spec.newton.patience is None
    diagram = Numerics()
    assert diagram.rtol == DIAGRAM_RTOL and JUMPS.at(diagram, DIAGRAM_RTOL) == (diagram, JUMPS.ftol)


def test_inner_numerics_follow_the_users_tolerance_by_one_rule() -> None:
    # A chart asked at 1e-6 (100x the default) runs its settled-cycle Newton 100x looser, and the "auto" rule
    # chooses the method again at that tolerance (DOP853 at 1e-8, where vern9 kept before).
    inner, ftol = SETTLING.at(Numerics(rtol=1e-6, atol=1e-6), DEFAULT_CHART_TOL)
    assert (inner.rtol, inner.atol, inner.method, ftol) == (1e-8, 1e-8, "dop853", 1e-6)
    # Tighter than the default: the map tightens, ftol stays (a residual can be asked tighter than it).
    inner, ftol = SETTLING.at(Numerics(rtol=1e-10, atol=1e-10), DEFAULT_CHART_TOL)
    assert (inner.rtol, ftol) == (1e-12, 1e-8)
    # Clipped: never looser than 1e-6, never tighter than 1e-13.
    assert ORBITS.at(Numerics(rtol=1e-2, atol=1e-2), 1e-8)[0].rtol == 1e-6
    assert ORBITS.at(Numerics(rtol=1e-15, atol=1e-15), 1e-8)[0].rtol == 1e-13
    # The user's explicit method is the Newton map's too; taylor (sections only) falls back to the rule.
    assert ORBITS.at(Numerics(method="dop853", rtol=1e-8, atol=1e-8), 1e-8)[0].method == "dop853"
    assert ORBITS.at(Numerics(method="taylor", rtol=1e-8, atol=1e-8), 1e-8)[0].method == "vern9"
    # follow=False: as set.
    fixed = ORBITS.replace(follow=False)
    assert fixed.at(Numerics(rtol=1e-6, atol=1e-6), 1e-8)[0].rtol == 1e-12


def test_the_specs_record_their_newton_options_and_the_map_it_ran_on() -> None:
    spec = chart_spec(FIG8B, "alpha", (0.0, 0.1), "g1", (0.0, 0.1), (2, 2), numerics=Numerics(rtol=1e-6, atol=1e-6))
    d = spec.as_dict()
    assert d["newton"]["ftol"] == 1e-8 and d["newton_numerics"]["rtol"] == 1e-8
    assert d["newton_numerics"]["method"] == "dop853"
    b = basin_spec(FIG8B, (-1, 1, -1, 1), (4, 4), numerics=Numerics(rtol=1e-6, atol=1e-6))
    assert b.as_dict()["newton_numerics"]["rtol"] == 1e-10 and b.newton_map()[1] == 1e-7
    with pytest.raises(ParameterError, match="newton must be a NewtonOptions"):
        diagram_spec(FIG8B, "alpha", [0.0, 0.1], newton={"ftol": 1e-3})


def test_the_basins_cycle_newton_runs_with_the_specs_settings(monkeypatch) -> None:
    seen = []
    real = basins_mod.find_orbits

    def spy(*a, **kw):
        seen.append((kw["numerics"], kw["ftol"], kw["patience"], kw["max_iter"]))
        return real(*a, **kw)

    monkeypatch.setattr(basins_mod, "find_orbits", spy)
    fig11 = get_scene("fig11").params.with_(I11=1.6, alpha=-0.5)  # a period-1 and a period-3 attractor
    spec = basin_spec(fig11, (-1.7, 1.5, -3.0, 1.0), (8, 8), numerics=Numerics(rtol=1e-6, atol=1e-6),
                      newton=ORBITS.replace(max_iter=12, patience=None))  # fmt: skip
    basins_mod.basins(spec)
    assert seen, "no cycle was handed to Newton"
    assert {(n.rtol, n.method, f, p, m) for n, f, p, m in seen} == {(1e-10, "vern9", 1e-7, None, 12)}
    assert {n.bound for n, *_ in seen} == {max(spec.numerics.bound, 1e4)}


def test_the_charts_settled_cycle_newton_runs_on_the_specs_derived_map(monkeypatch) -> None:
    seen = []
    real = regimes.newton

    def spy(pmap, *a, **kw):
        seen.append((pmap.numerics.rtol, kw["ftol"], kw["max_iter"]))
        return real(pmap, *a, **kw)

    monkeypatch.setattr(regimes, "newton", spy)
    fig10 = get_scene("fig10").params
    spec = chart_spec(fig10, "alpha", (-0.40, -0.39), "g1", (fig10.g1, fig10.g1 + 0.01), (2, 2),
                      ics=[(-0.0959, -1.962)], transient=60, periods=100, numerics=Numerics(rtol=1e-7, atol=1e-7),
                      newton=SETTLING.replace(max_iter=5))  # fmt: skip
    regimes.regime_chart(spec)
    assert seen and set(seen) == {(1e-9, 1e-7, 5)}


def test_numerics_loosened_chooses_again_only_what_the_rule_chose() -> None:
    auto = Numerics(rtol=1e-12, atol=1e-12)
    assert auto.method == "vern9" and auto.loosened(1e-7).method == "dop853"
    assert auto.loosened(1e-7) == Numerics(rtol=1e-7, atol=1e-7)
    mine = Numerics(method="vern9", rtol=1e-12, atol=1e-12)
    assert mine == auto and mine.loosened(1e-7).method == "vern9"  # the user's choice is kept


def test_options_are_checked_and_unknown_names_refused() -> None:
    with pytest.raises(ParameterError) as err:
        NewtonOptions(ftol=-1.0)
    assert err.value.option == "ftol" and "-1.0" in str(err.value)
    with pytest.raises(ParameterError, match="has no option 'tolerance'"):
        ORBITS.replace(tolerance=1e-3)
    flags = [o.flag for o in NewtonOptions.options()]
    assert "--newton-ftol" in flags and "--newton-max-iter" in flags


def test_the_accuracy_rule_for_every_computation() -> None:
    n, why = chosen_numerics("auto", "high", None)
    assert (n.rtol, n.method) == (1e-12, "vern9") and "high" in why
    n, why = chosen_numerics("auto", "plot", None, plot_rtol=1e-7)
    assert (n.rtol, n.method) == (1e-7, "dop853") and "picture" in why
    n, why = chosen_numerics("dop853", "plot", None)  # no picture: the computation's own tolerance
    assert (n.rtol, n.method) == (1e-10, "dop853") and "own tolerance" in why
    with pytest.raises(ParameterError, match="accuracy must be one of plot, high, got 'best'"):
        chosen_numerics("auto", "best", None)


def test_the_app_builds_no_numerics_of_its_own() -> None:
    found = [f"{p.relative_to(ROOT)}:{i}" for p in (ROOT / "app").rglob("*.py")
             for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"\bNumerics\(", line)]  # fmt: skip
    assert not found, f"numerics made up in the app instead of the core's rule: {found}"


def test_the_lyapunov_tab_measures_what_the_command_lines_ensemble_measures(monkeypatch) -> None:
    from app import analyses
    from app.controller import ExplorerSession
    from app.runner import WARM, InlineExecutor, Runner
    from app.state import ExplorerState
    from explorer_core.analyses.lyapunov import lyapunov_spec

    WARM.set()
    seen = []
    real = analyses.lyapunov_spectrum
    monkeypatch.setattr(analyses, "lyapunov_spectrum", lambda spec, **kw: seen.append(spec) or real(spec, **kw))
    st = ExplorerState(scene="fig8B")
    st.param.update(n_random=2, periods=10)
    tab = analyses.LyapunovTab(ExplorerSession(st, Runner(lambda fn: fn(), executor=InlineExecutor())))
    st.param.update(lyap_ic=(-0.5, -1.0), lyap_transient=20, lyap_periods=30, lyap_ensemble=3)
    tab.figure()
    tab.run()
    # The page's Method (auto) at the spectrum's own tolerance under "plot":
    # `bilimovich lyapunov --scene fig8B --ic -0.5,-1 --transient 20 --periods 30 --ensemble 3 --steps-per-period 200`
    assert (st.method, st.accuracy, st.steps_per_period) == ("auto", "plot", 200)
    cli = lyapunov_spec(FIG8B, [(-0.5, -1.0)], 30, transient=20, ensemble=3, numerics=Numerics(steps_per_period=200))
    assert seen == [cli]
    text = "\n".join(tab.view["result"])
    assert "numerics: vern9 at rtol 1e-10 (plot: its own tolerance, no picture's)" in text
    st.accuracy = "high"
    st.method = "dop853"
    tab.run()
    assert seen[-1].numerics == Numerics(method="dop853", rtol=1e-12, atol=1e-12, steps_per_period=200)


def test_every_analysis_is_in_the_registry_and_its_entry_points_exist() -> None:
    import dataclasses
    import inspect

    from explorer_core.cli import COMMANDS
    from explorer_core.registry import ANALYSES, by_command

    for a in ANALYSES.values():
        assert callable(a.get("run")) and isinstance(a.get("result"), type)
        if a.iterate:
            assert inspect.isgeneratorfunction(a.get("iterate")) or callable(a.get("iterate"))
        # every analysis has a frozen spec and the builder that validates it (the runner takes the spec)
        spec = a.get("spec")
        assert dataclasses.is_dataclass(spec) and spec.__dataclass_params__.frozen, a.name
        assert callable(a.get("builder")) and callable(getattr(spec, "as_dict", None)), a.name
        for name, cls in a.nested_options().items():
            # a nested option is a parameter of the builder, its preset the default (None: the class's defaults)
            default = inspect.signature(a.get("builder")).parameters[name].default
            assert default is None or isinstance(default, cls)
        if a.command is not None:
            assert a.command in COMMANDS and by_command(a.command) is a
    analyses_commands = {"section", "density", "critical", "tprime", "lyapunov", "bifurcation", "orbits",
                         "manifolds", "continue", "chart", "basins", "fit", "body", "symmetry", "birkhoff", "sali",
                         "ftle"}  # fmt: skip
    assert {a.command for a in ANALYSES.values() if a.command} == analyses_commands


@pytest.mark.parametrize(
    ("command", "preset"),
    [("chart", SETTLING), ("basins", basins_mod.BASIN_NEWTON), ("bifurcation", JUMPS)],
)
def test_the_command_line_sets_nested_newton_options_from_their_declarations(command, preset) -> None:
    import argparse

    from explorer_core.cli import _nested, build_parser
    from explorer_core.registry import by_command

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    flags = {s for a in sub._actions for s in a.option_strings}
    assert {o.flag for o in NewtonOptions.options()} <= flags
    args = argparse.Namespace(newton__max_iter="3", newton__patience="none", newton__max_step="inf")
    got = _nested(args, by_command(command).get("builder"))["newton"]
    assert got == preset.replace(max_iter=3, patience=None, max_step=math.inf)
    assert _nested(argparse.Namespace(), by_command(command).get("builder")) == {}


def test_a_charts_json_records_the_newton_it_ran_with(tmp_path) -> None:
    from tests.clirun import run_cli

    code, out, err = run_cli("chart", "--scene", "fig10", "--x-param", "alpha", "--x-range", "-0.4,-0.39",
                             "--y-param", "g1", "--y-range", "1,1.01", "--grid", "2,2", "--transient", "40",
                             "--periods", "60", "--rtol", "1e-7", "--newton-max-iter", "5", "--newton-max-step", "inf",
                             "--json")  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["newton"] == {**SETTLING.as_dict(), "max_iter": 5}
    assert d["newton"]["max_step"] == "inf"
    assert (d["newton_numerics"]["rtol"], d["newton_numerics"]["method"]) == (1e-9, "vern9")
    code, _, err = run_cli("chart", "--scene", "fig10", "--x-param", "alpha", "--x-range", "-0.4,-0.39", "--y-param",
                           "g1", "--y-range", "1,1.01", "--grid", "2,2", "--json", "--newton-ftol", "-1")  # fmt: skip
    assert code == 2 and "--newton-ftol: ftol must be a positive finite number, got -1.0" in err


def test_an_orbit_search_is_a_spec_the_command_line_only_builds() -> None:
    from explorer_core.analyses.orbits import orbit_search, orbit_spec

    spec = orbit_spec(FIG8B, max_period=2, seeds=[(-0.04, -2.4)], thorough=True)
    assert spec.periods == (1, 2) and spec.grid is None and spec.newton == ORBITS.replace(patience=None, max_iter=80)
    assert orbit_spec(FIG8B).grid == (10, 10)  # no seeds: the grid over the box
    with pytest.raises(ParameterError, match="not both") as err:
        orbit_spec(FIG8B, period=1, max_period=2)
    assert err.value.option == "period"
    with pytest.raises(ParameterError, match="outside the escape bound") as err:
        orbit_spec(FIG8B, seeds=[(1e9, 0.0)])
    assert err.value.option == "seeds"
    res = orbit_search(orbit_spec(FIG8B, period=1, seeds=[(-0.04, -2.4)]))
    assert res.completed and len(res.orbits) == 1 and res.summary()["spec"]["newton"] == ORBITS.as_dict()


#: Each generated command's own flags at c3075ef (before the command line was generated from the declarations):
#: every one of them must still be there (issue 31: the same options as today plus the new ones).
TODAYS_FLAGS = {
    "lyapunov": ["--ensemble", "--history", "--ic", "--offset", "--periods", "--seed", "--transient"],
    "bifurcation": [
        "--ic",
        "--n-values",
        "--out",
        "--param",
        "--points",
        "--range",
        "--scheduler",
        "--seeding",
        "--sweeps",
        "--transient",
    ],
    "orbits": [
        "--box",
        "--in-box",
        "--max-period",
        "--out",
        "--period",
        "--returns",
        "--seed",
        "--seeds",
        "--thorough",
    ],
    "continue": [
        "--ds",
        "--ds-max",
        "--ds-min",
        "--from",
        "--max-period",
        "--max-points",
        "--out",
        "--param",
        "--param2",
        "--period",
        "--range",
        "--range2",
        "--switch",
    ],
    "chart": [
        "--coarse",
        "--grid",
        "--ic",
        "--lyap-threshold",
        "--out",
        "--p-max",
        "--periods",
        "--refine",
        "--scheduler",
        "--tol",
        "--transient",
        "--x-param",
        "--x-range",
        "--y-param",
        "--y-range",
    ],
    "basins": ["--box", "--cell-box", "--cells", "--grid", "--max-periods", "--out"],
    "fit": ["--box", "--criterion", "--degree", "--ic", "--members", "--out", "--seed", "--window"],
    "body": ["--ic", "--k0", "--out", "--periods", "--samples"],
    "symmetry": ["--box", "--centre", "--ic", "--periods", "--random", "--seed", "--tol"],
    "manifolds": [
        "--delta-px",
        "--kinds",
        "--length",
        "--max-points",
        "--orbit",
        "--out",
        "--period",
        "--pixels",
        "--view",
    ],
}


@pytest.mark.parametrize("command", sorted(TODAYS_FLAGS))
def test_a_generated_command_has_no_body_and_keeps_todays_flags(command) -> None:
    import argparse

    from explorer_core.cli import COMMANDS, build_parser, cmd_analysis

    assert COMMANDS[command].run is cmd_analysis  # no cmd_X body: builder -> runner -> write -> report
    parser = build_parser(command)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    flags = {s for a in sub._actions for s in a.option_strings}
    assert set(TODAYS_FLAGS[command]) <= flags, set(TODAYS_FLAGS[command]) - flags
    # building the parser for another command loads none of this one's analysis
    other = build_parser("scenes")
    sub = next(a for a in other._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    assert "--newton-ftol" not in {s for a in sub._actions for s in a.option_strings} or command in (
        "chart",
        "basins",
        "bifurcation",
        "orbits",
    )


def test_generated_commands_write_one_record_per_file_under_out(tmp_path) -> None:
    from tests.clirun import run_cli

    out = tmp_path / "o.csv"
    args = ["orbits", "--scene", "fig8B", "--seed", "-0.04,-2.4", "--period", "1", "--out", str(out), "--json"]
    code, stdout, err = run_cli(*args)
    assert code == 0, err
    d = json.loads(stdout)
    assert d["out"] == [{"path": str(out), "rows": 1}] and "csv" not in d
    assert np.genfromtxt(out, delimiter=",", names=True)["period"].tolist() == 1


def test_an_options_default_is_declared_once_by_its_builder() -> None:
    """An option's default is declared by its builder's signature (the command line's help shows it): a frozen
    spec's fields have no defaults of their own (a second default would drift apart), except an option declared on
    the field itself (``option()``: default, check and help), whose builder reads it from there."""
    import dataclasses

    from explorer_core.registry import ANALYSES

    for a in ANALYSES.values():
        for f in dataclasses.fields(a.get("spec")):
            has_default = f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
            assert not has_default or "check" in f.metadata, (a.name, f.name)


#: A builder's parameters that are no option: the system (or the spec a runner takes) and the run's plumbing.
_NOT_OPTIONS = {"params", "spec", "progress", "cancel", "executor", "workers"}


@pytest.mark.parametrize("name", sorted(__import__("explorer_core.registry").registry.ANALYSES))
def test_every_option_of_a_builder_is_declared_once_with_its_check(name: str) -> None:
    """Every keyword a builder takes is one declaration (``declare``: default, check, help, flag); the function's
    own signature has no default of its own, and the generic validation refuses a bad value before the body runs,
    naming the option."""
    from explorer_core.registry import ANALYSES

    builder = ANALYSES[name].get("builder")
    declared = getattr(builder, "__options__", None)
    assert declared is not None, f"{name}: its builder is not made by declare()"
    taken = [p for p in inspect.signature(builder).parameters if p not in _NOT_OPTIONS]
    assert sorted(taken) == sorted(declared), name
    body = inspect.signature(inspect.unwrap(builder)).parameters
    assert all(body[p].default is inspect.Parameter.empty for p in declared), name
    for option, arg in declared.items():
        assert arg.check is not None or arg.checked_with, (name, option)
        assert set(arg.checked_with) <= set(declared) | {"params"}, (name, option)
