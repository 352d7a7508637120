"""HoloViews pictures of the core's results: ``result.to_holoviews()`` in a notebook.

Importing this module registers a drawer per result class with :mod:`explorer_core.drawing` (so does the
package's entry point ``bilimovich_explorer.drawing = app.holo:register``). Each drawer returns a HoloViews
element or overlay in the app's colours, markers and words (the constants are the app's own, imported from
``app.views``, ``app.analyses`` and ``app.controller``); overlays compose with ``*``, layouts with ``+``::

    section.to_holoviews() * search.to_holoviews() * manifolds.to_holoviews()

The served page never imports this module (HoloViews is not part of a session's cost:
``tests/test_holo.py`` checks ``app.main``'s imports). Keyword options given to ``to_holoviews`` are
HoloViews options of the object returned (``width=``, ``height=``, ``title=``, ...); a few drawers take
their own (``coord=`` of the diagrams, ``max_points=`` of the point clouds), named in their docstrings.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Sequence
from typing import Any

import holoviews as hv
import holoviews.plotting.bokeh  # the bokeh backend's options, without a notebook's extension call
import numpy as np
from bokeh.palettes import Category10

from app.analyses import CHART_LEGEND, CURVE_STYLE, codim2_points, codim2_style, curve_dash
from app.layers.basins import BASIN_COLOURS, OUTCOME_COLOURS, OUTCOME_NAMES, attractor_words
from app.layers.frozen import segments_by_type
from app.layers.ftle import ftle_shown
from app.layers.orbits import orbit_row
from app.views import (
    BASIN_ALPHA,
    DENSITY_PALETTE,
    FTLE_PALETTE,
    MANIFOLD_COLOURS,
    N_COLORS,
    ORBIT_COLOUR,
    ORBIT_KIND,
    TPRIME_PALETTE,
    TRAJ_PALETTE,
    TYPE_COLORS,
    equilibrium_label,
    orbit_label,
)
from app.words import counted
from explorer_core import drawing
from explorer_core.analyses.basins import Basins
from explorer_core.analyses.bifurcation import OrbitDiagram
from explorer_core.analyses.continuation import Continuation
from explorer_core.analyses.continuation.results import CODIM2_NAMES
from explorer_core.analyses.density import Density
from explorer_core.analyses.equilibria import Equilibria, Tracks
from explorer_core.analyses.ftle import FtleMap
from explorer_core.analyses.indicators import VERDICTS, Birkhoff, Sali
from explorer_core.analyses.lyapunov import LyapunovResult
from explorer_core.analyses.manifolds import Manifolds
from explorer_core.analyses.orbits import Orbit, OrbitSearch
from explorer_core.analyses.regimes import REGIMES, Chart
from explorer_core.analyses.tprime import TPrimeMap
from explorer_core.solve.section import Section
from explorer_core.system.params import ParameterError

#: Points drawn one by one at most; above, HoloViews' ``rasterize`` when datashader is installed, else every
#: n-th point (the title says which). A browser draws ~2e5 WebGL points fluently.
MAX_POINTS = 200_000
HAS_DATASHADER = importlib.util.find_spec("datashader") is not None
#: Λ1 and Λ2 (the app's Lyapunov tab), the forward and backward sweeps of an orbit diagram.
PAIR_COLOURS = (Category10[3][0], Category10[3][1])
#: Continued branches as in the app's bifurcation tab: stable green, unstable grey dashed, bifurcations purple.
STABLE_COLOUR, UNSTABLE_COLOUR, BIFURCATION_COLOUR = "#2ca02c", "#7f7f7f", "#9467bd"
#: Chart colours: index 0 not computed, 1..16 period p, then the other regimes (the app's legend, in order).
CHART_NOT_DONE = "#eeeeee"
CHART_PALETTE = (CHART_NOT_DONE, *(c for _, c in CHART_LEGEND))
CHART_OTHER = ("quasi_periodic", "chaotic", "escaped", "failed", "invalid")
N_PERIOD_COLOURS = len(CHART_LEGEND) - len(CHART_OTHER)
SIZE = {"width": 640, "height": 480}
#: The indicators' verdicts: undecided grey, regular blue, chaotic red (indexed by the core's verdict codes).
VERDICT_COLOURS = ("#7f7f7f", "#1f77b4", "#d62728")


# ---------------------------------------------------------------------------
# Pieces shared by the drawers.


def _finish(obj: Any, opts: dict[str, Any]) -> Any:
    """The caller's HoloViews options applied to the object returned."""
    return obj.opts(**opts) if opts else obj


def _check_max_points(max_points: Any) -> int:
    if isinstance(max_points, bool) or not isinstance(max_points, int | np.integer) or max_points < 1:
        raise ParameterError(f"max_points must be a positive integer, got {max_points!r}")
    return int(max_points)


