"""Physical constants and decibel conversions shared by the link modules."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

BOLTZMANN = 1.380649e-23
"""Boltzmann constant k_B in J/K (exact in the 2019 SI)."""
SPEED_OF_LIGHT = 299_792_458.0
"""c in m/s (exact)."""
REFERENCE_TEMPERATURE_K = 290.0
"""The standard noise temperature T0 (IEEE definition of the noise figure)."""


def db_to_linear(x_db: Any) -> Any:
    """10^(x/10)."""
    return np.power(10.0, np.asarray(x_db, dtype=float) / 10.0)


def linear_to_db(x: Any) -> Any:
    """10·log10(x)."""
    return 10.0 * np.log10(np.asarray(x, dtype=float))


def thermal_noise_dbm(bandwidth_hz: float, noise_figure_db: float = 0.0,
                      temperature_k: float = REFERENCE_TEMPERATURE_K) -> float:
    r"""Noise floor in dBm.

    .. math:: N = 10 \log_{10}(k_B T B / 1\,\mathrm{mW}) + NF

    (−173.98 dBm/Hz at 290 K).
    """
    return float(10.0 * math.log10(BOLTZMANN * temperature_k * bandwidth_hz * 1e3)
                 + noise_figure_db)
