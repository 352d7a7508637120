"""Serve the app and drive it in Debian's Chromium with Playwright (tests, latency and load benchmarks)."""

from __future__ import annotations

import contextlib
import os
import re
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


#: The log of the app served last (:func:`serve`): a wait that times out quotes its end (what the jobs did).
SERVED_LOG: list[str] = []


def log_tail(lines: int = 40) -> str:
    """The last ``lines`` lines of the served app's log (with the runner's job trace), or ""."""
    if not SERVED_LOG or SERVED_LOG[-1] == os.devnull:
        return ""
    try:
        text = Path(SERVED_LOG[-1]).read_text(errors="replace").splitlines()
    except OSError:
        return ""
    return "\nthe server's log ends with:\n" + "\n".join(text[-lines:])


class Server(NamedTuple):
    url: str
    pid: int
    log_path: str


@contextlib.contextmanager
def serve(
    log_path: str | None = None,
    threads: int = 4,
    env: dict[str, str] | None = None,
    session_lifetime: int = 15000,
    procs: int = 1,
) -> Iterator[Server]:
    """Run ``bilimovich serve`` on a free port until /liveness answers (it execs the server: same pid;
    with ``procs`` > 1 that pid is the parent of the workers, see :func:`tree_pids`)."""
    port = free_port()
    log = open(log_path or os.devnull, "w")
    # The same entry point users run (bilimovich serve execs panel serve with the project's flags).
    cmd = [
        sys.executable, "-m", "explorer_core.cli", "serve", "--port", str(port), "--address", "127.0.0.1",
        "--allow-websocket-origin", f"127.0.0.1:{port}", "--allow-websocket-origin", f"localhost:{port}",
        "--threads", str(threads), "--session-lifetime", str(session_lifetime), "--procs", str(procs),
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, **(env or {})})
    try:
        deadline = time.time() + 180
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/liveness", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if proc.poll() is not None or time.time() > deadline:
                raise RuntimeError(f"the server did not start (exit {proc.poll()}); see {log_path}")
            time.sleep(0.3)
        SERVED_LOG.append(log_path or os.devnull)
        yield Server(f"http://127.0.0.1:{port}/main", proc.pid, log_path or os.devnull)
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


def tree_pids(pid: int) -> list[int]:
    """A process and its children (the workers of ``--procs N``), from /proc."""
    out = [pid]
    with contextlib.suppress(OSError):
        for task in os.listdir(f"/proc/{pid}/task"):
            with contextlib.suppress(OSError, ValueError):
                out += [int(c) for c in Path(f"/proc/{pid}/task/{task}/children").read_text().split()]
    return out


@contextlib.contextmanager
def served_app(log_path: str | None = None, threads: int = 4, env: dict[str, str] | None = None) -> Iterator[str]:
    """:func:`serve`, yielding the app's URL."""
    with serve(log_path, threads, env) as server:
        yield server.url


def new_page(browser, width: int, height: int):
    """A page of its own browser context at ``width`` x ``height``; the errors it raises are kept in ``.errors``."""
    pg = browser.new_context(viewport={"width": width, "height": height}).new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.errors = errors
    return pg


# In-page probes (BokehJS models are looked up by the names set in app/views.py).
JS_COUNT = "() => Bokeh.documents[0].get_model_by_name('section_source').get_length()"

