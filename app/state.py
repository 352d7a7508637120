"""The explorer's state: every control's value, validation, and the URL form.

One :class:`ExplorerState` per browser session. It holds no numerics: it turns
control values into validated requests for :mod:`explorer_core` and back, and
encodes itself as URL query parameters so a link reproduces the view. Nothing
here imports Panel widgets; the views bind to these parameters.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import param

from explorer_core.scenes import get_scene, list_scenes, plot_tolerance
from explorer_core.solve.numerics import Numerics, check_box, random_ics
from explorer_core.system.params import INERTIA_NAMES, ParameterError, Params

#: Per-session bounds: one browser tab cannot ask for unbounded work.
MAX_RANDOM = 500
MAX_PERIODS = 5000
MAX_TRANSIENT = 5000
MAX_POINTS = 400_000
MAX_CLICKED = 200
TPRIME_GRID = 160
DEFAULT_SCENE = "fig1C"

SYSTEM_FIELDS = (*INERTIA_NAMES, "alpha", "g0", "g1", "g2", "omega", "t0")
#: Slider ranges; typed values outside them are accepted if the system is valid.
SLIDER_RANGES: dict[str, tuple[float, float, float]] = {
    "I11": (0.1, 6.0, 0.01),
    "I22": (0.1, 6.0, 0.01),
    "I33": (0.1, 6.0, 0.01),
    "I12": (-2.0, 2.0, 0.01),
    "I13": (-2.0, 2.0, 0.01),
    "I23": (-2.0, 2.0, 0.01),
    "alpha": (-1.0, 1.0, 0.001),
    "g0": (-2.0, 2.0, 0.01),
    "g1": (-2.0, 2.0, 0.01),
    "g2": (-2.0, 2.0, 0.01),
    "omega": (0.1, 4.0, 0.01),
    "t0": (0.0, 2 * math.pi, 0.01),
}


@dataclass(frozen=True)
class SectionRequest:
    """Everything one section computation needs, validated."""

    params: Params
    ics: np.ndarray
    periods: int
    transient: int
    numerics: Numerics


def _fmt(v: float) -> str:
    return repr(float(v)) if v != int(v) or abs(v) >= 1e15 else str(int(v))


class ExplorerState(param.Parameterized):
    """Control values of one session (the URL carries all of them)."""

    scene = param.String(default=DEFAULT_SCENE, doc="paper scene the view started from ('custom' once edited)")
    I11 = param.Number(default=1.0)
    I22 = param.Number(default=4.0)
    I33 = param.Number(default=2.0)
    I12 = param.Number(default=0.0)
    I13 = param.Number(default=0.0)
    I23 = param.Number(default=0.0)
    alpha = param.Number(default=0.1)
    g0 = param.Number(default=0.0)
    g1 = param.Number(default=1.0)
    g2 = param.Number(default=0.0)
    omega = param.Number(default=1.0)
    t0 = param.Number(default=0.0)

    method = param.Selector(default="dop853", objects=["dop853", "dp5", "rk4"])
    accuracy = param.Selector(default="plot", objects=["plot", "high"], doc="tolerance tied to pixels, or 1e-12")
    steps_per_period = param.Integer(default=200, bounds=(8, 20000), doc="RK4 steps per period")
    n_random = param.Integer(default=60, bounds=(0, MAX_RANDOM))
    seed = param.Integer(default=1, bounds=(0, 2**31 - 1))
    periods = param.Integer(default=500, bounds=(1, MAX_PERIODS))
    transient = param.Integer(default=0, bounds=(0, MAX_TRANSIENT))
    box = param.NumericTuple(default=(-3.0, 3.0, -5.0, 5.0), length=4, doc="random ICs box qmin,qmax,rmin,rmax")
    clicked = param.List(default=[], item_type=tuple, doc="initial conditions added by clicking")
    q_range = param.NumericTuple(default=(-3.5, 3.5), length=2)
    r_range = param.NumericTuple(default=(-5.5, 5.5), length=2)

    show_tracks = param.Boolean(default=True)
    show_tprime = param.Boolean(default=True)
    tprime_kind = param.Selector(default="instantaneous", objects=["instantaneous", "per-period"])
    selected = param.Integer(default=0, bounds=(0, None), doc="trajectory shown in the k-series plots")

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        if "scene" in params or not params:
            self.apply_scene(self.scene)

    # --- scenes -----------------------------------------------------------------------

    def apply_scene(self, scene_id: str) -> None:
        """Set every control from a paper scene (one batched update)."""
        s = get_scene(scene_id)
        p = s.params
        values: dict[str, Any] = dict(zip(INERTIA_NAMES, p.inertia, strict=True))
        values.update(alpha=p.alpha, g0=p.g0, g1=p.g1, g2=p.g2, omega=p.omega, t0=p.t0)
        n = min(MAX_RANDOM, s.n_random)
        periods = min(MAX_PERIODS, s.periods, max(1, MAX_POINTS // max(1, n + len(s.points))))
        self.param.update(
            scene=s.id,
            n_random=n,
            seed=s.seed,
            periods=periods,
            transient=min(MAX_TRANSIENT, s.transient),
            box=tuple(s.box),
            clicked=[tuple(pt) for pt in s.points],
            q_range=tuple(s.q_range),
            r_range=tuple(s.r_range),
            selected=0,
            **values,
        )

    @staticmethod
    def scene_ids() -> list[str]:
        return [s.id for s in list_scenes()]

    # --- requests ---------------------------------------------------------------------

    def system(self) -> Params:
        """The validated system; raises ParameterError naming the bad value."""
        return Params(
            inertia=tuple(getattr(self, n) for n in INERTIA_NAMES),
            alpha=self.alpha,
            g0=self.g0,
            g1=self.g1,
            g2=self.g2,
            omega=self.omega,
            t0=self.t0,
        )

    def pixel_size(self) -> float:
        return min(self.q_range[1] - self.q_range[0], self.r_range[1] - self.r_range[0]) / 800

    def numerics(self, bound: float | None = None) -> Numerics:
        """Method and tolerance; 'plot' ties the tolerance to a quarter pixel after all periods."""
        if self.accuracy == "high":
            tol = 1e-12
        else:
            tol = plot_tolerance(self.pixel_size(), self.periods + self.transient)
        span = max(abs(v) for v in (*self.q_range, *self.r_range))
        return Numerics(
            method=self.method,
            rtol=tol,
            atol=tol,
            steps_per_period=self.steps_per_period,
            bound=bound if bound is not None else max(1e3, 100.0 * span),
        )

    def initial_conditions(self) -> np.ndarray:
        """Clicked/scene points first (stable indices), then the seeded random ones."""
        parts = [np.array(self.clicked, dtype=float).reshape(-1, 2)]
        if self.n_random:
            parts.append(random_ics(self.n_random, self.box, seed=self.seed))
        return np.concatenate(parts)

    def section_request(self) -> SectionRequest:
        params = self.system()
        ics = self.initial_conditions()
        if ics.shape[0] == 0:
            raise ParameterError("no initial conditions: set 'random ICs' above 0 or click in the plot")
        n = ics.shape[0]
        if n * self.periods > MAX_POINTS:
            raise ParameterError(
                f"{n} trajectories x {self.periods} periods = {n * self.periods} points; "
                f"this server allows {MAX_POINTS} per view: lower one of them"
            )
        return SectionRequest(params, ics, self.periods, self.transient, self.numerics())

    # --- URL --------------------------------------------------------------------------

    def to_query(self) -> dict[str, str]:
        """The full state as URL query parameters (short, human-readable)."""
        q: dict[str, str] = {"scene": self.scene}
        for f in SYSTEM_FIELDS:
            q[f] = _fmt(getattr(self, f))
        q.update(
            method=self.method,
            accuracy=self.accuracy,
            steps=str(self.steps_per_period),
            n=str(self.n_random),
            seed=str(self.seed),
            periods=str(self.periods),
            transient=str(self.transient),
            box=",".join(_fmt(v) for v in self.box),
            qr=",".join(_fmt(v) for v in self.q_range),
            rr=",".join(_fmt(v) for v in self.r_range),
            ics=";".join(f"{_fmt(a)},{_fmt(b)}" for a, b in self.clicked),
            tracks=str(int(self.show_tracks)),
            tprime={"instantaneous": "inst", "per-period": "period"}[self.tprime_kind] if self.show_tprime else "off",
        )
        return q


# --- parsing URL query parameters ---------------------------------------------------------

_ID = re.compile(r"^[A-Za-z0-9_.-]{1,40}$")


def _qfloat(name: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ParameterError(f"{name} must be a number, got {text[:40]!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {text[:40]!r}")
    return v


def _qint(name: str, text: str, lo: int, hi: int) -> int:
    try:
        v = int(text)
    except ValueError:
        raise ParameterError(f"{name} must be an integer, got {text[:40]!r}") from None
    if not lo <= v <= hi:
        raise ParameterError(f"{name} must be between {lo} and {hi}, got {v}")
    return v


def _qlist(name: str, text: str, n: int) -> tuple[float, ...]:
    parts = text.split(",")
    if len(parts) != n:
        raise ParameterError(f"{name} needs {n} comma-separated numbers, got {text[:60]!r}")
    return tuple(_qfloat(name, p) for p in parts)


def parse_query(query: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Validated state updates from URL query parameters, and one message per bad value.

    Unknown keys are ignored; a bad value is reported and left out (the rest
    still applies). Values are never echoed unescaped: callers show messages as text.
    """
    updates: dict[str, Any] = {}
    errors: list[str] = []

    def get(key: str) -> str | None:
        v = query.get(key)
        if v is None:
            return None
        if isinstance(v, list | tuple):
            v = v[-1] if v else ""
        if isinstance(v, bytes):
            v = v.decode("utf-8", "replace")
        return str(v)

    def attempt(key: str, fn) -> None:
        text = get(key)
        if text is None:
            return
        try:
            fn(text)
        except ParameterError as exc:
            errors.append(f"URL parameter {key}: {exc}")

    def scene(text: str) -> None:
        if not _ID.match(text) or text == "custom":
            if text != "custom":
                raise ParameterError("unknown scene")
            updates["scene"] = "custom"
            return
        updates["scene"] = get_scene(text).id

    attempt("scene", scene)
    for f in SYSTEM_FIELDS:
        attempt(f, lambda t, f=f: updates.__setitem__(f, _qfloat(f, t)))

    def choice(key: str, field: str, options: Mapping[str, str]) -> None:
        def fn(t: str) -> None:
            if t not in options:
                raise ParameterError(f"must be one of {', '.join(options)}, got {t[:40]!r}")
            updates[field] = options[t]

        attempt(key, fn)

    choice("method", "method", {m: m for m in ("dop853", "dp5", "rk4")})
    choice("accuracy", "accuracy", {"plot": "plot", "high": "high"})
    attempt("steps", lambda t: updates.__setitem__("steps_per_period", _qint("steps", t, 8, 20000)))
    attempt("n", lambda t: updates.__setitem__("n_random", _qint("n", t, 0, MAX_RANDOM)))
    attempt("seed", lambda t: updates.__setitem__("seed", _qint("seed", t, 0, 2**31 - 1)))
    attempt("periods", lambda t: updates.__setitem__("periods", _qint("periods", t, 1, MAX_PERIODS)))
    attempt("transient", lambda t: updates.__setitem__("transient", _qint("transient", t, 0, MAX_TRANSIENT)))
    attempt("box", lambda t: updates.__setitem__("box", check_box(_qlist("box", t, 4))))

    def rng(key: str, field: str) -> None:
        def fn(t: str) -> None:
            lo, hi = _qlist(key, t, 2)
            if not lo < hi:
                raise ParameterError(f"needs lo < hi, got {t[:40]!r}")
            updates[field] = (lo, hi)

        attempt(key, fn)

    rng("qr", "q_range")
    rng("rr", "r_range")

    def ics(text: str) -> None:
        pts = [p for p in text.split(";") if p.strip()]
        if len(pts) > MAX_CLICKED:
            raise ParameterError(f"at most {MAX_CLICKED} initial conditions, got {len(pts)}")
        updates["clicked"] = [_qlist("ics", p, 2) for p in pts]

    attempt("ics", ics)
    choice("tracks", "show_tracks", {"1": True, "0": False})

    def tprime(text: str) -> None:
        opts = {"inst": ("instantaneous", True), "period": ("per-period", True), "off": (None, False)}
        if text not in opts:
            raise ParameterError(f"must be one of inst, period, off, got {text[:40]!r}")
        kind, show = opts[text]
        updates["show_tprime"] = show
        if kind:
            updates["tprime_kind"] = kind

    attempt("tprime", tprime)
    return updates, errors


def state_from_query(query: Mapping[str, Any]) -> tuple[ExplorerState, list[str]]:
    """A state for a new session: the scene named in the URL (or the default), then the URL's values."""
    updates, errors = parse_query(query)
    sid = updates.pop("scene", DEFAULT_SCENE)
    state = ExplorerState(scene=sid if sid != "custom" else DEFAULT_SCENE)
    if sid == "custom" or any(k in updates for k in SYSTEM_FIELDS):
        updates["scene"] = "custom" if sid == "custom" or _differs(state, updates) else state.scene
    state.param.update(**updates)
    return state, errors  # an invalid system is reported by the session when it validates


def _differs(state: ExplorerState, updates: Mapping[str, Any]) -> bool:
    return any(f in updates and float(updates[f]) != float(getattr(state, f)) for f in SYSTEM_FIELDS)
