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
