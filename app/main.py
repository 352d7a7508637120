"""The Bilimovich Explorer web app: ``panel serve app/main.py`` (or ``bilimovich serve``).

Layout: a sidebar with the scene selector, sliders for the system, the numerics
and the layers; the main area with the (q, r) plane (section points streamed as
they are computed, equilibrium tracks, the T' map) and the k-series of the
selected trajectory. The URL carries the whole state.
"""

from __future__ import annotations

import contextlib
import html
import logging
from typing import Any

import panel as pn
from bokeh.events import RangesUpdate, Tap
from panel.io.document import unlocked
from panel.io.state import set_curdoc

from app import warm
from app.analyses import BifurcationTab, ChartTab, LyapunovTab
from app.bench_tab import BenchTab
from app.controller import ExplorerSession
from app.runner import WARM, Runner
from app.state import SLIDER_RANGES, SYSTEM_FIELDS, ExplorerState, state_from_query
from app.views import ERROR_STYLE, TYPE_COLORS, SectionFigure, SeriesFigures
from explorer_core.scenes import get_scene

log = logging.getLogger(__name__)

pn.extension(notifications=False)

#: Style of the reliability warnings (errors use ERROR_STYLE).
WARNING_STYLE = "color:#664d03;background:#fff3cd;border:1px solid #ffecb5;border-radius:4px;padding:6px 10px"

LABELS = {
    "alpha": "α (constraint p − g q = α)",
    "g0": "g0  (g = g0 + g1 cos Ωt + g2 sin Ωt)",
    "g1": "g1",
    "g2": "g2",
    "omega": "Ω (forcing frequency)",
    "t0": "t0 (section phase)",
}


def _undebounced(widget: pn.widgets.Widget, *attrs: str) -> None:
    """Apply these browser changes at once (Panel debounces every change by ``_debounce`` ms)."""
    widget._priority_changes = [*widget._priority_changes, *attrs]


def _slider(state: ExplorerState, field: str) -> pn.widgets.EditableFloatSlider:
    lo, hi, step = SLIDER_RANGES[field]
    w = pn.widgets.EditableFloatSlider(
        label=LABELS.get(field, field),
        start=lo,
        end=hi,
        step=step,
        value=float(getattr(state, field)),
        fixed_start=None,
        fixed_end=None,
        format="0[.]000",
        sizing_mode="stretch_width",
        css_classes=[f"ctl-{field}"],
    )

    # A release is one event: skip Panel's 50 ms debounce of browser changes, which was a third
    # of the time to first points. A release that comes while the drag's last `value` waits out
    # its debounce joins it, so that debounce is short too (the drag's values still coalesce).
    _undebounced(w._slider, "value_throttled")
    _undebounced(w._value_edit, "value")
    w._slider._debounce = 15

    # Recompute on release (value_throttled), not on every pixel of a drag.
    def to_state(event: Any) -> None:
        if getattr(state, field) != event.new:
            state.param.update(**{field: float(event.new), "scene": "custom"})

    w.param.watch(to_state, "value_throttled")
    state.param.watch(lambda e: setattr(w, "value", float(e.new)), field)
    return w


def _int_input(state: ExplorerState, field: str, label: str) -> pn.widgets.IntInput:
    p = state.param[field]
    lo, hi = p.bounds
    w = pn.widgets.IntInput(label=label, value=getattr(state, field), start=lo, end=hi, sizing_mode="stretch_width",
                            css_classes=[f"ctl-{field}"])  # fmt: skip
    w.param.watch(lambda e: setattr(state, field, int(e.new)) if e.new is not None else None, "value")
    state.param.watch(lambda e: setattr(w, "value", int(e.new)), field)
    return w


