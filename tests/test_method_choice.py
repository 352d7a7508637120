"""The default method "auto": Verner 9(8) where it was measured to win (config.VERN9_MIN_RTOL..VERN9_MAX_RTOL),
DOP853 elsewhere; resolved when the settings are made, so what is saved says which method ran."""

from __future__ import annotations

import json

import numpy as np
import pytest
from naive import solve_ivp_section

from explorer_core import config
from explorer_core.analyses.manifolds import MANIFOLD_NUMERICS
from explorer_core.analyses.orbits import ORBIT_NUMERICS
from explorer_core.solve.integrators import Batch, advance
from explorer_core.solve.numerics import Numerics
from explorer_core.solve.tableaus import resolve_method
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params


@pytest.mark.parametrize(
    ("rtol", "method"),
    [(1e-6, "dop853"), (1e-8, "dop853"), (1e-9, "vern9"), (1e-10, "vern9"), (1e-12, "vern9"), (1e-13, "vern9"),
     (1e-14, "dop853"), (1e-15, "dop853")],
)  # fmt: skip
def test_auto_takes_vern9_between_the_measured_tolerances(rtol: float, method: str) -> None:
    assert config.DEFAULT_METHOD == "auto"
    assert Numerics(rtol=rtol, atol=rtol).method == method
    assert Numerics(method="AUTO", rtol=rtol).method == method
    assert resolve_method("auto", rtol) == method


def test_explicit_methods_are_honoured_and_fixed_steps_stay_dop853() -> None:
    for m in ("rk4", "dp5", "dop853", "vern9", "taylor"):
        assert Numerics(method=m, rtol=1e-12).method == m
        assert Numerics(method=m.upper(), rtol=1e-6).method == m
    # Fixed steps (adaptive=False) run DOP853's stages as before, whatever the tolerance.
    assert Numerics(rtol=1e-10, adaptive=False).method == "dop853"
    with pytest.raises(ParameterError, match=r"unknown method 'verner'.*auto"):
        Numerics(method="verner")


def test_saved_settings_name_the_method_that_ran() -> None:
    n = Numerics()
    assert n.method == "vern9"  # the default rtol, 1e-10
    d = json.loads(json.dumps(n.as_dict()))
    assert d["method"] == "vern9"
    assert Numerics(**{k: v for k, v in d.items() if k != "adaptive"}) == n
    # A copy with a looser tolerance keeps the concrete method it was given (no silent switch).
    assert Numerics(**{**d, "rtol": 1e-6}).method == "vern9"


def test_the_analyses_defaults() -> None:
    assert ORBIT_NUMERICS.method == "vern9" and ORBIT_NUMERICS.rtol == 1e-12
    assert MANIFOLD_NUMERICS.method == "vern9" and MANIFOLD_NUMERICS.rtol == 1e-10


def _run(method: str, tol: float, **kw) -> np.ndarray:
    p = Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1)
    b = Batch.start(np.array([[0.3, -0.2], [0.7, 0.5], [-0.9, 0.1]]), p.t0, p.period)
    out, npts = advance(Model(p), b, 20, method=method, rtol=tol, atol=tol, workers=1, **kw)
    assert np.all(npts == 20)
    return out


def test_the_engine_resolves_auto_as_numerics_does() -> None:
    assert np.array_equal(_run("auto", 1e-10), _run("vern9", 1e-10))
    assert np.array_equal(_run("auto", 1e-7), _run("dop853", 1e-7))
    assert np.array_equal(_run("auto", 1e-10, adaptive=False, steps_per_period=64),
                          _run("dop853", 1e-10, adaptive=False, steps_per_period=64))  # fmt: skip


def test_the_default_is_accurate_against_solve_ivp() -> None:
    """The default settings' section points against scipy's DOP853 at 1e-13 on the naive field (independent)."""
    p = Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1)
    n = Numerics()
    out = _run(n.method, n.rtol)
    for i, ic in enumerate([[0.3, -0.2], [0.7, 0.5], [-0.9, 0.1]]):
        ref = solve_ivp_section(p, ic, 20, rtol=1e-13, atol=1e-13)
        assert np.abs(out[i] - ref).max() < 1e-8
