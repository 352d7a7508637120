"""Analysis tabs: Lyapunov spectrum, bifurcation diagram, chart of regimes.

Each tab takes the session's current system, runs one analysis from
:mod:`explorer_core` on the session's :class:`~app.runner.Runner` (so a newer run
or a closed tab cancels it), shows progress, can be stopped, and draws the
result. Work per run is bounded (``LIMITS``). No numerics here.
"""

from __future__ import annotations

import html
import io
import math
import os
import tempfile
import time
from typing import Any

import numpy as np
import panel as pn
from bokeh.models import ColumnDataSource, LinearColorMapper
from bokeh.palettes import Category10, Category20
from bokeh.plotting import figure

from app.controller import ExplorerSession
from app.views import BACKEND, ERROR_STYLE
from explorer_core.analyses.bifurcation import bifurcation_diagram
from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.analyses.regimes import REGIMES, chart_spec, iter_chart
from explorer_core.analyses.sweeps import sweep_values
from explorer_core.parallel.cluster import SchedulerError, executor_for, scheduler_from_env
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import INERTIA_NAMES, ParameterError
from explorer_core.warm import warm_all

SWEEPABLE = ["alpha", *INERTIA_NAMES, "g0", "g1", "g2", "omega"]
LIMITS = {"lyap_periods": 20000, "ensemble": 16, "bif_values": 400, "bif_points": 400, "transient": 5000}
LIMITS |= {"grid": 120, "chart_periods": 3000}
BIFURCATION_HELP = (
    "Orbit diagram: for each value a transient, then section points. Continuation carries the state from "
    "value to value, forward (blue) and backward (orange) to expose hysteresis; escaped trajectories are "
    "counted, not drawn."
)
CHART_HELP = (
    "Chart of dynamical regimes: each pixel's attractor classified by the return of its section point "
    "(period p), its largest Lyapunov exponent (chaos) or escape. A coarse grid comes first, then "
    "refinement. **Click a pixel** to set those two parameters and see that section."
)
#: Minimum time between two partial pictures of a running analysis (seconds).
REFRESH = 0.25


def _fig(**kw: Any):
    f = figure(tools="pan,wheel_zoom,box_zoom,reset,save", output_backend=BACKEND, sizing_mode="stretch_width", **kw)
    f.toolbar.logo = None
    return f


def _floats(text: str, n: int, name: str) -> list[float]:
    try:
        vals = [float(v) for v in str(text).split(",")]
    except ValueError:
        raise ParameterError(f"{name} must be {n} comma-separated numbers, got {text[:40]!r}") from None
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ParameterError(f"{name} must be {n} finite comma-separated numbers, got {text[:40]!r}")
    return vals


class _Tab:
    """Shared plumbing: a message line, a progress bar, Run and Stop."""

    channel = "analysis"

    def __init__(self, session: ExplorerSession) -> None:
        self.session = session
        self.message = pn.pane.Str("", sizing_mode="stretch_width", css_classes=[f"{self.channel}-status"])
        self.error = pn.pane.HTML("", visible=False, sizing_mode="stretch_width", css_classes=[f"{self.channel}-error"])
        self.progress = pn.indicators.Progress(value=0, max=100, sizing_mode="stretch_width", visible=False)
        self.run_button = pn.widgets.Button(label="Run", button_type="primary", css_classes=[f"{self.channel}-run"])
        self.stop_button = pn.widgets.Button(label="Stop", button_type="warning")
        self.run_button.on_click(lambda e: self.run())
        self.stop_button.on_click(lambda e: self.stop())

    def fail(self, msg: str) -> None:
        self.error.object = f'<div style="{ERROR_STYLE}">{html.escape(msg)}</div>'
        self.error.visible = True

    def ok(self) -> None:
        self.error.visible = False

    def stop(self) -> None:
        self.session.runner.cancel(self.channel)
        self.progress.visible = False
        self.message.object += " — stopped"

    def set_progress(self, done: int, total: int, text: str) -> None:
        self.progress.visible = done < total
        self.progress.value = int(100 * done / max(1, total))
        self.message.object = text

    def run(self) -> None:
        raise NotImplementedError


