"""Stable and unstable manifolds of saddle periodic orbits of the Poincare map, and their crossings.

A saddle ``x*`` of period ``n`` (a fixed point of ``F = P^n``, :mod:`explorer_core.analyses.orbits`) has a
1-D unstable manifold ``W^u`` tangent at ``x*`` to the eigenvector of the expanding multiplier ``mu_u``
and a 1-D stable manifold ``W^s`` tangent to that of ``mu_s``; each has two branches, one on each side.
``W^u`` is grown by iterating ``G = F`` forwards, ``W^s`` by iterating ``G = F^-1``, i.e. integrating
backwards in time (the flow is invertible). When the multiplier is negative (a flip saddle) ``F`` swaps
the two branches, so ``G = F^2``.

Growth (Krauskopf & Osinga, *Growing 1D and quasi-2D unstable manifolds of maps*, J. Comput. Phys. 146,
1998, in its "parametrised by the fundamental domain" form): with ``lam = |mu_G| > 1`` the expansion of
``G`` along the eigenvector ``v``, the points ``y(t) = x* + sign delta lam^t v`` for ``t`` in ``[0, 1)``
form a fundamental domain (``G(y(0)) = y(1)`` to first order in ``delta``), and every point of the branch
is ``G^l(y(t))`` for one level ``l`` and one ``t``: the branch is the curve ``sigma = l + t ->
G^l(y(t))``, monotone in ``sigma``. A *member* is one ``t``, integrated by the one engine
(:func:`explorer_core.solve.integrators.advance`, lock-step blocks, both cores) level after level.
After each level the curve is checked **in pixels of the view**: a segment longer than ``delta_px``, or
at a bend sharper than ``alpha_max`` (longer than ``min_px``), gets a new member at the mid-``sigma``,
integrated from the fundamental domain. Segments entirely outside the view on one side are left coarse
(the view needs no more). Errors across the branch shrink as it grows (transverse directions contract
under ``G``), so the curve is as accurate as the linear start (``O(delta^2)``) and the integration.

A branch ends when it is ``length`` long (arc length in data units from ``x*``), when its level adds
less than a pixel (it ends on an attractor), when all its members escaped or failed, at the level limit,
or when the point budget is spent; a member that escapes or fails splits the branch into *pieces*.

Crossings of an unstable and a stable piece (other than at the saddle) are homoclinic points (of one
orbit) or heteroclinic points (of two); :func:`crossings` finds them segment against segment.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit

from explorer_core import config, export
from explorer_core.analyses.orbits import ORBIT_NUMERICS, Orbit, at_least_orbit_accuracy, find_orbits
from explorer_core.analyses.specs import Checking
from explorer_core.drawing import Drawable
from explorer_core.losses import Loss
from explorer_core.progress import Progress
from explorer_core.progress import run as run_updates
from explorer_core.solve.checks import check_point
from explorer_core.solve.integrators import Batch
from explorer_core.solve.numerics import Numerics, check_box, check_int
from explorer_core.solve.options import POSITIVE, Arg, Check, declare, integer, ints, optional_of
from explorer_core.solve.options import box as box_check
from explorer_core.solve.poincare import PoincareMap
from explorer_core.status import Status
from explorer_core.system.params import ParameterError, Params

KINDS = ("unstable", "stable")
#: Integration of the members: along the manifold errors only move points along it, across it they shrink.
MANIFOLD_NUMERICS = Numerics(rtol=1e-10, atol=1e-10)  # "auto": vern9 (config.VERN9_MAX_RTOL)
#: Default refinement, in pixels of the view (Krauskopf & Osinga's Delta and alpha_max).
DELTA_PX = 3.0
ALPHA_MAX = 0.3
MIN_PX = 0.25
#: Default view size in pixels when none is given.
PIXELS = (800, 600)
#: Members per branch in the fundamental domain before any refinement.
START_MEMBERS = 8
#: Distance of the fundamental domain from the saddle, as a fraction of the view's diagonal.
DELTA_FRACTION = 1e-5
MAX_LEVELS = 200
#: Refinement passes per level (each halves the offending gaps).
MAX_PASSES = 40
#: A branch whose last level added less than this many pixels of length has reached its end.
END_PX = 0.5
#: The pieces keep a point per this many pixels of arc.
THIN_PX = 0.5
#: ``t``-gaps below this cannot be split further in double precision (the segment stays as it is).
T_RESOLUTION = 1e-13


@dataclass(frozen=True)
class Branch:
    """One branch of a stable or unstable manifold: its pieces and how its growth ended.

    ``pieces``: list of (m, 3) arrays ``s, q, r`` (arc length from the saddle, point), split where a member
    escaped or failed. ``end``, how its growth ended: ``complete`` (reached the length), ``ends`` (its levels
    stopped adding length: it tends to an attractor or the saddle's orbit), ``escaped`` / ``failed`` (every
    member did), ``levels`` (level limit), ``budget`` (point budget), ``cancelled``, or ``growing`` (a partial
    result); ``status``, the same in the one vocabulary (the name of a :class:`~explorer_core.status.Status`):
    ``ok`` (complete, ends), ``escaped``, the engine failure of its members, ``budget`` (levels, budget),
    ``cancelled``, ``not_run`` (growing: no outcome yet).
    """

    point: int
    kind: str
    sign: int
    multiplier: float
    eigenvector: np.ndarray
    pieces: list[np.ndarray]
    length: float
    end: str
    levels: int
    members: int
    escaped: int
    failed: int
    unresolved: int
    status: str = Status.NOT_RUN.label

    @property
    def label(self) -> str:
        """``<orbit point><sign>``, e.g. ``0+``; a later piece of a split branch is ``0+#1``, ``0+#2``, ..."""
        return f"{self.point}{'+' if self.sign > 0 else '-'}"

    def piece_label(self, k: int) -> str:
        """The label of piece ``k``: the branch's own for the first, ``<label>#k`` after a split."""
        return self.label if k == 0 else f"{self.label}#{k}"

    def as_dict(self) -> dict[str, Any]:
        return {
            "branch": self.label,
            "kind": self.kind,
            "point": self.point,
            "sign": self.sign,
            "multiplier": float(self.multiplier),
            "eigenvector": [float(self.eigenvector[0]), float(self.eigenvector[1])],
            "length": float(self.length),
            "points": int(sum(p.shape[0] for p in self.pieces)),
            "pieces": len(self.pieces),
            "status": self.status,
            "end": self.end,
            "levels": self.levels,
            "members": self.members,
            "escaped": self.escaped,
            "failed": self.failed,
            "unresolved": self.unresolved,
        }


