"""Link realism: frames, MAC retries, datasheet radios, time-correlated shadowing.

Expected values come from independent computations: mpmath at 50 digits for the O-QPSK
formula, the standard's field sizes for the frame, closed forms (arcsine law, ρ = 0) and a
direct simulation of the AR(1) shadowing for the Gilbert–Elliott approximation.
"""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate, stats

from kfcrit.errors import InputError
from kfcrit.link.linkbudget import LinkBudget, design_section
from kfcrit.link.radios import radio_catalogue, radio_from_mapping
from kfcrit.link.shadowing import markov_from_threshold

MAC = 2 + 1 + 2 + 2 + 2 + 2
"""802.15.4 data frame, short addresses, PAN-ID compression (frame control, sequence,
destination PAN, destination, source, FCS)."""
PHY = 4 + 1 + 1
"""2.4 GHz O-QPSK PHY header: preamble 4, SFD 1, PHR 1. The PER covers it by default
(per_over: ppdu), as ns-3's lr-wpan error model does."""

LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "100", "packet_bytes": "40",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def mp_oqpsk_arrival(sinr_db: float, psdu: int, retries: int) -> mp.mpf:
    """1 − PER^{k+1}, PER = 1 − (1 − BER)^{8L}, BER the 802.15.4 formula, all at 50 digits."""
    with mp.workdps(50):
        s = mp.power(10, mp.mpf(sinr_db) / 10)
        ber = mp.mpf(8) / 15 / 16 * mp.fsum((-1) ** k * mp.binomial(16, k)
                                           * mp.e ** (20 * s * (mp.mpf(1) / k - 1))
                                           for k in range(2, 17))
        per = 1 - (1 - ber) ** (8 * psdu)
        return 1 - per ** (retries + 1)


def hand_sinr_db(tx: float, d: float, nf: float = 10.0) -> float:
    noise = 10 * math.log10(1.380649e-23 * 290 * 2e6 * 1e3) + nf
    return tx - (40.2 + 30 * math.log10(d)) - noise


@pytest.mark.parametrize("distance", ["90", "110", "125"])
def test_three_retries_match_a_50_digit_per(distance: str) -> None:
    link = LinkBudget.from_mapping({**LINK, "distance_m": distance, "max_retries": 3},
                                   "channel")
    s = hand_sinr_db(0.0, float(distance))
    assert link.sinr_db == pytest.approx(s, abs=1e-10)
    expected = mp_oqpsk_arrival(s, PHY + 40 + MAC, 3)
    assert link.arrival_value == pytest.approx(float(expected), rel=1e-11)
    # the retries help exactly as 1 − PER^4 against one attempt
    one = LinkBudget.from_mapping({**LINK, "distance_m": distance}, "channel")
    assert one.arrival_value == pytest.approx(float(mp_oqpsk_arrival(s, PHY + 40 + MAC, 0)),
                                              rel=1e-11)
    assert link.arrival_value > one.arrival_value


def test_retries_keep_tiny_loss_probabilities_accurate() -> None:
    """At d = 84 m (SINR ≈ 3 dB, PER ≈ 1e-5) seven retries lose an update with probability
    PER⁸ ≈ 1e-40: kept with full relative accuracy as exp(8·log PER)."""
    from kfcrit.link.frames import log_per

    link = LinkBudget.from_mapping({**LINK, "distance_m": "84", "max_retries": 7}, "channel")
    s = hand_sinr_db(0.0, 84.0)
    with mp.workdps(60):
        loss = 1 - mp_oqpsk_arrival(s, PHY + 40 + MAC, 7)
    assert 1e-60 < float(loss) < 1e-20
    assert link.per_bytes == PHY + 40 + MAC
    got = math.exp(8 * float(log_per(link.radio.log_arrival(s, link.per_bytes))))
    assert got == pytest.approx(float(loss), rel=1e-8)


def test_required_sinr_with_retries_inverts_the_arrival() -> None:
    link = LinkBudget.from_mapping({**LINK, "max_retries": 3}, "channel")
    for p in (0.36, 0.9, 0.999999):
        s = link.required_sinr_db(p)
        assert float(mp_oqpsk_arrival(s, PHY + 40 + MAC, 3)) == pytest.approx(p, rel=1e-9)


