"""The explorer inline in a notebook: ``Explorer(scene="fig8B")`` is a Panel component a cell shows.

It is the served page (:class:`app.page.Page`, the same controls, figures and tabs), built in the kernel
instead of per browser tab, with its state readable and settable from Python::

    ex = Explorer(scene="fig8B")
    ex                      # the page, inline
    ex.state.alpha          # -0.45
    ex.state.alpha = -0.41  # checked as a typed value, then recomputed; a refused value raises ParameterError
    ex.wait()               # until the section is computed (else it streams into the view shown)
    ex.url                  # the shareable query of what is shown
    Explorer.from_url("http://host/app?scene=fig8B&alpha=-0.41")   # a shared link's state

Jobs run on the app's threads; their results are delivered on the kernel's event loop (the thread that
owns the page's Bokeh models) and pushed to the notebook's view.
"""

from __future__ import annotations

import asyncio
import math
import queue
import time
import urllib.parse
from collections.abc import Callable
from typing import Any

import panel as pn
from panel.viewable import Viewer

from app import warm
from app.page import Page
from app.state import BY_NAME, TABS, ExplorerState
from explorer_core.analyses.tprime import check_range
from explorer_core.system.params import ParameterError

Deliver = Callable[[Callable[[], None]], None]
#: The plot's window (set as a pan or zoom sets it) and the tab shown, besides the page's controls.
VIEW = ("q_range", "r_range")
SETTABLE = (*BY_NAME, *VIEW, "tab")


def query_of_url(url: str) -> dict[str, list[str]]:
    """The query of a shared link (``http://host/app?scene=...&alpha=...``, or just ``?scene=...``) as the
    server receives it (key -> values); a value the app refuses is reported by the page, not here."""
    if not isinstance(url, str):
        raise ParameterError(f"url must be a string, got {url!r}")
    query = urllib.parse.urlsplit(url).query if "?" in url or "://" in url else url
    return urllib.parse.parse_qs(query, keep_blank_values=True)


def text_of(value: Any) -> str:
    """A Python value as the text a control takes (numbers exactly; pairs and boxes comma-separated)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list | tuple):
        if value and all(isinstance(v, list | tuple) for v in value):  # clicked points: "q,r;q,r"
            return ";".join(",".join(text_of(x) for x in v) for v in value)
        return ",".join(text_of(v) for v in value)
    return str(value)


class StateView:
    """The explorer's state from Python: reading gives the value in use, setting commits it like a typed value.

    A value the page would refuse raises :class:`ParameterError` with the page's message (naming the value
    and the one still in use); a system parameter set makes the scene ``custom``, as on the page.
    """

    def __init__(self, page: Page) -> None:
        object.__setattr__(self, "_page", page)

    @property
    def _state(self) -> ExplorerState:
        return self._page.state

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name not in self._state.param:
            raise AttributeError(f"the explorer's state has no {name!r}; its settings: {', '.join(SETTABLE)}")
        return getattr(self._state, name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name in VIEW:  # the plot's window, as a pan or a zoom sets it
            q_range, r_range = self._state.q_range, self._state.r_range
            rng = check_range(value, name)
            q_range, r_range = (rng, r_range) if name == "q_range" else (q_range, rng)
            self._page.fig.set_view(q_range, r_range)
            self._page.session.set_view_from_plot(q_range, r_range)
            return
        if name == "tab":  # the tab shown, as a click on it
            if value not in TABS:
                raise ParameterError(f"tab must be one of {', '.join(TABS)}, got {value!r}")
            self._page.handle({"action": "tab", "tab": value})
            return
        if name not in BY_NAME:
            raise AttributeError(f"{name!r} is not a setting of the explorer; its settings: {', '.join(SETTABLE)}")
        problem = self._page.commit(name, text_of(value))
        if problem:
            raise ParameterError(problem)

    def update(self, **values: Any) -> None:
        """Several values, in the order given (each checked as it is set)."""
        for name, value in values.items():
            setattr(self, name, value)

    def __dir__(self) -> list[str]:
        return [*SETTABLE, "update", "as_dict"]

    def as_dict(self) -> dict[str, Any]:
        """Every setting's value in use."""
        return {name: getattr(self._state, name) for name in SETTABLE}

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.as_dict().items())
        return f"ExplorerState({shown})"


def _kernel_deliver() -> Deliver:
    """Run a job's result on the event loop of the thread that builds the explorer (a notebook kernel's);
    without a running loop (a script), run it where it is delivered."""
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        return lambda fn: fn()
    return lambda fn: loop.call_soon_threadsafe(fn)


class Explorer(Viewer):
    """The Bilimovich Explorer as a notebook component (see the module docstring)."""

    def __init__(
        self,
        scene: str | None = None,
        *,
        query: dict[str, Any] | None = None,
        start: bool = True,
        deliver: Deliver | None = None,
        executor: Any = None,
        **params: Any,
    ) -> None:
        super().__init__(**params)
        query = dict(query or {})
        if scene is not None:
            if not isinstance(scene, str):
                raise ParameterError(f"scene must be a scene's id (e.g. 'fig8B'), got {scene!r}")
            query["scene"] = [scene]
        self._deliver = deliver or _kernel_deliver()
        self._pending: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._query: dict[str, str] = {}
        self.page = Page(query, self._delivered, publish_url=self._published, executor=executor)
        self.state = StateView(self.page)
        if self.page.url_errors:
            pn.state.log("; ".join(self.page.url_errors))
        if start:
            warm.start()  # as the served app: jobs wait until the kernels are loaded
            self.page.start()

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> Explorer:
        """The explorer in the state of a shared link; the link's refused values are in :attr:`url_errors`."""
        return cls(query=query_of_url(url), **kw)

    @property
    def url_errors(self) -> list[str]:
        """The values of the link this explorer was built from that were refused, and the values used instead."""
        return list(self.page.url_errors)

    @property
    def url(self) -> str:
        """The query of a link that opens the app in this state (``?scene=...&alpha=...``)."""
        return "?" + urllib.parse.urlencode(self.page.state.to_query(), safe=",;")

    def _published(self, q: dict[str, str]) -> None:
        self._query = dict(q)

    def _delivered(self, fn: Callable[[], None]) -> None:
        # Queued, then run by the kernel's loop or by wait(): whichever comes first, on the kernel's thread.
        self._pending.put(fn)
        self._deliver(self._drain)

    def _drain(self) -> None:
        ran = False
        while True:
            try:
                fn = self._pending.get_nowait()
            except queue.Empty:
                break
            fn()
            ran = True
        # Bokeh models changed in place reach a notebook's view only when pushed (a served page syncs itself).
        if ran and pn.state.curdoc is None and self.page.ui._models:
            pn.io.push_notebook(self.page.ui)

    def wait(self, timeout: float = 300.0) -> bool:
        """Run the jobs' results here until nothing of the section is computing (or ``timeout`` seconds passed:
        False). A cell that must show the finished picture calls it; without it the picture streams in."""
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 < timeout < math.inf:
            raise ParameterError(f"timeout must be a positive number of seconds, got {timeout!r}")
        end = time.monotonic() + timeout
        while True:
            self._drain()
            if not self.page.running() and self._pending.empty():
                return True
            if time.monotonic() > end:
                return False
            time.sleep(0.02)

    def running(self) -> bool:
        """Whether anything of the section is still being computed."""
        return self.page.running()

    def stop(self) -> None:
        """Stop every job of the section (as the page's Stop)."""
        self.page.handle({"action": "stop", "tab": "section"})

    def close(self) -> None:
        self.page.close()

    def __panel__(self) -> Any:
        return self.page.ui
