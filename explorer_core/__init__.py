"""Bilimovich Explorer core: the model, the one integration engine and the analyses (no UI imports).

Layers, each importing only those below it (docs/architecture.md): ``system`` -> ``solve`` ->
``scenes`` -> ``parallel`` -> ``analyses`` -> ``studies`` -> ``reports`` -> ``warm``, ``cli``.
"""

__all__ = ["Model", "ParameterError", "Params"]
__version__ = "0.1.0"


def __getattr__(name: str):
    # Model pulls in numba (~0.4 s) and Params numpy (~0.1 s): only when asked for, so that the console script
    # (explorer_core.launch) holds its signal handlers before any heavy import.
    if name == "Model":
        from explorer_core.system.model import Model

        return Model
    if name in ("Params", "ParameterError"):
        from explorer_core.system import params

        return getattr(params, name)
    raise AttributeError(f"module 'explorer_core' has no attribute {name!r}")
