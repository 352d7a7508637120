"""The rigid body itself along a trajectory: its orientation, angular velocity and energy, frame by frame.

The section shows ``(q, r)`` at ``t0 + k T``; the body they describe turns with the body-frame angular
velocity ``omega = (p, q, r)``, ``p = alpha + g(t) q`` (the constraint). Its orientation ``R(t)`` (body ->
space) obeys ``R' = R [omega]_x``; the engine integrates it as a unit quaternion ``Q = (w, x, y, z)``,
``Q' = 1/2 Q (x) (0, omega)`` (the system ``rk.BODY``), beside ``(q, r)`` and in the same steps, recording
``samples`` frames in every period (the steps land on the frame times exactly, as on section times).

The quaternion is never re-normalised: ``|Q| - 1`` stays at the integration error and is reported
(:attr:`BodySeries.norm_drift`) as an accuracy figure; :meth:`BodySeries.rotation` is the rotation of
``Q / |Q|``. ``tests/test_body.py`` checks the series against ``solve_ivp`` on the full 3-D
Lagrange-d'Alembert equations with ``R' = R [omega]_x`` as a 3x3 matrix (``tests/naive.py``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step
from explorer_core.progress import run as run_updates
from explorer_core.solve.integrators import advance_body, body_start
from explorer_core.solve.numerics import Numerics, check_ics
from explorer_core.solve.options import Arg, declare, integer, optional_of
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.tableaus import get_method
from explorer_core.status import Status
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, check_time

#: Most periods of one series, frames per period (least, most) and frames in all.
MAX_BODY_PERIODS = 10_000
MIN_SAMPLES, MAX_SAMPLES = 4, 512
MAX_FRAMES = 200_000
#: Periods integrated between two polls of ``cancel``.
CHUNK_PERIODS = 64


@dataclass(frozen=True)
class BodySeries(Drawable):
    """The body along ``periods`` periods from the section point after ``k0`` periods, ``samples`` frames each.

    Frame ``f`` is at ``t[f] = t0 + (k0 + f // samples) T + T (f % samples) / samples``; frame ``f = j samples``
    is the section point ``k0 + j`` (:meth:`section_frames`). ``F = periods samples + 1`` frames when complete,
    fewer when the orbit escaped or the integration failed (``status``, ``lost``).

    ``omega`` (F, 3) body-frame ``(p, q, r)``; ``quaternion`` (F, 4) ``(w, x, y, z)`` body -> space, the identity
    at frame 0 (by definition of the series: the orientation is measured from the body's position at
    ``t0 + k0 T``); ``energy`` (F,) ``T = (I omega, omega) / 2``; ``moments`` (3,) the principal moments,
    ascending; ``axes`` (3, 3) the principal axes in the body frame as columns (right-handed).
    ``origin`` is the initial condition given (at ``t0``), ``ic`` the point at ``t0 + k0 T`` it leads to
    (NaN if the trajectory never got there: then ``lost`` says why).
    """

    params: Params
    ic: np.ndarray
    k0: int
    periods: int
    samples: int
    t: np.ndarray
    omega: np.ndarray
    quaternion: np.ndarray
    energy: np.ndarray
    moments: np.ndarray
    axes: np.ndarray
    status: Status
    complete: bool
    lost: list[Loss]
    elapsed_s: float
    numerics: Numerics = field(default_factory=Numerics)
    origin: np.ndarray = field(default_factory=lambda: np.full(2, math.nan))
    steps: int = 0

    @property
    def frames(self) -> int:
        return int(self.t.shape[0])

    def rotation(self) -> np.ndarray:
        """(F, 3, 3) the rotation matrices body -> space of ``Q / |Q|``: ``v_space = R v_body``."""
        q = self.quaternion / np.linalg.norm(self.quaternion, axis=1, keepdims=True)
        w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        out = np.empty((q.shape[0], 3, 3))
        out[:, 0, 0] = 1.0 - 2.0 * (y * y + z * z)
        out[:, 0, 1] = 2.0 * (x * y - w * z)
        out[:, 0, 2] = 2.0 * (x * z + w * y)
        out[:, 1, 0] = 2.0 * (x * y + w * z)
        out[:, 1, 1] = 1.0 - 2.0 * (x * x + z * z)
        out[:, 1, 2] = 2.0 * (y * z - w * x)
        out[:, 2, 0] = 2.0 * (x * z - w * y)
        out[:, 2, 1] = 2.0 * (y * z + w * x)
        out[:, 2, 2] = 1.0 - 2.0 * (x * x + y * y)
        return out

    def space_omega(self) -> np.ndarray:
        """(F, 3) the angular velocity in space, ``R omega``."""
        return np.einsum("fij,fj->fi", self.rotation(), self.omega)

    def axis_trace(self, i: int) -> np.ndarray:
        """(F, 3) principal axis ``i`` (0, 1, 2: smallest, middle, largest moment) in space, on the unit sphere."""
        if isinstance(i, bool) or not isinstance(i, int | np.integer) or not 0 <= i <= 2:
            raise ParameterError(f"principal axis must be 0, 1 or 2, got {i!r}")
        return self.rotation() @ self.axes[:, int(i)]

    def box_sides(self) -> np.ndarray:
        """(3,) sides along the principal axes of the uniform box with these principal moments, the largest 1.

        A box of sides ``a_i`` has ``I_i = m (a_j^2 + a_k^2) / 12``, so ``a_i^2`` is proportional to
        ``I_j + I_k - I_i``. A tensor that breaks the triangle inequality (``I_i > I_j + I_k``, e.g. the paper's
        diag(1, 2, 4)) belongs to no rigid body's box: that side is 0 (a flat box; :attr:`box_exists` is False,
        and :meth:`ellipsoid_axes` always exists).
        """
        sq = np.maximum(self.moments.sum() - 2.0 * self.moments, 0.0)
        sides = np.sqrt(sq)
        return sides / sides.max()

    @property
    def box_exists(self) -> bool:
        """True if a uniform box has these principal moments (:func:`box_exists`)."""
        return box_exists(self.moments)

    def ellipsoid_axes(self) -> np.ndarray:
        """(3,) semi-axes of the inertia ellipsoid ``(I omega, omega) = 1`` along the principal axes, the largest 1."""
        a = 1.0 / np.sqrt(self.moments)
        return a / a.max()

    def section_frames(self) -> np.ndarray:
        """Frame index of each period start (section point ``k0 + j`` at frame ``j samples``)."""
        return np.arange(0, self.frames, self.samples)

    @property
    def norm_drift(self) -> float:
        """``max |(|Q| - 1)|`` over the frames: the integration's error in the orientation (never re-normalised)."""
        if self.frames == 0:
            return 0.0
        return float(np.max(np.abs(np.linalg.norm(self.quaternion, axis=1) - 1.0)))

    def summary(self) -> dict[str, Any]:
        e = self.energy
        return {
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
            "origin": [float(v) for v in self.origin],
            "ic": [float(v) for v in self.ic],
            "k0": self.k0,
            "periods": self.periods,
            "samples": self.samples,
            "frames": self.frames,
            "t": [float(self.t[0]), float(self.t[-1])] if self.frames else [],
            "status": self.status.label,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "moments": self.moments.tolist(),
            "axes": self.axes.tolist(),
            "box_sides": self.box_sides().tolist(),
            "box_exists": self.box_exists,
            "quaternion_norm_drift": self.norm_drift,
            "energy": {"first": float(e[0]), "last": float(e[-1]), "min": float(e.min()), "max": float(e.max())}
            if self.frames
            else {},
            "steps": self.steps,
            "elapsed_s": round(self.elapsed_s, 6),
        }

    def columns(self) -> tuple[list[str], np.ndarray]:
        """The frames as a table: header and (F, 11) rows ``frame, k, t, p, q, r, w, x, y, z, T``."""
        f = np.arange(self.frames)
        k = self.k0 + f // self.samples
        table = np.column_stack([f, k, self.t, self.omega, self.quaternion, self.energy])
        return ["frame", "k", "t", "p", "q", "r", "w", "x", "y", "z", "T"], table

    def report(self) -> list[str]:
        """What the command line prints: frames, moments, the orientation at the end, the energy."""
        s = self.summary()
        if not self.frames:
            return [f"status {s['status']}: no frame recorded"]
        (w, x, y, z), e = self.quaternion[-1], s["energy"]
        return [f"{s['frames']} frames ({s['samples']} a period), t {s['t'][0]:.6g} .. {s['t'][1]:.6g}, "
                f"status {s['status']}",
                f"principal moments {', '.join(f'{m:.6g}' for m in s['moments'])}"
                + ("" if s["box_exists"] else " (no box has them: they break the triangle inequality)"),
                f"orientation at the end (w, x, y, z) = ({w:.10g}, {x:.10g}, {y:.10g}, {z:.10g}); "
                f"|Q| drift {s['quaternion_norm_drift']:.2g}",
                f"T from {e['first']:.10g} to {e['last']:.10g} (min {e['min']:.6g}, max {e['max']:.6g})"]  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: one row per frame (:meth:`columns`); ``.npz``: the arrays and ``summary`` (JSON text);
        ``.json``: the summary."""

        def csv(p: str) -> int:
            header, table = self.columns()
            rows = ([int(r[0]), int(r[1]), *r[2:].tolist()] for r in table)
            return export.write_csv(p, header, rows, export.partial(self))

        def npz(p: str) -> None:
            export.write_npz(p, t=self.t, omega=self.omega, quaternion=self.quaternion, energy=self.energy,
                             moments=self.moments, axes=self.axes, section_frames=self.section_frames(),
                             summary=export.dumps(self.summary()))  # fmt: skip

        writers = {".csv": csv, ".npz": npz, ".json": lambda p: export.write_json(p, self.summary())}
        return export.write_by_suffix(path, writers, "body series")


def box_exists(moments: np.ndarray) -> bool:
    """True if a uniform box has the principal moments ``moments`` (3,): every ``I_j + I_k - I_i > 0``."""
    moments = np.asarray(moments, dtype=float)
    return bool(np.all(moments.sum() - 2.0 * moments > 0.0))


def principal_axes(params: Params) -> tuple[np.ndarray, np.ndarray]:
    """``(moments (3,) ascending, axes (3, 3))``: the eigen-decomposition of the inertia tensor, each axis with its
    largest component positive and the third flipped if needed so the frame is right-handed."""
    moments, axes = np.linalg.eigh(params.inertia_matrix)
    for i in range(3):
        if axes[np.argmax(np.abs(axes[:, i])), i] < 0.0:
            axes[:, i] = -axes[:, i]
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


#: The series' numerics unless given.
BODY_NUMERICS = Numerics()
#: The single-value checks of a series' sizes (the builder's declarations, and :func:`iter_body_series`').
_PERIODS = integer(1, MAX_BODY_PERIODS)
_SAMPLES = integer(MIN_SAMPLES, MAX_SAMPLES)
_K0 = integer(0, config.MAX_PERIODS)


def _check(params: Params, ic: Any, periods: int, samples: int, k0: int, numerics: Numerics) -> np.ndarray:
    """Every check of a series' inputs: each size's (:data:`_PERIODS` ...), then :func:`_check_together`."""
    periods, samples, k0 = _PERIODS("periods", periods), _SAMPLES("samples", samples), _K0("k0", k0)
    return _check_together(params, ic, periods, samples, k0, numerics)


def _check_together(params: Params, ic: Any, periods: int, samples: int, k0: int, numerics: Numerics) -> np.ndarray:
    """The checks that need several of a series' inputs (the sizes checked each already): the one initial
    condition inside the escape bound, the frames, the method and its steps, the series' end time."""
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    x = check_ics(ic)
    if x.shape[0] != 1:
        raise ParameterError(f"the body follows one trajectory: give one (q, r), got {x.shape[0]}")
    if np.max(np.abs(x)) > numerics.bound:
        raise ParameterError(f"initial condition {x[0].tolist()} lies outside the escape bound {numerics.bound:g}")
    if periods * samples + 1 > MAX_FRAMES:
        raise ParameterError(f"{periods} periods x {samples} samples + 1 = {periods * samples + 1} frames exceeds the "
                             f"limit {MAX_FRAMES}")  # fmt: skip
    method = get_method(numerics.method)
    if method.kind == "taylor":
        raise ParameterError("method taylor integrates sections only: the body's orientation needs dop853, dp5 or rk4")
    fixed = not (numerics.adaptive and method.adaptive)
    if fixed and numerics.steps_per_period % samples:
        raise ParameterError(f"fixed steps land on the frames only if steps_per_period ({numerics.steps_per_period}) "
                             f"is a multiple of samples ({samples})")  # fmt: skip
    check_time("the series' end t", params.t0 + (k0 + periods) * params.period, params.period)
    return x[0]


