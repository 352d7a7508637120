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
    p = st.system()
    code, _, err = run_cli(
        "chart", "--inertia", ",".join(repr(v) for v in p.inertia), "--alpha", repr(p.alpha), "--g0", repr(p.g0),
        "--g1", repr(p.g1), "--g2", repr(p.g2), "--omega", repr(p.omega), "--t0", repr(p.t0),
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
    p = st.system()
    ics = [f"--ic={float(q)!r},{float(r)!r}" for q, r in np.asarray(app.sweep.ics)]
    code, _, err = run_cli(
        "bifurcation", "--inertia", ",".join(repr(v) for v in p.inertia), "--alpha", repr(p.alpha), "--g0",
        repr(p.g0), "--g1", repr(p.g1), "--g2", repr(p.g2), "--omega", repr(p.omega), "--t0", repr(p.t0),
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
