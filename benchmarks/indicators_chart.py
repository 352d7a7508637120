"""The chaos indicators' chart for docs/indicators.md: agreement with a long Lyapunov run against periods and time.

    PYTHONPATH=. .venv/bin/python benchmarks/indicators_chart.py [--json docs/figures/indicators.json]
        [--out docs/figures/indicators.png]

Draws the result of ``benchmarks/indicators_speed.py --json FILE``
(:func:`explorer_core.studies.indicator_bench.measure`) as two panels: the percentage of initial conditions each
indicator classifies as the reference does (neither the opposite verdict nor undecided) against the periods it was
given per orbit, and against the batch's seconds; solid lines for the regular set (Fig. 5A's island), dashed for the
chaotic one (Fig. 8B's attractor), the reference a black star at 100 %. The points are those the speed tab draws
(:func:`app.bench_tab.indicator_columns`: the same columns).
matplotlib is imported here only (the package never draws with it).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from app.bench_tab import indicator_columns

HERE = Path(__file__).resolve().parents[1]


def draw(report: dict, out: str) -> None:
    """Write the two-panel PNG of ``report`` to ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines, pts = indicator_columns(report)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True, constrained_layout=True)
    for ax, along in zip(axes, ("periods", "seconds"), strict=True):
        for xs, ys, colour, dash, label in zip(
            *(lines[k] for k in ("xs", "ys", "color", "dash", "label")), strict=True
        ):
            x = xs if along == "periods" else [pts["seconds"][j] for j, lab in enumerate(pts["label"]) if lab == label]
            ax.plot(x, ys, color=colour, linestyle=dash, marker="o", markersize=4, label=label)
        refs = [j for j, lab in enumerate(pts["label"]) if lab.startswith("Lyapunov reference")]
        for j in refs:
            x = pts["x"][j] if along == "periods" else pts["seconds"][j]
            ax.plot([x], [100.0], marker="*", markersize=12, color="black", linestyle="none",
                    label="Lyapunov reference" if j == refs[0] else None)  # fmt: skip
        ax.set_xscale("log")
        ax.set_ylim(-5, 105)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel(
            "periods given to each orbit" if along == "periods" else "seconds of the batch (all ICs of a set)"
        )
    axes[0].set_ylabel("ICs classified as the long Lyapunov run (%)")
    axes[1].legend(fontsize=8, loc="lower right")
    fig.suptitle(f"Chaos indicators against a {report['reference_periods']}-period Lyapunov exponent, {report['n']} "
                 "ICs a set (solid: Fig. 5A's island, dashed: Fig. 8B's attractor)", fontsize=11)  # fmt: skip
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=str(HERE / "docs" / "figures" / "indicators.json"))
    ap.add_argument("--out", default=str(HERE / "docs" / "figures" / "indicators.png"))
    args = ap.parse_args()
    with open(args.json) as fh:
        report = json.load(fh)
    draw(report, args.out)
    print(args.out)


if __name__ == "__main__":
    main()
