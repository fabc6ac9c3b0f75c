"""The ``network`` section of a sensor network (theory §9): per-sensor critical values and
surfaces, uniform margin, N − 1 verdicts, bottleneck, necessary constraints, certificate and
the burst condition.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key
from kfcrit.records.bursty import StabilityFactsRecord
from kfcrit.records.contract import CriticalValueRecord, UpperBoundRecord
from kfcrit.records.link import DesignCheck, LinkState, MarginPolicy, Shadowing


@dataclass(frozen=True, kw_only=True)
class SensorCriticalValue:
    """`network.sensors[].critical_value`"""

    value: float | None
    interval: list[float | None] | None
    """[lower, upper] of the critical value; None when no p_i in [0, 1] gives mean stability
    (a necessary constraint without this sensor fails: ``basis`` says so)."""
    exact: bool
    expression: str | None
    basis: str


@dataclass(frozen=True, kw_only=True)
class NetworkCertificate:
    """`@NetworkCertificate`"""

    ok: bool
    p: list[float | None]
    received_sets: int
    all_received_sets: bool
    min_eig_x_lower: float | None
    margin_lower: float | None
    reason: str
    kind: str
    verified_by: str


@dataclass(frozen=True, kw_only=True)
class SufficientSurface:
    """`network.sensors[].surfaces.sufficient`"""

    value: float | None
    certificate: NetworkCertificate | None
    note: str


@dataclass(frozen=True, kw_only=True)
class NecessarySurfacePoint:
    """`network.sensors[].surfaces.necessary`: least p_i the necessary surface allows.

    ``expression`` is None when an ingredient is not exact."""

    value: float | None
    expression: str | None


@dataclass(frozen=True, kw_only=True)
class SensorSurfaces:
    """`network.sensors[].surfaces`: each None where not crossed on this coordinate.

    (No p_i works, or no certificate was found up to p_i = 1.)"""

    necessary: NecessarySurfacePoint | None
    sufficient: SufficientSurface | None


@dataclass(frozen=True, kw_only=True)
class SensorMargin:
    """`network.sensors[].margin`"""

    value: float | None
    interval: list[float | None] | None
    """None when the critical value has no interval (no p_i works)."""


@dataclass(frozen=True, kw_only=True)
class SensorNMinus1:
    """`network.sensors[].n_minus_1`"""

    verdict: str
    reason: str
    facts: StabilityFactsRecord = opt_key()
    burst_facts: StabilityFactsRecord = opt_key()


@dataclass(frozen=True, kw_only=True)
class SensorLink:
    """`network.sensors[].link`"""

    link: LinkState
    link_margin_db: float | None
    required_sinr_db: float | None
    max_distance_m: float | None
    margin_policy: MarginPolicy
    design_check: DesignCheck
    shadowing: Shadowing


@dataclass(frozen=True, kw_only=True)
class NetworkSensor:
    """`network.sensors[]`"""

    name: str
    arrival_probability: float | None
    arrival_probability_expression: str
    critical_value: SensorCriticalValue
    surfaces: SensorSurfaces
    margin: SensorMargin
    n_minus_1: SensorNMinus1
    link: SensorLink = opt_key()


@dataclass(frozen=True, kw_only=True)
class UniformMargin:
    """`network.uniform_margin`"""

    value: float | None
    interval: list[float | None] | None
    """None when δ is unbounded (``unbounded`` says which way)."""
    unbounded: str | None
    """``positive`` (mean-stable with every link dead), ``negative`` (a necessary constraint
    fails even with every link perfect) or None."""
    rule: str
    reason: str


@dataclass(frozen=True, kw_only=True)
class NetworkNMinus1:
    """`network.n_minus_1[]`"""

    name: str
    verdict: str
    reason: str
    facts: StabilityFactsRecord = opt_key()
    burst_facts: StabilityFactsRecord = opt_key()


@dataclass(frozen=True, kw_only=True)
class NetworkBottleneck:
    """`network.bottleneck`: the named bottleneck sensor, or (``name`` None) why the margin
    bounds name none and which sensors they cannot rank (``candidates``)."""

    name: str | None
    margin: float | None
    margin_interval: list[float | None] = opt_key()
    rule: str
    reason: str = opt_key()
    candidates: list[str] = opt_key()


@dataclass(frozen=True, kw_only=True)
class NecessaryConstraint:
    """`network.necessary_constraints[]`"""

    unobservable_without: list[str]
    blind_sensors: list[str]
    eigenvalue: str
    modulus2: float | None
    modulus2_expression: str | None
    """|λ|² exactly; None when the eigenvalue is only known in floats (e.g. n beyond the exact
    structure path)."""
    decided: str
    condition: str


@dataclass(frozen=True, kw_only=True)
class ExactRegion:
    """`network.exact_region`"""

    holds: bool
    reason: str
    basis: str


@dataclass(frozen=True, kw_only=True)
class NetworkMethod:
    """`network.method`"""

    received_sets: int
    all_received_sets: bool
    tolerance: float | None
    ball_checked: bool
    newton: int
    bisection: int
    certificates: int
    decided_by: str = opt_key()
    """``received-sets`` (docs/theory.md §9.3) or ``sequential`` (one-sensor maps, §15)."""


@dataclass(frozen=True, kw_only=True)
class DeadLinkBurst:
    """`network.burst_condition.n_minus_1[name]`: the burst condition with that sensor dead."""

    holds: bool | None
    facts: StabilityFactsRecord


@dataclass(frozen=True, kw_only=True)
class NetworkBurstCondition:
    """`network.burst_condition`: the burst condition of the bursty links (theory §9–§10) at
    the operating point and with each sensor dead."""

    holds: bool | None
    statement: str
    continuation: dict[str, float | None]
    facts: StabilityFactsRecord = opt_key()
    n_minus_1: dict[str, DeadLinkBurst] = opt_key()


@dataclass(frozen=True, kw_only=True)
class NetworkSection:
    """`network`"""

    verdict: str
    reason: str
    basis: str
    sensors: list[NetworkSensor]
    uniform_margin: UniformMargin
    n_minus_1: list[NetworkNMinus1]
    bottleneck: NetworkBottleneck
    necessary_constraints: list[NecessaryConstraint]
    exact_region: ExactRegion
    certificate: NetworkCertificate | None
    method: NetworkMethod
    claims: list[str]
    warnings: list[str]
    burst_condition: NetworkBurstCondition = opt_key()
    facts: StabilityFactsRecord = opt_key()
    stacked_critical_value: CriticalValueRecord | None = opt_key()
    """The stacked system's critical value (the record's top-level one), repeated by name."""
    stacked_upper_bound: UpperBoundRecord | None = opt_key()
    stacked_meaning: str = opt_key()
