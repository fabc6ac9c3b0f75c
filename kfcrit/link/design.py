r"""Design inversion: an arrival-probability requirement in radio terms (theory §11).

An accuracy requirement lim E[tr P] ≤ L gives an interval [p_S, p_V] of arrival probabilities:
p ≥ p_V is sufficient (tr V̄(p_V) = L), p < p_S fails (tr S̄(p_S) = L). The link's arrival
probability is monotone in distance, transmit power, payload size and retries, so each end maps
to a bound on the radio parameter by a monotone inversion:

* maximum distance — closed form through the required SINR s(p) and the path-loss inverse:
  Pt + G − PL(d) − (N ⊕ I) − m = s(p);
* minimum transmit power — closed form: Pt = s(p) + (N ⊕ I) + PL(d) − G + m;
* maximum payload — bisection over whole bytes, p decreasing in the PSDU length;
* retries needed — the least k with 1 − PER^{k+1} ≥ p (searched up to the standard's maximum).

m is the margin the design keeps (default: the link's margin policy, max(margin_db,
σ·Φ^{-1}(1 − max_outage))); "meets p" means p(s_0 − m) ≥ p, with p(·) the link's stationary
arrival probability at median SINR (retries and per-packet shadowing averages included).

Each bound is an interval: the *sufficient* value (from p_V) guarantees the requirement, the
*necessary* value (from p_S) is the limit beyond which it fails; between them the bounds of
§11 do not decide. For time-correlated (bursty) shadowing the interval, an i.i.d. result, is
computed from the stationary arrival probability and labelled as not deciding.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from kfcrit.io.typed import to_json
from kfcrit.link.linkbudget import MAX_PAYLOAD_BYTES, LinkBudget
from kfcrit.records.link import (
    LinkDesignBound,
    LinkDesignDistance,
    LinkDesignPayload,
    LinkDesignPayloadBound,
    LinkDesignRecord,
    LinkDesignRequirement,
)

STATUSES = ("value", "unbounded", "unreachable", "phy-limit")
"""``value``: a finite bound; ``unbounded``: no limit (any distance, any power is enough);
``unreachable``: no setting of this parameter meets the requirement; ``phy-limit``: every
payload the PHY allows meets it (the value is the PHY's largest payload)."""


@dataclass(frozen=True)
class RequirementInterval:
    """The required arrival probability: p_S (necessary end) ≤ p_V (sufficient end)."""

    necessary: float
    sufficient: float

    def __post_init__(self) -> None:
        lo, hi = float(self.necessary), float(self.sufficient)
        if not (0.0 <= lo <= hi <= 1.0):
            raise ValueError(f"need 0 <= p_S <= p_V <= 1, got [{lo!r}, {hi!r}]")

    def record(self) -> LinkDesignRequirement:
        return LinkDesignRequirement(interval=[self.necessary, self.sufficient],
                                     necessary=self.necessary, sufficient=self.sufficient)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


@dataclass(frozen=True)
class Bound:
    """One end of a radio bound: its value and what kind of value it is (:data:`STATUSES`)."""

    value: float | int | None
    status: str


@dataclass(frozen=True)
class RadioBound:
    """A radio parameter's bound as an interval [sufficient end, necessary end].

    ``sense`` is ``"at most"`` (distance, payload) or ``"at least"`` (power, retries): the
    parameter must be at most / at least the sufficient value to guarantee the requirement, and
    at most / at least the necessary value not to fail it.
    """

    quantity: str
    unit: str
    sense: str
    sufficient: Bound
    necessary: Bound
    method: str

    @property
    def interval(self) -> list[float | int | None]:
        return [self.sufficient.value, self.necessary.value]

    def distance_record(self) -> LinkDesignDistance:
        """The bound as the record states a real-valued one (distance, transmit power)."""
        return LinkDesignDistance(
            quantity=self.quantity, unit=self.unit, sense=self.sense, interval=self.interval,
            sufficient=LinkDesignBound(value=self.sufficient.value, status=self.sufficient.status),
            necessary=LinkDesignBound(value=self.necessary.value, status=self.necessary.status),
            method=self.method)

    def count_record(self) -> LinkDesignPayload:
        """The bound as the record states a whole-number one (payload bytes, retries)."""
        return LinkDesignPayload(
            quantity=self.quantity, unit=self.unit, sense=self.sense, interval=self.interval,
            sufficient=LinkDesignPayloadBound(value=self.sufficient.value,
                                              status=self.sufficient.status),
            necessary=LinkDesignPayloadBound(value=self.necessary.value,
                                             status=self.necessary.status),
            method=self.method)


@dataclass(frozen=True)
class LinkDesign:
    """The requirement [p_S, p_V] in radio terms for one link (see the module docstring)."""

    requirement: RequirementInterval
    margin_db: float
    max_distance: RadioBound
    min_tx_power: RadioBound
    max_payload: RadioBound
    retries_needed: RadioBound
    notes: tuple[str, ...] = field(default=())

    def record(self) -> LinkDesignRecord:
        """The design as the record states it (``design.radio``)."""
        return LinkDesignRecord(required_arrival_probability=self.requirement.record(),
                                margin_db=self.margin_db,
                                max_distance_m=self.max_distance.distance_record(),
                                min_tx_power_dbm=self.min_tx_power.distance_record(),
                                max_payload_bytes=self.max_payload.count_record(),
                                retries_needed=self.retries_needed.count_record(),
                                notes=list(self.notes))

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


def _margin(link: LinkBudget, margin_db: float | None) -> float:
    return link.effective_margin_db if margin_db is None else float(margin_db)


def _required_sinr(link: LinkBudget, p: float) -> tuple[float | None, str]:
    """(s(p), status): ``unbounded`` when no SINR is needed, ``unreachable`` when none does."""
    if p >= 1.0:
        return None, "unreachable"
    try:
        s = link.required_sinr_db(p)
    except ValueError:
        return None, "unreachable"
    return (None, "unbounded") if s is None else (s, "value")


def meets(link: LinkBudget, p: float, margin_db: float = 0.0) -> bool:
    """Whether the link keeps ``margin_db`` in reserve and still reaches p: p(s_0 − m) ≥ p."""
    return link.effective_arrival(link.sinr_db - margin_db) >= p


def distance_bound(link: LinkBudget, p: float, margin_db: float | None = None) -> Bound:
    r"""Largest distance d with p(s_0(d) − m) ≥ p.

    .. math:: PL(d) = P_t + G - (N \oplus I) - m - s(p)
    """
    s, status = _required_sinr(link, p)
    if s is None:
        return Bound(None, status)
    d = link.max_distance_m(s, _margin(link, margin_db))
    return Bound(d, "value") if d is not None else Bound(None, "unbounded")


def tx_power_bound(link: LinkBudget, p: float, margin_db: float | None = None) -> Bound:
    r"""Least transmit power (dBm) with p(s_0 − m) ≥ p at the configured distance.

    .. math:: P_t = s(p) + (N \oplus I) + PL(d) - G + m
    """
    s, status = _required_sinr(link, p)
    if s is None:
        return Bound(None, status)
    return Bound(s + link.noise.total_dbm + link.path_loss_db - link.antenna_gain_db
                 + _margin(link, margin_db), "value")


def payload_bound(link: LinkBudget, p: float, margin_db: float | None = None) -> Bound:
    """Largest payload (bytes) with p(s_0 − m) ≥ p: bisection, p decreasing in the length."""
    m = _margin(link, margin_db)
    top = link.radio.frame.max_payload_bytes(link.mac_overhead_bytes) or MAX_PAYLOAD_BYTES
    if top < 1 or not meets(link.with_changes(packet_bytes=1), p, m):
        return Bound(None, "unreachable")
    if meets(link.with_changes(packet_bytes=top), p, m):
        return Bound(top, "phy-limit" if link.radio.frame.max_psdu_bytes else "unbounded")
    lo, hi = 1, top  # invariant: lo meets p, hi does not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if meets(link.with_changes(packet_bytes=mid), p, m) else (lo, mid)
    return Bound(lo, "value")


def retries_bound(link: LinkBudget, p: float, margin_db: float | None = None) -> Bound:
    """Least number of MAC retries k with p(s_0 − m) ≥ p (up to the standard's maximum)."""
    m = _margin(link, margin_db)
    for k in range(link.radio.frame.max_retries + 1):
        if meets(link.with_changes(max_retries=k), p, m):
            return Bound(k, "value")
    return Bound(None, "unreachable")


def _pair(quantity: str, unit: str, sense: str, method: str, fn: Any, link: LinkBudget,
          req: RequirementInterval, margin_db: float) -> RadioBound:
    return RadioBound(quantity, unit, sense, fn(link, req.sufficient, margin_db),
                      fn(link, req.necessary, margin_db), method)


def link_design(link: LinkBudget, necessary: float, sufficient: float,
                margin_db: float | None = None) -> LinkDesign:
    """The requirement interval [p_S, p_V] as bounds on distance, power, payload and retries.

    Parameters
    ----------
    link : LinkBudget
        The configured link (its other parameters stay fixed while one is inverted).
    necessary, sufficient : float
        p_S and p_V (0 ≤ p_S ≤ p_V ≤ 1).
    margin_db : float, optional
        SINR reserve kept by the design (default: the link's margin policy).

    Returns
    -------
    LinkDesign
    """
    req = RequirementInterval(float(necessary), float(sufficient))
    m = _margin(link, margin_db)
    notes = [f"each bound holds with the other parameters as configured and {m:.4g} dB of "
             "SINR kept in reserve; the sufficient end (from p_V) guarantees the requirement, "
             "beyond the necessary end (from p_S) it fails"]
    if link.time_correlated:
        notes.append("time-correlated shadowing: losses are bursty, so an i.i.d. requirement "
                     "interval computed from the stationary arrival probability does not "
                     "decide the requirement")
    return LinkDesign(
        requirement=req, margin_db=m,
        max_distance=_pair("distance", "m", "at most",
                           "closed form: PL(d) = Pt + G - (N+I) - m - s(p)", distance_bound,
                           link, req, m),
        min_tx_power=_pair("transmit power", "dBm", "at least",
                           "closed form: Pt = s(p) + (N+I) + PL(d) - G + m", tx_power_bound,
                           link, req, m),
        max_payload=_pair("payload", "bytes", "at most",
                          "bisection over whole bytes (p decreasing in the PSDU length)",
                          payload_bound, link, req, m),
        retries_needed=_pair("MAC retries", "retries", "at least",
                             "least k with 1 - PER^(k+1) >= p, k up to the standard's maximum",
                             retries_bound, link, req, m),
        notes=tuple(notes))