def test_per_packet_shadowing_retries_share_the_shadowing_value() -> None:
    path = {**LINK["path_loss"], "shadowing_sigma_db": "4", "shadowing": "per-packet"}
    link = LinkBudget.from_mapping({**LINK, "path_loss": path, "max_retries": 2}, "channel")
    s = hand_sinr_db(0.0, 100.0)

    def p(z: float) -> float:
        return float(mp_oqpsk_arrival(s + 4 * z, PHY + 40 + MAC, 2))

    mean = integrate.quad(lambda z: p(z) * stats.norm.pdf(z), -12, 12, limit=200,
                          epsabs=1e-12)[0]
    assert link.arrival_value == pytest.approx(mean, abs=1e-7)
    # correlated attempts gain less than independent ones would: E[1 − PER^3] < 1 − E[PER]^3
    e_per = integrate.quad(lambda z: (1 - float(mp_oqpsk_arrival(s + 4 * z, PHY + 40 + MAC, 0)))
                           * stats.norm.pdf(z), -12, 12, limit=200, epsabs=1e-12)[0]
    assert link.arrival_value < 1 - e_per ** 3
    # redrawn per attempt (fading_per_attempt: independent): exactly 1 − E[PER]^3
    indep = LinkBudget.from_mapping({**LINK, "path_loss": path, "max_retries": 2,
                                     "fading_per_attempt": "independent"}, "channel")
    assert indep.arrival_value == pytest.approx(1 - e_per ** 3, abs=1e-7)
    assert indep.frame_dict()["fading_per_attempt"] == "independent"
    # without retries the two conventions agree
    one = [LinkBudget.from_mapping({**LINK, "path_loss": path, "fading_per_attempt": f},
                                   "channel").arrival_value for f in ("shared", "independent")]
    assert one[0] == pytest.approx(one[1], abs=1e-12)
    assert one[0] == pytest.approx(1 - e_per, abs=1e-7)


def test_independent_attempts_need_per_packet_shadowing() -> None:
    for mode in ("per-link", "time-correlated"):
        path = {**LINK["path_loss"], "shadowing_sigma_db": "4", "shadowing": mode}
        extra = ({"shadowing_correlation": {"sample_period_s": "0.1", "coherence_time_s": "1"}}
                 if mode == "time-correlated" else {})
        with pytest.raises(InputError, match=r"^channel\.fading_per_attempt: independent"):
            LinkBudget.from_mapping({**LINK, **extra, "path_loss": path,
                                     "fading_per_attempt": "independent"}, "channel")
    with pytest.raises(InputError, match=r"^channel\.fading_per_attempt: must be one of"):
        LinkBudget.from_mapping({**LINK, "fading_per_attempt": "per-attempt"}, "channel")


def test_per_over_psdu_leaves_the_phy_header_out() -> None:
    """per_over: psdu is the PSDU-only convention: L = 40 + 11 bytes instead of 6 + 40 + 11."""
    s = hand_sinr_db(0.0, 100.0)
    psdu = LinkBudget.from_mapping({**LINK, "per_over": "psdu"}, "channel")
    ppdu = LinkBudget.from_mapping(LINK, "channel")
    assert (psdu.per_bytes, ppdu.per_bytes) == (40 + MAC, PHY + 40 + MAC)
    assert psdu.arrival_value == pytest.approx(float(mp_oqpsk_arrival(s, 40 + MAC, 0)),
                                               rel=1e-11)
    assert ppdu.arrival_value == pytest.approx(float(mp_oqpsk_arrival(s, PHY + 40 + MAC, 0)),
                                               rel=1e-11)
    assert ppdu.frame_dict()["per_covers"].startswith("PPDU")
    assert psdu.frame_dict()["per_covers"].startswith("PSDU")
    with pytest.raises(InputError, match=r"^channel\.per_over: must be one of: ppdu, psdu"):
        LinkBudget.from_mapping({**LINK, "per_over": "mpdu"}, "channel")


