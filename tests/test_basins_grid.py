"""Basins: a pixel's kind does not depend on the grid around it (Fig. 4A: a chaotic sea around an island).

Fig. 4A's quasi-attractor is chaotic and weakly dissipative (Lyapunov sum about -0.02 per unit time), the
island around the elliptic point is conservative. On the code before the chaotic sets were measured over
``CHAOTIC_BLOCKS`` blocks (main a4bc0e5), whether a located chaotic set was called conservative hung on one
300-period window of ``log |det DP^k|`` (it wanders from +5.8 to -60 there): 22 of the 100 pixels of a 10x10
grid were chaotic, and the same initial conditions in a 30x30 grid (every third pixel is a 10x10 pixel)
conservative, the chaotic attractor's basin 24 % against 0.25 % at 20x20.
"""

from __future__ import annotations

import numpy as np
import pytest

from explorer_core.analyses.basins import basins
from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.scenes import get_scene

FIG4A = get_scene("fig4A")


def _kinds(b) -> np.ndarray:
    out = np.empty(b.label.shape, dtype=object)
    for idx, lab in np.ndenumerate(b.label):
        out[idx] = b.attractor(int(lab)).kind if lab >= 0 else int(lab)
    return out


@pytest.mark.slow
def test_fig4a_kinds_do_not_depend_on_the_grid() -> None:
    coarse = basins(FIG4A.params, FIG4A.box, (10, 10))
    fine = basins(FIG4A.params, FIG4A.box, (30, 30))
    assert np.allclose(fine.q[1::3], coarse.q) and np.allclose(fine.r[1::3], coarse.r)
    a, b = _kinds(coarse), _kinds(fine)[1::3, 1::3]
    for res in (coarse, fine):
        kinds = {x.kind for x in res.attractors}
        assert "chaotic" in kinds and "conservative" in kinds, kinds
    chaotic = [x for x in fine.attractors if x.kind == "chaotic"]
    assert all(x.attracting and x.log_det < -10 for x in chaotic)
    share = lambda k: float(np.mean(k == "chaotic"))  # noqa: E731
    assert abs(share(a) - share(b)) <= 0.05, (share(a), share(b))
    differ = np.argwhere(a != b)
    # Orbits that stick near the island's edge for hundreds of periods before joining the chaotic sea take
    # the island's label when its cells are met first (a known limit, at most a few pixels at the boundary)
    assert len(differ) <= 5, differ
    # What the pixels called chaotic in both grids are: a positive exponent and a contracting area over a
    # long run of the tangent system started at the pixel itself (not the basin code's sets); a sum of
    # -1e-3 per unit time is a log det of -25 over the run, an island curve gives 1e-5
    both = np.argwhere((a == "chaotic") & (b == "chaotic"))[:4]
    ics = np.array([[coarse.q[i], coarse.r[j]] for j, i in both])
    ly = lyapunov_spectrum(FIG4A.params, ics, 4000, transient=0)
    assert np.all(ly.exponents[:, 0] > 5e-3) and np.all(ly.exponents.sum(axis=1) < -1e-3), ly.exponents
