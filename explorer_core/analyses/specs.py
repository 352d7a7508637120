"""What the builders of analysis specs share: the option a refused value belongs to.

A builder (:func:`~explorer_core.analyses.continuation.continuation_spec`,
:func:`~explorer_core.analyses.lyapunov.lyapunov_spec`, :func:`~explorer_core.analyses.drift.drift_spec`)
checks its options one after the other inside ``with Checking() as at:``, calling ``at("periods")`` before
the checks of ``periods``. A :class:`ParameterError` raised meanwhile gets that keyword as ``exc.option``
(unless it has one already): the message names the value in the analysis' words, and a caller with its own
names for the options (the CLI's flags) can say which of them was refused.
"""

from __future__ import annotations

from collections.abc import Callable
from types import TracebackType
from typing import Any, TypeVar

from explorer_core.system.params import ParameterError

S = TypeVar("S")


class Checking:
    """Tags a :class:`ParameterError` raised inside the ``with`` block with the option being checked."""

    def __init__(self) -> None:
        self.option: str | None = None

    def __call__(self, option: str) -> None:
        self.option = option

    def __enter__(self) -> Checking:
        return self

    def __exit__(self, kind: type | None, exc: BaseException | None, tb: TracebackType | None) -> bool:
        if isinstance(exc, ParameterError) and getattr(exc, "option", None) is None:
            exc.option = self.option  # type: ignore[attr-defined]
        return False


def spec_of(kind: type[S], build: Callable[..., S], first: Any, args: tuple, kw: dict[str, Any]) -> S:
    """The spec an analysis is called with: ``first`` itself when it is a ``kind`` (which comes alone), else the
    one ``build`` makes of the keyword form's arguments ``build(first, *args, **kw)``."""
    if not isinstance(first, kind):
        return build(first, *args, **kw)
    if args or kw:
        given = ", ".join(map(repr, args)) or ", ".join(kw)
        raise TypeError(f"a {kind.__name__} comes alone, not with {given}")
    return first