def thin(n: int, max_points: int) -> tuple[np.ndarray, int]:
    """Indices of the points drawn of ``n``: all, or every ``stride``-th (the stride is returned)."""
    stride = max(1, math.ceil(n / max_points))
    return np.arange(0, n, stride), stride


def _many(points: hv.Points, n: int, stride: int, what: str) -> tuple[hv.Element, str]:
    """A point cloud above :data:`MAX_POINTS`: rasterised with datashader, else thinned; and the words saying so."""
    if stride == 1:
        return points, ""
    if HAS_DATASHADER:  # pragma: no cover - datashader is not a dependency of the project
        from holoviews.operation.datashader import rasterize

        return rasterize(points).opts(cmap=list(DENSITY_PALETTE), cnorm="log"), f" ({n} {what}, rasterised)"
    return points, f" (every {stride}th of {n} {what} drawn)"


def mu_text(mu: Sequence[complex]) -> str:
    """Multipliers as the app's hover writes them (``orbit_row``'s words)."""
    parts = [f"{m.real:.5g}{m.imag:+.5g}i" if abs(m.imag) > 1e-12 else f"{m.real:.6g}" for m in mu]
    return ", ".join(parts) + f"  (|μ| {abs(mu[0]):.4g}, {abs(mu[1]):.4g})"


def _image_bounds(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Bounds ``(x0, y0, x1, y1)`` of an image whose pixels are centred on the grid ``x`` by ``y``."""
    dx = (x[-1] - x[0]) / max(1, x.size - 1)
    dy = (y[-1] - y[0]) / max(1, y.size - 1)
    return float(x[0] - dx / 2), float(y[0] - dy / 2), float(x[-1] + dx / 2), float(y[-1] + dy / 2)


# ---------------------------------------------------------------------------
# The (q, r) plane.


def draw_section(s: Section, *, max_points: int = MAX_POINTS, **opts: Any) -> hv.Element:
    """The section's points coloured by trajectory (the app's 20 colours, ``traj % 20``); hover: trajectory, k, q, r."""
    max_points = _check_max_points(max_points)
    traj, k, q, r = s.long()
    idx, stride = thin(traj.size, max_points)
    # The colour of each point as the app's mapper gives it (palette[traj % 20]), as data: a mapper over a
    # column of one value (one trajectory) would draw nothing.
    colour = np.asarray(TRAJ_PALETTE)[traj[idx] % N_COLORS]
    data = {"q": q[idx], "r": r[idx], "traj": traj[idx], "k": k[idx], "colour": colour}
    pts = hv.Points(data, kdims=["q", "r"], vdims=["traj", "k", "colour"], label="section points")
    pts = pts.opts(color="colour", size=2.6, line_color=None, fill_alpha=0.9, tools=["hover"], show_legend=False,
                   hover_tooltips=[("trajectory", "@traj"), ("k", "@k"), ("q, r", "@q, @r")], **SIZE)  # fmt: skip
    elem, note = _many(pts, traj.size, stride, "points")
    lost = [f"{n} {lab}" for lab, n in zip(*np.unique(s.status_labels(), return_counts=True), strict=True)
            if lab != "ok"]  # fmt: skip
    title = f"Poincaré section: {counted(traj.size, 'point')} of {counted(s.n, 'trajectory')}{note}"
    if lost:
        title += f"; {', '.join(lost)}"
    if not s.completed:
        title += " (stopped)"
    return _finish(elem.opts(title=title), opts)


def draw_density(d: Density, **opts: Any) -> hv.Image:
    """Section points per pixel (log colour scale, empty pixels transparent), the app's density palette."""
    q0, q1, r0, r1 = (float(v) for v in d.view)
    image = np.where(d.counts > 0, d.counts, np.nan).astype(float)
    # HoloViews' row 0 is the top of the image; the density's row 0 is r0, the bottom.
    img = hv.Image(np.flipud(image), bounds=(q0, r0, q1, r1), kdims=["q", "r"],
                   vdims=[hv.Dimension("count", label="section points per pixel")])  # fmt: skip
    title = f"Density: {d.in_view} of {d.points} section points in view, {d.done_periods}/{d.total_periods} periods"
    if d.escaped or d.failed:
        title += f"; {d.escaped} escaped, {d.failed} failed"
    img = img.opts(cmap=list(DENSITY_PALETTE), logz=True, clim=(1, max(2.0, float(d.counts.max()))), colorbar=True,
                   clabel="section points per pixel (log scale)", tools=["hover"], title=title, **SIZE)  # fmt: skip
    return _finish(img, opts)