class LyapunovTab(_Tab):
    channel = "lyapunov"

    def __init__(self, session: ExplorerSession) -> None:
        super().__init__(session)
        self.ic = pn.widgets.TextInput(label="Initial condition q,r (blank: selected trajectory)", value="")
        self.transient = pn.widgets.IntInput(label="Transient periods", value=200, start=0, end=LIMITS["transient"])
        self.periods = pn.widgets.IntInput(
            label="Periods measured", value=1000, start=10, end=LIMITS["lyap_periods"], css_classes=["lyapunov-periods"]
        )
        self.ensemble = pn.widgets.IntInput(label="Ensemble members", value=4, start=1, end=LIMITS["ensemble"])
        self.source = ColumnDataSource({"k": [], "l1": [], "l2": []}, name="lyapunov_source")
        f = _fig(height=320, x_axis_label="periods measured", y_axis_label="running estimate (per unit time)")
        f.line("k", "l1", source=self.source, color=Category10[3][0], legend_label="Λ1")
        f.line("k", "l2", source=self.source, color=Category10[3][1], legend_label="Λ2")
        f.legend.location = "bottom_right"
        self.fig = f
        self.result = pn.pane.Markdown("", sizing_mode="stretch_width", css_classes=["lyapunov-result"])

    def panel(self) -> pn.Column:
        intro = (
            "Exponents of the `(q, r)` flow from the variational equations with the exact Jacobian, "
            "re-orthonormalised at each section time; `Λ3 = 0` is the time direction. The check "
            "`Λ1 + Λ2 = ⟨dQ/dq + dR/dr⟩` must hold."
        )
        return pn.Column(
            pn.pane.Markdown(intro),
            pn.Row(self.ic, self.transient, self.periods, self.ensemble),
            pn.Row(self.run_button, self.stop_button),
            self.error,
            self.progress,
            self.message,
            self.result,
            self.fig,
            sizing_mode="stretch_width",
        )

    def _ic(self) -> tuple[float, float]:
        if self.ic.value.strip():
            q, r = _floats(self.ic.value, 2, "initial condition")
            return q, r
        traj, k, q, r = self.session.data()
        sel = traj == self.session.state.selected
        if sel.any():
            j = np.flatnonzero(sel)[np.argmax(k[sel])]
            return float(q[j]), float(r[j])
        ics = self.session.state.initial_conditions()
        return float(ics[0, 0]), float(ics[0, 1])

    def run(self) -> None:
        try:
            params = self.session.state.system()
            q, r = self._ic()
            m = int(self.ensemble.value)
            transient, periods = int(self.transient.value), int(self.periods.value)
            if not (1 <= m <= LIMITS["ensemble"] and 10 <= periods <= LIMITS["lyap_periods"]):
                raise ParameterError(f"ensemble 1..{LIMITS['ensemble']}, periods 10..{LIMITS['lyap_periods']}")
            if not 0 <= transient <= LIMITS["transient"]:
                raise ParameterError(f"transient must be 0..{LIMITS['transient']}")
        except (ParameterError, TypeError) as exc:
            self.fail(str(exc))
            return
        self.ok()
        # Members start within 1e-3 of the IC; the transient brings them onto the attractor.
        rng = np.random.default_rng(0)
        ics = np.array([(q, r)] + [(q + 1e-3 * a, r + 1e-3 * b) for a, b in rng.normal(size=(m - 1, 2))])
        numerics = Numerics(method="dop853", rtol=1e-10, atol=1e-10, bound=1e4)
        history: list[tuple[int, float, float]] = []
        self.session.runner.ui(lambda: setattr(self.source, "data", {"k": [], "l1": [], "l2": []}))
        self.set_progress(0, 1, "computing…")

        def job(cancelled, emit) -> None:
            last = [0.0]

            def progress(p) -> None:
                if p.phase == "measure" and p.done_periods:
                    ok = p.status == 0
                    est = p.running[ok].mean(axis=0) if ok.any() else np.zeros(2)
                    history.append((p.done_periods, float(est[0]), float(est[1])))
                now = time.perf_counter()
                if now - last[0] > REFRESH:
                    last[0] = now
                    rows = list(history)
                    emit(lambda: self._partial(rows, p.phase, p.done_periods, p.total_periods))

            res = lyapunov_spectrum(params, ics, periods, transient=transient, numerics=numerics,
                                    progress=progress, cancel=cancelled)  # fmt: skip
            emit(lambda: self._done(res, list(history)))

        self.session.runner.start(self.channel, job)

    def _partial(self, rows, phase: str, done: int, total: int) -> None:
        if rows:
            k, l1, l2 = zip(*rows, strict=True)
            self.source.data = {"k": list(k), "l1": list(l1), "l2": list(l2)}
        self.set_progress(done, total, f"{phase}: {done}/{total} periods")

    def _done(self, res, rows) -> None:
        self._partial(rows, "measure", res.periods, res.periods)
        mean, spread = res.mean(), res.spread()
        labels = res.status_labels()
        status = {lab: labels.count(lab) for lab in sorted(set(labels))}
        ky = res.kaplan_yorke()
        div = float(np.mean(res.divergence_mean[res.ok])) if res.ok.any() else float("nan")
        lines = [
            f"**Λ1 = {mean[0]:.4f} ± {spread[0]:.4f}, Λ2 = {mean[1]:.4f} ± {spread[1]:.4f}, Λ3 = 0** "
            f"(per unit time; per iteration ×T = {mean[0] * res.period:.4f}, {mean[1] * res.period:.4f})",
            f"Kaplan–Yorke dimension D = {ky:.4f}" if ky == ky else "Kaplan–Yorke dimension: not applicable",
            f"check: Λ1 + Λ2 = {mean.sum():.6f}, time-averaged divergence = {div:.6f}",
            f"members: {status}; {res.elapsed_s:.2f} s" + ("" if res.completed else " (stopped)"),
        ]
        self.result.object = "  \n".join(lines)
        self.progress.visible = False
        self.message.object = "done" if res.completed else "stopped"


