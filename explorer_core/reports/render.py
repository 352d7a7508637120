"""Static PNG rendering (matplotlib, Agg) of explorer_core results.

Only pictures live here; every number comes from ``explorer_core``. Imported
lazily by the ``bilimovich chart`` and ``bilimovich reproduce`` commands, so the
core never needs matplotlib.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch

from explorer_core import export
from explorer_core.studies.bench import LINE_COLOURS

#: Colours of the non-periodic regimes (by regime name) in charts.
REGIME_COLOURS = {
    "chaotic": "#000000",
    "quasi_periodic": "#9a9a9a",
    "escaped": "#ffffff",
    "failed": "#d62728",
    "invalid": "#f3d9fa",
    "not_computed": "#e8e8e8",
}
_DPI = 110


def period_colours(p_max: int) -> list[str]:
    """Distinct colours for periods 1..p_max (1, 2, 4, 8 and 3, 6, 12 well apart)."""
    base = [
        "#1f77b4",  # 1
        "#2ca02c",  # 2
        "#ff7f0e",  # 3
        "#bcbd22",  # 4
        "#8c564b",  # 5
        "#e377c2",  # 6
        "#17becf",  # 7
        "#9467bd",  # 8
        "#7f7f00",  # 9
        "#aec7e8",  # 10
        "#98df8a",  # 11
        "#ff9896",  # 12
        "#c5b0d5",  # 13
        "#c49c94",  # 14
        "#f7b6d2",  # 15
        "#dbdb8d",  # 16
    ]
    out = list(base)
    while len(out) < p_max:
        out.extend(base)
    return out[:p_max]


def render_chart(chart: Any, path: str, ic: int = 0, title: str | None = None, filled: bool = True) -> None:
    """PNG of a chart of regimes: colour = period of the stable cycle, black = chaos, legend top right."""
    from explorer_core.analyses.regimes import REGIMES

    c = chart.filled() if filled else chart
    spec = c.spec
    code = c.code()[..., ic]
    code = np.where(c.computed, code, -REGIMES.index("not_computed"))
    p_max = spec.p_max
    names = list(REGIMES)
    # Colour index: 0..p_max-1 periods, then one per non-periodic regime.
    colours = period_colours(p_max) + [REGIME_COLOURS.get(n, "#ffffff") for n in names]
    idx = np.where(code > 0, code - 1, p_max + (-code))
    fig, ax = plt.subplots(figsize=(8.0, 5.6), dpi=_DPI)
    x, y = spec.x_values, spec.y_values
    dx = (x[-1] - x[0]) / max(1, x.size - 1) if x.size > 1 else 1.0
    dy = (y[-1] - y[0]) / max(1, y.size - 1) if y.size > 1 else 1.0
    ax.imshow(
        idx,
        origin="lower",
        aspect="auto",
        interpolation="nearest",
        cmap=ListedColormap(colours),
        vmin=-0.5,
        vmax=len(colours) - 0.5,
        extent=(x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2),
    )
    ax.set_xlabel(spec.x_param)
    ax.set_ylabel(spec.y_param)
    ax.set_title(title or f"Chart of regimes ({x.size} x {y.size})")
    present = set(np.unique(code[c.computed]).tolist()) if c.computed.any() else set()
    handles = [
        Patch(facecolor=colours[p - 1], edgecolor="k", label=f"period {p}") for p in range(1, p_max + 1) if p in present
    ]
    for n in ("quasi_periodic", "chaotic", "escaped", "failed", "invalid"):
        if -names.index(n) in present:
            handles.append(Patch(facecolor=REGIME_COLOURS[n], edgecolor="k", label=n.replace("_", "-")))
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.9, ncol=2 if len(handles) > 8 else 1)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_bifurcation(
    diagram: Any,
    path: str,
    coord: str = "q",
    title: str | None = None,
    sweeps: Sequence[str] | None = None,
    continuation: Any = None,
) -> None:
    """PNG of an orbit diagram: section coordinate ``coord`` against the parameter; sweeps overlaid.

    With ``continuation``, its branches over it (every point of each orbit; stable solid, unstable dashed)
    and the bifurcations marked.
    """
    col = {"q": 5, "r": 6}[coord]
    cols = diagram.long()
    s, vals, y = cols[0], cols[2], cols[col]
    fig, ax = plt.subplots(figsize=(8.0, 5.0), dpi=_DPI)
    colours = {"forward": "#1f77b4", "backward": "#d62728", "fixed": "#000000"}
    names = [str(v) for v in diagram.sweeps]
    for k, name in enumerate(names):
        if sweeps is not None and name not in sweeps:
            continue
        sel = s == k
        ax.plot(
            vals[sel], y[sel], ".", ms=0.6, mew=0, color=colours.get(name, "k"), alpha=0.6 if len(names) > 1 else 1.0
        )
        ax.plot([], [], "o", ms=5, color=colours.get(name, "k"), label=name)  # legend handle
    bad = ~diagram.drawn().all(axis=(0, 2))
    for v in np.flatnonzero(bad):
        ax.axvline(diagram.values[v], color="#f3c0c0", lw=0.5, zorder=0)
    if continuation is not None:
        _draw_branches(ax, continuation, 0 if coord == "q" else 1)
    ax.set_xlabel(diagram.param)
    ax.set_ylabel(f"{coord}_k")
    ax.set_title(title or f"Bifurcation diagram ({diagram.values.size} values)")
    if len(names) > 1:
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def _draw_branches(ax: Any, cont: Any, col: int) -> None:
    """Continued branches on an orbit diagram: each of the orbit's n points, stable solid, unstable dashed."""
    for br in cont.branches:
        vals = np.array(br.values)
        stable = br.stable
        orbit = np.array(br.orbits)  # (m, n, 2)
        # A segment is stable if either end is: the bifurcation points are on the branch, where stability changes.
        solid = stable[:-1] | stable[1:]
        for j in range(br.period):
            y = orbit[:, j, col]
            for i in range(len(vals) - 1):
                ax.plot(vals[i : i + 2], y[i : i + 2], "-" if solid[i] else "--",
                        color="#2ca02c" if solid[i] else "#7f7f7f", lw=0.9, zorder=3)  # fmt: skip
    for b in cont.bifurcations:
        ax.plot([b.value], [b.point[col]], "D", ms=4, color="#9467bd", zorder=4)
    ax.plot([], [], "-", color="#2ca02c", label="stable orbit (continuation)")
    ax.plot([], [], "--", color="#7f7f7f", label="unstable orbit")
    ax.plot([], [], "D", color="#9467bd", label="bifurcation")


