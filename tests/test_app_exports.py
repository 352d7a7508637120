"""Exports are what the screen shows: after a Stop the picture, its status and every CSV name the settings
the data were computed with, and say that the run was stopped (in the file and its name); every CSV the app
offers reads back with csv and numpy (``genfromtxt(..., names=True)`` as it comes) as numbers; the orbit
diagram, the Lyapunov spectrum and the basins download as the command line writes them."""

from __future__ import annotations

import csv
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest
from clirun import run_cli
from test_app_analyses import session
from test_app_cli_parity import _numerics_flags, _system_flags
from test_app_orbits import FLIP, page_for, tap

from app import analyses
from app.layers.section import SectionLayer
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
    """A download as the user gets it: its settings line, its rows (csv, comment lines skipped) and its table
    (numpy reading the file as it comes)."""
    data = page.session.csv(what).decode()
    header = next(line for line in data.splitlines() if line.startswith("# Bilimovich Explorer "))
    body = "\n".join(line for line in data.splitlines() if not line.startswith("#"))
    rows = list(csv.DictReader(io.StringIO(body)))
    table = _table(data)
    return header, rows, table


def _table(data: str) -> np.ndarray:
    """A downloaded CSV read by numpy as it comes (the old files' settings line before the header became the
    column names)."""
    return np.genfromtxt(io.StringIO(data), delimiter=",", names=True, dtype=None, encoding="utf-8")


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
        assert table.dtype.names == tuple(rows[0]), what  # the header line is the first, the comments follow
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


# --- stopped runs say so ---------------------------------------------------------------------------------------


def test_a_stopped_section_downloads_as_partial(monkeypatch) -> None:
    """Stop after the first points of 2,000 periods: the file is ``section-partial.csv`` and says after how many
    periods it was stopped (the old code wrote ``section.csv`` with the settings' periods=2000 and nothing else)."""
    page, jobs = page_for({})
    real = SectionLayer.apply_chunk

    def then_stop(self, *args, **kw):
        real(self, *args, **kw)
        page.handle({"action": "stop"})  # the Stop button, while the run is in flight

    monkeypatch.setattr(SectionLayer, "apply_chunk", then_stop)
    assert page.commit("periods", "2000") is None
    jobs.drain()
    monkeypatch.setattr(SectionLayer, "apply_chunk", real)
    done, total = page.session.section.shown_periods
    assert 0 < done < total == 2000
    sent = []
    monkeypatch.setattr(page.ui, "send_download", lambda *a: sent.append(a))
    page.handle({"action": "download", "what": "section"})
    ((name, mime, data),) = sent
    text = data.decode()
    assert name == "section-partial.csv" and mime == "text/csv"
    assert "\n# partial: the run was stopped before its end" in text
    assert f"not computed: the section was stopped after {done} of its 2000 periods" in text
    table = _table(text)
    assert table.dtype.names == ("traj", "k", "q", "r") and np.count_nonzero(table["traj"] == 0) == done
    # A run that ends is complete again: its file says nothing of a stop.
    page.session.recompute()
    jobs.drain()
    sent.clear()
    page.handle({"action": "download", "what": "section"})
    assert sent[0][0] == "section.csv" and b"partial" not in sent[0][2]


def test_a_stopped_chart_downloads_as_partial(monkeypatch) -> None:
    """Stop after two tiles: ``chart-partial.npz`` with ``complete`` False, the lost pixels named and ``computed``
    False where no pixel was computed, while the picture still fills them from coarser pixels (the old code
    downloaded ``chart.npz`` with every pixel ``computed``)."""
    monkeypatch.setattr(analyses, "REFRESH", 0.0)  # a picture after every tile
    sess = session("fig11")
    sess.state.param.update(chart_grid=(8, 6), chart_periods=30, chart_transient=20, chart_curves=False)
    tab = analyses.ChartTab(sess)
    tab.figure()
    real, shown = tab._show, []

    def then_stop(chart, done, total, final=False):
        real(chart, done, total, final)
        shown.append(done)
        if len(shown) == 2:
            tab.stop()

    monkeypatch.setattr(tab, "_show", then_stop)
    tab.run()
    assert shown == [1, 2] and "stopped" in tab.view["message"]
    file = tab.file("chart")
    assert file.name == "chart-partial.npz"
    assert np.all(tab.source.data["image"][0] > 0)  # the picture: every pixel coloured from a coarser one
    with np.load(io.BytesIO(file.data)) as z:
        assert not bool(z["complete"]) and 0 < z["computed"].sum() < z["computed"].size
        lost = json.loads(str(z["lost"]))
        assert {"what": "pixels", "count": int((~z["computed"]).sum()),
                "why": "not computed: the chart was stopped before them"} in lost  # fmt: skip
        assert np.all(np.isnan(z["period"][~z["computed"]]))
    # The page sends it under that name.
    sent: list = []
    ui = SimpleNamespace(send_download=lambda *a: sent.append(a))
    page = SimpleNamespace(tabs={"chart": tab}, session=sess, ui=ui)
    Page._download(page, "chart")  # type: ignore[arg-type]
    assert sent[0][0] == "chart-partial.npz"


