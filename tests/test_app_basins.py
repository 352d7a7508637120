"""The basins layer of the section tab: which attractor each point of the view reaches, coarse to fine."""

from __future__ import annotations

import numpy as np
import pytest
from test_app_orbits import Jobs

from app.page import Page
from app.runner import WARM

#: Fig. 11's tensor at alpha = -0.5, I11 = 1.6: coexisting attractors (the chart depends on the IC).
FIG11 = {"scene": "fig11", "alpha": "-0.5", "I11": "1.6", "n": "2", "periods": "5"}


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def page_for(query: dict) -> tuple[Page, Jobs]:
    jobs = Jobs()
    page = Page({**FIG11, **query}, lambda fn: fn(), executor=jobs)
    page.start()
    jobs.drain()
    return page, jobs


def test_the_basins_layer_colours_the_view_and_lists_the_attractors() -> None:
    page, jobs = page_for({"basins": "1", "bas_n": "24"})
    data = page.fig.basins.data
    assert data["image"] and np.asarray(data["image"][0]).shape == (24, 24)
    assert (data["x"][0], data["y"][0]) == (page.state.q_range[0], page.state.r_range[0])
    view = page.ui.view["section"]
    assert view["basin_status"].startswith("basins on 24 x 24 initial conditions:"), view["basin_status"]
    legend = view["basin_legend"]
    assert legend and all(c.startswith("#") and "%" in t for c, t in legend)
    total = sum(float(t.rsplit(": ", 1)[1].rstrip("%")) for _, t in legend)
    assert total == pytest.approx(100.0, abs=0.5)  # every computed pixel is in one row
    q = page.state.to_query()
    assert q["basins"] == "1" and q["bas_n"] == "24"


def test_a_pan_recomputes_the_basins_for_the_new_view_and_off_clears_them() -> None:
    page, jobs = page_for({"basins": "1", "bas_n": "12"})
    page.session.set_view_from_plot((-1.0, 0.5), (-3.0, -1.0))
    jobs.drain()
    data = page.fig.basins.data
    assert (data["x"][0], data["y"][0], data["dw"][0]) == (-1.0, -3.0, pytest.approx(1.5))
    assert page.commit("show_basins", "false") is None
    jobs.drain()
    assert page.fig.basins.data["image"] == [] and page.ui.view["section"]["basin_legend"] == []
    assert "basins" not in page.state.to_query()


def test_bad_basin_values_are_refused() -> None:
    page, _ = page_for({"bas_n": "5000", "basins": "maybe"})
    errors = page.ui.view["section"]["errors"]
    assert any(e.startswith("URL parameter bas_n:") for e in errors)
    assert any(e.startswith("URL parameter basins:") for e in errors)
    assert not page.state.show_basins and page.state.basin_grid == 80
    msg = page.commit("basin_grid", "3")
    assert msg is not None and "between 10 and 200" in msg


def test_the_layers_are_not_redone_when_only_the_section_changes() -> None:
    page, jobs = page_for({"basins": "1", "bas_n": "12", "man": "-0.1744,-2.1855,1", "man_len": "1"})
    assert page.commit("periods", "6") is None  # the section's setting: the same basins and manifolds
    assert not page.runner.busy("basins") and not page.runner.busy("manifolds")
    jobs.drain()
    assert page.fig.basins.data["image"]
    assert page.commit("alpha", "-0.49") is None  # a new system: both again
    assert page.runner.busy("basins") and page.runner.busy("manifolds")
    jobs.drain()
    assert page.commit("alpha", "-0.5") is None
    page.handle({"action": "stop"})  # stopped layers are computed again on the next change, any change
    assert page.commit("periods", "7") is None
    assert page.runner.busy("basins") and page.runner.busy("manifolds")
    jobs.drain()


def test_the_status_beside_the_legend_gives_the_basin_entropy_and_the_boundary() -> None:
    from explorer_core.analyses.basin_entropy import basin_entropy
    from explorer_core.analyses.basins import ESCAPE

    page, jobs = page_for({"basins": "1", "bas_n": "40"})
    status = page.ui.view["section"]["basin_status"]
    b = page.session.layer("basins").result
    e = basin_entropy(b.label, b.label >= ESCAPE)  # computed again from the labels shown
    words = f"basin entropy S_b = {e.s_b:.2f}, S_bb = {e.s_bb:.2f} ({e.boundary} boundary)"
    assert words in status, status
    assert e.boundary in ("fractal", "smooth")  # 40 x 40 pixels decide it (a 24 x 24 view is undecided)
    assert status.index("attractor(s)") < status.index("basin entropy") < status.index(" s")
