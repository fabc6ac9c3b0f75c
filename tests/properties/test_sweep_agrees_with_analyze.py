"""One decision, one place: a sweep row and ``analyze`` of the same point agree on the
stability verdict and the review decision (both come from :mod:`kfcrit.analysis.verdict`)."""
from __future__ import annotations

from pathlib import Path

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kfcrit
from kfcrit.analysis.spec import spec_from_mapping
from kfcrit.analysis.sweep import points as sweep_mod

from ..conftest import PROFILE

GENERAL = {"name": "general", "A": [[1.25, 0], [1, 1.1]], "C": [[1, 1]], "Q": 20, "R": 2.5}
"""Sinopoli's general example: p_c = 9/25, p_up = 57/121 (MATH §3)."""

THEORY: dict = {}
GE_EXAMPLES = 100 if PROFILE == "thorough" else 15
"""Each bursty point runs the coupled-certificate LMI (sweep row and analyze) and the critical curve."""


def row_and_record(doc: dict, assignments: list[tuple[str, str]]) -> tuple[dict, dict]:
    row = sweep_mod.evaluate_point(doc, ".", 1e-9, 400, assignments, THEORY)
    spec = spec_from_mapping(sweep_mod.apply_point(doc, assignments), base_dir=Path("."))
    record = kfcrit.analyze(spec, simulate=False).to_dict()
    return row, record


probability = st.fractions(min_value=0, max_value=1, max_denominator=50)
rate = st.fractions(min_value=sp.Rational(1, 50), max_value=1, max_denominator=50)


