"""The paper reproduced: every figure's data and every number it gives, computed honestly.

:func:`reproduce` computes, at a chosen :class:`Size`:

* the sections of Figs. 1, 2, 4-8 and 9 (the scenes of ``scenes.json``);
* the Lyapunov exponents and Kaplan-Yorke dimensions of Figs. 4A, 4B and 8B
  (ensembles on the attractor, uncertainty from the ensemble spread and from
  the two halves of the measurement);
* the polynomial fits of Figs. 3, 6 and 9 (members drawn at random until the
  wanted number is on the drift, as the paper averaged ten);
* the bifurcation diagram of Fig. 10 with its period-doubling points (bisection);
* the chart of regimes of Fig. 11 and the periods it contains;

and collects a table ``paper value | ours | uncertainty | settings``: in ``table.csv`` the values and the
uncertainty are numeric columns (NaN where there is none; the words a number cannot say in ``paper_text`` and
``ours_text``), so it reads back with ``numpy.genfromtxt(path, delimiter=",", names=True)``. Nothing
here is tuned to the paper's numbers: initial conditions are chosen by rules
stated in :data:`Size` and the code (first random IC of the scene found chaotic, by the SALI or the
finite-time exponent: ``chaos_test``, as the chart's, etc.). Pictures are drawn elsewhere
(``app/render.py``) so that this package stays free of plotting libraries.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage

from explorer_core import export
from explorer_core.analyses.bifurcation import OrbitDiagram, bifurcation_diagram, bilimovich_orbits
from explorer_core.analyses.continuation import Continuation, continue_orbit
from explorer_core.analyses.drift import DriftFit, drift_fit, fit_polynomial
from explorer_core.analyses.indicators import CHAOTIC as ALIGNED_CHAOS
from explorer_core.analyses.indicators import sali
from explorer_core.analyses.lyapunov import LyapunovResult, attractor_ensemble, kaplan_yorke, lyapunov_spectrum
from explorer_core.analyses.orbits import find_orbits
from explorer_core.analyses.regimes import (
    CHAOS_MARGIN,
    CHAOS_TESTS,
    CHAOTIC,
    DEFAULT_CHAOS_TEST,
    PERIODIC,
    Chart,
    chart_spec,
    regime_chart,
)
from explorer_core.analyses.sweeps import sweep_values
from explorer_core.losses import Loss
from explorer_core.progress import Progress, Step, run
from explorer_core.scenes import Scene, get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.section import Section, section
from explorer_core.system.params import ParameterError, Params


@dataclass(frozen=True)
class Size:
    """How much to compute. ``full`` is the reproduction; ``quick`` a few minutes; ``tiny`` a CI smoke run."""

    name: str
    section_ics: int | None  # cap on initial conditions per scene (None: the scene's)
    section_periods: int | None  # cap on periods per scene
    lyap_members: int
    lyap_periods: int
    lyap_transient: int
    lyap_search: int  # random scene ICs tried to find one on the (quasi-)attractor
    drift_members: int
    bif_values: int
    bif_points: int
    bif_transient: int
    doubling_steps: int  # bisection steps per period-doubling point
    chart_grid: tuple[int, int]
    chart_ics: int
    chart_transient: int
    chart_periods: int


SIZES = {
    "full": Size("full", None, None, 8, 20_000, 1000, 60, 10, 400, 200, 1000, 14, (160, 80), 2, 500, 500),
    "quick": Size("quick", 12, 300, 4, 5000, 300, 30, 5, 150, 100, 400, 10, (60, 30), 2, 300, 300),
    "tiny": Size("tiny", 3, 60, 2, 300, 50, 8, 1, 12, 40, 100, 3, (8, 4), 1, 60, 80),
}

#: Figures drawn as sections, with their scenes.
SECTION_FIGURES = {
    "fig1": ("fig1A", "fig1B", "fig1C", "fig1D"),
    "fig2": ("fig2C", "fig2D"),
    "fig4": ("fig4A", "fig4B"),
    "fig5": ("fig5A", "fig5B"),
    "fig6": ("fig6A", "fig6B"),
    "fig7": ("fig7A", "fig7B", "fig7C"),
    "fig8": ("fig8A", "fig8B", "fig8C"),
    "fig9": ("fig9",),
}
#: Start of the bifurcation diagram's sweeps and the chart's first IC: near the period-1 cycle of Fig. 10.
FIG10_IC = (-0.09, -2.0)
#: Second IC per pixel of the chart (finds coexisting cycles, e.g. period 4 at alpha = -0.36).
FIG11_IC2 = (-0.5, -1.0)
#: A finite-time exponent above this (per unit time) marks a trajectory on the (quasi-)attractor.
CHAOS_THRESHOLD = 5e-3
#: ``chaos_test="sali"``: the search for a chaotic IC carries two deviation vectors for at most this many periods after
#: the scene's transient, and takes the first IC whose vectors align while stretching by more than the chart's
#: CHAOS_MARGIN times the threshold (:func:`~explorer_core.analyses.indicators.sali`); if none does, the finite-time
#: exponent decides, as with ``chaos_test="lyapunov"``. On Figs. 4A, 4B and 8B at every size (8, 30 and 60 ICs) the
#: SALI picks the IC the exponent picks (decided in 141-163, 64-71 and 10 periods), with 16,730, 16,973 and 6,541
#: periods against the exponent's 66,000 for the full size's 60 ICs (25 periods decided none on Figs. 4A and 4B).
SALI_SEARCH_PERIODS = 200
#: Feigenbaum's delta, the limit of the ratios of successive period-doubling intervals.
FEIGENBAUM = 4.669201609102990
#: The paper's numbers, as printed.
PAPER = {
    "fig4": {"L1": 0.022, "L2": -0.034, "sum": -0.012, "D": 1.647},
    "fig8B": {"L1": 0.082, "L2": -0.385, "D": 1.21},
    "fig3": {"q": [-0.300263], "r": [26.779718, -0.2386278, -0.0002545]},
    "fig6A": {"q": [-0.5241223, -0.1461676], "r": [7.4115722, -1.5651429, 0.00009], "r1": [-17.1864607, -1.4616911]},
    "fig6B": {"q": [-2.7790128, -0.14597897], "r": [7.966923, -1.5598174, 0.00009], "r1": [-15.8130501, -1.459806]},
    "fig9": {"q6": -0.0001, "q5": 0.0146, "r6": -0.0005, "r5": 0.073},
}


@dataclass
class Row:
    """One line of the table: a number the paper gives, ours and the uncertainty of ours.

    ``paper``, ``ours`` and ``uncertainty`` are numbers, NaN where there is none (the CSV's numeric columns);
    ``paper_text`` and ``ours_text`` say what a number cannot ("figure only", "present", "of 5 connected
    sets"). ``digits``: significant digits shown in the Markdown table (the CSV holds every digit).
    """

    figure: str
    quantity: str
    paper: float = math.nan
    ours: float = math.nan
    uncertainty: float = math.nan
    settings: str = ""
    note: str = ""
    paper_text: str = ""
    ours_text: str = ""
    digits: int = 4

    def markdown_cells(self) -> list[str]:
        """``figure, quantity, paper, ours, uncertainty, settings, note`` as the Markdown table shows them."""
        paper = " ".join(t for t in (_shown(self.paper, self.digits), self.paper_text) if t)
        ours = " ".join(t for t in (_shown(self.ours, self.digits), self.ours_text) if t)
        unc = f"+-{_fmt(self.uncertainty, 2)}" if math.isfinite(self.uncertainty) else ""
        return [self.figure, self.quantity, paper, ours, unc, self.settings, self.note]


#: ``table.csv``'s columns: the numbers in their own columns, then the words.
TABLE_COLUMNS = ("figure", "quantity", "paper", "ours", "uncertainty", "paper_text", "ours_text", "settings", "note")


@dataclass
class Reproduction:
    """Everything :func:`reproduce` computed; the renderer and the table read from here."""

    size: Size
    #: How a trajectory is found chaotic: the Lyapunov stage's search for an IC, the chart's early stop (CHAOS_TESTS).
    chaos_test: str = DEFAULT_CHAOS_TEST
    sections: dict[str, Section] = field(default_factory=dict)
    lyapunov: dict[str, LyapunovResult] = field(default_factory=dict)
    drift: dict[str, DriftFit] = field(default_factory=dict)
    series: dict[str, np.ndarray] = field(default_factory=dict)
    bifurcation: OrbitDiagram | None = None
    doubling: list[dict[str, float]] = field(default_factory=list)
    cascade: Continuation | None = None
    chart: Chart | None = None
    rows: list[Row] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    completed: bool = True
    #: stages not run (cancelled)
    lost: list[Loss] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def table_markdown(self) -> str:
        head = "| figure | quantity | paper | ours | uncertainty | settings | note |\n|---|---|---|---|---|---|---|\n"
        esc = [[c.replace("|", "\\|") for c in r.markdown_cells()] for r in self.rows]
        return head + "".join("| " + " | ".join(cells) + " |\n" for cells in esc)

    def write_table(self, md_path: str, csv_path: str) -> None:
        """The table as Markdown and CSV (:data:`TABLE_COLUMNS`), each whole or not at all; a reproduction that
        was stopped says so in the CSV, after its header (``# `` lines).

        The CSV reads back with ``numpy.genfromtxt(path, delimiter=",", names=True)``: ``paper``, ``ours`` and
        ``uncertainty`` are numbers (``nan`` where there is none: an empty field of a column numpy takes for
        integers would read as -1), and no text holds a comma, a quote or a ``#`` (numpy splits at every
        comma, quoted or not, and cuts a line at ``#``)."""
        export.write_text(md_path, self.table_markdown())
        rows = ([r.figure, r.quantity, float(r.paper), float(r.ours), float(r.uncertainty), r.paper_text, r.ours_text,
                 r.settings, r.note] for r in self.rows)  # fmt: skip
        export.write_csv(csv_path, TABLE_COLUMNS, ([_plain_text(c) for c in row] for row in rows),
                         export.partial(self))  # fmt: skip

    def summary(self) -> dict[str, Any]:
        return {
            "size": asdict(self.size),
            "chaos_test": self.chaos_test,
            "rows": [asdict(r) for r in self.rows],
            "timings_s": {k: round(v, 2) for k, v in self.timings.items()},
            "doubling": self.doubling,
            "cascade": [b.as_dict() for b in self.cascade.bifurcations] if self.cascade is not None else [],
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
        }


def _fmt(v: float, digits: int = 4) -> str:
    if v == 0 or not math.isfinite(v):
        return f"{v:g}"
    return f"{v:.{digits}g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.{digits - 1}e}"


def _shown(v: float, digits: int) -> str:
    """A number of the Markdown table (nothing for NaN: no number)."""
    return _fmt(v, digits) if not math.isnan(v) else ""


def _plain_text(cell: Any) -> Any:
    """A CSV cell that ``numpy.genfromtxt`` splits as ``csv`` does: text without commas, quotes or ``#``."""
    if not isinstance(cell, str):
        return cell
    return cell.replace(", ", "; ").replace(",", ";").replace('"', "'").replace("#", "no. ").replace("\n", " ")


# ---------------------------------------------------------------------------
# Stages.


def _sections(rep: Reproduction, stop: Callable[[], bool]) -> None:
    size = rep.size
    for sids in SECTION_FIGURES.values():
        for sid in sids:
            if stop():
                return
            sc = get_scene(sid)
            ics = sc.initial_conditions()
            if size.section_ics is not None:
                ics = ics[: size.section_ics]
            periods = sc.periods if size.section_periods is None else min(sc.periods, size.section_periods)
            numerics = sc.numerics(periods + sc.transient)
            sec = section(sc.params, ics, periods, transient=sc.transient, numerics=numerics, cancel=stop)
            if not sec.completed:  # stopped inside: a cut section is not the figure (the stage's loss says so)
                return
            rep.sections[sid] = sec


def _find_attractor_ic(
    scene: Scene, tries: int, periods: int, stop: Callable[[], bool] | None = None, chaos_test: str = DEFAULT_CHAOS_TEST
) -> tuple[float, float] | None:
    """First of the scene's random ICs chaotic by the SALI (``chaos_test="sali"``, :data:`SALI_SEARCH_PERIODS`) or,
    with ``"lyapunov"`` or when the SALI finds none, whose finite-time largest exponent over ``periods`` exceeds
    :data:`CHAOS_THRESHOLD` (None if none is, or when ``stop`` stopped the search)."""
    ics = scene.initial_conditions()[:tries]
    numerics = Numerics(rtol=1e-9, atol=1e-9)
    if chaos_test == "sali":
        per_period = CHAOS_MARGIN * CHAOS_THRESHOLD * abs(scene.params.period)
        aligned = sali(scene.params, ics, min(SALI_SEARCH_PERIODS, periods), transient=scene.transient,
                       numerics=numerics, stretch_tol=per_period, cancel=stop)  # fmt: skip
        if not aligned.completed:
            return None
        hit = np.flatnonzero(aligned.verdict == ALIGNED_CHAOS)
        if hit.size:
            return float(ics[hit[0], 0]), float(ics[hit[0], 1])
    res = lyapunov_spectrum(scene.params, ics, periods, transient=scene.transient, numerics=numerics, cancel=stop)
    if not res.completed:
        return None
    for i in range(ics.shape[0]):
        if res.ok[i] and res.exponents[i, 0] > CHAOS_THRESHOLD:
            return float(ics[i, 0]), float(ics[i, 1])
    return None


def _lyapunov(rep: Reproduction, stop: Callable[[], bool]) -> None:
    size = rep.size
    numerics = Numerics(rtol=1e-10, atol=1e-10)
    for sid in ("fig4A", "fig4B", "fig8B"):
        if stop():
            return
        sc = get_scene(sid)
        ic = _find_attractor_ic(sc, size.lyap_search, max(200, min(1000, size.lyap_periods)), stop, rep.chaos_test)
        if stop():  # a search cut short says nothing (the stage's loss says it was stopped)
            return
        settings = (
            f"{size.lyap_members} members x {size.lyap_periods} periods after {size.lyap_transient}; "
            f"{numerics.method} 1e-10"
        )
        fig = "Fig. 4" + sid[-1] if sid.startswith("fig4") else "Fig. 8B"
        paper = PAPER["fig4"] if sid.startswith("fig4") else PAPER["fig8B"]
        if ic is None:
            rep.rows.append(Row(fig, "Lambda_1", paper["L1"], ours_text="no chaotic IC found", settings=settings))
            continue
        ics = attractor_ensemble(sc.params, ic, size.lyap_members, transient=size.lyap_transient, numerics=numerics)
        res = lyapunov_spectrum(sc.params, ics, size.lyap_periods, transient=size.lyap_transient, numerics=numerics,
                                cancel=stop)  # fmt: skip
        if not res.completed:
            return
        rep.lyapunov[sid] = res
        _lyapunov_rows(rep, fig, sid, res, paper, settings + f"; IC {ic[0]:.4g},{ic[1]:.4g}")


def _lyapunov_rows(rep: Reproduction, fig: str, sid: str, res: LyapunovResult, paper: dict, settings: str) -> None:
    ok = res.ok
    if not ok.any():
        rep.rows.append(Row(fig, "Lambda_1", paper["L1"], ours_text="every member failed", settings=settings))
        return
    ex = res.exponents[ok]
    half = res.periods // 2
    first = res.logs[ok, :half].sum(axis=1) / (half * res.period)
    second = res.logs[ok, half:].sum(axis=1) / ((res.periods - half) * res.period)
    drift = np.abs(first.mean(axis=0) - second.mean(axis=0)) / 2  # (2,): non-stationarity of the estimate
    spread = ex.std(axis=0, ddof=1) if ex.shape[0] > 1 else np.zeros(2)
    unc = np.maximum(spread, drift)
    mean = ex.mean(axis=0)
    dims = np.array([kaplan_yorke(a, b) for a, b in ex])
    d_unc = float(dims.std(ddof=1)) if dims.size > 1 else math.nan  # one member: no spread to measure
    log2 = sid.startswith("fig4")
    note2 = " x 1/ln 2 = " if log2 else ""
    for j, name in enumerate(("Lambda_1", "Lambda_2")):
        note = "per unit time (per iteration: x 2 pi)"
        if log2:
            note += f"; in bits{note2}{_fmt(mean[j] / math.log(2), 3)}"
        rep.rows.append(Row(fig, name, paper[f"L{j + 1}"], float(mean[j]), float(unc[j]), settings, note))
    rep.rows.append(Row(fig, "Lambda_3", 0.0, 0.0, 0.0, "time direction of (eq-a3)", "exact"))
    div = float(res.divergence_mean[ok].mean())
    if "sum" in paper:
        rep.rows.append(
            Row(
                fig,
                "Lambda_1 + Lambda_2",
                paper["sum"],
                float(mean.sum()),
                float(np.hypot(*unc)),
                settings,
                f"= mean divergence {_fmt(div)} (check: {abs(mean.sum() - div):.1e})"
                + (f"; in bits {_fmt(float(mean.sum()) / math.log(2), 3)}" if log2 else ""),
            )
        )
    rep.rows.append(
        Row(
            fig,
            "D = 1 + L1/|L2|",
            paper["D"],
            float(kaplan_yorke(*mean)),
            d_unc,
            settings,
            "section attractor; the flow's is D + 1; independent of the log base",
        )
    )


def _spread(fit: DriftFit) -> tuple[np.ndarray, np.ndarray]:
    """The members' spread of the coefficients (q, r); NaN for fewer than two members (no spread was measured:
    ``DriftFit.spread`` gives zeros, which the table would show as an exact value)."""
    sq, sr = fit.spread()
    if fit.members.shape[0] < 2:
        return np.full(np.shape(sq), math.nan), np.full(np.shape(sr), math.nan)
    return sq, sr


def _coef_rows(
    rep: Reproduction,
    fig: str,
    var: str,
    paper: list[float],
    fit_c: np.ndarray,
    fit_s: np.ndarray,
    settings: str,
    note: str = "",
) -> None:
    for p, (pv, ov, sv) in enumerate(zip(paper, fit_c, fit_s, strict=False)):
        if pv is None:
            continue
        rep.rows.append(Row(fig, f"{var}: coefficient of k^{p}", pv, float(ov), float(sv), settings, note, digits=7))


def _drift(rep: Reproduction, stop: Callable[[], bool]) -> None:
    size = rep.size
    m = size.drift_members
    # Fig. 3: the paper's own trajectory from (0, 8) for the picture, random members for the fit.
    p3 = get_scene("fig3").params
    s3 = section(p3, [(0.0, 8.0)], 900, numerics=Numerics())
    rep.series["fig3"] = np.concatenate([[[0.0, 8.0]], s3.points[0, : s3.npts[0]]])
    box1a = get_scene("fig1A").box
    fit = drift_fit(p3, (200, 900), degree=(0, 2), m=m, box=box1a, seed=1, cancel=stop)
    if not fit.completed:
        return
    rep.drift["fig3"] = fit
    cq, cr = fit.mean()
    sq, sr = _spread(fit)
    st = f"{fit.members.shape[0]} members on the curve over k = 200..900 (random in {list(box1a)}, seed 1)"
    _coef_rows(rep, "Fig. 3", "q", PAPER["fig3"]["q"], cq, sq, st, "polynomial variable is k (see text)")
    _coef_rows(rep, "Fig. 3", "r", PAPER["fig3"]["r"], cr, sr, st)
    err = fit.map_error()
    step = f"against a mean step of {_fmt(err['mean_step'], 3)}"
    for how, value, note in (
        ("the printed formula (with 2 pi; + branch)", err["paper_formula"],
         "the printed map assumes t and the wrong branch"),
        ("the formula read in k (- branch)", err["quadratic_in_k"], "read in k it tracks the data"),
    ):  # fmt: skip
        rep.rows.append(Row("Fig. 3", f"map r_(k+1)(r_k): one-step RMS error of {how}", ours=float(value), settings=st,
                            note=f"{note}; {step}", paper_text="(formula)", digits=3))  # fmt: skip
    if stop():
        return
    for sid, fig in (("fig6A", "Fig. 6A"), ("fig6B", "Fig. 6B")):
        sc = get_scene(sid)
        fit = drift_fit(sc.params, (200, 900), degree=(1, 2), m=m, box=sc.box, seed=1, cancel=stop)
        if not fit.completed:
            return
        rep.drift[sid] = fit
        cq, cr = fit.mean()
        sq, sr = _spread(fit)
        st = f"{fit.members.shape[0]} members on the curve over k = 200..900 (random in {list(sc.box)}, seed 1)"
        _coef_rows(rep, fig, "q", PAPER[sid]["q"], cq, sq, st)
        _coef_rows(rep, fig, "r", PAPER[sid]["r"], cr, sr, st, "paper prints the k^2 term to 1 digit")
        k = fit.k
        lin = np.array([fit_polynomial(k, x[200:901, 1], 1)[0] for x in fit.series])
        _coef_rows(
            rep,
            fig,
            "r (linear fit)",
            PAPER[sid]["r1"],
            lin.mean(axis=0),
            lin.std(axis=0, ddof=1) if lin.shape[0] > 1 else np.full(2, math.nan),
            st,
        )
        _phase_shift_rows(rep, fig, sid, fit, st)
        cub = np.array([fit_polynomial(k, x[200:901, 1], 3)[0] for x in fit.series])
        rep.rows.append(
            Row(
                fig,
                "r (cubic fit): coefficient of k^3",
                -5e-8,
                float(cub[:, 3].mean()),
                float(cub[:, 3].std(ddof=1)) if cub.shape[0] > 1 else math.nan,
                st,
                paper_text="(approximately)",
                digits=3,
            )
        )
        if stop():
            return
    sc = get_scene("fig9")
    fit = drift_fit(
        sc.params,
        (0, 60),
        degree=(6, 6),
        m=m,
        box=sc.box,
        seed=1,
        criterion="leaves",
        numerics=Numerics(bound=1e12),
        cancel=stop,
    )
    if not fit.completed:
        return
    rep.drift["fig9"] = fit
    cq, cr = fit.mean()
    sq, sr = _spread(fit)
    st = f"{fit.members.shape[0]} members leaving over k = 0..60 (random in {list(sc.box)}, seed 1), bound 1e12"
    note = f"growth is exponential: |x_k| ~ e^({_fmt(float(fit.growth_rate.mean()), 3)} k)"
    # The coefficients scale with e^(rate * escape time) and scatter by ~100%; their ratio r/q
    # is the direction of the noncompact curve and is well defined.
    ratio = fit.coef_r[:, 6] / fit.coef_q[:, 6]
    rep.rows.append(
        Row(
            "Fig. 9",
            "ratio r/q of the k^6 coefficients",
            PAPER["fig9"]["r6"] / PAPER["fig9"]["q6"],
            float(ratio.mean()),
            float(ratio.std(ddof=1)) if ratio.size > 1 else math.nan,
            st,
            "direction of the escape: r ~ 5 q on the noncompact curve",
        )
    )
    for var, c, s in (("q", cq, sq), ("r", cr, sr)):
        for p in (6, 5):
            rep.rows.append(
                Row(
                    "Fig. 9",
                    f"{var}: coefficient of k^{p}",
                    PAPER["fig9"][f"{var}{p}"],
                    float(c[p]),
                    float(s[p]),
                    st,
                    note,
                    digits=3,
                )
            )


def _phase_shift_rows(rep: Reproduction, fig: str, sid: str, fit: DriftFit, settings: str) -> None:
    """Test one explanation of the slope differences: the paper's members are further along the curve.

    On the curve ``q`` grows linearly, so the intercept difference ``dq0`` is a shift of
    ``shift = dq0 / |q slope|`` periods; the same members fitted over the window moved
    by ``shift`` should then give the paper's slopes (the speed along the curve drifts:
    ``r`` has a ``k^2`` term).
    """
    cq, _ = fit.mean()
    shift = round(float((cq[0] - PAPER[sid]["q"][0]) / abs(cq[1])))
    if not 0 < shift <= 400:
        return
    moved = drift_fit(fit.params, (200 + shift, 900 + shift), degree=(1, 1), ics=fit.members, numerics=fit.numerics)
    mq, mr = moved.mean()
    note = f"explanation test: same members, window k = {200 + shift}..{900 + shift} (shift {shift} from dq0)"
    rep.rows.append(
        Row(
            fig,
            "q slope, window shifted",
            PAPER[sid]["q"][1],
            float(mq[1]),
            float(_spread(moved)[0][1]),
            settings,
            note,
            digits=7,
        )
    )
    rep.rows.append(
        Row(
            fig,
            "r linear slope, window shifted",
            PAPER[sid]["r1"][1],
            float(mr[1]),
            float(_spread(moved)[1][1]),
            settings,
            note,
            digits=7,
        )
    )


#: How far (in widths of the starting bracket) :func:`_doubling` moves a bracket whose ends do not hold.
BRACKET_MOVES = 8


def _doubling(
    params: Params, lo: float, hi: float, seed: np.ndarray, p: int, steps: int, transient: int, numerics: Numerics
) -> tuple[float, float] | None:
    """Bisect the alpha where the period-p cycle (attracting near ``lo``, from ``seed``) has doubled (near ``hi``):
    the doubling is in ``[lo, hi]`` (either order) on return; None if no bracket was found.

    The verdict at each alpha is the cycle's own multiplier: Newton on ``P^p`` from where the orbit settled
    after ``transient`` periods, ``mu > -1`` (the cycle still attracts) or not. Until issue 35 it was the period
    read off the orbit after the transient, which near the doubling (``mu -> -1``) had not decayed (like
    ``|mu|^k``): the bisection stopped short, by more than its error bar (at the quick size 2e-5 for the
    4 -> 8 and 8 -> 16 doublings, the bars 1.5e-5 and 7e-6 from the difference of two transients). The
    starting bracket comes from the orbit diagram's periods, read the same way: its ends are checked by the
    multiplier and moved outwards by its width until they hold (at the full size the diagram saw period 2
    one grid value before the doubling, and the bisection converged onto that end, 8e-5 off).
    """

    def attracts(alpha: float, x: np.ndarray) -> tuple[bool, np.ndarray]:
        at = params.with_(alpha=alpha)
        _, _, status, fin, _ = bilimovich_orbits(at, x, transient, 1, numerics)
        start = fin if status[0] == 0 else x
        mu = _flip_multiplier(at, start, p)
        return mu is not None and mu > -1.0, start

    width = hi - lo
    for moves in range(BRACKET_MOVES + 1):  # the doubled end: the cycle no longer attracts there
        holds, x = attracts(hi, seed)
        if not holds:
            break
        if moves == BRACKET_MOVES:
            return None
        lo, hi, seed = hi, hi + width, x
    for moves in range(BRACKET_MOVES + 1):  # the other end: it still attracts
        holds, x = attracts(lo, seed)
        if holds:
            seed = x
            break
        if moves == BRACKET_MOVES:
            return None
        lo, hi = lo - width, lo
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        holds, x = attracts(mid, seed)
        if holds:
            lo, seed = mid, x
        else:
            hi = mid
    return lo, hi


def _flip_multiplier(params: Params, x: np.ndarray, p: int) -> float | None:
    """The real multiplier nearest -1 of the period-``p`` cycle Newton finds from ``x`` (None: none found)."""
    cycles = [o for o in find_orbits(params, x, [p]).orbits if o.period == p]
    if not cycles:
        return None
    mu = cycles[0].multipliers
    return float(mu[np.argmin(np.abs(mu + 1.0))].real)


def _bifurcation(rep: Reproduction, stop: Callable[[], bool]) -> None:
    size = rep.size
    sc = get_scene("fig10")
    values = sweep_values(tuple(sc.extra["sweep"]["range"]), size.bif_values)
    num = Numerics(rtol=1e-10, atol=1e-10)
    d = bifurcation_diagram(
        sc.params,
        "alpha",
        values,
        points=size.bif_points,
        transient=size.bif_transient,
        ics=[FIG10_IC],
        seeding="continuation",
        numerics=num,
        cancel=stop,
    )
    rep.bifurcation = d
    per = d.periods(p_max=16, tol=1e-6)
    st = f"{size.bif_values} values, {size.bif_transient} + {size.bif_points} periods, continuation both ways"
    # Backward sweep: from the period-1 cycle at -0.35 towards -0.42.
    back = per[1, :, 0]
    order = np.arange(values.size)[::-1]
    found = []
    for p in (1, 2, 4, 8):
        cand = [v for v in order if back[v] == 2 * p]
        prev = [v for v in order if back[v] == p]
        if not cand or not prev:
            break
        hi_i = cand[0]
        lo_i = min((v for v in prev if v > hi_i), default=None, key=lambda v: v - hi_i)
        if lo_i is None:
            break
        seed = d.final[1, lo_i]
        bracket = _doubling(
            sc.params, values[lo_i], values[hi_i], seed[None, :], p, size.doubling_steps, 4 * size.bif_transient, num
        )
        if bracket is None:  # (the multiplier never crossed -1 near where the diagram saw the period double)
            break
        # The multiplier is -1 between a (the cycle attracts) and b (it does not): the bracket is the error.
        a, b = bracket
        found.append({"from": p, "to": 2 * p, "alpha": 0.5 * (a + b), "uncertainty": 0.5 * abs(b - a)})
        if stop():
            break
    rep.doubling = found
    for f in found:
        rep.rows.append(
            Row(
                "Fig. 10",
                f"period doubling {f['from']} -> {f['to']}: alpha",
                ours=float(f["alpha"]),
                uncertainty=float(f["uncertainty"]),
                settings=st + "; bisection on the cycle's multiplier (Newton from the settled orbit)",
                paper_text="figure only",
                digits=8,
            )
        )
    alphas = [f["alpha"] for f in found]
    for j in range(len(alphas) - 2):
        delta = (alphas[j + 1] - alphas[j]) / (alphas[j + 2] - alphas[j + 1])
        rep.rows.append(
            Row(
                "Fig. 10",
                f"Feigenbaum ratio (a{j + 2} - a{j + 1})/(a{j + 3} - a{j + 2})",
                FEIGENBAUM,
                float(delta),
                settings=st,
                note="the limit of the ratios; early ratios converge slowly",
                paper_text="(Feigenbaum's delta)",
                digits=3,
            )
        )
    _cascade(rep, sc, found, stop)
    differ = np.flatnonzero((per[0, :, 0] != per[1, :, 0]) & (per[0, :, 0] >= 0) & (per[1, :, 0] >= 0))
    rep.rows.append(
        Row(
            "Fig. 10",
            "values where forward and backward sweeps differ",
            ours=float(differ.size),
            settings=st,
            note="coexisting attractors (hysteresis)",
            paper_text="not discussed",
            ours_text=f"of {values.size}"
            + (f" (alpha in [{values[differ].min():.4f}; {values[differ].max():.4f}])" if differ.size else ""),
        )
    )


def _cascade(rep: Reproduction, sc: Scene, bisected: list[dict[str, float]], stop: Callable[[], bool]) -> None:
    """The Fig. 10 cascade again, by continuation of the period-1 orbit with branch switching."""
    lo, hi = sc.extra["sweep"]["range"]
    start = sc.params.with_(alpha=hi)
    seeds = find_orbits(start, [FIG10_IC], [1]).orbits
    if not seeds or stop():
        return
    cas = continue_orbit(start, "alpha", (hi, lo), seeds[0].points[0], 1, switch=True, max_period=16, cancel=stop)
    rep.cascade = cas
    pds = [b for b in cas.bifurcations if b.kind == "period_doubling"]
    num = cas.numerics
    st = f"continuation of the period-1 orbit, {num.method} {num.rtol:g}; Newton on the defining system"
    for k, b in enumerate(pds):
        diag = next((f for f in bisected if f["from"] == b.period), None)
        note = "beyond the orbit diagram's resolution"
        if diag:
            off = abs(diag["alpha"] - b.value)
            note = f"bisection: {diag['alpha']:.8f} +-{_fmt(diag['uncertainty'], 2)} (off by {off:.1e})"
        rep.rows.append(Row("Fig. 10", f"period doubling {b.period} -> {2 * b.period} (continuation): alpha",
                            ours=float(b.value), uncertainty=float(b.error), settings=st, note=note,
                            paper_text="figure only", digits=12))  # fmt: skip
        if k + 2 < len(pds):
            delta = (pds[k + 1].value - b.value) / (pds[k + 2].value - pds[k + 1].value)
            rep.rows.append(Row("Fig. 10", f"Feigenbaum ratio (continuation) {k + 1}", FEIGENBAUM, float(delta),
                                settings=st, note="the limit of the ratios; early ratios converge slowly",
                                paper_text="(Feigenbaum's delta)", digits=6))  # fmt: skip
    rep.rows.append(Row(
        "Fig. 10", "which doubling values to trust", settings=st, ours_text="continuation",
        note="at a doubling the multiplier is exactly -1 and the orbit exact (Newton), so the value is limited only "
        "by the integration (the error column); the bisection brackets the same multiplier -1 between two alphas, "
        "so its error is half the bracket (its verdict was once the period read off a finite transient, which "
        "decays like |mu|^k with |mu| -> 1 there: it stopped short of the doubling)",
    ))  # fmt: skip


def _chart(rep: Reproduction, stop: Callable[[], bool]) -> None:
    size = rep.size
    sc = get_scene("fig11")
    ch = sc.extra["chart"]
    ics = [FIG10_IC, FIG11_IC2][: size.chart_ics]
    spec = chart_spec(
        sc.params,
        ch["x_param"],
        ch["x_range"],
        ch["y_param"],
        ch["y_range"],
        size.chart_grid,
        ics=ics,
        transient=size.chart_transient,
        periods=size.chart_periods,
        p_max=16,
        tol=1e-5,
        chaos_test=rep.chaos_test,
    )
    chart = regime_chart(spec, cancel=stop)
    rep.chart = chart
    st = (
        f"{size.chart_grid[0]} x {size.chart_grid[1]} px, {len(ics)} IC/px, {size.chart_transient} + "
        f"{size.chart_periods} periods, rtol 1e-8"
    )
    per = np.where(chart.regime == PERIODIC, chart.period, 0)
    present = sorted({int(v) for v in np.unique(per) if v > 0})
    counts = {p: int(np.count_nonzero((per == p).any(axis=-1))) for p in present}
    rep.rows.append(
        Row(
            "Fig. 11",
            "periods of stable cycles",
            settings=st,
            paper_text="1-2-4-8 and 3-6-12 cascades",
            ours_text="; ".join(f"{p}: {n} px" for p, n in counts.items()),
        )
    )
    for cascade in ((1, 2, 4, 8), (3, 6, 12)):
        seen = [p for p in cascade if p in counts]
        rep.rows.append(
            Row(
                "Fig. 11",
                f"cascade {'-'.join(map(str, cascade))}",
                settings=st,
                paper_text="present",
                ours_text="present" if len(seen) == len(cascade) else f"only {'-'.join(map(str, seen)) or 'none'}",
            )
        )
    chaos = (chart.regime == CHAOTIC).any(axis=-1)
    labels, n = ndimage.label(chaos)
    sizes = np.bincount(labels.ravel())[1:]
    big = int(np.count_nonzero(sizes >= max(4, chaos.size // 400)))
    rep.rows.append(
        Row(
            "Fig. 11",
            "black (chaotic) areas",
            2.0,
            float(big),
            settings=st,
            note=f"{int(chaos.sum())} chaotic px; {int(chart.multistable().sum())} multistable px",
            paper_text="(two)",
            ours_text=f"(of {n} connected sets)",
        )
    )


STAGES = (
    ("sections", _sections),
    ("lyapunov", _lyapunov),
    ("drift", _drift),
    ("bifurcation", _bifurcation),
    ("chart", _chart),
)


def iter_reproduce(
    size: str | Size = "quick",
    *,
    stages: tuple[str, ...] | None = None,
    cancel: Callable[[], bool] | None = None,
    chaos_test: str = DEFAULT_CHAOS_TEST,
) -> Iterator[Step[Reproduction]]:
    """:func:`reproduce` as a stream of :class:`~explorer_core.progress.Step` in ``stages`` (``detail``:
    the stage that finished and its seconds); the last update's ``result`` is the reproduction."""
    if isinstance(size, str):
        if size not in SIZES:
            raise ParameterError(f"size must be one of {', '.join(SIZES)}, got {size!r}")
        size = SIZES[size]
    if chaos_test not in CHAOS_TESTS:
        raise ParameterError(f"chaos_test must be one of {', '.join(CHAOS_TESTS)}, got {chaos_test!r}")
    names = [n for n, _ in STAGES]
    chosen = check_stages(stages, names)
    rep = Reproduction(size, chaos_test)

    def stop() -> bool:
        return cancel is not None and bool(cancel())

    runs = [(name, lambda fn=fn: fn(rep, stop)) for name, fn in STAGES if name in chosen]
    last = Step(Progress(0, len(runs), "stages"))
    for last in iter_stages(runs, rep.timings, stop):
        if last.result is None:
            yield last
    rep.completed = bool(last.result)
    if not rep.completed:
        left = [name for name, _ in runs if name not in rep.timings]
        if left:
            rep.lost.append(Loss("stages not run", len(left), f"cancelled ({', '.join(left)})"))
        else:
            rep.lost.append(Loss("stages", 1, "cancelled inside the last stage (its results may be partial)"))
    yield Step(last.progress, None, rep)


def reproduce(
    size: str | Size = "quick",
    *,
    stages: tuple[str, ...] | None = None,
    progress: Callable[[Step[Reproduction]], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    chaos_test: str = DEFAULT_CHAOS_TEST,
) -> Reproduction:
    """Compute every figure's data and the table of numbers (see the module docstring).

    Parameters
    ----------
    size : ``"full"``, ``"quick"``, ``"tiny"`` or a :class:`Size`.
    stages : subset of ``sections, lyapunov, drift, bifurcation, chart`` (default all).
    progress : called with every update of :func:`iter_reproduce` (after each stage).
    cancel : polled between (and inside long) stages; the result then has ``completed=False``.
    chaos_test : ``"sali"`` (default) or ``"lyapunov"``: how the Lyapunov stage finds a chaotic IC
        (:data:`SALI_SEARCH_PERIODS`) and the chart calls a member chaotic early (the chart's own option).
    """
    return run(iter_reproduce(size, stages=stages, cancel=cancel, chaos_test=chaos_test), progress)


def check_stages(stages: Sequence[str] | None, names: Sequence[str]) -> tuple[str, ...]:
    """``stages`` (default: all ``names``), each one of ``names``."""
    stages = tuple(names) if stages is None else tuple(stages)
    bad = [s for s in stages if s not in names]
    if bad:
        raise ParameterError(f"unknown stages {bad}; choose from {', '.join(names)}")
    return stages


def iter_stages(
    runs: Sequence[tuple[str, Callable[[], None]]], timings: dict[str, float], stop: Callable[[], bool]
) -> Iterator[Step[bool]]:
    """Run the named stages in order, timing each; a :class:`~explorer_core.progress.Step` (``detail``: the
    stage and its seconds) after each, and a last one whose ``result`` is False if stopped before the end."""
    start = time.perf_counter()
    done = 0
    detail = None
    for name, work in runs:
        if stop():
            break
        t = time.perf_counter()
        work()
        timings[name] = time.perf_counter() - t
        done += 1
        detail = (name, timings[name])
        yield Step(Progress(done, len(runs), "stages", time.perf_counter() - start), detail)
    # (a Step's result must not be None on the last update: the flag is a bool, never None)
    finished = not stop() and done == len(runs)
    yield Step(Progress(done, len(runs), "stages", time.perf_counter() - start), detail, finished)


def run_stages(
    runs: Sequence[tuple[str, Callable[[], None]]],
    timings: dict[str, float],
    progress: Callable[[str, float], None] | None,
    stop: Callable[[], bool],
) -> bool:
    """:func:`iter_stages` with ``progress(stage, elapsed_s)`` after each stage; False if stopped before the end."""
    for upd in iter_stages(runs, timings, stop):
        if upd.result is not None:
            return upd.result
        if progress is not None:
            progress(*upd.detail)
    return False
