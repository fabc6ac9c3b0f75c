"""The channel as the record states it: a Bernoulli, Gilbert–Elliott, trace or link-budget
channel (``ChannelRecord``, one class whose keys depend on ``model``) and the network
operating point's per-sensor channels (``NetworkChannel``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import sympy as sp

from kfcrit.io.typed import opt_key


@dataclass(frozen=True, kw_only=True)
class RadioFrameRecord:
    """`@RadioFrame`"""

    standard: str
    mac_overhead_bytes: int | None
    phy_header_bytes: int | None
    max_psdu_bytes: int | None
    bit_rate_bps: float | None
    max_retries: int | None
    ack_wait_s: float | None


@dataclass(frozen=True, kw_only=True)
class RadioRecord:
    """`@Radio`"""

    model: str
    formula: str
    source: str
    implementation_loss_db: float | None = opt_key()
    frame: RadioFrameRecord
    sensitivity_dbm: float | None = opt_key()
    reference_per: float | None = opt_key()
    reference_psdu_bytes: int = opt_key()
    reference_noise_dbm: float | None = opt_key()
    datasheet: str = opt_key()
    processing_gain_db: float | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class PathLossRecord:
    """`@Channel.path_loss`"""

    model: str
    exponent: float | None = opt_key()
    reference_distance_m: float | None = opt_key()
    reference_loss_db: float | None = opt_key()
    formula: str
    shadowing_sigma_db: float | None
    shadowing: str
    frequency_hz: float | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class NoiseRecord:
    """`@Channel.noise`"""

    noise_floor_dbm: float | None
    bandwidth_hz: float | None
    noise_figure_db: float | None
    temperature_k: float | None
    interference_dbm: float | None
    noise_plus_interference_dbm: float | None


@dataclass(frozen=True, kw_only=True)
class FrameRecord:
    """`@Frame`"""

    payload_bytes: int
    mac_overhead_bytes: int
    psdu_bytes: int
    phy_header_bytes: int | None
    ppdu_bytes: int | None
    max_psdu_bytes: int | None
    max_payload_bytes: int | None
    standard: str
    per_covers: str
    definition: str
    airtime_s: float | None
    max_retries: int
    max_retries_allowed: int | None
    attempts_duration_s: float | None
    retry_formula: str
    retry_assumption: str
    per_bytes: int = opt_key()
    per_over: str = opt_key()
    fading_per_attempt: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class ShadowingCorrelationRecord:
    """`@Channel.shadowing_correlation`"""

    sample_period_s: float | None
    coherence_time_s: float | None
    correlation_distance_m: float | None
    speed_mps: float | None
    correlation: float | None
    formula: str


@dataclass(frozen=True, kw_only=True)
class ShadowingMarkovRecord:
    """`@Channel.gilbert_elliott`"""

    correlation: float | None
    threshold_z: float | None
    failure_rate: float | None
    recovery_rate: float | None
    stationary_arrival_probability: float | None
    mean_burst_length: float | None
    formula: str
    assumption: str


@dataclass(frozen=True, kw_only=True)
class FadingRecord:
    """`@Channel.fading`"""

    model: str
    m: float | None


@dataclass(frozen=True, kw_only=True)
class ChannelRecord:
    """`@Channel`"""

    model: str
    arrival_probability: float | None
    arrival_probability_expression: str
    radio: RadioRecord = opt_key()
    tx_power_dbm: float | None = opt_key()
    distance_m: float | None = opt_key()
    packet_bytes: int = opt_key()
    antenna_gain_db: float | None = opt_key()
    path_loss: PathLossRecord = opt_key()
    noise: NoiseRecord = opt_key()
    margin_db: float | None = opt_key()
    max_outage: float | None = opt_key()
    max_retries: int = opt_key()
    frame: FrameRecord = opt_key()
    shadowing_correlation: ShadowingCorrelationRecord | None = opt_key()
    gilbert_elliott: ShadowingMarkovRecord | None = opt_key()
    sinr_db: float | None = opt_key()
    arrival_probability_basis: str = opt_key()
    path: str = opt_key()
    length: int = opt_key()
    failure_rate: float | None = opt_key()
    recovery_rate: float | None = opt_key()
    mean_burst_length: float | None = opt_key()
    per_over: str = opt_key()
    fading_per_attempt: str = opt_key()
    fading: FadingRecord = opt_key()
    coherence_time_s: float | None = opt_key()
    """Shadowing coherence time of correlated retries (``fading_per_attempt: correlated``)."""
    format: str = opt_key()
    """A trace's file format (theory §14)."""
    confidence: float | None = opt_key()
    """The confidence level of a trace's verdict (theory §14)."""
    sensor: str = opt_key()
    period_s: str = opt_key()
    """A receive log's sampling period as written in the file (exact decimal text)."""


@dataclass(frozen=True, kw_only=True)
class NetworkChannelSensor:
    """`@NetworkChannel.sensors[]`"""

    name: str
    channel: ChannelRecord | None


@dataclass(frozen=True, kw_only=True)
class NetworkChannel:
    """`@NetworkChannel`"""

    model: str
    sensors: list[NetworkChannelSensor]


@dataclass(frozen=True, kw_only=True)
class MeshChannel:
    """`@MeshChannel`: the channel of a mesh file's operating point (the hops are in ``mesh``)."""

    model: str
    relay_mode: str
    slots_per_period: int | None
    routing: str


def channel_record(channel: Any) -> ChannelRecord | None:
    r"""The record's typed form of a model channel (``None`` for none), built field by field.

    A Bernoulli, Gilbert–Elliott or trace channel is a model object (the layer below); a link
    budget states its own record (``channel.record()``, the link layer). Exact numbers are
    written as floats and as exact text (``arrival_probability_expression``).

    .. math::  \bar p = r / (f + r) \quad\text{(Gilbert–Elliott, stationary)}

    Raises
    ------
    TypeError
        A channel of a kind the record does not know.
    """
    if channel is None:
        return None
    if hasattr(channel, "record"):
        return channel.record()
    model = channel.model
    p = channel.arrival_probability
    common = {"model": model, "arrival_probability": float(p),
              "arrival_probability_expression": sp.sstr(p)}
    if model == "bernoulli":
        return ChannelRecord(**common)
    if model == "gilbert-elliott":
        return ChannelRecord(**common, failure_rate=float(channel.failure_rate),
                             recovery_rate=float(channel.recovery_rate),
                             mean_burst_length=float(1 / channel.recovery_rate))
    if model == "trace":
        extra = {k: getattr(channel, k) for k in ("sensor", "period_s")
                 if getattr(channel, k) is not None}
        return ChannelRecord(**common, path=channel.path, length=int(channel.arrivals.size),
                             format=channel.format, confidence=_float_or_none(
                                 channel.confidence), **extra)
    raise TypeError(f"channel model {model!r} has no record form")


def _float_or_none(value: Any) -> float | None:
    return None if value is None else float(value)
