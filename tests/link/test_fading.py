"""Fast fading in the link budget (docs/theory.md §11.1): Rayleigh and Nakagami-m per attempt.

Expected values come from independent computations: the closed form of Rayleigh-faded BPSK
(one bit), scipy.integrate.quad in ln γ, a numpy Monte Carlo with 1e6 draws, the no-fading
limit m → ∞, and a refined shadowing grid.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from scipy import integrate, special

from kfcrit.cli.main import main
from kfcrit.errors import InputError
from kfcrit.link.fading import FastFading, faded_per, laguerre_rule
from kfcrit.link.linkbudget import LinkBudget, design_section
from kfcrit.link.ns3.topology import build_plan

LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "100", "packet_bytes": "40",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}
RAYLEIGH = {"model": "rayleigh"}


def one_bit_bpsk_per(g: np.ndarray) -> np.ndarray:
    return 0.5 * special.erfc(np.sqrt(g))


def link(**extra: object) -> LinkBudget:
    return LinkBudget.from_mapping({**LINK, **extra}, "channel")


def quad_mean_per(per, gbar: float, m: float) -> float:
    """E[PER(γ)], γ ~ Gamma(m, γ̄/m), by adaptive quadrature in v = ln(γ/γ̄) (independent)."""
    def f(v: float) -> float:
        return float(per(np.array(gbar * math.exp(v)))) * math.exp(
            m * math.log(m) + m * v - m * math.exp(v) - special.gammaln(m))
    lo = math.log(special.gammaincinv(m, 1e-18) / m)
    hi = math.log(special.gammainccinv(m, 1e-18) / m)
    breaks = [v for v in np.log(np.array([0.3, 1.0, 3.0, 10.0]) / gbar) if lo < v < hi]
    value, _ = integrate.quad(f, lo, hi, points=breaks or None, epsabs=1e-14, epsrel=1e-12,
                              limit=500)
    return value


# --- (a) the closed form: Rayleigh-faded BPSK, one bit -------------------------------------------

@pytest.mark.parametrize("gbar_db", [-20.0, -5.0, 0.0, 3.0, 10.0, 20.0, 30.0, 50.0])
def test_rayleigh_one_bit_bpsk_matches_the_closed_form(gbar_db: float) -> None:
    gbar = 10 ** (gbar_db / 10)
    closed = 0.5 * (1 - math.sqrt(gbar / (1 + gbar)))
    value = float(FastFading("rayleigh").mean_per(one_bit_bpsk_per, gbar))
    assert value == pytest.approx(closed, abs=1e-10, rel=1e-9)


def test_the_link_budget_averages_its_own_per_over_rayleigh_fading() -> None:
    """BPSK radio, 1-byte payload (8 bits): the link's attempt PER against quad."""
    ch = link(radio="bpsk", packet_bytes="1", fading=RAYLEIGH)
    for s in (-3.0, 5.0, 15.0, 35.0):
        expected = quad_mean_per(ch.instantaneous_per, 10 ** (s / 10), 1.0)
        assert float(ch.attempt_per(s)) == pytest.approx(expected, abs=1e-11, rel=1e-9)


@pytest.mark.parametrize("m", [0.5, 1.0, 2.5, 30.0, 1000.0])
@pytest.mark.parametrize("gbar_db", [-5.0, 5.0, 15.0, 30.0])
def test_oqpsk_faded_per_agrees_with_adaptive_quadrature(m: float, gbar_db: float) -> None:
    ch = link(packet_bytes="100")
    gbar = 10 ** (gbar_db / 10)
    value, err = faded_per(ch.instantaneous_per, gbar, m)
    assert float(value) == pytest.approx(quad_mean_per(ch.instantaneous_per, gbar, m),
                                         abs=1e-11, rel=1e-9)
    assert float(err) <= 1e-9


def test_laguerre_node_counts_can_agree_while_both_are_wrong() -> None:
    """Far above the PER threshold, 64 and 128 nodes both miss the step (below their smallest
    node); the guard sends such points to the composite rule."""
    ch = link()
    gbar = 1e3                                   # 30 dB mean SNR, Rayleigh
    (x1, w1), (x2, w2) = laguerre_rule(64, 1.0), laguerre_rule(128, 1.0)
    coarse = float(np.sum(ch.instantaneous_per(gbar * x1) * w1))
    fine = float(np.sum(ch.instantaneous_per(gbar * x2) * w2))
    truth = quad_mean_per(ch.instantaneous_per, gbar, 1.0)
    assert abs(fine - coarse) < 1e-20 and abs(fine - truth) > 1e-4
    value, _ = faded_per(ch.instantaneous_per, gbar, 1.0)
    assert float(value) == pytest.approx(truth, rel=1e-9)


