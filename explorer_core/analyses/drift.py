"""Drift of noncompact trajectories: polynomial fits of ``q_k``, ``r_k`` and the implied map.

The paper (Figs. 3, 6 and 9) follows trajectories on a noncompact attractive
curve, fits univariate polynomials to the section data ``q_k``, ``r_k`` over a
window of ``k`` (e.g. ``k = 200..900``), averages the coefficients over ten
random initial conditions and reads an approximate map from them. For Fig. 3::

    q = -0.300263,   r = a t^2 + b t + c,
    q_{k+1} = q_k,   r_{k+1} = r_k + 2 pi sqrt(b^2 - 4 a c + 4 a r_k) + 4 a pi^2.

The fitted values only make sense with the **period index** ``k`` as the
polynomials' variable (``r`` reaches about -400 at ``k = 900``; with the time
``t = 2 pi k`` it would be about -9500), while the map's ``2 pi`` steps assume
the time ``t``. Fits here are in ``k``, and are converted to ``t = t0 + k T``
on request; :func:`implied_map` advances ``k`` by one on the fitted curve (in
``t``: by ``T``), and :func:`quadratic_map` is the paper's closed form for any
step, with the branch of the square root chosen by the sign of ``r'``.

Members: a random initial condition counts only if its trajectory is on the
drift (see :func:`on_drift`: along the curve during the whole window, or leaving
the compact region within it); random draws continue until ``m`` members
qualify, as the paper chose ten trajectories "turning into a noncompact
attractive curve".
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.polynomial import polynomial as P

from explorer_core import config, export
from explorer_core.analyses.specs import Checking, spec_of
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, stream
from explorer_core.progress import run as run_updates
from explorer_core.solve.checks import check_choice
from explorer_core.solve.integrators import tables
from explorer_core.solve.numerics import Numerics, check_int
from explorer_core.solve.options import Arg, Check, choice, declare, ics, integer, optional_of
from explorer_core.solve.options import box as box_check
from explorer_core.solve.options import seed as seed_check
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.rk import Status
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params

#: Criteria for a member to count (see :func:`on_drift`).
CRITERIA = ("on_curve", "leaves")
#: "on_curve": fraction of window steps in which |x_k| grows, and the largest allowed
#: turn (radians) of the step direction x_{k+1} - x_k over the window.
MONOTONE_FRACTION = 0.95
MAX_TURN = 0.05
#: "leaves": growth factor of |x| over the window.
LEAVE_GROWTH = 10.0
#: The fit's numerics unless the caller gives its own (the defaults of :class:`Numerics`).
DRIFT_NUMERICS = Numerics()


def fit_polynomial(k: np.ndarray, x: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares polynomial in ``k``: coefficients lowest first, and the residuals.

    The fit is done on a scaled variable (well conditioned for high degree and
    large ``k``) and converted back to powers of ``k``.
    """
    k = np.asarray(k, dtype=float)
    x = np.asarray(x, dtype=float)
    if k.size <= degree:
        raise ParameterError(f"a degree-{degree} fit needs more than {degree} points, got {k.size}")
    poly = np.polynomial.Polynomial.fit(k, x, degree)
    coef = poly.convert().coef
    coef = np.concatenate([coef, np.zeros(degree + 1 - coef.size)])
    return coef, x - P.polyval(k, coef)


def to_time(coef_k: np.ndarray, t0: float, period: float) -> np.ndarray:
    """Coefficients in ``t`` of the polynomial given in ``k``, with ``t = t0 + k T``."""
    # k = (t - t0) / T: substitute the linear polynomial into the power series (Horner).
    lin = np.array([-t0 / period, 1.0 / period])
    out = np.array([coef_k[-1]])
    for c in coef_k[-2::-1]:
        out = P.polyadd(P.polymul(out, lin), [c])
    return np.concatenate([out, np.zeros(coef_k.size - out.size)])


