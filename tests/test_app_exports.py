"""Exports are what the screen shows: after a Stop the picture, its status and every CSV name the settings
the data were computed with; every CSV the app offers reads back with csv and numpy as numbers."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from test_app_orbits import FLIP, page_for, tap

from app.page import Page
from app.runner import WARM

#: The number columns of each CSV download (the rest are labels).
NUMBER_COLUMNS = {
    "section": ("traj", "k", "q", "r"),
    "orbits": (
        "orbit",
        "period",
        "stable",
        "j",
        "q",
        "r",
        "mu1_re",
        "mu1_im",
        "mu2_re",
        "mu2_im",
        "det",
        "liouville",
        "residual",
    ),
    "manifolds": ("saddle", "s", "q", "r"),
}


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def _csv(page: Page, what: str) -> tuple[str, list[dict[str, str]], np.ndarray]:
    """A download as the user gets it: its header line, its rows (csv) and its table (numpy)."""
    data = page.session.csv(what).decode()
    header = data.splitlines()[0]
    body = "\n".join(line for line in data.splitlines() if not line.startswith("#"))
    rows = list(csv.DictReader(io.StringIO(body)))
    table = np.genfromtxt(io.StringIO(body), delimiter=",", names=True, dtype=None, encoding="utf-8")
    return header, rows, table


def _header_settings(header: str) -> dict[str, str]:
    return dict(kv.split("=", 1) for kv in header.split("; ", 1)[1].split("&"))


def test_every_csv_reads_back_as_numbers() -> None:
    """Fails on the old code: the orbits CSV wrote ``np.float64(-1.457…)`` in its number columns."""
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "man": f"{FLIP[0]},{FLIP[1]},1",
                           "man_len": "2"})  # fmt: skip
    assert page.session.n_points and page.session.orbits and page.session.n_manifolds
    for what, columns in NUMBER_COLUMNS.items():
        header, rows, table = _csv(page, what)
        assert header.startswith(f"# Bilimovich Explorer {'periodic orbits' if what == 'orbits' else what}")
        assert rows and table.size == len(rows), what
        for name in columns:
            values = [float(row[name]) for row in rows]  # plain numbers: float() reads every cell
            assert np.all(np.isfinite(values)), (what, name)
            assert np.issubdtype(table[name].dtype, np.number), (what, name, table[name].dtype)
            np.testing.assert_array_equal(table[name], values)
    _, rows, _ = _csv(page, "orbits")
    assert rows[0]["type"] == "flip saddle" and float(rows[0]["mu1_re"]) < -1  # the expanding multiplier


def test_a_stop_before_the_new_points_keeps_a_picture_that_says_whose_it_is() -> None:
    """Change alpha, Stop before the new run's first points: the old picture stays, its status names the alpha it
    is for, and the section CSV holds the old points under the OLD alpha (the old code wrote the new one)."""
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "man": f"{FLIP[0]},{FLIP[1]},1",
                           "man_len": "2"})  # fmt: skip
    header0, rows0, _ = _csv(page, "section")
    assert _header_settings(header0)["alpha"] == "-0.45"
    assert "picture is for" not in page.ui.view["section"]["status"]
    assert page.commit("alpha", "-0.44") is None
    assert page.running()
    page.handle({"action": "stop"})
    jobs.drain()  # the cancelled jobs start late and end without a trace
    view = page.ui.view["section"]
    assert "stopped" in view["status"] and "α = -0.45 (the controls: -0.44)" in view["status"], view["status"]
    header, rows, _ = _csv(page, "section")
    assert _header_settings(header)["alpha"] == "-0.45" and rows == rows0
    # The layers kept on screen say the same, and so do their exports.
    assert "α = -0.45 (the controls: -0.44)" in view["orbit_status"], view["orbit_status"]
    assert "α = -0.45 (the controls: -0.44)" in view["manifold_status"], view["manifold_status"]
    assert _header_settings(_csv(page, "orbits")[0])["alpha"] == "-0.45"
    assert _header_settings(_csv(page, "manifolds")[0])["alpha"] == "-0.45"
    # Once the new run's points come, the picture is the controls' again.
    page.session.recompute()
    jobs.drain()
    view = page.ui.view["section"]
    assert "picture is for" not in view["status"] and "stopped" not in view["status"]
    assert _header_settings(_csv(page, "section")[0])["alpha"] == "-0.44"


def test_orbits_of_a_stopped_system_are_not_mixed_with_the_new_ones() -> None:
    """A Stop keeps the old alpha's orbits; a click then finds the new alpha's orbit: the table and the CSV hold
    only the new system's orbits, under its alpha (the old code merged both systems' orbits)."""
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "click": "orbit"})
    assert len(page.session.orbits) == 1
    old_q = page.session.orbits[0]["q"]
    assert page.commit("alpha", "-0.40") is None
    page.handle({"action": "stop"})
    jobs.drain()
    assert len(page.session.orbits) == 1  # kept, and labelled as the old system's
    tap(page, *FLIP)
    jobs.drain()
    rows = page.session.orbits
    header, csv_rows, _ = _csv(page, "orbits")
    assert _header_settings(header)["alpha"] == "-0.4"
    assert all(r["q"] != old_q for r in rows), rows
    assert {int(r["orbit"]) for r in csv_rows} == set(range(len(rows)))


def test_a_stop_clears_the_frozen_field_layers_of_another_system() -> None:
    """The tracks and the T' map have no text saying whose they are: a Stop before the new ones clears them."""
    page, jobs = page_for({})
    assert list(page.fig.equilibria.data["q"]) and len(page.fig.tprime.data["image"]) == 1
    assert page.commit("alpha", "-0.40") is None
    page.handle({"action": "stop"})
    jobs.drain()
    assert list(page.fig.equilibria.data["q"]) == [] and len(page.fig.tprime.data["image"]) == 0