def create_app() -> pn.template.FastListTemplate:
    """Build one session's page."""
    warm.start()
    query = dict(pn.state.location.query_params) if pn.state.location else {}
    state, url_errors = state_from_query(query)
    doc = pn.state.curdoc
    location = pn.state.location

    def deliver(fn) -> None:
        if doc is None:
            fn()
            return

        def run() -> None:
            # One websocket message for everything fn changes (points, status, series...): the
            # browser then applies, lays out and paints once, not once per model change.
            with set_curdoc(doc), unlocked():
                fn()

        doc.add_next_tick_callback(run)

    def publish(q: dict[str, str]) -> None:
        if location is not None:
            location.update_query(**q)

    def connected() -> bool:
        # A closed tab drops its websocket at once, but Bokeh discards the session only after
        # --unused-session-lifetime: stop its jobs now (Bokeh's ServerSession has no public hook).
        server_session = getattr(doc.session_context, "_session", None) if doc is not None else None
        return server_session is None or server_session.connection_count > 0

    runner = Runner(
        deliver,
        on_error=lambda ch, exc: setattr(session, "error", f"{ch} computation failed: {exc}"),
        alive=connected,
    )
    fig = SectionFigure(state.q_range, state.r_range)
    series = SeriesFigures()
    session = ExplorerSession(state, runner, fig, series, on_query=publish)

    # --- sidebar ------------------------------------------------------------------------------
    scene_select = pn.widgets.Select(
        label="Scene (the paper's figures)", options=["custom", *state.scene_ids()], value=state.scene,
        css_classes=["ctl-scene"],
    )  # fmt: skip
    scene_info = pn.pane.Markdown("", sizing_mode="stretch_width", css_classes=["scene-info"])

    def show_scene_info(sid: str) -> None:
        if sid == "custom":
            scene_info.object = "*Custom parameters.*"
        else:
            s = get_scene(sid)
            scene_info.object = f"**{html.escape(s.figure)}** — {html.escape(s.title)}. {html.escape(s.shows)}"

    def on_scene(event: Any) -> None:
        if event.new != "custom" and event.new != state.scene:
            session.apply_scene(event.new)
        show_scene_info(event.new)

    scene_select.param.watch(on_scene, "value")
    state.param.watch(lambda e: setattr(scene_select, "value", e.new), "scene")
    show_scene_info(state.scene)

    error_box = pn.pane.HTML("", visible=False, sizing_mode="stretch_width", css_classes=["error-box"])

    def show_error(*_: Any) -> None:
        msgs = [m for m in [session.error, *url_errors] if m]
        error_box.object = f'<div style="{ERROR_STYLE}">' + "<br>".join(html.escape(m) for m in msgs) + "</div>"
        error_box.visible = bool(msgs)

    session.param.watch(show_error, "error")
    show_error()

    sliders = {f: _slider(state, f) for f in SYSTEM_FIELDS}
    method = pn.widgets.Select.from_param(state.param.method, label="Method", css_classes=["ctl-method"])
    accuracy = pn.widgets.RadioButtonGroup.from_param(state.param.accuracy, label="Accuracy")
    accuracy_help = pn.pane.Markdown(
        "<small>Accuracy — *plot*: tolerance tied to the pixel size (error under a quarter pixel on "
        "regular orbits); *high*: tolerance 1e-12.</small>"
    )
    n_random = _int_input(state, "n_random", "Random initial conditions")
    periods = _int_input(state, "periods", "Periods (section points each)")
    transient = _int_input(state, "transient", "Transient periods (dropped)")
    seed = _int_input(state, "seed", "Random seed")
    steps = _int_input(state, "steps_per_period", "RK4 steps per period")
    show_tracks = pn.widgets.Checkbox.from_param(state.param.show_tracks, label="Equilibrium tracks over one period")
    show_tp = pn.widgets.Checkbox.from_param(state.param.show_tprime, label="T′ map under the points")
    tp_kind = pn.widgets.RadioButtonGroup.from_param(state.param.tprime_kind, label="T′ map")
    click_mode = pn.widgets.RadioButtonGroup(label="Click in the plot", options=["add trajectory", "select trajectory"],
                                             value="add trajectory")  # fmt: skip
    stop = pn.widgets.Button(label="Stop", button_type="warning", css_classes=["ctl-stop"])
    stop.on_click(lambda e: session.stop())
    clear = pn.widgets.Button(label="Clear clicked points", css_classes=["ctl-clear"])
    clear.on_click(lambda e: session.clear_clicked())
    download = pn.widgets.FileDownload(callback=session.csv_bytes, filename="section.csv", label="Download section CSV",
                                       button_type="primary")  # fmt: skip
    selected = _int_input(state, "selected", "Trajectory shown below")

    # --- main area ------------------------------------------------------------------------------
    status = pn.pane.Str("", css_classes=["status-line"], sizing_mode="stretch_width")
    warming = pn.pane.Alert(
        "The server is warming up (compiling the numerical kernels); the first points will appear in a moment.",
        alert_type="warning",
        visible=not WARM.is_set(),
        css_classes=["warming"],
    )

    def show_status(*_: Any) -> None:
        text = session.status
        if session.escaped:
            ids = ", ".join(str(i) for i in session.escaped[:12]) + (" …" if len(session.escaped) > 12 else "")
            text += f"  |  escaped (noncompact drift, left the bound): {ids}"
        if session.failed:
            text += f"  |  failed: {', '.join(str(i) for i in session.failed[:12])}"
        status.object = text
        if WARM.is_set() and warming.visible:
            warming.visible = False

    session.param.watch(show_status, ["status", "escaped", "failed"])

    # When the method is unreliable for this scene (explorer_core.analyses.reliability): escaped text, one box each.
    reliability = pn.pane.HTML("", visible=False, sizing_mode="stretch_width", css_classes=["reliability-warning"])

    def show_reliability(*_: Any) -> None:
        items = session.reliability
        reliability.object = "".join(
            f'<div style="{ERROR_STYLE if w["level"] == "error" else WARNING_STYLE};margin-bottom:4px" '
            f'class="reliability-{html.escape(w["level"])}"><b>{html.escape(w["level"])}</b>: '
            f"{html.escape(w['message'])}</div>"
            for w in items
        )
        reliability.visible = bool(items)

    session.param.watch(show_reliability, "reliability")
    show_reliability()

    def on_tap(event: Tap) -> None:
        if click_mode.value == "add trajectory":
            session.add_initial_condition(event.x, event.y)
        else:
            session.select_nearest(event.x, event.y)

    fig.fig.on_event(Tap, on_tap)

    def on_ranges(event: RangesUpdate) -> None:
        if None not in (event.x0, event.x1, event.y0, event.y1):
            session.set_view_from_plot((event.x0, event.x1), (event.y0, event.y1))

    fig.fig.on_event(RangesUpdate, on_ranges)

    legend = " ".join(f'<span style="color:{c}">◆</span> {t}' for t, c in TYPE_COLORS.items() if t != "degenerate")
    sidebar = [
        scene_select,
        scene_info,
        error_box,
        pn.pane.Markdown("### Inertia tensor"),
        *(sliders[f] for f in ("I11", "I22", "I33", "I12", "I13", "I23")),
        pn.pane.Markdown("### Constraint and forcing"),
        *(sliders[f] for f in ("alpha", "g0", "g1", "g2", "omega", "t0")),
        pn.pane.Markdown("### Numerics"),
        method,
        accuracy,
        accuracy_help,
        steps,
        n_random,
        seed,
        periods,
        transient,
        pn.pane.Markdown("### Layers"),
        show_tracks,
        show_tp,
        tp_kind,
    ]
    section_tab = pn.Column(
        warming,
        pn.Row(click_mode, stop, clear, download, sizing_mode="stretch_width"),
        status,
        reliability,
        pn.pane.Bokeh(fig.fig, sizing_mode="stretch_width", height=650),
        pn.pane.HTML(f"<small>Equilibria (frozen field at t0; tracks over one period): {legend}</small>"),
        selected,
        pn.Row(*(pn.pane.Bokeh(f, sizing_mode="stretch_width") for f in series.figs), sizing_mode="stretch_width"),
        sizing_mode="stretch_width",
    )
    # The analysis tabs are built when first opened, and only the open tab is in the browser:
    # a session's page is built on the server's one event loop, so a class opening the page at
    # once waits for all of them (this cuts that time by ~45%, docs/load.md).
    analyses = {
        "Lyapunov spectrum": LyapunovTab,
        "Bifurcation diagram": BifurcationTab,
        "Chart of regimes": ChartTab,
        "Speed vs accuracy": BenchTab,
    }
    holders = [pn.Column(sizing_mode="stretch_width", css_classes=["analysis-tab"]) for _ in analyses]
    tabs = pn.Tabs(
        ("Poincaré section", section_tab),
        *zip(analyses, holders, strict=True),
        sizing_mode="stretch_width",
        dynamic=True,
    )

    def open_tab(event: Any) -> None:
        if event.new >= 1 and not holders[event.new - 1].objects:
            holders[event.new - 1].objects = [list(analyses.values())[event.new - 1](session).panel()]

    tabs.param.watch(open_tab, "active")
    main = [tabs]
    template = pn.template.FastListTemplate(
        title="Bilimovich Explorer",
        sidebar=sidebar,
        main=main,
        sidebar_width=340,
        accent="#2c5f8a",
        theme_toggle=False,
    )

    def destroyed(ctx: Any) -> None:
        # Only closure variables and local imports here: Bokeh has already emptied this
        # script's module (one per session) when the session is destroyed.
        from panel.links import Callback

        runner.close()
        # Panel keeps jscallbacks (the sliders' number boxes have one) in a class-level
        # WeakKeyDictionary whose values refer back to their keys, so nothing of a closed
        # session (widgets, figures, points) would ever be freed: ~3 MB per closed tab.
        for root in (*template.sidebar, *template.main):
            for obj in root.select():
                Callback.registry.pop(obj, None)

    pn.state.on_session_destroyed(destroyed)

    def start() -> None:
        session.recompute()
        # A pane's first update gives it its stylesheets, which makes Bokeh re-walk the whole
        # document (~50 ms of the event loop all sessions share): do it now, not at the user's
        # first move, when a class moving sliders together would queue 30 of them (docs/load.md).
        scene_info.param.trigger("object")

    # Start once the page is loaded, so the first chunk streams into a live plot.
    pn.state.onload(start)
    return template


if __name__.startswith("bokeh_app") or __name__ == "__main__":
    # One recompute of the document's model graph instead of one per root the template adds:
    # halves the time a new session holds the server's event loop (every other session waits).
    with pn.state.curdoc.models.freeze() if pn.state.curdoc is not None else contextlib.nullcontext():
        create_app().servable(title="Bilimovich Explorer")
