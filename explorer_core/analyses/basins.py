"""Basins of attraction of the Poincare map: which attractor each initial condition of a grid reaches.

Every pixel centre of an ``NX x NY`` grid over a box ``(q0, q1, r0, r1)`` is an initial condition at
``t0``. Its trajectory is iterated by the one engine (:func:`~explorer_core.solve.integrators.advance`,
lock-step blocks on both cores) in chunks of periods, many pixels at once, and each pixel stops as soon
as its fate is known:

* **recurrences on a grid of cells** (Datseris & Wagemakers, "Effortless estimation of basins of
  attraction", Chaos 32, 023104 (2022); Attractors.jl's ``AttractorsViaRecurrences``): the section
  points are mapped to cells of a grid over a box around the view; a trajectory that revisits cells it
  has visited before ``recurrences`` times in a row has found an attractor, which it then *locates*:
  for ``locate`` more periods every cell it visits becomes a cell of that attractor. A later trajectory
  that is in cells of one known attractor ``hit_attractor`` periods in a row is labelled with it at
  once: this is what makes basins cheap (a pixel stops after ~40 periods on Fig. 11's tensor). Only
  *classified* attractors label trajectories, and a cycle's cells are its points' cells only: 100
  recurrences can be a long chaotic transient, whose cells would otherwise capture other basins'
  pixels (see :meth:`_Run.add_periodic`).
  The cells must resolve the attractors (Attractors.jl warns so): a cell wider than the gap between two
  attractors hands one's pixels to the other. The default cells (64 across the box) are therefore
  checked against the attractors' own length scale whenever one is classified
  (:func:`attractor_scale`: the spacing of a cycle's points, their distance to other attractors) and,
  when too coarse, replaced by cells sized from the attractors and local to them
  (:func:`refined_cells`): a pixel's label does not depend on the box around it;
  Attractors.jl also labels a trajectory that crosses ``hit_basin`` cells in a row that earlier
  trajectories of one basin crossed; here that is off by default (``hit_basin=None``): on Fig. 11's
  tensor at ``alpha = -0.5, I11 = 1.6`` it mislabelled 35 of 10^4 pixels next to basin boundaries (a
  cell straddles the boundary) and saved no time, on Fig. 8B 13 of 3600 (measured against 400 periods
  of every pixel at 1e-10);
* **attracting cycles** are identified as orbits: the located points that return after ``p <= p_max``
  iterations (or a trajectory whose last section points do so to ``tol``, as the chart of regimes stops
  early, :mod:`explorer_core.analyses.regimes`) are handed to Newton on ``P^p(x) - x``
  (:func:`~explorer_core.analyses.orbits.find_orbits`), which gives the least period, the cycle's
  points and its multipliers; the attractor is periodic when every multiplier is inside the unit circle.
  An attractor that is no such cycle is ``chaotic`` when its largest Lyapunov exponent is above
  ``lyap_threshold`` and ``quasi_periodic`` (an attracting invariant curve, or a longer cycle) otherwise;
* **conservative islands** are no attractors: a recurrent set whose area ``|det DP^k|`` (the divergence
  integrated over ``k`` periods, from the same Lyapunov run) has no trend is an invariant curve (or a
  chaotic layer) of an island where the map preserves area (Fig. 5A; Fig. 4A around its elliptic point).
  All such sets are one entry of kind ``conservative`` (``attracting`` False), with a warning: neighbouring
  invariant curves are never reported as separate attractors;
* **escape** (label :data:`ESCAPE` = -1): the engine's status ESCAPED, ``|q|`` or ``|r|`` above the
  escape bound (by default ``max(100, 10 x`` the largest coordinate of the cell box), much below the
  sections' 1e4: along the noncompact curves the steps per period grow with ``|x|``, and a trajectory
  that far out has not been seen to come back; the bound is in the result);
* **failure** (label :data:`FAILED` = -2): any other engine status (step collapse, step budget,
  non-finite values); :data:`UNDECIDED` = -3: no fate within ``max_periods`` periods. Beside the labels,
  ``Basins.status`` gives every pixel its :class:`~explorer_core.status.Status` (the one vocabulary):
  ``ok`` (an attractor or a conservative set), ``escaped``, the engine failure that ended it
  (``step_collapsed``, ``too_many_steps``, ``nonfinite``), ``undecided``, ``not_run``. Nothing is lost in
  silence: the result's ``lost`` counts the pixels failed (by the engine's reason), undecided, not
  computed (cancelled) or still locating, and a grid of cells that does not resolve the attractors;
  ``complete`` is True only when it is empty.

Pixels are computed coarse to fine (:func:`iter_basins`: every 4th pixel, then every 2nd, then all);
the finer levels reuse the attractors (and their cells) already found. The work is not split into
independent tasks (an executor's): every trajectory reads and writes the shared cells, and the engine
already runs each chunk on both cores.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit

from explorer_core import config, export
from explorer_core.analyses.basin_entropy import DEFAULT_BOX, MAX_BOX, BasinEntropy, basin_entropy
from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.analyses.orbits import Orbit, find_orbits, pixel_centres, same_orbit
from explorer_core.analyses.specs import spec_of
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress
from explorer_core.progress import run as run_updates
from explorer_core.solve.integrators import Batch
from explorer_core.solve.numerics import Numerics, check_int
from explorer_core.solve.options import (
    ORBITS,
    Arg,
    Check,
    NewtonOptions,
    declare,
    fraction,
    instance,
    integer,
    number,
    option,
    optional_of,
)
from explorer_core.solve.options import box as box_check
from explorer_core.solve.poincare import PoincareMap
from explorer_core.solve.recurrence import CHART, SWEEP, recurrence
from explorer_core.status import Status, count_names, describe, status_names
from explorer_core.system.params import ParameterError, Params

#: Labels of pixels that reach no attractor (attractor ids are >= 0); why is the pixel's ``Basins.status``.
ESCAPE, FAILED, UNDECIDED, NOT_COMPUTED, LOCATING = -1, -2, -3, -4, -5
KINDS = ("periodic", "chaotic", "quasi_periodic", "conservative", "escape")
#: Integration tolerance: basins need the attractor, not 1e-10 accuracy (as the chart of regimes).
DEFAULT_BASIN_TOL = 1e-8
#: Newton on a basin's cycle: the orbits' settings, no patience (a cycle seen recurring is there to be found).
BASIN_NEWTON = ORBITS.replace(patience=None)
#: Periods of the Lyapunov exponent that tells a chaotic attractor from a quasi-periodic one, and the
#: fewest that count if the run fails (escapes) before the end.
LYAP_PERIODS, LYAP_MIN_PERIODS = 300, 50
#: The chaos test stays this exponent, not the SALI the chart and ``reproduce`` use (issue 34, item 3): here the same
#: run gives the area trend that tells an attractor from a conservative island, so a SALI verdict saves at most that
#: first run on a chaotic set, and it decides too few sets. Every call on three boxes (SALI over 25 periods from the
#: same point, 5,000-period exponents as the reference): Fig. 11's tensor (40 x 40) calls it never (cycles only);
#: Fig. 4A (16 x 16) 109 times: 107 conservative sets, all undecided by the SALI (a regular verdict needs 100 periods),
#: and 2 chaotic ones (reference 0.016), one decided in 13 periods; the confirmation's 1,500-period check, undecided.
#: Fig. 1C (20 x 20) 84 times: 79 conservative, 5 chaotic transients, 1 decided by the SALI (whose reference, 4.3e-3,
#: is below the threshold); on the crescent the confirmation's check is undecided by the SALI while its vectors stretch
#: by 0.093 per unit time over 25 periods where the reference is 1.1e-4: a longer SALI would call the crescent chaotic.
#: Refinement levels: every 4th pixel, then every 2nd, then all.
LEVELS = (4, 2, 1)
#: A set whose area ``|det DP^k|`` has a secular part (the least-squares trend of ``log |det DP^k|``, the
#: integrated divergence, over the ``LYAP_PERIODS`` of the Lyapunov run) above ``exp(-CONSERVATIVE_LOG_DET)``
#: attracts nothing measurable: invariant curves (or a chaotic layer, whose finite-time trend wanders
#: either way) of a conservative island, not an attractor. On Fig. 4A's and Fig. 5A's invariant curves the
#: trend is below 0.1 over 300 periods (the oscillation about it up to 3); an attractor contracting area by
#: ``exp(-0.05)`` a period gives -15. A trend between minus it and minus a quarter of it is measured again
#: over five times the periods.
CONSERVATIVE_LOG_DET = 1.0
#: A chaotic set is measured over this many blocks of ``LYAP_PERIODS`` and called conservative when its trend
#: per block is above ``-CONSERVATIVE_LOG_DET``: on Fig. 4A and Fig. 2C one block of a chaotic attractor gave
#: anywhere from +5.8 to -60 (so 22 of Fig. 4A's 100 pixels at 10x10 were chaotic and the same pixels at
#: 30x30 conservative), the mean of 20 blocks -13 to -31, that of an island's invariant curve within 0.05 of 0.
CHAOTIC_BLOCKS = 10
#: The recurrence cells resolve the attractors when a cell's diagonal is at most ``1/RESOLVE`` of the
#: attractors' length scale (:func:`attractor_scale`, set by the cycles: the spacing of a cycle's points,
#: their distance to other attractors, ``1 + |x|`` of a lone fixed point).
RESOLVE = 8
#: Times the default cells may be refined (the run restarted on a grid sized from the attractors) before
#: the result says the attractors are not resolved; most cells per axis of a refined grid.
MAX_REFINES, MAX_REFINED_CELLS = 4, 1024

# Member phases in the cell bookkeeping.
_SEARCH, _LOCATE, _LOCATED, _LABELLED, _FULL = 0, 1, 2, 3, 4
#: Basin-cell code of a cell that trajectories of different fates crossed (never used as evidence).
_MIXED = -(2**30)
#: Slots of a member's table of visited cells: a power of two, 8 per cell along the cell grid's diagonal,
#: in [TABLE_MIN, TABLE_MAX]; it may fill to 70 % (a member that visits more cells is undecided). The
#: most cells one trajectory visited before its fate was known: 387 on Fig. 8B, 852 on Fig. 1C (192 x 192
#: cells), so 2048 slots (int32: 8 kB a member, 4 MB for the default 512 in flight).
TABLE_MIN, TABLE_MAX = 1024, 16384


def table_size(cells: tuple[int, int]) -> int:
    """Slots of the visited-cell table of one member for a grid of ``cells`` (see :data:`TABLE_MIN`)."""
    want = 8 * math.hypot(*cells)
    return int(min(TABLE_MAX, max(TABLE_MIN, 2 ** math.ceil(math.log2(want)))))


#: Most attractors (provisional ones included) one computation may register.
MAX_ATTRACTORS = 4096
#: Periods a chaotic or quasi-periodic set's seed is continued past where it was located before the set is
#: listed as an attractor (``BasinSpec.confirm``): Fig. 1C's chaotic set (at the basins' 1e-8) falls onto the
#: crescent-moon curve after 2,000-9,000 periods at 1e-9..1e-12; Fig. 5A's slow drift escapes at once.
CONFIRM_PERIODS = 20_000
#: The continuation runs at the basins' tolerances divided by this, not below CONFIRM_MIN_TOL: at DOP853 1e-8
#: Fig. 1C's weakly attracting crescent does not hold its trajectories (they wander chaotically for 60,000
#: periods), at 1e-9 and tighter every seed tried settles on it.
CONFIRM_TIGHTEN, CONFIRM_MIN_TOL = 100.0, 1e-12
#: Periods per engine call of the continuation (it stops early when it escapes or falls onto an attractor).
CONFIRM_CHUNK = 1000
#: Periods of the Lyapunov run that tells whether a chaotic set's continuation ended on a regular set: on Fig.
#: 1C's crescent the finite-time exponent decays as 1/n (4.9e-3 over 300 periods, at the threshold; 1.6e-3
#: over 1000, 5e-4 over 3000), on Fig. 8B's strange attractor it stays near 0.08.
CONFIRM_LYAP_PERIODS = 5 * LYAP_PERIODS


# ---------------------------------------------------------------------------
# Results.


@dataclass(frozen=True)
class Attractor:
    """One attractor of the Poincare map found by :func:`basins`.

    ``points`` (m, 2): the cycle's points (periodic; ``x, P(x), ..., P^(n-1)(x)``) or a sample of the
    attractor's section points (chaotic, quasi-periodic); empty for escape. ``multipliers`` (2,) complex
    (periodic only), largest modulus first; ``lyapunov``: the largest exponent per unit time (chaotic,
    quasi-periodic only); ``fraction``: the share of the computed pixels in its basin; ``seed``: the
    initial condition whose trajectory found it.

    ``kind == "conservative"`` is no attractor: the invariant curves (or a chaotic layer) of a
    conservative island, whose area ``|det DP^k|`` does not contract (its trend stays above
    ``exp(-CONSERVATIVE_LOG_DET)``, ``attracting`` False). Every such set of one computation is this one
    entry: neighbouring invariant curves are not told apart (each is its own invariant set; none has a
    basin). ``log_det``: the secular part of ``log |det DP^k|`` (the integrated divergence) over the
    ``measured`` periods of the Lyapunov run (chaotic, quasi-periodic and conservative): per
    ``LYAP_PERIODS`` periods not below ``-CONSERVATIVE_LOG_DET`` on a conservative set, below it on an
    attractor (a chaotic set is measured over ``CHAOTIC_BLOCKS`` such blocks: its trend over one wanders);
    ``attracting``: True for attractors, False for a conservative set, None for escape.

    ``confirmed``: a chaotic or quasi-periodic attractor's seed, continued past where it was located at
    tighter tolerances (:meth:`_Run.confirm`), stayed on it (fell onto no other attractor, did not escape)
    for this many periods (``BasinSpec.confirm``); None when not checked (a cycle needs no check: Newton and
    its multipliers make it an attractor). Beyond that horizon such a set may still be a long transient
    (:attr:`may_be_transient`): a recurrence cannot tell a long transient from an attractor.
    """

    id: int
    kind: str
    period: int | None
    points: np.ndarray
    multipliers: np.ndarray | None = None
    lyapunov: float | None = None
    fraction: float = 0.0
    seed: tuple[float, float] = (math.nan, math.nan)
    orbit_type: str | None = None
    attracting: bool | None = None
    log_det: float | None = None
    measured: int = 0
    confirmed: int | None = None

    @property
    def may_be_transient(self) -> bool:
        """True for a chaotic or quasi-periodic attractor: no finite continuation proves it is no transient."""
        return bool(self.attracting) and self.kind in ("chaotic", "quasi_periodic")

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "id": self.id,
            "kind": self.kind,
            "period": self.period,
            "points": [[float(q), float(r)] for q, r in self.points],
            "fraction": float(self.fraction),
        }
        if self.multipliers is not None:
            out["multipliers"] = [[float(m.real), float(m.imag)] for m in self.multipliers]
            out["type"] = self.orbit_type
        if self.lyapunov is not None:
            out["lyapunov"] = float(self.lyapunov)
        out["attracting"] = self.attracting
        if self.log_det is not None:
            out["log_det"] = float(self.log_det)
            out["measured_periods"] = int(self.measured)
        if self.kind != "escape":
            out["seed"] = [float(self.seed[0]), float(self.seed[1])]
        if self.may_be_transient:
            out["may_be_transient"] = True
            out["confirmed_periods"] = self.confirmed
        return out

    def caveat(self) -> str:
        """What a listing of this attractor adds about its check (empty for a cycle, an island, escape)."""
        if not self.may_be_transient:
            return ""
        if self.confirmed is None:
            return "not checked: may be a long transient"
        return f"its seed stayed on it {self.confirmed} more periods; may be a longer transient"


@dataclass(frozen=True)
class Transient:
    """A recurrent set that is no attractor: its seed, continued (:meth:`_Run.confirm`), fell onto attractor
    ``onto`` (its id, at the end of a chain of transients; :data:`ESCAPE`: it escaped) within ``after`` periods
    past where it was located (to its first fall, or the horizon if it ended on a set found there). ``pixels``: the
    pixels the recurrences had given it, now ``onto``'s; ``points``: a sample of the set."""

    kind: str
    points: np.ndarray
    seed: tuple[float, float]
    onto: int
    after: int
    pixels: int

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "points": [[float(q), float(r)] for q, r in self.points[:16]],
                "seed": [float(v) for v in self.seed], "onto": self.onto, "after_periods": self.after,
                "pixels": self.pixels}  # fmt: skip

    def line(self) -> str:
        at = f" at ({self.points[-1, 0]:.6g}, {self.points[-1, 1]:.6g})" if self.points.shape[0] else ""
        where = "escaped" if self.onto == ESCAPE else f"fell onto attractor {self.onto}"
        return (f"a {self.kind.replace('_', '-')} set{at} is a transient, no attractor: its seed, continued, "
                f"{where} within {self.after} periods; its {self.pixels} pixels go with it")  # fmt: skip


