"""Analyses of the system, one per module, each using only the solving floor and the executors passed in:
equilibria of the frozen field, ``T'`` maps, Lyapunov spectra, parameter sweeps, orbit diagrams, charts of
regimes, drift fits, the symmetry check and the run-time reliability checks.
"""
