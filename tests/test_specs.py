"""The specs of continuation, Lyapunov exponents and drift fits (issue 20, item 4: ``X(spec)``, ``iter_X(spec)``).

Each builder refuses every bad value with a message naming the option and the value (the option's keyword
is also ``exc.option``, for the CLI's flags); a spec is plain data (it pickles, compares and hashes by value);
``X(spec)`` is the keyword form bit for bit, and the result carries its spec; the CLI turns a refused value into
one usage line naming its flag, exit status 2.
"""

from __future__ import annotations

import json
import math
import pickle
from typing import Any

import numpy as np
import pytest
from clirun import run_cli

from explorer_core import config, export
from explorer_core.analyses.continuation import (
    ContinuationOptions,
    ContinuationSpec,
    continuation_spec,
    continue_orbit,
    iter_continue_orbit,
)
from explorer_core.analyses.drift import DriftSpec, drift_fit, drift_spec, iter_drift_fit
from explorer_core.analyses.lyapunov import (
    LyapunovSpec,
    attractor_ensemble,
    iter_lyapunov,
    lyapunov_spec,
    lyapunov_spectrum,
)
from explorer_core.progress import run
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError

FIG10 = get_scene("fig10").params
FIG8B = get_scene("fig8B").params
FIG3 = get_scene("fig3").params
FIXED_POINT_035 = (-0.0959, -1.962)  # the stable fixed point of Fig. 10 at alpha = -0.35
NAN, INF = math.nan, math.inf


def _refused(build: Any, args: tuple, kw: dict[str, Any]) -> ParameterError:
    with pytest.raises(ParameterError) as info:
        build(*args, **kw)
    return info.value


# --- every bad value, named -------------------------------------------------------------------------------------

CONTINUATION = (FIG10, "alpha", (-0.35, -0.36), FIXED_POINT_035, 1)


@pytest.mark.parametrize(
    ("change", "option", "needles"),
    [
        ({"param": "I99"}, "param", ("I99",)),
        ({"value_range": (-0.35,)}, "value_range", ("range", "(-0.35,)")),
        ({"value_range": "ab"}, "value_range", ("range", "'ab'")),
        ({"value_range": (-0.35, -0.35)}, "value_range", ("range", "different")),
        ({"value_range": (-0.35, NAN)}, "value_range", ("range", "nan")),
        ({"value_range": (-1e308, 1e308)}, "value_range", ("range", "width")),
        ({"param": "I12", "value_range": (5.0, 0.0)}, "value_range", ("first value I12 = 5", "not a valid system")),
        ({"param": "I12", "value_range": (0.0, 5.0), "check_end": True}, "value_range", ("end I12 = 5",)),
        ({"period": 0}, "period", ("period", "got 0")),
        ({"period": 1.5}, "period", ("period", "1.5")),
        ({"period": 2, "max_period": 1}, "max_period", ("max_period", "got 1")),
        ({"ds": -1.0}, "ds", ("ds must", "-1.0")),
        ({"ds_min": NAN}, "ds_min", ("ds_min must", "nan")),
        ({"ds_max": "x"}, "ds_max", ("ds_max must", "'x'")),
        ({"ds": 0.5}, "ds", ("ds_min <= ds <= ds_max", "ds = 0.5")),
        ({"ds_min": 1.0}, "ds_min", ("ds_min <= ds <= ds_max", "ds_min = 1.0")),
        ({"max_points": 1}, "max_points", ("max_points", "got 1")),
        ({"options": {"ds": 0.1}}, "options", ("options must be a ContinuationOptions",)),
        ({"numerics": "fast"}, "numerics", ("numerics", "'fast'")),
        ({"seed": (INF, 0.0)}, "seed", ("initial condition 0 is not finite",)),
        ({"seed": [(0.0, 0.0), (1.0, 1.0)]}, "seed", ("seed must be one point", "got 2")),
        ({"seed": (1e9, 0.0)}, "seed", ("seed 1e+09,0", "escape bound")),
        ({"param2": "I11"}, "param2", ("param2 and range2 go together", "'I11'")),
        ({"range2": (1.0, 2.0)}, "param2", ("param2 and range2 go together", "(1.0, 2.0)")),
        ({"param2": "Alpha", "range2": (0.0, 1.0)}, "param2", ("param2 must differ", "'alpha'")),
        ({"param2": "I11", "range2": (2.0, 1.0)}, "range2", ("range2 must have C < D", "(2.0, 1.0)")),
        ({"param2": "I11", "range2": (1.0, INF)}, "range2", ("range2", "inf")),
        ({"window1": (0.0, INF)}, "window1", ("window1", "inf")),
    ],
)  # fmt: skip
def test_continuation_spec_names_each_bad_value(change: dict[str, Any], option: str, needles: tuple[str, ...]) -> None:
    names = ("params", "param", "value_range", "seed", "period")
    pos = {k: v for k, v in change.items() if k in names}
    args = tuple(pos.get(n, v) for n, v in zip(names, CONTINUATION, strict=True))
    exc = _refused(continuation_spec, args, {k: v for k, v in change.items() if k not in names})
    assert exc.option == option, (exc.option, str(exc))  # type: ignore[attr-defined]
    for needle in needles:
        assert needle in str(exc), (needle, str(exc))