def test_laguerre_is_used_where_it_converges() -> None:
    """Large m, mean SNR near the threshold: the Laguerre value itself, error ≤ 1e-9."""
    ch = link()
    (x2, w2) = laguerre_rule(128, 20.0)
    gbar = 1.0
    value, err = faded_per(ch.instantaneous_per, gbar, 20.0)
    assert float(value) == float(np.sum(ch.instantaneous_per(gbar / 20.0 * x2) * w2))
    assert 0 < float(err) <= 1e-9


# --- (b) m → ∞ is no fading ------------------------------------------------------------------------

def test_nakagami_tends_to_no_fading_as_m_grows() -> None:
    plain = link(max_retries="2")
    gaps = []
    for m in ("3", "30", "300", "3000"):
        faded = link(max_retries="2", fading={"model": "nakagami", "m": m})
        gaps.append(abs(faded.arrival_value - plain.arrival_value))
    assert all(a > b for a, b in zip(gaps, gaps[1:], strict=False)), gaps
    assert gaps[-1] < 1e-3 * gaps[0] and gaps[-1] < 1e-6


def test_rayleigh_is_nakagami_one() -> None:
    a = link(fading=RAYLEIGH)
    b = link(fading={"model": "nakagami", "m": 1})
    assert a.arrival_value == b.arrival_value
    assert a.fading.to_dict() == {"model": "rayleigh", "m": 1.0}


# --- (c) Monte Carlo -------------------------------------------------------------------------------

@pytest.mark.parametrize("fading, distance", [(RAYLEIGH, "40"), (RAYLEIGH, "100"),
                                              ({"model": "nakagami", "m": "2.5"}, "100"),
                                              ({"model": "nakagami", "m": "0.5"}, "60")])
def test_attempt_success_agrees_with_a_monte_carlo(fading: dict, distance: str) -> None:
    ch = link(fading=fading, distance_m=distance)
    m = ch.fading.shape
    gbar = 10 ** (ch.sinr_db / 10)
    rng = np.random.default_rng(20261203)
    gamma = gbar * rng.gamma(m, 1.0 / m, size=1_000_000)
    success = -ch.instantaneous_per(gamma) + 1.0
    se = success.std(ddof=1) / math.sqrt(success.size)
    q = float(np.exp(ch.attempt_log_arrival(ch.sinr_db)))
    assert abs(success.mean() - q) <= 4 * se, (success.mean(), q, se)


# --- (d) monotone in distance, with retries and shadowing -------------------------------------------

@pytest.mark.parametrize("extra", [
    {"fading": RAYLEIGH},
    {"fading": {"model": "nakagami", "m": "0.7"}, "max_retries": "3"},
    {"fading": RAYLEIGH, "path_loss": {**LINK["path_loss"], "shadowing_sigma_db": "4",
                                       "shadowing": "per-packet"}},
    {"fading": {"model": "nakagami", "m": "4"}, "max_retries": "2",
     "fading_per_attempt": "independent",
     "path_loss": {**LINK["path_loss"], "shadowing_sigma_db": "3", "shadowing": "per-packet"}},
])
def test_arrival_is_monotone_in_distance(extra: dict) -> None:
    values = [link(distance_m=str(d), **extra).arrival_value for d in (10, 30, 60, 100, 150, 250)]
    assert all(a > b for a, b in zip(values, values[1:], strict=False)), values
    assert values[0] > 0.99 and values[-1] < 0.9


def test_fading_costs_arrival_and_retries_recover_part_of_it() -> None:
    plain, faded = link(), link(fading=RAYLEIGH)
    retried = link(fading=RAYLEIGH, max_retries="3")
    assert faded.arrival_value < plain.arrival_value
    q = float(np.exp(faded.attempt_log_arrival(faded.sinr_db)))
    assert retried.arrival_value == pytest.approx(1 - (1 - q) ** 4, rel=1e-12)


def test_shadowing_average_step_with_fading_is_converged() -> None:
    """The coarser shadowing grid used with fading against the 0.02 dB grid."""
    path = {**LINK["path_loss"], "shadowing_sigma_db": "6", "shadowing": "per-packet"}
    for fading in (RAYLEIGH, {"model": "nakagami", "m": "3"}):
        ch = link(fading=fading, path_loss=path, max_retries="1")
        sigma = ch.sigma_db
        z = np.linspace(-9, 9, 2 * math.ceil(9 / (0.02 / sigma)) + 1)
        values = ch.link_arrival(ch.sinr_db + sigma * z) * np.exp(-0.5 * z * z)
        fine = float(np.trapezoid(values, z)) / math.sqrt(2 * math.pi)
        assert ch.arrival_value == pytest.approx(fine, abs=1e-11)