def on_drift(x: np.ndarray, criterion: str = "on_curve") -> bool:
    """Whether the window ``x`` (shape (n, 2), consecutive section points) is drift.

    ``"on_curve"``: the points move away along the curve's asymptotic direction the
    whole time -- ``|x_k|`` grows in at least :data:`MONOTONE_FRACTION` of the steps
    and the direction of the steps turns by at most :data:`MAX_TURN` radians over the
    window (a trajectory still sliding onto the curve turns by tens of degrees, one on
    a compact attractor all the way round); the paper's fits over ``k = 200..900``
    (Figs. 3, 6).
    ``"leaves"``: ``|x_k|`` grows by :data:`LEAVE_GROWTH` over the window (it leaves the
    compact region within it); the paper's fits over ``k = 0..60`` (Fig. 9).
    """
    x = np.asarray(x, dtype=float)
    norms = np.hypot(x[:, 0], x[:, 1])
    if check_choice("criterion", criterion, CRITERIA) == "leaves":
        return bool(norms[-1] >= LEAVE_GROWTH * max(1.0, norms[0]))
    d1 = np.diff(x, axis=0)
    if d1.shape[0] < 2:
        return False
    angle = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    return bool(
        np.mean(np.diff(norms) > 0) >= MONOTONE_FRACTION
        and angle.max() - angle.min() <= MAX_TURN
        and norms[-1] > norms[0]
    )


def quadratic_map(
    a: float, b: float, c: float, r: np.ndarray | float, step: float = 1.0, sign: float = 1.0
) -> np.ndarray:
    """``r(s + step)`` on the curve ``r = a s^2 + b s + c`` through ``r(s) = r_k``.

    ``2 a s + b = sign * sqrt(b^2 - 4 a c + 4 a r)``: ``sign`` picks the branch (the
    sign of ``dr/ds`` where the data lie). The paper's map is ``step = 2 pi`` and
    ``sign = +1``; on its own fit (``a, b < 0``, ``s = k > 0``) the branch is ``-1``.
    """
    r = np.asarray(r, dtype=float)
    disc = np.maximum(b * b - 4 * a * c + 4 * a * r, 0.0)
    return r + step * sign * np.sqrt(disc) + a * step * step


def implied_map(coef: np.ndarray, x: np.ndarray, k_guess: np.ndarray, step: float = 1.0) -> np.ndarray:
    """``P(kappa + step)`` where ``P(kappa) = x`` with ``kappa`` the real root nearest ``k_guess``.

    The fitted drift curve read as a map: the polynomial is a clock, one
    iteration advances it by ``step`` (1 in ``k``).
    """
    out = np.empty(np.shape(x))
    for n, (xv, kg) in enumerate(zip(np.ravel(x), np.ravel(k_guess), strict=True)):
        c = coef.astype(float).copy()
        c[0] -= xv
        roots = P.polyroots(c) if np.any(c[1:] != 0) else np.array([kg])
        real = roots[np.abs(roots.imag) <= 1e-7 * (1 + np.abs(roots.real))].real
        kappa = real[np.argmin(np.abs(real - kg))] if real.size else kg
        out.flat[n] = P.polyval(kappa + step, coef)
    return out