class BifurcationTab(_Tab):
    channel = "bifurcation"

    def __init__(self, session: ExplorerSession) -> None:
        super().__init__(session)
        self.param = pn.widgets.Select(label="Parameter", options=SWEEPABLE, value="alpha")
        self.range = pn.widgets.TextInput(label="Range lo,hi", value="")
        self.n_values = pn.widgets.IntInput(label="Values", value=120, start=2, end=LIMITS["bif_values"])
        self.points = pn.widgets.IntInput(label="Points per value", value=80, start=1, end=LIMITS["bif_points"])
        self.transient = pn.widgets.IntInput(label="Transient", value=300, start=0, end=LIMITS["transient"])
        self.seeding = pn.widgets.RadioButtonGroup(label="Seeding", options=["continuation", "fixed"],
                                                   value="continuation")  # fmt: skip
        self.coord = pn.widgets.RadioButtonGroup(label="Plot", options=["q", "r"], value="q")
        self.source = ColumnDataSource({"x": [], "y": [], "c": []}, name="bifurcation_source")
        f = _fig(height=420, x_axis_label="parameter", y_axis_label="q_k")
        f.scatter("x", "y", source=self.source, size=1.6, line_color=None,
                  fill_color={"field": "c", "transform": LinearColorMapper(palette=[Category10[3][0], Category10[3][1]],
                                                                          low=0, high=1)})  # fmt: skip
        self.fig = f
        self._data = None
        self.coord.param.watch(lambda e: self.session.runner.ui(self._draw), "value")
        sid = session.state.scene
        if sid != "custom" and "sweep" in get_scene(sid).extra:
            sw = get_scene(sid).extra["sweep"]
            self.param.value = sw["param"]
            self.range.value = f"{sw['range'][0]},{sw['range'][1]}"

    def panel(self) -> pn.Column:
        return pn.Column(
            pn.pane.Markdown(BIFURCATION_HELP),
            pn.Row(self.param, self.range, self.n_values, self.points, self.transient),
            pn.Row(self.seeding, self.coord, self.run_button, self.stop_button),
            self.error,
            self.progress,
            self.message,
            self.fig,
            sizing_mode="stretch_width",
        )

    def run(self) -> None:
        st = self.session.state
        try:
            params = st.system()
            name = self.param.value
            current = getattr(st, name)
            if self.range.value.strip():
                lo, hi = _floats(self.range.value, 2, "range")
            else:
                lo, hi = current - 0.05, current + 0.05
            if not lo < hi:
                raise ParameterError(f"range needs lo < hi, got {lo}, {hi}")
            n, pts, tr = int(self.n_values.value), int(self.points.value), int(self.transient.value)
            ok = 2 <= n <= LIMITS["bif_values"] and 1 <= pts <= LIMITS["bif_points"]
            if not (ok and 0 <= tr <= LIMITS["transient"]):
                raise ParameterError(
                    f"values 2..{LIMITS['bif_values']}, points 1..{LIMITS['bif_points']}, "
                    f"transient 0..{LIMITS['transient']}"
                )
            ics = st.initial_conditions()[:4]
            scheduler = scheduler_from_env()  # BILIMOVICH_SCHEDULER: a Dask cluster runs the sweep
        except (ParameterError, TypeError) as exc:
            self.fail(str(exc))
            return
        self.ok()
        values = sweep_values((lo, hi), n)
        self.set_progress(0, n, f"computing on {scheduler}…" if scheduler else "computing…")
        seeding = self.seeding.value
        numerics = Numerics(method="dop853", rtol=1e-9, atol=1e-9, bound=1e3)

        def job(cancelled, emit) -> None:
            last = [0.0]

            def progress(p) -> None:
                now = time.perf_counter()
                if now - last[0] > REFRESH:
                    last[0] = now
                    emit(lambda: self.set_progress(p.done, p.total, f"{p.done}/{p.total} values, {p.elapsed_s:.1f} s"))

            try:
                d = bifurcation_diagram(params, name, values, points=pts, transient=tr, seeding=seeding, ics=ics,
                                        numerics=numerics, progress=progress, cancel=cancelled,
                                        executor=executor_for(scheduler, warm_all))  # fmt: skip
            except SchedulerError as exc:  # unreachable or unusable cluster: say so in the tab
                emit(lambda msg=str(exc): self.set_progress(1, 1, "not computed") or self.fail(msg))
                return
            emit(lambda: self._done(d))

        self.session.runner.start(self.channel, job)

    def _done(self, d) -> None:
        self._data = d
        self._draw()
        counts = d.status_counts()
        self.progress.visible = False
        summary = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in counts.items())
        self.message.object = f"{len(d.values)} values, {d.elapsed_s:.1f} s, trajectories: {summary}" + (
            "" if d.completed else " (stopped)"
        )

    def _draw(self) -> None:
        d = self._data
        if d is None:
            return
        s, v, x, i, k, q, r = d.long()
        y = q if self.coord.value == "q" else r
        self.source.data = {"x": x, "y": y, "c": s.astype(float)}
        self.fig.xaxis.axis_label = d.param
        self.fig.yaxis.axis_label = f"{self.coord.value}_k"


