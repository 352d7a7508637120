"""Attractors are what recurs (issue 35 item 3): a set with no basin, a drift or a chaotic transient is no attractor.

The references are long runs from the sets' own points: scipy's solve_ivp on the naive field (tests/naive.py) where
a few hundred periods tell (a drift escapes), and the engine at 1e-12 (Vern9, not the basins' DOP853 at 1e-8) for
the 20,000 periods a chaotic transient of Fig. 1C needs (solve_ivp takes 43 ms a period there).
"""

from __future__ import annotations

import numpy as np
import pytest
from naive import ivp_fate

from explorer_core.analyses.basins import ESCAPE, basin_spec, basins
from explorer_core.scenes import get_scene
from explorer_core.solve.integrators import Batch
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.poincare import PoincareMap
from explorer_core.system.params import ParameterError

FIG5A, FIG1C = get_scene("fig5A"), get_scene("fig1C")


def _listed_sets(b) -> list:
    return [a for a in b.attractors if a.attracting and a.kind in ("chaotic", "quasi_periodic")]


def _hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    return float(max(d.min(axis=0).max(), d.min(axis=1).max()))


@pytest.fixture(scope="module")
def fig5a() -> object:
    return basins(FIG5A.params, FIG5A.box, (100, 100))


def test_fig5a_drift_is_no_attractor_and_every_set_has_a_basin(fig5a) -> None:
    b, bound = fig5a, fig5a.extra["escape_bound"]
    assert all(a.fraction > 0 for a in b.attractors)  # a set with no basin is not listed
    # every chaotic or quasi-periodic set listed as an attractor holds its points: solve_ivp from them stays bounded
    for a in _listed_sets(b):
        _, escaped = ivp_fate(FIG5A.params, a.points[-1], 200, bound=bound)
        assert not escaped, a
    # the drift Fig. 5A's recurrences located is said to be a transient, and solve_ivp from its points escapes
    # (after 150-300 periods from its last point, as where the run's recurrence test caught it varies)
    (drift,) = [t for t in b.transients if t.onto == ESCAPE]
    _, escaped = ivp_fate(FIG5A.params, drift.points[-1], 1000, bound=bound)
    assert escaped and drift.pixels > 0
    assert b.complete and any("transient" in w for w in b.warnings)
    s = b.summary()
    assert s["transients"][0]["onto"] == ESCAPE and not any(a.get("kind") == "quasi_periodic" for a in s["attractors"])


def _long_run(params, x, periods: int) -> np.ndarray:
    """Section points of ``periods`` periods from ``x`` by the engine at 1e-12 (Vern9), the reference's tolerance."""
    pmap = PoincareMap.of(params, Numerics(rtol=1e-12, atol=1e-12, bound=100.0))
    pts, npts = pmap.advance(Batch.start(np.asarray(x, float).reshape(1, 2), params.t0, params.period), periods)
    assert npts[0] == periods
    return pts[0]


def test_fig1c_lists_no_chaotic_transient_and_its_attractor_is_where_seeds_end() -> None:
    b = basins(FIG1C.params, FIG1C.box, (24, 24))
    listed = _listed_sets(b)
    assert listed
    for a in listed:
        # the seed's run at 1e-12 ends on the set listed: its last 1000 points and the set's points are one set (the
        # crescent attracts so weakly that the run at 1e-12 is still narrowing: 0.66 apart; the chaotic set Fig. 1C
        # showed before spread over the annulus 2 < |x| < 7 around it)
        tail = _long_run(FIG1C.params, a.seed, 20_000)[-1000:]
        assert _hausdorff(tail, a.points) < 1.0, a
        assert a.as_dict()["may_be_transient"] is True and "transient" in a.caveat()
    assert b.transients
    for t in b.transients:
        assert t.onto in {a.id for a in b.attractors} | {ESCAPE}
        # a transient's seed at 1e-12 does not end on the set it was taken for
        tail = _long_run(FIG1C.params, t.seed, 20_000)[-1000:]
        assert _hausdorff(tail, t.points) > 1.0, _hausdorff(tail, t.points)
    assert sum(a.fraction for a in b.attractors) == pytest.approx(1.0 - b.fraction.get(-3, 0.0))
    assert any(line.startswith("attractor") and "may be a longer transient" in line for line in b.report())


def test_the_horizon_is_an_option_declared_once() -> None:
    spec = basin_spec(FIG1C.params, FIG1C.box, (4, 4))
    assert spec.confirm == 20_000 and spec.as_dict()["confirm"] == 20_000
    assert spec.confirm_numerics().rtol == pytest.approx(spec.numerics.rtol / 100)
    with pytest.raises(ParameterError, match="confirm"):
        basin_spec(FIG1C.params, FIG1C.box, (4, 4), confirm=-1)
    import argparse

    from explorer_core.cli import build_parser

    parser = build_parser("basins")
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["basins"]
    assert "--confirm" in {s for a in sub._actions for s in a.option_strings}  # generated from the declaration
