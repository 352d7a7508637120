"""One session's page: the state, its jobs, the figures, the analysis tabs and the component.

:class:`Page` wires :class:`~app.controller.ExplorerSession` (the section) and the analysis
tabs to :class:`~app.ui.ExplorerUI` (what the browser draws). It needs no server: the tests
build one with a call-through ``deliver`` and drive it with the same messages a browser sends
(:meth:`Page.handle`). ``app/main.py`` builds one per browser tab.

What is built for a new page is only what its first view shows: the section figure and the
component (which draws the k-series from data); an analysis tab's figure is built when the tab
is first opened.

The section tab's view is the page's own (errors, the scene, the tour, the played parameter, the body) and each
layer's (:meth:`app.layers.base.Layer.view`); the page's actions and downloads that no tab answers go to the
layers (:meth:`app.controller.ExplorerSession.act`, :meth:`~app.controller.ExplorerSession.csv`). The page names
no layer. The view is rebuilt once per message from the page (:meth:`Page._one_view`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Executor
from typing import Any

from bokeh.events import RangesUpdate, Tap
from bokeh.models import Column

from app.analyses import AnalysisTab, BifurcationTab, ChartTab, LyapunovTab
from app.bench_tab import BenchTab
from app.bodyview import CHANNEL as BODY_CHANNEL
from app.bodyview import BodyView
from app.controller import ExplorerSession
from app.play import Player, Schedule
from app.runner import FairScheduler, Runner
from app.state import (
    BY_NAME,
    BY_URL,
    CONTROLS,
    LAYER_PICKS,
    NO_SELECTION,
    TABS,
    parse_query,
    plot_point,
    plot_view,
    query_value,
    state_from_query,
)
from app.tours import TOURS, Tour, TourError, nearest_step, parse_tours, read_tour_url
from app.ui import ExplorerUI, FigurePane
from app.views import SPARES, SeriesData
from app.words import page_words
from explorer_core.scenes import get_scene
from explorer_core.system.params import ParameterError

log = logging.getLogger(__name__)

TAB_CLASSES: dict[str, type[AnalysisTab]] = {
    "lyapunov": LyapunovTab,
    "bifurcation": BifurcationTab,
    "chart": ChartTab,
    "bench": BenchTab,
}
#: The runner's channel of the figures' drawing (a heavy job: a niced thread).
FIGURE_CHANNEL = "figure"
#: Scenes whose figure is an analysis tab's picture (scene.extra key -> tab), and the tabs' names as shown.
SCENE_TABS = {"sweep": "bifurcation", "chart": "chart"}
TAB_NAMES = {"bifurcation": "Bifurcation diagram", "chart": "Chart of regimes"}
#: What a tour's step starts from besides its scene: the layers' settings and picks, the played parameter and the
#: tab as on a new page (a step sets what it needs over them).
STEP_DEFAULTS: dict[str, Any] = {
    **{c.name: c.default for c in CONTROLS if c.area in ("layers", "play", "body")},
    **{name: p.default for name, p in LAYER_PICKS.items()}, "tab": "section",
}  # fmt: skip
#: The body view's settings as on a new page, set as a new page has them (unchecked: 'box' there means the box when
#: one has the moments, the ellipsoid else; a step's own value is checked as a link's).
BODY_DEFAULTS: dict[str, Any] = {c.name: c.default for c in CONTROLS if c.area == "bodyview"}


class Page:
    """Everything of one browser tab. ``deliver`` runs a callable on the document's thread."""

    def __init__(
        self,
        query: Mapping[str, Any],
        deliver: Callable[[Callable[[], None]], None],
        *,
        publish_url: Callable[[dict[str, str]], None] | None = None,
        alive: Callable[[], bool] | None = None,
        executor: Executor | None = None,
        scheduler: FairScheduler | None = None,
        schedule: Schedule | None = None,
        wait_for_browser: bool = False,
    ) -> None:
        self.deliver = deliver
        state, self.url_errors = state_from_query(query)
        self.state = state
        self.runner = Runner(deliver, on_error=self._job_failed, executor=executor, scheduler=scheduler, alive=alive,
                             on_busy=self._on_busy)  # fmt: skip
        self.fig = SPARES.take(state.q_range, state.r_range)
        self.series = SeriesData(on_change=self._on_series)
        self.session = ExplorerSession(state, self.runner, self.fig, self.series, on_query=publish_url)
        self.tabs: dict[str, AnalysisTab] = {}
        self.messages: dict[str, str] = {}
        #: Tab -> why the figure asked for last was not sent (shown among the tab's errors until the next one), and
        #: the tab of the figure asked for last.
        self.figure_problems: dict[str, str] = {}
        self._figure_tab = "section"
        #: While a message from the page is handled (else None): whether the view is to be rebuilt at its end, and
        #: whether even while a played frame is computed (``force``).
        self._view_due: dict[str, bool] | None = None
        self.player = Player(self.session, schedule or _timer(deliver), on_change=lambda: self._refresh_views(),
                             wait_for_browser=wait_for_browser)  # fmt: skip
        #: The tours on offer: the paper's, and a teacher's own (tour_url= or an uploaded file) over them.
        self.tours: dict[str, Tour] = dict(TOURS)
        #: What the page says about the tours (shown with the tour's strip on every tab), and whether it is a problem
        #: (a file not read, a tour or a step the link names that is not there).
        self.tour_message = ""
        self.tour_problem = False
        #: The link's own ``step=`` (checked against its tour's steps when the tour is known: :meth:`start`).
        self._url_step = query_value(query, "step")
        #: Tab -> (tour, step) whose Run the tour pressed there: not pressed again while that run computes or stands.
        self._step_runs: dict[str, tuple[str, int]] = {}
        self._analysis_box = Column(sizing_mode="stretch_both", name="analysis_box")
        #: The body in 3-D of the selected trajectory (computed once, animated by the page).
        self.body = BodyView(self.session, self._ship_body, on_change=lambda: self._refresh_views())
        self.ui = ExplorerUI(
            on_message=self.handle,
            values=self._values(),
            view={"section": self._section_view()},
            tab=state.tab,
            presentation=state.presentation,
            section_plot=FigurePane(self.fig.fig, sizing_mode="stretch_both"),
            analysis_plot=FigurePane(self._analysis_box, sizing_mode="stretch_both"),
            sizing_mode="stretch_both",
        )
        if state.presentation:
            self.fig.set_presentation(True)
        state.param.watch(self._on_state, [p for p in state.param if p != "name"])
        # Every session field changes what the section tab shows (what the layers publish included).
        self.session.param.watch(self._on_session, [p for p in self.session.param if p != "name"])
        self.fig.fig.on_event(Tap, self._on_tap)
        self.fig.fig.on_event(RangesUpdate, self._on_ranges)

    # --- lifecycle ------------------------------------------------------------------------------

    def start(self) -> None:
        """The page is loaded: compute the section (and open the tab the URL names); a link to a tour's step shows
        that step (a step it does not have: the nearest, and says so)."""
        st = self.state
        # The link's words about its tour are said with the tour (on every tab), not among the section's errors.
        # (A refused step=: a tour shown says it in nearest_step's words; without a tour it stays with the errors.)
        problems = [e for e in self.url_errors if _url_key(e) in ("tour", "tour_url")]
        self.url_errors = [e for e in self.url_errors if e not in problems]
        file_read = not st.tour_url or self._load_tours(lambda: read_tour_url(st.tour_url))
        info = self.tour_message if file_read else ""
        if not file_read:
            problems.append(self.tour_message)
        tour = self.tours.get(st.tour) if st.tour else None
        if st.tour and tour is None:
            why = "no tour {!r}" if file_read else "{!r} is not shown: it was to come from that file"
            problems.append("URL parameter tour: " + why.format(st.tour))
            st.tour = ""
        if tour is not None:
            step, note = nearest_step(tour, self._url_step)
            self.show_tour(tour.id, step)
            problems += [note] if note else []
        else:
            self.session.recompute()
        self._say_tour("\n".join(problems) or info, problem=bool(problems))
        if st.tab != "section":
            self._open_tab(st.tab)

    def close(self) -> None:
        self.runner.close()

    # --- messages from the page -------------------------------------------------------------

    def handle(self, msg: dict[str, Any]) -> None:
        """One checked message (:func:`app.ui.check_message`), on the document's thread: the view is rebuilt once
        for it."""
        with self._one_view():
            self._handle(msg)

    def _handle(self, msg: dict[str, Any]) -> None:
        if "commit" in msg:
            self.commit(msg["commit"], msg["text"])
            return
        action = msg["action"]
        tab = msg.get("tab", "section")
        if action == "stop":
            if tab == "section":
                self.session.stop()
                self.body.stop()
            elif tab in self.tabs:
                self._step_runs.pop(tab, None)  # a tour's step coming back presses Run again
                self.tabs[tab].stop()
        elif action == "run" and tab in TAB_CLASSES:
            self._step_runs.pop(tab, None)
            self._open_tab(tab).run()
        elif action == "clear":
            self.session.clear_clicked()
        elif action == "tab" and tab in TABS:
            self.state.tab = tab
        elif action == "presentation" and "on" in msg:
            self.state.presentation = msg["on"]
        elif action == "download" and msg.get("what") == "figure":
            self._figure(tab, msg.get("value", ""))
        elif action == "download":
            self._download(msg.get("what", ""))
        elif action == "play":
            self.player.play()
            self._refresh_views(force=True)  # the page shows it plays now, not when the first frame is computed
        elif action == "pause":
            self.player.pause()
        elif action == "step":
            self.player.step()
        elif action == "shown" and msg.get("value", "").isdigit():
            self.player.shown(int(msg["value"]))
        elif action == "tour":
            self._say_tour("")
            self.show_tour(msg.get("value", ""), 1)
        elif action == "tour_step" and msg.get("value") in ("next", "back"):
            self._say_tour("")
            self.show_tour(self.state.tour, self.state.tour_step + (1 if msg["value"] == "next" else -1))
        elif action == "tour_file":
            self._load_tours(lambda: parse_tours(msg.get("value", ""), "the uploaded file"))
        elif action == "load_bench":
            self._open_tab("bench").load_results(quiet=False)  # type: ignore[attr-defined]
        elif action == "bench_choice":
            problem = self._open_tab("bench").choose(msg.get("value"))  # type: ignore[attr-defined]
            if problem:
                self.tabs["bench"].fail(problem)
        else:
            self.session.act(action)  # a layer's button (e.g. "Find orbits in view"), if a layer has it

    def commit(self, name: str, text: Any) -> str | None:
        """A typed value: applied, or refused with a message next to the control and in the main area. The view is
        rebuilt once for it (a slider's move redoes the section and its layers: each says it computes)."""
        with self._one_view():
            return self._commit(name, text)

    def _commit(self, name: str, text: Any) -> str | None:
        problem = self.session.commit(name, text)
        if problem:
            self.messages[name] = problem
        else:
            self.messages.pop(name, None)
            if name == "scene":  # a new scene sets every control: no earlier refusal is about a value in use
                self.messages.clear()
                self.url_errors = []
            self.url_errors = [e for e in self.url_errors if not _about(e, name)]
        self.ui.param.update(messages=dict(self.messages), committed=name, revision=self.ui.revision + 1,
                             values=self._values())  # fmt: skip
        self._refresh_views()
        return problem

    def _download(self, what: str) -> None:
        """The file ``what`` of the analysis tab that offers it (:meth:`app.analyses.AnalysisTab.file`), else of the
        layer that does (:meth:`app.controller.ExplorerSession.download`); nothing when none is on screen. Its name
        ends in ``-partial`` when its run was stopped (the file says what was lost)."""
        tab = next((t for t in self.tabs.values() if what in t.downloads), None)
        file = tab.file(what) if tab is not None else self.session.download(what)
        if file is not None:
            self.ui.send_download(file.name, file.mime, file.data)

    def _figure(self, tab: str, value: str) -> None:
        """The figure of the tab's main plot (``value``: format, size and resolution, :func:`app.figures.parse_request`)
        as the file :func:`app.figures.figure_file` writes, sent like the other downloads (no prompt); a refused
        request or a tab with nothing drawn yet says why among the tab's errors. It is drawn on the runner (channel
        ``figure``: a niced thread), not on the document's thread: 1-2 s of drawing (the first: 3-6 s with the
        imports) would hold up every page of the server."""
        if tab not in TABS:  # not from our page
            return
        self.figure_problems.pop(tab, None)
        self._figure_tab = tab
        # What the picture reads that the document thread changes in place: the section's points (a copy now). The
        # rest (results, orbit and manifold lists, ranges) is replaced, never changed, on the document thread.
        data = self.session.data() if tab == "section" else None
        source = self.tabs.get(tab)
        about_state = self.state

        def job(cancelled: Callable[..., bool], emit: Callable[[Callable[[], None]], None]) -> None:
            from app import figures  # HoloViews and matplotlib: loaded when the first figure is asked for

            try:
                request = figures.parse_request(value)
            except ParameterError as exc:
                emit(lambda msg=str(exc): self._figure_problem(tab, msg))
                return
            with figures.DRAWING:
                if tab == "section":
                    picture = figures.section_picture(self.session, data)
                else:
                    picture = figures.tab_picture(source) if source is not None else None
                file = figures.figure_file(picture, tab, request, figures.settings_words(about_state))
            if file is None:
                emit(lambda: self._figure_problem(tab, "no figure yet: nothing is drawn on this tab (press Run first)"))
            else:
                emit(lambda: self.ui.send_download(file.name, file.mime, file.data))

        self._refresh_views()
        self.runner.start(FIGURE_CHANNEL, job, bump=False)  # every figure asked for is sent

    def _figure_problem(self, tab: str, message: str) -> None:
        self.figure_problems[tab] = message
        self._refresh_views()

    # --- tours ----------------------------------------------------------------------------------------

    def show_tour(self, tour_id: str, step: int) -> None:
        """Show step ``step`` (from 1) of a tour: its settings on top of its scene, its marks on the plot, the
        tour and step in the URL, and its tab's Run pressed when the step says so; an empty id closes the tour (the
        settings stay)."""
        if self.player.playing:
            self.player.pause()
        tour = self.tours.get(tour_id)
        if tour is None:
            self.fig.set_marks([])
            self.state.param.update(tour="", tour_step=1)
            self.session._publish_query()
            self._refresh_views()
            return
        step = min(max(1, step), len(tour.steps))
        s = tour.steps[step - 1]
        updates, _ = parse_query(s.settings)  # checked when the file was loaded
        # Each step stands alone (a link to it shows the same): the layers and the tab as a new page has them,
        # then the step's settings over its scene.
        fresh = {n: v for n, v in BODY_DEFAULTS.items() if n not in updates}
        self.session.apply_settings(tour.scene, {**STEP_DEFAULTS, **updates}, tour=tour.id, tour_step=step, **fresh)
        self.fig.set_marks([(m.q, m.r, m.label) for m in s.look])
        self.messages.clear()
        self.url_errors = []
        self.ui.values = self._values()
        if s.run:
            self._press_run(s.tab, (tour.id, step))
        self._refresh_views()

    def _press_run(self, name: str, step: tuple[str, int]) -> None:
        """A tour's step presses its tab's Run; not again when that step's run is on the tab (computing, or done:
        going back to the step shows it). The user's Run or Stop there, or a failure, lets the step press it again."""
        if self._step_runs.get(name) == step:
            return
        self._step_runs.pop(name, None)
        self._open_tab(name).run()
        if self.runner.busy(name):
            self._step_runs[name] = step

    def _say_tour(self, message: str, problem: bool = False) -> None:
        self.tour_message, self.tour_problem = message, problem
        self._refresh_views()

    def _load_tours(self, read: Callable[[], dict[str, Tour]]) -> bool:
        """Add a teacher's tours to the paper's (``read``: the file's); whether they were read (the page says what
        was loaded or why not)."""
        try:
            own = read()
        except (TourError, OSError) as exc:
            self._say_tour(str(exc), problem=True)
            return False
        self.tours = {**TOURS, **own}
        n = f"{len(own)} tours" if len(own) > 1 else "1 tour"
        self._say_tour(f"loaded {n}: {', '.join(t.title for t in own.values())}"[:300])
        return True

    def _tour_view(self) -> dict[str, Any]:
        st = self.state
        out: dict[str, Any] = {"choices": [[t.id, t.title] for t in self.tours.values()], "message": self.tour_message,
                               "problem": self.tour_problem}  # fmt: skip
        tour = self.tours.get(st.tour)
        if tour is not None:
            step = min(st.tour_step, len(tour.steps))
            s = tour.steps[step - 1]
            # plays: the step sets up a played parameter (its row stays in presentation mode)
            out.update(id=tour.id, title=tour.title, step=step, steps=len(tour.steps), text=s.text,
                       plays=any(k.startswith("play") for k in s.settings))  # fmt: skip
        return out

    # --- the figures' events --------------------------------------------------------------------

    def _on_tap(self, event: Tap) -> None:
        if event.x is None or event.y is None:
            return
        try:
            x, y = plot_point(event.x, event.y)  # a client may send any JSON here; no pointer gives more
        except ParameterError as exc:
            log.debug("refused a click: %s", exc)
            return
        mode = self.state.click_mode
        with self._one_view():
            if mode == "add":
                self.session.add_initial_condition(x, y)
            elif not self.session.act(mode, x, y):  # a layer's mode (e.g. "finds a periodic orbit")
                self.session.select_nearest(x, y)

    def _on_ranges(self, event: RangesUpdate) -> None:
        if None in (event.x0, event.x1, event.y0, event.y1):
            return
        try:
            q_range, r_range = plot_view(event.x0, event.x1, event.y0, event.y1)  # the URL's checks of qr, rr
        except ParameterError as exc:
            log.debug("refused a view: %s", exc)  # the last valid view stays in use
            return
        self.session.set_view_from_plot(q_range, r_range)

    # --- tabs -----------------------------------------------------------------------------------

    def _open_tab(self, name: str) -> AnalysisTab:
        """The analysis tab, built on first use; its figure goes in the page when the tab is shown."""
        tab = self.tabs.get(name)
        if tab is None:
            tab = self.tabs[name] = TAB_CLASSES[name](self.session, self._publish_tab)
        if self.state.tab == name:
            fig = tab.figure()
            self.deliver(lambda: setattr(self._analysis_box, "children", [fig]))
        self._refresh_views()
        return tab

    def _publish_tab(self, name: str, view: dict[str, Any]) -> None:
        self._refresh_views()

    def _job_failed(self, channel: str, exc: BaseException) -> None:
        self._step_runs.pop(channel, None)
        if channel == FIGURE_CHANNEL:
            self._figure_problem(self._figure_tab, f"the figure could not be drawn: {exc}")
        elif channel == BODY_CHANNEL:
            self.body.failed(exc)
        elif channel in self.tabs:
            self.tabs[channel].failed(exc)
        else:
            self.session.failed_job(channel, exc)

    def _on_busy(self, channel: str) -> None:
        self.session.on_busy(channel)
        if channel in self.tabs:
            self._refresh_views()

    # --- state -> page --------------------------------------------------------------------------

    def _values(self) -> dict[str, Any]:
        return {c.name: self.state.display(c.name) for c in CONTROLS}

    def _on_state(self, *events: Any) -> None:
        names = {e.name for e in events}
        if names & set(BY_NAME):
            values = self._values()
            if values != self.ui.values:
                self.ui.values = values
        if "tab" in names:
            self.ui.tab = self.state.tab
            if self.state.tab in TAB_CLASSES:
                self._open_tab(self.state.tab)
            else:
                self._refresh_views()  # the section's URL errors leave the analysis tab's view
        if "presentation" in names:
            on = self.state.presentation
            self.ui.presentation = on
            self.deliver(lambda: self.fig.set_presentation(on))
        if names & {"scene", "selected", "clicked", "n_random"}:
            self._refresh_views()

    def _on_session(self, *events: Any) -> None:
        self._refresh_views()

    def _ship_body(self, payload: dict[str, Any]) -> None:
        """The body's series to the page once ({}: the view drops the one it shows); its point joins the plot."""
        if payload:
            self.fig.show_body_point()
        self.ui.body = payload

    def _on_series(self, data: dict[str, list[float]]) -> None:
        ui = getattr(self, "ui", None)
        if ui is not None and data != ui.series:
            ui.series = data

    def _section_view(self) -> dict[str, Any]:
        s, st = self.session, self.state
        errors = [m for m in (s.error, *self._url_errors_of("section"), self.figure_problems.get("section")) if m]
        errors += [m for n, m in self.messages.items() if BY_NAME[n].area not in TAB_CLASSES]
        if st.scene == "custom":
            info = "Custom parameters."
        else:
            sc = get_scene(st.scene)
            info = f"{sc.figure} — {sc.title}. {sc.shows}"
            for key, tab in SCENE_TABS.items():
                if key in sc.extra:  # the figure is another tab's picture: the section alone is not it
                    info += f" This figure is drawn on the '{TAB_NAMES[tab]}' tab (open it and press Run)."
        sel = st.selected
        who = " (clicked)" if sel in st.clicked_indices() else ""  # numbered after the random ones
        caption = f"Trajectory {sel}{who}: q_k, r_k and the energy T_k"
        series_note = ""  # why the k-series are empty ("": they show a trajectory's, or it has no points)
        if sel == NO_SELECTION:
            caption = "No trajectory selected: type its number above, or click one with 'selects a trajectory'"
            series_note = "no trajectory selected"
        elif sel in s.escaped:
            caption += " (escaped: its valid points)"
        elif sel in s.failed:
            caption += " (failed: its points before the failure)"
        view = {key: value for layer in s.every for key, value in layer.view().items()}
        # The numerics' warnings in the page's words (they are written for the command line's options)
        view["warnings"] = [{**w, "message": page_words(w["message"])} for w in view.get("warnings", [])]
        turning = f"Trajectory {sel}{who}: the rigid body turning" if sel != NO_SELECTION else \
            "No trajectory selected: no body to turn"  # fmt: skip
        return {
            **view,
            "errors": errors,
            "running": s.running,
            "n_clicked": len(st.clicked),
            "scene_info": info,
            "series_caption": caption,
            "series_note": series_note,
            "play": self.player.view(),
            "tour": self._tour_view(),
            "body": {**self.body.view(), "caption": turning},
        }

    def _tab_view(self, name: str) -> dict[str, Any]:
        tab = self.tabs[name]
        v = dict(tab.view)
        errors = [v.pop("error", "")] + [m for n, m in self.messages.items() if BY_NAME[n].area == name]
        # The URL's refusals of this tab's settings are shown here, where they matter (with the value used
        # instead); those of the system it analyses too while the tab is the one open.
        errors += [*self._url_errors_of(name), self.figure_problems.get(name, "")]
        if self.state.tab == name:
            errors += self._url_errors_of("section")
        v["errors"] = [e for e in errors if e]
        v["running"] = self.runner.busy(name)
        return v

    def _url_errors_of(self, tab: str) -> list[str]:
        """The URL's errors about the settings of ``tab`` ("section": every one not about an analysis tab)."""
        return [e for e in self.url_errors if _url_tab(e) == tab]

    @contextlib.contextmanager
    def _one_view(self) -> Iterator[None]:
        """The view rebuilt once, at the end, for everything done meanwhile (a message from the page: a slider's
        move restarts the section and its layers, and each says so)."""
        if self._view_due is not None:  # within another: that one rebuilds
            yield
            return
        self._view_due = {}
        try:
            yield
        finally:
            due, self._view_due = self._view_due, None
            if due:
                self._refresh_views(force=due["force"])

    def _refresh_views(self, force: bool = False) -> None:
        if self._view_due is not None:  # rebuilt once the message is handled
            self._view_due["force"] = self._view_due.get("force", False) or force
            return
        if not force and self.player.computing():
            # A played frame on its way: its words go out once, with the frame (Player calls this when it is
            # computed), not a dozen times as its jobs start and end (each a message the page lays out).
            return
        view = {"section": self._section_view()}
        view.update({n: self._tab_view(n) for n in self.tabs})
        if view != self.ui.view:  # one websocket message per real change
            self.ui.view = view

    # --- for tests and the load test -------------------------------------------------------------

    def running(self, tab: str = "section") -> bool:
        """Whether the tab's Stop would stop something (the page enables it exactly then)."""
        if tab == "section":
            return any(self.runner.busy(c) for c in self.session.channels)
        return self.runner.busy(tab)


def _timer(deliver: Callable[[Callable[[], None]], None]) -> Schedule:
    """Run a callable on the document thread after a delay (a thread's timer; the server uses the document's)."""
    import threading

    def schedule(delay: float, fn: Callable[[], None]) -> None:
        t = threading.Timer(delay, lambda: deliver(fn))
        t.daemon = True
        t.start()

    return schedule


def _url_tab(message: str) -> str:
    """The tab whose setting a URL error message is about (by the URL key it names): an analysis tab, or
    "section" (the system, the numerics, the layers and the view)."""
    c = BY_URL.get(_url_key(message))
    return c.area if c is not None and c.area in TAB_CLASSES else "section"


def _url_key(message: str) -> str:
    """The URL key a URL error message names ("URL parameter KEY: ...")."""
    return message.removeprefix("URL parameter ").split(":", 1)[0]


def _about(message: str, name: str) -> bool:
    """Whether a URL error message is about control ``name`` (it names its URL key)."""
    c = BY_NAME.get(name)
    return c is not None and c.url is not None and message.startswith(f"URL parameter {c.url}:")
