"""The selected trajectory's verdict beside its k-series: regular (with its rotation number), chaotic or undecided, by
weighted Birkhoff averages (:func:`explorer_core.analyses.indicators.iter_birkhoff`, the command line's
``bilimovich birkhoff --ic Q,R --transient T``: 2 x 500 periods from the trajectory's initial condition).

It integrates the orbit again rather than averaging the section's points: those are computed at the plot's
tolerance, in lock-step blocks with the other trajectories, and their digits of convergence depend on both (Fig. 5A's
island orbit from (0.4, 0) gave 11 digits beside a stiff trajectory and 6.8 without it: "undecided"). At the
Birkhoff analysis' own numerics (the Lyapunov exponent's, under the page's Method and Accuracy) one orbit of 1000
periods takes about 0.1 s, on its own channel, after the section's first points. It is computed for the
trajectories clicked in the plot and the scene's own initial conditions (those numbered after the random ones), not
for a random one: a new page selects random trajectory 0, and its verdict was a sixth of the default page's work
(0.025 of 0.156 s of CPU).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, ClassVar

from app.controls import SYSTEM_FIELDS
from app.layers.base import KEEP, Layer
from app.runner import LAYER
from explorer_core.analyses.indicators import (
    CHAOTIC,
    NUMERICS_ARG,
    REGULAR,
    Birkhoff,
    BirkhoffSpec,
    birkhoff_spec,
    iter_birkhoff,
)
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status
from explorer_core.system.params import Params

#: Periods in each half of the test (the command line's default: ``birkhoff`` runs 2 x 500).
HALF_PERIODS = 500


@dataclass(frozen=True)
class VerdictInputs:
    """The selected trajectory ``traj``: its initial condition ``ic`` after ``transient`` periods, in ``params``."""

    params: Params
    traj: int
    ic: tuple[float, float]
    transient: int
    numerics: Numerics


def verdict_words(b: Birkhoff) -> str:
    """The verdict on the one orbit of ``b`` in the page's words: "regular (Birkhoff, 11 digits): rotation number
    0.2260682", "chaotic (Birkhoff, 1.6 digits after 1000 periods)", "undecided after 1000 periods (Birkhoff,
    5.2 digits)", or why there is none ("no verdict: escaped"; "no Birkhoff verdict: it drifts off ...": a drift has
    no invariant measure to average, and its negative digits are no chaos)."""
    digits, verdict, periods = float(b.digits[0]), int(b.verdict[0]), 2 * b.spec.periods
    status = Status(int(b.status[0]))
    if verdict == REGULAR:
        return f"regular (Birkhoff, {digits:.0f} digits): rotation number {float(b.rotation[0]):.7f}"
    if verdict == CHAOTIC:
        return f"chaotic (Birkhoff, {digits:.1f} digits after {periods} periods)"
    if b.drifting[0]:
        return f"no Birkhoff verdict: it drifts off within {periods} periods (no invariant measure to average)"
    if status in (Status.OK, Status.UNDECIDED):
        return f"undecided after {periods} periods (Birkhoff, {digits:.1f} digits)"
    return f"no Birkhoff verdict: {status.label} within {periods} periods"


class RotationLayer(Layer):
    """The verdict on the selected trajectory when it was clicked (no controls: it follows the selection and the
    system)."""

    name = "rotation"
    channels: ClassVar[dict[str, str]] = {"rotation": LAYER}
    fields = ("selected",)
    on_section = False
    after_section = True  # never before the section's first points
    dedupe = True
    depends = (*SYSTEM_FIELDS, "selected", "transient", "n_random", "seed", "clicked")
    publishes: ClassVar[dict[str, Any]] = {"series_verdict": ""}

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.text = ""

    def inputs(self) -> VerdictInputs | object | None:
        st = self.host.state
        params = self.system_params()
        if params is None:
            return KEEP
        if st.selected not in st.clicked_indices() or getattr(self.host, "frame_periods", None) is not None:
            # A random trajectory (a new page's first selection: its verdict would add a sixth to the page's work) or
            # none; or a parameter played (its frames are drawn whole, at their pace).
            return None
        ics = st.initial_conditions()
        numerics, _ = st.numerics_for(NUMERICS_ARG.default)
        q, r = (float(v) for v in ics[st.selected])
        return VerdictInputs(params, st.selected, (q, r), st.transient, numerics)

    @staticmethod
    def spec(inputs: VerdictInputs) -> BirkhoffSpec:
        """The command line's ``birkhoff --ic Q,R 500 --transient T`` with the page's numerics."""
        return birkhoff_spec(inputs.params, [inputs.ic], HALF_PERIODS, transient=inputs.transient,
                             numerics=inputs.numerics)  # fmt: skip

    def prepare(self, inputs: VerdictInputs) -> BirkhoffSpec:
        self.text = ""  # the last trajectory's verdict is not this one's
        return self.spec(inputs)

    def job(self, spec: BirkhoffSpec, cancelled: Callable[[], bool]) -> Iterator[str]:
        for step in iter_birkhoff(spec, cancel=cancelled):
            if step.result is not None and step.result.completed:
                yield verdict_words(step.result)

    def current(self, inputs: VerdictInputs) -> bool:
        return inputs.traj == self.host.state.selected and inputs.params == self.host.system()

    def apply(self, inputs: VerdictInputs, result: str) -> None:
        self.text = result

    def clear(self) -> None:
        self.text = ""

    def published(self) -> dict[str, Any]:
        return {"series_verdict": self.text}
