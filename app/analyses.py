"""Analysis tabs: Lyapunov spectrum, bifurcation diagram, chart of regimes.

Each tab takes the session's current system and its settings from the session's state (the
values in use: typed values went through :func:`app.state.commit`), runs one analysis from
:mod:`explorer_core` on the session's :class:`~app.runner.Runner` (so a newer run or a closed
tab cancels it), shows progress, can be stopped, and draws the result. Work per run is bounded
(:data:`app.state.LIMITS`). No numerics here.

What a tab shows besides its figure is a small dict (:attr:`AnalysisTab.view`: message, error,
progress, result lines, whether a download exists) that the page renders as text. A result that
is empty, or whose members all failed, says so and reports no numbers.
"""

from __future__ import annotations

import dataclasses
import io
import json
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from bokeh.models import ColumnDataSource, HoverTool, LinearColorMapper, Plot
from bokeh.palettes import Category10, Category20
from bokeh.plotting import figure

from app.controller import ExplorerSession
from app.layers.base import MIME, Download, named, result_file, written
from app.layers.base import plain as _plain
from app.state import plot_point
from app.views import BACKEND
from explorer_core import export
from explorer_core.analyses.bifurcation import DIAGRAM_PLOT_BOUND, DIAGRAM_PLOT_RTOL, bifurcation_diagram
from explorer_core.analyses.continuation import Boundaries, chart_boundaries, continue_from_seeds, seeds_spec
from explorer_core.analyses.continuation.results import CODIM2_NAMES
from explorer_core.analyses.lyapunov import lyapunov_spec, lyapunov_spectrum
from explorer_core.analyses.orbits import ORBIT_NUMERICS
from explorer_core.analyses.regimes import REGIMES, chart_numerics, chart_spec, iter_chart
from explorer_core.analyses.sweeps import sweep_values
from explorer_core.losses import Loss
from explorer_core.parallel.cluster import SchedulerError, executor_for, scheduler_from_env
from explorer_core.status import Status, describe
from explorer_core.system.params import ParameterError
from explorer_core.warm import warm_all

BIFURCATION_HELP = (
    "Orbit diagram: for each value a transient, then section points. Continuation carries the state from "
    "value to value, forward (blue) and backward (orange) to expose hysteresis; escaped trajectories are "
    "counted, not drawn. Over it, the periodic orbits near the diagram's attractors followed by "
    "pseudo-arclength continuation (green: stable, grey dashed: unstable), switching onto the doubled orbit "
    "at each period doubling; diamonds mark the bifurcations (listed with their error)."
)
CHART_HELP = (
    "Chart of dynamical regimes: each pixel's attractor classified by the return of its section point "
    "(period p), its largest Lyapunov exponent (chaos) or escape. A coarse grid comes first, then "
    "refinement. Click a pixel to set those two parameters (the pixel's centre) and see that section; "
    "the cross marks the current parameters. The lines are the {curves} curves of the chart's stable cycles "
    "of periods 1-3, followed in both parameters by continuation: the boundaries of the chart's regions as "
    "curves (hover one for its kind). Each pixel follows one initial condition (the first clicked or scene "
    "point, else the first random one): where attractors coexist it shows the one that point reaches, so a "
    "curve of a coexisting cycle can run through a region of another colour. A curve's dash is its cycle's period "
    "(1 solid, 2 dashed, 3 dotted, 4 dash-dotted: the legend in the plot). The marks on the curves are their "
    "codimension-two points (strong resonances R1-R4, fold-flip LPPD, generalised flip GPD, Chenciner CH, cusp "
    "CP; hover one, and the list under the plot)."
)
#: Bifurcation curves on the chart: colour and words per kind (the help, the result line and the hover use these).
CURVE_STYLE = {
    "period_doubling": ("#000000", "black", "period doubling"),
    "fold": ("#e377c2", "magenta", "fold"),
    "neimark_sacker": ("#17becf", "cyan", "Neimark–Sacker"),
}
CHART_HELP = CHART_HELP.format(curves=", ".join(f"{w} ({c})" for _, c, w in CURVE_STYLE.values()))
#: A curve's dash by the period of its cycle (Bokeh's patterns, in screen pixels, and in words): the curves of one
#: kind differ; the periods of a doubling cascade (1, 2, 4, 8, 16) and of the chart's cycles (1-6) each their own.
CURVE_DASHES = {1: ("solid", "solid"), 2: ("8 4", "dashed"), 3: ("2 3", "dotted"), 4: ("8 3 2 3", "dash-dotted"),
                5: ("8 3 2 3 2 3", "dash-dot-dotted"), 6: ("14 4", "long-dashed"), 8: ("4 4", "short-dashed"),
                16: ("14 3 2 3", "long-dash-dotted")}  # fmt: skip
#: Codimension-two points on the curves: Bokeh's marker and the fill colour per kind (the legend and the hover).
CODIM2_STYLE = {
    "R1": ("square", "#d62728"),
    "R2": ("triangle", "#ff7f0e"),
    "R3": ("inverted_triangle", "#2ca02c"),
    "R4": ("diamond", "#1f77b4"),
    "LPPD": ("hex", "#9467bd"),
    "GPD": ("star", "#ffd21f"),
    "CH": ("circle", "#8c564b"),
    "CP": ("plus", "#bcbd22"),
}


