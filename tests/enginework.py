"""Work the engine does, counted (steps and member-periods per system and tolerance): for tests that a change
integrates less, independent of the machine's load."""

from __future__ import annotations

from collections import Counter

import pytest

from explorer_core.solve import integrators, poincare, tangent


def count_engine(monkeypatch: pytest.MonkeyPatch) -> Counter:
    """``c[("steps" | "periods", system, rtol)]`` summed over every engine call from now on (the modules that call
    ``integrators.run`` by name are patched too)."""
    c: Counter = Counter()
    orig = integrators.run

    def run(system, coefs, batch, n_periods, **kw):
        before = batch.nsteps.copy()
        out = orig(system, coefs, batch, n_periods, **kw)
        c[("steps", system, kw.get("rtol"))] += int((batch.nsteps - before).sum())
        c[("periods", system, kw.get("rtol"))] += int(batch.n) * int(n_periods)
        return out

    for m in (integrators, poincare, tangent):
        monkeypatch.setattr(m, "run", run)
    return c
