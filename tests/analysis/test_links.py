"""The link policy check of kfcrit.analysis.links.design_check (a typed DesignCheck)."""
from __future__ import annotations

from kfcrit.analysis.links import design_check
from kfcrit.analysis.verdict import CheckStatus, link_reasons
from kfcrit.io.typed import ABSENT


def section(margin, needed=5.0, design=0.36, unbounded=False, outage=0.0):
    return {"applicable": True, "link_margin_db": margin, "max_distance_unbounded": unbounded,
            "max_distance_m": None if unbounded else 100.0,
            "margin_policy": {"effective_margin_db": needed, "max_outage": 0.1},
            "link": {"distance_m": 105.0},
            "required_arrival_probability": {"design_value": design, "basis": "p_c"},
            "thresholds": [{"arrival_probability": design, "outage_probability": outage}]}


def test_a_requirement_of_p_zero_has_an_unbounded_margin_and_meets_the_policy():
    # p_c = 0 (marginal modes): every SINR gives p > 0, so no finite margin is needed
    dc = design_check(section(None, design=0.0, unbounded=True))
    assert dc.margin_policy_met is True and dc.margin_unbounded is True
    reasons = link_reasons(dc)
    assert [r.status for r in reasons] == [CheckStatus.PASS, CheckStatus.PASS]
    assert "unbounded" in reasons[0].detail


def test_a_finite_margin_is_compared_with_the_policy():
    assert design_check(section(6.0)).margin_policy_met is True
    assert design_check(section(4.0)).margin_policy_met is False
    assert design_check(section(4.0)).margin_unbounded is ABSENT   # the key is left out


def test_a_missing_margin_with_a_positive_requirement_stays_unknown():
    dc = design_check(section(None, design=0.36, unbounded=False))
    assert dc.margin_policy_met is None
