"""Where the constraint pumps energy in and where it takes it out.

The paper (section "Two critical points", after Fig. 2) reads the power of the
constraint reaction ``T' = dT/dt = alpha * lambda`` as a guide: where ``T' > 0``
the body spins up, where ``T' < 0`` it slows down, alternating sign allows
compact motion. Two maps on a ``(q, r)`` grid:

* :func:`tprime_map` -- ``T'`` at a frozen time ``t`` (a quadratic in ``(q, r)``;
  one set of coefficients serves the whole grid);
* :func:`energy_change_map` -- ``T(t0 + T) - T(t0)`` for the trajectory starting
  at each grid point: a batch of one-period integrations.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from explorer_core import config, export
from explorer_core.analyses.specs import Checking
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.solve import checks
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.options import BOOL, Arg, Check, declare, number, optional_of, span
from explorer_core.solve.poincare import PoincareMap
from explorer_core.status import Status, status_names
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params


@dataclass(frozen=True)
class TPrimeMap(Drawable):
    """Values on a grid: ``values[j, i]`` at ``(q[i], r[j])``.

    ``ok[j, i]`` is False where the value could not be computed (the one-period
    trajectory escaped or failed); such cells hold 0 in ``values`` and their
    status code in ``status`` -- they are never NaN.
    """

    kind: str  # "instantaneous" (T' at t) or "per-period" (T(t0+T) - T(t0))
    t: float
    q: np.ndarray
    r: np.ndarray
    values: np.ndarray
    ok: np.ndarray
    status: np.ndarray
    params: Params
    elapsed_s: float

    @property
    def lost(self) -> list[Loss]:
        """Cells whose value could not be computed (``ok`` False: the one-period run failed there)."""
        bad = int(np.count_nonzero(~self.ok))
        return [Loss("cells", bad, "not computed: the one-period integration failed there")] if bad else []

    @property
    def complete(self) -> bool:
        return not self.lost

    @property
    def sign(self) -> np.ndarray:
        """+1 energy gain, -1 loss, 0 neutral or not computed."""
        return np.where(self.ok, np.sign(self.values), 0).astype(np.int8)

    def fractions(self) -> dict[str, float]:
        """Share of computed cells with gain / loss."""
        n = max(1, int(self.ok.sum()))
        return {
            "gain": float(np.count_nonzero(self.ok & (self.values > 0)) / n),
            "loss": float(np.count_nonzero(self.ok & (self.values < 0)) / n),
            "failed": float(np.count_nonzero(~self.ok) / self.ok.size),
        }

    def summary(self) -> dict[str, Any]:
        """What the command line prints: the kind, the grid, the shares of gain and loss, the extremes."""
        ok = self.values[self.ok]
        return {"kind": self.kind, "t": self.t, "grid": [self.q.size, self.r.size], "fractions": self.fractions(),
                "min": float(ok.min()) if ok.size else None, "max": float(ok.max()) if ok.size else None,
                "elapsed_s": round(self.elapsed_s, 6)}  # fmt: skip

    def report(self) -> list[str]:
        """No lines: ``tprime`` prints its JSON summary, unless it wrote a file (then only with ``--json``)."""
        return []

    def write(self, path: str) -> dict[str, Any]:
        """``.npz``: :meth:`to_npz`, at exactly ``path``."""
        return export.write_by_suffix(path, {".npz": lambda p: export.write_through(p, self.to_npz)}, "T' map")

    def to_npz(self, path: Any) -> None:
        """Arrays plus the parameters as JSON, so the file says what it holds. ``values`` and ``sign`` are NaN
        where nothing was computed (``ok`` false; until issue 35 the file held 0 there, which averages)."""
        np.savez_compressed(
            path,
            kind=self.kind,
            t=self.t,
            q=self.q,
            r=self.r,
            values=np.where(self.ok, self.values, np.nan),
            sign=np.where(self.ok, self.sign, np.nan),
            ok=self.ok,
            status=self.status,
            status_names=status_names(),
            params=json.dumps(self.params.as_dict()),
        )


#: The per-period map's integration unless given.
PER_PERIOD_NUMERICS = Numerics(rtol=1e-8, atol=1e-8)


def check_range(rng: Any, name: str) -> tuple[float, float]:
    """A finite ``(lo, hi)`` with ``lo < hi``; the error names the parameter (``solve.checks.check_range``)."""
    return checks.check_range(name, rng)


def _cells(grid: Any) -> int | tuple[int, int]:
    """``grid`` as given: ``N`` (as an ``int``) or ``(NQ, NR)`` (a tuple of ``int``), each in ``[2, MAX_GRID]``."""

    def whole(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ParameterError(f"grid must be an integer N or a pair (NQ, NR) of integers, got {grid!r}")
        return int(v)

    if isinstance(grid, int | np.integer) and not isinstance(grid, bool):
        nq = nr = int(grid)
        cells: int | tuple[int, int] = nq
    else:
        try:
            gq, gr = grid
        except (TypeError, ValueError):
            raise ParameterError(f"grid must be N or (NQ, NR), got {grid!r}") from None
        nq, nr = whole(gq), whole(gr)
        cells = (nq, nr)
    for v in (nq, nr):
        if not 2 <= v <= config.MAX_GRID:
            raise ParameterError(f"grid must be between 2 and {config.MAX_GRID} per axis, got {grid!r}")
    return cells


#: A grid's check (declared by :func:`tprime_spec`): N or (NQ, NR), as :func:`_cells`.
_GRID = Check(lambda n, v: _cells(v), f"an integer in [2, {config.MAX_GRID}] per axis", "int")


def _grid(q_range: Any, r_range: Any, grid: Any) -> tuple[np.ndarray, np.ndarray]:
    cells = _cells(grid)
    nq, nr = (cells, cells) if isinstance(cells, int) else cells
    qlo, qhi = check_range(q_range, "q_range")
    rlo, rhi = check_range(r_range, "r_range")
    return np.linspace(qlo, qhi, nq), np.linspace(rlo, rhi, nr)


def tprime_map(params: Params, t: float, q_range: Any, r_range: Any, grid: Any = 200) -> TPrimeMap:
    """``T' = alpha * lambda`` on a grid at the frozen time ``t``."""
    start = time.perf_counter()
    t = checks.parse_finite("t", t)
    q, r = _grid(q_range, r_range, grid)
    values = Model(params).tprime(q[None, :], r[:, None], t)
    ok = np.isfinite(values)
    status = np.where(ok, int(Status.OK), int(Status.NONFINITE)).astype(np.int8)
    return TPrimeMap(
        "instantaneous", t, q, r, np.where(ok, values, 0.0), ok, status, params, time.perf_counter() - start
    )


