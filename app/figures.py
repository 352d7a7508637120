"""Figures as files: a tab's picture written as PNG or SVG at a chosen size and resolution, on the server.

The picture is the results' own drawing (:mod:`app.holo`, the HoloViews drawers of ``result.to_holoviews()``)
rendered by HoloViews' matplotlib backend: no browser, no webdriver, nothing loaded from the internet. The
drawers style for Bokeh (the page's look); :func:`matplotlib_look` carries those options over to matplotlib
(colours, markers, sizes, dashes, colour maps and limits), so the file shows the page's colours. The size is
exact (``width`` x ``height`` pixels at ``dpi``; an SVG is ``width/dpi`` x ``height/dpi`` inches) and the fonts
are set in points (:data:`FONT_PT`: 10 pt and more at any size), so a figure at 300 dpi reads as one at 100.

What a figure shows is said in it: its title (the tab's result, then the scene and the system's parameters)
and its metadata; a figure of a stopped run is named ``-partial`` as the data downloads are
(:func:`app.layers.base.named`) and its title says "stopped".

Imported only when a figure is asked for (HoloViews and matplotlib are no part of a session's cost).
"""

from __future__ import annotations

import io
import textwrap
import threading
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import holoviews as hv
import numpy as np

from app import holo
from app.analyses import BifurcationTab, ChartTab, LyapunovTab
from app.controls import SYSTEM_FIELDS
from app.layers.base import Download, named
from app.words import counted
from explorer_core.scenes import get_scene
from explorer_core.system.params import ParameterError

if TYPE_CHECKING:
    from app.analyses import AnalysisTab
    from app.controller import ExplorerSession

#: The file formats offered and their MIME types.
FORMATS = {"png": "image/png", "svg": "image/svg+xml"}
#: One figure drawn at a time in the server (HoloViews' option trees and matplotlib's font cache are shared by the
#: runner's threads): held while a picture is built and drawn.
DRAWING = threading.RLock()
#: Bounds of a figure's size (pixels) and resolution (dots per inch).
PIXELS = (200, 8000)
DPI = (50, 600)
#: Pixels of a figure at most (20 megapixels: ~80 MB while drawn), whatever its sides.
MAX_AREA = 20_000_000
#: Lines of the title at most, shared by its parts (what is shown, the settings; the whole title is in the file's
#: metadata).
TITLE_LINES = 4
#: Font sizes in points: title, axis labels, tick labels, legend (>= 10 pt at every size and resolution).
FONT_PT = {"title": 12, "labels": 12, "ticks": 10, "legend": 10}
#: A screen pixel of the page (96 per inch) in points (72 per inch): marker sizes and line widths carry over.
PT_PER_PX = 0.75
#: Parameter and coordinate names in the paper's notation (matplotlib's mathtext).
#: The same in plain text (a title's settings line, the file's metadata).
TEXT_SYMBOLS = {"alpha": "α", "omega": "Ω", "t0": "t₀", "g0": "g₀", "g1": "g₁", "g2": "g₂",
                **{f"I{i}{j}": f"I{'₀₁₂₃'[i]}{'₀₁₂₃'[j]}" for i in range(1, 4) for j in range(i, 4)}}  # fmt: skip
SYMBOLS = {
    "alpha": r"$\alpha$", "omega": r"$\Omega$", "t0": r"$t_0$", "g0": r"$g_0$", "g1": r"$g_1$", "g2": r"$g_2$",
    **{f"I{i}{j}": f"$I_{{{i}{j}}}$" for i in range(1, 4) for j in range(i, 4)},
    "q": "$q$", "r": "$r$", "q_k": "$q_k$", "r_k": "$r_k$", "k": "$k$",
}  # fmt: skip
#: Bokeh's names of markers and dashes, in matplotlib's.
_MARKERS = {"circle": "o", "diamond": "D", "square": "s", "triangle": "^", "inverted_triangle": "v", "cross": "+",
            "x": "x", "asterisk": "*", "star": "*", "hex": "h", "plus": "P", "dot": "."}  # fmt: skip
