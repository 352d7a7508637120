"""A finite-time Lyapunov exponent (FTLE) map over the view: the largest exponent of every pixel's initial condition
over a few periods, forward (``P``) or backward (``P^-1``), as an image under the section points.

The map is the core's (:func:`explorer_core.analyses.ftle.iter_ftle`, the command line's ``bilimovich ftle``): its
spec is the one ``ftle --box Q0,Q1,R0,R1 --grid N,N --periods P --direction D`` builds with the page's numerics, and
its download the NPZ that command's ``--out ftle.npz`` writes. Pixels that escaped or failed have no exponent: they are
transparent, and the status line counts them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from app.controls import SYSTEM_FIELDS, Control, ints
from app.layers.base import KEEP, Download, Layer, plain, result_file
from app.runner import LAYER
from explorer_core.analyses.ftle import TILE_PIXELS, FtleMap, FtleSpec, ftle_spec, iter_ftle
from explorer_core.analyses.indicators import NUMERICS_ARG
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status, count_names
from explorer_core.system.params import Params

#: Pixels across the FTLE map (its work: up to 40,000 initial conditions, each with its tangent map).
MAX_FTLE_GRID = 200
#: Periods of each pixel's exponent at most (the picture sharpens with more; its time grows with them).
MAX_FTLE_PERIODS = 500
#: The control's choices: off, or the map's direction (the core's words).
FTLE_MODES = (("off", "off"), ("forward", "forward (P)"), ("backward", "backward (P⁻¹)"))
_OK = int(Status.OK)


@dataclass(frozen=True)
class FtleInputs:
    params: Params
    box: tuple[float, float, float, float]
    n: int
    periods: int
    direction: str
    query: dict[str, str] = field(default_factory=dict, compare=False)
    #: The page's Method and Accuracy by the core's rule, at the FTLE's own tolerance (the Lyapunov exponent's).
    numerics: Numerics | None = None


def ftle_shown(values: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, str]:
    """An FTLE map's ``values`` with NaN where a pixel has no exponent (its ``status`` not ok: drawn transparent,
    never data), and the words of the pixels computed without one ("" when none)."""
    shown = np.where(status == _OK, values, np.nan)
    missing = count_names(status[(status != _OK) & (status != int(Status.NOT_RUN))])
    return shown, ", ".join(f"{n} {name}" for name, n in missing.items())


class FtleLayer(Layer):
    name = "ftle"
    channels: ClassVar[dict[str, str]] = {"ftle": LAYER}
    fields = ("ftle", "ftle_periods", "ftle_grid")
    dedupe = True
    depends = (*SYSTEM_FIELDS, "ftle", "ftle_periods", "ftle_grid", "q_range", "r_range")
    controls = (
        Control("ftle", "FTLE map over the view", "select", "layers", "ftle", options=FTLE_MODES, default="off",
                help="The finite-time Lyapunov exponent of every pixel's initial condition over the periods below "
                "(forward: the map P; backward: P⁻¹, integrated back in time): the chaotic sea light, islands and "
                "regular orbits dark, the ridges the stable (forward) and unstable (backward) manifolds. Pixels that "
                "escape or fail are transparent. Redone when you pan or zoom.", url_when="changed"),
        ints("ftle_periods", "FTLE: periods", "layers", "ftle_p", 1, MAX_FTLE_PERIODS, 20, url_when="changed"),
        ints("ftle_grid", "FTLE: pixels across", "layers", "ftle_n", 10, MAX_FTLE_GRID, 40, url_when="changed"),
    )  # fmt: skip
    publishes: ClassVar[dict[str, Any]] = {"ftle_status": ""}
    #: Its download: the map on screen as ``bilimovich ftle --out ftle.npz`` writes it.
    download = "ftle"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.text = ""
        self.ran_with = ""
        self.result: FtleMap | None = None  # the map on screen (a snapshot of the core's: never changes)

    def inputs(self) -> FtleInputs | object | None:
        st = self.host.state
        if st.ftle == "off":
            return None
        params = self.system_params()
        if params is None:
            return KEEP
        numerics, self.ran_with = st.numerics_for(NUMERICS_ARG.default)
        return FtleInputs(params, (*st.q_range, *st.r_range), st.ftle_grid, st.ftle_periods, st.ftle, st.to_query(),
                          numerics)  # fmt: skip

    def on_view(self) -> bool:
        return self.host.state.ftle != "off"  # the initial conditions are the new view's pixels

    @staticmethod
    def spec(inputs: FtleInputs) -> FtleSpec:
        """The map as the core's builder makes it (the command line's ``ftle --box Q0,Q1,R0,R1 --grid N,N --periods
        P --direction D`` with the page's numerics)."""
        return ftle_spec(inputs.params, inputs.box, grid=(inputs.n, inputs.n), periods=inputs.periods,
                         direction=inputs.direction, numerics=inputs.numerics)  # fmt: skip

    def prepare(self, inputs: FtleInputs) -> FtleSpec:
        spec = self.spec(inputs)
        self.text = f"FTLE ({inputs.direction}, {inputs.periods} periods) on {inputs.n} x {inputs.n} pixels in view…"
        return spec

    def refused(self, exc: BaseException) -> None:
        self.text = f"FTLE: {plain(exc)}"

    def job(self, spec: FtleSpec, cancelled: Callable[[], bool]) -> Iterator[tuple[FtleMap, str]]:
        for step in iter_ftle(spec, cancel=cancelled):
            if cancelled():
                return
            total = spec.grid[0] * spec.grid[1]
            yield step.result, f"{min(step.progress.done * TILE_PIXELS, total)}/{total}"

    def current(self, inputs: FtleInputs) -> bool:
        st = self.host.state  # else for a system or a view no longer on screen
        return inputs.params == self.host.system() and inputs.box == (*st.q_range, *st.r_range)

    def apply(self, inputs: FtleInputs, result: tuple[FtleMap, str]) -> None:
        m, done = result
        self.shown_query = inputs.query
        self.result = m
        _, raw, status = m.maps()[0]
        values, missing = ftle_shown(raw, status)
        d, n = inputs.direction, inputs.periods
        self.host.fig.set_ftle(values, inputs.box, f"FTLE {d} over {n} periods (per unit time)")
        ok = values[np.isfinite(values)]
        if m.completed:
            head = f"FTLE {d} over {n} periods on {m.q.size} x {m.r.size} pixels"
            head += f": {ok.min():.3g} to {ok.max():.3g} per unit time, mean {ok.mean():.3g}" if ok.size else \
                ": no pixel has an exponent"  # fmt: skip
            if missing:
                head += f"; {int(np.count_nonzero(status != _OK))} pixels without one ({missing}: transparent)"
            self.text = f"{head}, {m.elapsed_s:.2f} s"
            if self.ran_with:
                self.text += f" · numerics: {self.ran_with}"
        else:
            self.text = f"FTLE {d}: {done} pixels…" + (f" ({missing}: transparent)" if missing else "")

    def clear(self) -> None:
        self.host.fig.set_ftle(None)
        self.text = ""
        self.shown_query = None
        self.result = None

    def file(self) -> Download | None:
        """The map on screen as the command line's NPZ (``ftle.npz``; ``ftle-partial.npz`` and its summary's
        ``completed``/``complete``/``lost`` when the run did not end)."""
        return None if self.result is None else result_file(self.result, "ftle", ".npz")

    def status(self) -> str:
        return self.text

    def published(self) -> dict[str, Any]:
        return {"ftle_status": self.text}

    def view(self) -> dict[str, Any]:
        return {**self.published(), "ftle_file": self.result is not None}  # its download button is offered

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        if self.host.state.ftle == "off":
            return
        note = self.stale(self.shown_query, now, self.depends)
        if note:
            self.text = f"stopped: the FTLE map shown is for {note}"
        elif busy:
            self.text = "stopped: " + (self.text if self.shown_query is not None else "no FTLE map computed yet")
