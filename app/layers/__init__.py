"""The layers of the section plot: each one small module, a :class:`~app.layers.base.Layer` the controller
(:class:`app.controller.ExplorerSession`) and the page drive alike. :data:`LAYERS` are those of every session, in the
order they start; a new layer is one module with a ``Layer`` subclass, added here (or passed to the session): its
controls, URL keys, published fields, page actions and CSV come with it (the state's tables take its settings).
"""

from __future__ import annotations

from app.layers.base import KEEP, Host, Layer
from app.layers.basins import BasinsLayer
from app.layers.frozen import TPrimeLayer
from app.layers.ftle import FtleLayer
from app.layers.manifolds import ManifoldsLayer
from app.layers.orbits import OrbitsLayer
from app.layers.rotation import RotationLayer
from app.layers.tracks import TracksLayer

#: The phase-plane layers over the section, in the order they start (the section itself comes first).
LAYERS: tuple[type[Layer], ...] = (OrbitsLayer, ManifoldsLayer, BasinsLayer, FtleLayer, TracksLayer, TPrimeLayer,
                                   RotationLayer)  # fmt: skip

__all__ = ["KEEP", "LAYERS", "BasinsLayer", "FtleLayer", "Host", "Layer", "ManifoldsLayer", "OrbitsLayer",
           "RotationLayer", "TPrimeLayer", "TracksLayer"]  # fmt: skip
