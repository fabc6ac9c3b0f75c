"""The ``mesh`` section of the record (theory §13): fully typed frozen dataclasses.

Built by :func:`kfcrit.analysis.mesh.build.mesh_sections` from the theory's facts
(:mod:`kfcrit.theory.mesh`); every verdict in it comes from :mod:`kfcrit.analysis.verdict`, and
``verdict`` (raw forwarding at the hops' operating values) equals ``operating_point.verdict``.
Exact values travel as text (``*_expression``) beside their floats.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt
from kfcrit.records.contract import Verdict


@dataclass(frozen=True)
class MeshNodeRow:
    """A node: its role, relay mode (for the hops it transmits) and position."""

    name: str
    role: str
    mode: str | None
    position_m: list[float] | None


@dataclass(frozen=True)
class MeshHopLinkRow:
    """A hop's link budget at its distance: median SINR, one attempt's packet error rate."""

    radio: str
    distance_m: float
    sinr_db: float
    attempt_per: float
    tx_power_dbm: float


@dataclass(frozen=True)
class MeshHopRow:
    r"""A hop: per-attempt success q_h, retries k_h and per-period success

    .. math:: s_h = 1 - (1 - q_h)^{k_h + 1},

    its critical per-attempt success σ*_h (the necessary condition fails below it, theory §13),
    the headroom q_h − σ*_h, and whether its loss alone breaks the necessary condition."""

    name: str
    source: str
    target: str
    attempt_success: float
    attempt_success_expression: str | None
    retries: int | None
    """k_h; None: not set (one attempt per period, or under a slot budget no cap)."""
    period_success: float
    period_success_expression: str | None
    origin: str
    critical: bool
    critical_attempt_success: float | None
    headroom: float | None
    link: MeshHopLinkRow | None = opt()
    distance_m: float | None = opt()


@dataclass(frozen=True)
class MeshRouteRow:
    """One route of a sensor: its nodes and hops, each hop's success (per period, or per
    attempt under a slot budget) and the route's delivery probability."""

    sensor: str
    nodes: list[str]
    hops: list[str]
    hop_success: list[float]
    arrival_probability: float
    arrival_expression: str | None
    origin: str


@dataclass(frozen=True)
class MeshAllLost:
    r"""P(no packet arrives) against the product of the marginals (independent links):

    .. math:: \text{ratio} = \frac{\pi(\emptyset)}{\prod_i (1 - a_i)}

    (1 for independent routes, above 1 when shared hops correlate the losses)."""

    value: float
    expression: str | None
    product_of_marginals: float
    product_expression: str | None
    ratio: float | None


@dataclass(frozen=True)
class MeshLawCell:
    """One received set S and π(S)."""

    received: list[str]
    probability: float


@dataclass(frozen=True)
class MeshLaw:
    """Summary of the joint law π(S) of the received set (2^N cells)."""

    method: str
    exact: bool
    cells: int
    largest: list[MeshLawCell]
    """The most probable received sets (at most 8, descending)."""


@dataclass(frozen=True)
class MeshConstraint:
    """P(S ⊆ T)·ρ_T² < 1 for one maximal unobservable sensor set T (theory §13)."""

    within: list[str]
    eigenvalue: str
    modulus2: float
    probability: float
    value: float
    value_expression: str | None
    holds: bool | None


@dataclass(frozen=True)
class MeshFacts:
    """The facts of mean stability under the mesh's law (necessary, certified sufficient,
    exact region) with the evidence behind each."""

    necessary: bool | None
    sufficient: bool
    exact_region: bool
    necessary_basis: str
    sufficient_basis: str
    decided: bool
    reason: str
    binding: MeshConstraint | None
    constraints: list[MeshConstraint]
    certificate: str
    exact_region_reason: str


@dataclass(frozen=True)
class MeshCutRow:
    """Estimate relaying for one sensor: the max-drop cut and p_cut·ρ(A)² against 1."""

    sensor: str
    p_cut: float
    p_cut_expression: str | None
    cut_hops: list[str]
    source_side: list[str]
    value: float
    value_expression: str | None
    detectable: bool
    holds: bool | None


@dataclass(frozen=True)
class MeshRelaying:
    """Estimate relaying (Gupta et al. 2009): p_cut·ρ(A)² < 1 by min-cut. ``p_cut`` is that
    of the sensor the verdict rests on (the smallest among detecting sensors)."""

    p_cut: float | None
    verdict: Verdict
    basis: str
    rho2: float
    sensors: list[MeshCutRow]


@dataclass(frozen=True)
class MeshSmartRow:
    """A smart sensor's estimate arriving with the sensor's arrival probability."""

    sensor: str
    arrival_probability: float
    detectable: bool
    above: bool | None


@dataclass(frozen=True)
class MeshSmart:
    """Smart sensors: each sends its own filter's estimate; critical value 1 − 1/ρ(A)²."""

    critical_value: float | None
    expression: str | None
    verdict: Verdict
    basis: str
    sensors: list[MeshSmartRow]


@dataclass(frozen=True)
class MeshMode:
    """One forwarding mode in the comparison: its verdict and the condition behind it."""

    mode: str
    verdict: Verdict
    condition: str


@dataclass(frozen=True)
class MeshFailure:
    """N − 1: a dead relay (every hop to or from it) or a dead hop; the sensors that lose
    every route; the verdict under raw forwarding with it dead."""

    kind: str
    element: str
    lost_sensors: list[str]
    verdict: Verdict
    basis: str


@dataclass(frozen=True)
class MeshSimulation:
    """Monte Carlo of the random Riccati equation with received sets drawn from the hop
    outcomes: E[tr P_t] at the horizon (or the sample statistics of a diverging mean), the
    empirical P(all lost) against π(∅), and whether it agrees with the verdict."""

    paths: int
    steps: int
    seed: int
    mean_trace: float | None
    mean_trace_band: list[float] | None
    tail_exponent: float | None
    tail_exponent_band: list[float] | None
    tail_exponent_theory: float | None
    empirical_all_lost: float
    all_lost: float
    consistent: bool | None
    statement: str


@dataclass(frozen=True)
class MeshSection:
    """The mesh (theory §13): routes, arrivals, joint losses, facts, forwarding modes, N − 1."""

    routing: str
    relay_mode: str
    slots_per_period: int | None
    nodes: list[MeshNodeRow]
    hops: list[MeshHopRow]
    routes: list[MeshRouteRow]
    arrival_probability: dict[str, float]
    arrival_expression: dict[str, str]
    all_lost: MeshAllLost
    law: MeshLaw
    facts: MeshFacts
    verdict: Verdict
    basis: str
    bottleneck: str | None
    bottleneck_headroom: float | None
    relaying: MeshRelaying
    smart_sensor: MeshSmart
    modes: list[MeshMode]
    recommendation: str
    failures: list[MeshFailure]
    simulation: MeshSimulation | None = opt()
