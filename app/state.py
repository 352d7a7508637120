"""The explorer's state: every control's value in use, validation, and the URL form.

One :class:`ExplorerState` per browser session. It holds no numerics: it turns control
values into validated requests for :mod:`explorer_core` and back, and encodes itself as
URL query parameters so a link reproduces the view (open tab, selected trajectory and
analysis settings included).

Every value reaches the state through one gate, :func:`commit` (a typed value, a slider
release, a URL parameter): it is parsed (:func:`parse_control`), checked against the rest
of the state (a positive-definite tensor, the work bound) and either applied or refused
with a message that names the value and says which value stays in use. So the state only
ever holds values that are used, and a control can always show exactly that.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import param

from app.controls import MAX_MAGNITUDE, PLOT_PIXELS, SYSTEM_FIELDS, Control, UrlKey
from app.controls import choice as _choice
from app.controls import finite as _finite
from app.controls import fmt as _fmt
from app.controls import ints as _ints
from app.controls import numbers as _numbers
from app.controls import points_text as _points_text
from app.controls import whole as _whole
from app.layers import LAYERS
from explorer_core.analyses.body import box_exists, principal_axes
from explorer_core.analyses.density import DensitySpec, density_numerics, density_spec
from explorer_core.analyses.sections import SectionSpec, section_spec
from explorer_core.scenes import get_scene, list_scenes, plot_tolerance
from explorer_core.solve.numerics import Numerics, check_box, chosen_numerics, random_ics
from explorer_core.solve.stability import spectral_rate, stability_interval
from explorer_core.system.params import INERTIA_NAMES, ParameterError, Params

#: Per-session bounds: one browser tab cannot ask for unbounded work.
MAX_RANDOM = 10_000
MAX_PERIODS = 100_000
MAX_TRANSIENT = 5000
#: Points drawn one by one (pickable, coloured by trajectory); beyond, the section is a density image.
MAX_POINTS = 400_000
#: Points of a section drawn as a density image (binned on the server, never sent or kept).
MAX_DENSITY_POINTS = 10_000_000
DENSITY_PIXELS = PLOT_PIXELS
MAX_CLICKED = 200
DEFAULT_SCENE = "fig1C"
#: Longest text a control accepts (longer is refused, never parsed).
MAX_TEXT = 200
#: Analysis limits (work per run).
LIMITS = {"lyap_periods": 20000, "ensemble": 16, "bif_values": 400, "bif_points": 400, "transient": 5000,
          "grid": 120, "chart_periods": 3000, "bench_periods": 500}  # fmt: skip
#: Frames across a played range, and frames per second asked (app/play.py).
MAX_PLAY_FRAMES = 2000
MAX_PLAY_FPS = 30
#: Steps of a tour (app/tours.json).
MAX_TOUR_STEPS = 6
#: The body view's animation speeds, periods per second (app/body.js).
BODY_SPEEDS = ("0.05", "0.1", "0.25", "0.5", "1", "2", "4")

SWEEPABLE = ("alpha", *INERTIA_NAMES, "g0", "g1", "g2", "omega")
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
TABS = ("section", "lyapunov", "bifurcation", "chart", "bench")
#: The system of a new session before its scene sets it.
SYSTEM_DEFAULTS = {"I11": 1.0, "I22": 4.0, "I33": 2.0, "I12": 0.0, "I13": 0.0, "I23": 0.0, "alpha": 0.1, "g0": 0.0,
                   "g1": 1.0, "g2": 0.0, "omega": 1.0, "t0": 0.0}  # fmt: skip


@dataclass(frozen=True)
class SectionRequest:
    """Everything one section computation needs, validated."""

    params: Params
    ics: np.ndarray
    periods: int
    transient: int
    numerics: Numerics
    #: Drawn as a density image of ``view`` (else as points); ``keep``: trajectories also drawn as points.
    density: bool = False
    view: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)
    keep: tuple[int, ...] = ()
    #: The spec the core's builder made of the page (the command line's for the same settings).
    spec: SectionSpec | DensitySpec | None = field(default=None, compare=False)


def _range(name: str, text: str) -> tuple[float, float]:
    lo, hi = _numbers(name, text, 2, "lo,hi")
    return _check_range(name, lo, hi, str(text))


def _check_range(name: str, lo: float, hi: float, shown: str) -> tuple[float, float]:
    if not lo < hi:
        raise ParameterError(f"{name} needs lo < hi, got {shown[:40]!r}")
    if max(abs(lo), abs(hi)) > MAX_MAGNITUDE:
        raise ParameterError(f"{name} must lie within ±{MAX_MAGNITUDE:g}, got {shown[:40]!r}")
    return lo, hi


def _plot_number(name: str, v: Any) -> float:
    # An event's value comes from the client as any JSON: text, lists, booleans and NaN are no coordinate.
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ParameterError(f"{name} must be a finite number, got {str(v)[:40]!r}")
    return float(v)


def plot_point(x: Any, y: Any) -> tuple[float, float]:
    """A point clicked in the (q, r) plot as a page sends it: finite numbers within the view's bounds.

    Raises
    ------
    ParameterError
        Naming the bad value (what no pointer gives: text, NaN, a coordinate beyond ±MAX_MAGNITUDE).
    """
    q, r = _plot_number("q", x), _plot_number("r", y)
    if max(abs(q), abs(r)) > MAX_MAGNITUDE:
        raise ParameterError(f"a clicked point must lie within ±{MAX_MAGNITUDE:g}, got ({q:g}, {r:g})")
    return q, r


def plot_view(x0: Any, x1: Any, y0: Any, y1: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    """The plot's window after a pan or zoom, checked as the URL's ``qr`` and ``rr`` are.

    Raises
    ------
    ParameterError
        Naming the bad range (not numbers, lo >= hi, beyond ±MAX_MAGNITUDE).
    """
    q = [_plot_number("qr", v) for v in (x0, x1)]
    r = [_plot_number("rr", v) for v in (y0, y1)]
    return _check_range("qr", *q, f"{q[0]:g},{q[1]:g}"), _check_range("rr", *r, f"{r[0]:g},{r[1]:g}")


def _optional_point(name: str, text: str) -> tuple[float, ...]:
    if not str(text).strip():
        return ()
    q, r = _numbers(name, text, 2, "q,r")
    if max(abs(q), abs(r)) > MAX_MAGNITUDE:
        raise ParameterError(f"{name} must lie within ±{MAX_MAGNITUDE:g}, got {str(text)[:40]!r}")
    return q, r


#: The value of ``selected`` when no trajectory is selected (``sel=none`` in the URL): nothing is ringed in the plot
#: and the k-series are empty, saying why.
NO_SELECTION = -1
#: How "no trajectory" is typed and shown (the box, the URL).
NONE_WORD = "none"


def _selection(name: str, text: str) -> int:
    """The selected trajectory: a number, or blank / 'none' for no trajectory (:data:`NO_SELECTION`)."""
    if text.strip().lower() in ("", NONE_WORD):
        return NO_SELECTION
    return _whole(name, text, 0, MAX_RANDOM + MAX_CLICKED)


def _optional_number(name: str, text: str) -> tuple[float, ...]:
    """A number, or () when blank (a played range's end: blank is the slider's value ∓ a step of the range)."""
    if not str(text).strip():
        return ()
    v = _finite(name, str(text).strip())
    if abs(v) > MAX_MAGNITUDE:
        raise ParameterError(f"{name} must lie within ±{MAX_MAGNITUDE:g}, got {str(text)[:40]!r}")
    return (v,)


def _optional_range(name: str, text: str) -> tuple[float, ...]:
    return _range(name, text) if str(text).strip() else ()


def _grid(name: str, text: str) -> tuple[int, int]:
    parts = str(text).split(",")
    if len(parts) != 2:
        raise ParameterError(f"{name} needs two whole numbers NX,NY, got {str(text)[:40]!r}")
    nx, ny = (_whole(name, p, 2, LIMITS["grid"]) for p in parts)
    return nx, ny


_SCENES = tuple((s.id, f"{s.figure}: {s.title}") for s in list_scenes())
_PARAM_OPTIONS = tuple((p, p) for p in SWEEPABLE)
LABELS = {
    "alpha": "α (constraint p − g q = α)",
    "g0": "g0  (g = g0 + g1 cos Ωt + g2 sin Ωt)",
    "omega": "Ω (forcing frequency)",
    "t0": "t0 (section phase)",
}

#: What the layers declare (app.layers.base.Layer): their controls, their modes of "Click in the plot", the state
#: they keep without a control and their URL keys beyond their controls'.
LAYER_CONTROLS: tuple[Control, ...] = tuple(c for layer in LAYERS for c in layer.controls)
CLICK_MODES: tuple[tuple[str, str], ...] = tuple((a.name, a.label) for layer in LAYERS for a in layer.actions
                                                  if a.click)  # fmt: skip
LAYER_PICKS: dict[str, param.Parameter] = {n: p for layer in LAYERS for n, p in layer.picks.items()}
LAYER_URLS: tuple[UrlKey, ...] = tuple(u for layer in LAYERS for u in layer.urls)

CONTROLS: tuple[Control, ...] = (
    Control(
        "scene",
        "Scene (the paper's figures)",
        "select",
        "scene",
        "scene",
        options=(("custom", "custom"), *_SCENES),
        default=DEFAULT_SCENE,
        doc="paper scene the view started from ('custom' once edited)",
    ),
    *(
        Control(
            f,
            LABELS.get(f, f),
            "float",
            "inertia" if f in INERTIA_NAMES else "forcing",
            f,
            SLIDER_RANGES[f][:2],
            SLIDER_RANGES[f][2],
            default=SYSTEM_DEFAULTS[f],
        )
        for f in SYSTEM_FIELDS
    ),
    Control(
        "method",
        "Method",
        "select",
        "numerics",
        "method",
        options=(
            ("dop853", "DOP853 (8th order)"),
            ("vern9", "Verner 9(8)"),
            ("auto", "auto: Verner 9(8) at tolerances 1e-9..1e-13, else DOP853"),
            ("dp5", "Dormand–Prince 5(4)"),
            ("rk4", "RK4, fixed steps"),
        ),
        help="Verner 9(8) takes fewer steps than DOP853 at high accuracy; auto picks the one measured fastest at the "
        "tolerance in use (README, performance), for every computation of the page.",
        # auto, as the command line: the page's method reaches every computation (the Lyapunov spectrum at 1e-10,
        # the orbit diagram at 1e-9 run vern9, the sections at plot tolerances DOP853).
        default="auto",
    ),
    Control(
        "accuracy",
        "Accuracy",
        "radio",
        "numerics",
        "accuracy",
        options=(("plot", "plot"), ("high", "high")),
        help="plot: tolerance tied to the pixel size (error under a quarter pixel on regular orbits); "
        "high: tolerance 1e-12.",
        default="plot",
    ),
    _ints("steps_per_period", "RK4 steps per period", "numerics", "steps", 8, 20000, 200),
    _ints("n_random", "Random initial conditions", "numerics", "n", 0, MAX_RANDOM, 60),
    _ints("seed", "Random seed", "numerics", "seed", 0, 2**31 - 1, 1),
    _ints("periods", "Periods (section points each)", "numerics", "periods", 1, MAX_PERIODS, 500),
    _ints("transient", "Transient periods (dropped)", "numerics", "transient", 0, MAX_TRANSIENT, 0),
    # The layers' own controls (app/layers: each layer declares its settings), in the order of the layers.
    *LAYER_CONTROLS,
    Control(
        "render",
        "Section drawn as",
        "radio",
        "layers",
        "render",
        options=(("auto", "auto"), ("points", "points"), ("density", "density")),
        help=f"points: pickable, coloured by trajectory (up to {MAX_POINTS:,}); density: an image of how many points "
        f"fall in each pixel, computed on the server (up to {MAX_DENSITY_POINTS:,}; zooming recomputes it for the "
        f"new view, seeds in the view); auto: points up to {MAX_POINTS:,}, density beyond.",
        default="auto",
        url_when="changed",
    ),
    Control(
        "click_mode",
        "Click in the plot",
        "radio",
        "section",
        "click",
        # Adding and selecting trajectories are the section's; the other modes are the layers' (their click actions).
        options=(("add", "adds a trajectory"), ("select", "selects a trajectory"), *CLICK_MODES),
        default="add",
        url_when=lambda s: s.click_mode not in ("add", "select"),  # the modes a shared link is about
    ),
    Control(
        "selected",
        "Trajectory shown in the k-series",
        "int",
        "section",
        "sel",
        (NO_SELECTION, MAX_RANDOM + MAX_CLICKED),
        parse=_selection,
        placeholder="none",
        default=0,
        doc="the trajectory ringed in the plot and drawn in the k-series ('none': no trajectory)",
    ),
    Control(
        "show_body",
        "Body in 3-D",
        "check",
        "body",
        "body",
        default=False,
        url_when="changed",
        doc="the rigid body of the selected trajectory turning, its axes, omega and an axis's trace (app/body.js)",
    ),
    # The body view's own settings (area "bodyview": drawn in the view's bar by app/body.js), in the URL while the
    # view is open and they differ from a new page's.
    Control(
        "body_speed",
        "Body: speed",
        "select",
        "bodyview",
        "body_v",
        options=tuple((v, f"{v} periods/s") for v in BODY_SPEEDS),
        default="0.25",
        url_when=lambda s: s.show_body and s.body_speed != "0.25",
        doc="periods of the body's motion shown per second of the animation",
    ),
    Control(
        "body_axis",
        "Body: axis traced",
        "select",
        "bodyview",
        "body_axis",
        options=(("1", "trace: axis 1"), ("2", "trace: axis 2"), ("3", "trace: axis 3")),
        default="3",
        url_when=lambda s: s.show_body and s.body_axis != "3",
        doc="the principal axis (1: smallest moment .. 3: largest) whose trace on the unit sphere is drawn",
    ),
    Control(
        "body_shape",
        "Body: drawn as",
        "select",
        "bodyview",
        "body_shape",
        options=(("box", "box"), ("ellipsoid", "ellipsoid")),
        default="box",
        url_when=lambda s: s.show_body and s.body_shape != "box",  # 'box' on a tensor no box has: a new page's too
        doc="the uniform box with the principal moments (when a rigid body has them) or the inertia ellipsoid",
    ),
    Control(
        "lyap_ic",
        "Initial condition q,r (blank: the selected trajectory's last point)",
        "text",
        "lyapunov",
        "ly_ic",
        parse=_optional_point,
        placeholder="selected trajectory",
        default=(),
        url_when="changed",
    ),
    _ints("lyap_transient", "Transient periods", "lyapunov", "ly_tr", 0, LIMITS["transient"], 200, url_when="changed"),
    _ints("lyap_periods", "Periods measured", "lyapunov", "ly_n", 10, LIMITS["lyap_periods"], 1000, url_when="changed"),
    _ints("lyap_ensemble", "Ensemble members", "lyapunov", "ly_m", 1, LIMITS["ensemble"], 4, url_when="changed"),
    Control(
        "bif_param",
        "Parameter",
        "select",
        "bifurcation",
        "bif_p",
        options=_PARAM_OPTIONS,
        default="alpha",
        url_when="changed",
    ),
    Control(
        "bif_range",
        "Range lo,hi (blank: current ± 0.05)",
        "text",
        "bifurcation",
        "bif_r",
        parse=_optional_range,
        placeholder="current ± 0.05",
        default=(),
        url_when="changed",
    ),
    _ints("bif_values", "Values", "bifurcation", "bif_n", 2, LIMITS["bif_values"], 120, url_when="changed"),
    _ints("bif_points", "Points per value", "bifurcation", "bif_pts", 1, LIMITS["bif_points"], 80, url_when="changed"),
    _ints("bif_transient", "Transient", "bifurcation", "bif_tr", 0, LIMITS["transient"], 300, url_when="changed"),
    Control(
        "bif_seeding",
        "Seeding",
        "radio",
        "bifurcation",
        "bif_seed",
        options=(("continuation", "continuation"), ("fixed", "fixed")),
        default="continuation",
        url_when="changed",
    ),
    Control(
        "bif_coord",
        "Plot",
        "radio",
        "bifurcation",
        "bif_xy",
        options=(("q", "q"), ("r", "r")),
        default="q",
        url_when="changed",
    ),
    Control(
        "bif_orbits",
        "Continued orbits over the diagram (stable solid, unstable dashed)",
        "check",
        "bifurcation",
        "bif_orb",
        default=True,
        url_when="changed",
        doc="continue the orbits near the diagram's attractors and draw them",
    ),
    Control(
        "chart_x", "x parameter", "select", "chart", "ch_x", options=_PARAM_OPTIONS, default="alpha", url_when="changed"
    ),
    Control(
        "chart_xrange", "x range", "text", "chart", "ch_xr", parse=_range, default=(-0.6, -0.4), url_when="changed"
    ),
    Control(
        "chart_y", "y parameter", "select", "chart", "ch_y", options=_PARAM_OPTIONS, default="I11", url_when="changed"
    ),
    Control("chart_yrange", "y range", "text", "chart", "ch_yr", parse=_range, default=(1.0, 2.0), url_when="changed"),
    Control("chart_grid", "grid NX,NY", "text", "chart", "ch_grid", parse=_grid, default=(40, 30), url_when="changed"),
    _ints("chart_periods", "Periods", "chart", "ch_n", 10, LIMITS["chart_periods"], 300, url_when="changed"),
    _ints("chart_transient", "Transient", "chart", "ch_tr", 0, LIMITS["transient"], 300, url_when="changed"),
    Control(
        "chart_curves",
        "Fold and period-doubling curves (continuation)",
        "check",
        "chart",
        "ch_curves",
        default=True,
        url_when="changed",
        doc="follow folds and period doublings in both chart parameters",
    ),
    Control(
        "bench_ic",
        "Initial condition q,r (blank: the selected trajectory's)",
        "text",
        "bench",
        "be_ic",
        parse=_optional_point,
        placeholder="selected trajectory",
        default=(),
        url_when="changed",
    ),
    _ints(
        "bench_periods",
        "Periods (longest horizon)",
        "bench",
        "be_n",
        2,
        LIMITS["bench_periods"],
        50,
        url_when="changed",
    ),
    # Play a parameter (app/play.py): one compact row over the section.
    Control(
        "play_param",
        "Play",
        "select",
        "play",
        "play",
        options=tuple((f, LABELS.get(f, f).split(" (")[0].split("  ")[0]) for f in SYSTEM_FIELDS),
        default="alpha",
        url_when=lambda s: s.play_param != "alpha" or bool(s.play_from or s.play_to),
        doc="the parameter played across a range",
    ),
    Control(
        "play_from",
        "from",
        "text",
        "play",
        "play_from",
        parse=_optional_number,
        placeholder="value − 0.05",
        default=(),
        url_when="changed",
    ),
    Control(
        "play_to",
        "to",
        "text",
        "play",
        "play_to",
        parse=_optional_number,
        placeholder="value + 0.05",
        default=(),
        url_when="changed",
    ),
    _ints("play_frames", "frames", "play", "play_n", 2, MAX_PLAY_FRAMES, 40, url_when="changed"),
    _ints("play_fps", "frames/s", "play", "play_fps", 1, MAX_PLAY_FPS, 8, url_when="changed"),
    Control(
        "play_dir",
        "direction",
        "radio",
        "play",
        "play_dir",
        options=(("forward", "→"), ("backward", "←"), ("bounce", "↔")),
        default="forward",
        url_when="changed",
    ),
)
BY_NAME: dict[str, Control] = {c.name: c for c in CONTROLS}
BY_URL: dict[str, Control] = {c.url: c for c in CONTROLS if c.url}


def plain_label(name: str) -> str:
    """The words a control shows for itself, without its parenthesised help: what messages call it
    ("Random initial conditions", not the attribute ``n_random``)."""
    c = BY_NAME.get(name)
    return c.label.split(" (")[0].strip() if c is not None else name


def _parameter(c: Control) -> param.Parameter:
    """The state's attribute of control ``c``, generated from its entry (bounds, options, default: one place)."""
    doc = c.doc or c.label
    if c.kind == "float":
        return param.Number(default=c.default, doc=doc)
    if c.kind == "int":
        return param.Integer(default=c.default, bounds=c.bounds, doc=doc)
    if c.kind == "check":
        return param.Boolean(default=c.default, doc=doc)
    if c.kind in ("select", "radio"):
        objects = [v for v, _ in c.options]
        if c.name == "scene":  # a scene's id from the URL is checked against the scenes (parse_control)
            return param.String(default=c.default, doc=doc)
        return param.Selector(default=c.default, objects=objects, doc=doc)
    return param.Parameter(default=c.default, doc=doc)  # text: a parsed tuple (() when blank)


