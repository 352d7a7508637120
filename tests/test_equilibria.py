"""Equilibria of the frozen field: closed forms from the paper, a brute-force reference, tracks."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from scipy.optimize import root

from explorer_core.analyses.equilibria import (
    TYPES,
    Equilibria,
    classify,
    count_survey,
    equilibria,
    equilibrium_tracks,
    solve_conics,
)
from explorer_core.system.model import Model
from explorer_core.system.params import ParameterError, Params, inertia_entries

PAPER_3 = (1.0, 2.0, 4.0, 0.0, 0.1, 0.0)  # [[1,0,0.1],[0,2,0],[0.1,0,4]]
PAPER_4 = (1.0, 2.0, 4.0, 0.0, 0.5, 0.3)  # [[1,0,0.5],[0,2,0.3],[0.5,0.3,4]]


def _random_params(rng: np.random.Generator) -> Params:
    a = rng.normal(size=(3, 3))
    return Params(
        inertia=inertia_entries(a @ a.T + 0.3 * np.eye(3)),
        alpha=float(rng.normal()),
        g0=float(rng.normal()),
        g1=float(rng.normal()),
        g2=float(rng.normal()),
        omega=float(rng.uniform(0.3, 3.0)),
    )


def _assert_points(e: Equilibria, expected: list[tuple[float, float]], tol: float = 1e-10) -> None:
    """The returned points are exactly ``expected`` (any order), each within ``tol (1 + |x|)``."""
    got = list(zip(e.q.tolist(), e.r.tolist(), strict=True))
    assert len(got) == len(expected), f"t={e.t}: got {got}, want {expected}"
    free = list(range(len(got)))
    for q0, r0 in expected:
        k = min(free, key=lambda i: math.hypot(got[i][0] - q0, got[i][1] - r0))
        assert math.hypot(got[k][0] - q0, got[k][1] - r0) <= tol * (1.0 + math.hypot(q0, r0)), (got, expected)
        free.remove(k)


def _rel_residual(model: Model, t: float, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """|(Q, R)| relative to the size of the field's terms (independent of the solver's own measure)."""
    c = model.coefficients(t)[:2]
    fq, fr = model.field(q, r, t)
    rho = np.hypot(q, r) + 1e-12
    scale = (
        np.abs(c[:, :1]) + np.abs(c[:, 1:3]).sum(axis=1)[:, None] * rho + np.abs(c[:, 3:]).sum(axis=1)[:, None] * rho**2
    )
    return np.maximum(np.abs(fq) / scale[0], np.abs(fr) / scale[1])


# ---------------------------------------------------------------------------
# Two critical points: diagonal tensors (paper, eqs. (sol-1), (case1-r)).

DIAGONALS = [(1.0, 2.0, 4.0), (4.0, 2.0, 1.0), (1.0, 4.0, 2.0), (4.0, 1.0, 2.0)]
T_OK = [0.0, 0.3, 1.0, 2.0, 2.5, math.pi, 3.9, 5.0, 6.0]  # |cos t| > 0.3


@pytest.mark.parametrize("diag", DIAGONALS)
def test_diagonal_has_exactly_the_two_points_of_sol1(diag: tuple[float, float, float]) -> None:
    a, b, c = diag
    alpha = 0.1
    model = Model(Params(inertia=(a, b, c, 0.0, 0.0, 0.0), alpha=alpha))
    for t in T_OK:
        g, gp = math.cos(t), -math.sin(t)
        e = equilibria(model, t)
        # (sol-1) with g' = dg/dt; the two missing intersections are at infinity.
        _assert_points(e, [(0.0, 0.0), (-alpha / g, a * gp / (b - c))])
        assert e.at_infinity == 2 and e.n_complex == 0 and not e.degenerate


def test_paper_case1r_sign_is_a_slip() -> None:
    """(case1-r) prints ``+I11 sin t / (I22 - I33)``; with g = cos t, g' = -sin t it must be ``-``."""
    model = Model(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1))
    t = 0.7
    q2 = -0.1 / math.cos(t)
    printed = (q2, 1.0 * math.sin(t) / (2.0 - 4.0))
    corrected = (q2, -1.0 * math.sin(t) / (2.0 - 4.0))
    e = equilibria(model, t)
    assert np.min(np.hypot(e.q - printed[0], e.r - printed[1])) > 0.1
    assert np.min(np.hypot(e.q - corrected[0], e.r - corrected[1])) < 1e-12
    fq, _ = model.field(*printed, t)
    assert abs(fq) > 1e-3  # the printed point is not an equilibrium