@dataclass(frozen=True)
class Crossing:
    """A point where an unstable piece crosses a stable piece (homoclinic: one orbit; heteroclinic: two)."""

    q: float
    r: float
    kind: str
    unstable: str
    stable: str
    s_unstable: float
    s_stable: float

    def as_dict(self) -> dict[str, Any]:
        return {"q": self.q, "r": self.r, "kind": self.kind, "unstable": self.unstable, "stable": self.stable,
                "s_unstable": self.s_unstable, "s_stable": self.s_stable}  # fmt: skip


@dataclass(frozen=True)
class Manifolds(Drawable):
    """The manifolds of one saddle orbit (and their crossings), complete or as grown so far."""

    params: Params
    numerics: Numerics
    orbit: Orbit
    branches: list[Branch]
    crossings: list[Crossing]
    view: tuple[float, float, float, float]
    pixels: tuple[int, int]
    length: float
    elapsed_s: float
    completed: bool
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def progress(self) -> Progress:
        """Arc length grown on the least grown branch, of the length asked."""
        grown = [max((float(p[-1, 0]) for p in b.pieces if p.size), default=0.0) for b in self.branches]
        done = self.length if self.completed else min(min(grown, default=0.0), self.length)
        return Progress(done, self.length, "arc length", self.elapsed_s)

    @property
    def result(self) -> Manifolds:
        """The update is the result (as grown so far; the last one of :func:`iter_manifolds` is final)."""
        return self

    @property
    def lost(self) -> list[Loss]:
        """Branches that stopped short of the length for want of resources or by failure, and members lost."""
        why = {"escaped": "every member escaped", "failed": "every member's integration failed",
               "levels": "the level limit was reached before the length", "budget": "the point budget ran out",
               "cancelled": "cancelled", "growing": "not grown to the end (a partial result)"}  # fmt: skip
        out = [Loss(f"branch {b.label} ({b.kind})", 1, why[b.end]) for b in self.branches if b.end in why]
        for attr, reason in (("escaped", "escaped: the branch is split there"),
                             ("failed", "the integration failed: the branch is split there"),
                             ("unresolved", "segments below the parameter resolution: a gap may remain")):  # fmt: skip
            n = sum(int(getattr(b, attr)) for b in self.branches)
            if n:
                out.append(Loss(f"members ({attr})", n, reason))
        if self.extra.get("crossings_skipped"):
            out.append(Loss("crossings", 1, "not computed: the growth was cancelled"))
        return out

    @property
    def complete(self) -> bool:
        return self.completed and not self.lost

    def report(self) -> list[str]:
        """What the command line prints: the saddle, each branch, the crossings."""
        o = self.orbit
        out = [f"period {o.period} {o.kind} at ({o.points[0, 0]:.10g}, {o.points[0, 1]:.10g}), "
               f"mu = {o.multipliers[0].real:.6g}, {o.multipliers[1].real:.6g}"]  # fmt: skip
        for b in self.branches:
            npts = sum(p.shape[0] for p in b.pieces)
            out.append(f"  {b.kind:8s} {b.label}: length {b.length:.4g}, {npts} points, {len(b.pieces)} piece(s), "
                       f"{b.end}" + (f", {b.escaped} escaped" if b.escaped else ""))  # fmt: skip
        homoclinic = sum(c.kind == "homoclinic" for c in self.crossings)
        return [*out, f"{len(self.crossings)} crossings ({homoclinic} homoclinic), {self.elapsed_s:.2f} s"]

    def summary(self) -> dict[str, Any]:
        return {
            "complete": self.complete,
            "lost": [loss.as_dict() for loss in self.lost],
            "orbit": self.orbit.as_dict(),
            "branches": [b.as_dict() for b in self.branches],
            "crossings": [c.as_dict() for c in self.crossings],
            "length": self.length,
            "view": list(self.view),
            "pixels": list(self.pixels),
            "completed": self.completed,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": self.params.as_dict(),
            "numerics": self.numerics.as_dict(),
            **self.extra,
        }

    def rows(self) -> Iterator[tuple[str, str, float, float, float]]:
        """``(branch, kind, s, q, r)`` for every point, pieces of a split branch labelled ``0+#1``, ..."""
        for b in self.branches:
            for k, piece in enumerate(b.pieces):
                label = b.piece_label(k)
                for s, q, r in piece:
                    yield label, b.kind, float(s), float(q), float(r)

    def write(self, path: str) -> dict[str, Any]:
        """``.csv``: :meth:`to_csv`; ``.json``: the summary."""
        return export.write_by_suffix(
            path, {".csv": self.to_csv, ".json": lambda p: export.write_json(p, self.summary())}, "set of manifolds"
        )

    def to_csv(self, path: str) -> int:
        """CSV ``branch,kind,s,q,r`` (``kind`` = stable | unstable, ``s`` the arc length), whole or not at all; a
        set whose run was stopped says so after its header (``# `` lines: :func:`explorer_core.export.partial`).
        Returns the rows."""
        n = 0
        with export.atomic(path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["branch", "kind", "s", "q", "r"])
            fh.writelines(export.comment_lines(export.partial(self)))
            for label, kind, s, q, r in self.rows():
                w.writerow([label, kind, float(s), float(q), float(r)])
                n += 1
        return n


# ---------------------------------------------------------------------------
# Growth of the branches of one kind (one direction of time), all at once.


