"""kfcrit — will a Kalman filter stay stable over a lossy link, and by how much margin?

Public API: :class:`System`, :func:`load_system`, :func:`load_spec`, :func:`analyze`,
:func:`critical_value`, :func:`upper_bound`, :func:`simulate`.
"""
from __future__ import annotations

__version__ = "0.1.0"

from .analysis import Analysis, AnalysisOptions, analyze  # noqa: E402
from .errors import ExitCode, KfcritError  # noqa: E402
from .system import System  # noqa: E402
from .systemfile import SystemSpec, load_spec, load_system  # noqa: E402

__all__ = ["Analysis", "AnalysisOptions", "ExitCode", "KfcritError", "System", "SystemSpec",
           "__version__", "analyze", "load_spec", "load_system"]