def _equilibria_points(q: np.ndarray, r: np.ndarray, types: Sequence[str], eig: np.ndarray) -> hv.Overlay:
    layers = []
    for kind in dict.fromkeys(types):
        m = np.array([t == kind for t in types])
        data = {"q": q[m], "r": r[m], "type": [kind] * int(m.sum()),
                "eigenvalues": [mu_text(e).split("  ")[0] for e in eig[m]]}  # fmt: skip
        pts = hv.Points(data, kdims=["q", "r"], vdims=["type", "eigenvalues"], label=equilibrium_label(kind))
        layers.append(pts.opts(marker="diamond", size=15, color=TYPE_COLORS.get(kind, "#000000"), line_color="black",
                               tools=["hover"], hover_tooltips=[("frozen-field equilibrium", "@type"),
                                                                ("eigenvalues", "@eigenvalues"),
                                                                ("q, r", "@q, @r")], **SIZE))  # fmt: skip
    return hv.Overlay(layers)


def draw_equilibria(e: Equilibria, **opts: Any) -> hv.Overlay:
    """The frozen field's equilibria at ``t``: a diamond per point, one colour per type (the app's legend words)."""
    out = _equilibria_points(e.q, e.r, e.types, e.eigenvalues)
    title = f"Frozen-field equilibria at t = {e.t:.6g}"
    if e.degenerate:
        title += f" (degenerate: {e.message})"
    return _finish(out.opts(title=title), opts)


def track_segments(tr: Tracks) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """Each branch split where its type changes, as the app draws it (consecutive pieces share a sample)."""
    return segments_by_type(tr.branches())


def draw_tracks(tr: Tracks, **opts: Any) -> hv.Overlay:
    """Equilibrium tracks over one period, dashed, coloured by type where they run."""
    segments = track_segments(tr)
    layers = []
    for kind in dict.fromkeys(s[2] for s in segments):
        paths = [{"q": q, "r": r, "type": kind} for q, r, t in segments if t == kind]
        path = hv.Path(paths, kdims=["q", "r"], vdims=["type"], label=f"{equilibrium_label(kind)} (track)")
        layers.append(path.opts(color=TYPE_COLORS.get(kind, "#000000"), line_width=1.6, alpha=0.7, line_dash="dashed",
                                show_legend=True,
                                **SIZE))  # fmt: skip
    title = f"Equilibrium tracks over t ∈ [{tr.t_start:.4g}, {tr.t_start + tr.period:.4g}]: {tr.n_branches} branches"
    if tr.lost:
        title += "; " + "; ".join(loss.line() for loss in tr.lost)
    return _finish(hv.Overlay(layers).opts(title=title), opts)


def tprime_title(m: TPrimeMap) -> str:
    """The colour bar's words (the app's)."""
    if m.kind == "per-period":
        return "ΔT over a period: red gain, blue loss"
    return f"T′ at t = {m.t:.6g}: red energy gain, blue loss"


def draw_tprime(m: TPrimeMap, **opts: Any) -> hv.Image:
    """T' (or ΔT over a period) on its grid: red gain, blue loss, symmetric about 0; cells not computed blank."""
    values = np.where(m.ok, m.values, np.nan)
    finite = np.abs(m.values[m.ok])
    lim = float(np.percentile(finite, 98)) if finite.size else 1.0
    lim = lim or 1.0
    img = hv.Image(np.flipud(values), bounds=_image_bounds(m.q, m.r), kdims=["q", "r"],
                   vdims=[hv.Dimension("value", label="T′" if m.kind == "instantaneous" else "ΔT")])  # fmt: skip
    failed = int((~m.ok).sum())
    title = tprime_title(m) + (f" ({failed} cells not computed)" if failed else "")
    img = img.opts(cmap=list(TPRIME_PALETTE), clim=(-lim, lim), alpha=0.55, colorbar=True, clabel=tprime_title(m),
                   tools=["hover"], title=title, **SIZE)  # fmt: skip
    return _finish(img, opts)


def draw_ftle(m: FtleMap, **opts: Any) -> hv.Element:
    """The FTLE map (the app's palette: dark islands, light chaotic sea), pixels without an exponent (escaped,
    failed, not computed) transparent and counted in the title; forward and backward side by side when both ran."""
    images = []
    for d, values, status in m.maps():
        shown, missing = ftle_shown(values, status)
        img = hv.Image(np.flipud(shown), bounds=_image_bounds(m.q, m.r), kdims=["q", "r"],
                       vdims=[hv.Dimension("ftle", label="FTLE (per unit time)")])  # fmt: skip
        title = f"FTLE {d} over {m.spec.periods} periods ({m.q.size} x {m.r.size} pixels)"
        title += f"; no exponent: {missing}" if missing else ""
        title += "" if m.completed else " (stopped)"
        images.append(img.opts(cmap=list(FTLE_PALETTE), colorbar=True, clabel=f"FTLE {d} (per unit time)",
                               tools=["hover"], title=title, **SIZE))  # fmt: skip
    return _finish(images[0] if len(images) == 1 else hv.Layout(images).cols(2), opts)