class ExplorerState(param.Parameterized):
    """Control values in use of one session (the URL carries all of them).

    Every control's attribute is generated from :data:`CONTROLS` (below the class), and so are the layers' picks
    (:data:`LAYER_PICKS`: the state a layer keeps without a control); the fields declared here are the state that no
    control edits directly (the view, the clicked points, the open tab).
    """

    box = param.NumericTuple(default=(-3.0, 3.0, -5.0, 5.0), length=4, doc="random ICs box qmin,qmax,rmin,rmax")
    clicked = param.List(default=[], item_type=tuple, doc="initial conditions added by clicking")
    q_range = param.NumericTuple(default=(-3.5, 3.5), length=2)
    r_range = param.NumericTuple(default=(-5.5, 5.5), length=2)
    tab = param.Selector(default="section", objects=list(TABS))
    presentation = param.Boolean(default=False, doc="larger fonts, sidebar collapsed (for a projector)")
    tour = param.String(default="", doc="the guided tour shown (app/tours.json or tour_url), '' for none")
    tour_step = param.Integer(default=1, bounds=(1, MAX_TOUR_STEPS), doc="the tour's step shown, from 1")
    tour_url = param.String(default="", doc="a same-origin path of a teacher's own tours file")

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        #: The last system built (:meth:`system`) and the values it was built from.
        self._system: tuple[tuple[Any, ...], Params] | None = None
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
        if "sweep" in s.extra:
            values.update(bif_param=s.extra["sweep"]["param"], bif_range=tuple(s.extra["sweep"]["range"]))
        if "chart" in s.extra:
            c = s.extra["chart"]
            values.update(chart_x=c["x_param"], chart_y=c["y_param"], chart_xrange=tuple(c["x_range"]),
                          chart_yrange=tuple(c["y_range"]))  # fmt: skip
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
            selected=n if len(s.points) else 0,  # the scene's first own point (numbered after the random ones)
            **values,
        )

    @staticmethod
    def scene_ids() -> list[str]:
        return [s.id for s in list_scenes()]

    # --- requests ---------------------------------------------------------------------

    def system(self, **changes: float) -> Params:
        """The validated system (with ``changes``); raises ParameterError naming the bad value.

        Built once per set of values: the last one built is given again while the system's controls hold the values
        it was built from (every layer, the section and the page's checks ask for it after a move), and a new value
        of a system control builds a new one. A commit checks a value with ``changes`` and then sets it: the system
        checked is the one used.
        """
        v = {f: changes.get(f, getattr(self, f)) for f in SYSTEM_FIELDS}
        # -0.0 == 0.0, but the sign of a zero reaches the numbers: the key tells them apart
        key = tuple((x, math.copysign(1.0, x)) if isinstance(x, float) else x for x in v.values())
        if self._system is not None and self._system[0] == key:
            return self._system[1]
        params = Params(
            inertia=tuple(v[n] for n in INERTIA_NAMES), alpha=v["alpha"], g0=v["g0"], g1=v["g1"], g2=v["g2"],
            omega=v["omega"], t0=v["t0"],
        )  # fmt: skip
        self._system = (key, params)
        return params

    def pixel_size(self) -> float:
        return min(self.q_range[1] - self.q_range[0], self.r_range[1] - self.r_range[0]) / PLOT_PIXELS[0]

    def numerics(self, bound: float | None = None) -> Numerics:
        """The section's method and tolerance; 'plot' ties the tolerance to a quarter pixel after all periods."""
        tol = plot_tolerance(self.pixel_size(), self.periods + self.transient)
        return self.numerics_for(None, plot_rtol=tol, bound=self.page_bound() if bound is None else bound)[0]

    def page_bound(self) -> float:
        """The escape bound of the page's computations: 100 times the view's extent, at least 1e3."""
        return max(1e3, 100.0 * max(abs(v) for v in (*self.q_range, *self.r_range)))

    def numerics_for(
        self, own: Numerics | None, *, plot_rtol: float | None = None, bound: float | None = None
    ) -> tuple[Numerics, str]:
        """The numerics a computation runs with under the page's Method and Accuracy, and why (the core's one
        rule, :func:`~explorer_core.solve.numerics.chosen_numerics`): ``own`` the computation's default,
        ``plot_rtol`` its picture's tolerance (None: not a picture), ``bound`` the escape bound (None: own's)."""
        return chosen_numerics(self.method, self.accuracy, own, plot_rtol=plot_rtol, bound=bound,
                               steps_per_period=self.steps_per_period)  # fmt: skip

    def initial_conditions(self) -> np.ndarray:
        """The seeded random ones first, then the clicked/scene points: a click never renumbers the random
        trajectories (the escaped list and the CSV's ids stay), the clicked ones are numbered from n_random."""
        parts = [np.zeros((0, 2))]
        if self.n_random:
            parts.append(random_ics(self.n_random, self.box, seed=self.seed))
        parts.append(np.array(self.clicked, dtype=float).reshape(-1, 2))
        return np.concatenate(parts)

    def analysis_ics(self) -> np.ndarray:
        """The initial conditions an analysis tab starts from: the clicked/scene points first (the user's or the
        figure's choice), then the random ones."""
        ics = self.initial_conditions()
        return np.concatenate([ics[self.n_random :], ics[: self.n_random]])

    def clicked_indices(self) -> range:
        """The trajectory numbers of the clicked/scene initial conditions (after the random ones)."""
        return range(self.n_random, self.n_random + len(self.clicked))

    def n_trajectories(self) -> int:
        return len(self.clicked) + self.n_random

    def density_view(self, n: int | None = None, periods: int | None = None, render: str | None = None) -> bool:
        """Whether the section is drawn as a density image (``render``, or ``auto`` beyond the point bound)."""
        render = render or self.render
        n = self.n_trajectories() if n is None else n
        periods = self.periods if periods is None else periods
        return render == "density" or (render == "auto" and n * periods > MAX_POINTS)

    def density_box(self) -> tuple[float, float, float, float]:
        """Where a density view's random seeds start: the box within the view (zoomed in: seeds in the
        view; the view holding the whole box again, e.g. zoomed out: the box, as before)."""
        b, v = self.box, (*self.q_range, *self.r_range)
        q0, q1, r0, r1 = max(b[0], v[0]), min(b[1], v[1]), max(b[2], v[2]), min(b[3], v[3])
        return (q0, q1, r0, r1) if (q0 < q1 and r0 < r1) else v  # type: ignore[return-value]

    def section_request(self) -> SectionRequest:
        """The section's computation, its spec built by the core's builder (the command line's:
        :func:`~explorer_core.analyses.sections.section_spec`, or
        :func:`~explorer_core.analyses.density.density_spec` for a density view)."""
        params = self.system()
        n = self.n_trajectories()
        if n == 0:
            raise ParameterError("no initial conditions: set 'Random initial conditions' above 0 or click in the plot")
        self.check_work(n, self.periods)
        clicked = np.array(self.clicked, dtype=float).reshape(-1, 2) if self.clicked else None
        if not self.density_view(n):
            spec = section_spec(params, self.periods, random=self.n_random or None, box=self.box, seed=self.seed,
                                ics=clicked, transient=self.transient, numerics=self.numerics())  # fmt: skip
            return SectionRequest(spec.params, spec.ics, spec.periods, spec.transient, spec.numerics, spec=spec)
        view = (*self.q_range, *self.r_range)
        numerics = self.numerics()  # "high" as for points; "plot": a quarter pixel over the density's window
        if self.accuracy != "high":
            numerics = density_numerics(view, DENSITY_PIXELS, numerics.bound, self.method)
        dspec = density_spec(params, self.periods, self.density_box(), random=self.n_random, seed=self.seed,
                             ics=clicked, transient=self.transient, view=view, pixels=PLOT_PIXELS,
                             numerics=numerics)  # fmt: skip
        ics = dspec.ics
        # Kept as points: the clicked trajectories (drawn), the selected one (ringed, its k-series) and the
        # first few, so that a selected trajectory lost in the transient can hand over to one with points.
        selected = (self.selected,) if self.selected != NO_SELECTION else ()
        keep = (*self.clicked_indices(), *selected, *range(min(ics.shape[0], 8)))
        return SectionRequest(params, ics, dspec.periods, dspec.transient, dspec.numerics, True, dspec.view,
                              tuple(sorted(set(keep))), spec=dspec)  # type: ignore[arg-type]  # fmt: skip

    def box_problem(self, **changes: float) -> str:
        """'' if a uniform box has the principal moments of the system (with ``changes``), else why none has (a
        tensor breaking the triangle inequality, e.g. the paper's diag(1, 2, 4)). An invalid system: ''."""
        try:
            moments = principal_axes(self.system(**changes))[0]
        except ParameterError:
            return ""
        if box_exists(moments):
            return ""
        m = ", ".join(f"{x:.4g}" for x in moments)
        return f"no uniform box has the principal moments {m} (a box needs I3 < I1 + I2)"

    def body_shape_used(self) -> str:
        """The body's drawing in use: the one chosen, the inertia ellipsoid when no box has the moments."""
        return "ellipsoid" if self.body_shape == "box" and self.box_problem() else self.body_shape

    def chart_range_around(self, name: str) -> tuple[float, float]:
        """A chart range for parameter ``name``: its value ± a tenth of its slider's span, narrowed until both
        ends are valid systems (e.g. a positive definite tensor)."""
        lo, hi, _ = SLIDER_RANGES[name]
        v = float(getattr(self, name))
        half = 0.1 * (hi - lo)
        for _ in range(20):
            ends = (round(max(lo, v - half), 6), round(min(hi, v + half), 6))
            try:
                for end in ends:
                    self.system(**{name: end})
            except ParameterError:
                half /= 2
                continue
            if ends[0] < ends[1]:
                return ends
            half /= 2
        return (v - 1e-3 * abs(v or 1), v + 1e-3 * abs(v or 1))

    def check_work(self, n: int, periods: int, render: str | None = None) -> None:
        if n * periods > MAX_DENSITY_POINTS:
            raise ParameterError(
                f"{n} trajectories x {periods} periods = {n * periods} points; "
                f"this server allows {MAX_DENSITY_POINTS} per view (as a density image): lower one of them"
            )
        if n * periods > MAX_POINTS and (render or self.render) == "points":
            raise ParameterError(
                f"{n} trajectories x {periods} periods = {n * periods} points; "
                f"this server allows {MAX_POINTS} per view drawn as points: lower one of them, or draw the "
                f"section as a density (up to {MAX_DENSITY_POINTS})"
            )

    # --- one gate for every value -----------------------------------------------------

    def check(self, name: str, value: Any) -> None:
        """Refuse (ParameterError) a parsed value that the rest of the state makes unusable."""
        if name in SYSTEM_FIELDS:
            self.check_runnable(name, value, self.system(**{name: value}))
        elif name in ("n_random", "periods"):
            n = len(self.clicked) + (value if name == "n_random" else self.n_random)
            self.check_work(max(1, n), value if name == "periods" else self.periods)
        elif name == "render":
            self.check_work(max(1, self.n_trajectories()), self.periods, value)
        elif name == "selected" and value >= max(1, self.n_trajectories()):
            raise ParameterError(
                f"{plain_label(name)} must be a trajectory 0..{self.n_trajectories() - 1}, got {value}"
            )
        elif name == "body_shape" and value == "box" and self.box_problem():
            raise ParameterError(f"{plain_label(name)} = box: {self.box_problem()}")
        elif name in ("play_from", "play_to") and value:
            try:
                self.system(**{self.play_param: value[0]})
            except ParameterError as exc:
                raise ParameterError(f"{self.play_param} = {value[0]:g} is not a valid system: {exc}") from None
        elif name in ("bif_range", "chart_xrange", "chart_yrange") and value:
            p = {"bif_range": self.bif_param, "chart_xrange": self.chart_x, "chart_yrange": self.chart_y}[name]
            for end in value:  # the set of valid values of one parameter is an interval: its ends suffice
                try:
                    self.system(**{p: end})
                except ParameterError as exc:
                    raise ParameterError(f"{p} = {end:g} at an end of the range is not a valid system: {exc}") from None

    def check_runnable(self, name: str, value: float, params: Params) -> None:
        """Refuse (ParameterError) the value ``value`` of ``name`` when its system ``params`` is one no trajectory of
        the page can run: the steps one period needs at every initial condition (the stability floor: the field's
        fastest rate times the period over the method's stability limit, :mod:`explorer_core.solve.stability`)
        exceed the step budget of the page's numerics, or the rates overflow double precision (alpha = 1e308).
        Every trajectory would stop unfinished after seconds of work; the value is refused with that reason."""
        lo, hi, _ = SLIDER_RANGES.get(name, (0.0, 0.0, 0.0))
        if lo <= value <= hi:  # the sliders' values are the model's (a slider's move costs nothing here)
            return
        numerics = self.numerics_for(None)[0]
        ics = self.initial_conditions()
        if not ics.shape[0] or not numerics.adaptive:
            return
        with np.errstate(all="ignore"):
            # 8 phases of the forcing: a lower floor than the 64 of the reliability check (never a refusal more)
            rho = spectral_rate(params, ics[:, 0], ics[:, 1], n_t=8)
            floor = float(np.min(rho)) * params.period / stability_interval(numerics.method)
        if math.isfinite(floor) and floor <= numerics.max_steps:
            return
        need = f"at least {math.ceil(floor):,} steps" if math.isfinite(floor) else "more steps than doubles can count"
        raise ParameterError(
            f"{plain_label(name)} = {_fmt(value)} leaves the model nothing to compute: one period needs {need} at "
            f"every starting point, more than the step budget of {numerics.max_steps:,} (every trajectory would stop "
            f"unfinished). Choose a value nearer the slider's range"
        )

    # The URL table's words for the layers (app/layers cannot import this module: it imports them).

    def keys_of(self, fields: tuple[str, ...] | list[str]) -> tuple[str, ...]:
        """:func:`url_keys` of state fields."""
        return url_keys(fields)

    def words_of(self, key: str) -> str:
        """:func:`key_words` of a URL key."""
        return key_words(key)

    def to_query(self) -> dict[str, str]:
        """The full state as URL query parameters (short, human-readable): :data:`URL_KEYS`, in their order."""
        return {u.key: u.encode(self) for u in URL_KEYS if u.when(self)}

    def display(self, name: str) -> Any:
        """The value in use of a control as the page shows it (text; bool for a checkbox)."""
        if name == "body_shape":
            return self.body_shape_used()  # the ellipsoid when no box has the moments: what is drawn
        if name == "selected" and self.selected == NO_SELECTION:
            return NONE_WORD
        v = getattr(self, name)
        kind = BY_NAME[name].kind
        if kind == "check":
            return bool(v)
        if kind == "float":
            return _fmt(v)
        if kind == "text":
            return ",".join(str(x) if isinstance(x, int) else _fmt(x) for x in v)
        return str(v)