@dataclass(frozen=True)
class DriftFit:
    """Polynomial fits of the drift over a window, per member and averaged.

    Coefficients are lowest power first, in the **period index** ``k``
    (``coef_*_t`` in the time ``t = t0 + k T``). ``members`` are the initial
    conditions that were on the drift through the window; ``series[m]`` their
    ``(k, q, r)`` over ``0..k1``.
    """

    params: Params | None
    t0: float
    period: float
    window: tuple[int, int]
    degree: tuple[int, int]
    criterion: str
    members: np.ndarray
    rejected: int
    failed: int
    series: np.ndarray  # (M, k1 + 1, 2) q, r at k = 0..k1
    coef_q: np.ndarray  # (M, dq + 1)
    coef_r: np.ndarray  # (M, dr + 1)
    rms_q: np.ndarray  # (M,) residual RMS of each member's own fit
    rms_r: np.ndarray
    growth_rate: np.ndarray  # (M,) slope of log |x_k| per period over the window
    numerics: Numerics
    elapsed_s: float
    completed: bool = True  # False: cancelled
    #: members wanted but not found (cancelled, or the draws spent)
    lost: list[Loss] = field(default_factory=list)
    #: what was asked
    spec: DriftSpec | None = None

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: the members' series ``member,k,q,r``; ``.json``: the summary."""
        rows = lambda: ((i, k, x[k, 0], x[k, 1]) for i, x in enumerate(self.series) for k in range(x.shape[0]))  # noqa: E731
        csv_ = lambda p: export.write_csv(p, ("member", "k", "q", "r"), rows(), export.partial(self))  # noqa: E731
        return export.write_by_suffix(
            path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())}, "drift fit"
        )

    @property
    def k(self) -> np.ndarray:
        k0, k1 = self.window
        return np.arange(k0, k1 + 1)

    def mean(self) -> tuple[np.ndarray, np.ndarray]:
        """Averaged coefficients (the paper's procedure); NaN when no member was found (cancelled)."""
        if self.members.shape[0] == 0:
            return np.full(self.coef_q.shape[1], np.nan), np.full(self.coef_r.shape[1], np.nan)
        return self.coef_q.mean(axis=0), self.coef_r.mean(axis=0)

    def spread(self) -> tuple[np.ndarray, np.ndarray]:
        """Standard deviation of the coefficients over members (ddof=1; zeros for one member)."""
        if self.members.shape[0] < 2:  # (a zero-member fit: zeros of the coefficients' shape)
            return np.zeros_like(self.coef_q[0]), np.zeros_like(self.coef_r[0])
        return self.coef_q.std(axis=0, ddof=1), self.coef_r.std(axis=0, ddof=1)

    def mean_in_time(self) -> tuple[np.ndarray, np.ndarray]:
        """Averaged coefficients in ``t = t0 + k T``."""
        cq, cr = self.mean()
        return to_time(cq, self.t0, self.period), to_time(cr, self.t0, self.period)

    def residuals_of_mean(self) -> tuple[float, float]:
        """RMS over all members and window points of data minus the averaged polynomials."""
        cq, cr = self.mean()
        k0, k1 = self.window
        k = self.k
        dq = self.series[:, k0 : k1 + 1, 0] - P.polyval(k, cq)
        dr = self.series[:, k0 : k1 + 1, 1] - P.polyval(k, cr)
        return float(np.sqrt(np.mean(dq * dq))), float(np.sqrt(np.mean(dr * dr)))

    def map_error(self) -> dict[str, float]:
        """One-step RMS error of the implied map ``r_k -> r_{k+1}`` on the members' data.

        ``implied``: the averaged ``r`` polynomial advanced by one in ``k``;
        ``paper_formula``: for a quadratic fit, the paper's closed form with steps of
        ``2 pi`` (its reading of the variable as time), sign as printed (``+``).
        """
        _, cr = self.mean()
        k0, k1 = self.window
        r = self.series[:, k0:k1, 1]
        nxt = self.series[:, k0 + 1 : k1 + 1, 1]
        kk = np.broadcast_to(np.arange(k0, k1), r.shape)
        out = {"implied": float(np.sqrt(np.mean((implied_map(cr, r, kk) - nxt) ** 2)))}
        if cr.size == 3:
            c, b, a = cr
            disc = np.maximum(b * b - 4 * a * c + 4 * a * r, 0.0)
            paper = r + 2 * math.pi * np.sqrt(disc) + 4 * a * math.pi**2
            out["paper_formula"] = float(np.sqrt(np.mean((paper - nxt) ** 2)))
            sign = math.copysign(1.0, 2 * a * 0.5 * (k0 + k1) + b)  # dr/dk in the window
            out["quadratic_in_k"] = float(np.sqrt(np.mean((quadratic_map(a, b, c, r, 1.0, sign) - nxt) ** 2)))
        out["mean_step"] = float(np.mean(np.abs(nxt - r)))
        return out

    def report(self) -> list[str]:
        """What the command line prints: the members, the fitted polynomials, the residuals."""
        s = self.summary()
        return [f"{s['members']} members (rejected {s['rejected']}, failed {s['failed']})",
                f"q(k) = {s['q']['formula']}", f"r(k) = {s['r']['formula']}",
                f"residual RMS q {s['residual_rms']['q']:.4g}, r {s['residual_rms']['r']:.4g}"]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        if self.members.shape[0] == 0:  # cancelled before any member was found
            return {"window": list(self.window), "degree": list(self.degree), "criterion": self.criterion,
                    "members": 0, "rejected": self.rejected, "failed": self.failed, "completed": self.completed,
                    "complete": False, "lost": [loss.as_dict() for loss in self.lost],
                    "elapsed_s": round(self.elapsed_s, 6),
                    "params": self.params.as_dict() if self.params is not None else None,
                    "numerics": self.numerics.as_dict(), **self._spec()}  # fmt: skip
        cq, cr = self.mean()
        sq, sr = self.spread()
        tq, tr = self.mean_in_time()
        rq, rr = self.residuals_of_mean()
        return {
            "window": list(self.window),
            "degree": list(self.degree),
            "criterion": self.criterion,
            "variable": "k (period index); *_t: time t = t0 + k T",
            "members": int(self.members.shape[0]),
            "rejected": self.rejected,
            "failed": self.failed,
            "q": {"coef": cq.tolist(), "spread": sq.tolist(), "coef_t": tq.tolist(), "formula": poly_text(cq, "k")},
            "r": {"coef": cr.tolist(), "spread": sr.tolist(), "coef_t": tr.tolist(), "formula": poly_text(cr, "k")},
            "residual_rms": {
                "q": rq,
                "r": rr,
                "q_member_mean": float(self.rms_q.mean()),
                "r_member_mean": float(self.rms_r.mean()),
            },
            "map_error": self.map_error(),
            "growth_rate_per_period": float(self.growth_rate.mean()),
            "ics": self.members.tolist(),
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict() if self.params is not None else None,
            "numerics": self.numerics.as_dict(),
            **self._spec(),
        }

    def _spec(self) -> dict[str, Any]:
        """What was asked (the random draws' box, seed and budget too), for the summary."""
        return {"spec": self.spec.as_dict()} if self.spec is not None else {}


