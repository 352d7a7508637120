"""How unpredictable a basin picture is: basin entropy, boundary basin entropy and the uncertainty exponent.

From a grid of labels (each initial condition's final state; :class:`~explorer_core.analyses.basins.Basins`'
``label``), with the cells that reached no verdict excluded and counted:

* **basin entropy** ``S_b`` (Daza, Wagemakers, Georgeot, Guery-Odelin, Sanjuan, "Basin entropy: a new tool to
  analyze uncertainty in dynamical systems", Sci. Rep. 6, 31416 (2016)): the grid is cut into boxes of
  ``box x box`` cells (the paper's 5 x 5 by default); in box ``i`` the fraction ``p_ij`` of its cells that end in
  outcome ``j`` gives the Gibbs entropy ``S_i = -sum_j p_ij log p_ij`` (natural log), and ``S_b`` is the mean of
  ``S_i`` over the ``N`` boxes. ``S_b = 0`` for one basin; with ``N_A`` outcomes equally mixed at every scale it
  tends to ``log N_A``;
* **boundary basin entropy** ``S_bb``: the same sum over the ``N_b`` boxes that hold more than one outcome,
  divided by ``N_b``: how mixed a box on the boundary is. ``S_bb > log 2`` is a *sufficient* condition for a
  fractal boundary (the paper's log 2 criterion): boxes on a smooth boundary between two basins hold the two in
  every proportion, whose mean entropy is below ``log 2`` (a straight boundary: ``<= log 2``; at random offsets
  the mean of ``H(p)`` over ``p`` uniform, 1/2), and only boxes with three or more outcomes, or a boundary
  crossing every box many times, lift the mean above it. ``S_bb <= log 2`` proves nothing (a fractal boundary
  between two basins can stay below it), so a smaller ``S_bb`` is judged with the uncertainty exponent;
* **uncertainty exponent** ``alpha`` (McDonald, Grebogi, Ott, Yorke, Physica D 17, 125 (1985)): the fraction
  ``f(eps)`` of initial conditions whose outcome changes under a perturbation of size ``eps`` scales as
  ``eps^alpha``, and the boundary's box-counting dimension is ``d = D - alpha`` (``D = 2``, the plane of
  initial conditions): ``alpha = 1`` for a smooth boundary, ``alpha < 1`` for a fractal one, ``alpha -> 0``
  riddled. ``alpha`` is the least-squares slope of ``log f`` against ``log eps`` over several ``eps``, with the
  slope's standard error.

**The approximation of the exponent.** ``f(eps)`` is measured on the grid already computed, not by new
integrations: ``eps`` is a whole number ``k`` of cells, and a cell is ``k``-uncertain when one of the four
cells ``k`` away along the grid's axes (left, right, down, up) has another outcome. So the perturbed initial
conditions are the grid's own cells (a perturbation along the axes only, of exactly ``k`` cells), and ``f`` is
resolved down to one cell: a boundary whose structure is finer than a cell looks smoother than it is at ``k =
1``. With cells of different sizes in ``q`` and ``r`` the perturbation is an ellipse, not a circle: the exponent
does not depend on it (``f`` scales the same under a linear change of coordinates). Every ``k`` judges the same
cells (those at least ``max k`` from the grid's edge); a cell is judged at ``k`` when it and its four
neighbours there are all valid. Re-classifying perturbed initial conditions through the basins' own runner
would resolve ``f`` below a cell but needs new trajectories for every perturbed point (a second basin
computation per ``eps``), so it is not done here.

Nothing is NaN: a value that cannot be computed is None with its status (``undecided``) and the reason (too few
boxes, too few boundary boxes, too few distances with uncertain cells for a fit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core.solve.checks import check_int
from explorer_core.status import Status
from explorer_core.system.params import ParameterError

#: Cells per side of a box (Daza et al. 2016 use boxes of 5 x 5 pixels).
DEFAULT_BOX = 5
#: Largest box side accepted.
MAX_BOX = 1000
#: Fewer boundary boxes than this: ``S_bb`` is given but says nothing about the boundary (undecided).
MIN_BOUNDARY_BOXES = 10
#: A distance ``k`` enters the exponent's fit when at least this many cells are ``k``-uncertain.
MIN_UNCERTAIN = 10
#: Fewest distances in the fit (fewer: undecided), and how many the default ladder of distances has at most.
MIN_FIT_POINTS, FIT_POINTS = 4, 8
#: The largest default distance is this fraction of the grid's shorter side: the judged cells stay most of it.
EPS_SHARE = 8
#: ``alpha`` within ``max(2 err, SMOOTH_TOL)`` of 1: a smooth boundary; below that: a fractal one.
SMOOTH_TOL = 0.15
#: Verdicts on the boundary.
FRACTAL, SMOOTH, UNDECIDED, NO_BOUNDARY = "fractal", "smooth", "undecided", "none"
LOG2 = math.log(2.0)


@dataclass(frozen=True)
class UncertaintyExponent:
    """``f(eps) ~ eps^alpha``: the uncertainty exponent of the boundary (module docstring: the approximation).

    ``eps`` (cells), ``fraction`` ``f(eps)``, ``judged`` and ``uncertain`` (cells) at every distance tried;
    ``fitted``: the distances in the fit (those with at least :data:`MIN_UNCERTAIN` uncertain cells); ``alpha``
    and ``error`` (the slope's standard error) are None when the fit is undecided (``status``, ``why``).
    """

    eps: tuple[int, ...]
    fraction: tuple[float, ...]
    judged: tuple[int, ...]
    uncertain: tuple[int, ...]
    fitted: tuple[int, ...]
    alpha: float | None
    error: float | None
    status: Status
    why: str = ""

    @property
    def dimension(self) -> float | None:
        """The boundary's box-counting dimension ``d = D - alpha`` (``D = 2``)."""
        return None if self.alpha is None else 2.0 - self.alpha

    def as_dict(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "error": self.error, "dimension": self.dimension, "status": self.status.label,
                "why": self.why or None, "eps_cells": list(self.eps), "fraction": list(self.fraction),
                "judged": list(self.judged), "uncertain": list(self.uncertain),
                "fitted_eps": list(self.fitted)}  # fmt: skip


@dataclass(frozen=True)
class BasinEntropy:
    """Basin entropy ``S_b`` and boundary basin entropy ``S_bb`` of a label grid (Daza et al. 2016), the
    uncertainty exponent, and the verdict on the boundary.

    ``box``: cells per side of a box; ``boxes`` (``N``): the whole boxes of valid cells used;
    ``boundary_boxes`` (``N_b``): those with more than one outcome; ``skipped_boxes``: whole boxes left out
    because they hold an excluded cell; ``excluded_cells``: cells with no outcome (failed, undecided, not
    computed), anywhere in the grid; ``unboxed_cells``: cells of the strips at the top and right edges too thin
    for a whole box (never used); ``outcomes``: the outcomes seen in the boxes used. ``s_b`` is None when no box
    was used, ``s_bb`` when none holds a boundary (``status`` undecided, ``why``). ``boundary``:
    :data:`FRACTAL` (``S_bb > log 2``, the paper's sufficient criterion, or ``alpha`` clearly below 1),
    :data:`SMOOTH` (``S_bb <= log 2`` and ``alpha`` consistent with 1), :data:`NO_BOUNDARY` (one outcome) or
    :data:`UNDECIDED` (too few boundary boxes, or ``S_bb <= log 2`` with no decided exponent).
    """

    box: int
    boxes: int
    boundary_boxes: int
    skipped_boxes: int
    excluded_cells: int
    unboxed_cells: int
    outcomes: int
    s_b: float | None
    s_bb: float | None
    boundary: str
    status: Status
    why: str = ""
    exponent: UncertaintyExponent | None = field(default=None)

    @property
    def fractal_by_log2(self) -> bool:
        """The paper's sufficient criterion ``S_bb > log 2`` (on enough boundary boxes)."""
        return self.s_bb is not None and self.boundary_boxes >= MIN_BOUNDARY_BOXES and self.s_bb > LOG2

    def as_dict(self) -> dict[str, Any]:
        return {"s_b": self.s_b, "s_bb": self.s_bb, "box": self.box, "boxes": self.boxes,
                "boundary_boxes": self.boundary_boxes, "skipped_boxes": self.skipped_boxes,
                "excluded_cells": self.excluded_cells, "unboxed_cells": self.unboxed_cells,
                "outcomes": self.outcomes, "boundary": self.boundary, "s_bb_above_log2": self.fractal_by_log2,
                "status": self.status.label, "why": self.why or None,
                "uncertainty_exponent": None if self.exponent is None else self.exponent.as_dict()}  # fmt: skip

    def words(self) -> str:
        """Short, for a legend: ``S_b = 0.31, S_bb = 0.72 (fractal boundary)``."""
        if self.s_b is None:
            return f"basin entropy undecided ({self.why})"
        bb = "" if self.s_bb is None else f", S_bb = {self.s_bb:.2f}"
        verdict = {NO_BOUNDARY: "no boundary", UNDECIDED: UNDECIDED}.get(self.boundary, f"{self.boundary} boundary")
        return f"S_b = {self.s_b:.2f}{bb} ({verdict})"

    def line(self) -> str:
        """What the command line prints: both entropies, the verdict and the exponent."""
        if self.s_b is None:
            return f"basin entropy undecided: {self.why}"
        out = f"basin entropy S_b = {self.s_b:.3g} over {self.boxes} boxes of {self.box}x{self.box} pixels"
        if self.s_bb is None:
            return out + ", no boundary box (one outcome)"
        if self.fractal_by_log2:
            why = "> log 2: fractal boundary"
        elif self.boundary == FRACTAL:
            why = "<= log 2, but the uncertainty exponent is below 1: fractal boundary"
        elif self.boundary == SMOOTH:
            why = "<= log 2 and the uncertainty exponent ~ 1: smooth boundary"
        else:
            why = f"undecided: {self.why}"
        out += f", boundary S_bb = {self.s_bb:.3g} over {self.boundary_boxes} boxes ({why})"
        e = self.exponent
        if e is not None:
            if e.alpha is None:
                out += f", uncertainty exponent undecided ({e.why})"
            else:
                out += f", uncertainty exponent {e.alpha:.2f} +- {e.error:.1g} (boundary dimension {e.dimension:.2f})"
        if self.excluded_cells:
            out += f"; {self.excluded_cells} pixels without an outcome excluded ({self.skipped_boxes} boxes skipped)"
        return out


def _checked(labels: Any, valid: Any) -> tuple[np.ndarray, np.ndarray]:
    """``labels`` as a 2-D integer array and ``valid`` (default: every cell) as a boolean array of its shape."""
    lab = np.asarray(labels)
    if lab.ndim != 2 or not np.issubdtype(lab.dtype, np.integer):
        raise ParameterError(f"labels must be a 2-D array of integers, got shape {lab.shape} of {lab.dtype}")
    ok = np.ones(lab.shape, bool) if valid is None else np.asarray(valid)
    if ok.shape != lab.shape or ok.dtype != bool:
        raise ParameterError(f"valid must be a boolean array of the labels' shape {lab.shape}, got {ok.shape} "
                             f"of {ok.dtype}")  # fmt: skip
    return lab, ok


def box_entropies(labels: np.ndarray, valid: np.ndarray, box: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The Gibbs entropy of every whole ``box x box`` box of valid cells and whether it holds a boundary.

    Boxes tile the grid from cell ``(0, 0)``; a box with an excluded cell is skipped. Returns ``(S_i, boundary,
    skipped, outcomes)``: ``S_i`` (N,) of the boxes used, ``boundary`` (N,) bool (more than one outcome), the
    boxes skipped and the outcomes seen in the boxes used.
    """
    ny, nx = (labels.shape[0] // box) * box, (labels.shape[1] // box) * box
    lab, ok = labels[:ny, :nx], valid[:ny, :nx]
    outcomes, code = np.unique(lab, return_inverse=True)
    k = outcomes.size + 1  # the last code: an excluded cell
    code = np.where(ok, code.reshape(lab.shape), k - 1)
    jj, ii = np.mgrid[0:ny, 0:nx]
    which = (jj // box) * (nx // box) + ii // box
    counts = np.bincount((which * k + code).ravel(), minlength=which.size // box**2 * k).reshape(-1, k)
    skip = counts[:, -1] > 0
    used = counts[~skip, :-1]
    p = used / float(box * box)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -np.where(p > 0, p * np.log(p), 0.0).sum(axis=1)
    seen = int(np.count_nonzero(used.sum(axis=0)))
    return s, np.count_nonzero(used, axis=1) > 1, int(skip.sum()), seen


def default_eps(shape: tuple[int, ...]) -> tuple[int, ...]:
    """Distances (cells) for the exponent: up to :data:`FIT_POINTS` roughly geometric from 1 to the shorter side
    / :data:`EPS_SHARE`."""
    top = max(1, min(shape) // EPS_SHARE)
    return tuple(sorted({int(v) for v in np.rint(np.geomspace(1, top, FIT_POINTS))}))


def uncertain_fraction(labels: np.ndarray, valid: np.ndarray, eps: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """``(judged, uncertain)`` cells at every distance of ``eps``: a cell at least ``max(eps)`` from the edge is
    judged at ``k`` when it and its four neighbours ``k`` cells away along the axes are valid, and is uncertain
    when one of them has another label."""
    m = max(eps)
    ny, nx = labels.shape
    judged, uncertain = np.zeros(len(eps), np.int64), np.zeros(len(eps), np.int64)
    if ny <= 2 * m or nx <= 2 * m:
        return judged, uncertain
    core = (slice(m, ny - m), slice(m, nx - m))
    c, ok = labels[core], valid[core]
    for n, k in enumerate(eps):
        live, moved = ok.copy(), np.zeros(c.shape, bool)
        for dj, di in ((0, k), (0, -k), (k, 0), (-k, 0)):
            near = (slice(m + dj, ny - m + dj), slice(m + di, nx - m + di))
            live &= valid[near]
            moved |= labels[near] != c
        judged[n], uncertain[n] = np.count_nonzero(live), np.count_nonzero(live & moved)
    return judged, uncertain


def uncertainty_exponent(labels: Any, valid: Any = None, eps: tuple[int, ...] | None = None) -> UncertaintyExponent:
    """The uncertainty exponent of the boundaries of a label grid (module docstring: the grid's approximation).

    Parameters
    ----------
    labels : (NY, NX) integers, one outcome per cell.
    valid : (NY, NX) bool, the cells with an outcome (default: all).
    eps : distances in cells, increasing, at least 1 (default :func:`default_eps`).

    Returns
    -------
    UncertaintyExponent : ``alpha`` (the slope of ``log f(eps)`` against ``log eps``) with its standard error,
        or undecided (None) when fewer than :data:`MIN_FIT_POINTS` distances have :data:`MIN_UNCERTAIN`
        uncertain cells.
    """
    lab, ok = _checked(labels, valid)
    if eps is None:
        ks = default_eps(lab.shape)
    else:
        ks = tuple(check_int("eps", k, 1, max(1, min(lab.shape))) for k in eps)
        if list(ks) != sorted(set(ks)):
            raise ParameterError(f"eps must be increasing distances in cells, got {eps!r}")
    judged, uncertain = uncertain_fraction(lab, ok, ks)
    frac = np.divide(uncertain, judged, out=np.zeros(len(ks)), where=judged > 0)
    use = uncertain >= MIN_UNCERTAIN
    fitted = tuple(k for k, u in zip(ks, use, strict=True) if u)
    counts = (tuple(float(f) for f in frac), tuple(int(v) for v in judged), tuple(int(v) for v in uncertain))
    common = (ks, *counts, fitted)
    if len(fitted) < MIN_FIT_POINTS:
        why = (f"{len(fitted)} of {len(ks)} distances (cells {list(ks)}) have at least {MIN_UNCERTAIN} uncertain "
               f"pixels, a fit needs {MIN_FIT_POINTS}")  # fmt: skip
        return UncertaintyExponent(*common, None, None, Status.UNDECIDED, why)
    x, y = np.log(np.asarray(fitted, float)), np.log(frac[use])
    slope, icept = np.polyfit(x, y, 1)
    res = y - (slope * x + icept)
    err = math.sqrt(float(res @ res) / (x.size - 2) / float(((x - x.mean()) ** 2).sum()))
    return UncertaintyExponent(*common, float(slope), err, Status.OK)


def basin_entropy(labels: Any, valid: Any = None, *, box: int = DEFAULT_BOX, exponent: bool = True) -> BasinEntropy:
    """Basin entropy and boundary basin entropy of a label grid (Daza et al. 2016) and the verdict on the boundary.

    Parameters
    ----------
    labels : (NY, NX) integers, one outcome per cell (any values: only equality matters).
    valid : (NY, NX) bool, the cells with an outcome (default: all); the others are excluded and counted, and a
        box holding one is skipped.
    box : cells per side of a box (default :data:`DEFAULT_BOX`, the paper's 5).
    exponent : also measure the uncertainty exponent (:func:`uncertainty_exponent`; cheap: it reads the grid).

    Returns
    -------
    BasinEntropy : ``S_b``, ``S_bb``, the boxes used, the cells excluded, the exponent and the verdict.
    """
    lab, ok = _checked(labels, valid)
    box = check_int("box", box, 2, MAX_BOX)
    s, edge, skipped, seen = box_entropies(lab, ok, box)
    unboxed = lab.size - (lab.shape[0] // box) * (lab.shape[1] // box) * box * box
    exp = uncertainty_exponent(lab, ok) if exponent else None
    n, nb = int(s.size), int(edge.sum())
    base = (box, n, nb, skipped, int(lab.size - ok.sum()), unboxed, seen)
    if n == 0:
        why = (f"no whole {box}x{box} box of pixels with an outcome (grid {lab.shape[1]}x{lab.shape[0]}, "
               f"{skipped} boxes skipped)")  # fmt: skip
        return BasinEntropy(*base, None, None, UNDECIDED, Status.UNDECIDED, why, exp)
    s_b = float(s.sum() / n)
    if nb == 0:
        return BasinEntropy(*base, s_b, None, NO_BOUNDARY, Status.OK, "no box holds two outcomes", exp)
    s_bb = float(s.sum() / nb)
    verdict, why = _verdict(s_bb, nb, exp)
    return BasinEntropy(*base, s_b, s_bb, verdict, Status.OK if verdict != UNDECIDED else Status.UNDECIDED, why, exp)


def _verdict(s_bb: float, nb: int, exp: UncertaintyExponent | None) -> tuple[str, str]:
    """Fractal, smooth or undecided, and why (the class docstring of :class:`BasinEntropy`)."""
    if nb < MIN_BOUNDARY_BOXES:
        return UNDECIDED, f"only {nb} boundary boxes (a verdict needs {MIN_BOUNDARY_BOXES})"
    if s_bb > LOG2:
        return FRACTAL, "S_bb > log 2 (sufficient for a fractal boundary)"
    if exp is None or exp.alpha is None:
        return UNDECIDED, "S_bb <= log 2 proves nothing, and the uncertainty exponent is undecided"
    tol = max(2.0 * (exp.error or 0.0), SMOOTH_TOL)
    if exp.alpha < 1.0 - tol:
        return FRACTAL, f"uncertainty exponent {exp.alpha:.2f} < 1 (boundary dimension {exp.dimension:.2f})"
    if abs(exp.alpha - 1.0) <= tol:
        return SMOOTH, f"S_bb <= log 2 and uncertainty exponent {exp.alpha:.2f} ~ 1"
    return UNDECIDED, f"uncertainty exponent {exp.alpha:.2f} above 1: the grid does not resolve the boundary"
