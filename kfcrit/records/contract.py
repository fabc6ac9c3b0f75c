"""The contract sections of the record: critical value, bounds, operating point, requirements,
verification, system and provenance (the keys every record has had since schema 1, typed field by
field, with their nested payloads).

Optional keys are :func:`~kfcrit.io.typed.opt_key` (absent in some records; a ``null`` value is
kept as ``null``), except ``critical_value.basis`` (:func:`~kfcrit.io.typed.opt`: written only
when set).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

from kfcrit.io.typed import opt, opt_key
from kfcrit.records.bounds import (
    UpperCertificate,
    UpperLowerEvidence,
    UpperSolver,
)
from kfcrit.records.channel import ChannelRecord, MeshChannel, NetworkChannel
from kfcrit.records.system import (
    AnalysisOptionsRecord,
    ContinuousModel,
    Matrices,
    SensorRecord,
)


class Verdict(str, enum.Enum):
    """Mean stability of the filter at the operating point."""

    MEAN_STABLE = "mean-stable"
    MEAN_UNSTABLE = "mean-unstable"
    UNDETERMINED = "undetermined"


class Classification(str, enum.Enum):
    """Structure class of (A, C) that decides which theorem gives p_c (theory §3–4, §11)."""

    STABLE = "stable"
    NON_DEGENERATE = "non-degenerate"
    DEGENERATE_SECOND_ORDER = "degenerate-second-order"
    DEGENERATE = "degenerate"
    NON_DIAGONALIZABLE = "non-diagonalizable"
    MARGINAL = "marginal"
    NOT_DETECTABLE = "not-detectable"


@dataclass(frozen=True)
class CriticalValueRecord:
    """p_c: value, whether it is exact, its exact expression and the theorem that gives it."""

    value: float | None
    exact: bool | None
    expression: str | None
    latex: str | None
    reason: str
    basis: str | None = opt()


@dataclass(frozen=True, kw_only=True)
class NearbyCase:
    """A case decided at the user's tolerance (``robust_critical_value.alternatives[]``)."""

    value: float | None
    expression: str | None
    classification: str
    case: str


@dataclass(frozen=True, kw_only=True)
class LowCase:
    """A case within the tolerance with a *lower* critical value."""

    value: float | None
    expression: str | None
    case: str


@dataclass(frozen=True)
class RobustCriticalValue:
    """The largest critical value of a system within the relative tolerance (and which)."""

    value: float | None
    tolerance: float | None
    expression: str | None = opt_key()
    nearby_case: str | None = opt_key()
    low: LowCase = opt_key()
    """A case within the tolerance with a *lower* critical value ``{value, expression, case}``."""
    alternatives: list[NearbyCase] = opt_key()


@dataclass(frozen=True)
class LowerBound:
    """p_low = max(1 − 1/ρ(A)², 0) (Sinopoli Thm 3)."""

    value: float | None
    expression: str | None


@dataclass(frozen=True)
class BlockLowerBound:
    """The best block lower bound of p_c (Mo–Sinopoli Thm 3) and its basis."""

    value: float | None
    expression: str | None
    reason: str | None


@dataclass(frozen=True)
class UpperBoundRecord:
    """p_up (Sinopoli Thm 5): value, certified interval, method, certificate."""

    value: float | None
    interval: list[float | None] | None
    certified: bool | None
    status: str | None
    method: str | None
    certificate: UpperCertificate | None
    warnings: list[str]
    tolerance: float | None
    lower_evidence: UpperLowerEvidence = opt_key()
    solver: UpperSolver = opt_key()
    applicable: bool | None = opt_key()
    not_applicable_reason: str | None = opt_key()
    reason: str | None = opt_key()
    error: str | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class TraceTransitions:
    """Transition counts of a recorded trace."""

    received_to_lost: int
    received: int
    lost_to_received: int
    lost: int


@dataclass(frozen=True, kw_only=True)
class TraceCondition:
    """The theory §7 condition (1 − r̂)·ρ(A)² < 1 at the fitted recovery rate (for information)."""

    expression: str
    value: float | None
    holds: bool


@dataclass(frozen=True, kw_only=True)
class TraceFit:
    """Maximum-likelihood Gilbert–Elliott fit of a recorded trace (for information)."""

    available: bool
    failure_rate: float | None = opt_key()
    recovery_rate: float | None = opt_key()
    stationary_arrival_probability: float | None = opt_key()
    mean_burst_length: float | None = opt_key()
    transitions: TraceTransitions
    method: str
    status: str
    reason: str = opt_key()
    condition: TraceCondition = opt_key()


