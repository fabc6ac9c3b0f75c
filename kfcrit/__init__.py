"""kfcrit — will a Kalman filter stay stable over a lossy link, and by how much margin?

Public API: :class:`System`, :func:`load_system`, :func:`load_spec`, :func:`analyze`,
:func:`critical_value`, :func:`upper_bound`, :func:`simulate`. The numerical modules (cvxpy,
matplotlib, …) are imported lazily, on first use, so that ``kfcrit --help`` and input errors
answer at once.
"""
from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

from .analysis import Analysis, AnalysisOptions, analyze  # noqa: E402
from .errors import ExitCode, KfcritError  # noqa: E402
from .system import System  # noqa: E402
from .systemfile import SystemSpec, load_spec, load_system  # noqa: E402

_LAZY = {"critical_value": "critical", "upper_bound": "upper", "simulate": "montecarlo",
         "covariance_bounds": "bounds"}


def __getattr__(name: str) -> Any:
    """Import :func:`critical_value`, :func:`upper_bound`, :func:`simulate` on first use."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'kfcrit' has no attribute {name!r}")


__all__ = ["Analysis", "AnalysisOptions", "ExitCode", "KfcritError", "System", "SystemSpec",
           "__version__", "analyze", "covariance_bounds", "critical_value", "load_spec",
           "load_system", "simulate", "upper_bound"]
