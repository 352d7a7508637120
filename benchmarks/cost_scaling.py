"""Cost linear in the work (issue 32, item 4): sections in periods and ICs, charts in pixels, basins in cells.

    .venv/bin/python benchmarks/cost_scaling.py [--repeat 3] [--png docs/figures/cost_scaling.png] [--json out.json]

Each point is a ``bilimovich`` command as typed, run in this process (``explorer_core.cli.main``, output to a
temporary folder), once untimed (kernels loaded, scene built) and then ``--repeat`` times: the median wall
seconds, on every core (``BILIMOVICH_THREADS`` as set). The fitted exponent of each series is the slope of
log(time) against log(work) by least squares (and between the two largest runs: the marginal cost): 1.0 is
linear; below 1 the fixed cost of a command (the scene, the first block, writing the file) is still visible at the
small end. The PNG is a log-log plot of the series,
each against its own unit of work, with the fitted exponents in the legend (matplotlib imported only to draw).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from explorer_core import cli

SECTION = ["section", "--scene", "fig1C", "--method", "auto", "--rtol", "1e-10", "--json"]
CHART = ["chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.6,-0.4", "--y-param", "I11",
         "--y-range", "1,2", "--ic", "-0.09,-2", "--out", "ch.npz", "--quiet"]  # fmt: skip
BASINS = ["basins", "--inertia", "1.6,2,4,0,0.5,0.3", "--alpha", "-0.5", "--box=-1.7,1.5,-3,1", "--out", "b.npz",
          "--quiet"]  # fmt: skip

#: series -> (unit of work, [(work, argv)]).
SERIES: dict[str, tuple[str, list[tuple[int, list[str]]]]] = {
    "section: periods (64 ICs)": ("periods", [(k, [*SECTION, "--random", "64", "--periods", str(k)])
                                              for k in (125, 250, 500, 1000, 2000)]),
    "section: ICs (250 periods)": ("ICs", [(n, [*SECTION, "--random", str(n), "--periods", "250"])
                                           for n in (32, 64, 128, 256, 512)]),
    "chart: pixels (fig11, 1 IC)": ("pixels", [(g * g, [*CHART, "--grid", f"{g},{g}"]) for g in (5, 10, 20, 40)]),
    "basins: cells": ("cells", [(g * g, [*BASINS, "--grid", f"{g},{g}"]) for g in (10, 20, 40, 80)]),
}  # fmt: skip


def timed(argv: list[str], repeat: int) -> float:
    """Median wall seconds of ``bilimovich argv`` in this process after one untimed run."""
    walls = []
    for i in range(repeat + 1):
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = cli.main(argv)
        if status:
            raise SystemExit(f"{' '.join(argv)}: exit status {status}")
        if i:
            walls.append(time.perf_counter() - t0)
    return statistics.median(walls)


def slope(work: list[int], sec: list[float]) -> float:
    """Least-squares slope of log(sec) against log(work)."""
    return float(np.polyfit(np.log(work), np.log(sec), 1)[0])


def plot(results: dict[str, dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.6), dpi=110)
    for name, r in results.items():
        w, s = np.array(r["work"], float), np.array(r["seconds"])
        ax.loglog(
            w / w[0], s, "o-", label=f"{name}: exponent {r['exponent']:.2f} ({r['exponent_last_two']:.2f} at the end)"
        )
        ax.loglog(w / w[0], s[-1] * (w / w[-1]), ":", color=ax.lines[-1].get_color(), lw=0.8)
    ax.set_xlabel("work relative to the smallest run of the series (periods, ICs, pixels, cells)")
    ax.set_ylabel("wall seconds (median, every core)")
    ax.set_title("Cost against work, commands as typed (dotted: linear through the largest run)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", help="comma-separated prefixes of series names (section, chart, basins)")
    ap.add_argument("--png", help="write the log-log plot here")
    ap.add_argument("--json", help="write the figures here")
    a = ap.parse_args()
    names = [n for n in SERIES if not a.only or any(n.startswith(p) for p in a.only.split(","))]
    load0 = os.getloadavg()[0]
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        here = os.getcwd()
        os.chdir(tmp)
        try:
            for name in names:
                unit, runs = SERIES[name]
                sec = [timed(argv, a.repeat) for _, argv in runs]
                work = [w for w, _ in runs]
                results[name] = {
                    "unit": unit,
                    "work": work,
                    "seconds": sec,
                    "exponent": slope(work, sec),
                    "exponent_last_two": slope(work[-2:], sec[-2:]),
                }
                cells = ", ".join(f"{w} {unit}: {s:.3f} s" for w, s in zip(work, sec, strict=True))
                print(
                    f"{name}: exponent {results[name]['exponent']:.2f}, between the two largest "
                    f"{results[name]['exponent_last_two']:.2f} ({cells})",
                    flush=True,
                )
        finally:
            os.chdir(here)
    print(f"load average before {load0:.2f} / after {os.getloadavg()[0]:.2f} (1 min); median of {a.repeat}")
    if a.json:
        Path(a.json).write_text(json.dumps({"load": [load0, os.getloadavg()[0]], "series": results}, indent=1))
    if a.png:
        plot(results, a.png)


if __name__ == "__main__":
    main()
