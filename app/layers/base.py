"""The layers of the section plot: each one small module, a :class:`Layer` the controller drives alike.

A layer owns its settings, what it says and what the page can ask of it. It declares:

* its **settings**: its controls (``controls``: :class:`app.controls.Control` entries, from which the state
  generates its attributes, bounds and URL keys as for its own), the state it keeps without a control
  (``picks``: seeds clicked, saddles picked) and the URL keys beyond its controls' (``urls``). The state's
  tables (:data:`app.state.CONTROLS`, :data:`app.state.URL_KEYS`) take them from :data:`app.layers.LAYERS`;
* the state fields whose change redoes it (``fields``), the runner channels it uses (each with its kind of
  job: ``channels``) and whether the section's settings or the view redo it;
* its **published fields** (``publishes``: name -> default): the session (:class:`app.controller.ExplorerSession`)
  creates one watched field for each, which the layer sets through :meth:`Layer.published`;
* its **page actions** (``actions``: :class:`Action`): the buttons whose message it answers, and the modes of
  "Click in the plot" it adds;
* its **download** (``download``: the file's name; :meth:`Layer.table` the rows on screen, written by the core's
  writer, :func:`csv_bytes`; or :meth:`Layer.file`, a core result as the command line writes it), named
  ``name-partial.csv`` when its run was stopped (:func:`named`); and its part of the page's view of the section
  tab (:meth:`Layer.view`).

It says what a job needs (:meth:`Layer.inputs`, on the document thread), computes on the runner
(:meth:`Layer.job`, a generator of results: each is drawn as it comes) and draws a result (:meth:`Layer.apply`).
The session coordinates them (which are on, cancel on change, the runner, Stop, the actions); the page draws
their views and sends them the page's actions. A new layer is one module here with a class that subclasses
:class:`Layer`, listed in :data:`app.layers.LAYERS` (or passed to the session): neither the controller nor the
page changes.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from app.controls import Control, UrlKey
from app.runner import LAYER
from explorer_core import export
from explorer_core.losses import Loss

if TYPE_CHECKING:
    import param

    from app.runner import Runner
    from app.views import SectionFigure
    from explorer_core.system.params import Params

#: What :meth:`Layer.inputs` returns while the system is invalid: nothing to compute, the picture stays
#: (the error is shown by the section).
KEEP = object()


@dataclass(frozen=True)
class Action:
    """Something the page asks of a layer: the method ``method`` of the layer answers the page's message
    ``{"action": name}`` (a button), or, ``click=True``, a click in the plot while "Click in the plot" is on the
    mode ``name`` (offered with the words ``label``; the method gets the click's q and r)."""

    name: str
    method: str
    label: str = ""
    click: bool = False


@dataclass(frozen=True)
class Table:
    """What a layer's CSV download holds: a title and the settings of the data in a comment line (``notes``: more
    comment lines; ``partial``: what a stopped run lost, :func:`stopped_lines`), then the rows (cells as
    :func:`explorer_core.export.cell` writes them) under the header."""

    title: str
    settings: dict[str, str]
    header: tuple[str, ...]
    rows: Iterable[Sequence[Any]]
    notes: tuple[str, ...] = ()
    partial: tuple[str, ...] = ()


@dataclass(frozen=True)
class Download:
    """A file the page hands to the browser: its name, MIME type and bytes."""

    name: str
    mime: str
    data: bytes


@dataclass(frozen=True)
class _Stopped:
    """A run stopped before its end, as :func:`explorer_core.export.partial` reads a result."""

    lost: list[Loss]
    completed: bool = False


def stopped_lines(lost: Sequence[Loss]) -> tuple[str, ...]:
    """The core's head comments of a run stopped before its end (:func:`explorer_core.export.partial`), with
    what it lost: the words the command line writes."""
    return tuple(export.partial(_Stopped(list(lost))))


def loss_lines(lost: Sequence[Loss], stopped: bool) -> tuple[str, ...]:
    """The head comments of a download that is not whole: a run stopped before its end (:func:`stopped_lines`), or
    one that ended having lost some of what it was to compute (each loss in the core's words); () when whole."""
    if stopped:
        return stopped_lines(lost)
    if not lost:
        return ()
    return ("partial: the run ended without some of what it was to compute; this file holds the rest "
            "(complete: false)", *(loss.line() for loss in lost))  # fmt: skip


def written(name: str, writer: Callable[[str], Any]) -> bytes:
    """The bytes a core writer (it takes a path, e.g. a result's ``write``) writes to the file ``name`` of a
    temporary folder."""
    with tempfile.TemporaryDirectory(prefix="bilimovich-download-") as folder:
        path = os.path.join(folder, name)
        writer(path)
        with open(path, "rb") as fh:
            return fh.read()


def named(stem: str, suffix: str, partial: bool) -> str:
    """A download's file name: ``stem-partial.suffix`` for what a stopped run computed (the file says so too)."""
    return f"{stem}{'-partial' if partial else ''}{suffix}"


#: The MIME type of each kind of download.
MIME = {".csv": "text/csv", ".json": "application/json", ".npz": "application/octet-stream"}


def result_file(result: Any, stem: str, suffix: str) -> Download:
    """A core result as the command line writes it (its ``write(path)``, the columns and entries of ``--out``),
    named ``stem-partial.suffix`` when its run was stopped (:func:`explorer_core.export.partial`: its CSV head
    says so, its JSON and NPZ summary hold ``completed``/``complete``/``lost``)."""
    return Download(named(stem, suffix, bool(export.partial(result))), MIME[suffix],
                    written(f"{stem}{suffix}", result.write))  # fmt: skip


def csv_bytes(table: Table) -> bytes:
    """``table`` as the file the page downloads, written by the core's one CSV writer
    (:func:`explorer_core.export.write_csv`, the CLI's): the header, then its comment lines (the title and
    settings, the notes, what a stopped run lost: ``numpy.genfromtxt(..., names=True)`` reads it as it comes),
    then the rows."""
    words = "&".join(f"{a}={b}" for a, b in table.settings.items())
    comments = (f"Bilimovich Explorer {table.title}; {words}", *table.notes, *table.partial)
    return written("download.csv", lambda path: export.write_csv(path, table.header, table.rows, comments))


class Host(Protocol):
    """What a layer may use of the session: the state, the figure, the system on screen, the runner, the other
    layers, and the session's ways to redo, clear and publish a layer."""

    state: Any  # app.state.ExplorerState (the state imports the layers: not imported here)
    fig: SectionFigure
    runner: Runner
    layers: dict[str, Layer]

    def system(self) -> Params | None: ...

    def data(self) -> tuple[Any, Any, Any, Any]: ...

    def publish(self, layer: Layer) -> None: ...

    def refresh(self, layer: Layer) -> None: ...

    def clear(self, layer: Layer) -> None: ...

    def suspended(self) -> AbstractContextManager[None]: ...

    def run(self, layer: Layer, inputs: Any, *, channel: str | None = None, bump: bool = True) -> None: ...


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
    #: Its controls (the state's attributes and URL keys are generated from them), the state it keeps without a
    #: control (name -> its param attribute) and its URL keys beyond its controls'.
    controls: ClassVar[tuple[Control, ...]] = ()
    picks: ClassVar[dict[str, param.Parameter]] = {}
    urls: ClassVar[tuple[UrlKey, ...]] = ()
    #: The session's fields it publishes (name -> value before it says anything): :meth:`published` sets them.
    publishes: ClassVar[dict[str, Any]] = {}
    #: What the page can ask of it (buttons, click modes).
    actions: ClassVar[tuple[Action, ...]] = ()
    #: Its download's name (the page's ``{"action": "download", "what": name}``, the file ``name.csv`` or what
    #: :meth:`file` names); "": none.
    download: ClassVar[str] = ""

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
        """The values of the session's fields it publishes (``publishes``): its text, its counts."""
        return {}

    def view(self) -> dict[str, Any]:
        """Its part of the page's view of the section tab (what app/ui.js draws): its published fields by default."""
        return self.published()

    def table(self) -> Table | None:
        """What its CSV download holds now; None: nothing on screen to download."""
        return None

    def csv(self) -> bytes | None:
        """Its CSV download (:meth:`table` through :func:`csv_bytes`), or None when nothing is on screen."""
        table = self.table()
        return None if table is None else csv_bytes(table)

    def file(self) -> Download | None:
        """Its download as the page sends it: by default :meth:`table` as ``name.csv`` (``name-partial.csv`` when
        its run was stopped); None when nothing is on screen."""
        table = self.table()
        if table is None:
            return None
        return Download(named(self.download, ".csv", bool(table.partial)), MIME[".csv"], csv_bytes(table))

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        """After a Stop (``busy``: a job of it was running): say whether what it shows is of the controls'
        settings (``now``), or clear what would otherwise stay under other settings without saying so."""

    def system_params(self) -> Params | None:
        return self.host.system()

    def stale(self, then: dict[str, str] | None, now: dict[str, str], fields: Sequence[str]) -> str:
        """:func:`stale_note` for the settings ``fields`` (state fields, named by their URL keys)."""
        st = self.host.state
        return stale_note(then, now, st.keys_of(fields), st.words_of)


def stale_note(then: dict[str, str] | None, now: dict[str, str], keys: tuple[str, ...],
               words: Callable[[str], str], most: int = 3) -> str:  # fmt: skip
    """ "" when the settings ``keys`` of a result (``then``) are those in use (``now``); else what differs, in
    the controls' words (``words``: a URL key's): "α = 0.1 (the controls: 0.3)"."""
    if then is None:
        return ""
    diff = [k for k in keys if then.get(k) != now.get(k)]
    parts = [f"{words(k)} = {_short(then.get(k))} (the controls: {_short(now.get(k))})" for k in diff[:most]]
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


__all__ = ["KEEP", "LAYER", "MIME", "Action", "Download", "Host", "Layer", "Table", "csv_bytes", "loss_lines", "named",
           "plain",
           "result_file", "stale_note", "stopped_lines", "written"]  # fmt: skip
