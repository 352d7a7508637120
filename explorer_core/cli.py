"""The ``bilimovich`` command line: batch work on the same core the app uses.

Every command takes the system as ``--scene ID`` and/or explicit flags
(``--inertia I11,I22,I33,I12,I13,I23 --alpha A --g0 --g1 --g2 --omega --t0``, or
single entries ``--I13 0.2``); explicit flags override the scene. Bad input
gives one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import signal
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from explorer_core import __version__, config
from explorer_core.scenes import Scene, get_scene, list_scenes
from explorer_core.solve.numerics import Numerics, check_box, random_ics
from explorer_core.system.params import INERTIA_NAMES, ParameterError, Params


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


def _numerics(args: argparse.Namespace, scene: Scene | None, periods: int, base: Numerics | None = None) -> Numerics:
    base = base or (scene.numerics(periods) if scene else Numerics())
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


def _periods_transient(args: argparse.Namespace, scene: Scene | None) -> tuple[int, int]:
    """``--periods`` and ``--transient``, or the scene's."""
    periods = args.periods if args.periods is not None else (scene.periods if scene else None)
    if periods is None:
        raise UsageError("--periods is required (no --scene to take it from)")
    transient = args.transient if args.transient is not None else (scene.transient if scene else 0)
    return periods, transient


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
    from explorer_core.solve.section import SectionChunk, section

    params, scene = _params(args)
    periods, transient = _periods_transient(args, scene)
    if args.ic:
        ics = np.array([_floats(s, 2, "--ic") for s in args.ic])
    elif args.random is not None:
        box = check_box(_floats(args.box, 4, "--box")) if args.box else (scene.box if scene else (-2, 2, -2, 2))
        ics = random_ics(args.random, box, seed=args.seed)
    elif scene is not None:
        ics = scene.initial_conditions()
    else:
        raise UsageError("give initial conditions: --ic Q,R (repeatable) or --random N")
    numerics = _numerics(args, scene, periods + transient)
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
    warnings = []
    if args.json or not args.quiet:
        from explorer_core.analyses.reliability import assess_section

        window = (*scene.q_range, *scene.r_range) if scene else None
        warnings = assess_section(sec, pixel=scene.pixel_size() if scene else None, window=window)
        summary["reliability"] = [w.as_dict() for w in warnings]
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        labels = sec.status_labels()
        counts = {lab: labels.count(lab) for lab in sorted(set(labels))}
        print(f"{sec.n} trajectories, {int(sec.npts.sum())} points, {sec.elapsed_s:.3f} s, status {counts}")
    if not args.quiet:
        # When the method is unreliable for this run, say so (one line each; --quiet silences them).
        for w in warnings:
            sys.stderr.write(f"bilimovich section: {w.line()}\n")
    if not sec.completed:
        sys.stderr.write("bilimovich: interrupted; the points computed so far were written\n")
        return 130
    return 0


def cmd_density(args: argparse.Namespace) -> int:
    from explorer_core.analyses.density import MAX_DENSITY_POINTS, density_numerics, iter_density

    params, scene = _params(args)
    periods, transient = _periods_transient(args, scene)
    box = check_box(_floats(args.box, 4, "--box"), "--box") if args.box else (scene.box if scene else None)
    if box is None:
        raise UsageError("give --box Q0,Q1,R0,R1 for the random initial conditions (no --scene to take it from)")
    view = (
        check_box(_floats(args.view, 4, "--view"), "--view")
        if args.view
        else ((*scene.q_range, *scene.r_range) if scene else box)
    )
    pixels = [int(v) for v in _floats(args.pixels, 2, "--pixels")] if args.pixels else [800, 600]
    if args.pixels and not all(float(v).is_integer() and 1 <= v <= 4096 for v in _floats(args.pixels, 2, "--pixels")):
        raise UsageError(f"--pixels W,H must be whole numbers in [1, 4096], got {args.pixels!r}")
    if args.random * periods > MAX_DENSITY_POINTS:
        raise UsageError(f"--random {args.random} x --periods {periods} = {args.random * periods} points; "
                         f"at most {MAX_DENSITY_POINTS}")  # fmt: skip
    bound = scene.bound if scene else config.DEFAULT_ESCAPE_BOUND
    numerics = _numerics(args, None, 1, base=density_numerics(view, pixels, bound))
    if args.out:
        _check_out(args.out)
    ics = random_ics(args.random, box, seed=args.seed)
    write, show = _progress_line(args.quiet)
    img = None
    with _Interrupt() as stop:
        for img, _ in iter_density(params, ics, periods, view=view, pixels=pixels, transient=transient,
                                   numerics=numerics, max_chunk=64, cancel=stop):  # fmt: skip
            write(f"{img.done_periods}/{periods} periods, {img.points:,} points, {img.elapsed_s:.1f} s")
    if show:
        sys.stderr.write("\n")
    assert img is not None
    summary = {**img.summary(), "params": params.as_dict(), "numerics": numerics.as_dict(),
               "ics": {"random": args.random, "box": list(box), "seed": args.seed}, "transient": transient}  # fmt: skip
    if scene is not None:
        summary["scene"] = scene.id
    if args.out:
        q = np.linspace(view[0], view[1], pixels[0] + 1)
        r = np.linspace(view[2], view[3], pixels[1] + 1)
        np.savez_compressed(args.out, counts=img.counts, q_edges=q, r_edges=r, summary=json.dumps(summary))
        summary["npz"] = {"path": args.out}
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        print(f"{img.points:,} points, {img.in_view:,} in view, {img.escaped} escaped, {img.failed} failed, "
              f"{img.elapsed_s:.2f} s")  # fmt: skip
    if stop():
        sys.stderr.write("bilimovich: interrupted; the image so far was written\n")
        return 130
    return 0


def cmd_critical(args: argparse.Namespace) -> int:
    from explorer_core.analyses.equilibria import equilibria, equilibrium_tracks

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
    from explorer_core.analyses.tprime import energy_change_map, tprime_map

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


class _Interrupt:
    """Ctrl-C sets a flag that long work polls (``cancel``); the previous handler is restored."""

    def __init__(self) -> None:
        self.flag = False
        self._old: Any = None

    def __enter__(self) -> _Interrupt:
        def on_signal(signum: int, frame: Any) -> None:
            self.flag = True

        self._old = signal.signal(signal.SIGINT, on_signal)
        return self

    def __exit__(self, *exc: Any) -> None:
        signal.signal(signal.SIGINT, self._old)

    def __call__(self) -> bool:
        return self.flag


