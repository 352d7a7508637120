"""Results that draw themselves: ``result.to_holoviews()``, with the drawers kept out of the core.

The core is numpy/numba/scipy only and never imports the app, so it cannot draw. Each result class
mixes in :class:`Drawable`; ``to_holoviews`` looks up the drawer registered for its type. Drawers are
registered by :func:`register` (``app.holo`` registers all of them when imported) or found on first use
through the package entry point group :data:`ENTRY_POINT_GROUP` (the explorer's own points at
``app.holo:register``), as pandas finds its plotting backends (hvplot): the core names no module of the app.
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from typing import Any

#: Entry point group of drawing backends: each entry is a callable that registers its drawers.
ENTRY_POINT_GROUP = "bilimovich_explorer.drawing"
#: What to install for the explorer's own drawers (named in the error when none is found).
INSTALL_HINT = "pip install holoviews (the drawers are the explorer's app.holo: `import app.holo` registers them)"

Drawer = Callable[..., Any]
_DRAWERS: dict[type, Drawer] = {}
#: Entry points already tried, and why each failed (a backend missing its own dependency, e.g. holoviews).
_LOADED = False
_LOAD_ERRORS: list[str] = []


class NoDrawerError(LookupError):
    """No drawer is registered for a result's type (HoloViews or the drawing backend is not installed)."""


def register(cls: type, drawer: Drawer) -> None:
    """``drawer(result, **opts)`` draws instances of ``cls`` (and of its subclasses without a drawer of their own)."""
    if not isinstance(cls, type):
        raise TypeError(f"register needs a class, got {cls!r}")
    if not callable(drawer):
        raise TypeError(f"the drawer of {cls.__name__} must be callable, got {drawer!r}")
    _DRAWERS[cls] = drawer


def _lookup(cls: type) -> Drawer | None:
    for base in cls.__mro__:
        if base in _DRAWERS:
            return _DRAWERS[base]
    return None


def load_entry_points() -> list[str]:
    """Call every registered backend of :data:`ENTRY_POINT_GROUP` once; returns the failures (also kept)."""
    global _LOADED
    if _LOADED:
        return list(_LOAD_ERRORS)
    _LOADED = True
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            ep.load()()
        except ImportError as exc:  # the backend's own dependency is missing: said in the error if nothing draws
            _LOAD_ERRORS.append(f"{ep.name} ({ep.value}): {exc}")
    return list(_LOAD_ERRORS)


def drawer_for(cls: type) -> Drawer:
    """The drawer of ``cls``: registered, else loaded through the entry points; NoDrawerError saying what to install."""
    drawer = _lookup(cls)
    if drawer is None:
        load_entry_points()
        drawer = _lookup(cls)
    if drawer is None:
        tried = "; ".join(_LOAD_ERRORS)
        why = f" (entry points that failed to load: {tried})" if tried else ""
        raise NoDrawerError(
            f"{cls.__name__}.to_holoviews() needs a drawer and none is registered for {cls.__name__}{why}: "
            f"{INSTALL_HINT}"
        )
    return drawer


def draw(result: Any, **opts: Any) -> Any:
    """The HoloViews object of ``result`` (its type's drawer called with ``opts``)."""
    return drawer_for(type(result))(result, **opts)


class Drawable:
    """Mixin of the result classes: ``to_holoviews(**opts)`` draws the result with its registered drawer."""

    __slots__ = ()

    def to_holoviews(self, **opts: Any) -> Any:
        """A HoloViews element or overlay of this result; compose with ``*`` (overlay) and ``+`` (layout)."""
        return draw(self, **opts)
