"""The app and the command line build the same spec for the same settings (issue 31: the settings shown are the
settings used). Each test runs an app tab on a page, takes the spec the tab handed the core, runs the command line
with the flags that say the same, takes its spec, and compares them as the results' JSON records them."""

from __future__ import annotations

import numpy as np
import pytest
from clirun import run_cli
from test_app_analyses import session as _session

from app import analyses
from app.runner import WARM
from explorer_core.analyses import regimes


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def _system_flags(p) -> list[str]:
    """The command line's flags for the system ``p`` (every value as the page holds it)."""
    return ["--inertia", ",".join(repr(v) for v in p.inertia), "--alpha", repr(p.alpha), "--g0", repr(p.g0), "--g1",
            repr(p.g1), "--g2", repr(p.g2), "--omega", repr(p.omega), "--t0", repr(p.t0)]  # fmt: skip


@pytest.mark.parametrize(("method", "accuracy"), [("auto", "plot"), ("dop853", "high")])
def test_a_charts_spec_is_the_command_lines(monkeypatch, method: str, accuracy: str) -> None:
    seen: dict[str, object] = {}
    real_iter = analyses.iter_chart
    monkeypatch.setattr(
        analyses, "iter_chart", lambda spec, **kw: seen.setdefault("app", spec) and real_iter(spec, **kw)
    )
    real_run = regimes.regime_chart
    monkeypatch.setattr(
        regimes, "regime_chart", lambda spec, **kw: seen.setdefault("cli", spec) and real_run(spec, **kw)
    )

    sess = _session("fig11")
    st = sess.state
    st.param.update(chart_grid=(3, 2), chart_periods=30, chart_transient=20, method=method, accuracy=accuracy)
    tab = analyses.ChartTab(sess)
    tab.figure()
    tab.run()
    app = seen["app"]
    q, r = (float(v) for v in st.analysis_ics()[0])
    numerics = ["--method", method, "--steps-per-period", str(st.steps_per_period)]
    numerics += ["--rtol", "1e-12"] if accuracy == "high" else []
    code, _, err = run_cli(
        "chart", *_system_flags(st.system()),
        "--x-param", st.chart_x, f"--x-range={st.chart_xrange[0]!r},{st.chart_xrange[1]!r}",
        "--y-param", st.chart_y, f"--y-range={st.chart_yrange[0]!r},{st.chart_yrange[1]!r}", "--grid", "3,2",
        f"--ic={q!r},{r!r}", "--transient", "20", "--periods", "30", "--p-max", str(app.p_max), *numerics, "--json",
    )  # fmt: skip
    assert code == 0, err
    cli = seen["cli"]
    assert app.as_dict() == cli.as_dict()
    assert np.array_equal(app.x_values, cli.x_values) and np.array_equal(app.y_values, cli.y_values)
    assert app.numerics.method == ("vern9" if accuracy == "high" and method == "auto" else
                                   "dop853")  # fmt: skip
    assert f"numerics: {app.numerics.method} at rtol {app.numerics.rtol:.3g}" in "\n".join(tab.view["result"])


def test_an_orbit_diagrams_spec_is_the_command_lines(monkeypatch) -> None:
    from explorer_core.analyses import bifurcation
    from explorer_core.analyses.bifurcation import DIAGRAM_PLOT_BOUND, DIAGRAM_PLOT_RTOL, diagram_spec

    seen: dict[str, object] = {}
    real = bifurcation.bifurcation_diagram

    def app_side(*a, progress=None, cancel=None, executor=None, **kw):  # the tab's keyword call, as its spec
        seen["app"] = diagram_spec(*a, **kw)
        return real(seen["app"], progress=progress, cancel=cancel, executor=executor)

    monkeypatch.setattr(analyses, "bifurcation_diagram", app_side)
    monkeypatch.setattr(bifurcation, "bifurcation_diagram", lambda spec, **kw: seen.setdefault("cli", spec)
                        and real(spec, **kw))  # fmt: skip
    sess = _session("fig10")
    st = sess.state
    st.param.update(bif_values=5, bif_points=10, bif_transient=30, bif_range=(-0.42, -0.40), bif_orbits=False)
    analyses.BifurcationTab(sess).run()
    app = seen["app"]
    ics = [f"--ic={float(q)!r},{float(r)!r}" for q, r in np.asarray(app.sweep.ics)]
    code, _, err = run_cli(
        "bifurcation", *_system_flags(st.system()),
        "--param", st.bif_param, "--range=-0.42,-0.4", "--n-values", "5", "--points", "10", "--transient", "30",
        "--seeding", st.bif_seeding, *ics, "--method", st.method, "--steps-per-period", str(st.steps_per_period),
        "--rtol", repr(DIAGRAM_PLOT_RTOL), "--bound", repr(DIAGRAM_PLOT_BOUND), "--json",
    )  # fmt: skip
    assert code == 0, err
    cli = seen["cli"]
    a, c = app.sweep, cli.sweep
    assert (a.params, a.param, a.transient, a.n_points, a.numerics, a.newton) == (
        c.params, c.param, c.transient, c.n_points, c.numerics, c.newton)  # fmt: skip
    assert np.array_equal(a.values, c.values) and np.array_equal(a.ics, c.ics)
    assert (app.seeding, app.sweeps) == (cli.seeding, cli.sweeps)


