"""kfcrit's 802.15.4 link budget against ns-3's lr-wpan model (recorded facts, no ns-3 needed).

``tests/data/ns3/lrwpan_per.json`` was written by ``tests/data/ns3/generate_facts.py`` (ns-3 3.44
Python wheel): two nodes, 0 dBm, 20-byte MSDU, no ACK, no retry, ns-3's default log-distance
loss, 10,000 packets per distance, with ns-3's own analytic success probability
``LrWpanErrorModel::GetChunkSuccessRate(sinr, nbits)`` at the SINR ns-3 computes.

The link budget is configured to ns-3's parameters:

* path loss: ``LogDistancePropagationLossModel`` defaults, PL(d) = 46.6777 + 30·log10(d / 1 m);
* noise: ns-3's ``LrWpanSpectrumValueHelper`` noise PSD is k·T per Hz with its own constant
  k = 1.3803e-23 J/K (kfcrit uses the exact SI value 1.380649e-23, 0.0011 dB higher), T = 290 K,
  noise factor 1 (0 dB), and ``TotalAvgPower`` integrates it over the channel's 5 bands of
  1 MHz — a 5 MHz noise bandwidth. So the noise floor is given as ``noise_floor_dbm`` =
  10·log10(1.3803e-23 · 290 · 5e6 / 1 mW) ≈ −106.987 dBm, computed here by hand;
* the transmit PSD puts (0.005 + 0.495 + 1 + 0.495 + 0.005)/2 = 1 of the power in those bands,
  so the received power is Pt − PL(d) (checked against the recorded value);
* frame: ns-3's MAC sends a 31-byte PSDU for a 20-byte MSDU with short addresses (11 bytes of
  MAC header and FCS: kfcrit's default), and its error model covers every bit of the PPDU
  (``nbits`` = duration × 250 kb/s = 8·(6 + 31) = 296): kfcrit's default ``per_over: ppdu``.

ns-3 also drops a frame whose SINR is ≤ −5 dB before decoding (``LrWpanPhy::StartRx``); every
recorded point lies above that, and the analytic value there is already < 1e-5.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from kfcrit.link.linkbudget import LinkBudget

DATA = Path(__file__).resolve().parents[1] / "data" / "ns3"
PER_FILE = DATA / "lrwpan_per.json"
CONTENTION_FILE = DATA / "lrwpan_contention.json"

NS3_BOLTZMANN = 1.3803e-23
NS3_NOISE_DBM = 10 * math.log10(NS3_BOLTZMANN * 290.0 * 5e6 / 1e-3)
MAC_OVERHEAD = 2 + 1 + 2 + 2 + 2 + 2
PHY_HEADER = 4 + 1 + 1


def per_facts() -> dict:
    return json.loads(PER_FILE.read_text())


def ns3_link(distance_m: float, **extra: str) -> LinkBudget:
    """The link budget with ns-3's parameters (module docstring)."""
    return LinkBudget.from_mapping(
        {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
         "distance_m": repr(float(distance_m)), "packet_bytes": "20",
         "path_loss": {"model": "log-distance", "exponent": "3", "reference_distance_m": "1",
                       "reference_loss_db": "46.6777"},
         "noise": {"noise_floor_dbm": repr(NS3_NOISE_DBM)}, **extra}, "channel")


POINTS = per_facts()["points"]
LOSSY = [pt for pt in POINTS if 0.02 < ns3_link(pt["distance_m"]).arrival_value < 0.98]


def test_the_recorded_run_is_the_configured_one() -> None:
    meta = per_facts()["meta"]
    assert meta["ns3_python_wheel"].startswith("3.44")
    assert meta["parameters"]["payload_bytes"] == 20
    assert meta["parameters"]["packets_per_distance"] == 10_000
    assert len(LOSSY) >= 6  # the lossy range is sampled
    for pt in POINTS:
        link = ns3_link(pt["distance_m"])
        assert pt["requested"] == pt["transmitted"] == 10_000  # CSMA-CA never gave up
        assert pt["psdu_bytes"] == 20 + MAC_OVERHEAD == link.psdu_bytes
        assert pt["error_model_bits"] == 8 * (PHY_HEADER + 20 + MAC_OVERHEAD)
        assert link.per_bytes * 8 == pt["error_model_bits"]
        assert pt["noise_dbm"] == pytest.approx(NS3_NOISE_DBM, abs=1e-9)
        assert pt["rx_power_dbm"] == pytest.approx(
            -46.6777 - 30 * math.log10(pt["distance_m"]), abs=1e-9)
        assert link.sinr_db == pytest.approx(pt["sinr_db"], abs=1e-9)
        assert pt["sinr_db"] > -5.0


@pytest.mark.parametrize("pt", POINTS, ids=lambda pt: f"{pt['distance_m']:g}m")
def test_arrival_equals_ns3_analytic_success(pt: dict) -> None:
    """Same SINR, same formula, same 296 bits: agreement to rounding (observed ≤ 1e-14)."""
    assert ns3_link(pt["distance_m"]).arrival_value == pytest.approx(
        pt["ns3_analytic_success"], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("pt", LOSSY, ids=lambda pt: f"{pt['distance_m']:g}m")
def test_arrival_lies_in_the_ns3_confidence_interval(pt: dict) -> None:
    lo, hi = pt["ci95"]
    assert lo <= ns3_link(pt["distance_m"]).arrival_value <= hi


def test_psdu_only_convention_is_what_ns3_rejects() -> None:
    """The PSDU-only PER (the old default) lies outside ns-3's 95 % interval at most lossy
    distances (8 of the 11 recorded points, 105–135 m): the PHY header matters."""
    outside = [pt["distance_m"] for pt in LOSSY
               if not pt["ci95"][0] <= ns3_link(pt["distance_m"], per_over="psdu").arrival_value
               <= pt["ci95"][1]]
    assert len(outside) >= len(LOSSY) - 3 and len(outside) >= 4


def test_contention_facts_are_consistent() -> None:
    """The contention record's summaries are those of its 0/1 traces (a guard on the data; the
    traces are for network-level comparisons: synchronous sampling with CSMA-CA and no ACK
    makes the losses of different sensors dependent)."""
    facts = json.loads(CONTENTION_FILE.read_text())
    assert {c["name"] for c in facts["cases"]} == {"hidden-4-tetrahedron-110m",
                                                   "dense-8-circle-30m"}
    for case in facts["cases"]:
        traces = case["traces"]
        periods = case["periods"]
        assert len(traces) == case["sensors"] and all(len(t) == periods for t in traces)
        assert [t.count("1") for t in traces] == case["delivered"]
        lost_all = sum(all(t[k] == "0" for t in traces) for k in range(periods))
        assert lost_all == case["all_lost_periods"]
        assert case["product_of_marginal_losses"] == pytest.approx(
            math.prod(1 - d / periods for d in case["delivered"]), rel=1e-12)
    hidden = next(c for c in facts["cases"] if c["name"].startswith("hidden"))
    # hidden terminals: pairwise beyond the −5 dB decoding threshold of ns-3's PHY
    assert hidden["min_pairwise_distance_m"] > 160
