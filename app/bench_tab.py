"""Speed vs accuracy tab: work-precision diagrams (error against time per trajectory, log-log).

Two sources of data, both produced by :mod:`explorer_core.bench` (no numerics here):

* **Measure** runs a small benchmark on the session's current system and initial condition (a few
  methods and tolerances, a short horizon; a reference from ``solve_ivp`` at 3e-14, cached) on the
  session's :class:`~app.runner.Runner`, with progress and Stop.
* The latest full ``bilimovich bench`` run, read from ``$BILIMOVICH_BENCH_RESULTS`` or the file
  the command leaves in the cache (:func:`explorer_core.bench.latest_path`): one diagram per case, and
  when the run compared the chaos indicators (issue 34, :mod:`explorer_core.studies.indicator_bench`) their
  chart: each indicator's agreement with a long Lyapunov run against the periods it was given.

Timings measured in a shared server are indicative; the command line's are the measured ones.
"""

from __future__ import annotations

import os
import time
from dataclasses import replace
from typing import Any

import numpy as np
from bokeh.core.properties import field
from bokeh.layouts import column
from bokeh.models import ColumnDataSource, HoverTool, Legend, LegendItem, Plot, Range1d, Span
from bokeh.plotting import figure

from app.analyses import REFRESH, AnalysisTab, Publish
from app.controller import ExplorerSession
from explorer_core.studies import bench
from explorer_core.system.params import ParameterError