def energy_change_map(
    params: Params,
    q_range: Any,
    r_range: Any,
    grid: Any = 100,
    numerics: Numerics | None = None,
    workers: int | None = None,
) -> TPrimeMap:
    """``T(t0 + T) - T(t0)`` for the trajectory starting at each grid point at ``t0``.

    The period's energy balance is what decides spin-up or decay on average;
    the instantaneous sign alternates within a period almost everywhere.
    """
    start = time.perf_counter()
    numerics = numerics or PER_PERIOD_NUMERICS
    q, r = _grid(q_range, r_range, grid)
    qq, rr = np.meshgrid(q, r)
    ics = np.column_stack([qq.ravel(), rr.ravel()])
    pmap = PoincareMap.of(params, numerics, workers=workers)
    batch = pmap.start(ics)
    out, npts = pmap.advance(batch, 1)
    ok = npts == 1
    # g is T-periodic, so T at both ends uses the same g(t0).
    e0 = pmap.model.energy(ics[:, 0], ics[:, 1], params.t0)
    e1 = pmap.model.energy(out[:, 0, 0], out[:, 0, 1], params.t0)
    values = np.where(ok, e1 - e0, 0.0)
    shape = qq.shape
    return TPrimeMap(
        "per-period",
        params.t0,
        q,
        r,
        values.reshape(shape),
        ok.reshape(shape),
        batch.status.astype(np.int8).reshape(shape),
        params,
        time.perf_counter() - start,
    )


# ---------------------------------------------------------------------------
# As a spec (``bilimovich tprime``): one call for both kinds.


@dataclass(frozen=True)
class TPrimeSpec:
    """What defines a T' map (made by :func:`tprime_spec`): the instantaneous ``T'`` at the frozen time ``t``, or
    (``per_period``) the energy change over one period from ``t0`` integrated with ``numerics``."""

    params: Params
    t: float
    q_range: tuple[float, float]
    r_range: tuple[float, float]
    grid: int | tuple[int, int]
    per_period: bool
    numerics: Numerics

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "t": self.t, "q_range": list(self.q_range),
                "r_range": list(self.r_range), "grid": self.grid, "per_period": self.per_period,
                "numerics": self.numerics.as_dict()}  # fmt: skip


@declare(
    t=Arg("frozen time (default t0)", default=None, check=number(optional=True)),
    q_range=Arg("the q axis", "range", metavar="A,B", scene="q_range", default=(-3.0, 3.0), check=span()),
    r_range=Arg("the r axis", "range", metavar="C,D", scene="r_range", default=(-3.0, 3.0), check=span()),
    grid=Arg("cells per axis", "int", default=200, check=_GRID),
    per_period=Arg("energy change over one period from t0 instead", "switch", default=False, check=BOOL),
    numerics=Arg(
        "the per-period map's integration",
        cli=False,
        default=PER_PERIOD_NUMERICS,
        check=optional_of(Numerics, PER_PERIOD_NUMERICS),
    ),
)
def tprime_spec(
    params: Params,
    t: float | None,
    q_range: tuple[float, float],
    r_range: tuple[float, float],
    grid: int | tuple[int, int],
    *,
    per_period: bool,
    numerics: Numerics,
) -> TPrimeSpec:
    """A validated :class:`TPrimeSpec` (a bad value raises ParameterError naming it, ``exc.option``: its keyword).
    ``t`` (default ``t0``) is the instantaneous map's; the per-period map starts at ``t0`` and refuses a ``t``.
    The options are declared above: defaults, checks (run before this body), flags."""
    with Checking() as at:
        at("per_period")
        if per_period and t is not None:
            raise ParameterError("per_period integrates over one period from t0; give t0, not t")
    return TPrimeSpec(params, params.t0 if t is None else t, q_range, r_range, grid, per_period, numerics)


def tprime(spec: TPrimeSpec, workers: int | None = None) -> TPrimeMap:
    """The map of ``spec``: :func:`tprime_map` or (``per_period``) :func:`energy_change_map`."""
    if spec.per_period:
        return energy_change_map(spec.params, spec.q_range, spec.r_range, spec.grid, spec.numerics, workers)
    return tprime_map(spec.params, spec.t, spec.q_range, spec.r_range, spec.grid)