@dataclass(frozen=True)
class BodySpec:
    """What defines a body series (validated by :func:`body_spec`; plain data)."""

    params: Params
    ic: tuple[float, float]
    periods: int
    samples: int
    k0: int
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "ic": list(self.ic), "periods": self.periods, "samples": self.samples,
                "k0": self.k0, "numerics": self.numerics.as_dict()}  # fmt: skip


@declare(
    ic=Arg(
        "initial condition at t0 (one: the body follows one trajectory)",
        "points",
        flag="--ic",
        scene="points",
        positional=True,
        cli_default=[(0.1, 0.1)],
        checked_with=("numerics",),
    ),
    periods=Arg("periods of the series", "int", positional=True, default=20, check=_PERIODS),
    samples=Arg("frames per period", "int", default=48, check=_SAMPLES),
    k0=Arg("start after this many periods (the orientation is the identity there)", "int", default=0, check=_K0),
    numerics=Arg("the integration", cli=False, default=BODY_NUMERICS, check=optional_of(Numerics, BODY_NUMERICS)),
)
def body_spec(params: Params, ic: Any, periods: int, *, samples: int, k0: int, numerics: Numerics) -> BodySpec:
    """A validated :class:`BodySpec` (the checks of :func:`body_series`, naming the bad value, ``exc.option``: its
    keyword for a single value's). The options are declared above: defaults, checks (run before this body), flags.
    """
    x = _check_together(params, ic, periods, samples, k0, numerics)
    return BodySpec(params, (float(x[0]), float(x[1])), periods, samples, k0, numerics)