def poly_text(coef: np.ndarray, var: str = "k", digits: int = 7) -> str:
    """``c_n var^n + ... + c_0``, highest power first (the paper's way of writing)."""
    terms = []
    for p in range(coef.size - 1, -1, -1):
        c = float(coef[p])
        v = f"{c:.{digits}g}"
        terms.append(v if p == 0 else f"{v} {var}" if p == 1 else f"{v} {var}^{p}")
    return " + ".join(terms).replace("+ -", "- ")


@dataclass(frozen=True)
class Tables:
    """A quadratic field given by raw coefficient tables (the format of :class:`Model`)."""

    num: np.ndarray
    gpc: np.ndarray
    den: np.ndarray
    forcing: np.ndarray
    t0: float
    period: float


def _series(field: Tables, ics: np.ndarray, k1: int, numerics: Numerics) -> tuple[np.ndarray, np.ndarray]:
    """``x_k`` for ``k = 0..k1`` (k = 0 is the IC) and the status of each trajectory."""
    coefs = tables(field.num, field.gpc, field.den, field.forcing, np.zeros(ics.shape[0], dtype=np.int64))
    pmap = PoincareMap.rows(coefs, field.t0, field.period, numerics)
    batch = pmap.start(ics)
    pts, npts = pmap.advance(batch, k1)
    out = np.concatenate([ics[:, None, :], pts], axis=1)
    ok = (batch.status == Status.OK) & (npts == k1)
    return out, np.where(ok, Status.OK, np.where(batch.status == Status.OK, Status.TOO_MANY_STEPS, batch.status))


@dataclass(frozen=True)
class DriftSpec:
    """Everything that defines a drift fit (validated by :func:`drift_spec`; plain data: picklable,
    comparable). ``ics`` None: random initial conditions in ``box`` (seeded by ``seed``), drawn until ``m``
    are on the drift or ``max_draws`` are spent; given: all of them are tried (``m`` and ``box`` unused)."""

    params: Params | None
    window: tuple[int, int]
    degree: tuple[int, int]
    m: int
    ics: tuple[tuple[float, float], ...] | None
    box: tuple[float, float, float, float] | None
    seed: int | None
    max_draws: int
    criterion: str
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return {"params": None if self.params is None else self.params.as_dict(), "window": list(self.window),
                "degree": list(self.degree), "m": self.m,
                "ics": None if self.ics is None else [list(x) for x in self.ics],
                "box": None if self.box is None else list(self.box), "seed": self.seed, "max_draws": self.max_draws,
                "criterion": self.criterion, "numerics": self.numerics.as_dict()}  # fmt: skip


