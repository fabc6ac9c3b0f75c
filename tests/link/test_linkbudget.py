"""Link-budget formulas against values from the issue text and textbook closed forms."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy import integrate, stats
from scipy.special import erfc

from kfcrit.analysis.bursty import ge_horizon, gilbert_elliott_section
from kfcrit.errors import InputError
from kfcrit.link.linkbudget import LinkBudget, design_section, thermal_noise_dbm
from kfcrit.link.radios import CoherentBpsk, Ieee802154Oqpsk
from kfcrit.model.channels import Bernoulli, GilbertElliott
from kfcrit.model.system import System

LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "30", "packet_bytes": "40",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def test_oqpsk_values_from_issue() -> None:
    r = Ieee802154Oqpsk()
    assert r.per(0.0, 20) == pytest.approx(0.0255, abs=5e-5)
    assert r.per(0.0, 127) == pytest.approx(0.151, abs=5e-4)
    assert r.required_sinr_db(0.99, 20) == pytest.approx(0.4035, abs=5e-4)


def test_bpsk_textbook() -> None:
    for db in (0.0, 7.0, 9.6):
        assert CoherentBpsk().ber(10 ** (db / 10)) == pytest.approx(
            0.5 * erfc(math.sqrt(10 ** (db / 10))), rel=1e-12)
    assert CoherentBpsk().ber(10 ** 0.7) == pytest.approx(7.73e-4, rel=1e-3)


def test_noise_floor_and_path_loss() -> None:
    assert thermal_noise_dbm(2e6, 10) == pytest.approx(-174 + 10 * math.log10(2e6) + 10, abs=0.03)
    ch = LinkBudget.from_mapping(LINK, "channel")
    assert ch.path_loss_db == pytest.approx(40.2 + 30 * math.log10(30), abs=1e-12)


def test_unknown_key_names_field() -> None:
    bad = {**LINK, "path_loss": {**LINK["path_loss"], "exponnent": "3"}}
    with pytest.raises(InputError, match="channel.path_loss.exponnent"):
        LinkBudget.from_mapping(bad, "channel")


# ---- the check numbers, from the formulas written out here -------------------------------

KB = 1.380649e-23
MAC_OVERHEAD = 2 + 1 + 2 + 2 + 2 + 2
"""802.15.4 data frame, short addresses, PAN-ID compression: frame control 2, sequence 1,
destination PAN 2, destination 2, source 2, FCS 2 (IEEE 802.15.4-2006 §7.2)."""
PSDU40 = 40 + MAC_OVERHEAD
PHY_HEADER = 4 + 1 + 1
"""2.4 GHz O-QPSK PHY header: preamble 4, SFD 1, PHR 1 (IEEE 802.15.4-2006 §6.3)."""
PPDU40 = PHY_HEADER + PSDU40
"""The PER covers the whole PPDU by default (per_over: ppdu, as ns-3's lr-wpan model)."""
SENSOR = Path(__file__).resolve().parents[2] / "reports" / "link-oqpsk-sensor.yaml"


def oqpsk_ber(sinr_lin: float) -> float:
    """(8/15)(1/16) Σ_{k=2}^{16} (−1)^k C(16,k) exp(20·SINR·(1/k − 1)), SINR linear."""
    return (8 / 15) / 16 * sum((-1) ** k * math.comb(16, k) * math.exp(20 * sinr_lin * (1 / k - 1))
                               for k in range(2, 17))


def per(sinr_db: float, packet_bytes: int) -> float:
    """1 − (1 − BER)^{8L}, written as −expm1(8L·log1p(−BER)) so that tiny PERs keep digits."""
    return -math.expm1(8 * packet_bytes * math.log1p(-oqpsk_ber(10 ** (sinr_db / 10))))


def required_sinr(p: float, packet_bytes: int) -> float:
    """Bisection on the written-out formula: 1 − PER(s) = p."""
    lo, hi = -40.0, 60.0
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if 1 - per(mid, packet_bytes) < p else (lo, mid)
    return (lo + hi) / 2


def test_issue_check_numbers_from_the_written_out_formula() -> None:
    # the numbers of the issue hold for the formula itself ...
    assert per(0.4035, 20) == pytest.approx(0.01, abs=2e-5)
    assert per(0.0, 20) == pytest.approx(0.0255, abs=5e-5)
    assert per(0.0, 127) == pytest.approx(0.151, abs=5e-4)
    # ... and the radio implements that formula at every SINR (−10 … 10 dB)
    r = Ieee802154Oqpsk()
    for db in np.linspace(-10, 10, 41):
        assert float(r.ber(10 ** (db / 10))) == pytest.approx(oqpsk_ber(10 ** (db / 10)),
                                                              rel=1e-9, abs=1e-300)
        for size in (20, 40, 127):
            assert float(r.per(db, size)) == pytest.approx(per(db, size), rel=1e-9, abs=1e-15)
    assert r.required_sinr_db(0.99, 20) == pytest.approx(required_sinr(0.99, 20), abs=1e-8)


def test_bpsk_textbook_values() -> None:
    b = CoherentBpsk()
    for db in (-3.0, 0.0, 4.0, 7.0, 9.6, 12.0):
        ebn0 = 10 ** (db / 10)
        assert float(b.ber(ebn0)) == pytest.approx(stats.norm.sf(math.sqrt(2 * ebn0)), rel=1e-10)
    assert float(b.ber(1.0)) == pytest.approx(0.0786, abs=1e-4)  # 0 dB
    assert float(b.ber(10 ** 0.96)) == pytest.approx(1e-5, rel=0.03)  # 1e-5 near 9.6 dB
    # processing gain G shifts the curve by G dB: Eb/N0 = SINR + G
    assert float(CoherentBpsk(3.0).ber(10 ** 0.66)) == pytest.approx(float(b.ber(10 ** 0.96)),
                                                                     rel=1e-12)
    s = b.required_sinr_db(0.9, 40)
    assert (1 - stats.norm.sf(math.sqrt(2 * 10 ** (s / 10)))) ** 320 == pytest.approx(0.9,
                                                                                      rel=1e-9)


# ---- design outputs of the shipped sensor link, in the record and the terminal view -------

@pytest.fixture(scope="module")
def sensor_record() -> dict:
    from click.testing import CliRunner

    from kfcrit.cli.main import main

    r = CliRunner().invoke(main, ["analyze", str(SENSOR), "--json", "--no-simulate"])
    # mean-stable, but the 105 m link misses its margin and outage policy: the review fails
    assert r.exit_code == 5, r.stderr
    rec = json.loads(r.stdout)
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert rec["review"]["decision"] == "fail"
    assert [x["status"] for x in rec["review"]["reasons"]] == ["pass", "fail", "fail"]
    return rec


def test_sensor_link_design_outputs(sensor_record: dict) -> None:
    lb = sensor_record["link_budget"]
    noise = 10 * math.log10(KB * 290 * 2e6 / 1e-3) + 10
    pl = 40.2 + 30 * math.log10(105)
    sinr = 0 - pl - noise
    link = lb["link"]
    assert link["path_loss_db"] == pytest.approx(pl, abs=1e-9)
    assert link["noise_floor_dbm"] == pytest.approx(noise, abs=1e-9)
    assert link["sinr_db"] == pytest.approx(sinr, abs=1e-9)
    assert link["arrival_probability"] == pytest.approx(1 - per(sinr, PPDU40), rel=1e-9)
    req = lb["required_arrival_probability"]
    assert req["critical_value"] == pytest.approx(9 / 25, abs=1e-15)
    assert req["design_value"] == req["critical_value"] and "critical value" in req["basis"]
    assert "robust_value" in req and "bracket" in req
    s_req = required_sinr(0.36, PPDU40)
    assert lb["required_sinr_db"] == pytest.approx(s_req, abs=1e-8)
    assert lb["required_rx_power_dbm"] == pytest.approx(s_req + noise, abs=1e-8)
    assert lb["link_margin_db"] == pytest.approx(sinr - s_req, abs=1e-8)
    # margin policy: max(2 dB, σ Φ^{-1}(1 − 0.1)) = 5.126 dB; then solve the log-distance law
    margin = max(2.0, 4 * stats.norm.ppf(0.9))
    assert lb["margin_policy"]["effective_margin_db"] == pytest.approx(margin, abs=1e-12)
    d_max = 10 ** ((0 - noise - s_req - margin - 40.2) / 30)
    assert lb["max_distance_m"] == pytest.approx(d_max, rel=1e-8)
    assert lb["mean_stable_at_distance"] is True
    # shadowing: average of p over X ~ N(0, 16) dB, and the outage P(p(X) < p_c), P(p < p_up)
    sh = lb["shadowing"]
    mean = integrate.quad(lambda z: (1 - per(sinr + 4 * z, PPDU40)) * stats.norm.pdf(z), -12, 12,
                          points=[(s_req - sinr) / 4], limit=200, epsabs=1e-12)[0]
    assert sh["mean_arrival_probability"] == pytest.approx(mean, abs=1e-7)
    assert sh["outage_below_critical"] == pytest.approx(
        stats.norm.cdf((s_req - sinr) / 4), abs=1e-9)
    p_up = sensor_record["upper_bound"]["value"]
    assert 0.36 < p_up < 1
    assert sh["outage_below_upper"] == pytest.approx(
        stats.norm.cdf((required_sinr(p_up, PPDU40) - sinr) / 4), abs=1e-9)
    labels = [row["label"] for row in lb["thresholds"]]
    assert labels == ["critical_value", "upper_bound"]


def test_sensor_link_design_outputs_in_the_terminal_view(sensor_record: dict) -> None:
    from kfcrit.analysis.sections import record_from_json
    from kfcrit.views.text.terminal import summary

    text = summary(record_from_json(sensor_record))
    lb = sensor_record["link_budget"]
    for label, key in (("required SINR", "required_sinr_db"),
                       ("required rx power", "required_rx_power_dbm"),
                       ("link margin", "link_margin_db"), ("max distance", "max_distance_m")):
        line = next(x for x in text.splitlines() if x.strip().startswith(label))
        assert float(line.split()[-2]) == pytest.approx(lb[key], rel=1e-5)


def test_design_requirement_uses_robust_value_or_bracket() -> None:
    ch = LinkBudget.from_mapping({**LINK, "margin_db": "3"}, "channel")
    robust = design_section(ch, critical_value=0.36, robust_value=0.4, bracket=(None, None),
                            upper_bound=0.45)
    assert robust["required_arrival_probability"]["design_value"] == 0.4
    assert robust["required_arrival_probability"]["basis"] == "robust critical value"
    assert robust["required_sinr_db"] == pytest.approx(required_sinr(0.4, PPDU40), abs=1e-8)
    # no p_c: the upper end of the bracket is sufficient, and both ends get their own rows
    br = design_section(ch, critical_value=None, robust_value=None, bracket=(0.3, 0.5),
                        upper_bound=0.5)
    assert br["required_arrival_probability"]["design_value"] == 0.5
    assert "bracket" in br["required_arrival_probability"]["basis"]
    rows = {row["label"]: row for row in br["thresholds"]}
    assert set(rows) == {"bracket_low", "bracket_high", "upper_bound"}
    assert rows["bracket_low"]["required_sinr_db"] == pytest.approx(required_sinr(0.3, PPDU40),
                                                                    abs=1e-8)
    noise = 10 * math.log10(KB * 290 * 2e6 / 1e-3) + 10
    d = 10 ** ((0 - noise - required_sinr(0.5, PPDU40) - 3 - 40.2) / 30)
    assert br["max_distance_m"] == pytest.approx(d, rel=1e-8)
    assert design_section(Bernoulli(sp.Rational(1, 2)), critical_value=0.36, robust_value=None,
                          bracket=(None, None), upper_bound=None)["applicable"] is False


# ---- Gilbert–Elliott (MATH §7) -------------------------------------------------------------

def ge_paths(a: float, f: float, r: float, paths: int, steps: int, seed: int,
             q: float = 1.0, rn: float = 2.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate P_t of the scalar filter (c = 1) under a stationary Gilbert–Elliott chain.

    Returns the sample means of P_t (t = 0 … steps), the final P and the final arrivals.
    """
    rng = np.random.default_rng(seed)
    got = rng.random(paths) < r / (f + r)
    P = np.ones(paths)
    means = [1.0]
    for _ in range(steps):
        u = rng.random(paths)
        got = np.where(got, u >= f, u < r)
        pred = a * a * P + q
        P = np.where(got, pred * rn / (pred + rn), pred)  # Kalman update, c = 1
        means.append(P.mean())
    return np.array(means), P, got


def test_ge_scalar_mean_bounded_below_the_threshold_by_simulation() -> None:
    # a = 1.25, r = 0.7: (1 − r) a² = 0.47 < 1. The simulated mean settles, and equals the
    # burst decomposition of MATH §7: a loss run of age j (probability r(1 − r)^{j−1}) maps the
    # posterior μ = E[P | arrival] to a^{2j} μ + q (a^{2j} − 1)/(a² − 1), so
    # E[P] = π_a μ + π_l (μ r a²/(1 − v) + q/(a² − 1) (r a²/(1 − v) − 1)), v = (1 − r) a².
    a, f, r, q = 1.25, 0.5, 0.7, 1.0
    means, P, got = ge_paths(a, f, r, 40_000, 80, seed=5, q=q)
    se = P.std() / math.sqrt(P.size)
    assert abs(means[80] - means[40]) < 6 * se
    v, a2 = (1 - r) * a * a, a * a
    mu = P[got].mean()
    pi_a = r / (f + r)
    lost = mu * r * a2 / (1 - v) + q / (a2 - 1) * (r * a2 / (1 - v) - 1)
    predicted = pi_a * mu + (1 - pi_a) * lost
    assert means[80] == pytest.approx(predicted, rel=0.03)
    sec = gilbert_elliott_section(System([[sp.Rational(5, 4)]], [[1]], 1, sp.Rational(5, 2)),
                                  GilbertElliott(sp.Rational(1, 2), sp.Rational(7, 10)))
    assert sec["condition"]["holds"] is True and sec["condition"]["decides"] is True
    assert sec["simulation_consistent"] is True


def test_ge_scalar_mean_grows_above_the_threshold_by_simulation() -> None:
    # a = 1.25, r = 0.1: (1 − r) a² = 1.406 > 1, although the stationary arrival probability
    # (1/2) exceeds the i.i.d. p_c = 0.36. E[P_t] grows like 1.406^t: over 12 steps by ~60.
    means, _, _ = ge_paths(1.25, 0.1, 0.1, 40_000, 24, seed=6)
    assert means[24] / means[12] > 15
    assert means[24] / means[12] < 400
    sec = gilbert_elliott_section(System([[sp.Rational(5, 4)]], [[1]], 1, sp.Rational(5, 2)),
                                  GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 10)))
    assert sec["condition"]["holds"] is False and sec["condition"]["decides"] is True
    assert sec["simulation_consistent"] is True
    assert sec["simulation"]["growth_ratio"] > 2


@pytest.mark.parametrize("r", ["0.05", "0.2", "0.3", "0.42", "0.6", "0.95"])
def test_ge_scalar_condition_is_the_recovery_rate_against_1_minus_1_over_a2(r: str) -> None:
    rr = float(r)
    sys1 = System([[sp.Rational(5, 4)]], [[1]], 1, sp.Rational(5, 2))
    sec = gilbert_elliott_section(sys1, GilbertElliott(sp.Rational(1, 5), sp.nsimplify(r)))
    cond = sec["condition"]
    assert cond["value"] == pytest.approx((1 - rr) * 1.5625, rel=1e-12)
    assert cond["holds"] == (rr > 1 - 1 / 1.5625)  # r > 0.36, f does not enter
    assert cond["status"].startswith("theorem (scalar case")
    assert sec["required_recovery_rate"] == pytest.approx(0.36, abs=1e-12)
    assert sec["stationary_arrival_probability"] == pytest.approx(rr / (0.2 + rr))
    if abs(cond["value"] - 1) >= 0.15 and sec["simulation_consistent"] is not None:
        assert sec["simulation_consistent"] is True
    if abs(cond["value"] - 1) < 0.15:
        assert sec["simulation_consistent"] is None and "not compared" in sec["simulation_note"]


def test_ge_horizon_keeps_about_100_paths_lost_since_the_start() -> None:
    for a, f, r in ((1.25, 0.1, 0.1), (2.0, 0.5, 0.25), (1.1, 0.05, 0.05)):
        T = ge_horizon(a, f, r, 4000)
        lost = 4000 * f / (f + r)
        assert lost * (1 - r) ** T >= 100 > lost * (1 - r) ** (T + 1)
    assert ge_horizon(1.25, 0.1, 0.7, 4000) == 40  # bounded side: long enough to settle


def test_ge_other_cases_are_labelled_as_what_they_are() -> None:
    ge = GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2))
    eye = [[1, 0], [0, 1]]
    cases = {
        "non-degenerate": (System([[2, 0], [0, sp.Rational(1, 2)]], [[1, 1]], eye, 1),
                           "claim: necessary and sufficient for non-degenerate", False),
        "degenerate-second-order": (System([[2, 0], [0, -2]], [[1, 1]], eye, 1),
                                    "necessary condition only", False),
        "stable": (System([[sp.Rational(1, 2), 0], [0, sp.Rational(1, 5)]], [[1, 1]], eye, 1),
                   "theorem: rho(A) < 1", True),
        "not-detectable": (System([[2, 0], [0, sp.Rational(1, 2)]], [[0, 1]], eye, 1),
                           "not applicable", False),
    }
    for cls, (system, status, decides) in cases.items():
        sec = gilbert_elliott_section(system, ge)
        assert sec["classification"] == cls
        assert sec["condition"]["status"].startswith(status), sec["condition"]["status"]
        assert sec["condition"]["decides"] is decides
        # the simulation checks the scalar theorem and the literature's claim for small
        # non-degenerate systems; nothing else is simulated
        assert (sec["simulation"] is not None) == (cls == "non-degenerate")
        assert sec["condition"]["value"] == pytest.approx((1 - 0.5) * sec["spectral_radius"] ** 2)
    assert all(c["status"].startswith("claim") and c["source"] for c in sec["claims"])
    assert gilbert_elliott_section(cases["stable"][0], Bernoulli(sp.Rational(1, 2)))[
        "applicable"] is False
