"""Fast chaos indicators of the Poincare map: weighted Birkhoff averages and the alignment indices SALI, GALI_2.

Both answer "is this orbit regular or chaotic?" in far fewer periods than a converged Lyapunov exponent
(:mod:`explorer_core.analyses.lyapunov`), and both are written twice over: a **core** that works on any
planar map given as ``advance(x, idx) -> (P(x), DP(x), status)`` or on the orbit's points (so the tests run
it on maps with known answers: an irrational rotation, Chirikov's standard map, the logistic map), and an
**analysis** of this system (spec, ``iter_X``, ``X``, result, losses, files) that feeds the core with the
engine's section points and tangent map (:class:`~explorer_core.solve.poincare.PoincareMap`).

Weighted Birkhoff averages (Das, Saiki, Sander, Yorke, *Nonlinearity* 30, 2017)
    ``WB_N(f)(x) = sum_{n<N} w(n/N) f(P^n x) / sum_{n<N} w(n/N)`` with the bump ``w(t) = exp(-1/(t(1-t)))``.
    On a quasi-periodic orbit (an invariant curve, a cycle) it converges faster than any power of ``N``; on
    a chaotic one like ``N^-1/2``. The *digits of convergence* compare two consecutive runs of ``N`` periods:
    ``dig = -log10 |WB_N(f)(x) - WB_N(f)(P^N x)|`` (the paper's two-half test), capped at
    :data:`MAX_DIGITS`. ``dig >= regular_digits``: regular; ``dig < chaotic_digits``: chaotic; in between,
    undecided (and undecided with fewer than ``min_chaotic_periods`` a half unless regular: a regular orbit's
    average may not have converged to 3 digits by then). An orbit that drifts off (its distance from the origin
    growing steadily, :func:`~explorer_core.analyses.reliability.escaping`) has no invariant measure to average:
    undecided, and ``drifting`` says why (its averages disagree to negative digits, which is no chaos). The
    rotation number of a regular orbit is the weighted average of the angle increments about the orbit's centre
    (its own weighted average), over ``2 pi``, mod 1.

SALI and GALI_2 (Skokos 2001; Skokos, Bountis, Antonopoulos 2007)
    Two deviation vectors are carried by ``DP`` along the orbit and normalised each period;
    ``SALI = min(|u1 + u2|, |u1 - u2|)``, ``GALI_2 = |u1 ^ u2|`` (the area they span). Both fall
    exponentially (at the rate ``lambda_1 - lambda_2``) on a chaotic orbit and like a power law (``n^-2`` for
    an area-preserving planar map) on an invariant curve. A map that contracts area also aligns the vectors on
    an attracting cycle, by contraction rather than stretching: the vectors' growth (the finite-time exponent
    carried along, ``stretch``) tells the two apart. An orbit is *chaotic* once ``SALI < sali_tol`` with a
    mean stretch above ``stretch_tol`` per period, from period ``min_periods`` on (it stops there: no more periods
    are spent on it), *regular* when it aligned with no stretching, or when after all periods ``SALI`` decays no
    faster than ``n^-max_power`` over the second half of the run (of at least ``min_regular`` periods), and
    *undecided* otherwise.

Statuses, never NaN: an orbit whose integration escaped or failed keeps its engine status and the verdict
``undecided``; a run cancelled keeps what was computed (``completed`` False, a :class:`~explorer_core.losses.Loss`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.lyapunov import LYAPUNOV_NUMERICS
from explorer_core.analyses.reliability import escaping
from explorer_core.analyses.sections import TRANSIENT_ARG
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, stoppable
from explorer_core.progress import run as run_updates
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.options import Arg, choice, declare, ics, integer, number, optional_of
from explorer_core.solve.poincare import PoincareMap
from explorer_core.status import Status, count_names
from explorer_core.system.params import ParameterError, Params

#: Digits of agreement reported for two averages that agree to the last bit (no NaN, no infinity).
MAX_DIGITS = 16.0
#: The verdicts, by code: an indicator's class of an orbit (a classification, as the chart's regimes: why an orbit
#: has none is its status).
VERDICTS = ("undecided", "regular", "chaotic")
NO_VERDICT = 0
REGULAR = 1
CHAOTIC = 2
#: Observables of the Birkhoff analysis: smooth functions of the section point.
OBSERVABLES = ("q", "r", "cos_q", "sin_r")
#: Default thresholds (declared as options below): digits of a regular and of a chaotic orbit.
REGULAR_DIGITS = 7.0
CHAOTIC_DIGITS = 3.0
#: Fewest periods per half for a "chaotic" verdict: with fewer, a regular orbit's average may not have converged
#: to 3 digits yet (the standard map's invariant curves reach 3.5 digits at 100).
MIN_CHAOTIC_PERIODS = 100
#: SALI below which the deviation vectors count as aligned, the stretching that makes an alignment chaos
#: (mean log growth of the vectors per period), and the fastest power law of a regular orbit's decay.
SALI_TOL = 1e-8
STRETCH_TOL = 0.02
MAX_POWER = 3.0
#: Fewest periods before an alignment is a verdict: one period from far out may align the vectors already (an
#: orbit on its way out of the bound is not chaos).
MIN_ALIGN_PERIODS = 10
#: Fewest periods for a "regular" verdict without alignment: by then a chaotic orbit whose vectors align at the rate
#: ln(1/SALI_TOL) / 100 ~ 0.18 per period or faster has aligned (a shorter run is undecided).
MIN_REGULAR_PERIODS = 100
_OK = int(Status.OK)
_UNDECIDED_STATUS = int(Status.UNDECIDED)


# ---------------------------------------------------------------------------
# The core: any planar map.


def birkhoff_weights(n: int) -> np.ndarray:
    """The normalised weights ``w(k/n) / sum w``, ``k = 0 .. n-1``, of ``w(t) = exp(-1/(t(1-t)))`` (``w(0) = 0``)."""
    if n < 3:
        raise ParameterError(f"a weighted Birkhoff average needs at least 3 values, got {n}")
    t = np.arange(1, n) / n
    w = np.zeros(n)
    w[1:] = np.exp(-1.0 / (t * (1.0 - t)))
    return w / w.sum()


def weighted_birkhoff(values: Any) -> np.ndarray:
    """``WB_N`` of ``values`` (..., N) (the observable along the orbit, first axis last): shape (...)."""
    v = np.asarray(values, dtype=float)
    return v @ birkhoff_weights(v.shape[-1])


def birkhoff_digits(values: Any) -> np.ndarray:
    """Digits of convergence of ``values`` (..., 2N): ``-log10 |WB_N(first N) - WB_N(last N)|``, at most
    :data:`MAX_DIGITS` (the paper's two-half test)."""
    v = np.asarray(values, dtype=float)
    n = v.shape[-1] // 2
    diff = np.abs(weighted_birkhoff(v[..., :n]) - weighted_birkhoff(v[..., n : 2 * n]))
    with np.errstate(divide="ignore"):
        dig = -np.log10(diff)
    return np.minimum(dig, MAX_DIGITS)


def wrapped_increments(points: Any, centre: Any) -> np.ndarray:
    """Angle increments ``(..., n-1)`` of ``points`` (..., n, 2) about ``centre`` (..., 2), in ``(-pi, pi]``."""
    p = np.asarray(points, dtype=float)
    c = np.asarray(centre, dtype=float)[..., None, :]
    theta = np.arctan2(p[..., 1] - c[..., 1], p[..., 0] - c[..., 0])
    d = np.diff(theta, axis=-1)
    return d - 2.0 * math.pi * np.ceil((d - math.pi) / (2.0 * math.pi))


def rotation_number(points: Any, centre: Any = None) -> np.ndarray:
    """Rotation number in ``[0, 1)`` of orbits ``(..., n, 2)`` about ``centre`` (default: each orbit's weighted
    average, the centre of its invariant measure): the weighted Birkhoff average of the angle increments over
    ``2 pi``. Meaningful on an invariant curve that winds once about the centre."""
    p = np.asarray(points, dtype=float)
    c = weighted_birkhoff(np.moveaxis(p, -1, -2)) if centre is None else np.asarray(centre, dtype=float)
    rho = weighted_birkhoff(wrapped_increments(p, c)) / (2.0 * math.pi)
    return np.mod(rho, 1.0)


def digits_verdict(
    digits: Any, regular: float, chaotic: float, periods: int, min_chaotic: int = MIN_CHAOTIC_PERIODS
) -> np.ndarray:
    """:data:`REGULAR` where ``digits >= regular``, :data:`CHAOTIC` where ``digits < chaotic`` after at least
    ``min_chaotic`` periods a half (``periods``: the half's length), else undecided (too short to say chaos)."""
    d = np.asarray(digits, dtype=float)
    slow = (d < chaotic) & (periods >= min_chaotic)
    return np.where(d >= regular, REGULAR, np.where(slow, CHAOTIC, NO_VERDICT)).astype(np.int64)


#: A planar map for the alignment indices: ``advance(x (m, 2), idx (m,)) -> (P(x) (m, 2), DP(x) (m, 2, 2),
#: status (m,))`` for members ``idx`` (status 0: ok; anything else ends the member).
Advance = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def closed_map(step: Callable[[np.ndarray], np.ndarray], jacobian: Callable[[np.ndarray], np.ndarray]) -> Advance:
    """An :data:`Advance` of a map in closed form: ``step(x)`` (m, 2) and ``jacobian(x)`` (m, 2, 2), vectorised."""

    def advance(x: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        y, jac = step(x), jacobian(x)
        bad = ~(np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(jac), axis=(1, 2)))
        return y, jac, np.where(bad, int(Status.NONFINITE), _OK)

    return advance


def align_step(u1: np.ndarray, u2: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, ...]:
    """One period of the deviation vectors: ``u -> DP u / |DP u|`` for both (rows of (m, 2)).

    Returns the new ``u1, u2``, ``SALI = min(|u1 + u2|, |u1 - u2|)``, ``GALI_2 = |u1 ^ u2|`` (of the new
    vectors) and the log growth of each, ``log |DP u1|`` and ``log |DP u2|`` (m,)."""
    w1 = np.einsum("mij,mj->mi", jac, u1)
    w2 = np.einsum("mij,mj->mi", jac, u2)
    n1 = np.linalg.norm(w1, axis=1)
    n2 = np.linalg.norm(w2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        v1, v2 = w1 / n1[:, None], w2 / n2[:, None]
        g1, g2 = np.log(n1), np.log(n2)
    sali = np.minimum(np.linalg.norm(v1 + v2, axis=1), np.linalg.norm(v1 - v2, axis=1))
    gali = np.abs(v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0])
    return v1, v2, sali, gali, g1, g2


@dataclass(frozen=True)
class Alignment:
    """SALI and GALI_2 along ``m`` orbits (see :func:`iter_alignment`).

    ``sali``, ``gali`` (m, periods): after each period (0 beyond ``npts``); ``stretch`` (m, periods): the log
    growth of ``u1`` each period (its running mean is a finite-time Lyapunov exponent per period); ``npts`` (m,):
    periods done (fewer when decided early or failed); ``status`` (m,) :class:`Status`; ``verdict`` (m,)
    :data:`VERDICTS` codes; ``points`` (m, 2): where each orbit stopped."""

    sali: np.ndarray
    gali: np.ndarray
    stretch: np.ndarray
    npts: np.ndarray
    status: np.ndarray
    verdict: np.ndarray
    points: np.ndarray
    completed: bool = True


def alignment_verdict(
    sali: np.ndarray,
    stretch: np.ndarray,
    n: int,
    *,
    sali_tol: float,
    stretch_tol: float,
    max_power: float,
    min_periods: int = MIN_ALIGN_PERIODS,
    min_regular: int = MIN_REGULAR_PERIODS,
) -> int:
    """The verdict on one orbit from its first ``n`` periods of SALI and stretch (see the module docstring); an
    alignment counts from period ``min_periods`` on, a decay no faster than a power law after ``min_regular``."""
    if n == 0:
        return NO_VERDICT
    s = sali[:n]
    below = np.flatnonzero(s < sali_tol)
    below = below[below + 1 >= min_periods]
    if below.size:
        k = int(below[0]) + 1
        return CHAOTIC if float(np.mean(stretch[:k])) > stretch_tol else REGULAR
    if n < max(8, min_regular):
        return NO_VERDICT
    # Power-law exponent of the decay: the envelope (largest log SALI) of the last quarter against that of the quarter
    # ending half way (a factor 2 apart). SALI oscillates along an invariant curve and dips near its folds; the
    # envelope of an oscillating power law is that power law, where a window's mean follows the dips.
    logs = np.log(np.maximum(s, 1e-300))
    late, early = logs[(3 * n) // 4 :].max(), logs[(3 * n) // 8 : n // 2].max()
    power = (early - late) / math.log(2.0)
    return REGULAR if power <= max_power else NO_VERDICT


def iter_alignment(
    advance: Advance,
    x0: Any,
    periods: int,
    *,
    sali_tol: float = SALI_TOL,
    stretch_tol: float = STRETCH_TOL,
    max_power: float = MAX_POWER,
    min_periods: int = MIN_ALIGN_PERIODS,
    min_regular: int = MIN_REGULAR_PERIODS,
    u1: Any = (1.0, 0.0),
    u2: Any = (0.0, 1.0),
    chunk: int = 16,
    cancel: Callable[[], bool] | None = None,
) -> Iterator[Step[Alignment]]:
    """SALI and GALI_2 along the orbits of ``x0`` (m, 2) under ``advance``, for at most ``periods`` periods;
    an orbit stops once it is decided chaotic. Yields a :class:`~explorer_core.progress.Step` every ``chunk``
    periods (the live :class:`Alignment` as its result; the last one final)."""
    x = np.array(x0, dtype=float).reshape(-1, 2)
    m = x.shape[0]
    v1 = np.tile(np.asarray(u1, dtype=float) / np.linalg.norm(u1), (m, 1))
    v2 = np.tile(np.asarray(u2, dtype=float) / np.linalg.norm(u2), (m, 1))
    sali, gali, stretch = np.zeros((m, periods)), np.zeros((m, periods)), np.zeros((m, periods))
    npts = np.zeros(m, dtype=np.int64)
    status = np.where(np.all(np.isfinite(x), axis=1), _OK, int(Status.NONFINITE)).astype(np.int64)
    verdict = np.zeros(m, dtype=np.int64)
    live = status == _OK
    start = time.perf_counter()
    completed = True
    kw = {
        "sali_tol": sali_tol,
        "stretch_tol": stretch_tol,
        "max_power": max_power,
        "min_periods": min_periods,
        "min_regular": min_regular,
    }

    def snapshot(done: bool) -> Alignment:
        return Alignment(sali, gali, stretch, npts.copy(), status.copy(), verdict.copy(), x.copy(), done)

    for k in range(periods):
        if k % chunk == 0 and k:
            yield Step(Progress(k, periods, "periods", time.perf_counter() - start), result=snapshot(False))
            if cancel is not None and cancel():
                completed = False
                break
        idx = np.flatnonzero(live)
        if idx.size == 0:
            break
        y, jac, st = advance(x[idx], idx)
        bad = st != _OK
        status[idx[bad]] = st[bad]
        live[idx[bad]] = False
        good = idx[~bad]
        nv1, nv2, s, g, l1, l2 = align_step(v1[good], v2[good], jac[~bad])
        finite = np.isfinite(s) & np.isfinite(l1) & np.isfinite(l2)  # DP u = 0: the vectors are lost
        status[good[~finite]] = int(Status.NONFINITE)
        live[good[~finite]] = False
        good, sel = good[finite], np.flatnonzero(finite)
        x[good], v1[good], v2[good] = y[~bad][sel], nv1[sel], nv2[sel]
        sali[good, k], gali[good, k], stretch[good, k] = s[sel], g[sel], l1[sel]
        npts[good] += 1
        for i in good[
            (s[sel] < sali_tol) & (npts[good] >= min_periods)
        ]:  # decided (chaotic, or aligned by contraction): no more periods for it
            verdict[i] = alignment_verdict(sali[i], stretch[i], int(npts[i]), **kw)
            live[i] = False
    for i in np.flatnonzero(live & (npts == periods)):  # ran every period without aligning
        verdict[i] = alignment_verdict(sali[i], stretch[i], periods, **kw)
    done = periods if completed else int(k)
    yield Step(Progress(done, periods, "periods", time.perf_counter() - start), result=snapshot(completed))


def alignment(advance: Advance, x0: Any, periods: int, **kw: Any) -> Alignment:
    """The final :class:`Alignment` of :func:`iter_alignment` (same arguments)."""
    return run_updates(iter_alignment(advance, x0, periods, **kw))


# ---------------------------------------------------------------------------
# The analyses of this system: the map integrated by the engine.


def _verdict_status(verdict: np.ndarray, status: np.ndarray) -> np.ndarray:
    """Per orbit: the engine's failure, else ``undecided`` where no verdict was reached, else ok."""
    return np.where(status != _OK, status, np.where(verdict == NO_VERDICT, _UNDECIDED_STATUS, _OK))


def _verdict_losses(status: np.ndarray, what: str) -> list[Loss]:
    """Orbits without a verdict for a reason other than "undecided": failed, escaped, cancelled (their statuses)."""
    lost = []
    for code in np.unique(status[(status != _OK) & (status != _UNDECIDED_STATUS)]):
        s = Status(int(code))
        why = f"{s.label}: {s.meaning}; no verdict" if s != Status.CANCELLED else "cancelled before a verdict"
        lost.append(Loss(what, int(np.count_nonzero(status == code)), why))
    return lost


def _observable(points: np.ndarray, name: str) -> np.ndarray:
    q, r = points[..., 0], points[..., 1]
    return {"q": q, "r": r, "cos_q": np.cos(q), "sin_r": np.sin(r)}[name]


def spec_dict(spec: Any) -> dict[str, Any]:
    """A plain-data spec as JSON: its fields in order, those with ``as_dict`` (the system, the numerics) as theirs,
    tuples as lists."""
    out: dict[str, Any] = {}
    for f in fields(spec):
        v = getattr(spec, f.name)
        out[f.name] = v.as_dict() if hasattr(v, "as_dict") else [list(x) if isinstance(x, tuple) else x for x in v] \
            if isinstance(v, tuple) else v  # fmt: skip
    return out


@dataclass(frozen=True)
class BirkhoffSpec:
    """Weighted Birkhoff averages along the orbits of ``ics``: ``2 periods`` section points each after
    ``transient``, the digits of ``observable`` over the two halves, the verdict by the two thresholds (chaos only
    with at least ``min_chaotic_periods`` a half)."""

    params: Params
    ics: tuple[tuple[float, float], ...]
    periods: int
    transient: int
    observable: str
    regular_digits: float
    chaotic_digits: float
    min_chaotic_periods: int
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return spec_dict(self)


#: Options the Birkhoff and SALI analyses share (declared once here).
ICS_ARG = Arg("initial condition (repeatable)", "points", flag="--ic", scene="points", positional=True, check=ics())
NUMERICS_ARG = Arg(
    "method and tolerances (default: the Lyapunov exponent's)",
    cli=False,
    default=LYAPUNOV_NUMERICS,
    check=optional_of(Numerics, LYAPUNOV_NUMERICS),
)
_DIGITS = number(0.0, MAX_DIGITS)


@declare(
    ics=ICS_ARG,
    periods=Arg("periods in each half (2x this many are run)", "int", positional=True, cli_default=500,
                check=integer(8, config.MAX_PERIODS // 2)),
    transient=TRANSIENT_ARG,
    observable=Arg("the smooth observable averaged", "str", choices=OBSERVABLES, default="q",
                   check=choice(OBSERVABLES)),
    regular_digits=Arg("digits of convergence at or above which an orbit is regular", default=REGULAR_DIGITS,
                       check=_DIGITS),
    chaotic_digits=Arg("digits below which an orbit is chaotic", default=CHAOTIC_DIGITS, check=_DIGITS),
    min_chaotic_periods=Arg("fewest periods a half for a chaotic verdict (fewer: undecided)", "int",
                            default=MIN_CHAOTIC_PERIODS, check=integer(1, config.MAX_PERIODS)),
    numerics=NUMERICS_ARG,
)  # fmt: skip
def birkhoff_spec(
    params: Params,
    ics: np.ndarray,
    periods: int,
    *,
    transient: int,
    observable: str,
    regular_digits: float,
    chaotic_digits: float,
    min_chaotic_periods: int,
    numerics: Numerics,
) -> BirkhoffSpec:
    """A validated :class:`BirkhoffSpec` (a bad value raises ParameterError naming it; ``exc.option`` its keyword).
    The options are declared above; the body checks the two thresholds together and the run's size."""
    with Checking() as at:
        at("chaotic_digits")
        if chaotic_digits > regular_digits:
            raise ParameterError(f"chaotic_digits ({chaotic_digits:g}) must not exceed regular_digits "
                                 f"({regular_digits:g})")  # fmt: skip
        at("periods")
        if ics.shape[0] * 2 * periods > config.MAX_POINTS:
            raise ParameterError(f"{ics.shape[0]} orbits x {2 * periods} periods exceeds the limit {config.MAX_POINTS}")
    ics_ = tuple((float(q), float(r)) for q, r in ics)
    return BirkhoffSpec(params, ics_, periods, transient, observable, float(regular_digits), float(chaotic_digits),
                        min_chaotic_periods, numerics)  # fmt: skip


class _Verdicts(Drawable):
    """What the Birkhoff and SALI results share: their losses (orbits without a verdict for a failure, a cancel),
    completeness, and the summary's tail."""

    status: np.ndarray
    verdict: np.ndarray
    completed: bool
    elapsed_s: float
    spec: Any

    @property
    def lost(self) -> list[Loss]:
        return _verdict_losses(self.status, "orbits")

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def verdicts(self) -> list[str]:
        return [VERDICTS[int(v)] for v in self.verdict]

    def _summary(self, orbits: list[dict[str, Any]]) -> dict[str, Any]:
        return {"orbits": orbits, "verdicts": {v: self.verdicts().count(v) for v in VERDICTS},
                "statuses": count_names(self.status), "elapsed_s": round(self.elapsed_s, 6),
                "completed": self.completed, "complete": self.complete,
                "lost": [loss.as_dict() for loss in self.lost], "spec": self.spec.as_dict()}  # fmt: skip


@dataclass(frozen=True)
class Birkhoff(_Verdicts):
    """Weighted Birkhoff averages of a :class:`BirkhoffSpec`'s orbits.

    ``average`` (m,): ``WB_N`` of the observable over the first half; ``digits`` (m,) of convergence (0 where
    the orbit failed); ``verdict`` (m,) :data:`VERDICTS` codes; ``rotation`` (m,) the rotation number of a
    regular orbit about its centre ``centre`` (m, 2) (0 where ``has_rotation`` is False: not regular);
    ``status`` (m,): ok, undecided (no verdict) or the engine's failure; ``npts`` (m,) periods integrated;
    ``drifting`` (m,): the orbit drifted off (undecided: no invariant measure to average)."""

    spec: BirkhoffSpec
    average: np.ndarray
    digits: np.ndarray
    verdict: np.ndarray
    rotation: np.ndarray
    has_rotation: np.ndarray
    centre: np.ndarray
    status: np.ndarray
    npts: np.ndarray
    drifting: np.ndarray
    elapsed_s: float
    completed: bool = True

    def rows(self) -> Iterator[tuple]:
        for i, (q, r) in enumerate(self.spec.ics):
            rot = float(self.rotation[i]) if self.has_rotation[i] else ""
            yield (i, q, r, VERDICTS[int(self.verdict[i])], float(self.digits[i]), float(self.average[i]), rot,
                   Status(int(self.status[i])).label, int(self.npts[i]), bool(self.drifting[i]))  # fmt: skip

    def summary(self) -> dict[str, Any]:
        keys = ("ic", "verdict", "digits", "average", "rotation", "status", "periods", "drifting")
        return self._summary([dict(zip(keys, ([q, r], v, d, a, None if rot == "" else rot, s, n, dr), strict=True))
                              for _, q, r, v, d, a, rot, s, n, dr in self.rows()])  # fmt: skip

    def report(self) -> list[str]:
        return [f"({q:.6g}, {r:.6g}): {v}, {d:.2f} digits" + (f", rotation number {rot:.12f}" if rot != "" else "")
                + (" (drifting off: no invariant measure to average)" if dr else "")
                + ("" if s == "ok" else f" ({s})") for _, q, r, v, d, _, rot, s, _, dr in self.rows()]  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: one row per orbit; ``.json``: the summary."""
        header = ("orbit", "q0", "r0", "verdict", "digits", "average", "rotation", "status", "periods", "drifting")
        csv_ = lambda p: export.write_csv(p, header, self.rows(), export.partial(self))  # noqa: E731
        return export.write_by_suffix(path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())},
                                      "Birkhoff result")  # fmt: skip


def iter_birkhoff(
    spec: BirkhoffSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[Birkhoff]]:
    """Stream the section points of the spec's orbits (the engine, both cores) in chunks; the last update's result is
    the :class:`Birkhoff` result. ``iter_birkhoff(spec)`` or the builder's keyword form."""
    spec = spec_of(BirkhoffSpec, birkhoff_spec, spec, args, kw)
    start = time.perf_counter()
    x0 = np.array(spec.ics, dtype=float)
    m, total = x0.shape[0], 2 * spec.periods
    points = np.zeros((m, total, 2))
    npts = np.zeros(m, dtype=np.int64)
    status = np.zeros(m, dtype=np.int64)
    pmap = PoincareMap.of(spec.params, spec.numerics, workers=workers)
    done = 0
    for chunk in pmap.iterate(x0, total, transient=spec.transient, cancel=cancel):
        for i in range(m):
            n = int(chunk.npts[i])
            points[i, npts[i] : npts[i] + n] = chunk.points[i, :n]
        npts += chunk.npts
        status = chunk.status.copy()
        done = chunk.done_periods
        yield Step(Progress(done, total, "periods", time.perf_counter() - start))
    # Stopped early only by a cancel: the section ends early by itself only when no trajectory is left.
    completed = not np.any((status == _OK) & (npts < total))
    ran = (npts == total) & (status == _OK)
    f = _observable(points, spec.observable)
    digits = np.where(ran, birkhoff_digits(f), 0.0)
    average = np.where(ran, weighted_birkhoff(f[:, : spec.periods]), 0.0)
    # a drift's averages follow it off and disagree to negative digits: no chaos, no verdict
    drifting = np.array([bool(ran[i]) and escaping(np.hypot(points[i, :, 0], points[i, :, 1])) for i in range(m)])
    verdict = np.where(ran & ~drifting, digits_verdict(digits, spec.regular_digits, spec.chaotic_digits, spec.periods,
                                                       spec.min_chaotic_periods), NO_VERDICT)  # fmt: skip
    centre = np.where(ran[:, None], weighted_birkhoff(np.moveaxis(points, -1, -2)), 0.0)
    has_rotation = verdict == REGULAR
    with np.errstate(invalid="ignore"):  # failed orbits' zeros: masked out below
        rotation = np.where(has_rotation, rotation_number(points, centre), 0.0)
    if not completed:
        status = np.where((status == _OK) & (npts < total), int(Status.CANCELLED), status)
    result = Birkhoff(spec, average, digits, verdict, rotation, has_rotation, centre,
                      _verdict_status(verdict, status), npts, drifting, time.perf_counter() - start,
                      completed)  # fmt: skip
    yield Step(Progress(total if completed else done, total, "periods", result.elapsed_s), result=result)


def birkhoff(
    spec: BirkhoffSpec | Params,
    *args: Any,
    progress: Callable[[Any], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Birkhoff:
    """Weighted Birkhoff averages, digits, verdicts and rotation numbers of :func:`iter_birkhoff`'s last update."""
    return run_updates(iter_birkhoff(spec, *args, cancel=cancel, workers=workers, **kw), progress)


@dataclass(frozen=True)
class SaliSpec:
    """SALI and GALI_2 along the orbits of ``ics`` after ``transient``: at most ``periods`` periods of the
    tangent map, verdicts by ``sali_tol``, ``stretch_tol`` and ``max_power`` (the module docstring)."""

    params: Params
    ics: tuple[tuple[float, float], ...]
    periods: int
    transient: int
    sali_tol: float
    stretch_tol: float
    max_power: float
    min_periods: int
    min_regular: int
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return spec_dict(self)


@declare(
    ics=ICS_ARG,
    periods=Arg("most periods of the tangent map (a chaotic orbit stops when decided)", "int", positional=True,
                cli_default=1000, check=integer(8, config.MAX_PERIODS)),
    transient=TRANSIENT_ARG,
    sali_tol=Arg("SALI below which the deviation vectors are aligned", default=SALI_TOL, check=number(1e-300, 1.0)),
    stretch_tol=Arg("mean log growth per period above which an alignment is chaos", default=STRETCH_TOL,
                    check=number(0.0, 100.0)),
    max_power=Arg("fastest power-law decay of SALI on a regular orbit", default=MAX_POWER, check=number(0.0, 100.0)),
    min_periods=Arg("fewest periods before an alignment is a verdict", "int", default=MIN_ALIGN_PERIODS,
                    check=integer(1, config.MAX_PERIODS)),
    min_regular=Arg("fewest periods for a regular verdict without alignment (fewer: undecided)", "int",
                    default=MIN_REGULAR_PERIODS, check=integer(1, config.MAX_PERIODS)),
    numerics=NUMERICS_ARG,
)  # fmt: skip
def sali_spec(
    params: Params,
    ics: np.ndarray,
    periods: int,
    *,
    transient: int,
    sali_tol: float,
    stretch_tol: float,
    max_power: float,
    min_periods: int,
    min_regular: int,
    numerics: Numerics,
) -> SaliSpec:
    """A validated :class:`SaliSpec` (a bad value raises ParameterError naming it; ``exc.option`` its keyword)."""
    with Checking() as at:
        at("periods")
        if ics.shape[0] * periods > config.MAX_POINTS:
            raise ParameterError(f"{ics.shape[0]} orbits x {periods} periods exceeds the limit {config.MAX_POINTS}")
    ics_ = tuple((float(q), float(r)) for q, r in ics)
    return SaliSpec(params, ics_, periods, transient, float(sali_tol), float(stretch_tol), float(max_power),
                    min_periods, min_regular, numerics)  # fmt: skip


def engine_map(pmap: PoincareMap) -> Advance:
    """The :data:`Advance` of this system: ``P`` and ``DP`` over one period by the engine's tangent system
    (:meth:`PoincareMap.derivative`, the members in lock-step blocks), with each member's status."""

    def advance(x: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        mono = pmap.derivative(x, 1)
        return mono.end, mono.matrix, mono.status

    return advance


@dataclass(frozen=True)
class Sali(_Verdicts):
    """SALI and GALI_2 of a :class:`SaliSpec`'s orbits: the :class:`Alignment` (histories per period), the
    verdicts, and per orbit ``status`` (ok, undecided, or the engine's failure)."""

    spec: SaliSpec
    alignment: Alignment
    status: np.ndarray
    elapsed_s: float

    @property
    def completed(self) -> bool:
        return self.alignment.completed

    @property
    def verdict(self) -> np.ndarray:
        return self.alignment.verdict

    @property
    def npts(self) -> np.ndarray:
        return self.alignment.npts

    def final(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per orbit: SALI, GALI_2 at its last period and the mean stretch per period (0 where none ran)."""
        a, n = self.alignment, np.maximum(self.alignment.npts, 1)
        last = n - 1
        rows = np.arange(n.size)
        ran = a.npts > 0
        mean = np.where(ran, np.cumsum(a.stretch, axis=1)[rows, last] / n, 0.0)
        return np.where(ran, a.sali[rows, last], 0.0), np.where(ran, a.gali[rows, last], 0.0), mean

    def rows(self) -> Iterator[tuple]:
        sali, gali, mean = self.final()
        for i, (q, r) in enumerate(self.spec.ics):
            yield (i, q, r, VERDICTS[int(self.verdict[i])], int(self.npts[i]), float(sali[i]), float(gali[i]),
                   float(mean[i]), Status(int(self.status[i])).label)  # fmt: skip

    def summary(self) -> dict[str, Any]:
        keys = ("ic", "verdict", "periods", "sali", "gali2", "stretch", "status")
        return self._summary([dict(zip(keys, ([q, r], *rest), strict=True)) for _, q, r, *rest in self.rows()])

    def report(self) -> list[str]:
        return [f"({q:.6g}, {r:.6g}): {v} after {n} periods (SALI {s:.3g}, GALI_2 {g:.3g}, stretch {st:.3g}/period)"
                + ("" if lab == "ok" else f" ({lab})") for _, q, r, v, n, s, g, st, lab in self.rows()]  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: one row per orbit; ``.npz``: the histories (``sali``, ``gali``, ``stretch``, ``npts``, codes
        with ``status_names``) and the summary; ``.json``: the summary."""
        header = ("orbit", "q0", "r0", "verdict", "periods", "sali", "gali2", "stretch", "status")
        csv_ = lambda p: export.write_csv(p, header, self.rows(), export.partial(self))  # noqa: E731

        def npz(p: str) -> None:
            from explorer_core.status import status_names

            a = self.alignment
            export.write_npz(p, sali=a.sali, gali=a.gali, stretch=a.stretch, npts=a.npts, verdict=a.verdict,
                             verdict_names=np.array(VERDICTS), status=self.status, status_names=status_names(),
                             summary=export.dumps(self.summary()))  # fmt: skip

        return export.write_by_suffix(path, {".csv": csv_, ".npz": npz,
                                             ".json": lambda p: export.write_json(p, self.summary())},
                                      "SALI result")  # fmt: skip


def iter_sali(
    spec: SaliSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Iterator[Step[Sali]]:
    """SALI and GALI_2 along the spec's orbits by the engine's tangent map, period by period (all orbits of a
    period in lock-step blocks); the last update's result is the :class:`Sali` result."""
    spec = spec_of(SaliSpec, sali_spec, spec, args, kw)

    def body(stop: Callable[[], bool]) -> Iterator[Step[Sali]]:
        start = time.perf_counter()
        pmap = PoincareMap.of(spec.params, spec.numerics, workers=workers)
        x0 = np.array(spec.ics, dtype=float)
        failed = np.zeros(x0.shape[0], dtype=np.int64)
        if spec.transient:
            batch = pmap.start(x0)
            pmap.advance(batch, spec.transient, store=False)
            x0, failed = batch.y[:, :2].copy(), batch.status.copy()
        live = failed == _OK
        x0 = np.where(live[:, None], x0, np.nan)  # a member lost in the transient starts as non-finite
        kwargs = {
            "sali_tol": spec.sali_tol,
            "stretch_tol": spec.stretch_tol,
            "max_power": spec.max_power,
            "min_periods": spec.min_periods,
            "min_regular": spec.min_regular,
        }
        last = None
        for update in iter_alignment(engine_map(pmap), x0, spec.periods, cancel=stop, **kwargs):
            if last is not None:
                yield Step(last.progress)
            last = update
        a = last.result
        status = np.where(live, a.status, failed)
        if not a.completed:
            status = np.where((status == _OK) & (a.verdict == NO_VERDICT), int(Status.CANCELLED), status)
        res = Sali(spec, a, _verdict_status(a.verdict, status), time.perf_counter() - start)
        yield Step(Progress(last.progress.done, spec.periods, "periods", res.elapsed_s), result=res)

    return stoppable(body, cancel)


def sali(
    spec: SaliSpec | Params,
    *args: Any,
    progress: Callable[[Any], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    **kw: Any,
) -> Sali:
    """SALI, GALI_2 and the verdicts of :func:`iter_sali`'s last update."""
    return run_updates(iter_sali(spec, *args, cancel=cancel, workers=workers, **kw), progress)
