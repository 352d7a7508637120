"""What a continuation computed: its branches (:class:`Branch`), the bifurcations located on them
(:class:`Bifurcation`), its two-parameter curves (:class:`Curve`), all in one :class:`Continuation`, and the set of
continuations that bound a chart's regions (:class:`Boundaries`). Each writes its own files (``.csv``, ``.json``).

Nothing is lost in silence: a branch or curve that stopped other than at a range end or at a located bifurcation
where it was meant to stop is a :class:`~explorer_core.losses.Loss` of the result.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import export
from explorer_core.analyses.continuation.engine import _Point
from explorer_core.analyses.continuation.normal_forms import NormalForm
from explorer_core.analyses.continuation.options import ContinuationOptions, ContinuationSpec
from explorer_core.analyses.orbits import UNIT_TOL, classify, multipliers
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status
from explorer_core.system.params import Params


@dataclass
class Branch:
    """Points of one branch: ``values`` (m,), ``states`` (m,) of ``(q, r)``, ``mults`` (m,) of 2 complex numbers.

    Plain Python numbers throughout (written to CSV and JSON as they are). ``status``: how the branch ended in the
    one vocabulary (``ok``: at the range's end, its birth point or a stop it meant; ``cancelled``; ``budget``:
    ``max_points``; ``not_converged``; ``invalid``: it left the valid parameters; an engine failure); ``stop``
    the detail in words.
    """

    period: int
    values: list[float] = field(default_factory=list)
    states: list[tuple[float, float]] = field(default_factory=list)
    mults: list[tuple[complex, complex]] = field(default_factory=list)
    orbits: list[np.ndarray] = field(default_factory=list)  # (n, 2) each: x, P(x), ..., P^(n-1)(x)
    stop: str = ""
    parent: int | None = None
    status: Status = Status.OK

    def add(self, p: float, pt: _Point) -> None:
        self.values.append(float(p))
        self.states.append((float(pt.X[0]), float(pt.X[1])))
        self.mults.append(tuple(complex(m) for m in multipliers(pt.A)))
        self.orbits.append(np.array(pt.pts, dtype=float))

    @property
    def stable(self) -> np.ndarray:
        return np.array([bool(np.all(np.abs(m) < 1.0 - UNIT_TOL)) for m in self.mults], dtype=bool)

    def as_dict(self) -> dict[str, Any]:
        return {
            "period": self.period,
            "status": self.status.label,
            "stop": self.stop,
            "parent": self.parent,
            "points": [
                {"value": v, "q": x[0], "r": x[1],
                 "multipliers": [[m.real, m.imag] for m in mu],
                 "stable": bool(np.all(np.abs(mu) < 1.0 - UNIT_TOL))}
                for v, x, mu in zip(self.values, self.states, self.mults, strict=True)
            ],
        }  # fmt: skip


@dataclass(frozen=True)
class Bifurcation:
    """A located bifurcation on a branch; ``normal_form`` its coefficient, error estimate, criticality and (at a
    Neimark-Sacker point) resonance (:mod:`.normal_forms`), None where it could not be computed (``messages``
    of the continuation say why)."""

    kind: str
    value: float
    error: float
    period: int
    point: np.ndarray
    multipliers: np.ndarray
    branch: int
    normal_form: NormalForm | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "type": self.kind,
            "value": float(self.value),
            "error": float(self.error),
            "period": int(self.period),
            "point": [float(self.point[0]), float(self.point[1])],
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "branch": int(self.branch),
            **_normal_form_fields(self.normal_form),
        }

    def describe(self, param: str) -> str:
        """The line the command line prints: "supercritical period doubling of the period-1 orbit at alpha =
        -0.375344852807 +- 1e-15 (b = 7.4152 +- 0.0001)"."""
        nf = self.normal_form
        crit = f"{nf.criticality} " if nf is not None and nf.criticality else ""
        line = f"{crit}{self.kind.replace('_', ' ')} of the period-{self.period} orbit at {param} = {self.value:.12g}"
        line += f" +- {self.error:.1g}"
        if nf is not None:
            near = f", near the strong resonance {nf.resonance}" if nf.resonance else ""
            line += f" ({COEFFICIENT_NAMES[self.kind]} = {nf.coefficient:.6g} +- {nf.error:.1g}{near})"
        return line