def _progress_line(quiet: bool):
    """A throttled ``\r``-progress writer for stderr (silent unless stderr is a terminal)."""
    show = not quiet and sys.stderr.isatty()
    last = [0.0]

    def write(text: str, final: bool = False) -> None:
        now = time.perf_counter()
        if show and (final or now - last[0] > 0.2):
            last[0] = now
            sys.stderr.write(f"\r{text} ")
            sys.stderr.flush()

    return write, show


def _ics_arg(args: argparse.Namespace, scene: Scene | None) -> np.ndarray | None:
    if args.ic:
        return np.array([_floats(s, 2, "--ic") for s in args.ic])
    return None


def cmd_lyapunov(args: argparse.Namespace) -> int:
    from explorer_core.analyses.lyapunov import attractor_ensemble, lyapunov_spectrum

    params, scene = _params(args)
    ics = _ics_arg(args, scene)
    if ics is None:
        if scene is None or not scene.points:
            raise UsageError("give an initial condition: --ic Q,R")
        ics = np.array(scene.points[:1])
    transient = args.transient if args.transient is not None else (scene.transient if scene else 100)
    numerics = _numerics(args, None, args.periods)
    if args.ensemble > 1:
        if ics.shape[0] > 1:
            raise UsageError("--ensemble M takes one --ic (the members are placed on its attractor)")
        ics = attractor_ensemble(
            params, ics[0], args.ensemble, transient=transient, offset=args.offset, seed=args.seed, numerics=numerics
        )
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        res = lyapunov_spectrum(
            params,
            ics,
            args.periods,
            transient=transient,
            numerics=numerics,
            progress=lambda p: write(
                f"{p.phase} {p.done_periods}/{p.total_periods} periods, "
                f"L1 ~ {float(p.running[0, 0]):.5f}, {p.elapsed_s:.1f} s"
            ),
            cancel=stop,
        )
    if show:
        sys.stderr.write("\n")
    summary = res.summary()
    if args.scene:
        summary["scene"] = args.scene
    if args.history:
        _check_out(args.history)
        with open(args.history, "w") as fh:
            fh.write("member,k,L1,L2,divergence_mean\n")
            for i in range(res.ics.shape[0]):
                run = res.running(i)
                m = run.shape[0]
                dmean = np.cumsum(res.divs[i, :m]) / (np.arange(1, m + 1) * res.period)
                for k in range(m):
                    fh.write(f"{i},{res.transient + k + 1},{run[k, 0]!r},{run[k, 1]!r},{dmean[k]!r}\n")
        summary["history_csv"] = args.history
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        if summary["exponents"] is None:
            print(f"status {summary['status']}: no member completed the measurement")
        else:
            l1, l2, _ = summary["exponents"]
            s1, s2, _ = summary["spread"]
            print(f"Lambda (per unit time) = {l1:.6f} +- {s1:.6f}, {l2:.6f} +- {s2:.6f}, 0")
            it = summary["per_iteration"]
            print(f"per iteration (x T = {res.period:.6g}): {it[0]:.6f}, {it[1]:.6f}")
            print(
                f"Kaplan-Yorke D = {summary['kaplan_yorke']:.6f}; L1 + L2 = {l1 + l2:.6e}, "
                f"mean divergence = {summary['divergence_mean']:.6e}; status {summary['status']}"
            )
    if not res.completed:
        sys.stderr.write("bilimovich: interrupted; the estimate covers the periods computed so far\n")
        return 130
    return 0


def _seed_list(args: argparse.Namespace, numerics: Numerics) -> list[tuple[float, float]]:
    seeds = [tuple(_floats(v, 2, "--seed")) for v in (args.seed or [])]
    for q, r in seeds:
        if abs(q) > numerics.bound or abs(r) > numerics.bound:
            raise UsageError(f"--seed {q:g},{r:g} is outside the escape bound {numerics.bound:g}")
    return seeds  # type: ignore[return-value]


def cmd_orbits(args: argparse.Namespace) -> int:
    from explorer_core.analyses.orbits import (
        MAX_ITER,
        MAX_PERIOD,
        ORBIT_NUMERICS,
        PATIENCE,
        find_orbits,
        grid_seeds,
        return_seeds,
    )

    params, scene = _params(args)
    if args.period is not None and args.max_period is not None:
        raise UsageError("give --period N (that period only) or --max-period N (1..N), not both")
    cap = args.period if args.period is not None else (args.max_period if args.max_period is not None else 1)
    if not 1 <= cap <= MAX_PERIOD:
        raise UsageError(f"the period must be in [1, {MAX_PERIOD}], got {cap}")
    periods = [cap] if args.period is not None else list(range(1, cap + 1))
    numerics = _numerics(args, None, 1, base=ORBIT_NUMERICS)
    seeds = _seed_list(args, numerics)
    box = check_box(_floats(args.box, 4, "--box")) if args.box else (scene.box if scene else (-2.0, 2.0, -2.0, 2.0))
    grid = [int(v) for v in _floats(args.seeds, 2, "--seeds")] if args.seeds else None
    if grid is not None and not all(1 <= v <= config.MAX_GRID for v in grid):
        raise UsageError(f"--seeds NX,NY must be whole numbers in [1, {config.MAX_GRID}], got {args.seeds}")
    pairs: list[tuple[tuple[float, float], list[int]]] = [(s_, periods) for s_ in seeds]
    if grid is not None or not (seeds or args.returns):
        nx, ny = grid or (10, 10)
        pairs += [((float(q), float(r)), periods) for q, r in grid_seeds(box, nx, ny)]
    if args.returns:
        from explorer_core.solve.section import section

        sec = section(params, random_ics(args.returns, box, seed=0), 200, transient=300, numerics=numerics)
        tol = 0.02 * max(box[1] - box[0], box[3] - box[2])
        pairs += [((float(x[0]), float(x[1])), [n]) for x, n in return_seeds(sec.points, sec.npts, cap, tol)
                  if n in periods]  # fmt: skip
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        found: list = []
        failures: list = []
        by_periods: dict[tuple[int, ...], list] = {}
        for seed_, per in pairs:
            by_periods.setdefault(tuple(per), []).append(seed_)
        elapsed = 0.0
        for per, group in by_periods.items():
            write(f"{len(group)} seeds x periods {per[0]}..{per[-1]}")
            res = find_orbits(params, np.array(group), list(per), numerics=numerics, bound=box if args.in_box else None,
                              patience=None if args.thorough else PATIENCE, max_iter=80 if args.thorough else MAX_ITER,
                              cancel=stop)  # fmt: skip
            elapsed += res.elapsed_s
            failures += res.failures
            for o in res.orbits:
                if not any(_same(o, f) for f in found):
                    found.append(o)
            if not res.completed:
                break
    if show:
        sys.stderr.write("\n")
    found.sort(key=lambda o: (o.period, float(o.points[0, 0]), float(o.points[0, 1])))
    summary = {
        "orbits": [o.as_dict() for o in found],
        "failures": [f.as_dict() for f in failures],
        "seeds": len(pairs),
        "periods": periods,
        "completed": not stop(),
        "elapsed_s": round(elapsed, 6),
        "params": params.as_dict(),
        "numerics": numerics.as_dict(),
    }
    if args.scene:
        summary["scene"] = args.scene
    if args.out:
        _check_out(args.out)
        from explorer_core.analyses.orbits import OrbitSearch

        summary["csv"] = {"path": args.out, "rows": OrbitSearch(params, numerics, found, failures, len(pairs),
                                                                elapsed).to_csv(args.out)}  # fmt: skip
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        for o in found:
            mu = ", ".join(f"{m.real:.6g}{m.imag:+.6g}i" if m.imag else f"{m.real:.6g}" for m in o.multipliers)
            print(f"period {o.period} {o.kind:15s} at ({o.points[0, 0]:.10g}, {o.points[0, 1]:.10g})  mu = {mu}")
        print(f"{len(found)} orbits, {len(failures)} seeds without one, {elapsed:.2f} s")
    if stop():
        sys.stderr.write("bilimovich: interrupted; the orbits found so far were written\n")
        return 130
    return 0