def test_frame_over_the_phy_limit_is_refused_naming_the_field() -> None:
    assert LinkBudget.from_mapping({**LINK, "packet_bytes": 127 - MAC}, "channel").psdu_bytes \
        == 127
    with pytest.raises(InputError, match=r"^channel\.packet_bytes: .*127") as exc:
        LinkBudget.from_mapping({**LINK, "packet_bytes": 128 - MAC}, "channel")
    assert "\n" not in str(exc.value)
    # without MAC overhead the whole 127-byte PSDU is payload
    ok = LinkBudget.from_mapping({**LINK, "packet_bytes": 127, "mac_overhead_bytes": 0},
                                 "channel")
    assert ok.psdu_bytes == 127
    with pytest.raises(InputError, match=r"^channel\.max_retries: must be between 0 and 7"):
        LinkBudget.from_mapping({**LINK, "max_retries": 8}, "channel")
    # an unframed modulation has no PHY limit and no MAC overhead
    bpsk = LinkBudget.from_mapping({**LINK, "radio": "bpsk", "packet_bytes": 1000}, "channel")
    assert bpsk.psdu_bytes == 1000


def test_frame_record_defines_payload_and_overheads() -> None:
    link = LinkBudget.from_mapping({**LINK, "max_retries": 2}, "channel")
    fr = link.frame_dict()
    assert (fr["payload_bytes"], fr["mac_overhead_bytes"], fr["psdu_bytes"]) == (40, 11, 51)
    assert fr["ppdu_bytes"] == 51 + 4 + 1 + 1  # preamble, SFD, PHR
    assert fr["airtime_s"] == pytest.approx(57 * 8 / 250e3)  # 250 kb/s
    assert fr["attempts_duration_s"] == pytest.approx(3 * (57 * 8 / 250e3 + 54 * 16e-6))
    assert "application payload" in fr["definition"]


@pytest.mark.parametrize("name,sensitivity", [("cc2420", -95.0), ("cc2520", -98.0),
                                              ("at86rf233", -101.0), ("nrf52840", -100.0)])
def test_datasheet_radio_reproduces_its_sensitivity(name: str, sensitivity: float) -> None:
    """At the datasheet sensitivity, over the thermal noise of 2 MHz (no noise figure), a
    20-byte PSDU (9-byte payload + 11) arrives with probability 0.99 (PER 1 %), the PER
    counted over the 26-byte PPDU as a default link counts it."""
    noise = 10 * math.log10(1.380649e-23 * 290 * 2e6 * 1e3)
    link = LinkBudget.from_mapping(
        {**LINK, "radio": name, "packet_bytes": 20 - MAC, "tx_power_dbm": "0",
         "path_loss": {"model": "log-distance", "exponent": "2",
                       "reference_loss_db": str(-sensitivity)},
         "distance_m": "1", "noise": {"bandwidth_hz": "2e6"}}, "channel")
    assert link.rx_power_dbm == pytest.approx(sensitivity, abs=1e-12)
    assert link.arrival_value == pytest.approx(0.99, abs=1e-9)
    # implementation loss = S − N − s_ideal(0.99, 6 + 20), s_ideal by 50-digit bisection
    lo, hi = mp.mpf(-5), mp.mpf(5)
    for _ in range(80):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if mp_oqpsk_arrival(float(mid), PHY + 20, 0) < 0.99 else (lo, mid)
    loss = sensitivity - noise - float(lo)
    assert link.radio.implementation_loss_db == pytest.approx(loss, abs=1e-6)
    entry = {r.name: r for r in radio_catalogue()}[name]
    assert entry.kind == "datasheet" and entry.parameters["sensitivity_dbm"] == sensitivity
    assert "PER" in entry.description and "20" in entry.description


def test_custom_calibrated_radio_and_unknown_radio_names_the_field() -> None:
    r = radio_from_mapping({"model": "ieee802154-oqpsk-calibrated", "sensitivity_dbm": -95},
                           "channel.radio")
    assert r.implementation_loss_db == pytest.approx(
        radio_from_mapping("cc2420", "channel.radio").implementation_loss_db, abs=1e-12)
    with pytest.raises(InputError, match=r"^channel\.radio\.sensitivity_dbm: is required"):
        radio_from_mapping({"model": "ieee802154-oqpsk-calibrated"}, "channel.radio")
    with pytest.raises(InputError, match=r"^channel\.radio: unknown radio"):
        radio_from_mapping("cc9999", "channel.radio")


# ---- time-correlated shadowing → Gilbert–Elliott -----------------------------------------

