"""The ``link_budget`` section built as its record classes by the link layer.

The typed section must be a valid record (its JSON form reads back strictly as the same
class), whatever the accuracy design says — an interval, no interval (``impossible``, or not
computed) — and the plain forms other code reads (``design_section``, ``LinkBudget.frame_dict``)
are that section's JSON.
"""
from __future__ import annotations

import json

import pytest

from kfcrit.io.typed import from_json, to_json
from kfcrit.link.budgetsection import frame_record, link_budget_record
from kfcrit.link.linkbudget import FRAME_KEYS, LinkBudget, design_section
from kfcrit.records.link import LinkBudgetRecord

LINK = {"radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0", "distance_m": "100",
        "packet_bytes": "40", "margin_db": "2", "max_outage": "0.1", "max_retries": "2",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2", "shadowing_sigma_db": "4"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def accuracy(interval, status: str, reason: str) -> dict:
    return {"requirement": "lim E[tr P] ≤ 10",
            "required_arrival_probability": {
                "status": status, "interval": interval, "reason": reason,
                "p_S": {"certified": True}, "p_V": {"certified": False}}}


@pytest.fixture(scope="module")
def link() -> LinkBudget:
    return LinkBudget.from_mapping(LINK, "channel")


@pytest.mark.parametrize("acc", [
    None,
    accuracy([0.375, 0.4125], "interval", "bounds"),
    accuracy(None, "impossible", "L below the no-loss floor"),
    accuracy(None, "undetermined", "Riccati iteration not converged"),
], ids=["none", "interval", "impossible", "undetermined"])
def test_section_reads_back_strictly_as_its_class(link, acc) -> None:
    rec = link_budget_record(link, critical_value=0.36, robust_value=None,
                             bracket=(None, None), upper_bound=0.4, accuracy=acc)
    assert from_json(LinkBudgetRecord, to_json(rec)) == rec
    assert design_section(link, critical_value=0.36, robust_value=None, bracket=(None, None),
                          upper_bound=0.4, accuracy=acc) == to_json(rec)
    json.dumps(to_json(rec), allow_nan=False)   # finite numbers only
    if acc is not None:
        summary = rec.required_arrival_probability.accuracy
        assert summary.interval == acc["required_arrival_probability"]["interval"]
        assert (summary.p_S_certified, summary.p_V_certified) == (True, False)


def test_impossible_requirement_leaves_no_design_value(link) -> None:
    rec = link_budget_record(link, critical_value=0.36, robust_value=None,
                             bracket=(None, None), upper_bound=None,
                             accuracy=accuracy(None, "impossible", "L below the floor"))
    assert rec.required_arrival_probability.design_value is None
    assert rec.design_check.requirement_reachable is False
    assert rec.design_check.margin_policy_met is False


def test_frame_dict_is_the_frame_record_in_the_channel_key_order(link) -> None:
    frame = frame_record(link)
    plain = link.frame_dict()
    assert tuple(plain) == FRAME_KEYS
    assert plain == to_json(frame)
    # 40-byte payload + 11-byte MAC header and FCS; the 6-byte PHY header adds to the PPDU
    assert (frame.psdu_bytes, frame.ppdu_bytes, frame.per_bytes) == (51, 57, 57)
    # 8 bits per PPDU byte at 250 kb/s, three attempts of airtime + 864 µs acknowledgement wait
    assert frame.airtime_s == pytest.approx(8 * 57 / 250e3, rel=1e-15)
    assert frame.attempts_duration_s == pytest.approx(3 * (8 * 57 / 250e3 + 864e-6), rel=1e-15)
