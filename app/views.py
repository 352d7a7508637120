"""Bokeh figures of the explorer: data in, glyphs out, no numerics.

The (q, r) figure stacks the layers, bottom to top: the T' map, the equilibrium tracks over
one period, the streamed section points, the selected trajectory (thin rings), the equilibria at
the section phase, and the clicked initial conditions. The k-series of the selected trajectory
are data here; the page draws them (:class:`SeriesData`).

Every session builds its own figures (a Bokeh model belongs to one document), and building
and sending them is most of what a new page costs the server: they are assembled from Bokeh's
models directly, without the ``figure()`` helper's extra models (a second glyph per renderer
for the unselected state, a view per renderer, one label policy per axis), ~50 models instead
of ~80 for the section (docs/load.md). The mouse wheel scrolls the page; the wheel-zoom tool
zooms only once picked in the toolbar.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any

import numpy as np
from bokeh.core.property.validation import validate
from bokeh.models import (
    AllIndices,
    AllLabels,
    BasicTicker,
    BoxZoomTool,
    CDSView,
    ColorBar,
    ColumnDataSource,
    GlyphRenderer,
    Grid,
    HoverTool,
    Image,
    ImageRGBA,
    Legend,
    LegendItem,
    LinearAxis,
    LinearColorMapper,
    LogColorMapper,
    MultiLine,
    PanTool,
    Plot,
    Range1d,
    ResetTool,
    SaveTool,
    Scatter,
    Text,
    Toolbar,
    UnionRenderers,
    WheelZoomTool,
)
from bokeh.palettes import Category20, Inferno256, RdBu11, Viridis256, interp_palette

#: One colour per equilibrium type (shared by the tracks and the markers).
TYPE_COLORS = {
    "saddle": "#d62728",
    "stable node": "#1f77b4",
    "unstable node": "#ff7f0e",
    "stable focus": "#2ca02c",
    "unstable focus": "#9467bd",
    "centre": "#17becf",
    "degenerate": "#7f7f7f",
}
#: Periodic orbits of the map, one layer per marker (filled: stable, open: unstable, a cross: saddles;
#: a constant marker per renderer: WebGL draws a per-point marker column wrongly).
ORBIT_KIND = {
    "stable node": "stable",
    "stable focus": "stable",
    "unstable node": "unstable",
    "unstable focus": "unstable",
    "elliptic": "unstable",
    "neutral": "unstable",
    "saddle": "saddle",
    "flip saddle": "saddle",
}
ORBIT_COLOUR = "#c2006b"
#: What a tour says to look at (a ring and its words): a colour no layer uses.
MARK_COLOUR = "#0a58ca"
#: The section point of the period the body view shows (a filled star: no other mark is one).
BODY_COLOUR = "#ffd21f"
#: Invariant manifolds of saddles: unstable and stable (apart from the T' map's red and blue).
MANIFOLD_COLOURS = {"unstable": "#e8590c", "stable": "#0b7285"}
N_COLORS = 20
#: Section points: their size (px), and the selected trajectory's rings over them (size, line width, opacity).
POINT_SIZE = 2.6
SELECTED_RING, SELECTED_LINE, SELECTED_ALPHA = 3.6, 0.5, 0.45
#: Section points described by a hover at most (the rest under the cursor are the same kind of thing).
POINT_TIPS = 3
#: Bokeh output backend of the point plots ("webgl" or "canvas"); see README (performance).
BACKEND = os.environ.get("BILIMOVICH_BACKEND", "webgl")
#: Palettes built once per process (every session's figures refer to the same lists).
TPRIME_PALETTE = interp_palette(RdBu11, 255)  # blue (loss) .. white .. red (gain); odd: 0 is white
TRAJ_PALETTE = Category20[N_COLORS]
#: Density images: light (few points) to dark (many), empty pixels transparent over the T' map.
DENSITY_PALETTE = tuple(reversed(Inferno256))
#: FTLE maps: dark (islands, FTLE near 0) to light (the chaotic sea); pixels without a value transparent.
FTLE_PALETTE = Viridis256
#: Opacity of the basins image (over the page's white: the T' map is hidden under it).
BASIN_ALPHA = 0.5
#: Font sizes (points) of axis labels and ticks: normal and presentation mode.
FONTS = {False: ("11pt", "9pt"), True: ("16pt", "13pt")}


def _mapper(cls: type, palette: Any, **kw: Any) -> Any:
    """A colour mapper over one of the palettes above, without Bokeh's check of each of its colours.

    Bokeh checks every colour of a palette each time a mapper is made (~5 ms for 255 colours, a twentieth of what a
    new page cost); these palettes are checked once, at import.
    """
    with validate(False):
        return cls(palette=palette, **kw)


# Bokeh's check of the palettes, once per process (a palette it refuses fails the import, as it failed every page).
for _palette in (TPRIME_PALETTE, TRAJ_PALETTE, DENSITY_PALETTE, FTLE_PALETTE):
    LinearColorMapper(palette=_palette)


def _empty_points() -> dict[str, list]:
    return {"q": [], "r": [], "traj": [], "k": [], "c": []}


def _image_data(image: np.ndarray | None = None, q0: float = 0, q1: float = 0, r0: float = 0, r1: float = 0) -> dict:
    """An image source's data: ``image`` over ``[q0, q1] x [r0, r1]`` (row 0 at ``r0``), or empty."""
    if image is None:
        return {"image": [], "x": [], "y": [], "dw": [], "dh": []}
    return {"image": [image], "x": [q0], "y": [r0], "dw": [q1 - q0], "dh": [r1 - r0]}