for _c in CONTROLS:
    ExplorerState.param.add_parameter(_c.name, _parameter(_c))
for _name, _p in LAYER_PICKS.items():
    ExplorerState.param.add_parameter(_name, _p)


# --- parsing --------------------------------------------------------------------------------------

_ID = re.compile(r"^[A-Za-z0-9_.-]{1,40}$")


def parse_control(name: str, text: Any, label: str | None = None) -> Any:
    """A control's text as its value; ParameterError naming the value when it is malformed or out of range.

    ``label`` names the value in messages (the control's own words, :func:`plain_label`; its name by default).
    """
    c = BY_NAME[name]
    label = label or name
    if isinstance(text, bool):
        text = "true" if text else "false"
    text = "" if text is None else str(text)
    if len(text) > MAX_TEXT:
        raise ParameterError(f"{label}: at most {MAX_TEXT} characters, got {len(text)}")
    t = text.strip()
    if c.kind == "int" and c.parse is not None:  # a number with words of its own (the selection's 'none')
        return c.parse(label, t)
    if c.kind in ("float", "int") and not t:
        raise ParameterError(f"{label} is empty: type a number")
    if c.kind == "float":
        return _finite(label, t)
    if c.kind == "int":
        lo, hi = c.bounds  # type: ignore[misc]
        return _whole(label, t, int(lo), int(hi))
    if c.kind == "check":
        if t.lower() not in ("true", "false", "1", "0"):
            raise ParameterError(f"{label} must be true or false, got {t[:40]!r}")
        return t.lower() in ("true", "1")
    if c.kind in ("select", "radio"):
        if name == "scene":
            if t == "custom":
                return t
            if not _ID.match(t):
                raise ParameterError("unknown scene")
            return get_scene(t).id
        values = [v for v, _ in c.options]
        if t not in values:
            raise ParameterError(f"{label} must be one of {', '.join(values)}, got {t[:40]!r}")
        return t
    return c.parse(label, t)  # type: ignore[misc]


