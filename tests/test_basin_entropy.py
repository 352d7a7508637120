"""Basin entropy S_b, boundary basin entropy S_bb (Daza et al. 2016) and the uncertainty exponent: exact values on
synthetic grids, a fractal and a smooth boundary, a plain-Python reference, metamorphic checks, the basins' result."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from naive import naive_basin_entropy, naive_uncertain_fraction
from scipy.stats import binom

from explorer_core.analyses.basin_entropy import (
    FRACTAL,
    MIN_BOUNDARY_BOXES,
    NO_BOUNDARY,
    SMOOTH,
    UNDECIDED,
    basin_entropy,
    default_eps,
    uncertainty_exponent,
)
from explorer_core.analyses.basins import ESCAPE, FAILED, NOT_COMPUTED, basin_spec, basins
from explorer_core.analyses.basins import UNDECIDED as UNDECIDED_LABEL
from explorer_core.scenes import get_scene
from explorer_core.status import Status
from explorer_core.system.params import ParameterError

LOG2 = math.log(2.0)


def gibbs(*p: float) -> float:
    """The Gibbs entropy of the fractions ``p`` (natural log)."""
    return -sum(x * math.log(x) for x in p if x > 0)


def pixels(n: int, lo: float = -1.0, hi: float = 1.0) -> np.ndarray:
    """(n,) pixel centres across ``[lo, hi]``."""
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def newton_cubic(n: int, iterations: int = 60) -> np.ndarray:
    """Basins of Newton's method for ``z^3 = 1`` on ``n x n`` pixels over ``[-2, 2]^2``: the root each pixel ends
    nearest (the Julia set between them is a fractal, box dimension about 1.4)."""
    x = pixels(n, -2.0, 2.0)
    z = (x[None, :] + 1j * x[:, None]).astype(complex)
    with np.errstate(all="ignore"):  # z = 0 (never a pixel centre here) would divide by zero
        for _ in range(iterations):
            z = z - (z**3 - 1) / (3 * z**2)
    roots = np.exp(2j * np.pi * np.arange(3) / 3)
    return np.argmin(np.abs(z[..., None] - roots), axis=-1)


def disk(n: int, r2: float = 0.2) -> np.ndarray:
    x = pixels(n)
    return (x[None, :] ** 2 + x[:, None] ** 2 < r2).astype(np.int64)


# --- exact values on synthetic grids ---------------------------------------------------------------------------


def test_one_basin_has_no_entropy_and_no_boundary() -> None:
    e = basin_entropy(np.full((40, 30), 7))
    assert e.s_b == 0.0 and e.s_bb is None and e.boundary == NO_BOUNDARY and e.status == Status.OK
    assert (e.boxes, e.boundary_boxes, e.skipped_boxes, e.excluded_cells, e.outcomes) == (48, 0, 0, 0, 1)
    assert e.exponent is not None and e.exponent.alpha is None and e.exponent.status == Status.UNDECIDED


@pytest.mark.parametrize("j", [1, 2, 3, 4])
def test_a_straight_boundary_between_two_basins(j: int) -> None:
    # The boundary at column 5 m + j cuts one column of boxes into j/5 and 1 - j/5: each of its boxes has
    # S_i = H(j/5), the others 0, so S_bb = H(j/5) and S_b = H(j/5) / (boxes across); H(p) <= log 2.
    ny, nx = 50, 60
    lab = np.zeros((ny, nx), np.int64)
    lab[:, 5 * 7 + j :] = 1
    e = basin_entropy(lab)
    h = gibbs(j / 5, 1 - j / 5)
    assert e.s_bb == pytest.approx(h, rel=1e-14) and e.s_b == pytest.approx(h / (nx // 5), rel=1e-14)
    assert (e.boxes, e.boundary_boxes) == (120, 10) and e.s_bb < LOG2 and not e.fractal_by_log2
    # the uncertain cells are the k columns on either side: f(k) = 2 k ny' / judged, exactly linear
    x = e.exponent
    assert x.alpha == pytest.approx(1.0, abs=1e-12) and x.error == pytest.approx(0.0, abs=1e-12)
    assert e.boundary == SMOOTH


def test_a_straight_boundary_through_the_middle_of_even_boxes_is_log_2_and_no_more() -> None:
    lab = np.zeros((40, 40), np.int64)
    lab[:, 22:] = 1  # boxes of 4: the column of boxes 20..23 is cut in halves
    e = basin_entropy(lab, box=4)
    assert e.s_bb == pytest.approx(LOG2, rel=1e-14) and e.s_b == pytest.approx(LOG2 / 10, rel=1e-14)
    assert not e.fractal_by_log2  # the criterion is strict: a straight boundary never passes it
    # at random offsets the boundary boxes of a straight line average H(p) over p, below log 2 (1/2 for p uniform)
    offsets = [basin_entropy(np.where(np.arange(60) >= 30 + j, 1, 0)[None, :].repeat(30, 0)).s_bb for j in range(1, 5)]
    assert np.mean(offsets) == pytest.approx((gibbs(0.2, 0.8) + gibbs(0.4, 0.6)) / 2, rel=1e-14)


def test_checkerboards() -> None:
    jj, ii = np.mgrid[0:50, 0:50]
    aligned = ((jj // 5 + ii // 5) % 2).astype(np.int64)  # squares of a box: every box one outcome
    e = basin_entropy(aligned)
    assert e.s_b == 0.0 and e.s_bb is None and e.boundary == NO_BOUNDARY
    # the same squares shifted by 2 cells: every box holds 2x2 + 3x3 = 13 cells of one colour and 12 of the other
    shifted = (((jj + 2) // 5 + (ii + 2) // 5) % 2).astype(np.int64)
    e = basin_entropy(shifted)
    assert e.s_b == pytest.approx(gibbs(13 / 25, 12 / 25), rel=1e-14) == e.s_bb
    assert e.boundary_boxes == e.boxes == 100 and e.s_bb < LOG2
    # at the cell's scale: 13 and 12 again; four colours in 2x2 cells: 9, 6, 6, 4 in every box, above log 2
    assert basin_entropy((jj + ii) % 2).s_bb == pytest.approx(gibbs(13 / 25, 12 / 25), rel=1e-14)
    four = basin_entropy(2 * (jj % 2) + ii % 2)
    assert four.s_bb == pytest.approx(gibbs(9 / 25, 6 / 25, 6 / 25, 4 / 25), rel=1e-14) and four.fractal_by_log2
    assert four.boundary == FRACTAL and four.outcomes == 4


def test_a_random_two_label_grid_tends_to_log_2() -> None:
    # Each box of n = b^2 cells holds X ~ Bin(n, 1/2) of one label: E[S_i] = E[H(X/n)] exactly, -> log 2 as n grows.
    rng = np.random.default_rng(1)
    lab = rng.integers(0, 2, (1000, 1000))
    for b in (5, 20):
        n = b * b
        h = np.array([gibbs(x / n, 1 - x / n) for x in range(n + 1)])
        pmf = binom.pmf(np.arange(n + 1), n, 0.5)
        mean, sd = float(pmf @ h), math.sqrt(float(pmf @ (h - pmf @ h) ** 2))
        e = basin_entropy(lab, box=b, exponent=b == 5)
        assert abs(e.s_b - mean) < 4 * sd / math.sqrt(e.boxes), (b, e.s_b, mean)
        assert e.s_bb == pytest.approx(e.s_b, rel=1e-3)  # (nearly) every box is on the boundary
    assert LOG2 - e.s_b < 2e-3  # boxes of 400 cells: within 1/(2 n) of log 2
    x = basin_entropy(lab).exponent
    assert abs(x.alpha) < 0.01 and basin_entropy(lab).boundary == FRACTAL  # riddled: f(eps) = 1 - 1/16 at every eps


# --- a fractal and a smooth boundary -----------------------------------------------------------------------------


def test_newton_s_basins_have_a_fractal_boundary() -> None:
    e = basin_entropy(newton_cubic(400))
    assert e.s_bb > LOG2 and e.fractal_by_log2 and e.boundary == FRACTAL, e.line()
    # the Julia set of z^3 - 1: box dimension about 1.4 (d = 2 - alpha)
    x = e.exponent
    assert 0.4 < x.alpha < 0.7 and x.error < 0.05, x
    assert 1.3 < x.dimension < 1.6


@pytest.mark.parametrize("n", [100, 200])
def test_a_disk_has_a_smooth_boundary(n: int) -> None:
    e = basin_entropy(disk(n))
    assert e.s_bb < LOG2 and e.boundary == SMOOTH, e.line()
    assert e.exponent.alpha == pytest.approx(1.0, abs=0.02) and e.exponent.dimension == pytest.approx(1.0, abs=0.02)


# --- the plain-Python reference and metamorphic checks ----------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_against_the_plain_python_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ny, nx = rng.integers(17, 41, 2)
    # a grid with structure at several scales, three outcomes and a few cells without one
    lab = ((np.add.outer(np.arange(ny) // 3, np.arange(nx) // 4) + rng.integers(0, 3, (ny, nx)) // 2) % 3).astype(int)
    valid = rng.random((ny, nx)) > 0.02
    box = int(rng.integers(2, 7))
    e = basin_entropy(lab, valid, box=box)
    s_b, s_bb, n, nb, skipped = naive_basin_entropy(lab.tolist(), valid.tolist(), box)
    assert (e.boxes, e.boundary_boxes, e.skipped_boxes) == (n, nb, skipped)
    assert e.s_b == pytest.approx(s_b, rel=1e-12) and e.s_bb == pytest.approx(s_bb, rel=1e-12)
    assert e.excluded_cells == int((~valid).sum())
    eps = [1, 2, 3, 5]
    x = uncertainty_exponent(lab, valid, tuple(eps))
    assert list(zip(x.judged, x.uncertain, strict=True)) == naive_uncertain_fraction(lab.tolist(), valid.tolist(), eps)


def test_relabelling_or_transposing_changes_nothing() -> None:
    lab = newton_cubic(120)
    e = basin_entropy(lab)
    relabelled = np.choose(lab, [7, ESCAPE, 3])  # a permutation of the outcomes, escape among them
    t = basin_entropy(relabelled)
    assert (t.s_b, t.s_bb) == pytest.approx((e.s_b, e.s_bb), rel=1e-14) and t.boundary == e.boundary
    assert t.exponent.fraction == e.exponent.fraction and t.exponent.alpha == e.exponent.alpha
    tr = basin_entropy(lab.T.copy())
    assert (tr.s_b, tr.s_bb) == pytest.approx((e.s_b, e.s_bb), rel=1e-14)
    assert tr.exponent.uncertain == e.exponent.uncertain


def test_a_cell_without_an_outcome_is_excluded_and_counted() -> None:
    lab = newton_cubic(60)
    valid = np.ones(lab.shape, bool)
    full = basin_entropy(lab, valid)
    j, i = 33, 21  # in box (6, 4), on the boundary
    valid[j, i] = False
    e = basin_entropy(lab, valid)
    assert (e.excluded_cells, e.skipped_boxes, e.boxes) == (1, 1, full.boxes - 1)
    box = lab[30:35, 20:25]
    s_box = gibbs(*(np.unique(box, return_counts=True)[1] / 25))
    assert s_box > 0 and e.boundary_boxes == full.boundary_boxes - 1
    assert e.s_b == pytest.approx((full.s_b * full.boxes - s_box) / (full.boxes - 1), rel=1e-12)
    assert e.s_bb == pytest.approx((full.s_bb * full.boundary_boxes - s_box) / (full.boundary_boxes - 1), rel=1e-12)
    # the exponent: the cell and the cells whose neighbours it is are not judged
    assert all(a < b for a, b in zip(e.exponent.judged, full.exponent.judged, strict=True))


# --- undecided, never NaN; bad input ---------------------------------------------------------------------------


def test_too_little_to_decide_is_undecided_and_never_nan() -> None:
    small = basin_entropy(np.zeros((4, 9), np.int64))
    assert small.s_b is None and small.status == Status.UNDECIDED and "no whole 5x5 box" in small.why
    assert "undecided" in small.line() and "undecided" in small.words()
    lab = np.zeros((20, 20), np.int64)
    lab[:, 12:] = 1  # 4 boundary boxes
    few = basin_entropy(lab)
    assert few.boundary_boxes == 4 < MIN_BOUNDARY_BOXES and few.boundary == UNDECIDED and few.s_bb is not None
    assert few.exponent.alpha is None and "a fit needs" in few.exponent.why  # distances 1, 2: too few
    assert default_eps((24, 24)) == (1, 2, 3)
    for e in (small, few, basin_entropy(np.full((30, 30), 1)), basin_entropy(disk(50))):
        json.dumps(e.as_dict(), allow_nan=False)  # a NaN or an inf would raise
    skipped = basin_entropy(np.zeros((10, 10), np.int64), np.zeros((10, 10), bool))
    assert skipped.s_b is None and skipped.skipped_boxes == 4 and skipped.excluded_cells == 100


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: basin_entropy(np.zeros((10, 10), int), box=1), "box must be an integer in [2, 1000], got 1"),
        (lambda: basin_entropy(np.zeros((10, 10))), "labels must be a 2-D array of integers"),
        (lambda: basin_entropy(np.zeros(10, int)), "labels must be a 2-D array"),
        (lambda: basin_entropy(np.zeros((4, 4), int), np.ones((4, 3), bool)), "valid must be a boolean array"),
        (lambda: uncertainty_exponent(np.zeros((10, 10), int), eps=(2, 1)), "eps must be increasing"),
        (lambda: uncertainty_exponent(np.zeros((10, 10), int), eps=(0, 1)), "eps must be an integer"),
    ],
)
def test_bad_input_names_the_value(call, words) -> None:
    with pytest.raises(ParameterError) as exc:
        call()
    assert words in str(exc.value)


# --- the basins' result -----------------------------------------------------------------------------------------

#: Fig. 11's tensor at alpha = -0.5, I11 = 1.6: a period-1 and a period-3 attractor coexist (tests/test_basins.py).
FIG11 = get_scene("fig11").params.with_(I11=1.6, alpha=-0.5)
BOX = (-1.7, 1.5, -3.0, 1.0)


@pytest.fixture(scope="module")
def fig11_40() -> object:
    return basins(FIG11, BOX, (40, 40))


def test_the_paper_s_two_attractors_numbers_are_finite_and_stable_under_refinement(fig11_40) -> None:
    coarse, fine = fig11_40, basins(FIG11, BOX, (80, 80))
    a, b = coarse.entropy, fine.entropy
    assert a.outcomes == b.outcomes == 2 and a.excluded_cells == b.excluded_cells == 0
    for e in (a, b):
        assert all(math.isfinite(v) for v in (e.s_b, e.s_bb, e.exponent.alpha, e.exponent.error))
    # measured: S_bb 0.581 / 0.571 (0.576, 0.570 at 160, 320 pixels), alpha 0.277 / 0.269 (0.261, 0.259)
    assert a.s_bb == pytest.approx(b.s_bb, abs=0.03) and a.exponent.alpha == pytest.approx(b.exponent.alpha, abs=0.03)
    # S_b at one box in the plane (5 pixels of 40, 10 of 80): 0.508 / 0.515 (0.522 at 20 of 160, 40 of 320)
    same_box = basin_entropy(fine.label, fine.label >= ESCAPE, box=10, exponent=False)
    assert a.s_b == pytest.approx(same_box.s_b, abs=0.03)
    # intertwined stripes: S_bb below log 2 (which proves nothing) and alpha far below 1: a fractal boundary
    assert a.boundary == b.boundary == FRACTAL and b.exponent.alpha < 0.5


def test_the_basins_result_carries_the_entropy_in_its_files_and_its_lines(fig11_40, tmp_path) -> None:
    e = fig11_40.entropy
    assert e is fig11_40.entropy  # computed once
    s = fig11_40.summary()
    assert s["entropy"]["s_b"] == e.s_b and s["entropy"]["boundary_boxes"] == e.boundary_boxes
    assert s["entropy"]["uncertainty_exponent"]["alpha"] == e.exponent.alpha and s["entropy_box"] == 5
    fig11_40.write(str(tmp_path / "b.json"))
    assert json.loads((tmp_path / "b.json").read_text())["entropy"]["s_bb"] == pytest.approx(e.s_bb)
    fig11_40.write(str(tmp_path / "b.npz"))
    with np.load(tmp_path / "b.npz") as z:
        assert json.loads(str(z["summary"]))["entropy"]["boxes"] == 64
    line = next(x for x in fig11_40.report() if x.startswith("basin entropy"))
    assert f"S_b = {e.s_b:.3g} over 64 boxes of 5x5 pixels, boundary S_bb = {e.s_bb:.3g}" in line
    assert f"uncertainty exponent {e.exponent.alpha:.2f} +- " in line


def test_pixels_without_an_outcome_are_excluded_from_the_basins_entropy(fig11_40) -> None:
    lab = fig11_40.label.copy()
    lab[0, 0], lab[10, 13], lab[39, 39] = FAILED, UNDECIDED_LABEL, NOT_COMPUTED
    e = replace(fig11_40, label=lab).entropy
    assert e.excluded_cells == 3 and e.skipped_boxes == 3 and e.boxes == 61
    ref = naive_basin_entropy(lab.tolist(), (lab >= ESCAPE).tolist(), 5)
    assert (e.s_b, e.s_bb) == pytest.approx(ref[:2], rel=1e-12)
    assert "3 pixels without an outcome excluded (3 boxes skipped)" in e.line()


def test_the_box_is_an_option_of_the_basins() -> None:
    spec = basin_spec(FIG11, BOX, (10, 10), entropy_box=2)
    assert spec.entropy_box == 2 and spec.as_dict()["entropy_box"] == 2
    assert basin_spec(FIG11, BOX, (10, 10)).entropy_box == 5
    with pytest.raises(ParameterError, match="entropy_box must be an integer in"):
        basin_spec(FIG11, BOX, (10, 10), entropy_box=1)


def test_the_command_line_prints_the_entropy_line_and_takes_the_box() -> None:
    from clirun import run_cli

    rc, out, err = run_cli("basins", "--scene", "fig11", "--I11", "1.6", "--box", "-1.7,1.5,-3,1", "--grid", "20,20",
                           "--entropy-box", "4")  # fmt: skip
    assert rc == 0, err
    line = next(x for x in out.splitlines() if x.startswith("basin entropy"))
    assert "S_b = " in line and "over 25 boxes of 4x4 pixels, boundary S_bb = " in line, line
    assert "uncertainty exponent" in line
    rc, _, err = run_cli("basins", "--scene", "fig11", "--entropy-box", "1")
    assert rc == 2 and "entropy-box" in err and "got 1" in err
