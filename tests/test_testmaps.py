"""The continuation engine on maps in closed form (explorer_core.analyses.continuation.testmaps): the Henon map's
fold and period doublings, the delayed logistic map's Neimark-Sacker point and the Henon fold and flip curves in
(a, b), against their exact values."""

from __future__ import annotations

import numpy as np
import pytest

from explorer_core.analyses.continuation import continue_map
from explorer_core.analyses.continuation.testmaps import DelayedLogistic, Henon
from explorer_core.system.params import ParameterError


@pytest.mark.parametrize("b", [0.3, -0.2])
def test_the_henon_cascade_doubles_at_its_closed_forms(b: float) -> None:
    res = continue_map(Henon(b=b), "a", (0.1, 1.7), Henon.fixed_point(0.1, b), 1, switch=True, max_period=4)
    pds = [bif for bif in res.bifurcations if bif.kind == "period_doubling"][:2]
    assert [bif.period for bif in pds] == [1, 2]
    assert [br.period for br in res.branches] == [1, 2, 4]
    exact = (3 * (1 - b) ** 2 / 4, (1 - b) ** 2 + (1 + b) ** 2 / 4)
    np.testing.assert_allclose([bif.value for bif in pds], exact, rtol=0, atol=1e-10)
    x = (1 - b) / (2 * exact[0])  # det(DP + I) = 1 - b - 2 a x = 0
    np.testing.assert_allclose(pds[0].point, [x, b * x], atol=1e-10)
    for bif in pds:
        assert bif.error < 1e-10
        assert np.min(np.abs(bif.multipliers + 1.0)) < 1e-10
    if b == 0.3:  # the flip coefficient at the located point: 3087/22672 (tests/test_normal_forms.py, by sympy)
        nf = pds[0].normal_form
        assert abs(nf.coefficient - 3087 / 22672) < 1e-9 and nf.criticality == "supercritical"
        line = res.report()[len(res.branches)]
        assert line.startswith("supercritical period doubling of the period-1 orbit at a = 0.3675 +- "), line
        assert "(b = 0.136159 +- " in line and line.endswith(")"), line


def test_the_henon_fold_is_at_its_closed_form() -> None:
    b = 0.3
    res = continue_map(Henon(b=b), "a", (-0.1, -0.2), Henon.fixed_point(-0.1, b), 1)
    (fold,) = res.bifurcations
    assert fold.kind == "fold"
    assert abs(fold.value + (1 - b) ** 2 / 4) < 1e-10
    np.testing.assert_allclose(fold.point, [2 / (1 - b), 2 * b / (1 - b)], atol=1e-7)  # sqrt of the 1e-14 noise
    assert np.min(np.abs(fold.multipliers - 1.0)) < 1e-10
    assert "after a fold" in res.branches[0].stop  # turned back onto the other fixed point
    assert abs(fold.normal_form.coefficient - 49 * np.sqrt(109) / 5668) < 1e-8  # (tests/test_normal_forms.py)
    assert fold.normal_form.criticality == "" and res.summary()["bifurcations"][0]["criticality"] is None


def test_the_delayed_logistic_map_has_its_neimark_sacker_point_at_2() -> None:
    res = continue_map(DelayedLogistic(), "a", (1.5, 2.5), (1 / 3, 1 / 3), 1)
    (ns,) = res.bifurcations
    assert ns.kind == "neimark_sacker"
    assert abs(ns.value - 2.0) < 1e-10
    assert abs(ns.normal_form.coefficient + 1.0) < 1e-8 and ns.normal_form.criticality == "supercritical"
    assert res.summary()["bifurcations"][0]["criticality"] == "supercritical"
    np.testing.assert_allclose(ns.point, [0.5, 0.5], atol=1e-10)
    np.testing.assert_allclose(sorted(np.angle(ns.multipliers)), [-np.pi / 3, np.pi / 3], atol=1e-10)
    br = res.branches[0]
    assert br.stable[np.array(br.values) < 2 - 1e-6].all() and not br.stable[np.array(br.values) > 2 + 1e-6].any()


def test_the_henon_fold_and_flip_curves_in_a_b_are_their_closed_forms() -> None:
    flip = continue_map(Henon(b=0.3), "a", (0.2, 1.0), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                        range2=(0.0, 0.6)).curves  # fmt: skip
    fold = continue_map(Henon(b=0.3), "a", (-0.1, -0.2), Henon.fixed_point(-0.1, 0.3), 1, param2="b",
                        range2=(0.0, 0.6), window1=(-1.0, 1.0)).curves  # fmt: skip
    for curves, kind, exact in ((flip, "period_doubling", lambda b: 3 * (1 - b) ** 2 / 4),
                                (fold, "fold", lambda b: -((1 - b) ** 2) / 4)):  # fmt: skip
        (curve,) = curves
        assert curve.kind == kind and curve.stop == "range end; range end"
        a, b = np.array(curve.rows)[:, :2].T
        assert len(a) > 10 and b.min() == 0.0  # from the b = 0 edge ...
        np.testing.assert_allclose(a, exact(b), rtol=0, atol=1e-9)
    assert np.array(flip[0].rows)[:, 0].min() == 0.2 and np.array(fold[0].rows)[:, 1].max() == 0.6  # ... to the box


def test_a_map_continuation_refuses_bad_input_by_name() -> None:
    with pytest.raises(ParameterError, match="'c'"):
        continue_map(Henon(), "c", (0.1, 0.2), (1.0, 0.3), 1)
    with pytest.raises(ParameterError, match="no period-1 orbit"):
        continue_map(Henon(b=0.3), "a", (-0.2, 0.0), (1.0, 0.3), 1)  # no fixed point below -(1 - b)^2 / 4
    with pytest.raises(ParameterError, match="range"):
        continue_map(Henon(), "a", (0.1, 0.1), (1.0, 0.3), 1)


def test_map_spec_shares_continuation_specs_declarations_and_messages() -> None:
    from explorer_core.analyses.continuation import continuation_spec, map_spec

    for name in ("value_range", "period", "switch", "max_period", "options", "range2", "window1", "codim2_nf"):
        assert map_spec.__options__[name] is continuation_spec.__options__[name], name
    spec = map_spec(Henon(), "a", (0.1, 0.2), (1.0, 0.3), 1)
    assert (spec.options, spec.switch, spec.codim2_nf, spec.window1) == (continuation_spec.__options__["options"]
                                                                          .default, False, False, None)  # fmt: skip
    for kw, match in (({"param2": "b"}, "param2 and range2 go together"),
                      ({"param2": "a", "range2": (0.0, 1.0)}, "param2 must differ from param"),
                      ({"range2": (1.0, 0.0), "param2": "b"}, "range2 must have C < D"),
                      ({"max_period": 0}, "max_period"), ({"period": 0}, "period")):  # fmt: skip
        with pytest.raises(ParameterError, match=match) as exc:
            map_spec(Henon(), "a", (0.1, 0.2), (1.0, 0.3), **{"period": 1, **kw})
        assert exc.value.option in kw
    with pytest.raises(ParameterError, match="not finite") as exc:  # continuation_spec's message, tagged seed
        map_spec(Henon(), "a", (0.1, 0.2), (np.inf, 0.3), 1)
    assert exc.value.option == "seed"
    with pytest.raises(ParameterError, match="cmap"):
        map_spec(object(), "a", (0.1, 0.2), (1.0, 0.3), 1)