def test_diagonal_far_point_at_infinity_when_g_vanishes() -> None:
    model = Model(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1))
    e = equilibria(model, math.pi / 2)  # g = 6e-17: x2* at |q| ~ 1.6e15
    _assert_points(e, [(0.0, 0.0)])
    assert e.at_infinity == 3
    e = equilibria(model, math.pi / 2 + 1e-4)  # x2* still finite, q = -alpha/g ~ 1e3
    assert len(e) == 2 and e.q.max() == pytest.approx(-0.1 / math.cos(math.pi / 2 + 1e-4), rel=1e-9)


# ---------------------------------------------------------------------------
# Three critical points: I12 = I23 = 0.


def _three_point_closed_form(
    inertia: tuple[float, ...], alpha: float, g: float, gp: float
) -> list[tuple[float, float]]:
    """The paper's two fixed points, plus the time-dependent one derived by resultants (docs/equilibria.md)."""
    a, b, c, _, e, _ = inertia
    s = math.sqrt((a - c) ** 2 + 4 * e * e)
    fixed = [(0.0, (c - a + s) / (2 * e) * alpha), (0.0, (c - a - s) / (2 * e) * alpha)]
    k = (a - b) * (b - c) + e * e
    den = alpha * k - e * b * gp
    q3 = -(alpha**2 * k + alpha * e * (a - 2 * b + c) * gp - e * e * gp * gp) / (g * den)
    r3 = gp * (alpha * (a * (a - b) + e * e) - a * e * gp) / den
    return [*fixed, (q3, r3)]


@pytest.mark.parametrize("alpha", [0.1, -0.1, 0.4, -0.4])
def test_three_point_case_paper_tensor(alpha: float) -> None:
    model = Model(Params(inertia=PAPER_3, alpha=alpha))
    for t in np.linspace(0.05, 2 * math.pi, 23):
        g, gp = model.g(t)
        if abs(g) < 0.05:
            continue
        e = equilibria(model, t)
        _assert_points(e, _three_point_closed_form(PAPER_3, alpha, g, gp), tol=1e-9)
        assert e.at_infinity == 1


def test_three_point_case_random_tensors() -> None:
    rng = np.random.default_rng(3)
    for _ in range(10):
        a, b, c = rng.uniform(1.0, 5.0, 3)
        e13 = rng.uniform(-0.5, 0.5) * math.sqrt(a * c)
        inertia = (a, b, c, 0.0, e13, 0.0)
        params = Params(inertia=inertia, alpha=float(rng.uniform(-1, 1)), g0=float(rng.normal()), g1=1.0)
        model = Model(params)
        for t in rng.uniform(0, 2 * math.pi, 5):
            g, gp = model.g(t)
            want = [p for p in _three_point_closed_form(inertia, params.alpha, g, gp) if math.hypot(*p) < 1e6]
            _assert_points(equilibria(model, t), want, tol=1e-8)


def test_three_point_fixed_points_do_not_move() -> None:
    """The two q = 0 points are rotations about an eigenvector of I, the same for every t."""
    params = Params(inertia=PAPER_3, alpha=0.1)
    eigvec = np.linalg.eigh(params.inertia_matrix)[1]
    # Eigenvectors in the (e1, e3) plane scaled to p = alpha give (q, r) = (0, alpha v3 / v1).
    want = sorted(0.1 * v[2] / v[0] for v in eigvec.T if abs(v[1]) < 1e-12)
    model = Model(params)
    for t in (0.2, 1.0, 2.0, 4.0):
        e = equilibria(model, t)
        on_axis = sorted(e.r[np.abs(e.q) < 1e-12])
        assert on_axis == pytest.approx(want, rel=1e-12)


# ---------------------------------------------------------------------------
# General tensors: nothing is missed (independent brute-force reference).


