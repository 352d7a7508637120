"""The paper's figures as data (``scenes.json``), and what each needs to compute.

A scene fixes the system (inertia, alpha, forcing, section phase), the plot
window, suggested initial conditions, how many periods to show and which views
it needs (``section``, ``critical``, ``tprime``, ``series``, ``bifurcation``,
``chart``). It computes only what it shows, at the accuracy the picture needs:
:meth:`Scene.numerics` ties the tolerance to the size of a pixel in the plot
window; :meth:`Scene.numerics` with ``accuracy="high"`` is the explicit choice
for long runs or quantitative work.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import numpy as np

from explorer_core import config
from explorer_core.solve.numerics import Numerics, check_box, random_ics
from explorer_core.system.params import ParameterError, Params

#: Pixels across a plot: the resolution the "plot" accuracy is tied to.
PLOT_PIXELS = 800
VIEWS = ("section", "critical", "tprime", "series", "bifurcation", "chart")


@dataclass(frozen=True)
class Scene:
    """One figure of the paper as computable data."""

    id: str
    figure: str
    title: str
    shows: str
    params: Params
    q_range: tuple[float, float]
    r_range: tuple[float, float]
    box: tuple[float, float, float, float]
    n_random: int
    seed: int
    points: tuple[tuple[float, float], ...]
    periods: int
    transient: int
    views: tuple[str, ...]
    bound: float
    extra: dict[str, Any] = field(default_factory=dict)

    def initial_conditions(self) -> np.ndarray:
        """The scene's explicit points followed by its seeded random ones."""
        parts = [np.array(self.points, dtype=float).reshape(-1, 2)]
        if self.n_random:
            parts.append(random_ics(self.n_random, self.box, seed=self.seed))
        return np.concatenate(parts)

    def pixel_size(self, pixels: int = PLOT_PIXELS) -> float:
        """Data units per pixel along the narrower axis of the plot window."""
        return pixel_size((*self.q_range, *self.r_range), pixels)

    def numerics(self, periods: int | None = None, accuracy: str = "plot", pixels: int = PLOT_PIXELS) -> Numerics:
        """Integration settings for this scene: ``"plot"`` (:func:`plot_tolerance`) or ``"high"`` (1e-12).

        On chaotic orbits pointwise error grows anyway; the picture is then right in the
        shadowing sense, and ``"high"`` is the explicit choice for quantitative work.
        """
        if accuracy == "high":
            return Numerics(rtol=1e-12, atol=1e-12, bound=self.bound)
        if accuracy == "plot":
            return plot_numerics((*self.q_range, *self.r_range), periods or self.periods + self.transient, self.bound,
                                 pixels)  # fmt: skip
        raise ParameterError(f"accuracy must be 'plot' or 'high', got {accuracy!r}")

    def as_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "figure": self.figure,
            "title": self.title,
            "shows": self.shows,
            "params": self.params.as_dict(),
            "q_range": list(self.q_range),
            "r_range": list(self.r_range),
            "ics": {"random": self.n_random, "box": list(self.box), "seed": self.seed, "points": self.points},
            "periods": self.periods,
            "transient": self.transient,
            "views": list(self.views),
            "bound": self.bound,
            **self.extra,
        }


#: Pointwise error on regular orbits after k periods, in units of ``tol * k``, that the "plot"
#: tolerance assumes: calibrated on the paper's section scenes against solve_ivp
#: (``benchmarks/plot_accuracy.py``, docs/plot_accuracy.md). The worst orbits measured reach ~40-55
#: (fig5A, fig2C; 2-5 px off after 500 periods at 1e-6); 100 leaves a factor ~2 to spare.
PLOT_ERROR_PER_PERIOD = 100.0


def pixel_size(view: Sequence[float], pixels: int = PLOT_PIXELS) -> float:
    """Data units per pixel along the narrower axis of the window ``view = (q0, q1, r0, r1)``."""
    return min(view[1] - view[0], view[3] - view[2]) / pixels


def plot_numerics(view: Sequence[float], periods: int, bound: float, pixels: int = PLOT_PIXELS) -> Numerics:
    """A picture's numerics for the window ``view`` over ``periods`` periods (:func:`plot_tolerance`), escaping
    at ``bound``: the default rule's method (dop853 at plot tolerances)."""
    tol = plot_tolerance(pixel_size(view, pixels), periods)
    return Numerics(rtol=tol, atol=tol, bound=bound)


def plot_tolerance(pixel: float, periods: int) -> float:
    """DOP853 tolerance that keeps section points of regular orbits within a quarter pixel of the
    exact ones after ``periods`` periods (the error is a phase drift along the invariant curve,
    growing like k); clamped to [1e-12, 1e-6]."""
    n = max(1, int(periods))
    return min(1e-6, max(1e-12, 0.25 * float(pixel) / (PLOT_ERROR_PER_PERIOD * n)))


def _scene_from(d: dict[str, Any]) -> Scene:
    known = {"id", "figure", "title", "shows", "params", "q_range", "r_range", "ics", "periods", "transient"}
    known |= {"views", "bound"}
    views = tuple(d["views"])
    bad = [v for v in views if v not in VIEWS]
    if bad:
        raise ParameterError(f"scene {d['id']}: unknown views {bad}")
    ics = d["ics"]
    bound = float(d.get("bound", config.DEFAULT_ESCAPE_BOUND))
    return Scene(
        id=str(d["id"]),
        figure=str(d["figure"]),
        title=str(d["title"]),
        shows=str(d["shows"]),
        params=Params(
            inertia=tuple(d["params"]["inertia"]), **{k: v for k, v in d["params"].items() if k != "inertia"}
        ),
        q_range=(float(d["q_range"][0]), float(d["q_range"][1])),
        r_range=(float(d["r_range"][0]), float(d["r_range"][1])),
        box=check_box(ics["box"]),
        n_random=int(ics.get("random", 0)),
        seed=int(ics.get("seed", 0)),
        points=tuple((float(p[0]), float(p[1])) for p in ics.get("points", [])),
        periods=int(d["periods"]),
        transient=int(d.get("transient", 0)),
        views=views,
        bound=bound if math.isfinite(bound) else config.DEFAULT_ESCAPE_BOUND,
        extra={k: v for k, v in d.items() if k not in known},
    )


@cache
def _load() -> dict[str, Scene]:
    text = resources.files("explorer_core").joinpath("scenes.json").read_text()
    return {s.id: s for s in (_scene_from(d) for d in json.loads(text)["scenes"])}


def list_scenes() -> list[Scene]:
    """All scenes in the paper's order."""
    return list(_load().values())


def get_scene(scene_id: str) -> Scene:
    """The scene ``scene_id`` (case-insensitive); the error lists the valid ids."""
    scenes = _load()
    key = str(scene_id).strip()
    for sid, s in scenes.items():
        if sid.lower() == key.lower():
            return s
    # Echo only plain ids: the message may end up in a web page or a terminal.
    plain = re.fullmatch(r"[A-Za-z0-9_.-]{1,40}", key)
    shown = repr(key) if plain else f"(a {len(key)}-character name that is not an id)"
    raise ParameterError(f"unknown scene {shown}; available: {', '.join(scenes)}")
