"""The ``bilimovich`` command line: batch work on the same core the app uses.

Every command takes the system as ``--scene ID`` and/or explicit flags
(``--inertia I11,I22,I33,I12,I13,I23 --alpha A --g0 --g1 --g2 --omega --t0``, or
single entries ``--I13 0.2``); explicit flags override the scene. Bad input
gives one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from explorer_core import __version__, config
from explorer_core.model import INERTIA_NAMES, ParameterError, Params
from explorer_core.scenes import Scene, get_scene, list_scenes
from explorer_core.section import Numerics, SectionChunk, check_box, random_ics, section


class UsageError(Exception):
    """Bad command-line input (reported as one line, exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line, not a usage block."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def _floats(text: str, n: int | None, name: str) -> list[float]:
    parts = [p.strip() for p in str(text).split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"{name} must be comma-separated numbers, got {text!r}") from None
    if n is not None and len(vals) != n:
        raise UsageError(f"{name} needs {n} comma-separated numbers, got {len(vals)} in {text!r}")
    for v in vals:
        if not math.isfinite(v):
            raise UsageError(f"{name} must be finite, got {text!r}")
    return vals


def _number(name: str):
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return v

    return parse


def _count(name: str, lo: int, hi: int):
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
    g.add_argument("--method", choices=["rk4", "dp5", "dop853"], help=f"default {config.DEFAULT_METHOD}")
    g.add_argument("--rtol", type=_number("rtol"), help=f"relative tolerance (default {config.DEFAULT_RTOL:g})")
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
    for n in INERTIA_NAMES:
        if getattr(args, n) is not None:
            changes[n] = getattr(args, n)
    for f in ("alpha", "g0", "g1", "g2", "omega", "t0"):
        if getattr(args, f) is not None:
            changes[f] = getattr(args, f)
    return base.with_(**changes), scene


def _numerics(args: argparse.Namespace, scene: Scene | None, periods: int) -> Numerics:
    base = scene.numerics(periods) if scene else Numerics()
    kw = base.as_dict()
    kw.pop("adaptive", None)
    if args.method:
        kw["method"] = args.method
    if args.rtol is not None:
        kw["rtol"] = args.rtol
        kw["atol"] = args.atol if args.atol is not None else args.rtol
    elif args.atol is not None:
        kw["atol"] = args.atol
    if args.steps_per_period is not None:
        kw["steps_per_period"] = args.steps_per_period
    if args.bound is not None:
        kw["bound"] = args.bound
    if args.max_steps is not None:
        kw["max_steps"] = args.max_steps
    return Numerics(**kw)


def _write_json(obj: Any) -> None:
    sys.stdout.write(json.dumps(obj, indent=None, separators=(",", ": ")) + "\n")
    sys.stdout.flush()


def _check_out(path: str) -> None:
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise UsageError(f"--out directory does not exist: {d}")


# --- commands ------------------------------------------------------------------------


def cmd_scenes(args: argparse.Namespace) -> int:
    scenes = list_scenes()
    if args.json:
        _write_json([s.as_dict() for s in scenes])
        return 0
    width = max(len(s.id) for s in scenes)
    for s in scenes:
        p = s.params
        print(f"{s.id:<{width}}  alpha={p.alpha:<7g} I={','.join(f'{v:g}' for v in p.inertia):<22} {s.title}")
    return 0


def cmd_section(args: argparse.Namespace) -> int:
    params, scene = _params(args)
    periods = args.periods if args.periods is not None else (scene.periods if scene else None)
    if periods is None:
        raise UsageError("--periods is required (no --scene to take it from)")
    transient = args.transient if args.transient is not None else (scene.transient if scene else 0)
    if args.ic:
        ics = np.array([_floats(s, 2, "--ic") for s in args.ic])
    elif args.random is not None:
        box = check_box(_floats(args.box, 4, "--box")) if args.box else (scene.box if scene else (-2, 2, -2, 2))
        ics = random_ics(args.random, box, seed=args.seed)
    elif scene is not None:
        ics = scene.initial_conditions()
    else:
        raise UsageError("give initial conditions: --ic Q,R (repeatable) or --random N")
    numerics = _numerics(args, scene, periods)
    if args.out:
        _check_out(args.out)

    stop = {"flag": False}

    def on_signal(signum: int, frame: Any) -> None:
        stop["flag"] = True

    old = signal.signal(signal.SIGINT, on_signal)
    show = not args.quiet and sys.stderr.isatty()
    last = [0.0]

    def progress(chunk: SectionChunk) -> None:
        now = time.perf_counter()
        if show and (now - last[0] > 0.2 or chunk.done_periods == chunk.total_periods):
            last[0] = now
            alive = int(np.count_nonzero(chunk.status == 0))
            sys.stderr.write(
                f"\r{chunk.done_periods}/{chunk.total_periods} periods, {alive}/{chunk.status.size} running, "
                f"{chunk.elapsed_s:.1f} s "
            )
            sys.stderr.flush()

    try:
        sec = section(
            params,
            ics,
            periods,
            transient=transient,
            numerics=numerics,
            direction=-1 if args.backward else 1,
            progress=progress,
            cancel=lambda: stop["flag"],
        )
    finally:
        signal.signal(signal.SIGINT, old)
        if show:
            sys.stderr.write("\n")
    rows = sec.to_csv(args.out) if args.out else None
    summary = sec.summary()
    if args.scene:
        summary["scene"] = args.scene
    if rows is not None:
        summary["csv"] = {"path": args.out, "rows": rows}
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        labels = sec.status_labels()
        counts = {lab: labels.count(lab) for lab in sorted(set(labels))}
        print(f"{sec.n} trajectories, {int(sec.npts.sum())} points, {sec.elapsed_s:.3f} s, status {counts}")
    if not sec.completed:
        sys.stderr.write("bilimovich: interrupted; the points computed so far were written\n")
        return 130
    return 0


def cmd_critical(args: argparse.Namespace) -> int:
    from explorer_core.equilibria import equilibria, equilibrium_tracks

    params, _ = _params(args)
    if args.track:
        if not args.out and not args.json:
            raise UsageError("--track needs --out FILE.csv (or --json)")
        tracks = equilibrium_tracks(params, n_t=args.n_t)
        if args.out:
            _check_out(args.out)
            tracks.to_csv(args.out)
        if args.json:
            _write_json(tracks.summary())
        return 0
    t = args.t if args.t is not None else params.t0
    _write_json(equilibria(params, t).to_dict())
    return 0


def cmd_tprime(args: argparse.Namespace) -> int:
    from explorer_core.tprime import energy_change_map, tprime_map

    params, scene = _params(args)
    q_range = _floats(args.q_range, 2, "--q-range") if args.q_range else (scene.q_range if scene else (-3.0, 3.0))
    r_range = _floats(args.r_range, 2, "--r-range") if args.r_range else (scene.r_range if scene else (-3.0, 3.0))
    if args.out:
        _check_out(args.out)
    if args.per_period:
        if args.t is not None:
            raise UsageError("--per-period integrates over one period from t0; use --t0, not --t")
        tmap = energy_change_map(params, q_range, r_range, args.grid, numerics=_numerics(args, None, 1))
    else:
        t = args.t if args.t is not None else params.t0
        tmap = tprime_map(params, t, q_range, r_range, args.grid)
    if args.out:
        tmap.to_npz(args.out)
    if args.json or not args.out:
        _write_json(
            {
                "kind": tmap.kind,
                "t": tmap.t,
                "grid": [int(tmap.q.size), int(tmap.r.size)],
                "fractions": tmap.fractions(),
                "min": float(tmap.values[tmap.ok].min()) if tmap.ok.any() else None,
                "max": float(tmap.values[tmap.ok].max()) if tmap.ok.any() else None,
                "elapsed_s": round(tmap.elapsed_s, 6),
                "out": args.out,
            }
        )
    return 0


def cmd_warmup(args: argparse.Namespace) -> int:
    from explorer_core.integrators import warmup

    start = time.perf_counter()
    warmup()
    print(f"kernels ready in {time.perf_counter() - start:.2f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bilimovich",
        description="Inhomogeneous nonholonomic Bilimovich system: sections, equilibria, T' maps.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("scenes", help="list the paper's scenes")
    p.add_argument("--json", action="store_true", help="full scene data as JSON")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("section", help="stroboscopic (Poincare) section at t0 + k T")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--ic", action="append", metavar="Q,R", help="initial condition (repeatable)")
    p.add_argument("--random", type=_count("random", 1, config.MAX_TRAJECTORIES), metavar="N")
    p.add_argument("--seed", type=_count("seed", 0, 2**63 - 1), default=0)
    p.add_argument("--box", metavar="QMIN,QMAX,RMIN,RMAX", help="box for --random")
    p.add_argument("--periods", type=_count("periods", 1, config.MAX_PERIODS), help="section points per trajectory")
    p.add_argument("--transient", type=_count("transient", 0, config.MAX_PERIODS), help="periods dropped first")
    p.add_argument("--backward", action="store_true", help="integrate backward in time (points at t0 - k T)")
    p.add_argument("--out", metavar="FILE.csv", help="CSV with columns traj,k,q,r")
    p.add_argument("--json", action="store_true", help="print a JSON summary to stdout")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_section)

    p = sub.add_parser("critical", help="equilibria ('critical points') of the frozen-time field")
    _add_system_args(p)
    p.add_argument("--t", type=_number("t"), help="frozen time (default t0)")
    p.add_argument("--track", action="store_true", help="track them over one period")
    p.add_argument("--n-t", type=_count("n-t", 2, 1_000_000), default=721, help="time samples for --track")
    p.add_argument("--out", metavar="FILE.csv")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_critical)

    p = sub.add_parser("tprime", help="sign and value of T' = dT/dt on a (q, r) grid")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--t", type=_number("t"), help="frozen time (default t0)")
    p.add_argument("--q-range", metavar="A,B")
    p.add_argument("--r-range", metavar="C,D")
    p.add_argument("--grid", type=_count("grid", 2, config.MAX_GRID), default=200)
    p.add_argument("--per-period", action="store_true", help="energy change over one period from t0 instead")
    p.add_argument("--out", metavar="FILE.npz")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_tprime)

    p = sub.add_parser("warmup", help="compile the numba kernels into the on-disk cache")
    p.set_defaults(func=cmd_warmup)
    return parser


