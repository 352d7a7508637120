"""The scene's own field: the kernels compute and evaluate only the monomials a scene's structure holds.

The form (:data:`explorer_core.system.model.FORM_MASKS`) is read off the coefficient tables' exact zeros; the
specialised evaluation must equal sympy's field from scratch and the general evaluation, and trajectories must
agree with ``solve_ivp`` on the naive field (``tests/naive.py``). Near-zero entries (1e-300) are terms.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from naive import NaiveField, complex_step_jacobian, solve_ivp_section
from test_model import _random_spd, _sympy_field

from explorer_core.solve import rk
from explorer_core.solve.integrators import Batch, coefficients, run, tables
from explorer_core.system.model import (
    DIAGONAL,
    DIAGONAL_HOMOGENEOUS,
    FORM_MASKS,
    GENERAL,
    HOMOGENEOUS,
    Model,
    field_form,
    form_coefficients,
    form_gradient,
    form_value,
    quadratic,
)
from explorer_core.system.params import Params

FORMS = (GENERAL, HOMOGENEOUS, DIAGONAL, DIAGONAL_HOMOGENEOUS)


def _form(params: Params) -> int:
    m = Model(params)
    return field_form(m.num, m.gpc)


@pytest.mark.parametrize(
    ("inertia", "alpha", "form"),
    [
        ((1.0, 4.0, 2.0, 0.0, 0.0, 0.0), 0.1, DIAGONAL),
        ((1.0, 4.0, 2.0, 0.0, 0.0, 0.0), 0.0, DIAGONAL_HOMOGENEOUS),
        ((1.0, 2.0, 4.0, 0.0, 0.5, 0.3), 0.0, HOMOGENEOUS),
        ((1.0, 2.0, 4.0, 0.0, 0.5, 0.3), -0.45, GENERAL),
        ((1.0, 4.0, 2.0, 0.2, 0.0, 0.0), 0.1, GENERAL),  # I12 alone gives R a constant term
        # near-zero entries are terms: never the diagonal form
        ((1.0, 4.0, 2.0, 1e-300, 0.0, 0.0), 0.1, GENERAL),
        ((1.0, 4.0, 2.0, 0.0, 0.0, 1e-300), 0.0, HOMOGENEOUS),
        ((1.0, 4.0, 2.0, 0.0, 0.0, 0.0), 1e-300, DIAGONAL),
    ],
)
def test_form_of_a_structure(inertia: tuple[float, ...], alpha: float, form: int) -> None:
    params = Params(inertia=inertia, alpha=alpha)
    assert _form(params) == form
    # the engine's tables take the form the model caches with its tables: the same
    assert coefficients(Model(params), n=1).form == form
    other = Model(Params(inertia=inertia, alpha=0.0))
    assert coefficients([Model(params), other], np.array([0, 1])).form == field_form(
        np.stack([Model(params).num, other.num]), np.stack([Model(params).gpc, other.gpc])
    )


def test_form_of_stacked_tables_holds_every_row() -> None:
    diag = Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.0))
    gen = Model(Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=0.0))
    co = coefficients([diag, gen], np.array([0, 1]))
    assert co.form == HOMOGENEOUS
    assert coefficients(diag, n=3).form == DIAGONAL_HOMOGENEOUS
    # a table entry that is NaN is not zero
    num = diag.num.copy()
    num[0, 0, 0] = math.nan
    assert field_form(num, diag.gpc) == GENERAL


def _random_structure(rng: np.random.Generator) -> Params:
    """A random tensor with random zero off-diagonal entries, alpha and forcing terms zero or not (1e-300 entries,
    which sympy's exact rationals make very slow, are tested by their form and by a trajectory below)."""
    entries = list(_random_spd(rng))
    for j in (3, 4, 5):
        u = rng.uniform()
        entries[j] = 0.0 if u < 0.5 else entries[j]
    # keep it positive definite after zeroing: a strong diagonal
    for j in (0, 1, 2):
        entries[j] = abs(entries[j]) + 3.0 * sum(abs(x) for x in entries[3:])
    pick = lambda v: 0.0 if rng.uniform() < 0.4 else v  # noqa: E731
    return Params(
        inertia=tuple(entries),
        alpha=pick(float(rng.normal())),
        g0=pick(float(rng.normal())),
        g1=float(rng.normal()),
        g2=pick(float(rng.normal())),
        omega=float(rng.uniform(0.3, 3.0)),
    )


def _field_in_form(model: Model, form: int, q: float, r: float, t: float) -> tuple[float, float, np.ndarray]:
    """``Q, R`` and the Jacobian by the kernels' pieces in ``form`` (coefficients the form leaves unset are NaN)."""
    g, gp = model.g(t)
    out = np.full((1, 2, 6), np.nan)
    form_coefficients(form, model.num[None, :2].copy(), model.gpc[None, :2].copy(), model.den[None].copy(), 0, g, gp,
                      out, 0)  # fmt: skip
    vals, jac = [], np.empty((2, 2))
    for row in range(2):
        c = out[0, row]
        vals.append(form_value(form, row, *c, q, r))
        jac[row] = form_gradient(form, row, *c, q, r)
    return vals[0], vals[1], jac


@pytest.mark.parametrize("seed", range(5))
def test_form_field_matches_sympy_and_the_general_evaluation(seed: int) -> None:
    """Random structures: the form's field against sympy's from scratch, its Jacobian against the naive field's
    complex-step derivative, and both against the general evaluation (to rounding)."""
    rng = np.random.default_rng(100 + seed)
    params = _random_structure(rng)
    model = Model(params)
    form = field_form(model.num, model.gpc)
    (q, r, t), qe, re_, *_ = _sympy_field(params)
    f = sp.lambdify((q, r, t), [qe, re_], "math")
    naive = NaiveField(params)
    for _ in range(6):
        qv, rv, tv = rng.normal(scale=2.0, size=3)
        qs, rs = f(qv, rv, tv)
        qf, rf, jf = _field_in_form(model, form, qv, rv, tv)
        qg, rg, jg = _field_in_form(model, GENERAL, qv, rv, tv)
        scale = (1.0 + abs(qv) + abs(rv)) ** 2
        assert qf == pytest.approx(qs, rel=1e-9, abs=1e-9 * scale)
        assert rf == pytest.approx(rs, rel=1e-9, abs=1e-9 * scale)
        np.testing.assert_allclose(jf, complex_step_jacobian(naive, tv, qv, rv), rtol=1e-9, atol=1e-9 * scale)
        # the form's sums are the general sums without their zero terms
        assert qf == pytest.approx(qg, rel=1e-14, abs=1e-300)
        assert rf == pytest.approx(rg, rel=1e-14, abs=1e-300)
        np.testing.assert_allclose(jf, jg, rtol=1e-14, atol=1e-300)


@pytest.mark.parametrize("form", FORMS)
def test_each_form_drops_only_its_zero_monomials(form: int) -> None:
    """With random coefficients on the form's monomials and zeros elsewhere, the form's value and gradient are
    the general quadratic's (a form that dropped a live monomial or kept a wrong one fails)."""
    rng = np.random.default_rng(form)
    for row in range(2):
        mask = FORM_MASKS[form][row]
        for _ in range(20):
            c = np.where([(mask >> m) & 1 for m in range(6)], rng.normal(size=6), 0.0)
            q, r = rng.normal(scale=3.0, size=2)
            assert form_value(form, row, *c, q, r) == pytest.approx(quadratic(*c, q, r), rel=1e-14, abs=1e-14)
            dq = c[1] + 2.0 * c[3] * q + c[4] * r
            dr = c[2] + c[4] * q + 2.0 * c[5] * r
            np.testing.assert_allclose(form_gradient(form, row, *c, q, r), (dq, dr), rtol=1e-14, atol=1e-14)


def _run(system: int, co: rk.Coefficients, ics: np.ndarray, periods: int, block: int, **kw) -> Batch:
    y = np.zeros((ics.shape[0], rk.STATE_SIZE[system]))
    y[:, :2] = ics
    if system in (rk.TANGENT, rk.LYAPUNOV):
        y[:, 2] = y[:, 5] = 1.0
    if system == rk.BODY:
        y[:, 2] = 1.0
    n = ics.shape[0]
    b = Batch(y, np.zeros(n), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), 0, 0.0, 2 * math.pi)
    run(system, co, b, periods, workers=1, block=block, samples=4 if system == rk.BODY else 1, **kw)
    return b