def _section_panel(ax: Any, sec: Any, scene: Any, title: str) -> None:
    """Scatter of a section's valid points in the scene's plot window."""
    _, _, q, r = sec.long()
    ax.plot(q, r, ",", color="k", alpha=0.8, rasterized=True)
    ax.set_xlim(*scene.q_range)
    ax.set_ylim(*scene.r_range)
    ax.set_xlabel("q")
    ax.set_ylabel("r")
    ax.set_title(title, fontsize=9)


def render_sections(panels: Sequence[tuple[Any, Any, str]], path: str, suptitle: str = "") -> None:
    """PNG of several section panels ``(section, scene, title)`` side by side (2 x 2 for four)."""
    n = len(panels)
    rows, cols = (2, 2) if n == 4 else (1, n)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.8 * rows), dpi=_DPI, squeeze=False)
    for ax, (sec, scene, title) in zip(axes.ravel(), panels, strict=False):
        _section_panel(ax, sec, scene, title)
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_series(
    k: np.ndarray,
    series: Sequence[np.ndarray],
    fits: Sequence[tuple[np.ndarray, np.ndarray, str, str]],
    path: str,
    title: str = "",
    log: bool = False,
) -> None:
    """PNG of ``q_k`` (top) and ``r_k`` (bottom) for several trajectories, with fitted curves.

    ``series`` are (n, 2) arrays over ``k``; ``fits`` are ``(k_fit, values (n_fit, 2), label, style)``.
    """
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.0), dpi=_DPI, sharex=True)
    for x in series:
        for c in (0, 1):
            y = np.abs(x[:, c]) if log else x[:, c]
            axes[c].plot(k[: x.shape[0]], y, ".", ms=1.5, color="0.35")
    for kf, vals, label, style in fits:
        for c in (0, 1):
            y = np.abs(vals[:, c]) if log else vals[:, c]
            axes[c].plot(kf, y, style, lw=1.2, label=label)
    for c, name in enumerate(("q_k", "r_k")):
        axes[c].set_ylabel(f"|{name}|" if log else name)
        if log:
            axes[c].set_yscale("log")
        if fits:
            axes[c].legend(fontsize=7, loc="best")
    axes[1].set_xlabel("k")
    if title:
        axes[0].set_title(title, fontsize=9)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_convergence(results: Sequence[tuple[str, Any, Sequence[float] | None]], path: str) -> None:
    """PNG of running Lyapunov estimates (per unit time) against k, one panel per result.

    ``results`` are ``(title, LyapunovResult, paper (L1, L2) or None)``.
    """
    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(4.4 * n, 3.6), dpi=_DPI, squeeze=False)
    for ax, (title, res, paper) in zip(axes[0], results, strict=True):
        for i in range(res.ics.shape[0]):
            run = res.running(i)
            k = np.arange(1, run.shape[0] + 1)
            ax.plot(k, run[:, 0], color="#1f77b4", lw=0.7, alpha=0.7)
            ax.plot(k, run[:, 1], color="#d62728", lw=0.7, alpha=0.7)
        if paper is not None:
            for v, c in zip(paper, ("#1f77b4", "#d62728"), strict=True):
                ax.axhline(v, color=c, ls="--", lw=1.0)
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.set_xscale("log")
        ax.set_xlabel("measured periods k")
        ax.set_ylabel("running exponent (per unit time)")
        ax.set_title(title + " (dashed: paper)", fontsize=9)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


