"""The covariance sections: ``covariance_bounds`` (S̄ and V̄ at the operating point),
``static_gain``, ``phase_transition``, ``invariant`` (scalar systems), ``tail`` (the power-law
exponent of tr P) and ``design`` (the accuracy requirement as a required arrival probability).
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key
from kfcrit.records.bounds import CertificateCheck
from kfcrit.records.link import LinkDesignRecord


@dataclass(frozen=True, kw_only=True)
class MareEnclosure:
    """`covariance_bounds.upper.certificate`: a verified enclosure (1 − ε)V ⪯ V̄ ⪯ (1 + ε)V."""

    relative_width: float
    trace_interval: list[float]
    proves_p_above_p_up: bool
    margins: list[float | None]
    method: str


@dataclass(frozen=True, kw_only=True)
class CovarianceSummary:
    """`@CovarianceSummary`"""

    exists: bool
    trace: float | None
    max_eig: float | None
    matrix: list[list[float | None]] | None
    residual: float | None = opt_key()
    method: str = opt_key()
    iterations: int = opt_key()
    computed: bool = opt_key()
    not_reached: bool = opt_key()
    beyond_float64: bool = opt_key()
    certified: bool = opt_key()
    certificate: MareEnclosure | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class MarkovJumpLower:
    """`covariance_bounds.markov_jump.lower`: lim E[tr P_t] from below (losses-only recursion)."""

    trace: float | None
    exists: bool
    basis: str


@dataclass(frozen=True, kw_only=True)
class MarkovJumpUpper:
    """`covariance_bounds.markov_jump.upper`: lim sup E[tr P_t] from above (fixed gains)."""

    trace: float | None
    exists: bool
    basis: str
    spectral_radius: float | None
    gains: list[list[float | None]] | None


@dataclass(frozen=True, kw_only=True)
class MarkovJumpRecord:
    """`covariance_bounds.markov_jump`: bounds valid for a Gilbert–Elliott channel (theory §10);
    the i.i.d. bounds beside them are at the stationary arrival probability only."""

    failure_rate: float | None
    recovery_rate: float | None
    lower: MarkovJumpLower
    upper: MarkovJumpUpper
    method: str


@dataclass(frozen=True, kw_only=True)
class CovarianceBounds:
    """`covariance_bounds`"""

    p: float | None
    lower: CovarianceSummary
    upper: CovarianceSummary
    ordered: bool | None = opt_key()
    warnings: list[str] = opt_key()
    applicable: bool = opt_key()
    reason: str = opt_key()
    markov_jump: MarkovJumpRecord = opt_key()


@dataclass(frozen=True, kw_only=True)
class StaticGainEstimate:
    """`static_gain.kalman`"""

    available: bool
    critical_value: float | None = opt_key()
    stable_up_to_one: bool = opt_key()
    crossings: list[float | None] = opt_key()
    covariance_exists: bool = opt_key()
    covariance_trace: float | None = opt_key()
    covariance_max_eig: float | None = opt_key()
    covariance_matrix: list[list[float | None]] | None = opt_key()
    gain: list[list[float | None]] = opt_key()
    reason: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class BestStaticGain:
    """`static_gain.best`"""

    available: bool
    critical_value: float | None = opt_key()
    stable_up_to_one: bool = opt_key()
    crossings: list[float | None] = opt_key()
    covariance_exists: bool = opt_key()
    covariance_trace: float | None = opt_key()
    covariance_max_eig: float | None = opt_key()
    covariance_matrix: list[list[float | None]] | None = opt_key()
    gain: list[list[float | None]] = opt_key()
    difference: float | None = opt_key()
    equals_p_up: bool = opt_key()
    reason: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class StaticGain:
    """`static_gain`"""

    p: float | None
    kalman: StaticGainEstimate
    best: BestStaticGain
    p_up: float | None
    p_up_interval: list[float | None] | None
    skipped: str = opt_key()
    """Why the static gains were not computed (e.g. a state dimension beyond their limit)."""


@dataclass(frozen=True, kw_only=True)
class Markers:
    """`phase_transition.markers`"""

    p_low: float | None
    p_c: float | None
    p_up: float | None
    operating: float | None


@dataclass(frozen=True, kw_only=True)
class Limits:
    """`phase_transition.limits`"""

    points: int
    requested_points: int
    method: str
    time_budget_seconds: float | None
    stopped: str | None


@dataclass(frozen=True, kw_only=True)
class PhaseTransition:
    """`phase_transition`"""

    p: list[float | None]
    trace_lower: list[float | None]
    trace_upper: list[float | None]
    markers: Markers
    warnings: list[str]
    limits: Limits = opt_key()


@dataclass(frozen=True, kw_only=True)
class ValueExpression:
    """`invariant.fixed_point`"""

    value: float | None
    expression: str


@dataclass(frozen=True, kw_only=True)
class InvariantMaps:
    """`invariant.maps`"""

    loss: str
    arrival: str


@dataclass(frozen=True, kw_only=True)
class InvariantGap:
    """`invariant.first_gap`"""

    lower: float | None
    upper: float | None
    lower_expression: str
    upper_expression: str
    width: float | None


@dataclass(frozen=True, kw_only=True)
class InvariantGapLevel:
    """`invariant.gap_levels[]`"""

    n: int
    lower: float | None
    upper: float | None
    lower_expression: str
    upper_expression: str


@dataclass(frozen=True, kw_only=True)
class SelfSimilarity:
    """`invariant.self_similarity`"""

    scale: float | None
    offset: float | None
    statement: str
    pieces: str


@dataclass(frozen=True, kw_only=True)
class SupportPointsRecord:
    """`invariant.support_points`"""

    depth: int
    count: int
    min: float | None
    window: list[float | None]
    largest_gaps: list[list[float | None]]


@dataclass(frozen=True, kw_only=True)
class Invariant:
    """`invariant`"""

    fixed_point: ValueExpression
    maps: InvariantMaps
    arrival_limit: ValueExpression
    first_gap: InvariantGap | None
    gap_levels: list[InvariantGapLevel]
    self_similarity: SelfSimilarity
    support_points: SupportPointsRecord
    holes: list[list[float | None]]
    note: str
    warnings: list[str] = opt_key()


@dataclass(frozen=True, kw_only=True)
class RequiredArrivalEnd:
    """`design.required_arrival_probability.p_S`"""

    value: float | None
    certified: bool
    how: str
    check: CertificateCheck | None


@dataclass(frozen=True, kw_only=True)
class RequiredArrivalProbability:
    """`design.required_arrival_probability`"""

    status: str
    level: float | None
    interval: list[float | None] | None
    p_S: RequiredArrivalEnd
    p_V: RequiredArrivalEnd
    floor_trace: float | None
    floor_certified: bool
    reason: str
    meaning: str


@dataclass(frozen=True, kw_only=True)
class AccuracyDesign:
    """`design`"""

    requirement: str
    required_arrival_probability: RequiredArrivalProbability
    radio: LinkDesignRecord = opt_key()


@dataclass(frozen=True, kw_only=True)
class TailExponentRecord:
    """`tail.exponent`"""

    value: float | None
    expression: str | None
    applicable: bool
    finite_mean: bool | None
    finite_variance: bool | None
    statement: str
    label: str
    source: str
    formula: str


@dataclass(frozen=True, kw_only=True)
class TailSimulationCheck:
    """`tail.simulation_check`"""

    method: str
    paths: int
    horizon: int
    points: int
    slope: float | None = opt_key()
    exponent_estimate: float | None = opt_key()
    relative_difference: float | None = opt_key()
    trace_range: list[float | None] = opt_key()
    note: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class TailSection:
    """`tail`"""

    exponent: TailExponentRecord
    simulation_check: TailSimulationCheck = opt_key()