def _same(a: Any, b: Any) -> bool:
    from explorer_core.analyses.orbits import same_orbit

    return same_orbit(a, b)


def cmd_continue(args: argparse.Namespace) -> int:
    from explorer_core.analyses.continuation import continue_orbit
    from explorer_core.analyses.orbits import ORBIT_NUMERICS
    from explorer_core.analyses.sweeps import check_param

    params, _ = _params(args)
    name = check_param(args.param)
    lo, hi = _floats(args.range, 2, "--range")
    for v in (lo, hi):  # positive-definite tensors are convex: both ends valid means the whole range is
        try:
            params.with_(**{name: v})
        except ParameterError as exc:
            raise UsageError(f"--range {args.range}: {name} = {v:g} is not a valid system ({exc})") from None
    numerics = _numerics(args, None, 1, base=ORBIT_NUMERICS)
    if args.from_ is None:
        raise UsageError("give --from Q,R: a point near the period-N orbit at the range's first value")
    q, r = _floats(args.from_, 2, "--from")
    if abs(q) > numerics.bound or abs(r) > numerics.bound:
        raise UsageError(f"--from {q:g},{r:g} is outside the escape bound {numerics.bound:g}")
    if (args.param2 is None) != (args.range2 is None):
        raise UsageError("--param2 and --range2 go together")
    range2 = _floats(args.range2, 2, "--range2") if args.range2 else None
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        res = continue_orbit(params, name, (lo, hi), (q, r), args.period, switch=args.switch,
                             max_period=args.max_period, numerics=numerics, param2=args.param2, range2=range2,
                             max_points=args.max_points, progress=lambda n, v: write(f"{n} points, {name} = {v:.8g}"),
                             cancel=stop)  # fmt: skip
    if show:
        sys.stderr.write("\n")
    summary = res.summary()
    if args.out:
        _check_out(args.out)
        with open(args.out, "w") as fh:
            fh.write("branch,period,value,q,r,mu1_re,mu1_im,mu2_re,mu2_im,stable\n")
            rows = 0
            for i, br in enumerate(res.branches):
                for v, x, mu, st in zip(br.values, br.states, br.mults, br.stable, strict=True):
                    fh.write(f"{i},{br.period},{v!r},{x[0]!r},{x[1]!r},{mu[0].real!r},{mu[0].imag!r},"
                             f"{mu[1].real!r},{mu[1].imag!r},{int(st)}\n")  # fmt: skip
                    rows += 1
        summary["csv"] = {"path": args.out, "rows": rows}
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        for i, br in enumerate(res.branches):
            print(f"branch {i}: period {br.period}, {len(br.values)} points, {name} {br.values[0]:.10g} .. "
                  f"{br.values[-1]:.10g} ({br.stop})")  # fmt: skip
        for b in res.bifurcations:
            print(f"{b.kind} of the period-{b.period} orbit at {name} = {b.value:.12g} +- {b.error:.1g}")
        for m in res.messages:
            print(m)
    if not res.completed:
        sys.stderr.write("bilimovich: interrupted; the branches computed so far were written\n")
        return 130
    return 0


def cmd_manifolds(args: argparse.Namespace) -> int:
    from explorer_core.analyses.manifolds import KINDS, PIXELS, iter_manifolds, saddle_orbit

    params, scene = _params(args)
    bound = scene.bound if scene else config.DEFAULT_ESCAPE_BOUND
    numerics = _numerics(args, None, 1, base=Numerics(method="dop853", rtol=1e-10, atol=1e-10, bound=bound))
    point = _floats(args.orbit, 2, "--orbit")
    kinds = [k.strip() for k in args.kinds.split(",")] if args.kinds else list(KINDS)
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        raise UsageError(f"--kinds must be unstable, stable or both (comma-separated), got {args.kinds!r}")
    view = check_box(_floats(args.view, 4, "--view"), "--view") if args.view else None
    if view is None and scene is not None:
        view = (*scene.q_range, *scene.r_range)
    pixels = [int(v) for v in _floats(args.pixels, 2, "--pixels")] if args.pixels else list(PIXELS)
    if args.pixels and not all(float(v).is_integer() for v in _floats(args.pixels, 2, "--pixels")):
        raise UsageError(f"--pixels W,H must be whole numbers, got {args.pixels!r}")
    write, show = _progress_line(args.quiet)
    orbit = saddle_orbit(params, point, args.period)
    result = None
    with _Interrupt() as stop:
        for result in iter_manifolds(params, orbit, kinds=kinds, length=args.length, view=view, pixels=pixels,
                                     delta_px=args.delta_px, numerics=numerics, max_points=args.max_points,
                                     cancel=stop):  # fmt: skip
            grown = ", ".join(f"{b.kind[0]}{b.label} {b.length:.3g}" for b in result.branches)
            write(f"{result.elapsed_s:.1f} s: {grown}")
    if show:
        sys.stderr.write("\n")
    assert result is not None
    summary = result.summary()
    if scene is not None:
        summary["scene"] = scene.id
    if args.out:
        _check_out(args.out)
        summary["csv"] = {"path": args.out, "rows": result.to_csv(args.out)}
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        o = result.orbit
        print(f"period {o.period} {o.kind} at ({o.points[0, 0]:.10g}, {o.points[0, 1]:.10g}), "
              f"mu = {o.multipliers[0].real:.6g}, {o.multipliers[1].real:.6g}")  # fmt: skip
        for b in result.branches:
            npts = sum(p.shape[0] for p in b.pieces)
            print(f"  {b.kind:8s} {b.label}: length {b.length:.4g}, {npts} points, {len(b.pieces)} piece(s), "
                  f"{b.status}" + (f", {b.escaped} escaped" if b.escaped else ""))  # fmt: skip
        print(f"{len(result.crossings)} crossings ({sum(c.kind == 'homoclinic' for c in result.crossings)} "
              f"homoclinic), {result.elapsed_s:.2f} s")  # fmt: skip
    if stop():
        sys.stderr.write("bilimovich: interrupted; the manifolds grown so far were written\n")
        return 130
    return 0


