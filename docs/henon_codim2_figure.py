"""The picture of docs/continuation.md: the Henon map's (a, b) plane with its fold, flip and Neimark-Sacker curves
and their codimension-two points, as the app draws them (``app.holo.draw_curves``, ``app.figures``), over the
closed forms (red dots). ``tests/test_codim2.py`` checks every curve and point against those closed forms.

    python docs/henon_codim2_figure.py  # writes docs/figures/henon_codim2.png
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import holoviews as hv
import numpy as np

from app import figures, holo
from explorer_core.analyses.continuation import Curve, continue_map
from explorer_core.analyses.continuation.testmaps import Henon

OUT = Path(__file__).parent / "figures" / "henon_codim2.png"
BOX = {"a": (-1.5, 4.5), "b": (-1.5, 0.6)}


def swapped(res):
    """A continuation in (b, a) as one in (a, b): its curves' rows and points with the two parameters swapped."""

    def point(c):
        return dataclasses.replace(c, values=(c.values[1], c.values[0]))

    curves = [Curve(cu.kind, cu.period, [(r[1], r[0], r[2], r[3]) for r in cu.rows], cu.stop, cu.status,
                    [point(c) for c in cu.codim2]) for cu in res.curves]  # fmt: skip
    return dataclasses.replace(res, param=res.param2, param2=res.param, curves=curves)


def main() -> None:
    fold = continue_map(Henon(b=0.3), "a", (-0.1, -0.2), Henon.fixed_point(-0.1, 0.3), 1, param2="b",
                        range2=BOX["b"], window1=BOX["a"])  # fmt: skip
    flip = continue_map(Henon(b=0.3), "a", (0.2, 1.0), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                        range2=BOX["b"], window1=BOX["a"], switch=True, max_period=2)  # fmt: skip
    ns = continue_map(Henon(a=1.0, b=-0.9), "b", (-0.9, -1.1), Henon.fixed_point(1.0, -0.9), 1, param2="a",
                      range2=BOX["a"])  # fmt: skip
    b = np.linspace(*BOX["b"], 200)
    # over the curves, thin and dotted: where the two agree the dots run along the curve's middle
    style = {"color": "#d62728", "line_width": 1.2, "line_dash": "2 2"}
    exact = [hv.Curve((-((1 - b) ** 2) / 4, b), "a", "b", label="closed forms (fold, flip)").opts(**style),
             hv.Curve((3 * (1 - b) ** 2 / 4, b), "a", "b").opts(**style)]  # fmt: skip
    drawn = holo.draw_curves([fold, flip, swapped(ns)])
    obj = hv.Overlay([*drawn, *exact]).opts(xlim=BOX["a"], ylim=BOX["b"])
    request = figures.FigureRequest("png", 1600, 1000, 200)
    title = ("Henon map (x, y) -> (1 - a x^2 + y, b x): fold, flip and Neimark-Sacker curves of its fixed point "
             "(and the flip and Neimark-Sacker curves of the 2-cycle switched onto at R2)")  # fmt: skip
    OUT.write_bytes(figures.figure_bytes(obj, request, title, "docs/henon_codim2_figure.py"))


if __name__ == "__main__":
    main()
