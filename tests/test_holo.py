"""Results drawn as HoloViews (app/holo.py through explorer_core/drawing.py): each picture's data is the result's.

Every test builds a small result, draws it and reads the picture back (``dimension_values``, the rendered
Bokeh glyphs and hover tools): the points, the colours' mapping and the hover fields must be the result's
and the app's. The registry's own contract (an explicit ``import app.holo``, the entry point declared in
pyproject.toml, the clear error without a drawer) is tested without HoloViews' help.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from explorer_core import drawing

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------------
# The registry (no HoloViews needed).


class _Thing(drawing.Drawable):
    pass


class _Child(_Thing):
    pass


def test_without_a_drawer_to_holoviews_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(drawing, "_LOADED", True)  # no entry point is tried
    with pytest.raises(drawing.NoDrawerError, match=r"_Thing\.to_holoviews\(\) needs a drawer.*pip install holoviews"):
        _Thing().to_holoviews()


def test_an_entry_point_that_cannot_load_is_named_in_the_error(monkeypatch: pytest.MonkeyPatch) -> None:
    class EP:
        name, value = "broken", "nowhere.module:register"

        def load(self):
            raise ImportError("No module named 'holoviews'")

    monkeypatch.setattr(drawing, "_LOADED", False)
    monkeypatch.setattr(drawing, "_LOAD_ERRORS", [])
    monkeypatch.setattr(drawing.importlib.metadata, "entry_points", lambda group: [EP()] if group else [])
    with pytest.raises(drawing.NoDrawerError, match=r"broken \(nowhere.module:register\): No module named 'holoviews'"):
        _Thing().to_holoviews()


def test_entry_points_register_on_first_use_and_subclasses_inherit(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    class EP:
        name, value = "test", "tests:register"

        def load(self):
            return lambda: calls.append(1) or drawing.register(_Thing, lambda obj, **o: ("drawn", type(obj), o))

    monkeypatch.setattr(drawing, "_DRAWERS", {})
    monkeypatch.setattr(drawing, "_LOADED", False)
    monkeypatch.setattr(drawing, "_LOAD_ERRORS", [])
    monkeypatch.setattr(drawing.importlib.metadata, "entry_points", lambda group: [EP()])
    assert _Child().to_holoviews(width=3) == ("drawn", _Child, {"width": 3})
    assert _Thing().to_holoviews() == ("drawn", _Thing, {})
    assert calls == [1]  # loaded once


def test_register_refuses_what_is_not_a_class_or_a_drawer() -> None:
    with pytest.raises(TypeError, match="needs a class"):
        drawing.register("Section", lambda r: r)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="must be callable"):
        drawing.register(_Thing, "draw")  # type: ignore[arg-type]


def test_the_entry_point_is_declared_and_names_the_registering_function() -> None:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    eps = meta["project"]["entry-points"][drawing.ENTRY_POINT_GROUP]
    assert eps == {"holoviews": "app.holo:register"}
    assert "holoviews" in " ".join(meta["project"]["dependencies"])
    # Where the package is installed from a checkout with this pyproject, the metadata carries it too.
    installed = {ep.value for ep in importlib.metadata.entry_points(group=drawing.ENTRY_POINT_GROUP)}
    assert not installed or "app.holo:register" in installed
    module, _, attr = eps["holoviews"].partition(":")
    holo = pytest.importorskip(module)
    assert callable(getattr(holo, attr))


def test_the_served_page_does_not_import_holoviews() -> None:
    code = "import app.main, app.page, app.controller; import sys; print(' '.join(m for m in ('holoviews', 'app.holo', 'app.notebook') if m in sys.modules))"  # noqa: E501
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True,
                         timeout=300)  # fmt: skip
    assert out.stdout.strip() == ""


# ---------------------------------------------------------------------------
# The drawers: small results, their pictures read back.

hv = pytest.importorskip("holoviews")
holo = pytest.importorskip("app.holo")

from app import views  # noqa: E402
from app.analyses import CHART_LEGEND, CURVE_STYLE  # noqa: E402
from app.layers.basins import BASIN_COLOURS  # noqa: E402
from explorer_core.analyses.basins import basins  # noqa: E402
from explorer_core.analyses.bifurcation import bifurcation_diagram  # noqa: E402
from explorer_core.analyses.continuation import continue_orbit  # noqa: E402
from explorer_core.analyses.density import density  # noqa: E402
from explorer_core.analyses.equilibria import equilibria, equilibrium_tracks  # noqa: E402
from explorer_core.analyses.lyapunov import lyapunov_spectrum  # noqa: E402
from explorer_core.analyses.manifolds import manifolds, saddle_orbit  # noqa: E402
from explorer_core.analyses.orbits import find_orbits  # noqa: E402
from explorer_core.analyses.regimes import REGIMES, chart_spec, regime_chart  # noqa: E402
from explorer_core.analyses.tprime import tprime_map  # noqa: E402
from explorer_core.scenes import get_scene  # noqa: E402
from explorer_core.solve.section import section  # noqa: E402
from explorer_core.system.params import ParameterError  # noqa: E402

FIG8B = get_scene("fig8B")
FIG10 = get_scene("fig10").params
FIG11 = get_scene("fig11").params


def render(obj):
    return hv.render(obj, backend="bokeh")


def glyph_renderers(fig):
    return [r for r in fig.renderers if hasattr(r, "glyph")]


def drawn_colours(fig):
    """The fill colour of every point of the figure's one scatter, as the browser gets it."""
    (r,) = glyph_renderers(fig)
    colour = r.glyph.fill_color
    if isinstance(colour, str):  # one colour for every point: HoloViews sends it once
        return np.full(len(next(iter(r.data_source.data.values()))), str(colour))
    return np.asarray(r.data_source.data[colour.field])