@dataclass(frozen=True)
class BasinSpec:
    """Everything that defines a basin computation (validated by :func:`basin_spec`)."""

    params: Params
    box: tuple[float, float, float, float]
    nx: int
    ny: int
    numerics: Numerics
    cell_box: tuple[float, float, float, float]
    cells: tuple[int, int]
    chunk: int
    max_periods: int
    recurrences: int
    locate: int
    hit_attractor: int
    hit_basin: int | None
    p_max: int
    tol: float
    lyap_threshold: float
    inflight: int
    #: True: ``cells``/``cell_box`` are the defaults, refined from the attractors when they do not resolve
    #: them (:func:`iter_basins`); False: the caller's, kept (an unresolved grid is reported as a loss).
    adapt_cells: bool
    #: Newton on a cell's cycle (:meth:`_Run.cycle`); its map follows ``numerics``' tolerance
    #: (:meth:`~explorer_core.solve.options.NewtonOptions.at`, reference DEFAULT_BASIN_TOL).
    newton: NewtonOptions
    #: The continuation that confirms a chaotic or quasi-periodic set (:meth:`_Run.confirm`).
    confirm: int = option(
        CONFIRM_PERIODS,
        integer(0, config.MAX_PERIODS),
        "periods a chaotic or quasi-periodic set's seed is continued (at the tolerances / "
        f"{CONFIRM_TIGHTEN:g}) to confirm it falls onto no other attractor and does not escape (0: no check)",
    )
    #: The basin entropy's boxes (:attr:`Basins.entropy`): read from the labels, it changes no label.
    entropy_box: int = option(
        DEFAULT_BOX,
        integer(2, MAX_BOX),
        "pixels per side of the boxes of the basin entropy S_b and the boundary basin entropy S_bb (Daza et al. "
        "2016: 5)",
    )

    @property
    def q(self) -> np.ndarray:
        """(NX,) pixel centres in ``q``."""
        return pixel_centres(self.box, self.nx, self.ny)[0]

    @property
    def r(self) -> np.ndarray:
        """(NY,) pixel centres in ``r``."""
        return pixel_centres(self.box, self.nx, self.ny)[1]

    @property
    def cell_size(self) -> tuple[float, float]:
        b = self.cell_box
        return (b[1] - b[0]) / self.cells[0], (b[3] - b[2]) / self.cells[1]

    def as_dict(self) -> dict[str, Any]:
        return {
            "params": self.params.as_dict(),
            "box": list(self.box),
            "grid": [self.nx, self.ny],
            "numerics": self.numerics.as_dict(),
            "cell_box": list(self.cell_box),
            "cells": list(self.cells),
            "chunk": self.chunk,
            "max_periods": self.max_periods,
            "recurrences": self.recurrences,
            "locate": self.locate,
            "hit_attractor": self.hit_attractor,
            "hit_basin": self.hit_basin,
            "p_max": self.p_max,
            "tol": self.tol,
            "lyap_threshold": self.lyap_threshold,
            "adapt_cells": self.adapt_cells,
            "newton": self.newton.as_dict(),
            "newton_numerics": self.newton_map()[0].as_dict(),
            "confirm": self.confirm,
            "confirm_numerics": self.confirm_numerics().as_dict(),
            "entropy_box": self.entropy_box,
        }

    def newton_map(self) -> tuple[Numerics, float]:
        """The map Newton iterates on a cell's cycle and its ``ftol`` (the rule of ``NewtonOptions.at``)."""
        return self.newton.at(self.numerics, DEFAULT_BASIN_TOL)

    def confirm_numerics(self) -> Numerics:
        """The continuation's numerics: the tolerances divided by CONFIRM_TIGHTEN, not below CONFIRM_MIN_TOL."""
        n = self.numerics
        tight = lambda v: min(v, max(CONFIRM_MIN_TOL, v / CONFIRM_TIGHTEN))  # noqa: E731
        return n.loosened(tight(n.rtol), tight(n.atol))


