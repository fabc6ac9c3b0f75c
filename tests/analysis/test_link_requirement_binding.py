"""The link design reads its margin, distance and policy at the binding requirement
max(p_c, p_V) of an accuracy requirement (MATH §11).

Expected values, derived independently of the code under test:

* scalar plant x' = a x + w, y = x + v (q = r = 1): the Lyapunov bound tr S̄(p) = q / (1 − (1 − p)a²)
  gives p_S = 1 − (1 − q/L)/a²; the scalar MARE V = a²V + q − p a²V²/(V + r) at V = L gives
  p_V = (a²L + q − L)(L + r)/(a² L²);
* the radio: the 802.15.4 O-QPSK BER written out and evaluated at 50 digits (mpmath), the
  log-distance law SINR(d) = 0 − 40.2 − 30 log10 d − N solved by hand; the inversion is
  monotone, so the maximum distance is checked by the arrival probability at ± 1 %.
"""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from kfcrit.analysis.sweep.journal import valid_result
from kfcrit.analysis.sweep.points import RESULT_COLUMNS, row_of
from kfcrit.analysis.verdict import CheckStatus, link_reasons
from kfcrit.io.typed import ABSENT, to_json
from kfcrit.link.budgetsection import link_budget_record
from kfcrit.link.linkbudget import LinkBudget, design_section
from kfcrit.model.system import System
from kfcrit.theory.covariance.design import required_arrival

A, Q, R, L = 1.2, 1.0, 1.0, 10.0
P_C = 1 - 1 / A**2
P_S = 1 - (1 - Q / L) / A**2                        # 0.375
P_V = (A**2 * L + Q - L) * (L + R) / (A**2 * L**2)  # 0.4125
PSDU = 40 + 11
PPDU = 4 + 1 + 1 + PSDU
"""The PER covers the PHY header (preamble 4, SFD 1, PHR 1) too: per_over: ppdu (default)."""
MARGIN = 2.0
NOISE = 10 * math.log10(1.380649e-23 * 290 * 2e6 * 1e3) + 10
LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "100", "packet_bytes": "40", "margin_db": "2",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def arrival(sinr_db: float) -> float:
    """1 − PER of one attempt from the written-out 802.15.4 BER at 50 digits."""
    with mp.workdps(50):
        s = mp.power(10, mp.mpf(sinr_db) / 10)
        ber = mp.mpf(8) / 15 / 16 * mp.fsum((-1) ** k * mp.binomial(16, k)
                                           * mp.e ** (20 * s * (mp.mpf(1) / k - 1))
                                           for k in range(2, 17))
        return float((1 - ber) ** (8 * PPDU))


def sinr(distance: float) -> float:
    return 0 - 40.2 - 30 * math.log10(distance) - NOISE


def accuracy(interval, status="interval", reason=None) -> dict:
    return {"requirement": f"lim E[tr P] ≤ {L:g}",
            "required_arrival_probability": {"status": status, "interval": interval,
                                             "reason": reason}}


def section(link: LinkBudget, acc: dict | None) -> dict:
    args = {"critical_value": P_C, "robust_value": None, "bracket": (None, None),
            "upper_bound": None, "accuracy": acc}
    lb = design_section(link, **args)
    lb["design_check"] = link_budget_record(link, **args).design_check
    return lb


@pytest.fixture(scope="module")
def link() -> LinkBudget:
    return LinkBudget.from_mapping(LINK, "channel")


def test_scalar_closed_forms_match_the_accuracy_design() -> None:
    s = System(np.array([[A]]), np.array([[1.0]]), np.array([[Q]]), np.array([[R]]))
    req = required_arrival(s, L)
    assert req.status == "interval"
    assert req.interval[0] == pytest.approx(P_S, abs=1e-6)
    assert req.interval[1] == pytest.approx(P_V, abs=1e-6)
    assert P_C < P_S < P_V


