"""The registry of analyses: every analysis of the core, where its spec, builder, runner and result live, and the
nested options its spec carries. The command line and the contract tests read it; modules are imported only when
an entry is used (``bilimovich --help`` loads no numerics).

An entry names things by module and attribute, not by object, so reading the registry imports nothing. Every
analysis has a frozen spec and the builder that validates it (``tests/test_options.py``); its runner takes the spec
(or the builder's keywords).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Analysis:
    """One analysis.

    name : its name (the CLI command where there is one: ``command``).
    module : the module that holds it.
    run : the convenience call ``X(spec or keywords, progress=None, cancel=None)``.
    iterate : the generator ``iter_X`` (None: it reports no progress).
    builder, spec : the validating builder and the frozen spec it returns.
    result : the result type.
    nested : the spec's nested options: field name -> the options class's ``module:Name``.
    reference_rtol : the tolerance its defaults are set for (``module:NAME``), from which its nested Newton
        derives its map (:meth:`~explorer_core.solve.options.NewtonOptions.at`).
    """

    name: str
    module: str
    run: str
    result: str
    iterate: str | None = None
    builder: str | None = None
    spec: str | None = None
    command: str | None = None
    nested: dict[str, str] = field(default_factory=dict)
    reference_rtol: str | None = None

    def get(self, attr: str) -> Any:
        """An attribute of the analysis' module (``"run"``, ``"builder"``, ... or a name), imported now."""
        name = getattr(self, attr, None) if attr in {"run", "result", "iterate", "builder", "spec"} else attr
        if name is None:
            raise LookupError(f"the analysis {self.name!r} has no {attr}")
        return getattr(importlib.import_module(self.module), name)

    def nested_options(self) -> dict[str, type]:
        """The spec's nested options classes, imported now."""
        out = {}
        for name, path in self.nested.items():
            mod, _, cls = path.partition(":")
            out[name] = getattr(importlib.import_module(mod), cls)
        return out


_NEWTON = {"newton": "explorer_core.solve.options:NewtonOptions"}
_A = "explorer_core.analyses."

ANALYSES: dict[str, Analysis] = {
    a.name: a
    for a in (
        Analysis(
            "section",
            _A + "sections",
            "poincare_section",
            "AssessedSection",
            None,
            "section_spec",
            "SectionSpec",
            command="section",
        ),
        Analysis(
            "density",
            _A + "density",
            "density",
            "Density",
            "iter_density",
            "density_spec",
            "DensitySpec",
            command="density",
        ),
        Analysis(
            "equilibria",
            _A + "equilibria",
            "critical_points",
            "Tracks",
            "iter_equilibrium_tracks",
            "critical_spec",
            "CriticalSpec",
            command="critical",
        ),
        Analysis("tprime", _A + "tprime", "tprime", "TPrimeMap", None, "tprime_spec", "TPrimeSpec", command="tprime"),
        Analysis(
            "lyapunov",
            _A + "lyapunov",
            "lyapunov_spectrum",
            "LyapunovResult",
            "iter_lyapunov",
            "lyapunov_spec",
            "LyapunovSpec",
            command="lyapunov",
        ),
        Analysis(
            "bifurcation",
            _A + "bifurcation",
            "bifurcation_diagram",
            "OrbitDiagram",
            "iter_bifurcation_diagram",
            "diagram_spec",
            "DiagramSpec",
            command="bifurcation",
            nested=_NEWTON,
            reference_rtol=_A + "bifurcation:DIAGRAM_RTOL",
        ),
        Analysis(
            "orbits",
            _A + "orbits",
            "orbit_search",
            "OrbitSearch",
            "iter_orbit_search",
            "orbit_spec",
            "OrbitSpec",
            command="orbits",
            nested=_NEWTON,
        ),
        Analysis(
            "manifolds",
            _A + "manifolds",
            "manifolds",
            "Manifolds",
            "iter_manifolds",
            "manifold_spec",
            "ManifoldSpec",
            command="manifolds",
        ),
        Analysis(
            "continuation",
            _A + "continuation",
            "continue_orbit",
            "Continuation",
            "iter_continue_orbit",
            "continuation_spec",
            "ContinuationSpec",
            command="continue",
            nested={"options": _A + "continuation:ContinuationOptions"},
        ),
        Analysis(
            "continue_from_seeds",
            _A + "continuation",
            "continue_from_seeds",
            "Continuation",
            "iter_continue_from_seeds",
            "seeds_spec",
            "SeedsSpec",
            nested={"options": _A + "continuation:ContinuationOptions"},
        ),
        Analysis(
            "chart_boundaries",
            _A + "continuation",
            "chart_boundaries",
            "Boundaries",
            "iter_chart_boundaries",
            "boundaries_spec",
            "BoundariesSpec",
        ),
        Analysis(
            "chart",
            _A + "regimes",
            "regime_chart",
            "Chart",
            "iter_chart",
            "chart_spec",
            "ChartSpec",
            command="chart",
            nested=_NEWTON,
            reference_rtol=_A + "regimes:DEFAULT_CHART_TOL",
        ),
        Analysis(
            "basins",
            _A + "basins",
            "basins",
            "Basins",
            "iter_basins",
            "basin_spec",
            "BasinSpec",
            command="basins",
            nested=_NEWTON,
            reference_rtol=_A + "basins:DEFAULT_BASIN_TOL",
        ),
        Analysis(
            "drift", _A + "drift", "drift_fit", "DriftFit", "iter_drift_fit", "drift_spec", "DriftSpec", command="fit"
        ),
        Analysis(
            "body",
            _A + "body",
            "body_series",
            "BodySeries",
            "iter_body_series",
            "body_spec",
            "BodySpec",
            command="body",
        ),
        Analysis(
            "symmetry",
            _A + "symmetry",
            "check_symmetry",
            "SymmetryCheck",
            None,
            "symmetry_spec",
            "SymmetrySpec",
            command="symmetry",
        ),
        Analysis(
            "birkhoff",
            _A + "indicators",
            "birkhoff",
            "Birkhoff",
            "iter_birkhoff",
            "birkhoff_spec",
            "BirkhoffSpec",
            command="birkhoff",
        ),
        Analysis("sali", _A + "indicators", "sali", "Sali", "iter_sali", "sali_spec", "SaliSpec", command="sali"),
        Analysis("ftle", _A + "ftle", "ftle_map", "FtleMap", "iter_ftle", "ftle_spec", "FtleSpec", command="ftle"),
    )
}


def by_command(command: str) -> Analysis | None:
    """The analysis behind a CLI command (None: the command is no analysis: scenes, serve, bench, ...)."""
    return next((a for a in ANALYSES.values() if a.command == command), None)
