"""What a control and a URL key are, and the parsers they share: the words the state and the layers declare
their settings in.

The state (:mod:`app.state`) holds the table of every control and URL key: its own (the system, the numerics, the
analysis tabs) and each layer's (:attr:`app.layers.base.Layer.controls`, ``picks`` and ``urls``). The layers
declare theirs with the classes here, so that the state can import the layers without the layers importing the
state.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from explorer_core.solve.checks import parse_finite
from explorer_core.system.params import INERTIA_NAMES, ParameterError

#: Largest magnitude of a swept parameter or a typed initial condition (beyond, nothing is meaningful).
MAX_MAGNITUDE = 1e6
#: The section plot's size in pixels on a large screen, the one place it is set: the density image's pixels,
#: the manifolds' refinement (segments of at most 3 of them) and the 'plot' tolerance (a quarter pixel) use it.
PLOT_PIXELS = (800, 600)
#: The state fields of the system (what :meth:`app.state.ExplorerState.system` validates).
SYSTEM_FIELDS = (*INERTIA_NAMES, "alpha", "g0", "g1", "g2", "omega", "t0")


def fmt(v: float) -> str:
    """A number as the page and the URL show it (a whole number without its ``.0``)."""
    return repr(float(v)) if v != int(v) or abs(v) >= 1e15 else str(int(v))


def finite(name: str, text: str) -> float:
    return parse_finite(name, text)


def whole(name: str, text: str, lo: int, hi: int) -> int:
    t = str(text).strip()
    try:
        v = int(t)
    except ValueError:
        try:  # "12.0" and "1e3" are whole numbers too; "1.5" is not
            f = float(t)
        except (ValueError, OverflowError):
            f = math.nan
        if not (math.isfinite(f) and f == int(f)):
            raise ParameterError(f"{name} must be a whole number, got {t[:40]!r}") from None
        v = int(f)
    if not lo <= v <= hi:
        raise ParameterError(f"{name} must be between {lo} and {hi}, got {t if len(t) <= 40 else t[:40] + '…'}")
    return v


def numbers(name: str, text: str, n: int, what: str) -> tuple[float, ...]:
    parts = str(text).split(",")
    if len(parts) != n:
        raise ParameterError(f"{name} needs {n} comma-separated numbers ({what}), got {str(text)[:60]!r}")
    return tuple(finite(name, p.strip()) for p in parts)


@dataclass(frozen=True)
class Control:
    """One input of the page: how it is drawn, parsed, shown and carried in the URL.

    ``kind``: ``float`` (a slider with a number box), ``int``, ``select``, ``radio``,
    ``check`` or ``text`` (parsed by ``parse``). ``area`` says where it is drawn: a
    sidebar group, the section tab's bar, or an analysis tab.
    """

    name: str
    label: str
    kind: str
    area: str
    url: str | None = None
    bounds: tuple[float, float] | None = None  # int: inclusive bounds; float: the slider's range
    step: float | None = None
    options: tuple[tuple[str, str], ...] = ()  # (value, label) for select/radio
    parse: Callable[[str, str], Any] | None = None  # text kinds: (name, text) -> value
    placeholder: str = ""
    help: str = ""
    #: The value of a new session (before a scene sets it) and the state's ``param`` attribute's default.
    default: Any = None
    #: When the URL carries the value: "always", or "changed" (only when it differs from ``default``), or a
    #: predicate of the state.
    url_when: str | Callable[[Any], bool] = "always"
    doc: str | None = None


def ints(name: str, label: str, area: str, url: str, lo: int, hi: int, default: int, help: str = "",
         url_when: str | Callable[[Any], bool] = "always") -> Control:  # fmt: skip
    """A whole-number control with inclusive bounds ``lo..hi``."""
    return Control(name, label, "int", area, url, (lo, hi), help=help, default=default, url_when=url_when)


@dataclass(frozen=True)
class UrlKey:
    """One URL query parameter: the state fields it carries, when it is written, how it is written and read,
    and its words in messages ("the picture is for q range = …"). ``encode`` and ``when`` get the state
    (:class:`app.state.ExplorerState`)."""

    key: str
    fields: tuple[str, ...]
    encode: Callable[[Any], str]
    decode: Callable[[str], dict[str, Any]]  # text -> state updates; ParameterError naming the bad value
    when: Callable[[Any], bool] = lambda s: True  # written only when this says so
    words: str = ""


def places(key: str, text: str, most: int, what: str, n: int, fields: str) -> list[tuple[float, ...]]:
    """``;``-separated points of a URL value (``n`` numbers each, the first two ``q, r`` within
    ±MAX_MAGNITUDE), at most ``most`` of them."""
    parts = [p for p in text.split(";") if p.strip()]
    if len(parts) > most:
        raise ParameterError(f"at most {most} {what}, got {len(parts)}")
    out = [numbers(key, p, n, fields) for p in parts]
    for p, v in zip(parts, out, strict=True):
        if max(abs(v[0]), abs(v[1])) > MAX_MAGNITUDE:
            raise ParameterError(f"{what} must lie within ±{MAX_MAGNITUDE:g}, got {p.strip()[:40]!r}")
    return out


def points_text(points: list[tuple[float, ...]]) -> str:
    """Points as a URL value: ``q,r[,n];...`` (the inverse of :func:`places`)."""
    return ";".join(",".join(fmt(v) if i < 2 else str(v) for i, v in enumerate(p)) for p in points)


def choice(options: Mapping[str, dict[str, Any]]) -> Callable[[str], dict[str, Any]]:
    """A URL value's decoder: one of ``options``' keys, read as the state updates it stands for."""

    def decode(t: str) -> dict[str, Any]:
        if t not in options:
            raise ParameterError(f"must be one of {', '.join(options)}, got {t[:40]!r}")
        return dict(options[t])

    return decode


__all__ = ["MAX_MAGNITUDE", "PLOT_PIXELS", "SYSTEM_FIELDS", "Control", "UrlKey", "choice", "finite", "fmt", "ints",
           "numbers", "places", "points_text", "whole"]  # fmt: skip