class _Growth:
    """The members of every branch of one kind, level by level (see the module docstring).

    Member ``i`` is ``t[i]`` in branch ``br[i]``; ``pts[i, l]`` is ``G^l(y(t[i]))`` for ``l < npts[i]``.
    All members of unfinished branches are at the same level; a finished branch's members stay where
    they are.
    """

    def __init__(
        self,
        params: Params,
        kind: str,
        saddles: np.ndarray,
        vectors: np.ndarray,
        mus: np.ndarray,
        n: int,
        *,
        length: float,
        view: tuple[float, float, float, float],
        pixels: tuple[int, int],
        delta: float,
        delta_px: float,
        alpha_max: float,
        min_px: float,
        numerics: Numerics,
        max_levels: int,
        budget: list[int],
        workers: int | None,
    ) -> None:
        self.params, self.kind = params, kind
        self.map = PoincareMap.of(params, numerics, workers=workers)
        lam = mus if kind == "unstable" else 1.0 / mus
        self.m = 2 if np.any(lam < 0) else 1  # a flip: G = F^2 keeps each branch on its side
        self.lam = np.abs(lam) ** self.m  # expansion of G along v, > 1
        self.periods = self.m * n  # periods of one level
        self.direction = 1 if kind == "unstable" else -1
        nb = 2 * saddles.shape[0]
        self.saddle = np.repeat(saddles, 2, axis=0)  # branch b: point b // 2, sign + for even b
        self.sign = np.tile([1.0, -1.0], saddles.shape[0])
        self.vec = np.repeat(vectors, 2, axis=0)
        self.blam = np.repeat(self.lam, 2)
        self.bmu = np.repeat(mus, 2)
        self.delta = delta
        self.length = length
        self.view = view
        self.scale = np.array([pixels[0] / (view[1] - view[0]), pixels[1] / (view[3] - view[2])])
        self.delta_px, self.alpha_max, self.min_px = delta_px, alpha_max, min_px
        self.max_levels = max_levels
        self.budget = budget
        self.level = 0
        self.status = ["growing"] * nb
        self.unresolved = np.zeros(nb, np.int64)
        self.lengths = np.zeros(nb)
        self.added: list[np.ndarray] = []  # length each level added, per branch
        # Members: the fundamental domain of every branch at START_MEMBERS values of t.
        t0 = np.arange(START_MEMBERS) / START_MEMBERS
        self.t = np.tile(t0, nb)
        self.br = np.repeat(np.arange(nb), START_MEMBERS)
        self.pts = np.zeros((self.t.size, 8, 2))
        self.npts = np.ones(self.t.size, np.int64)
        start = self._start_points(self.t, self.br)
        self.pts[:, 0] = start
        self.batch = self.map.start(start, self.direction)
        budget[0] -= self.t.size

    # -- members ------------------------------------------------------------------------------------

    def _start_points(self, t: np.ndarray, br: np.ndarray) -> np.ndarray:
        amp = self.delta * self.blam[br] ** t
        return self.saddle[br] + (self.sign[br] * amp)[:, None] * self.vec[br]

    def _store(self, idx: np.ndarray, level: int, points: np.ndarray) -> None:
        if level >= self.pts.shape[1]:
            grown = np.zeros((self.pts.shape[0], max(level + 1, 2 * self.pts.shape[1]), 2))
            grown[:, : self.pts.shape[1]] = self.pts
            self.pts = grown
        self.pts[idx, level] = points

    def _advance(self, batch: Batch, idx: np.ndarray, levels: int, first: int) -> None:
        """Advance members ``idx`` (the whole of ``batch``) by ``levels`` levels from level ``first``."""
        if levels <= 0 or batch.n == 0:
            return
        rec, npts = self.map.advance(batch, levels * self.periods)
        for lv in range(1, levels + 1):
            ok = npts >= lv * self.periods
            self._store(idx[ok], first + lv, rec[ok, lv * self.periods - 1])
            self.npts[idx[ok]] = first + lv + 1

    def _add_members(self, t: np.ndarray, br: np.ndarray) -> None:
        """New members, integrated from the fundamental domain to the current level and joined to the batch."""
        start = self._start_points(t, br)
        first = self.t.size
        idx = np.arange(first, first + t.size)
        self.t, self.br = np.concatenate([self.t, t]), np.concatenate([self.br, br])
        self.pts = np.concatenate([self.pts, np.zeros((t.size, self.pts.shape[1], 2))])
        self.npts = np.concatenate([self.npts, np.ones(t.size, np.int64)])
        self.pts[idx, 0] = start
        part = self.map.start(start, self.direction)
        self._advance(part, idx, self.level, 0)
        b = self.batch
        self.batch = Batch(np.concatenate([b.y, part.y]), np.concatenate([b.h, part.h]),
                           np.concatenate([b.status, part.status]), np.concatenate([b.nsteps, part.nsteps]),
                           b.k, b.t0, b.period)  # fmt: skip
        self.budget[0] -= t.size

    # -- the curve ----------------------------------------------------------------------------------

    def curve(self, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Branch ``b`` in ``sigma`` order: points (k, 2), ok (k,), level (k,), t (k,); the saddle excluded."""
        mem = np.flatnonzero(self.br == b)
        order = mem[np.argsort(self.t[mem], kind="stable")]
        levels = self.level + 1
        lv = np.repeat(np.arange(levels), order.size)
        who = np.tile(order, levels)
        # A member's point at level l exists if l < npts; a failed member marks a break at its first missing level.
        have = lv < self.npts[who]
        broken = (lv == self.npts[who]) & (self.batch.status[who] != Status.OK)
        keep = have | broken
        lv, who = lv[keep], who[keep]
        pts = np.where(have[keep][:, None], self.pts[who, np.minimum(lv, self.pts.shape[1] - 1)], np.nan)
        return pts, have[keep], lv, self.t[who]

    def _pixels(self, p: np.ndarray) -> np.ndarray:
        return (p - np.array([self.view[0], self.view[2]])) * self.scale

    def refine(self, b: int) -> np.ndarray:
        """New ``t`` values (level-local midpoints) where branch ``b``'s newest level breaks the criteria."""
        pts, ok, lv, t = self.curve(b)
        if pts.shape[0] < 2:
            return np.zeros(0)
        px = self._pixels(np.where(ok[:, None], pts, 0.0))
        seg_ok = ok[:-1] & ok[1:]
        d = px[1:] - px[:-1]
        gap = np.hypot(d[:, 0], d[:, 1])
        # Only the segments that touch the newest level (the lower ones were refined before).
        fresh = seg_ok & (lv[1:] >= self.level) & (lv[:-1] >= self.level - 1)
        w, h = self.scale * np.array([self.view[1] - self.view[0], self.view[3] - self.view[2]])
        a, c = px[:-1], px[1:]
        off = ((a[:, 0] < 0) & (c[:, 0] < 0)) | ((a[:, 0] > w) & (c[:, 0] > w))
        off |= ((a[:, 1] < 0) & (c[:, 1] < 0)) | ((a[:, 1] > h) & (c[:, 1] > h))
        need = fresh & ~off & (gap > self.delta_px)
        # Bends: the angle between consecutive segments, refined on both sides when they are long enough.
        if gap.size >= 2:
            dot = np.einsum("ij,ij->i", d[:-1], d[1:])
            with np.errstate(invalid="ignore", divide="ignore"):
                cos = dot / (gap[:-1] * gap[1:])
            bend = seg_ok[:-1] & seg_ok[1:] & (np.arccos(np.clip(np.nan_to_num(cos, nan=1.0), -1, 1)) > self.alpha_max)
            bend &= ~(off[:-1] & off[1:])
            need[:-1] |= bend & fresh[:-1] & (gap[:-1] > self.min_px)
            need[1:] |= bend & fresh[1:] & (gap[1:] > self.min_px)
        j = np.flatnonzero(need)
        if j.size == 0:
            return np.zeros(0)
        # Midpoint in sigma = level + t of the segment's ends (adjacent levels at most).
        sa = t[j]
        sb = t[j + 1] + (lv[j + 1] - lv[j])
        mid = 0.5 * (sa + sb)
        tiny = (sb - sa) < T_RESOLUTION
        self.unresolved[b] += int(np.count_nonzero(tiny))
        return np.unique(np.mod(mid[~tiny], 1.0))

    def pieces(self, b: int) -> tuple[list[np.ndarray], float]:
        """Branch ``b`` as pieces ``(s, q, r)`` split at failed members, the saddle first, and its length.

        The arc length is that of every computed point; the pieces keep a point per ``THIN_PX`` pixels of
        arc (members added for a later level crowd the earlier ones far below a pixel).
        """
        pts, ok, _, _ = self.curve(b)
        pts = np.vstack([self.saddle[b][None, :], pts])
        ok = np.concatenate([[True], ok])
        piece = np.cumsum(~ok)
        good = np.flatnonzero(ok)
        p, pid = pts[good], piece[good]
        d = p[1:] - p[:-1]
        same = pid[1:] == pid[:-1]
        s = np.concatenate([[0.0], np.cumsum(np.where(same, np.hypot(d[:, 0], d[:, 1]), 0.0))])
        dp = d * self.scale
        spx = np.concatenate([[0.0], np.cumsum(np.where(same, np.hypot(dp[:, 0], dp[:, 1]), 0.0))])
        cell = np.floor(spx / THIN_PX)
        first = np.concatenate([[True], ~same])
        last = np.concatenate([~same, [True]])
        keep = first | last | np.concatenate([[True], cell[1:] != cell[:-1]])
        rows = np.column_stack([s, p])[keep]
        cuts = np.flatnonzero(np.diff(pid[keep]) != 0) + 1
        pieces = [x for x in np.split(rows, cuts) if x.shape[0] > 1 or x[0, 0] == 0.0]
        return pieces, float(s[-1]) if s.size else 0.0

    # -- levels -------------------------------------------------------------------------------------

    def growing(self) -> np.ndarray:
        return np.flatnonzero(np.array([s == "growing" for s in self.status]))

    def step(self, cancel: Callable[[], bool] | None) -> None:
        """One more level for every growing branch, refined, then the ends decided."""
        live_br = self.growing()
        if live_br.size == 0:
            return
        idx = np.flatnonzero(np.isin(self.br, live_br) & (self.batch.status == Status.OK))
        part = self.batch.take(idx)
        self._advance(part, idx, 1, self.level)
        self.batch.put(idx, part)
        self.level += 1
        if cancel is not None and cancel():  # within a level of the Ctrl-C: the pieces are cut where they are
            for b in live_br:
                self.status[b] = "cancelled"
            return
        for _ in range(MAX_PASSES):
            if cancel is not None and cancel():
                break
            new_t, new_b = [], []
            for b in live_br:
                tb = self.refine(int(b))
                new_t.append(tb)
                new_b.append(np.full(tb.size, b, np.int64))
            t = np.concatenate(new_t) if new_t else np.zeros(0)
            if t.size == 0:
                break
            if self.budget[0] < t.size:
                for b in live_br:
                    self.status[b] = "budget"
                break
            self._add_members(t, np.concatenate(new_b))
        prev = self.lengths.copy()
        added = np.full(self.lengths.size, np.inf)
        for b in live_br:
            _, self.lengths[b] = self.pieces(int(b))
            added[b] = self.lengths[b] - prev[b]
            mem = self.br == b
            st = self.batch.status[mem]
            if self.status[b] != "growing":
                continue
            if self.lengths[b] >= self.length:
                self.status[b] = "complete"
            elif not np.any(st == Status.OK):
                self.status[b] = "escaped" if np.any(st == Status.ESCAPED) else "failed"
            elif self._ends(b, added[b]):
                self.status[b] = "ends"
            elif self.level >= self.max_levels:
                self.status[b] = "levels"
        self.added.append(added)
        if cancel is not None and cancel():
            for b in self.growing():
                self.status[b] = "cancelled"

    def _ends(self, b: int, added: float) -> bool:
        # Levels that add less than a pixel, each less than the one before: the branch tends to an
        # attractor (near the saddle every level adds lam times the last, so this never fires there).
        if len(self.added) < 2 or added * float(self.scale.min()) >= END_PX:
            return False
        a1, a2 = self.added[-1][b], self.added[-2][b]
        return bool(added < a1 < a2)

    def branches(self, n_points: int) -> list[Branch]:
        out = []
        for b in range(2 * n_points):
            pieces, length = self.pieces(b)
            pieces = _cut(pieces, self.length)
            mem = self.br == b
            st = self.batch.status[mem]
            out.append(Branch(b // 2, self.kind, int(self.sign[b]), float(self.bmu[b]), self.vec[b].copy(), pieces,
                              min(length, self.length), self.status[b], self.level, int(np.count_nonzero(mem)),
                              int(np.count_nonzero(st == Status.ESCAPED)),
                              int(np.count_nonzero((st != Status.OK) & (st != Status.ESCAPED))),
                              int(self.unresolved[b]), _outcome(self.status[b], st).label))  # fmt: skip
        return out


def _outcome(end: str, members: np.ndarray) -> Status:
    """A branch's growth end in the one vocabulary; ``failed`` is its members' most frequent engine failure."""
    if end == "failed":
        codes = members[(members != Status.OK) & (members != Status.ESCAPED)].astype(np.int64)
        return Status.of(int(np.bincount(codes).argmax())) if codes.size else Status.NOT_RUN
    return {"complete": Status.OK, "ends": Status.OK, "escaped": Status.ESCAPED, "levels": Status.BUDGET,
            "budget": Status.BUDGET, "cancelled": Status.CANCELLED}.get(end, Status.NOT_RUN)  # fmt: skip


def _cut(pieces: list[np.ndarray], length: float) -> list[np.ndarray]:
    """The pieces up to arc length ``length`` (the last point interpolated onto it)."""
    out = []
    for p in pieces:
        if p[0, 0] >= length:
            break
        if p[-1, 0] <= length:
            out.append(p)
            continue
        k = int(np.searchsorted(p[:, 0], length))
        a, b = p[k - 1], p[k]
        f = (length - a[0]) / (b[0] - a[0]) if b[0] > a[0] else 0.0
        out.append(np.vstack([p[:k], a + f * (b - a)]))
        break
    return out


# ---------------------------------------------------------------------------
# Public calls.


def saddle_eigenvectors(matrix: np.ndarray) -> tuple[float, np.ndarray, float, np.ndarray]:
    """``(mu_u, v_u, mu_s, v_s)`` of a saddle's ``DP^n`` (unit vectors); ParameterError if it is no saddle."""
    mu, vec = np.linalg.eig(np.asarray(matrix, dtype=float))
    if np.any(np.abs(mu.imag) > 0) or not (abs(mu.real).max() > 1.0 > abs(mu.real).min()):
        raise ParameterError(f"not a saddle: multipliers {np.round(mu, 6).tolist()} (a saddle has |mu_s| < 1 < |mu_u|)")
    mu, vec = mu.real, vec.real
    u, s = (0, 1) if abs(mu[0]) > abs(mu[1]) else (1, 0)
    vu, vs = vec[:, u] / np.linalg.norm(vec[:, u]), vec[:, s] / np.linalg.norm(vec[:, s])
    # A fixed orientation so that "+" means the same side every time: first nonzero component positive.
    vu = vu if (vu[0] > 0 or (vu[0] == 0 and vu[1] > 0)) else -vu
    vs = vs if (vs[0] > 0 or (vs[0] == 0 and vs[1] > 0)) else -vs
    return float(mu[u]), vu, float(mu[s]), vs


def saddle_orbit(params: Params, point: Sequence[float], period: int, *, numerics: Numerics | None = None) -> Orbit:
    """The saddle orbit of least period dividing ``period`` that Newton finds from ``point``.

    Raises ParameterError (naming the point) when Newton finds none, or when the orbit is not a saddle.
    """
    period = check_int("period", period, 1, 64)
    x = np.asarray(point, dtype=float).reshape(-1)
    if x.size != 2 or not np.all(np.isfinite(x)):
        raise ParameterError(f"the orbit's point must be two finite numbers Q,R, got {point!r}")
    found = find_orbits(params, x[None, :], [period], numerics=numerics or ORBIT_NUMERICS)
    if not found.orbits:
        why = found.failures[0].reason if found.failures else "no convergence"
        raise ParameterError(f"no periodic orbit of period {period} found from ({x[0]:.6g}, {x[1]:.6g}): {why}")
    orbit = found.orbits[0]
    if orbit.kind not in ("saddle", "flip saddle"):
        article = "an" if orbit.kind[0] in "aeiou" else "a"
        raise ParameterError(f"the orbit of period {orbit.period} found from ({x[0]:.6g}, {x[1]:.6g}) is {article} "
                             f"{orbit.kind}, not a saddle: it has no 1-D stable and unstable manifolds")  # fmt: skip
    return orbit


def default_view(orbit: Orbit, length: float) -> tuple[float, float, float, float]:
    """A box around the orbit wide enough to show a good part of branches of ``length``."""
    c = orbit.points.mean(axis=0)
    half = max(1.0, min(float(length), 10.0)) / 2 + np.ptp(orbit.points, axis=0).max() / 2
    return (float(c[0] - half), float(c[0] + half), float(c[1] - half), float(c[1] + half))


def iter_manifolds(
    params: Params,
    orbit: Orbit,
    *,
    kinds: Sequence[str] = KINDS,
    length: float = 10.0,
    view: Sequence[float] | None = None,
    pixels: Sequence[int] = PIXELS,
    delta_px: float = DELTA_PX,
    alpha_max: float = ALPHA_MAX,
    min_px: float = MIN_PX,
    delta: float | None = None,
    numerics: Numerics | None = None,
    max_points: int = 200_000,
    max_levels: int = MAX_LEVELS,
    others: Sequence[Manifolds] = (),
    cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
) -> Iterator[Manifolds]:
    """Grow the manifolds of the saddle ``orbit``; yield the manifolds grown so far after every level.

    Parameters
    ----------
    orbit : a saddle or flip saddle (:func:`saddle_orbit`); its every point gets its two branches of
        each kind in ``kinds`` (``"unstable"``, ``"stable"``).
    length : arc length (data units) each branch is grown to.
    view, pixels : the plot window ``(q0, q1, r0, r1)`` and its size in pixels: the refinement criteria
        (``delta_px``: longest segment, ``alpha_max``: sharpest bend in radians, ``min_px``: shortest
        segment refined for a bend) are measured there; segments outside the view on one side are not
        refined. Default: :func:`default_view`, 800 x 600.
    delta : distance of the fundamental domain from the saddle (default ``1e-5`` of the view's diagonal).
    max_points : members (points per level) over all branches; branches still growing when it is
        spent end with status ``budget``.
    others : manifolds of other saddles: crossings of their stable (unstable) pieces with these
        unstable (stable) ones are reported as heteroclinic.
    cancel : polled between refinement passes and levels.

    Yields
    ------
    Manifolds : partial (``completed=False``, branches ``growing``) after each level, then the final one.
    """
    start = time.perf_counter()
    if not isinstance(orbit, Orbit):
        raise ParameterError("orbit must be an Orbit (see saddle_orbit)")
    kinds = tuple(kinds)
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        raise ParameterError(f"kinds must be among {KINDS}, got {list(kinds)!r}")
    if not (isinstance(length, int | float) and math.isfinite(length) and 0 < length <= 1e6):
        raise ParameterError(f"length must be a number in (0, 1e6], got {length!r}")
    box = check_box(view, "view") if view is not None else default_view(orbit, float(length))
    px = tuple(check_int(n, int(v) if isinstance(v, float) and v.is_integer() else v, 16, 20_000)
               for n, v in zip(("pixels (width)", "pixels (height)"), tuple(pixels), strict=True))  # fmt: skip
    for name, v, lo, hi in (("delta_px", delta_px, 0.05, 1e4), ("alpha_max", alpha_max, 1e-3, math.pi),
                            ("min_px", min_px, 1e-3, 1e4)):  # fmt: skip
        if not (isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi):
            raise ParameterError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
    diag = math.hypot(box[1] - box[0], box[3] - box[2])
    delta = DELTA_FRACTION * diag if delta is None else delta
    if not (isinstance(delta, int | float) and math.isfinite(delta) and 0 < delta <= 0.1 * diag):
        raise ParameterError(f"delta must be a positive number at most a tenth of the view's diagonal, got {delta!r}")
    check_int("max_points", max_points, 100, 10_000_000)
    check_int("max_levels", max_levels, 1, 10_000)
    numerics = numerics or MANIFOLD_NUMERICS
    n = orbit.period
    pts = orbit.points
    # the saddle's eigenvectors on the map it is found on (ManifoldSpec.saddle_numerics: the same rule)
    mono = PoincareMap.of(params, at_least_orbit_accuracy(numerics), workers=workers).derivative(pts, n)
    if not np.all(mono.ok):
        raise ParameterError("the monodromy matrix at a point of the orbit could not be computed")
    eig = [saddle_eigenvectors(mono.matrix[j]) for j in range(pts.shape[0])]
    budget = [int(max_points)]
    growth = []
    for kind in kinds:
        col = (0, 1) if kind == "unstable" else (2, 3)
        mus = np.array([e[col[0]] for e in eig])
        vecs = np.array([e[col[1]] for e in eig])
        growth.append(_Growth(params, kind, pts, vecs, mus, n, length=float(length), view=box, pixels=px,
                              delta=float(delta), delta_px=float(delta_px), alpha_max=float(alpha_max),
                              min_px=float(min_px), numerics=numerics, max_levels=int(max_levels), budget=budget,
                              workers=workers))  # fmt: skip

    def snapshot(done: bool) -> Manifolds:
        branches = [b for g in growth for b in g.branches(pts.shape[0])]
        stopped = cancel is not None and cancel()
        mine = Manifolds(params, numerics, orbit, branches, [], box, px, float(length),  # type: ignore[arg-type]
                         time.perf_counter() - start, done)  # fmt: skip
        cross = [replace(c, unstable=c.unstable.removeprefix("A:"), stable=c.stable.removeprefix("A:"))
                 for c in (crossings([mine, *others]) if done and not stopped else [])]  # fmt: skip
        extra = {"members_left": budget[0], "delta": float(delta)}
        if done and stopped:
            extra["crossings_skipped"] = True  # the crossings of a large run take seconds: not after a cancel
        return Manifolds(params, numerics, orbit, branches, cross, box, px, float(length),  # type: ignore[arg-type]
                         time.perf_counter() - start, done, extra)  # fmt: skip

    while any(g.growing().size for g in growth):
        for g in growth:
            g.step(cancel)
        if cancel is not None and cancel():
            for g in growth:
                for b in g.growing():
                    g.status[b] = "cancelled"
            break
        if any(g.growing().size for g in growth):
            yield snapshot(False)
    yield snapshot(True)


def manifolds(
    params: Params | ManifoldSpec,
    orbit: Orbit | None = None,
    *,
    progress: Callable[[Manifolds], None] | None = None,
    **kw: Any,
) -> Manifolds:
    """The final result of :func:`iter_manifolds` (same arguments; or a :class:`ManifoldSpec` alone, whose saddle
    Newton finds first); ``progress`` gets each of its updates."""
    if isinstance(params, ManifoldSpec):
        if orbit is not None:
            raise TypeError("a ManifoldSpec comes alone, not with an orbit")
        spec = params
        params, orbit = spec.params, spec.saddle()
        kw = {**spec.growth(), **kw}
    return run_updates(iter_manifolds(params, orbit, **kw), progress)


@dataclass(frozen=True)
class ManifoldSpec:
    """What defines the manifolds of a saddle orbit (``bilimovich manifolds``), made by :func:`manifold_spec`:
    the orbit (a point near it and its period: Newton finds it when the manifolds are grown), the branches, the
    window they are refined for and the numerics."""

    params: Params
    point: tuple[float, float]
    period: int
    kinds: tuple[str, ...]
    length: float
    view: tuple[float, float, float, float] | None
    pixels: tuple[int, int]
    delta_px: float
    max_points: int
    numerics: Numerics

    @property
    def saddle_numerics(self) -> Numerics:
        """The map Newton finds the saddle on: these numerics, at least as accurate as an orbit's
        (:data:`~explorer_core.analyses.orbits.ORBIT_NUMERICS`: 1e-12), the method chosen again by the rule."""
        return at_least_orbit_accuracy(self.numerics)

    def saddle(self) -> Orbit:
        """The saddle orbit (:func:`saddle_orbit` from ``point`` on :attr:`saddle_numerics`); ParameterError when
        Newton finds none or the orbit is not a saddle."""
        return saddle_orbit(self.params, self.point, self.period, numerics=self.saddle_numerics)

    def growth(self) -> dict[str, Any]:
        """:func:`iter_manifolds`' keywords for this spec (the branches, window, refinement, numerics)."""
        return {"kinds": self.kinds, "length": self.length, "view": self.view, "pixels": self.pixels,
                "delta_px": self.delta_px, "numerics": self.numerics, "max_points": self.max_points}  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        return {"params": self.params.as_dict(), "point": list(self.point), "period": self.period,
                "kinds": list(self.kinds), "length": self.length,
                "view": None if self.view is None else list(self.view),
                "pixels": list(self.pixels), "delta_px": self.delta_px, "max_points": self.max_points,
                "numerics": self.numerics.as_dict()}  # fmt: skip


def _kinds() -> Check:
    """Which branches: a non-empty sequence of names in :data:`KINDS`, as a tuple."""

    def fn(name: str, value: Any) -> tuple[str, ...]:
        kinds = tuple(value)
        if not kinds or any(k not in KINDS for k in kinds):
            raise ParameterError(f"{name} must be unstable, stable or both (comma-separated), got {','.join(kinds)!r}")
        return kinds

    return Check(fn, "unstable, stable or both", "str")


@declare(
    point=Arg(
        "a point near the saddle orbit (Newton finds it)",
        "point",
        flag="--orbit",
        metavar="Q,R",
        required=True,
        positional=True,
        checked_with=("numerics",),
    ),
    period=Arg("the orbit's period", "int", positional=True, default=1, check=integer(1, 64)),
    length=Arg("arc length of each branch", default=10.0, check=POSITIVE),
    kinds=Arg("the branches grown", "list", metavar="K[,K]", default=KINDS, check=_kinds()),
    view=Arg(
        "the plot window the curves are refined for (default: around the orbit)",
        "box",
        scene="view",
        default=None,
        check=box_check(optional=True),
    ),
    pixels=Arg("the window's size in pixels", "ints", metavar="W,H", default=PIXELS, check=ints(2, 1, 100_000, "W,H")),
    delta_px=Arg("longest segment in pixels", "float", default=DELTA_PX, check=POSITIVE),
    max_points=Arg("points computed over all branches", "int", default=200_000, check=integer(100, 10_000_000)),
    bound=Arg("", scene="bound", flag="", default=None, checked_with=("numerics",)),
    numerics=Arg("default: MANIFOLD_NUMERICS", cli=False, default=None, check=optional_of(Numerics)),
)
def manifold_spec(
    params: Params,
    point: Any,
    period: int,
    *,
    kinds: tuple[str, ...],
    length: float,
    view: tuple[float, float, float, float] | None,
    pixels: tuple[int, int],
    delta_px: float,
    max_points: int,
    bound: float | None,
    numerics: Numerics | None,
) -> ManifoldSpec:
    """A validated :class:`ManifoldSpec` (a bad value raises ParameterError naming it, ``exc.option``: its keyword).
    ``numerics`` default: :data:`MANIFOLD_NUMERICS` with the escape ``bound`` (a scene's). The options are declared
    above: defaults, checks (run before this body), flags."""
    with Checking() as at:
        at("numerics")
        if numerics is None:
            numerics = MANIFOLD_NUMERICS if bound is None else replace(MANIFOLD_NUMERICS, bound=float(bound))
        at("point")
        q, r = check_point("orbit", point, numerics.bound)
    return ManifoldSpec(params, (q, r), period, kinds, length, view, pixels, delta_px, max_points, numerics)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------
# Crossings of unstable and stable pieces.


@njit(nogil=True, cache=True)
def _cross(a: np.ndarray, i: int, b: np.ndarray, j: int) -> tuple[bool, float, float]:  # pragma: no cover
    # Segment a[i] a[i+1] against b[j] b[j+1]: fractions u, v in [0, 1) (a shared vertex counts once).
    ax0, ay0, ax1, ay1 = a[i, 0], a[i, 1], a[i + 1, 0], a[i + 1, 1]
    bx0, by0, bx1, by1 = b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1]
    if max(bx0, bx1) < min(ax0, ax1) or min(bx0, bx1) > max(ax0, ax1):
        return False, 0.0, 0.0
    if max(by0, by1) < min(ay0, ay1) or min(by0, by1) > max(ay0, ay1):
        return False, 0.0, 0.0
    dax, day, dbx, dby = ax1 - ax0, ay1 - ay0, bx1 - bx0, by1 - by0
    den = dax * dby - day * dbx
    if den == 0.0:  # parallel: never a transverse crossing
        return False, 0.0, 0.0
    ex, ey = bx0 - ax0, by0 - ay0
    u = (ex * dby - ey * dbx) / den
    v = (ex * day - ey * dax) / den
    return (0.0 <= u < 1.0) and (0.0 <= v < 1.0), u, v


