"""Read the top-level Dockerfile and replay its install and start commands outside Docker.

No Docker engine runs in CI, so ``docker build`` is impossible. Instead the commands the
Dockerfile itself contains are taken from its text and run in a temporary directory that
stands in for the image's file system:

* every absolute path the image owns (``/opt/venv``, ``/src``, ``/home/...``: the first
  components used by WORKDIR, COPY, ENV and ``python -m venv``) is re-rooted under the
  temporary directory; ``python`` is the interpreter running the tests (the base image's);
* COPY takes files from the build context exactly as ``.dockerignore`` filters it;
* RUN commands are split at ``&&``; package and user administration (``useradd``,
  ``chown``, ``apt-get``, ...) is skipped, ``mkdir``, ``python``, ``pip`` and ``bilimovich``
  run with the stage's ENV; any other command is an error, so a new kind of RUN step has to
  be classified here rather than silently ignored; a replayed program must live under the
  temporary root (the base interpreter may only create a venv), so the host is never changed;
* a new stage starts without the previous stages' files, except those it copies
  ``--from`` them (so the runtime stage cannot lean on the build stage's source tree).

What this cannot check: the base image's contents, file ownership and permissions, the
USER switch (everything runs as the test's user) and the network of a real build.
"""

from __future__ import annotations

import fnmatch
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

#: First path components that belong to the base system, never re-rooted.
SYSTEM_DIRS = {"bin", "boot", "dev", "etc", "lib", "lib64", "proc", "root", "run", "sbin", "sys", "tmp", "usr"}
#: RUN commands that configure the OS image (users, packages, ownership): skipped here.
SKIPPED_COMMANDS = {"useradd", "groupadd", "adduser", "addgroup", "chown", "chgrp", "chmod", "apt-get", "apt"}
#: RUN commands replayed here (matched on the basename of the first word).
REPLAYED_COMMANDS = {"mkdir", "python", "python3", "pip", "pip3", "bilimovich"}
#: Host variables a build may need for its package index (pip configuration, proxies, certificates).
PASSTHROUGH = re.compile(r"^(PIP_\w+|https?_proxy|no_proxy|HTTPS?_PROXY|NO_PROXY|SSL_CERT_\w+|REQUESTS_CA_BUNDLE)$")


@dataclass
class Instruction:
    keyword: str
    args: str
    line: int


@dataclass
class Stage:
    name: str
    base: str
    instructions: list[Instruction] = field(default_factory=list)


@dataclass
class Dockerfile:
    global_args: dict[str, str]
    stages: list[Stage]

    @property
    def final(self) -> Stage:
        return self.stages[-1]

    def exec_form(self, keyword: str, stage: Stage | None = None) -> list[str]:
        """The JSON argv of the last ``keyword`` (CMD, ENTRYPOINT) of a stage; ``[]`` if absent."""
        found = [i for i in (stage or self.final).instructions if i.keyword == keyword]
        if not found:
            return []
        return parse_exec_form(found[-1])

    def healthcheck(self, stage: Stage | None = None) -> tuple[dict[str, str], list[str]]:
        """Options and exec-form command of the HEALTHCHECK."""
        found = [i for i in (stage or self.final).instructions if i.keyword == "HEALTHCHECK"]
        if not found:
            return {}, []
        text = found[-1].args
        opts: dict[str, str] = {}
        while text.startswith("--"):
            flag, _, text = text.partition(" ")
            key, _, value = flag[2:].partition("=")
            opts[key] = value
            text = text.lstrip()
        if not text.startswith("CMD "):
            raise ValueError(f"HEALTHCHECK must be 'CMD [...]', got {found[-1].args!r}")
        return opts, parse_exec_form(Instruction("CMD", text[4:].strip(), found[-1].line))


def parse_exec_form(ins: Instruction) -> list[str]:
    try:
        argv = json.loads(ins.args)
    except json.JSONDecodeError:
        raise ValueError(f"line {ins.line}: {ins.keyword} must be in exec (JSON) form, got {ins.args!r}") from None
    if not (isinstance(argv, list) and argv and all(isinstance(a, str) for a in argv)):
        raise ValueError(f"line {ins.line}: {ins.keyword} must be a JSON list of strings")
    return argv