LYAPUNOV = (FIG8B, [(-0.5, -1.0)], 50)


@pytest.mark.parametrize(
    ("change", "option", "needles"),
    [
        ({"ics": [(NAN, 0.0)]}, "ics", ("initial condition 0 is not finite",)),
        ({"ics": [(0.0, 1.0, 2.0)]}, "ics", ("(q, r) pairs",)),
        ({"periods": 0}, "periods", ("periods must be", "got 0")),
        ({"periods": config.MAX_PERIODS + 1}, "periods", ("periods must be",)),
        ({"transient": -1}, "transient", ("transient must be", "got -1")),
        ({"transient": 2.5}, "transient", ("transient must be", "2.5")),
        ({"numerics": "fast"}, "numerics", ("numerics", "'fast'")),
        ({"ensemble": 0}, "ensemble", ("ensemble must be", "got 0")),
        ({"ensemble": 3, "ics": [(0.0, 1.0), (1.0, 1.0)]}, "ensemble", ("ensemble of 3 takes one initial", "got 2")),
        ({"offset": 0.0}, "offset", ("offset must be in (0, 1]", "0.0")),
        ({"offset": 1e308}, "offset", ("offset must be in (0, 1]", "1e+308")),
        ({"offset": NAN}, "offset", ("offset", "nan")),
        ({"offset": "x"}, "offset", ("offset", "'x'")),
        ({"seed": -1}, "seed", ("seed must be", "got -1")),
        ({"ensemble": 1000, "periods": config.MAX_POINTS // 1000 + 1}, "periods", ("1000 members x",)),
    ],
)  # fmt: skip
def test_lyapunov_spec_names_each_bad_value(change: dict[str, Any], option: str, needles: tuple[str, ...]) -> None:
    names = ("params", "ics", "periods")
    args = tuple(change.get(n, v) for n, v in zip(names, LYAPUNOV, strict=True))
    exc = _refused(lyapunov_spec, args, {k: v for k, v in change.items() if k not in names})
    assert exc.option == option, (exc.option, str(exc))  # type: ignore[attr-defined]
    for needle in needles:
        assert needle in str(exc), (needle, str(exc))


@pytest.mark.parametrize(
    ("change", "option", "needles"),
    [
        ({"window": (5, 5)}, "window", ("window must satisfy", "(5, 5)")),
        ({"window": (-1, 5)}, "window", ("window must satisfy", "(-1, 5)")),
        ({"window": (0, config.MAX_PERIODS + 1)}, "window", ("window must satisfy",)),
        ({"window": (2.5, 10)}, "window", ("window must be two integers", "2.5")),
        ({"window": "x"}, "window", ("window must be two integers", "'x'")),
        ({"degree": (13, 1)}, "degree", ("degree must be in [0, 12]", "(13, 1)")),
        ({"window": (0, 10), "degree": (1, 11)}, "degree", ("below the window length", "(1, 11)")),
        ({"degree": (1,)}, "degree", ("degree must be two integers", "(1,)")),
        ({"criterion": "x"}, "criterion", ("criterion must be one of", "'x'")),
        ({"m": 0}, "m", ("m (members) must be", "got 0")),
        ({"ics": [(NAN, 0.0)]}, "ics", ("initial condition 0 is not finite",)),
        ({"ics": None, "box": None}, "box", ("give initial conditions (ics) or a box",)),
        ({"ics": None, "box": (1, 0, 0, 1)}, "box", ("box must have qmin < qmax", "1.0, 0.0")),
        ({"seed": -1}, "seed", ("seed must be", "got -1")),
        ({"max_draws": 0}, "max_draws", ("max_draws must be", "got 0")),
        ({"numerics": "fast"}, "numerics", ("numerics", "'fast'")),
    ],
)  # fmt: skip
def test_drift_spec_names_each_bad_value(change: dict[str, Any], option: str, needles: tuple[str, ...]) -> None:
    kw: dict[str, Any] = {"ics": [(0.0, 8.0)], **change}
    exc = _refused(drift_spec, (FIG3, kw.pop("window", (200, 210))), kw)
    assert exc.option == option, (exc.option, str(exc))  # type: ignore[attr-defined]
    for needle in needles:
        assert needle in str(exc), (needle, str(exc))


def test_the_keyword_forms_check_through_the_builders() -> None:
    """What the old functions let through: a range2 without param2 was ignored, a window of 200.5 cut to 200, a
    bad range2 refused only after the branches were computed, an offset checked only by the CLI (all fail on the
    old code: the calls below ran without a word)."""
    with pytest.raises(ParameterError, match="param2 and range2 go together"):
        continue_orbit(*CONTINUATION, range2=(1.0, 2.0))
    with pytest.raises(ParameterError, match="range2 must have C < D"):
        iter_continue_orbit(*CONTINUATION, param2="I11", range2=(1.0, 0.9))  # at the call, before any work
    with pytest.raises(ParameterError, match="window must be two integers"):
        drift_fit(FIG3, (200.5, 210), ics=[(0.0, 8.0)])
    with pytest.raises(ParameterError, match="offset"):
        lyapunov_spectrum(*LYAPUNOV, ensemble=2, offset=5.0)
    with pytest.raises(TypeError, match="comes alone"):
        continue_orbit(continuation_spec(*CONTINUATION), "alpha")
    with pytest.raises(TypeError, match="comes alone"):
        lyapunov_spectrum(lyapunov_spec(*LYAPUNOV), transient=3)
    with pytest.raises(TypeError, match="comes alone"):
        drift_fit(drift_spec(FIG3, (200, 210), ics=[(0.0, 8.0)]), degree=(0, 2))


# --- plain data -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "spec",
    [
        continuation_spec(*CONTINUATION, switch=True, max_period=4, ds=0.01, param2="I11", range2=(0.9, 1.1)),
        continuation_spec(*CONTINUATION, options=ContinuationOptions(ds=0.03, growth=2.0), window1=(-0.36, -0.35)),
        lyapunov_spec(*LYAPUNOV, transient=10),
        lyapunov_spec(FIG8B, [(-0.5, -1.0)], 50, ensemble=4, offset=1e-3, seed=None),
        drift_spec(FIG3, (200, 300), degree=(0, 2), m=6, box=(-3, 3, 6, 10), seed=1),
        drift_spec(FIG3, (200, 210), ics=np.array([[0.0, 8.0], [0.1, 8.0]])),
    ],
    ids=["continuation", "continuation-options", "lyapunov", "lyapunov-ensemble", "drift-box", "drift-ics"],
)  # fmt: skip
def test_a_spec_pickles_and_round_trips(spec: Any) -> None:
    back = pickle.loads(pickle.dumps(spec))
    assert back == spec and hash(back) == hash(spec) and type(back) is type(spec)
    assert json.loads(export.dumps(spec.as_dict())) == json.loads(export.dumps(back.as_dict()))
    assert "np." not in repr(spec.as_dict())  # plain numbers, as written to JSON


def test_the_builders_fill_in_the_defaults() -> None:
    s = continuation_spec(*CONTINUATION, ds_max=0.01)
    assert isinstance(s, ContinuationSpec) and (s.options.ds, s.options.ds_max) == (0.01, 0.01)  # ds_max bounds ds
    assert s.range == (-0.35, -0.36) and s.seed == FIXED_POINT_035 and s.numerics.rtol == 1e-12
    assert continuation_spec(FIG10, "Alpha", [-0.35, -0.36], np.array(FIXED_POINT_035), 1).param == "alpha"
    l_ = lyapunov_spec(*LYAPUNOV)
    assert isinstance(l_, LyapunovSpec) and l_.ics == ((-0.5, -1.0),) and l_.transient == 0
    d = drift_spec(FIG3, (200, 300), m=3, box=(-3, 3, 6, 10))
    assert isinstance(d, DriftSpec) and d.max_draws == 150 and d.degree == (1, 2) and d.ics is None


# --- X(spec) is the keyword form, bit for bit ------------------------------------------------------------------


def _same_summary(a: dict, b: dict) -> None:
    strip = lambda d: {k: v for k, v in d.items() if "elapsed" not in k}  # noqa: E731
    assert export.dumps(strip(a)) == export.dumps(strip(b))


def test_continuation_of_a_spec_is_the_keyword_form() -> None:
    kw = {"switch": True, "max_period": 2}
    spec = continuation_spec(*CONTINUATION, **kw)
    by_spec = continue_orbit(spec)
    by_keywords = continue_orbit(*CONTINUATION, **kw)
    assert by_spec.csv_rows() == by_keywords.csv_rows() and by_spec.n_points > 2
    assert [b.as_dict() for b in by_spec.bifurcations] == [b.as_dict() for b in by_keywords.bifurcations]
    _same_summary(by_spec.summary(), by_keywords.summary())
    assert by_spec.spec == spec and by_keywords.spec == spec
    assert run(iter_continue_orbit(spec)).csv_rows() == by_spec.csv_rows()


def test_lyapunov_of_a_spec_is_the_keyword_form() -> None:
    spec = lyapunov_spec(FIG8B, [(-0.5, -1.0), (-0.4, -2.1)], 50, transient=10)
    by_spec = lyapunov_spectrum(spec)
    by_keywords = lyapunov_spectrum(FIG8B, [(-0.5, -1.0), (-0.4, -2.1)], 50, transient=10)
    for name in ("exponents", "divergence_mean", "logs", "divs", "points", "npts", "status", "nsteps"):
        assert np.array_equal(getattr(by_spec, name), getattr(by_keywords, name)), name
    _same_summary(by_spec.summary(), by_keywords.summary())
    assert by_spec.spec == spec == by_keywords.spec and by_spec.npts.tolist() == [50, 50]
    assert np.array_equal(run(iter_lyapunov(spec)).logs, by_spec.logs)


def test_a_lyapunov_ensemble_spec_is_what_the_cli_computed_before() -> None:
    """The members placed on the attractor by the spec's run are the old CLI's (attractor_ensemble first)."""
    spec = lyapunov_spec(FIG8B, [(-0.5, -1.0)], 50, transient=20, ensemble=3, offset=1e-4, seed=2)
    res = lyapunov_spectrum(spec)
    ics = attractor_ensemble(FIG8B, (-0.5, -1.0), 3, transient=20, offset=1e-4, seed=2)
    old = lyapunov_spectrum(FIG8B, ics, 50, transient=20)
    assert np.array_equal(res.ics, old.ics) and np.array_equal(res.logs, old.logs) and res.ics.shape == (3, 2)


def test_a_drift_fit_of_a_spec_is_the_keyword_form() -> None:
    # The method is pinned: (0, 8) reaches the drift after a chaotic transient near k = 200, before it with
    # DOP853's digits at 1e-10, after it with vern9's (the "auto" default); this tests the spec's plumbing.
    kw: dict[str, Any] = {"degree": (0, 2), "ics": [(0.0, 8.0), (0.05, 8.0)], "numerics": Numerics(method="dop853")}
    spec = drift_spec(FIG3, (200, 230), **kw)
    by_spec = drift_fit(spec)
    by_keywords = drift_fit(FIG3, (200, 230), **kw)
    for name in ("members", "series", "coef_q", "coef_r", "rms_q", "rms_r", "growth_rate"):
        assert np.array_equal(getattr(by_spec, name), getattr(by_keywords, name)), name
    _same_summary(by_spec.summary(), by_keywords.summary())
    assert by_spec.spec == spec == by_keywords.spec
    drawn = drift_spec(FIG3, (200, 260), degree=(0, 2), m=2, box=(-3, 3, 6, 10), seed=1)
    a, b = run(iter_drift_fit(drawn)), drift_fit(FIG3, (200, 260), degree=(0, 2), m=2, box=(-3, 3, 6, 10), seed=1)
    assert np.array_equal(a.members, b.members) and np.array_equal(a.coef_r, b.coef_r) and a.members.shape == (2, 2)


# --- the CLI: the builder's check, one usage line --------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "needles"),
    [
        (["continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.36", "--from=-0.0959,-1.962",
          "--range2", "1,2"], ("--param2: param2 and range2 go together",)),
        (["continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.36", "--from=-0.0959,-1.962",
          "--ds-min", "1"], ("--ds-min: the steps must satisfy ds-min <= ds <= ds-max", "ds-min = 1.0")),
        (["continue", "--scene", "fig10", "--param", "I12", "--range", "0,5", "--from", "0,0"],
         ("--range: the range's end I12 = 5 is not a valid system",)),
        (["lyapunov", "--scene", "fig8B", "--ic", "0,1", "--periods", "3", "--ensemble", "2", "--offset", "2"],
         ("--offset: offset must be in (0, 1]", "got 2.0")),
        (["lyapunov", "--scene", "fig8B", "--ic", "0,1", "--ic", "1,1", "--ensemble", "2", "--periods", "3"],
         ("--ensemble: an ensemble of 2 takes one initial condition",)),
        (["fit", "--scene", "fig3", "--window", "200,210", "--degree", "13,2", "--ic", "0,8"],
         ("--degree: degree must be in [0, 12]", "[13, 2]")),
        (["fit", "--window", "200,210"], ("--box: give initial conditions",)),
    ],
)  # fmt: skip
def test_the_cli_reports_a_refused_value_in_one_line(argv: list[str], needles: tuple[str, ...]) -> None:
    rc, out, err = run_cli(*argv)
    assert rc == 2 and out == "" and err.count("\n") == 1, (rc, err)
    assert err.startswith(f"bilimovich {argv[0]}: error: ") and "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)


