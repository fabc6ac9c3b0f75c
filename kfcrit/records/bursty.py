"""The Gilbert–Elliott section (``link_budget`` of a bursty channel, ``link_budget.bursty`` of a
link budget with time-correlated shadowing): the conditions of theory §7 and §10, the coupled
certificate, the critical curve and the simulation check.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from kfcrit.io.typed import opt_key
from kfcrit.records.bounds import CertificateCheck


@dataclass(frozen=True, kw_only=True)
class StabilityFactsRecord:
    """What the theory establishes at this operating point (``facts`` of a network or bursty
    section): the necessary and the sufficient condition, each with its basis."""

    necessary: bool | None
    sufficient: bool
    exact_region: bool
    necessary_basis: str
    sufficient_basis: str


@dataclass(frozen=True, kw_only=True)
class BurstCondition:
    """`@GilbertElliottSection.condition`"""

    expression: str
    value: float | None
    holds: bool
    status: str
    decides: bool


@dataclass(frozen=True, kw_only=True)
class BurstSimulationCheck:
    """`@GilbertElliottSection.simulation`"""

    paths: int
    steps: int
    seed: int
    horizon_rule: str
    mean_half: float | None
    mean_end: float | None
    growth_ratio: float | None
    expected_growth_if_unbounded: float | None
    capped: bool
    simulator: str


@dataclass(frozen=True, kw_only=True)
class LiteratureClaim:
    """`@GilbertElliottSection.claims[]`"""

    statement: str
    source: str
    status: str


@dataclass(frozen=True, kw_only=True)
class NecessaryBurstCondition:
    """`@GilbertElliottSection.certificate.necessary`"""

    holds: bool
    value: float | None
    enclosure: list[float | None]
    rho2: float | None
    rho2_expression: str | None
    recovery_rate: float | None
    rigorous: bool
    how: str
    statement: str
    condition: str


@dataclass(frozen=True, kw_only=True)
class CoupledCertificateMatrices:
    """`@GilbertElliottSection.certificate.certificate.matrices`"""

    K: list[list[float | None]]
    X0: list[list[float | None]]
    X1: list[list[float | None]]
    K1: list[list[float | None]] = opt_key()
    """The gain after a reception when the gains depend on the previous arrival (``K`` is then
    the gain after a loss; theory §10)."""


@dataclass(frozen=True, kw_only=True)
class CoupledCertificate:
    """`@GilbertElliottSection.certificate.certificate`"""

    certified: bool
    failure_rate: float | None
    recovery_rate: float | None
    spectral_radius: float | None
    gain_origin: str | None
    check: CertificateCheck | None
    reason: str
    lmi_margin: float | None
    matrices: CoupledCertificateMatrices | None
    kind: str


@dataclass(frozen=True, kw_only=True)
class BurstClaim:
    """`@GilbertElliottSection.certificate.claim`"""

    label: str
    source: str
    statement: str
    verdict_if_true: str
    stable_if_true: bool = opt_key()


@dataclass(frozen=True, kw_only=True)
class BurstCertificateRecord:
    """`@GilbertElliottSection.certificate`"""

    verdict: str
    basis: str
    failure_rate: float | None
    recovery_rate: float | None
    stationary_arrival: float | None
    necessary: NecessaryBurstCondition
    certificate: CoupledCertificate | None
    claim: BurstClaim | None
    facts: StabilityFactsRecord = opt_key()


@dataclass(frozen=True, kw_only=True)
class RatesPoint:
    """`@GilbertElliottSection.critical_curve.operating_point`"""

    failure_rate: float | None
    recovery_rate: float | None


@dataclass(frozen=True, kw_only=True)
class BurstCurveRecord:
    """`@GilbertElliottSection.critical_curve`"""

    failure_rates: list[float | None]
    necessary_recovery: list[float | None]
    necessary_expression: str | None
    sufficient_recovery: list[float | None]
    tolerance: float | None
    method: str
    operating_point: RatesPoint
    notes: list[str]
    meaning: str


@dataclass(frozen=True, kw_only=True)
class GilbertElliottSection:
    """`@GilbertElliottSection`"""

    applicable: bool
    failure_rate: float | None
    recovery_rate: float | None
    stationary_arrival_probability: float | None
    mean_burst_length: float | None
    spectral_radius: float | None
    classification: str
    condition: BurstCondition
    required_recovery_rate: float | None
    max_mean_burst_length: float | None
    simulation: BurstSimulationCheck | None
    simulation_consistent: bool | None
    simulation_note: str | None
    claims: list[LiteratureClaim]
    certificate: BurstCertificateRecord = opt_key()
    critical_curve: BurstCurveRecord = opt_key()
    facts: StabilityFactsRecord = opt_key()


def facts_record(facts: Any) -> StabilityFactsRecord:
    """The record form of the theory's :class:`kfcrit.theory.facts.StabilityFacts`."""
    necessary = facts.necessary
    return StabilityFactsRecord(necessary=None if necessary is None else bool(necessary),
                                sufficient=bool(facts.sufficient),
                                exact_region=bool(facts.exact_region),
                                necessary_basis=str(facts.necessary_basis),
                                sufficient_basis=str(facts.sufficient_basis))