def curve_dash(period: int) -> str:
    """The dash of a bifurcation curve of the period-``period`` cycle (:data:`CURVE_DASHES`; another period: those
    in turn)."""
    dashes = list(CURVE_DASHES.values())
    return CURVE_DASHES.get(int(period), dashes[(int(period) - 1) % len(dashes)])[0]


def codim2_style(kind: str) -> tuple[str, str]:
    """Marker and colour of a codimension-two point of ``kind`` (one not in :data:`CODIM2_STYLE`: a grey x)."""
    return CODIM2_STYLE.get(kind, ("x", "#7f7f7f"))


def codim2_points(parts: Any) -> list[Any]:
    """The codimension-two points of the curves of ``parts`` (continuations), each once: a point found on two curves
    (an R2 on a flip curve where a Neimark-Sacker curve ends, an LPPD on a fold and a flip curve) or by two
    continuations is listed and drawn once (the same kind and period within the larger error estimate, at least
    1e-7 of the values: the two locations of one point can differ by more than their estimates, e.g. 7e-9 for the
    Henon 8-cycle's R2 on its flip and its NS curve)."""
    out: list[Any] = []
    for c in (c for cont in parts for cu in cont.curves for c in cu.codim2):
        tol = [max(c.error, 1e-7 * (1.0 + abs(v))) for v in c.values]
        if not any(o.kind == c.kind and o.period == c.period
                   and all(abs(a - b) <= max(t, o.error) for a, b, t in zip(o.values, c.values, tol, strict=True))
                   for o in out):  # fmt: skip
            out.append(c)
    return out


def codim2_lines(parts: Any, names: tuple[str, str]) -> list[str]:
    """The chart's list of codimension-two points in the command line's words ("R2 (1:2 resonance) of the period-1
    orbit on the period doubling curve at (alpha, I11) = (..., ...) ± ..."), or that there are none."""
    points = codim2_points(parts)
    if not points:
        return ["codimension-two points: none in this window"]
    return [f"codimension-two points: {len(points)}",
            *(c.describe(*names).replace(" +- ", " ± ") for c in points)]  # fmt: skip


LYAPUNOV_HELP = (
    "Exponents of the (q, r) flow from the variational equations with the exact Jacobian, re-orthonormalised "
    "at each section time; Λ3 = 0 is the time direction. The check Λ1 + Λ2 = ⟨dQ/dq + dR/dr⟩ must hold."
)
#: Minimum time between two partial pictures of a running analysis (seconds).
REFRESH = 0.25
Publish = Callable[[str, dict[str, Any]], None]


def _fig(**kw: Any) -> Plot:
    f = figure(tools="pan,wheel_zoom,box_zoom,reset,save", output_backend=BACKEND, sizing_mode="stretch_both",
               min_height=260, **kw)  # fmt: skip
    f.toolbar.logo = None
    f.toolbar.active_scroll = None  # the wheel scrolls the page until the zoom tool is picked
    return f


class AnalysisTab:
    """Shared plumbing: the view dict (message, error, progress, result), Stop, failures."""

    channel = "analysis"
    help = ""
    #: Its downloads: the page's ``{"action": "download", "what": ...}`` -> (the button's words, its class).
    downloads: ClassVar[dict[str, tuple[str, str]]] = {}
    #: The numerics the last run used and why (the core's rule for the page's Method and Accuracy), said on screen.
    ran_with = ""

    def __init__(self, session: ExplorerSession, publish: Publish | None = None) -> None:
        self.session = session
        self._publish = publish
        self.view: dict[str, Any] = {"message": "", "error": "", "progress": None, "result": [], "download": False,
                                     "help": self.help}  # fmt: skip
        self._fig: Plot | None = None
        self.view["downloads"] = [[what, words, cls, False] for what, (words, cls) in self.downloads.items()]

    # --- what the page shows ---------------------------------------------------------------

    def set_view(self, **kw: Any) -> None:
        self.view.update(kw, downloads=self._offered())
        if self._publish is not None:
            self._publish(self.channel, dict(self.view))

    def fail(self, msg: str) -> None:
        self.set_view(error=msg, progress=None)

    # --- downloads ---------------------------------------------------------------------------

    def _offered(self) -> list[list[Any]]:
        """The page's download buttons of this tab: ``[what, words, class, whether there is a file]``."""
        return [[what, words, cls, self.file(what, probe=True) is not None]
                for what, (words, cls) in self.downloads.items()]  # fmt: skip

    def file(self, what: str, probe: bool = False) -> Download | None:
        """The download ``what`` of the result on screen, written by the core's writer as the command line writes it
        (named ``-partial`` when its run was stopped); None before there is one. ``probe``: only whether there is
        one (any non-None value; nothing written)."""
        return None

    def failed(self, exc: BaseException) -> None:
        """The job raised (document thread): a one-line message; nothing stays "computing"."""
        self.set_view(error=f"{self.channel} computation failed: {_plain(exc)}", progress=None, message="failed")

    def stop(self) -> None:
        if self.session.runner.busy(self.channel):
            self.session.runner.cancel(self.channel)
            self.set_view(message=(self.view["message"] + " — stopped").strip(" —"), progress=None)

    def set_progress(self, done: int, total: int, text: str) -> None:
        self.set_view(progress=int(100 * done / max(1, total)) if done < total else None, message=text)

    def figure(self) -> Plot:
        """The tab's figure, built when the tab is first opened."""
        if self._fig is None:
            self._fig = self._build()
        return self._fig

    def _build(self) -> Plot:
        raise NotImplementedError

    def run(self) -> None:
        raise NotImplementedError

    def _start(self, job: Callable, text: str = "computing…") -> None:
        self.set_view(error="", result=[], message=text, progress=0)
        self.session.runner.start(self.channel, job)


