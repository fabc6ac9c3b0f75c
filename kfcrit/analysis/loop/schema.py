"""The typed ``loop`` section of the analysis record (theory §12), field by field.

The designs, curves and Monte Carlo of :mod:`kfcrit.analysis.loop.designs` build their parts as
these classes (Python numbers); :func:`kfcrit.analysis.loop.section.loop_record` assembles the
section from them. Non-finite numbers (an infinite cost) are ``None`` (``null`` in JSON);
``finite`` then says which case it is.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.analysis.verdict import LoopVerdict, Verdict
from kfcrit.io.typed import opt


@dataclass(frozen=True)
class LoopThreshold:
    """A critical arrival probability of one link (γ_c of the sensing link, ν_c of the
    actuation link): its value where known, the exact expression, and an enclosing interval."""

    value: float | None
    expression: str | None
    exact: bool
    interval: list[float] | None
    basis: str
    certified: bool
    reason: str


@dataclass(frozen=True)
class LoopCostSummary:
    """The stationary average cost J = lim (1/T) E Σ (x'Wx + a'Ua) with lower ≤ J ≤ upper
    (``null`` where infinite or unknown; ``finite`` True/False proven, null undecided)."""

    value: float | None
    lower: float | None
    upper: float | None
    finite: bool | None
    method: str
    error: float | None
    reason: str


@dataclass(frozen=True)
class LoopStability:
    """Mean-square stability of a fixed design: ρ(Σ π_m Φ_m ⊗ Φ_m) < 1 decided exactly (or
    by a ball-arithmetic Lyapunov certificate), with the float spectral radius."""

    status: str
    holds: bool | None
    spectral_radius: float
    method: str
    dimension: int


@dataclass(frozen=True)
class LoopCurve:
    """The boundary of the stable region in the (γ̄, ν̄) plane of one design.

    ``points`` are [γ̄, ν̄] on the boundary (the stable side is above/right of it);
    ``rho`` the float spectral radius on ``gamma`` × ``nu_grid`` (fixed designs), for shading.
    """

    design: str
    kind: str
    points: list[list[float]]
    region: str
    gamma: list[float] | None = opt()
    nu_star: list[float | None] | None = opt()
    monotone: list[bool] | None = opt()
    nu_grid: list[float] | None = opt()
    rho: list[list[float | None]] | None = opt()


@dataclass(frozen=True)
class LoopDesignRow:
    """One design of the side-by-side comparison (TCP-like against UDP-like) at the operating
    point: its stability fact, spectral radius, cost and critical ν̄ at the operating γ̄."""

    design: str
    acknowledged: bool
    on_loss: str
    stability: str
    spectral_radius: float | None
    cost: LoopCostSummary
    critical_nu: float | None
    critical_nu_interval: list[float] | None = opt()


@dataclass(frozen=True)
class LoopCostCurve:
    """Cost against one link's arrival probability, the other link at its operating value."""

    link: str
    probability: list[float]
    costs: dict[str, list[float | None]]
    operating: float


@dataclass(frozen=True)
class LoopSimulationSummary:
    """The seeded closed-loop Monte Carlo at the operating point and its check of the cost."""

    design: str
    cost: float | None
    ci: list[float | None]
    std_error: float | None
    confidence: float
    growth_rate: float | None
    finite: bool
    paths: int
    steps: int
    burn_in: int
    seed: int
    status: str
    detail: str


@dataclass(frozen=True)
class LoopLinkCheck:
    """The actuation link budget against its margin policy, read against the arrival
    probability the loop needs on that link (ν_c, or the design's critical ν̄)."""

    required_arrival_probability: float | None
    required_basis: str
    arrival_probability: float | None
    link_margin_db: float | None
    required_margin_db: float | None
    margin_policy_met: bool | None
    distance_m: float | None
    max_distance_m: float | None
    outage_probability: float | None
    max_outage: float | None
    outage_within_policy: bool | None
    sinr_db: float | None = opt()
    radio: str | None = opt()


@dataclass(frozen=True)
class LoopGains:
    """The gains of the design judged: estimator K (filter form) and controller L."""

    estimator_gain: list[list[float]]
    controller_gain: list[list[float]]
    source: str


@dataclass(frozen=True)
class LoopSection:
    """A closed loop over the sensing link (``channel``) and the actuation link
    (``loop.channel``), theory §12.

    ``verdict`` is the loop's mean-square stability at the operating point (decided by
    :func:`kfcrit.analysis.verdict.loop_verdict` from the facts); ``operating_verdict`` is the
    record's one ``operating_point.verdict`` (the estimator's mean stability AND this, README
    "Closed loops").
    """

    acknowledged: bool
    on_loss: str
    design: str
    sensing_arrival_probability: float
    actuation_arrival_probability: float
    sensing_iid: bool
    actuation_iid: bool
    actuation_model: str
    sensing_critical: LoopThreshold
    actuation_critical: LoopThreshold
    verdict: LoopVerdict
    basis: str
    operating_verdict: Verdict
    spectral_radius: float | None
    stability: LoopStability | None
    cost: LoopCostSummary
    critical_curve: LoopCurve | None
    alternative_curve: LoopCurve | None
    comparison: list[LoopDesignRow]
    cost_curves: list[LoopCostCurve]
    simulation: LoopSimulationSummary | None
    actuation_link: LoopLinkCheck | None
    gains: LoopGains | None
    control_gain: list[list[float]] | None
    notes: list[str]