def _executor(args: argparse.Namespace) -> Any:
    """The Dask executor of ``--scheduler`` (None: this machine's threads)."""
    from explorer_core.parallel.cluster import executor_for
    from explorer_core.warm import warm_all

    return executor_for(args.scheduler, warm=warm_all)


def cmd_bifurcation(args: argparse.Namespace) -> int:
    from explorer_core.analyses.bifurcation import bifurcation_diagram
    from explorer_core.analyses.sweeps import sweep_values

    params, scene = _params(args)
    if not args.out and not args.json:
        raise UsageError("give --out FILE.csv and/or --json")
    if args.out:
        _check_out(args.out)
    lo, hi = _floats(args.range, 2, "--range")
    values = sweep_values((lo, hi), args.n_values)
    ics = _ics_arg(args, scene)
    if ics is None:
        ics = np.array(scene.points[:1]) if scene is not None and scene.points else np.array([[0.1, 0.1]])
    sweeps = tuple(s.strip() for s in args.sweeps.split(",")) if args.sweeps else ("forward", "backward")
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        diag = bifurcation_diagram(
            params,
            args.param,
            values,
            points=args.points,
            transient=args.transient,
            seeding=args.seeding,
            ics=ics,
            sweeps=sweeps,
            numerics=_numerics(args, None, args.transient + args.points),
            progress=lambda p: write(f"{p.done}/{p.total} values, {p.elapsed_s:.1f} s"),
            cancel=stop,
            executor=_executor(args),
        )
    if show:
        sys.stderr.write("\n")
    summary = diag.summary()
    if args.scheduler:
        summary["scheduler"] = args.scheduler
    if args.out:
        summary["csv"] = {"path": args.out, "rows": diag.to_csv(args.out)}
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        print(f"{diag.values.size} values x {diag.sweeps.size} sweeps, status {summary['status']}, "
              f"{diag.elapsed_s:.2f} s")  # fmt: skip
    if not diag.completed:
        sys.stderr.write("bilimovich: interrupted; the values computed so far were written\n")
        return 130
    return 0


def cmd_chart(args: argparse.Namespace) -> int:
    from explorer_core.analyses.regimes import DEFAULT_CHART_TOL, chart_spec, regime_chart

    params, scene = _params(args)
    outs = args.out or []
    for path in outs:
        _check_out(path)
        if not path.lower().endswith((".npz", ".csv", ".png")):
            raise UsageError(f"--out must end in .npz, .csv or .png, got {path!r}")
    if not outs and not args.json:
        raise UsageError("give --out FILE(.npz/.csv/.png) (repeatable) and/or --json")
    grid = [int(v) for v in _floats(args.grid, 2, "--grid")]
    ics = _ics_arg(args, scene)
    if ics is None:
        ics = np.array(scene.points[:1]) if scene is not None and scene.points else np.array([[0.1, 0.1]])
    if args.rtol is None and args.atol is None:
        args.rtol = DEFAULT_CHART_TOL  # a chart needs the regime, not 1e-10 accuracy
    spec = chart_spec(
        params,
        args.x_param,
        _floats(args.x_range, 2, "--x-range"),
        args.y_param,
        _floats(args.y_range, 2, "--y-range"),
        grid,
        ics=ics,
        transient=args.transient,
        periods=args.periods,
        p_max=args.p_max,
        tol=args.tol,
        lyap_threshold=args.lyap_threshold,
        numerics=_numerics(args, None, args.transient + args.periods),
    )
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        chart = regime_chart(
            spec,
            coarse=args.coarse,
            progress=lambda u: write(
                f"{int(u.chart.computed.sum())}/{u.chart.computed.size} pixels, {u.chart.elapsed_s:.1f} s"
            ),
            cancel=stop,
            executor=_executor(args),
            refine=args.refine,
        )
    if show:
        sys.stderr.write("\n")
    summary = chart.summary()
    if args.scheduler:
        summary["scheduler"] = args.scheduler
    written = []
    for path in outs:
        low = path.lower()
        if low.endswith(".npz"):
            chart.to_npz(path)
        elif low.endswith(".csv"):
            chart.to_csv(path)
        else:
            from explorer_core.reports.render import render_chart  # matplotlib only when a picture is asked for

            render_chart(chart, path)
        written.append(path)
    summary["out"] = written
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        print(f"{summary['computed']}/{summary['pixels']} pixels, {summary['counts']}, {chart.elapsed_s:.1f} s")
    if not chart.completed:
        sys.stderr.write("bilimovich: interrupted; the pixels computed so far were written\n")
        return 130
    return 0


