r"""Time-correlated shadowing turned into a two-state (Gilbert–Elliott) arrival process.

The shadowing X_t (dB) of the sample periods t = 0, 1, … is a stationary Gaussian AR(1)
process with standard deviation σ and the exponential autocorrelation of Gudmundson's model
(M. Gudmundson, "Correlation model for shadow fading in mobile radio systems", Electronics
Letters 27(23), 1991):

.. math:: \rho = \mathrm{corr}(X_t, X_{t+1}) = e^{-v T_s / d_c}
          \quad\text{or}\quad \rho = e^{-T_s / T_c},

with d_c the correlation distance (m) at speed v (m/s), or T_c the coherence time (the
e-folding time of the autocorrelation), and T_s the sample period.

Thresholding: a sample period delivers its update iff s_0 + X_t ≥ s*, the *effective required
SINR* s*, chosen so that the stationary arrival probability of the thresholded process equals the
shadowing average p̄ = E_X[p(s_0 + X)] of the link (retries included):
P(s_0 + X ≥ s*) = p̄, i.e. a* = (s* − s_0)/σ = Φ^{-1}(1 − p̄). For a step-shaped PER curve s* is
exactly the required SINR; for a real curve the thresholding treats the packet-level randomness
within a shadowing state as part of the state (a two-state approximation).

Two-state Markov approximation: with Z_t = X_t/σ and α = √((1 − ρ)/(1 + ρ)), the probability of
a crossing from good to bad between consecutive periods is (Owen's T function)

.. math:: q = P(Z_t \ge a^*, Z_{t+1} < a^*) = \Phi(a^*) - \Phi_2(a^*, a^*; \rho)
          = 2\,T(a^*, \alpha),

so the failure rate f = q / (1 − Φ(a*)) and the recovery rate r = q / Φ(a*) of the
Gilbert–Elliott chain (f = P(lost next | received now), r = P(received next | lost now)). The
chain has the right stationary law r/(f + r) = 1 − Φ(a*) = p̄ and the right one-step
transition probabilities; it ignores the longer memory of the AR(1) process (the sojourn times
of a thresholded Gaussian process are not exactly geometric). For ρ = 0, f = Φ(a*) and
r = 1 − Φ(a*), f + r = 1: i.i.d. arrivals with probability p̄.

The shadowing averages E_X[p(s + X)] themselves are trapezoid sums on a fixed grid in
z = X/σ (:func:`shadowing_grid`, :func:`shadowing_averages`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.typed import to_json
from kfcrit.link.fields import mapping_field, real_field
from kfcrit.model.channels import check_keys
from kfcrit.records.channel import ShadowingCorrelationRecord, ShadowingMarkovRecord


@dataclass(frozen=True)
class ShadowingCorrelation:
    """How fast the shadowing changes between sample periods.

    Either ``coherence_time_s`` T_c, or ``correlation_distance_m`` d_c with ``speed_mps`` v;
    ``sample_period_s`` T_s is always needed.
    """

    sample_period_s: float
    coherence_time_s: float | None = None
    correlation_distance_m: float | None = None
    speed_mps: float | None = None

    KEYS = ("sample_period_s", "coherence_time_s", "correlation_distance_m", "speed_mps")

    @classmethod
    def from_mapping(cls, value: Any, prefix: str) -> ShadowingCorrelation:
        data = mapping_field(value, prefix)
        check_keys(data, set(cls.KEYS), {"sample_period_s"}, prefix)
        ts = real_field(data, "sample_period_s", prefix, low=0, high=1e6, low_open=True)
        if "coherence_time_s" in data:
            for key in ("correlation_distance_m", "speed_mps"):
                if key in data:
                    raise InputError("give either coherence_time_s or correlation_distance_m "
                                     "with speed_mps, not both", field=f"{prefix}.{key}")
            return cls(ts, coherence_time_s=real_field(data, "coherence_time_s", prefix, low=0,
                                                       high=1e9, low_open=True))
        for key in ("correlation_distance_m", "speed_mps"):
            if key not in data:
                raise InputError("is required (or give coherence_time_s)",
                                 field=f"{prefix}.{key}")
        return cls(ts, correlation_distance_m=real_field(data, "correlation_distance_m", prefix,
                                                         low=0, high=1e7, low_open=True),
                   speed_mps=real_field(data, "speed_mps", prefix, low=0, high=1e4))

    @property
    def correlation(self) -> float:
        r"""ρ = exp(−v T_s / d_c) or exp(−T_s / T_c)."""
        if self.coherence_time_s is not None:
            return math.exp(-self.sample_period_s / self.coherence_time_s)
        return math.exp(-self.speed_mps * self.sample_period_s / self.correlation_distance_m)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())

    def record(self) -> ShadowingCorrelationRecord:
        """The shadowing correlation as the record states it (``channel.shadowing_correlation``)."""
        formula = ("rho = exp(-T_s / T_c)" if self.coherence_time_s is not None
                   else "rho = exp(-v T_s / d_c) (Gudmundson 1991)")
        return ShadowingCorrelationRecord(
            sample_period_s=self.sample_period_s, coherence_time_s=self.coherence_time_s,
            correlation_distance_m=self.correlation_distance_m, speed_mps=self.speed_mps,
            correlation=self.correlation, formula=formula)


@dataclass(frozen=True)
class ShadowingMarkov:
    """The Gilbert–Elliott approximation of thresholded AR(1) shadowing (module docstring)."""

    correlation: float
    threshold_z: float
    failure_rate: float
    recovery_rate: float

    @property
    def stationary_arrival_probability(self) -> float:
        """r / (f + r) = 1 − Φ(a*)."""
        from scipy.special import ndtr

        return float(ndtr(-self.threshold_z))

    @property
    def mean_burst_length(self) -> float:
        """1 / r sample periods."""
        return 1.0 / self.recovery_rate if self.recovery_rate > 0 else math.inf

    def record(self) -> ShadowingMarkovRecord:
        """The chain as the record states it (``gilbert_elliott``; an infinite mean burst
        length, r = 0, is null)."""
        burst = self.mean_burst_length
        return ShadowingMarkovRecord(
            correlation=self.correlation, threshold_z=self.threshold_z,
            failure_rate=self.failure_rate, recovery_rate=self.recovery_rate,
            stationary_arrival_probability=self.stationary_arrival_probability,
            mean_burst_length=burst if math.isfinite(burst) else None,
            formula="q = 2 T(a*, sqrt((1 - rho)/(1 + rho))), f = q / (1 - Phi(a*)), "
                    "r = q / Phi(a*), a* = Phi^-1(1 - p_mean)",
            assumption="two-state Markov approximation of Gaussian AR(1) shadowing "
                       "thresholded at the effective required SINR")

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


def markov_from_threshold(correlation: float, threshold_z: float) -> ShadowingMarkov:
    r"""f and r of the AR(1) process with correlation ρ thresholded at a* (in units of σ).

    .. math:: q = 2\,T\!\left(a^*, \sqrt{\tfrac{1-\rho}{1+\rho}}\right),\quad
              f = \frac{q}{1 - \Phi(a^*)},\quad r = \frac{q}{\Phi(a^*)}
    """
    rho = float(correlation)
    if not -1.0 < rho < 1.0:
        raise ValueError("the correlation must lie in (-1, 1)")
    a = float(threshold_z)
    alpha = math.sqrt((1.0 - rho) / (1.0 + rho))
    from scipy.special import ndtr, owens_t

    q = 2.0 * float(owens_t(a, alpha))
    good, bad = float(ndtr(-a)), float(ndtr(a))
    f = min(1.0, q / good) if good > 0 else 1.0
    r = min(1.0, q / bad) if bad > 0 else 1.0
    return ShadowingMarkov(rho, a, f, r)


def markov_from_mean_arrival(correlation: float, mean_arrival: float) -> ShadowingMarkov:
    """:func:`markov_from_threshold` at a* = Φ^{-1}(1 − p̄) (the stationary law matches p̄)."""
    p = min(max(float(mean_arrival), 1e-300), 1.0 - 1e-16)
    from scipy.special import ndtri

    return markov_from_threshold(correlation, float(ndtri(1.0 - p)))


# ---------------------------------------------------------------------------------------------
# Shadowing averages E_X[p(s + X)] (the grid of the trapezoid rule)
# ---------------------------------------------------------------------------------------------

Z_RANGE = 9.0
"""Shadowing averages integrate the standard normal over [−9, 9] (mass outside < 1e-18)."""


@lru_cache(maxsize=64)
def shadowing_grid(step: float) -> tuple[np.ndarray, np.ndarray]:
    r"""The trapezoid grid of a shadowing average and the normal density on it (read-only).

    .. math:: z_i = -9 + i\,\frac{18}{N - 1},\quad N = 2\lceil 9/h \rceil + 1,\qquad
              w_i = \frac{e^{-z_i^2/2}}{\sqrt{2\pi}}

    Parameters
    ----------
    step : float
        The largest step h in z.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        z and φ(z); computed once per step (a pure function of it).
    """
    count = 2 * math.ceil(Z_RANGE / step) + 1
    z = np.linspace(-Z_RANGE, Z_RANGE, count)
    weights = np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)
    z.setflags(write=False)
    weights.setflags(write=False)
    return z, weights


@lru_cache(maxsize=64)
def shadowing_steps(step: float) -> np.ndarray:
    """z_{i+1} − z_i on the grid of :func:`shadowing_grid` (read-only; once per step)."""
    dz = np.diff(shadowing_grid(step)[0])
    dz.setflags(write=False)
    return dz


def shadowing_averages(values: np.ndarray, step: float) -> list[float]:
    r"""The trapezoid rule of shadowing averages on the grid of :func:`shadowing_grid`.

    .. math:: \bar p = \min\Bigl(1, \sum_i \frac{z_{i+1} - z_i}{2}
              \bigl(p_i w_i + p_{i+1} w_{i+1}\bigr)\Bigr)

    The floating-point operations of ``numpy.trapezoid(values * w, z)``, with the steps of the
    grid computed once. ``values`` holds p on the grid, one row per average (a single
    average: a 1-D array); each row's sum is that row's alone, so an average computed with
    others has the bits it has alone.
    """
    _, weights = shadowing_grid(step)
    y = values * weights
    terms = shadowing_steps(step) * (y[..., 1:] + y[..., :-1]) / 2.0
    return [float(min(1.0, row.sum())) for row in np.atleast_2d(terms)]
