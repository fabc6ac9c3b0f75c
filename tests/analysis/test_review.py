"""The review decision as a CI gate sees it: four designs, their decisions and exit codes.

Expected values by hand: the scalar plant a = −5/4 has p_c = 1 − 1/a² = 9/25 (Sinopoli Thm 3,
C invertible); the 802.15.4 link's margin policy is max(2 dB, σ·Φ⁻¹(1 − 0.1)) = 5.126 dB with
σ = 4 dB.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS

SCALAR = "name: {name}\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"


def run(path: Path, *extra: str) -> tuple[int, dict]:
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", "--quick", *extra])
    return r.exit_code, json.loads(r.stdout)


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / f"{name}.yaml"
    p.write_text(text)
    return p


def comfortable_link(tmp_path: Path) -> Path:
    # the sensor example at 40 m instead of 105 m: the path loss drops by 30 log10(105/40)
    # = 12.6 dB, so the 1.78 dB margin becomes about 14.3 dB > 5.13 dB
    text = (REPORTS / "link-oqpsk-sensor.yaml").read_text().replace("distance_m: 105",
                                                                    "distance_m: 40")
    return write(tmp_path, "comfortable", text)


CASES = {
    # a link whose policy fails (1.78 dB < 5.13 dB; outage 33 % > 10 %) although mean-stable
    "policy": (lambda tmp: REPORTS / "link-oqpsk-sensor.yaml", "fail", 5,
               ["pass", "fail", "fail"]),
    # P(tr P > 0.1) ≈ 1: every P is at least the no-loss fixed point P* ≈ 3.19 > 0.1
    "requirement": (lambda tmp: write(tmp, "req", SCALAR.format(name="req") +
                                      "channel: {model: bernoulli, arrival_probability: 0.8}\n"
                                      "requirements: {max_error_trace: 0.1, "
                                      "max_tail_probability: 0.01}\n"), "fail", 5,
                    ["pass", "fail"]),
    "comfortable": (comfortable_link, "pass", 0, ["pass", "pass", "pass"]),
    # p = 0.3 ≤ p_c = 9/25
    "lossy": (lambda tmp: write(tmp, "lossy", SCALAR.format(name="lossy") +
                                "channel: {model: bernoulli, arrival_probability: 0.3}\n"),
              "fail", 5, ["fail"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_decisions_and_exit_codes(case: str, tmp_path: Path) -> None:
    make, decision, code, statuses = CASES[case]
    got_code, rec = run(make(tmp_path))
    assert rec["review"]["decision"] == decision
    assert [r["status"] for r in rec["review"]["reasons"]] == statuses
    assert got_code == code


def test_accuracy_requirement_below_the_no_loss_floor_fails(tmp_path: Path) -> None:
    # even with every packet delivered the prediction covariance is the DARE solution
    # P* = (77 + √16169)/64 ≈ 3.190 (Kar–Sinopoli–Moura's example constant) > L = 3: impossible
    path = write(tmp_path, "acc", SCALAR.format(name="acc") +
                 "channel: {model: bernoulli, arrival_probability: 0.8}\n"
                 "requirements: {max_mean_error_trace: 3}\n")
    code, rec = run(path, "--no-simulate")
    item = rec["requirements"]["assessments"][0]
    req = rec["design"]["required_arrival_probability"]
    assert req["status"] == "impossible"
    assert req["floor_trace"] == pytest.approx((77 + 16169 ** 0.5) / 64, rel=1e-9)
    assert item["status"] == "not met"
    assert rec["review"]["decision"] == "fail" and code == 5


def test_accuracy_requirement_above_the_mare_bound_passes(tmp_path: Path) -> None:
    # V̄ solves v = a²v + q − p a² v² / (v + r) (scalar MARE, Sinopoli eq. 16): with a² = 25/16,
    # q = 1, r = 5/2, p = 4/5 the positive root of 0.5625 v² + ... is below 10 (hand: 4.338)
    path = write(tmp_path, "acc2", SCALAR.format(name="acc2") +
                 "channel: {model: bernoulli, arrival_probability: 0.8}\n"
                 "requirements: {max_mean_error_trace: 10}\n")
    code, rec = run(path, "--no-simulate")
    item = rec["requirements"]["assessments"][0]
    a2, q, r, p = 25 / 16, 1.0, 2.5, 0.8
    # v (v + r) = (a² v + q)(v + r) − p a² v²  ⇔  (1 − a² + p a²) v² + (r − a² r − q) v − q r = 0
    A, B, C = 1 - a2 + p * a2, r - a2 * r - q, -q * r
    v = (-B + (B * B - 4 * A * C) ** 0.5) / (2 * A)
    assert item["interval"][1] == pytest.approx(v, rel=1e-7)
    assert item["status"] == "met" and rec["review"]["decision"] == "pass" and code == 0


def test_no_channel_has_nothing_to_fail(tmp_path: Path) -> None:
    code, rec = run(write(tmp_path, "bare", SCALAR.format(name="bare")), "--no-simulate")
    assert rec["operating_point"] is None
    assert rec["review"]["decision"] == "pass"
    assert rec["review"]["reasons"][0]["status"] == "not applicable"
    assert code == 0


def test_required_arrival_interval_in_the_record(tmp_path: Path) -> None:
    """L = 10 for a = −5/4, q = 1, r = 5/2 (MATH §11): tr S̄(p_S) = L gives
    1/(1 − (1 − p)·25/16) = 10 ⇒ p_S = 1 − 0.9·16/25 = 0.424; tr V̄(p_V) = L with the scalar
    MARE v = a²v + q − p a² v²/(v + r) ⇒ p_V = (a²v + q − v)(v + r)/(a² v²) = 0.53."""
    path = write(tmp_path, "design", SCALAR.format(name="design") +
                 "channel: {model: bernoulli, arrival_probability: 0.8}\n"
                 "requirements: {max_mean_error_trace: 10}\n")
    code, rec = run(path, "--no-simulate")
    req = rec["design"]["required_arrival_probability"]
    assert req["status"] == "interval"
    p_s, p_v = req["interval"]
    assert p_s == pytest.approx(0.424, abs=1e-6) and p_v == pytest.approx(0.53, abs=1e-6)
    assert rec["review"]["decision"] == "pass" and code == 0    # p = 0.8 ≥ p_V


def test_network_link_policy_and_requirement_enter_the_review(tmp_path: Path) -> None:
    """A network's requirement uses its own Lyapunov bound S̄ = Π(1 − p_i)·a²·S̄ + q:
    a = 2, p = (0.6, 0.5): S̄ = 1/(1 − 0.4·0.5·4) = 5 > L = 2, so the requirement fails; and a
    link-budget sensor's margin policy is a reason of its own (named by the sensor)."""
    path = write(tmp_path, "netreq", "name: n\nA: 2\nQ: 1\nsensors:\n"
                 "  - {name: a, C: 1, R: 1, channel: {model: bernoulli, arrival_probability: 0.6}}\n"
                 "  - {name: b, C: 1, R: 2, channel: {model: bernoulli, arrival_probability: 0.5}}\n"
                 "requirements: {max_mean_error_trace: 2}\n")
    code, rec = run(path, "--no-simulate")
    item = rec["requirements"]["assessments"][0]
    assert item["status"] == "not met" and item["interval"][0] == pytest.approx(5.0)
    assert code == 5
    text = (REPORTS / "network-planar-tracker.yaml").read_text().replace(
        "  margin_db: 2\n", "  margin_db: 30\n")
    assert "margin_db: 30" in text
    code, rec = run(write(tmp_path, "policy", text), "--no-simulate")
    checks = {r["check"]: r["status"] for r in rec["review"]["reasons"]}
    assert checks.get("link policy: margin (corner)") == "fail"
    assert rec["review"]["decision"] == "fail" and code == 5
