"""The layered core: every import (inside functions too) goes to the same floor or one below, never up.

Floors, bottom to top (docs/architecture.md): config -> system -> solve -> scenes -> parallel ->
analyses -> studies -> reports -> warm, cli. Within a floor modules may import each other, without a
cycle. ``app`` is web only: it uses the core and never numba or matplotlib directly.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FLOORS = (
    ("config", "losses", "progress", "export", "status", "drawing", "registry", "launch", "allocator"),
    ("system",),
    ("solve",),
    ("scenes",),
    ("parallel",),
    ("analyses",),
    ("studies",),
    ("reports",),
    ("warm", "worker", "cli", "__main__"),
)


def modules(package: str) -> dict[str, Path]:
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imports(mod: str, path: Path, known: set[str]) -> set[str]:
    """Modules of the project that ``mod`` imports anywhere in its file (the longest known name)."""
    out = set()
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = mod.split(".")[: None if is_pkg else -1]
                base_parts = base_parts[: len(base_parts) - (node.level - 1)]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != mod:
                out.add(t)
    return out


def floor(mod: str) -> int:
    part = mod.split(".")[1]
    for n, names in enumerate(FLOORS):
        if part in names:
            return n
    raise AssertionError(f"{mod} is on no floor: add it to FLOORS and docs/architecture.md")


CORE = modules("explorer_core")
APP = modules("app")
KNOWN = set(CORE) | set(APP)
EDGES = {m: imports(m, p, KNOWN) for m, p in {**CORE, **APP}.items()}


def test_every_core_import_goes_down_or_sideways() -> None:
    upward = []
    for mod in CORE:
        if mod == "explorer_core":
            continue
        for t in EDGES[mod]:
            if t == "explorer_core":  # the package itself (its __init__ re-exports Params)
                continue
            assert not t.startswith("app"), f"{mod} imports {t}: the core never imports the app"
            if floor(t) > floor(mod):
                upward.append(f"{mod} (floor {floor(mod)}) -> {t} (floor {floor(t)})")
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_no_import_cycle() -> None:
    graph = {m: {t for t in ts if t in CORE and t != "explorer_core"} for m, ts in EDGES.items() if m in CORE}
    graph.pop("explorer_core")
    state: dict[str, int] = {}

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*path[path.index(t) :], t]))
            if t not in state:
                visit(t, [*path, t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


def test_analyses_get_the_dask_executor_passed_in() -> None:
    for mod in CORE:
        if mod.startswith("explorer_core.analyses"):
            assert "explorer_core.parallel.cluster" not in EDGES[mod], mod


def test_the_app_is_web_only() -> None:
    for mod, path in APP.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        names |= {(n.module or "").split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert not names & {"numba", "matplotlib", "scipy"}, f"{mod} imports {names & {'numba', 'matplotlib', 'scipy'}}"


@pytest.mark.parametrize(
    ("code", "absent"),
    [
        # `bilimovich --help` answers without the compiler or any analysis.
        (
            "import sys; from explorer_core.cli import build_parser; build_parser()",
            ("numba", "explorer_core.analyses", "explorer_core.solve.rk", "panel", "dask"),
        ),
        # The web app's state and controller load no offline study, no matplotlib, no scipy.integrate.
        (
            "import app.controller, app.state",
            ("explorer_core.studies", "matplotlib", "scipy.integrate", "explorer_core.reports"),
        ),
    ],
)
def test_what_is_imported_is_what_is_used(code: str, absent: tuple[str, ...]) -> None:
    probe = f"{code}; import sys; print(' '.join(m for m in {absent!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"loaded: {out.stdout.strip()}"
