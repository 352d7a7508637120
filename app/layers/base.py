"""The layers of the section plot: each one small module, a :class:`Layer` the controller drives alike.

A layer declares the state fields whose change redoes it (``fields``), the runner channels it uses (each
with its kind of job: ``channels``) and whether the section's settings or the view redo it; it says what a
job needs (:meth:`Layer.inputs`, on the document thread), computes on the runner (:meth:`Layer.job`, a
generator of results: each is drawn as it comes), draws a result (:meth:`Layer.apply`) and says what it
shows (:meth:`Layer.status`, :meth:`Layer.legend`, the session's fields it :meth:`Layer.published`).
:class:`app.controller.ExplorerSession` coordinates them: which are on, cancel on change, the runner, Stop.
A new layer is one module here with a class that subclasses :class:`Layer`, listed in :data:`LAYERS` (or
passed to the session): the controller does not change.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from app.runner import LAYER
from app.state import key_words

if TYPE_CHECKING:
    from app.state import ExplorerState
    from app.views import SectionFigure
    from explorer_core.system.params import Params

#: What :meth:`Layer.inputs` returns while the system is invalid: nothing to compute, the picture stays
#: (the error is shown by the section).
KEEP = object()


class Host(Protocol):
    """What a layer may use of the session: the state, the figure, the system on screen, the runner."""

    state: ExplorerState
    fig: SectionFigure

    def system(self) -> Params | None: ...

    def publish(self, layer: Layer) -> None: ...

    def run(self, layer: Layer, inputs: Any, *, channel: str | None = None, bump: bool = True,
            job: Callable[..., Iterator[Any]] | None = None) -> None: ...  # fmt: skip


class Layer:
    """One layer of the section plot. Subclasses set the class attributes and override what they need."""

    #: The layer's name and its main runner channel.
    name: ClassVar[str] = ""
    #: Every channel its jobs use, with the kind of job (app.runner: POINTS a user waits for, LAYER).
    channels: ClassVar[dict[str, str]] = {}
    #: State fields of its own settings: a change redoes it (and publishes the URL).
    fields: ClassVar[tuple[str, ...]] = ()
    #: Redone when the section's settings change (a new system), or started once the section's first
    #: points are out (``after_section``: its updates would redraw the plot while the points come).
    on_section: ClassVar[bool] = True
    after_section: ClassVar[bool] = False
    #: Not redone when its inputs equal those of its last job (a layer of the system and the view, when
    #: only the section's numerics or initial conditions change).
    dedupe: ClassVar[bool] = False
    #: The settings its result depends on (state fields: their URL keys name them when the result shown is
    #: not the controls', e.g. after a Stop).
    depends: ClassVar[tuple[str, ...]] = ()

    def __init__(self, host: Host) -> None:
        self.host = host
        self.shown_query: dict[str, str] | None = None  # the settings of the result on screen

    # --- what to compute (document thread) ----------------------------------------------------

    def inputs(self) -> Any:
        """What the job needs from the state, hashable and comparable; None: the layer is off; KEEP: nothing
        to do now (the system is invalid)."""
        raise NotImplementedError

    def on_view(self) -> bool:
        """Whether a pan or zoom redoes it."""
        return False

    def prepare(self, inputs: Any) -> Any:
        """Checks before the job starts and the status while it runs; returns what the job gets. A
        ParameterError is shown as the layer's status (:meth:`refused`)."""
        return inputs

    def refused(self, exc: BaseException) -> None:
        """Its inputs cannot be computed (a message of the core)."""

    # --- the job (runner thread) --------------------------------------------------------------

    def job(self, inputs: Any, cancelled: Callable[[], bool]) -> Iterator[Any]:
        """Compute; yield each result to draw (the last one is the final one)."""
        raise NotImplementedError

    # --- results (document thread) --------------------------------------------------------------

    def current(self, inputs: Any) -> bool:
        """Whether a result for ``inputs`` still belongs on screen (the system or the view moved on)."""
        return True

    def apply(self, inputs: Any, result: Any) -> None:
        """Draw a result on the figure and update the status."""
        raise NotImplementedError

    def clear(self) -> None:
        """Turned off: nothing of it on screen."""
        raise NotImplementedError

    def status(self) -> str:
        """What it says under the plot."""
        return ""

    def legend(self) -> list[list[str]]:
        """Legend rows (colour, text)."""
        return []

    def published(self) -> dict[str, Any]:
        """The session's fields (app.controller.ExplorerSession params) this layer's text goes to."""
        return {}

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        """After a Stop (``busy``: a job of it was running): say whether what it shows is of the controls'
        settings (``now``), or clear what would otherwise stay under other settings without saying so."""

    def system_params(self) -> Params | None:
        return self.host.system()


def stale_note(then: dict[str, str] | None, now: dict[str, str], keys: tuple[str, ...], most: int = 3) -> str:
    """ "" when the settings ``keys`` of a result (``then``) are those in use (``now``); else what differs, in
    the controls' words: "α = 0.1 (the controls: 0.3)"."""
    if then is None:
        return ""
    diff = [k for k in keys if then.get(k) != now.get(k)]
    parts = [f"{key_words(k)} = {_short(then.get(k))} (the controls: {_short(now.get(k))})" for k in diff[:most]]
    if len(diff) > most:
        parts.append(f"and {len(diff) - most} more settings")
    return ", ".join(parts)


def plain(exc: BaseException, limit: int = 300) -> str:
    """An exception as one short line of text (never a multi-line array dump)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _short(v: str | None, limit: int = 40) -> str:
    v = v or "(none)"
    return v if len(v) <= limit else v[: limit - 1] + "…"


__all__ = ["KEEP", "LAYER", "Host", "Layer", "plain", "stale_note"]
