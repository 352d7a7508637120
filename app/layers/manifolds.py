"""Stable and unstable manifolds of the saddles the user picked (from the orbits layer), refined for the view."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import param

from app.controls import PLOT_PIXELS, SYSTEM_FIELDS, UrlKey, ints, places, points_text
from app.layers.base import KEEP, Action, Layer, Table, loss_lines, plain
from app.layers.orbits import MAX_ORBIT_PERIOD
from app.runner import LAYER
from explorer_core.analyses.manifolds import MANIFOLD_NUMERICS, Manifolds, ManifoldSpec, iter_manifolds, manifold_spec
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError, Params

#: A click picks the saddle whose point is nearest, within this fraction of the view's width and height.
PICK_RADIUS = 0.03
#: Saddles whose stable and unstable manifolds are drawn at once, per session.
MAX_MANIFOLDS = 4


def _saddles(text: str) -> dict[str, Any]:
    """The URL's saddles: ``q,r,period;...``."""
    out = []
    for q, r, n in places("man", text, MAX_MANIFOLDS, "saddles", 3, "q,r,period"):
        if not (n == int(n) and 1 <= n <= MAX_ORBIT_PERIOD):
            raise ParameterError(f"the period must be a whole number 1..{MAX_ORBIT_PERIOD}, got {n:g}")
        out.append((q, r, int(n)))
    return {"manifold_saddles": out}


@dataclass(frozen=True)
class ManifoldInputs:
    params: Params
    view: tuple[float, float, float, float]
    saddles: tuple[tuple[float, float, int], ...]
    length: float
    query: dict[str, str] = field(default_factory=dict, compare=False)
    #: The page's Method and Accuracy by the core's rule, at the manifolds' own tolerance under "plot".
    numerics: Numerics = field(default_factory=lambda: MANIFOLD_NUMERICS)


