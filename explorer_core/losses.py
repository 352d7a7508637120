"""What a result lost, and why: the one shape every analysis reports its losses in.

A result is *complete* when it holds everything its spec asked for. Anything else (a branch that stopped
other than at the range's end or a located bifurcation, members that failed or escaped, seeds that found
nothing, pixels not computed, work cancelled) is a :class:`Loss`. The command line prints each on
stderr (``lost: ...``), ``--json`` carries them under ``"lost"``, the app shows them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Loss:
    """``count`` items of ``what`` (e.g. ``"branch 3 (period 8)"``, ``"pixels"``) lost because of ``why``."""

    what: str
    count: int
    why: str

    def __post_init__(self) -> None:
        # The count comes from numpy sums more often than not: keep a plain int (JSON, CSV).
        object.__setattr__(self, "count", int(self.count))

    def as_dict(self) -> dict[str, Any]:
        return {"what": self.what, "count": self.count, "why": self.why}

    def line(self) -> str:
        """One line for a terminal or a status bar."""
        n = f"{self.count} " if self.count != 1 else ""
        return f"lost: {n}{self.what}: {self.why}"


def loss_lines(losses: Iterable[Loss]) -> list[str]:
    return [loss.line() for loss in losses]
