"""The objects whose docstrings follow numpydoc with runnable examples (the public API of
``kfcrit.__all__`` and the theory entry points), shared by ``test_docstrings.py`` and
``test_doctests.py``."""
from __future__ import annotations

import importlib
from typing import Any

import kfcrit

THEORY_ENTRY_POINTS = (
    "kfcrit.theory.critical.section:critical_value",
    "kfcrit.theory.critical.section:critical_section",
    "kfcrit.theory.upper.bracket:upper_bound",
    "kfcrit.theory.covariance.bounds:covariance_bounds",
    "kfcrit.theory.covariance.bounds:lower_covariance",
    "kfcrit.theory.covariance.bounds:upper_covariance",
    "kfcrit.theory.covariance.bounds:mare_iteration",
    "kfcrit.theory.links.network:network_analysis",
    "kfcrit.theory.links.markov:burst_facts",
    "kfcrit.theory.mesh.law:mesh_law",
    "kfcrit.theory.mesh.stability:law_stability",
    "kfcrit.theory.mesh.stability:mesh_analysis",
    "kfcrit.theory.mesh.relaying:estimate_relaying",
    "kfcrit.theory.mesh.relaying:smart_sensor_critical_value",
    "kfcrit.theory.loop.thresholds:actuation_threshold",
    "kfcrit.theory.loop.thresholds:sensing_threshold",
    "kfcrit.theory.loop.tcp:tcp_loop",
    "kfcrit.theory.loop.stack:fixed_design",
    "kfcrit.theory.loop.fixed:mean_square_stability",
    "kfcrit.theory.loop.fixed:fixed_loop",
    "kfcrit.theory.loop.curve:loop_critical_curve",
    "kfcrit.sim.engine:simulate",
)

PUBLIC = tuple(f"kfcrit:{name}" for name in sorted(kfcrit.__all__) if name != "__version__")

DOCUMENTED = PUBLIC + THEORY_ENTRY_POINTS
"""Every object, as ``module:qualname``."""

NO_PARAMETERS = frozenset({"kfcrit:ExitCode", "kfcrit:Channel"})
"""Objects that take no parameters (an enum, an abstract base class): no Parameters section."""

NEEDS = {"kfcrit:from_continuous_statespace": "control", "kfcrit:from_statespace": "control"}
"""Optional packages an object's examples import (python-control: the ``control`` extra)."""


def resolve(spec: str) -> Any:
    """The object named by ``module:qualname``."""
    module, _, qual = spec.partition(":")
    obj: Any = importlib.import_module(module)
    for part in qual.split("."):
        obj = getattr(obj, part)
    return obj
