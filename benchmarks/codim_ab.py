"""A/B workload of issue 33's continuation (docs/continuation.md): whole processes timed from outside, this
checkout against another (each with its own PYTHONPATH).

    python benchmarks/codim_ab.py chart  # Fig. 11's window: a 20 x 10 chart (three ICs, 100 + 100 periods) and
                                         # its boundaries (periods 1, 2, 3, 4, 6: fold, flip, NS curves in I11)
    bilimovich continue --scene fig10 --param alpha --range=-0.35,-0.42 --from=-0.0959,-1.962 --switch  # the other

Prints the number of curves and codimension-two points, so that A and B are seen to do the same work.
"""

from __future__ import annotations

import sys

import numpy as np

from explorer_core.analyses.continuation import chart_boundaries
from explorer_core.analyses.regimes import chart_spec, regime_chart
from explorer_core.scenes import get_scene

FIG11 = get_scene("fig11").params
ICS = np.array([(-0.09, -2.0), (-0.5, -1.0), (-0.1744, -2.1855)])


def chart() -> None:
    spec = chart_spec(FIG11, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (20, 10), ics=ICS, transient=100, periods=100)
    ch = regime_chart(spec)
    b = chart_boundaries(ch, periods=(1, 2, 3, 4, 6))
    curves = [cu for part in b for cu in part.curves]
    print(len(curves), "curves,", sum(len(cu.codim2) for cu in curves), "codimension-two points")


if __name__ == "__main__":
    {"chart": chart}[sys.argv[1]]()