def hovers(fig):
    return [t for t in fig.tools if type(t).__name__ == "HoverTool"]


def elements(obj):
    return list(obj) if isinstance(obj, hv.Overlay) else [obj]


@pytest.fixture(scope="module")
def sec():
    return section(FIG8B.params, FIG8B.initial_conditions()[:25], 40, numerics=FIG8B.numerics(40))


def test_section_points_are_the_sections_coloured_as_in_the_app(sec) -> None:
    pts = sec.to_holoviews() if hasattr(sec, "to_holoviews") else drawing.draw(sec)
    traj, k, q, r = sec.long()
    np.testing.assert_array_equal(pts.dimension_values("q"), q)
    np.testing.assert_array_equal(pts.dimension_values("r"), r)
    np.testing.assert_array_equal(pts.dimension_values("traj"), traj)
    np.testing.assert_array_equal(pts.dimension_values("k"), k)
    # The app's mapper: palette TRAJ_PALETTE over 0..N_COLORS-1 on traj % N_COLORS, i.e. palette[traj % 20].
    np.testing.assert_array_equal(pts.dimension_values("colour"), np.asarray(views.TRAJ_PALETTE)[traj % views.N_COLORS])
    fig = render(pts)
    np.testing.assert_array_equal(drawn_colours(fig), np.asarray(views.TRAJ_PALETTE)[traj % views.N_COLORS])
    (hover,) = hovers(fig)
    assert [name for name, _ in hover.tooltips] == ["trajectory", "k", "q, r"]
    assert f"{traj.size} points of 25 trajectories" in pts.opts.get().kwargs["title"]


