"""The ``link_budget`` section of a link-budget channel: the link, its margin policy and
thresholds, the shadowing, the design check and the curves the report draws.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key
from kfcrit.records.bursty import GilbertElliottSection
from kfcrit.records.channel import FrameRecord, RadioRecord, ShadowingMarkovRecord


@dataclass(frozen=True, kw_only=True)
class LinkDesignRequirement:
    """`@LinkDesignRecord.required_arrival_probability`"""

    interval: list[float | None]
    necessary: float | None
    sufficient: float | None


@dataclass(frozen=True, kw_only=True)
class LinkDesignBound:
    """`@LinkDesignRecord.max_distance_m.sufficient`"""

    value: float | None
    status: str


@dataclass(frozen=True, kw_only=True)
class LinkDesignDistance:
    """`@LinkDesignRecord.max_distance_m`"""

    quantity: str
    unit: str
    sense: str
    interval: list[float | None]
    sufficient: LinkDesignBound
    necessary: LinkDesignBound
    method: str


@dataclass(frozen=True, kw_only=True)
class LinkDesignPayloadBound:
    """`@LinkDesignRecord.max_payload_bytes.sufficient`"""

    value: float | None
    status: str


@dataclass(frozen=True, kw_only=True)
class LinkDesignPayload:
    """`@LinkDesignRecord.max_payload_bytes`"""

    quantity: str
    unit: str
    sense: str
    interval: list[float | None]
    sufficient: LinkDesignPayloadBound
    necessary: LinkDesignPayloadBound
    method: str


@dataclass(frozen=True, kw_only=True)
class LinkDesignRecord:
    """`@LinkDesignRecord`"""

    required_arrival_probability: LinkDesignRequirement
    margin_db: float | None
    max_distance_m: LinkDesignDistance
    min_tx_power_dbm: LinkDesignDistance
    max_payload_bytes: LinkDesignPayload
    retries_needed: LinkDesignPayload
    notes: list[str]


@dataclass(frozen=True, kw_only=True)
class LinkState:
    """`@LinkState`"""

    tx_power_dbm: float | None
    antenna_gain_db: float | None
    distance_m: float | None
    packet_bytes: int
    psdu_bytes: int
    per_bytes: int = opt_key()
    max_retries: int
    path_loss_db: float | None
    rx_power_dbm: float | None
    noise_floor_dbm: float | None
    bandwidth_hz: float | None
    noise_figure_db: float | None
    temperature_k: float | None
    interference_dbm: float | None
    noise_plus_interference_dbm: float | None
    sinr_db: float | None
    sinr_linear: float | None
    bit_error_rate: float | None
    packet_error_rate: float | None
    attempt_arrival_probability: float | None
    arrival_probability_nominal: float | None
    arrival_probability_mean: float | None
    arrival_probability: float | None


@dataclass(frozen=True, kw_only=True)
class MarginPolicy:
    """`@MarginPolicy`"""

    margin_db: float | None
    max_outage: float | None
    effective_margin_db: float | None
    rule: str


@dataclass(frozen=True, kw_only=True)
class DesignCheck:
    """`@DesignCheck`"""

    link_margin_db: float | None
    required_margin_db: float | None
    margin_policy_met: bool | None
    distance_m: float | None
    max_distance_m: float | None
    outage_probability: float | None
    max_outage: float | None
    outage_within_policy: bool | None
    design_value: float | None = opt_key()
    basis: str = opt_key()
    requirement_reachable: bool = opt_key()
    margin_unbounded: bool = opt_key()
    """True when the requirement is p = 0 (p_c = 0): every SINR meets it, so the link margin
    (``link_margin_db`` null) is unbounded and the policy is met."""


@dataclass(frozen=True, kw_only=True)
class Shadowing:
    """`@Shadowing`"""

    sigma_db: float | None
    mode: str
    mean_arrival_probability: float | None
    outage_below_critical: float | None
    outage_below_upper: float | None


@dataclass(frozen=True, kw_only=True)
class Accuracy:
    """`@RequiredArrival.accuracy`"""

    requirement: str
    status: str
    interval: list[float | None] | None
    """[p_S, p_V]; None when the accuracy design gives no interval (``impossible``, or not
    computed)."""
    p_S_certified: bool
    p_V_certified: bool
    reason: str


@dataclass(frozen=True, kw_only=True)
class RequiredArrivalDesign:
    """`@RequiredArrival`"""

    critical_value: float | None
    robust_value: float | None
    bracket: list[float | None] | None
    design_value: float | None
    basis: str
    binding: str = opt_key()
    stability_value: float | None = opt_key()
    stability_basis: str = opt_key()
    accuracy: Accuracy = opt_key()
    fails_below: float | None = opt_key()
    determined: bool = opt_key()
    short_basis: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class LinkThreshold:
    """`link_budget.thresholds[]`"""

    label: str
    arrival_probability: float | None
    required_sinr_db: float | None
    required_rx_power_dbm: float | None
    link_margin_db: float | None
    max_distance_m: float | None
    max_distance_unbounded: bool
    outage_probability: float | None
    reachable: bool


@dataclass(frozen=True, kw_only=True)
class ArrivalVsDistance:
    """`link_budget.curves.arrival_vs_distance`"""

    distance_m: list[float | None]
    arrival: list[float | None]
    mean_arrival: list[float | None] | None
    """None without shadowing (the median link is the only curve)."""
    configured_distance_m: float | None
    max_retries: int
    psdu_bytes: int


@dataclass(frozen=True, kw_only=True)
class PerVsSinr:
    """`link_budget.curves.per_vs_sinr`"""

    radio: str
    sinr_db: list[float | None]
    psdu_bytes: list[int]
    per: list[list[float | None]]
    header_bytes: int = opt_key()


@dataclass(frozen=True, kw_only=True)
class OutageVsDistance:
    """`link_budget.curves.outage_vs_distance`"""

    distance_m: list[float | None]
    requirements: list[list[str | float | None]]
    outage: list[list[float | None]]
    sigma_db: float | None
    max_outage: float | None
    configured_distance_m: float | None


@dataclass(frozen=True, kw_only=True)
class LinkCurves:
    """`link_budget.curves`"""

    arrival_vs_distance: ArrivalVsDistance
    per_vs_sinr: PerVsSinr
    marks: dict[str, float | None]
    outage_vs_distance: OutageVsDistance = opt_key()


@dataclass(frozen=True, kw_only=True)
class LinkBudgetRecord:
    """`link_budget`"""

    applicable: bool
    radio: RadioRecord
    link: LinkState
    margin_policy: MarginPolicy
    required_arrival_probability: RequiredArrivalDesign
    max_distance_unbounded: bool
    mean_stable_at_distance: bool
    shadowing: Shadowing
    thresholds: list[LinkThreshold]
    notes: list[str]
    design_check: DesignCheck
    warnings: list[str]
    frame: FrameRecord
    curves: LinkCurves = opt_key()
    required_sinr_db: float | None = opt_key()
    required_rx_power_dbm: float | None = opt_key()
    link_margin_db: float | None = opt_key()
    max_distance_m: float | None = opt_key()
    gilbert_elliott: ShadowingMarkovRecord | None = opt_key()
    bursty: GilbertElliottSection = opt_key()