def _kind_words(b: Any) -> str:
    """A located bifurcation's kind for a tooltip, with its criticality where its normal form decided it."""
    nf = getattr(b, "normal_form", None)
    crit = f"{nf.criticality} " if nf is not None and nf.criticality else ""
    return crit + b.kind.replace("_", " ")


class LyapunovTab(AnalysisTab):
    channel = "lyapunov"
    help = LYAPUNOV_HELP
    downloads: ClassVar[dict[str, tuple[str, str]]] = {
        "lyapunov": ("Download running estimates CSV", "btn-lyapunov-csv"),
        "lyapunov_summary": ("Download exponents JSON", "btn-lyapunov-json"),
    }

    def __init__(self, session: ExplorerSession, publish: Publish | None = None) -> None:
        super().__init__(session, publish)
        self.result = None  # the last run's LyapunovResult (a stopped run's never comes: the runner drops it)
        self.source = ColumnDataSource({"k": [], "l1": [], "l2": []}, name="lyapunov_source")

    def _build(self) -> Plot:
        f = _fig(x_axis_label="periods measured", y_axis_label="running estimate (per unit time)")
        f.line("k", "l1", source=self.source, color=Category10[3][0], legend_label="Λ1")
        f.line("k", "l2", source=self.source, color=Category10[3][1], legend_label="Λ2")
        f.legend.location = "bottom_right"
        return f

    def _ic(self) -> tuple[float, float]:
        st = self.session.state
        if st.lyap_ic:
            return float(st.lyap_ic[0]), float(st.lyap_ic[1])
        traj, k, q, r = self.session.data()
        sel = traj == st.selected
        if sel.any():
            j = np.flatnonzero(sel)[np.argmax(k[sel])]
            return float(q[j]), float(r[j])
        ics = st.analysis_ics()
        if ics.shape[0] == 0:
            raise ParameterError("no initial condition: type one, or add trajectories in the section tab")
        return float(ics[0, 0]), float(ics[0, 1])

    def run(self) -> None:
        st = self.session.state
        try:
            params = st.system()
            q, r = self._ic()
        except ParameterError as exc:
            self.fail(str(exc))
            return
        # The spec the command line builds for `--ensemble M`: the members placed on the IC's attractor (the
        # spec's offset and seed), the numerics of the page's Method and Accuracy by the core's rule.
        numerics, self.ran_with = st.numerics_for(None)
        try:
            spec = lyapunov_spec(params, [(q, r)], st.lyap_periods, transient=st.lyap_transient,
                                 ensemble=st.lyap_ensemble, numerics=numerics)  # fmt: skip
        except ParameterError as exc:
            self.fail(str(exc))
            return
        history: list[tuple[int, float, float]] = []
        self.session.runner.ui(lambda: setattr(self.source, "data", {"k": [], "l1": [], "l2": []}))

        def job(cancelled, emit) -> None:
            last = [0.0]

            def progress(p) -> None:
                ok = p.status == Status.OK
                if p.phase == "measure" and p.done_periods and ok.any():  # no estimate from failed members
                    est = p.running[ok].mean(axis=0)
                    history.append((p.done_periods, float(est[0]), float(est[1])))
                now = time.perf_counter()
                if now - last[0] > REFRESH:
                    last[0] = now
                    rows = list(history)
                    emit(lambda: self._partial(rows, p.phase, p.done_periods, p.total_periods))

            res = lyapunov_spectrum(spec, progress=progress, cancel=cancelled)
            emit(lambda: self._done(res, list(history)))

        self._start(job)

    def _partial(self, rows, phase: str, done: int, total: int) -> None:
        if rows:
            k, l1, l2 = zip(*rows, strict=True)
            self.source.data = {"k": list(k), "l1": list(l1), "l2": list(l2)}
        self.set_progress(done, total, f"{phase}: {done}/{total} periods")

    def _done(self, res, rows) -> None:
        self.result = res
        self._partial(rows, "measure", res.periods, res.periods)
        labels = res.status_labels()
        status = describe(res.status)
        n_ok = int(res.ok.sum())
        tail = f"{res.elapsed_s:.2f} s" + ("" if res.completed else " (stopped)")
        if n_ok == 0:
            lines = [f"No exponents: none of the {len(labels)} members ran the whole measurement ({status}).", tail]
            self.set_view(result=lines, progress=None, message="done: no result" if res.completed else "stopped")
            return
        mean, spread = res.mean(), res.spread()
        ky = res.kaplan_yorke()
        div = float(np.mean(res.divergence_mean[res.ok]))
        lines = [
            f"Λ1 = {mean[0]:.4f} ± {spread[0]:.4f}, Λ2 = {mean[1]:.4f} ± {spread[1]:.4f}, Λ3 = 0 "
            f"(per unit time; per iteration ×T = {mean[0] * res.period:.4f}, {mean[1] * res.period:.4f})",
            f"Kaplan–Yorke dimension D = {ky:.4f}" if ky == ky else "Kaplan–Yorke dimension: not applicable",
            f"check: Λ1 + Λ2 = {mean.sum():.6f}, time-averaged divergence = {div:.6f}",
            f"members used: {n_ok} of {len(labels)} ({status}); {tail}",
            f"numerics: {self.ran_with}",
        ]
        self.set_view(result=lines, progress=None, message="done" if res.completed else "stopped")

    def _start(self, job: Callable, text: str = "computing…") -> None:
        self.result = None  # the plot starts again from nothing: so does the download
        super()._start(job, text)

    def file(self, what: str, probe: bool = False) -> Download | None:
        """``lyapunov``: every member's running estimates, as ``bilimovich lyapunov --history x.csv`` writes them;
        ``lyapunov_summary``: the summary, as ``--json`` prints it."""
        if self.result is None or what not in self.downloads:
            return None
        suffix = ".csv" if what == "lyapunov" else ".json"
        return self.result if probe else result_file(self.result, what, suffix)