def commit(state: ExplorerState, name: str, text: Any) -> str | None:
    """Apply a typed value if it can be used; otherwise leave the state as it is and say why.

    Returns None when applied, else a message naming the refused value and the value that stays in use.
    """
    if name not in BY_NAME:
        return f"unknown control {str(name)[:40]!r}"
    label = plain_label(name)
    try:
        value = parse_control(name, text, label)
        if name == "scene":
            if value != "custom" and value != state.scene:
                state.apply_scene(value)
            return None
        state.check(name, value)
    except ParameterError as exc:
        return f"{exc} — still using {label} = {_shown(state.display(name))}"
    if getattr(state, name) != value:
        if name in SYSTEM_FIELDS:
            state.param.update(**{name: value, "scene": "custom"})
        elif name in _RANGE_OF:
            # A new parameter on an axis: the old one's range means nothing for it (I11's 1..2 as a range of g0).
            state.param.update(**{name: value, _RANGE_OF[name]: state.chart_range_around(value)})
        else:
            setattr(state, name, value)
    return None


#: The chart's axis parameters and their ranges (a new parameter gets a range of its own).
_RANGE_OF = {"chart_x": "chart_xrange", "chart_y": "chart_yrange"}


def _shown(v: Any) -> str:
    return (v or "(blank)") if isinstance(v, str) else str(v)