_DASHES = {"solid": "-", "dashed": "--", "dotted": ":", "dotdash": "-.", "dashdot": "-."}
#: Plot options that mean the same in both backends.
_SAME_PLOT = ("xlim", "ylim", "logx", "logy", "logz", "clim", "colorbar", "clabel", "show_legend", "xlabel", "ylabel")


@dataclass(frozen=True)
class FigureRequest:
    """A figure asked for: the format (``png``/``svg``), the size in pixels and the resolution."""

    fmt: str = "png"
    width: int = 1600
    height: int = 1000
    dpi: int = 200

    @property
    def inches(self) -> tuple[float, float]:
        return self.width / self.dpi, self.height / self.dpi


def parse_request(text: str) -> FigureRequest:
    """The page's ``"png 1600x1000 200"`` (format, width x height in pixels, dots per inch); "" is the default.
    Raises :class:`ParameterError` naming the value refused."""
    parts = text.split()
    if not parts:
        return FigureRequest()
    if len(parts) != 3 or parts[0].lower() not in FORMATS or parts[1].lower().count("x") != 1:
        raise ParameterError(f"figure: expected a format (png or svg), width x height and dpi, got {text[:60]!r}")
    w, h = parts[1].lower().split("x")
    values = {"width": w, "height": h, "dpi": parts[2]}
    out: dict[str, int] = {}
    for name, v in values.items():
        lo, hi = DPI if name == "dpi" else PIXELS
        if not v.strip().isdigit() or not lo <= int(v) <= hi:
            unit = "" if name == "dpi" else " pixels"
            raise ParameterError(f"figure {name} must be a whole number from {lo} to {hi}{unit}, got {v[:20]!r}")
        out[name] = int(v)
    if out["width"] * out["height"] > MAX_AREA:
        raise ParameterError(f"figure: {out['width']}x{out['height']} pixels is more than {MAX_AREA:,} in all "
                             "(choose a smaller size, or SVG: it scales to any size)")  # fmt: skip
    return FigureRequest(parts[0].lower(), **out)


# --- the pictures of the tabs -------------------------------------------------------------------------------


def section_picture(session: ExplorerSession, data: tuple[np.ndarray, ...] | None = None) -> tuple[Any, bool] | None:
    """The section plot's picture (its points coloured by trajectory, the basins under them, the manifolds and
    the periodic orbits over them) and whether its run was stopped; None when no point is on screen. ``data``: the
    points ``(traj, k, q, r)`` as read on the document thread (default: read now)."""
    sec = session.section
    traj, k, q, r = session.data() if data is None else data
    if not traj.size:
        return None
    done, total = sec.shown_periods or (0, 0)
    stopped = done < total
    n = max(int(traj.max()) + 1, sec.n_traj)
    lost = {i: "escaped" for i in session.escaped} | {i: "failed" for i in session.failed}
    points = _SectionPoints(traj, k, q, r, n, np.array([lost.get(i, "ok") for i in range(n)]), not stopped)
    layers: list[Any] = []
    basins = getattr(session.layers.get("basins"), "result", None)
    if basins is not None:
        layers.append(holo.draw_basins(basins))
    layers.append(holo.draw_section(points))  # type: ignore[arg-type]
    layers += [holo.draw_manifolds(m) for m in getattr(session.layers.get("manifolds"), "manifolds", [])]
    orbits = getattr(session.layers.get("orbits"), "orbits", [])
    if orbits:
        layers.append(holo.draw_orbits(orbits))
    head = f"Poincaré section: {counted(traj.size, 'point')} of {counted(n, 'trajectory')}"
    if stopped:
        head += f" (stopped after {done} of {total} periods)"
    if orbits:
        head += f", {counted(len(orbits), 'periodic orbit')}"
    obj = hv.Overlay([el for layer in layers for el in _elements(layer)]).opts(
        title=head, xlim=tuple(session.state.q_range), ylim=tuple(session.state.r_range))  # fmt: skip
    return obj, stopped


