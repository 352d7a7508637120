"""Play a parameter: a slider's value swept across a range, one section per frame, driven by the server.

A frame is the section (and the layers on) for one value of the played parameter, with only as many periods per
trajectory as a moving picture needs (:data:`FRAME_PERIODS`, not a still's); the periodic orbits on screen are
continued from frame to frame (the orbits layer's Newton starts from the last frame's orbits, an orbit that
has passed a period doubling is searched for the orbit born there, and a trajectory of the frame that settled on a
cycle no orbit on screen is near, an orbit born at a fold, is handed to Newton once the frame's jobs are done).
The next frame is asked for only once the last one is drawn: every job of the section view is over and, in a
browser, the page has said it shows the frame (:meth:`Player.shown`). So frames never pile up: a slow machine or
browser sees fewer frames, not a lag; the speed asked is a most (frames are not sent faster than ``play_fps``).
Nothing here runs in the browser's timers: :class:`Player` is told when a frame is drawn and schedules the next
one with ``schedule`` (the document's timeout callback in a server, a fake clock in tests).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from app.controller import ExplorerSession
from app.state import SLIDER_RANGES, commit, plain_label
from explorer_core.system.params import ParameterError

#: Periods per trajectory of a frame: 60 trajectories x 100 points show an attractor's shape at a glance; a
#: still (Pause) is computed again with the state's periods.
FRAME_PERIODS = 100
#: Without a word from the browser that a frame is shown, the next one goes after this long (a tab whose
#: messages were lost must not stop playing for ever).
ACK_TIMEOUT = 1.0
#: Frames whose settled searches a Player keeps a record of.
SETTLED_KEPT = 1000

Schedule = Callable[[float, Callable[[], None]], None]


class Player:
    """The played parameter of one session. ``schedule(delay_s, fn)`` runs ``fn`` on the document thread later."""

    def __init__(
        self,
        session: ExplorerSession,
        schedule: Schedule,
        *,
        clock: Callable[[], float] = time.perf_counter,
        on_change: Callable[[], None] | None = None,
        wait_for_browser: bool = False,
    ) -> None:
        self.session = session
        self.state = session.state
        self._schedule = schedule
        self._clock = clock
        self._on_change = on_change
        #: In a server, a frame counts as drawn once the page says it shows it (messages "shown").
        self.wait_for_browser = wait_for_browser
        self.playing = False
        self.frame = -1  # index of the frame on screen in values(), -1: none yet
        self._sign = 1  # bounce: +1 up the range, -1 down
        self._gen = 0  # a Pause or a new Play makes the timers of the old one void
        self._waiting = False  # a frame is asked for and not drawn yet
        self._computed = False  # its jobs are over
        self._acked = -1  # the last frame number the page said it shows
        self._number = 0  # frames asked for, numbered (what the page acknowledges)
        self._settled = 0  # the last frame number whose settled trajectories were searched for new orbits
        #: A still (Pause, Step) following the orbits shown, whose settled trajectories are searched for new orbits
        #: once its jobs end, as a frame's are: it shows what its frame would.
        self._still = False
        #: Newton searches started for settled trajectories (orbits born at a fold), per frame of this Play (the
        #: last frames': a bounded record).
        self.settled_searches: deque[int] = deque(maxlen=SETTLED_KEPT)
        self.t_play = 0.0
        self.t_request = 0.0
        self.first_frame_s: float | None = None  # Play to the first frame drawn
        #: The picture on screen while a frame is computed: its frame index (-1: the still before Play) and value.
        self._on_screen: tuple[int, float] | None = None
        self.drawn: list[float] = []  # when each frame of this Play was drawn
        self.message = ""
        session.param.watch(lambda *e: self._check_done(), ["running"])

    # --- the range ---------------------------------------------------------------------------------

    def values(self) -> np.ndarray:
        """The played parameter's values, one per frame, from ``from`` to ``to`` (blank ends: the bifurcation
        diagram's range when it plays this parameter, else the value ∓ 5 % of the slider's span)."""
        st = self.state
        p = st.play_param
        v = float(getattr(st, p))
        if st.bif_param == p and st.bif_range:
            lo, hi = st.bif_range
        else:
            lo_s, hi_s, _ = SLIDER_RANGES[p]
            lo, hi = v - 0.05 * (hi_s - lo_s), v + 0.05 * (hi_s - lo_s)
        lo = st.play_from[0] if st.play_from else lo
        hi = st.play_to[0] if st.play_to else hi
        return np.linspace(lo, hi, st.play_frames)

    def check(self) -> str:
        """'' when every frame is a valid system, else why not (naming the bad end)."""
        vals = self.values()
        if not vals[0] != vals[-1]:
            return f"Play: from and to are the same value ({vals[0]:g}): nothing to play"
        for end in (vals[0], vals[-1]):  # the valid values of one parameter are an interval: its ends suffice
            try:
                self.state.system(**{self.state.play_param: float(end)})
            except ParameterError as exc:
                return f"Play: {self.state.play_param} = {end:g} at an end of the range is not a valid system: {exc}"
        return ""

    def _nearest(self) -> int:
        vals = self.values()
        return int(np.argmin(np.abs(vals - float(getattr(self.state, self.state.play_param)))))

    def _next_index(self) -> int:
        n = self.state.play_frames
        if self.frame < 0:
            return self._nearest()
        d = self.state.play_dir
        if d == "forward":
            return (self.frame + 1) % n
        if d == "backward":
            return (self.frame - 1) % n
        if not 0 <= self.frame + self._sign < n:  # bounce: back at either end
            self._sign = -self._sign
        return self.frame + self._sign

    # --- what the user does ------------------------------------------------------------------------

    def play(self) -> None:
        """Start (or restart) playing from the frame nearest the value in use."""
        self.message = self.check()
        if self.message:
            self._changed()
            return
        self._gen += 1
        self.playing = True
        self._still = False
        self._on_screen = (self.frame, float(getattr(self.state, self.state.play_param)))
        self.frame = -1
        self._sign = -1 if self.state.play_dir == "backward" else 1
        self.t_play = self._clock()
        self.first_frame_s = None
        self.drawn = []
        self.settled_searches.clear()
        self.session.frame_periods = FRAME_PERIODS
        self._request(self._next_index())

    def pause(self) -> None:
        """Stop at the frame on screen; it is computed again as a still (the state's periods), keeping the
        orbits found while playing (the teacher who pauses explains what was on screen).

        The frame on screen is the last one drawn: the next one, asked for and not computed yet, is not shown (a
        frame's points replace the last frame's only once all computed), so Pause then goes back to the one shown
        (it landed on the next frame)."""
        if not self.playing:
            return
        self._gen += 1
        self.playing = False
        shown = self._on_screen if self._waiting and not self._computed else None
        self._waiting = False
        self.session.frame_periods = None
        if shown is not None and shown[1] != float(getattr(self.state, self.state.play_param)):
            self.frame = shown[0]
            self._still = self._with_orbits_shown(lambda: self._commit(shown[1]))
        else:
            self._still = self._with_orbits_shown(self.session.recompute)
        self._changed()

    def step(self) -> None:
        """One frame on (in the direction set), shown as a still."""
        if self.playing:
            self.pause()
        self.message = self.check()
        if self.message:
            self._changed()
            return
        if self._frame_of_value() < 0:
            self.frame = self._nearest()
        self.frame = self._next_index()
        self._still = self._with_orbits_shown(lambda: self._set(self.frame))  # the orbits shown, to the next frame
        self._check_done()  # (an unchanged value computes nothing)
        self._changed()

    def shown(self, number: int) -> None:
        """The page shows frame ``number`` (its acknowledgement)."""
        self._acked = max(self._acked, number)
        self._check_done()

    # --- frames --------------------------------------------------------------------------------------

    def _frame_of_value(self) -> int:
        """The frame index if the played parameter holds that frame's value of the current range, else -1."""
        vals = self.values() if self.state.play_frames >= 2 else np.zeros(1)
        i = int(self.frame)
        current = float(getattr(self.state, self.state.play_param))
        return i if 0 <= i < vals.size and abs(float(vals[i]) - current) <= 1e-12 else -1

    def _set(self, i: int) -> None:
        self._commit(float(self.values()[i]))

    def _commit(self, value: float) -> None:
        problem = commit(self.state, self.state.play_param, repr(value))
        if problem:
            self.message = f"Play stopped: {problem}"
            self.playing = False
            self.session.frame_periods = None

    def _orbits_shown(self) -> tuple[tuple[float, float, int], ...]:
        """The periodic orbits on screen as the orbits layer follows them: ``(q, r, period)`` each."""
        orbits = self.session.layers["orbits"].orbits if "orbits" in self.session.layers else []  # type: ignore[attr-defined]
        return tuple((float(o.points[0, 0]), float(o.points[0, 1]), int(o.period)) for o in orbits)

    def _with_orbits_shown(self, recompute: Callable[[], None]) -> bool:
        """``recompute`` (a still: Pause, Step) with the orbits on screen followed to it, not dropped: the orbits
        layer starts its job from them (and its seeds) during the call; later changes follow nothing. Returns
        whether any orbit was shown (none, e.g. cleared: the still searches its settled trajectories for none)."""
        self.session.follow_orbits = shown = self._orbits_shown()
        try:
            recompute()
        finally:
            self.session.follow_orbits = ()
        return bool(shown)

    def _request(self, i: int) -> None:
        self.session.follow_orbits = self._orbits_shown()
        self.frame = i
        self._number += 1
        self._waiting, self._computed = True, False
        self.t_request = self._clock()
        before = getattr(self.state, self.state.play_param)
        self._set(i)
        if self.playing and getattr(self.state, self.state.play_param) == before:
            self.session.recompute()  # the same value (a range of one point, or the value in use): computed again
        self._changed()
        self._check_done()

    def _check_done(self) -> None:
        """A frame asked for is drawn once the section view runs nothing and the page (if any) shows it."""
        # The runner's own count, not the session's ``running``: that is told on the next turn of the event loop, so
        # right after a frame's jobs start it still says the last frame's "not running".
        if self._still and not self.playing and not self.session.busy():
            self._still = False
            self._search_settled()  # the still's trajectories that settled on a cycle no orbit shown is near
            return
        if not (self._waiting and self.playing) or self.session.busy():
            return
        if self._settled != self._number:
            # The frame's section and followed orbits are done: its trajectories that settled on a cycle no orbit on
            # screen is near (an orbit born at a fold since the last frame) are handed to Newton; the frame is drawn
            # once that is done too (this is called again when the section view stops running).
            self._settled = self._number
            started = self._search_settled()
            self.settled_searches.append(started)
            if started and self.session.busy():
                return
        if not self._computed:
            self._computed = True
            self._changed()  # the page learns the frame number it is to acknowledge
            if self.wait_for_browser:
                gen, number = self._gen, self._number
                self._schedule(ACK_TIMEOUT, lambda: self._ack_timeout(gen, number))
        if self.wait_for_browser and self._acked < self._number:
            return
        self._drawn()

    def _search_settled(self) -> int:
        layer = self.session.layers.get("orbits")
        return layer.find_settled() if layer is not None else 0  # type: ignore[attr-defined]

    def _ack_timeout(self, gen: int, number: int) -> None:
        if gen == self._gen and self._waiting and self._number == number:
            self._acked = max(self._acked, number)
            self._check_done()

    def _drawn(self) -> None:
        self._waiting = False
        self._on_screen = (self.frame, float(getattr(self.state, self.state.play_param)))
        now = self._clock()
        if self.first_frame_s is None:
            self.first_frame_s = now - self.t_play
        self.drawn.append(now)
        gen = self._gen
        delay = max(0.0, self.t_request + 1.0 / self.state.play_fps - now)
        self._schedule(delay, lambda: self._tick(gen))
        self._changed()

    def _tick(self, gen: int) -> None:
        if gen != self._gen or not self.playing or self._waiting:
            return
        self._request(self._next_index())

    # --- what the page shows ----------------------------------------------------------------------------

    def computing(self) -> bool:
        """A frame is asked for and not computed yet (the page's words wait for it)."""
        return self.playing and self._waiting and not self._computed

    def fps(self) -> float:
        """Frames drawn per second over the last (up to) 2 seconds of this Play."""
        t = [x for x in self.drawn if x >= self.drawn[-1] - 2.0] if self.drawn else []
        return (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0

    def view(self) -> dict[str, Any]:
        st = self.state
        vals = self.values() if st.play_frames >= 2 else np.zeros(1)
        # Not playing, a frame of another parameter, range or value (the played parameter switched, a slider
        # moved) is no frame of this one: the page then says the range, not a stale "frame 5/8: g1 = ...".
        frame = int(self.frame) if self.playing else self._frame_of_value()
        return {
            "playing": self.playing,
            "frame": frame,
            "frames": int(st.play_frames),
            "number": self._number if self._computed or not self._waiting else -1,
            "label": plain_label(st.play_param),
            "value": float(getattr(st, st.play_param)),
            "range": [float(vals[0]), float(vals[-1])],
            "fps": round(self.fps(), 1),
            "first_ms": None if self.first_frame_s is None else round(1e3 * self.first_frame_s),
            "message": self.message,
        }

    def _changed(self) -> None:
        if self._on_change is not None:
            self._on_change()


__all__ = ["ACK_TIMEOUT", "FRAME_PERIODS", "Player"]
