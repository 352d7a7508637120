"""The system: its parameters (:mod:`.params`) and the reduced field with its exact coefficient tables (:mod:`.model`).

The bottom floor: imports nothing of the package but :mod:`explorer_core.config`.
"""