# --- the analyses' downloads are the command line's files --------------------------------------------------------


def _same_csv(app: bytes, cli_path: str) -> np.ndarray:
    """The app's CSV and the command line's, read by numpy as they come: the same columns and values."""
    a = _table(app.decode())
    with open(cli_path) as fh:
        c = _table(fh.read())
    assert a.dtype.names == c.dtype.names and a.shape == c.shape
    for name in a.dtype.names:
        if np.issubdtype(a[name].dtype, np.number):
            np.testing.assert_array_equal(a[name], c[name], err_msg=name)
        else:
            assert a[name].tolist() == c[name].tolist(), name
    return a


def test_the_orbit_diagram_downloads_as_the_command_line_writes_it(tmp_path) -> None:
    sess = session("fig10")
    st = sess.state
    st.param.update(bif_values=4, bif_points=8, bif_transient=30, bif_range=(-0.42, -0.40), bif_orbits=False)
    tab = analyses.BifurcationTab(sess)
    assert [d[3] for d in tab.view["downloads"]] == [False, False, False]  # nothing yet
    tab.run()
    assert [d[0] for d in tab.view["downloads"] if d[3]] == ["bifurcation"]  # not continued: no branches
    assert tab.file("branches") is None
    file = tab.file("bifurcation")
    assert file.name == "bifurcation.csv"
    ics = [f"--ic={float(q)!r},{float(r)!r}" for q, r in np.asarray(tab._data.ics)]
    out = str(tmp_path / "d.csv")
    code, _, err = run_cli("bifurcation", *_system_flags(st.system()), "--param", st.bif_param, "--range=-0.42,-0.4",
                           "--n-values", "4", "--points", "8", "--transient", "30", "--seeding", st.bif_seeding, *ics,
                           *_numerics_flags(tab._data.numerics), "--out", out)  # fmt: skip
    assert code == 0, err
    table = _same_csv(file.data, out)
    assert table.dtype.names == ("sweep", "value_index", "value", "ic", "k", "q", "r", "status") and table.size


def test_the_continued_branches_download_with_their_bifurcations() -> None:
    sess = session("fig10")
    sess.state.param.update(bif_values=4, bif_points=8, bif_transient=200, bif_range=(-0.36, -0.355),
                            bif_orbits=True)  # fmt: skip
    tab = analyses.BifurcationTab(sess)
    tab.run()
    cont = tab._cont
    assert cont is not None and cont.branches
    branches = tab.file("branches")
    assert branches.name == "branches.csv"
    table = _table(branches.data.decode())
    assert table.dtype.names == cont.CSV_HEADER and table.size == cont.n_points
    np.testing.assert_array_equal(table["value"], [v for b in cont.branches for v in b.values])
    summary = json.loads(tab.file("bifurcations").data)
    assert summary["complete"] == cont.complete and len(summary["branches"]) == len(cont.branches)
    assert [(b["type"], b["value"], b["error"]) for b in summary["bifurcations"]] == [
        (b.kind, b.value, b.error) for b in cont.bifurcations]  # fmt: skip