def test_a_large_section_is_thinned_and_says_so(sec) -> None:
    traj, _, q, _ = sec.long()
    pts = drawing.draw(sec, max_points=100)
    stride = -(-traj.size // 100)
    np.testing.assert_array_equal(pts.dimension_values("q"), q[::stride])
    assert f"every {stride}th of {traj.size} points drawn" in pts.opts.get().kwargs["title"]
    with pytest.raises(ParameterError, match="max_points must be a positive integer, got 0"):
        drawing.draw(sec, max_points=0)


def test_options_given_are_applied(sec) -> None:
    pts = drawing.draw(sec, width=333, title="mine")
    assert pts.opts.get().kwargs["width"] == 333 and pts.opts.get().kwargs["title"] == "mine"


def test_density_image_holds_the_counts_where_they_are() -> None:
    s = get_scene("fig1C")
    view = (*s.q_range, *s.r_range)
    d = density(s.params, s.initial_conditions()[:10], 60, view=view, pixels=(40, 30))
    img = drawing.draw(d)
    q0, q1, r0, r1 = view
    j, i = np.argwhere(d.counts > 0)[0]
    qc = q0 + (i + 0.5) * (q1 - q0) / 40
    rc = r0 + (j + 0.5) * (r1 - r0) / 30
    assert img[qc, rc] == d.counts[j, i]  # the pixel at (q, r) holds the count binned there (row 0 at the bottom)
    assert np.nansum(img.dimension_values("count")) == d.counts.sum() == d.in_view
    opts = img.opts.get().kwargs
    assert opts["logz"] and list(opts["cmap"]) == list(views.DENSITY_PALETTE)


def test_equilibria_are_diamonds_coloured_by_type_with_the_apps_words() -> None:
    e = equilibria(FIG8B.params, 0.3)
    ov = drawing.draw(e)
    got = {}
    for el in elements(ov):
        kind = el.label.removeprefix("frozen-field ")
        got[kind] = el
        assert el.opts.get().kwargs["color"] == views.TYPE_COLORS[kind]
        assert el.label == views.equilibrium_label(kind)
    for kind in set(e.types):
        m = np.array([t == kind for t in e.types])
        np.testing.assert_array_equal(got[kind].dimension_values("q"), e.q[m])
        np.testing.assert_array_equal(got[kind].dimension_values("r"), e.r[m])
    fig = render(ov)
    assert all(h.tooltips[0][0] == "frozen-field equilibrium" for h in hovers(fig))


def test_tracks_are_the_branches_split_by_type() -> None:
    tr = equilibrium_tracks(FIG8B.params, n_t=60)
    ov = drawing.draw(tr)
    drawn = sum(len(el.split()) for el in elements(ov))
    assert drawn == len(holo.track_segments(tr))
    legend = {item.label.value for lg in render(ov).legend for item in lg.items}
    assert legend == {el.label for el in elements(ov)}
    for el in elements(ov):
        kind = el.label.removeprefix("frozen-field ").removesuffix(" (track)")
        assert el.opts.get().kwargs["color"] == views.TYPE_COLORS[kind]
        for piece in el.split():
            q, r = piece.dimension_values("q"), piece.dimension_values("r")
            rows = np.flatnonzero(np.isin(tr.q, q) & np.isin(tr.r, r))
            assert rows.size >= q.size and {tr.types[i] for i in rows[1:-1]} <= {kind}


def test_tprime_image_is_the_map_with_a_symmetric_scale() -> None:
    m = tprime_map(FIG8B.params, 0.0, (-2, 1.5), (-3.5, 0.5), grid=(30, 20))
    img = drawing.draw(m)
    assert img[m.q[7], m.r[3]] == pytest.approx(m.values[3, 7])
    lo, hi = img.opts.get().kwargs["clim"]
    assert lo == -hi == -np.percentile(np.abs(m.values), 98)
    assert list(img.opts.get().kwargs["cmap"]) == list(views.TPRIME_PALETTE)


@pytest.fixture(scope="module")
def search():
    return find_orbits(FIG8B.params, [(-0.04, -2.40), (-1.457, -4.13)], [1])


def test_orbits_hover_shows_the_multipliers_first(search) -> None:
    assert search.orbits
    ov = drawing.draw(search)
    fig = render(ov)
    hv_tips = hovers(fig)
    assert hv_tips and all(h.tooltips[0][0] == "multipliers" for h in hv_tips)
    pts = [el for el in elements(ov) if el.label]
    qs = np.concatenate([el.dimension_values("q") for el in pts])
    assert sorted(qs) == sorted(float(q) for o in search.orbits for q in o.points[:, 0])
    o = search.orbits[0]
    one = drawing.draw(o)
    mu = next(el for el in elements(one) if el.label).dimension_values("mu")[0]
    assert mu == holo.mu_text(o.multipliers)
    for el in pts:
        assert el.opts.get().kwargs["line_color"] == views.ORBIT_COLOUR


@pytest.fixture(scope="module")
def mans():
    orbit = saddle_orbit(FIG8B.params, (-0.04, -2.40), 1)
    return manifolds(FIG8B.params, orbit, length=2.0, view=(-2.0, 1.5, -3.5, 0.5))


def test_manifolds_are_their_pieces_in_their_colours(mans) -> None:
    ov = drawing.draw(mans)
    for kind in ("unstable", "stable"):
        (path,) = [el for el in elements(ov) if el.label == f"{kind} manifold"]
        assert path.opts.get().kwargs["color"] == views.MANIFOLD_COLOURS[kind]
        pieces = [p for b in mans.branches if b.kind == kind for p in b.pieces if p.shape[0] > 1]
        got = path.split()
        assert len(got) == len(pieces)
        for g, p in zip(got, pieces, strict=True):
            np.testing.assert_array_equal(g.dimension_values("q"), p[:, 1])
            np.testing.assert_array_equal(g.dimension_values("r"), p[:, 2])
    legend = {item.label.value for lg in render(ov).legend for item in lg.items}
    assert {"unstable manifold", "stable manifold", views.orbit_label(mans.orbit.kind)} <= legend
    # The saddle itself is drawn, as an orbit of the map (a cross).
    assert any(el.label == views.orbit_label(mans.orbit.kind) for el in elements(ov))


def test_section_overlays_orbits_and_manifolds_and_lays_out_beside_others(sec, search, mans) -> None:
    ov = drawing.draw(sec) * drawing.draw(search) * drawing.draw(mans)
    assert isinstance(ov, hv.Overlay) and len(ov) == 1 + len(elements(drawing.draw(search))) + len(
        elements(drawing.draw(mans))
    )
    layout = ov + drawing.draw(tprime_map(FIG8B.params, 0.0, (-2, 1.5), (-3.5, 0.5), grid=10))
    assert isinstance(layout, hv.Layout) and len(layout) == 2
    render(layout)  # draws


def test_lyapunov_convergence_is_the_running_estimate() -> None:
    res = lyapunov_spectrum(FIG8B.params, [(-0.5, -2.0), (-0.4, -2.1)], 60, transient=20)
    ov = drawing.draw(res)
    curves = [el for el in elements(ov) if isinstance(el, hv.Curve)]
    assert len(curves) == 4
    l1 = curves[0]
    k = l1.dimension_values("k").astype(int)
    np.testing.assert_allclose(l1.dimension_values("Λ1"), res.running(0)[k - 1, 0])
    assert k[0] == 1 and k[-1] == 60
    assert curves[0].opts.get().kwargs["color"] == holo.PAIR_COLOURS[0]
    assert curves[1].opts.get().kwargs["color"] == holo.PAIR_COLOURS[1]
    lines = [el for el in elements(ov) if isinstance(el, hv.HLine)]
    assert [ln.data for ln in lines] == pytest.approx(list(res.mean()))


def test_orbit_diagram_is_the_drawn_points() -> None:
    d = bifurcation_diagram(FIG10, "alpha", np.linspace(-0.37, -0.36, 3), points=10, transient=30,
                            ics=[(-0.09, -2.0)])  # fmt: skip
    pts = drawing.draw(d, coord="r")
    s, _, value, _, _, _, r = d.long()
    np.testing.assert_array_equal(pts.dimension_values("alpha"), value)
    np.testing.assert_array_equal(pts.dimension_values("r_k"), r)
    np.testing.assert_array_equal(
        pts.dimension_values("colour"), np.asarray(holo.PAIR_COLOURS)[(d.sweeps[s] == "backward").astype(int)]
    )
    # One sweep alone (a constant colour column, which a colour mapper once drew as nothing) is drawn in its colour.
    one = dataclasses.replace(d, sweeps=d.sweeps[:1], points=d.points[:1], npts=d.npts[:1], status=d.status[:1],
                              final=d.final[:1])  # fmt: skip
    assert set(drawn_colours(render(drawing.draw(one)))) == {holo.PAIR_COLOURS[0]}
    with pytest.raises(ParameterError, match="coord must be 'q' or 'r', got 'x'"):
        drawing.draw(d, coord="x")


@pytest.fixture(scope="module")
def cascade():
    return continue_orbit(FIG10, "alpha", (-0.35, -0.38), (-0.0959, -1.962), 1, switch=True, max_period=4)


def test_continued_branches_split_by_stability_and_bifurcations_marked(cascade) -> None:
    ov = drawing.draw(cascade)
    by_label = {el.label: el for el in elements(ov)}
    assert cascade.bifurcations and set(by_label) >= {"bifurcations"}
    bif = by_label["bifurcations"]
    np.testing.assert_array_equal(bif.dimension_values("alpha"), [b.value for b in cascade.bifurcations])
    np.testing.assert_array_equal(bif.dimension_values("q"), [b.point[0] for b in cascade.bifurcations])
    n_points = 0
    for label, stable in (("stable orbits", True), ("unstable orbits", False)):
        for piece in by_label[label].split() if label in by_label else []:
            br = cascade.branches[int(piece.dimension_values("branch")[0])]
            x = piece.dimension_values("alpha")
            idx = [br.values.index(v) for v in x]
            # every point but the one shared with the next run has the piece's stability
            assert {bool(br.stable[i]) for i in idx[:-1]} == {stable}
            n_points += len(idx) - 1
    assert n_points >= cascade.n_points - 2 * len(cascade.branches)
    legend = {item.label.value for lg in render(ov).legend for item in lg.items}
    assert {"stable orbits", "bifurcations"} <= legend
    tips = [
        h.tooltips for h in hovers(render(ov)) if "bifurcation" not in str(h.tooltips) and "kind" in str(h.tooltips)
    ]
    assert tips and "of the period-" in tips[0][0][1] and tips[0][-1][0] == "multipliers"


def test_chart_pixels_are_the_apps_colour_indices_and_curves_overlay() -> None:
    spec = chart_spec(FIG11, "alpha", (-0.6, -0.36), "I11", (1.0, 2.0), (6, 5), ics=[(-0.09, -2.0)], transient=60,
                      periods=40, p_max=8)  # fmt: skip
    chart = regime_chart(spec, workers=1)
    img = drawing.draw(chart)
    code = chart.code()[..., 0]
    for j, i in [(0, 0), (4, 5), (2, 3)]:
        x, y = spec.x_values[i], spec.y_values[j]
        idx = img[x, y].dimension_values("colour")[0]  # the pixel at (x, y)
        colour = holo.CHART_PALETTE[int(idx)]
        if code[j, i] > 0:
            assert colour == CHART_LEGEND[min(code[j, i], 16) - 1][1]
        else:
            name = REGIMES[-code[j, i]].replace("_", "-")
            assert (name, colour) in CHART_LEGEND
    regime = img.dimension_values("regime", flat=False)
    assert sorted(set(regime.ravel())) == sorted({REGIMES[c] for c in chart.regime[..., 0].ravel()})
    two = continue_orbit(FIG10, "alpha", (-0.35, -0.42), (-0.0959, -1.962), 1, param2="I11", range2=(0.9, 1.3))
    curves = drawing.draw(two)
    lines = [el for el in elements(curves) if el.label]
    words = {holo.curve_words(c.kind, c.period): CURVE_STYLE[c.kind][0] for c in two.curves}
    assert lines and all(el.opts.get().kwargs["color"] == words[el.label] for el in lines)
    assert isinstance(img * curves, hv.Overlay)


def test_basins_image_colours_each_attractor_as_the_app() -> None:
    b = basins(FIG11.with_(I11=1.6, alpha=-0.5), (-1.7, 1.5, -3.0, 1.0), (12, 12))
    ov = drawing.draw(b)
    img = elements(ov)[0]
    labels = b.filled()
    np.testing.assert_array_equal(img.dimension_values("basin", flat=False), labels)
    colours = holo.basin_colours(b)
    cmap = img.opts.get().kwargs["cmap"]
    codes = sorted(colours)
    for j, i in [(0, 0), (5, 7), (11, 11)]:
        assert cmap[int(img.dimension_values("colour", flat=False)[j, i])] == colours[labels[j, i]]
        assert img[b.q[i], b.r[j]].dimension_values("basin")[0] == labels[j, i]  # row 0 at the bottom
    for n, a in enumerate(b.attractors):
        assert colours[a.id] == BASIN_COLOURS[n % len(BASIN_COLOURS)]
    assert len(codes) == len(cmap)
    assert [el.label for el in elements(ov)[1:]] == [holo.basin_words(b, a) for a in b.attractors
                                                     if a.kind != "escape" and len(a.points)]  # fmt: skip


def test_every_result_class_draws_itself_without_the_core_importing_holoviews(sec) -> None:
    for cls in holo.DRAWERS:
        assert issubclass(cls, drawing.Drawable), cls
    pts = sec.to_holoviews(width=300)
    np.testing.assert_array_equal(pts.dimension_values("q"), sec.long()[2])
    code = (
        "import sys; from explorer_core.solve.section import Section; import explorer_core.analyses.basins;"
        "print('holoviews' in sys.modules, 'app' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True,
                         timeout=300)  # fmt: skip
    assert out.stdout.split() == ["False", "False"]


def test_an_installed_entry_point_is_found_without_importing_app_holo(tmp_path: Path) -> None:
    # A distribution on the path that declares the drawers as pyproject.toml does (as `pip install .` writes it).
    dist = tmp_path / "bilimovich_probe-0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: bilimovich-probe\nVersion: 0\n", encoding="utf-8")
    (dist / "entry_points.txt").write_text(f"[{drawing.ENTRY_POINT_GROUP}]\nholoviews = app.holo:register\n",
                                           encoding="utf-8")  # fmt: skip
    code = (
        "import sys, numpy as np; from explorer_core.analyses.equilibria import Equilibria\n"
        "e = Equilibria(0.0, np.array([0.5]), np.array([1.0]), np.zeros((1, 2), complex), ('saddle',))\n"
        "assert 'app.holo' not in sys.modules\n"
        "ov = e.to_holoviews()\n"
        "print(type(ov).__name__, 'app.holo' in sys.modules, list(ov)[0].dimension_values('q'))"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["Overlay", "True", "[0.5]"]


def test_an_ftle_map_draws_its_values_with_the_pixels_without_one_blank() -> None:
    from app.views import FTLE_PALETTE
    from explorer_core.analyses.ftle import ftle_map
    from explorer_core.status import Status

    m = ftle_map(FIG8B.params, (-1.5, 0.5, -3.0, -1.0), grid=(8, 6), periods=3, direction="both")
    status = m.status_backward.copy()
    status[2, 5] = Status.ESCAPED  # as a pixel that left the bound: no value, said in the title
    m = dataclasses.replace(m, status_backward=status)
    lay = m.to_holoviews()
    fwd, bwd = list(lay)
    for img, values, st, d in ((fwd, m.forward, m.status_forward, "forward"), (bwd, m.backward, status, "backward")):
        drawn = img.dimension_values("ftle", flat=False)
        np.testing.assert_array_equal(drawn[st == Status.OK], values[st == Status.OK])  # rows: r ascending
        assert np.isnan(drawn[st != Status.OK]).all()
        for j, i in [(0, 0), (4, 6)]:  # row 0 at the bottom, at the pixels' centres
            assert img[m.q[i], m.r[j]] == pytest.approx(values[j, i])
        opts = img.opts.get().kwargs
        assert opts["cmap"] == list(FTLE_PALETTE) and opts["title"].startswith(f"FTLE {d} over 3 periods (8 x 6")
    assert "no exponent: 1 escaped" in bwd.opts.get().kwargs["title"]
    assert "no exponent" not in fwd.opts.get().kwargs["title"]
    render(lay)


def test_the_indicators_verdicts_draw_in_their_colours() -> None:
    from explorer_core.analyses.indicators import VERDICTS, birkhoff, sali

    fig5a = get_scene("fig5A").params
    ics = [(0.4, 0.0), (0.05, 0.02)]
    b = birkhoff(fig5a, ics, 100, regular_digits=5.0)
    ov = b.to_holoviews()
    for el in elements(ov):
        code = VERDICTS.index(el.label.split(" (")[0])
        assert el.opts.get().kwargs["color"] == holo.VERDICT_COLOURS[code]
        mine = b.verdict == code
        np.testing.assert_array_equal(el.dimension_values("q"), np.asarray(ics)[mine, 0])
        np.testing.assert_array_equal(el.dimension_values("digits"), b.digits[mine])
    assert sum(len(el) for el in elements(ov)) == 2
    s = sali(FIG8B.params, [(-1.0, -2.0)], 50, transient=100)
    (curve,) = elements(s.to_holoviews())
    n = int(s.npts[0])
    np.testing.assert_array_equal(curve.dimension_values("SALI"), s.alignment.sali[0, :n])
    assert curve.label == VERDICTS[int(s.verdict[0])]
    assert curve.opts.get().kwargs["color"] == holo.VERDICT_COLOURS[int(s.verdict[0])]
    render(ov)
    render(curve)


def test_curves_are_dashed_by_period_and_their_codimension_two_points_marked() -> None:
    """Fails on the old code (every period-doubling curve the same black line, no marks): the Henon map's flip
    curves of its cascade's orbits (switched onto the doubled orbits), each period its dash, and their
    points a marker per kind, each once, hover with the kind, period, values and error."""
    from app.analyses import CODIM2_STYLE, codim2_points, curve_dash
    from explorer_core.analyses.continuation import Boundaries, continue_map
    from explorer_core.analyses.continuation.results import CODIM2_NAMES
    from explorer_core.analyses.continuation.testmaps import Henon

    res = continue_map(Henon(b=0.3), "a", (0.2, 1.5), Henon.fixed_point(0.2, 0.3), 1, param2="b",
                       range2=(-1.5, 0.6), window1=(-2.0, 5.0), switch=True)  # fmt: skip
    ov = holo.draw_curves(Boundaries([res, res]))  # twice: each point drawn once still
    lines = [el for el in elements(ov) if isinstance(el, hv.Curve) and el.label]
    dash = {el.label: el.opts.get().kwargs["line_dash"] for el in lines}
    cascade = sorted({cu.period for cu in res.curves if cu.kind == "period_doubling"})
    assert cascade == [1, 2, 4, 8, 16]  # each its own dash
    assert len({dash[holo.curve_words("period_doubling", p)] for p in cascade}) == len(cascade)
    assert all(dash[holo.curve_words("period_doubling", p)] == curve_dash(p) for p in cascade)
    marks = {el.label: el for el in elements(ov) if isinstance(el, hv.Points)}
    kinds = {c.kind for cu in res.curves for c in cu.codim2}
    assert set(marks) == {f"{k} ({CODIM2_NAMES[k]})" for k in kinds} and {"R2", "R3", "R4"} <= kinds
    r2 = marks["R2 (1:2 resonance)"]
    o = r2.opts.get().kwargs
    assert (o["marker"], o["color"]) == CODIM2_STYLE["R2"]
    located = [c for cu in res.curves for c in cu.codim2 if c.kind == "R2"]
    once = [c for c in codim2_points([res]) if c.kind == "R2"]  # an R2 on a flip curve where a NS curve ends: once
    periods = [int(p.split("period-")[1].split()[0]) for p in r2.dimension_values("point")]
    assert len(r2) == len(once) < len(located) and periods == [c.period for c in once]
    assert sorted(periods) == sorted(set(periods))  # the Henon map has one R2 per period on b = -1
    assert (3.0, -1.0) == pytest.approx((r2.dimension_values("a")[0], r2.dimension_values("b")[0]), abs=1e-6)
    tips = [h.tooltips for h in hovers(render(ov)) if "@{point}" in str(h.tooltips)]
    assert tips and ("error estimate", "@{error}") in tips[0]
    title = hv.Store.lookup_options("bokeh", ov, "plot").kwargs["title"]
    assert title.endswith(f"{2 * len(res.curves)}, {sum(len(m) for m in marks.values())} codimension-two points")


def test_a_figure_thins_x_ticks_that_would_run_together() -> None:
    """Fails on the old code: the chart figure at 1600x1000 (200 dpi) beside its legend wrote -0.600-0.575-0.550...
    run together. Here a narrow axes: after the thinning no two labels overlap, and a wide one keeps its ticks."""
    import itertools

    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator, MultipleLocator

    from app.figures import _fewer_ticks

    def labels_apart(fig) -> bool:
        fig.draw_without_rendering()
        ax = fig.axes[0]
        lo, hi = sorted(ax.get_xlim())
        boxes = sorted((t.get_window_extent() for t, x in zip(ax.get_xticklabels(), ax.get_xticks(), strict=True)
                        if t.get_text() and lo <= x <= hi), key=lambda b: b.x0)  # fmt: skip
        return len(boxes) >= 2 and all(a.x1 < b.x0 for a, b in itertools.pairwise(boxes))

    narrow = Figure(figsize=(6, 4), dpi=200, layout="constrained")
    ax = narrow.add_gridspec(1, 3)[0, 0]
    ax = narrow.add_subplot(ax)
    ax.plot([-0.6, -0.4], [1, 2])
    ax.xaxis.set_major_locator(MaxNLocator(nbins=8, steps=[1, 2.5, 5, 10]))  # the chart's -0.600, -0.575, ...
    ax.tick_params(labelsize=10)
    narrow.add_subplot(narrow.add_gridspec(1, 3)[0, 1:]).axis("off")
    assert not labels_apart(narrow)
    assert _fewer_ticks(narrow)
    assert labels_apart(narrow)
    other = Figure(figsize=(8, 5), dpi=200, layout="constrained")  # a locator without bins: left as it is
    ax = other.add_subplot(other.add_gridspec(1, 3)[0, 0])
    ax.plot([-0.6, -0.4], [1, 2])
    ax.xaxis.set_major_locator(MultipleLocator(0.025))
    other.draw_without_rendering()
    assert not _fewer_ticks(other)
    assert isinstance(ax.xaxis.get_major_locator(), MultipleLocator)
    wide = Figure(figsize=(8, 5), dpi=100, layout="constrained")
    wide.add_subplot().plot([-0.6, -0.4], [1, 2])
    wide.draw_without_rendering()
    before = list(wide.axes[0].get_xticks())
    assert not _fewer_ticks(wide)
    wide.draw_without_rendering()
    assert list(wide.axes[0].get_xticks()) == before


def test_a_figure_draws_bokeh_dash_patterns() -> None:
    from app.figures import _dash

    assert _dash("dashed", 1.65) == "--" and _dash("solid", 1.0) == "-"
    assert _dash("8 4", 1.5) == (0, (4.0, 2.0))  # 8 px = 6 pt = 4 line widths of 1.5 pt
    assert _dash("8 3 2", 1.5) == "-"  # not a pattern of pairs