def cmd_basins(args: argparse.Namespace) -> int:
    from explorer_core.analyses.basins import basin_spec, iter_basins

    params, scene = _params(args)
    if args.box:
        box = check_box(_floats(args.box, 4, "--box"))
    elif scene is not None:
        box = scene.box
    else:
        raise UsageError("give --box Q0,Q1,R0,R1 (no --scene to take it from)")
    grid = _floats(args.grid, 2, "--grid")
    if not all(v == int(v) for v in grid):
        raise UsageError(f"--grid must be two whole numbers NX,NY, got {args.grid!r}")
    if args.out:
        _check_out(args.out)
        if not args.out.lower().endswith(".npz"):
            raise UsageError(f"--out must end in .npz, got {args.out!r}")
    opts: dict[str, Any] = {"max_periods": args.max_periods}
    if args.cell_box:
        opts["cell_box"] = check_box(_floats(args.cell_box, 4, "--cell-box"), "--cell-box")
    if args.cells:
        opts["cells"] = [int(v) for v in _floats(args.cells, 2, "--cells")]
    nx, ny = (int(v) for v in grid)
    base = basin_spec(params, box, (nx, ny), **opts)
    spec = basin_spec(params, box, (nx, ny), numerics=_numerics(args, None, 1, base=base.numerics), **opts)
    write, show = _progress_line(args.quiet)
    result = None
    with _Interrupt() as stop:
        for upd in iter_basins(spec, cancel=stop):
            result = upd.basins
            write(f"every {upd.stride}th pixel: {upd.done_pixels}/{upd.total_pixels} pixels, "
                  f"{len(result.attractors)} attractors, {result.elapsed_s:.1f} s")  # fmt: skip
    if show:
        sys.stderr.write("\n")
    if result is None:
        sys.stderr.write("bilimovich: interrupted before any pixel was computed\n")
        return 130
    summary = result.summary()
    if args.scene:
        summary["scene"] = args.scene
    if args.out:
        result.to_npz(args.out)
        summary["out"] = args.out
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        for a in result.attractors:
            per = f" period {a.period}" if a.period else ""
            at = f" at ({a.points[0, 0]:.6g}, {a.points[0, 1]:.6g})" if a.points.shape[0] else ""
            print(f"attractor {a.id}: {a.kind}{per}{at}, basin {100 * a.fraction:.2f}%")
        print(f"{summary['computed']}/{summary['pixels']} pixels, {summary['statuses']}, {result.elapsed_s:.2f} s")
        if "note" in summary:
            print(summary["note"])
    if not result.completed:
        sys.stderr.write("bilimovich: interrupted; the pixels computed so far were written\n")
        return 130
    return 0


def cmd_fit(args: argparse.Namespace) -> int:
    from explorer_core.analyses.drift import drift_fit

    params, scene = _params(args)
    k0, k1 = (int(v) for v in _floats(args.window, 2, "--window"))
    dq, dr = (int(v) for v in _floats(args.degree, 2, "--degree"))
    ics = _ics_arg(args, scene)
    box = check_box(_floats(args.box, 4, "--box")) if args.box else (scene.box if scene else None)
    if ics is None and box is None:
        raise UsageError("give --ic Q,R (repeatable) or --box QMIN,QMAX,RMIN,RMAX for random members")
    if args.out:
        _check_out(args.out)
    write, show = _progress_line(args.quiet)
    with _Interrupt() as stop:
        fit = drift_fit(
            params,
            (k0, k1),
            degree=(dq, dr),
            m=args.members,
            ics=ics,
            box=box,
            seed=args.seed,
            criterion=args.criterion,
            numerics=_numerics(args, None, k1),
            progress=lambda found, draws: write(f"{found}/{args.members} members on the drift, {draws} tried"),
            cancel=stop,
        )
    if show:
        sys.stderr.write("\n")
    summary = fit.summary()
    if args.out:
        with open(args.out, "w") as fh:
            fh.write("member,k,q,r\n")
            for i, x in enumerate(fit.series):
                for k in range(x.shape[0]):
                    fh.write(f"{i},{k},{x[k, 0]!r},{x[k, 1]!r}\n")
        summary["csv"] = args.out
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        print(f"{summary['members']} members (rejected {summary['rejected']}, failed {summary['failed']})")
        print(f"q(k) = {summary['q']['formula']}")
        print(f"r(k) = {summary['r']['formula']}")
        print(f"residual RMS q {summary['residual_rms']['q']:.4g}, r {summary['residual_rms']['r']:.4g}")
    return 0


def cmd_symmetry(args: argparse.Namespace) -> int:
    from explorer_core.analyses.symmetry import check_symmetry

    params, scene = _params(args)
    ics = _ics_arg(args, scene)
    if ics is None:
        box = check_box(_floats(args.box, 4, "--box")) if args.box else (-1.0, 1.0, -1.0, 1.0)
        ics = random_ics(args.random, box, seed=args.seed)
    numerics = _numerics(args, None, args.periods) if (args.rtol or args.method) else None
    check = check_symmetry(params, ics, args.periods, centre=args.centre, tol=args.tol, numerics=numerics)
    summary = check.summary()
    if args.json:
        _write_json(summary)
    else:
        verdict = "holds" if check.holds else "is broken"
        print(f"involution t -> {2 * check.centre:g} - t, r -> -r {verdict}: max distance {check.max_distance:.3g}")
        for reason in summary["broken_by"]:
            print(f"  broken by: {reason}")
    return 0


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
    try:
        procs = config.resolve_procs(args.procs)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    spec = {"port": args.port, "address": args.address, "threads": args.threads, "origins": origins,
            "session_lifetime": args.session_lifetime, "procs": procs, "show": bool(args.show)}  # fmt: skip
    sys.stderr.write(f"Bilimovich Explorer on http://{args.address}:{args.port}/main ({procs} process(es))\n")
    sys.stderr.flush()
    os.execv(sys.executable, [sys.executable, "-m", "app.serve", "--launch", json.dumps(spec)])
    return 0  # not reached


def _out_dir(args: argparse.Namespace) -> str:
    """``--out`` as an absolute folder, created (its parent must exist: a typo fails at once)."""
    out = os.path.abspath(args.out)
    parent = os.path.dirname(out)
    if not os.path.isdir(parent):
        raise UsageError(f"--out parent directory does not exist: {parent}")
    os.makedirs(out, exist_ok=True)
    return out


def _report(args: argparse.Namespace, summary: dict[str, Any], lines: list[str], completed: bool, what: str) -> int:
    """End of a long batch command: JSON or ``lines`` on stdout; exit 130 if interrupted (``what`` was written)."""
    if args.json:
        _write_json(summary)
    elif not args.quiet:
        print("\n".join(lines))
    if not completed:
        sys.stderr.write(f"bilimovich: interrupted; what was {what} was written\n")
        return 130
    return 0


def _staged_run(args: argparse.Namespace) -> tuple[str, str, tuple[str, ...] | None, Callable[[str, float], None]]:
    """Output folder (created), size, stages and a progress printer of ``reproduce`` / ``failures``."""
    out = _out_dir(args)
    size = args.size or ("quick" if args.quick else "full")
    stages = tuple(s.strip() for s in args.stages.split(",")) if args.stages else None

    def progress(stage: str, elapsed: float) -> None:
        if not args.quiet:
            sys.stderr.write(f"{stage}: {elapsed:.1f} s\n")
            sys.stderr.flush()

    return out, size, stages, progress