def _verdict_points(ics: Any, verdict: np.ndarray, extra: dict[str, Any], title: str) -> hv.Overlay:
    """Initial conditions coloured by verdict (one layer per verdict, for the legend), hover: ``extra``'s columns."""
    ics = np.asarray(ics, dtype=float).reshape(-1, 2)
    layers: list[Any] = []
    for code, name in enumerate(VERDICTS):
        sel = verdict == code
        if not sel.any():
            continue
        data = {"q": ics[sel, 0], "r": ics[sel, 1], **{k: np.asarray(v)[sel] for k, v in extra.items()}}
        pts = hv.Points(data, kdims=["q", "r"], vdims=list(extra), label=f"{name} ({int(sel.sum())})")
        layers.append(pts.opts(color=VERDICT_COLOURS[code], size=7, line_color="black", tools=["hover"], **SIZE))
    return hv.Overlay(layers).opts(title=title, legend_position="top_left")


def draw_birkhoff(b: Birkhoff, **opts: Any) -> hv.Overlay:
    """Each orbit's initial condition coloured by its verdict; hover: the digits of convergence, the rotation number
    of a regular orbit (-1: none) and the status."""
    rotation = np.where(b.has_rotation, b.rotation, -1.0)
    labels = np.array([str(lab) for lab in (row[7] for row in b.rows())])
    title = f"Weighted Birkhoff averages over 2 x {b.spec.periods} periods: " + ", ".join(
        f"{v} {n}" for v, n in b.summary()["verdicts"].items() if n)  # fmt: skip
    out = _verdict_points(b.spec.ics, b.verdict, {"digits": b.digits, "rotation": rotation, "status": labels}, title)
    return _finish(out, opts)


def draw_sali(s: Sali, **opts: Any) -> hv.Overlay:
    """SALI against the periods (log scale) along each orbit, coloured by its verdict: falling to 0 on chaos,
    staying finite or decaying by a power law on a regular orbit."""
    a = s.alignment
    layers: list[Any] = []
    shown: set[int] = set()
    for i in range(a.npts.size):
        n = int(a.npts[i])
        if not n:
            continue
        code = int(a.verdict[i])
        k = np.arange(1, n + 1)
        curve = hv.Curve({"k": k, "SALI": np.maximum(a.sali[i, :n], 1e-300), "orbit": np.full(n, i)}, kdims=["k"],
                         vdims=["SALI", "orbit"], label=VERDICTS[code] if code not in shown else "")  # fmt: skip
        layers.append(curve.opts(color=VERDICT_COLOURS[code], logy=True, show_legend=code not in shown,
                                 tools=["hover"], **SIZE))  # fmt: skip
        shown.add(code)
    counts = ", ".join(f"{v} {n}" for v, n in s.summary()["verdicts"].items() if n)
    out = hv.Overlay(layers).opts(title=f"SALI along {a.npts.size} orbits: {counts}")
    return _finish(out.redim.label(k="periods k"), opts)


# ---------------------------------------------------------------------------
# Periodic orbits and manifolds.


def _orbit_rows(orbits: Sequence[Orbit]) -> dict[str, dict[str, list]]:
    data: dict[str, dict[str, list]] = {k: {"q": [], "r": [], "mu": [], "period": [], "type": []}
                                        for k in ("saddle", "unstable", "stable")}  # fmt: skip
    for o in orbits:
        d = data[ORBIT_KIND.get(o.kind, "unstable")]
        mu = orbit_row(o)["mu"]
        for q, r in o.points:
            d["q"].append(float(q))
            d["r"].append(float(r))
            d["mu"].append(mu)
            d["period"].append(int(o.period))
            d["type"].append(o.kind)
    return data


#: Marker and fill per kind of orbit (the app's: filled yellow stable, open unstable, a cross for saddles).
ORBIT_MARKERS = {
    "saddle": ("x", "white", 0.0),
    "unstable": ("circle", "white", 0.85),
    "stable": ("circle", "#ffd21f", 1.0),
}
#: The hover: the multipliers first (they tell the kind of orbit).
ORBIT_TIPS = [("multipliers", "@mu"), ("periodic orbit of the map", "period @period, @type"), ("q, r", "@q, @r")]