@pytest.mark.parametrize("system", [rk.FIELD, rk.TANGENT, rk.LYAPUNOV, rk.BODY])
@pytest.mark.parametrize("alpha", [0.1, 0.0])
def test_specialised_kernels_equal_the_general_one(system: int, alpha: float) -> None:
    """The engine in the scene's form against the same engine told the field is general: shared tables and a
    parameter set per member, blocks of one and lock-step blocks."""
    ics = np.array([[0.3, -0.2], [-0.5, 0.4], [0.1, 0.8], [0.6, 0.1], [-0.2, -0.7]])
    shared = coefficients(Model(Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=alpha)), n=ics.shape[0])
    own = coefficients([Model(Params(inertia=(1.0 + 0.1 * i, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=alpha))
                        for i in range(ics.shape[0])], np.arange(ics.shape[0]))  # fmt: skip
    expected = DIAGONAL if alpha else DIAGONAL_HOMOGENEOUS
    for co in (shared, own):
        assert co.form == expected
        for block in (1, 4):
            a = _run(system, co, ics, 3, block, method="dop853", rtol=1e-11, atol=1e-11)
            b = _run(system, co._replace(form=GENERAL), ics, 3, block, method="dop853", rtol=1e-11, atol=1e-11)
            assert np.all(a.status == 0)
            np.testing.assert_allclose(a.y, b.y, rtol=1e-14, atol=1e-14)
            np.testing.assert_array_equal(a.nsteps, b.nsteps)


@pytest.mark.parametrize("system", [rk.FIELD, rk.TANGENT])
def test_members_own_tables_equal_each_model_alone(system: int) -> None:
    """A block with a parameter set per member (the members' tables copied into the block, coefficients computed
    over the members at once) against each model run alone: fixed steps, so the same steps, the same numbers.
    Blocks of one member with a parameter set each (charts, Newton) take each member's set straight from the
    tables, as a model alone does: the same numbers bit for bit, adaptive steps too."""
    ics = np.array([[0.3, -0.2], [-0.5, 0.4], [0.1, 0.8], [0.6, 0.1], [-0.2, -0.7], [0.2, 0.2]])
    params = [Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=a, g0=0.1 * i, g2=0.05 * i)
              for i, a in enumerate(np.linspace(-0.42, -0.35, ics.shape[0]))]  # fmt: skip
    models = [Model(p) for p in params]
    own = coefficients(models, np.arange(len(models)))
    kw = dict(method="dop853", adaptive=False, steps_per_period=64)
    adaptive = dict(method="dop853", rtol=1e-10, atol=1e-10)
    together = _run(system, own, ics, 3, 8, **kw)
    ones = _run(system, own, ics, 3, 1, **adaptive)
    for i, m in enumerate(models):
        alone = _run(system, coefficients(m, n=1), ics[i : i + 1], 3, 1, **kw)
        np.testing.assert_allclose(together.y[i], alone.y[0], rtol=1e-14, atol=1e-15)
        alone = _run(system, coefficients(m, n=1), ics[i : i + 1], 3, 1, **adaptive)
        np.testing.assert_array_equal(ones.y[i], alone.y[0])
        assert ones.nsteps[i] == alone.nsteps[0]