def test_the_lyapunov_spectrum_downloads_as_the_command_line_writes_it(tmp_path) -> None:
    sess = session("fig8B")
    st = sess.state
    st.param.update(lyap_ic=(-0.5, -1.0), lyap_transient=20, lyap_periods=30, lyap_ensemble=2)
    tab = analyses.LyapunovTab(sess)
    tab.figure()
    assert tab.file("lyapunov") is None
    tab.run()
    history, summary = tab.file("lyapunov"), tab.file("lyapunov_summary")
    assert (history.name, summary.name) == ("lyapunov.csv", "lyapunov_summary.json")
    out = str(tmp_path / "h.csv")
    code, stdout, err = run_cli("lyapunov", *_system_flags(st.system()), "--ic=-0.5,-1.0", "--periods", "30",
                                "--transient", "20", "--ensemble", "2", *_numerics_flags(tab.result.numerics),
                                "--history", out, "--json")  # fmt: skip
    assert code == 0, err
    table = _same_csv(history.data, out)
    assert table.dtype.names == ("member", "k", "L1", "L2", "divergence_mean") and set(table["member"]) == {0, 1}
    cli = json.loads(stdout)
    app = json.loads(summary.data)
    assert app["exponents"] == cli["exponents"] and app["complete"] is True
    # A new run starts from nothing: the old run's files are not offered for it.
    tab._start(lambda cancelled, emit: None)
    assert tab.file("lyapunov") is None


def test_the_basins_download_as_the_command_line_writes_them(tmp_path) -> None:
    page, jobs = page_for({"basins": "1", "bas_n": "10"})
    layer = page.session.layer("basins")
    assert layer.result is not None and layer.result.completed and page.ui.view["section"]["basins_file"]
    file = page.session.download("basins")
    assert (file.name, file.mime) == ("basins.npz", "application/octet-stream")
    spec = layer.result.spec
    box = ",".join(repr(float(v)) for v in spec.box)
    out = str(tmp_path / "b.npz")
    code, _, err = run_cli("basins", *_system_flags(page.state.system()), f"--box={box}", "--grid", "10,10",
                           *_numerics_flags(spec.numerics), "--out", out)  # fmt: skip
    assert code == 0, err
    with np.load(io.BytesIO(file.data)) as a, np.load(out) as c:
        assert sorted(a.files) == sorted(c.files)
        for name in ("q", "r", "label", "status", "computed"):
            np.testing.assert_array_equal(a[name], c[name], err_msg=name)
        assert json.loads(str(a["summary"]))["complete"] is True
    # Turned off: nothing to download.
    assert page.commit("show_basins", False) is None
    jobs.drain()
    assert page.session.download("basins") is None and not page.ui.view["section"]["basins_file"]


def test_the_section_downloads_as_the_command_line_writes_it(tmp_path) -> None:
    """The page's section CSV is the command line's for the same settings, row for row: k-major (every
    trajectory's point at k, then k + 1; the page once wrote trajectory by trajectory) and the same numbers
    though the page's run came in chunks of its own pace (the engine's points do not depend on them)."""
    page, _ = page_for({"n": "40", "periods": "80", "transient": "3"})
    spec = page.state.section_request().spec
    ics = [f"--ic={float(q)!r},{float(r)!r}" for q, r in np.asarray(spec.ics)]
    out = str(tmp_path / "s.csv")
    code, _, err = run_cli("section", *_system_flags(page.state.system()), *ics, "--periods", "80", "--transient",
                           "3", *_numerics_flags(spec.numerics), "--out", out)  # fmt: skip
    assert code == 0, err
    table = _same_csv(page.session.csv("section"), out)
    assert table.size > 40 * 40 and np.all(np.diff(table["k"]) >= 0) and list(table["k"][:40]) == [4] * 40


# --- figures: PNG and SVG at a chosen size, written on the server (issue 36, item 1) --------------------------------


def _png_size(data: bytes) -> tuple[int, int]:
    """Width and height from a PNG's header (its IHDR chunk), read without an image library."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def _svg_size(data: bytes) -> tuple[float, float]:
    """Width and height of an SVG in points, parsed as XML."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(data)
    assert root.tag.endswith("svg")
    w, h = root.get("width"), root.get("height")
    assert w.endswith("pt") and h.endswith("pt"), (w, h)
    return float(w[:-2]), float(h[:-2])


def _figures(page: Page, jobs, tab: str, *values: str) -> list[tuple[str, str, bytes]]:
    """The files the page sends for figure requests (drawn on the runner: ``jobs`` runs them)."""
    sent: list = []
    page.ui.send_download = lambda *a: sent.append(a)  # type: ignore[method-assign]
    for value in values:
        page.handle({"action": "download", "what": "figure", "tab": tab, "value": value})
        jobs.drain()
    return sent


