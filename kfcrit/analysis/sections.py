"""The typed analysis record: one frozen dataclass per section.

The record's JSON form (``--json``), its JSON Schema (``kfcrit schema record``) and the typed
objects are generated from these classes by :mod:`kfcrit.io.typed`; views and tests build records
through the same classes. Contract sections (critical value, bounds, operating point, review,
requirements, verification) are typed field by field; the detail sections type their top-level
keys and keep the payload of each key as JSON (matrices, curves, per-eigenvalue tables whose shape
belongs to the theory and simulation layers).

``schema_version`` changes when a key is renamed or removed (never for an added key).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

from kfcrit.analysis.measured.section import ChannelFitSection
from kfcrit.analysis.verdict import Reason, Review, Verdict
from kfcrit.io.typed import JSON, from_json, internal, json_schema, opt, to_json

SCHEMA_VERSION = "2.0"
"""Version of the record's JSON contract (2.0: typed record with ``review``)."""


class Classification(str, enum.Enum):
    """Structure class of (A, C) that decides which theorem gives p_c (theory §3–§4, §11)."""

    STABLE = "stable"
    NON_DEGENERATE = "non-degenerate"
    DEGENERATE_SECOND_ORDER = "degenerate-second-order"
    DEGENERATE = "degenerate"
    NON_DIAGONALIZABLE = "non-diagonalizable"
    MARGINAL = "marginal"
    NOT_DETECTABLE = "not-detectable"


# ----------------------------------------------------------------------------- contract

@dataclass(frozen=True)
class CriticalValue:
    """p_c: value, whether it is exact, its exact expression and the theorem that gives it."""

    value: float | None
    exact: bool | None
    expression: str | None
    latex: str | None
    reason: str
    basis: str | None = opt()


@dataclass(frozen=True)
class RobustCriticalValue:
    """The largest critical value of a system within the relative tolerance (and which)."""

    value: float | None
    tolerance: float | None
    expression: str | None = opt()
    nearby_case: str | None = opt()
    alternatives: JSON = opt()
    low: JSON = opt()
    """A case within the tolerance with a *lower* critical value ``{value, expression, case}``."""


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
class UpperBound:
    """p_up (Sinopoli Thm 5): value, certified interval, method, certificate."""

    value: float | None
    interval: list[float | None] | None
    certified: bool | None
    status: str | None
    method: str | None
    certificate: JSON
    warnings: list[str]
    tolerance: float | None
    lower_evidence: JSON = opt()
    solver: JSON = opt()
    applicable: bool | None = opt()
    not_applicable_reason: str | None = opt()
    reason: str | None = opt()
    error: str | None = opt()


@dataclass(frozen=True)
class OperatingPoint:
    """The configured channel's arrival probability against p_c, and the stability verdict."""

    arrival_probability: float
    channel: JSON
    iid: bool
    margin: float | None
    margin_robust: float | None
    bracket: list[float | None] | None
    verdict: Verdict
    basis: str
    margin_to_bracket: list[float | None] | None = opt()
    note: str | None = opt()
    reason: str | None = opt()
    iid_comparison_verdict: str | None = opt()
    diverges_for_all_p: bool | None = opt()
    trace: JSON = opt()
    burst: JSON = opt()
    arrival_probabilities: JSON = opt()
    """Per-sensor arrival probabilities of a network (``arrival_probability`` is then the
    bottleneck sensor's and ``margin`` the uniform margin)."""
    bottleneck: str | None = opt()


@dataclass(frozen=True)
class RequirementAssessment:
    """One requirement against the analysis: met / not met / not demonstrated, and why."""

    requirement: str
    status: str | None
    basis: str
    estimate: float | None = opt()
    interval: list[float | None] | None = opt()


@dataclass(frozen=True)
class Requirements:
    """The system file's requirements and their assessments (``assessment``: the tail one)."""

    max_error_trace: float | None
    max_tail_probability: float | None
    max_mean_error_trace: float | None = opt()
    assessment: JSON = opt()
    assessments: list[RequirementAssessment] = field(default_factory=list)


@dataclass(frozen=True)
class VerificationCheck:
    """A check the record relies on and its outcome."""

    check: str
    passed: bool | None
    status: str
    detail: str | None = opt()
    reason: str | None = opt()
    value: JSON = opt()


@dataclass(frozen=True)
class SystemSection:
    """Sizes, exactness and exact matrices of the system (and the configured channel)."""

    n: int
    m: int
    exact_input: bool
    matrices: JSON
    channel: JSON
    continuous: JSON = opt()
    """The continuous-time model and its sampling (method, exactness, error bound)."""
    sensors: JSON = opt()
    """The sensors of a network file (name, rows of C, noise, channel)."""
    sink_position_m: JSON = opt()