def _brute_force(model: Model, t: float, box: float = 50.0, n: int = 9) -> list[np.ndarray]:
    """Slow reference: scipy root from a log-spaced grid of starts over [-box, box]^2."""
    axis = np.geomspace(1e-3, box, n)
    axis = np.concatenate([-axis[::-1], [0.0], axis])

    def f(x: np.ndarray) -> list[float]:
        fq, fr = model.field(x[0], x[1], t)
        return [float(fq), float(fr)]

    out = []
    for q0 in axis:
        for r0 in axis:
            x = root(f, [q0, r0], jac=lambda x: model.jacobian(x[0], x[1], t), method="hybr").x
            if np.all(np.isfinite(x)) and _rel_residual(model, t, x[0], x[1]) < 1e-10:
                out.append(x)
    return out


def _assert_nothing_missed(model: Model, t: float) -> int:
    e = equilibria(model, t)
    found = e.points
    for x in _brute_force(model, t):
        dist = np.hypot(*(found - x).T) if len(found) else np.array([np.inf])
        assert dist.min() <= 1e-6 * (1 + np.hypot(*x)), f"t={t}: missed {x}, found {found.tolist()}"
    return len(e)


def test_general_tensor_every_point_is_a_root_and_none_is_missed() -> None:
    model = Model(Params(inertia=PAPER_4, alpha=-0.45))
    counts = set()
    for t in np.linspace(0.0, 2 * math.pi, 16, endpoint=False) + 0.01:
        e = equilibria(model, t)
        assert np.all(_rel_residual(model, t, e.q, e.r) < 1e-12)
        counts.add(_assert_nothing_missed(model, t))
    assert counts == {1, 3}  # never 4 (see docs/equilibria.md)


