"""Payloads of the ``system`` and ``provenance`` sections: exact matrices, the continuous-time
model, the sensors of a network file, the analysis options.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.records.channel import ChannelRecord


@dataclass(frozen=True, kw_only=True)
class Matrices:
    """`system.matrices`"""

    A: list[list[str]]
    C: list[list[str]]
    Q: list[list[str]]
    R: list[list[str]]
    Sigma0: list[list[str]]


@dataclass(frozen=True, kw_only=True)
class ContinuousModel:
    """`system.continuous`"""

    A: list[list[str]]
    Q: list[list[str]]
    sampling_time: str
    method: str
    exact: bool
    reason: str
    error_bound: float | None


@dataclass(frozen=True, kw_only=True)
class SensorRecord:
    """`system.sensors[]`"""

    name: str
    m: int
    C: list[list[str]]
    R: list[list[str]]
    channel: ChannelRecord | None
    position_m: list[float | None] | None


@dataclass(frozen=True, kw_only=True)
class AnalysisOptionsRecord:
    """`provenance.options`"""

    tolerance: float | None
    upper_tol: float | None
    simulate: bool
    quick: bool
    seed: int
    paths: int | None
    steps: int | None
    details: bool