def test_the_section_figure_downloads_as_png_and_svg_at_the_chosen_size() -> None:
    """Fails on the old code (no figure download: PNG only at screen size through Bokeh's save tool and a prompt)."""
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1", "man": f"{FLIP[0]},{FLIP[1]},1",
                           "man_len": "2"})  # fmt: skip
    (png, svg, small) = _figures(page, jobs, "section", "png 1200x800 150", "svg 1200x800 150", "png 640x400 80")
    assert (png[0], png[1]) == ("section.png", "image/png") and _png_size(png[2]) == (1200, 800)
    assert (svg[0], svg[1]) == ("section.svg", "image/svg+xml")
    assert _svg_size(svg[2]) == (1200 / 150 * 72, 800 / 150 * 72)  # 8 x 5.33 inches
    assert _png_size(small[2]) == (640, 400)
    # The file says what it shows: the scene and the system's parameters (title and metadata).
    assert b"Fig. 8B" in png[2] and "Fig. 8B" in svg[2].decode() and "α = -0.45" in svg[2].decode()
    assert not page.ui.view["section"]["errors"]


def test_a_figure_request_out_of_bounds_is_refused_with_the_reason() -> None:
    page, jobs = page_for({})
    assert _figures(page, jobs, "section", "png 8000x8000 100", "no tab", "png 50x800 150", "gif 800x600 100",
                    "png 800x600 5000") == []  # fmt: skip
    assert _figures(page, jobs, "nowhere", "png 800x600 100") == [] and "nowhere" not in page.figure_problems
    assert "figure dpi must be a whole number from 50 to 600" in page.ui.view["section"]["errors"][-1]
    assert _figures(page, jobs, "section", "png 800x600 100")[0][0] == "section.png"  # the next good one clears it
    assert not page.ui.view["section"]["errors"]
    page.handle({"action": "tab", "tab": "lyapunov"})
    assert _figures(page, jobs, "lyapunov", "png 800x600 100") == []  # nothing drawn yet: said, not sent
    assert "no figure yet" in page.ui.view["lyapunov"]["errors"][-1]


def test_a_stopped_section_figure_is_named_partial(monkeypatch) -> None:
    page, jobs = page_for({})
    real = SectionLayer.apply_chunk

    def then_stop(self, *args, **kw):
        real(self, *args, **kw)
        page.handle({"action": "stop"})

    monkeypatch.setattr(SectionLayer, "apply_chunk", then_stop)
    assert page.commit("periods", "2000") is None
    jobs.drain()
    ((name, _, data),) = _figures(page, jobs, "section", "svg 800x600 100")
    assert name == "section-partial.svg" and "stopped after" in data.decode()


def test_an_analysis_figure_downloads_at_the_chosen_size() -> None:
    """The Lyapunov tab's running estimates as SVG and PNG (the orbit diagram and the chart go the same way)."""
    page, jobs = page_for({"lyap_ic": "-0.5,-1", "lyap_periods": "30", "lyap_transient": "20", "lyap_n": "2"})
    page.handle({"action": "tab", "tab": "lyapunov"})
    page.handle({"action": "run", "tab": "lyapunov"})
    jobs.drain()
    assert page.tabs["lyapunov"].result is not None
    png, svg = _figures(page, jobs, "lyapunov", "png 1000x700 100", "svg 1000x700 100")
    assert png[0] == "lyapunov.png" and _png_size(png[2]) == (1000, 700)
    assert svg[0] == "lyapunov.svg" and _svg_size(svg[2]) == (720.0, 504.0)