@njit(nogil=True, cache=True)
def segment_crossings(a: np.ndarray, b: np.ndarray, cell: float) -> np.ndarray:  # pragma: no cover - compiled
    """Every crossing of a segment of polyline ``a`` (m, 2) with one of ``b`` (k, 2).

    Returns (c, 4) rows ``i, j, u, v``: segment ``a[i] a[i+1]`` at fraction ``u`` meets ``b[j] b[j+1]`` at
    ``v``, both in ``[0, 1)``. Segments no longer than ``cell`` are hashed by the cell of their midpoint
    (sorted cell keys, no dense grid: the curves may reach far off the view) and tested against the 3 x 3
    cells around (a short segment reaches at most one cell from its midpoint's); longer ones against all.
    """
    out = np.empty((16, 4))
    c = 0
    na, nb = a.shape[0] - 1, b.shape[0] - 1
    if na < 1 or nb < 1:
        return out[:0]
    lo_x = min(a[:, 0].min(), b[:, 0].min())
    lo_y = min(a[:, 1].min(), b[:, 1].min())
    h = max(cell, 1e-300)
    stride = np.int64(1) << 31
    key = np.full(nb, -1, np.int64)
    for j in range(nb):
        if abs(b[j + 1, 0] - b[j, 0]) <= h and abs(b[j + 1, 1] - b[j, 1]) <= h:
            gx = np.int64((0.5 * (b[j, 0] + b[j + 1, 0]) - lo_x) / h)
            gy = np.int64((0.5 * (b[j, 1] + b[j + 1, 1]) - lo_y) / h)
            key[j] = gx * stride + gy
    order = np.argsort(key)
    sorted_keys = key[order]
    long_b = np.flatnonzero(key < 0)
    for i in range(na):
        short = abs(a[i + 1, 0] - a[i, 0]) <= h and abs(a[i + 1, 1] - a[i, 1]) <= h
        if short:
            gx = np.int64((0.5 * (a[i, 0] + a[i + 1, 0]) - lo_x) / h)
            gy = np.int64((0.5 * (a[i, 1] + a[i + 1, 1]) - lo_y) / h)
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    if gx + dx < 0 or gy + dy < 0:
                        continue
                    k = (gx + dx) * stride + (gy + dy)
                    m = np.searchsorted(sorted_keys, k)
                    while m < nb and sorted_keys[m] == k:
                        j = order[m]
                        m += 1
                        hit, u, v = _cross(a, i, b, j)
                        if hit:
                            if c == out.shape[0]:
                                grown = np.empty((2 * c, 4))
                                grown[:c] = out
                                out = grown
                            out[c, 0], out[c, 1], out[c, 2], out[c, 3] = i, j, u, v
                            c += 1
            candidates = long_b
        else:
            candidates = np.arange(nb)
        # The same append as above, written out: a helper returning the grown array cost reference
        # counting on every pair tested (5-7x slower measured).
        for j in candidates:
            hit, u, v = _cross(a, i, b, j)
            if hit:
                if c == out.shape[0]:
                    grown = np.empty((2 * c, 4))
                    grown[:c] = out
                    out = grown
                out[c, 0], out[c, 1], out[c, 2], out[c, 3] = i, j, u, v
                c += 1
    return out[:c]


