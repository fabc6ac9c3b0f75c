"""Payloads of the ``system`` and ``provenance`` sections: exact matrices, the continuous-time
model, the sensors of a network file, the analysis options.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import sympy as sp

from kfcrit.records.channel import ChannelRecord, channel_record


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


def _text(M: Any) -> list[list[str]]:
    """An exact sympy matrix as rows of exact text."""
    return [[sp.sstr(e) for e in M.row(i)] for i in range(M.shape[0])]


def continuous_record(model: Any) -> ContinuousModel:
    r"""``system.continuous``: how a continuous-time model was sampled (exact text).

    .. math::  A = e^{A_c T}, \quad Q = \int_0^T e^{A_c s} Q_c e^{A_c' s}\,ds
    """
    return ContinuousModel(A=_text(model.A_c), Q=_text(model.Q_c),
                           sampling_time=sp.sstr(model.sampling_time), method=model.method,
                           exact=bool(model.exact), reason=model.reason,
                           error_bound=None if model.error_bound is None
                           else float(model.error_bound))


def sensor_records(network: Any) -> list[SensorRecord]:
    """``system.sensors``: each sensor of a network file with exact C, R and its channel."""
    return [SensorRecord(name=s.name, m=int(s.m), C=_text(s.C), R=_text(s.R),
                         channel=channel_record(s.channel),
                         position_m=None if s.position is None
                         else [float(x) for x in s.position])
            for s in network.sensors]
