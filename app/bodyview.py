"""The body in 3-D (issue 23, item 3): the selected trajectory's rigid body, computed once, animated by the page.

When "Body in 3-D" is on (``body=1`` in the URL), the orientation of the body along the selected trajectory is
computed by the core (:func:`explorer_core.analyses.body.body_series`) in one job on the session's runner, never on
the event loop, and its arrays go to the page once (:func:`encode_series`: little-endian float32, base64, ~46 kB
for 20 periods x 48 frames); ``app/body.js`` animates them alone, with no message to the server per frame, and
moves the highlighted section point (the ``body_source`` of the section figure) as the periods go by.

What is computed: the last :data:`PERIODS` periods of the selected trajectory as the section shows it: from its
section point ``k_start`` (the ``PERIODS + 1``-th last point on screen; the first one if there are fewer) to its
last point, starting from that point itself (the forcing has period ``T``: starting at ``t0`` from the point at
``t0 + k_start T`` is the same motion, with the orientation at ``k_start`` the identity), so the highlighted
points of the body's periods are the trajectory's points on screen (to the section's tolerance) whatever the
transient and the number of periods. The body is integrated with the page's Method and Accuracy by the core's
rule (:func:`~explorer_core.solve.numerics.chosen_numerics`): under Accuracy "plot" at its own tolerance
:data:`TOLERANCE` (the orientation does not depend on the plot's pixel size; vern9 by the "auto" rule), under
"high" at 1e-12.

What is on screen is always the state's: a new selection, a parameter, new numerics or points, or the view closed
drop the series shown at once (and cancel the job computing one); while the section computes or a parameter
plays, no series is computed.
"""

from __future__ import annotations

import base64
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from app.layers.base import plain
from app.layers.section import SECTION_FIELDS
from app.runner import LAYER, Emit
from explorer_core import config
from explorer_core.analyses.body import BodySeries, BodySpec, body_series, body_spec
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import ParameterError, Params

if TYPE_CHECKING:
    from app.controller import ExplorerSession

#: Periods of the selected trajectory the body is shown for (the last ones on screen), and frames per period.
PERIODS = 20
SAMPLES = 48
#: Tolerance (relative and absolute) of the body's integration: the orientation after 20 periods to ~1e-8.
TOLERANCE = config.DEFAULT_RTOL
#: The version of the payload's layout (app/body.js reads it).
FORMAT = 1
CHANNEL = "body"


@dataclass(frozen=True)
class BodyInputs:
    """What one series is computed from (compared to tell whether the series shown is still the state's)."""

    params: Params
    selected: int
    k_start: int  # the section point the series starts from (absolute k: t0 + k T)
    q: float
    r: float
    periods: int
    numerics: Numerics


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype="<f4").tobytes()).decode("ascii")


def _floats(text: str, shape: tuple[int, ...]) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype="<f4").reshape(shape)


def encode_series(series: BodySeries, k_start: int = 0) -> dict[str, Any]:
    """The payload shipped to the page once: arrays as base64 of little-endian float32 (``t`` from the series'
    start, its start ``t_start`` as a number: float32 would round a late time to ~0.1), the rest as numbers."""
    t = np.asarray(series.t, dtype=float)
    frames = int(t.size)
    period = float(series.params.period)
    t_start = (float(t[0]) if frames else float(series.params.t0)) + k_start * period
    return {
        "format": FORMAT,
        "frames": frames,
        "samples": int(series.samples),
        "periods": int(series.periods),
        "k0": int(k_start),
        "period": period,
        "t_start": t_start,
        "t": _b64(t - t[0] if frames else t),
        "omega": _b64(np.asarray(series.omega).reshape(frames, 3)),
        "quaternion": _b64(np.asarray(series.quaternion).reshape(frames, 4)),
        "energy": _b64(np.asarray(series.energy).reshape(frames)),
        "moments": [float(m) for m in series.moments],
        "axes": [[float(v) for v in row] for row in np.asarray(series.axes)],
        "box_sides": [float(s) for s in series.box_sides()],
        "box_exists": bool(series.box_exists),
        "ellipsoid_axes": [float(a) for a in series.ellipsoid_axes()],
        "status": series.status.label,
        "complete": bool(series.complete),
        "lost": [loss.as_dict() for loss in series.lost],
    }


