"""Periodic orbits of the map P (fixed points of P^n): Newton from clicked seeds and a grid over the view."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
import param

from app.controls import MAX_MAGNITUDE, SYSTEM_FIELDS, Control, UrlKey, choice, ints, places, points_text
from app.layers.base import KEEP, Action, Layer, Table, loss_lines
from app.runner import LAYER, POINTS
from app.words import counted
from explorer_core.analyses.orbits import (
    ORBIT_NUMERICS,
    Orbit,
    OrbitSearch,
    OrbitSpec,
    eigenvector,
    find_orbits,
    grid_seeds,
    ladder_seeds,
    orbit_search,
    orbit_spec,
    same_orbit,
    settled_seeds,
)
from explorer_core.losses import Loss
from explorer_core.solve.numerics import Numerics
from explorer_core.system.params import Params

#: Points clicked to find periodic orbits from (each a Newton search), per session.
MAX_ORBIT_SEEDS = 60
#: Longest period the orbit search tries (P^n of a chaotic region: Newton's basin shrinks like e^(-lambda n T)).
MAX_ORBIT_PERIOD = 16

#: Seeds of the "every orbit in view" search: a grid over the plot window.
ORBIT_GRID = (10, 10)
#: Orbits listed in the table (all of them are drawn and in the CSV).
ORBIT_ROWS = 40
#: While a parameter is played, an orbit of period n found with a real multiplier past -1 (a period doubling
#: happened since the last frame) is searched for the period-2n orbit born there, from seeds along the
#: multiplier's eigenvector at the distances of the continuation's branch switching (the core's one ladder,
#: :data:`~explorer_core.analyses.orbits.SWITCH_LADDER`): the born orbit's distance grows like the square root of
#: the parameter's distance from the doubling, which a frame's step does not tell.
#: While a parameter is played, a frame's trajectory whose last points repeat with period n (the core's rule
#: ``recurrence.PLAY``) has settled on a cycle; one no orbit on screen is within NEAR of (relative to 1 + |x|: an
#: orbit born at a fold since the last frame, a pair out of nothing, away from every followed orbit) is handed to
#: Newton for period n, at most MAX_SETTLED cycles a frame (the added work: one Newton search of one period each).
NEAR = 5e-2
MAX_SETTLED = 4
SETTLED_WORDS = "born since the last frame (a trajectory settled on it)"
#: A fold pair's partner: an orbit of period n whose largest multiplier is real and within FOLD_NEAR of +1, with no
#: orbit of period n near it (0.3, relative to 1 + |x|), is searched for its partner across the fold (the saddle of a
#: node found settled, or the node of a followed saddle) from seeds on both sides along that multiplier's eigenvector
#: (the same ladder): the pair's distance grows like the square root of the parameter's distance from the fold.
FOLD_NEAR = 0.25
#: Follow jobs whose work the layer keeps a record of (OrbitsLayer.work).
WORK_KEPT = 200
#: The orbit search's button: an action, then a mode that stays on (redone after every pan or zoom).
FIND_OFF = ("Find orbits in view", "Newton on P^n(x) - x from a grid of starting points over the plot window")
FIND_ON = ("Orbits in view: on", "A mode: the search is redone after every pan or zoom; 'Clear orbits' ends it")
CSV_HEADER = ("orbit", "period", "type", "stable", "j", "q", "r", "mu1_re", "mu1_im", "mu2_re", "mu2_im", "det",
              "liouville", "residual")  # fmt: skip


@dataclass(frozen=True)
class OrbitInputs:
    params: Params
    seeds: tuple[tuple[float, float], ...]
    periods: tuple[int, ...]
    #: "" for the whole search (it replaces the orbits shown); a click's words for one seed (merged).
    where: str = ""
    query: dict[str, str] = field(default_factory=dict, compare=False)
    #: While a parameter is played (app/play.py): the last frame's orbits, (q, r, period) each, continued to
    #: this frame by Newton from where they were, each for its own period (not the grid over the view).
    follow: tuple[tuple[float, float, int], ...] = ()
    #: The map Newton iterates: the page's Method and Accuracy by the core's rule, at the orbits' own tolerance
    #: under "plot" (an orbit's residual is no picture; :func:`~explorer_core.solve.numerics.chosen_numerics`).
    numerics: Numerics = field(default_factory=lambda: ORBIT_NUMERICS)


def birth_seeds(orbits: list[Orbit], max_period: int) -> dict[int, list[tuple[float, float]]]:
    """Seeds, by period, of the orbits born at the period doublings of ``orbits``: for each orbit of period n with
    a real multiplier below -1 and no orbit of period 2n near it (2n up to ``max_period``), points along that
    multiplier's eigenvector (the continuation's ladder: ``ladder_seeds``). A seed Newton takes back to the orbit
    itself gives that orbit again (least period), drawn once."""
    out: dict[int, list[tuple[float, float]]] = {}
    for o in orbits:
        n2 = 2 * int(o.period)
        mu = o.multipliers[int(np.argmin(np.abs(o.multipliers + 1.0)))]
        if n2 > max_period or abs(mu.imag) > 1e-12 or mu.real >= -1.0:
            continue
        x = o.points[0]
        scale = 1.0 + float(np.abs(x).max())
        if any(p.period == n2 and np.linalg.norm(p.points - x, axis=1).min() < 0.3 * scale for p in orbits):
            continue  # its doubled orbit is followed already
        seeds = ladder_seeds(x, eigenvector(o.matrix, -1.0))  # the continuation's ladder (branch switching)
        out.setdefault(n2, []).extend((float(p[0]), float(p[1])) for p in seeds)
    return out


def partner_seeds(orbits: list[Orbit], max_period: int) -> dict[int, list[tuple[float, float]]]:
    """Seeds, by period, of the partners of the orbits near a fold (their largest multiplier real and within
    :data:`FOLD_NEAR` of +1, no other orbit of their period near): both sides along that multiplier's eigenvector,
    the same ladder away. A seed Newton takes back to the orbit itself gives that orbit again, drawn once."""
    out: dict[int, list[tuple[float, float]]] = {}
    for o in orbits:
        n = int(o.period)
        w, vecs = np.linalg.eig(o.matrix)
        i = int(np.argmax(np.abs(w)))  # the one that passes +1 at a fold: a node's weakest, a saddle's expanding one
        if n > max_period or abs(w[i].imag) > 1e-12 or abs(w[i].real - 1.0) > FOLD_NEAR:
            continue
        x = o.points[0]
        scale = 1.0 + float(np.abs(x).max())
        if any(p is not o and p.period == n and np.linalg.norm(p.points - x, axis=1).min() < 0.3 * scale
               for p in orbits):  # fmt: skip
            continue  # its partner is shown already
        v = np.real(vecs[:, i])
        seeds = ladder_seeds(x, v / np.linalg.norm(v), both=True)  # the same ladder, on both sides
        out.setdefault(n, []).extend((float(p[0]), float(p[1])) for p in seeds)
    return out


def settled_cycles(traj: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray,
                   max_period: int) -> list[tuple[float, float, int]]:  # fmt: skip
    """The cycles the section's trajectories end on, ``(q, r, n)`` each, those within :data:`NEAR` of each other
    one (:func:`~explorer_core.analyses.orbits.settled_seeds`)."""
    return settled_seeds(traj, k, q, r, max_period, NEAR)


def unfollowed(cycles: list[tuple[float, float, int]], orbits: list[Orbit]) -> list[tuple[float, float, int]]:
    """The cycles no orbit in ``orbits`` has a point within :data:`NEAR` (relative to 1 + |x|) of."""
    out = []
    for q, r, n in cycles:
        x = np.array([q, r])
        scale = NEAR * (1.0 + float(np.abs(x).max()))
        if not any(np.linalg.norm(o.points - x, axis=1).min() < scale for o in orbits):
            out.append((q, r, n))
    return out


class OrbitsLayer(Layer):
    name = "orbits"
    #: "orbit": one job per click, all kept, waited for like points; "orbits": the whole search.
    channels: ClassVar[dict[str, str]] = {"orbits": LAYER, "orbit": POINTS}
    fields = ("show_orbits", "orbit_period")
    depends = (*SYSTEM_FIELDS, "orbit_period")
    controls = (
        Control("show_orbits", "Periodic orbits of the map P (fixed points of P^n)", "check", "layers", "orbits",
                help="● stable, ○ unstable, ✕ saddle (hover: period and multipliers). Click in the plot with "
                "'finds a periodic orbit', or find every orbit in view.", default=True),
        ints("orbit_period", "Orbits: longest period searched", "layers", "orb_n", 1, MAX_ORBIT_PERIOD, 4),
    )  # fmt: skip
    picks: ClassVar[dict[str, param.Parameter]] = {
        "orbit_seeds": param.List(default=[], item_type=tuple, doc="points clicked to find periodic orbits from"),
        "orbit_view": param.Boolean(default=False, doc="also every orbit Newton finds from a grid over the view"),
    }
    urls = (
        UrlKey("orb", ("orbit_seeds",), lambda s: points_text(s.orbit_seeds),
               lambda t: {"orbit_seeds": places("orb", t, MAX_ORBIT_SEEDS, "orbit seeds", 2, "q,r")},
               lambda s: bool(s.orbit_seeds), "orbit seeds"),
        UrlKey("orb_all", ("orbit_view",), lambda s: "1",
               choice({"1": {"orbit_view": True}, "0": {"orbit_view": False}}), lambda s: s.orbit_view,
               "orbits in view"),
    )  # fmt: skip
    #: The orbits on screen as table rows (:func:`orbit_row`, the first :data:`ORBIT_ROWS`), what the last search said.
    publishes: ClassVar[dict[str, Any]] = {"orbits": [], "orbit_status": ""}
    actions = (
        Action("find_orbits", "find_in_view"),
        Action("clear_orbits", "clear_all"),
        Action("orbit", "find_at", "finds a periodic orbit", click=True),
    )
    download = "orbits"

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self.orbits: list[Orbit] = []
        #: What the orbits on screen lack: a search stopped before its end (the download says so).
        self.lost: list[Loss] = []
        self.rows: list[dict[str, Any]] = []
        self.text = ""
        self.ran_with = ""
        #: While a parameter plays: the last follow jobs' Newton work (searches, seeds by kind and period), in order
        #: (a bounded record: a session may play for hours).
        self.work: deque[dict[str, Any]] = deque(maxlen=WORK_KEPT)

    def inputs(self) -> OrbitInputs | object | None:
        st = self.host.state
        seeds = [tuple(s) for s in st.orbit_seeds]
        follow = tuple(getattr(self.host, "follow_orbits", ()) or ())
        # A played frame follows the last frame's orbits instead of the grid (its Newton work per frame); a still
        # (Pause, Step) follows the orbits shown and searches the grid too.
        frame = getattr(self.host, "frame_periods", None) is not None
        if st.orbit_view and not (follow and frame):
            seeds += [tuple(x) for x in grid_seeds((*st.q_range, *st.r_range), *ORBIT_GRID)]
        if not st.show_orbits or not (seeds or follow):
            return None
        params = self.system_params()
        if params is None:
            return KEEP
        return OrbitInputs(params, tuple(seeds), tuple(range(1, st.orbit_period + 1)), "", st.to_query(), follow,
                           self.numerics())  # fmt: skip

    def on_view(self) -> bool:
        return bool(self.host.state.orbit_view)

    def numerics(self) -> Numerics:
        """The map the orbits are found on, and the words that say so under the plot (:attr:`ran_with`)."""
        numerics, self.ran_with = self.host.state.numerics_for(ORBIT_NUMERICS)
        return numerics

    def prepare(self, inputs: OrbitInputs) -> OrbitInputs:
        if not inputs.where and inputs.follow:  # a played parameter's frame: the orbits shown, continued
            searching = f" and searching from {counted(len(inputs.seeds), 'point')}…" if inputs.seeds else "…"
            self.text = f"following {counted(len(inputs.follow), 'periodic orbit')} to this frame{searching}"
        elif not inputs.where:
            self.text = (f"finding periodic orbits (periods 1..{max(inputs.periods)}) from "
                         f"{counted(len(inputs.seeds), 'starting point')}…")  # fmt: skip
        return inputs

    @staticmethod
    def spec(inputs: OrbitInputs) -> OrbitSpec:
        """The search from the page's seeds as the core's builder makes it (the command line's ``orbits --seed
        Q,R ... --max-period N`` with the page's numerics)."""
        return orbit_spec(inputs.params, max_period=max(inputs.periods), seeds=list(inputs.seeds),
                          numerics=inputs.numerics)  # fmt: skip

    def job(self, inputs: OrbitInputs, cancelled: Callable[[], bool]) -> Iterator[OrbitSearch]:
        if not inputs.follow:
            if inputs.seeds:  # the command line's search (``orbits --seed Q,R ... --max-period N``)
                res = orbit_search(self.spec(inputs), cancel=cancelled)
            else:
                res = find_orbits(inputs.params, [], list(inputs.periods), numerics=inputs.numerics)
            if not cancelled(wait=False):  # type: ignore[call-arg]  # the runner's poll (app/runner.py)
                yield res
            return
        # Followed: each period's orbits from their last points (one Newton each), then the clicked seeds, then
        # the orbits born at a period doubling since the last frame, then the partners of orbits near a fold.
        parts = []
        for n in sorted({p for _, _, p in inputs.follow}):
            pts = [(q, r) for q, r, p in inputs.follow if p == n]
            parts.append(find_orbits(inputs.params, pts, [n], numerics=inputs.numerics, cancel=cancelled))
        if inputs.seeds:
            parts.append(
                find_orbits(
                    inputs.params, list(inputs.seeds), list(inputs.periods), numerics=inputs.numerics, cancel=cancelled
                )
            )
        # The orbits born at a doubling since the last frame (a grid would find them; following alone would not).
        have: list[Orbit] = []
        for o in (o for part in parts for o in part.orbits):
            if not any(same_orbit(o, k) for k in have):
                have.append(o)  # once each: an orbit found twice is not its own partner
        births = birth_seeds(have, max(inputs.periods))
        for n, seeds in sorted(births.items()):
            parts.append(find_orbits(inputs.params, seeds, [n], numerics=inputs.numerics, cancel=cancelled))
        # The partners of orbits near a fold (the saddle of a node born there, found settled).
        partners = partner_seeds(have, max(inputs.periods))
        for n, seeds in sorted(partners.items()):
            parts.append(find_orbits(inputs.params, seeds, [n], numerics=inputs.numerics, cancel=cancelled))
        if cancelled():
            return
        found: list[Orbit] = []
        for o in (o for part in parts for o in part.orbits):
            if not any(same_orbit(o, k) for k in found):
                found.append(o)
        periods = sorted({p for part in parts for p in part.extra.get("periods", [])})
        yield replace(
            parts[0],
            orbits=found,
            failures=[f for part in parts for f in part.failures],
            seeds=sum(part.seeds for part in parts),
            elapsed_s=sum(part.elapsed_s for part in parts),
            completed=all(part.completed for part in parts),
            # Each followed orbit was searched for its own period only: the Newton searches made, counted per part.
            # The work added to following (benchmarks/play_speed.py --orbit-work): seeds of each kind, by period.
            extra={**parts[0].extra, "periods": periods,
                   "searches": sum(part.seeds * len(part.extra.get("periods", [])) for part in parts),
                   "birth_seeds": {n: len(v) for n, v in births.items()},
                   "partner_seeds": {n: len(v) for n, v in partners.items()}},
        )  # fmt: skip

    def current(self, inputs: OrbitInputs) -> bool:
        return inputs.params == self.host.system()  # else found for a system no longer on screen

    def apply(self, inputs: OrbitInputs, res: OrbitSearch) -> None:
        if inputs.follow:
            self.work.append({"settled": inputs.where == SETTLED_WORDS, "followed": len(inputs.follow),
                              "searches": int(res.extra.get("searches", 0)),
                              "birth_seeds": res.extra.get("birth_seeds", {}),
                              "partner_seeds": res.extra.get("partner_seeds", {})})  # fmt: skip
        if not inputs.where:
            self.orbits, self.lost = [], []
        elif self.stale(self.shown_query, inputs.query, SYSTEM_FIELDS):
            self.orbits, self.lost = [], []  # those on screen are another system's (a Stop kept them): never mixed
        self.shown_query = inputs.query
        new = [o for o in res.orbits if not any(same_orbit(o, k) for k in self.orbits)]
        self.orbits = sorted([*self.orbits, *new], key=lambda o: (o.period, float(o.points[0, 0])))
        self._draw()
        if inputs.where == SETTLED_WORDS and not new:
            pass  # a trajectory lingering near a cycle not there (a fold's ghost): the frame's words stay
        elif inputs.where:
            if new:
                what = ", ".join(f"period {o.period} ({o.kind})" for o in new)
                self.text = f"{inputs.where}: {what}"
            elif res.orbits:
                self.text = f"{inputs.where}: an orbit already shown (period {res.orbits[0].period})"
            else:
                reason = res.failures[0].reason if res.failures else "nothing found"
                self.text = f"{inputs.where}: no orbit of period ≤ {max(res.extra.get('periods', [0]))} ({reason})"
        else:
            periods = list(res.extra.get("periods", [])) or [0]
            tries = res.extra.get("searches", res.seeds * len(periods))
            if inputs.follow:
                # Played: a frame; paused or stepped: a still (the orbits shown, followed to it).
                to = "this frame" if getattr(self.host, "frame_periods", None) is not None else "this still"
                self.text = (f"{counted(len(self.orbits), 'periodic orbit')} followed to {to} "
                             f"({counted(tries, 'Newton search')}, "
                             f"one per orbit followed at its own period; {len(res.failures)} found none; "
                             f"{res.elapsed_s:.2f} s)")  # fmt: skip
            else:
                self.text = (f"{counted(len(self.orbits), 'periodic orbit')} of period 1..{max(periods)} from "
                             f"{counted(res.seeds, 'starting point')} ({len(res.failures)} of the {tries} "
                             "Newton searches, one per starting point and period, found none; "
                             f"{res.elapsed_s:.2f} s)")  # fmt: skip

    def clear(self) -> None:
        self.orbits, self.lost = [], []
        self.shown_query = None
        self.text = ""
        self._draw()

    def _draw(self) -> None:
        rows = [orbit_row(o) for o in self.orbits]
        self.host.fig.set_orbits(rows)
        self.rows = rows[:ORBIT_ROWS]

    def status(self) -> str:
        return self.text

    def published(self) -> dict[str, Any]:
        # The numerics the orbits were found with are said with them (the page's Method and Accuracy, the rule).
        # First: the line is cut at the plot's width, and the counts at its end matter least.
        text = f"Newton on {self.ran_with} · {self.text}" if self.text and self.orbits and self.ran_with else self.text
        return {"orbits": self.rows, "orbit_status": text}

    def view(self) -> dict[str, Any]:
        on = bool(self.host.state.orbit_view)
        label, title = FIND_ON if on else FIND_OFF
        return {**self.published(), "n_orbits": len(self.rows), "orbit_view": on, "find_label": label,
                "find_title": title}  # fmt: skip

    def stopped(self, busy: bool, now: dict[str, str]) -> None:
        if not self.host.state.show_orbits or not (busy or self.orbits):
            return
        note = self.stale(self.shown_query, now, self.depends) if self.orbits else ""
        if note:
            self.text = f"stopped: the {counted(len(self.orbits), 'periodic orbit')} shown are for {note}"
        elif busy:
            self.text = f"stopped: {counted(len(self.orbits), 'periodic orbit')} shown (the search did not end)"
            self.lost = [Loss("orbit search", 1, "not computed: the search was stopped before its end (orbits it "
                              "would have found are not here)")]  # fmt: skip

    # --- what the user does -----------------------------------------------------------------

    def find_in_view(self) -> None:
        """Also search from a grid of seeds over the plot window (kept in the URL; redone on a new view)."""
        st = self.host.state
        if st.orbit_view and st.show_orbits:
            return
        with self.host.suspended():
            st.param.update(orbit_view=True, show_orbits=True)
        self.host.refresh(self)

    def clear_all(self) -> None:
        """The orbits, their seeds and the search in view, gone."""
        for channel in self.channels:
            self.host.runner.cancel(channel)
        self.host.state.param.update(orbit_seeds=[], orbit_view=False)
        self.host.clear(self)

    def find_at(self, q: float, r: float) -> bool:
        """Newton from a click, for every period up to the setting; drawn as soon as found. Returns whether
        the seeds changed (the URL)."""
        if not (np.isfinite(q) and np.isfinite(r)) or max(abs(q), abs(r)) > MAX_MAGNITUDE:
            return False
        st = self.host.state
        if len(st.orbit_seeds) >= MAX_ORBIT_SEEDS:
            self.text = f"at most {MAX_ORBIT_SEEDS} orbit seeds; clear the orbits first"
            self.host.publish(self)
            return False
        params = self.system_params()
        if params is None:
            return False
        seed = (float(q), float(r))
        st.orbit_seeds = [*st.orbit_seeds, seed]
        if not st.show_orbits:
            st.show_orbits = True  # recomputes every seed, this one included
            return False
        inputs = OrbitInputs(params, (seed,), tuple(range(1, st.orbit_period + 1)), f"from ({q:.4g}, {r:.4g})",
                             st.to_query(), numerics=self.numerics())  # fmt: skip
        # One job per click, all kept: a second click does not cancel the first.
        self.host.run(self, inputs, channel="orbit", bump=False)
        return True

    def find_settled(self) -> int:
        """While a parameter plays, once a frame's section and orbits are done: Newton from the frame's
        trajectories that settled on a cycle no orbit on screen is near (:func:`settled_cycles`; an orbit born
        at a fold since the last frame), each for its own period, the orbits found merged with those shown.
        Returns the Newton searches started (0: none needed; at most :data:`MAX_SETTLED`)."""
        st = self.host.state
        if not st.show_orbits:
            return 0
        params = self.system_params()
        if params is None:
            return 0
        traj, k, q, r = self.host.data()
        cycles = unfollowed(settled_cycles(traj, k, q, r, st.orbit_period), self.orbits)[:MAX_SETTLED]
        if not cycles:
            return 0
        inputs = OrbitInputs(params, (), tuple(range(1, st.orbit_period + 1)), SETTLED_WORDS, st.to_query(),
                             tuple(cycles), self.numerics())  # fmt: skip
        self.host.run(self, inputs, channel="orbit", bump=False)
        return len(cycles)

    def table(self) -> Table | None:
        """The orbits on screen (one row per orbit point), under the settings they were found with."""
        if not self.rows:
            return None

        def rows() -> Iterator[tuple[Any, ...]]:
            for i, o in enumerate(self.orbits):
                m = o.multipliers
                for j, (q, r) in enumerate(o.points):
                    yield (i, int(o.period), o.kind, int(o.stable), j, q, r, m[0].real, m[0].imag, m[1].real,
                           m[1].imag, o.det, o.liouville, o.residual)  # fmt: skip

        return Table("periodic orbits", self.shown_query or self.host.state.to_query(), CSV_HEADER, rows(),
                     partial=loss_lines(self.lost, bool(self.lost)))  # fmt: skip


def _mu_text(mu: np.ndarray) -> str:
    parts = []
    for m in mu:
        parts.append(f"{m.real:.5g}{m.imag:+.5g}i" if abs(m.imag) > 1e-12 else f"{m.real:.6g}")
    return ", ".join(parts) + f"  (|μ| {abs(mu[0]):.4g}, {abs(mu[1]):.4g})"


def orbit_row(o: Orbit) -> dict[str, Any]:
    """An orbit as plain data for the page (table) and the figure (markers, hover)."""
    return {
        "period": int(o.period),
        "type": o.kind,
        "stable": bool(o.stable),
        "q": float(o.points[0, 0]),
        "r": float(o.points[0, 1]),
        "points": [[float(a), float(b)] for a, b in o.points],
        "mu": _mu_text(o.multipliers),
        "det": float(o.det),
    }