#: The orbit diagram's colours: the sweep forward and backward, the continued orbits, the bifurcations.
_FORWARD, _BACKWARD = Category10[3][0], Category10[3][1]
_STABLE, _UNSTABLE, _BIFURCATION = "#2ca02c", "#7f7f7f", "#9467bd"
#: Its key under the plot (label, colour): the page draws the swatches.
BIFURCATION_LEGEND = [["sweep forward", _FORWARD], ["backward", _BACKWARD], ["stable orbit", _STABLE],
                      ["unstable orbit (dashed)", _UNSTABLE], ["bifurcation (diamond)", _BIFURCATION]]  # fmt: skip


class BifurcationTab(AnalysisTab):
    channel = "bifurcation"
    help = BIFURCATION_HELP
    cont_with = ""  # the continuation's numerics, in words
    downloads: ClassVar[dict[str, tuple[str, str]]] = {
        "bifurcation": ("Download diagram CSV", "btn-bifurcation-csv"),
        "branches": ("Download branches CSV", "btn-branches-csv"),
        "bifurcations": ("Download branches and bifurcations JSON", "btn-branches-json"),
    }

    def __init__(self, session: ExplorerSession, publish: Publish | None = None) -> None:
        super().__init__(session, publish)
        self.view.update(legend=BIFURCATION_LEGEND, legend_title="")
        self.source = ColumnDataSource({"x": [], "y": [], "c": []}, name="bifurcation_source")
        self.stable = ColumnDataSource({"xs": [], "ys": []}, name="branches_stable")
        self.unstable = ColumnDataSource({"xs": [], "ys": []}, name="branches_unstable")
        self.bifs = ColumnDataSource({"x": [], "y": [], "kind": [], "value": [], "period": []}, name="bif_points")
        self._data = None
        self._cont = None
        session.state.param.watch(lambda e: session.runner.ui(self._draw), "bif_coord")
        #: The current value of the swept parameter (a vertical line; it follows a played parameter).
        self.now: Any = None
        session.state.param.watch(lambda *e: session.runner.ui(self._mark_now), ["bif_param", *_SWEPT])

    def _mark_now(self) -> None:
        if self.now is not None:
            self.now.location = float(getattr(self.session.state, self.session.state.bif_param))

    def _build(self) -> Plot:
        from bokeh.models import HoverTool, Span

        f = _fig(x_axis_label=self.session.state.bif_param, y_axis_label=f"{self.session.state.bif_coord}_k")
        self.now = Span(location=float(getattr(self.session.state, self.session.state.bif_param)), dimension="height",
                        line_color="#0a58ca", line_width=2, line_alpha=0.8, name="bifurcation_current")  # fmt: skip
        f.add_layout(self.now)
        mapper = LinearColorMapper(palette=[_FORWARD, _BACKWARD], low=0, high=1)
        f.scatter("x", "y", source=self.source, size=1.6, line_color=None,
                  fill_color={"field": "c", "transform": mapper})  # fmt: skip
        f.multi_line("xs", "ys", source=self.unstable, line_color=_UNSTABLE, line_dash="dashed", line_width=1.4)
        f.multi_line("xs", "ys", source=self.stable, line_color=_STABLE, line_width=2.2)
        marks = f.scatter("x", "y", source=self.bifs, marker="diamond", size=11, fill_color=_BIFURCATION,
                          line_color="black", name="bifurcation_marks")  # fmt: skip
        f.add_tools(HoverTool(renderers=[marks], tooltips=[("", "@kind of the period-@period orbit"),
                                                           ("value", "@value")]))  # fmt: skip
        return f

    def run(self) -> None:
        st = self.session.state
        try:
            params = st.system()
            name = st.bif_param
            lo, hi = st.bif_range or (getattr(st, name) - 0.05, getattr(st, name) + 0.05)
            for end in (lo, hi):
                st.system(**{name: end})  # blank range: current ± 0.05 must be valid too
            ics = st.analysis_ics()[:4]
            if ics.shape[0] == 0:
                raise ParameterError(
                    "no initial conditions: set 'Random initial conditions' above 0 or click in the section"
                )
            scheduler = scheduler_from_env()  # BILIMOVICH_SCHEDULER: a Dask cluster runs the sweep
        except (ParameterError, SchedulerError) as exc:
            self.fail(str(exc))
            return
        n, pts, tr, seeding = st.bif_values, st.bif_points, st.bif_transient, st.bif_seeding
        values = sweep_values((lo, hi), n)
        numerics, self.ran_with = st.numerics_for(None, plot_rtol=DIAGRAM_PLOT_RTOL, bound=DIAGRAM_PLOT_BOUND)
        # The orbits continued after the sweep: the orbits' own map under the page's Method and Accuracy.
        cont_numerics, self.cont_with = st.numerics_for(ORBIT_NUMERICS)
        follow = st.bif_orbits

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
                emit(lambda msg=str(exc): self.set_view(message="not computed", progress=None, error=msg))
                return
            emit(lambda: self._done(d))
            if not follow or cancelled():
                return
            emit(lambda: self.set_view(message=self.view["message"] + "; continuing the orbits…"))
            # Seeds: where the sweep's trajectories settled at the first value, and its initial conditions.
            seeds = np.concatenate([d.final[0, 0][np.asarray(d.status[0, 0]) == Status.OK], ics])
            spec = seeds_spec(params, name, (lo, hi), seeds, max_orbits=4, numerics=cont_numerics)
            cont = continue_from_seeds(spec, cancel=cancelled)
            if not cancelled(wait=False):
                emit(lambda: self._continued(cont))

        self._start(job, f"computing on {scheduler}…" if scheduler else "computing…")

    def _done(self, d) -> None:
        self._data = d
        self._cont = None
        self._draw()
        counts = d.status_counts()
        summary = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in counts.items())
        n_points = int(d.long()[0].size)
        head = f"{len(d.values)} values, {d.elapsed_s:.1f} s" + ("" if d.completed else " (stopped)")
        if n_points == 0:
            lines = [f"No points: every trajectory escaped or failed before its section points ({summary})."]
        else:
            lines = [f"{n_points:,} points; trajectories: {summary}"]
        settled = d.settled_summary()
        n_settled = settled["repeated"] + settled["newton"]
        if n_settled:
            # Their later points are the cycle's, copied at the right phase, not integrated: say so (README).
            lines.append(f"{n_settled} of {d.status.size} trajectories settled on an attracting cycle "
                         f"({settled['repeated']} repeated to 1e-9, {settled['newton']} by Newton): "
                         f"{settled['periods_copied']:,} periods copied from the cycle, not integrated")  # fmt: skip
        lines.append(f"numerics: {self.ran_with}")
        self.set_view(message=head, progress=None, result=lines)

    def _continued(self, cont) -> None:
        self._cont = cont
        self._draw()
        lines = list(self.view["result"])
        bifs = cont.bifurcations
        lines.append(f"continuation: {len(cont.branches)} branches, {cont.n_points} points, {cont.elapsed_s:.1f} s"
                     + ("" if bifs else "; no bifurcation in the range"))  # fmt: skip
        # the command line's words: criticality and the normal-form coefficient with their error estimates
        lines += [b.describe(cont.param).replace(" +- ", " ± ") for b in bifs[:12]]
        lines += cont.messages[:3]
        lines += [loss.line() for loss in cont.lost[:4]]  # a branch that stopped short says so on screen
        lines.append(f"continuation numerics: {self.cont_with}")
        head = self.view["message"].replace("; continuing the orbits…", "")
        self.set_view(result=lines, message=head)

    def file(self, what: str, probe: bool = False) -> Download | None:
        """``bifurcation``: the diagram on screen as ``bilimovich bifurcation --out x.csv`` writes it; ``branches``:
        the continued branches as ``bilimovich continue --out x.csv`` writes them; ``bifurcations``: the
        continuation's summary (branches, bifurcations with their error estimates) as JSON."""
        result = self._data if what == "bifurcation" else self._cont if what in self.downloads else None
        if result is None or probe:
            return result
        return result_file(result, what, ".json" if what == "bifurcations" else ".csv")

    def _draw(self) -> None:
        d = self._data
        if d is None:
            return
        s, v, x, i, k, q, r = d.long()
        coord = self.session.state.bif_coord
        self.source.data = {"x": x, "y": q if coord == "q" else r, "c": s.astype(float)}
        stable, unstable = branch_lines(self._cont, 0 if coord == "q" else 1)
        self.stable.data, self.unstable.data = stable, unstable
        cont = self._cont
        col = 0 if coord == "q" else 1
        self.bifs.data = {
            "x": [b.value for b in cont.bifurcations] if cont else [],
            "y": [float(b.point[col]) for b in cont.bifurcations] if cont else [],
            "kind": [_kind_words(b) for b in cont.bifurcations] if cont else [],
            "value": [f"{b.value:.12g} ± {b.error:.1g}" for b in cont.bifurcations] if cont else [],
            "period": [b.period for b in cont.bifurcations] if cont else [],
        }
        if self._fig is not None:
            self._fig.xaxis.axis_label = d.param
            self._fig.yaxis.axis_label = f"{coord}_k"


