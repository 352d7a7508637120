"""The compiled equilibria (explorer_core.analyses.equilibria_kernels) against the plain-Python reference.

``tests/naive.py`` keeps the solver of two conics, the classification and the tracks' matching as they
were in plain Python. The kernels must give the same points to rounding (same count, points at infinity,
complex pairs, degeneracy) on a battery of conic pairs chosen to reach every branch of the algorithm,
and the same tracks on the paper's scenes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from explorer_core.analyses import equilibria_kernels as ek
from explorer_core.analyses.equilibria import (
    TYPES,
    _Samples,
    classify,
    equilibria,
    equilibrium_tracks,
    solve_conics,
)
from explorer_core.scenes import list_scenes
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, inertia_entries
from tests.naive import _eig2, _type, naive_equilibria, naive_solve_conics, naive_tracks

# ---------------------------------------------------------------------------
# A battery of conic pairs (rows 1, q, r, q^2, q r, r^2).


def _through(points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random conic through up to 5 given points (the null space of their monomial rows)."""
    q, r = points[:, 0], points[:, 1]
    m = np.column_stack([np.ones_like(q), q, r, q * q, q * r, r * r])
    _, _, vt = np.linalg.svd(m)
    null = vt[len(points) :]
    return rng.normal(size=null.shape[0]) @ null


def _transform(c: np.ndarray, angle: float, shift: tuple[float, float], scale: float) -> np.ndarray:
    """The conic ``c`` in coordinates ``x = scale R(angle) y + shift`` (as a function of ``y``)."""
    a = np.array([[c[3], c[4] / 2], [c[4] / 2, c[5]]])
    b = np.array([c[1], c[2]])
    m = scale * np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    s = np.array(shift)
    a2 = m.T @ a @ m
    b2 = m.T @ (2 * a @ s + b)
    c0 = s @ a @ s + b @ s + c[0]
    return np.array([c0, b2[0], b2[1], a2[0, 0], 2 * a2[0, 1], a2[1, 1]])


def _battery(n: int, seed: int = 0) -> tuple[np.ndarray, list[str]]:
    """``n`` conic pairs (n, 2, 6) of many kinds, with each pair's kind."""
    rng = np.random.default_rng(seed)
    circle = np.array([-1.0, 0, 0, 1, 0, 1])
    kinds = {
        # generic: normal coefficients (0, 2 or 4 real points, complex pairs)
        "generic": lambda: rng.normal(size=(2, 6)),
        # through 2, 3 or 4 random common points (every real intersection count)
        "through": lambda: _common_points(rng, int(rng.integers(2, 5))),
        # near-tangent: a circle and a line r = 1 + eps, moved together about the plane
        "tangent": lambda: _same_move(rng, circle, np.r_[-1.0 - _tiny(rng, -15, -5), 0, 1, 0, 0, 0]),
        # two circles touching (from outside), slightly pulled apart or pushed together
        "touching": lambda: _same_move(rng, circle, _transform(circle, 0.0, (2.0 + _tiny(rng, -14, -4), 0.0), 1.0)),
        # a line and a conic (no v^2 term in one of them)
        "line": lambda: np.array([np.r_[rng.normal(size=3), 0.0, 0.0, 0.0], rng.normal(size=6)])[rng.permutation(2)],
        "two lines": lambda: np.array([np.r_[rng.normal(size=3), 0, 0, 0], np.r_[rng.normal(size=3), 0, 0, 0]]),
        # quadratic parts sharing a linear factor (the frozen field's structure: a point at infinity,
        # the resultant's top coefficient vanishes)
        "shared factor": lambda: _shared_factor(rng),
        # two parabolas with the same axis direction: more points at infinity
        "parabolas": lambda: np.array(
            [
                [rng.normal(), rng.normal(), rng.normal(), 0.0, 0.0, 1.0],
                [rng.normal(), rng.normal(), rng.normal(), 0, 0, 1],
            ]
        ),
        # huge and tiny coefficients: a whole conic scaled, or the plane scaled (q -> s q)
        "scaled": lambda: _common_points(rng, 3) * 10.0 ** rng.uniform(-150, 150, size=(2, 1)),
        "plane scaled": lambda: np.array(
            [_transform(c, 0.0, (0.0, 0.0), 10.0 ** rng.uniform(-60, 60)) for c in rng.normal(size=(2, 6))]
        ),
        # one 4-fold point: a circle and a circle + k (its tangent line)^2 meet only at the tangency
        "double": lambda: _double(rng),
        # the real use: the frozen field of a random body at a random time
        "field": lambda: _field(rng),
    }
    names = list(kinds)
    out, which = [], []
    for k in range(n):
        name = names[k % len(names)]
        out.append(np.asarray(kinds[name](), dtype=float).reshape(2, 6))
        which.append(name)
    return np.array(out), which