def draw_orbits(orbits: Sequence[Orbit], title: str = "") -> hv.Overlay:
    """Every point of every orbit, one layer per marker kind, with a white halo under each marker."""
    layers = []
    for kind, d in _orbit_rows(orbits).items():
        if not d["q"]:
            continue
        marker, fill, alpha = ORBIT_MARKERS[kind]
        label = "; ".join(dict.fromkeys(orbit_label(t) for t in d["type"]))
        halo = hv.Points(d, kdims=["q", "r"], vdims=["mu", "period", "type"]).opts(
            marker=marker, size=15, line_color="white", line_width=6, fill_alpha=0.0, show_legend=False, **SIZE
        )
        pts = hv.Points(d, kdims=["q", "r"], vdims=["mu", "period", "type"], label=label).opts(
            marker=marker, size=15, line_color=ORBIT_COLOUR, line_width=2.5, fill_color=fill, fill_alpha=alpha,
            tools=["hover"], hover_tooltips=ORBIT_TIPS, **SIZE)  # fmt: skip
        layers += [halo, pts]
    return hv.Overlay(layers).opts(title=title) if title else hv.Overlay(layers)


def draw_orbit(o: Orbit, **opts: Any) -> hv.Overlay:
    """One periodic orbit of the map: its points, the marker of its kind, the multipliers in the hover."""
    return _finish(draw_orbits([o], f"Period-{o.period} orbit of the map ({o.kind}), μ = {mu_text(o.multipliers)}"),
                   opts)  # fmt: skip


def draw_orbit_search(s: OrbitSearch, **opts: Any) -> hv.Overlay:
    """The orbits found (the seeds that found none are counted in the title)."""
    title = f"{counted(len(s.orbits), 'periodic orbit')} of the map from {counted(s.seeds, 'seed')}"
    if s.failures:
        title += f"; {counted(len(s.failures), 'seed')} found none"
    return _finish(draw_orbits(s.orbits, title), opts)


def draw_manifolds(m: Manifolds, **opts: Any) -> hv.Overlay:
    """Unstable and stable manifolds of the saddle orbit, their crossings (black diamonds), the saddle's points."""
    layers: list[Any] = []
    for kind in ("unstable", "stable"):
        paths = [{"q": p[:, 1], "r": p[:, 2], "s": p[:, 0], "branch": b.piece_label(k)}
                 for b in m.branches if b.kind == kind for k, p in enumerate(b.pieces) if p.shape[0] > 1]  # fmt: skip
        if paths:
            path = hv.Path(paths, kdims=["q", "r"], vdims=["s", "branch"], label=f"{kind} manifold")
            layers.append(path.opts(color=MANIFOLD_COLOURS[kind], line_width=1.6, alpha=0.9, show_legend=True, **SIZE))
    if m.crossings:
        data = {"q": [c.q for c in m.crossings], "r": [c.r for c in m.crossings],
                "what": [f"{c.kind} point ({c.unstable} × {c.stable})" for c in m.crossings]}  # fmt: skip
        layers.append(hv.Points(data, kdims=["q", "r"], vdims=["what"], label="homoclinic/heteroclinic points").opts(
            marker="diamond", size=8, color="black", line_color="white", line_width=1, tools=["hover"],
            hover_tooltips=[("", "@what"), ("q, r", "@q, @r")], **SIZE))  # fmt: skip
    layers += list(draw_orbits([m.orbit]))
    title = f"Manifolds of the period-{m.orbit.period} saddle orbit (length {m.length:g})"
    if m.lost:
        title += "; " + "; ".join(loss.line() for loss in m.lost)
    return _finish(hv.Overlay(layers).opts(title=title), opts)


def basin_colours(b: Basins) -> dict[int, str]:
    """The app's colour of every label: attractors in the order found, then escape, failed, undecided."""
    colours = {a.id: BASIN_COLOURS[i % len(BASIN_COLOURS)] for i, a in enumerate(b.attractors)}
    colours.update(OUTCOME_COLOURS)
    return colours


def basin_words(b: Basins, a: Any) -> str:
    """The app's legend words for an attractor."""
    return f"{attractor_words(a)}: {100 * b.fraction.get(a.id, 0.0):.1f}%"


