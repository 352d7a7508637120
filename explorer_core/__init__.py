"""Bilimovich Explorer core: the model, the one integration engine and the analyses (no UI imports).

Layers, each importing only those below it (docs/architecture.md): ``system`` -> ``solve`` ->
``scenes`` -> ``parallel`` -> ``analyses`` -> ``studies`` -> ``reports`` -> ``warm``, ``cli``.
"""

from explorer_core.system.params import ParameterError, Params

__all__ = ["Model", "ParameterError", "Params"]
__version__ = "0.1.0"


def __getattr__(name: str):
    # Model pulls in numba (~0.4 s): only when asked for, so `bilimovich --help` starts at once.
    if name == "Model":
        from explorer_core.system.model import Model

        return Model
    raise AttributeError(f"module 'explorer_core' has no attribute {name!r}")
