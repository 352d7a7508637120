"""The frozen-field layers' common ground (:class:`FrozenLayer`, :func:`segments_by_type`) and the T′ map under
the points; the equilibrium tracks of the field with t frozen are :mod:`app.layers.tracks`.

Both start once the section's first points are out (``after_section``): computed alongside, they would take
CPU from the section's first points, and every update they send makes the browser redraw the whole plot while the
points are still coming. A played parameter's frame is drawn whole: there they start with its section
(app/controller.py). Neither has text of its own: a Stop that leaves them for another system clears them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from app.controls import Control, UrlKey, choice
from app.layers.base import KEEP, Layer
from app.runner import LAYER
from explorer_core.analyses.tprime import TPrimeSpec, tprime, tprime_spec
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import Params

TPRIME_GRID = 160
PER_PERIOD_GRID = 80
#: The T′ map's URL key: one value for both its controls.
_TPRIME = {"inst": {"show_tprime": True, "tprime_kind": "instantaneous"},
           "period": {"show_tprime": True, "tprime_kind": "per-period"}, "off": {"show_tprime": False}}  # fmt: skip
_TPRIME_KEY = {"instantaneous": "inst", "per-period": "period"}


class FrozenLayer(Layer):
    """A layer of the system alone, cleared by a Stop that leaves it for another system."""

    on_section = False
    after_section = True

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.params: Params | None = None  # the system of what is on screen

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        if self.params is not None and self.params != self.host.system():
            self.clear()  # no text says whose it is: not left under other settings


@dataclass(frozen=True)
class TPrimeInputs:
    params: Params
    kind: str
    q_range: tuple[float, float]
    r_range: tuple[float, float]
    numerics: Numerics


class TPrimeLayer(FrozenLayer):
    name = "tprime"
    channels: ClassVar[dict[str, str]] = {"tprime": LAYER}
    fields = ("show_tprime", "tprime_kind")
    controls = (
        Control("show_tprime", "T′ map under the points", "check", "layers", default=True),
        Control("tprime_kind", "T′ map", "radio", "layers", None,
                options=(("instantaneous", "at t0"), ("per-period", "over a period")), default="instantaneous"),
    )  # fmt: skip
    urls = (
        UrlKey("tprime", ("show_tprime", "tprime_kind"),
               lambda s: _TPRIME_KEY[s.tprime_kind] if s.show_tprime else "off", choice(_TPRIME), words="T′ map"),
    )  # fmt: skip

    def inputs(self) -> TPrimeInputs | object | None:
        params = self.system_params()
        if params is None:
            return KEEP
        st = self.host.state
        if not st.show_tprime:
            return None
        return TPrimeInputs(params, st.tprime_kind, st.q_range, st.r_range, st.numerics())

    def on_view(self) -> bool:
        return True  # the map is of the view's window

    @staticmethod
    def spec(inputs: TPrimeInputs) -> TPrimeSpec:
        """The map as the core's builder makes it (the command line's ``tprime --q-range ... --grid N``, with
        ``--per-period`` and the page's numerics over a period)."""
        per = inputs.kind == "per-period"
        grid = PER_PERIOD_GRID if per else TPRIME_GRID
        return tprime_spec(inputs.params, None, inputs.q_range, inputs.r_range, grid, per_period=per,
                           numerics=inputs.numerics)  # fmt: skip

    def job(self, inputs: TPrimeInputs, cancelled: Callable[[], bool]) -> Iterator[tuple[Any, str]]:
        spec = self.spec(inputs)
        # the titles fit the plot's height at 1280x720
        title = "ΔT over a period: red gain, blue loss" if spec.per_period else "T′ at t0: red energy gain, blue loss"
        yield tprime(spec), title

    def apply(self, inputs: TPrimeInputs, result: tuple[Any, str]) -> None:
        m, title = result
        self.params = inputs.params
        self.host.fig.set_tprime(m.values, m.q, m.r, title)

    def clear(self) -> None:
        self.params = None
        self.host.fig.set_tprime(None, np.zeros(0), np.zeros(0), "")

    def view(self) -> dict[str, Any]:
        return {"colour_note": colour_note(self.host.fig.tprime_hidden_by)}


def colour_note(hidden_by: str) -> str:
    """Why the T' map is not drawn although it is on (its colours would tint those of the layer over it)."""
    if not hidden_by:
        return ""
    verb = "are" if hidden_by == "the basins" else "is"
    return f"The T′ map is hidden while {hidden_by} {verb} shown (its colours would mix with theirs)."


def segments_by_type(branches: Any) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """Split each track where the equilibrium's type changes, so each piece has one colour."""
    out: list[tuple[np.ndarray, np.ndarray, str]] = []
    for b in branches:
        q, r, types = b["q"], b["r"], b["types"]
        start = 0
        for i in range(1, len(types) + 1):
            if i == len(types) or types[i] != types[start]:
                # Overlap one sample so consecutive pieces join.
                end = min(i + 1, len(types))
                if end - start >= 2:
                    out.append((q[start:end], r[start:end], types[start]))
                start = i
    return out
