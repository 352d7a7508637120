"""Every analysis of the registry keeps one contract (issue 31): its builder makes a frozen spec from keywords, the
spec says what it is as JSON, its runner takes the spec alone, and the result says what it computed and what it
lost in the one vocabulary (``summary()`` as JSON, ``lost`` a list of losses, ``complete`` true only if nothing
was lost). A new analysis in the registry fails here until it is given a small case."""

from __future__ import annotations

import inspect
import json
from typing import Any

import pytest
from test_contract import FIG8B, FIG10, _small_chart

from explorer_core import export
from explorer_core.losses import Loss
from explorer_core.registry import ANALYSES
from explorer_core.scenes import get_scene

FLIP = (-0.0377, -2.3979)  # Fig. 8B's flip saddle
P1 = (-0.27, -1.93)  # near Fig. 10's period-1 orbit at alpha = -0.36

#: Each analysis' small inputs: the builder's arguments (a callable for inputs that are themselves computed).
SMALL: dict[str, Any] = {
    "section": lambda: ((FIG8B, 5), {"ics": [(0.1, 0.2)], "transient": 2}),
    "density": lambda: ((FIG8B, 20, (-2.0, 1.0, -4.0, 0.0)), {"random": 4, "pixels": (16, 12)}),
    "equilibria": lambda: ((FIG10,), {"track": True, "n_t": 40}),
    "tprime": lambda: ((FIG8B,), {"grid": 8}),
    "lyapunov": lambda: ((FIG8B, [(-1.0, -2.0)], 32), {"transient": 8}),
    "bifurcation": lambda: (
        (FIG10, "alpha"),
        {"value_range": (-0.42, -0.41), "n_values": 3, "points": 4, "transient": 5, "ics": [(-0.5, -1.0)]},
    ),
    "orbits": lambda: ((FIG8B,), {"seeds": [FLIP], "period": 1}),
    "manifolds": lambda: ((FIG8B, FLIP, 1), {"length": 0.5}),
    "continuation": lambda: ((FIG10, "alpha", (-0.36, -0.355), P1, 1), {"max_points": 20}),
    "continue_from_seeds": lambda: ((FIG10, "alpha", (-0.36, -0.355), [P1]), {"periods": (1,), "max_orbits": 1}),
    "chart_boundaries": lambda: ((_small_chart(),), {"periods": (1,)}),
    "chart": lambda: (
        (FIG10, "alpha", (-0.38, -0.36), "I11", (1.0, 1.002), (2, 2)),
        {"ics": [P1], "transient": 20, "periods": 32, "p_max": 4},
    ),
    "basins": lambda: ((FIG8B, (-1.7, 1.5, -3.0, 1.0), (3, 3)), {"max_periods": 60, "confirm": 0}),
    "drift": lambda: ((get_scene("fig3").params, (200, 300)), {"degree": (0, 2), "m": 4, "box": get_scene("fig3").box}),
    "body": lambda: ((FIG8B, [(0.1, 0.1)], 2), {"samples": 4}),
    "symmetry": lambda: ((FIG8B,), {"periods": 3, "random": 2}),
    "birkhoff": lambda: ((FIG8B, [(-1.0, -2.0)], 8), {"transient": 4}),
    "sali": lambda: ((FIG8B, [(-1.0, -2.0)], 8), {"transient": 4}),
    "ftle": lambda: ((FIG8B, (-1.5, 0.5, -3.0, -1.0)), {"grid": (2, 2), "periods": 3}),
}


def test_every_analysis_of_the_registry_has_a_case() -> None:
    assert set(SMALL) == set(ANALYSES)


@pytest.mark.parametrize("name", sorted(ANALYSES))
def test_an_analysis_runs_from_its_spec_and_reports_in_the_one_vocabulary(name: str) -> None:
    a = ANALYSES[name]
    args, kw = SMALL[name]()
    spec = a.get("builder")(*args, **kw)
    assert isinstance(spec, a.get("spec"))
    json.loads(export.dumps(spec.as_dict()))  # the spec says what it is, as JSON
    run = a.get("run")
    accepts = inspect.signature(run).parameters
    seen: list[Any] = []
    if "progress" in accepts:
        result = run(spec, progress=seen.append)
    else:
        result = run(spec)
    assert isinstance(result, a.get("result")), type(result)
    summary = json.loads(export.dumps(result.summary()))
    assert isinstance(summary, dict) and summary
    lost = getattr(result, "lost", None)
    assert isinstance(lost, list | tuple) and all(isinstance(x, Loss) for x in lost), name
    complete = getattr(result, "complete", None)
    assert isinstance(complete, bool) and (not complete or not lost), name
    if a.iterate is not None and "progress" in accepts:
        assert seen, f"{name}: its runner reported no progress"