@pytest.mark.parametrize("seed", range(4))
def test_random_tensors_and_forcing_none_missed(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = Model(_random_params(rng))
    for t in rng.uniform(0, model.params.period, 3):
        e = equilibria(model, t)
        assert np.all(_rel_residual(model, t, e.q, e.r) < 1e-12)
        _assert_nothing_missed(model, t)


def test_bezout_bookkeeping_and_common_point_at_infinity() -> None:
    """real + complex + infinite = 4 (no root silently lost), and >= 1 always at infinity."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        model = Model(_random_params(rng))
        for t in rng.uniform(0, model.params.period, 25):
            e = equilibria(model, t)
            assert len(e) + e.n_complex + e.at_infinity == 4, e.to_dict(full=True)
            assert e.at_infinity >= 1 and len(e) <= 3


def test_quadratic_parts_share_a_factor() -> None:
    """Energy identity: l1 Q2 + l3 R2 == 0, l1 = (b, I w_h), l3 = (e3, I w_h), b = (g, 1, 0), w_h = (g q, q, r)."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        params = _random_params(rng)
        model = Model(params)
        inertia = params.inertia_matrix
        t = float(rng.uniform(0, params.period))
        g, _ = model.g(t)
        c = model.coefficients(t)
        for q, r in rng.normal(size=(5, 2)):
            q2 = c[0, 3] * q * q + c[0, 4] * q * r + c[0, 5] * r * r
            r2 = c[1, 3] * q * q + c[1, 4] * q * r + c[1, 5] * r * r
            iw = inertia @ np.array([g * q, q, r])
            l1, l3 = g * iw[0] + iw[1], iw[2]
            assert abs(l1 * q2 + l3 * r2) <= 1e-12 * (abs(l1 * q2) + abs(l3 * r2) + 1e-300)
            # Explicitly: Q2 = -l3 m / k, R2 = l1 m / k, m = (a, I w_h), k = det(I) (a, I^-1 a).
            a = np.array([1.0, -g, 0.0])
            k = np.linalg.det(inertia) * (a @ np.linalg.solve(inertia, a))
            m = a @ iw
            assert q2 == pytest.approx(-l3 * m / k, rel=1e-9, abs=1e-12)
            assert r2 == pytest.approx(l1 * m / k, rel=1e-9, abs=1e-12)


def test_paper_general_tensor_counts_over_a_period() -> None:
    s = count_survey(Params(inertia=PAPER_4, alpha=-0.45), n_t=400, n_track=200)
    assert set(s["fraction"]) == {1, 3}
    assert s["at_infinity"] == (1, 1)
    assert s["fraction"][1] == pytest.approx(0.117, abs=0.01)


# ---------------------------------------------------------------------------
# Classification.

CASES = [
    ([[1.0, 0.0], [0.0, -2.0]], "saddle", [1.0, -2.0]),
    ([[-1.0, 0.0], [0.0, -3.0]], "stable node", [-1.0, -3.0]),
    ([[2.0, 1.0], [0.0, 3.0]], "unstable node", [3.0, 2.0]),
    ([[-1.0, -2.0], [2.0, -1.0]], "stable focus", [-1 + 2j, -1 - 2j]),
    ([[0.5, 3.0], [-3.0, 0.5]], "unstable focus", [0.5 + 3j, 0.5 - 3j]),
    ([[0.0, 2.0], [-0.5, 0.0]], "centre", [1j, -1j]),
    ([[1.0, 2.0], [0.5, 1.0]], "degenerate", [2.0, 0.0]),
    ([[-1.0, 1.0], [0.0, -1.0]], "stable node", [-1.0, -1.0]),  # tr^2 = 4 det
]


@pytest.mark.parametrize(("jac", "kind", "eig"), CASES)
def test_classification_by_hand(jac: list[list[float]], kind: str, eig: list[complex]) -> None:
    e, types = classify(np.array([jac]))
    assert types == (kind,)
    assert e[0] == pytest.approx(np.array(eig, dtype=complex), abs=1e-14)
    assert kind in TYPES


def test_diagonal_origin_is_a_centre_when_gprime_vanishes() -> None:
    """At t = 0: J(0) = [[0, -alpha (A - C) / D], [alpha (A - B) / C, 0]], D = A g^2 + B."""
    a, b, c, alpha = 1.0, 2.0, 4.0, 0.1
    e = equilibria(Model(Params(inertia=(a, b, c, 0, 0, 0), alpha=alpha)), 0.0)
    i = int(np.argmin(np.hypot(e.q, e.r)))
    det = -(-alpha * (a - c) / (a + b)) * (alpha * (a - b) / c)
    assert e.types[i] == "centre"
    assert e.eigenvalues[i] == pytest.approx([1j * math.sqrt(det), -1j * math.sqrt(det)], abs=1e-14)
    # The other point (-alpha, 0) at t = 0: J = [[0, -alpha (B - C) / D], [-alpha (A - B) / C, 0]]: a saddle.
    assert e.types[1 - i] == "saddle"


# ---------------------------------------------------------------------------
# Degenerate input, JSON, bad input, speed.


def test_alpha_zero_diagonal_is_degenerate() -> None:
    e = equilibria(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.0), 0.5)
    assert e.degenerate and len(e) == 0 and "common factor" in e.message
    assert e.to_dict() == {"t": 0.5, "equilibria": []}
    assert e.to_dict(full=True)["degenerate"] is True


def test_alpha_zero_general_tensor_at_gprime_zero_is_degenerate() -> None:
    """alpha = 0 and g' = 0: Q and R are both multiples of the common linear factor of their quadratic parts."""
    model = Model(Params(inertia=PAPER_4, alpha=0.0))
    assert equilibria(model, 0.0).degenerate
    e = equilibria(model, 1.0)
    assert not e.degenerate and np.min(np.hypot(e.q, e.r)) < 1e-14  # the origin is always at rest


def test_solve_conics_common_component_and_constant() -> None:
    # Q = q r, R = q^2 + q: share the line q = 0.
    assert solve_conics([0, 0, 0, 0, 1, 0], [0, 1, 0, 1, 0, 0]).degenerate
    # Q = 1 (no zeros).
    s = solve_conics([1, 0, 0, 0, 0, 0], [0, 1, 0, 1, 0, 0])
    assert not s.degenerate and s.q.size == 0
    # Two circles meeting at (0, 0) and (1, 1) tangentially? No: two transversal points.
    s = solve_conics([0, -2, 0, 1, 0, 1], [0, 0, -2, 1, 0, 1])  # (q-1)^2+r^2=1, q^2+(r-1)^2=1
    assert sorted(zip(s.q.round(12).tolist(), s.r.round(12).tolist(), strict=True)) == [(0.0, 0.0), (1.0, 1.0)]
    assert s.n_complex == 0 and s.at_infinity == 2  # the circular points at infinity


