"""Solving: methods as data (:mod:`.tableaus`), the one Runge-Kutta engine (:mod:`.rk`), batches and their
driver (:mod:`.integrators`), the tangent system (:mod:`.tangent`), settings and input checks
(:mod:`.numerics`), the stroboscopic section (:mod:`.section`) and step-size limits (:mod:`.stability`).

Imports only :mod:`explorer_core.system` and :mod:`explorer_core.config`.
"""
