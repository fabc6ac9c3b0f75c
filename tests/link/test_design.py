"""Design inversion: [p_S, p_V] into distance, power, payload and retries (MATH §11).

Expected values: the log-distance law solved by hand for distance and power, and direct
evaluation of the written-out O-QPSK formula (50-digit mpmath) on either side of every
returned bound for payload and retries.
"""
from __future__ import annotations

import math

import mpmath as mp
import pytest

from kfcrit.link.design import RequirementInterval, link_design
from kfcrit.link.linkbudget import LinkBudget

MAC = 11
PHY = 4 + 1 + 1
"""PHY header (preamble, SFD, PHR): the PER covers the PPDU by default (per_over: ppdu)."""
LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "100", "packet_bytes": "40", "margin_db": "2",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}
NOISE = 10 * math.log10(1.380649e-23 * 290 * 2e6 * 1e3) + 10


def arrival(sinr_db: float, psdu: int, retries: int) -> float:
    """1 − PER^{k+1} from the written-out 802.15.4 BER at 50 digits."""
    with mp.workdps(50):
        s = mp.power(10, mp.mpf(sinr_db) / 10)
        ber = mp.mpf(8) / 15 / 16 * mp.fsum((-1) ** k * mp.binomial(16, k)
                                           * mp.e ** (20 * s * (mp.mpf(1) / k - 1))
                                           for k in range(2, 17))
        return float(1 - (1 - (1 - ber) ** (8 * psdu)) ** (retries + 1))


def required_sinr(p: float, psdu: int, retries: int) -> float:
    lo, hi = -20.0, 30.0
    for _ in range(100):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if arrival(mid, psdu, retries) < p else (lo, mid)
    return hi


@pytest.fixture(scope="module")
def design():
    link = LinkBudget.from_mapping({**LINK, "distance_m": "90"}, "channel")
    return link, link_design(link, necessary=0.6, sufficient=0.9)


def test_distance_and_power_solve_the_budget_by_hand(design) -> None:
    link, d = design
    for end, p in (("sufficient", 0.9), ("necessary", 0.6)):
        s = required_sinr(p, PHY + 40 + MAC, 0)
        dist = getattr(d.max_distance, end)
        assert dist.status == "value"
        # 0 − (40.2 + 30 log10 d) − N − 2 = s
        assert dist.value == pytest.approx(10 ** ((0 - NOISE - 2 - s - 40.2) / 30), rel=1e-8)
        pw = getattr(d.min_tx_power, end)
        assert pw.value == pytest.approx(s + NOISE + 40.2 + 30 * math.log10(90) + 2, abs=1e-7)
    # the interval is ordered: a guaranteed distance is shorter than the failing one
    assert d.max_distance.sufficient.value < d.max_distance.necessary.value
    assert d.min_tx_power.sufficient.value > d.min_tx_power.necessary.value


def test_payload_bound_is_the_last_byte_that_meets_the_requirement(design) -> None:
    link, d = design
    s = link.sinr_db - 2.0
    for end, p in (("sufficient", 0.9), ("necessary", 0.6)):
        b = getattr(d.max_payload, end)
        assert b.status == ("value" if end == "sufficient" else "phy-limit")
        if b.status == "value":
            length = PHY + b.value + MAC
            assert arrival(s, length, 0) >= p > arrival(s, length + 1, 0)
        else:
            assert b.status == "phy-limit" and b.value == 127 - MAC
            assert arrival(s, PHY + 127, 0) >= p


def test_retries_needed_is_the_least_k(design) -> None:
    link, _ = design
    far = link.with_changes(distance_m=100.0)
    d = link_design(far, necessary=0.6, sufficient=0.99)
    s = far.sinr_db - 2.0
    for end, p in (("sufficient", 0.99), ("necessary", 0.6)):
        b = getattr(d.retries_needed, end)
        assert b.status == "value"
        k = b.value
        assert arrival(s, PHY + 40 + MAC, k) >= p
        assert k == 0 or arrival(s, PHY + 40 + MAC, k - 1) < p
    assert d.retries_needed.sufficient.value >= d.retries_needed.necessary.value >= 1


def test_unreachable_and_unbounded_ends_are_labelled() -> None:
    dead = LinkBudget.from_mapping({**LINK, "distance_m": "5000"}, "channel")
    d = link_design(dead, necessary=0.0, sufficient=0.999)
    assert d.retries_needed.sufficient.status == "unreachable"
    assert d.max_payload.sufficient.status == "unreachable"
    assert d.max_distance.necessary.status == "unbounded"  # p_S = 0 needs no SINR
    with pytest.raises(ValueError):
        RequirementInterval(0.9, 0.6)
    rec = d.to_dict()
    assert rec["required_arrival_probability"]["interval"] == [0.0, 0.999]
    assert set(rec) >= {"max_distance_m", "min_tx_power_dbm", "max_payload_bytes",
                        "retries_needed", "margin_db", "notes"}
    assert rec["max_distance_m"]["interval"][1] is None