def _empty_orbits() -> dict[str, list]:
    return {"q": [], "r": [], "period": [], "type": [], "mu": [], "label": []}


def as_drawn(colour: str, alpha: float = BASIN_ALPHA) -> str:
    """The colour ``#rrggbb`` seen when drawn with opacity ``alpha`` over white (a legend swatch that matches)."""
    rgb = [round(255 - alpha * (255 - int(colour[i : i + 2], 16))) for i in (1, 3, 5)]
    return "#" + "".join(f"{v:02x}" for v in rgb)


def orbit_label(kind: str) -> str:
    """The legend's words for a periodic orbit of the map ("saddle orbit of the map")."""
    return f"{kind} orbit of the map"


def equilibrium_label(kind: str) -> str:
    """The legend's words for an equilibrium of the frozen field ("frozen-field saddle")."""
    return f"frozen-field {kind}"


def _axes(plot: Plot, x_label: str, y_label: str, *, grid: bool = True) -> list[LinearAxis]:
    policy = AllLabels()
    axes = []
    for place, dim, label in (("below", 0, x_label), ("left", 1, y_label)):
        ticker = BasicTicker()
        axis = LinearAxis(ticker=ticker, axis_label=label, major_label_policy=policy)
        plot.add_layout(axis, place)
        if grid:
            plot.add_layout(Grid(dimension=dim, ticker=ticker))
        axes.append(axis)
    return axes


def set_fonts(axes: list[LinearAxis], presentation: bool) -> None:
    label, ticks = FONTS[presentation]
    for a in axes:
        a.update(axis_label_text_font_size=label, major_label_text_font_size=ticks)


class _OfLayer:
    """An attribute of :class:`SectionFigure` made by one of its layers: read, it builds that layer."""

    def __init__(self, layer: str) -> None:
        self.layer = layer

    def __set_name__(self, owner: type, name: str) -> None:
        self.attr = f"_{name}"

    def __get__(self, fig: Any, owner: type | None = None) -> Any:
        if fig is None:
            return self
        fig._build(self.layer)
        return getattr(fig, self.attr)