@settings(max_examples=12, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(p=probability)
def test_bernoulli_grid_points_agree(p) -> None:  # noqa: ANN001
    doc = {**GENERAL, "channel": {"model": "bernoulli", "arrival_probability": "0"}}
    row, rec = row_and_record(doc, [("channel.arrival_probability", f"{p.numerator}/"
                                                                     f"{p.denominator}")])
    assert row["status"] == "ok"
    assert row["verdict"] == rec["operating_point"]["verdict"]
    assert row["decision"] == rec["review"]["decision"]
    # hand: p > 9/25 is stable, p <= 9/25 unstable (Mo–Sinopoli Thm 4, non-degenerate)
    assert row["verdict"] == ("mean-stable" if p > sp.Rational(9, 25) else "mean-unstable")


@settings(max_examples=GE_EXAMPLES, suppress_health_check=[HealthCheck.too_slow],
          deadline=None)
@given(f=rate, r=rate)
def test_gilbert_elliott_grid_points_agree(f, r) -> None:  # noqa: ANN001
    doc = {**GENERAL, "channel": {"model": "gilbert-elliott", "failure_rate": "1/10",
                                  "recovery_rate": "1/2"}}
    row, rec = row_and_record(doc, [("channel.failure_rate", f"{f.numerator}/{f.denominator}"),
                                    ("channel.recovery_rate", f"{r.numerator}/{r.denominator}")])
    assert row["status"] == "ok"
    assert row["verdict"] == rec["operating_point"]["verdict"]
    assert row["decision"] == rec["review"]["decision"]
    # the margin of a bursty link is r − r_nec, r_nec = 1 − 1/ρ(A)² = 9/25 (by hand), as in
    # the record, never p − p_c
    assert row["margin"] == rec["operating_point"]["margin"]
    assert row["margin"] == pytest.approx(float(r - sp.Rational(9, 25)), abs=1e-12)
    # necessary burst condition (MATH §10): (1 − r)·ρ(A)² ≥ 1 ⇔ r ≤ 1 − 1/1.5625 = 9/25
    if r <= sp.Rational(9, 25) and f + r != 1:
        assert row["verdict"] == "mean-unstable" and row["decision"] == "fail"


def test_the_bursty_example_of_the_issue() -> None:
    """f = 0.1: r = 0.2 gives (1 − r)·ρ² = 1.25 > 1 (mean-unstable, fail) in both views."""
    doc = {**GENERAL, "channel": {"model": "gilbert-elliott", "failure_rate": 0.1,
                                  "recovery_rate": 0.5}}
    for r in ("0.5", "0.2"):
        row, rec = row_and_record(doc, [("channel.recovery_rate", r)])
        assert (row["verdict"], row["decision"]) == (rec["operating_point"]["verdict"],
                                                     rec["review"]["decision"])
    assert (row["verdict"], row["decision"]) == ("mean-unstable", "fail")


NETWORK = {"name": "net", "A": 2, "Q": 1, "sensors": [
    {"name": "a", "C": 1, "R": 1, "channel": {"model": "bernoulli", "arrival_probability": "0.6"}},
    {"name": "b", "C": 1, "R": 2, "channel": {"model": "bernoulli",
                                              "arrival_probability": "0.5"}}]}


@pytest.mark.parametrize("p_a, verdict", [("3/10", "mean-unstable"), ("1/2", "mean-unstable"),
                                          ("7/10", "mean-stable")])
def test_network_sweep_points_agree(p_a: str, verdict: str) -> None:
    """A scalar plant a = 2 seen by two sensors is stable iff (1 − p_a)(1 − p_b)·4 < 1
    (MATH §9); with p_b = 1/2 the boundary is p_a = 1/2 (unstable there)."""
    row, rec = row_and_record(NETWORK, [("sensors.a.channel.arrival_probability", p_a)])
    assert row["status"] == "ok"
    assert (row["verdict"], row["decision"]) == (rec["operating_point"]["verdict"],
                                                 rec["review"]["decision"])
    assert row["verdict"] == verdict
    # uniform margin: (1 − p_a + δ)(1/2 + δ)·4 = 1
    q = 1 - float(sp.Rational(p_a))
    delta = (-(q + 0.5) + ((q + 0.5) ** 2 - 4 * (q * 0.5 - 0.25)) ** 0.5) / 2
    assert row["margin"] == pytest.approx(delta, abs=1e-9)


def test_bursty_link_in_a_network_uses_the_burst_condition() -> None:
    """a = 3 seen by radar (p 0.6), float (p 0.5) and a Gilbert–Elliott pressure link
    (f 0.1, r 0.3, stationary 3/4): all three lost for k steps has probability ~
    (0.4·0.5·0.7)^k while P grows 9^k, and 0.4·0.5·0.7·9 = 1.26 ≥ 1, so E[P_t] diverges
    although the stationary i.i.d. surface (0.4·0.5·0.25·9 = 0.45 < 1) would call it stable."""
    doc = {"name": "gauges", "A": 3, "Q": 1, "sensors": [
        {"name": "radar", "C": 1, "R": "1/2",
         "channel": {"model": "bernoulli", "arrival_probability": "0.6"}},
        {"name": "float", "C": 1, "R": 2,
         "channel": {"model": "bernoulli", "arrival_probability": "0.5"}},
        {"name": "pressure", "C": 1, "R": 1,
         "channel": {"model": "gilbert-elliott", "failure_rate": "0.1",
                     "recovery_rate": "0.3"}}]}
    row, rec = row_and_record(doc, [])
    assert rec["operating_point"]["verdict"] == "mean-unstable" == row["verdict"]
    assert rec["review"]["decision"] == "fail" == row["decision"]
    # recovery 0.8: 0.4·0.5·0.2·9 = 0.36 < 1 holds, and for a scalar plant that suffices: any
    # arrival bounds P by min R_i/C_i², so E[P_t] is finite iff the all-lost runs decay faster
    # than a^(-2k) (docs/theory.md §10)
    row, rec = row_and_record(doc, [("sensors.pressure.channel.recovery_rate", "0.8")])
    assert rec["operating_point"]["verdict"] == "mean-stable" == row["verdict"]
    assert rec["network"]["verdict"] == "mean-stable"


def test_one_bursty_sensor_equals_the_single_link() -> None:
    """N = 1 over a Gilbert–Elliott link: (1 − r)a² = 0.9·25/16 ≥ 1, as ge-bursty-scalar; the
    network row states the link's own margin r − r_nec = 1/10 − 9/25 = −0.26 (by hand), and no
    i.i.d. critical value (losses in bursts are not judged by their arrival probability)."""
    doc = {"name": "n1", "A": "-5/4", "Q": 1, "sensors": [
        {"name": "only", "C": 1, "R": "5/2",
         "channel": {"model": "gilbert-elliott", "failure_rate": "1/20",
                     "recovery_rate": "1/10"}}]}
    row, rec = row_and_record(doc, [])
    assert rec["operating_point"]["verdict"] == "mean-unstable" == row["verdict"]
    assert rec["review"]["decision"] == "fail" == row["decision"]
    sensor = rec["network"]["sensors"][0]
    assert sensor["critical_value"]["value"] is None
    assert "r_nec = 0.36" in sensor["critical_value"]["basis"]
    assert sensor["margin"]["value"] == pytest.approx(-0.26, abs=1e-12)
    assert rec["operating_point"]["margin"] == pytest.approx(-0.26, abs=1e-12)


def test_exact_margin_keeps_a_tiny_difference() -> None:
    doc = {**GENERAL, "channel": {"model": "bernoulli", "arrival_probability": "9/25 + 10**-40"}}
    row, rec = row_and_record(doc, [])
    assert rec["operating_point"]["verdict"] == "mean-stable"       # exact: p > 9/25
    assert rec["operating_point"]["margin"] == pytest.approx(1e-40, rel=1e-12)


@pytest.mark.parametrize("p, sign, verdict", [("9/25 + 10^-40", 1, "mean-stable"),
                                              ("9/25 - 10^-40", -1, "mean-unstable")])
def test_margin_at_an_exact_threshold_keeps_its_sign(p: str, sign: int, verdict: str) -> None:
    """Sinopoli's general plant has p_c = 9/25 exactly: 10^-40 above or below it, the sweep row
    and the record give the same verdict and a margin of the same sign (±1e-40, not 0.0)."""
    doc = {"name": "general", "A": [[1.25, 0], [1, 1.1]], "C": [[1, 1]], "Q": 20, "R": 2.5,
           "channel": {"model": "bernoulli", "arrival_probability": "1/2"}}
    row, rec = row_and_record(doc, [("channel.arrival_probability", p)])
    assert row["verdict"] == rec["operating_point"]["verdict"] == verdict
    assert row["margin"] == rec["operating_point"]["margin"] == pytest.approx(sign * 1e-40,
                                                                             rel=1e-9)
