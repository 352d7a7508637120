"""Basins of attraction over the view: which attractor each pixel centre reaches, coarse to fine."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

from app.controls import SYSTEM_FIELDS, Control, ints
from app.layers.base import KEEP, Download, Layer, plain, result_file
from app.runner import LAYER
from app.views import as_drawn
from explorer_core.analyses.basins import ESCAPE, FAILED, UNDECIDED, Basins, BasinSpec, basin_spec, iter_basins
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status, describe
from explorer_core.system.params import ParameterError, Params

#: Pixels across the basins layer (its work: up to 40,000 initial conditions).
MAX_BASIN_GRID = 200
#: A colour per attractor id (cycled), and the pixels that reach none.
BASIN_COLOURS = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#1f78b4")
#: Escaped pixels mid grey, failed ones dark grey (the old light grey at half opacity looked like the page's white);
#: undecided ones are left blank, and the legend says so.
OUTCOME_COLOURS = {ESCAPE: "#555555", FAILED: "#000000", UNDECIDED: "#ffffff"}
#: In the one status vocabulary's words (explorer_core.status), as the CLI prints them.
OUTCOME_NAMES = {
    ESCAPE: f"{Status.ESCAPED.word} (noncompact drift)",
    FAILED: "integration failed",
    UNDECIDED: f"{Status.UNDECIDED.word} (blank)",
}


def attractor_words(a: Any) -> str:
    """What an attractor is, in the legend's words (the app's and the notebook's)."""
    if not a.attracting:  # invariant curves of a conservative island: no attractor
        what = "conservative island (not an attractor)"
    elif a.kind == "periodic":
        what = f"period-{a.period} cycle"
    else:
        what = a.kind.replace("_", "-") + " attractor"
    what += f" ({a.orbit_type})" if a.orbit_type else ""
    # a chaotic or quasi-periodic set recurred; its seed stayed on it a horizon: no proof it is no long transient
    return what + (", may be a long transient" if getattr(a, "may_be_transient", False) else "")


@dataclass(frozen=True)
class BasinInputs:
    params: Params
    box: tuple[float, float, float, float]
    n: int
    query: dict[str, str] = field(default_factory=dict, compare=False)
    #: The page's Method and Accuracy by the core's rule, at the basins' own tolerance under "plot".
    numerics: Numerics | None = None