#: Label of the dataset measured in this session.
MEASURED = "this system (Measure)"
LATEST = "latest bench run"
COLOURS = bench.LINE_COLOURS
HELP = (
    "Error against an independent reference (`solve_ivp` DOP853 at 3e-14, cross-checked) over the wall "
    "time per trajectory, for this project's RK4, DP5 and DOP853 and for `solve_ivp`. Lower left is better. "
    "On chaotic orbits the error is measured only up to the horizon where perturbations have grown 1000-fold. "
    "Measure runs a small benchmark on the current system; full results come from `bilimovich bench`."
)
FOOTNOTE = (
    "Solid: one trajectory at a time (one core); dashed: this project's batch kernel, time per trajectory of a "
    "batch on every core; dotted: the reference's error bound."
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


def summary_text(data: dict[str, Any], case: str, target: float = 1e-6) -> list[str]:
    """Plain lines: the horizon, the reference's bound and the time each line needs for ``target`` error."""
    info = data["cases"].get(case)
    if info is None:
        return []
    lines = [
        f"{case} ({info.get('scene') or 'custom'}), IC ({info['ic'][0]:.6g}, {info['ic'][1]:.6g}): error over "
        f"K = {info['horizon']} of {info['k_max']} periods"
        + (" (chaos horizon: perturbations grow 1000-fold by K)" if info["horizon"] < info["k_max"] else "")
        + f"; reference bound {info['reference_bound']:.1e}.",
    ]
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
        txt = ", ".join(f"{n} {t * 1e3:.3g} ms{' (at most)' if how == 'at most' else ''}" for t, n, how in best)
        lines.append(f"Time per trajectory for error {target:g}: {txt}.")
    elif rows:
        lines.append(f"No line reaches error {target:g} on this case.")
    if failed:
        lines.append("Not ok: " + "; ".join(failed[:6]) + (" …" if len(failed) > 6 else ""))
    for key, value in (data.get("ratios") or {}).items():
        if " / " in key and value is not None and case == "regular":
            lines.append(f"{key} at error {target:g}: {value:g}x")
    return lines


# --- the chaos indicators' chart (issue 34) ---------------------------------------------------------------------

#: The diagram selector's word for the indicators' chart of a bench run that compared them.
INDICATORS = "chaos indicators"
INDICATOR_COLOURS = {"birkhoff": "#1f77b4", "sali": "#d62728", "ftle": "#2ca02c"}
#: Dash per set of orbits: regular (Fig. 5A's island) solid, chaotic (Fig. 8B's attractor) dashed.
SET_DASH = {"regular": "solid", "chaotic": "dashed"}
INDICATOR_FOOTNOTE = (
    "Each indicator's verdicts (regular, chaotic or undecided) on the same initial conditions as the reference, at "
    "each length it was given; an undecided verdict counts as no agreement. Hover a point for the batch's seconds."
)


def indicator_periods(name: str, length: int) -> int:
    """Periods an orbit is given at a rung of ``length``: Birkhoff averages two halves of ``length``."""
    return 2 * int(length) if name == "birkhoff" else int(length)


def indicator_columns(report: dict[str, Any]) -> tuple[dict[str, list], dict[str, list]]:
    """Bokeh columns (lines, points) of an indicator comparison (``bench.json``'s ``indicators``): per set and
    indicator, the percentage of ICs classified as the reference classifies them (neither the opposite verdict nor
    undecided) against the periods given, the batch's seconds beside; the reference itself is a point at its periods
    and 100 %."""
    n = int(report["n"])
    lines: dict[str, list] = {"xs": [], "ys": [], "color": [], "dash": [], "label": []}
    pts: dict[str, list] = {"x": [], "y": [], "color": [], "label": [], "seconds": [], "wrong": [], "undecided": []}
    for set_name, e in report["sets"].items():
        for name, d in e["indicators"].items():
            label = f"{name} ({set_name})"
            secs = e.get("seconds", {}).get(name) or [float("nan")] * len(d["rungs"])
            xs = [indicator_periods(name, k) for k, _, _ in d["rungs"]]
            ys = [100.0 * (n - wrong - undecided) / n for _, wrong, undecided in d["rungs"]]
            lines["xs"].append(xs)
            lines["ys"].append(ys)
            lines["color"].append(INDICATOR_COLOURS.get(name, "#000000"))
            lines["dash"].append(SET_DASH.get(set_name, "dotted"))
            lines["label"].append(label)
            for x, y, t, (_, wrong, undecided) in zip(xs, ys, secs, d["rungs"], strict=True):
                pts["x"].append(x)
                pts["y"].append(y)
                pts["color"].append(INDICATOR_COLOURS.get(name, "#000000"))
                pts["label"].append(label)
                pts["seconds"].append(t)
                pts["wrong"].append(wrong)
                pts["undecided"].append(undecided)
        pts["x"].append(int(report["reference_periods"]))
        pts["y"].append(100.0)
        pts["color"].append("#000000")
        pts["label"].append(f"Lyapunov reference ({set_name})")
        pts["seconds"].append(e["reference_s"])
        pts["wrong"].append(0)
        pts["undecided"].append(n - int(e["reference_ok"]))
    return lines, pts


def indicator_text(report: dict[str, Any]) -> list[str]:
    """Plain lines: the reference, and per set and indicator the fewest periods from which every IC agrees with it
    and that batch's seconds against the reference's."""
    n = int(report["n"])
    lines = [f"Chaos indicators against a Lyapunov exponent over {report['reference_periods']} periods (chaotic when "
             f"lambda_1 T > {report['lyap_tol']}), {n} ICs a set: regular on Fig. 5A's island (solid), chaotic on "
             f"Fig. 8B's attractor (dashed); right end at 100 %: the reference."]  # fmt: skip
    for set_name, e in report["sets"].items():
        said = []
        for name, d in e["indicators"].items():
            if d["all_agree_at"] is None:
                said.append(f"{name} never all ({d['agree_at_longest']}/{n} at the longest)")
            else:
                said.append(f"{name} all from {indicator_periods(name, d['all_agree_at'])} periods "
                            f"({d['seconds_at_that_rung']:g} s, {d['speedup']:g}x faster)")  # fmt: skip
        lines.append(f"{set_name} (reference {e['reference_s']:g} s): " + "; ".join(said) + ".")
    return lines


def indicator_figure(lines: ColumnDataSource, points: ColumnDataSource) -> Plot:
    """The indicators' chart: agreement (%) against periods given (log), in the work-precision diagram's style."""
    f = figure(x_axis_type="log", sizing_mode="stretch_both", min_height=260, y_range=Range1d(-5, 105),
               name="bench_indicators", tools="pan,wheel_zoom,box_zoom,reset,save",
               x_axis_label="periods given to each orbit",
               y_axis_label="ICs classified as the long Lyapunov run (%)")  # fmt: skip
    f.toolbar.logo = None
    f.toolbar.active_scroll = None
    drawn = f.multi_line("xs", "ys", color="color", line_dash="dash", line_width=2, source=lines)
    f.add_layout(Legend(items=[LegendItem(label=field("label"), renderers=[drawn])], label_text_font_size="8pt"),
                 "right")  # fmt: skip
    dots = f.scatter("x", "y", color="color", size=6, source=points)
    f.add_tools(HoverTool(renderers=[dots], tooltips=[("", "@label"), ("periods", "@x"), ("agree", "@y{0.0} %"),
                                                      ("opposite verdict", "@wrong"), ("undecided", "@undecided"),
                                                      ("batch time", "@seconds{0.000} s")]))  # fmt: skip
    f.visible = False  # shown when its diagram is chosen
    return f


class BenchTab(AnalysisTab):
    """The speed-vs-accuracy tab of one session."""

    channel = "bench"
    help = HELP
    footnote = FOOTNOTE

    def __init__(
        self,
        session: ExplorerSession,
        publish: Publish | None = None,
        results_path: str | None = None,
        cache_dir: str | None = None,
    ) -> None:
        super().__init__(session, publish)
        self.cache_dir = cache_dir
        self.results_path = results_path or os.environ.get("BILIMOVICH_BENCH_RESULTS") or bench.latest_path()
        self.datasets: dict[str, tuple[dict[str, Any], str]] = {}  # label -> (bench.json dict, case)
        self.view.update(options=[], choice=None, footnote=FOOTNOTE)
        self.solid = ColumnDataSource({"xs": [], "ys": [], "color": [], "label": []}, name="bench_solid")
        self.dashed = ColumnDataSource({"xs": [], "ys": [], "color": [], "label": []}, name="bench_dashed")
        self.points = ColumnDataSource({"x": [], "y": [], "color": [], "label": [], "setting": [], "status": []},
                                       name="bench_points")  # fmt: skip
        self.floor = Span(location=1e-16, dimension="width", line_dash="dotted", line_color="#777777", visible=False)
        self.indicator_lines = ColumnDataSource({"xs": [], "ys": [], "color": [], "dash": [], "label": []},
                                                name="bench_indicator_lines")  # fmt: skip
        self.indicator_points = ColumnDataSource(
            {"x": [], "y": [], "color": [], "label": [], "seconds": [], "wrong": [], "undecided": []},
            name="bench_indicator_points",
        )
        self.work_precision: Plot | None = None
        self.indicators: Plot | None = None
        if os.path.exists(self.results_path):
            self.load_results(quiet=True)

    def _build(self) -> Plot:
        f = figure(x_axis_type="log", y_axis_type="log", sizing_mode="stretch_both", min_height=260,
                   tools="pan,wheel_zoom,box_zoom,reset,save", x_axis_label="wall time per trajectory (s)",
                   y_axis_label="max error over k = 1..K")  # fmt: skip
        f.toolbar.logo = None
        f.toolbar.active_scroll = None
        solid = f.multi_line("xs", "ys", color="color", line_width=2, source=self.solid)
        dashed = f.multi_line("xs", "ys", color="color", line_width=2, line_dash="dashed", source=self.dashed)
        # One legend item per source: with legend_field on both, figure() merges them into one item
        # whose renderers' sources differ (Bokeh's check E-1006), and the dashed lines' labels are lost.
        # Beside the plot, not over it: inside it covered the solve_ivp line's end (far right).
        items = [LegendItem(label=field("label"), renderers=[r]) for r in (solid, dashed)]
        f.add_layout(Legend(items=items, label_text_font_size="8pt"), "right")
        dots = f.scatter("x", "y", color="color", size=6, source=self.points)
        f.add_tools(HoverTool(renderers=[dots], tooltips=[("", "@label"), ("setting", "@setting"),
                                                          ("error", "@y{0.00e}"), ("time / traj", "@x{0.000e} s"),
                                                          ("status", "@status")]))  # fmt: skip
        f.add_layout(self.floor)
        f.name = "bench_work_precision"
        self.work_precision, self.indicators = f, indicator_figure(self.indicator_lines, self.indicator_points)
        return column(f, self.indicators, sizing_mode="stretch_both")

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
        if data.get("indicators"):
            self.datasets[f"{source}: {INDICATORS}"] = (data, INDICATORS)
            labels.append(f"{source}: {INDICATORS}")
        self.set_view(options=list(self.datasets))
        return labels

    def choose(self, label: Any) -> str | None:
        """Show another diagram; a label that is not offered is refused (message), the shown one stays."""
        if label not in self.datasets:
            return f"no diagram {str(label)[:60]!r}; still showing {self.view['choice']!r}"
        self.set_view(choice=label)
        self.session.runner.ui(self._draw)
        return None

    def load_results(self, quiet: bool = False) -> None:
        """Read the latest full run (``results_path``) and offer its cases in the diagram selector."""
        try:
            data = bench.load_result(self.results_path)
        except (OSError, ValueError) as exc:
            if not quiet:
                reason = "no file" if isinstance(exc, FileNotFoundError) else str(exc)
                self.fail(f"no bench results at {self.results_path} ({reason}): run `bilimovich bench --out DIR`")
            return
        self.set_view(error="")
        label = f"{LATEST} ({data.get('config', {}).get('label', '?')})"
        labels = self.add_dataset(data, label)
        if labels and (self.view["choice"] not in self.datasets or not quiet):
            self.set_view(choice=labels[0])
        self.session.runner.ui(self._draw)

    def _ic(self) -> tuple[float, float]:
        st = self.session.state
        if st.bench_ic:
            return float(st.bench_ic[0]), float(st.bench_ic[1])
        ics = st.initial_conditions()
        if ics.shape[0] == 0:
            raise ParameterError("no initial condition: type one, or add trajectories in the section tab")
        i = min(max(0, int(st.selected)), ics.shape[0] - 1)  # no trajectory selected (-1): the first
        return float(ics[i, 0]), float(ics[i, 1])

    def run(self) -> None:
        """Measure the current system (a small bench) on the session's runner."""
        st = self.session.state
        try:
            params = st.system()
            q, r = self._ic()
        except ParameterError as exc:
            self.fail(str(exc))
            return
        periods = st.bench_periods
        cfg = replace(bench.app_config(), k_max=periods)
        case = bench.Case(MEASURED, params, (q, r), k_max=periods, cloud=0.01, scene=st.scene,
                          why="the current system of this session")  # fmt: skip
        cache_dir = self.cache_dir

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
                emit(lambda msg=str(exc): self.set_view(message="not measured", progress=None, error=msg))
                return
            data = res.as_dict()
            emit(lambda: self._measured(data, res.completed))

        self._start(job, "measuring…")

    def _measured(self, data: dict[str, Any], completed: bool) -> None:
        self.add_dataset(data, MEASURED)
        self.set_view(choice=MEASURED)
        self._draw()
        rows = data["rows"]
        ok = sum(1 for r in rows if r["status"] == "ok" and r["error"] is not None)
        tail = "" if completed else " (stopped)"
        if not ok:
            self.set_view(progress=None, message=f"{len(rows)} measurements{tail}: none ok, no timings to compare")
        else:
            self.set_view(progress=None, message=f"{len(rows)} measurements ({ok} ok), {data['elapsed_s']:.1f} s{tail}")

    def _draw(self) -> None:
        if self.view["choice"] not in self.datasets:
            return
        data, case = self.datasets[self.view["choice"]]
        if self.work_precision is not None and self.indicators is not None:
            self.work_precision.visible, self.indicators.visible = case != INDICATORS, case == INDICATORS
        if case == INDICATORS:
            self.indicator_lines.data, self.indicator_points.data = indicator_columns(data["indicators"])
            self.set_view(result=indicator_text(data["indicators"]), footnote=INDICATOR_FOOTNOTE)
            return
        self.set_view(footnote=FOOTNOTE)
        solid, dashed, pts = _lines(data, case)
        self.solid.data = solid
        self.dashed.data = dashed
        self.points.data = pts
        bound = data["cases"][case].get("reference_bound")
        self.floor.visible = bool(bound) and bool(np.isfinite(bound))
        if self.floor.visible:
            self.floor.location = float(bound)
        self.set_view(result=summary_text(data, case))