def draw_basins(b: Basins, **opts: Any) -> hv.Overlay:
    """The basins (pixels not yet computed show their coarser neighbour), translucent, and each attractor's points."""
    labels = b.filled()
    colours = basin_colours(b)
    codes = sorted(colours)
    # Pixels are coloured by their label's place in ``codes``; a label with no colour (not computed) stays blank.
    index = np.full(labels.shape, np.nan)
    for n, code in enumerate(codes):
        index[labels == code] = n
    q0, q1, r0, r1 = b.spec.box
    img = hv.Image((b.q, b.r, index, labels), kdims=["q", "r"], vdims=["colour", "basin"])
    img = img.opts(cmap=[colours[c] for c in codes], clim=(-0.5, len(codes) - 0.5), alpha=BASIN_ALPHA,
                   colorbar=False, tools=["hover"], hover_tooltips=[("basin", "@basin"), ("q, r", "$x, $y")],
                   **SIZE)  # fmt: skip
    layers: list[Any] = [img]
    for a in b.attractors:
        if a.kind == "escape" or not len(a.points):
            continue
        pts = hv.Points({"q": a.points[:, 0], "r": a.points[:, 1]}, kdims=["q", "r"], label=basin_words(b, a))
        layers.append(pts.opts(color=colours[a.id], line_color="black", size=6 if a.kind == "periodic" else 2,
                               **SIZE))  # fmt: skip
    shares = [f"{name}: {100 * b.fraction[c]:.1f}%" for c, name in OUTCOME_NAMES.items() if b.fraction.get(c, 0.0)]
    title = f"Basins of attraction ({int(b.computed.sum())}/{b.computed.size} pixels computed)"
    if shares:
        title += "; " + ", ".join(shares)
    return _finish(hv.Overlay(layers).opts(title=title, xlim=(q0, q1), ylim=(r0, r1)), opts)


# ---------------------------------------------------------------------------
# Parameter planes and convergence.


def draw_lyapunov(res: LyapunovResult, *, n: int = 400, **opts: Any) -> hv.Overlay:
    """Running estimates of Λ1 (blue) and Λ2 (orange) per member against the periods measured (about ``n``
    log-spaced of them), the ensemble means as horizontal lines; the title gives the spectrum and D_KY."""
    layers: list[Any] = []
    for i in range(res.ics.shape[0]):
        run = res.running(i)
        if not run.shape[0]:
            continue
        ks = np.unique(np.geomspace(1, run.shape[0], n).astype(int))
        first = i == 0
        for j, name in enumerate(("Λ1", "Λ2")):
            curve = hv.Curve({"k": ks, name: run[ks - 1, j], "member": np.full(ks.size, i)}, kdims=["k"],
                             vdims=[name, "member"], label=name if first else "")  # fmt: skip
            layers.append(curve.opts(color=PAIR_COLOURS[j], line_width=2 if first else 1, alpha=1 if first else 0.4,
                                     logx=True, show_legend=first, tools=["hover"], **SIZE))  # fmt: skip
    title = "Lyapunov exponents per unit time"
    if res.ok.any():
        l1, l2 = res.mean()
        for j, v in enumerate((l1, l2)):
            layers.append(hv.HLine(float(v)).opts(color=PAIR_COLOURS[j], line_dash="dotted", line_width=1))
        title += f": Λ = ({l1:.4g}, {l2:.4g}, 0), D_KY = {res.kaplan_yorke():.4g} ({int(res.ok.sum())} members)"
    lost = res.ics.shape[0] - int(res.ok.sum())
    if lost:
        title += f"; {lost} members did not complete ({', '.join(sorted(set(res.status_labels())))})"
    out = hv.Overlay(layers).opts(title=title)
    out = out.redim.label(k="measured periods k")
    return _finish(out, opts)


def _check_coord(coord: str) -> int:
    if coord not in ("q", "r"):
        raise ParameterError(f"coord must be 'q' or 'r', got {coord!r}")
    return 0 if coord == "q" else 1