def _numerics_flags(n) -> list[str]:
    """The command line's flags for the numerics ``n`` the page chose (its Method and Accuracy: "auto" where the
    rule chose ``n.method``, as the page's Method said: the inner maps derived from it choose again then)."""
    return ["--method", "auto" if n.by_rule else n.method, "--rtol", repr(n.rtol), "--atol", repr(n.atol),
            "--steps-per-period", str(n.steps_per_period), "--bound", repr(n.bound), "--max-steps",
            str(n.max_steps)]  # fmt: skip


class _Captured(BaseException):  # not an Exception: the command line's error path lets it through
    pass


def _cli_spec(monkeypatch, command: str, *flags: str, run: bool = True):
    """The spec the command line hands its analysis' runner (the registry's) for ``bilimovich COMMAND FLAGS``
    (``run=False``: taken, and the run stopped there)."""
    import functools
    import importlib

    from explorer_core.registry import by_command

    a = by_command(command)
    module = importlib.import_module(a.module)
    real = getattr(module, a.run)
    seen = []

    @functools.wraps(real)
    def spy(spec, *args, **kw):
        seen.append(spec)
        if not run:
            raise _Captured
        return real(spec, *args, **kw)

    monkeypatch.setattr(module, a.run, spy)
    try:
        code, _, err = run_cli(command, *flags, "--json")
        assert code == 0, err
    except _Captured:
        pass
    finally:
        monkeypatch.setattr(module, a.run, real)
    return seen[0]


@pytest.mark.parametrize(("method", "accuracy", "render"),
                         [("auto", "plot", "points"), ("dop853", "high", "points"), ("auto", "plot", "density"),
                          ("vern9", "high", "density")])  # fmt: skip
def test_a_sections_spec_is_the_command_lines(monkeypatch, method: str, accuracy: str, render: str) -> None:
    sess = _session("fig8B")
    st = sess.state
    st.param.update(n_random=6, seed=3, periods=25, transient=4, method=method, accuracy=accuracy, render=render,
                    clicked=[(0.25, -0.5)])  # fmt: skip
    app = st.section_request().spec
    ics = ["--random", "6", "--seed", "3", "--ic=0.25,-0.5", "--periods", "25", "--transient", "4"]
    if render == "points":
        box = ",".join(repr(float(v)) for v in st.box)
        cli = _cli_spec(monkeypatch, "section", *_system_flags(st.system()), *ics, f"--box={box}",
                        *_numerics_flags(app.numerics))  # fmt: skip
    else:
        box = ",".join(repr(float(v)) for v in st.density_box())
        view = ",".join(repr(float(v)) for v in app.view)
        cli = _cli_spec(monkeypatch, "density", *_system_flags(st.system()), *ics, f"--box={box}", f"--view={view}",
                        "--pixels", ",".join(map(str, app.pixels)), *_numerics_flags(app.numerics))  # fmt: skip
    assert type(app) is type(cli)
    assert app.as_dict() == cli.as_dict()
    assert np.array_equal(app.ics, cli.ics) and app.ics.shape == (7, 2)
    assert (app.numerics.rtol == 1e-12) == (accuracy == "high")  # the page's Accuracy reached the spec
    assert method == "auto" or app.numerics.method == method  # and its Method


FLIP = (-0.0377, -2.3979)  # Fig. 8B's flip saddle


