"""The explorer in a notebook: the inline component (app/notebook.py) and the example notebook, executed.

The component is the served page built in the kernel: its state is read and set from Python (a set value
is checked as a typed one and recomputes), a shared link's state loads into it. The example notebook
(examples/paper_story.ipynb, outputs not stored) runs top to bottom with nbclient in a fresh kernel, and its
rendering in docs/ loads nothing from the internet.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from jobs import Jobs

from app.notebook import Explorer, query_of_url, text_of
from app.runner import WARM
from explorer_core.system.params import ParameterError

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "paper_story.ipynb"
SMALL = {"n": ["2"], "periods": ["5"]}


@pytest.fixture(autouse=True)
def _warm() -> None:
    WARM.set()


def explorer(scene: str = "fig8B", **query: str) -> tuple[Explorer, Jobs]:
    jobs = Jobs()
    ex = Explorer(scene, query={**SMALL, **{k: [v] for k, v in query.items()}}, deliver=lambda fn: fn(),
                  executor=jobs)  # fmt: skip
    jobs.drain()
    return ex, jobs


def test_state_reads_the_values_in_use_and_a_set_value_recomputes() -> None:
    ex, jobs = explorer()
    assert ex.state.alpha == -0.45 and ex.state.scene == "fig8B"
    before = ex.page.session.system()
    assert before is not None and before.alpha == -0.45
    ex.state.alpha = -0.41
    jobs.drain()
    assert ex.state.alpha == -0.41 and ex.state.scene == "custom"  # as a typed value on the page
    assert ex.page.session.system().alpha == -0.41  # the section on screen is of the new system
    assert "alpha=-0.41" in ex.url
    ex.state.update(periods=7, q_range=(-1.5, 1.0))
    jobs.drain()
    assert ex.state.periods == 7 and ex.state.q_range == (-1.5, 1.0)
    assert (ex.page.fig.x_range.start, ex.page.fig.x_range.end) == (-1.5, 1.0) and "qr=-1.5,1" in ex.url
    ex.state.tab = "lyapunov"
    assert ex.page.ui.tab == "lyapunov" and "lyapunov" in ex.page.tabs


def test_a_refused_value_raises_with_the_pages_message_and_changes_nothing() -> None:
    ex, jobs = explorer()
    with pytest.raises(ParameterError, match=r"still using"):
        ex.state.periods = 0
    assert ex.state.periods == 5
    with pytest.raises(ParameterError, match=r"must be finite|number"):
        ex.state.alpha = float("nan")
    assert ex.state.alpha == -0.45
    with pytest.raises(ParameterError, match="q_range must be finite with lo < hi"):
        ex.state.q_range = (1.0, -1.0)
    with pytest.raises(ParameterError, match="tab must be one of"):
        ex.state.tab = "nowhere"
    with pytest.raises(AttributeError, match="'colour' is not a setting"):
        ex.state.colour = 1
    with pytest.raises(AttributeError, match="has no 'colour'"):
        _ = ex.state.colour
    with pytest.raises(ParameterError, match="scene must be a scene's id"):
        Explorer(8, start=False)  # type: ignore[arg-type]


def test_a_shared_link_loads_its_state_and_reports_what_it_refused() -> None:
    ex, _ = explorer(alpha="-0.41")
    link = "http://localhost:5006/app" + ex.url
    jobs = Jobs()
    again = Explorer.from_url(link, deliver=lambda fn: fn(), executor=jobs)
    jobs.drain()
    assert again.state.as_dict() == ex.state.as_dict()
    assert again.url == ex.url
    bad = Explorer.from_url("?scene=fig8B&periods=-3", start=False)
    assert bad.state.periods == 1000 and any("periods" in e for e in bad.url_errors)
    assert query_of_url("?a=1&b=") == {"a": ["1"], "b": [""]}
    with pytest.raises(ParameterError, match="url must be a string, got 3"):
        Explorer.from_url(3)  # type: ignore[arg-type]


def test_wait_runs_the_results_delivered_to_the_kernel_until_the_section_is_done() -> None:
    later: list = []  # a kernel's loop that never gets to run: wait() must run the results itself
    ex = Explorer("fig8B", query=SMALL, deliver=later.append)
    assert ex.wait(timeout=120) and not ex.running()
    assert ex.page.session.n_points == 2 * 5 and ex.page.session.system().alpha == -0.45
    for fn in later:  # the loop's turn comes later: nothing left to run
        fn()
    with pytest.raises(ParameterError, match="timeout must be a positive number of seconds, got 0"):
        ex.wait(timeout=0)


def test_values_become_the_text_a_control_takes() -> None:
    assert text_of(-0.41) == "-0.41" and text_of(0.1 + 0.2) == "0.30000000000000004"
    assert text_of((1.0, 2.5)) == "1.0,2.5" and text_of([(0.1, 2.0), (3.0, -1.0)]) == "0.1,2.0;3.0,-1.0"
    assert text_of(True) == "true" and text_of(5) == "5"


def test_the_component_renders_as_the_page() -> None:
    ex, _ = explorer()
    assert ex.__panel__() is ex.page.ui
    import panel as pn

    root = pn.panel(ex).get_root()  # what a notebook's cell output is built from
    assert root.select_one({"name": "section_figure"}) is not None
    assert hasattr(ex, "_repr_mimebundle_")


# ---------------------------------------------------------------------------
# The example notebook.


def test_the_example_notebook_stores_no_outputs() -> None:
    nb = json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    cells = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert cells and all(not c["outputs"] and c["execution_count"] is None for c in cells)


@pytest.mark.slow
def test_the_example_notebook_runs() -> None:
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    env_path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    os.environ["PYTHONPATH"] = env_path  # the kernel imports this checkout's explorer_core and app
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}
    )
    client.kernel_manager_class = "jupyter_client.manager.KernelManager"
    client.execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    # Every result drew itself: the cells that end with a picture show one (HoloViews' bokeh output).
    shown = [c for c in nb.cells if c.cell_type == "code" and any("data" in o for o in c.outputs)]
    assert len(shown) >= 6


def test_the_rendered_notebook_loads_nothing_from_the_internet() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("notebook_render", ROOT / "docs" / "notebook_render.py")
    render = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(render)  # type: ignore[union-attr]
    html = (ROOT / "docs" / "notebook_paper_story.html").read_text(encoding="utf-8")
    assert render.remote_loads(html) == []
    # The check finds what nbconvert's lab template and HoloViews' renderer load by default.
    page = '<script src="https://cdnjs.cloudflare.com/ajax/libs/require.js/2.1.10/require.min.js"></script>'
    page += '{"name":"ImportedStyleSheet","id":"p1","attributes":{"url":"https://cdn.holoviz.org/panel/x/a.css"}}'
    page += 'var js_urls = ["https://cdn.bokeh.org/bokeh/release/bokeh-3.9.2.min.js"];'
    assert len(render.remote_loads(page)) == 3