@dataclass(frozen=True)
class Provenance:
    """Versions, seed, options and the input file's SHA-256."""

    versions: dict[str, str | None]
    seed: int
    input_path: str | None
    input_sha256: str | None
    options: JSON


# ----------------------------------------------------------------------------- details

@dataclass(frozen=True)
class Structure:
    """Eigen-structure of (A, C): eigenvalues, equi-blocks, decisions and tolerances."""

    path: JSON = opt()
    path_reason: JSON = opt()
    tolerances: JSON = opt()
    eigenvalues: JSON = opt()
    equi_blocks: JSON = opt()
    equal_modulus_pairs: JSON = opt()
    diagonalizable: JSON = opt()
    detectable: JSON = opt()
    controllable_Q: JSON = opt()
    observability_index: JSON = opt()
    observable: JSON = opt()
    standard_form: JSON = opt()
    resolution: JSON = opt()
    unresolved: JSON = opt()
    degenerate: JSON = opt()
    im: JSON = opt()
    indices: JSON = opt()
    modulus: JSON = opt()
    modulus_expression: JSON = opt()
    one_step_observable: JSON = opt()
    q: JSON = opt()
    rank: JSON = opt()
    re: JSON = opt()
    size: JSON = opt()
    turn: JSON = opt()
    turn_expression: JSON = opt()
    unstable_or_critical: JSON = opt()
    value: JSON = opt()


@dataclass(frozen=True)
class Theory:
    """Statements of the theory at this system: moments, boundedness, almost-sure stability."""

    moment_thresholds: JSON = opt()
    moment_thresholds_note: JSON = opt()
    stochastic_boundedness: JSON = opt()
    almost_sure: JSON = opt()
    observability_index: JSON = opt()
    marginal: JSON = opt()
    applies: JSON = opt()
    expression: JSON = opt()
    q: JSON = opt()
    value: JSON = opt()


@dataclass(frozen=True)
class CovarianceBounds:
    """S̄ ⪯ lim E[P_t] ⪯ V̄ at the operating point (Sinopoli Thm 4, 6)."""

    p: JSON = opt()
    lower: JSON = opt()
    upper: JSON = opt()
    ordered: JSON = opt()
    warnings: JSON = opt()
    applicable: JSON = opt()
    reason: JSON = opt()
    available: JSON = opt()
    best: JSON = opt()
    covariance_bounds: JSON = opt()
    iterations: JSON = opt()
    kalman: JSON = opt()
    markers: JSON = opt()
    method: JSON = opt()
    not_reached: JSON = opt()
    operating: JSON = opt()
    p_c: JSON = opt()
    p_low: JSON = opt()
    p_up: JSON = opt()
    p_up_interval: JSON = opt()
    phase_transition: JSON = opt()
    residual: JSON = opt()
    static_gain: JSON = opt()
    trace_lower: JSON = opt()
    trace_upper: JSON = opt()


@dataclass(frozen=True)
class StaticGain:
    """Fixed-gain estimators at the operating point (journal §V)."""

    p: JSON = opt()
    kalman: JSON = opt()
    best: JSON = opt()
    p_up: JSON = opt()
    p_up_interval: JSON = opt()
    available: JSON = opt()
    reason: JSON = opt()
    applicable: JSON = opt()
    covariance_bounds: JSON = opt()
    difference: JSON = opt()
    equals_p_up: JSON = opt()
    gain: JSON = opt()
    iterations: JSON = opt()
    lower: JSON = opt()
    markers: JSON = opt()
    method: JSON = opt()
    operating: JSON = opt()
    ordered: JSON = opt()
    p_c: JSON = opt()
    p_low: JSON = opt()
    phase_transition: JSON = opt()
    residual: JSON = opt()
    skipped: JSON = opt()
    static_gain: JSON = opt()
    trace_lower: JSON = opt()
    trace_upper: JSON = opt()
    upper: JSON = opt()
    warnings: JSON = opt()


@dataclass(frozen=True)
class PhaseTransition:
    """tr S̄(p) and tr V̄(p) on a grid of arrival probabilities, with the markers."""

    p: JSON = opt()
    trace_lower: JSON = opt()
    trace_upper: JSON = opt()
    markers: JSON = opt()
    warnings: JSON = opt()
    limits: JSON = opt()
    applicable: JSON = opt()
    available: JSON = opt()
    best: JSON = opt()
    covariance_bounds: JSON = opt()
    iterations: JSON = opt()
    kalman: JSON = opt()
    lower: JSON = opt()
    method: JSON = opt()
    operating: JSON = opt()
    ordered: JSON = opt()
    p_c: JSON = opt()
    p_low: JSON = opt()
    p_up: JSON = opt()
    p_up_interval: JSON = opt()
    phase_transition: JSON = opt()
    points: JSON = opt()
    reason: JSON = opt()
    requested_points: JSON = opt()
    residual: JSON = opt()
    static_gain: JSON = opt()
    stopped: JSON = opt()
    time_budget_seconds: JSON = opt()
    upper: JSON = opt()


