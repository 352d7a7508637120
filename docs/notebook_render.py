"""Execute examples/paper_story.ipynb and render it to docs/notebook_paper_story.html (+ a screenshot).

    PYTHONPATH=. .venv/bin/python docs/notebook_render.py [--no-screenshot]

The notebook inlines BokehJS and Panel (``hv.extension("bokeh", inline=True)``, ``pn.extension(inline=True)``),
the stylesheets HoloViews' renderer leaves on the CDN become data: URLs of Panel's own files, and the HTML
is written with ``docs/notebook_offline.html.j2`` (the lab template without require.js, MathJax and
mermaid), so the page loads nothing from the internet: checked before it is written. The screenshot is
taken with Debian's chromium through Playwright, offline (every request to another host is refused).
"""

from __future__ import annotations

import argparse
import base64
import os
import re
import sys
import time
from pathlib import Path

import nbclient
import nbformat
from nbconvert import HTMLExporter

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "paper_story.ipynb"
HTML = ROOT / "docs" / "notebook_paper_story.html"
PNG = ROOT / "docs" / "notebook_paper_story.png"
#: What a page fetches from another host: a script or stylesheet tag, the notebook loader's URL lists, a
#: Bokeh stylesheet model (its URL is loaded when the plot is drawn). A URL in text or in code that only a
#: feature not used here would fetch (MathJax, an icon font) is not a load.
REMOTE = (
    re.compile(r"""<(?:script|link)\b[^>]*(?:src|href)\s*=\s*["']?(?:https?:)?//[^"'>\s]*""", re.I),
    re.compile(r"""(?:js_urls|css_urls|js_modules)\s*=\s*\[[^\]]*?(?:https?:)?//[^"'\s]*"""),
    re.compile(r"""ImportedStyleSheet[^}]{0,200}?https?://[^"'&\s\\]*"""),
)


def inline_stylesheets(nb: nbformat.NotebookNode) -> int:
    """Panel's stylesheets that HoloViews' renderer leaves on the CDN, as data: URLs of Panel's own files.

    (Panel inlines its components' stylesheets with ``inline=True``; a HoloViews plot rendered in a notebook
    keeps ``ImportedStyleSheet`` URLs on cdn.holoviz.org.) Returns how many were replaced.
    """
    from panel.io.resources import CDN_DIST, DIST_DIR

    pattern = re.compile(re.escape(CDN_DIST) + r"([A-Za-z0-9_./@^-]+\.css)")
    count = 0

    def data_url(m: re.Match) -> str:
        nonlocal count
        path = DIST_DIR / m.group(1)
        if not path.is_file():
            return m.group(0)
        count += 1
        return "data:text/css;base64," + base64.b64encode(path.read_bytes()).decode("ascii")

    for cell in nb.cells:
        for out in cell.get("outputs", []):
            for mime, value in out.get("data", {}).items():
                if isinstance(value, str) and CDN_DIST in value:
                    out["data"][mime] = pattern.sub(data_url, value)
    return count


def execute(path: Path) -> nbformat.NotebookNode:
    nb = nbformat.read(path, as_version=4)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    client = nbclient.NotebookClient(
        nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}
    )
    client.start_new_kernel = _with_env(client.start_new_kernel, env)
    client.execute(env=env)
    return nb


def _with_env(start, env):
    def start_new_kernel(**kw):
        return start(**{**kw, "env": env})

    return start_new_kernel


def remote_loads(html: str) -> list[str]:
    """Every script or stylesheet the page would fetch from the internet."""
    return sorted({m.group(0)[-160:] for pattern in REMOTE for m in pattern.finditer(html)})


def render(nb: nbformat.NotebookNode) -> str:
    exporter = HTMLExporter(template_name="lab", extra_template_paths=[str(ROOT / "docs")])
    exporter.template_file = "notebook_offline.html.j2"
    html, _ = exporter.from_notebook_node(nb, resources={"metadata": {"name": "The paper's story in code"}})
    return html


def screenshot(html_path: Path, png_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium",
                                     args=["--headless", "--no-sandbox", "--disable-gpu"])  # fmt: skip
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.route(re.compile(r"^https?://"), lambda route: route.abort())  # offline: nothing from the internet
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(html_path.as_uri())
        page.wait_for_selector(".bk-Canvas, .bk-canvas, canvas", timeout=60_000)
        time.sleep(3)  # the plots finish drawing
        page.screenshot(path=str(png_path), full_page=True)
        browser.close()
        if errors:
            print("page errors:", *errors[:5], sep="\n  ", file=sys.stderr)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-screenshot", action="store_true")
    args = ap.parse_args()
    t = time.perf_counter()
    nb = execute(NOTEBOOK)
    print(f"executed in {time.perf_counter() - t:.1f} s")
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    if errors:
        sys.exit(f"the notebook failed: {errors[0].ename}: {errors[0].evalue}")
    print(f"{inline_stylesheets(nb)} stylesheets inlined")
    html = render(nb)
    remote = remote_loads(html)
    if remote:
        sys.exit("the page would load from the internet:\n  " + "\n  ".join(remote))
    HTML.write_text(html, encoding="utf-8")
    print(f"wrote {HTML.relative_to(ROOT)} ({len(html) / 1e6:.1f} MB), no remote scripts")
    if not args.no_screenshot:
        screenshot(HTML, PNG)
        print(f"wrote {PNG.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
