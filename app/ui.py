"""The page as one Panel component: layout, controls, messages and status (``app/ui.js``).

A new session's page used to be ~140 Panel widgets and panes in a template (~550, then ~320
Bokeh models; ~1 s of the server's event loop to build and send). Here every control, message,
button and status line is drawn by one ES module in the browser from a few plain dicts, so the
server builds one component and the figures (docs/load.md). The server keeps the values in use
(:class:`~app.state.ExplorerState`); the page sends what the user typed and shows what the
server answers: the value in use, and why a typed value was refused.

Messages from the page (``send_msg``) are dicts, checked here before anything uses them:
``{"commit": name, "text": str}`` or ``{"action": ..., ...}`` (stop, clear, run, tab,
presentation, download, load_bench, bench_choice, find_orbits, clear_orbits, clear_manifolds; play, pause,
step, shown: a played parameter's frame drawn; tour, tour_step, tour_file: the guided tours).
"""

from __future__ import annotations

import base64
import logging
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import panel as pn
import param
from bokeh.model import DataModel
from panel.custom import JSComponent
from panel.io.model import remove_root
from panel.viewable import Child

from app.state import BY_NAME, CONTROLS, MAX_TEXT, TABS
from app.views import TYPE_COLORS

log = logging.getLogger(__name__)

ACTIONS = frozenset({"stop", "clear", "run", "tab", "presentation", "download", "load_bench", "bench_choice",
                     "find_orbits", "clear_orbits", "clear_manifolds", "play", "pause", "step", "shown", "tour",
                     "tour_step", "tour_file"})  # fmt: skip
#: An uploaded tours file is the one long text a page sends (app/tours.py checks it).
MAX_UPLOAD = 200_000


def _spec() -> dict[str, Any]:
    """What the page needs to draw the controls: the same for every session, built once."""
    out = []
    for c in CONTROLS:
        d: dict[str, Any] = {"name": c.name, "label": c.label, "kind": c.kind, "area": c.area}
        if c.kind == "float":
            d.update(lo=c.bounds[0], hi=c.bounds[1], step=c.step)  # type: ignore[index]
        if c.options:
            d["options"] = [list(o) for o in c.options]
        if c.placeholder:
            d["placeholder"] = c.placeholder
        if c.help:
            d["help"] = c.help
        out.append(d)
    eq = [[t, col] for t, col in TYPE_COLORS.items() if t != "degenerate"]
    return {"controls": out, "tabs": list(TABS), "eq_colors": eq}


SPEC = _spec()
#: The page's one ES module: the body in 3-D (app/body.js: plain functions) and the page (app/ui.js) after it.
ESM = "\n".join(Path(__file__).with_name(f).read_text(encoding="utf-8") for f in ("body.js", "ui.js"))


#: The module as Panel sends it to a page (flush left).
_ESM_RENDERED = textwrap.dedent(ESM)


def check_message(data: Any) -> dict[str, Any] | None:
    """A message from the page if it is well formed, else None (dropped: it did not come from our page)."""
    if not isinstance(data, dict):
        return None
    if "commit" in data:
        name, text = data.get("commit"), data.get("text")
        if name in BY_NAME and isinstance(text, str | bool | int | float) and len(str(text)) <= MAX_TEXT:
            return {"commit": name, "text": text}
        if name in BY_NAME and isinstance(text, str):  # too long: still answered (refused with a message)
            return {"commit": name, "text": text[: MAX_TEXT + 1]}
        return None
    action = data.get("action")
    if action not in ACTIONS:
        return None
    out: dict[str, Any] = {"action": action}
    for key in ("tab", "what", "value"):
        if key in data:
            v = data[key]
            if not isinstance(v, str) or len(v) > (MAX_UPLOAD if action == "tour_file" else MAX_TEXT):
                return None
            out[key] = v
    if "on" in data:
        if not isinstance(data["on"], bool):
            return None
        out["on"] = data["on"]
    return out


class FigurePane(pn.pane.Bokeh):
    """A Bokeh model (a figure, the analysis tab's box) as a child of the page.

    Panel's pane searches everything under the model for ``CustomJS`` callbacks to renumber each time it is
    rendered: a walk of every model of the section figure (~60) for a new page, a tenth of what building it
    costs the event loop (docs/load.md). The page's figures have no ``CustomJS``, so this pane skips that search;
    the rest is Panel's (1.9) ``Bokeh._get_model``.
    """

    def _get_model(self, doc: Any, root: Any = None, parent: Any = None, comm: Any = None) -> Any:
        if root is None or comm is not None or self.object is None:
            return super()._get_model(doc, root, parent, comm)
        model = self.object
        if model._document and doc is not model._document:
            remove_root(model, doc)
        self._models[root.ref["id"]] = (model, parent)
        self._design.apply_bokeh_theme_to_model(model, self.theme)
        return model


class ExplorerUI(JSComponent):
    """The whole page of one session (figures are its children)."""

    spec = param.Dict(default=SPEC, doc="controls to draw (the same for every session)")
    values = param.Dict(default={}, doc="value in use of every control, as shown")
    messages = param.Dict(default={}, doc="control -> why the value typed last was refused")
    revision = param.Integer(default=0, doc="bumped with every answer to a typed value")
    committed = param.String(default="", doc="the control the last answer is about")
    view = param.Dict(default={}, doc="per tab: status, errors, running, progress, result, ...")
    tab = param.String(default="section")
    presentation = param.Boolean(default=False)
    series = param.Dict(default={}, doc="k, q, r, T of the selected trajectory (drawn by the page)")
    body = param.Dict(default={}, doc="the body's series for the 3-D view (app/bodyview.py; {}: none)")
    section_plot = Child()
    analysis_plot = Child()

    _esm = ESM

    @classmethod
    def _render_esm(cls, compiled: Any = True, server: bool = False) -> str:
        # Panel dedents the module's text (~83 kB) again for every page (~1.3 ms); it is the same each time.
        return _ESM_RENDERED

    def __init__(self, on_message: Callable[[dict[str, Any]], None] | None = None, **params: Any) -> None:
        super().__init__(**params)
        self._on_message = on_message

    @classmethod
    def _patch_datamodel_ref(cls, props: Any, ref: str) -> None:
        # Panel tags every data model found under this one, walking all its references (the figures
        # too, ~5 ms) on every update of a value; this component's only data model is its own.
        tag = f"__ref:{ref}"
        if isinstance(props, DataModel) and tag not in props.tags:
            props.tags.append(tag)

    def _handle_msg(self, data: Any) -> None:
        msg = check_message(data)
        if msg is None:
            log.warning("dropped a malformed message from a page: %.200r", data)
            return
        if self._on_message is not None:
            self._on_message(msg)

    def send_download(self, filename: str, mime: str, payload: bytes) -> None:
        """Hand a file to the page (it saves it under ``filename``)."""
        self._send_msg({"download": filename, "mime": mime, "data": base64.b64encode(payload).decode("ascii")})
