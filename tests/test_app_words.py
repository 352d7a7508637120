"""Clear words (issue 21, item 4): stable trajectory numbers, modes that say they are on, honest progress."""

from __future__ import annotations

import numpy as np
import pytest
from test_app_orbits import page_for

from app.runner import WARM


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def test_a_click_does_not_renumber_the_random_trajectories() -> None:
    """Metamorphic: adding a clicked initial condition leaves every random trajectory's number, points and fate
    as they were. Fails on the old code (clicked ones came first: every random id shifted by one, the escaped
    list and the CSV's ids with them)."""
    page, jobs = page_for({"n": "40", "periods": "150", "transient": "0"})
    traj0, k0, q0, r0 = page.session.data()
    escaped0 = list(page.session.escaped)
    assert escaped0, "Fig. 8B: some of 40 random trajectories escape"
    page.session.add_initial_condition(0.1, -1.0)
    jobs.drain()
    traj, k, q, r = page.session.data()
    assert page.state.selected == 40 and set(traj[traj >= 40].tolist()) <= {40}  # the clicked one: number 40
    # Each random trajectory keeps its number: the same count of points, and its first point to within the
    # integration tolerance (the core's batch shares its adaptive steps, so a trajectory's numbers move at the
    # tolerance level with the batch's make-up, and chaos grows that later on: only the first is compared).
    for i in range(40):
        assert np.count_nonzero(traj == i) == np.count_nonzero(traj0 == i), i
        if np.any(traj0 == i):
            a, b = np.argmin(np.where(traj0 == i, k0, np.inf)), np.argmin(np.where(traj == i, k, np.inf))
            assert abs(q0[a] - q[b]) + abs(r0[a] - r[b]) < 1e-4, i
    assert [i for i in page.session.escaped if i < 40] == escaped0
    # More random ones: the clicked trajectory keeps the selection (renumbered after them).
    assert page.commit("n_random", "45") is None
    jobs.drain()
    assert page.state.selected == 45
    assert tuple(page.state.initial_conditions()[45]) == (0.1, -1.0)