def _whole(name: str, value: Any, what: str) -> tuple[int, int]:
    """Two whole numbers, or a ParameterError naming ``name`` and ``value``."""
    try:
        vals = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        vals = ()
    if len(vals) != 2 or not all(math.isfinite(v) and v.is_integer() for v in vals):
        raise ParameterError(f"{name} must be two integers {what}, got {value!r}")
    return int(vals[0]), int(vals[1])


def _window(name: str, value: Any) -> tuple[int, int]:
    k0, k1 = _whole(name, value, "k0,k1")
    if not 0 <= k0 < k1 <= config.MAX_PERIODS:
        raise ParameterError(f"{name} must satisfy 0 <= k0 < k1 <= {config.MAX_PERIODS}, got {value!r}")
    return k0, k1


def _members(name: str, value: Any) -> int:
    return check_int(f"{name} (members)", value, 1, 10_000)


@declare(
    window=Arg(
        "inclusive k range (k = 0 is the IC)",
        "ints",
        metavar="K0,K1",
        required=True,
        positional=True,
        check=Check(_window, f"two integers 0 <= k0 < k1 <= {config.MAX_PERIODS}", "str"),
    ),
    # Below the window's length: checked with it in the body.
    degree=Arg("degrees of the q and r polynomials", "ints", metavar="DQ,DR", default=(1, 2), checked_with=("window",)),
    m=Arg(
        "drifting ICs to average",
        "int",
        flag="--members",
        default=10,
        check=Check(_members, "an integer in [1, 10000]", "int"),
    ),
    ics=Arg(
        "explicit ICs instead of random ones (repeatable)",
        "points",
        flag="--ic",
        default=None,
        check=ics(optional=True),
    ),
    box=Arg(
        "box for random ICs",
        "box",
        metavar="QMIN,QMAX,RMIN,RMAX",
        scene="box",
        default=None,
        check=box_check(optional=True),
    ),
    seed=Arg("random seed of the ICs", "int", default=0, check=seed_check(optional=True)),
    criterion=Arg("which ICs count", "str", choices=CRITERIA, default="on_curve", check=choice(CRITERIA)),
    max_draws=Arg(
        "random initial conditions drawn at most (None: 50 m)",
        cli=False,
        default=None,
        check=integer(1, 10**7, optional=True),
    ),
    numerics=Arg(
        "integration settings", cli=False, default=DRIFT_NUMERICS, check=optional_of(Numerics, DRIFT_NUMERICS)
    ),
)
def drift_spec(
    params: Params | None,
    window: tuple[int, int],
    *,
    degree: Sequence[int],
    m: int,
    ics: np.ndarray | None,
    box: tuple[float, float, float, float] | None,
    seed: int | None,
    max_draws: int | None,
    criterion: str,
    numerics: Numerics,
) -> DriftSpec:
    """A validated :class:`DriftSpec`; every bad value raises :class:`ParameterError` naming it (and
    carrying the keyword as ``exc.option``, :mod:`explorer_core.analyses.specs`). The options are declared above
    (defaults, checks run before this body, flags); the body checks what needs several of them.

    Parameters
    ----------
    params : the system (None for a field that is not a Bilimovich system, :func:`drift_fit_tables`).
    window : inclusive ``k`` range ``(k0, k1)`` of the fit, ``0 <= k0 < k1 <= config.MAX_PERIODS`` (``k = 0``
        is the initial condition).
    degree : ``(degree of q, degree of r)``, each in ``[0, 12]`` and below the window's length.
    m : members wanted, in ``[1, 10000]`` (ignored when ``ics`` is given: all of them are tried).
    ics : explicit finite initial conditions; else uniform random ones in ``box`` (needed then) drawn in
        batches (seeded by ``seed``, an integer >= 0 or None) until ``m`` are on the drift or ``max_draws``
        (default ``50 m``, at most ``10^7``) are spent.
    criterion : which trajectories count as drifting (:func:`on_drift`): ``"on_curve"`` through the whole
        window, or ``"leaves"`` the compact region within it.
    numerics : integration settings (default :data:`DRIFT_NUMERICS`; None: the default); the escape ``bound``
        must exceed the drift's reach.
    """
    k0, k1 = window
    with Checking() as at:
        at("degree")
        dq, dr = _whole("degree", degree, "(q, r)")
        for d in (dq, dr):
            if not 0 <= d <= 12 or d >= k1 - k0 + 1:
                raise ParameterError(f"degree must be in [0, 12] and below the window length, got {degree!r}")
        at("box")
        if ics is None and box is None:
            raise ParameterError("give initial conditions (ics) or a box for random ones")
    pool = None if ics is None else tuple((float(q), float(r)) for q, r in ics)
    max_draws = 50 * m if max_draws is None else max_draws
    return DriftSpec(params, window, (dq, dr), m, pool, box, seed, max_draws, criterion, numerics)


