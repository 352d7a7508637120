"""Clear pictures (issue 21, item 4): marks told apart in the legend and the hovers, colour layers that do not
tint each other, colour bars only for what is drawn."""

from __future__ import annotations

import re

import numpy as np
import pytest
from bokeh.models import HoverTool
from test_app_orbits import page_for

from app.runner import WARM
from app.views import SectionFigure


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def _hovers(fig: SectionFigure) -> list[HoverTool]:
    return [t for t in fig.fig.toolbar.tools if isinstance(t, HoverTool)]


def test_every_hover_names_only_fields_of_the_marks_it_describes() -> None:
    """Fails on the old code: one hover over the points and the diamonds showed 'frozen-field equilibrium: ???'
    on every section point (the points have no 'type')."""
    page, jobs = page_for({"orb_all": "1", "orb_n": "1", "qr": "-1.7,1", "rr": "-4.5,0.5"})
    page.fig.set_manifolds([(np.array([0.0, 1.0]), np.array([0.0, 1.0]), "unstable")], [(0.5, 0.5, "homoclinic")])
    assert page.fig.equilibria.data["type"] and page.session.orbits  # diamonds and orbits drawn
    hovers = _hovers(page.fig)
    described = {r.name for h in hovers for r in h.renderers}
    assert {"section_points", "frozen_field_equilibria", "homoclinic_points"} <= described
    for h in hovers:
        fields = set(re.findall(r"@\{?(\w+)", " ".join(v for _, v in h.tooltips)))
        for r in h.renderers:
            assert fields <= set(r.data_source.data), (r.name, fields - set(r.data_source.data))


def test_the_orbit_hover_puts_the_multipliers_first_and_few_point_entries() -> None:
    """Fails on the old code: the multipliers came second, after dozens of point entries (no limit)."""
    page, jobs = page_for({"orb": "-0.0377,-2.3979", "orb_n": "1"})
    (orbits,) = [h for h in _hovers(page.fig) if any(r.name.startswith("orbit_points") for r in h.renderers)]
    assert orbits.tooltips[0][0] == "multipliers" and orbits.limit == 1
    (points,) = [h for h in _hovers(page.fig) if any(r.name == "section_points" for r in h.renderers)]
    assert points.limit is not None and points.limit <= 5


def test_frozen_field_equilibria_and_orbits_of_the_map_have_their_own_names() -> None:
    """Fails on the old code: the legend said 'stable focus' for a diamond under an 'unstable focus' ring of the
    map (Fig. 8B), and the orbits had no legend entry."""
    page, jobs = page_for({"orb_all": "1", "orb_n": "1", "qr": "-1.7,1", "rr": "-4.5,0.5"})
    eq = page.fig.equilibria.data
    assert eq["label"] and all(lab == f"frozen-field {t}" for lab, t in zip(eq["label"], eq["type"], strict=True))
    drawn = page.fig.orbit_data()
    assert sorted(set(drawn["label"])) == ["flip saddle orbit of the map", "saddle orbit of the map",
                                           "unstable focus orbit of the map"]  # fmt: skip
    items = page.fig.legend.items
    assert all(it.label.field == "label" for it in items)
    legend_renderers = {r.name for it in items for r in it.renderers}
    assert {"frozen_field_equilibria", "orbit_points_saddle", "orbit_points_unstable"} <= legend_renderers


def test_colour_bars_only_for_the_colour_layer_seen() -> None:
    """Fails on the old code: the T' colour bar stayed when the map was off, and the density image had none."""
    fig = SectionFigure((-1.0, 1.0), (-1.0, 1.0))
    assert not fig.colorbar.visible  # nothing coloured yet
    grid = np.linspace(-1, 1, 5)
    fig.set_tprime(np.outer(grid, grid), grid, grid, "T′ at t0: red energy gain, blue loss")
    assert fig.colorbar.visible and fig.colorbar.color_mapper is fig.tprime_mapper
    fig.set_tprime(None, np.zeros(0), np.zeros(0), "")
    assert not fig.colorbar.visible
    fig.set_tprime(np.outer(grid, grid), grid, grid, "T′ at t0: red energy gain, blue loss")
    fig.set_density(np.arange(16.0).reshape(4, 4), (-1.0, 1.0, -1.0, 1.0))
    assert fig.colorbar.visible and fig.colorbar.color_mapper is fig.density_mapper
    assert "per pixel" in fig.colorbar.title
    assert not fig._tprime_renderer.visible and fig.tprime_hidden_by == "the density image"
    fig.set_density(None)
    assert fig._tprime_renderer.visible and fig.colorbar.color_mapper is fig.tprime_mapper


def test_the_basins_are_not_tinted_by_the_tprime_map_and_their_legend_matches() -> None:
    """Fails on the old code: the T' map stayed under the half-transparent basins (their colours no longer those
    of the legend) and nothing said so."""
    from app.layers.basins import OUTCOME_COLOURS
    from app.views import BASIN_ALPHA, as_drawn
    from explorer_core.analyses.basins import ESCAPE, FAILED

    page, jobs = page_for({"basins": "1", "bas_n": "12"})
    assert page.fig.tprime.data["image"] and page.fig.basins.data["image"]  # both computed
    assert not page.fig._tprime_renderer.visible and not page.fig.colorbar.visible
    assert "T′ map is hidden while the basins are shown" in page.ui.view["section"]["colour_note"]
    image = page.fig.basins.data["image"][0].view(np.uint8).reshape(12, 12, 4)
    drawn = {"#" + "".join(f"{v:02x}" for v in px[:3]) for px in image.reshape(-1, 4) if px[3]}
    swatches = {c for c, _ in page.ui.view["section"]["basin_legend"]}
    assert swatches == {as_drawn(c) for c in drawn}, (swatches, drawn)  # each swatch the colour seen
    assert page.commit("show_basins", "false") is None
    jobs.drain()
    assert page.fig._tprime_renderer.visible and page.fig.colorbar.visible
    assert page.ui.view["section"]["colour_note"] == ""
    # Escaped and failed pixels are clearly darker than the page's white (the old escape grey showed as #cfcfcf).
    for code in (ESCAPE, FAILED):
        seen = as_drawn(OUTCOME_COLOURS[code], BASIN_ALPHA)
        assert max(int(seen[i : i + 2], 16) for i in (1, 3, 5)) <= 0xB0, (code, seen)


def test_the_legend_is_shown_only_with_entries() -> None:
    """With the tracks off and no orbit, the legend was a blank box in the plot's corner (basins screenshot)."""
    fig = SectionFigure((-1.0, 1.0), (-1.0, 1.0))
    assert not fig.legend.visible
    fig.set_equilibria(np.array([0.1]), np.array([0.2]), ("saddle",))
    assert fig.legend.visible
    fig.set_equilibria(np.array([]), np.array([]), ())
    assert not fig.legend.visible
    fig.set_orbits([{"points": [(0.1, 0.2)], "period": 1, "type": "stable focus", "mu": "0.5, 0.4"}])
    assert fig.legend.visible
    fig.set_orbits([])
    assert not fig.legend.visible
