"""The periodic-orbit search's work (issue 22), counted, and its independence of the seeds' order.

Seeds that reach an orbit's neighbourhood together (the accurate phase of Newton, within ``DUPLICATE_TOL`` of each
other) go on as one: the orbit costs one accurate monodromy or two, not one per seed. Which seed goes on must not
depend on the order the seeds were given in.
"""

from __future__ import annotations

import numpy as np
import pytest
from enginework import count_engine

from explorer_core.analyses.orbits import ORBIT_NUMERICS, find_orbits, grid_seeds, same_orbit
from explorer_core.scenes import get_scene
from explorer_core.solve import poincare, rk
from explorer_core.solve.poincare import _twins

FIG8B = get_scene("fig8B")
FIG10 = get_scene("fig10")


def test_seeds_reaching_an_orbit_together_take_one_accurate_monodromy(monkeypatch: pytest.MonkeyPatch) -> None:
    # Fig. 10's 10 x 10 period-1 search (``bilimovich orbits --scene fig10``): on main 56 accurate monodromies
    # for its 3 orbits (every seed that reached one integrated the tangent system at 1e-12 once or twice).
    c = count_engine(monkeypatch)
    res = find_orbits(FIG10.params, grid_seeds(FIG10.box, 10, 10), [1])
    assert len(res.orbits) == 3 and len(res.failures) == 10
    accurate = c[("periods", rk.TANGENT, ORBIT_NUMERICS.rtol)]
    assert accurate <= 2 * len(res.orbits), c


def test_the_orbits_found_do_not_depend_on_the_seeds_order() -> None:
    seeds = grid_seeds(FIG8B.box, 8, 8)
    ref = find_orbits(FIG8B.params, seeds, [1, 2, 3, 4])
    for perm in (np.arange(len(seeds))[::-1], np.random.default_rng(3).permutation(len(seeds))):
        res = find_orbits(FIG8B.params, seeds[perm], [1, 2, 3, 4])
        assert [o.period for o in res.orbits] == [o.period for o in ref.orbits]
        assert len(res.failures) == len(ref.failures)
        for a, b in zip(res.orbits, ref.orbits, strict=True):
            assert same_orbit(a, b, tol=1e-8)
            np.testing.assert_allclose(a.multipliers, b.multipliers, rtol=1e-6, atol=1e-9)


def test_twins_keep_the_smallest_residual_whatever_the_order() -> None:
    x = np.array([[0.0, 0.0], [1e-6, 0.0], [2e-5, 0.0], [1.0, 1.0], [1.0 + 1e-6, 1.0], [3.0, 3.0]])
    res = np.array([1e-6, 1e-8, 1e-7, np.inf, np.inf, 1e-3])
    for perm in (np.arange(6), np.array([5, 4, 3, 2, 1, 0]), np.array([2, 0, 4, 1, 5, 3])):
        twin = _twins(x[perm], res[perm], np.zeros(6, bool))
        kept = sorted(map(tuple, x[perm][~twin].tolist()))
        # (0, 0), (1e-6, 0), (2e-5, 0) chain into one cluster: 1e-6 (smallest residual) goes on; of the two
        # with no residual yet, the smaller point; (3, 3) alone.
        assert kept == [(1e-6, 0.0), (1.0, 1.0), (3.0, 3.0)], (perm, kept)
    stopped = np.array([False, True, False, False, False, False])  # a member stopped already is not a survivor
    twin = _twins(x, res, stopped)
    assert twin.tolist() == [True, False, False, False, True, False]  # (2e-5, 0) has the smaller residual now


def test_twins_of_a_dense_cluster_in_linear_memory() -> None:
    """20,000 iterates of one orbit together (a fine grid of seeds): one goes on, the rest stop, in memory linear in
    their number (a dense distance matrix was 6.4 GB); a lone iterate 1e-3 away (ten tolerances) goes on too."""
    rng = np.random.default_rng(5)
    x = np.vstack([np.array([0.5, -1.0]) + rng.uniform(-1e-6, 1e-6, (20_000, 2)), [[0.501, -1.0]]])
    res = rng.uniform(1e-9, 1e-7, x.shape[0])
    twin = _twins(x, res, np.zeros(x.shape[0], bool))
    assert int((~twin).sum()) == 2 and not twin[-1]
    assert not twin[int(np.argmin(res[:-1]))]  # the smallest residual is the survivor


def test_far_iterates_take_the_roughest_map(monkeypatch: pytest.MonkeyPatch) -> None:
    # Residual above FAR_UNTIL: the tangent system at 1e-6 (main: 1e-8 until the residual is below 1e-5), where
    # most of a grid search's work is; the orbits are the same (tests/test_orbits.py checks them independently).
    c = count_engine(monkeypatch)
    res = find_orbits(FIG8B.params, grid_seeds(FIG8B.box, 6, 6), [1, 2, 3])
    assert res.orbits
    far, rough = c[("periods", rk.TANGENT, poincare.FAR_RTOL)], c[("periods", rk.TANGENT, 1e-8)]
    assert far > rough > 0, c