@dataclass(frozen=True)
class Simulation:
    """Monte Carlo of the random Riccati equation at the operating point and around p_c."""

    seed: JSON = opt()
    quick: JSON = opt()
    budget: JSON = opt()
    seeds: JSON = opt()
    operating_point: JSON = opt()
    phase_demo: JSON = opt()
    checks: JSON = opt()
    warnings: JSON = opt()
    skipped: JSON = opt()
    reason: JSON = opt()
    ergodic: JSON = opt()
    network: JSON = opt()
    almost_sure: JSON = opt()
    arrival_probability: JSON = opt()
    batches: JSON = opt()
    bursts: JSON = opt()
    channel: JSON = opt()
    confidence: JSON = opt()
    critical_bracket: JSON = opt()
    critical_value: JSON = opt()
    curves: JSON = opt()
    description: JSON = opt()
    diverged_fraction: JSON = opt()
    divergence: JSON = opt()
    diverges: JSON = opt()
    exceedance: JSON = opt()
    exists: JSON = opt()
    horizon: JSON = opt()
    iid: JSON = opt()
    invariant: JSON = opt()
    label: JSON = opt()
    log10_lower: JSON = opt()
    log10_mean: JSON = opt()
    log10_upper: JSON = opt()
    lower: JSON = opt()
    mean: JSON = opt()
    mean_basis: JSON = opt()
    mean_exists: JSON = opt()
    mean_is_lower_bound: JSON = opt()
    mean_lambda_max: JSON = opt()
    mean_trace: JSON = opt()
    name: JSON = opt()
    paths: JSON = opt()
    provenance: JSON = opt()
    reference: JSON = opt()
    reference_value: JSON = opt()
    reliability: JSON = opt()
    requirements: JSON = opt()
    review: JSON = opt()
    sample_time_average: JSON = opt()
    schema_version: JSON = opt()
    side: JSON = opt()
    simulation: JSON = opt()
    statement: JSON = opt()
    std: JSON = opt()
    steps: JSON = opt()
    system: JSON = opt()
    times: JSON = opt()
    upper: JSON = opt()
    upper_bound: JSON = opt()
    verification: JSON = opt()


@dataclass(frozen=True)
class Invariant:
    """Support of the invariant distribution (Kar–Sinopoli–Moura), scalar systems."""

    fixed_point: JSON = opt()
    maps: JSON = opt()
    arrival_limit: JSON = opt()
    first_gap: JSON = opt()
    gap_levels: JSON = opt()
    self_similarity: JSON = opt()
    support_points: JSON = opt()
    holes: JSON = opt()
    note: JSON = opt()
    warnings: JSON = opt()
    available: JSON = opt()
    reason: JSON = opt()
    arrival: JSON = opt()
    count: JSON = opt()
    depth: JSON = opt()
    expression: JSON = opt()
    largest_gaps: JSON = opt()
    loss: JSON = opt()
    lower: JSON = opt()
    lower_exact: JSON = opt()
    lower_expression: JSON = opt()
    min: JSON = opt()
    n: JSON = opt()
    offset: JSON = opt()
    pieces: JSON = opt()
    scale: JSON = opt()
    statement: JSON = opt()
    upper: JSON = opt()
    upper_exact: JSON = opt()
    upper_expression: JSON = opt()
    value: JSON = opt()
    width: JSON = opt()
    window: JSON = opt()


@dataclass(frozen=True)
class LinkBudget:
    """The link: a radio link budget's design, or a Gilbert–Elliott channel's conditions."""

    applicable: JSON = opt()
    reason: JSON = opt()
    radio: JSON = opt()
    link: JSON = opt()
    margin_policy: JSON = opt()
    required_arrival_probability: JSON = opt()
    required_sinr_db: JSON = opt()
    required_rx_power_dbm: JSON = opt()
    link_margin_db: JSON = opt()
    max_distance_m: JSON = opt()
    max_distance_unbounded: JSON = opt()
    mean_stable_at_distance: JSON = opt()
    shadowing: JSON = opt()
    thresholds: JSON = opt()
    notes: JSON = opt()
    design_check: JSON = opt()
    warnings: JSON = opt()
    failure_rate: JSON = opt()
    recovery_rate: JSON = opt()
    stationary_arrival_probability: JSON = opt()
    mean_burst_length: JSON = opt()
    spectral_radius: JSON = opt()
    classification: JSON = opt()
    condition: JSON = opt()
    required_recovery_rate: JSON = opt()
    max_mean_burst_length: JSON = opt()
    simulation: JSON = opt()
    simulation_consistent: JSON = opt()
    simulation_note: JSON = opt()
    claims: JSON = opt()
    retries: JSON = opt()
    frame: JSON = opt()
    certificate: JSON = opt()
    critical_curve: JSON = opt()
    gilbert_elliott: JSON = opt()
    bursty: JSON = opt()
    curves: JSON = opt()
    """Arrival probability and outage against distance, PER against SINR (for the figures)."""
    basis: JSON = opt()
    bracket: JSON = opt()
    critical_value: JSON = opt()
    decides: JSON = opt()
    design_value: JSON = opt()
    effective_margin_db: JSON = opt()
    expression: JSON = opt()
    holds: JSON = opt()
    link_budget: JSON = opt()
    margin_db: JSON = opt()
    max_outage: JSON = opt()
    mean_arrival_probability: JSON = opt()
    mode: JSON = opt()
    outage_below_critical: JSON = opt()
    outage_below_upper: JSON = opt()
    robust_value: JSON = opt()
    rule: JSON = opt()
    sigma_db: JSON = opt()
    status: JSON = opt()
    value: JSON = opt()