def test_solve_conics_tangency_gives_one_double_point() -> None:
    # Circle q^2 + r^2 = 1 and the line r = 1 (as a conic): tangent at (0, 1).
    s = solve_conics([-1, 0, 0, 1, 0, 1], [-1, 0, 1, 0, 0, 0])
    assert s.q.size == 1 and s.q[0] == pytest.approx(0.0, abs=1e-7) and s.r[0] == pytest.approx(1.0)


def test_to_dict_shape() -> None:
    e = equilibria(Model(Params(inertia=PAPER_4, alpha=-0.45)), 1.0)
    d = json.loads(json.dumps(e.to_dict()))
    assert set(d) == {"t", "equilibria"} and d["t"] == 1.0
    assert len(d["equilibria"]) == len(e) == 3
    for item, q, z in zip(d["equilibria"], e.q, e.eigenvalues, strict=True):
        assert set(item) == {"q", "r", "eigenvalues", "type"}
        assert item["q"] == q and item["type"] in TYPES
        assert item["eigenvalues"] == [[z[0].real, z[0].imag], [z[1].real, z[1].imag]]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, "abc", None])
def test_bad_t_raises(bad: object) -> None:
    with pytest.raises(ParameterError, match="t must be"):
        equilibria(Params(), bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [1, 0, -5, 10**7, 2.5, True])
def test_bad_n_t_raises(bad: object) -> None:
    with pytest.raises(ParameterError, match=rf"n_t .*{bad!r}"):
        equilibrium_tracks(Params(), n_t=bad)  # type: ignore[arg-type]


def test_bad_t_start_and_model_raise() -> None:
    with pytest.raises(ParameterError, match="t_start must be finite"):
        equilibrium_tracks(Params(), n_t=10, t_start=math.nan)
    with pytest.raises(ParameterError, match="Model or Params"):
        equilibria("diag", 0.0)  # type: ignore[arg-type]


def test_equilibria_is_fast() -> None:
    import time

    model = Model(Params(inertia=PAPER_4, alpha=-0.45))
    equilibria(model, 0.0)
    ts = np.linspace(0, 2 * math.pi, 300)
    t0 = time.perf_counter()
    for t in ts:
        equilibria(model, t)
    assert (time.perf_counter() - t0) / ts.size < 2e-3  # typically ~0.12 ms


# ---------------------------------------------------------------------------
# Tracks.


def _compact(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    x = np.column_stack([q, r])
    return x / (1.0 + np.hypot(q, r))[:, None]


@pytest.mark.parametrize(
    ("inertia", "alpha"),
    [((1.0, 2.0, 4.0, 0.0, 0.0, 0.0), 0.1), (PAPER_3, 0.1), (PAPER_4, -0.45), (PAPER_4, -0.05)],
)
def test_tracks_are_continuous_and_match_equilibria(inertia: tuple[float, ...], alpha: float) -> None:
    model = Model(Params(inertia=inertia, alpha=alpha))
    tr = equilibrium_tracks(model, n_t=300)
    assert np.all(np.diff(tr.sample_t) > 0) and tr.sample_t[0] == 0.0 and tr.sample_t[-1] == 2 * math.pi
    for b in tr.branches():
        assert np.all(np.diff(b["t"]) > 0)
        # Continuity on the compactified plane; never an antipodal (through infinity) jump.
        jumps = np.hypot(*np.diff(_compact(b["q"], b["r"]), axis=0).T)
        assert np.all(jumps <= 0.5)
        assert np.mean(jumps <= 0.05) > 0.99
        # Near the origin continuity in the plain sense.
        small = (np.hypot(b["q"], b["r"]) < 1.0)[:-1] & (np.hypot(b["q"], b["r"]) < 1.0)[1:]
        assert np.all(np.hypot(np.diff(b["q"]), np.diff(b["r"]))[small] <= 0.05 * 4)
    # Every sample's rows are exactly equilibria() there.
    for t, n in zip(tr.sample_t[::7], tr.sample_count[::7], strict=True):
        rows = tr.rows_at(t)
        e = equilibria(model, float(t))
        assert len(rows) == n == len(e)
        assert sorted(zip(tr.q[rows], tr.r[rows], strict=True)) == sorted(zip(e.q, e.r, strict=True))
    assert tr.branch.size == tr.sample_count.sum()


def test_diagonal_far_branch_is_cut_at_g_zero() -> None:
    model = Model(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1))
    # Offset start: no sample lands exactly on g = 0, so the cut must come from the matching.
    tr = equilibrium_tracks(model, n_t=401, t_start=0.1234)
    for b in tr.branches():
        q = b["q"]
        # no segment joins q >> 0 to q << 0
        assert not np.any((q[:-1] > 1.0) & (q[1:] < -1.0)) and not np.any((q[:-1] < -1.0) & (q[1:] > 1.0))
        g = np.cos(b["t"])
        assert np.all(g > 0) or np.all(g < 0) or np.all(np.abs(q) < 1e-12), "a branch crosses g = 0"
    # The origin is one branch over the whole period; x2* is cut twice: 4 branches.
    assert tr.n_branches == 4
    ends = sorted(float(b["t"][-1]) for b in tr.branches() if b["t"][-1] < tr.t_start + 2 * math.pi)
    assert ends == pytest.approx([math.pi / 2, 3 * math.pi / 2], abs=1e-4)