def logical_lines(text: str) -> Iterator[tuple[int, str]]:
    """Instructions with continuations joined and comment lines dropped (Docker's rules)."""
    buf: list[str] = []
    start = 0
    for n, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        if stripped.startswith("#") or (not stripped and not buf):
            continue
        if not buf:
            start = n
        if stripped.endswith("\\"):
            buf.append(stripped[:-1].strip())
            continue
        buf.append(stripped)
        yield start, " ".join(p for p in buf if p)
        buf = []
    if buf:
        yield start, " ".join(p for p in buf if p)


def parse(text: str) -> Dockerfile:
    global_args: dict[str, str] = {}
    stages: list[Stage] = []
    for line, logical in logical_lines(text):
        keyword, _, args = logical.partition(" ")
        keyword = keyword.upper()
        args = args.strip()
        if keyword == "FROM":
            parts = args.split()
            base = expand(parts[0], global_args)
            name = parts[2] if len(parts) == 3 and parts[1].upper() == "AS" else str(len(stages))
            stages.append(Stage(name, base))
        elif not stages:
            if keyword != "ARG":
                raise ValueError(f"line {line}: only ARG may precede FROM, got {keyword}")
            key, _, default = args.partition("=")
            global_args[key] = default
        else:
            stages[-1].instructions.append(Instruction(keyword, args, line))
    if not stages:
        raise ValueError("no FROM in the Dockerfile")
    return Dockerfile(global_args, stages)


_VAR = re.compile(r"\$(?:\{(\w+)\}|(\w+))")


def expand(text: str, env: Mapping[str, str]) -> str:
    """``$VAR`` and ``${VAR}`` as Docker expands them in ENV, WORKDIR, COPY and FROM."""
    return _VAR.sub(lambda m: env.get(m.group(1) or m.group(2), ""), text)


def env_pairs(args: str) -> list[tuple[str, str]]:
    """``ENV K=V K2="V 2"`` (and the legacy ``ENV K V``) as pairs, values unexpanded."""
    words = shlex.split(args, posix=True)
    if words and "=" not in words[0]:
        return [(words[0], " ".join(words[1:]))]
    return [tuple(w.split("=", 1)) for w in words]  # type: ignore[misc]


# --- .dockerignore --------------------------------------------------------------------------


def _pattern_regex(pattern: str) -> re.Pattern[str]:
    out = ""
    i = 0
    while i < len(pattern):
        c = pattern[i]
        if pattern.startswith("**", i):
            i += 2
            if pattern.startswith("/", i):  # "**/" matches zero or more directories
                out += "(?:.*/)?"
                i += 1
            else:
                out += ".*"
            continue
        if c == "*":
            out += "[^/]*"
        elif c == "?":
            out += "[^/]"
        elif c == "[":
            j = pattern.find("]", i)
            if j < 0:
                out += re.escape(c)
            else:
                cls = pattern[i + 1 : j]
                out += "[" + ("^" + cls[1:] if cls.startswith("!") else cls) + "]"
                i = j
        else:
            out += re.escape(c)
        i += 1
    return re.compile(out + r"\Z")


def read_dockerignore(path: Path) -> list[tuple[bool, re.Pattern[str], str]]:
    """``(negated, regex, pattern)`` per rule of a ``.dockerignore``."""
    rules = []
    if path.exists():
        for raw in path.read_text().splitlines():
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            negate = line.startswith("!")
            pat = os.path.normpath(line[1:].strip() if negate else line).lstrip("/")
            rules.append((negate, _pattern_regex(pat), pat))
    return rules


def ignored(rel: str, rules: list[tuple[bool, re.Pattern[str], str]]) -> bool:
    """Docker's rule: the last pattern matching the path or one of its parent directories wins."""
    parts = rel.split("/")
    prefixes = ["/".join(parts[: k + 1]) for k in range(len(parts))]
    result = False
    for negate, rx, _ in rules:
        if any(rx.match(p) for p in prefixes):
            result = not negate
    return result


def _may_reinclude(rel_dir: str, rules: list[tuple[bool, re.Pattern[str], str]]) -> bool:
    """Could a ``!`` rule re-include something below the (ignored) directory ``rel_dir``?"""
    dc = rel_dir.split("/")
    for negate, _, pat in rules:
        pc = pat.split("/")
        if negate and ("**" in pat or (len(pc) > len(dc) and all(map(fnmatch.fnmatchcase, dc, pc)))):
            return True
    return False