# ----------------------------------------------------------------------------- the record

CONTRACT_KEYS = ("name", "classification", "critical_value", "robust_critical_value",
                 "lower_bound", "block_lower_bound", "upper_bound", "operating_point",
                 "warnings")
"""The keys every record has had since schema 1 (kept, never renamed)."""


@dataclass(frozen=True)
class Analysis:
    """The analysis record of one system file (JSON contract, schema :data:`SCHEMA_VERSION`).

    Build with :func:`kfcrit.analyze`; read with :meth:`to_dict` (the ``--json`` form), by
    attribute (typed sections) or by key (``record["critical_value"]``, the JSON form of one
    section).
    """

    name: str
    classification: Classification | None
    critical_value: CriticalValue | None
    robust_critical_value: RobustCriticalValue | None
    lower_bound: LowerBound | None
    block_lower_bound: BlockLowerBound | None
    upper_bound: UpperBound | None
    operating_point: OperatingPoint | None
    warnings: list[str]
    schema_version: str
    review: Review
    description: str | None
    system: SystemSection
    structure: Structure | None
    theory: Theory | None
    covariance_bounds: CovarianceBounds | None
    static_gain: StaticGain | None
    phase_transition: PhaseTransition | None
    simulation: Simulation | None
    invariant: Invariant | None
    link_budget: LinkBudget | None
    requirements: Requirements | None
    verification: list[VerificationCheck]
    provenance: Provenance
    design: JSON = opt()
    tail: JSON = opt()
    network: JSON = opt()
    channel_fit: ChannelFitSection | None = opt()
    """A measured trace's fits and the confidence region of its verdict (theory §14)."""
    timings: dict[str, float] = internal(dict)
    """Wall-clock seconds of the sections (kept out of the JSON form: same input and seed give
    byte-identical JSON)."""

    def to_dict(self) -> dict[str, Any]:
        """The record as plain JSON types (what ``--json`` prints and every view renders)."""
        return to_json(self)

    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    @property
    def decision(self) -> str:
        """The review decision: ``pass``, ``fail`` or ``undetermined``."""
        return self.review.decision.value

    @property
    def verdict(self) -> str | None:
        """Mean stability at the operating point (None without a channel)."""
        return self.operating_point.verdict.value if self.operating_point else None

    def __repr__(self) -> str:
        pc = self.critical_value.value if self.critical_value else None
        pc_text = (self.critical_value.expression or f"{pc:.6g}") if pc is not None else "bracket"
        cls = self.classification.value if self.classification else "?"
        return (f"<kfcrit Analysis {self.name!r}: {cls}, "
                f"p_c = {pc_text}, verdict {self.verdict or 'n/a'}, review {self.decision}>")


def record_from_json(data: dict[str, Any]) -> Analysis:
    """The typed record from its JSON form (strict: unknown, missing or mistyped keys fail)."""
    return from_json(Analysis, data)


def record_schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of the record's JSON form."""
    schema = json_schema(Analysis, title="kfcrit analysis record")
    schema["$id"] = f"https://kfcrit.invalid/schema/record-{SCHEMA_VERSION}.json"
    return schema


__all__ = ["SCHEMA_VERSION", "BlockLowerBound", "Classification", "CovarianceBounds",
           "CriticalValue", "Invariant", "LinkBudget", "LowerBound", "OperatingPoint",
           "PhaseTransition", "Provenance", "Reason", "Analysis", "RequirementAssessment",
           "Requirements", "Review", "RobustCriticalValue", "Simulation", "StaticGain",
           "Structure", "SystemSection", "Theory", "UpperBound", "VerificationCheck",
           "record_from_json", "record_schema"]
