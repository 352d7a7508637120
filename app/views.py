"""Bokeh figures of the explorer: data in, glyphs out, no numerics.

The (q, r) figure stacks the layers the issue asks for, bottom to top: the T'
map, the equilibrium tracks over one period, the streamed section points, the
equilibria at the section phase, and the clicked initial conditions. The
k-series figures share their k axis.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from bokeh.models import (
    ColorBar,
    ColumnDataSource,
    HoverTool,
    LinearColorMapper,
    Range1d,
)
from bokeh.palettes import Category10, Category20, RdBu11, interp_palette
from bokeh.plotting import figure
from bokeh.transform import linear_cmap

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
N_COLORS = 20
#: Style of the error boxes. They are HTML panes holding escaped text: a Markdown pane
#: (pn.pane.Alert) would turn values such as ![x](https://...) into images or links.
ERROR_STYLE = "color:#842029;background:#f8d7da;border:1px solid #f5c2c7;border-radius:4px;padding:8px 12px"
#: Bokeh output backend of the point plots ("webgl" or "canvas"); see README (performance).
BACKEND = os.environ.get("BILIMOVICH_BACKEND", "webgl")


def _empty_points() -> dict[str, list]:
    return {"q": [], "r": [], "traj": [], "k": [], "c": []}


class SectionFigure:
    """The (q, r) plane with all its layers."""

    def __init__(self, q_range: tuple[float, float], r_range: tuple[float, float]) -> None:
        self.x_range = Range1d(*q_range, name="q_range")
        self.y_range = Range1d(*r_range, name="r_range")
        fig = figure(
            x_range=self.x_range,
            y_range=self.y_range,
            x_axis_label="q",
            y_axis_label="r",
            tools="pan,wheel_zoom,box_zoom,reset,save",
            active_scroll="wheel_zoom",
            output_backend=BACKEND,
            sizing_mode="stretch_width",
            height=640,
            name="section_figure",
        )
        fig.toolbar.logo = None
        # Bokeh's RdBu11 runs from blue (#053061) to red: loss (< 0) blue, gain (> 0) red;
        # interpolated to 255 levels (odd, so 0 is the white middle) for a smooth map.
        self.tprime_mapper = LinearColorMapper(palette=interp_palette(RdBu11, 255), low=-1, high=1)
        self.tprime = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []}, name="tprime_source")
        self.tprime_renderer = fig.image(
            image="image", x="x", y="y", dw="dw", dh="dh", source=self.tprime, color_mapper=self.tprime_mapper,
            alpha=0.55, level="image",
        )  # fmt: skip
        self.colorbar = ColorBar(
            color_mapper=self.tprime_mapper,
            title="T′ — red: energy gain (body spins up), blue: loss",
            title_text_font_size="10pt",
            width=10,
            location=(0, 0),
        )
        fig.add_layout(self.colorbar, "right")

        self.tracks = ColumnDataSource({"xs": [], "ys": [], "color": [], "type": []}, name="tracks_source")
        self.tracks_renderer = fig.multi_line(
            xs="xs", ys="ys", line_color="color", line_width=1.6, line_alpha=0.7, line_dash="dashed", source=self.tracks
        )
        self.points = ColumnDataSource(_empty_points(), name="section_source")
        cmap = linear_cmap("c", Category20[N_COLORS], 0, N_COLORS - 1)
        self.points_renderer = fig.scatter(
            "q", "r", source=self.points, size=2.6, line_color=None, fill_color=cmap, fill_alpha=0.9,
            name="section_points",
        )  # fmt: skip
        self.equilibria = ColumnDataSource({"q": [], "r": [], "color": [], "type": []}, name="equilibria_source")
        self.eq_renderer = fig.scatter(
            "q", "r", source=self.equilibria, marker="diamond", size=15, fill_color="color", line_color="black",
            legend_field="type",
        )  # fmt: skip
        self.ics = ColumnDataSource({"q": [], "r": []}, name="ics_source")
        fig.scatter("q", "r", source=self.ics, marker="x", size=11, line_color="black", line_width=2)
        fig.legend.location = "top_left"
        fig.legend.background_fill_alpha = 0.7
        fig.legend.label_text_font_size = "9pt"
        fig.add_tools(
            HoverTool(
                renderers=[self.points_renderer], tooltips=[("trajectory", "@traj"), ("k", "@k"), ("q, r", "@q, @r")]
            )
        )
        fig.add_tools(HoverTool(renderers=[self.eq_renderer], tooltips=[("equilibrium", "@type"), ("q, r", "@q, @r")]))
        self.fig = fig

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

    def set_ics(self, ics: np.ndarray) -> None:
        self.ics.data = {"q": ics[:, 0], "r": ics[:, 1]} if ics.size else {"q": [], "r": []}

    def set_tracks(self, segments: list[tuple[np.ndarray, np.ndarray, str]]) -> None:
        self.tracks.data = {
            "xs": [s[0] for s in segments],
            "ys": [s[1] for s in segments],
            "color": [TYPE_COLORS.get(s[2], "#000000") for s in segments],
            "type": [s[2] for s in segments],
        }

    def set_equilibria(self, q: np.ndarray, r: np.ndarray, types: tuple[str, ...]) -> None:
        self.equilibria.data = {
            "q": list(q),
            "r": list(r),
            "color": [TYPE_COLORS.get(t, "#000000") for t in types],
            "type": list(types),
        }

    def set_tprime(self, values: np.ndarray | None, q: np.ndarray, r: np.ndarray, title: str) -> None:
        if values is None or values.size == 0:
            self.tprime.data = {"image": [], "x": [], "y": [], "dw": [], "dh": []}
            return
        # Symmetric colour scale about 0 so the sign is the colour; clip outliers.
        lim = float(np.percentile(np.abs(values), 98)) or 1.0
        self.tprime_mapper.update(low=-lim, high=lim)
        self.colorbar.title = title
        dq = (q[-1] - q[0]) / max(1, q.size - 1)
        dr = (r[-1] - r[0]) / max(1, r.size - 1)
        self.tprime.data = {
            "image": [values],
            "x": [q[0] - dq / 2],
            "y": [r[0] - dr / 2],
            "dw": [q[-1] - q[0] + dq],
            "dh": [r[-1] - r[0] + dr],
        }


class SeriesFigures:
    """q_k, r_k and T_k of the selected trajectory, sharing the k axis."""

    def __init__(self) -> None:
        self.source = ColumnDataSource({"k": [], "q": [], "r": [], "T": []}, name="series_source")
        self.figs: list[Any] = []
        first = None
        for col, label, color in zip(("q", "r", "T"), ("q_k", "r_k", "T_k (energy)"), Category10[3], strict=True):
            shared = {"x_range": first.x_range} if first is not None else {}
            f = figure(
                height=190,
                sizing_mode="stretch_width",
                x_axis_label="k",
                y_axis_label=label,
                tools="pan,wheel_zoom,box_zoom,reset,save",
                output_backend="canvas",  # a few hundred points: WebGL's blit would cost more than it saves
                **shared,
            )
            f.toolbar.logo = None
            f.line("k", col, source=self.source, line_color=color)
            f.scatter("k", col, source=self.source, size=3, color=color)
            self.figs.append(f)
            first = first or f

    def set(self, k: np.ndarray, q: np.ndarray, r: np.ndarray, energy: np.ndarray) -> None:
        self.source.data = {"k": k, "q": q, "r": r, "T": energy}
