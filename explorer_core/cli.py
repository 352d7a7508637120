"""The ``bilimovich`` command line: batch work on the same core the app uses.

Every command takes the system as ``--scene ID`` and/or explicit flags
(``--inertia I11,I22,I33,I12,I13,I23 --alpha A --g0 --g1 --g2 --omega --t0``, or
single entries ``--I13 0.2``); explicit flags override the scene. Any option's value may start with a minus
sign, written ``--from -0.1,-2`` or ``--from=-0.1,-2``.

The commands are a table (:data:`COMMANDS`): each adds its arguments, builds the analysis' inputs from
them, runs it with one progress line, and writes its outputs through :mod:`explorer_core.export`, at
exactly the paths given, which are checked before the work starts. Bad input, an unusable output or a
refused parameter gives one line ``bilimovich CMD: error: ...`` on stderr and exit status 2, never a
traceback. What a result lost (``result.lost``) is printed on stderr, one line per loss (``--quiet`` never
hides one), and ``--json`` carries ``complete`` and ``lost``. Every file is whole or absent (written to a
temporary name, renamed when complete); one of a run that was stopped says so (``# partial: ...`` after a CSV's
header, ``complete: false`` in JSON).

Exit statuses: 0 done (a ``lost:`` line may say what is missing); 1 an internal error (a bug); 2 bad input
or an unusable output; 3 (:data:`FAILED_STATUS`) every member of the run (trajectory, pixel, value, seed)
failed, said in a ``failed:`` line; 128 + the signal (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP) interrupted:
the work stops at its next look at the signal, writes what it computed, prints the ``lost:`` lines and an
``interrupted`` line, then exits (with the warm worker too, :mod:`explorer_core.worker`; a second signal
leaves at once without waiting).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a program (the worker, tests): stop signals handled before the imports below
    from explorer_core.launch import early

    early()

import argparse
import contextlib
import importlib
import inspect
import math
import os
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from explorer_core import __version__, config, export, launch
from explorer_core.launch import STOP_SIGNALS
from explorer_core.scenes import Scene, get_scene, list_scenes
from explorer_core.solve.numerics import Numerics
from explorer_core.status import Status
from explorer_core.system.params import INERTIA_NAMES, ParameterError, Params

CSV, NPZ = (".csv",), (".npz",)


class UsageError(Exception):
    """Bad command-line input (reported as one line, exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line, and lets any option's value start with a minus sign."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see --help)\n")

    def parse_args(self, args: Any = None, namespace: Any = None) -> argparse.Namespace:  # type: ignore[override]
        # An unknown option is named with its command (argparse's top-level message says only "bilimovich").
        ns, unknown = self.parse_known_args(args, namespace)
        if unknown:
            subs = [a for a in self._actions if isinstance(a, argparse._SubParsersAction)]
            command = getattr(ns, "command", None)
            where = subs[0].choices[command] if subs and command in subs[0].choices else self
            where.error(f"unrecognized arguments: {' '.join(unknown)}")
        return ns

    def _parse_optional(self, arg_string: str) -> Any:
        # A word with one leading '-' that is no option of this parser is a value (-0.1,-2, -inf, -x): the
        # commands have no short options but -h, so nothing else could be meant. One rule, no list of names.
        if arg_string[:1] == "-" and arg_string[1:2] not in ("", "-") and arg_string not in self._option_string_actions:
            return None
        return super()._parse_optional(arg_string)


# --- values ----------------------------------------------------------------------------------------------


def _floats(text: str, n: int | None, name: str) -> list[float]:
    parts = [p.strip() for p in str(text).split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"{name} must be comma-separated numbers, got {text!r}") from None
    if n is not None and len(vals) != n:
        raise UsageError(f"{name} needs {n} comma-separated numbers, got {len(vals)} in {text!r}")
    if not all(math.isfinite(v) for v in vals):
        raise UsageError(f"{name} must be finite, got {text!r}")
    return vals


def _ints(text: str, name: str, metavar: str, lo: int | None = None, hi: int | None = None) -> list[int]:
    """``NX,NY``-style whole numbers (as many as ``metavar`` has parts), optionally each in ``[lo, hi]``."""
    n = metavar.count(",") + 1
    vals = _floats(text, n, name)
    within = f" in [{lo}, {hi}]" if lo is not None else ""
    if not all(v.is_integer() and (lo is None or lo <= v <= hi) for v in vals):  # type: ignore[operator]
        raise UsageError(f"{name} must be {['one', 'two'][n - 1]} whole numbers {metavar}{within}, got {text!r}")
    return [int(v) for v in vals]


def _span(text: str, name: str) -> list[float]:
    """``A,B``: a parameter or coordinate range, either way round, whose width is a finite number."""
    lo, hi = _floats(text, 2, name)
    if not math.isfinite(hi - lo):
        raise UsageError(f"{name} is too wide: its width overflows, got {text!r}")
    return [lo, hi]


def _number(name: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return v

    return parse


def _count(name: str, lo: int, hi: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{name} must be between {lo} and {hi}, got {v}")
        return v

    return parse


def _add_system_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("system (explicit flags override --scene)")
    g.add_argument("--scene", help="load a paper scene (see `bilimovich scenes`)")
    g.add_argument("--inertia", help="I11,I22,I33,I12,I13,I23 (symmetric positive-definite tensor)")
    for n in INERTIA_NAMES:
        g.add_argument(f"--{n}", type=_number(n), help=argparse.SUPPRESS)
    g.add_argument("--alpha", type=_number("alpha"), help="constraint inhomogeneity alpha")
    g.add_argument("--g0", type=_number("g0"), help="forcing g = g0 + g1 cos(omega t) + g2 sin(omega t)")
    g.add_argument("--g1", type=_number("g1"))
    g.add_argument("--g2", type=_number("g2"))
    g.add_argument("--omega", type=_number("omega"), help="forcing frequency (> 0); period 2 pi / omega")
    g.add_argument("--t0", type=_number("t0"), help="section phase: points at t0 + k T")


def _add_numerics_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("numerics")
    g.add_argument("--method", choices=["auto", "rk4", "dp5", "dop853", "vern9", "taylor"],
                   help=f"default {config.DEFAULT_METHOD}: vern9 (Verner 9(8)) at rtol {config.VERN9_MIN_RTOL:g}.."
                        f"{config.VERN9_MAX_RTOL:g}, where it needs less work, else dop853; taylor: sections only, "
                        "for now")  # fmt: skip
    g.add_argument(
        "--rtol", type=_number("rtol"), help="relative tolerance (default: the command's own, in the JSON's numerics)"
    )
    g.add_argument("--atol", type=_number("atol"), help="absolute tolerance (default: same as rtol)")
    g.add_argument("--steps-per-period", type=_count("steps-per-period", 1, 10_000_000), help="RK4 steps")
    g.add_argument("--bound", type=_number("bound"), help="escape bound on |q|, |r|")
    g.add_argument("--max-steps", type=_count("max-steps", 10, 1_000_000_000), help="step budget per period")


def _params(args: argparse.Namespace) -> tuple[Params, Scene | None]:
    scene = get_scene(args.scene) if args.scene else None
    base = scene.params if scene else Params()
    changes: dict[str, Any] = {}
    if args.inertia is not None:
        changes["inertia"] = tuple(_floats(args.inertia, 6, "--inertia"))
    for f in (*INERTIA_NAMES, "alpha", "g0", "g1", "g2", "omega", "t0"):
        if getattr(args, f) is not None:
            changes[f] = getattr(args, f)
    return base.with_(**changes), scene


#: The numerics flags taken as given (``--rtol``/``--atol`` have a rule of their own, :func:`_numerics`).
_NUMERICS_AS_GIVEN = ("method", "steps_per_period", "bound", "max_steps")


def _numerics(args: argparse.Namespace, base: Numerics) -> Numerics:
    """The analysis' own numerics ``base`` with the numerics flags given (``--rtol`` lets the rule choose again)."""
    kw = base.as_dict()
    kw.pop("adaptive", None)
    if args.rtol is not None:
        kw["rtol"] = args.rtol
        kw["atol"] = args.atol if args.atol is not None else args.rtol
        kw["method"] = config.DEFAULT_METHOD  # the rule chooses again for the tolerance asked (unless --method)
    elif args.atol is not None:
        kw["atol"] = args.atol
    for name in _NUMERICS_AS_GIVEN:
        if getattr(args, name) is not None:
            kw[name] = getattr(args, name)
    return Numerics(**kw)


# --- running and reporting ---------------------------------------------------------------------------------


#: Exit status of a run in which every member (trajectory, pixel, value, seed) failed: nothing usable was computed.
FAILED_STATUS = 3


class Interrupted(KeyboardInterrupt):
    """A stop signal before the work began, raised by the command line's handlers. A subclass, not
    ``KeyboardInterrupt`` itself: CPython marks a bare ``KeyboardInterrupt`` that passes through code it runs
    from C (an import's) as unhandled, and then ends the process by SIGINT (exit -2) whatever status the
    command returns (a SIGTERM came out as a death by SIGINT)."""


class _Signals:
    """The stop signals one command received. Before its work starts a signal ends the command at once (a
    ``KeyboardInterrupt``: nothing is computed yet); once a :class:`_Run` has started it is a request the work
    polls, and the command goes on to write what it computed, then exits ``128 + signal`` (:meth:`status`)."""

    def __init__(self) -> None:
        self.received: list[int] = []
        self.defer = False
        self._old: dict[int, Any] = {}

    def __enter__(self) -> _Signals:
        if threading.current_thread() is threading.main_thread():  # Python takes signals in the main thread only
            for s in STOP_SIGNALS:
                self._old[s] = signal.signal(s, self._on_signal)
        return self

    def __exit__(self, *exc: Any) -> None:
        for s, handler in self._old.items():
            signal.signal(s, handler)
        self._old.clear()

    def _on_signal(self, signum: int, frame: Any) -> None:
        self.received.append(int(signum))
        if not self.defer:
            raise Interrupted

    def status(self) -> int:
        """The exit status of an interrupted command: ``128 +`` the first signal (130 without one: a
        ``KeyboardInterrupt`` raised by other means)."""
        return 128 + self.received[0] if self.received else 130

    def name(self) -> str:
        return signal.Signals(self.received[0]).name if self.received else "SIGINT"


#: The signals of the command being run by :func:`main` (None outside it: a :class:`_Run` then takes its own).
_signals: _Signals | None = None


class _Run:
    """One long computation: a stop signal (Ctrl-C, SIGTERM, SIGHUP) sets a flag that the work polls (call the
    object: ``cancel=run``), and one throttled ``\\r`` progress line on stderr (only on a terminal, never with
    ``--quiet``). From here on the command writes what it computed before it exits (see :class:`_Signals`)."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.show = not getattr(args, "quiet", False) and sys.stderr.isatty()
        self._last = 0.0
        self._shown = False
        self._own = _signals is None
        self.signals = _Signals() if self._own else _signals

    def __enter__(self) -> _Run:
        if self._own:
            self.signals.__enter__()
        self.signals.defer = True
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._own:
            self.signals.__exit__()
        if self._shown:
            sys.stderr.write("\n")

    @property
    def flag(self) -> bool:
        return bool(self.signals.received)

    def __call__(self) -> bool:
        return self.flag

    def update(self, update: Any) -> None:
        """The progress callback of every long analysis: its update's ``progress`` as the one line."""
        self.line(update.progress.line())

    def line(self, text: str) -> None:
        now = time.perf_counter()
        if self.show and now - self._last > 0.2:
            self._last, self._shown = now, True
            sys.stderr.write(f"\r{text} ")
            sys.stderr.flush()


def _build(args: argparse.Namespace, builder: Callable[..., Any], *a: Any, **kw: Any) -> Any:
    """An analysis' spec from its builder: a value it refuses is one usage line naming the option's flag
    (``--offset: offset must be in (0, 1] ...``), its keywords written as flags (``ds_min`` as ``ds-min``).
    The nested options given as flags (``--newton-ftol``) replace those of the builder's default."""
    try:
        kw.update(_nested(args, builder))
        return builder(*a, **kw)
    except ParameterError as exc:
        text, key = str(exc), getattr(exc, "option", None) or ""
        for name in (k for k in vars(args) if "_" in k.strip("_")):
            text = re.sub(rf"\b{name}\b", name.replace("_", "-"), text)
        declared = _declared(builder).get(key)  # the flag of a declared keyword, else of a flag with its name
        flag = (
            f"{declared.flag_of(key)}: " if declared else f"--{key.replace('_', '-')}: " if hasattr(args, key) else ""
        )
        raise UsageError(flag + text) from None


#: The dest of a nested option's flag: ``newton__ftol`` for ``--newton-ftol``.
_NESTED = "__"


def _add_nested_args(p: argparse.ArgumentParser, command: str) -> None:
    """The flags of the nested options of the command's analysis (the registry), from the options' declarations:
    ``--newton-ftol`` etc. Their defaults are the analysis' (its builder's), read when the command runs."""
    from explorer_core.registry import by_command

    analysis = by_command(command)
    if analysis is None or "newton" not in analysis.nested:
        return
    from explorer_core.solve.options import NewtonOptions

    g = p.add_argument_group("Newton on P^n(x) - x (default: this analysis' preset; the JSON's spec has it)")
    for o in NewtonOptions.options():
        g.add_argument(o.flag, dest=f"newton{_NESTED}{o.name}", metavar=o.metavar or o.check.kind.upper(),
                       help=f"{o.help} ({o.accepts})")  # fmt: skip


def _nested(args: argparse.Namespace, builder: Callable[..., Any]) -> dict[str, Any]:
    """``{"newton": NewtonOptions}`` when any ``--newton-*`` flag was given: the builder's default with them."""
    given = {k: v for k, v in vars(args).items() if _NESTED in k and v is not None}
    if not given:
        return {}
    out: dict[str, Any] = {}
    for name in {k.split(_NESTED, 1)[0] for k in given}:
        default = inspect.signature(builder).parameters[name].default
        changes = {}
        for o in type(default).options():
            text = given.get(f"{name}{_NESTED}{o.name}")
            if text is not None:
                try:
                    changes[o.name] = o.check.parse(o.name, text)
                except ParameterError as exc:
                    raise UsageError(f"{o.flag}: {exc}") from None
        out[name] = default.replace(**changes)
    return out


def _print_json(obj: Any) -> None:
    sys.stdout.write(export.dumps(obj) + "\n")
    sys.stdout.flush()


def _finish(args: argparse.Namespace, summary: dict[str, Any], lines: Callable[[], list[str]], *, result: Any = None,
            completed: bool | None = None, what: str = "results", notes: Sequence[str] = (),
            as_json: bool | None = None) -> int:  # fmt: skip
    """The end of every command: the losses into the summary, JSON (``--json``, or ``as_json``) or ``lines()`` on
    stdout, the losses and ``notes`` on stderr; exit ``128 + signal`` when the work was interrupted (what was
    computed has been written), :data:`FAILED_STATUS` when every member failed."""
    lost = getattr(result, "lost", None)
    if completed is None:
        completed = bool(getattr(result, "completed", True))
    if result is not None:  # one completeness vocabulary in every JSON: `completed` (reached its end), `complete`
        summary["completed"] = completed  # (completed, nothing lost), `lost` (what, how many, why)
        summary["complete"] = completed and bool(getattr(result, "complete", not lost))
        summary["lost"] = [loss.as_dict() for loss in lost or ()]
    if getattr(args, "json", False) if as_json is None else as_json:
        _print_json(summary)
    elif not getattr(args, "quiet", False):
        text = "\n".join(lines())
        if text:
            print(text)
    for note in [*(loss.line() for loss in lost or ()), *notes]:
        sys.stderr.write(f"bilimovich {args.command}: {note}\n")
    if not completed:
        sys.stderr.write(f"bilimovich {args.command}: interrupted; the {what} computed so far were written\n")
        return _signals.status() if _signals is not None else 130
    failed = _all_failed(result)
    if failed:
        sys.stderr.write(f"bilimovich {args.command}: failed: every member failed ({failed}); exit status "
                         f"{FAILED_STATUS}\n")  # fmt: skip
        return FAILED_STATUS
    return 0


#: What a member ends with when it failed (numerically, or refused): escaping the bound is an outcome, a budget
#: or an undecided class a verdict, a cancelled or never-run member no attempt.
_FAILURES = frozenset({Status.STEP_COLLAPSED, Status.TOO_MANY_STEPS, Status.NONFINITE, Status.NOT_CONVERGED,
                       Status.INVALID})  # fmt: skip


def _all_failed(result: Any) -> str | None:
    """The members' statuses in words if every member of ``result`` that ran failed (its ``status``: one status
    or an array or list of them), else None."""
    status = getattr(result, "status", None)
    if status is None:
        return None
    try:
        if isinstance(status, np.ndarray) and status.dtype.kind in "iu":
            codes, counts = np.unique(status, return_counts=True)
            found = {Status.of(int(c)): int(n) for c, n in zip(codes, counts, strict=True)}
        else:
            items = [status] if isinstance(status, (str, int, Status)) else list(np.asarray(status).ravel().tolist())
            found = {}
            for item in items:
                found[Status.of(item)] = found.get(Status.of(item), 0) + 1
    except (ValueError, TypeError):
        return None
    ran = {s: n for s, n in found.items() if s not in (Status.CANCELLED, Status.NOT_RUN)}
    if not ran or not set(ran) <= _FAILURES:
        return None
    return ", ".join(f"{n} {s.word}" for s, n in sorted(ran.items()))


def _with_scene(summary: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    if getattr(args, "scene", None):
        summary["scene"] = args.scene
    return summary


# --- commands generated from the analyses' declarations ---------------------------------------------------
#
# An analysis command (``Command(analysis=...)``) has no body here: its flags come from the ``@declare``
# declarations of its builder and runner (one ``explorer_core.solve.options.Arg`` per option: default, check, help),
# its run is builder -> runner -> ``result.write`` for every output -> ``result.report()`` (the lines printed),
# and its JSON is ``result.summary()`` with ``out`` (one record per file written) and ``scene``.


def _declared(fn: Callable[..., Any]) -> dict[str, Any]:
    return getattr(fn, "__cli__", {})


#: The metavar of a declared option by how it is parsed (unless it declares one).
_METAVARS = {"points": "Q,R", "point": "Q,R", "range": "A,B", "box": "Q0,Q1,R0,R1", "ints": "NX,NY"}


def _add_declared_args(p: argparse.ArgumentParser, fn: Callable[..., Any], title: str) -> None:
    """The flags of ``fn``'s declared keywords (help with the signature's default)."""
    params = inspect.signature(fn).parameters
    g = p.add_argument_group(title)
    for name, arg in _declared(fn).items():
        if arg.flag == "":  # taken from the scene only (a scene's escape bound): no flag of its own
            continue
        default = params[name].default if arg.cli_default is None else arg.cli_default
        text = arg.help
        if arg.check is not None and arg.parse not in ("switch", "points") and not arg.choices:
            text += f" ({arg.check.text.removesuffix(' or none')})"  # the declared check's range
        # (by identity: a default of 0 is shown, though 0 == False)
        if not any(default is v for v in (inspect.Parameter.empty, None, False)) and default != () \
                and arg.parse != "switch":  # fmt: skip
            text += f" (default {_shown(default)})"
        if arg.scene:
            text += f" (with --scene: the scene's {arg.scene.replace('_', ' ')})"
        kw: dict[str, Any] = {"dest": name, "help": text.strip() or None}
        if arg.parse == "switch":
            g.add_argument(arg.flag_of(name), action="store_true", **kw)
        elif arg.parse == "points":
            g.add_argument(arg.flag_of(name), action="append", metavar=arg.metavar or "Q,R", **kw)
        else:
            metavar = arg.metavar or _METAVARS.get(arg.parse, name.upper())
            g.add_argument(arg.flag_of(name), metavar=metavar, required=arg.required,
                           choices=arg.choices, **kw)  # fmt: skip


def _shown(v: Any) -> str:
    if isinstance(v, tuple | list):
        return ",".join(_shown(x) for x in v)
    return f"{v:g}" if isinstance(v, float) else str(v)


def _declared_values(args: argparse.Namespace, fn: Callable[..., Any], scene: Scene | None) -> tuple[list, dict]:
    """``fn``'s declared keywords from the command line (text parsed), or the scene's where declared; the
    positional ones in order and the others by keyword (only those given: the signature has the defaults)."""
    pos: list[Any] = []
    kw: dict[str, Any] = {}
    for name, arg in _declared(fn).items():
        raw = getattr(args, name, None)
        flag = arg.flag_of(name)
        if raw is None or raw is False:
            instead = any(getattr(args, other, None) is not None for other in arg.unless)
            value = _scene_value(scene, arg.scene) if raw is None and not instead else None
            value = arg.cli_default if value is None else value
            if value is None and arg.positional:  # a positional keyword left out: its default, or say what is missing
                value = inspect.signature(fn).parameters[name].default
                if value is inspect.Parameter.empty:
                    where = " (no --scene to take it from)" if arg.scene else ""
                    raise UsageError(f"give {flag} {arg.metavar or _METAVARS.get(arg.parse, name.upper())}{where}")
        elif arg.parse == "switch":
            value = True
        elif arg.parse in ("int", "float"):
            try:  # the value's range is the builder's check, which names the option
                value = int(raw) if arg.parse == "int" else float(raw)
            except ValueError:
                raise UsageError(f"{flag} must be {'an integer' if arg.parse == 'int' else 'a number'}, "
                                 f"got {raw!r}") from None  # fmt: skip
        elif arg.parse == "range":
            value = _span(raw, flag)
        elif arg.parse == "ints":
            value = _ints(raw, flag, arg.metavar or "NX,NY")
        elif arg.parse == "box":
            value = _floats(raw, 4, flag)
        elif arg.parse == "points":
            value = [_floats(v, 2, flag) for v in raw]
        elif arg.parse == "point":
            value = _floats(raw, 2, flag)
        elif arg.parse == "list":
            value = [w.strip() for w in str(raw).split(",")]
            if not all(value):  # '' or 'a,,b' names nothing: never "the default"
                raise UsageError(f"{flag} must be comma-separated names, got {raw!r}")
        else:
            value = raw
        if arg.positional:
            pos.append(value)
        elif value is not None:
            kw[name] = value
    return pos, kw


def _scene_value(scene: Scene | None, attr: str | None) -> Any:
    """What a scene gives an option declared with ``scene=attr`` (None: nothing, the builder's default)."""
    if scene is None or attr is None:
        return None
    if attr == "points":
        return [list(p) for p in scene.points[:1]] or None
    if attr == "view":
        return [*scene.q_range, *scene.r_range]
    value = getattr(scene, attr)
    return value() if callable(value) else value  # a scene's initial conditions are drawn when asked


def _numerics_given(args: argparse.Namespace) -> bool:
    return any(getattr(args, n, None) is not None for n in ("rtol", "atol", *_NUMERICS_AS_GIVEN))


def cmd_analysis(args: argparse.Namespace) -> int:
    """An analysis command: builder -> runner -> outputs -> report, from the registry and the declarations."""
    from explorer_core.registry import by_command

    c = COMMANDS[args.command]
    a = by_command(args.command)
    builder, runner = a.get("builder"), a.get("run")
    out = getattr(args, "out", None)
    outs = out if isinstance(out, list) else [out] if out else []
    params, scene = _params(args)
    pos, kw = _declared_values(args, builder, scene)
    kw.update(c.fixed)
    spec = _build(args, builder, params, *pos, **kw)
    need = c.needs_output(spec) if callable(c.needs_output) else c.needs_output
    if need and not outs and not args.json:
        raise UsageError(f"give --out FILE ({', '.join(c.out)}) and/or --json: nothing would be kept")
    if _numerics_given(args):  # the flags change the analysis' own default numerics, whatever it is
        spec = _build(args, builder, params, *pos, **kw, numerics=_numerics(args, spec.numerics))
    _, run_kw = _declared_values(args, runner, scene)
    if c.scheduler:
        run_kw["executor"] = _executor(args)
    # A short check has neither progress nor cancel; a runner that passes keywords on (**kw) takes both.
    accepts = inspect.signature(runner).parameters
    anything = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepts.values())
    with contextlib.ExitStack() as stack, _Run(args) as run:
        streams = _streams(a.get("result"), outs, stack) if anything or "progress" in accepts else {}
        run_kw.update({k: v for k, v in (("cancel", run), ("progress", _tap(run, streams.values())))
                       if anything or k in accepts})  # fmt: skip
        if "stop" in accepts:  # a runner whose threads poll a stop flag themselves (a chart's running tiles)
            run_kw["stop"] = run
        result = runner(spec, **run_kw)
        summary = _with_scene(result.summary(), args)
        if getattr(args, "scheduler", None):
            summary["scheduler"] = args.scheduler
        written = []
        for path in [*outs, *(getattr(args, f) for f in c.files if getattr(args, f, None))]:
            picture = next((fn for suffix, fn in c.pictures.items() if path.lower().endswith(suffix)), None)
            if path in streams:  # its rows are on the disk: a head and a rename
                written.append(streams[path].write_result(result))
            elif picture is None:
                written.append(result.write(path))
            else:  # matplotlib (reports/) only when a picture is asked for
                module, _, name = picture.partition(":")
                getattr(importlib.import_module(module), name)(result, path)
                written.append({"path": path})
    if written:
        summary["out"] = written
    # Stopped: what its files say (export.partial: not `completed`, or a loss by the cancel, as manifolds cancelled
    # mid-growth say). A signal that came as the last piece of work ended stopped nothing: its files are complete
    # and main says "interrupted as its work ended" (it said "the points computed so far" over a whole file).
    completed = not export.partial(result)
    as_json = bool(getattr(args, "json", False)) or (c.json_unless_out and not written)
    # A result's notes (the section's reliability warnings) go to stderr unless --quiet.
    notes = [] if getattr(args, "quiet", False) else getattr(result, "notes", list)()
    return _finish(args, summary, result.report, result=result, completed=completed, what=c.what, as_json=as_json,
                   notes=notes)  # fmt: skip


def _streams(result_type: type, outs: Sequence[str], stack: contextlib.ExitStack) -> dict[str, Any]:
    """The outputs ``result_type`` writes while its run goes (its ``streamed(path)``: a writer fed every progress
    update, ``write_result(result)`` at the end; a section's CSV), each discarded if the command fails."""
    streamed = getattr(result_type, "streamed", None)
    out: dict[str, Any] = {}
    for path in outs if streamed is not None else ():
        writer = streamed(path)
        if writer is not None:
            out[path] = stack.enter_context(writer)
    return out


def _tap(run: _Run, streams: Any) -> Callable[[Any], None]:
    """The run's progress callback: the progress line, and every update to the outputs written as it goes."""
    streams = list(streams)
    if not streams:
        return run.update

    def update(u: Any) -> None:
        for s in streams:
            s.feed(u)
        run.update(u)

    return update


# --- commands ----------------------------------------------------------------------------------------------


def _scenes_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="full scene data as JSON")


def cmd_scenes(args: argparse.Namespace) -> int:
    scenes = list_scenes()
    if args.json:
        _print_json([s.as_dict() for s in scenes])
        return 0
    width = max(len(s.id) for s in scenes)
    for s in scenes:
        p = s.params
        print(f"{s.id:<{width}}  alpha={p.alpha:<7g} I={','.join(f'{v:g}' for v in p.inertia):<22} {s.title}")
    return 0


def _executor(args: argparse.Namespace) -> Any:
    """The Dask executor of ``--scheduler`` (None: this machine's threads)."""
    from explorer_core.parallel.cluster import executor_for
    from explorer_core.warm import warm_all

    return executor_for(args.scheduler, warm=warm_all)


def _scheduler_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask cluster: tcp://HOST:PORT or local:N (docs/dask.md)")


def _serve_args(p: argparse.ArgumentParser) -> None:
    env = os.environ  # defaults from the environment, so a container (exec-form CMD) can be configured
    p.add_argument("--port", type=_count("port", 1, 65535), default=env.get("BILIMOVICH_PORT", "5006"))
    p.add_argument("--address", default=env.get("BILIMOVICH_ADDRESS", "127.0.0.1"),
                   help="interface to listen on (0.0.0.0 for all); env BILIMOVICH_ADDRESS")  # fmt: skip
    p.add_argument("--threads", type=_count("threads", 1, 64), default=env.get("BILIMOVICH_SESSION_THREADS", "4"),
                   help="threads for session callbacks; env BILIMOVICH_SESSION_THREADS")  # fmt: skip
    p.add_argument("--allow-websocket-origin", action="append", metavar="HOST[:PORT]",
                   help="host names browsers may connect from (repeatable; default localhost); "
                        "env BILIMOVICH_ALLOWED_ORIGINS, comma-separated")  # fmt: skip
    p.add_argument("--session-lifetime", type=_count("session-lifetime", 1000, 3_600_000), default=15000,
                   metavar="MS", help="discard a closed tab's session after this many ms (default 15000)")  # fmt: skip
    p.add_argument("--procs", default=env.get("BILIMOVICH_PROCS", "1"), metavar="N|auto",
                   help="server processes on one port ('auto': one per usable CPU); env BILIMOVICH_PROCS")  # fmt: skip
    p.add_argument("--max-sessions-per-address", type=_count("max-sessions-per-address", 1, 100_000), metavar="N",
                   default=env.get("BILIMOVICH_MAX_SESSIONS_PER_ADDRESS", "50"),
                   help="sessions one client address may hold per server process; more get a page saying so "
                        "(default 50; raise it for a classroom behind one NAT address); "
                        "env BILIMOVICH_MAX_SESSIONS_PER_ADDRESS")  # fmt: skip
    p.add_argument("--show", action="store_true", help="open a browser")


def cmd_serve(args: argparse.Namespace) -> int:
    """Run the web app: ``python -m app.serve`` (panel serve app/main.py with the project's flags, app/serve.py).

    The settings are checked here; the app's own module builds the server command, in the process this one
    becomes (the core never imports the app).
    """
    from importlib.util import find_spec

    if find_spec("app") is None:
        raise UsageError("the web app (package 'app') is not installed beside explorer_core")
    env_origins = [o.strip() for o in os.environ.get("BILIMOVICH_ALLOWED_ORIGINS", "").split(",") if o.strip()]
    origins = args.allow_websocket_origin or env_origins or [f"localhost:{args.port}", f"127.0.0.1:{args.port}"]
    for origin in origins:
        if not re.fullmatch(r"[A-Za-z0-9.\-\[\]:]+", origin) or origin == "*":
            raise UsageError(f"--allow-websocket-origin must be HOST[:PORT] (never '*'), got {origin!r}")
    procs = config.resolve_procs(args.procs)  # a ValueError is a usage error
    _check_listen(args.address, args.port)
    spec = {"port": args.port, "address": args.address, "threads": args.threads, "origins": origins,
            "session_lifetime": args.session_lifetime, "procs": procs, "show": bool(args.show),
            "max_sessions_per_address": args.max_sessions_per_address}  # fmt: skip
    sys.stderr.write(f"Bilimovich Explorer on http://{args.address}:{args.port}/main ({procs} process(es))\n")
    sys.stderr.flush()
    os.execv(sys.executable, [sys.executable, "-m", "app.serve", "--launch", export.dumps(spec)])
    return 0  # not reached


def _check_listen(address: str, port: int) -> None:
    """The server can listen on ``address:port`` (a name that resolves to an address of this machine, a port
    free): one usage line naming the value, before the server starts (it printed "ERROR: -2" and exited 1)."""
    import socket

    try:
        infos = socket.getaddrinfo(address, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        raise UsageError(f"--address {address!r} is no address or host name ({exc})") from None
    family, kind, proto, _, where = infos[0]
    with socket.socket(family, kind, proto) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(where)
        except OSError as exc:
            raise UsageError(f"cannot listen on --address {address} --port {port}: {exc.strerror or exc}") from None


def _out_dir(args: argparse.Namespace) -> str:
    """``--out`` as an absolute folder, created (its parent must exist: a typo fails at once)."""
    out = os.path.abspath(args.out)
    parent = os.path.dirname(out)
    if not os.path.isdir(parent):
        raise UsageError(f"--out parent directory does not exist: {parent}")
    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"--out must be a directory, got the file {out}")
    os.makedirs(out, exist_ok=True)
    if not os.access(out, os.W_OK | os.X_OK):
        raise UsageError(f"--out directory cannot be written: {out}")
    return out


def _staged_args(p: argparse.ArgumentParser, stages: str, quick: str) -> None:
    p.add_argument("--quick", action="store_true", help=f"reduced sizes: {quick}")
    p.add_argument("--size", choices=["tiny", "quick", "full"], help="explicit size (overrides --quick)")
    p.add_argument("--stages", metavar="LIST", help=f"subset of {stages}")


def _reproduce_args(p: argparse.ArgumentParser) -> None:
    _staged_args(p, "sections,lyapunov,drift,bifurcation,chart", "a few minutes")
    p.add_argument("--chaos-test", metavar="NAME", help="how a trajectory is found chaotic: in the Lyapunov "
                   "stage's search for an IC and the chart's early stop, as the chart's --chaos-test (default: "
                   "the chart's)")  # fmt: skip


def _staged_run(args: argparse.Namespace) -> tuple[str, str, tuple[str, ...] | None, Callable[[str, float], None]]:
    """Output folder (created), size, stages and a progress printer of ``reproduce`` / ``failures``."""
    stages = None if args.stages is None else tuple(s.strip() for s in args.stages.split(","))
    if stages is not None and not all(stages):  # '' or 'a,,b' named no stage: never "all of them"
        raise UsageError(f"--stages must name stages, comma-separated, got {args.stages!r}")
    out = _out_dir(args)
    size = args.size or ("quick" if args.quick else "full")

    def progress(stage: str, elapsed: float) -> None:
        if not args.quiet:
            sys.stderr.write(f"{stage}: {elapsed:.1f} s\n")
            sys.stderr.flush()

    return out, size, stages, progress


def cmd_reproduce(args: argparse.Namespace) -> int:
    from explorer_core.studies.reproduce import reproduce

    out, size, stages, progress = _staged_run(args)
    start = time.perf_counter()
    with _Run(args) as run:
        chosen = {} if args.chaos_test is None else {"chaos_test": args.chaos_test}  # checked by reproduce
        rep = reproduce(size, stages=stages, progress=lambda u: u.detail and progress(*u.detail), cancel=run, **chosen)
    if run() or not rep.completed:  # stopped: no figures, and no wait for matplotlib's import (a second or more)
        from explorer_core.losses import Loss

        figures: list[str] = []
        rep.lost.append(Loss("figures", 1, "not drawn: the run was stopped (run it again for them)"))
    else:
        from explorer_core.reports.render import render_reproduction  # matplotlib only here

        figures = render_reproduction(rep, out, cancel=run)  # a stop signal: no more figures
    table = [os.path.join(out, "table.md"), os.path.join(out, "table.csv")]
    rep.write_table(*table)
    summary = {**rep.summary(), "figures": figures, "table": table, "elapsed_s": round(time.perf_counter() - start, 2)}
    export.write_json(os.path.join(out, "reproduce.json"), summary)
    lines = [rep.table_markdown(),
             f"{len(figures)} figures and the table in {out} ({summary['elapsed_s']:.0f} s, size {size})"]  # fmt: skip
    return _finish(args, summary, lambda: lines, result=rep, what="results")


def _bench_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="a small run (under a minute): short horizons, few settings")
    p.add_argument("--cases", metavar="LIST", help="subset of regular,chaotic,attractor,drift")
    p.add_argument("--repeat", type=_count("repeat", 1, 100), help="timing repeats (median; default 3, quick 1)")
    p.add_argument("--no-peers", action="store_true", help="only this project's methods")
    p.add_argument("--no-throughput", action="store_true", help="skip the throughput and target measurements")
    p.add_argument(
        "--indicators",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the chaos indicators against a long Lyapunov run (~20 s; default: on, off with --quick)",
    )
    p.add_argument("--cache-dir", metavar="DIR", help="reference cache (default $BILIMOVICH_CACHE_DIR/bench)")


def cmd_bench(args: argparse.Namespace) -> int:
    import dataclasses

    from explorer_core.studies import bench

    cfg = bench.quick_config() if args.quick else bench.full_config()
    changes: dict[str, Any] = {}
    if args.cases is not None:
        changes["cases"] = tuple(c.strip() for c in args.cases.split(",") if c.strip())
    if args.repeat is not None:
        changes["repeat"] = args.repeat
    if args.no_peers:
        changes["peers"] = ()
    if args.no_throughput:
        changes["throughput"] = False
    if args.indicators is not None:
        changes["indicators"] = args.indicators
    cfg = dataclasses.replace(cfg, **changes)
    cfg.validate()
    out = _out_dir(args)

    def progress(p: Any) -> None:
        if not args.quiet:
            sys.stderr.write(f"[{p.done}/{p.total} {p.elapsed_s:5.0f} s] {p.text}\n")
            sys.stderr.flush()

    with _Run(args) as run:
        res = bench.run_bench(cfg, cache_dir_=args.cache_dir, progress=progress, cancel=run)
    data = res.as_dict()
    files = res.write(out)
    from explorer_core.reports.render import render_work_precision  # matplotlib only here

    png = os.path.join(out, "work_precision.png")
    render_work_precision(data, png)
    files.append(png)
    bench.save_latest(data, args.cache_dir)  # the app's speed-vs-accuracy tab shows the latest run
    summary = {"out": files, "completed": res.completed, "elapsed_s": round(res.elapsed_s, 1),
               "horizons": {k: c.horizon for k, c in res.cases.items()}, "peers": res.peers,
               "ratios": data["ratios"], "throughput": data["throughput"],
               "indicators": data["indicators"]}  # fmt: skip
    lines = [res.headline(), f"{len(res.rows)} rows; {', '.join(os.path.basename(f) for f in files)} in {out}"]
    return _finish(args, summary, lambda: lines, result=res, what="measurements")


def cmd_failures(args: argparse.Namespace) -> int:
    from explorer_core.studies.failures import failure_map

    out, size, stages, progress = _staged_run(args)
    start = time.perf_counter()
    with _Run(args) as run:
        fm = failure_map(size, stages=stages, progress=progress, cancel=run)
    from explorer_core.reports.failure_render import render_failures  # matplotlib only here

    figures = render_failures(fm, out)
    summary = {**fm.summary(), "figures": figures, "elapsed_s": round(time.perf_counter() - start, 2)}
    export.write_json(os.path.join(out, "failures.json"), summary)
    line = f"failures.json and {len(figures)} pictures in {out} ({summary['elapsed_s']:.0f} s, size {size})"
    return _finish(args, summary, lambda: [line], result=fm, what="measurements")


def cmd_worker(args: argparse.Namespace) -> int:
    from explorer_core import worker

    if args.action == "stop":
        stopped = worker.stop_all()
        print(f"stopped {len(stopped)} worker(s)" + "".join(f"\n  {p}" for p in stopped))
    else:
        print(worker.status_text())  # pings the socket: a dead worker's file is not "listening"
    return 0


def cmd_warmup(args: argparse.Namespace) -> int:
    from explorer_core.warm import warm_all

    start = time.perf_counter()
    warm_all()
    print(f"kernels ready in {time.perf_counter() - start:.2f} s")
    return 0


# --- the table ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Command:
    """One command: its arguments, its run (arguments -> inputs -> analysis -> outputs), its output files.

    ``out``: the suffixes ``--out`` may end in (checked, with writability, before the run; ``"dir"``: a folder
    the command creates; empty: no ``--out``); ``system``/``numerics``: the shared argument groups;
    ``flags``: which of ``--json``/``--quiet`` it has.
    """

    help: str
    arguments: Callable[[argparse.ArgumentParser], None] | None
    run: Callable[[argparse.Namespace], int]
    out: tuple[str, ...] = ()
    out_help: str = ""
    system: bool = True
    numerics: bool = True
    flags: tuple[str, ...] = ("json", "quiet")
    files: dict[str, tuple[str, ...]] = field(default_factory=dict)  # other output options: dest -> suffixes
    #: An analysis command (run by :func:`cmd_analysis`, its flags from the registry's builder and runner).
    analysis: bool = False
    #: It refuses to run with neither ``--out`` nor ``--json`` (nothing would be kept): always, or when this says
    #: so of the spec (``critical --track``).
    needs_output: bool | Callable[[Any], bool] = False
    #: ``--scheduler`` (a Dask cluster) is passed to the runner as ``executor``.
    scheduler: bool = False
    #: Output suffixes drawn by a function of reports/ (``module:name``, called with the result and the path).
    pictures: dict[str, str] = field(default_factory=dict)
    #: What an interrupted run wrote ("pixels", "values", ...).
    what: str = "results"
    #: Help of the other output options (``files``).
    file_help: dict[str, str] = field(default_factory=dict)
    #: Prints its JSON without ``--json`` too when it wrote no file (``tprime``, ``critical``).
    json_unless_out: bool = False
    #: Keywords the command always gives the builder (the range's end checked before the work: ``check_end``).
    fixed: dict[str, Any] = field(default_factory=dict)


def _no_args(p: argparse.ArgumentParser) -> None:
    pass


COMMANDS: dict[str, Command] = {
    "scenes": Command("list the paper's scenes", _scenes_args, cmd_scenes, system=False, numerics=False, flags=()),
    "section": Command("stroboscopic (Poincare) section at t0 + k T", None, cmd_analysis, CSV,
                       "CSV with columns traj,k,q,r", analysis=True, what="points"),
    "density": Command("a long section (up to 10^7 points) as a density image of a window", None, cmd_analysis,
                       NPZ, "counts (H x W, row 0 at R0), q_edges, r_edges, summary", analysis=True,
                       what="image's points"),
    "critical": Command("equilibria ('critical points') of the frozen-time field", None, cmd_analysis, CSV,
                        "CSV branch,t,q,r,type,eig... of --track", numerics=False, flags=("json",), analysis=True,
                        json_unless_out=True, needs_output=lambda spec: spec.track),
    "tprime": Command("sign and value of T' = dT/dt on a (q, r) grid", None, cmd_analysis, NPZ,
                      "arrays kind,t,q,r,values,sign,ok,status,params", flags=("json",), analysis=True,
                      json_unless_out=True),
    "lyapunov": Command("Lyapunov exponents, Kaplan-Yorke dimension, divergence check", None, cmd_analysis,
                        files={"history": CSV}, analysis=True, what="periods' estimates",
                        file_help={"history": "running estimates per period (member,k,L1,L2,...)"}),
    "bifurcation": Command("orbit diagram of the Poincare map over one parameter", None, cmd_analysis, CSV,
                           "CSV sweep,value_index,value,ic,k,q,r,status", analysis=True, needs_output=True,
                           scheduler=True, what="values"),
    "orbits": Command("periodic orbits of the Poincare map: Newton on P^n(x) - x, multipliers, type", None,
                      cmd_analysis, CSV, "orbit,period,type,stable,j,q,r,mu1_re,mu1_im,mu2_re,mu2_im", analysis=True,
                      what="orbits"),
    "manifolds": Command("stable and unstable manifolds of a saddle orbit, homoclinic points", None, cmd_analysis,
                         CSV, "CSV branch,kind,s,q,r (s: arc length from the saddle)", analysis=True,
                         what="manifolds' points"),
    "continue": Command("follow a periodic orbit in a parameter through folds and period doublings", None,
                        cmd_analysis, CSV, "FILE.csv: a row per point: branch,period,value,q,r,mu1_re,mu1_im,"
                        "mu2_re,mu2_im,stable,bifurcation,coefficient,coefficient_error,criticality; FILE.codim2.csv "
                        "(with --param2): a row per codimension-two point of the curves instead: curve,curve_type,"
                        "period,type,name,value,value2,error,q,r,mu1_re,mu1_im,mu2_re,mu2_im,switched_from "
                        "(docs/continuation.md)",
                        analysis=True, what="branches", fixed={"check_end": True}),
    "chart": Command("chart of dynamical regimes on a plane of two parameters", None, cmd_analysis,
                     (".npz", ".csv", ".png", ".json"), ".npz, .csv, .json or .png (repeatable)", analysis=True,
                     needs_output=True, scheduler=True, what="pixels",
                     pictures={".png": "explorer_core.reports.render:render_chart"}),
    "basins": Command("basins of attraction: which attractor each IC of a grid reaches", None, cmd_analysis,
                      NPZ, "arrays q (NX), r (NY), label (NY x NX)", analysis=True, what="pixels"),
    "fit": Command("polynomial fits of the drift q_k, r_k over a window of k, and the implied map", None,
                   cmd_analysis, CSV, "the members' series member,k,q,r", analysis=True),
    "body": Command("the rigid body's orientation along a trajectory (quaternions, omega, T; frames in a period)",
                    None, cmd_analysis, (".csv", ".npz", ".json"), "frame,k,t,p,q,r,w,x,y,z,T (.csv), or .npz/.json",
                    analysis=True, what="frames"),
    "symmetry": Command("check the involution t -> -t, q -> q, r -> -r on sections", None, cmd_analysis,
                        flags=("json",), analysis=True),
    "birkhoff": Command("weighted Birkhoff averages: digits of convergence, regular or chaotic, rotation numbers",
                        None, cmd_analysis, (".csv", ".json"), "one row per orbit (.csv) or the summary (.json)",
                        analysis=True, what="orbits"),
    "sali": Command("SALI and GALI_2 of two deviation vectors: regular or chaotic in few periods", None, cmd_analysis,
                    (".csv", ".npz", ".json"), "one row per orbit (.csv), the histories (.npz) or the summary (.json)",
                    analysis=True, what="orbits"),
    "ftle": Command("finite-time Lyapunov exponent map over a grid of initial conditions (forward, backward)",
                    None, cmd_analysis, (".npz", ".csv", ".json"), "arrays q, r, forward/backward (NY x NX), "
                    "status_* (.npz), one row per pixel (.csv) or the summary (.json)", analysis=True,
                    needs_output=True, scheduler=True, what="pixels"),
    "serve": Command("run the web explorer (panel serve app/main.py)", _serve_args, cmd_serve, system=False,
                     numerics=False, flags=()),
    "reproduce": Command("every figure of the paper as PNG and the table of its numbers",
                         _reproduce_args, cmd_reproduce, ("dir",), "output directory (created)", system=False,
                         numerics=False),
    "bench": Command("work-precision benchmark: error vs time, ours against solve_ivp/numbalsoda", _bench_args,
                     cmd_bench, ("dir",), "writes bench.json/.csv/.md, work_precision.png, ...", system=False,
                     numerics=False),
    "failures": Command("where the methods fail: RK4 on the drift, costs, statuses, float32, Lyapunov",
                        lambda p: _staged_args(p, "rk4,cost,scenarios,floats,lyapunov", "about 30 s on 2 cores"),
                        cmd_failures, ("dir",), "output directory (created): failures.json, PNGs", system=False,
                        numerics=False),
    "worker": Command("the warm worker that answers small commands at once: status or stop",
                      lambda p: p.add_argument("action", choices=["status", "stop"]), cmd_worker, system=False,
                      numerics=False, flags=()),
    "warmup": Command("compile the numba kernels into the on-disk cache", _no_args, cmd_warmup, system=False,
                      numerics=False, flags=()),
}  # fmt: skip

_FLAG_HELP = {
    "json": "print the JSON result",
    "quiet": "no progress line and no result lines (errors and lost: lines still go to stderr)",
}


#: ``build_parser(EVERY)``: every analysis command's flags (loads every analysis: for tests and docs).
EVERY = "*"


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; ``command``'s analysis flags (from its builder's declarations) are added when it is the command
    being run or asked for help: building the parser for another command, or for ``--help``, loads no analysis."""
    description = "Inhomogeneous nonholonomic Bilimovich system: sections, equilibria, T' maps."
    parser = _Parser(prog="bilimovich", description=description)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for name, c in COMMANDS.items():
        p = sub.add_parser(name, help=c.help)
        if c.system:
            _add_system_args(p)
        if c.numerics:
            _add_numerics_args(p)
        if c.arguments is not None:
            c.arguments(p)
        if c.analysis and command in (name, EVERY):
            from explorer_core.registry import by_command

            a = by_command(name)
            _add_declared_args(p, a.get("builder"), f"{name} (the analysis' options)")
            if _declared(a.get("run")):
                _add_declared_args(p, a.get("run"), "how it runs")
        if c.scheduler:
            _scheduler_arg(p)
        for dest, suffixes in c.files.items():
            p.add_argument(f"--{dest}", metavar=f"FILE{suffixes[0]}", help=c.file_help.get(dest))
        _add_nested_args(p, name)
        if c.out:
            dir_ = c.out == ("dir",)
            metavar = "DIR" if dir_ else "FILE" + (c.out[0] if len(c.out) == 1 else "")
            p.add_argument("--out", required=dir_, action="append" if len(c.out) > 1 else "store", metavar=metavar,
                           help=c.out_help)  # fmt: skip
        for flag in c.flags:
            p.add_argument(f"--{flag}", action="store_true", help=_FLAG_HELP[flag])
        p.set_defaults(func=c.run)
    return parser


def _check_outputs(args: argparse.Namespace, c: Command) -> None:
    """Every output file's suffix and writability, before any work (a folder ``--out`` is made by the run)."""
    options = dict(c.files)
    if c.out and c.out != ("dir",):
        options["out"] = c.out
    for dest, suffixes in options.items():
        paths = getattr(args, dest, None)
        for path in paths if isinstance(paths, list) else [paths] if paths is not None else []:
            export.check_output(path, suffixes, f"--{dest.replace('_', '-')}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; its exit status. A stop signal (:data:`STOP_SIGNALS`) before the work starts ends it at
    once; once the work runs, the work stops at its next look, writes what it computed, prints what was lost and
    exits ``128 + signal`` (130 for Ctrl-C, 143 for SIGTERM). A run in which every member failed exits
    :data:`FAILED_STATUS`."""
    global _signals
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    args = parser.parse_args(argv)
    prefix = f"bilimovich {args.command}"
    # Python warnings (numpy's overflow in a hostile input, say) are collected: one line each, in this
    # command's words, after a run that succeeded; a failed run says only why it failed.
    outer = _signals
    with warnings.catch_warnings(record=True) as caught, _Signals() as signals:
        warnings.simplefilter("always")
        _signals, launch.began = signals, True
        try:
            status = _run(args, prefix)
        finally:
            _signals = outer
        if signals.received and status == 0:  # the work was done when the signal came: all was written
            sys.stderr.write(f"{prefix}: interrupted ({signals.name()}) as its work ended; what it wrote is "
                             "complete unless a lost: line above says otherwise\n")  # fmt: skip
            status = signals.status()
    if status == 0:
        for text in dict.fromkeys(f"{w.category.__name__}: {' '.join(str(w.message).split())}" for w in caught):
            sys.stderr.write(f"{prefix}: warning: {text}\n")
    return status


def _run(args: argparse.Namespace, prefix: str) -> int:
    """The one error path: bad input or an unusable output is one line and exit 2, never a traceback."""
    try:
        _check_outputs(args, COMMANDS[args.command])
        return args.func(args)
    except BrokenPipeError:  # the reader went away (| head): nothing left to say
        return 0
    # ParameterError and export.OutputError are ValueErrors; SchedulerError (an unusable Dask cluster) a
    # ConnectionError; an OSError is an output that failed after all.
    except (UsageError, ValueError, ConnectionError, OSError) as exc:
        text = str(exc)
        if isinstance(exc, OSError) and exc.strerror:  # an OSError without a file name is not "...: None"
            text = exc.strerror if exc.filename is None else f"{exc.strerror}: {exc.filename}"
        sys.stderr.write(f"{prefix}: error: {' '.join(text.split())}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"{prefix}: interrupted\n")
        return _signals.status() if _signals is not None else 130
    except Exception as exc:  # never a traceback for users; BILIMOVICH_DEBUG=1 shows it
        if os.environ.get("BILIMOVICH_DEBUG"):
            raise
        sys.stderr.write(f"{prefix}: internal error ({type(exc).__name__}): {' '.join(str(exc).split())}\n")
        return 1


def entry() -> None:
    """``python -m explorer_core.cli``: :func:`explorer_core.worker.entry` with this module's :func:`main`."""
    from explorer_core import worker

    worker.entry(lambda: main)


if __name__ == "__main__":
    entry()