def cmd_reproduce(args: argparse.Namespace) -> int:
    from explorer_core.studies.reproduce import reproduce

    out, size, stages, progress = _staged_run(args)
    start = time.perf_counter()

    with _Interrupt() as stop:
        rep = reproduce(size, stages=stages, progress=progress, cancel=stop)
    from explorer_core.reports.render import render_reproduction  # matplotlib only here

    figures = render_reproduction(rep, out)
    rep.write_table(os.path.join(out, "table.md"), os.path.join(out, "table.csv"))
    summary = rep.summary()
    summary["figures"] = figures
    summary["table"] = [os.path.join(out, "table.md"), os.path.join(out, "table.csv")]
    summary["elapsed_s"] = round(time.perf_counter() - start, 2)
    with open(os.path.join(out, "reproduce.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    lines = [
        rep.table_markdown(),
        f"{len(figures)} figures and the table in {out} ({summary['elapsed_s']:.0f} s, size {size})",
    ]
    return _report(args, summary, lines, rep.completed, "computed")


def cmd_bench(args: argparse.Namespace) -> int:
    import dataclasses

    from explorer_core.studies import bench

    cfg = bench.quick_config() if args.quick else bench.full_config()
    changes: dict[str, Any] = {}
    if args.cases:
        changes["cases"] = tuple(c.strip() for c in args.cases.split(",") if c.strip())
    if args.repeat is not None:
        changes["repeat"] = args.repeat
    if args.no_peers:
        changes["peers"] = ()
    if args.no_throughput:
        changes["throughput"] = False
    cfg = dataclasses.replace(cfg, **changes)
    cfg.validate()
    out = _out_dir(args)

    def progress(p: Any) -> None:
        if not args.quiet:
            sys.stderr.write(f"[{p.done}/{p.total} {p.elapsed_s:5.0f} s] {p.text}\n")
            sys.stderr.flush()

    with _Interrupt() as stop:
        res = bench.run_bench(cfg, cache_dir_=args.cache_dir, progress=progress, cancel=stop)
    data = res.as_dict()
    files = res.write(out)
    from explorer_core.reports.render import render_work_precision  # matplotlib only here

    png = os.path.join(out, "work_precision.png")
    render_work_precision(data, png)
    files.append(png)
    bench.save_latest(data, args.cache_dir)  # the app's speed-vs-accuracy tab shows the latest run
    summary = {"out": files, "completed": res.completed, "elapsed_s": round(res.elapsed_s, 1),
               "horizons": {k: c.horizon for k, c in res.cases.items()}, "peers": res.peers,
               "ratios": data["ratios"], "throughput": data["throughput"]}  # fmt: skip
    lines = [res.headline(), f"{len(res.rows)} rows; {', '.join(os.path.basename(f) for f in files)} in {out}"]
    return _report(args, summary, lines, res.completed, "measured")


def cmd_failures(args: argparse.Namespace) -> int:
    from explorer_core.studies.failures import failure_map

    out, size, stages, progress = _staged_run(args)
    start = time.perf_counter()

    with _Interrupt() as stop:
        fm = failure_map(size, stages=stages, progress=progress, cancel=stop)
    from explorer_core.reports.failure_render import render_failures  # matplotlib only here

    figures = render_failures(fm, out)
    summary = fm.summary()
    summary["figures"] = figures
    summary["elapsed_s"] = round(time.perf_counter() - start, 2)
    with open(os.path.join(out, "failures.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    lines = [f"failures.json and {len(figures)} pictures in {out} ({summary['elapsed_s']:.0f} s, size {size})"]
    return _report(args, summary, lines, fm.completed, "measured")


def cmd_warmup(args: argparse.Namespace) -> int:
    from explorer_core.warm import warm_all as warmup

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

    p = sub.add_parser("density", help="a long section (up to 10^7 points) as a density image of a window")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--random", type=_count("random", 1, config.MAX_TRAJECTORIES), default=1000, metavar="N",
                   help="random initial conditions in --box (default 1000)")  # fmt: skip
    p.add_argument("--seed", type=_count("seed", 0, 2**63 - 1), default=0)
    p.add_argument("--box", metavar="Q0,Q1,R0,R1", help="box of the initial conditions (default: the scene's)")
    p.add_argument("--periods", type=_count("periods", 1, config.MAX_PERIODS), help="section points per trajectory")
    p.add_argument("--transient", type=_count("transient", 0, config.MAX_PERIODS), help="periods dropped first")
    p.add_argument("--view", metavar="Q0,Q1,R0,R1", help="the image's window (default: the scene's)")
    p.add_argument("--pixels", metavar="W,H", help="the image's size (default 800,600; at most 4096 each)")
    p.add_argument("--out", metavar="FILE.npz", help="counts (H x W, row 0 at R0), q_edges, r_edges, summary")
    p.add_argument("--json", action="store_true", help="print a JSON summary to stdout")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_density)

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

    p = sub.add_parser("lyapunov", help="Lyapunov exponents, Kaplan-Yorke dimension, divergence check")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--ic", action="append", metavar="Q,R", help="initial condition (repeatable: one member each)")
    p.add_argument("--transient", type=_count("transient", 0, config.MAX_PERIODS), help="periods dropped first")
    p.add_argument("--periods", type=_count("periods", 1, config.MAX_PERIODS), default=2000, help="measured periods")
    p.add_argument("--ensemble", type=_count("ensemble", 1, 10_000), default=1, metavar="M", help="members")
    p.add_argument("--offset", type=_number("offset"), default=1e-6, help="relative offset of ensemble members")
    p.add_argument("--seed", type=_count("seed", 0, 2**63 - 1), default=0)
    p.add_argument("--history", metavar="FILE.csv", help="running estimates per period (member,k,L1,L2,...)")
    p.add_argument("--json", action="store_true", help="print the JSON summary")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_lyapunov)

    p = sub.add_parser("bifurcation", help="orbit diagram of the Poincare map over one parameter")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--param", required=True, help="alpha, I11..I23, g0, g1, g2 or omega")
    p.add_argument("--range", required=True, metavar="A,B", help="parameter range")
    p.add_argument("--n-values", type=_count("n-values", 1, 65536), default=200, metavar="N")
    p.add_argument("--points", type=_count("points", 1, 1_000_000), default=200, help="section points per value")
    p.add_argument("--transient", type=_count("transient", 0, config.MAX_PERIODS), default=500)
    p.add_argument("--seeding", choices=["continuation", "fixed"], default="continuation")
    p.add_argument("--sweeps", metavar="forward,backward", help="continuation sweeps (default both)")
    p.add_argument("--ic", action="append", metavar="Q,R", help="initial condition (repeatable)")
    p.add_argument("--out", metavar="FILE.csv", help="CSV sweep,value_index,value,ic,k,q,r,status")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask cluster: tcp://HOST:PORT or local:N (docs/dask.md)")
    p.add_argument("--json", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_bifurcation)

    p = sub.add_parser("orbits", help="periodic orbits of the Poincare map: Newton on P^n(x) - x, multipliers, type")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--period", type=_count("period", 1, 1_000_000), help="this period only")
    p.add_argument("--max-period", type=_count("max-period", 1, 1_000_000), help="periods 1..N (default 1)")
    p.add_argument("--seed", action="append", metavar="Q,R", help="a starting point (repeatable)")
    p.add_argument("--box", help="Q0,Q1,R0,R1: the grid of seeds (default: the scene's box)")
    p.add_argument("--seeds", metavar="NX,NY", help="a grid of NX x NY seeds over --box (default 10,10 without --seed)")
    p.add_argument("--returns", type=_count("returns", 1, 10_000), metavar="N",
                   help="also seed from near-returns of a section of N random trajectories in the box")  # fmt: skip
    p.add_argument("--in-box", action="store_true", help="keep only orbits whose points are all in the box")
    p.add_argument("--thorough", action="store_true", help="no early stop of slow seeds (slower, finds more)")
    p.add_argument("--out", metavar="FILE.csv", help="orbit,period,type,stable,j,q,r,mu1_re,mu1_im,mu2_re,mu2_im")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_orbits)

    p = sub.add_parser("manifolds", help="stable and unstable manifolds of a saddle orbit, homoclinic points")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--orbit", required=True, metavar="Q,R", help="a point near the saddle orbit (Newton finds it)")
    p.add_argument("--period", type=_count("period", 1, 64), default=1, help="the orbit's period (default 1)")
    p.add_argument("--length", type=_number("length"), default=10.0, help="arc length of each branch (default 10)")
    p.add_argument("--kinds", metavar="K[,K]", help="unstable, stable or both (default both)")
    p.add_argument(
        "--view",
        metavar="Q0,Q1,R0,R1",
        help="the plot window the curves are refined for (default: the scene's, else around the orbit)",
    )
    p.add_argument("--pixels", metavar="W,H", help="the window's size in pixels (default 800,600)")
    p.add_argument("--delta-px", type=_number("delta-px"), default=3.0, help="longest segment in pixels (default 3)")
    p.add_argument("--max-points", type=_count("max-points", 100, 10_000_000), default=200_000,
                   help="points computed over all branches (default 200000)")  # fmt: skip
    p.add_argument("--out", metavar="FILE.csv", help="CSV branch,kind,s,q,r (s: arc length from the saddle)")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_manifolds)

    p = sub.add_parser("continue", help="follow a periodic orbit in a parameter through folds and period doublings")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--param", required=True, help="alpha, I11..I23, g0, g1, g2 or omega")
    p.add_argument("--range", required=True, metavar="A,B", help="from A (where the orbit is seeded) to B")
    p.add_argument("--from", dest="from_", metavar="Q,R", help="a point near the period-N orbit at A")
    p.add_argument("--period", type=_count("period", 1, 1024), default=1)
    p.add_argument("--switch", action="store_true", help="at each period doubling, follow the doubled orbit too")
    p.add_argument("--max-period", type=_count("max-period", 1, 1024), default=16, help="cap of a cascade")
    p.add_argument("--max-points", type=_count("max-points", 2, 1_000_000), default=5000, help="per branch")
    p.add_argument("--param2", help="also follow each fold / period doubling in (PARAM, PARAM2)")
    p.add_argument("--range2", metavar="C,D", help="the range of PARAM2")
    p.add_argument("--out", metavar="FILE.csv", help="branch,period,value,q,r,mu1_re,mu1_im,mu2_re,mu2_im,stable")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_continue)

    p = sub.add_parser("chart", help="chart of dynamical regimes on a plane of two parameters")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--x-param", required=True, help="alpha, I11..I23, g0, g1, g2 or omega")
    p.add_argument("--x-range", required=True, metavar="A,B")
    p.add_argument("--y-param", required=True)
    p.add_argument("--y-range", required=True, metavar="C,D")
    p.add_argument("--grid", default="40,40", metavar="NX,NY", help="pixels (default 40,40)")
    p.add_argument("--ic", action="append", metavar="Q,R", help="initial condition per pixel (repeatable)")
    p.add_argument("--transient", type=_count("transient", 0, config.MAX_PERIODS), default=500)
    p.add_argument("--periods", type=_count("periods", 4, 1_000_000), default=500, help="measured periods")
    p.add_argument("--p-max", type=_count("p-max", 1, 1000), default=16, help="longest cycle detected")
    p.add_argument("--tol", type=_number("tol"), default=1e-5, help="return tolerance (relative to 1 + |x|)")
    p.add_argument("--lyap-threshold", type=_number("lyap-threshold"), default=5e-3, help="chaos above (per time)")
    p.add_argument("--coarse", type=_count("coarse", 1, 1024), default=8, help="stride of the first coarse pass")
    p.add_argument("--refine", action="store_true", help="finer levels only where neighbours differ (README)")
    p.add_argument("--out", action="append", metavar="FILE", help=".npz, .csv or .png (repeatable)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask cluster: tcp://HOST:PORT or local:N (docs/dask.md)")
    p.add_argument("--json", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_chart)

    p = sub.add_parser("basins", help="basins of attraction: which attractor each IC of a grid reaches")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--box", metavar="Q0,Q1,R0,R1", help="the initial conditions' window (default: the scene's box)")
    p.add_argument("--grid", default="100,100", metavar="NX,NY", help="pixels (default 100,100)")
    p.add_argument("--max-periods", type=_count("max-periods", 1, config.MAX_PERIODS), default=3000,
                   help="a pixel with no fate after this many periods is undecided (label -3)")  # fmt: skip
    p.add_argument("--cell-box", metavar="Q0,Q1,R0,R1", help="box of the recurrence cells (default: --box widened "
                   "by its size on every side)")  # fmt: skip
    p.add_argument("--cells", metavar="NQ,NR", help="recurrence cells per axis (default 64 across --box)")
    p.add_argument("--out", metavar="FILE.npz", help="arrays q (NX), r (NY), label (NY x NX)")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=cmd_basins)

    p = sub.add_parser("fit", help="polynomial fits of the drift q_k, r_k over a window of k, and the implied map")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--window", required=True, metavar="K0,K1", help="inclusive k range (k = 0 is the IC)")
    p.add_argument("--degree", default="1,2", metavar="DQ,DR", help="degrees of the q and r polynomials")
    p.add_argument("--members", type=_count("members", 1, 10_000), default=10, help="drifting ICs to average")
    p.add_argument("--ic", action="append", metavar="Q,R", help="explicit ICs instead of random ones")
    p.add_argument("--box", metavar="QMIN,QMAX,RMIN,RMAX", help="box for random ICs (default: the scene's)")
    p.add_argument("--seed", type=_count("seed", 0, 2**63 - 1), default=0)
    p.add_argument("--criterion", choices=["on_curve", "leaves"], default="on_curve", help="which ICs count")
    p.add_argument("--out", metavar="FILE.csv", help="the members' series member,k,q,r")
    p.add_argument("--json", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser("symmetry", help="check the involution t -> -t, q -> q, r -> -r on sections")
    _add_system_args(p)
    _add_numerics_args(p)
    p.add_argument("--ic", action="append", metavar="Q,R", help="initial condition (repeatable)")
    p.add_argument("--random", type=_count("random", 1, 10_000), default=4, metavar="N", help="random ICs")
    p.add_argument("--box", metavar="QMIN,QMAX,RMIN,RMAX", help="box for random ICs (default +-1)")
    p.add_argument("--seed", type=_count("seed", 0, 2**63 - 1), default=0)
    p.add_argument("--periods", type=_count("periods", 1, 100_000), default=10, help="compared section points")
    p.add_argument("--centre", type=_number("centre"), help="centre s of t -> 2s - t (default t0)")
    p.add_argument("--tol", type=_number("tol"), default=1e-6, help="largest distance counted as symmetric")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_symmetry)

    p = sub.add_parser("serve", help="run the web explorer (panel serve app/main.py)")
    # Defaults come from the environment so a container (exec-form CMD) can be configured.
    env = os.environ
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
    p.add_argument("--show", action="store_true", help="open a browser")
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("reproduce", help="every figure of the paper as PNG and the table of its numbers")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created)")
    p.add_argument("--quick", action="store_true", help="reduced sizes: a few minutes on 2 cores")
    p.add_argument("--size", choices=["tiny", "quick", "full"], help="explicit size (overrides --quick)")
    p.add_argument("--stages", metavar="LIST", help="subset of sections,lyapunov,drift,bifurcation,chart")
    p.add_argument("--json", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("bench", help="work-precision benchmark: error vs time, ours against solve_ivp/numbalsoda")
    p.add_argument("--out", required=True, metavar="DIR", help="writes bench.json/.csv/.md, work_precision.png, ...")
    p.add_argument("--quick", action="store_true", help="a small run (under a minute): short horizons, few settings")
    p.add_argument("--cases", metavar="LIST", help="subset of regular,chaotic,attractor,drift")
    p.add_argument("--repeat", type=_count("repeat", 1, 100), help="timing repeats (median; default 3, quick 1)")
    p.add_argument("--no-peers", action="store_true", help="only this project's methods")
    p.add_argument("--no-throughput", action="store_true", help="skip the throughput and target measurements")
    p.add_argument("--cache-dir", metavar="DIR", help="reference cache (default $BILIMOVICH_CACHE_DIR/bench)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("failures", help="where the methods fail: RK4 on the drift, costs, statuses, float32, Lyapunov")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created): failures.json, PNGs")
    p.add_argument("--quick", action="store_true", help="reduced sizes: about 30 s on 2 cores")
    p.add_argument("--size", choices=["tiny", "quick", "full"], help="explicit size (overrides --quick)")
    p.add_argument("--stages", metavar="LIST", help="subset of rk4,cost,scenarios,floats,lyapunov")
    p.add_argument("--json", action="store_true", help="print the JSON summary")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_failures)

    p = sub.add_parser("worker", help="the warm worker that answers small commands at once: status or stop")
    p.add_argument("action", choices=["status", "stop"])
    p.set_defaults(func=cmd_worker)

    p = sub.add_parser("warmup", help="compile the numba kernels into the on-disk cache")
    p.set_defaults(func=cmd_warmup)
    return parser