@pytest.mark.parametrize("a", [-1.5, -0.3, 0.0, 0.8, 2.0])
def test_uncorrelated_shadowing_gives_iid_arrivals(a: float) -> None:
    ch = markov_from_threshold(0.0, a)
    assert ch.failure_rate == pytest.approx(stats.norm.cdf(a), rel=1e-12)
    assert ch.recovery_rate == pytest.approx(stats.norm.sf(a), rel=1e-12)


@pytest.mark.parametrize("rho", [0.1, 0.5, 0.9, 0.99])
def test_median_threshold_follows_the_arcsine_law(rho: float) -> None:
    """At a* = 0: P(Z_t ≥ 0, Z_{t+1} < 0) = 1/4 − arcsin(ρ)/(2π), so f = r = 1/2 − arcsin ρ/π."""
    ch = markov_from_threshold(rho, 0.0)
    assert ch.failure_rate == pytest.approx(0.5 - math.asin(rho) / math.pi, rel=1e-12)
    assert ch.recovery_rate == pytest.approx(ch.failure_rate, rel=1e-12)


def test_markov_rates_match_a_simulated_ar1_shadowing() -> None:
    rho, a, n = 0.8, 0.7, 400_000
    rng = np.random.default_rng(11)
    z = np.empty(n)
    z[0] = rng.standard_normal()
    w = rng.standard_normal(n) * math.sqrt(1 - rho * rho)
    for t in range(1, n):
        z[t] = rho * z[t - 1] + w[t]
    good = z >= a
    f_hat = np.count_nonzero(good[:-1] & ~good[1:]) / np.count_nonzero(good[:-1])
    r_hat = np.count_nonzero(~good[:-1] & good[1:]) / np.count_nonzero(~good[:-1])
    ch = markov_from_threshold(rho, a)
    assert f_hat == pytest.approx(ch.failure_rate, rel=0.03)
    assert r_hat == pytest.approx(ch.recovery_rate, rel=0.03)


def test_time_correlated_link_is_a_bursty_channel() -> None:
    path = {**LINK["path_loss"], "shadowing_sigma_db": "6", "shadowing": "time-correlated"}
    corr = {"sample_period_s": "0.1", "correlation_distance_m": "20", "speed_mps": "1.5"}
    link = LinkBudget.from_mapping({**LINK, "path_loss": path, "shadowing_correlation": corr},
                                   "channel")
    rho = math.exp(-1.5 * 0.1 / 20)  # Gudmundson
    assert link.shadowing_correlation.correlation == pytest.approx(rho, rel=1e-14)
    assert link.iid is False
    proc = link.arrival_process()
    assert proc.kind == "markov"
    f, r = proc.failure_rate, proc.recovery_rate
    assert r / (f + r) == pytest.approx(link.arrival_value, rel=1e-9)
    ge = link.gilbert_elliott()
    assert float(ge.failure_rate) == pytest.approx(f) and float(ge.recovery_rate) == \
        pytest.approx(r)
    assert f + r < 0.2  # strongly correlated: long bursts
    sec = design_section(link, critical_value=0.36, robust_value=None, bracket=(None, None),
                         upper_bound=0.47)
    assert sec["gilbert_elliott"]["failure_rate"] == pytest.approx(f)
    assert any("bursty" in w and "does not decide" in w for w in sec["warnings"])
    same_t = LinkBudget.from_mapping(
        {**LINK, "path_loss": path,
         "shadowing_correlation": {"sample_period_s": "0.1",
                                   "coherence_time_s": str(20 / 1.5)}}, "channel")
    assert same_t.shadowing_correlation.correlation == pytest.approx(rho, rel=1e-14)
    with pytest.raises(InputError, match=r"^channel\.path_loss\.shadowing: .*shadowing_corr"):
        LinkBudget.from_mapping({**LINK, "path_loss": path}, "channel")
    with pytest.raises(InputError, match=r"^channel\.shadowing_correlation: only with"):
        LinkBudget.from_mapping({**LINK, "shadowing_correlation": corr}, "channel")
    with pytest.raises(InputError, match=r"^channel\.shadowing_correlation\.speed_mps: is req"):
        LinkBudget.from_mapping({**LINK, "path_loss": path, "shadowing_correlation": {
            "sample_period_s": "0.1", "correlation_distance_m": "20"}}, "channel")