@dataclass(frozen=True, kw_only=True)
class TraceSummary:
    """Length, empirical arrival rate and Gilbert–Elliott fit of a measured trace."""

    length: int
    empirical_arrival_probability: float | None
    gilbert_elliott_fit: TraceFit


@dataclass(frozen=True)
class OperatingPoint:
    """The configured channel's arrival probability against p_c, and the stability verdict."""

    arrival_probability: float
    channel: ChannelRecord | NetworkChannel | MeshChannel
    iid: bool
    margin: float | None
    margin_robust: float | None
    bracket: list[float | None] | None
    verdict: Verdict
    basis: str
    margin_to_bracket: list[float | None] | None = opt_key()
    note: str | None = opt_key()
    reason: str | None = opt_key()
    iid_comparison_verdict: str | None = opt_key()
    diverges_for_all_p: bool | None = opt_key()
    trace: TraceSummary = opt_key()
    arrival_probabilities: dict[str, float | None] = opt_key()
    """Per-sensor arrival probabilities of a network (``arrival_probability`` is then the
    bottleneck sensor's and ``margin`` the uniform margin)."""
    bottleneck: str | None = opt_key()
    margin_basis: str | None = opt_key()
    """What ``margin`` measures: p − p_c for i.i.d. links, r − r_nec for a bursty link."""
    iid_margin: float | None = opt_key()
    """The i.i.d. comparison p − p_c of a channel with memory (not its margin)."""
    recovery_threshold: float | None = opt_key()
    """r_nec = max(1 − 1/ρ(A)², 0) of a bursty link (theory §10)."""
    margin_to_sufficient: float | None = opt_key()
    """r − r_suf(f): the distance to the certified sufficient curve of a bursty link."""


@dataclass(frozen=True, kw_only=True)
class PowerLawEstimate:
    """The tail requirement read with the tail exponent beside the Monte Carlo (a claim)."""

    value: float | None
    anchor_level: float | None
    anchor_probability: float | None
    exponent: float | None
    label: str | None
    formula: str


@dataclass(frozen=True, kw_only=True)
class TailAssessment:
    """The tail requirement against the simulated exceedance (schema 1's ``assessment``)."""

    status: str | None
    basis: str
    estimate: float | None
    interval: list[float | None] | None
    power_law_estimate: PowerLawEstimate = opt_key()


@dataclass(frozen=True)
class RequirementAssessment:
    """One requirement against the analysis: met / not met / not demonstrated, and why."""

    requirement: str
    status: str | None
    basis: str
    estimate: float | None = opt_key()
    interval: list[float | None] | None = opt_key()


@dataclass(frozen=True)
class RequirementsRecord:
    """The system file's requirements and their assessments (``assessment``: the tail one)."""

    max_error_trace: float | None
    max_tail_probability: float | None
    max_mean_error_trace: float | None = opt_key()
    max_cost: float | None = opt_key()
    """Largest acceptable average LQG cost of a closed loop (theory §12)."""
    assessment: TailAssessment = opt_key()
    assessments: list[RequirementAssessment] = field(default_factory=list)


@dataclass(frozen=True)
class VerificationCheck:
    """A check the record relies on and its outcome."""

    check: str
    passed: bool | None
    status: str
    detail: str | None = opt_key()
    reason: str | None = opt_key()
    value: float | None = opt_key()


@dataclass(frozen=True)
class SystemSection:
    """Sizes, exactness and exact matrices of the system (and the configured channel)."""

    n: int
    m: int
    exact_input: bool
    matrices: Matrices
    channel: ChannelRecord | None
    continuous: ContinuousModel = opt_key()
    """The continuous-time model and its sampling (method, exactness, error bound)."""
    sensors: list[SensorRecord] | None = opt_key()
    """The sensors of a network file (name, rows of C, noise, channel)."""
    sink_position_m: list[float | None] | None = opt_key()


@dataclass(frozen=True)
class Provenance:
    """Versions, seed, options and the input file's SHA-256."""

    versions: dict[str, str | None]
    seed: int
    input_path: str | None
    input_sha256: str | None
    options: AnalysisOptionsRecord