def body_series(
    params: Params | BodySpec,
    ic: Any = None,
    periods: int = 20,
    *,
    samples: int = 48,
    k0: int = 0,
    numerics: Numerics | None = None,
    progress: Callable[[Step[BodySeries]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> BodySeries:
    """The body's orientation, angular velocity and energy along the trajectory from ``ic`` (at ``t0``).

    The field is integrated ``k0`` periods first (the Poincare map: the same section point ``section()``
    gives), then the body's system from there for ``periods`` periods, ``samples`` frames each; the
    orientation at ``t0 + k0 T`` is the identity by definition of the series. An escape or a failed step
    ends the series early (``status``, ``complete=False``, a :class:`Loss`); ``cancel`` is polled every
    :data:`CHUNK_PERIODS` periods (a cancelled series keeps the frames computed). ``progress`` gets every
    update of :func:`iter_body_series`.

    Raises ParameterError (naming the value) for periods outside 1..10_000, samples outside 4..512, more than
    200_000 frames, an initial condition not finite or outside the escape bound, or the method taylor.
    """
    if isinstance(params, BodySpec):
        if ic is not None:
            raise TypeError(f"a BodySpec comes alone, not with {ic!r}")
        spec = params
        params, ic, periods, samples, k0, numerics = spec.params, spec.ic, spec.periods, spec.samples, spec.k0, \
            spec.numerics  # fmt: skip
    updates = iter_body_series(params, ic, periods, samples=samples, k0=k0, numerics=numerics, cancel=cancel)
    return run_updates(updates, progress)


def iter_body_series(
    params: Params,
    ic: Any,
    periods: int,
    *,
    samples: int = 48,
    k0: int = 0,
    numerics: Numerics | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Iterator[Step[BodySeries]]:
    """:func:`body_series` as updates (the contract of :mod:`explorer_core.progress`): one after the ``k0``
    periods before the start and one per :data:`CHUNK_PERIODS` periods, in periods of ``k0 + periods``; the
    last carries the series. The inputs are checked at once (a ParameterError before the first update)."""
    numerics = numerics or BODY_NUMERICS
    x0 = _check(params, ic, periods, samples, k0, numerics)
    return _iter_body_series(params, x0, int(periods), int(samples), int(k0), numerics, cancel)


def _iter_body_series(
    params: Params, x0: np.ndarray, periods: int, samples: int, k0: int, numerics: Numerics, cancel: Any
) -> Iterator[Step[BodySeries]]:
    start = time.perf_counter()
    moments, axes = principal_axes(params)
    total = periods * samples + 1
    lost: list[Loss] = []

    def where(done_periods: int) -> Progress:
        return Progress(done_periods, k0 + periods, "periods", time.perf_counter() - start)

    def empty(status: Status, why: str) -> Step[BodySeries]:
        lost.append(Loss("frames", total, why))
        z = np.empty((0, 3))
        series = BodySeries(params, np.full(2, math.nan), k0, periods, samples, np.empty(0), z, np.empty((0, 4)),
                            np.empty(0), moments, axes, status, False, lost, time.perf_counter() - start, numerics,
                            x0.copy())  # fmt: skip
        return Step(where(0 if status == Status.CANCELLED else k0 + periods), result=series)

    x = x0.copy()
    if k0 > 0:
        pmap = PoincareMap.of(params, numerics, workers=1)
        chunks = list(pmap.iterate(x0[None], 1, transient=k0 - 1, cancel=cancel))  # one chunk: the point k0
        chunk = chunks[-1] if chunks else None
        if chunk is None:
            yield empty(Status.CANCELLED, f"cancelled before the start (period {k0})")
            return
        if chunk.npts[0] < 1:
            word = Status.of(int(chunk.status[0])).word
            yield empty(Status.of(int(chunk.status[0])), f"the trajectory ended ({word}) before period {k0}")
            return
        x = chunk.points[0, 0].copy()
        yield Step(where(k0))

    out = np.empty((total, 6))
    out[0, :2] = x
    out[0, 2:] = (1.0, 0.0, 0.0, 0.0)
    batch = body_start(params, x, k0)
    done = 1  # frames filled
    status = Status.OK
    for first in range(0, periods, CHUNK_PERIODS):
        if cancel is not None and cancel():
            status = Status.CANCELLED
            break
        n = min(CHUNK_PERIODS, periods - first)
        frames, nframes = advance_body(params, batch, n, samples, numerics)
        m = int(nframes[0])
        out[done : done + m] = frames[0, :m]
        done += m
        if batch.status[0] != Status.OK:
            status = Status.of(int(batch.status[0]))
            break
        if first + n < periods:
            yield Step(where(k0 + first + n))
    f = np.arange(done)
    s = f % samples
    t = params.t0 + (k0 + f // samples) * params.period + params.period * (s / samples)
    if done < total:
        if status == Status.CANCELLED:
            lost.append(Loss("frames", total - done, "cancelled"))
        else:
            why = f"the trajectory ended ({status.word}) after the frame at t = {t[-1]:.6g}"
            lost.append(Loss("frames", total - done, why))
    # omega and T from the model, at each frame's phase as the engine took it (t0 + T j / samples: g is periodic).
    model = Model(params)
    q, r = out[:done, 0], out[:done, 1]
    omega, energy = np.empty((done, 3)), np.empty(done)
    for j in range(min(samples, done)):
        at, tj = s == j, params.t0 + params.period * (j / samples)
        omega[at] = model.omega_vector(q[at], r[at], tj)
        energy[at] = model.energy(q[at], r[at], tj)
    series = BodySeries(params, x, k0, periods, samples, t, omega, out[:done, 2:].copy(), energy, moments, axes,
                        status, done == total, lost, time.perf_counter() - start, numerics, x0.copy(),
                        int(batch.nsteps[0]))  # fmt: skip
    # A run that ended early (escape, failure) has nothing left to compute: its last update is at the end.
    yield Step(where(k0 + periods if status != Status.CANCELLED else k0 + (done - 1) // samples), result=series)
