"""Guided tours of the paper's figures: data in one file (``app/tours.json``), checked when loaded.

A tour is a few steps; each step is a sentence or two, the settings it needs (as in a link: URL keys and
values of :data:`app.state.URL_KEYS`, on top of the tour's scene, so every step stands alone and
``tour=ID&step=N`` in a URL shows it), what to look at (points of the section plane ringed and labelled) and
whether the page presses the Run of the analysis tab the step opens (``"run": true``: the class sees the
result come, instead of being told to press a button).
A teacher's own tours file has the same form: loaded from a path of this server (``tour_url=``) or uploaded
in the page, never fetched from another site. Every entry is checked on load; a bad one is refused with a
message that names it (the tour, the step and the key).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.state import _ID, MAX_TOUR_STEPS, TABS, URL_KEYS, state_from_query
from explorer_core.scenes import get_scene

TOURS_FILE = Path(__file__).with_name("tours.json")
#: Where ``tour_url=/tours/NAME.json`` is read from (a directory of this server; default ``app/tours/``).
TOURS_DIR = Path(os.environ.get("BILIMOVICH_TOURS_DIR", str(Path(__file__).with_name("tours"))))
#: A tours file's largest size (an upload or a file of the server).
MAX_TOURS_BYTES = 200_000
MAX_TOURS = 40
MAX_TEXT_CHARS = 600
MAX_LOOK = 8
_SETTING_KEYS = {u.key for u in URL_KEYS} - {"scene", "tour", "step", "tour_url", "present"}
#: The tabs whose Run a step may press (the speed-vs-accuracy tab measures this server: not a lesson's step).
RUN_TABS = tuple(t for t in TABS if t not in ("section", "bench"))


class TourError(ValueError):
    """A tours file that cannot be used; the message names the bad entry."""


@dataclass(frozen=True)
class Look:
    """A point of the section plane to look at: ringed and labelled on the plot."""

    q: float
    r: float
    label: str


@dataclass(frozen=True)
class Step:
    text: str
    settings: dict[str, str]
    look: tuple[Look, ...]
    #: The page presses Run on the step's tab when it shows the step.
    run: bool = False

    @property
    def tab(self) -> str:
        return self.settings.get("tab", "section")


@dataclass(frozen=True)
class Tour:
    id: str
    title: str
    scene: str
    steps: tuple[Step, ...]


def _where(tour: Any, step: int | None = None) -> str:
    name = f"tour {tour!r}" if isinstance(tour, str) else f"tour #{tour}"
    return f"{name} step {step}" if step is not None else name


def _step(data: Any, where: str, scene: str) -> Step:
    if not isinstance(data, dict):
        raise TourError(f"{where}: a step is an object with 'text', 'settings' and 'look', got {type(data).__name__}")
    extra = set(data) - {"text", "settings", "look", "run"}
    if extra:
        raise TourError(f"{where}: unknown field {sorted(extra)[0]!r} (a step has 'text', 'settings', 'look', 'run')")
    text = data.get("text")
    if not isinstance(text, str) or not text.strip() or len(text) > MAX_TEXT_CHARS:
        raise TourError(f"{where}: 'text' must be a sentence or two (1..{MAX_TEXT_CHARS} characters)")
    settings = data.get("settings", {})
    if not isinstance(settings, dict):
        raise TourError(f'{where}: \'settings\' must be an object of URL keys and values, e.g. {{"alpha": "-0.4"}}')
    for key, value in settings.items():
        if key not in _SETTING_KEYS:
            raise TourError(f"{where}: setting {key!r} is not a setting a step may make (URL keys: "
                            f"{', '.join(sorted(_SETTING_KEYS)[:12])}, …)")  # fmt: skip
        if not isinstance(value, str | int | float) or isinstance(value, bool):
            raise TourError(f"{where}: setting {key!r} must be text or a number, got {type(value).__name__}")
    clean = {k: str(v) for k, v in settings.items()}
    _, errors = state_from_query({"scene": scene, **clean})  # as a link would: each value against the scene's
    if errors:
        raise TourError(f"{where}: {errors[0]}")
    look = data.get("look", [])
    if not isinstance(look, list) or len(look) > MAX_LOOK:
        raise TourError(f"{where}: 'look' must be a list of at most {MAX_LOOK} points {{q, r, label}}")
    marks = []
    for i, m in enumerate(look, 1):
        if not isinstance(m, dict) or set(m) - {"q", "r", "label"}:
            raise TourError(f"{where}: look #{i} must be an object {{q, r, label}}")
        q, r, label = m.get("q"), m.get("r"), m.get("label", "")
        if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in (q, r)):
            raise TourError(f"{where}: look #{i} needs finite numbers q and r, got q={q!r}, r={r!r}")
        if not isinstance(label, str) or len(label) > 80:
            raise TourError(f"{where}: look #{i}'s label must be text of at most 80 characters")
        marks.append(Look(float(q), float(r), label))
    run = data.get("run", False)
    if not isinstance(run, bool):
        raise TourError(f"{where}: 'run' must be true or false, got {run!r}")
    if run and clean.get("tab") not in RUN_TABS:
        raise TourError(f"{where}: 'run' presses the Run of the tab the step opens: its settings need 'tab' one of "
                        f"{', '.join(RUN_TABS)}, got {clean.get('tab', 'section')!r}")  # fmt: skip
    return Step(text.strip(), clean, tuple(marks), run)


def parse_tours(text: str | bytes, source: str = "tours file") -> dict[str, Tour]:
    """The tours of a file's text, in order; TourError naming the bad entry (``source``: the file's name)."""
    if len(text) > MAX_TOURS_BYTES:
        raise TourError(f"{source}: at most {MAX_TOURS_BYTES} bytes, got {len(text)}")
    try:
        data = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise TourError(f"{source}: not JSON ({' '.join(str(exc).split())[:120]})") from None
    if not isinstance(data, dict) or not isinstance(data.get("tours"), list):
        raise TourError(f'{source}: expected {{"tours": [...]}}')
    if not 1 <= len(data["tours"]) <= MAX_TOURS:
        raise TourError(f"{source}: 1..{MAX_TOURS} tours, got {len(data['tours'])}")
    out: dict[str, Tour] = {}
    for i, t in enumerate(data["tours"], 1):
        if not isinstance(t, dict):
            raise TourError(f"{source}: {_where(i)} must be an object with id, title, scene, steps")
        tid = t.get("id")
        if not isinstance(tid, str) or not _ID.match(tid):
            raise TourError(f"{source}: {_where(i)}: 'id' must be letters, digits, '_', '.', '-' (1..40), got {tid!r}")
        if tid in out:
            raise TourError(f"{source}: {_where(tid)} appears twice")
        extra = set(t) - {"id", "title", "scene", "steps"}
        if extra:
            raise TourError(f"{source}: {_where(tid)}: unknown field {sorted(extra)[0]!r}")
        title = t.get("title")
        if not isinstance(title, str) or not 0 < len(title) <= 120:
            raise TourError(f"{source}: {_where(tid)}: 'title' must be text of 1..120 characters")
        scene = t.get("scene")
        try:
            if not isinstance(scene, str) or not _ID.match(scene):
                raise KeyError(scene)
            get_scene(scene)
        except (KeyError, ValueError):
            raise TourError(f"{source}: {_where(tid)}: unknown scene {scene!r}") from None
        steps = t.get("steps")
        if not isinstance(steps, list) or not 1 <= len(steps) <= MAX_TOUR_STEPS:
            raise TourError(f"{source}: {_where(tid)}: 'steps' must be a list of 1..{MAX_TOUR_STEPS} steps")
        out[tid] = Tour(
            tid, title, scene, tuple(_step(s, f"{source}: {_where(tid, n)}", scene) for n, s in enumerate(steps, 1))
        )
    return out


def load_tours(path: Path = TOURS_FILE) -> dict[str, Tour]:
    return parse_tours(path.read_bytes(), path.name)


def read_tour_url(url: str) -> dict[str, Tour]:
    """A teacher's tours file named by ``tour_url=/tours/NAME.json``: read from :data:`TOURS_DIR` on this server."""
    if not url.startswith("/tours/") or ".." in url or "//" in url:
        raise TourError(f"tour_url must be a path /tours/NAME.json on this server, got {url[:60]!r}")
    path = (TOURS_DIR / url.removeprefix("/tours/")).resolve()
    if TOURS_DIR.resolve() not in path.parents or not path.is_file():
        raise TourError(
            f"tour_url: no tours file {url[:60]!r} on this server (a teacher's tours files go in its "
            "directory of tours, app/tours/ or BILIMOVICH_TOURS_DIR): only the paper's tours are offered"
        )
    if path.stat().st_size > MAX_TOURS_BYTES:
        raise TourError(f"tour_url {url[:60]!r}: at most {MAX_TOURS_BYTES} bytes")
    return parse_tours(path.read_bytes(), url)


def nearest_step(tour: Tour, text: str | None) -> tuple[int, str]:
    """The step a link's ``step=`` names (``text``; None: none, the first), or else the nearest one and a message
    that names the value and the step shown instead ("" when the value names a step)."""
    if text is None:
        return 1, ""
    n = len(tour.steps)
    try:
        wanted = float(text.strip())
    except ValueError:
        wanted = math.nan
    if math.isfinite(wanted) and wanted == int(wanted) and 1 <= wanted <= n:
        return int(wanted), ""
    # A number: the step nearest to it; anything else: the first.
    step = min(max(1, round(wanted)), n) if math.isfinite(wanted) else 1
    what = f"there is no step {text[:20]}" if math.isfinite(wanted) else f"{text[:20]!r} is not a step number"
    return step, f"URL parameter step: {what} (the tour '{tour.title}' has steps 1 to {n}): showing step {step}"


#: The paper's tours (the file shipped with the app): a bad file stops the server at start, naming the entry.
TOURS: dict[str, Tour] = load_tours()

__all__ = ["RUN_TABS", "TOURS", "Look", "Step", "Tour", "TourError", "load_tours",
           "nearest_step", "parse_tours", "read_tour_url"]  # fmt: skip