@pytest.mark.parametrize(
    "params",
    [
        Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.1),
        Params(inertia=(1.0, 4.0, 2.0, 0.0, 0.0, 0.0), alpha=0.0, g0=0.2, g2=0.3),
        Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=0.0),
        Params(inertia=(1.0, 2.0, 4.0, 0.0, 0.5, 0.3), alpha=-0.37),
    ],
)
def test_agrees_with_solve_ivp(params: Params) -> None:
    """Three periods at a tight tolerance against scipy's DOP853 on the naive field (no tables, no kernels)."""
    ics = np.array([[0.3, -0.2], [-0.5, 0.4]])
    model = Model(params)
    assert field_form(model.num, model.gpc) != GENERAL or params.alpha != 0.0
    b = Batch.start(ics, params.t0, params.period)
    pts, _ = run(rk.FIELD, coefficients(model, n=2), b, 3, method="vern9", rtol=1e-15, atol=1e-15, workers=1, block=1)
    for i in range(2):
        ref = solve_ivp_section(params, ics[i], 3, rtol=2.3e-14, atol=1e-15)  # (scipy's smallest rtol)
        # relative to the trajectory's size: 1e-13
        assert np.max(np.abs(pts[i] - ref)) <= 1e-13 * np.max(np.abs(ref))


def test_a_tiny_entry_is_a_term() -> None:
    """``Q = 1e-300`` (the constant monomial, outside every diagonal form) moves ``q`` by ``1e-300 T`` per period:
    dropped as a zero it would not move at all."""
    num = np.zeros((3, 6, 5))
    num[0, 0, 0] = 1e-300  # Q = 1e-300
    num[1, 4, 0] = 1.0  # R = q r (a diagonal-form monomial)
    gpc = np.zeros((3, 2))
    den = np.array([1.0, 0.0, 0.0])
    forcing = np.array([0.0, 1.0, 0.0, 1.0])
    for stacked in (False, True):
        if stacked:
            co = tables(np.stack([num, num]), np.stack([gpc, gpc]), np.stack([den, den]), np.stack([forcing, forcing]),
                        np.array([0, 1]), stacked=True)  # fmt: skip
        else:
            co = tables(num, gpc, den, forcing, np.zeros(2, dtype=np.int64))
        assert co.form == GENERAL
        b = Batch.start(np.zeros((2, 2)), 0.0, 2 * math.pi)
        run(rk.FIELD, co, b, 1, method="rk4", adaptive=False, steps_per_period=8, workers=1, block=2)
        np.testing.assert_allclose(b.y[:, 0], 2 * math.pi * 1e-300, rtol=1e-12)