#: Options whose value is a comma list that may start with a minus sign.
_LIST_OPTIONS = {"--ic", "--box", "--inertia", "--q-range", "--r-range"}


def _glue_negative_lists(argv: list[str]) -> list[str]:
    """Let ``--q-range -1,1`` mean ``--q-range=-1,1`` (argparse would take -1,1 for an option)."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in _LIST_OPTIONS and i + 1 < len(argv) and re.match(r"^-[0-9.]", argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_glue_negative_lists(list(sys.argv[1:] if argv is None else argv)))
    try:
        return args.func(args)
    except (UsageError, ParameterError, ValueError) as exc:
        sys.stderr.write(f"bilimovich {args.command}: error: {exc}\n")
        return 2
    except OSError as exc:
        sys.stderr.write(f"bilimovich {args.command}: error: {exc.strerror or exc}: {exc.filename or ''}\n")
        return 2
    except BrokenPipeError:
        return 0
    except Exception as exc:  # never a traceback for users; BILIMOVICH_DEBUG=1 shows it
        if os.environ.get("BILIMOVICH_DEBUG"):
            raise
        sys.stderr.write(f"bilimovich {args.command}: internal error ({type(exc).__name__}): {exc}\n")
        return 1


if __name__ == "__main__":
    sys.exit(main())
