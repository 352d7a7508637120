"""The Bilimovich Explorer web app: ``panel serve app/main.py`` (or ``bilimovich serve``).

One :class:`app.page.Page` per browser tab: a sidebar with the scene selector, sliders with
number boxes for the system, the numerics and the layers; the main area with the (q, r) plane
(section points streamed as they are computed, equilibrium tracks, the T' map), the k-series of
the selected trajectory and the analysis tabs. The URL carries the whole state.
"""

from __future__ import annotations

import urllib.parse
from typing import Any

import panel as pn
from panel.io.location import Location

from app import pacing, warm
from app.location import AppLocation, raw_query
from app.page import Page

# Bokeh runs this file again for every session, as a new module (``bokeh_app_<uuid>``): nothing at
# module level may register itself globally (``logging.getLogger(__name__)`` here kept one Logger per
# session for the life of the server) or define a class (a Parameterized subclass here, the page's
# location, stayed alive, one per session: 1,300 more between minutes 15 and 40 of a long day). What is
# built once lives in the modules imported above.
pn.extension(notifications=False)


def create_app() -> tuple[Any, Location | None]:
    """Build one session's page: its root component, and the location the app writes the URL to."""
    warm.start()
    doc = pn.state.curdoc
    request = doc.session_context.request if doc is not None and doc.session_context is not None else None
    query = raw_query(request)
    location = AppLocation.from_request(request) if request is not None else None

    def deliver(fn) -> None:
        if doc is None:
            fn()
            return
        pacing.DELIVERIES.put(doc, fn)

    pacing.DELIVERIES.bind()

    def publish(q: dict[str, str]) -> None:
        if location is not None:
            # The whole query, replaced (keys of a state no longer in use disappear, e.g. tab=).
            location.search = "?" + urllib.parse.urlencode(q, safe=",;")

    def connected() -> bool:
        # A closed tab drops its websocket at once, but Bokeh discards the session only after
        # --unused-session-lifetime: stop its jobs now (Bokeh's ServerSession has no public hook).
        server_session = getattr(doc.session_context, "_session", None) if doc is not None else None
        return server_session is None or server_session.connection_count > 0

    def schedule(delay: float, fn) -> None:
        # A played parameter's next frame (app/play.py), on the document's thread after ``delay`` seconds.
        if doc is None:
            fn()
            return
        doc.add_timeout_callback(fn, max(0, int(1e3 * delay)))

    page = Page(query, deliver, publish_url=publish, alive=connected, schedule=schedule, wait_for_browser=True)
    # Messages from the browser run on the document's thread, like every other change of the page.
    page.ui._on_message = lambda msg: deliver(pacing.urgent(lambda: page.handle(msg)))

    def destroyed(ctx: Any) -> None:
        page.close()

    pn.state.on_session_destroyed(destroyed)
    # Start once the page is loaded, so the first chunk streams into a live plot. Panel runs onload
    # callbacks on its thread pool; the start changes models (e.g. clears the orbits layer), which
    # only the document's thread may do.
    pn.state.onload(lambda: deliver(page.start))
    return page.ui, location


def local_stylesheets(doc: Any) -> None:
    """Point Panel's stylesheets at this server, not its CDN.

    Panel does so when it renders a session's HTML page; with ``--reuse-sessions`` a session is
    built when its websocket connects, after the page, and keeps the CDN's URLs (a page on a
    network without internet would then miss them and log errors).
    """
    from bokeh.models import ImportedStyleSheet
    from panel.io.resources import LOCAL_DIST, patch_stylesheet

    dist_url = f"{pn.state.rel_path}/{LOCAL_DIST}" if pn.state.rel_path else LOCAL_DIST
    doc._template_variables["dist_url"] = dist_url
    # What Panel's patch_model_css does for each root, over the document's models at hand (it walked every root's
    # models again, ~10 ms a page); the session is not connected yet, so its changes need no holding back.
    for model in list(doc.models):
        if isinstance(model, ImportedStyleSheet):
            patch_stylesheet(model, dist_url)


if __name__.startswith("bokeh_app") or __name__ == "__main__":
    try:
        ui, location = create_app()
        ui.servable(title="Bilimovich Explorer", location=location if location is not None else True)
        if pn.state.curdoc is not None:
            local_stylesheets(pn.state.curdoc)
    finally:
        pacing.page_built()  # the next tab's page may be built now (app/pacing.py)