# --- the contract, with a spec ----------------------------------------------------------------------------------

SPECS = {
    "continuation": (lambda: continuation_spec(FIG10, "alpha", (-0.35, -0.38), FIXED_POINT_035, 1, switch=True,
                                               max_period=2), iter_continue_orbit, continue_orbit),
    "lyapunov": (lambda: lyapunov_spec(FIG8B, [(-1.0, -2.0), (-0.9, -2.1)], 64, transient=40), iter_lyapunov,
                 lyapunov_spectrum),
    "drift": (lambda: drift_spec(FIG3, (200, 300), degree=(0, 2), m=6, box=(-3, 3, 6, 10), seed=1), iter_drift_fit,
              drift_fit),
}  # fmt: skip


@pytest.mark.parametrize("name", list(SPECS))
def test_a_spec_runs_under_the_contract(name: str) -> None:
    """``X(spec, progress=)`` gives every update, the last carrying the result; ``iter_X(spec, cancel=)`` cancelled
    after its first update returns what it computed, incomplete, with its spec, and does not raise."""
    make, iterate, call = SPECS[name]
    spec = make()
    seen: list[Any] = []
    result = call(spec, progress=seen.append)
    assert seen and seen[-1].result is result and result.spec == spec and result.complete
    cut: list[Any] = []
    part = run(iterate(spec, cancel=lambda: len(cut) >= 1), cut.append)
    assert part.spec == spec and not part.complete and not part.completed and part.lost