def iter_drift_fit(
    spec: DriftSpec | Params, *args: Any, cancel: Callable[[], bool] | None = None, **kw: Any
) -> Iterator[Step[DriftFit]]:
    """:func:`drift_fit` as a stream of :class:`~explorer_core.progress.Step` (draws tried of the draws
    allowed, after each batch); the last update's ``result`` is the fit. ``iter_drift_fit(spec)``, or the
    keyword form ``iter_drift_fit(params, window, **options)`` (the spec built by :func:`drift_spec`, checked
    at the call)."""
    spec = spec_of(DriftSpec, drift_spec, spec, args, kw)
    if spec.params is None:
        raise ParameterError("a drift fit of the Bilimovich system needs its params (drift_fit_tables fits a field)")
    params = spec.params
    model = Model(params)
    field = Tables(model.num, model.gpc, model.den, np.ascontiguousarray(model.forcing), params.t0, params.period)
    return stream(lambda emit, stop: _drift_fit(field, spec, progress=emit, cancel=stop, final=True), cancel)


def drift_fit(
    spec: DriftSpec | Params,
    *args: Any,
    progress: Callable[[Step[DriftFit]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    **kw: Any,
) -> DriftFit:
    """Fit polynomials to the drift of the Bilimovich system (see :func:`drift_fit_tables`); ``progress``
    gets every update of :func:`iter_drift_fit`. ``drift_fit(spec)`` with a :class:`DriftSpec`, or the
    keyword form ``drift_fit(params, window, **options)`` (the options of :func:`drift_spec`)."""
    return run_updates(iter_drift_fit(spec, *args, cancel=cancel, **kw), progress)


def drift_fit_tables(
    field: Tables,
    window: Sequence[int],
    *,
    progress: Callable[[Step[DriftFit]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    params: Params | None = None,
    final: bool = False,
    **options: Any,
) -> Any:
    """Fit polynomials to ``q_k``, ``r_k`` over ``window = (k0, k1)``, averaged over drifting members.

    Parameters
    ----------
    field : the quadratic field's tables, section phase ``t0`` and period (any field in
        the model's format: :func:`drift_fit` passes the Bilimovich system's).
    window, **options : the window and the options of :func:`drift_spec` (degree, m, ics, box, seed,
        max_draws, criterion, numerics).
    progress : called with a :class:`~explorer_core.progress.Step` (draws tried of the draws allowed, the
        members found as its ``detail``) after each batch; ``cancel`` polled between batches: a cancelled
        fit has ``completed`` False and the members not found in ``lost`` (no member at all: NaN means).
    params : recorded in the result (``None`` for a field that is not a Bilimovich system).
    final : return the last update (a ``Step`` carrying the fit, :func:`iter_drift_fit`) instead of the fit.

    Raises
    ------
    ParameterError
        If no member is on the drift (the message says how many were tried and why they failed).
    """
    spec = drift_spec(params, window, **options)
    return _drift_fit(field, spec, progress=progress, cancel=cancel, final=final)


def _drift_fit(
    field: Tables,
    spec: DriftSpec,
    *,
    progress: Callable[[Step[DriftFit]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    final: bool = False,
) -> Any:
    """The fit of :func:`drift_fit_tables` on a checked spec."""
    start = time.perf_counter()
    (k0, k1), (dq, dr), m, criterion, numerics = spec.window, spec.degree, spec.m, spec.criterion, spec.numerics
    params, ics, box, max_draws = spec.params, spec.ics, spec.box, spec.max_draws
    if ics is not None:
        pool = np.array(ics, dtype=float)
        batches = [pool]
    else:
        rng = np.random.default_rng(spec.seed)
        batches = None
    members, series, rejected, failed, draws = [], [], 0, 0, 0
    cancelled = False
    allowed = pool.shape[0] if ics is not None else max_draws

    def consider(ic_batch: np.ndarray) -> None:
        nonlocal rejected, failed
        xs, status = _series(field, ic_batch, k1, numerics)
        for ic, x, st in zip(ic_batch, xs, status, strict=True):
            if st != Status.OK:
                failed += 1
            elif on_drift(x[k0 : k1 + 1], criterion):
                members.append(ic)
                series.append(x)
            else:
                rejected += 1

    if batches is not None:
        consider(batches[0])
        draws = batches[0].shape[0]
    else:
        while len(members) < m and draws < max_draws:
            if cancel is not None and cancel():
                cancelled = True
                break
            n = min(max(2 * config.N_WORKERS, 2 * (m - len(members))), max_draws - draws)
            batch = np.column_stack([rng.uniform(box[0], box[1], n), rng.uniform(box[2], box[3], n)])
            consider(batch)
            draws += n
            if progress is not None:
                progress(Step(Progress(draws, max_draws, "draws", time.perf_counter() - start), len(members)))
        del members[m:], series[m:]
    lost = []
    wanted = m if ics is None else 0
    if len(members) < wanted:
        why = "cancelled" if cancelled else f"{draws} draws spent: {rejected} not drifting, {failed} failed or escaped"
        lost.append(Loss("members not found", wanted - len(members), why))
    if not members and not cancelled:
        raise ParameterError(
            f"no trajectory is on the drift over k = {k0}..{k1}: {draws} tried, {rejected} not drifting "
            f"(criterion {criterion!r}), {failed} failed or escaped (raise the bound?)"
        )
    ser = np.array(series).reshape(len(series), k1 + 1, 2)
    k = np.arange(k0, k1 + 1)
    cq, cr, rq, rr, gr = [], [], [], [], []
    for x in ser:
        c, res = fit_polynomial(k, x[k0 : k1 + 1, 0], dq)
        cq.append(c)
        rq.append(float(np.sqrt(np.mean(res * res))))
        c, res = fit_polynomial(k, x[k0 : k1 + 1, 1], dr)
        cr.append(c)
        rr.append(float(np.sqrt(np.mean(res * res))))
        norms = np.log(np.hypot(x[k0 : k1 + 1, 0], x[k0 : k1 + 1, 1]))
        gr.append(float(np.polyfit(k, norms, 1)[0]))
    fit = DriftFit(
        params=params,
        t0=float(field.t0),
        period=float(field.period),
        window=(k0, k1),
        degree=(dq, dr),
        criterion=criterion,
        members=np.array(members).reshape(len(members), 2),
        rejected=rejected,
        failed=failed,
        series=ser,
        coef_q=np.array(cq).reshape(len(cq), dq + 1),
        coef_r=np.array(cr).reshape(len(cr), dr + 1),
        rms_q=np.array(rq),
        rms_r=np.array(rr),
        growth_rate=np.array(gr),
        numerics=numerics,
        elapsed_s=time.perf_counter() - start,
        completed=not cancelled,
        lost=lost,
        spec=spec,
    )
    if not final:
        return fit
    return Step(Progress(draws if cancelled else allowed, allowed, "draws", fit.elapsed_s), len(members), fit)