#: Watches the section source after a user action: time of the action (pointerup or
#: Enter), of the first animation frame holding points of the new generation (the
#: server stamps each reset in `tags`), and of the frame holding `expected` of them.
JS_INSTALL_PROBE = """
(expected) => {
  const src = Bokeh.documents[0].get_model_by_name('section_source');
  const gen0 = src.tags.length ? src.tags[0] : 0;
  const p = {t0: null, first: null, full: null, cleared: false};
  window.__probe = p;
  const mark = () => { if (p.t0 === null) p.t0 = performance.now(); };
  window.addEventListener('pointerup', mark, {capture: true, once: true});
  window.addEventListener('keydown', (e) => { if (e.key === 'Enter') mark(); }, {capture: true, once: true});
  // The server replaces the data (reset), then stamps a new generation; only points
  // streamed after both count.
  src.properties.data.change.connect(() => { if (p.t0 !== null) p.cleared = true; });
  const tick = () => {
    const fresh = p.cleared && src.tags.length && src.tags[0] !== gen0;
    const n = src.get_length();
    if (fresh) {
      if (n > 0 && p.first === null) p.first = performance.now();
      if (n >= expected && p.full === null) p.full = performance.now();
    }
    if (p.full === null) requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
}
"""
JS_READ_PROBE = "() => window.__probe"


def wait_points(page, n: int, timeout: float = 60.0) -> None:
    """Wait until the section source holds at least ``n`` points."""
    page.wait_for_function(f"() => Bokeh.documents.length && ({JS_COUNT})() >= {n}", timeout=timeout * 1000)


def frame_centre(page) -> dict[str, float]:
    """The centre of the section plot's frame (the data area, between the axes) in page coordinates."""
    return page.evaluate(
        """() => {
          const find = (v) => v.model.name === 'section_figure' ? v
                              : Array.from(v.child_views || []).map(find).find((x) => x) || null;
          const plot = Object.values(Bokeh.index).map(find).find((x) => x);
          const b = plot.frame.bbox;
          const r = plot.canvas_view.el.getBoundingClientRect();
          return {x: r.left + b.left + b.width / 2, y: r.top + b.top + b.height / 2};
        }"""
    )


def text(page, css: str) -> str:
    """Visible text of a Panel pane (its content lives in a shadow root)."""
    return page.locator(css).first.evaluate(
        "el => { const r = el.shadowRoot; if (!r) return el.innerText;"
        " return Array.from(r.children).filter(c => !['STYLE', 'LINK'].includes(c.tagName))"
        ".map(c => c.innerText).join('\\n'); }"
    )


def wait_text(page, css: str, words: str, timeout: float = 30.0) -> str:
    """Wait until the pane ``css`` shows ``words``; return its text."""
    deadline = time.time() + timeout
    while words not in (shown := text(page, css)):
        if time.time() > deadline:
            raise TimeoutError(f"{css} did not show {words!r}; it shows {shown!r}{log_tail()}")
        time.sleep(0.05)
    return shown


def wait_finished(page, timeout: float = 60.0) -> str:
    """Wait until the status line reports a finished run; return it."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        status = text(page, ".status-line")
        if re.search(r"\b1 trajectory\b|trajectories", status) and not status.startswith("computing"):
            return status
        time.sleep(0.1)
    raise TimeoutError(f"run did not finish; status {status!r}{log_tail()}")


def section_q(page) -> list[float]:
    return page.evaluate("() => Array.from(Bokeh.documents[0].get_model_by_name('section_source').data.q)")


def set_number(page, field: str, value: float | str) -> None:
    """Type a value into a control's box and press Enter, like a user."""
    box = page.locator(f".ctl-{field} input.num, .ctl-{field} input.txt").first
    box.fill(str(value))
    box.press("Enter")


def box_value(page, field: str) -> str:
    """What a control's box shows."""
    return page.locator(f".ctl-{field} input.num, .ctl-{field} input.txt").first.input_value()


def drag_slider(page, field: str, fraction: float) -> None:
    """Drag a slider's thumb to ``fraction`` of its track and release it."""
    rng = page.locator(f".ctl-{field} input[type=range]").first
    box = rng.bounding_box()
    lo, hi = float(rng.get_attribute("min")), float(rng.get_attribute("max"))
    v = float(rng.input_value())
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + (v - lo) / (hi - lo) * box["width"], y)
    page.mouse.down()
    page.mouse.move(box["x"] + fraction * box["width"], y, steps=8)
    page.mouse.up()