class _Stopped(Exception):
    """The figures of a reproduction stop being drawn (a stop signal)."""


def render_reproduction(rep: Any, outdir: str, cancel: Callable[[], bool] | None = None) -> list[str]:
    """Every figure of the paper from a :class:`explorer_core.studies.reproduce.Reproduction`; returns the paths.

    None for a reproduction that was stopped, and no more once ``cancel()`` is true (a stop signal while they
    are drawn): drawing them took seconds after the stop (6.4 s after a SIGTERM). The numbers are in the
    table and the JSON; ``rep.lost`` says which figures were not drawn.
    """
    import os

    from explorer_core.losses import Loss

    out: list[str] = []

    def path(name: str) -> str:
        if not rep.completed or (cancel is not None and cancel()):
            raise _Stopped
        p = os.path.join(outdir, name)
        out.append(p)
        return p

    try:
        _reproduction_figures(rep, path)
    except _Stopped:
        what = "figures" if not out else f"figures after {os.path.basename(out[-1])}"
        rep.lost.append(Loss(what, 1, "not drawn: the run was stopped (run it again for them)"))
    return out


def _reproduction_figures(rep: Any, path: Callable[[str], str]) -> None:
    """Draw the figures of ``rep``, each at ``path(name)``."""
    from explorer_core.scenes import get_scene
    from explorer_core.studies.reproduce import PAPER, SECTION_FIGURES

    P = np.polynomial.polynomial
    for fig, sids in SECTION_FIGURES.items():
        if fig == "fig9" or not all(s in rep.sections for s in sids):
            continue
        panels = []
        for sid in sids:
            sc = get_scene(sid)
            panels.append((rep.sections[sid], sc, f"{sc.figure}: {sc.title}"))
        render_sections(panels, path(f"{fig}.png"))
    if "fig3" in rep.drift:
        fit = rep.drift["fig3"]
        x = rep.series["fig3"]
        k = np.arange(x.shape[0])
        cq, cr = fit.mean()
        kf = fit.k
        ours = np.column_stack([P.polyval(kf, cq), P.polyval(kf, cr)])
        pq, pr = PAPER["fig3"]["q"], PAPER["fig3"]["r"]
        paper = np.column_stack([P.polyval(kf, pq), P.polyval(kf, pr)])
        render_series(
            k,
            [x],
            [
                (kf, ours, "our fit (mean of members), k = 200..900", "b-"),
                (kf, paper, "paper's polynomials, read in k", "r--"),
            ],
            path("fig3.png"),
            "Fig. 3: q_k, r_k from (0, 8), diag(1,2,4), alpha = 0.1",
        )
    if "fig9" in rep.drift and "fig9" in rep.sections:
        fit = rep.drift["fig9"]
        k = np.arange(fit.series.shape[1])
        cq, cr = fit.mean()
        fits = [(k, np.column_stack([P.polyval(k, cq), P.polyval(k, cr)]), "mean 6th-order fit", "b-")]
        render_series(
            k,
            list(fit.series),
            fits,
            path("fig9_series.png"),
            "Fig. 9: |q_k|, |r_k| of trajectories leaving the attractor, alpha = -0.45",
            log=True,
        )
        sc = get_scene("fig9")
        render_sections([(rep.sections["fig9"], sc, f"{sc.figure}: {sc.title}")], path("fig9.png"))
    if rep.bifurcation is not None:
        render_bifurcation(
            rep.bifurcation,
            path("fig10.png"),
            title="Fig. 10: bifurcation diagram (blue: forward, red: backward sweep) and continued orbits",
            continuation=rep.cascade,
        )
    if rep.chart is not None:
        ics = rep.chart.spec.ics
        for i in range(ics.shape[0]):
            name = "fig11.png" if i == 0 else f"fig11_ic{i + 1}.png"
            title = f"Fig. 11: chart of regimes, IC ({ics[i, 0]:g}, {ics[i, 1]:g}) in every pixel"
            render_chart(rep.chart, path(name), ic=i, title=title)
    if rep.lyapunov:
        res = []
        for sid, title in (
            ("fig4A", "Fig. 4A, alpha = 0.1"),
            ("fig4B", "Fig. 4B, alpha = -0.1"),
            ("fig8B", "Fig. 8B, alpha = -0.45"),
        ):
            if sid in rep.lyapunov:
                paper = PAPER["fig4"] if sid.startswith("fig4") else PAPER["fig8B"]
                res.append((title, rep.lyapunov[sid], (paper["L1"], paper["L2"])))
        render_convergence(res, path("lyapunov_convergence.png"))


