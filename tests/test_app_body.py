"""The body in 3-D in the app (issue 23, item 3): the series shipped once round-trips, the toggle is in the URL,
the job is cancellable and runs off the event loop, what is on screen is always the state's (a new selection, a
parameter or closing the view drop the series), the body starts at the selected trajectory's own section point
and its periods' points are that trajectory's points, and the orientation matches an independent integration."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from jobs import Jobs
from scipy.integrate import solve_ivp

from app.bodyview import PERIODS, SAMPLES, decode_series, encode_series, payload_bytes
from app.page import Page
from app.runner import WARM
from app.state import parse_query, state_from_query
from explorer_core.analyses.body import body_series
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import Params


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


BASE = {"scene": "fig1C", "n": "4", "periods": "60", "tracks": "0", "tprime": "off", "orbits": "0",
        "accuracy": "high", "body": "1"}  # fmt: skip


def page_for(query: dict[str, str] | None = None) -> tuple[Page, Jobs, list[dict[str, Any]]]:
    jobs = Jobs()
    page = Page({**BASE, **(query or {})}, lambda fn: fn(), executor=jobs)
    shipped: list[dict[str, Any]] = []
    ship = page.body._ship
    page.body._ship = lambda payload: (shipped.append(payload), ship(payload))  # type: ignore[method-assign]
    page.start()
    jobs.drain()
    return page, jobs, shipped


# --- an independent reference: the naive 3x3 Lagrange-d'Alembert field with R' = R [omega]_x -------------------


def ivp_orientation(params: Params, ic: tuple[float, float], periods: int) -> tuple[np.ndarray, np.ndarray]:
    """(q, r) and the rotation body -> space after each of ``periods`` periods from ``ic`` at ``t0`` (R = 1 there),
    by scipy's DOP853 at 1e-12 on I w' = (I w) x w + lambda a (PHYSICS.md), term by term."""
    inertia = params.inertia_matrix
    minv = np.linalg.inv(inertia)

    def g(t: float) -> tuple[float, float]:
        w = params.omega
        return (params.g0 + params.g1 * math.cos(w * t) + params.g2 * math.sin(w * t),
                w * (params.g2 * math.cos(w * t) - params.g1 * math.sin(w * t)))  # fmt: skip

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        q, r = y[0], y[1]
        gt, gp = g(t)
        om = np.array([params.alpha + gt * q, q, r])
        a = np.array([1.0, -gt, 0.0])
        euler = minv @ np.cross(inertia @ om, om)
        lam = (-(a @ euler) + gp * q) / (a @ minv @ a)
        wd = euler + lam * (minv @ a)
        hat = np.array([[0.0, -om[2], om[1]], [om[2], 0.0, -om[0]], [-om[1], om[0], 0.0]])
        return np.concatenate([[wd[1], wd[2]], (y[2:].reshape(3, 3) @ hat).ravel()])

    t_eval = params.t0 + params.period * np.arange(1, periods + 1)
    sol = solve_ivp(rhs, (params.t0, t_eval[-1]), np.concatenate([ic, np.eye(3).ravel()]), method="DOP853",
                    rtol=1e-12, atol=1e-12, t_eval=t_eval)  # fmt: skip
    assert sol.success, sol.message
    return sol.y[:2].T, sol.y[2:].T.reshape(-1, 3, 3)


def rotation_of(quaternion: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])  # fmt: skip


# --- the shipping format ------------------------------------------------------------------------------------------


def test_the_shipped_series_round_trips_as_float32_and_is_small() -> None:
    params = state_from_query({"scene": "fig1C"})[0].system()
    series = body_series(params, np.array([0.3, 1.2]), PERIODS, samples=SAMPLES,
                         numerics=Numerics(method="dop853", rtol=1e-10, atol=1e-10))  # fmt: skip
    payload = encode_series(series, k_start=480)
    text = json.dumps(payload, allow_nan=False)  # plain JSON: numbers as numbers, arrays as base64 text
    meta = json.dumps({k: v for k, v in payload.items() if k not in ("t", "omega", "quaternion", "energy")})
    assert "np." not in meta and "float" not in meta
    back = decode_series(json.loads(text))
    frames = series.t.size
    assert back["frames"] == frames == PERIODS * SAMPLES + 1
    for key in ("omega", "quaternion", "energy"):
        exact = np.asarray(getattr(series, key)).reshape(back[key].shape)
        assert np.array_equal(back[key], exact.astype(np.float32)), key  # float32, bit for bit
        assert np.max(np.abs(back[key] - exact)) <= 1e-6 * max(1.0, np.max(np.abs(exact)))
    # t: the series' start as a number (float32 would lose a late time), the frames' offsets in float32
    assert back["t"][0] == pytest.approx(series.t[0] + 480 * params.period, abs=0)
    assert np.max(np.abs(back["t"] - (series.t + 480 * params.period))) < 1e-5
    assert np.array_equal(back["axes"], series.axes) and np.array_equal(back["moments"], series.moments)
    assert np.array_equal(back["box_sides"], series.box_sides())
    assert back["complete"] is True and back["lost"] == [] and back["status"] == "ok"
    assert payload_bytes(payload) < 1_000_000
    assert 40_000 < payload_bytes(payload) < 60_000  # 961 frames x 9 float32 in base64, and the rest


# --- the URL ----------------------------------------------------------------------------------------------


def test_the_body_view_toggle_is_in_the_url() -> None:
    assert state_from_query({"scene": "fig1C", "body": "1"})[0].show_body is True
    st = state_from_query({"scene": "fig1C"})[0]
    assert st.show_body is False and "body" not in st.to_query()  # written only when open
    st.show_body = True
    assert st.to_query()["body"] == "1"
    assert state_from_query(st.to_query())[0].show_body is True
    _, errors = parse_query({"body": "yes"})
    assert errors == ["URL parameter body: Body in 3-D must be true or false, got 'yes'"]
    assert state_from_query({"body": "1", "present": "1"})[0].presentation  # in presentation mode too


def test_the_body_views_settings_round_trip_through_the_url() -> None:
    # A box has the moments of the scene's system only after I33 = 3 (1, 3, 4 break the triangle inequality; 1, 3, 3
    # do not): fig1C's 1, 4, 2 has none.
    q = {"scene": "fig1C", "body": "1", "body_v": "2", "body_axis": "1", "body_shape": "ellipsoid"}
    st, errors = state_from_query(q)
    assert errors == [] and (st.body_speed, st.body_axis, st.body_shape) == ("2", "1", "ellipsoid")
    back = st.to_query()
    assert {k: back[k] for k in ("body_v", "body_axis", "body_shape")} == {k: q[k] for k in ("body_v", "body_axis",
                                                                                           "body_shape")}  # fmt: skip
    assert state_from_query(back)[0].to_query() == back
    box = {"scene": "custom", "I11": "2", "I22": "3", "I33": "4", "body": "1", "body_shape": "box"}
    st, errors = state_from_query(box)
    assert errors == [] and st.display("body_shape") == "box"
    assert "body_shape" not in st.to_query()  # a new page's: not written
    # Written only while the view is open (closed, they are not in use) and when not a new page's.
    st, _ = state_from_query({"scene": "fig1C", "body_v": "2", "body_axis": "1"})
    assert (st.body_speed, st.body_axis) == ("2", "1") and not {"body_v", "body_axis"} & set(st.to_query())
    st.show_body = True
    assert st.to_query()["body_v"] == "2" and st.to_query()["body_axis"] == "1"


def test_bad_body_settings_in_the_url_are_refused_naming_the_value() -> None:
    _, errors = parse_query({"body_v": "3", "body_axis": "0", "body_shape": "cube"})
    assert errors == [
        "URL parameter body_v: Body: speed must be one of 0.05, 0.1, 0.25, 0.5, 1, 2, 4, got '3'",
        "URL parameter body_axis: Body: axis traced must be one of 1, 2, 3, got '0'",
        "URL parameter body_shape: Body: drawn as must be one of box, ellipsoid, got 'cube'",
    ]
    # The paper's tensors (1, 2, 4 in some order) belong to no box: 'box' is refused, the ellipsoid is what is drawn
    # and shown (and what a link without the key draws: it is not written).
    st, errors = state_from_query({"scene": "fig1C", "body": "1", "body_shape": "box"})
    assert errors == ["URL parameter body_shape: Body: drawn as = box: no uniform box has the principal moments 1, 2, "
                      "4 (a box needs I3 < I1 + I2); using Body: drawn as = ellipsoid"]  # fmt: skip
    assert st.display("body_shape") == "ellipsoid" and "body_shape" not in st.to_query()
    assert state_from_query(st.to_query())[0].display("body_shape") == "ellipsoid"


def test_a_body_setting_chosen_is_in_use_shown_and_published_and_a_box_without_a_body_is_refused() -> None:
    urls: list[dict[str, str]] = []
    jobs = Jobs()
    page = Page(dict(BASE), lambda fn: fn(), executor=jobs, publish_url=urls.append)
    page.start()
    jobs.drain()
    assert page.ui.values["body_shape"] == "ellipsoid"  # fig1C: no box has its moments
    assert page.commit("body_speed", "1") is None and page.ui.values["body_speed"] == "1"
    assert urls[-1]["body_v"] == "1"
    assert page.commit("body_axis", "2") is None and urls[-1]["body_axis"] == "2"
    problem = page.commit("body_shape", "box")
    assert problem == ("Body: drawn as = box: no uniform box has the principal moments 1, 2, 4 (a box needs I3 < I1 + "
                       "I2) — still using Body: drawn as = ellipsoid")  # fmt: skip
    assert page.ui.values["body_shape"] == "ellipsoid" and page.ui.messages["body_shape"] == problem
    # A system with a box: the box is drawn (a new page's choice), and the URL says nothing about it.
    for name, v in (("I22", "3"), ("I33", "3")):
        assert page.commit(name, v) is None
    jobs.drain()
    assert page.ui.values["body_shape"] == "box" and "body_shape" not in urls[-1]
    assert page.commit("body_shape", "ellipsoid") is None and urls[-1]["body_shape"] == "ellipsoid"
    page.show_tour("fig8B", 1)  # a tour's step starts from a new page's settings
    assert (page.state.body_speed, page.state.body_axis, page.state.body_shape) == ("0.25", "3", "box")


def test_the_toggle_publishes_the_url_and_a_tour_step_closes_the_view() -> None:
    urls: list[dict[str, str]] = []
    jobs = Jobs()
    page = Page({**BASE, "body": "0"}, lambda fn: fn(), executor=jobs, publish_url=urls.append)
    page.start()
    jobs.drain()
    assert page.commit("show_body", True) is None
    assert urls[-1]["body"] == "1"
    page.show_tour("fig8B", 1)  # each step stands alone: the view as on a new page
    assert page.state.show_body is False


# --- the wiring -------------------------------------------------------------------------------------------------


def selected_points(page: Page) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    traj, k, q, r = page.session.data()
    sel = traj == page.state.selected
    order = np.argsort(k[sel])
    return k[sel][order], q[sel][order], r[sel][order]


def test_the_body_starts_at_the_selected_trajectorys_point_and_its_periods_are_that_trajectorys_points() -> None:
    page, _, shipped = page_for()
    ks, qs, rs = selected_points(page)
    got = decode_series(page.ui.body)
    assert len(shipped) == 1 and got["frames"] == PERIODS * SAMPLES + 1  # shipped once
    assert got["k0"] == ks[-1] - PERIODS  # the last 20 periods on screen
    at = got["omega"][:: got["samples"], 1:]  # (q, r) at the start of each period: points of the map
    np.testing.assert_allclose(at[:, 0], qs[-PERIODS - 1 :], atol=1e-6)
    np.testing.assert_allclose(at[:, 1], rs[-PERIODS - 1 :], atol=1e-6)
    period = page.state.system().period
    assert got["t"][0] == pytest.approx(page.state.t0 + got["k0"] * period)
    view = page.ui.view["section"]["body"]
    assert view["open"] and f"k = {got['k0']}..{ks[-1]}" in view["status"] and not view["lost"]
    assert page.fig.fig.select_one({"name": "body_point"}) is not None  # the highlighted point's glyph


def test_the_series_does_not_depend_on_the_transient_or_the_periods_before_it() -> None:
    # The same last 20 periods of the same trajectory (k = 61..80), shown after 80 periods or after a transient
    # of 40 and 40 periods: the same body (the series starts from the point on screen, not from t0).
    a, _, _ = page_for({"periods": "80", "transient": "0"})
    b, _, _ = page_for({"periods": "40", "transient": "40"})
    sa, sb = decode_series(a.ui.body), decode_series(b.ui.body)
    assert sa["k0"] == sb["k0"] == 60
    np.testing.assert_allclose(sa["quaternion"], sb["quaternion"], atol=2e-6)
    np.testing.assert_allclose(sa["t"], sb["t"], rtol=0, atol=1e-9)


def test_the_orientation_matches_an_independent_integration() -> None:
    page, _, _ = page_for()
    got = decode_series(page.ui.body)
    ks, qs, rs = selected_points(page)
    i = int(np.flatnonzero(ks == got["k0"])[0])
    n = 10
    qr, rot = ivp_orientation(page.state.system(), (qs[i], rs[i]), n)
    for m in (1, n):
        frame = m * got["samples"]
        assert np.max(np.abs(rotation_of(got["quaternion"][frame]) - rot[m - 1])) < 1e-6, m
        assert np.max(np.abs(got["omega"][frame, 1:] - qr[m - 1])) < 1e-6, m
    params = page.state.system()
    w = got["omega"][:: got["samples"]][1 : n + 1].astype(float)
    energy = 0.5 * np.einsum("fi,ij,fj->f", w, params.inertia_matrix, w)
    np.testing.assert_allclose(got["energy"][:: got["samples"]][1 : n + 1], energy, rtol=1e-6)


def test_the_job_is_cancellable_and_a_stale_series_never_reaches_the_page() -> None:
    page, jobs, shipped = page_for()
    assert page.ui.body
    page.state.selected = 1  # a new trajectory: the old series goes at once, a job is queued
    assert page.ui.body == {} and shipped[-1] == {}
    assert "computing the body's motion" in page.ui.view["section"]["body"]["status"]
    first = page.body.inputs
    page.state.selected = 2  # again before that job ran: it is cancelled (the runner's generation moved on)
    assert len(jobs.queue) == 2
    jobs.queue.pop(0)()  # the stale job: it sees cancelled() and ships nothing
    assert page.ui.body == {} and page.body.inputs != first
    jobs.drain()
    got = decode_series(page.ui.body)
    ks, qs, rs = selected_points(page)
    assert page.state.selected == 2 and got["omega"][0, 1] == pytest.approx(qs[-PERIODS - 1], abs=1e-6)
    assert [bool(p) for p in shipped].count(True) == 2  # the first series, then trajectory 2's: never trajectory 1's


def test_a_parameter_or_closing_the_view_drops_the_series_and_stop_stops_the_job() -> None:
    page, jobs, shipped = page_for()
    assert page.ui.body
    page.commit("alpha", "0.12")  # a new system: the series of the old one leaves the page before the new points
    assert page.ui.body == {}
    jobs.drain()
    assert page.ui.body and page.body.inputs.params.alpha == 0.12  # type: ignore[union-attr]
    page.commit("show_body", False)
    view = page.ui.view["section"]["body"]
    assert page.ui.body == {} and not view["open"] and view["status"] == ""
    assert not jobs.queue
    page.commit("show_body", True)  # open again: computed for the state
    assert len(jobs.queue) == 1
    page.handle({"action": "stop"})
    jobs.drain()
    assert page.ui.body == {} and "stopped" in page.ui.view["section"]["body"]["status"]


def test_no_series_while_a_parameter_plays_or_for_a_trajectory_without_points() -> None:
    page, jobs, _ = page_for()
    page.session.frame_periods = 100  # a played parameter's frames (app/play.py)
    page.body.refresh()
    assert page.ui.body == {} and "played parameter" in page.body.status
    page.session.frame_periods = None
    page.body.refresh()
    jobs.drain()
    assert page.ui.body


def test_a_series_that_ends_early_says_what_it_lost() -> None:
    from app.bodyview import BodyInputs, BodyView

    params = state_from_query({"scene": "fig1A"})[0].system()  # a noncompact attractive curve: r drifts away
    series = body_series(params, np.array([0.0, 8.0]), PERIODS, samples=SAMPLES,
                         numerics=Numerics(method="dop853", rtol=1e-10, atol=1e-10, bound=9.0))  # fmt: skip
    assert not series.complete
    payload = encode_series(series, k_start=0)
    back = decode_series(payload)
    assert back["frames"] == series.t.size < PERIODS * SAMPLES + 1 and back["complete"] is False
    assert back["lost"] == [loss.as_dict() for loss in series.lost] and back["status"] == "escaped"
    inputs = BodyInputs(params, 0, 0, 0.0, 8.0, PERIODS, Numerics(method="dop853", rtol=1e-10, atol=1e-10, bound=9.0))
    text = BodyView.describe(series, inputs, payload, 0.01)
    assert text.startswith("the series ends early (escaped, at k = ") and series.lost[0].why in text


def test_the_renderer_is_in_the_pages_module_and_fetches_nothing() -> None:
    # Offline: app/body.js is joined into the page's one ES module (served with the page), and loads nothing.
    from pathlib import Path

    from app.ui import ESM

    source = (Path(__file__).resolve().parents[1] / "app" / "body.js").read_text(encoding="utf-8")
    assert source in ESM and ESM.index(source) < ESM.index("export function render")
    for word in ("import ", "import(", "fetch(", "XMLHttpRequest", "http:", "https:", "<script"):
        assert word not in source, word
