"""Speed vs accuracy tab: work-precision diagrams (error against time per trajectory, log-log).

Two sources of data, both produced by :mod:`explorer_core.studies.bench` (no numerics here):

* **Measure** runs a small benchmark on the session's current system and initial condition (a few
  methods and tolerances, a short horizon; a reference from ``solve_ivp`` at 3e-14, cached) on the
  session's :class:`~app.runner.Runner`, with progress and Stop.
* The latest full ``bilimovich bench`` run, read from ``$BILIMOVICH_BENCH_RESULTS`` or the file
  the command leaves in the cache (:func:`explorer_core.studies.bench.latest_path`): one diagram per case.

Timings measured in a shared server are indicative; the command line's are the measured ones.
"""

from __future__ import annotations

import html
import math
import os
import time
from typing import Any

import numpy as np
import panel as pn
from bokeh.models import ColumnDataSource, HoverTool, Span
from bokeh.plotting import figure

from app.controller import ExplorerSession
from app.views import ERROR_STYLE
from explorer_core.studies import bench
from explorer_core.system.params import ParameterError

#: Label of the dataset measured in this session.
MEASURED = "this system (Measure)"
LATEST = "latest bench run"
#: Longest horizon the Measure button accepts (periods).
MAX_PERIODS = 500
REFRESH = 0.25
COLOURS = bench.LINE_COLOURS
HELP = (
    "Error against an independent reference (`solve_ivp` DOP853 at 3e-14, cross-checked) over the wall "
    "time per trajectory, for this project's RK4, DP5 and DOP853 and for `solve_ivp`. Lower left is better. "
    "On chaotic orbits the error is measured only up to the horizon where perturbations have grown 1000-fold. "
    "**Measure** runs a small benchmark on the current system; full results come from `bilimovich bench`."
)


def _lines(data: dict[str, Any], case: str) -> tuple[dict[str, list], dict[str, list], dict[str, list]]:
    """Bokeh columns (solid lines, dashed lines, points) of one case of a bench.json dict."""
    series: dict[str, list[dict[str, Any]]] = {}
    for row in data["rows"]:
        if row["case"] == case:
            series.setdefault(row["series"], []).append(row)
    solid: dict[str, list] = {"xs": [], "ys": [], "color": [], "label": []}
    dashed: dict[str, list] = {"xs": [], "ys": [], "color": [], "label": []}
    pts: dict[str, list] = {"x": [], "y": [], "color": [], "label": [], "setting": [], "status": []}
    for name, rows in series.items():  # rows in setting order, loose to tight
        colour = COLOURS.get((rows[0]["implementation"], rows[0]["method"]), "#000000")
        good = [r for r in rows if r["error"] is not None and r["error"] > 0 and r["time_per_traj_s"] > 0]
        target = dashed if rows[0]["mode"] == "batch" else solid
        target["xs"].append([r["time_per_traj_s"] for r in good])
        target["ys"].append([r["error"] for r in good])
        target["color"].append(colour)
        target["label"].append(name)
        for r in good:
            pts["x"].append(r["time_per_traj_s"])
            pts["y"].append(r["error"])
            pts["color"].append(colour)
            pts["label"].append(name)
            pts["setting"].append(r["setting"])
            pts["status"].append(r["status"])
    return solid, dashed, pts


def summary_text(data: dict[str, Any], case: str, target: float = 1e-6) -> str:
    """Markdown: the horizon, the reference's bound and the time each line needs for ``target`` error."""
    info = data["cases"].get(case)
    if info is None:
        return ""
    lines = [
        f"**{html.escape(case)}** ({html.escape(str(info.get('scene') or 'custom'))}), IC "
        f"({info['ic'][0]:.6g}, {info['ic'][1]:.6g}): error over **K = {info['horizon']}** of {info['k_max']} "
        f"periods" + (" (chaos horizon: perturbations grow 1000-fold by K)" if info["horizon"] < info["k_max"] else "")
        + f"; reference bound {info['reference_bound']:.1e}.",
    ]  # fmt: skip
    rows: dict[str, list[tuple[float | None, float]]] = {}
    failed: list[str] = []
    for row in data["rows"]:
        if row["case"] == case:
            rows.setdefault(row["series"], []).append((row["error"], row["time_per_traj_s"]))
            if row["status"] != "ok":
                failed.append(f"{row['series']} {row['setting']}: {row['status']}")
    best = []
    for name, pts in rows.items():
        t, how = bench.time_at_error(pts, target)
        if t is not None:
            best.append((t, name, how))
    if best:
        best.sort()
        txt = ", ".join(f"{html.escape(n)} {t * 1e3:.3g} ms{' (at most)' if how == 'at most' else ''}"
                        for t, n, how in best)  # fmt: skip
        lines.append(f"Time per trajectory for error {target:g}: {txt}.")
    if failed:
        lines.append("Not ok: " + html.escape("; ".join(failed[:6])) + (" …" if len(failed) > 6 else ""))
    for key, value in (data.get("ratios") or {}).items():
        if " / " in key and value is not None and case == "regular":
            lines.append(f"{html.escape(key)} at error {target:g}: **{value:g}x**")
    return "  \n".join(lines)