_WP_COLOURS = LINE_COLOURS


def render_work_precision(data: dict[str, Any], path: str) -> None:
    """PNG of work-precision diagrams from a ``bench.json`` dict: one log-log panel per case.

    Error against the reference (y) over wall time per trajectory (x), one line per method and
    implementation (dashed: our batch mode, per-trajectory share of the batch), the reference's
    error bound as a dotted floor. Failed points (no error) are left out.
    """
    cases = list(data["cases"])
    n = max(1, len(cases))
    cols = 2 if n > 1 else 1
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 4.6 * rows), dpi=_DPI, squeeze=False)
    for ax, name in zip(axes.ravel(), cases, strict=False):
        info = data["cases"][name]
        lines: dict[str, list[dict[str, Any]]] = {}
        for row in data["rows"]:
            if row["case"] == name and row["error"] is not None and row["error"] > 0:
                lines.setdefault(row["series"], []).append(row)
        for series, pts in lines.items():  # rows come in the order of their settings, loose to tight
            colour = _WP_COLOURS.get((pts[0]["implementation"], pts[0]["method"]), "k")
            batch = pts[0]["mode"] == "batch"
            ax.plot(
                [r["time_per_traj_s"] for r in pts],
                [r["error"] for r in pts],
                "--" if batch else "-",
                marker="s" if batch else "o",
                ms=3.5,
                lw=1.1,
                color=colour,
                label=series,
            )
        bound = info.get("reference_bound")
        if bound:
            ax.axhline(bound, color="0.5", ls=":", lw=1.0, label="reference bound")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per trajectory (s)")
        ax.set_ylabel("max error over k = 1..K")
        ax.set_title(
            f"{name} ({info.get('scene', '')}), K = {info['horizon']} periods"
            + ("" if info["horizon"] == info["k_max"] else " (chaos horizon)"),
            fontsize=9,
        )
        ax.grid(True, which="major", color="0.9", lw=0.6)
    for ax in axes.ravel()[len(cases) :]:
        ax.set_visible(False)
    handles, labels = {}, []
    for ax in axes.ravel()[: len(cases)]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in handles:
                handles[lab] = h
                labels.append(lab)
    fig.legend([handles[lab] for lab in labels], labels, loc="lower center", ncol=min(5, len(labels)), fontsize=7,
               frameon=False)  # fmt: skip
    fig.tight_layout(rect=(0, 0.06 + 0.02 * (len(labels) // 5), 1, 1))
    export.save_figure(fig, path)
    plt.close(fig)