def _page(query: dict):
    from jobs import Jobs

    from app.page import Page

    jobs = Jobs()
    page = Page({"scene": "fig8B", "n": "2", "periods": "5", **query}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page


@pytest.mark.parametrize(("method", "accuracy"), [("auto", "plot"), ("dop853", "high")])
def test_the_orbit_and_manifold_layers_specs_are_the_command_lines(monkeypatch, method: str, accuracy: str) -> None:
    page = _page({"orb": f"{FLIP[0]},{FLIP[1]};0.5,-1", "orb_n": "2", "man": f"{FLIP[0]},{FLIP[1]},1",
                  "man_len": "2", "method": method, "accuracy": accuracy})  # fmt: skip
    system = _system_flags(page.state.system())
    orbits = page.session.layer("orbits")
    app = orbits.spec(orbits.inputs())
    cli = _cli_spec(monkeypatch, "orbits", *system, f"--seed={FLIP[0]!r},{FLIP[1]!r}", "--seed=0.5,-1",
                    "--max-period", "2", *_numerics_flags(app.numerics))  # fmt: skip
    assert app == cli and app.as_dict() == cli.as_dict()
    man = page.session.layer("manifolds")
    inputs = man.inputs()
    app = man.spec(inputs, inputs.saddles[0][:2], inputs.saddles[0][2])
    view = ",".join(repr(float(v)) for v in inputs.view)
    cli = _cli_spec(monkeypatch, "manifolds", *system, f"--orbit={FLIP[0]!r},{FLIP[1]!r}", "--period", "1",
                    "--length", "2", f"--view={view}", "--pixels", ",".join(map(str, app.pixels)),
                    *_numerics_flags(app.numerics))  # fmt: skip
    assert app == cli and app.as_dict() == cli.as_dict()
    assert (app.numerics.rtol == 1e-12) == (accuracy == "high")
    # Newton finds the saddle on the same map in both (at least as accurate as an orbit's)
    assert app.saddle_numerics == cli.saddle_numerics and app.saddle_numerics.rtol <= 1e-12


@pytest.mark.parametrize(("kind", "accuracy"), [("instantaneous", "plot"), ("per-period", "high")])
def test_the_tprime_layers_spec_is_the_command_lines(monkeypatch, kind: str, accuracy: str) -> None:
    page = _page({"tprime": "period" if kind == "per-period" else "inst", "accuracy": accuracy})
    layer = page.session.layer("tprime")
    assert page.state.tprime_kind == kind
    app = layer.spec(layer.inputs())
    st = page.state
    flags = [
        f"--q-range={st.q_range[0]!r},{st.q_range[1]!r}",
        f"--r-range={st.r_range[0]!r},{st.r_range[1]!r}",
        "--grid",
        str(app.grid),
        *(["--per-period"] if app.per_period else []),
        *_numerics_flags(app.numerics),
    ]
    cli = _cli_spec(monkeypatch, "tprime", *_system_flags(st.system()), *flags)
    assert app == cli and app.as_dict() == cli.as_dict()
    assert app.per_period == (kind == "per-period")


def test_the_tracks_layers_spec_is_the_command_lines(monkeypatch) -> None:
    page = _page({})
    layer = page.session.layer("tracks")
    app = layer.spec(layer.inputs())
    cli = _cli_spec(monkeypatch, "critical", *_system_flags(page.state.system()), "--track", "--n-t", str(app.n_t))
    assert app == cli and app.as_dict() == cli.as_dict() and app.track


@pytest.mark.parametrize("accuracy", ["plot", "high"])
def test_the_body_views_spec_is_the_command_lines(monkeypatch, accuracy: str) -> None:
    page = _page({"scene": "fig1C", "n": "4", "periods": "30", "body": "1", "accuracy": accuracy})
    inputs = page.body.inputs
    assert inputs is not None
    app = page.body.spec(inputs)
    flags = [f"--ic={inputs.q!r},{inputs.r!r}", "--periods", str(app.periods), "--samples", str(app.samples)]
    cli = _cli_spec(monkeypatch, "body", *_system_flags(page.state.system()), *flags, *_numerics_flags(app.numerics))
    assert app == cli and app.as_dict() == cli.as_dict()


@pytest.mark.parametrize(("method", "accuracy"), [("auto", "plot"), ("dop853", "high")])
def test_the_orbit_diagrams_continuation_is_the_command_lines(monkeypatch, method: str, accuracy: str) -> None:
    seen = []
    real = analyses.continue_from_seeds
    monkeypatch.setattr(analyses, "continue_from_seeds", lambda spec, **kw: seen.append(spec) or real(spec, **kw))
    sess = _session("fig10")
    st = sess.state
    st.param.update(bif_values=4, bif_points=8, bif_transient=200, bif_range=(-0.36, -0.355), bif_orbits=True,
                    method=method, accuracy=accuracy)  # fmt: skip
    tab = analyses.BifurcationTab(sess)
    tab.run()
    (spec,) = seen
    assert (spec.numerics.rtol, spec.numerics.method) == (1e-12, "vern9" if method == "auto" else method)
    assert f"continuation numerics: {spec.numerics.method} at rtol 1e-12" in "\n".join(tab.view["result"])
    # each orbit found is continued as `bilimovich continue` continues it from the same point
    q, r = -0.5, -1.0
    app = spec.for_orbit((q, r), 1)
    cli = _cli_spec(monkeypatch, "continue", *_system_flags(st.system()), "--param", "alpha", "--range=-0.36,-0.355",
                    f"--from={q!r},{r!r}", "--period", "1", "--switch", "--max-points", "30",
                    *_numerics_flags(app.numerics))  # fmt: skip
    assert app == cli.__class__(**{**cli.__dict__, "options": app.options})  # the CLI's --max-points aside


@pytest.mark.parametrize(("method", "accuracy"), [("auto", "plot"), ("dop853", "high")])
def test_the_basins_layers_spec_is_the_command_lines(monkeypatch, method: str, accuracy: str) -> None:
    page = _page({"basins": "1", "bas_n": "12", "method": method, "accuracy": accuracy})
    layer = page.session.layer("basins")
    app = layer.spec(layer.inputs())
    box = ",".join(repr(float(v)) for v in app.box)
    cli = _cli_spec(monkeypatch, "basins", *_system_flags(page.state.system()), f"--box={box}", "--grid", "12,12",
                    *_numerics_flags(app.numerics), run=False)  # fmt: skip
    assert app.as_dict() == cli.as_dict()
    assert (app.numerics.rtol == 1e-12) == (accuracy == "high") and (method == "auto" or app.numerics.method == method)
    assert f"numerics: {app.numerics.method}" in layer.status() or not layer.status().startswith("basins on")
