"""The FTLE layer of the section tab (a finite-time Lyapunov exponent map over the view, under the points) and the
selected trajectory's verdict beside its k-series (weighted Birkhoff: regular with its rotation number, chaotic)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from naive import naive_rotation_number, solve_ivp_section
from test_app_cli_parity import _cli_spec, _numerics_flags, _system_flags
from test_app_orbits import Jobs

from app.page import Page
from app.runner import WARM
from explorer_core.analyses.ftle import ftle_map
from explorer_core.status import Status

FIG5A = {"scene": "fig5A", "n": "2", "periods": "5"}


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def page_for(query: dict) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page({**FIG5A, **query}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page, jobs


def test_the_layer_is_off_by_default_and_its_keys_stay_out_of_the_url() -> None:
    page, _ = page_for({})
    assert page.state.ftle == "off"
    assert "ftle" not in page.fig._built and not page.runner.busy("ftle")  # nothing built, nothing computed
    view = page.ui.view["section"]
    assert view["ftle_status"] == "" and not view["ftle_file"]
    assert not {"ftle", "ftle_p", "ftle_n"} & set(page.state.to_query())
    assert page.session.download("ftle") is None


@pytest.mark.parametrize(("direction", "method", "accuracy"), [("forward", "auto", "plot"),
                                                               ("backward", "dop853", "high")])  # fmt: skip
def test_the_layers_spec_is_the_command_lines(monkeypatch, direction: str, method: str, accuracy: str) -> None:
    page, _ = page_for({"ftle": direction, "ftle_n": "10", "ftle_p": "3", "method": method, "accuracy": accuracy})
    layer = page.session.layer("ftle")
    app = layer.spec(layer.inputs())
    box = ",".join(repr(float(v)) for v in (*page.state.q_range, *page.state.r_range))
    cli = _cli_spec(monkeypatch, "ftle", *_system_flags(page.state.system()), f"--box={box}", "--grid", "10,10",
                    "--periods", "3", "--direction", direction, *_numerics_flags(app.numerics), run=False)  # fmt: skip
    assert app == cli and app.as_dict() == cli.as_dict()
    assert (app.numerics.rtol == 1e-12) == (accuracy == "high")  # the page's Accuracy reached the spec


def test_the_map_is_drawn_under_the_points_with_its_colour_key_and_downloads_as_the_clis_npz() -> None:
    page, _ = page_for({"ftle": "backward", "ftle_n": "12", "ftle_p": "4"})
    fig = page.fig
    data = fig.ftle.data
    image = np.asarray(data["image"][0])
    assert image.shape == (12, 12) and np.isfinite(image).all()
    assert (data["x"][0], data["y"][0]) == (page.state.q_range[0], page.state.r_range[0])
    names = [r.name for r in fig.fig.renderers]
    assert names.index("ftle_image") < names.index("section_points")  # under the points
    assert fig.colorbar.visible and fig.colorbar.color_mapper is fig.ftle_mapper
    assert fig.colorbar.title == "FTLE backward over 4 periods (per unit time)"
    assert (fig.ftle_mapper.low, fig.ftle_mapper.high) == pytest.approx((image.min(), image.max()))
    status = page.ui.view["section"]["ftle_status"]
    assert status.startswith("FTLE backward over 4 periods on 12 x 12 pixels: "), status
    assert "without one" not in status  # every pixel has its exponent
    # the download: the NPZ the command line's writer writes, of the map an independent run of the core computes
    got = page.session.download("ftle")
    assert got.name == "ftle.npz" and page.ui.view["section"]["ftle_file"]
    npz = np.load(io.BytesIO(got.data))
    ref = ftle_map(page.session.layer("ftle").result.spec)
    assert np.array_equal(npz["backward"], ref.backward) and np.array_equal(npz["status_backward"],
                                                                            ref.status_backward)  # fmt: skip
    assert np.array_equal(image, ref.backward.astype(np.float32))
    assert "forward" not in npz.files and "summary" in npz.files


def test_a_link_reopens_the_map_and_off_drops_it() -> None:
    page, jobs = page_for({"ftle": "forward", "ftle_n": "10", "ftle_p": "2"})
    q = page.state.to_query()
    assert (q["ftle"], q["ftle_n"], q["ftle_p"]) == ("forward", "10", "2")
    again, _ = page_for(q)  # the link opened anew
    assert again.state.ftle == "forward" and (again.state.ftle_grid, again.state.ftle_periods) == (10, 2)
    assert np.array_equal(np.asarray(again.fig.ftle.data["image"][0]), np.asarray(page.fig.ftle.data["image"][0]))
    assert page.commit("ftle", "off") is None
    jobs.drain()
    assert page.fig.ftle.data["image"] == [] and page.ui.view["section"]["ftle_status"] == ""
    assert not page.fig.colorbar.visible or page.fig.colorbar.color_mapper is not page.fig.ftle_mapper
    assert "ftle" not in page.state.to_query() and page.session.download("ftle") is None


def test_a_new_system_or_view_redoes_the_map_and_bad_values_are_refused() -> None:
    page, jobs = page_for({"ftle": "forward", "ftle_n": "10", "ftle_p": "2"})
    first = page.session.layer("ftle").result
    assert page.commit("periods", "6") is None  # the section's setting only: the same map
    assert not page.runner.busy("ftle")
    assert page.commit("alpha", "-0.3") is None  # a new system: computed again
    assert page.runner.busy("ftle")
    jobs.drain()
    again = page.session.layer("ftle").result
    assert again is not first and again.spec.params.alpha == -0.3
    page.session.set_view_from_plot((-1.0, 0.5), (-2.0, -1.0))
    jobs.drain()
    data = page.fig.ftle.data
    assert (data["x"][0], data["y"][0], data["dw"][0]) == (-1.0, -2.0, pytest.approx(1.5))
    bad, _ = page_for({"ftle": "sideways", "ftle_n": "5000"})
    errors = bad.ui.view["section"]["errors"]
    assert any(e.startswith("URL parameter ftle:") for e in errors)
    assert any(e.startswith("URL parameter ftle_n:") for e in errors)
    assert bad.state.ftle == "off"


def test_the_status_line_counts_the_pixels_without_an_exponent_and_leaves_them_transparent() -> None:
    page, jobs = page_for({"ftle": "forward", "ftle_n": "10", "ftle_p": "1"})
    page.session.set_view_from_plot((-15000.0, 15000.0), (-1.0, 1.0))  # the outer columns escape the bound
    jobs.drain()
    m = page.session.layer("ftle").result
    escaped = int(np.count_nonzero(m.status_forward == Status.ESCAPED))
    assert 0 < escaped < m.status_forward.size and np.all((m.status_forward == Status.OK)
                                                           | (m.status_forward == Status.ESCAPED))  # fmt: skip
    status = page.ui.view["section"]["ftle_status"]
    assert f"{escaped} pixels without one ({escaped} escaped: transparent)" in status, status
    image = np.asarray(page.fig.ftle.data["image"][0])
    assert np.array_equal(np.isnan(image), m.status_forward != Status.OK)  # no value drawn for them
    assert np.isfinite(image[m.status_forward == Status.OK]).all()


# --- the selected trajectory's verdict -------------------------------------------------------------------


def test_a_regular_trajectory_gets_its_rotation_number_and_a_chaotic_one_its_verdict() -> None:
    page, jobs = page_for({"n": "0", "periods": "5", "ics": "0.4,0;0.05,0.02"})
    said = page.ui.view["section"]["series_verdict"]
    assert said.startswith("regular (Birkhoff, ") and ": rotation number 0." in said, said
    # against an independent integration (scipy's DOP853 on the naive field at 1e-12) and reduction (plain loops)
    pts = solve_ivp_section(page.state.system(), (0.4, 0.0), 400)
    assert float(said.rsplit(" ", 1)[1]) == pytest.approx(naive_rotation_number(pts.tolist()), abs=1e-6)
    assert page.commit("selected", "1") is None
    jobs.drain()
    other = page.ui.view["section"]["series_verdict"]
    assert other.startswith("regular") and other != said
    chaos, _ = page_for({"scene": "fig8B", "n": "0", "periods": "5", "transient": "100", "ics": "-1,-2"})
    words = chaos.ui.view["section"]["series_verdict"]
    assert words.startswith("chaotic (Birkhoff, ") and words.endswith(" digits after 1000 periods)"), words


def test_a_drifting_trajectory_is_said_to_drift_not_to_be_chaotic() -> None:
    # Fig. 5A from (1.5, 0) drifts off; its Birkhoff "digits" are negative, which read as chaos before
    page, _ = page_for({"n": "0", "periods": "5", "ics": "1.5,0"})
    said = page.ui.view["section"]["series_verdict"]
    assert said.startswith("no Birkhoff verdict: it drifts off within 1000 periods"), said


def test_the_verdicts_spec_is_the_command_lines(monkeypatch) -> None:
    page, _ = page_for({"n": "3", "seed": "7", "transient": "4", "ics": "0.3,0.1;0.2,-0.1", "sel": "4",
                        "method": "dop853", "accuracy": "high"})  # fmt: skip
    layer = page.session.layer("rotation")
    inputs = layer.inputs()
    app = layer.spec(inputs)
    q, r = (float(v) for v in page.state.initial_conditions()[4])
    assert (q, r) == (0.2, -0.1)
    assert inputs.ic == (q, r)
    cli = _cli_spec(monkeypatch, "birkhoff", *_system_flags(page.state.system()), f"--ic={q!r},{r!r}", "--periods",
                    "500", "--transient", "4", *_numerics_flags(app.numerics), run=False)  # fmt: skip
    assert app == cli and app.as_dict() == cli.as_dict()


def test_no_verdict_for_an_escaped_trajectory_or_none_selected_and_none_before_the_new_one() -> None:
    page, jobs = page_for({"n": "0", "periods": "5", "ics": "0.4,0;20000,0"})
    assert page.ui.view["section"]["series_verdict"].startswith("regular")
    assert page.commit("selected", "1") is None  # (20000, 0) is beyond the bound: no orbit to judge
    assert page.ui.view["section"]["series_verdict"] == ""  # not trajectory 0's any more
    jobs.drain()
    assert page.ui.view["section"]["series_verdict"] == "no Birkhoff verdict: escaped within 1000 periods"
    assert page.commit("selected", "none") is None
    jobs.drain()
    assert page.ui.view["section"]["series_verdict"] == ""


def test_no_verdict_is_computed_for_a_random_trajectory_or_the_frames_of_a_played_parameter() -> None:
    page, jobs = page_for({"n": "2", "periods": "5", "ics": "0.4,0", "sel": "0"})
    layer = page.session.layer("rotation")
    assert layer.inputs() is None and page.ui.view["section"]["series_verdict"] == ""  # a new page's selection
    assert page.commit("selected", "2") is None  # the scene's (clicked) point
    jobs.drain()
    assert page.ui.view["section"]["series_verdict"].startswith("regular")
    assert layer.inputs() is not None
    page.session.frame_periods = 5  # as app/play.py sets it while it plays: each frame drawn whole, at its pace
    assert layer.inputs() is None