def _common_points(rng: np.random.Generator, k: int) -> np.ndarray:
    """Two random conics through the same ``k`` random points."""
    points = rng.normal(size=(k, 2))
    return np.array([_through(points, rng), _through(points, rng)])


def _tiny(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A small number of either sign, log-uniform in ``[10^lo, 10^hi]``."""
    return float(10.0 ** rng.uniform(lo, hi) * rng.choice([-1.0, 1.0]))


def _move(rng: np.random.Generator) -> tuple[float, tuple[float, float], float]:
    return float(rng.uniform(0, 2 * math.pi)), (float(rng.normal()), float(rng.normal())), float(rng.uniform(0.2, 5))


def _same_move(rng: np.random.Generator, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    move = _move(rng)
    return np.array([_transform(a, *move), _transform(b, *move)])


def _shared_factor(rng: np.random.Generator) -> np.ndarray:
    l1, l2, l3 = rng.normal(size=(3, 2))  # Q2 = l1 l2, R2 = l1 l3

    def prod(x: np.ndarray, y: np.ndarray) -> list[float]:
        return [x[0] * y[0], x[0] * y[1] + x[1] * y[0], x[1] * y[1]]

    return np.array([np.r_[rng.normal(size=3), prod(l1, l2)], np.r_[rng.normal(size=3), prod(l1, l3)]])


def _double(rng: np.random.Generator) -> np.ndarray:
    """A circle and ``a circle + k l^2`` (``l`` the tangent line at a random point of it), moved together."""
    th = rng.uniform(0, 2 * math.pi)
    x0, y0 = math.cos(th), math.sin(th)
    # l = x0 q + y0 r - 1; l^2 in the monomials (1, q, r, q^2, q r, r^2)
    line_sq = np.array([1.0, -2 * x0, -2 * y0, x0 * x0, 2 * x0 * y0, y0 * y0])
    circle = np.array([-1.0, 0, 0, 1, 0, 1])
    return _same_move(rng, circle, circle * rng.normal() + rng.normal() * line_sq)


def _field(rng: np.random.Generator) -> np.ndarray:
    a = rng.normal(size=(3, 3))
    params = Params(
        inertia=inertia_entries(a @ a.T + 0.3 * np.eye(3)),
        alpha=float(rng.normal()),
        g0=float(rng.normal()),
        g1=float(rng.normal()),
        g2=float(rng.normal()),
    )
    return Model(params).coefficients(float(rng.uniform(0, 2 * math.pi)))[:2]


def _compare(coef: np.ndarray) -> tuple[list[int], float]:
    """Pairs where the kernel and the reference disagree in anything but rounding, and the worst relative
    distance between their points (relative to the largest point of the pair)."""
    m = coef.shape[0]
    points = np.zeros((m, 4, 2))
    info = np.zeros((m, 4), np.int64)
    ek.solve_pairs(coef, 1e8, 1e-5, 1e-9, 1e-7, points, info)
    bad, worst = [], 0.0
    for k in range(m):
        ref = naive_solve_conics(coef[k, 0], coef[k, 1])
        code, n, at_inf, n_cx = info[k].tolist()
        same = (n, at_inf, n_cx, code in (ek.Q_ZERO, ek.R_ZERO, ek.COMMON)) == (
            ref.q.size,
            ref.at_infinity,
            ref.n_complex,
            ref.degenerate,
        )
        if not same:
            bad.append(k)
            continue
        if n:
            size = max(float(np.max(np.hypot(ref.q, ref.r))), 1e-300)
            d = float(np.max(np.hypot(points[k, :n, 0] - ref.q, points[k, :n, 1] - ref.r))) / size
            if d > 1e-12:
                bad.append(k)
            worst = max(worst, d)
    return bad, worst


def test_battery_of_conic_pairs_matches_the_python_reference() -> None:
    coef, kinds = _battery(2400)
    bad, worst = _compare(coef)
    assert not bad, [(kinds[k], coef[k].tolist()) for k in bad[:5]]
    assert worst <= 1e-12
    # The battery reaches what it is meant to: every count of real points, points at infinity, complex pairs.
    points = np.zeros((coef.shape[0], 4, 2))
    info = np.zeros((coef.shape[0], 4), np.int64)
    ek.solve_pairs(coef, 1e8, 1e-5, 1e-9, 1e-7, points, info)
    assert set(info[:, 1].tolist()) >= {0, 1, 2, 3, 4}
    assert set(info[:, 2].tolist()) >= {0, 1, 2, 3, 4}
    assert set(info[:, 3].tolist()) >= {0, 2, 4}


def test_degenerate_and_constant_pairs_match_the_reference() -> None:
    line = np.array([0.5, 1.0, -2.0, 0.0, 0.0, 0.0])
    other = np.array([1.0, 2.0, 0.5, 0.0, 0.0, 0.0])
    pairs = [
        (np.zeros(6), np.r_[1.0, 0, 0, 1, 0, 1]),  # Q == 0
        (np.r_[1.0, 0, 0, 1, 0, 1], np.zeros(6)),  # R == 0
        (np.r_[3.0, 0, 0, 0, 0, 0], np.r_[-1.0, 0, 0, 1, 0, 1]),  # a constant
        # a common line: Q = line * other, R = line * (q + r)
        (np.r_[0.5, 1.25, -0.75, 2.0, -3.5, -1.0], np.r_[0.0, 0.5, 0.5, 1.0, -1.0, -2.0]),
        (line, line * 3.0),  # the same line twice
        (line, other),  # two lines: one point
    ]
    for cq, cr in pairs:
        got, ref = solve_conics(cq, cr), naive_solve_conics(cq, cr)
        assert (got.degenerate, got.message, got.at_infinity, got.n_complex) == (
            ref.degenerate,
            ref.message,
            ref.at_infinity,
            ref.n_complex,
        )
        np.testing.assert_allclose(got.q, ref.q, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(got.r, ref.r, rtol=1e-12, atol=1e-15)


def test_a_batch_does_not_depend_on_its_neighbours() -> None:
    """The kernel reuses its scratch space from pair to pair: a pair's result must not depend on which
    pairs were solved before it in the same call (shuffled batch == one by one)."""
    coef, _ = _battery(600, seed=7)
    m = coef.shape[0]
    perm = np.random.default_rng(1).permutation(m)
    points = np.zeros((m, 4, 2))
    info = np.zeros((m, 4), np.int64)
    ek.solve_pairs(np.ascontiguousarray(coef[perm]), 1e8, 1e-5, 1e-9, 1e-7, points, info)
    one_p = np.zeros((1, 4, 2))
    one_i = np.zeros((1, 4), np.int64)
    for k in range(m):
        ek.solve_pairs(np.ascontiguousarray(coef[perm[k] : perm[k] + 1]), 1e8, 1e-5, 1e-9, 1e-7, one_p, one_i)
        n = one_i[0, 1]
        assert info[k].tolist() == one_i[0].tolist()
        assert points[k, :n].tolist() == one_p[0, :n].tolist()


def test_equilibria_at_many_times_equal_one_time_at_a_time() -> None:
    """The grid solved in one call and the times solved one by one, in another order, agree bit for bit."""
    model = Model(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=-0.45))
    ts = np.linspace(0.0, 2 * math.pi, 97)
    batch = _Samples(model, ts.size, 1e8, 1e-12)
    batch.add(ts)
    for k in np.random.default_rng(2).permutation(ts.size).tolist():
        e = equilibria(model, float(ts[k]))
        b = batch.equilibria(k)
        assert (e.q.tolist(), e.r.tolist(), e.types, e.at_infinity, e.n_complex) == (
            b.q.tolist(),
            b.r.tolist(),
            b.types,
            b.at_infinity,
            b.n_complex,
        )
        assert e.eigenvalues.tolist() == b.eigenvalues.tolist()


@pytest.mark.parametrize("seed", range(3))
def test_equilibria_and_their_types_match_the_reference(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    for _ in range(5):
        model = Model(Params(inertia=_random_inertia(rng), alpha=float(rng.normal()), g0=float(rng.normal())))
        for t in rng.uniform(0, 2 * math.pi, 20).tolist():
            e = equilibria(model, t)
            ref = naive_equilibria(model, t)
            assert (len(e), e.at_infinity, e.n_complex, e.degenerate) == (
                ref["q"].size,
                ref["at_infinity"],
                ref["n_complex"],
                ref["degenerate"],
            )
            np.testing.assert_allclose(e.q, ref["q"], rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(e.r, ref["r"], rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(e.eigenvalues, ref["eigenvalues"], rtol=1e-10, atol=1e-13)
            assert e.types == ref["types"]


def _random_inertia(rng: np.random.Generator) -> tuple[float, ...]:
    a = rng.normal(size=(3, 3))
    return inertia_entries(a @ a.T + 0.3 * np.eye(3))


def test_classify_matches_the_reference() -> None:
    rng = np.random.default_rng(4)
    jac = np.concatenate(
        [
            rng.normal(size=(500, 2, 2)),
            rng.integers(-2, 3, size=(500, 2, 2)).astype(float),  # exact ties: tr = 0, det = 0, tr^2 = 4 det
            np.array([[[0.0, 2.0], [-0.5, 0.0]], [[1.0, 2.0], [0.5, 1.0]], [[-1.0, 1.0], [0.0, -1.0]]]),
        ]
    )
    for rtol in (1e-12, 0.0, 1e-3):
        eig, types = classify(jac, rtol)
        for k, m in enumerate(jac.tolist()):
            (j11, j12), (j21, j22) = m
            assert eig[k].tolist() == list(_eig2(j11, j12, j21, j22))
            assert types[k] == _type(j11, j12, j21, j22, rtol)
    assert set(classify(jac)[1]) == set(TYPES)


# ---------------------------------------------------------------------------
# Tracks of the paper's scenes.


@pytest.mark.parametrize("scene", [s.id for s in list_scenes()])
def test_scene_tracks_match_the_reference(scene: str) -> None:
    """Same samples, same branches, points within 1e-10 (n_t = 120, default refinement; and a frame's)."""
    params = next(s.params for s in list_scenes() if s.id == scene)
    model = Model(params)
    for n_t, refine in ((120, None), (60, 30)):
        got = equilibrium_tracks(model, n_t=n_t, max_refine=refine)
        ref = naive_tracks(model, n_t, max_refine=refine)
        np.testing.assert_array_equal(got.sample_t, ref["sample_t"])
        np.testing.assert_array_equal(got.sample_count, ref["sample_count"])
        np.testing.assert_array_equal(got.branch, ref["branch"])
        np.testing.assert_array_equal(got.t, ref["t"])
        scale = 1.0 + np.hypot(ref["q"], ref["r"])
        assert np.all(np.abs(got.q - ref["q"]) <= 1e-10 * scale)
        assert np.all(np.abs(got.r - ref["r"]) <= 1e-10 * scale)


# ---------------------------------------------------------------------------
# Input checks.


@pytest.mark.parametrize(
    ("cq", "match"),
    [
        ([1.0, 0.0, math.nan, 1.0, 0.0, 1.0], "cq must be 6 finite"),
        ([1.0, 0.0, 0.0, math.inf, 0.0, 1.0], "cq must be 6 finite"),
        ([1.0, 0.0, 0.0], "cq must be 6 finite"),
        ("abcdef", "cq must be 6"),
    ],
)
def test_solve_conics_rejects_bad_coefficients(cq: object, match: str) -> None:
    """A NaN coefficient used to come back as 'a common factor' (degenerate): now it is named."""
    with pytest.raises(ParameterError, match=match):
        solve_conics(cq, [0.0, 1.0, 0.0, 1.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("kw", "match"),
    [({"inf_norm": 0.0}, "inf_norm"), ({"imag_tol": -1.0}, "imag_tol"), ({"dedupe_tol": math.nan}, "dedupe_tol")],
)
def test_solve_conics_rejects_bad_tolerances(kw: dict[str, float], match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        solve_conics([-1.0, 0, 0, 1, 0, 1], [-1.0, 0, 1, 0, 0, 0], **kw)


@pytest.mark.parametrize("scale", [1e20, 1e36, 1e38])
def test_points_far_out_are_found_where_they_are(scale: float) -> None:
    """Two conics through 4 known points, the plane blown up: the points come back at ``scale`` times
    their place. The resultant's roots reach 1e38: unscaled, scipy's LAPACK lost them beyond ~1e35 (fails
    with equilibria_kernels._BIG_ENTRY = inf). Beyond ~1e40 the algorithm's own limits come (underflow)."""
    rng = np.random.default_rng(8)
    for _ in range(20):
        points = rng.normal(size=(4, 2))
        cq, cr = (_transform(_through(points, rng), 0.0, (0.0, 0.0), 1.0 / scale) for _ in range(2))
        s = solve_conics(cq, cr, inf_norm=1e100)
        assert s.q.size == 4 and s.at_infinity == 0 and s.n_complex == 0
        want = sorted(map(tuple, points * scale))
        np.testing.assert_allclose(np.column_stack([s.q, s.r]), want, rtol=1e-9, atol=1e-9 * scale)


@pytest.mark.parametrize("rtol", [-1e-12, math.nan, "1e-12"])
def test_classify_rejects_a_bad_rtol(rtol: object) -> None:
    with pytest.raises(ParameterError, match="rtol must be"):
        classify(np.eye(2), rtol)  # type: ignore[arg-type]