@dataclass
class Basins(Drawable):
    """Basins of attraction on a grid of initial conditions (possibly partial: see ``computed``).

    ``q`` (NX,) and ``r`` (NY,) are the pixel centres; ``label`` (NY, NX) int: the id of the attractor
    the pixel's trajectory reaches (match ``Attractor.id``), or :data:`ESCAPE`, :data:`FAILED`,
    :data:`UNDECIDED`, :data:`NOT_COMPUTED`, or (partial results only) :data:`LOCATING`: an attractor
    that is still being located. ``computed`` (NY, NX) bool. Ids are 0, 1, ... in the order attractors
    are published, stable while the computation refines (an attractor later found to be one already
    known is merged into it; its id is not reused). ``fraction`` maps every label present (ids and
    negative outcomes) to its share of the computed pixels; ``status`` (NY, NX) int8: each pixel's
    :class:`~explorer_core.status.Status` code (``ok``: reached an attractor or a conservative set;
    ``escaped``: the engine's bound, or basin cells of escape with ``hit_basin``; the engine failure;
    ``undecided``; ``not_run``: not computed); ``statuses`` counts the computed pixels by status name;
    ``periods`` and ``steps`` are the work done (member-periods, RK steps).

    ``complete``: ``completed`` and nothing lost; ``lost``: the :class:`~explorer_core.losses.Loss` es
    (pixels undecided, failed, not computed or cancelled, still locating; attractors the recurrence
    cells may not resolve), with counts and reasons; ``warnings``: what the labels mean beyond the
    attractors (pixels on conservative invariant curves, which are in no basin; transients).

    ``not_reached``: recurrent sets no pixel ends on (the seed that located one escaped, failed or was
    undecided): no basin, so no attractor; their ids are not in ``label``. ``transients``: sets whose seed,
    continued ``spec.confirm`` periods (``Attractor.confirmed``), fell onto another attractor or escaped; the
    pixels the recurrences had given them are labelled with where they fell (:class:`Transient`).

    ``entropy``: the basin entropy ``S_b``, the boundary basin entropy ``S_bb`` and the uncertainty exponent of
    the labels (:mod:`explorer_core.analyses.basin_entropy`), computed when first asked.
    """

    spec: BasinSpec
    q: np.ndarray
    r: np.ndarray
    label: np.ndarray
    computed: np.ndarray
    attractors: list[Attractor]
    fraction: dict[int, float]
    statuses: dict[str, int]
    elapsed_s: float
    completed: bool
    stride: int
    periods: int = 0
    steps: int = 0
    extra: dict[str, Any] = field(default_factory=dict)
    complete: bool = False
    lost: list[Loss] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    status: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int8))
    not_reached: list[Attractor] = field(default_factory=list)
    transients: list[Transient] = field(default_factory=list)

    def attractor(self, ident: int) -> Attractor:
        for a in self.attractors:
            if a.id == ident:
                return a
        raise KeyError(f"no attractor with id {ident}")

    @functools.cached_property
    def entropy(self) -> BasinEntropy:
        """Basin entropy and boundary basin entropy (Daza et al. 2016) over boxes of ``spec.entropy_box`` pixels,
        and the uncertainty exponent read from the grid. Every final state is an outcome: an attractor, escape
        (:data:`ESCAPE`, an exit as in the paper's open systems) and a conservative island's label; pixels with
        none (failed, undecided, not computed, still locating) are excluded and counted, and a box holding one
        is skipped."""
        return basin_entropy(self.label, self.label >= ESCAPE, box=self.spec.entropy_box)

    def filled(self) -> np.ndarray:
        """(NY, NX) labels where every uncomputed pixel shows its nearest computed coarser-lattice pixel."""
        out = self.label.copy()
        done = self.computed.copy()
        ny, nx = done.shape
        jj, ii = np.mgrid[0:ny, 0:nx]
        s = 2
        while not done.all() and s <= 2 * max(ny, nx):
            pj, pi = (jj // s) * s, (ii // s) * s
            take = ~done & self.computed[pj, pi]
            out[take] = self.label[pj[take], pi[take]]
            done |= take
            s *= 2
        return out

    def summary(self) -> dict[str, Any]:
        """The result as JSON-ready data: ``{"attractors": [{"id", "kind", "period", "points", "fraction"}, ...]}``."""
        computed = int(self.computed.sum())
        if computed and not any(self.fraction.get(k, 0.0) for k in self.fraction if k >= ESCAPE):
            note = "every computed pixel failed or was undecided: no attractor to report"
        else:
            note = "; ".join(self.warnings) or None
        out: dict[str, Any] = {
            "attractors": [a.as_dict() for a in self.attractors],
            "not_reached": [a.as_dict() for a in self.not_reached],
            "transients": [t.as_dict() for t in self.transients],
            "failed_fraction": float(self.fraction.get(FAILED, 0.0)),
            "undecided_fraction": float(self.fraction.get(UNDECIDED, 0.0)),
            "statuses": dict(self.statuses),
            "pixels": int(self.computed.size),
            "computed": computed,
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "warnings": list(self.warnings),
            "elapsed_s": round(self.elapsed_s, 6),
            "entropy": self.entropy.as_dict(),
            "periods": int(self.periods),
            "steps": int(self.steps),
            **self.spec.as_dict(),
            **self.extra,
        }
        if note:
            out["note"] = note
        return out

    def report(self) -> list[str]:
        """What the command line prints: the attractors with their basins, then the pixels."""
        s = self.summary()
        out = []
        for a in self.attractors:
            per = f" period {a.period}" if a.period else ""
            at = f" at ({a.points[0, 0]:.6g}, {a.points[0, 1]:.6g})" if a.points.shape[0] else ""
            what = "attractor" if a.attracting else "not an attractor"  # a conservative island's curves
            note = f" ({a.caveat()})" if a.caveat() else ""
            out.append(f"{what} {a.id}: {a.kind}{per}{at}, basin {100 * a.fraction:.2f}%{note}")
        for a in self.not_reached:
            at = f" at ({a.points[0, 0]:.6g}, {a.points[0, 1]:.6g})" if a.points.shape[0] else ""
            out.append(f"not reached {a.id}: a {a.kind} set{at} that no pixel ends on (no basin, no attractor)")
        out.append(self.entropy.line())
        out.append(f"{s['computed']}/{s['pixels']} pixels ({describe(self.status[self.computed])}), "
                   f"{self.elapsed_s:.2f} s")  # fmt: skip
        return out + ([s["note"]] if "note" in s else [])

    def write(self, path: str) -> dict[str, Any]:
        """``.npz``: :meth:`to_npz`; ``.json``: the summary."""
        npz = lambda p: export.write_through(p, self.to_npz)  # noqa: E731
        return export.write_by_suffix(
            path, {".npz": npz, ".json": lambda p: export.write_json(p, self.summary())}, "basins image"
        )

    def to_npz(self, path: str) -> None:
        """Arrays ``q`` (NX,), ``r`` (NY,), ``label`` (NY, NX), ``status`` (NY, NX) codes with ``status_names``
        (the name of code ``c`` is ``status_names[c]``); ``computed`` and the summary as JSON."""
        import json

        np.savez_compressed(path, q=self.q, r=self.r, label=self.label, status=self.status,
                            status_names=status_names(), computed=self.computed,
                            summary=json.dumps(self.summary()))  # fmt: skip


@dataclass(frozen=True)
class BasinsUpdate:
    """Yielded by :func:`iter_basins`: the live result after a refinement level (or a progress tick)."""

    stride: int
    level_done: bool
    done_pixels: int
    total_pixels: int
    basins: Basins
    #: pixels computed in earlier passes (a pass restarted with finer cells counts as work done)
    earlier: int = 0

    @property
    def progress(self) -> Progress:
        done, total = self.earlier + self.done_pixels, self.earlier + self.total_pixels
        return Progress(done, total, "pixels", self.basins.elapsed_s)

    @property
    def result(self) -> Basins:
        """The live result (the last update's is final)."""
        return self.basins


# ---------------------------------------------------------------------------
# Validation.


#: The confirmation horizon's declaration (default, check, help) on the spec's field: the builder's option reads it.
_CONFIRM = BasinSpec.__dataclass_fields__["confirm"]
_ENTROPY_BOX = BasinSpec.__dataclass_fields__["entropy_box"]


def _grid(n: str, v: Any) -> tuple[int, int]:
    """``(NX, NY)`` pixels, each in ``[1, config.MAX_BASIN_GRID]``, at most ``config.MAX_BASIN_PIXELS`` in all."""
    try:
        nx, ny = (x for x in v)
    except (TypeError, ValueError):
        raise ParameterError(f"{n} must be two integers NX,NY, got {v!r}") from None
    nx = check_int(f"{n} NX", nx, 1, config.MAX_BASIN_GRID)
    ny = check_int(f"{n} NY", ny, 1, config.MAX_BASIN_GRID)
    if nx * ny > config.MAX_BASIN_PIXELS:
        raise ParameterError(f"{n} {nx}x{ny} has {nx * ny} pixels, more than {config.MAX_BASIN_PIXELS}")
    return nx, ny


def _cells(n: str, v: Any) -> tuple[int, int]:
    """``(NQ, NR)`` recurrence cells, each in ``[1, 4096]`` (its Check is optional: None, the default from the
    boxes, never reaches here)."""
    try:
        cq, cr = (x for x in v)
    except (TypeError, ValueError):
        raise ParameterError(f"{n} must be two integers, got {v!r}") from None
    return check_int(f"{n} NQ", cq, 1, 4096), check_int(f"{n} NR", cr, 1, 4096)


@declare(
    box=Arg(
        "the initial conditions' window", "box", metavar="Q0,Q1,R0,R1", scene="box", positional=True, check=box_check()
    ),
    grid=Arg(
        "pixels",
        "ints",
        metavar="NX,NY",
        positional=True,
        default=(100, 100),
        check=Check(
            _grid, f"two integers in [1, {config.MAX_BASIN_GRID}], at most {config.MAX_BASIN_PIXELS} pixels", "str"
        ),
    ),
    max_periods=Arg(
        "a pixel with no fate after this many periods is undecided (label -3)",
        "int",
        default=3000,
        check=integer(1, config.MAX_PERIODS),
    ),
    cell_box=Arg(
        "box of the recurrence cells (default: --box widened by its size on every side)",
        "box",
        metavar="Q0,Q1,R0,R1",
        default=None,
        check=box_check(optional=True),
    ),
    cells=Arg(
        "recurrence cells per axis (default 64 across --box)",
        "ints",
        metavar="NQ,NR",
        default=None,
        check=Check(_cells, "two integers in [1, 4096] or none", "str", optional=True),
    ),
    confirm=Arg(
        _CONFIRM.metadata["help"], "int", metavar="PERIODS", default=_CONFIRM.default, check=_CONFIRM.metadata["check"]
    ),
    entropy_box=Arg(
        _ENTROPY_BOX.metadata["help"],
        "int",
        metavar="PIXELS",
        default=_ENTROPY_BOX.default,
        check=_ENTROPY_BOX.metadata["check"],
    ),
    # None: derived from the cell box (the body).
    numerics=Arg("integration", cli=False, default=None, check=optional_of(Numerics)),
    chunk=Arg("periods per engine call", cli=False, default=5, check=integer(1, 1000)),
    recurrences=Arg("recurrences that locate an attractor", cli=False, default=100, check=integer(2, 1_000_000)),
    locate=Arg("periods that locate an attractor's cells", cli=False, default=1000, check=integer(1, 1_000_000)),
    hit_attractor=Arg("attractor cells that label a pixel", cli=False, default=3, check=integer(1, 1_000_000)),
    hit_basin=Arg(
        "basin cells that label a pixel (None: none)",
        cli=False,
        default=None,
        check=integer(1, 1_000_000, optional=True),
    ),
    p_max=Arg("longest cycle that goes to Newton", cli=False, default=16, check=integer(1, 64)),
    inflight=Arg("trajectories integrated at once", cli=False, default=512, check=integer(1, config.MAX_TRAJECTORIES)),
    tol=Arg("a cycle's points return within tol (1 + |x|)", cli=False, default=1e-5, check=fraction()),
    lyap_threshold=Arg("chaotic above it, quasi-periodic below", cli=False, default=5e-3, check=number()),
    newton=Arg("Newton on a cycle", cli=False, default=BASIN_NEWTON, check=instance(NewtonOptions)),
)
def basin_spec(
    params: Params,
    box: tuple[float, float, float, float],
    grid: tuple[int, int],
    *,
    numerics: Numerics | None,
    cell_box: tuple[float, float, float, float] | None,
    cells: tuple[int, int] | None,
    chunk: int,
    max_periods: int,
    recurrences: int,
    locate: int,
    hit_attractor: int,
    hit_basin: int | None,
    p_max: int,
    tol: float,
    lyap_threshold: float,
    inflight: int,
    newton: NewtonOptions,
    confirm: int,
    entropy_box: int,
) -> BasinSpec:
    """A validated :class:`BasinSpec`; every bad value raises :class:`ParameterError` naming it. The options are
    declared above (defaults, checks run before this body, flags); the body derives what depends on several.

    Parameters
    ----------
    box : ``(q0, q1, r0, r1)``, ordered and finite: the initial conditions' window.
    grid : ``(NX, NY)`` pixels, each in ``[1, config.MAX_BASIN_GRID]``, ``NX * NY <= config.MAX_BASIN_PIXELS``.
    numerics : integration (default DOP853 at :data:`DEFAULT_BASIN_TOL`, escape bound
        ``max(100, 10 max |cell_box|)``, at most the sections' 1e4 unless the cell box reaches beyond it).
    cell_box : the box of the recurrence cells (default: ``box`` widened by its size on every side).
    cells : cells per axis of ``cell_box`` (default: 64 across ``box``, so 192 across the default cell box).
        With both defaults the grid is refined from the attractors found when it does not resolve them
        (:func:`iter_basins`), so a pixel's label does not depend on the box around it; a grid the caller
        gives is kept, and the result reports it as a loss if it does not resolve the attractors.
    chunk : periods per engine call; ``max_periods``: a pixel still undecided then is :data:`UNDECIDED`.
    recurrences, locate, hit_attractor, hit_basin : the recurrence algorithm's counts (module docstring;
        Attractors.jl's ``consecutive_recurrences``, ``attractor_locate_steps``,
        ``consecutive_attractor_steps``, ``consecutive_basin_steps``); ``hit_basin=None`` (default):
        no labelling by basin cells.
    p_max, tol : cycles up to ``p_max`` whose points return within ``tol (1 + |x|)`` go to Newton.
    lyap_threshold : a non-periodic attractor is chaotic above it (per unit time), quasi-periodic below.
    inflight : trajectories integrated at once (finished ones are replaced by new pixels). Fewer reach
        the first level sooner: until the first attractor is classified every member in flight runs on
        (Fig. 11's tensor, 200 x 200, first level after 0.44 s with 512, 1.5 s with 2048 at about the same
        total; Fig. 8B 2.5 s against 8.8 s in all).
    newton : Newton on a cycle (default :data:`BASIN_NEWTON`: the orbits' preset without patience; its map
        follows ``numerics``' tolerance, 1e-12 at the default 1e-8).
    confirm : periods a chaotic or quasi-periodic set's seed is continued before the set is listed as an
        attractor (default :data:`CONFIRM_PERIODS`, declared on :attr:`BasinSpec.confirm`; 0: no check), see
        :meth:`_Run.confirm`.
    entropy_box : pixels per side of the basin entropy's boxes (default 5, the paper's; declared on
        :attr:`BasinSpec.entropy_box`): read from the labels afterwards (:attr:`Basins.entropy`), it changes none.
    """
    b = box
    if cell_box is None:
        wq, wr = b[1] - b[0], b[3] - b[2]
        cb = (b[0] - wq, b[1] + wq, b[2] - wr, b[3] + wr)
    else:
        cb = cell_box
    if cells is None:
        nq = max(1, round(64 * (cb[1] - cb[0]) / (b[1] - b[0])))
        nr = max(1, round(64 * (cb[3] - cb[2]) / (b[3] - b[2])))
        cl = (min(nq, 4096), min(nr, 4096))
    else:
        cl = cells
    if numerics is None:
        big = max(abs(v) for v in cb)
        bound = min(max(100.0, 10.0 * big), max(config.DEFAULT_ESCAPE_BOUND, 2.0 * big))
        numerics = Numerics(rtol=DEFAULT_BASIN_TOL, atol=DEFAULT_BASIN_TOL, bound=bound)
    return BasinSpec(params, b, *grid, numerics, cb, cl, chunk, max_periods, recurrences, locate, hit_attractor,
                     hit_basin, p_max, tol, lyap_threshold, inflight, cells is None and cell_box is None, newton,
                     confirm, entropy_box)  # fmt: skip


# ---------------------------------------------------------------------------
# The cell bookkeeping (numba: sequential over members, since they share the grids).


@njit(nogil=True, cache=True)
def _insert(table: np.ndarray, s: int, key: int) -> bool:
    """Put ``key`` (> 0) in member ``s``'s open-addressing table; True if it was there already."""
    size = table.shape[1]
    h = (key * 2654435761) & (size - 1)
    while True:
        v = table[s, h]
        if v == key:
            return True
        if v == 0:
            table[s, h] = key
            return False
        h = (h + 1) & (size - 1)


@njit(nogil=True, cache=True)
def _record(
    points: np.ndarray,
    npts: np.ndarray,
    slots: np.ndarray,
    geom: np.ndarray,
    att: np.ndarray,
    bas: np.ndarray,
    root: np.ndarray,
    ready: np.ndarray,
    table: np.ndarray,
    state: np.ndarray,
    ring: np.ndarray,
    counts: np.ndarray,
    overlaps: np.ndarray,
    recurrences: int,
    locate: int,
    hit_attractor: int,
    hit_basin: int,
    max_fill: int,
) -> None:
    """Feed each member's new section points to the recurrence algorithm (Datseris & Wagemakers 2022).

    ``points`` (n, c, 2) with ``npts[m]`` valid for member ``m`` in slot ``slots[m]``; ``geom`` =
    ``(q0, r0, 1/dq, 1/dr, NQ, NR)`` of the cells; ``att`` (NQ*NR,) attractor cells (provisional id + 1,
    0 none); ``bas`` (NQ*NR,) basin cells (id + 1, -1 escape, ``_MIXED``, 0 none); ``root`` maps a
    provisional id to the one it was merged into; ``ready`` (ids,) 1 for a classified attractor (only
    those label members: a provisional one may be a long transient, see :meth:`_Run.add_periodic`);
    ``table`` (slots, S) int32 each member's visited cells (open addressing); ``state`` (slots, 11)
    int64: phase, consecutive recurrences, attractor hit, its consecutive hits, basin hit, its
    consecutive hits, provisional id being located, periods located, outcome, cells visited, section
    points seen (the ring's write position); ``ring`` (slots, W, 2) the
    last W section points; ``counts`` = ``[provisional ids used, overlaps]``; ``overlaps`` (K, 2) pairs
    of attractors whose located cells touch. ``hit_basin = 0``: no labelling by basin cells.
    """
    q0, r0, iq, ir = geom[0], geom[1], geom[2], geom[3]
    nq, nr = int(geom[4]), int(geom[5])
    w = ring.shape[1]
    for m in range(slots.shape[0]):
        s = slots[m]
        for c in range(npts[m]):
            ph = state[s, 0]
            if ph != _SEARCH and ph != _LOCATE:
                break
            x, y = points[m, c, 0], points[m, c, 1]
            pos = state[s, 10] % w
            ring[s, pos, 0] = x
            ring[s, pos, 1] = y
            state[s, 10] += 1
            fq = (x - q0) * iq
            fr = (y - r0) * ir
            cell = -1
            if 0.0 <= fq < nq and 0.0 <= fr < nr:
                cell = int(fr) * nq + int(fq)
            if ph == _LOCATE:
                if cell >= 0:
                    a = att[cell]
                    mine = state[s, 6]
                    if a == 0:
                        att[cell] = mine + 1
                    elif root[a - 1] != root[mine] and counts[1] < overlaps.shape[0]:
                        overlaps[counts[1], 0] = mine
                        overlaps[counts[1], 1] = a - 1
                        counts[1] += 1
                state[s, 7] += 1
                if state[s, 7] >= locate:
                    state[s, 0] = _LOCATED
                continue
            if cell < 0:
                state[s, 1] = 0
                state[s, 3] = 0
                state[s, 5] = 0
                continue
            a = att[cell]
            if a > 0 and ready[root[a - 1]] != 0:
                ra = root[a - 1]
                if state[s, 2] == ra:
                    state[s, 3] += 1
                else:
                    state[s, 2] = ra
                    state[s, 3] = 1
                if state[s, 3] >= hit_attractor:
                    state[s, 8] = ra
                    state[s, 0] = _LABELLED
                    break
            else:
                state[s, 3] = 0
            b = bas[cell] if hit_basin > 0 else 0
            if b != 0 and b != _MIXED:
                lab = root[b - 1] if b > 0 else -1
                if state[s, 4] == lab and state[s, 5] > 0:
                    state[s, 5] += 1
                else:
                    state[s, 4] = lab
                    state[s, 5] = 1
                if state[s, 5] >= hit_basin:
                    state[s, 8] = lab
                    state[s, 0] = _LABELLED
                    break
            else:
                state[s, 5] = 0
            if _insert(table, s, cell + 1):
                state[s, 1] += 1
            else:
                state[s, 1] = 0
                state[s, 9] += 1
                if state[s, 9] >= max_fill:
                    state[s, 0] = _FULL
                    break
            if state[s, 1] >= recurrences and a == 0:  # (in a cell of one being located: wait for it)
                if counts[0] >= root.shape[0]:
                    state[s, 0] = _FULL
                    break
                mine = counts[0]
                counts[0] += 1
                state[s, 6] = mine
                state[s, 7] = 0
                state[s, 0] = _LOCATE
                att[cell] = mine + 1


@njit(nogil=True, cache=True)
def _settle(table: np.ndarray, s: int, att: np.ndarray, bas: np.ndarray, root: np.ndarray, code: int) -> None:
    """Member ``s`` ended with basin code ``code`` (id + 1, or -1 escape; 0: failed): mark the cells it crossed.

    A cell crossed by trajectories of different fates becomes ``_MIXED`` (no evidence). Clears the table.
    """
    size = table.shape[1]
    for h in range(size):
        key = table[s, h]
        if key == 0:
            continue
        table[s, h] = 0
        if code == 0:
            continue
        cell = key - 1
        if att[cell] != 0:
            continue
        b = bas[cell]
        if b == 0:
            bas[cell] = code
        elif b != _MIXED and b != code:
            same = b > 0 and code > 0 and root[b - 1] == root[code - 1]
            if not same:
                bas[cell] = _MIXED


def warmup() -> None:
    """Compile (or load from the on-disk cache) the bookkeeping kernels."""
    att = np.zeros(4, np.int64)
    bas = np.zeros(4, np.int64)
    root = np.arange(4, dtype=np.int64)
    table = np.zeros((1, 8), np.int32)
    state = np.zeros((1, 11), np.int64)
    ring = np.zeros((1, 4, 2))
    slots = np.zeros(1, np.int64)
    pts = np.array([[[0.5, 0.5], [0.5, 0.5], [1.5, 0.5]]])
    _record(pts, np.array([3], np.int64), slots, np.array([0.0, 0.0, 1.0, 1.0, 2.0, 2.0]), att, bas, root, root,
            table, state, ring, np.zeros(2, np.int64), np.zeros((2, 2), np.int64), 2, 1, 2, 2, 5)  # fmt: skip
    _settle(table, 0, att, bas, root, 1)
    # the recurrence kernel, as the run calls it
    recurrence(ring, CHART.with_(tol=1e-6, p_max=1, window=2), count=np.array([3]), rows=slots, ring=True)


# ---------------------------------------------------------------------------
# The driver.


@dataclass
class _Found:
    """An attractor as the driver tracks it (``internal`` is its provisional id)."""

    internal: int
    kind: str
    period: int | None
    points: np.ndarray
    multipliers: np.ndarray | None
    lyapunov: float | None
    seed: tuple[float, float]
    orbit: Orbit | None = None
    log_det: float | None = None
    measured: int = 0
    #: where the member that located it was when it was classified (the seed's trajectory, to continue)
    tip: np.ndarray | None = None
    #: periods the continuation stayed on it (:meth:`_Run.confirm`); why it could not be confirmed
    confirmed: int | None = None
    unconfirmed: str | None = None


def _area_trend(divs: np.ndarray) -> float:
    """The secular part of ``log |det DP^k|`` over ``k = 1..n`` (``divs``: the divergence integrated over
    each period): the least-squares slope times ``n``. On invariant curves of an island ``log |det|``
    oscillates (by up to ~3 on Fig. 4A) about a constant; on an attractor it falls."""
    k = np.arange(1, divs.shape[0] + 1)
    return float(np.polyfit(k, np.cumsum(divs), 1)[0] * divs.shape[0])


def _min_distance(a: np.ndarray, b: np.ndarray | None = None) -> float:
    """Smallest distance between a point of ``a`` and one of ``b`` (or between two points of ``a``)."""
    if b is None:
        if a.shape[0] < 2:
            return math.inf
        d = np.linalg.norm(a[:, None] - a[None], axis=-1)
        return float(d[np.triu_indices(a.shape[0], 1)].min())
    if a.shape[0] == 0 or b.shape[0] == 0:
        return math.inf
    return float(np.linalg.norm(a[:, None] - b[None], axis=-1).min())


def attractor_scale(found: Sequence[_Found]) -> float | None:
    """The length the recurrence cells must resolve (a cell's diagonal at most ``1 / RESOLVE`` of it).

    Set by the cycles, whose points Newton makes exact: the smallest of the distances between two points
    of one cycle, between a cycle's points and another attractor's points, and ``1 + |x|`` of a cycle's
    points (a lone fixed point has no length of its own: the size of the state stands in, as in the
    tolerances). The sampled points of chaotic and quasi-periodic attractors do not set it among
    themselves: 256 located points may be an arc of a slow invariant curve (Fig. 7A: 0.05 x 0.005), and
    two samples of one chaotic attractor not merged yet lie close (Fig. 1C: 0.45); on both, cells that
    fine left most pixels undecided. Conservative sets never count (a chaotic sea comes arbitrarily close
    to its islands). None while no cycle is classified.
    """
    scale = math.inf
    cycles, others = [], []
    for f in found:
        pts = np.asarray(f.points, float).reshape(-1, 2)
        pts = pts[np.isfinite(pts).all(axis=1)]
        if pts.shape[0] == 0 or f.kind == "conservative":
            continue
        if f.kind == "periodic":
            scale = min(scale, _min_distance(pts), 1.0 + float(np.linalg.norm(pts, axis=1).min()))
            cycles.append(pts)
        else:
            others.append(pts)
    for i, a in enumerate(cycles):
        for b in cycles[i + 1 :] + others:
            scale = min(scale, _min_distance(a, b))
    return scale if math.isfinite(scale) and scale > 0 else None


def refined_cells(
    found: Sequence[_Found], scale: float, within: Sequence[float] | None = None
) -> tuple[tuple[float, float, float, float], tuple[int, int]]:
    """A recurrence grid whose cells are sized from the attractors, not from the box: square, diagonal
    ``scale / (1.25 RESOLVE)``. It covers ``within`` (the default cell box) and the attractors' points
    (conservative sets aside) widened on every side by the larger of their extent and ``4 scale``, when
    that takes at most :data:`MAX_REFINED_CELLS` per axis (attractors not found yet are found by their
    recurrences there as before); else the attractors' region alone (a +-500 box), with cells coarsened
    only if even that needs more."""
    pts = np.vstack([np.asarray(f.points, float).reshape(-1, 2) for f in found if f.kind != "conservative"])
    pts = pts[np.isfinite(pts).all(axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = max(float((hi - lo).max()), 4.0 * scale)
    lo, hi = lo - margin, hi + margin
    h = scale / (1.25 * RESOLVE * math.sqrt(2.0))
    if within is not None:
        wlo = np.minimum(lo, [within[0], within[2]])
        whi = np.maximum(hi, [within[1], within[3]])
        if float((whi - wlo).max()) / h <= MAX_REFINED_CELLS:
            lo, hi = wlo, whi
    h = max(h, float((hi - lo).max()) / MAX_REFINED_CELLS)
    cells = (max(1, math.ceil((hi[0] - lo[0]) / h)), max(1, math.ceil((hi[1] - lo[1]) / h)))
    box = (float(lo[0]), float(lo[0] + cells[0] * h), float(lo[1]), float(lo[1] + cells[1] * h))
    return box, cells


def _levels(ny: int, nx: int) -> list[tuple[int, np.ndarray]]:
    """``(stride, flat pixel indices)`` of each level, every pixel once, coarse first."""
    jj, ii = np.mgrid[0:ny, 0:nx]
    taken = np.zeros((ny, nx), bool)
    out = []
    for s in LEVELS:
        sel = (jj % s == 0) & (ii % s == 0) & ~taken
        taken |= sel
        out.append((s, np.flatnonzero(sel.ravel())))
    return out


class _Run:
    """State of one basin computation (see :func:`iter_basins`)."""

    def __init__(self, spec: BasinSpec) -> None:
        self.spec = spec
        self.map = PoincareMap.of(spec.params, spec.numerics)
        qq, rr = np.meshgrid(spec.q, spec.r)
        self.ics = np.column_stack([qq.ravel(), rr.ravel()])
        n_pix = self.ics.shape[0]
        self.label = np.full(n_pix, NOT_COMPUTED, dtype=np.int64)  # internal ids until published
        self.fate = np.full(n_pix, Status.NOT_RUN, dtype=np.int8)  # the Status of each pixel
        nq, nr = spec.cells
        cq, cr = spec.cell_size
        self.geom = np.array([spec.cell_box[0], spec.cell_box[2], 1.0 / cq, 1.0 / cr, float(nq), float(nr)])
        self.att = np.zeros(nq * nr, np.int64)
        self.bas = np.zeros(nq * nr, np.int64)
        self.root = np.arange(MAX_ATTRACTORS, dtype=np.int64)
        self.ready = np.zeros(MAX_ATTRACTORS, dtype=np.int64)
        self.counts = np.zeros(2, np.int64)
        self.overlaps = np.zeros((4096, 2), np.int64)
        slots = min(spec.inflight, n_pix)
        self.slots = slots
        self.table = np.zeros((slots, table_size(spec.cells)), np.int32)
        self.state = np.zeros((slots, 11), np.int64)
        self.window = 3 * spec.p_max
        # a member's last points return as a chart's (its early look): every pair of the ring within tol (1 + |x|)
        self.returns = CHART.with_(tol=spec.tol, p_max=spec.p_max, window=self.window)
        self.ring = np.zeros((slots, max(256, self.window), 2))
        self.y = np.zeros((slots, 2))
        self.h = np.zeros(slots)
        self.status = np.zeros(slots, np.int64)
        self.nsteps = np.zeros(slots, np.int64)
        self.pixel = np.full(slots, -1, np.int64)
        self.age = np.zeros(slots, np.int64)
        self.may_check = np.ones(slots, bool)
        self.k = 0
        self.found: dict[int, _Found] = {}  # internal id -> classified attractor (roots and merged)
        self.locating: dict[int, int] = {}  # internal id -> slot of its locating member
        self.public: dict[int, int] = {}  # internal id of a root -> the id the results show
        self.touch: set[tuple[int, int]] = set()  # attractors whose located cells touch, to merge once classified
        self.periods = 0
        self.steps = 0
        self.version = 0  # bumped when an attractor is classified or merged (the grid's resolution is checked)
        self.scale: float | None = None  # the attractors' length scale (attractor_scale), when last checked
        self.refinements = 0  # runs restarted on cells sized from the attractors before this one
        self.earlier = (0, 0)  # periods and steps of those runs
        self.transients: list[tuple[_Found, int, int, int]] = []  # (set, onto: internal id or ESCAPE, after, pixels)

    def roots(self) -> list[_Found]:
        """The classified attractors (roots of the merges)."""
        return [f for i, f in sorted(self.found.items()) if self.find(i) == i]

    # -- attractors ----------------------------------------------------------

    def find(self, a: int) -> int:
        while self.root[a] != a:
            a = int(self.root[a])
        return a

    def merge(self, a: int, into: int) -> None:
        a, into = self.find(a), self.find(into)
        if a != into:
            self.root[a] = into
            # path compression for the kernel: every id points at its root
            for i in range(int(self.counts[0])):
                self.root[i] = self.find(i)

    def new_id(self) -> int:
        if self.counts[0] >= MAX_ATTRACTORS:
            raise RuntimeError(f"more than {MAX_ATTRACTORS} attractors registered")
        i = int(self.counts[0])
        self.counts[0] += 1
        return i

    def mark_cells(self, ident: int, pts: np.ndarray) -> None:
        nq, nr = self.spec.cells
        fq = (pts[:, 0] - self.geom[0]) * self.geom[2]
        fr = (pts[:, 1] - self.geom[1]) * self.geom[3]
        ok = (fq >= 0) & (fq < nq) & (fr >= 0) & (fr < nr)
        cells = fr[ok].astype(np.int64) * nq + fq[ok].astype(np.int64)
        owner = self.att[cells]
        free = cells[(owner == 0) | (self.ready[self.root[np.maximum(owner, 1) - 1]] == 0)]  # none, or pending
        self.att[free] = ident + 1

    def periodic_match(self, x: np.ndarray) -> int | None:
        """A known periodic attractor with a point within ``tol``-ish of ``x`` (or None)."""
        for f in self.found.values():
            if f.kind == "periodic" and self.find(f.internal) == f.internal:
                d = np.linalg.norm(f.points - x[None, :], axis=1).min()
                if d <= max(1e-3, 100 * self.spec.tol) * (1.0 + float(np.abs(x).max())):
                    return f.internal
        return None

    def cycle(self, x: np.ndarray, p: int) -> Orbit | None:
        """The attracting cycle Newton finds from ``x`` with period ``p`` (least period), or None."""
        numerics, ftol = self.spec.newton_map()
        search = find_orbits(self.spec.params, np.asarray(x, float).reshape(1, 2), [int(p)], numerics=numerics,
                             ftol=ftol, workers=1, **self.spec.newton.newton_kwargs())  # fmt: skip
        if not search.orbits:
            return None
        orbit = search.orbits[0]
        if not orbit.stable:
            return None
        return orbit

    def add_periodic(self, ident: int, orbit: Orbit, seed: tuple[float, float]) -> int:
        """Register ``orbit`` as attractor ``ident`` (or merge into the same orbit found before); its root.

        A cycle's cells are the cells of its points only: the cells a member marked while locating it are
        dropped, since 100 recurrences can be a long transient (on Fig. 11's tensor a chaotic transient of
        ~1000 periods near the basin boundary marked 127 cells from ``r = -2.7`` to ``0.6`` before it fell
        on the period-1 focus; with those cells 130 of 40000 pixels were mislabelled).
        """
        self.att[self.att == ident + 1] = 0
        for f in list(self.found.values()):
            if f.orbit is not None and self.find(f.internal) == f.internal and same_orbit(f.orbit, orbit, 1e-6):
                self.merge(ident, f.internal)
                self.mark_cells(f.internal, orbit.points)
                return f.internal
        self.found[ident] = _Found(ident, "periodic", orbit.period, orbit.points, orbit.multipliers, None, seed,
                                   orbit)  # fmt: skip
        self.mark_cells(ident, orbit.points)
        self.ready[ident] = 1
        self.version += 1
        return ident

    def ring_points(self, s: int) -> np.ndarray:
        n = int(self.state[s, 10])
        w = self.ring.shape[1]
        m = min(n, w)
        idx = (n - m + np.arange(m)) % w
        return self.ring[s, idx].copy()

    def classify_located(self, ident: int, s: int) -> None:
        """The member in slot ``s`` located attractor ``ident``: a cycle (Newton) or not (Lyapunov exponent)."""
        spec = self.spec
        pts = self.ring_points(s)
        seed = tuple(float(v) for v in self.ics[self.pixel[s]])
        if pts.shape[0] > spec.p_max + 1:
            cq, cr = spec.cell_size
            tail = pts[-min(pts.shape[0], self.window) :]
            p = int(recurrence(tail, SWEEP, tol=math.hypot(cq, cr), p_max=spec.p_max).period)
            if p:
                orbit = self.cycle(pts[-1], p)
                if orbit is not None:
                    d = np.linalg.norm(orbit.points - pts[-1][None, :], axis=1).min()
                    if d <= 2 * math.hypot(cq, cr):
                        self.add_periodic(ident, orbit, seed)  # type: ignore[arg-type]
                        return
        lyap = log_det = None
        measured = blocks = 0
        if pts.shape[0]:
            res = lyapunov_spectrum(
                spec.params, pts[-1:], LYAP_PERIODS, transient=20, numerics=spec.numerics, workers=1
            )
            # a leaky set (the run escapes) still has an exponent over the periods it completed
            measured = int(res.npts[0])
            if measured >= LYAP_MIN_PERIODS:
                lyap = float(res.exponents[0, 0])
                log_det = _area_trend(res.divs[0, :measured])
                if lyap > spec.lyap_threshold:
                    # a chaotic set's finite-time trend wanders either way (Fig. 2C's attractor, whose blocks of
                    # 300 periods contract by 22 on average, showed +2.3 over one): decide on the mean of
                    # CHAOTIC_BLOCKS blocks, not on one
                    more = lyapunov_spectrum(spec.params, pts[-1:], CHAOTIC_BLOCKS * LYAP_PERIODS, transient=0,
                                             numerics=spec.numerics, workers=1)  # fmt: skip
                    if int(more.npts[0]) >= 2 * LYAP_PERIODS:
                        blocks = int(more.npts[0]) // LYAP_PERIODS
                        measured = blocks * LYAP_PERIODS
                        log_det = _area_trend(more.divs[0, :measured])
                        lyap = float(more.exponents[0, 0])
                elif -CONSERVATIVE_LOG_DET < log_det < -CONSERVATIVE_LOG_DET / 4:
                    # 300 periods cannot tell a weak contraction from the oscillation: five times longer
                    more = lyapunov_spectrum(spec.params, pts[-1:], 5 * LYAP_PERIODS, transient=20,
                                             numerics=spec.numerics, workers=1)  # fmt: skip
                    if int(more.npts[0]) >= 5 * LYAP_PERIODS:
                        measured = int(more.npts[0])
                        log_det = _area_trend(more.divs[0, :measured])
        kind = "chaotic" if lyap is not None and lyap > spec.lyap_threshold else "quasi_periodic"
        if log_det is not None and log_det / max(blocks, 1) > -CONSERVATIVE_LOG_DET:
            # area not contracted: invariant curves (or a chaotic layer, whose finite-time trend wanders either
            # way: +5.9 over 300 periods in Fig. 2C's merged island) of an island, no attractor
            kind = "conservative"
        found = _Found(ident, kind, None, pts, None, lyap, seed, None, log_det, measured,  # type: ignore[arg-type]
                       pts[-1].copy() if pts.shape[0] else None)  # fmt: skip
        self.found[ident] = found
        self.ready[ident] = 1
        self.version += 1
        if kind == "conservative":
            # one entry for every conservative set: neighbouring invariant curves are not separate attractors
            for f in self.found.values():
                if f.kind == "conservative" and f.internal != ident and self.find(f.internal) == f.internal:
                    self.merge(ident, f.internal)
                    f.points = np.vstack([f.points, pts])[-512:]
                    f.log_det = max(f.log_det, log_det, key=abs)  # type: ignore[arg-type]
                    f.measured = min(f.measured, measured)
                    break

    def merge_overlaps(self) -> None:
        """Attractors whose located cells touch are one (both classified and not periodic: a cycle is exact)."""
        n = int(self.counts[1])
        self.touch.update((int(a), int(b)) for a, b in self.overlaps[:n])
        self.counts[1] = 0
        for a, b in sorted(self.touch):
            ra, rb = self.find(a), self.find(b)
            fa, fb = self.found.get(ra), self.found.get(rb)
            if ra != rb and (fa is None or fb is None):
                continue  # one is still being located
            self.touch.discard((a, b))
            # (a conservative island next to an attractor stays apart: it is in no basin)
            if (
                ra != rb
                and "periodic" not in (fa.kind, fb.kind)
                and (fa.kind == "conservative") == (fb.kind == "conservative")
            ):
                self.version += 1
                lo, hi = sorted((ra, rb))
                self.merge(hi, lo)
                f, g = self.found[lo], self.found[hi]
                exps = [v for v in (f.lyapunov, g.lyapunov) if v is not None]
                f.lyapunov = max(exps) if exps else None
                f.kind = "chaotic" if "chaotic" in (f.kind, g.kind) else f.kind
                f.points = np.vstack([f.points, g.points])[-256:]
                f.log_det = max((v for v in (f.log_det, g.log_det) if v is not None), default=None, key=abs)

    # -- confirmation --------------------------------------------------------------

    def pixels_of(self) -> dict[int, int]:
        """Pixels labelled with each attractor (root id -> count)."""
        lab = self.label[self.label >= 0]
        roots, counts = np.unique(self.root[lab], return_counts=True)  # (the roots are path-compressed)
        return {int(r): int(c) for r, c in zip(roots, counts, strict=True)}

    def falls_onto(self, pts: np.ndarray, own: int, carry: tuple[int, int]) -> tuple[int, int, tuple[int, int]]:
        """Scan section points ``pts`` (n, 2) for ``hit_attractor`` in a row in the cells of one classified
        attractor other than ``own`` (conservative sets aside: nothing falls onto an island), as a pixel is
        labelled. ``carry``: (attractor, points in a row) from the previous points. Returns ``(that attractor's
        root or -1, points scanned up to the hit, carry)``."""
        eligible = [i for i, f in self.found.items()
                    if self.find(i) == i and i != own and f.kind != "conservative" and self.ready[i]]  # fmt: skip
        nq, nr = self.spec.cells
        fq = (pts[:, 0] - self.geom[0]) * self.geom[2]
        fr = (pts[:, 1] - self.geom[1]) * self.geom[3]
        ok = (fq >= 0) & (fq < nq) & (fr >= 0) & (fr < nr)
        owner = np.full(pts.shape[0], -1, np.int64)
        a = self.att[fr[ok].astype(np.int64) * nq + fq[ok].astype(np.int64)]
        owner[ok] = np.where(a > 0, self.root[np.maximum(a, 1) - 1], -1)
        owner[~np.isin(owner, eligible)] = -1
        prev, count = carry
        for j, o in enumerate(owner.tolist()):
            prev, count = (o, count + 1 if o == prev else 1) if o >= 0 else (-1, 0)
            if count >= self.spec.hit_attractor:
                return o, j + 1, (prev, count)
        return -1, -1, (prev, count)

    def confirm(self, cancel: Callable[[], bool] | None = None) -> bool:
        """Continue the seed of every chaotic or quasi-periodic attractor with pixels ``spec.confirm`` periods past
        where it was located, at ``spec.confirm_numerics()`` (Attractors.jl's rule: an attractor is what recurs
        after a transient long enough; 100 recurrences can be a long transient). A set whose continuation
        escapes, lands ``hit_attractor`` times in a row in another attractor's cells, or ends (its last
        CONFIRM_CHUNK points) on a stable cycle (Newton) or, for a chaotic set, with a Lyapunov exponent below
        ``lyap_threshold`` (a regular set: registered as a quasi-periodic attractor), is a transient: its pixels
        go to where it fell (:meth:`reassign`). One that stays is ``confirmed`` for the horizon. False if
        ``cancel`` stopped it (the sets not done are ``unconfirmed``, a loss of the result)."""
        spec = self.spec
        pixels = self.pixels_of()
        todo = [f for f in self.roots() if f.kind in ("chaotic", "quasi_periodic") and f.tip is not None
                and f.confirmed is None and f.unconfirmed is None and pixels.get(f.internal, 0)]  # fmt: skip
        if not todo or spec.confirm == 0:
            return True
        cmap = PoincareMap.of(spec.params, spec.confirm_numerics())
        state = Batch.start(np.array([f.tip for f in todo]), spec.params.t0, spec.params.period)
        carry = [(-1, 0)] * len(todo)
        tails = [np.zeros((0, 2))] * len(todo)
        live = np.ones(len(todo), bool)
        onto: dict[int, tuple[int, int]] = {}  # internal id -> (where it fell: internal id or ESCAPE, after periods)
        done = 0
        while done < spec.confirm and live.any():
            if cancel is not None and cancel():
                for i in np.flatnonzero(live):
                    todo[i].unconfirmed = f"cancelled after {done} of {spec.confirm} periods of its seed's continuation"
                return False
            idx = np.flatnonzero(live)
            n = min(CONFIRM_CHUNK, spec.confirm - done)
            # (every chunk starts at the section phase t0: the forcing is periodic, and no large time is summed)
            sub = Batch(state.y[idx], state.h[idx], state.status[idx], state.nsteps[idx], 0, spec.params.t0,
                        spec.params.period)  # fmt: skip
            steps0 = int(sub.nsteps.sum())
            pts, npts = cmap.advance(sub, n)
            state.y[idx], state.h[idx], state.status[idx], state.nsteps[idx] = sub.y, sub.h, sub.status, sub.nsteps
            self.steps += int(sub.nsteps.sum()) - steps0
            self.periods += int(npts.sum())
            for c, i in enumerate(idx):
                f, p = todo[i], pts[c, : npts[c]]
                hit, j, carry[i] = self.falls_onto(p, f.internal, carry[i])
                st = Status.of(int(sub.status[c]))
                if hit >= 0:
                    onto[f.internal] = (hit, done + j)
                elif st == Status.ESCAPED:
                    onto[f.internal] = (ESCAPE, done + int(npts[c]) + 1)  # (it escaped during the next period)
                elif st != Status.OK:
                    f.unconfirmed = f"its seed's continuation failed after {done + int(npts[c])} periods: {st.word}"
                else:
                    tails[i] = np.vstack([tails[i], p])[-CONFIRM_CHUNK:]
                    continue
                live[i] = False
            done += n
        for i in np.flatnonzero(live):
            f = todo[i]
            hit = self.ends_on(f, tails[i])
            if hit is None:
                f.confirmed = spec.confirm
            else:
                onto[f.internal] = (hit, spec.confirm)
        self.reassign(onto)
        return True

    def ends_on(self, f: _Found, tail: np.ndarray) -> int | None:
        """The attractor (internal id) the last points ``tail`` of ``f``'s continuation lie on if it is not ``f``:
        another's cells (one registered since), a stable cycle (registered), or for a chaotic ``f`` a regular
        set (Lyapunov exponent below the threshold over CONFIRM_LYAP_PERIODS: registered as quasi-periodic); else
        None."""
        spec = self.spec
        hit, _, _ = self.falls_onto(tail, f.internal, (-1, 0))
        if hit >= 0:
            return hit
        cq, cr = spec.cell_size
        if tail.shape[0] > spec.p_max + 1:
            p = int(recurrence(tail[-self.window :], SWEEP, tol=math.hypot(cq, cr), p_max=spec.p_max).period)
            orbit = self.cycle(tail[-1], p) if p else None
            if orbit is not None:
                return self.add_periodic(self.new_id(), orbit, f.seed)
        if f.kind != "chaotic" or tail.shape[0] == 0:
            return None
        res = lyapunov_spectrum(spec.params, tail[-1:], CONFIRM_LYAP_PERIODS, transient=20,
                                numerics=spec.confirm_numerics(), workers=1)  # fmt: skip
        measured = int(res.npts[0])
        if measured < LYAP_MIN_PERIODS or float(res.exponents[0, 0]) > spec.lyap_threshold:
            return None
        ident = self.new_id()
        self.found[ident] = _Found(ident, "quasi_periodic", None, tail[-256:].copy(), None, float(res.exponents[0, 0]),
                                   f.seed, None, _area_trend(res.divs[0, :measured]), measured, tail[-1].copy(),
                                   tail.shape[0])  # fmt: skip
        self.ready[ident] = 1
        self.mark_cells(ident, tail)
        self.version += 1
        return ident

    def reassign(self, onto: dict[int, tuple[int, int]]) -> None:
        """The sets of ``onto`` (internal id -> (where it fell, after periods)) are transients: their pixels go to
        where they fall in the end (a chain followed; sets that fall onto each other stay, one recurrent set),
        escape for those that escape; they label nothing more and are listed as :class:`Transient`."""
        pixels = self.pixels_of()
        for ident, (target, after) in onto.items():
            seen = {ident}
            while target in onto and target not in seen:
                seen.add(target)
                target = onto[target][0]
            f = self.found[ident]
            if target in seen:
                f.confirmed = self.spec.confirm  # (a loop: they recur among themselves)
                continue
            mine = self.label >= 0
            mine[mine] = self.root[self.label[mine]] == ident
            self.label[mine] = target
            if target == ESCAPE:
                self.fate[mine] = Status.ESCAPED
            self.transients.append((f, target, after, pixels.get(ident, 0)))
        for f, _, _, _ in self.transients:
            if f.internal in self.found:
                ids = np.flatnonzero(self.root[: int(self.counts[0])] == f.internal)
                self.att[np.isin(self.att, ids + 1)] = 0
                self.ready[f.internal] = 0
                del self.found[f.internal]

    # -- members ---------------------------------------------------------------

    def end(self, s: int, label: int, code: int, status: Status = Status.OK) -> None:
        """Member in slot ``s`` is done: pixel label (internal id or negative outcome) and status, its cells marked."""
        pix = self.pixel[s]
        self.label[pix] = label
        self.fate[pix] = status
        _settle(self.table, s, self.att, self.bas, self.root, code)
        self.pixel[s] = -1

    def step(self, queue: list[int]) -> None:
        """Fill free slots, advance every live member by one chunk, and settle those whose fate is known."""
        spec = self.spec
        free = np.flatnonzero(self.pixel < 0)
        take = min(free.size, len(queue))
        if take:
            slots = free[:take]
            pix = np.array(queue[:take], dtype=np.int64)
            del queue[:take]
            self.pixel[slots] = pix
            self.y[slots] = self.ics[pix]
            self.h[slots] = 0.0
            self.status[slots] = Status.OK
            self.nsteps[slots] = 0
            self.state[slots] = 0
            self.state[slots, 2] = -(2**40)
            self.state[slots, 4] = -(2**40)
            self.age[slots] = 0
            self.may_check[slots] = True
        live = np.flatnonzero(self.pixel >= 0)
        if live.size == 0:
            return
        batch = Batch(self.y[live], self.h[live], self.status[live], self.nsteps[live], self.k,
                      spec.params.t0, spec.params.period)  # fmt: skip
        steps0 = int(batch.nsteps.sum())
        pts, npts = self.map.advance(batch, spec.chunk)
        self.k += spec.chunk
        self.y[live], self.h[live], self.status[live], self.nsteps[live] = batch.y, batch.h, batch.status, batch.nsteps
        self.steps += int(batch.nsteps.sum()) - steps0
        self.periods += int(npts.sum())
        self.age[live] += npts
        _record(pts, npts, live, self.geom, self.att, self.bas, self.root, self.ready, self.table, self.state,
                self.ring,
                self.counts, self.overlaps, spec.recurrences, spec.locate, spec.hit_attractor, spec.hit_basin or 0,
                int(0.7 * self.table.shape[1]))  # fmt: skip
        phase = self.state[live, 0]
        # Located attractors: classify (a cycle or not).
        for s in live[phase == _LOCATED]:
            ident = int(self.state[s, 6])
            self.locating.pop(ident, None)
            self.classify_located(ident, s)
            r = self.find(ident)
            self.end(s, r, r + 1)
        for s in live[phase == _LOCATE]:
            self.locating[int(self.state[s, 6])] = int(s)
        for s in live[phase == _LABELLED]:
            lab = int(self.state[s, 8])
            # a negative label from basin cells is escape (only with hit_basin)
            self.end(s, lab, lab + 1 if lab >= 0 else -1, Status.OK if lab >= 0 else Status.ESCAPED)
        for s in live[phase == _FULL]:
            self.end(s, UNDECIDED, 0, Status.UNDECIDED)
        # Cycles: members whose last points return (as the chart's early stops) go to Newton.
        search = live[(self.state[live, 0] == _SEARCH) & (self.pixel[live] >= 0) & self.may_check[live]
                      & (self.status[live] == Status.OK)]  # fmt: skip
        if search.size:
            # (each slot's ring holds its last points, point k at k % w; state[s, 10] of them written)
            per = recurrence(self.ring, self.returns, count=self.state[search, 10], rows=search, ring=True).period
            for s, p in zip(search[per > 0], per[per > 0], strict=True):
                x = self.ring_points(int(s))[-1]
                known = self.periodic_match(x)
                if known is None:
                    orbit = self.cycle(x, int(p))
                    if orbit is None:
                        self.may_check[s] = False
                        continue
                    known = self.add_periodic(self.new_id(), orbit, tuple(float(v) for v in self.ics[self.pixel[s]]))
                self.end(int(s), known, known + 1)
        # Engine failures and escapes of members still running; the undecided.
        for s in np.flatnonzero((self.pixel >= 0) & (self.status != Status.OK)):
            st = Status.of(int(self.status[s]))
            self._drop_locating(int(s))
            self.end(int(s), ESCAPE if st == Status.ESCAPED else FAILED, -1 if st == Status.ESCAPED else 0, st)
        for s in np.flatnonzero((self.pixel >= 0) & (self.age >= spec.max_periods)):
            self._drop_locating(int(s))
            self.end(int(s), UNDECIDED, 0, Status.UNDECIDED)
        self.merge_overlaps()

    def _drop_locating(self, s: int) -> None:
        """A locating member ended early: classify its attractor from what it saw."""
        if self.state[s, 0] == _LOCATE:
            ident = int(self.state[s, 6])
            self.locating.pop(ident, None)
            self.classify_located(ident, s)

    # -- results -----------------------------------------------------------------

    def snapshot(self, start: float, completed: bool, stride: int, cancelled: bool = False) -> Basins:
        spec = self.spec
        lab = self.label.copy()
        pos = lab >= 0
        # Public ids: 0, 1, ... in the order attractors are first published (stable while refining).
        for ident in sorted(self.found):
            if self.find(ident) == ident and ident not in self.public:
                self.public[ident] = len(self.public)
        if pos.any():
            roots = np.array([self.find(int(v)) for v in range(int(self.counts[0]))], dtype=np.int64)
            lab[pos] = roots[lab[pos]]
            table = np.full(int(self.counts[0]), LOCATING, dtype=np.int64)  # attractors still being located
            for ident, pub in self.public.items():
                table[ident] = pub
            lab[pos] = table[lab[pos]]
        computed = lab != NOT_COMPUTED
        n = max(1, int(computed.sum()))
        values, counts = np.unique(lab[computed], return_counts=True)
        fraction = {int(v): float(c) / n for v, c in zip(values, counts, strict=True)}
        attractors, not_reached = [], []
        for ident in sorted(self.found):
            f = self.found[ident]
            if self.find(ident) != ident:
                continue
            a = Attractor(self.public[ident], f.kind, f.period, f.points, f.multipliers, f.lyapunov,
                          fraction.get(self.public[ident], 0.0), f.seed, f.orbit.kind if f.orbit is not None else None,
                          f.kind != "conservative", f.log_det, f.measured, f.confirmed)  # fmt: skip
            # a set no pixel reaches (its own seed escaped, failed or was undecided) has no basin: no attractor
            (attractors if self.public[ident] in fraction else not_reached).append(a)
        attractors.sort(key=lambda a: a.id)
        transients = [Transient(f.kind, f.points, f.seed, self.public.get(onto, onto), after, n)
                      for f, onto, after, n in self.transients]  # fmt: skip
        if fraction.get(ESCAPE):
            attractors.append(Attractor(ESCAPE, "escape", None, np.zeros((0, 2)), fraction=fraction[ESCAPE]))
        statuses = count_names(self.fate[computed])
        lost, warnings = self.losses(lab, completed, cancelled)
        warnings = [t.line() for t in transients] + warnings
        extra = {"escape_bound": spec.numerics.bound, "cell_refinements": self.refinements,
                 "attractor_scale": self.scale}  # fmt: skip
        return Basins(spec, spec.q, spec.r, lab.reshape(spec.ny, spec.nx), computed.reshape(spec.ny, spec.nx),
                      attractors, fraction, statuses, time.perf_counter() - start, completed, stride,
                      self.periods + self.earlier[0], self.steps + self.earlier[1], extra, completed and not lost,
                      lost, warnings, self.fate.reshape(spec.ny, spec.nx).copy(), not_reached,
                      transients)  # fmt: skip

    def losses(self, lab: np.ndarray, completed: bool, cancelled: bool) -> tuple[list[Loss], list[str]]:
        """What the labels ``lab`` (public) lost, and what they mean beyond attractors."""
        spec = self.spec
        lost = []
        n = int(np.count_nonzero(lab == NOT_COMPUTED))
        if n:
            why = "cancelled before their fate was known" if cancelled else "not computed yet (still running)"
            lost.append(Loss("pixels not computed", n, why))
        n = int(np.count_nonzero(lab == LOCATING))
        if n:
            lost.append(Loss("pixels", n, "their attractor was still being located when the result was taken"))
        n = int(np.count_nonzero(lab == UNDECIDED))
        if n:
            cap = int(0.7 * self.table.shape[1])
            lost.append(Loss("pixels undecided", n, f"no attractor, escape or failure within {spec.max_periods} "
                             f"periods (or more than {cap} recurrence cells visited)"))  # fmt: skip
        for name, k in count_names(self.fate[lab == FAILED]).items():
            lost.append(Loss("pixels failed", k, f"the integrator stopped: {name}"))
        if self.scale is not None:
            cq, cr = spec.cell_size
            if math.hypot(cq, cr) > self.scale / RESOLVE:
                lost.append(Loss("attractors possibly merged", 1,
                                 f"the recurrence cells ({cq:.3g} x {cr:.3g}) are wider than 1/{RESOLVE} of the "
                                 f"attractors' length scale {self.scale:.3g} (the smallest distance between them): "
                                 "attractors closer than a cell may be taken as one; give finer cells"))  # fmt: skip
        pending = [f for i, f in self.found.items() if self.find(i) == i and f.unconfirmed]
        if pending:
            why = "; ".join(sorted({str(f.unconfirmed) for f in pending}))
            lost.append(Loss("attractors not confirmed", len(pending), f"{why}: may be long transients"))
        warnings = []
        cons = [f for i, f in self.found.items() if f.kind == "conservative" and self.find(i) == i]
        if cons:
            n = int(sum(np.count_nonzero(lab == self.public.get(f.internal, -99)) for f in cons))
            worst = max(abs(f.log_det or 0.0) for f in cons)
            warnings.append(f"{n} pixels lie on conservative invariant curves (the area |det DP^k| has no trend: "
                            f"|log det| {worst:.2g} over {min(f.measured for f in cons)} periods, nothing attracted): "
                            "they are in no basin, and neighbouring curves are one label (kind 'conservative'), "
                            "not separate attractors; an attractor contracting area by less than "
                            f"exp(-{CONSERVATIVE_LOG_DET:g}) over those periods would look the same")  # fmt: skip
        return lost, warnings


def _resolved(run: _Run) -> bool:
    """Measure the attractors' length scale (``run.scale``); False if the cells are too coarse for it."""
    run.scale = attractor_scale(run.roots())
    return run.scale is None or math.hypot(*run.spec.cell_size) <= run.scale / RESOLVE


def iter_basins(
    spec: BasinSpec,
    *,
    cancel: Callable[[], bool] | None = None,
    update_s: float = 0.5,
) -> Iterator[BasinsUpdate]:
    """Compute the basins coarse to fine, yielding the live result (see the module docstring).

    Yields a :class:`BasinsUpdate` when each level (every 4th pixel, every 2nd, all) is complete
    (``level_done``), and in between at most every ``update_s`` seconds. ``cancel`` is polled after
    every chunk of periods; once it returns True the last update has ``completed=False`` and the
    pixels still running are :data:`NOT_COMPUTED`.

    The recurrence cells must resolve the attractors (Attractors.jl's warning): cells wider than the gap
    between two attractors label one's pixels with the other (Fig. 11's tensor at ``alpha = -0.5,
    I11 = 1.6`` in a +-500 box: 64 cells across it, one period-3 attractor over 100 %, while 281 of 900
    pixels end on the period-1 focus). Whenever an attractor is classified, the cells are checked
    against the attractors' length scale (:func:`attractor_scale`); with the default cells
    (``spec.adapt_cells``) a grid that does not resolve it is replaced by one sized from the attractors
    (:func:`refined_cells`) and the computation starts again (levels from the coarsest; at most
    :data:`MAX_REFINES` times), so a pixel's label does not depend on the box around it. The result's
    ``spec`` holds the cells used; a grid still too coarse is a loss of the result.
    """
    start = time.perf_counter()
    refinements, earlier = 0, (0, 0)
    passed = 0  # pixels done in the passes restarted with finer cells (for the progress)
    default_box = spec.cell_box
    while True:
        run = _Run(spec)
        run.refinements, run.earlier = refinements, earlier
        restart = None
        levels = _levels(spec.ny, spec.nx)
        queue = [int(p) for _, pix in levels for p in pix]
        total = len(queue)
        level = 0
        last = start
        checked = 0
        cancelled = False
        while True:
            cancelled = cancel is not None and cancel()
            if cancelled:
                break
            if not queue and not (run.pixel >= 0).any():
                break
            run.step(queue)
            if run.version != checked:
                checked = run.version
                if not _resolved(run) and spec.adapt_cells and refinements < MAX_REFINES:
                    cell_box, cells = refined_cells(run.roots(), run.scale, default_box)  # type: ignore[arg-type]
                    finer = replace(spec, cell_box=cell_box, cells=cells)
                    # (capped at MAX_REFINED_CELLS the new cells may be no finer: keep these, reported as a loss)
                    if math.hypot(*finer.cell_size) < 0.99 * math.hypot(*spec.cell_size):
                        restart = finer
                        break
            done = total - len(queue) - int(np.count_nonzero(run.pixel >= 0))
            # a level is done when all its pixels are (the queue is level-ordered; slots may hold later ones)
            while level < len(levels) and np.all(run.label[levels[level][1]] != NOT_COMPUTED):
                if level == len(levels) - 1 and not run.confirm(cancel):  # every pixel done: check the sets
                    cancelled = True
                    break
                level += 1
                last = time.perf_counter()
                yield BasinsUpdate(levels[level - 1][0], True, done, total,
                                   run.snapshot(start, level == len(levels), levels[level - 1][0]), passed)  # fmt: skip
            if cancelled:
                break
            if level < len(levels) and time.perf_counter() - last > update_s:
                last = time.perf_counter()
                stride = levels[level - 1][0] if level else LEVELS[0]
                yield BasinsUpdate(stride, False, done, total, run.snapshot(start, False, stride), passed)
        if restart is None:
            break
        passed += max(0, total - len(queue) - int(np.count_nonzero(run.pixel >= 0)))
        refinements += 1
        earlier = (earlier[0] + run.periods, earlier[1] + run.steps)
        spec = restart
    if level < len(levels):
        stride = levels[level - 1][0] if level else LEVELS[0]
        done = int(np.count_nonzero(run.label != NOT_COMPUTED))
        yield BasinsUpdate(stride, False, done, total, run.snapshot(start, False, stride, cancelled), passed)


def basins(
    spec: BasinSpec | Params,
    *args: Any,
    cancel: Callable[[], bool] | None = None,
    progress: Callable[[BasinsUpdate], None] | None = None,
    **kw: Any,
) -> Basins:
    """Basins of attraction of the Poincare map over ``box`` on a ``grid = (NX, NY)`` of pixel centres:
    ``basins(spec)`` with a :class:`BasinSpec`, or the keyword form ``basins(params, box, grid, **options)``,
    which builds the spec with :func:`basin_spec`.

    Parameters
    ----------
    spec : a :class:`BasinSpec`, or the system (the keyword form).
    box : ``(q0, q1, r0, r1)`` (keyword form).
    grid : ``(NX, NY)`` (keyword form).
    cancel : polled after every chunk of periods (a cancelled result has ``completed=False``).
    progress : called with every :class:`BasinsUpdate` of :func:`iter_basins`.
    **kw : the options of :func:`basin_spec` (numerics, cells, recurrence counts, ...).

    Returns
    -------
    Basins : ``q`` (NX,), ``r`` (NY,), ``label`` (NY, NX), the attractors and their basin fractions.

    References
    ----------
    G. Datseris and A. Wagemakers, "Effortless estimation of basins of attraction", Chaos 32, 023104
    (2022) (the recurrences); the attracting cycles by Newton, :mod:`explorer_core.analyses.orbits`.
    """
    return run_updates(iter_basins(spec_of(BasinSpec, basin_spec, spec, args, kw), cancel=cancel), progress)