#: The normal-form coefficients' names (Kuznetsov's, MatContM's): fold ``a``, flip ``b``, Neimark-Sacker ``Re d``.
COEFFICIENT_NAMES = {"fold": "a", "period_doubling": "b", "neimark_sacker": "Re d"}


def _normal_form_fields(nf: NormalForm | None) -> dict[str, Any]:
    """A normal form's JSON fields, all None where it was not computed (a fold has no criticality: None too)."""
    if nf is None:
        return {"coefficient": None, "coefficient_error": None, "criticality": None, "resonance": None}
    return {**nf.as_dict(), "criticality": nf.criticality or None}


#: The codimension-two points' names in words (:mod:`.codim2`).
CODIM2_NAMES = {"CP": "cusp", "R1": "1:1 resonance", "R2": "1:2 resonance", "R3": "1:3 resonance",
                "R4": "1:4 resonance", "LPPD": "fold-flip", "GPD": "generalised flip", "CH": "Chenciner"}  # fmt: skip


@dataclass(frozen=True)
class Codim2Point:
    """A codimension-two point located on a curve of ``curve`` points (:mod:`.codim2`): ``kind`` (``CP``, ``R1``
    .. ``R4``, ``LPPD``, ``GPD``, ``CH``), the two parameters' ``values``, their ``error`` estimate (the larger of
    the two), the orbit's ``period``, its ``point`` ``(q, r)`` and ``multipliers`` there."""

    kind: str
    curve: str
    period: int
    values: tuple[float, float]
    error: float
    point: tuple[float, float]
    multipliers: tuple[complex, complex]

    def as_dict(self, name1: str, name2: str) -> dict[str, Any]:
        return {"type": self.kind, "name": CODIM2_NAMES[self.kind], "curve": self.curve, "period": self.period,
                name1: self.values[0], name2: self.values[1], "error": self.error,
                "point": list(self.point), "multipliers": [[m.real, m.imag] for m in self.multipliers]}  # fmt: skip

    def describe(self, name1: str, name2: str) -> str:
        """The line the command line prints: "R2 (1:2 resonance) of the period-1 orbit on the period doubling curve at
        (a, b) = (3, -1) +- 1e-13"."""
        return (f"{self.kind} ({CODIM2_NAMES[self.kind]}) of the period-{self.period} orbit on the "
                f"{self.curve.replace('_', ' ')} curve at ({name1}, {name2}) = ({self.values[0]:.12g}, "
                f"{self.values[1]:.12g}) +- {self.error:.1g}")  # fmt: skip


@dataclass
class Curve:
    """A fold, period-doubling or Neimark-Sacker point followed in two parameters: rows ``(p1, p2, q, r)``;
    ``status`` as a branch's (the first half that did not end well decides), ``stop`` both halves' ends in words;
    ``codim2`` the codimension-two points located on it, in the curve's order (:mod:`.codim2`); ``origin``: the
    codimension-two point it was switched onto from (None: a bifurcation of a branch)."""

    kind: str
    period: int
    rows: list[tuple[float, float, float, float]] = field(default_factory=list)
    stop: str = ""
    status: Status = Status.OK
    codim2: list[Codim2Point] = field(default_factory=list)
    origin: Codim2Point | None = None

    def as_dict(self, name1: str, name2: str) -> dict[str, Any]:
        return {
            "type": self.kind,
            "period": self.period,
            "status": self.status.label,
            "stop": self.stop,
            "points": [{name1: a, name2: b, "q": q, "r": r} for a, b, q, r in self.rows],
            "codim2": [c.as_dict(name1, name2) for c in self.codim2],
            "origin": None if self.origin is None else self.origin.as_dict(name1, name2),
        }


