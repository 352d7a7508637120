"""PNG pictures of the failure map (``explorer_core.studies.failures``), in the style of ``app/render.py``.

Only pictures: every number comes from the :class:`~explorer_core.studies.failures.FailureMap`.
Imported lazily by ``bilimovich failures`` so the core never needs matplotlib.
"""

from __future__ import annotations

import os
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from explorer_core import export
from explorer_core.reports.render import _DPI, period_colours

#: Status colours (ok, escaped, step_collapsed, too_many_steps, nonfinite; refused: a time the doubles cannot resolve).
STATUS_COLOURS = {
    "ok": "#2ca02c",
    "escaped": "#ff7f0e",
    "step_collapsed": "#9467bd",
    "too_many_steps": "#8c564b",
    "nonfinite": "#d62728",
    "refused": "#7f7f7f",
}


def _colours(n: int) -> list[str]:
    return period_colours(max(n, 1))[:n]


def render_rk4_drift(rk4: Any, path: str) -> None:
    """``r_k`` and the relative error against ``k`` for RK4 at several steps per period, with DOP853."""
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.4), dpi=_DPI)
    k = rk4.k
    cols = _colours(rk4.steps.size)
    ax = axes[0]
    ax.plot(k, np.abs(rk4.reference[:, 1]), "k-", lw=2.0, label="reference (DOP853 1e-13)")
    for j, n in enumerate(rk4.steps):
        x = rk4.points[j, :, 1]
        ok = np.isfinite(x)
        ax.plot(k[ok], np.abs(x[ok]), "-", lw=1.0, color=cols[j], label=f"rk4 N={n}")
        if not ok.all() and ok.any():
            last = np.flatnonzero(ok)[-1]
            ax.plot(k[last], abs(x[last]), "x", ms=8, mew=2, color=cols[j])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("k (periods from |r| = 20 on the curve)")
    ax.set_ylabel("|r_k|")
    ax.set_title("Fig. 1A drift: RK4 stalls at spurious fixed points (x: nonfinite)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax = axes[1]
    for j, n in enumerate(rk4.steps):
        e = rk4.error[j]
        ok = np.isfinite(e) & (e > 0)
        ax.plot(k[ok], e[ok], "-", lw=1.0, color=cols[j], label=f"rk4 N={n}")
    for name, style in (("dop853 1e-10", "k--"), ("dop853 1e-6", "k:")):
        if name in rk4.adaptive:
            e = rk4.adaptive[name]["error"]
            ok = np.isfinite(e) & (e > 0)
            ax.plot(k[ok], e[ok], style, lw=1.2, label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("k")
    ax.set_ylabel("|x_k - x_ref| / (1 + |x_ref|)")
    ax.set_title("relative error against the reference", fontsize=9)
    ax.legend(fontsize=7, loc="lower right", ncol=2)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_rk4_local(rk4: Any, path: str) -> None:
    """One period of RK4 from points of the drift: error, drift step and failures against ``rho h``."""
    lm = rk4.local
    th = lm.thresholds()
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.4), dpi=_DPI)
    cols = _colours(lm.r0.size)
    for ax, values, ylabel, log in (
        (axes[0], lm.error, "relative error after one period", True),
        (axes[1], lm.step_ratio, "RK4 drift step / reference drift step", False),
    ):
        for i, r0 in enumerate(lm.r0):
            ok = lm.status[i] == 0
            ax.plot(lm.z[i, ok], values[i, ok], "o-", ms=3, lw=0.8, color=cols[i], label=f"|r| = {r0:.0f}")
            failed = ~ok
            if failed.any():
                y = np.full(failed.sum(), 1.0 if log else 0.0)
                ax.plot(lm.z[i, failed], y, "x", ms=6, color=cols[i])
        ax.set_xscale("log")
        if log:
            ax.set_yscale("log")
        else:
            ax.set_ylim(-3, 3)
            ax.axhspan(0.9, 1.1, color="0.85", zorder=0)
        ax.set_xlabel("rho h: fastest rate x step  (= |r| h / 3 on the drift)")
        ax.set_ylabel(ylabel)
        for key, colour, ls, lab, y in (("z_drift_lost_min", "m", "--", "drift lost", 0.93),
                                        ("z_unstable_min", "r", "-", "unstable", 0.85)):  # fmt: skip
            v = th.get(key)
            if v is not None:
                ax.axvline(v, color=colour, ls=ls, lw=1.0)
                ax.text(v, y, f" {lab} ({v:.2g})", color=colour, fontsize=7, transform=ax.get_xaxis_transform())
    axes[0].set_title(f"x: overflow (nonfinite); reference {lm.reference_kind}", fontsize=9)
    axes[1].set_title("grey band: within 10 %; x: overflow", fontsize=9)
    axes[1].legend(fontsize=7, loc="lower left", ncol=2)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_adaptive_cost(cost: Any, rk4: Any | None, path: str) -> None:
    """Steps per period against ``|r|`` (with stability floors), along the drift against ``k``, and scaling."""
    fig, axes = plt.subplots(1, 3, figsize=(15.0, 4.4), dpi=_DPI)
    ax = axes[0]
    keys = list(cost.steps)
    for method, cmap, marker in (("dop853", plt.cm.Blues, "o-"), ("dp5", plt.cm.Oranges, "s--")):
        mine = [k for k in keys if k[0] == method]
        for j, key in enumerate(mine):
            shade = cmap(0.4 + 0.6 * j / max(1, len(mine) - 1))
            ax.plot(cost.r0, cost.steps[key], marker, ms=3, lw=1.0, color=shade, label=f"{method} {key[1]:g}")
    for method, style in (("dp5", "k--"), ("dop853", "k-")):
        ax.plot(cost.r0, cost.floor(method), style, lw=0.8, alpha=0.6, label=f"{method} stability floor")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("|r| on the drift")
    ax.set_ylabel("steps per period")
    ax.set_title("adaptive cost grows with |r|; loose tolerances hit the floor", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    ax = axes[1]
    if rk4 is not None:
        ax.plot(rk4.k, rk4.ref_steps, "k-", lw=1.0, label="dop853 1e-13 (reference)")
        for name, style in (("dop853 1e-10", "b-"), ("dop853 1e-6", "g-")):
            if name in rk4.adaptive:
                ax.plot(rk4.k, rk4.adaptive[name]["steps_per_period"], style, lw=1.0, label=name)
        for n in rk4.steps:
            if n in (100, 400, 1600):
                ax.axhline(n, color="0.5", ls=":", lw=0.8)
                ax.text(rk4.k[0], n, f" rk4 N={n}", fontsize=7, va="bottom", color="0.4")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
    ax.set_xlabel("k (from |r| = 20)")
    ax.set_ylabel("steps per period")
    ax.set_title("cost along the drift", fontsize=9)
    ax = axes[2]
    sc = cost.scaling
    for key, xs_key, style, lab in (("vs_periods", "periods", "o-", "periods (fixed ICs)"),
                                    ("vs_ics", "ics", "s-", "initial conditions (fixed periods)")):  # fmt: skip
        d = sc[key]
        xs = np.asarray(d[xs_key], dtype=float)
        line = ax.plot(xs / xs[0], np.asarray(d["steps"], float) / d["steps"][0], style, ms=4,
                       label=f"{lab}: steps ~ x^{d['steps_exponent']}")  # fmt: skip
        ax.plot(xs / xs[0], np.asarray(d["cpu_s"], float) / d["cpu_s"][0], style[0] + ":", ms=3,
                color=line[0].get_color(), label=f"  CPU time ~ x^{d['cpu_exponent']}")  # fmt: skip
    ax.plot([1, 16], [1, 16], "k-", lw=0.6, alpha=0.5, label="linear")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("work relative to the smallest")
    ax.set_ylabel("steps (solid) and CPU time (dotted), relative")
    ax.set_title(f"fig1C sections, {sc['numerics']}; 2-core speedup {sc['parallel']['speedup']}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_collapse(collapse: dict[str, Any], path: str) -> None:
    """Status of one DOP853 period against the size of ``t0`` for several tolerances."""
    names = list(STATUS_COLOURS)
    tols = list(collapse["by_tol"])
    grid = np.array([[names.index(s) for s in collapse["by_tol"][t]["status"]] for t in tols])
    fig, ax = plt.subplots(figsize=(8.0, 2.2 + 0.35 * len(tols)), dpi=_DPI)
    ax.imshow(grid, cmap=ListedColormap(list(STATUS_COLOURS.values())), vmin=-0.5, vmax=len(names) - 0.5,
              aspect="auto")  # fmt: skip
    ex = collapse["t0_exponents"]
    ax.set_xticks(range(len(ex)), [f"1e{e}" for e in ex], fontsize=7)
    ax.set_yticks(range(len(tols)), [f"tol {t}" for t in tols], fontsize=8)
    ax.set_xlabel("t0 (section phase): the size of t")
    ax.set_title(f"one period of DOP853 on {collapse['scene']} from {tuple(collapse['ic'])}: status", fontsize=9)
    present = sorted(set(grid.ravel().tolist()))
    ax.legend(handles=[Patch(facecolor=STATUS_COLOURS[names[i]], label=names[i]) for i in present], fontsize=7,
              loc="upper left", bbox_to_anchor=(1.0, 1.0))  # fmt: skip
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_float(floats: Any, path: str) -> None:
    """Section error against ``k``: RK4 in float64, float32 and float32 with a float64 clock."""
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2), dpi=_DPI)
    styles = {"float64": "k-", "float32": "r-", "float32, float64 clock": "b--"}
    for ax, data, title in (
        (axes[0], floats.error, f"Fig. 1A island orbits, RK4 N={floats.steps}, against DOP853 1e-13"),
        (axes[1], floats.chaotic_error, f"Fig. 8B attractor, RK4 N={floats.chaos_steps}, against DOP853 1e-13"),
    ):
        for name, e in data.items():
            k = np.arange(1, e.size + 1)
            ok = np.isfinite(e) & (e > 0)
            ax.plot(k[ok], e[ok], styles.get(name, "-"), lw=1.0, label=name)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("k")
        ax.set_ylabel("max relative error over the ICs")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_lyapunov(lyap: Any, path: str) -> None:
    """Lambda_1 and Lambda_2 of Fig. 8B per setting, with the ensemble's standard error."""
    all_rows = lyap.rows()
    rows = [r for r in all_rows if r["L1"] is not None]
    failed = [f"{r['setting']}: {r['statuses']}" for r in all_rows if r["L1"] is None]
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.0), dpi=_DPI)
    y = np.arange(len(rows))
    ref = next(r for r in rows if r["setting"] == lyap.reference) if rows else None
    for ax, key in ((axes[0], "L1"), (axes[1], "L2")):
        vals = np.array([r[key] for r in rows])
        errs = np.array([r[f"{key}_sem"] for r in rows])
        ax.errorbar(vals, y, xerr=errs, fmt="o", ms=4, color="k", ecolor="0.4", capsize=2)
        if ref is not None:
            ax.axvspan(ref[key] - ref[f"{key}_sem"], ref[key] + ref[f"{key}_sem"], color="#cfe2f3", zorder=0)
        ax.set_yticks(y, [r["setting"] for r in rows], fontsize=8)
        ax.set_xlabel(f"{key} per unit time (mean +- standard error over the ensemble)")
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.invert_yaxis()
    axes[0].set_title(f"Fig. 8B; band: the reference ({lyap.reference})", fontsize=9)
    if failed:
        axes[1].set_title("no exponents: " + "; ".join(failed), fontsize=8)
    fig.tight_layout()
    export.save_figure(fig, path)
    plt.close(fig)


def render_failures(fm: Any, outdir: str) -> list[str]:
    """Every picture of a :class:`~explorer_core.studies.failures.FailureMap`; returns the paths."""
    out: list[str] = []

    def path(name: str) -> str:
        p = os.path.join(outdir, name)
        out.append(p)
        return p

    if fm.rk4 is not None:
        render_rk4_drift(fm.rk4, path("failure_rk4_drift.png"))
        render_rk4_local(fm.rk4, path("failure_rk4_local.png"))
    if fm.cost is not None:
        render_adaptive_cost(fm.cost, fm.rk4, path("failure_adaptive_cost.png"))
    if fm.collapse:
        render_collapse(fm.collapse, path("failure_step_collapse.png"))
    if fm.floats is not None:
        render_float(fm.floats, path("failure_float32.png"))
    if fm.lyapunov is not None:
        render_lyapunov(fm.lyapunov, path("failure_lyapunov.png"))
    return out
