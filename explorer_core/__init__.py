"""Bilimovich Explorer core: the model, integrators and analyses (no UI imports)."""

from explorer_core.system.model import Model, ParameterError, Params

__all__ = ["Model", "ParameterError", "Params"]
__version__ = "0.1.0"
