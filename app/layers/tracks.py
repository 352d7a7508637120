"""The equilibrium tracks of the field with t frozen over one period, and the equilibria at the section phase.

A layer of the system alone (:class:`app.layers.frozen.FrozenLayer`): it starts once the section's first points are
out and a Stop that leaves it for another system clears it. Its one setting is the checkbox ``show_tracks`` (URL key
``tracks``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, ClassVar

from app.controls import Control
from app.layers.base import KEEP
from app.layers.frozen import FrozenLayer, segments_by_type
from app.runner import LAYER
from explorer_core.analyses.equilibria import CriticalSpec, critical_points, critical_spec
from explorer_core.system.params import Params

TRACK_SAMPLES = 360
#: Samples of a played parameter's frame (app/play.py), and the bisections allowed where the equilibria's count
#: changes (a still's default: 4 per sample): a fold in t is drawn to a sixtieth of the period, not to 2^-12 of it.
#: Since the conic solves are numba kernels a frame's tracks cost ~1.2 ms and a still's ~4 ms (were ~28 and ~90 ms of
#: Python); the frame's fewer samples still keep its jobs short beside the section's integration.
FRAME_TRACK_SAMPLES = 60
FRAME_TRACK_REFINE = 30


class TracksLayer(FrozenLayer):
    name = "tracks"
    channels: ClassVar[dict[str, str]] = {"tracks": LAYER}
    fields = ("show_tracks",)
    controls = (
        Control("show_tracks", "Frozen-field equilibria (tracks over one period)", "check", "layers", "tracks",
                help="Equilibria of the field with t frozen: a heuristic for slow forcing, not orbits of P.",
                default=True),
    )  # fmt: skip

    def inputs(self) -> tuple[Params, int, int | None] | object | None:
        """``(params, samples, bisections)``: a frame's (fewer) or a still's (the default refinement)."""
        params = self.system_params()
        if params is None:
            return KEEP
        if not self.host.state.show_tracks:
            return None
        frame = getattr(self.host, "frame_periods", None) is not None  # a frame of a played parameter
        return (params, FRAME_TRACK_SAMPLES, FRAME_TRACK_REFINE) if frame else (params, TRACK_SAMPLES, None)

    @staticmethod
    def spec(inputs: tuple[Params, int, int | None]) -> CriticalSpec:
        """The tracks as the core's builder makes them (the command line's ``critical --track --n-t N``)."""
        params, samples, refine = inputs
        return critical_spec(params, track=True, n_t=samples, max_refine=refine)

    def prepare(self, inputs: tuple[Params, int, int | None]) -> CriticalSpec:
        return self.spec(inputs)  # a system whose tables overflow is refused here, in words (not in the job)

    def job(self, spec: CriticalSpec, cancelled: Callable[[], bool]) -> Iterator[tuple[list, Any]]:
        tr = critical_points(spec, cancel=cancelled)
        if tr.completed:  # else a newer setting: its own tracks job is on the way
            yield segments_by_type(tr.branches()), tr.section()

    def apply(self, inputs: tuple[Params, int, int | None], result: tuple[list, Any]) -> None:
        segments, at_t0 = result
        self.params = inputs[0]
        self.host.fig.set_tracks(segments)
        self.host.fig.set_equilibria(at_t0.q, at_t0.r, at_t0.types)

    def clear(self) -> None:
        self.params = None
        self.host.fig.set_tracks([])
        self.host.fig.set_equilibria([], [], ())