def test_tracks_pair_death_ends_two_branches_together() -> None:
    model = Model(Params(inertia=PAPER_4, alpha=-0.45))
    tr = equilibrium_tracks(model, n_t=300)
    finite_ends = [
        (float(b["t"][-1]), b["q"][-1], b["r"][-1])
        for b in tr.branches()
        if b["t"][-1] < 2 * math.pi and math.hypot(b["q"][-1], b["r"][-1]) < 10.0
    ]
    assert len(finite_ends) == 2  # the pair dying at t ~ 3.934
    (t1, q1, r1), (t2, q2, r2) = finite_ends
    assert t1 == t2 == pytest.approx(3.9336, abs=1e-3)
    assert math.hypot(q1 - q2, r1 - r2) < 1e-2


def test_tracks_csv_and_section(tmp_path) -> None:
    params = Params(inertia=PAPER_4, alpha=-0.45, t0=0.3)
    tr = equilibrium_tracks(params, n_t=50)
    assert tr.t_start == 0.3 and tr.sample_t[-1] == pytest.approx(0.3 + 2 * math.pi)
    path = tmp_path / "tracks.csv"
    tr.to_csv(path)
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["branch", "t", "q", "r", "type", "eig1_re", "eig1_im", "eig2_re", "eig2_im"]
    assert len(rows) == 1 + tr.branch.size
    first = rows[1]
    assert int(first[0]) == tr.branch[0] and float(first[2]) == tr.q[0] and first[4] == tr.types[0]
    summary = json.loads(json.dumps(tr.summary()))
    assert summary["n_branches"] == tr.n_branches == len(summary["branches"])
    assert sum(summary["count_samples"].values()) == tr.sample_t.size
    sec = tr.section()
    assert sec.t == 0.3
    rows0 = tr.rows_at(tr.t_start)
    assert sorted(tr.q[rows0].tolist()) == sorted(sec.q.tolist())


def test_tracks_speed() -> None:
    import time

    model = Model(Params(inertia=PAPER_4, alpha=-0.45))
    equilibrium_tracks(model, n_t=20)
    t0 = time.perf_counter()
    equilibrium_tracks(model, n_t=1000)
    assert time.perf_counter() - t0 < 2.0  # typically ~0.2 s


def test_cancelled_tracks_return_what_was_computed_marked_incomplete() -> None:
    # Cancelling never raises: the tracks of the start of the period come back, and the rest is a loss.
    params = Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.0, 0.0), alpha=0.1)
    full = equilibrium_tracks(params, n_t=40)
    assert full.completed and full.lost == ()
    polls = []
    part = equilibrium_tracks(params, n_t=40, cancel=lambda: polls.append(1) or len(polls) > 10)
    assert not part.completed and len(part.lost) == 1
    assert part.lost[0].count == 40 - 1 - 10 and "cancelled" in part.lost[0].why
    assert part.t.size and part.t.max() < full.t.max()
    early = full.t <= part.t.max()
    np.testing.assert_allclose(np.sort(part.q), np.sort(full.q[early]))