class SectionFigure:
    """The (q, r) plane with all its layers."""

    def __init__(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> None:
        self.x_range = Range1d(*q_range, name="q_range")
        self.y_range = Range1d(*r_range, name="r_range")
        fig = Plot(
            x_range=self.x_range, y_range=self.y_range, output_backend=BACKEND, sizing_mode="stretch_both",
            min_height=300, min_width=300, name="section_figure", title=None, toolbar_location="right",
        )  # fmt: skip
        self.axes = _axes(fig, "q", "r")
        policy = UnionRenderers()
        # One filter for every renderer's view: each view would have its own (a model more per layer to build and
        # send); it selects nothing, so sharing it changes nothing.
        self._every = AllIndices()

        def source(data: dict, name: str) -> ColumnDataSource:
            return ColumnDataSource(data, name=name, selection_policy=policy)

        self.tprime_mapper = _mapper(LinearColorMapper, TPRIME_PALETTE, low=-1, high=1)
        self.tprime = source(_image_data(), "tprime_source")
        image = Image(image="image", x="x", y="y", dw="dw", dh="dh", color_mapper=self.tprime_mapper, global_alpha=0.55)
        tp = self._renderer(self.tprime, image, level="image", name="tprime_image")
        self._tprime_renderer = tp
        self.colorbar = ColorBar(
            color_mapper=self.tprime_mapper,
            title="T′ — red: energy gain (body spins up), blue: loss",
            title_text_font_size="10pt",
            width=10,
            location=(0, 0),
            visible=False,  # until a colour layer is drawn
        )
        fig.add_layout(self.colorbar, "right")
        self._tprime_title, self._presentation = self.colorbar.title, False
        self._ftle_title = ""
        self.tracks = source({"xs": [], "ys": [], "color": [], "type": []}, "tracks_source")
        tracks = self._renderer(self.tracks, MultiLine(xs="xs", ys="ys", line_color="color", line_width=1.6,
                                                       line_alpha=0.7, line_dash="dashed"))  # fmt: skip
        self.points = source(_empty_points(), "section_source")
        self.traj_mapper = _mapper(LinearColorMapper, TRAJ_PALETTE, low=0, high=N_COLORS - 1)
        colour = {"field": "c", "transform": self.traj_mapper}
        dots = Scatter(x="q", y="r", size=POINT_SIZE, line_color=None, fill_alpha=0.9, fill_color=colour)
        pts = self._renderer(self.points, dots, name="section_points")
        # The selected trajectory, ringed on top of the others: thin translucent rings just wider than a point, so
        # an attractor it lies on keeps its structure and colours (6 px rings at 0.7 hid Fig. 8B's; issue 36).
        self.selected = source({"q": [], "r": []}, "selected_source")
        ring = Scatter(x="q", y="r", size=SELECTED_RING, line_color="black", line_width=SELECTED_LINE,
                       line_alpha=SELECTED_ALPHA, fill_color=None)  # fmt: skip
        sel = self._renderer(self.selected, ring, name="selected_points")
        self.equilibria = source({"q": [], "r": [], "color": [], "type": [], "label": []}, "equilibria_source")
        eq = self._renderer(self.equilibria, Scatter(x="q", y="r", marker="diamond", size=15, fill_color="color",
                                                     line_color="black"), name="frozen_field_equilibria")  # fmt: skip
        self._source = source
        # The layers a new page does not show (basins, density, manifolds, periodic orbits, clicked points) are built
        # when first used and join the plot then, in their place (a string here): a new page builds
        # ~55 models fewer and sends ~30 fewer (Bokeh spends ~0.4 ms a model: docs/load.md).
        self._order: list[Any] = [tp, "basins", "ftle", "density", tracks, pts, sel, eq, "ics", "manifolds", "orbits",
                                 "body", "marks"]  # fmt: skip
        self._built: dict[str, list[GlyphRenderer]] = {}
        self._shown: set[str] = set()
        fig.renderers.extend([r for r in self._order if not isinstance(r, str)])
        # The frozen field's equilibria and the map's periodic orbits share words (saddle, focus): the legend
        # names them apart ("frozen-field saddle" vs "saddle orbit of the map").
        # Compact: with the orbits' entries it has up to ~8 rows over a 300 px plot at 1280x720.
        self.legend = Legend(items=[LegendItem(label={"field": "label"}, renderers=[eq])], location="top_left",
                             background_fill_alpha=0.7, label_text_font_size="8pt", label_height=12,
                             glyph_height=12, glyph_width=12, spacing=0, padding=4, margin=4,
                             visible=False)  # fmt: skip
        fig.add_layout(self.legend)
        # One hover per kind of mark, each with that mark's fields only (one tool over the points and the
        # diamonds showed "frozen-field equilibrium: ???" on every point). A few point entries at most: dozens
        # of them under a flip saddle buried its multipliers.
        hover = HoverTool(renderers=[pts], tooltips=[("trajectory", "@traj"), ("k", "@k"), ("q, r", "@q, @r")],
                          limit=POINT_TIPS)  # fmt: skip
        self._eq_renderer = eq
        self._hovers: dict[str, HoverTool] = {}
        # No active scroll tool: the wheel scrolls the page until the user picks the zoom tool.
        fig.toolbar = Toolbar(tools=[PanTool(), WheelZoomTool(), BoxZoomTool(), ResetTool(), SaveTool(), hover],
                              logo=None, active_scroll=None)  # fmt: skip
        self.fig = fig

    def _renderer(self, source: ColumnDataSource, glyph: Any, **kw: Any) -> GlyphRenderer:
        # Its own CDSView (BokehJS keeps the view's indices for one source) and no glyph of its own
        # for the unselected state (nothing is ever selected here).
        return GlyphRenderer(data_source=source, glyph=glyph, view=CDSView(filter=self._every), **kw)

    # --- the layers built on first use ------------------------------------------------------

    def _build(self, layer: str) -> list[GlyphRenderer]:
        if layer not in self._built:
            self._built[layer] = getattr(self, f"_build_{layer}")()
        return self._built[layer]

    def _build_density(self) -> list[GlyphRenderer]:
        # A long section as a density image (counts per pixel, binned on the server), under the points.
        self._density_mapper = _mapper(LogColorMapper, DENSITY_PALETTE, low=1, high=2, nan_color=(0, 0, 0, 0))
        self._density = self._source(_image_data(), "density_source")
        shade = Image(image="image", x="x", y="y", dw="dw", dh="dh", color_mapper=self._density_mapper)
        return [self._renderer(self._density, shade, level="image", name="density_image")]

    def _build_ics(self) -> list[GlyphRenderer]:
        # The initial conditions clicked in the plot (none on a new page but a link's own).
        self._ics = self._source({"q": [], "r": []}, "ics_source")
        cross = Scatter(x="q", y="r", marker="x", size=11, line_color="black", line_width=2)
        return [self._renderer(self._ics, cross, name="clicked_points")]

    def _build_basins(self) -> list[GlyphRenderer]:
        # Basins of attraction: a colour per attractor, translucent, over the T' map and under the points.
        self._basins = self._source(_image_data(), "basins_source")
        rgba = ImageRGBA(image="image", x="x", y="y", dw="dw", dh="dh", global_alpha=BASIN_ALPHA)
        return [self._renderer(self._basins, rgba, level="image", name="basins_image")]

    def _build_ftle(self) -> list[GlyphRenderer]:
        # An FTLE map: a colour scale (its key the colour bar), under the points; failed pixels transparent.
        self._ftle_mapper = _mapper(
            LinearColorMapper, FTLE_PALETTE, low=0, high=1, nan_color=(0, 0, 0, 0), name="ftle_mapper"
        )
        self._ftle = self._source(_image_data(), "ftle_source")
        shade = Image(image="image", x="x", y="y", dw="dw", dh="dh", color_mapper=self._ftle_mapper)
        return [self._renderer(self._ftle, shade, level="image", name="ftle_image")]

    def _build_manifolds(self) -> list[GlyphRenderer]:
        # Stable and unstable manifolds of saddles over the points, their crossings (homoclinic points) on them.
        self._manifolds = self._source({"xs": [], "ys": [], "color": [], "kind": []}, "manifolds_source")
        man = self._renderer(self._manifolds, MultiLine(xs="xs", ys="ys", line_color="color", line_width=1.6,
                                                        line_alpha=0.9), name="manifold_lines")  # fmt: skip
        self._crossings = self._source({"q": [], "r": [], "what": []}, "crossings_source")
        diamond = Scatter(x="q", y="r", marker="diamond", size=8, fill_color="black", line_color="white", line_width=1)
        cross = self._renderer(self._crossings, diamond, name="homoclinic_points")
        self._hovers["manifolds"] = HoverTool(renderers=[cross], tooltips=[("", "@what"), ("q, r", "@q, @r")])
        return [man, cross]

    def _build_orbits(self) -> list[GlyphRenderer]:
        # Periodic orbits of the map, on top of everything (a white halo under each marker).
        self._orbit_sources = {
            k: self._source(_empty_orbits(), f"orbits_{k}") for k in ("stable", "unstable", "saddle")
        }
        orb = []
        for kind, marker, fill, alpha in (("saddle", "x", "white", 0.0), ("unstable", "circle", "white", 0.85),
                                          ("stable", "circle", "#ffd21f", 1.0)):  # fmt: skip
            src = self._orbit_sources[kind]
            orb.append(self._renderer(src, Scatter(x="q", y="r", marker=marker, size=15, line_color="white",
                                                   line_width=6, fill_alpha=0.0)))  # fmt: skip
            orb.append(self._renderer(src, Scatter(x="q", y="r", marker=marker, size=15, line_color=ORBIT_COLOUR,
                                                   line_width=2.5, fill_color=fill, fill_alpha=alpha),
                                      name=f"orbit_points_{kind}"))  # fmt: skip
        # The multipliers first: they are what tells the kind of orbit; one orbit point described at a time.
        tips = [("multipliers", "@mu"), ("periodic orbit of the map", "period @period, @type"), ("q, r", "@q, @r")]
        self._hovers["orbits"] = HoverTool(renderers=orb[1::2], tooltips=tips, limit=1)
        # Legend entries of the orbits drawn ("saddle orbit of the map"), beside the frozen field's.
        self.legend.items = [*self.legend.items, *(LegendItem(label={"field": "label"}, renderers=[r])
                                                   for r in orb[1::2])]  # fmt: skip
        return orb

    def _build_marks(self) -> list[GlyphRenderer]:
        # What a tour's step says to look at: a thick ring and its words, over everything.
        self._marks = self._source({"q": [], "r": [], "label": []}, "marks_source")
        ring = self._renderer(self._marks, Scatter(x="q", y="r", marker="circle", size=34, fill_alpha=0.0,
                                                   line_color=MARK_COLOUR, line_width=4),
                              name="tour_marks")  # fmt: skip
        words = self._renderer(self._marks, Text(x="q", y="r", text="label", x_offset=20, y_offset=-10,
                                                 text_font_size="13pt", text_font_style="bold", text_color=MARK_COLOUR,
                                                 background_fill_color="white", background_fill_alpha=0.75),
                               name="tour_labels")  # fmt: skip
        return [ring, words]

    def _build_body(self) -> list[GlyphRenderer]:
        # The section point of the period the body view shows (app/body.js): its data is written by the page
        # alone, in place (no message per period); the server only puts the glyph in the plot. On the overlay level:
        # moving it repaints only BokehJS's overlay layer, not the section's points (30,000 of them by default: a
        # repaint each period took 0.5-1.2 s in headless Chromium and the body ran at 2-14 frames/s at 1-4 periods/s).
        self._body = self._source({"q": [], "r": []}, "body_source")
        star = Scatter(x="q", y="r", marker="star", size=22, fill_color=BODY_COLOUR, line_color="black", line_width=1.5)
        return [self._renderer(self._body, star, level="overlay", name="body_point")]

    def show_body_point(self) -> None:
        """Put the body view's highlighted section point in the plot (built on first use; the page moves it)."""
        self._activate("body")

    def set_marks(self, marks: list[tuple[float, float, str]]) -> None:
        """Points to look at (a tour's step), ringed and labelled; [] removes them (built on first use)."""
        if not marks and "marks" not in self._built:
            return
        self._activate("marks")
        self._marks.data = {"q": [m[0] for m in marks], "r": [m[1] for m in marks], "label": [m[2] for m in marks]}

    def marks_data(self) -> dict[str, list]:
        return dict(self._marks.data) if "marks" in self._built else {"q": [], "r": [], "label": []}

    def _build_equilibria_hover(self) -> list[GlyphRenderer]:
        # Joins the toolbar with the first equilibria drawn (not a model of the new page).
        tips = [("frozen-field equilibrium", "@type"), ("q, r", "@q, @r")]
        self._hovers["equilibria_hover"] = HoverTool(renderers=[self._eq_renderer], tooltips=tips)
        return []

    # Models of the layers built on first use (reading one builds its layer, not showing it).
    density = _OfLayer("density")
    density_mapper = _OfLayer("density")
    basins = _OfLayer("basins")
    ftle = _OfLayer("ftle")
    ftle_mapper = _OfLayer("ftle")
    manifolds = _OfLayer("manifolds")
    crossings = _OfLayer("manifolds")
    orbit_sources = _OfLayer("orbits")
    ics = _OfLayer("ics")

    def _activate(self, layer: str) -> None:
        """Put a layer's renderers in the plot (in their place among the others), once."""
        if layer in self._shown:
            return
        doc = self.fig.document
        # The document's models are recomputed once, not once per change (renderers, legend items, tools): each
        # walks every model of the page (the orbits' layer took 37 ms in a bare document, 18 ms frozen).
        with doc.models.freeze() if doc is not None else contextlib.nullcontext():
            self._build(layer)
            self._shown.add(layer)
            if layer in self._order:
                self._place_renderers()
            if layer in self._hovers:
                self.fig.toolbar.tools = [*self.fig.toolbar.tools, self._hovers[layer]]

    def _place_renderers(self) -> None:
        self.fig.renderers = [
            r
            for x in self._order
            for r in ((self._built[x] if x in self._shown else []) if isinstance(x, str) else [x])
        ]

    # --- updates (always called on the document's thread) ------------------------------

    def set_view(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> None:
        self.x_range.update(start=q_range[0], end=q_range[1])
        self.y_range.update(start=r_range[0], end=r_range[1])

    def replace_points(self, traj: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray) -> None:
        """Start a new run's points. The generation stamp (set after the data) lets a page,
        and the latency probe, tell the new data from the old."""
        self.points.data = {"q": q, "r": r, "traj": traj, "k": k, "c": traj % N_COLORS}
        self.points.tags = [int(self.points.tags[0]) + 1 if self.points.tags else 1]

    def stream_points(self, traj: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray) -> None:
        if traj.size:
            self.points.stream({"q": q, "r": r, "traj": traj, "k": k, "c": traj % N_COLORS})

    def _clear_image(self, layer: str) -> None:
        """No image of ``layer`` (one built on first use) on screen, and the colour bar of what is seen then."""
        if self._has_image(layer):
            getattr(self, f"_{layer}").data = _image_data()
            self._refresh_colours()

    def set_density(self, counts: np.ndarray | None, view: tuple[float, ...] | None = None) -> None:
        """The density image (counts per pixel, row 0 at the bottom of ``view``), or none."""
        if counts is None or counts.size == 0:
            self._clear_image("density")
            return
        self._activate("density")
        image = np.where(counts > 0, counts, np.nan).astype(np.float32)
        self.density_mapper.high = max(2.0, float(counts.max()))
        self.density.data = _image_data(image, *view)  # type: ignore[misc]
        self._refresh_colours()

    def set_basins(self, labels: np.ndarray | None, view: tuple[float, ...] | None = None,
                   colours: dict[int, str] | None = None) -> None:  # fmt: skip
        """Basin labels (NY, NX), row 0 at the bottom of ``view``, as colours (``colours[label]``; others clear)."""
        if labels is None or labels.size == 0:
            self._clear_image("basins")
            return
        self._activate("basins")
        rgba = np.zeros(labels.shape, dtype=np.uint32)
        view8 = rgba.view(np.uint8).reshape(*labels.shape, 4)
        for label, hex_ in (colours or {}).items():
            m = labels == label
            if m.any():
                view8[m] = (int(hex_[1:3], 16), int(hex_[3:5], 16), int(hex_[5:7], 16), 255)
        self.basins.data = _image_data(rgba, *view)  # type: ignore[misc]
        self._refresh_colours()

    def set_ftle(self, values: np.ndarray | None, view: tuple[float, ...] | None = None,
                 title: str = "") -> None:  # fmt: skip
        """An FTLE map (NY, NX), row 0 at the bottom of ``view``, NaN where a pixel has no value (drawn
        transparent), its colour bar titled ``title``; or none."""
        if values is None or values.size == 0:
            self._clear_image("ftle")
            return
        self._activate("ftle")
        ok = values[np.isfinite(values)]
        low, high = (float(ok.min()), float(ok.max())) if ok.size else (0.0, 1.0)
        self.ftle_mapper.update(low=low, high=high if high > low else low + 1e-12)
        self._ftle_title = title
        self.ftle.data = _image_data(values.astype(np.float32), *view)  # type: ignore[misc]
        self._refresh_colours()

    def set_selected(self, q: np.ndarray, r: np.ndarray) -> None:
        self.selected.data = {"q": q, "r": r}

    def set_ics(self, ics: np.ndarray) -> None:
        if not ics.size and "ics" not in self._built:
            return
        self._activate("ics")
        self.ics.data = {"q": ics[:, 0], "r": ics[:, 1]} if ics.size else {"q": [], "r": []}

    def set_orbits(self, rows: list[dict[str, Any]]) -> None:
        """Every point of every orbit (rows of :func:`app.layers.orbits.orbit_row`), in its kind's layer."""
        if not rows and "orbits" not in self._built:
            return
        self._activate("orbits")
        data = {k: _empty_orbits() for k in self.orbit_sources}
        for o in rows:
            d = data[ORBIT_KIND.get(o["type"], "unstable")]
            for q, r in o["points"]:
                d["q"].append(q)
                d["r"].append(r)
                d["period"].append(o["period"])
                d["type"].append(o["type"])
                d["mu"].append(o["mu"])
                d["label"].append(orbit_label(o["type"]))
        for k, src in self.orbit_sources.items():
            src.data = data[k]
        self._legend_shown()

    def _legend_shown(self) -> None:
        # An empty legend is drawn as a blank box in the plot's corner (e.g. basins with the tracks off)
        built = self._orbit_sources.values() if "orbits" in self._built else ()  # never built for this
        n = len(self.equilibria.data["q"]) + sum(len(s.data["q"]) for s in built)
        if self.legend.visible != (n > 0):
            self.legend.visible = n > 0

    def set_manifolds(self, lines: list[tuple[Any, Any, str]], marks: list[tuple[float, float, str]]) -> None:
        """Pieces of manifolds ``(q, r, kind)`` (kind: unstable | stable) and crossings ``(q, r, text)``."""
        if not (lines or marks) and "manifolds" not in self._built:
            return
        self._activate("manifolds")
        self.manifolds.data = {
            "xs": [ln[0] for ln in lines],
            "ys": [ln[1] for ln in lines],
            "color": [MANIFOLD_COLOURS[ln[2]] for ln in lines],
            "kind": [ln[2] for ln in lines],
        }
        self.crossings.data = {"q": [m[0] for m in marks], "r": [m[1] for m in marks], "what": [m[2] for m in marks]}

    def orbit_data(self) -> dict[str, list]:
        """All orbit points drawn, every layer together (tests and probes)."""
        out = _empty_orbits()
        for src in (self.orbit_sources if "orbits" in self._built else {}).values():
            for key in out:
                out[key] += list(src.data[key])
        return out

    def set_tracks(self, segments: list[tuple[np.ndarray, np.ndarray, str]]) -> None:
        self.tracks.data = {
            "xs": [s[0] for s in segments],
            "ys": [s[1] for s in segments],
            "color": [TYPE_COLORS.get(s[2], "#000000") for s in segments],
            "type": [s[2] for s in segments],
        }

    def set_equilibria(self, q: np.ndarray, r: np.ndarray, types: tuple[str, ...]) -> None:
        if len(types):
            self._activate("equilibria_hover")
        self.equilibria.data = {
            "q": list(q),
            "r": list(r),
            "color": [TYPE_COLORS.get(t, "#000000") for t in types],
            "type": list(types),
            "label": [equilibrium_label(t) for t in types],
        }
        self._legend_shown()

    def set_tprime(self, values: np.ndarray | None, q: np.ndarray, r: np.ndarray, title: str) -> None:
        if values is None or values.size == 0:
            self.tprime.data = _image_data()
            self._refresh_colours()
            return
        # Symmetric colour scale about 0 so the sign is the colour; clip outliers.
        lim = float(np.percentile(np.abs(values), 98)) or 1.0
        self.tprime_mapper.update(low=-lim, high=lim)
        self._tprime_title = title
        dq = (q[-1] - q[0]) / max(1, q.size - 1)
        dr = (r[-1] - r[0]) / max(1, r.size - 1)
        # Each value is a pixel centred on its grid point.
        self.tprime.data = _image_data(values, q[0] - dq / 2, q[-1] + dq / 2, r[0] - dr / 2, r[-1] + dr / 2)
        self._refresh_colours()

    def set_presentation(self, on: bool) -> None:
        set_fonts(self.axes, on)
        self._presentation = on
        # Readable from the back of a room, still short enough for the 300 px plot of 1280x720.
        size = 14 if on else 12
        self.legend.update(label_text_font_size="10pt" if on else "8pt", label_height=size, glyph_height=size,
                           glyph_width=size)  # fmt: skip
        self.colorbar.update(title_text_font_size="13pt" if on else "10pt", title=self._colorbar_title())

    def _has_image(self, layer: str) -> bool:
        return layer in self._built and bool(getattr(self, f"_{layer}").data["image"])

    @property
    def tprime_hidden_by(self) -> str:
        """What hides the T' map computed ("" if nothing): the basins or the density image, whose colours it
        would tint (their legends and scale would no longer match what is drawn)."""
        if not self.tprime.data["image"]:
            return ""
        for layer, words in (("density", "the density image"), ("ftle", "the FTLE map"), ("basins", "the basins")):
            if self._has_image(layer):
                return words
        return ""

    def _refresh_colours(self) -> None:
        """One colour layer seen at a time under the points, and the colour bar of the one seen (or none)."""
        tprime = bool(self.tprime.data["image"]) and not self.tprime_hidden_by
        if self._tprime_renderer.visible != tprime:
            self._tprime_renderer.visible = tprime
        mapper = self.density_mapper if self._has_image("density") else self.ftle_mapper if self._has_image("ftle") \
            else self.tprime_mapper if tprime else None  # fmt: skip
        if mapper is not None and self.colorbar.color_mapper is not mapper:
            self.colorbar.color_mapper = mapper
        self.colorbar.update(visible=mapper is not None, title=self._colorbar_title())

    def _colorbar_title(self) -> str:
        if self._has_image("density"):
            return "points per pixel (log)" if self._presentation else "section points per pixel (log scale)"
        if self._has_image("ftle"):
            return self._ftle_title
        # At presentation size the long title runs past the plot's height (seen at 1280x720).
        title = self._tprime_title
        if self._presentation:
            return ("T′" if title.startswith("T′") else "ΔT over a period") + ": red gain, blue loss"
        return title


class SpareFigures:
    """Section figures built ahead, while the server's event loop has nothing else to do.

    A section figure is the largest part of a new page the server builds (~60 Bokeh models, a quarter of its
    event-loop time, docs/load.md) and depends on nothing of the visitor's (its view is set when taken). When a
    class opens the link together, each worker builds its pages one after the other and the last student waits
    for all of them: with figures built beforehand, in the quiet moments before (one per turn of an idle loop),
    each page costs that much less. Taken one by one (:meth:`take`); without spares, a figure is built then.
    """

    def __init__(self, size: int = 16, every: float = 0.05) -> None:
        self.size = size
        self.every = every
        self._spares: list[SectionFigure] = []
        self._filling: Any = None  # the loop the spares are being built on

    def __len__(self) -> int:
        return len(self._spares)

    def take(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> SectionFigure:
        """A section figure over ``q_range`` x ``r_range``: a spare if there is one, else built now."""
        if not self._spares:
            return SectionFigure(q_range, r_range)
        fig = self._spares.pop()
        fig.set_view(q_range, r_range)
        return fig

    def fill(self, loop: Any, idle: Any) -> None:
        """Build spares on ``loop`` (an asyncio loop), one at a time while ``idle()`` says the server has nothing
        more urgent to do and nothing else is ready to run, until there are :attr:`size` of them."""
        if (self._filling is loop and not loop.is_closed()) or len(self._spares) >= self.size:
            return
        self._filling = loop
        loop.call_later(self.every, self._one, loop, idle)

    def _one(self, loop: Any, idle: Any) -> None:
        # CPython's loop keeps its ready callbacks in ``_ready``: none waiting means the loop is idle.
        if idle() and not getattr(loop, "_ready", None):
            self._spares.append(SectionFigure((0.0, 1.0), (0.0, 1.0)))
        if len(self._spares) >= self.size:
            self._filling = None
            return
        loop.call_later(self.every, self._one, loop, idle)


#: The spare section figures of this process (filled by the server: app/pacing.py); env BILIMOVICH_SPARE_FIGURES:
#: how many (0: none, for measurements of a page's whole cost: benchmarks/session_cost.py).
SPARES = SpareFigures(int(os.environ.get("BILIMOVICH_SPARE_FIGURES", "16")))


class SeriesData:
    """q_k, r_k and T_k of the selected trajectory. The page draws them itself (app/ui.js, three small
    SVG charts): three Bokeh figures cost a new session ~90 ms of the server's event loop to build
    and send (docs/load.md), more than the rest of its first view after the page."""

    #: Points per series sent to the page at most (every n-th beyond: a chart ~400 px wide).
    MAX_DRAWN = 1500

    def __init__(self, on_change: Any = None) -> None:
        self.data: dict[str, np.ndarray] = {c: np.zeros(0) for c in ("k", "q", "r", "T")}
        self.on_change = on_change

    def set(self, k: np.ndarray, q: np.ndarray, r: np.ndarray, energy: np.ndarray) -> None:
        self.data = {"k": np.asarray(k), "q": np.asarray(q), "r": np.asarray(r), "T": np.asarray(energy)}
        if self.on_change is not None:
            self.on_change(self.drawn())

    def drawn(self) -> dict[str, list[float]]:
        """What the page draws: every point, or every n-th of a long series (the last one kept)."""
        n = self.data["k"].size
        idx = np.arange(n) if n <= self.MAX_DRAWN else np.unique(np.r_[np.arange(0, n, -(-n // self.MAX_DRAWN)), n - 1])
        return {c: [float(v) for v in self.data[c][idx]] for c in ("k", "q", "r", "T")}
