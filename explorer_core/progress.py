"""Where a long analysis is: one shape for every progress line.

Every update a long analysis yields or passes to its ``progress`` callback (``SectionChunk``, ``Density``,
``SweepProgress``, ``LyapunovProgress``, ``ChartUpdate``, ``Manifolds`` as grown so far, ...) has a
``progress`` property of this type, so the command line's progress line and the app's status read them
all alike.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """``done`` of ``total`` ``unit`` (e.g. 120 of 700 periods), after ``elapsed_s`` seconds."""

    done: float
    total: float
    unit: str
    elapsed_s: float = 0.0

    @property
    def fraction(self) -> float:
        return min(1.0, max(0.0, self.done / self.total)) if self.total > 0 else 0.0

    def line(self) -> str:
        def num(v: float) -> str:
            return f"{v:.4g}" if v != int(v) else str(int(v))

        return f"{num(self.done)}/{num(self.total)} {self.unit} ({100 * self.fraction:.0f} %, {self.elapsed_s:.1f} s)"