@dataclass
class Continuation(Drawable):
    """Branches, the bifurcations on them and (two-parameter) curves.

    ``completed`` is False when the run was cancelled; ``complete`` is False when anything was lost
    (cancellation included): ``lost`` says what and why.
    """

    params: Params  # or, on a map in closed form (:class:`~.options.MapSpec`), the map
    param: str
    range: tuple[float, float]
    numerics: Numerics | None  # None on a map in closed form
    branches: list[Branch]
    bifurcations: list[Bifurcation]
    curves: list[Curve] = field(default_factory=list)
    param2: str | None = None
    range2: tuple[float, float] | None = None
    elapsed_s: float = 0.0
    completed: bool = True
    messages: list[str] = field(default_factory=list)
    lost: list[Loss] = field(default_factory=list)
    options: ContinuationOptions = field(default_factory=ContinuationOptions)
    #: what was asked (None for the orbits of several seeds, :func:`continue_from_seeds`)
    spec: ContinuationSpec | None = None

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    @property
    def n_points(self) -> int:
        return sum(len(b.values) for b in self.branches)

    def report(self) -> list[str]:
        """What the command line prints: the branches, the bifurcations with their errors, the messages."""
        codim2 = [c.describe(self.param, self.param2 or "") for cu in self.curves for c in cu.codim2]
        return [*(f"branch {i}: period {br.period}, {len(br.values)} points, {self.param} {br.values[0]:.10g} .. "
                  f"{br.values[-1]:.10g} ({br.stop})" for i, br in enumerate(self.branches)),
                *(b.describe(self.param) for b in self.bifurcations), *codim2, *self.messages]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "param": self.param,
            "range": [float(v) for v in self.range],
            "branches": [b.as_dict() for b in self.branches],
            "bifurcations": [b.as_dict() for b in self.bifurcations],
            "points": self.n_points,
            "messages": list(self.messages),
            "completed": self.completed,
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "elapsed_s": round(float(self.elapsed_s), 6),
            "options": self.options.as_dict(),
            "params": self.params.as_dict(),
            "numerics": None if self.numerics is None else self.numerics.as_dict(),
        }
        if self.param2 is not None:
            out["param2"] = self.param2
            out["range2"] = [float(v) for v in self.range2 or ()]
            out["curves"] = [c.as_dict(self.param, self.param2) for c in self.curves]
        if self.spec is not None:  # what was asked: the seed, period, switching, ... (enough to run it again)
            out["spec"] = self.spec.as_dict()
        return out

    as_dict = summary

    #: the CSV's columns (:meth:`csv_rows`)
    CSV_HEADER = ("branch", "period", "value", "q", "r", "mu1_re", "mu1_im", "mu2_re", "mu2_im", "stable",
                  "bifurcation", "coefficient", "coefficient_error", "criticality")  # fmt: skip

    #: the codimension-two points' CSV's columns (:meth:`codim2_rows`): ``value``, ``value2`` of ``param``, ``param2``
    CODIM2_CSV_HEADER = ("curve", "curve_type", "period", "type", "name", "value", "value2", "error", "q", "r",
                         "mu1_re", "mu1_im", "mu2_re", "mu2_im", "switched_from")  # fmt: skip

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: a row per point (:attr:`CSV_HEADER`); ``.codim2.csv``: a row per codimension-two point of the
        curves (:attr:`CODIM2_CSV_HEADER`); ``.json``: the summary."""
        csv_ = lambda p: export.write_csv(p, self.CSV_HEADER, self.csv_rows(), export.partial(self))  # noqa: E731
        codim2 = lambda p: export.write_csv(p, self.CODIM2_CSV_HEADER, self.codim2_rows(), export.partial(self))  # noqa: E731
        return export.write_by_suffix(
            path,
            {".codim2.csv": codim2, ".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())},
            "continuation",
        )

    def codim2_rows(self) -> list[tuple[Any, ...]]:
        """A row per codimension-two point of the curves, in the curves' order: the curve's index, type and period,
        the point's type and name, the two parameters' values, the error estimate, the state and the multipliers,
        and the point the curve was switched onto from (empty for a curve of a branch's bifurcation)."""
        return [(i, cu.kind, c.period, c.kind, CODIM2_NAMES[c.kind], *c.values, c.error, *c.point,
                 c.multipliers[0].real, c.multipliers[0].imag, c.multipliers[1].real, c.multipliers[1].imag,
                 None if cu.origin is None else cu.origin.kind)
                for i, cu in enumerate(self.curves) for c in cu.codim2]  # fmt: skip

    def csv_rows(self) -> list[tuple[Any, ...]]:
        """``branch, period, value, q, r, mu1_re, mu1_im, mu2_re, mu2_im, stable`` per point, plain numbers; at a
        located bifurcation (a point of its branch) also ``bifurcation`` (its type), ``coefficient``,
        ``coefficient_error`` and ``criticality`` of its normal form (else empty)."""
        at = {(b.branch, float(b.value)): b for b in self.bifurcations}
        rows = []
        for i, br in enumerate(self.branches):
            for v, x, mu, st in zip(br.values, br.states, br.mults, br.stable, strict=True):
                b = at.get((i, float(v)))
                nf = _normal_form_fields(None if b is None else b.normal_form)
                rows.append((i, br.period, v, x[0], x[1], mu[0].real, mu[0].imag, mu[1].real, mu[1].imag, int(st),
                             None if b is None else b.kind, nf["coefficient"], nf["coefficient_error"],
                             nf["criticality"]))  # fmt: skip
        return rows


def classify_branch(br: Branch) -> list[str]:
    """The type of every point of a branch (see :func:`explorer_core.analyses.orbits.classify`)."""
    return [classify(m) for m in br.mults]


class Boundaries(list):
    """The continuations of :func:`chart_boundaries` (a list of :class:`Continuation`), with what was lost:
    directions not continued because cancelled, and every loss of the continuations themselves."""

    completed: bool = True

    @property
    def lost(self) -> list[Loss]:
        own = getattr(self, "_lost", [])
        return own + [loss for c in self for loss in c.lost]

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def summary(self) -> dict[str, Any]:
        return {"continuations": [c.summary() for c in self], "completed": self.completed,
                "complete": self.complete, "lost": [loss.as_dict() for loss in self.lost]}  # fmt: skip

    def npz_entries(self) -> dict[str, Any]:
        """The curves of every continuation as NPZ entries beside a chart's pixels (``numpy.load`` reads them back):
        ``curve_points`` (n, 4): the rows ``(p1, p2, q, r)`` of every curve one after another, named by
        ``curve_columns``; curve ``i`` is ``curve_points[curve_start[i]:curve_start[i + 1]]``, of kind
        ``curve_kind[i]`` (``fold``, ``period_doubling``, ...) of the period-``curve_period[i]`` cycle, ended as
        ``curve_status[i]`` (a status name) because ``curve_stop[i]``; ``curves_complete`` and ``curves_lost``
        (JSON, as the summary's) say what was not followed. The codimension-two points located on the curves
        (:class:`Codim2Point`), a row each in the curves' order: ``codim2_values`` (n, 2) in ``curve_columns[:2]``,
        ``codim2_error`` their error estimate, ``codim2_kind`` (``R2``, ``LPPD``, ...), ``codim2_period`` the
        orbit's period, ``codim2_curve`` the index of the curve it lies on."""
        curves = [(c, cv) for c in self for cv in c.curves]
        rows = [np.asarray(cv.rows, dtype=float).reshape(-1, 4) for _, cv in curves]
        names = next((c for c, _ in curves), None)
        points = [(i, p) for i, (_, cv) in enumerate(curves) for p in cv.codim2]
        return {
            "curve_points": np.concatenate(rows) if rows else np.zeros((0, 4)),
            "curve_start": np.cumsum([0, *(r.shape[0] for r in rows)]),
            "curve_columns": np.array([names.param, names.param2, "q", "r"] if names else ["p1", "p2", "q", "r"]),
            "curve_kind": np.array([cv.kind for _, cv in curves], dtype=str),
            "curve_period": np.array([cv.period for _, cv in curves], dtype=int),
            "curve_status": np.array([cv.status.label for _, cv in curves], dtype=str),
            "curve_stop": np.array([cv.stop for _, cv in curves], dtype=str),
            "codim2_values": np.array([p.values for _, p in points], dtype=float).reshape(-1, 2),
            "codim2_error": np.array([p.error for _, p in points], dtype=float),
            "codim2_kind": np.array([p.kind for _, p in points], dtype=str),
            "codim2_period": np.array([p.period for _, p in points], dtype=int),
            "codim2_curve": np.array([i for i, _ in points], dtype=int),
            "curves_complete": self.complete,
            "curves_lost": json.dumps([loss.as_dict() for loss in self.lost]),
        }

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: the continuations' points, a column ``continuation`` first; ``.json``: the summary."""

        def csv_(p: str) -> int:
            rows = ((k, *row) for k, c in enumerate(self) for row in c.csv_rows())
            return export.write_csv(p, ("continuation", *Continuation.CSV_HEADER), rows, export.partial(self))

        return export.write_by_suffix(
            path, {".csv": csv_, ".json": lambda p: export.write_json(p, self.summary())}, "set of boundaries"
        )
