"""The link policy check: :func:`kfcrit.link.budgetsection.policy_check` (a typed DesignCheck),
as :func:`kfcrit.analysis.links.design_check` reads it from the section and its JSON form."""
from __future__ import annotations

from dataclasses import replace

from kfcrit.analysis.verdict import CheckStatus, link_reasons
from kfcrit.io.typed import ABSENT
from kfcrit.link.budgetsection import policy_check
from kfcrit.link.requirement import binding_requirement, stability_requirement
from kfcrit.records.link import LinkThreshold, MarginPolicy, Shadowing


def check(margin, needed=5.0, design=0.36, unbounded=False, outage=0.0):
    """The check of a link whose margin over the requirement ``design`` is ``margin`` dB."""
    need = binding_requirement(stability_requirement(design, None, None, None))
    row = LinkThreshold(label="design", arrival_probability=design, required_sinr_db=None,
                        required_rx_power_dbm=None, link_margin_db=margin,
                        max_distance_m=None if unbounded else 100.0,
                        max_distance_unbounded=unbounded, outage_probability=outage,
                        reachable=True)
    policy = MarginPolicy(margin_db=2.0, max_outage=0.1, effective_margin_db=needed,
                          rule="keep the margin")
    shadowing = Shadowing(sigma_db=4.0, mode="per-link", mean_arrival_probability=0.9,
                          outage_below_critical=None, outage_below_upper=None)
    return policy_check(need, row, [replace(row, label="critical_value")], policy, shadowing,
                        105.0)


def test_a_requirement_of_p_zero_has_an_unbounded_margin_and_meets_the_policy():
    # p_c = 0 (marginal modes): every SINR gives p > 0, so no finite margin is needed
    dc = check(None, design=0.0, unbounded=True)
    assert dc.margin_policy_met is True and dc.margin_unbounded is True
    reasons = link_reasons(dc)
    assert [r.status for r in reasons] == [CheckStatus.PASS, CheckStatus.PASS]
    assert "unbounded" in reasons[0].detail


def test_a_finite_margin_is_compared_with_the_policy():
    assert check(6.0).margin_policy_met is True
    assert check(4.0).margin_policy_met is False
    assert check(4.0).margin_unbounded is ABSENT   # the key is left out


def test_a_missing_margin_with_a_positive_requirement_stays_unknown():
    dc = check(None, design=0.36, unbounded=False)
    assert dc.margin_policy_met is None