def test_accuracy_binds_design_value_margin_and_distance(link) -> None:
    lb = section(link, accuracy([P_S, P_V]))
    req = lb["required_arrival_probability"]
    assert req["design_value"] == P_V
    assert req["binding"] == "accuracy" and req["stability_value"] == P_C
    assert req["fails_below"] == P_S and req["determined"] is False
    assert "p_V" in req["basis"] and "lim E[tr P] ≤ 10" in req["basis"]
    # the maximum distance at the policy: p(SINR(d) − m) crosses p_V there (monotone in d)
    d = lb["max_distance_m"]
    assert arrival(sinr(0.99 * d) - MARGIN) >= P_V > arrival(sinr(1.01 * d) - MARGIN)
    # the link margin is read against p_V: SINR(100 m) − s(p_V), s(p_V) found by bisection
    lo, hi = -20.0, 30.0
    for _ in range(80):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if arrival(mid) < P_V else (lo, mid)
    assert lb["link_margin_db"] == pytest.approx(sinr(100.0) - hi, abs=1e-6)
    # the stability verdict at the distance still compares with p_c
    assert lb["mean_stable_at_distance"] is (arrival(sinr(100.0)) > P_C)


def test_policy_check_and_review_use_the_binding_value(link) -> None:
    # d chosen between the p_c and the p_V distances: the margin to p_c passes, to p_V fails
    d_c, d_v = (section(link, acc)["max_distance_m"] for acc in (None, accuracy([P_S, P_V])))
    assert d_v < d_c
    near = link.with_changes(distance_m=0.5 * (d_c + d_v))
    plain, bound = section(near, None), section(near, accuracy([P_S, P_V]))
    assert plain["design_check"].margin_policy_met is True
    assert bound["design_check"].margin_policy_met is False
    assert bound["design_check"].design_value == P_V
    [reason] = link_reasons(bound["design_check"])
    assert reason.status is CheckStatus.FAIL and "0.4125" in reason.detail


def test_stability_binds_when_p_v_is_below_p_c(link) -> None:
    lb = section(link, accuracy([0.1, 0.2]))
    req = lb["required_arrival_probability"]
    assert req["design_value"] == P_C and req["binding"] == "stability"
    assert lb["max_distance_m"] == section(link, None)["max_distance_m"]


def test_impossible_requirement_has_no_margin_and_fails_the_policy(link) -> None:
    lb = section(link, accuracy(None, "impossible", "L below the floor"))
    assert lb["required_arrival_probability"]["design_value"] is None
    assert lb["max_distance_m"] is None and lb["link_margin_db"] is None
    dc = lb["design_check"]
    assert dc.requirement_reachable is False and dc.margin_policy_met is False
    assert {r.status for r in link_reasons(dc)} == {CheckStatus.FAIL}


def test_undetermined_interval_keeps_p_c_and_says_so(link) -> None:
    lb = section(link, accuracy(None, "undetermined", "Riccati not reached"))
    req = lb["required_arrival_probability"]
    assert req["design_value"] == P_C and req["determined"] is False
    assert "not included" in req["basis"]


def test_without_requirement_the_section_has_only_the_stability_fields(link) -> None:
    lb = section(link, None)
    assert set(lb["required_arrival_probability"]) == {
        "critical_value", "robust_value", "bracket", "design_value", "basis"}
    assert lb["required_arrival_probability"]["basis"] == "critical value p_c"
    assert lb["design_check"].design_value is ABSENT   # the key is left out
    assert not any(r["label"].startswith("accuracy") for r in lb["thresholds"])


def test_sweep_row_reads_the_binding_requirement(link) -> None:
    typed = section(link, accuracy([P_S, P_V]))
    lb = {**typed, "design_check": to_json(typed["design_check"])}   # the record's JSON form
    p = arrival(sinr(100.0))
    record = {"critical_value": {"value": P_C}, "link_budget": lb,
              "operating_point": {"arrival_probability": p, "iid": True,
                                  "verdict": "mean-stable"},
              "review": {"decision": "fail"}}
    row = row_of(record)
    assert row["requirement"] == P_V
    assert row["margin"] == pytest.approx(p - P_V, abs=1e-12)
    assert row["max_distance_m"] == lb["max_distance_m"]
    assert valid_result(row, RESULT_COLUMNS)
    stability = section(link, None)
    plain = row_of({**record, "link_budget": {**stability, "design_check": to_json(
        stability["design_check"])}})
    assert plain["requirement"] == P_C and plain["requirement_basis"] == "critical value"