class BasinsLayer(Layer):
    name = "basins"
    channels: ClassVar[dict[str, str]] = {"basins": LAYER}
    fields = ("show_basins", "basin_grid")
    dedupe = True
    depends = (*SYSTEM_FIELDS, "basin_grid", "q_range", "r_range")
    controls = (
        Control("show_basins", "Basins of attraction over the view", "check", "layers", "basins",
                help="Which attractor each point of the view reaches (a colour per attractor, grey: escape), computed "
                "coarse to fine by recurrences (as Attractors.jl) and Newton on the cycles; redone when you pan or "
                "zoom.", default=False, url_when="changed"),
        ints("basin_grid", "Basins: pixels across", "layers", "bas_n", 10, MAX_BASIN_GRID, 80, url_when="changed"),
    )  # fmt: skip
    #: What it says, and its legend rows (colour, text).
    publishes: ClassVar[dict[str, Any]] = {"basin_status": "", "basin_legend": []}
    #: Its download: the basins on screen as ``bilimovich basins --out basins.npz`` writes them.
    download = "basins"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.text = ""
        self.rows: list[list[str]] = []
        self.ran_with = ""
        self.result: Basins | None = None  # the basins on screen (a snapshot of the core's: never changes)

    def inputs(self) -> BasinInputs | object | None:
        st = self.host.state
        if not st.show_basins:
            return None
        params = self.system_params()
        if params is None:
            return KEEP
        box = (*st.q_range, *st.r_range)
        try:  # the basins' own numerics for this box (its escape bound), under the page's Method and Accuracy
            own = basin_spec(params, box, (st.basin_grid, st.basin_grid)).numerics
        except ParameterError:
            own = None  # refused again, in words, when the spec is built (prepare)
        numerics, self.ran_with = st.numerics_for(own) if own is not None else (None, "")
        return BasinInputs(params, box, st.basin_grid, st.to_query(), numerics)

    def on_view(self) -> bool:
        return bool(self.host.state.show_basins)  # the initial conditions are the new view's pixels

    def prepare(self, inputs: BasinInputs) -> BasinSpec:
        spec = self.spec(inputs)
        self.text = f"basins of attraction on {inputs.n} x {inputs.n} initial conditions in view…"
        return spec

    @staticmethod
    def spec(inputs: BasinInputs) -> BasinSpec:
        """The basins as the core's builder makes them (the command line's ``basins --box Q0,Q1,R0,R1 --grid N,N``
        with the page's numerics)."""
        return basin_spec(inputs.params, inputs.box, (inputs.n, inputs.n), numerics=inputs.numerics)

    def refused(self, exc: BaseException) -> None:
        self.text = f"basins: {plain(exc)}"

    def job(self, spec: BasinSpec, cancelled: Callable[[], bool]) -> Iterator[tuple[Basins, str]]:
        for upd in iter_basins(spec, cancel=cancelled):
            if cancelled():
                return
            if upd.basins.completed:
                upd.basins.entropy  # noqa: B018 (read here, on the runner's thread: cached for apply)
            yield upd.basins, f"{upd.done_pixels}/{upd.total_pixels}"

    def current(self, inputs: BasinInputs) -> bool:
        st = self.host.state  # else for a system or a view no longer on screen
        return inputs.params == self.host.system() and inputs.box == (*st.q_range, *st.r_range)

    def apply(self, inputs: BasinInputs, result: tuple[Basins, str]) -> None:
        b, done = result
        self.shown_query = inputs.query
        self.result = b
        colours = {a.id: BASIN_COLOURS[i % len(BASIN_COLOURS)] for i, a in enumerate(b.attractors)}
        colours.update(OUTCOME_COLOURS)
        self.host.fig.set_basins(b.filled(), inputs.box, colours)
        legend = []
        for a in b.attractors:
            if a.kind == "escape":
                continue
            what = attractor_words(a)
            if len(a.points):
                what += f" at ({a.points[0, 0]:.4g}, {a.points[0, 1]:.4g})"
            legend.append([as_drawn(colours[a.id]), f"{what}: {100 * b.fraction.get(a.id, 0.0):.1f}%"])
        for code, name in OUTCOME_NAMES.items():
            if b.fraction.get(code, 0.0) > 0:
                if code == FAILED:  # which failures, in the status words
                    name += f" ({describe(b.status[b.label == FAILED])})"
                legend.append([as_drawn(OUTCOME_COLOURS[code]), f"{name}: {100 * b.fraction[code]:.1f}%"])
        self.rows = legend
        n_att = sum(a.kind != "escape" and a.attracting for a in b.attractors)
        if b.completed:
            head = f"basins on {b.label.shape[1]} x {b.label.shape[0]} initial conditions: {n_att} attractor(s)"
            if not n_att:
                head += " (none found: every pixel escaped, failed or was undecided)"
            unsure = sum(a.may_be_transient for a in b.attractors)
            if unsure:
                followed = b.spec.confirm
                checked = f"beyond the {followed} periods their seeds were followed" if followed else "unchecked"
                head += f" ({unsure} chaotic or quasi-periodic: may be long transients, {checked})"
            head += f"; basin entropy {b.entropy.words()}"  # Daza et al. 2016: how mixed the basins are
            said = [*b.warnings, *(loss.line() for loss in b.lost)]
            self.text = f"{head}, {b.elapsed_s:.2f} s" + "".join(f"; {w}" for w in said[:3])
            if self.ran_with:  # the numerics come last: the attractors are what the class looks at first
                self.text += f" · numerics: {self.ran_with}"
        else:
            self.text = f"basins: {done} pixels, {n_att} attractor(s) so far…"

    def clear(self) -> None:
        self.host.fig.set_basins(None)
        self.text, self.rows = "", []
        self.shown_query = None
        self.result = None

    def file(self) -> Download | None:
        """The basins on screen as the command line's NPZ (``basins.npz``; ``basins-partial.npz`` and its summary's
        ``completed``/``complete``/``lost`` when the run did not end)."""
        return None if self.result is None else result_file(self.result, "basins", ".npz")

    def status(self) -> str:
        return self.text

    def legend(self) -> list[list[str]]:
        return self.rows

    def published(self) -> dict[str, Any]:
        return {"basin_status": self.text, "basin_legend": self.rows}

    def view(self) -> dict[str, Any]:
        return {**self.published(), "basins_file": self.result is not None}  # its download button is offered

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        if not self.host.state.show_basins:
            return
        note = self.stale(self.shown_query, now, self.depends)
        if note:
            self.text = f"stopped: the basins shown are for {note}"
        elif busy:
            shown = self.shown_query is not None
            self.text = "stopped: " + (self.text if shown else "no basins computed yet")