def tab_picture(tab: AnalysisTab) -> tuple[Any, bool] | None:
    """An analysis tab's main plot as on screen and whether its run was stopped; None before it has a result."""
    if isinstance(tab, LyapunovTab) and tab.result is not None:
        res = tab.result
        # the y axis is both exponents' (the page's words), not the first curve's
        return holo.draw_lyapunov(res).redim.label(**{"Λ1": "running estimate (per unit time)"}), not res.completed
    if isinstance(tab, BifurcationTab) and tab._data is not None:
        coord = tab.session.state.bif_coord
        d, cont = tab._data, tab._cont
        layers = [*_elements(holo.draw_orbit_diagram(d, coord=coord))]
        if cont is not None:
            layers += _elements(holo.draw_continuation(cont, coord=coord))
        title = _title_of(layers[0])
        stopped = not d.completed or (cont is not None and not cont.complete)
        return hv.Overlay(layers).opts(title=title), stopped
    if isinstance(tab, ChartTab) and tab.chart is not None:
        chart = tab.chart
        curves = _elements(holo.draw_curves(tab.boundaries)) if tab.boundaries else []
        layers = [holo.draw_chart(chart), *curves, *_chart_key(chart)]
        title = _title_of(layers[0])
        return hv.Overlay(layers).opts(title=title), not chart.completed
    return None


def _chart_key(chart: Any) -> list[Any]:
    """The chart's colour key as legend entries (the page draws it beside the plot): one square per colour shown."""
    shown = set(np.unique(holo.chart_index(chart)).astype(int).tolist())
    words = ["not computed", *(f"period {p}" if p.isdigit() else p for p, _ in holo.CHART_LEGEND)]
    return [hv.Points(([np.nan], [np.nan]), label=words[i]).opts(color=holo.CHART_PALETTE[i], marker="square", size=9,
                                                                 line_color="black", line_width=0.5)
            for i in sorted(shown)]  # fmt: skip


def _title_of(obj: Any) -> str:
    """The title a drawer gave ``obj``."""
    return str(hv.Store.lookup_options("bokeh", obj, "plot").kwargs.get("title", ""))


def _elements(obj: Any) -> list[Any]:
    """The elements of a drawing (an element, or the layers of an overlay)."""
    return list(obj) if isinstance(obj, hv.Overlay) else [obj]