def draw_orbit_diagram(d: OrbitDiagram, *, coord: str = "q", max_points: int = MAX_POINTS, **opts: Any) -> hv.Element:
    """Section points against the swept parameter: forward sweep blue, backward orange (the app's)."""
    c = _check_coord(coord)
    max_points = _check_max_points(max_points)
    s, _, value, ic, k, q, r = d.long()
    idx, stride = thin(s.size, max_points)
    y = (q, r)[c]
    backward = d.sweeps[s[idx]] == "backward"
    data = {d.param: value[idx], f"{coord}_k": y[idx], "sweep": d.sweeps[s[idx]].astype(str),
            "colour": np.asarray(PAIR_COLOURS)[backward.astype(int)], "ic": ic[idx], "k": k[idx]}  # fmt: skip
    pts = hv.Points(data, kdims=[d.param, f"{coord}_k"], vdims=["sweep", "colour", "ic", "k"], label="orbit diagram")
    pts = pts.opts(color="colour", size=1.6, line_color=None, show_legend=False, tools=["hover"], **SIZE)
    elem, note = _many(pts, s.size, stride, "points")
    n_lost = int((~d.drawn()).sum())
    title = f"Orbit diagram in {d.param} ({', '.join(str(v) for v in d.sweeps)}){note}"
    if n_lost:
        title += f"; {n_lost} trajectories not drawn ({', '.join(f'{n} {k}' for k, n in d.status_counts().items())})"
    return _finish(elem.opts(title=title), opts)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[lo, hi)`` runs of equal values of ``mask``, each extended by one sample so consecutive runs join."""
    out, lo = [], 0
    for i in range(1, mask.size + 1):
        if i == mask.size or mask[i] != mask[lo]:
            out.append((lo, min(i + 1, mask.size)))
            lo = i
    return out


def draw_continuation(c: Continuation, *, coord: str = "q", **opts: Any) -> hv.Overlay:
    """Branches against the parameter (stable green, unstable grey dashed) and the located bifurcations
    (purple diamonds); a two-parameter continuation draws its fold / period-doubling curves in the
    (parameter, parameter2) plane, in the chart's colours (overlay it on the chart)."""
    j = _check_coord(coord)
    if c.param2 is not None:
        return _finish(draw_curves(c), opts)
    stable_paths, unstable_paths = [], []
    for n, br in enumerate(c.branches):
        if len(br.values) < 2:
            continue
        x = np.array(br.values)
        y = np.array([s[j] for s in br.states])
        st = br.stable
        for lo, hi in _runs(st):
            seg = {c.param: x[lo:hi], f"{coord}": y[lo:hi], "branch": n, "period": br.period}
            (stable_paths if st[lo] else unstable_paths).append(seg)
    layers: list[Any] = []
    styles = ((unstable_paths, UNSTABLE_COLOUR, "dashed", 1.4, "unstable orbits"),
              (stable_paths, STABLE_COLOUR, "solid", 2.2, "stable orbits"))  # fmt: skip
    for paths, colour, dash, width, label in styles:
        if paths:
            layers.append(
                hv.Path(paths, kdims=[c.param, coord], vdims=["branch", "period"], label=label).opts(
                    color=colour, line_dash=dash, line_width=width, show_legend=True, **SIZE
                )
            )
    if c.bifurcations:
        data = {c.param: [b.value for b in c.bifurcations], coord: [float(b.point[j]) for b in c.bifurcations],
                "kind": [b.kind.replace("_", " ") for b in c.bifurcations],
                "period": [b.period for b in c.bifurcations],
                "mu": [mu_text(b.multipliers) for b in c.bifurcations],
                "error": [b.error for b in c.bifurcations]}  # fmt: skip
        layers.append(hv.Points(data, kdims=[c.param, coord], vdims=["kind", "period", "mu", "error"],
                                label="bifurcations").opts(
            marker="diamond", size=11, color=BIFURCATION_COLOUR, line_color="black", tools=["hover"],
            hover_tooltips=[("", "@kind of the period-@period orbit"), ("value", f"@{{{c.param}}}"),
                            ("multipliers", "@mu")], **SIZE))  # fmt: skip
    title = f"Continuation in {c.param}: {len(c.branches)} branches, {len(c.bifurcations)} bifurcations"
    if c.lost:
        title += "; " + "; ".join(loss.line() for loss in c.lost)
    return _finish(hv.Overlay(layers).opts(title=title), opts)


def curve_words(kind: str, period: int) -> str:
    """The app's hover words for a bifurcation curve."""
    words = CURVE_STYLE.get(kind, ("#7f7f7f", "grey", kind.replace("_", " ")))[2]
    return f"{words} of the period-{period} cycle"