# --- URL query parameters -------------------------------------------------------------------------


def query_value(query: Mapping[str, Any], key: str) -> str | None:
    """The text of URL parameter ``key`` (its last value; raw bytes decoded), None when the URL has none."""
    v = query.get(key)
    if v is None:
        return None
    if isinstance(v, list | tuple):
        v = v[-1] if v else ""
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    return str(v)


def parse_query(query: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Validated state updates from URL query parameters, and one message per bad value.

    A key that is not a setting is reported (with the nearest key, a typo's likely meaning) and
    ignored, except Bokeh's own (``bokeh-*``); a bad value is reported and left out (the rest
    still applies). Values are never echoed unescaped: callers show messages as text.
    Only the syntax and ranges are checked here; :func:`state_from_query` checks the values
    against each other (a positive-definite tensor, the work bound).
    """
    updates: dict[str, Any] = {}
    errors: list[str] = []

    def attempt(key: str, fn: Callable[[str], None]) -> None:
        text = query_value(query, key)
        if text is None:
            return
        try:
            fn(text)
        except ParameterError as exc:
            errors.append(f"URL parameter {key}: {exc}")

    for u in URL_KEYS:
        attempt(u.key, lambda t, u=u: updates.update(u.decode(t)))
    known = {u.key for u in URL_KEYS}
    for key in query:
        key = str(key)
        if key not in known and not key.startswith("bokeh-"):
            near = [k for k in sorted(known) if k.startswith(key.lower())] or difflib.get_close_matches(
                key.lower(), sorted(known), n=1, cutoff=0.6
            )
            hint = f" (did you mean {near[0]}?)" if near else ""
            errors.append(f"URL parameter {key[:40]!r} is not a setting of this page: ignored{hint}")
    return updates, errors


def _ALWAYS(s: ExplorerState) -> bool:
    return True


def _control_key(c: Control) -> UrlKey:
    """A control's URL parameter, generated from its entry: its text as shown (a checkbox 1/0), read back by
    :func:`parse_control` (the same gate as a typed value)."""

    def encode(s: ExplorerState) -> str:
        return str(int(getattr(s, c.name))) if c.kind == "check" else str(s.display(c.name))

    def changed(s: ExplorerState) -> bool:
        return getattr(s, c.name) != c.default

    when = {"always": _ALWAYS, "changed": changed}.get(c.url_when, c.url_when)  # type: ignore[arg-type]
    return UrlKey(c.url, (c.name,), encode, lambda t: {c.name: parse_control(c.name, t, plain_label(c.name))}, when,
                  plain_label(c.name))  # type: ignore[arg-type]  # fmt: skip


def _box(t: str) -> dict[str, Any]:
    if len(t) > MAX_TEXT:
        raise ParameterError(f"at most {MAX_TEXT} characters")
    return {"box": check_box(_numbers("box", t, 4, "qmin,qmax,rmin,rmax"))}


def _ics(text: str) -> dict[str, Any]:
    pts = [p for p in text.split(";") if p.strip()]
    if len(pts) > MAX_CLICKED:
        raise ParameterError(f"at most {MAX_CLICKED} initial conditions, got {len(pts)}")
    return {"clicked": [_optional_point("ics", p) for p in pts]}  # within ±MAX_MAGNITUDE, as a click is


def _tour_id(t: str) -> dict[str, Any]:
    if not _ID.match(t):
        raise ParameterError(f"a tour's id is letters, digits, '_', '.', '-' (at most 40), got {t[:40]!r}")
    return {"tour": t}


#: A teacher's tours file: a path on this server (never a URL of another site: nothing is fetched from outside).
_TOUR_PATH = re.compile(r"^/[A-Za-z0-9_./-]{1,200}\.json$")


def _tour_path(t: str) -> dict[str, Any]:
    if not _TOUR_PATH.match(t) or "//" in t or ".." in t:
        raise ParameterError(f"must be a path on this server ending in .json (e.g. /tours/mine.json), got {t[:60]!r}")
    return {"tour_url": t}


#: Every URL query parameter, the one place their keys are written: the controls' (generated from CONTROLS),
#: then the state that no control edits (the view, the clicked points, the layers' own keys, the tab).
URL_KEYS: tuple[UrlKey, ...] = (
    *(_control_key(c) for c in CONTROLS if c.url),
    UrlKey("box", ("box",), lambda s: ",".join(_fmt(v) for v in s.box), _box,
           words="box of the random initial conditions"),
    UrlKey("qr", ("q_range",), lambda s: ",".join(_fmt(v) for v in s.q_range),
           lambda t: {"q_range": _range("qr", t)}, words="q range"),
    UrlKey("rr", ("r_range",), lambda s: ",".join(_fmt(v) for v in s.r_range),
           lambda t: {"r_range": _range("rr", t)}, words="r range"),
    UrlKey("ics", ("clicked",), lambda s: _points_text(s.clicked), _ics, words="clicked initial conditions"),
    *LAYER_URLS,
    UrlKey("tab", ("tab",), lambda s: s.tab, _choice({t: {"tab": t} for t in TABS}), lambda s: s.tab != "section",
           "tab"),
    UrlKey("tour", ("tour",), lambda s: s.tour, _tour_id, lambda s: bool(s.tour), "tour"),
    UrlKey("step", ("tour_step",), lambda s: str(s.tour_step),
           lambda t: {"tour_step": _whole("step", t, 1, MAX_TOUR_STEPS)}, lambda s: bool(s.tour), "tour step"),
    UrlKey("tour_url", ("tour_url",), lambda s: s.tour_url, _tour_path, lambda s: bool(s.tour_url), "tours file"),
    UrlKey("present", ("presentation",), lambda s: "1",
           _choice({"1": {"presentation": True}, "0": {"presentation": False}}), lambda s: s.presentation,
           "presentation"),
)  # fmt: skip
#: A state field's URL key (the T′ map's two fields share one).
URL_OF: dict[str, str] = {f: u.key for u in URL_KEYS for f in u.fields}
_URL_BY_KEY: dict[str, UrlKey] = {u.key: u for u in URL_KEYS}


def key_words(key: str) -> str:
    """What a URL key is called in messages (a control's own words)."""
    u = _URL_BY_KEY.get(key)
    return u.words if u is not None and u.words else key


def url_keys(fields: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The URL keys of state fields, in order, each once: what a result computed from those fields depends on."""
    out: list[str] = []
    for f in fields:
        k = URL_OF[f]
        if k not in out:
            out.append(k)
    return tuple(out)


#: Order in which URL values meet the state's checks: what others are checked against comes first.
_ORDER = ("render", "clicked", "n_random", "periods", "bif_param", "chart_x", "chart_y")


def state_from_query(query: Mapping[str, Any]) -> tuple[ExplorerState, list[str]]:
    """A state for a new session: the scene named in the URL (or the default), then the URL's values.

    Every value goes through the same checks as a typed one: a value that makes the system invalid
    or the work too large is refused with a message and the scene's value stays in use.
    """
    updates, errors = parse_query(query)
    sid = updates.pop("scene", DEFAULT_SCENE)
    state = ExplorerState(scene=sid if sid != "custom" else DEFAULT_SCENE)
    names = sorted(updates, key=lambda n: _ORDER.index(n) if n in _ORDER else len(_ORDER))
    # The scene shows its own first point (numbered after the random ones): it stays shown if the URL changes n.
    scene_point = bool(state.clicked) and state.selected == state.n_random
    changed_system = False
    for name in names:
        value = updates[name]
        try:
            if name == "clicked":
                state.check_work(len(value) + state.n_random, state.periods)
            elif name in BY_NAME:
                state.check(name, value)
        except ParameterError as exc:
            kept = _shown(state.display(name)) if name in BY_NAME else "the scene's"
            errors.append(f"URL parameter {URL_OF.get(name, name)}: {exc}; using {plain_label(name)} = {kept}")
            continue
        changed_system |= name in SYSTEM_FIELDS and float(value) != float(getattr(state, name))
        setattr(state, name, value)
    if sid == "custom" or changed_system:
        state.scene = "custom"
    if scene_point and "selected" not in updates and state.clicked:
        state.selected = state.n_random
    if state.selected >= max(1, state.n_trajectories()):
        state.selected = 0
    return state, [_with_value_used(state, e) for e in errors]


def _with_value_used(state: ExplorerState, message: str) -> str:
    """A URL error that does not yet say which value is used instead, saying it (the scene's or the default)."""
    key = message.removeprefix("URL parameter ").split(":", 1)[0]
    c = BY_URL.get(key)
    if c is None or "; using " in message:
        return message
    return f"{message}; using {plain_label(c.name)} = {_shown(state.display(c.name))}"