#: Options whose value is a comma list that may start with a minus sign.
_LIST_OPTIONS = {"--ic", "--box", "--inertia", "--q-range", "--r-range", "--orbit", "--view", "--pixels"}
# Options of the analyses (bifurcation, chart, fit) whose values may start with a minus sign.
_LIST_OPTIONS |= {"--range", "--x-range", "--y-range", "--window", "--ic-box"}
_LIST_OPTIONS |= {"--cell-box"}  # basins


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
    # ParameterError is a ValueError; SchedulerError (an unusable Dask cluster) a ConnectionError.
    except (UsageError, ValueError, ConnectionError) as exc:
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


def cmd_worker(args: argparse.Namespace) -> int:
    from explorer_core import worker

    if args.action == "stop":
        stopped = worker.stop_all()
        print(f"stopped {len(stopped)} worker(s)" + "".join(f"\n  {p}" for p in stopped))
    else:
        path = worker.socket_path()
        up = path.exists()
        state = "on" if worker.enabled() else "off (BILIMOVICH_WORKER=0)"
        print(
            f"worker: {state}; for this code and environment: {'listening at ' + str(path) if up else 'none running'}"
        )
    return 0


#: The hidden first argument of the worker process (``python -m explorer_core.cli _worker PATH``).
_WORKER = "_worker"


def entry() -> None:
    """The ``bilimovich`` console script: a free warm worker runs the command if there is one (see
    :mod:`explorer_core.worker`), else this process does, and leaves a worker for the next command."""
    from explorer_core import worker

    argv = sys.argv[1:]
    if argv[:1] == [_WORKER] and len(argv) == 2:
        worker.serve(argv[1], main)
        return
    cmd = worker.command_of(argv)
    use = worker.enabled() and cmd is not None and cmd not in worker.LOCAL and not {"-h", "--help"} & set(argv)
    if use:
        status = worker.run_in_worker(argv)
        if status is not None:
            sys.exit(status)
    status = main(argv)
    if use and "numba" in sys.modules:  # this run paid for the kernels: the next one need not
        with contextlib.suppress(OSError):
            worker.spawn([sys.executable, "-m", "explorer_core.cli", _WORKER])
    sys.exit(status)


if __name__ == "__main__":
    entry()
