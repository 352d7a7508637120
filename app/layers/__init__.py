"""The layers of the section plot: each one small module, a :class:`~app.layers.base.Layer` the controller
(:class:`app.controller.ExplorerSession`) drives alike. :data:`LAYERS` are those of every session, in the
order they start; a new layer is one module with a ``Layer`` subclass, added here (or passed to the session).
"""

from __future__ import annotations

from app.layers.base import KEEP, Host, Layer
from app.layers.basins import BasinsLayer
from app.layers.frozen import TPrimeLayer, TracksLayer
from app.layers.manifolds import ManifoldsLayer
from app.layers.orbits import OrbitsLayer

#: The phase-plane layers over the section, in the order they start (the section itself comes first).
LAYERS: tuple[type[Layer], ...] = (OrbitsLayer, ManifoldsLayer, BasinsLayer, TracksLayer, TPrimeLayer)

__all__ = ["KEEP", "LAYERS", "BasinsLayer", "Host", "Layer", "ManifoldsLayer", "OrbitsLayer", "TPrimeLayer",
           "TracksLayer"]  # fmt: skip