class BenchTab:
    """The speed-vs-accuracy tab of one session."""

    channel = "bench"

    def __init__(
        self,
        session: ExplorerSession,
        results_path: str | None = None,
        cache_dir: str | None = None,
    ) -> None:
        self.session = session
        self.cache_dir = cache_dir
        self.results_path = results_path or os.environ.get("BILIMOVICH_BENCH_RESULTS") or bench.latest_path()
        self.datasets: dict[str, tuple[dict[str, Any], str]] = {}  # label -> (bench.json dict, case)
        self.message = pn.pane.Str("", sizing_mode="stretch_width", css_classes=["bench-status"])
        self.error = pn.pane.HTML("", visible=False, sizing_mode="stretch_width", css_classes=["bench-error"])
        self.progress = pn.indicators.Progress(value=0, max=100, sizing_mode="stretch_width", visible=False)
        self.ic = pn.widgets.TextInput(label="Initial condition q,r (blank: the selected trajectory's)", value="")
        self.periods = pn.widgets.IntInput(label="Periods (longest horizon)", value=50, start=2, end=MAX_PERIODS)
        self.measure_button = pn.widgets.Button(label="Measure", color="primary", css_classes=["bench-run"])
        self.stop_button = pn.widgets.Button(label="Stop", color="warning")
        self.load_button = pn.widgets.Button(label="Load latest bench run")
        self.view = pn.widgets.Select(label="Diagram", options=[], css_classes=["bench-view"])
        self.measure_button.on_click(lambda e: self.run())
        self.stop_button.on_click(lambda e: self.stop())
        self.load_button.on_click(lambda e: self.load_results())
        self.view.param.watch(lambda e: self.session.runner.ui(self._draw), "value")
        self.solid = ColumnDataSource({"xs": [], "ys": [], "color": [], "label": []}, name="bench_solid")
        self.dashed = ColumnDataSource({"xs": [], "ys": [], "color": [], "label": []}, name="bench_dashed")
        self.points = ColumnDataSource({"x": [], "y": [], "color": [], "label": [], "setting": [], "status": []},
                                       name="bench_points")  # fmt: skip
        f = figure(x_axis_type="log", y_axis_type="log", height=460, sizing_mode="stretch_width",
                   tools="pan,wheel_zoom,box_zoom,reset,save", x_axis_label="wall time per trajectory (s)",
                   y_axis_label="max error over k = 1..K")  # fmt: skip
        f.toolbar.logo = None
        f.multi_line("xs", "ys", color="color", legend_field="label", line_width=2, source=self.solid)
        f.multi_line("xs", "ys", color="color", legend_field="label", line_width=2, line_dash="dashed",
                     source=self.dashed)  # fmt: skip
        dots = f.scatter("x", "y", color="color", size=6, source=self.points)
        f.add_tools(HoverTool(renderers=[dots], tooltips=[("", "@label"), ("setting", "@setting"),
                                                          ("error", "@y{0.00e}"), ("time / traj", "@x{0.000e} s"),
                                                          ("status", "@status")]))  # fmt: skip
        f.legend.location = "top_right"
        f.legend.label_text_font_size = "8pt"
        self.floor = Span(location=1e-16, dimension="width", line_dash="dotted", line_color="#777777", visible=False)
        f.add_layout(self.floor)
        self.fig = f
        self.summary = pn.pane.Markdown("", sizing_mode="stretch_width", css_classes=["bench-summary"])
        if os.path.exists(self.results_path):
            self.load_results(quiet=True)

    def panel(self) -> pn.Column:
        return pn.Column(
            pn.pane.Markdown(HELP),
            pn.Row(self.ic, self.periods),
            pn.Row(self.measure_button, self.stop_button, self.load_button, self.view),
            self.error,
            self.progress,
            self.message,
            self.summary,
            self.fig,
            pn.pane.HTML("<small>Solid: one trajectory at a time (one core); dashed: this project's batch kernel, "
                         "time per trajectory of a batch on every core; dotted: the reference's error bound.</small>"),
            sizing_mode="stretch_width",
        )  # fmt: skip

    # --- messages -----------------------------------------------------------------------

    def fail(self, msg: str) -> None:
        self.error.object = f'<div style="{ERROR_STYLE}">{html.escape(msg)}</div>'
        self.error.visible = True

    def ok(self) -> None:
        self.error.visible = False

    def set_progress(self, done: int, total: int, text: str) -> None:
        self.progress.visible = done < total
        self.progress.value = int(100 * done / max(1, total))
        self.message.object = text

    def stop(self) -> None:
        self.session.runner.cancel(self.channel)
        self.progress.visible = False
        self.message.object += " — stopped"

    # --- data -----------------------------------------------------------------------------

    def add_dataset(self, data: dict[str, Any], source: str) -> list[str]:
        """Register every case of a bench.json dict under ``source``; returns the new labels."""
        for label in [k for k in self.datasets if k.startswith(source)]:
            del self.datasets[label]
        labels = []
        for case in data["cases"]:
            label = source if source == MEASURED else f"{source}: {case}"
            self.datasets[label] = (data, case)
            labels.append(label)
        self.view.options = list(self.datasets)
        return labels

    def load_results(self, quiet: bool = False) -> None:
        """Read the latest full run (``results_path``) and offer its cases in the diagram selector."""
        try:
            data = bench.load_result(self.results_path)
        except (OSError, ValueError) as exc:
            if not quiet:
                reason = "no file" if isinstance(exc, FileNotFoundError) else str(exc)
                self.fail(f"no bench results at {self.results_path} ({reason}): run `bilimovich bench --out DIR`")
            return
        self.ok()
        label = f"{LATEST} ({data.get('config', {}).get('label', '?')})"
        labels = self.add_dataset(data, label)
        if labels and (self.view.value not in self.datasets or not quiet):
            self.view.value = labels[0]
        self.session.runner.ui(self._draw)

    def _ic(self) -> tuple[float, float]:
        if self.ic.value.strip():
            parts = self.ic.value.split(",")
            try:
                q, r = (float(v) for v in parts)
            except ValueError:
                raise ParameterError(f"initial condition must be two numbers q,r, got {self.ic.value[:40]!r}") from None
            if not (math.isfinite(q) and math.isfinite(r)):
                raise ParameterError(f"initial condition must be finite, got {self.ic.value[:40]!r}")
            return q, r
        ics = self.session.state.initial_conditions()
        if ics.shape[0] == 0:
            raise ParameterError("no initial condition: type one, or add trajectories in the section tab")
        i = min(int(self.session.state.selected), ics.shape[0] - 1)
        return float(ics[i, 0]), float(ics[i, 1])

    def run(self) -> None:
        """Measure the current system (a small bench) on the session's runner."""
        try:
            params = self.session.state.system()
            q, r = self._ic()
            periods = int(self.periods.value)
            if not 2 <= periods <= MAX_PERIODS:
                raise ParameterError(f"periods must be between 2 and {MAX_PERIODS}, got {periods}")
        except (ParameterError, TypeError) as exc:
            self.fail(str(exc))
            return
        self.ok()
        cfg = bench.app_config()
        from dataclasses import replace

        cfg = replace(cfg, k_max=periods)
        case = bench.Case(MEASURED, params, (q, r), k_max=periods, cloud=0.01, scene=self.session.state.scene,
                          why="the current system of this session")  # fmt: skip
        cache_dir = self.cache_dir
        self.set_progress(0, 1, "measuring…")

        def job(cancelled, emit) -> None:
            last = [0.0]

            def progress(p: bench.BenchProgress) -> None:
                now = time.perf_counter()
                if now - last[0] > REFRESH:
                    last[0] = now
                    emit(lambda: self.set_progress(p.done, p.total, f"{p.text} ({p.elapsed_s:.1f} s)"))

            try:
                res = bench.run_bench(cfg, cases=[case], cache_dir_=cache_dir, progress=progress, cancel=cancelled)
            except ParameterError as exc:  # e.g. the reference escapes in the first period
                emit(lambda msg=str(exc): self.set_progress(1, 1, "not measured") or self.fail(msg))
                return
            data = res.as_dict()
            emit(lambda: self._measured(data, res.completed))

        self.session.runner.start(self.channel, job)

    def _measured(self, data: dict[str, Any], completed: bool) -> None:
        self.add_dataset(data, MEASURED)
        self.view.value = MEASURED
        self._draw()
        rows = len(data["rows"])
        self.set_progress(1, 1, f"{rows} measurements, {data['elapsed_s']:.1f} s" + ("" if completed else " (stopped)"))

    def _draw(self) -> None:
        if self.view.value not in self.datasets:
            return
        data, case = self.datasets[self.view.value]
        solid, dashed, pts = _lines(data, case)
        self.solid.data = solid
        self.dashed.data = dashed
        self.points.data = pts
        bound = data["cases"][case].get("reference_bound")
        self.floor.visible = bool(bound) and bool(np.isfinite(bound))
        if self.floor.visible:
            self.floor.location = float(bound)
        self.summary.object = summary_text(data, case)