def decode_series(payload: dict[str, Any]) -> dict[str, Any]:
    """A payload read back as the page reads it (tests; the same layout as app/body.js's ``decode``)."""
    f = int(payload["frames"])
    return {
        "frames": f,
        "samples": int(payload["samples"]),
        "k0": int(payload["k0"]),
        "t": float(payload["t_start"]) + _floats(payload["t"], (f,)).astype(float),
        "omega": _floats(payload["omega"], (f, 3)),
        "quaternion": _floats(payload["quaternion"], (f, 4)),
        "energy": _floats(payload["energy"], (f,)),
        "moments": np.array(payload["moments"]),
        "axes": np.array(payload["axes"]),
        "box_sides": np.array(payload["box_sides"]),
        "box_exists": payload["box_exists"],
        "ellipsoid_axes": np.array(payload["ellipsoid_axes"]),
        "status": payload["status"],
        "complete": payload["complete"],
        "lost": payload["lost"],
    }


def payload_bytes(payload: dict[str, Any]) -> int:
    """How many bytes the payload takes as the JSON the page receives."""
    import json

    return len(json.dumps(payload, separators=(",", ":")).encode())


class BodyView:
    """The body view of one session: which series the state asks for, its job, what the page is told.

    ``ship(payload)`` hands the series to the page (``{}``: none); ``on_change()`` says the status changed.
    """

    def __init__(self, session: ExplorerSession, ship: Callable[[dict[str, Any]], None],
                 on_change: Callable[[], None] | None = None) -> None:  # fmt: skip
        self.session = session
        self.state = session.state
        self.runner = session.runner
        self._ship = ship
        self._on_change = on_change
        #: The inputs of the series shown or being computed (None: none).
        self.inputs: BodyInputs | None = None
        self.series: BodySeries | None = None
        self.payload: dict[str, Any] = {}
        self.status = ""
        self.lost = False
        self.runner.declare({CHANNEL: LAYER})
        self.state.param.watch(lambda *e: self.refresh(), ["show_body", "selected", "clicked", *SECTION_FIELDS])
        session.param.watch(lambda *e: self.refresh(), ["status", "running"])

    # --- what the state asks for (document thread) ----------------------------------------------

    def wanted(self) -> tuple[BodyInputs | None, str]:
        """The series the state asks for, or None and why there is none."""
        st, s = self.state, self.session
        if not st.show_body:
            return None, ""
        if s.frame_periods is not None:
            return None, "the body's motion is computed when the played parameter pauses"
        try:
            params = st.system()
            # The section's escape bound (the body escapes where its points do); the page's Method and Accuracy
            # by the core's rule, at the body's own tolerance under "plot" (the orientation is no picture).
            numerics = st.numerics_for(None, bound=st.page_bound())[0]
        except ParameterError:
            return None, "no body: the system is not valid (see the message above)"
        if self.runner.busy(s.section.name) or s.section.params != params:
            return None, "the body's motion: computed once the section is done"
        traj, k, q, r = s.data()
        if st.selected < 0:
            return None, "no body: no trajectory is selected (type its number, or click with 'selects a trajectory')"
        sel = traj == st.selected
        if not sel.any():
            return None, f"no body: trajectory {st.selected} has no section points"
        order = np.argsort(k[sel], kind="stable")
        ks, qs, rs = k[sel][order], q[sel][order], r[sel][order]
        periods = max(1, min(PERIODS, ks.size - 1))
        i = max(0, ks.size - 1 - periods)
        inputs = BodyInputs(params, int(st.selected), int(ks[i]), float(qs[i]), float(rs[i]), periods, numerics)
        return inputs, ""

    def refresh(self) -> None:
        """Compare what the state asks for with what is shown or computing; drop and start as needed."""
        inputs, why = self.wanted()
        if inputs is not None and inputs == self.inputs:
            return  # shown, or on its way
        self.runner.cancel(CHANNEL)
        if self.inputs is not None or self.payload:
            self._drop()
        self.inputs = inputs
        if inputs is None:
            self._say(why)
            return
        self._start(inputs)

    def _drop(self) -> None:
        self.inputs = None
        self.series = None
        if self.payload:
            self.payload = {}
            self._ship({})

    def _say(self, text: str, lost: bool = False) -> None:
        if (text, lost) != (self.status, self.lost):
            self.status, self.lost = text, lost
            if self._on_change is not None:
                self._on_change()

    # --- the job ------------------------------------------------------------------------------------

    def _start(self, inputs: BodyInputs) -> None:
        last = inputs.k_start + inputs.periods
        self._say(f"computing the body's motion over k = {inputs.k_start}..{last} ({SAMPLES} frames a period)…")
        spec = self.spec(inputs)

        def job(cancelled: Callable[[], bool], emit: Emit) -> None:
            t = time.perf_counter()
            series = body_series(spec, cancel=cancelled)
            if cancelled():
                return
            payload = encode_series(series, inputs.k_start)
            elapsed = time.perf_counter() - t
            emit(lambda: self._apply(inputs, series, payload, elapsed))

        self.runner.start(CHANNEL, job)

    @staticmethod
    def spec(inputs: BodyInputs) -> BodySpec:
        """The series as the core's builder makes it (the command line's ``body --ic Q,R --periods N --samples
        S``, from the selected trajectory's section point, with the page's numerics)."""
        return body_spec(inputs.params, [(inputs.q, inputs.r)], inputs.periods, samples=SAMPLES,
                         numerics=inputs.numerics)  # fmt: skip

    def _apply(self, inputs: BodyInputs, series: BodySeries, payload: dict[str, Any], elapsed: float) -> None:
        if inputs != self.inputs:
            return  # the state moved on (its own job follows)
        self.series, self.payload = series, payload
        self._ship(payload)
        self._say(self.describe(series, inputs, payload, elapsed), lost=not series.complete)

    @staticmethod
    def describe(series: BodySeries, inputs: BodyInputs, payload: dict[str, Any], elapsed: float) -> str:
        """The line under the body: what it shows, how long it took, what it lost."""
        frames = payload["frames"]
        last = inputs.k_start + (frames - 1) / max(1, series.samples)
        text = (f"k = {inputs.k_start}..{last:g}: {frames} frames ({series.samples} a period), computed in "
                f"{1e3 * elapsed:.0f} ms, {payload_bytes(payload) / 1e3:.0f} kB sent once")  # fmt: skip
        if not series.box_exists:
            m = series.moments
            text += (f". No rigid body has the moments {m[0]:.4g}, {m[1]:.4g}, {m[2]:.4g} (every body has I3 ≤ I1 + "
                     "I2): shown as the inertia ellipsoid")  # fmt: skip
        if not series.complete:
            why = "; ".join(f"{loss.what}: {loss.why}" for loss in series.lost) or series.status.word
            text = f"the series ends early ({series.status.word}, at k = {last:g}): {why}. " + text
        return text

    def stop(self) -> None:
        """Stop pressed: the job in flight ends; a series shown stays (it is the state's)."""
        if self.runner.busy(CHANNEL):
            self.runner.cancel(CHANNEL)
            self.inputs = None
            self._say("stopped: the body's motion was not computed (toggle the view to compute it)")

    def failed(self, exc: BaseException) -> None:
        self.inputs = None
        self._say(f"the body's motion failed: {plain(exc)}", lost=True)

    def view(self) -> dict[str, Any]:
        """What the page shows besides the series: whether the view is open, its status line."""
        return {"open": bool(self.state.show_body), "status": self.status, "lost": self.lost}


__all__ = ["PERIODS", "SAMPLES", "TOLERANCE", "BodyInputs", "BodyView", "decode_series", "encode_series"]