# Colours of the chart: period p (1..16), then the other regimes.
_PERIOD_COLORS = list(Category20[20][:16])
_OTHER = {"quasi_periodic": "#bdbdbd", "chaotic": "#000000", "escaped": "#ffffff", "failed": "#ff00ff",
          "invalid": "#f4cccc"}  # fmt: skip
_NOT_DONE = "#eeeeee"
#: The chart's legend as (label, colour): the page draws the swatches.
CHART_LEGEND = [*((str(p), c) for p, c in zip(range(1, 17), _PERIOD_COLORS, strict=True)),
                *((k.replace("_", "-"), c) for k, c in _OTHER.items())]  # fmt: skip
#: Regimes that classify a pixel (failed and invalid pixels do not).
_CLASSIFIED = ("periodic", "quasi_periodic", "chaotic", "escaped")


#: The columns of the chart's sources of curves and of codimension-two points.
_CURVE_COLUMNS = ("xs", "ys", "color", "kind", "dash")
_CODIM2_COLUMNS = ("x", "y", "marker", "color", "label", "name", "values")


def _empty(columns: tuple[str, ...]) -> dict[str, list]:
    return {k: [] for k in columns}


class ChartTab(AnalysisTab):
    channel = "chart"
    help = CHART_HELP
    downloads: ClassVar[dict[str, tuple[str, str]]] = {"chart": ("Download chart NPZ", "btn-npz")}

    def __init__(self, session: ExplorerSession, publish: Publish | None = None) -> None:
        super().__init__(session, publish)
        self.view.update(legend=CHART_LEGEND, legend_title="period of the cycle:")
        self.source = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []}, name="chart_source")
        self.current = ColumnDataSource({"x": [], "y": []}, name="chart_current")
        self.curves = ColumnDataSource(_empty(_CURVE_COLUMNS), name="chart_curves")
        #: The codimension-two points on the curves: a mark per point (marker and colour of its kind).
        self.codim2 = ColumnDataSource(_empty(_CODIM2_COLUMNS), name="chart_codim2")
        self.chart = None  # the chart on screen: the pixels computed so far (those not computed: ``computed`` False)
        #: The bifurcation curves drawn on it (None: none followed), and whether the run on screen was to follow them.
        self.boundaries = None
        self.follows = False
        session.state.param.watch(lambda *e: session.runner.ui(self._mark), list(_SWEPT))

    def _build(self) -> Plot:
        from bokeh.events import Tap

        st = self.session.state
        self.mapper = LinearColorMapper(palette=[_NOT_DONE, *_PERIOD_COLORS, *_OTHER.values()], low=-0.5,
                                        high=len(_PERIOD_COLORS) + len(_OTHER) + 0.5)  # fmt: skip
        f = _fig(x_axis_label=st.chart_x, y_axis_label=st.chart_y)
        f.image(image="image", x="x", y="y", dw="dw", dh="dh", source=self.source, color_mapper=self.mapper)
        # Bifurcation curves from two-parameter continuation, with a white halo to show on any colour.
        f.multi_line("xs", "ys", source=self.curves, line_color="white", line_width=5, line_alpha=0.8)
        # Dashed by the cycle's period: the curves of one kind (three black period doublings) differ.
        lines = f.multi_line("xs", "ys", source=self.curves, line_color="color", line_dash="dash", line_width=2.2,
                             legend_field="kind", name="chart_curve_lines")  # fmt: skip
        f.add_tools(HoverTool(renderers=[lines], tooltips=[("curve", "@kind")], line_policy="interp"))
        marks = f.scatter("x", "y", source=self.codim2, marker="marker", fill_color="color", line_color="black",
                          line_width=1.2, size=13, legend_field="label", name="chart_codim2_marks")  # fmt: skip
        f.add_tools(HoverTool(renderers=[marks], tooltips=[("", "@name"), ("", "@values")]))
        f.legend.location = "top_right"
        f.legend.label_text_font_size = "8pt"
        f.legend.background_fill_alpha = 0.75
        f.legend.spacing, f.legend.padding, f.legend.margin = 0, 4, 4
        f.legend.visible = False  # until there are curves
        # The current parameters: a cross with a white halo, visible on every colour.
        f.scatter("x", "y", source=self.current, marker="cross", size=18, line_color="white", line_width=5)
        f.scatter("x", "y", source=self.current, marker="cross", size=18, line_color="black", line_width=2,
                  name="chart_current_marker")  # fmt: skip
        f.on_event(Tap, self._on_tap)
        return f

    def run(self) -> None:
        st = self.session.state
        try:
            params = st.system()
            nx, ny = st.chart_grid
            periods = st.chart_periods
            numerics, self.ran_with = st.numerics_for(chart_numerics())
            spec = chart_spec(params, st.chart_x, st.chart_xrange, st.chart_y, st.chart_yrange, (nx, ny),
                              ics=st.analysis_ics()[:1], transient=st.chart_transient, numerics=numerics,
                              periods=periods, p_max=max(1, min(16, (periods - 1) // 2)))  # fmt: skip
            scheduler = scheduler_from_env()  # BILIMOVICH_SCHEDULER: tiles run on a Dask cluster
        except (ParameterError, SchedulerError, ValueError) as exc:
            self.fail(str(exc))
            return
        labels = (st.chart_x, st.chart_y)
        self.session.runner.ui(lambda: self._label(*labels))
        self.curves.data, self.codim2.data = _empty(_CURVE_COLUMNS), _empty(_CODIM2_COLUMNS)
        if self._fig is not None:
            self._fig.legend.visible = False
        curves = st.chart_curves
        self.boundaries, self.follows = None, curves

        def job(cancelled, emit) -> None:
            last = [0.0]
            upd = None
            try:
                # Refined (finer levels only where the coarser one is not uniform) on this machine; every pixel
                # on a Dask cluster (the refinement is untested there).
                for upd in iter_chart(spec, cancel=cancelled, executor=executor_for(scheduler, warm_all),
                                      refine=scheduler is None):  # fmt: skip
                    now = time.perf_counter()
                    if now - last[0] > REFRESH:
                        last[0] = now
                        snap = _copy(upd.chart)  # the pixels computed: the picture fills the rest (_show)
                        emit(lambda c=snap, u=upd: self._show(c, u.done_tiles, u.total_tiles))
            except SchedulerError as exc:  # unreachable or unusable cluster: say so in the tab
                emit(lambda msg=str(exc): self.set_view(message="not computed", progress=None, error=msg))
                return
            if upd is not None:
                final = upd.chart
                emit(lambda: self._show(final, upd.done_tiles, upd.total_tiles, final=True))
            if upd is None or not curves or cancelled():
                return
            emit(lambda: self.set_view(message=self.view["message"] + "; following the boundaries…"))
            parts = chart_boundaries(final, cancel=cancelled)
            if not cancelled(wait=False):
                emit(lambda: self._curves(parts))

        self._start(job, f"computing on {scheduler}…" if scheduler else "computing…")

    def _label(self, x: str, y: str) -> None:
        if self._fig is not None:
            self._fig.xaxis.axis_label, self._fig.yaxis.axis_label = x, y

    def _show(self, chart, done: int, total: int, final: bool = False) -> None:
        self.chart = chart
        # While it runs, a pixel not computed yet shows its nearest computed coarser one (never in the download).
        drawn = chart if final else chart.filled()
        code = drawn.code()[..., 0]
        idx = np.zeros(code.shape)
        per = code > 0
        idx[per] = np.minimum(code[per], len(_PERIOD_COLORS))
        for n, name in enumerate(_OTHER):
            idx[code == -REGIMES.index(name)] = len(_PERIOD_COLORS) + 1 + n
        idx[~drawn.computed] = 0
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
        self._mark()
        result: list[str] = []
        if final:
            counts = chart.counts()
            classified = sum(v for k, v in counts.items() if k.startswith("period_") or k in _CLASSIFIED)
            summary = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in counts.items())
            result = [f"pixels: {summary}"] if classified else [
                f"No pixel could be classified: every one failed or was invalid ({summary})."]  # fmt: skip
            inferred = int(chart.inferred.sum()) if chart.inferred is not None else 0
            if classified and inferred:
                result.append(f"{inferred} of {chart.inferred.size} pixels filled from a uniform neighbourhood "
                              "(refinement: only where neighbours differ are finer pixels computed)")  # fmt: skip
            result.append(f"numerics: {self.ran_with}")
        self.set_view(download=True, result=result)
        self.set_progress(done, total, f"{done}/{total} tiles" + ("" if not final or chart.completed else " (stopped)"))

    def _curves(self, parts) -> None:
        self.boundaries = parts
        xs, ys, colours, kinds, dashes = [], [], [], [], []
        for c in [c for cont in parts for c in cont.curves]:
            if len(c.rows) < 2:
                continue
            rows = np.array(c.rows)
            xs.append(rows[:, 0].tolist())
            ys.append(rows[:, 1].tolist())
            colour, _, words = CURVE_STYLE.get(c.kind, ("#7f7f7f", "grey", c.kind.replace("_", " ")))
            colours.append(colour)
            kinds.append(f"{words} of the period-{c.period} cycle")
            dashes.append(curve_dash(c.period))
        self.curves.data = {"xs": xs, "ys": ys, "color": colours, "kind": kinds, "dash": dashes}
        names = (self.chart.spec.x_param, self.chart.spec.y_param) if self.chart is not None else ("x", "y")
        points = codim2_points(parts)
        self.codim2.data = {
            "x": [c.values[0] for c in points], "y": [c.values[1] for c in points],
            "marker": [codim2_style(c.kind)[0] for c in points], "color": [codim2_style(c.kind)[1] for c in points],
            "label": [f"{c.kind} ({CODIM2_NAMES.get(c.kind, c.kind)})" for c in points],
            "name": [f"{c.kind} ({CODIM2_NAMES.get(c.kind, c.kind)}) of the period-{c.period} orbit" for c in points],
            "values": [f"({names[0]}, {names[1]}) = ({c.values[0]:.10g}, {c.values[1]:.10g}) ± {c.error:.1g}"
                       for c in points],
        }  # fmt: skip
        if self._fig is not None:
            self._fig.legend.visible = bool(xs or points)
        lines = list(self.view["result"])
        n_bif = sum(len(cont.bifurcations) for cont in parts)
        # The colours of the curves drawn, and only those (the help promised magenta folds on charts without any).
        drawn = [k for k in CURVE_STYLE if any(c.kind == k and len(c.rows) >= 2 for cont in parts for c in cont.curves)]
        key = ", ".join(f"{CURVE_STYLE[k][2]}: {CURVE_STYLE[k][1]}" for k in drawn)
        periods = sorted({c.period for cont in parts for c in cont.curves if len(c.rows) >= 2})
        if len(periods) > 1:  # the curves of one kind differ by their dash
            key += "; by period: " + ", ".join(f"{p} {dict(CURVE_DASHES.values())[curve_dash(p)]}" for p in periods)
        lines.append(f"boundaries: {len(xs)} curves" + (f" ({key})" if key else "") + f" from {n_bif} "
                     "bifurcations of the stable cycles of periods 1-3 of the chart")  # fmt: skip
        if xs:
            lines += codim2_lines(parts, names)
        lines += [m for cont in parts for m in cont.messages][:2]
        lines += [loss.line() for cont in parts for loss in cont.lost][:3]
        self.set_view(result=lines, message=self.view["message"].replace("; following the boundaries…", ""))

    def _mark(self) -> None:
        """Mark the current values of the chart's two parameters (document thread)."""
        if self.chart is None:
            self.current.data = {"x": [], "y": []}
            return
        st, spec = self.session.state, self.chart.spec
        self.current.data = {"x": [float(getattr(st, spec.x_param))], "y": [float(getattr(st, spec.y_param))]}

    def pixel_centre(self, x: float, y: float) -> tuple[float, float] | None:
        """The centre of the chart's pixel under (x, y); None outside the chart."""
        if self.chart is None:
            return None
        spec = self.chart.spec
        xs, ys = np.asarray(spec.x_values), np.asarray(spec.y_values)
        dx = (xs[-1] - xs[0]) / max(1, xs.size - 1)
        dy = (ys[-1] - ys[0]) / max(1, ys.size - 1)
        i, j = round((x - xs[0]) / dx), round((y - ys[0]) / dy)
        if not (0 <= i < xs.size and 0 <= j < ys.size):
            return None
        return float(xs[i]), float(ys[j])

    def _on_tap(self, event) -> None:
        """A click on a pixel sets those two parameters to the pixel's centre; the section recomputes."""
        try:  # what no pointer sends (text, NaN, 1e300) is refused as the section plot's clicks are
            x, y = plot_point(event.x, event.y)
        except ParameterError:
            return
        centre = self.pixel_centre(x, y)
        if centre is None:
            return
        spec, st = self.chart.spec, self.session.state
        values = {spec.x_param: centre[0], spec.y_param: centre[1]}
        try:
            st.system(**values)  # the same check a typed value gets
        except ParameterError as exc:  # a pixel whose system is invalid: keep the state, say why
            self.fail(f"{spec.x_param} = {centre[0]:g}, {spec.y_param} = {centre[1]:g}: {exc}")
            return
        self.set_view(error="")
        st.param.update(**values, scene="custom")

    def npz_bytes(self) -> bytes | None:
        """The chart on screen as NPZ; None before there is one (the download is disabled then)."""
        file = self.file("chart")
        return None if file is None else file.data

    def file(self, what: str, probe: bool = False) -> Download | None:
        """``chart``: the chart on screen as ``bilimovich chart --out x.npz`` writes it (``chart-partial.npz`` and
        ``complete`` False, ``computed`` False where no pixel was computed, after a Stop), with the bifurcation
        curves drawn on it (:meth:`~explorer_core.analyses.continuation.Boundaries.npz_entries`; not followed:
        none, ``curves_complete`` False and why in ``curves_lost``, the file ``-partial``)."""
        if self.chart is None or what != "chart":
            return None
        if probe:
            return self.chart
        pixels = result_file(self.chart, "chart", ".npz")
        with np.load(io.BytesIO(pixels.data)) as z:
            entries = {name: z[name] for name in z.files}
        curves = self.boundaries if self.boundaries is not None else Boundaries()
        entries.update(curves.npz_entries())
        if self.boundaries is None and self.follows:
            why = "the chart was stopped" if not self.chart.completed else "stopped before their end"
            entries.update(curves_complete=False, curves_lost=json.dumps(
                [Loss("bifurcation curves", 1, f"not followed: {why}").as_dict()]))  # fmt: skip
        partial = pixels.name.endswith("-partial.npz") or (not bool(entries["curves_complete"]) and self.follows)
        data = written("chart.npz", lambda path: export.write_npz(path, **entries))
        return Download(named("chart", ".npz", partial), MIME[".npz"], data)


def _copy(chart):
    """A copy of a chart still being computed (the job goes on adding to its arrays)."""
    return dataclasses.replace(chart, regime=chart.regime.copy(), period=chart.period.copy(), lyap=chart.lyap.copy(),
                               status=chart.status.copy(), computed=chart.computed.copy(), errors=dict(chart.errors),
                               inferred=chart.inferred.copy())  # fmt: skip


_SWEPT = ("alpha", "I11", "I22", "I33", "I12", "I13", "I23", "g0", "g1", "g2", "omega")


def branch_lines(cont, col: int) -> tuple[dict[str, list], dict[str, list]]:
    """Continued branches as polylines (every point of each orbit): stable and unstable pieces.

    A segment is stable if either end is (the bifurcation points are on the branch, where the
    stability changes), so the pieces meet there.
    """
    out = ({"xs": [], "ys": []}, {"xs": [], "ys": []})
    if cont is None:
        return out
    for br in cont.branches:
        vals = np.array(br.values)
        if vals.size < 2:
            continue
        st = br.stable
        solid = st[:-1] | st[1:]
        orbit = np.array(br.orbits)  # (m, n, 2)
        for j in range(br.period):
            y = orbit[:, j, col]
            start = 0
            for i in range(1, solid.size + 1):
                if i == solid.size or solid[i] != solid[start]:
                    d = out[0 if solid[start] else 1]
                    d["xs"].append(vals[start : i + 1].tolist())
                    d["ys"].append(y[start : i + 1].tolist())
                    start = i
    return out