def test_the_chart_npz_carries_the_curves_drawn_on_it() -> None:
    """Fails on the old code (the NPZ held the pixels only): every curve drawn, its kind and period, read back with
    numpy, equal to the lines on the plot."""
    sess = session("fig11")
    sess.state.param.update(chart_grid=(8, 6), chart_periods=30, chart_transient=20, chart_curves=True)
    tab = analyses.ChartTab(sess)
    tab.figure()
    tab.run()
    assert tab.boundaries is not None
    file = tab.file("chart")
    with np.load(io.BytesIO(file.data)) as z:
        start, points = z["curve_start"], z["curve_points"]
        kinds, periods = z["curve_kind"].tolist(), z["curve_period"].tolist()
        assert z["curve_columns"].tolist() == ["alpha", "I11", "q", "r"]
        assert bool(z["curves_complete"]) == tab.boundaries.complete
        assert json.loads(str(z["curves_lost"])) == [loss.as_dict() for loss in tab.boundaries.lost]
        assert "regime" in z.files and bool(z["complete"])  # the pixels as before
    assert file.name == ("chart.npz" if tab.boundaries.complete else "chart-partial.npz")
    drawn = tab.curves.data
    long = [i for i in range(len(kinds)) if start[i + 1] - start[i] >= 2]  # the plot draws curves of 2+ points
    assert len(long) == len(drawn["xs"]) > 0
    for n, i in enumerate(long):
        np.testing.assert_array_equal(points[start[i] : start[i + 1], 0], drawn["xs"][n])
        np.testing.assert_array_equal(points[start[i] : start[i + 1], 1], drawn["ys"][n])
        assert drawn["kind"][n] == f"{analyses.CURVE_STYLE[kinds[i]][2]} of the period-{periods[i]} cycle"
    # A chart whose curves were stopped: no curves, and the file says they were not followed.
    tab.boundaries = None
    with np.load(io.BytesIO(tab.file("chart").data)) as z:
        assert z["curve_points"].shape == (0, 4) and not bool(z["curves_complete"])
        assert "not followed" in json.loads(str(z["curves_lost"]))[0]["why"]
    assert tab.file("chart").name == "chart-partial.npz"


def _reads_as_it_comes(data: bytes) -> np.ndarray:
    """A CSV download read by numpy and pandas as they come: the same rows."""
    import pandas as pd

    table = _table(data.decode())
    frame = pd.read_csv(io.BytesIO(data), comment="#")
    assert list(frame.columns) == list(table.dtype.names) and len(frame) == table.size
    return table


def test_a_stopped_orbit_search_downloads_as_partial() -> None:
    """Fails on the old code: ``orbits.csv`` with nothing saying the search was stopped."""
    page, jobs = page_for({"orb": f"{FLIP[0]},{FLIP[1]}", "orb_n": "1"})
    whole = page.session.download("orbits")
    assert whole.name == "orbits.csv" and b"partial" not in whole.data
    _reads_as_it_comes(whole.data)
    page.handle({"action": "find_orbits"})  # queued, then stopped before it ends
    page.handle({"action": "stop"})
    jobs.drain()
    file = page.session.download("orbits")
    assert file.name == "orbits-partial.csv"
    text = file.data.decode()
    assert "\n# partial: the run was stopped before its end" in text and "the search was stopped" in text
    assert _reads_as_it_comes(file.data).size == len(page.session.orbits[0]["points"])
    # The search redone to its end: whole again.
    page.session.recompute()
    jobs.drain()
    assert page.session.download("orbits").name == "orbits.csv"


def test_stopped_manifolds_download_as_partial(monkeypatch) -> None:
    """Stop while the manifolds grow: ``manifolds-partial.csv`` whose head says so (fails on the old code)."""
    from app.layers.manifolds import ManifoldsLayer

    page, jobs = page_for({"man": f"{FLIP[0]},{FLIP[1]},1", "man_len": "2"})
    whole = page.session.download("manifolds")
    assert whole.name == "manifolds.csv" and b"# partial" not in whole.data
    _reads_as_it_comes(whole.data)
    real = ManifoldsLayer.apply

    def then_stop(self, inputs, result):
        real(self, inputs, result)
        if result[0] and not all(m.completed for m in result[0]):
            page.handle({"action": "stop"})

    monkeypatch.setattr(ManifoldsLayer, "apply", then_stop)
    assert page.commit("manifold_length", "3") is None
    jobs.drain()
    file = page.session.download("manifolds")
    assert file.name == "manifolds-partial.csv", page.ui.view["section"]["manifold_status"]
    assert "\n# partial: the run was stopped before its end" in file.data.decode()
    assert _reads_as_it_comes(file.data).size > 0


def test_a_figure_that_cannot_be_drawn_says_so(monkeypatch) -> None:
    """Drawn on the runner: a failure is said among the tab's errors, never a traceback, nothing sent."""
    from app import figures

    def broken(*args, **kw):
        raise RuntimeError("no fonts")

    monkeypatch.setattr(figures, "figure_file", broken)
    page, jobs = page_for({})
    assert _figures(page, jobs, "section", "png 800x600 100") == []
    assert "the figure could not be drawn: no fonts" in page.ui.view["section"]["errors"][-1]