class ManifoldsLayer(Layer):
    name = "manifolds"
    channels: ClassVar[dict[str, str]] = {"manifolds": LAYER}
    fields = ("manifold_saddles", "manifold_length")
    dedupe = True
    depends = (*SYSTEM_FIELDS, "manifold_length", "q_range", "r_range")
    controls = (
        ints("manifold_length", "Manifolds: arc length of each branch", "layers", "man_len", 1, 200, 10,
             help="Click a saddle ✕ with 'draws a saddle's manifolds': its unstable (orange) and stable (teal) "
             "manifolds, grown to this arc length and refined for the view; ◆ black: homoclinic points.",
             url_when=lambda s: bool(s.manifold_saddles) or s.manifold_length != 10),
    )  # fmt: skip
    picks: ClassVar[dict[str, param.Parameter]] = {
        "manifold_saddles": param.List(default=[], item_type=tuple, doc="(q, r, period) of the saddles with manifolds"),
    }
    urls = (
        UrlKey("man", ("manifold_saddles",), lambda s: points_text(s.manifold_saddles), _saddles,
               lambda s: bool(s.manifold_saddles), "saddles with manifolds"),
    )  # fmt: skip
    #: The saddles whose manifolds are on screen (the CSV download offers exactly these), what the last growth said.
    publishes: ClassVar[dict[str, Any]] = {"n_manifolds": 0, "manifold_status": ""}
    actions = (
        Action("clear_manifolds", "clear_all"),
        Action("manifolds", "pick", "draws a saddle's manifolds", click=True),
    )
    download = "manifolds"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.manifolds: list[Manifolds] = []
        self.text = ""
        self.ran_with = ""

    def inputs(self) -> ManifoldInputs | object | None:
        st = self.host.state
        if not st.manifold_saddles:
            return None
        params = self.system_params()
        if params is None:
            return KEEP
        view = (*st.q_range, *st.r_range)
        numerics, self.ran_with = st.numerics_for(MANIFOLD_NUMERICS)
        return ManifoldInputs(params, view, tuple(st.manifold_saddles), float(st.manifold_length), st.to_query(),
                              numerics)  # fmt: skip

    def on_view(self) -> bool:
        return bool(self.host.state.manifold_saddles)  # refined for the new view's pixels

    def prepare(self, inputs: ManifoldInputs) -> ManifoldInputs:
        self.text = f"growing the manifolds of {len(inputs.saddles)} saddle(s)…"
        return inputs

    def job(self, inputs: ManifoldInputs, cancelled: Callable[[], bool]) -> Iterator[tuple[list[Manifolds], str]]:
        done: list[Manifolds] = []
        notes: list[str] = []
        for q, r, n in inputs.saddles:
            try:
                spec = self.spec(inputs, (q, r), n)
                orbit = spec.saddle()
            except ParameterError as exc:  # e.g. no longer a saddle for this system
                notes.append(f"({q:.4g}, {r:.4g}): {plain(exc)}")
                continue
            for m in iter_manifolds(spec.params, orbit, **spec.growth(), others=done, cancel=cancelled):
                if cancelled():
                    return
                shown = [*done, m]
                text = "; ".join([*(_manifold_text(x) for x in shown), *notes])
                yield shown, ("growing… " + text if not m.completed else text)
            done.append(m)
        if not done:
            yield [], "; ".join(notes)

    @staticmethod
    def spec(inputs: ManifoldInputs, point: tuple[float, float], period: int) -> ManifoldSpec:
        """One saddle's manifolds as the core's builder makes them (the command line's ``manifolds --orbit Q,R
        --period N`` with the view, its pixels and the page's numerics)."""
        return manifold_spec(inputs.params, point, period, length=inputs.length, view=inputs.view,
                             pixels=PLOT_PIXELS, numerics=inputs.numerics)  # fmt: skip

    def current(self, inputs: ManifoldInputs) -> bool:
        return inputs.params == self.host.system()  # else grown for a system no longer on screen

    def apply(self, inputs: ManifoldInputs, result: tuple[list[Manifolds], str]) -> None:
        shown, self.text = result
        self.manifolds = shown
        self.shown_query = inputs.query
        lines = [(p[:, 1], p[:, 2], b.kind) for m in shown for b in m.branches for p in b.pieces]
        marks = [(c.q, c.r, f"{c.kind}: unstable {c.unstable}, stable {c.stable}") for m in shown for c in m.crossings]
        self.host.fig.set_manifolds(lines, marks)

    def clear(self) -> None:
        self.manifolds = []
        self.shown_query = None
        self.text = ""
        self.host.fig.set_manifolds([], [])

    def status(self) -> str:
        return self.text

    def published(self) -> dict[str, Any]:
        # n_manifolds: on screen (the CSV download offers exactly these); the numerics they were grown with
        text = f"{self.text}; grown on {self.ran_with}" if self.text and self.manifolds and self.ran_with else self.text
        return {"n_manifolds": len(self.manifolds), "manifold_status": text}

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        if not self.host.state.manifold_saddles:
            return
        note = self.stale(self.shown_query, now, self.depends) if self.manifolds else ""
        if note:
            self.text = f"stopped: the manifolds shown are for {note}"
        elif busy:
            self.text = "stopped: " + self.text.removeprefix("growing… ")

    # --- what the user does -----------------------------------------------------------------

    def clear_all(self) -> None:
        """Every saddle's manifolds gone (and the message of a pick that drew none)."""
        for channel in self.channels:
            self.host.runner.cancel(channel)
        self.host.state.manifold_saddles = []  # the watcher redoes the layer: off
        self.host.clear(self)

    def pick(self, q: float, r: float) -> None:
        """A click in "manifolds" mode: the saddle of the orbits layer nearest the click (drawn, or removed)."""
        if not (np.isfinite(q) and np.isfinite(r)):
            return
        orbits = getattr(self.host.layers.get("orbits"), "orbits", [])  # the saddles it found
        st = self.host.state
        sq = st.q_range[1] - st.q_range[0]
        sr = st.r_range[1] - st.r_range[0]
        best, where = None, np.inf
        for o in orbits:
            if o.kind not in ("saddle", "flip saddle"):
                continue
            d = float(np.min(np.hypot((o.points[:, 0] - q) / sq, (o.points[:, 1] - r) / sr)))
            if d < where:
                best, where = o, d
        if best is None or where > PICK_RADIUS:
            self.text = (
                "no saddle ✕ near the click: find the orbits first ('Find orbits in view', or click with "
                "'finds a periodic orbit')"
                if best is None
                else f"no saddle ✕ near ({q:.4g}, {r:.4g}): click on a saddle's cross"
            )
            self.host.publish(self)
            return
        x = best.points[0]
        entry = (float(x[0]), float(x[1]), int(best.period))
        kept = [s for s in st.manifold_saddles if not _same_saddle(s, entry, sq, sr)]
        if len(kept) < len(st.manifold_saddles):
            st.manifold_saddles = kept  # a second click on a drawn saddle removes its manifolds
            return
        if len(kept) >= MAX_MANIFOLDS:
            self.text = f"at most {MAX_MANIFOLDS} saddles at once: click a drawn one to remove it"
            self.host.publish(self)
            return
        st.manifold_saddles = [*kept, entry]

    def table(self) -> Table | None:
        """The manifolds on screen, ``saddle,branch,kind,s,q,r``, under the settings they were grown with."""
        if not self.manifolds:
            return None
        rows = ((i, *row) for i, m in enumerate(self.manifolds) for row in m.rows())
        # Not whole: a growth stopped before its length (a Stop), or branches that ended short (escaped, budget).
        stopped = not all(m.completed for m in self.manifolds)
        lost = [loss for m in self.manifolds for loss in m.lost]
        return Table("manifolds", self.shown_query or self.host.state.to_query(),
                     ("saddle", "branch", "kind", "s", "q", "r"), rows, partial=loss_lines(lost, stopped))  # fmt: skip


def _same_saddle(a: tuple, b: tuple, sq: float, sr: float) -> bool:
    """The same saddle entry ``(q, r, period)``: equal periods, points within a thousandth of the view."""
    return a[2] == b[2] and abs(a[0] - b[0]) <= 1e-3 * sq and abs(a[1] - b[1]) <= 1e-3 * sr


def _manifold_text(m: Manifolds) -> str:
    o = m.orbit
    ends = sorted({b.end for b in m.branches})
    homoclinic = sum(c.kind == "homoclinic" for c in m.crossings)
    hetero = len(m.crossings) - homoclinic
    text = (f"{o.kind} (period {o.period}) at ({o.points[0, 0]:.4g}, {o.points[0, 1]:.4g}): "
            f"{len(m.branches)} branches to s = {m.length:g} ({', '.join(ends)})")  # fmt: skip
    if m.completed:
        text += f", {homoclinic} homoclinic" + (f" and {hetero} heteroclinic" if hetero else "") + " points"
        escaped = sum(b.escaped for b in m.branches)
        if escaped:
            text += f", {escaped} points escaped (pieces split)"
        text += f", {m.elapsed_s:.2f} s"
    return text