def test_the_summary_says_what_was_asked() -> None:
    """The JSON of a result carries its spec (the fit's random box and seed, the ensemble's offset, the
    continuation's seed and period were in no summary before); the keys that were there are unchanged."""
    spec = lyapunov_spec(FIG8B, [(-0.5, -1.0)], 5, ensemble=2, offset=1e-4, seed=3)
    s = json.loads(export.dumps(lyapunov_spectrum(spec).summary()))
    assert s["spec"] == json.loads(export.dumps(spec.as_dict())) and s["spec"]["offset"] == 1e-4
    assert s["ensemble"] == {"size": 2, "ok": 2} and s["periods"] == 5
    # The method pinned as in test_a_drift_fit_of_a_spec_is_the_keyword_form.
    fit = ("fit", "--scene", "fig3", "--window", "200,210", "--degree", "0,2", "--ic", "0,8", "--method", "dop853")
    rc, out, err = run_cli(*fit, "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert d["spec"]["window"] == [200, 210] and d["spec"]["ics"] == [[0.0, 8.0]] and d["window"] == [200, 210]
    rc, out, err = run_cli("continue", "--scene", "fig10", "--param", "alpha", "--range=-0.35,-0.352",
                           "--from=-0.0959,-1.962", "--ds", "0.05", "--json")  # fmt: skip
    assert rc == 0, err
    d = json.loads(out)
    assert d["spec"]["seed"] == [-0.0959, -1.962] and d["spec"]["period"] == 1 and d["range"] == [-0.35, -0.352]


# --- the orbit diagram and basins take a spec too -------------------------------------------------------------


def test_an_orbit_diagram_of_a_spec_is_the_keyword_form() -> None:
    from explorer_core.analyses.bifurcation import DiagramSpec, bifurcation_diagram, diagram_spec

    vals = np.linspace(-0.40, -0.36, 5)
    kw = {"points": 16, "transient": 40, "ics": [(-0.5, -1.0)]}
    spec = diagram_spec(FIG10, "alpha", vals, **kw)
    assert isinstance(spec, DiagramSpec) and spec.sweeps == ("forward", "backward")
    assert pickle.loads(pickle.dumps(spec)).sweep.param == "alpha"
    a, b = bifurcation_diagram(spec), bifurcation_diagram(FIG10, "alpha", vals, **kw)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.status, b.status)
    with pytest.raises(TypeError, match="comes alone"):
        bifurcation_diagram(spec, points=3)
    assert diagram_spec(FIG10, "alpha", vals, seeding="fixed").sweeps == ("fixed",)


