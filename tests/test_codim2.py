"""Neimark-Sacker curves, codimension-two points and the switching at them (explorer_core.analyses.continuation
.codim2, .curves) on maps in closed form: every curve and point against its closed form, derived here with sympy
from the map's fixed points and multipliers (and, for CP, GPD and CH, from the normal-form coefficients by
formulas that are not the code's), never from the engine's own output."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from explorer_core.analyses.continuation import continue_map
from explorer_core.analyses.continuation.codim2 import NOT_IN_THE_PLANE, ON_CURVE
from explorer_core.analyses.continuation.testmaps import DelayedLogistic, FoldFlip, Henon, NeimarkSacker

A, B, X, Y = sp.symbols("a b x y", real=True)
#: How close a located point must be to its closed form.
TOL = 1e-6


def _points(res, kind: str | None = None) -> list:
    return [c for cu in res.curves for c in cu.codim2 if kind is None or c.kind == kind]


def _check(point, exact: tuple[float, float]) -> None:
    """Located to TOL, and the error estimate covers the true error."""
    err = max(abs(point.values[0] - exact[0]), abs(point.values[1] - exact[1]))
    assert err <= TOL, (point, exact)
    assert err <= point.error + 1e-15, (point, exact, err)


def _henon_fixed(cond):
    """The Henon fixed points (a, b, x) with the extra conditions ``cond(tr, det)`` (two equations), by sympy."""
    f = sp.Matrix([1 - A * X**2 + X * B, B * X])  # y = b x at a fixed point
    jac = sp.Matrix([[-2 * A * X, 1], [B, 0]])
    eqs = [f[0] - X, *cond(jac.trace(), jac.det())]
    return [tuple(float(v) for v in s) for s in sp.solve(eqs, [A, B, X], dict=False)]


def test_the_henon_fold_and_flip_curves_meet_r1_and_r2_at_their_closed_forms() -> None:
    flip = continue_map(Henon(b=0.3), "a", (0.2, 1.0), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                        range2=(-1.5, 0.6), window1=(-2.0, 5.0))  # fmt: skip
    fold = continue_map(Henon(b=0.3), "a", (-0.1, -0.2), Henon.fixed_point(-0.1, 0.3), 1, param2="b",
                        range2=(-1.5, 0.6), window1=(-2.0, 1.0))  # fmt: skip
    # mu1 = 1 (fold) or -1 (flip) and mu2 = the same: (tr, det) = (2, 1) or (-2, 1)
    (r1,) = _henon_fixed(lambda tr, det: [tr - 2, det - 1])
    (r2,) = _henon_fixed(lambda tr, det: [tr + 2, det - 1])
    assert r1[:2] == (-1.0, -1.0) and r2[:2] == (3.0, -1.0)
    assert [c.kind for c in _points(fold)] == ["R1"] and [c.kind for c in _points(flip)] == ["R2"]
    _check(_points(fold)[0], r1[:2])
    _check(_points(flip)[0], r2[:2])
    for res, exact in ((fold, lambda b: -((1 - b) ** 2) / 4), (flip, lambda b: 3 * (1 - b) ** 2 / 4)):
        (curve,) = res.curves
        a, b = np.array(curve.rows)[:, :2].T
        np.testing.assert_allclose(a, exact(b), rtol=0, atol=1e-8)  # at every point, the R point included
        assert b.min() == pytest.approx(-1.5) and b.max() == pytest.approx(0.6)
    line = flip.report()[-1] if not flip.messages else flip.report()[len(flip.branches) + 1]
    assert line.startswith("R2 (1:2 resonance) of the period-1 orbit on the period doubling curve at (a, b) = (3, -1)")
    d = flip.summary()["curves"][0]["codim2"][0]
    assert d["type"] == "R2" and d["a"] == pytest.approx(3.0) and d["b"] == pytest.approx(-1.0) and d["error"] < TOL


def test_the_henon_neimark_sacker_curve_has_its_resonances_and_ends_at_r1_and_r2() -> None:
    res = continue_map(Henon(a=1.0, b=-0.9), "b", (-0.9, -1.1), Henon.fixed_point(1.0, -0.9), 1, param2="a",
                       range2=(-2.0, 5.0))  # fmt: skip
    (curve,) = res.curves
    assert curve.kind == "neimark_sacker"
    b, a = np.array(curve.rows)[:, :2].T
    np.testing.assert_allclose(b, -1.0, rtol=0, atol=1e-12)  # det DP = -b = 1
    # Resonances on det = 1: tr = 2 cos theta, theta = 0, pi/2, 2 pi/3, pi
    exact = {name: _henon_fixed(lambda tr, det, c=c: [tr - c, det - 1])
             for name, c in (("R1", 2), ("R4", 0), ("R3", -1), ("R2", -2))}  # fmt: skip
    assert [c.kind for c in curve.codim2] == ["R1", "R4", "R3", "R2"]  # in the curve's order, no CH (Re d = 0)
    for c in curve.codim2:
        (e,) = exact[c.kind]
        _check(c, (e[1], e[0]))  # the curve is in (b, a)
    assert a.min() == pytest.approx(-1.0) and a.max() == pytest.approx(3.0)  # it ends at R1 and R2
    assert "R1 (1:1 resonance)" in curve.stop and "R2 (1:2 resonance)" in curve.stop and curve.status.label == "ok"
    assert not res.lost


def test_the_delayed_logistic_neimark_sacker_curve_in_a_c_has_r4_r3_r2_at_their_closed_forms() -> None:
    res = continue_map(DelayedLogistic(), "a", (1.5, 2.5), (1 / 3, 1 / 3), 1, param2="c", range2=(-4.0, 0.9))
    (curve,) = res.curves
    a, c = np.array(curve.rows)[:, :2].T
    np.testing.assert_allclose(a, 2.0, rtol=0, atol=1e-8)
    av, cv = sp.symbols("a c", real=True)
    x0 = 1 - 1 / av
    jac = sp.Matrix([[av * (1 - x0), -av * x0], [1 - cv, cv]])
    for c_ in curve.codim2:
        k = {"R4": 0, "R3": sp.Rational(-1, 2), "R2": -1}[c_.kind]
        (sol,) = sp.solve([jac.det() - 1, jac.trace() / 2 - k], [av, cv], dict=True)
        _check(c_, (float(sol[av]), float(sol[cv])))
    assert [c_.kind for c_ in curve.codim2] == ["R2", "R3", "R4"]
    assert c.min() == pytest.approx(-3.0) and c.max() == pytest.approx(0.9)  # ends at R2; the other way at the box


def _flip_coefficient(f: sp.Matrix, at: dict) -> sp.Expr:
    """Kuznetsov's flip coefficient of the planar map ``f`` at a fixed point with the multiplier -1 whose
    eigenvectors are ``e_1`` (both ways): Taylor coefficients of ``x``'s equation on the centre manifold
    ``y = y0 + h x^2`` (no B, C forms): ``b = 1/6 f_xxx + 1/2 f_xy * 2 h``."""
    fx, fy = f[0], f[1]
    lam = sp.diff(fy, Y).subs(at)
    h = sp.diff(fy, X, 2).subs(at) / 2 / (1 - lam)  # y = y0 + h x^2: the invariance at order x^2
    return sp.simplify(sp.diff(fx, X, 3).subs(at) / 6 + sp.diff(fx, X, Y).subs(at) * h)


def test_the_fold_flip_map_has_gpd_lppd_and_r2_at_their_closed_forms() -> None:
    av, bv, cv, dv = sp.symbols("a b c d", real=True)
    f = sp.Matrix([-(1 + av) * X + X * Y + dv * X**3, Y + bv + cv * Y**2 + Y**3 + X**2])
    for c, d, kinds in ((1.0, 1.0, {"GPD", "LPPD"}), (3.0, 0.0, {"LPPD", "R2"})):
        y0 = 0.2
        res = continue_map(FoldFlip(b=-(c * y0**2 + y0**3), c=c, d=d), "a", (0.5, -0.5), (0.0, y0), 1,
                           param2="b", range2=(-3.0, 3.0), window1=(-3.0, 3.0), codim2_nf=True)  # fmt: skip
        (curve,) = res.curves
        assert curve.kind == "period_doubling" and {p.kind for p in curve.codim2} == kinds
        # The flip curve: x = 0, y = a (multiplier y - (1 + a) = -1), b = -c y^2 - y^3; the other multiplier
        # mu2 = 1 + 2 c y + 3 y^2.
        on = {cv: c, dv: d, X: 0, Y: av, bv: -c * av**2 - av**3}
        mu2 = sp.diff(f[1], Y).subs(on)
        a, b = np.array(curve.rows)[:, :2].T
        np.testing.assert_allclose(b, -c * a**2 - a**3, rtol=0, atol=1e-8)
        exact = {"LPPD": sp.solve(mu2 - 1, av), "R2": sp.solve(mu2 + 1, av),
                 "GPD": sp.solve(sp.numer(sp.together(_flip_coefficient(f.subs({cv: c, dv: d}), on))), av)}  # fmt: skip
        for p in curve.codim2:
            roots = [float(r) for r in exact[p.kind] if r.is_real]
            r = min(roots, key=lambda r: abs(r - p.values[0]))
            _check(p, (r, -c * r**2 - r**3))
        assert len(curve.codim2) == sum(1 for k in kinds for r in exact[k] if r.is_real and -3 < float(r) < 3
                                        and abs(-c * float(r) ** 2 - float(r) ** 3) < 3)  # fmt: skip


def test_the_fold_flip_map_has_a_cusp_on_its_fold_curve() -> None:
    # Continued in b at c = 1 from the fixed point y0: the fold at y = 0, b = 0 for every c; its fold coefficient
    # (the x^2 .. y^2 coefficient of y's equation, the eigenvector e_2 both ways) is c: a cusp at c = 0.
    y0 = float(sp.nsolve(Y**2 + Y**3 - 0.1, Y, 0.3))
    res = continue_map(FoldFlip(b=-0.1, c=1.0), "b", (-0.1, 0.1), (0.0, y0), 1, param2="c", range2=(-1.0, 1.0),
                       codim2_nf=True)  # fmt: skip
    (curve,) = [cu for cu in res.curves if cu.kind == "fold"]
    cv = sp.symbols("c", real=True)
    fold_coefficient = sp.diff(Y + B + cv * Y**2 + Y**3, Y, 2).subs(Y, 0) / 2
    (c_star,) = sp.solve(fold_coefficient, cv)
    (cp,) = [p for p in curve.codim2 if p.kind == "CP"]
    _check(cp, (0.0, float(c_star)))
    np.testing.assert_allclose(np.array(curve.rows)[:, 0], 0.0, atol=1e-9)


def test_the_neimark_sacker_normal_form_has_its_chenciner_point_and_resonances() -> None:
    # Re d from the Taylor coefficients of the map in z (Kuznetsov's formula, as in tests/test_normal_forms.py):
    # z -> e z (1 + c |z|^2) + conj(z)^2 has g21 = 2 e c, g02 = 2, g20 = g11 = 0.
    cv, th = sp.symbols("c theta", real=True)
    e = sp.exp(sp.I * th)
    g21, g02 = 2 * e * cv, 2
    re_d = sp.simplify(sp.re(sp.conjugate(e) * g21 / 2) - sp.Abs(g02) ** 2 / 4)
    (c_star,) = sp.solve(re_d, cv)
    res = continue_map(NeimarkSacker(), "a", (-0.1, 0.1), (0.0, 0.0), 1, param2="c", range2=(0.0, 2.0))
    assert not _points(res)  # the normal-form test functions only when asked
    res = continue_map(NeimarkSacker(), "a", (-0.1, 0.1), (0.0, 0.0), 1, param2="c", range2=(0.0, 2.0),
                       codim2_nf=True)  # fmt: skip
    (ch,) = _points(res)
    assert ch.kind == "CH"
    np.testing.assert_allclose(np.array(res.curves[0].rows)[:, 0], 0.0, atol=1e-9)  # det DP = (1 + a)^2 = 1
    _check(ch, (0.0, float(c_star)))
    res = continue_map(NeimarkSacker(), "a", (-0.1, 0.1), (0.0, 0.0), 1, param2="theta", range2=(0.1, 3.0))
    assert [p.kind for p in _points(res)] == ["R4", "R3"]
    for p in _points(res):  # det (1 + a)^2 = 1, 2 cos theta = tr
        _check(p, (0.0, float(sp.solve(sp.cos(th) - {"R4": 0, "R3": sp.Rational(-1, 2)}[p.kind], th)[0])))


def test_switching_at_the_henon_r2_follows_the_period_two_neimark_sacker_curve() -> None:
    res = continue_map(Henon(b=0.3), "a", (0.2, 0.5), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                       range2=(-1.5, 0.6), window1=(-2.0, 5.0), switch=True, max_period=2)  # fmt: skip
    (ns2,) = [cu for cu in res.curves if cu.origin is not None]
    assert ns2.origin.kind == "R2" and ns2.kind == "neimark_sacker" and ns2.period == 2
    # The 2-cycle: x1 + x2 = (1 - b)/a, x1 x2 = ((1 - b)^2 - a)/a^2; DP^2 = J(x2) J(x1), det = b^2.
    s, prod = (1 - B) / A, ((1 - B) ** 2 - A) / A**2
    tr2 = sp.expand(4 * A**2 * prod + 2 * B)
    for name, k in (("R1", 1), ("R4", 0), ("R3", sp.Rational(-1, 2)), ("R2", -1)):
        (av,) = sp.solve((tr2 / 2 - k).subs(B, -1), A)
        assert name != "R1" or av == 3  # the 2-cycle is born at the period-1 R2
        for p in (p for p in ns2.codim2 if p.kind == name):
            _check(p, (float(av), -1.0))
    assert [p.kind for p in ns2.codim2] == ["R4", "R3", "R2"]
    a, b = np.array(ns2.rows)[:, :2].T
    np.testing.assert_allclose(b, -1.0, atol=1e-9)
    assert a.min() < 3.01 and a.max() == pytest.approx(4.0)  # from the R2 point to the 2-cycle's own R2
    for av, bv, q, r in ns2.rows:  # independently: period-2 points of the map with det DP^2 = 1, |tr| < 2
        x = np.array([q, r])
        jac = np.eye(2)
        for _ in range(2):
            jac = np.array([[-2 * av * x[0], 1.0], [bv, 0.0]]) @ jac
            x = np.array([1 - av * x[0] ** 2 + x[1], bv * x[0]])
        assert np.allclose(x, [q, r], atol=1e-9) and abs(np.linalg.det(jac) - 1) < 1e-8
        assert abs(np.trace(jac)) <= 2 + 1e-8 and s.subs({A: av, B: bv}) != 2 * q


def test_switching_at_lppd_and_gpd_follows_the_doubled_orbits_curves() -> None:
    y0 = 0.2
    res = continue_map(FoldFlip(b=-(y0**2 + y0**3), c=1.0, d=1.0), "a", (0.5, -0.5), (0.0, y0), 1, param2="b",
                       range2=(-3.0, 3.0), window1=(-3.0, 3.0), switch=True, max_period=2,
                       codim2_nf=True)  # fmt: skip
    switched = [cu for cu in res.curves if cu.origin is not None]
    assert {(cu.origin.kind, cu.kind) for cu in switched} >= {("GPD", "fold"), ("LPPD", "neimark_sacker")}
    m = FoldFlip(c=1.0, d=1.0)
    for cu in switched:
        start = np.array(cu.origin.values)
        near = min(np.abs(np.array(r[:2]) - start).max() for r in cu.rows)
        assert near < 0.05, cu.origin  # it emanates from the point
        two = 0
        for av, bv, q, r in cu.rows:
            end, jac, pts = Henon.orbit(m.over(["a", "b"]), np.array([q, r]), [av, bv], 2)
            assert np.allclose(end, [q, r], atol=1e-8)  # the curve's corrector: steps below 1e-9
            if np.linalg.norm(pts[0] - [q, r]) < 1e-6:
                continue  # where the doubled orbit is born (on the curve's end)
            two += 1
            mu = np.linalg.eigvals(jac)
            if cu.kind == "fold":
                assert np.min(np.abs(mu - 1)) < 1e-7
            else:
                assert abs(np.linalg.det(jac) - 1) < 1e-7 and abs(np.trace(jac)) < 2
        assert two >= len(cu.rows) - 2


def test_the_codimension_two_points_of_three_dimensional_maps_are_said_not_to_occur() -> None:
    assert NOT_IN_THE_PLANE == ("LPNS", "PDNS", "NSNS")
    assert not set(NOT_IN_THE_PLANE) & {k for names in ON_CURVE.values() for k in names}


def test_the_codimension_two_points_are_written_and_printed(tmp_path) -> None:
    import csv
    import json

    res = continue_map(Henon(a=1.0, b=-0.9), "b", (-0.9, -1.1), Henon.fixed_point(1.0, -0.9), 1, param2="a",
                       range2=(-2.0, 5.0))  # fmt: skip
    res.write(str(tmp_path / "c.codim2.csv"))
    res.write(str(tmp_path / "c.json"))
    res.write(str(tmp_path / "c.csv"))
    with open(tmp_path / "c.codim2.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["type"] for r in rows] == ["R1", "R4", "R3", "R2"] and rows[2]["name"] == "1:3 resonance"
    assert float(rows[2]["value2"]) == pytest.approx(1.25) and float(rows[2]["value"]) == pytest.approx(-1.0)
    with open(tmp_path / "c.csv") as fh:
        assert len(list(csv.DictReader(fh))) == res.n_points  # the branch table as it was
    d = json.loads((tmp_path / "c.json").read_text())
    assert [c["type"] for c in d["curves"][0]["codim2"]] == ["R1", "R4", "R3", "R2"]
    lines = [ln for ln in res.report() if ln.startswith("R")]
    assert lines[2].startswith(
        "R3 (1:3 resonance) of the period-1 orbit on the neimark sacker curve at (b, a) = (-1, 1.25) +- "
    )


def test_a_switch_not_offered_is_said_with_the_point_s_kind() -> None:
    """With ``switch``, every R1, R3, R4 (and CH) met says that no switching is offered there and why, and an R2
    whose doubled orbit is beyond ``max_period`` says so: the report (what the command line prints) has each
    once; without ``switch`` nothing is said."""
    args = (Henon(a=1.0, b=-0.9), "b", (-0.9, -1.1), Henon.fixed_point(1.0, -0.9), 1)
    res = continue_map(*args, param2="a", range2=(-2.0, 5.0), switch=True, max_period=1)
    said = [m for m in res.messages if m.startswith("no switching at ")]
    assert [m.split()[3] for m in said] == ["R1", "R4", "R3", "R2"]
    assert said[2].startswith("no switching at R3 (1:3 resonance) of the period-1 orbit at (b, a) = (-1, 1.25")
    assert "not offered" in said[0] and "init_R3_NS3m" in said[2] and "init_R4_NS4m" in said[1]
    assert "period-2 orbit is beyond max_period = 1" in said[3]
    assert [ln for ln in res.report() if ln.startswith("no switching")] == said
    quiet = continue_map(*args, param2="a", range2=(-2.0, 5.0))
    assert not [m for m in quiet.messages if m.startswith("no switching")]


def test_the_points_of_a_curve_switched_onto_say_that_switching_is_not_repeated() -> None:
    res = continue_map(Henon(b=0.3), "a", (0.2, 0.5), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                       range2=(-1.5, 0.6), window1=(-2.0, 5.0), switch=True, max_period=4)  # fmt: skip
    (ns2,) = [cu for cu in res.curves if cu.origin is not None]
    said = {m.split()[3]: m for m in res.messages if "switching is not repeated" in m}
    assert set(said) == {p.kind for p in ns2.codim2} == {"R4", "R3", "R2"}
    assert "of the period-2 orbit at (a, b) = (4.0000000" in said["R2"]


def test_the_henon_cascade_s_r2_points_are_within_their_error_estimates_on_both_curves() -> None:
    """The R2 of the period-1 .. 16 orbits (flip curves switched onto at R2, and the Neimark-Sacker curves that end
    there) against the point solved independently in 40 digits (mpmath: ``P^n(x) = x``, ``tr DP^n = -2`` on
    ``b = -1``, where ``det DP^n = b^n = 1``). Fails on the old estimate: the 8-cycle's R2 on its flip curve is
    ``7.3e-9`` off, estimated ``3.7e-9`` (the corrector's untaken step moves ``tr A``, steep in ``a``), and the
    16-cycle's ``1.2e-11`` off, estimated ``7e-12`` (the test function's own error, where it is flat)."""
    import mpmath as mp

    res = continue_map(Henon(b=0.3), "a", (0.2, 1.5), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                       range2=(-1.5, 0.6), window1=(-2.0, 5.0), switch=True)  # fmt: skip
    r2 = [(cu.kind, c) for cu in res.curves for c in cu.codim2 if c.kind == "R2"]
    assert {c.period for _, c in r2} >= {1, 2, 4, 8, 16} and {k for k, _ in r2} == {"period_doubling", "neimark_sacker"}
    mp.mp.dps = 40

    def g(x, y, a, n):
        jac = mp.eye(2)
        x0, y0 = x, y
        for _ in range(n):
            jac = mp.matrix([[-2 * a * x, 1], [-1, 0]]) * jac
            x, y = 1 - a * x**2 + y, -x
        return [x - x0, y - y0, jac[0, 0] + jac[1, 1] + 2]

    for kind, c in r2:
        x, y, a = mp.findroot(lambda x, y, a, n=c.period: g(x, y, a, n), (*map(mp.mpf, c.point), mp.mpf(c.values[0])))
        err = max(abs(c.values[0] - float(a)), abs(c.values[1] + 1.0))
        assert err <= c.error, (kind, c.period, c.values, float(a), err, c.error)