def _cell(*polylines: np.ndarray) -> float:
    # All but 1% of the segments short enough to be hashed (each long one is tested against every other:
    # with 5% long the long ones took 3/4 of the time on Fig. 8B's manifolds to arc length 200).
    ext = [np.abs(np.diff(p, axis=0)).max(axis=1) for p in polylines if p.shape[0] > 1]
    return float(np.quantile(np.concatenate(ext), 0.99)) if ext else 1.0


def crossings(sets: Sequence[Manifolds]) -> list[Crossing]:
    """Crossings of the unstable pieces of ``sets[0]`` with every stable piece, and of every unstable piece
    with the stable pieces of ``sets[0]`` (the others' crossings among themselves were found with them).

    Pieces of ``sets[0]`` are labelled ``A:<branch>``, of the others ``<orbit index>:<branch>``; a crossing
    of one orbit's two manifolds is homoclinic, of two orbits' heteroclinic. The saddles themselves
    (where the branches start) are not crossings: each piece's first segment from the saddle is skipped.
    """
    out: list[Crossing] = []
    parts: list[tuple[str, str, int, np.ndarray]] = []
    for k, m in enumerate(sets):
        tag = "A:" if k == 0 else f"{k}:"
        for b in m.branches:
            for i, p in enumerate(b.pieces):
                label = tag + b.piece_label(i)
                body = p[1:] if i == 0 else p  # from the first point off the saddle
                if body.shape[0] >= 2:
                    parts.append((label, b.kind, k, body))
    pairs = [(u, s_) for u in parts if u[1] == "unstable" for s_ in parts if s_[1] == "stable" and 0 in (u[2], s_[2])]

    def hits_of(pair: tuple) -> np.ndarray:
        a, b = np.ascontiguousarray(pair[0][3][:, 1:]), np.ascontiguousarray(pair[1][3][:, 1:])
        return segment_crossings(a, b, _cell(a, b))

    # The kernel releases the GIL: the pairs of pieces on every core.
    with ThreadPoolExecutor(max_workers=max(1, min(config.N_WORKERS, len(pairs)))) as pool:
        found = list(pool.map(hits_of, pairs))
    for ((lu, _, ou, pu), (ls, _, os_, ps)), hits in zip(pairs, found, strict=True):
        for i, j, u, v in hits:
            i, j = int(i), int(j)
            q = pu[i, 1] + u * (pu[i + 1, 1] - pu[i, 1])
            r = pu[i, 2] + u * (pu[i + 1, 2] - pu[i, 2])
            su = pu[i, 0] + u * (pu[i + 1, 0] - pu[i, 0])
            ss = ps[j, 0] + v * (ps[j + 1, 0] - ps[j, 0])
            out.append(Crossing(float(q), float(r), "homoclinic" if ou == os_ else "heteroclinic", lu, ls,
                                float(su), float(ss)))  # fmt: skip
    return out


def warmup() -> None:
    """Compile the crossing kernel (the growth itself runs on the engine's kernels)."""
    segment_crossings(np.zeros((2, 2)), np.ones((2, 2)), 1.0)
