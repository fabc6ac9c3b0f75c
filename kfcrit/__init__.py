"""kfcrit — will a Kalman filter stay stable over a lossy link, and by how much margin?

Public API: :class:`System`, :func:`load_system`, :func:`load_spec`, :func:`analyze`,
:func:`critical_value`, :func:`upper_bound`, :func:`simulate`, :func:`from_statespace`, and the
channel models :class:`Bernoulli`, :class:`GilbertElliott`, :class:`Trace`, :class:`LinkBudget`. The
numerical modules (cvxpy, matplotlib, …) are imported lazily, on first use, so that
``kfcrit --help`` and input errors answer at once.
"""
from __future__ import annotations

from typing import Any

from kfcrit.errors import ExitCode, KfcritError  # noqa: E402
from kfcrit.version import __version__

# Everything else is imported on first use: ``kfcrit --help``, input errors and signals
# answer at once instead of after the ~1 s import of sympy, numpy and scipy.
_LAZY = {"Analysis": "api", "AnalysisOptions": "analysis.record",
         "analyze": "api", "sweep": "api", "SweepTable": "api", "System": "model.system",
         "SystemSpec": "io.systemfile",
         "load_spec": "analysis.spec", "load_system": "analysis.spec",
         "critical_value": "theory.critical.section", "upper_bound": "theory.upper.bracket",
         "simulate": "sim.montecarlo", "covariance_bounds": "theory.covariance.bounds",
         "from_continuous_statespace": "model.continuous", "sample": "model.continuous",
         "from_statespace": "model.continuous",
         "network_analysis": "theory.links.network",
         "Channel": "model.channels", "Bernoulli": "model.channels",
         "GilbertElliott": "model.channels", "Trace": "model.channels",
         "LinkBudget": "link.linkbudget"}


def __getattr__(name: str) -> Any:
    """Import the public API (:func:`analyze`, :class:`System`, …) on first use."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'kfcrit' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public API (what ``dir(kfcrit)`` and tab completion list)."""
    return sorted(set(__all__) | {"__version__"})


__all__ = ["Analysis", "AnalysisOptions", "ExitCode", "KfcritError", "System", "SystemSpec",
           "__version__", "analyze", "covariance_bounds", "critical_value", "load_spec",
           "load_system", "simulate", "upper_bound", "from_continuous_statespace", "sample",
           "network_analysis", "sweep", "SweepTable", "from_statespace", "Channel",
           "Bernoulli", "GilbertElliott", "Trace", "LinkBudget"]