@pytest.mark.parametrize(
    ("kw", "needle"),
    [({"points": 0}, "points must be"), ({"transient": -1}, "transient must be"), ({"seeding": "random"}, "seeding"),
     ({"sweeps": ("up",)}, "sweeps must be"), ({"values": [NAN]}, "finite")],
)  # fmt: skip
def test_diagram_spec_names_each_bad_value(kw: dict[str, Any], needle: str) -> None:
    from explorer_core.analyses.bifurcation import diagram_spec

    values = kw.pop("values", [-0.4])
    with pytest.raises(ParameterError, match=needle):
        diagram_spec(FIG10, "alpha", values, **kw)


def test_basins_of_a_spec_is_the_keyword_form() -> None:
    from explorer_core.analyses.basins import basin_spec, basins

    box, grid = (-1.0, 0.5, -3.0, -1.0), (4, 3)
    spec = basin_spec(FIG10.with_(alpha=-0.36), box, grid, max_periods=400)
    a, b = basins(spec), basins(FIG10.with_(alpha=-0.36), box, grid, max_periods=400)
    np.testing.assert_array_equal(a.label, b.label)
    with pytest.raises(TypeError, match="comes alone"):
        basins(spec, box)


def test_the_cli_refuses_a_bad_diagram_or_basin_value_in_one_line() -> None:
    for argv in (
        [
            "bifurcation",
            "--scene",
            "fig10",
            "--param",
            "alpha",
            "--range=-0.4,-0.36",
            "--n-values",
            "3",
            "--sweeps",
            "up",
            "--json",
        ],
        ["basins", "--scene", "fig10", "--grid", "3,3", "--box=-1,0.5,-3,-1", "--cells", "5000,5", "--json"],
    ):
        rc, out, err = run_cli(*argv)  # fmt: skip
        assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, (rc, err)