def build_context(root: Path) -> list[str]:
    """Relative paths of the files ``docker build`` would send (``.dockerignore`` applied)."""
    rules = read_dockerignore(root / ".dockerignore")
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        rel_dir = os.path.relpath(dirpath, root)
        keep = []
        for d in dirnames:
            rel = os.path.normpath(os.path.join(rel_dir, d))
            if not ignored(rel, rules) or _may_reinclude(rel, rules):
                keep.append(d)
        dirnames[:] = keep
        for f in filenames:
            rel = os.path.normpath(os.path.join(rel_dir, f))
            if not ignored(rel, rules):
                files.append(rel)
    return sorted(files)


# --- replay ---------------------------------------------------------------------------------


class Replay:
    """Run a Dockerfile's steps under ``root`` (see the module docstring)."""

    def __init__(self, dockerfile: Dockerfile, context: Path, root: Path, extra_env: Mapping[str, str] = ()) -> None:
        self.df = dockerfile
        self.context = context
        self.root = root
        self.extra_env = dict(extra_env)
        self.log: list[str] = []
        self.context_files = build_context(context)
        # The base image's /usr/local/bin: python is the interpreter running the tests.
        base_bin = root / "_base" / "bin"
        base_bin.mkdir(parents=True, exist_ok=True)
        for name in ("python", "python3"):
            link = base_bin / name
            if not link.exists():
                link.symlink_to(getattr(sys, "_base_executable", sys.executable))
        self.base_env = {"PATH": f"{base_bin}:/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8"}
        self.base_env.update({k: v for k, v in os.environ.items() if PASSTHROUGH.match(k)})
        self.owned = self._owned_roots()
        self.env: dict[str, str] = {}
        self.cwd = root
        self.stage: Stage | None = None

    # paths ------------------------------------------------------------------------------

    def _owned_roots(self) -> set[str]:
        found: set[str] = set()
        for st in self.df.stages:
            for ins in st.instructions:
                words = re.findall(r"(?<![\w.$}-])/[\w.-]+", ins.args)
                if ins.keyword in ("WORKDIR", "COPY", "ENV") or "venv" in ins.args:
                    found.update(w.split("/")[1] for w in words)
        return {d for d in found if d not in SYSTEM_DIRS}

    def remap(self, text: str) -> str:
        """Re-root the image-owned absolute paths in ``text`` under ``root``."""
        if not self.owned:
            return text
        rx = r"(?<![\w.$}/-])(/(?:" + "|".join(map(re.escape, sorted(self.owned))) + r")(?=/|\b))"
        return re.sub(rx, lambda m: f"{self.root}{m.group(1)}", text)

    def path(self, p: str) -> Path:
        p = expand(p, self.env)
        if os.path.isabs(p):
            return Path(self.remap(p)) if p.split("/")[1] in self.owned else Path(p)
        return self.cwd / p

    # steps ------------------------------------------------------------------------------

    def run_stage(self, stage: Stage, timeout: float = 600) -> None:
        self._isolate(stage)
        self.stage = stage
        self.env = dict(self.base_env)
        self.env.setdefault("HOME", os.environ.get("HOME", str(self.root)))  # pip config and cache
        self.env.update(self.extra_env)
        self.cwd = self.root
        for ins in stage.instructions:
            getattr(self, f"_do_{ins.keyword.lower()}", self._do_other)(ins, timeout)

    def _isolate(self, stage: Stage) -> None:
        """Drop what earlier stages created, except what this or a later stage copies --from them."""
        keep: list[str] = []
        for st in self.df.stages[self.df.stages.index(stage) :]:
            for ins in st.instructions:
                if ins.keyword == "COPY" and "--from=" in ins.args:
                    keep.append(self.remap(shlex.split(ins.args)[-2]).rstrip("/"))

        def prune(d: Path) -> None:
            for p in d.iterdir():
                s = str(p)
                if any(s == k or s.startswith(k + "/") for k in keep):
                    continue
                if any(k.startswith(s + "/") for k in keep):
                    prune(p)
                elif p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p)
                else:
                    p.unlink()

        for d in sorted(self.owned):
            top = self.root / d
            if not top.is_dir():
                continue
            if any(k == str(top) or k.startswith(f"{top}/") for k in keep):
                prune(top)
            else:
                shutil.rmtree(top)

    def _do_env(self, ins: Instruction, timeout: float) -> None:
        before = dict(self.env)
        for k, v in env_pairs(ins.args):
            self.env[k] = self.remap(expand(v, before))
        self.env.update(self.extra_env)

    def _do_arg(self, ins: Instruction, timeout: float) -> None:
        key, _, default = ins.args.partition("=")
        self.env.setdefault(key, self.df.global_args.get(key, default))

    def _do_workdir(self, ins: Instruction, timeout: float) -> None:
        self.cwd = self.path(ins.args)
        self.cwd.mkdir(parents=True, exist_ok=True)

    def _do_copy(self, ins: Instruction, timeout: float) -> None:
        words = shlex.split(ins.args)
        flags = [w for w in words if w.startswith("--")]
        srcs, dest = [w for w in words if not w.startswith("--")][:-1], words[-1]
        target = self.path(dest)
        from_stage = next((f.split("=", 1)[1] for f in flags if f.startswith("--from=")), None)
        for src in srcs:
            if from_stage is not None:
                s = Path(self.remap(src))
                if s.resolve() != target.resolve():
                    shutil.copytree(s, target, symlinks=True, dirs_exist_ok=True)
                continue
            rel = os.path.normpath(src)
            chosen = [f for f in self.context_files if f == rel or f.startswith(rel + "/")]
            if not chosen:
                raise FileNotFoundError(f"line {ins.line}: COPY {src}: not in the build context (.dockerignore?)")
            into_dir = dest.endswith("/") or len(srcs) > 1
            for f in chosen:
                if f == rel:
                    out = target / os.path.basename(f) if into_dir else target
                else:
                    out = target / os.path.relpath(f, rel)
                out.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(self.context / f, out)

    def _do_run(self, ins: Instruction, timeout: float) -> None:
        text = ins.args
        if text.startswith("["):
            commands = [shlex.join(parse_exec_form(ins))]
        else:
            while text.startswith("--"):  # --mount=..., --network=...: build-time only
                text = text.split(None, 1)[1]
            if re.search(r"(?<!&)&(?!&)|\|\||;|\|", text):
                raise ValueError(f"line {ins.line}: keep RUN to commands joined by && (got {text!r})")
            commands = [c.strip() for c in text.split("&&")]
        for cmd in commands:
            name = os.path.basename(shlex.split(cmd)[0])
            if name in SKIPPED_COMMANDS:
                self.log.append(f"skip (OS image setup): {cmd}")
                continue
            if name not in REPLAYED_COMMANDS:
                raise ValueError(
                    f"line {ins.line}: RUN {name!r} is neither replayed nor skipped by {Path(__file__).name}; "
                    "classify it there"
                )
            cmd = self.remap(cmd)
            self._check_confined(cmd, ins)
            self.log.append(f"run: {cmd}")
            proc = subprocess.run(
                ["/bin/sh", "-c", cmd], cwd=self.cwd, env=self.env, capture_output=True, text=True, timeout=timeout
            )
            if proc.returncode != 0:
                raise RuntimeError(
                    f"line {ins.line}: {cmd!r} exited {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
                )

    def _check_confined(self, cmd: str, ins: Instruction) -> None:
        """Never touch the host: programs and directories must live under ``root``.

        The base interpreter (``python`` in the stand-in /usr/local/bin) may only create a venv;
        anything else it ran (``python -m pip install``) would change the Python running the tests.
        """
        argv = [expand(a, self.env) for a in shlex.split(cmd)]
        roots = (str(self.root) + "/", str(self.root.resolve()) + "/")

        def inside(p: str | Path) -> bool:
            return os.path.abspath(p).startswith(roots)

        if os.path.basename(argv[0]) == "mkdir":
            bad = [a for a in argv[1:] if not a.startswith("-") and not inside(self.path(a))]
        else:
            exe = shutil.which(argv[0], path=self.env.get("PATH", "")) if "/" not in argv[0] else argv[0]
            if exe is not None and Path(exe).parent == self.root / "_base" / "bin":
                bad = [] if argv[1:3] == ["-m", "venv"] else [argv[0]]
            else:
                bad = [] if exe and inside(exe) else [exe or argv[0]]
        if bad:
            raise ValueError(f"line {ins.line}: {cmd!r} would act outside the replay root ({bad}); use the venv")

    def _do_other(self, ins: Instruction, timeout: float) -> None:
        # USER, EXPOSE, HEALTHCHECK, CMD, ENTRYPOINT, LABEL: read by the caller, nothing to run.
        if ins.keyword not in {"USER", "EXPOSE", "HEALTHCHECK", "CMD", "ENTRYPOINT", "LABEL", "STOPSIGNAL"}:
            raise ValueError(f"line {ins.line}: {ins.keyword} is not handled by {Path(__file__).name}")

    def build(self, timeout: float = 600) -> None:
        for stage in self.df.stages:
            self.run_stage(stage, timeout)