@dataclass(frozen=True)
class _SectionPoints:
    """The section on screen as :func:`app.holo.draw_section` reads a :class:`~explorer_core.solve.section.Section`
    (the page keeps its points, not the core's result)."""

    traj: np.ndarray
    k: np.ndarray
    q: np.ndarray
    r: np.ndarray
    n: int
    labels: np.ndarray
    completed: bool

    def long(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.traj, self.k, self.q, self.r

    def status_labels(self) -> np.ndarray:
        return self.labels


def settings_words(state: Any) -> str:
    """The scene and the system's parameters, as a figure's second title line says them."""
    query = state.to_query()
    values = ", ".join(f"{TEXT_SYMBOLS.get(name, name)} = {query[name]}" for name in SYSTEM_FIELDS if name in query)
    if state.scene == "custom":
        return f"custom parameters: {values}"
    sc = get_scene(state.scene)
    return f"{sc.figure} ({sc.title}): {values}"


# --- rendering --------------------------------------------------------------------------------------------------


def matplotlib_look(obj: Any) -> Any:
    """``obj`` with the options its Bokeh style sets carried over to the matplotlib backend (each element's)."""
    hv.renderer("matplotlib")  # loads the backend's options once; Bokeh stays the current backend (the drawers')

    def element(el: Any) -> Any:
        style = hv.Store.lookup_options("bokeh", el, "style").kwargs
        plot = hv.Store.lookup_options("bokeh", el, "plot").kwargs
        opts = {k: plot[k] for k in _SAME_PLOT if k in plot}
        opts.update(_style(el, style))
        if el.label and el.get_dimension(el.label) is not None:
            # HoloViews' matplotlib backend reads a style value that names a column as that column: a curve
            # labelled as its values ("Λ1") would get one legend label per point
            el = el.relabel(f"{el.label} ")  # the legend reads the same
        return el.opts(backend="matplotlib", **opts) if opts else el

    return obj.map(element, [hv.Element])


def _style(el: Any, style: dict[str, Any]) -> dict[str, Any]:
    """One element's Bokeh style options in matplotlib's words."""
    out: dict[str, Any] = {}
    colour = style.get("color")
    line = style.get("line_color", colour)
    if "alpha" in style:
        out["alpha"] = style["alpha"]
    if isinstance(el, hv.Points):
        marker = _MARKERS.get(style.get("marker", "circle"), "o")
        fill = style.get("fill_color", colour)
        if marker in "+x":  # lines only: drawn in the line colour, whatever the (absent) fill says
            out["color"] = line
        elif style.get("fill_alpha") == 0:
            out["facecolors"] = "none"
        elif fill is not None:
            out["color"] = fill
            if "fill_alpha" in style and "alpha" not in style:
                out["alpha"] = style["fill_alpha"]
        if marker not in "+x":  # an unfilled marker has no edge
            out["edgecolors"] = "none" if line is None else line
        out["linewidth"] = PT_PER_PX * float(style.get("line_width", 1.0))
        out["s"] = (PT_PER_PX * float(style.get("size", 6.0))) ** 2  # matplotlib's marker area in points²
        out["marker"] = marker
    elif isinstance(el, hv.Image):
        for key in ("cmap",):
            if key in style:
                out[key] = style[key]
    else:  # lines: Curve, Path, HLine
        if line is not None:
            out["color"] = line
        if "line_width" in style:
            out["linewidth"] = PT_PER_PX * float(style["line_width"])
        if "line_dash" in style:
            out["linestyle"] = _dash(style["line_dash"], out.get("linewidth", PT_PER_PX))
    return out


def _dash(dash: str, width_pt: float) -> Any:
    """A Bokeh dash (a name, or a pattern in screen pixels: ``"8 3 2 3"``) as matplotlib's linestyle (a pattern in
    line widths)."""
    if dash in _DASHES:
        return _DASHES[dash]
    pattern = [PT_PER_PX * float(n) / max(width_pt, 1e-3) for n in str(dash).split()]
    return (0, tuple(pattern)) if len(pattern) >= 2 and len(pattern) % 2 == 0 else "-"


def _words(obj: Any) -> Any:
    """Dimension names in the paper's notation (:data:`SYMBOLS`)."""
    dims = [d for el in obj.traverse(lambda x: x, [hv.Element]) for d in el.dimensions()]
    names = {d.name for d in dims if d.label == d.name}  # a drawer's own words stay
    labels = {n: SYMBOLS[n] for n in names if n in SYMBOLS}
    return obj.redim.label(**labels) if labels else obj


def _legend_entries(obj: Any) -> int:
    return len({el.label for el in obj.traverse(lambda x: x, [hv.Element]) if el.label})


def figure_bytes(obj: Any, request: FigureRequest, title: str, about: str = "") -> bytes:
    """``obj`` (a HoloViews drawing) as a PNG or SVG of exactly ``request``'s size, fonts in points
    (:data:`FONT_PT`), under ``title`` (wrapped to the width); ``about`` goes in the file's metadata."""
    w_in, h_in = request.inches
    # Characters per title line: the figure's width over an average glyph of the title's size (~0.5 em); at most
    # TITLE_LINES lines (the whole title is in the file's metadata).
    wrap = max(30, int(0.9 * w_in * 72 / (0.55 * FONT_PT["title"])))
    parts = title.splitlines() or [""]
    each = max(1, TITLE_LINES // len(parts))
    lines = [ln for part in parts for ln in textwrap.wrap(part, wrap, max_lines=each, placeholder=" …")]
    obj = obj if isinstance(obj, hv.Overlay) else hv.Overlay([obj])  # the figure's options are an overlay's
    entries = _legend_entries(obj)
    with DRAWING, warnings.catch_warnings():
        look = _words(matplotlib_look(obj)).opts(
            title="", fontsize=dict(FONT_PT), aspect="auto", fig_inches=(w_in, h_in),
            legend_position="right" if entries > 6 else "best", legend_cols=2 if entries > 14 else 1,
            backend="matplotlib")  # fmt: skip
        # HoloViews' matplotlib points pass an edge colour to unfilled markers (the saddles' x), which it ignores.
        warnings.filterwarnings("ignore", message="You passed an edgecolor", category=UserWarning)
        fig = hv.render(look, backend="matplotlib")
        return _saved(fig, request, lines, title, about)


def _saved(fig: Any, request: FigureRequest, lines: list[str], title: str, about: str) -> bytes:
    """A rendered figure at exactly the size asked for, as bytes of its format."""
    w_in, h_in = request.inches
    try:
        fig.set_size_inches(w_in, h_in)
        fig.set_dpi(request.dpi)
        # The title over the whole figure (not the axes: a legend beside them would push it off the edge), and the
        # layout that keeps the title, the axes' labels and the legend inside the size asked for.
        fig.suptitle("\n".join(lines), fontsize=FONT_PT["title"])
        fig.set_layout_engine("constrained")
        meta = {"Title": title, "Description": about}
        buf = io.BytesIO()
        fig.savefig(buf, format=request.fmt, dpi=request.dpi, metadata=meta)
        if _fewer_ticks(fig):  # drawn again only then (a layout costs as much as the drawing)
            buf = io.BytesIO()
            fig.savefig(buf, format=request.fmt, dpi=request.dpi, metadata=meta)
        return buf.getvalue()
    finally:
        fig.clear()  # HoloViews' figure is not kept by pyplot; its artists are freed now


def _fewer_ticks(fig: Any) -> bool:
    """Fewer ticks on a linear x axis of the figure as last drawn whose labels ran together ("-0.600-0.575-0.550" on
    a chart narrowed by its legend): as many as fit with a gap of half the widest label between them. The axis' own
    locator is told fewer bins (matplotlib's automatic one, HoloViews' fixed ticks); another kind of locator is left
    as it is. Returns whether any axis changed (the figure must be drawn again)."""
    changed = False
    for ax in fig.axes:
        if ax.get_xscale() != "linear":
            continue
        lo, hi = sorted(ax.get_xlim())
        labels = [
            t for t, x in zip(ax.get_xticklabels(), ax.get_xticks(), strict=True) if t.get_text() and lo <= x <= hi
        ]
        if len(labels) < 2:
            continue
        widest = max(t.get_window_extent().width for t in labels)
        fit = int(ax.get_window_extent().width // (1.5 * widest))
        if fit < len(labels):
            try:
                ax.xaxis.get_major_locator().set_params(nbins=max(1, fit - 1))
            except TypeError:  # a locator without bins (matplotlib's MultipleLocator, ...)
                continue
            changed = True
    return changed


def figure_file(picture: tuple[Any, bool] | None, stem: str, request: FigureRequest, about: str) -> Download | None:
    """A tab's picture (:func:`section_picture`, :func:`tab_picture`) as the file the page sends: ``stem.png`` or
    ``stem-partial.svg`` for a stopped run; the title is the picture's own, then ``about`` (the settings)."""
    if picture is None:
        return None
    obj, stopped = picture
    head = _title_of(obj)
    title = f"{head}\n{about}" if head else about
    data = figure_bytes(obj, request, title, about)
    return Download(named(stem, f".{request.fmt}", stopped), FORMATS[request.fmt], data)


__all__ = ["DPI", "DRAWING", "FONT_PT", "FORMATS", "PIXELS", "FigureRequest", "figure_bytes", "figure_file",
           "matplotlib_look", "parse_request", "section_picture", "settings_words", "tab_picture"]  # fmt: skip