# Colours of the chart: period p (1..16), then the other regimes.
_PERIOD_COLORS = list(Category20[20][:16])
_OTHER = {"quasi_periodic": "#bdbdbd", "chaotic": "#000000", "escaped": "#ffffff", "failed": "#ff00ff",
          "invalid": "#f4cccc"}  # fmt: skip
_NOT_DONE = "#eeeeee"


class ChartTab(_Tab):
    channel = "chart"

    def __init__(self, session: ExplorerSession) -> None:
        super().__init__(session)
        self.x_param = pn.widgets.Select(label="x parameter", options=SWEEPABLE, value="alpha")
        self.x_range = pn.widgets.TextInput(label="x range", value="-0.6,-0.4")
        self.y_param = pn.widgets.Select(label="y parameter", options=SWEEPABLE, value="I11")
        self.y_range = pn.widgets.TextInput(label="y range", value="1,2")
        self.grid = pn.widgets.TextInput(label="grid NX,NY", value="40,30", css_classes=["chart-grid"])
        self.periods = pn.widgets.IntInput(
            label="Periods", value=300, start=10, end=LIMITS["chart_periods"], css_classes=["chart-periods"]
        )
        self.transient = pn.widgets.IntInput(
            label="Transient", value=300, start=0, end=LIMITS["transient"], css_classes=["chart-transient"]
        )
        self.mapper = LinearColorMapper(palette=[_NOT_DONE, *_PERIOD_COLORS, *_OTHER.values()], low=-0.5,
                                        high=len(_PERIOD_COLORS) + len(_OTHER) + 0.5)  # fmt: skip
        self.source = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []}, name="chart_source")
        f = _fig(height=460, x_axis_label="alpha", y_axis_label="I11")
        f.image(image="image", x="x", y="y", dw="dw", dh="dh", source=self.source, color_mapper=self.mapper)
        self.fig = f
        self.chart = None
        legend = " ".join(f'<span style="background:{c}">&nbsp;&nbsp;&nbsp;</span> {p}' for p, c in
                          zip(range(1, 17), _PERIOD_COLORS, strict=True))  # fmt: skip
        legend += " &nbsp; " + " ".join(
            f'<span style="background:{c};border:1px solid #999">&nbsp;&nbsp;&nbsp;</span> {k.replace("_", "-")}'
            for k, c in _OTHER.items()
        )
        self.legend = pn.pane.HTML(f"<small>period of the cycle: {legend}</small>", sizing_mode="stretch_width")
        self.download = pn.widgets.FileDownload(callback=self._npz, filename="chart.npz", label="Download chart NPZ")
        from bokeh.events import Tap

        f.on_event(Tap, self._on_tap)
        sid = session.state.scene
        if sid != "custom" and "chart" in get_scene(sid).extra:
            c = get_scene(sid).extra["chart"]
            self.x_param.value, self.y_param.value = c["x_param"], c["y_param"]
            self.x_range.value = ",".join(str(v) for v in c["x_range"])
            self.y_range.value = ",".join(str(v) for v in c["y_range"])

    def panel(self) -> pn.Column:
        return pn.Column(
            pn.pane.Markdown(CHART_HELP),
            # Wraps instead of running off the right edge on a narrow window (or a projector).
            pn.FlexBox(self.x_param, self.x_range, self.y_param, self.y_range, self.grid, self.periods, self.transient),
            pn.Row(self.run_button, self.stop_button, self.download),
            self.error,
            self.progress,
            self.message,
            self.fig,
            self.legend,
            sizing_mode="stretch_width",
        )

    def run(self) -> None:
        st = self.session.state
        try:
            params = st.system()
            xr = _floats(self.x_range.value, 2, "x range")
            yr = _floats(self.y_range.value, 2, "y range")
            nx, ny = (int(v) for v in _floats(self.grid.value, 2, "grid"))
            if not (2 <= nx <= LIMITS["grid"] and 2 <= ny <= LIMITS["grid"]):
                raise ParameterError(f"grid must be between 2 and {LIMITS['grid']} per axis, got {nx},{ny}")
            periods = int(self.periods.value)
            spec = chart_spec(params, self.x_param.value, xr, self.y_param.value, yr, (nx, ny),
                              ics=st.initial_conditions()[:1], transient=int(self.transient.value),
                              periods=periods, p_max=max(1, min(16, (periods - 1) // 2)))  # fmt: skip
            scheduler = scheduler_from_env()  # BILIMOVICH_SCHEDULER: tiles run on a Dask cluster
        except (ParameterError, TypeError, ValueError) as exc:
            self.fail(str(exc))
            return
        self.ok()
        labels = (self.x_param.value, self.y_param.value)
        self.session.runner.ui(lambda: self._label(*labels))
        self.set_progress(0, 1, f"computing on {scheduler}…" if scheduler else "computing…")

        def job(cancelled, emit) -> None:
            last = [0.0]
            upd = None
            try:
                for upd in iter_chart(spec, cancel=cancelled, executor=executor_for(scheduler, warm_all)):
                    now = time.perf_counter()
                    if now - last[0] > REFRESH:
                        last[0] = now
                        snap = upd.chart.filled()
                        emit(lambda c=snap, u=upd: self._show(c, u.done_tiles, u.total_tiles))
            except SchedulerError as exc:  # unreachable or unusable cluster: say so in the tab
                emit(lambda msg=str(exc): self.set_progress(1, 1, "not computed") or self.fail(msg))
                return
            if upd is not None:
                final = upd.chart
                emit(lambda: self._show(final, upd.done_tiles, upd.total_tiles, final=True))

        self.session.runner.start(self.channel, job)

    def _label(self, x: str, y: str) -> None:
        self.fig.xaxis.axis_label, self.fig.yaxis.axis_label = x, y

    def _show(self, chart, done: int, total: int, final: bool = False) -> None:
        self.chart = chart
        code = chart.code()[..., 0]
        idx = np.zeros(code.shape)
        per = code > 0
        idx[per] = np.minimum(code[per], len(_PERIOD_COLORS))
        for n, name in enumerate(_OTHER):
            idx[code == -REGIMES.index(name)] = len(_PERIOD_COLORS) + 1 + n
        idx[~chart.computed] = 0
        spec = chart.spec
        xs, ys = np.asarray(spec.x_values), np.asarray(spec.y_values)
        dx = (xs[-1] - xs[0]) / max(1, xs.size - 1)
        dy = (ys[-1] - ys[0]) / max(1, ys.size - 1)
        self.source.data = {
            "image": [idx],
            "x": [xs[0] - dx / 2],
            "y": [ys[0] - dy / 2],
            "dw": [xs[-1] - xs[0] + dx],
            "dh": [ys[-1] - ys[0] + dy],
        }
        counts = chart.counts() if final else {}
        summary = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in counts.items())
        self.set_progress(done, total, f"{done}/{total} tiles" + (f" — pixels: {summary}" if summary else ""))

    def _on_tap(self, event) -> None:
        """A click on a pixel sets those two parameters; the section tab recomputes."""
        if self.chart is None or event.x is None:
            return
        spec = self.chart.spec
        st = self.session.state
        try:
            st.param.update(**{spec.x_param: float(event.x), spec.y_param: float(event.y), "scene": "custom"})
        except Exception as exc:  # a click outside the valid region: keep the state, say why
            self.fail(str(exc))

    def _npz(self) -> io.BytesIO:
        if self.chart is None:
            return io.BytesIO(b"")
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "chart.npz")
            self.chart.to_npz(path)
            with open(path, "rb") as fh:
                return io.BytesIO(fh.read())