def draw_curves(c: Continuation | Sequence[Continuation]) -> hv.Overlay:
    """Fold / period-doubling / Neimark-Sacker curves in the plane of the two parameters (a white halo under each;
    dashed by the cycle's period, :func:`app.analyses.curve_dash`) and their codimension-two points (a marker and
    colour per kind, :data:`app.analyses.CODIM2_STYLE`; each point once, :func:`app.analyses.codim2_points`); ``c``
    a two-parameter continuation or several (a chart's :class:`~explorer_core.analyses.continuation.Boundaries`)."""
    parts = [c] if isinstance(c, Continuation) else list(c)
    names = next(((p.param, p.param2) for p in parts if p.param2 is not None), ("p1", "p2"))
    layers: list[Any] = []
    curves = [curve for p in parts for curve in p.curves]
    for curve in curves:
        if len(curve.rows) < 2:
            continue
        rows = np.array(curve.rows)
        colour = CURVE_STYLE.get(curve.kind, ("#7f7f7f",))[0]
        words = curve_words(curve.kind, curve.period)
        data = {names[0]: rows[:, 0], names[1]: rows[:, 1], "curve": [words] * rows.shape[0]}
        layers.append(
            hv.Curve(data, kdims=[names[0]], vdims=[names[1], "curve"]).opts(
                color="white", line_width=5, alpha=0.8, show_legend=False, **SIZE
            )
        )
        layers.append(
            hv.Curve(data, kdims=[names[0]], vdims=[names[1], "curve"], label=words).opts(
                color=colour,
                line_width=2.2,
                line_dash=curve_dash(curve.period),
                tools=["hover"],
                hover_tooltips=[("curve", "@curve")],
                **SIZE,
            )
        )
    points = codim2_points(parts)
    for kind in dict.fromkeys(pt.kind for pt in points):
        these = [pt for pt in points if pt.kind == kind]
        marker, colour = codim2_style(kind)
        name = f"{kind} ({CODIM2_NAMES.get(kind, kind)})"
        data = {names[0]: [pt.values[0] for pt in these], names[1]: [pt.values[1] for pt in these],
                "point": [f"{name} of the period-{pt.period} orbit" for pt in these],
                "error": [pt.error for pt in these]}  # fmt: skip
        layers.append(hv.Points(data, kdims=list(names), vdims=["point", "error"], label=name).opts(
            marker=marker, size=13, color=colour, line_color="black", line_width=1.2, tools=["hover"],
            hover_tooltips=[("", "@point"), (names[0], f"@{{{names[0]}}}"), (names[1], f"@{{{names[1]}}}"),
                            ("error estimate", "@error")], **SIZE))  # fmt: skip
    title = f"Bifurcation curves in ({names[0]}, {names[1]}): {len(curves)}, {len(points)} codimension-two points"
    lost = [loss for p in parts for loss in p.lost]
    if lost:
        title += "; " + "; ".join(loss.line() for loss in lost)
    return hv.Overlay(layers).opts(title=title)


def chart_index(chart: Chart, ic: int = 0) -> np.ndarray:
    """``[j, i]`` colour index of the app's chart: 0 not computed, ``p`` a period-p cycle (16 and above share the
    last period colour), then quasi-periodic, chaotic, escaped, failed, invalid."""
    code = chart.code()[..., ic]
    idx = np.zeros(code.shape)
    per = code > 0
    idx[per] = np.minimum(code[per], N_PERIOD_COLOURS)
    for n, name in enumerate(CHART_OTHER):
        idx[code == -REGIMES.index(name)] = N_PERIOD_COLOURS + 1 + n
    idx[~chart.computed] = 0
    return idx


def draw_chart(chart: Chart, *, ic: int = 0, **opts: Any) -> hv.Image:
    """The chart of regimes of initial condition ``ic`` in the app's colours; hover: regime, period, Λ1."""
    if isinstance(ic, bool) or not isinstance(ic, int | np.integer) or not 0 <= ic < chart.spec.ics.shape[0]:
        raise ParameterError(f"ic must be an initial condition's index below {chart.spec.ics.shape[0]}, got {ic!r}")
    spec = chart.spec
    x, y = np.asarray(spec.x_values, float), np.asarray(spec.y_values, float)
    regime = np.array(REGIMES, dtype=object)[chart.regime[..., ic]]
    period, lyap = chart.measured()  # NaN (shown as such) where nothing was measured, never 0
    img = hv.Image((x, y, chart_index(chart, ic), regime, period[..., ic], lyap[..., ic]),
                   kdims=[spec.x_param, spec.y_param], vdims=["colour", "regime", "period", "Λ1"])  # fmt: skip
    title = f"Chart of regimes in ({spec.x_param}, {spec.y_param})"
    if chart.lost:
        title += "; " + "; ".join(loss.line() for loss in chart.lost)
    img = img.opts(cmap=list(CHART_PALETTE), clim=(-0.5, len(CHART_PALETTE) - 0.5), colorbar=False, tools=["hover"],
                   hover_tooltips=[("regime", "@regime"), ("period", "@period"), ("Λ1", "@{Λ1}"),
                                   (spec.x_param, "$x"), (spec.y_param, "$y")], title=title, **SIZE)  # fmt: skip
    return _finish(img, opts)


# ---------------------------------------------------------------------------
# Registration.

DRAWERS = {
    Section: draw_section,
    Density: draw_density,
    Equilibria: draw_equilibria,
    Tracks: draw_tracks,
    TPrimeMap: draw_tprime,
    LyapunovResult: draw_lyapunov,
    OrbitDiagram: draw_orbit_diagram,
    Continuation: draw_continuation,
    Chart: draw_chart,
    Orbit: draw_orbit,
    OrbitSearch: draw_orbit_search,
    Manifolds: draw_manifolds,
    Basins: draw_basins,
    FtleMap: draw_ftle,
    Birkhoff: draw_birkhoff,
    Sali: draw_sali,
}


def register() -> None:
    """Register every drawer with :mod:`explorer_core.drawing` (the entry point's target; importing does it too)."""
    for cls, fn in DRAWERS.items():
        drawing.register(cls, fn)


register()