def test_required_sinr_inverts_the_faded_arrival() -> None:
    ch = link(fading=RAYLEIGH, max_retries="2")
    for p in (0.5, 0.9, 0.999):
        s = ch.link_required_sinr_db(p)
        assert ch.nominal_arrival(s) == pytest.approx(p, rel=1e-8)
    assert ch.link_required_sinr_db(0.9) > link(max_retries="2").link_required_sinr_db(0.9)


# --- (e) bad values --------------------------------------------------------------------------------

@pytest.mark.parametrize("fading, field", [
    ({"model": "nakagami", "m": "0.3"}, "channel.fading.m"),
    ({"model": "nakagami"}, "channel.fading.m"),
    ({"model": "rayleigh", "m": "2"}, "channel.fading.m"),
    ({"model": "rician"}, "channel.fading.model"),
    ({"m": "2"}, "channel.fading.model"),
    ({"model": "rayleigh", "k": "2"}, "channel.fading.k"),
    ("rayleigh", "channel.fading"),
])
def test_bad_fading_is_refused_by_field(fading: object, field: str) -> None:
    with pytest.raises(InputError) as err:
        link(fading=fading)
    assert str(err.value).startswith(field + ":")


@pytest.mark.parametrize("fading, field", [({"model": "nakagami", "m": 0.3}, "channel.fading.m"),
                                           ({"model": "rician"}, "channel.fading.model")])
def test_bad_fading_exits_2_naming_the_field(tmp_path: Path, fading: dict, field: str) -> None:
    system = {"name": "f", "A": [[1.2]], "C": [[1]], "Q": 1, "R": 1,
              "channel": {**LINK, "fading": fading}}
    path = tmp_path / "f.yaml"
    path.write_text(yaml.safe_dump(system))
    for command in ("check", "analyze"):
        r = CliRunner().invoke(main, [command, str(path)])
        assert r.exit_code == 2 and f"error: {field}:" in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1


# --- the record ------------------------------------------------------------------------------------

def test_fading_in_the_channel_dict_and_the_notes() -> None:
    ch = link(fading={"model": "nakagami", "m": "2"}, max_retries="1")
    assert ch.to_dict()["fading"] == {"model": "nakagami", "m": 2.0}
    assert link().to_dict()["fading"] == {"model": "none", "m": None}
    section = design_section(ch, critical_value=0.5, robust_value=None, bracket=(None, None),
                             upper_bound=None)
    assert any("Nakagami-m (m = 2)" in note and "per attempt" in note
               for note in section["notes"])
    assert "fast fading" in section["frame"]["retry_assumption"]
    assert section["link"]["attempt_arrival_probability"] == pytest.approx(
        1 - float(ch.attempt_per(ch.sinr_db)), rel=1e-14)


def test_analyze_records_the_fading(tmp_path: Path) -> None:
    system = {"name": "f", "A": [[1.2]], "C": [[1]], "Q": 1, "R": 1,
              "channel": {**LINK, "fading": {"model": "rayleigh"}, "max_retries": 2}}
    path = tmp_path / "f.yaml"
    path.write_text(yaml.safe_dump(system))
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", "--no-simulate"])
    assert r.exit_code in (0, 1, 3), r.stderr     # a verdict, not an input or internal error
    record = json.loads(r.stdout)
    channel = record["operating_point"]["channel"]
    assert channel["fading"] == {"model": "rayleigh", "m": 1.0}
    expected = link(fading=RAYLEIGH, max_retries="2").arrival_value
    assert channel["arrival_probability"] == pytest.approx(expected, rel=1e-12)
    assert any("Rayleigh (m = 1) fast fading" in n for n in record["link_budget"]["notes"])
    # without shadowing the distance curve has no shadowing average (null, a valid record)
    assert record["link_budget"].get("curves") is None or \
        record["link_budget"]["curves"]["arrival_vs_distance"]["mean_arrival"] is None


# --- ns-3 takes the file's fading --------------------------------------------------------------------

def test_ns3_plan_takes_the_links_fading_and_refuses_a_contradiction() -> None:
    ch = link(fading={"model": "nakagami", "m": "2"})
    plan = build_plan([("s", ch, None)], sink_position_m=None, periods=10, period_s=0.1, seed=0)
    assert plan.nakagami_m == 2.0
    with pytest.raises(InputError, match=r"^channel\.fading: --nakagami-m 3"):
        build_plan([("s", ch, None)], sink_position_m=None, periods=10, period_s=0.1, seed=0,
                   nakagami_m=3.0)
    mixed = [("a", ch, (10.0, 0.0, 0.0)), ("b", link(), (20.0, 0.0, 0.0))]
    with pytest.raises(InputError, match=r"^sensors\[\]\.channel\.fading: ns-3 applies one"):
        build_plan(mixed, sink_position_m=None, periods=10, period_s=0.1, seed=0)
