"""Retries whose shadowing is correlated in time (``fading_per_attempt: correlated``): the
Gauss–Markov recursion of kfcrit.link.fading.correlated_all_fail against its two limits (shared
and independent attempts) and against a Monte Carlo written here."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from kfcrit.analysis.spec import spec_from_mapping
from kfcrit.cli.main import main

BASE = {"name": "corr", "A": [[1.25, 0], [1, 1.1]], "C": [[1, 1]], "Q": 20, "R": 2.5}
CHANNEL = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": 0,
           "distance_m": 150, "packet_bytes": 20, "max_retries": 3,
           "path_loss": {"model": "log-distance", "exponent": 3.0, "reference_distance_m": 1,
                         "reference_loss_db": 40.2, "shadowing": "per-packet",
                         "shadowing_sigma_db": 4},
           "noise": {"noise_figure_db": 10, "bandwidth_hz": 2.0e6}}


def link(**extra):  # noqa: ANN003, ANN201
    doc = dict(BASE, channel=dict(CHANNEL, **extra))
    return spec_from_mapping(doc).channel


def test_limits_are_the_shared_and_the_independent_attempts() -> None:
    shared = link().arrival_value
    independent = link(fading_per_attempt="independent").arrival_value
    slow = link(fading_per_attempt="correlated", coherence_time_s=1e6)
    fast = link(fading_per_attempt="correlated", coherence_time_s=1e-9)
    assert slow.attempt_correlation == pytest.approx(1.0, abs=1e-8)
    assert fast.attempt_correlation == pytest.approx(0.0, abs=1e-12)
    assert slow.arrival_value == pytest.approx(shared, abs=1e-5)
    assert fast.arrival_value == pytest.approx(independent, abs=1e-5)
    assert shared < independent


def test_arrival_falls_as_the_attempts_decorrelate_less() -> None:
    values = [link(fading_per_attempt="correlated", coherence_time_s=t).arrival_value
              for t in (1e-4, 1e-3, 1e-2, 1e-1, 1.0)]
    assert all(a > b for a, b in zip(values, values[1:]))


def test_agrees_with_a_monte_carlo_of_the_gauss_markov_shadowing() -> None:
    lb = link(fading_per_attempt="correlated", coherence_time_s=0.01)
    rho, sigma, k1 = lb.attempt_correlation, lb.sigma_db, lb.max_retries + 1
    assert lb.attempt_spacing_s > 0 and 0.5 < rho < 0.95
    rng = np.random.default_rng(5)
    n = 400_000
    z = rng.standard_normal(n)
    fail = np.ones(n)
    for _ in range(k1):
        fail *= lb.attempt_per(lb.sinr_db + sigma * z)
        z = rho * z + math.sqrt(1 - rho * rho) * rng.standard_normal(n)
    p_mc = 1.0 - fail.mean()
    se = fail.std() / math.sqrt(n)
    assert abs(lb.arrival_value - p_mc) < 4 * se + 1e-6


@pytest.mark.parametrize("extra, field", [
    ({"fading_per_attempt": "correlated"}, "channel.coherence_time_s"),
    ({"coherence_time_s": 0.01}, "channel.coherence_time_s"),
    ({"fading_per_attempt": "correlated", "coherence_time_s": -1}, "channel.coherence_time_s"),
])
def test_bad_correlated_retries_exit_2_naming_the_field(tmp_path: Path, extra: dict,
                                                        field: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(dict(BASE, channel=dict(CHANNEL, **extra))))
    r = CliRunner().invoke(main, ["analyze", str(path), "--no-simulate"])
    assert r.exit_code == 2 and field in r.stderr and "\n" not in r.stderr.strip()


def test_correlated_needs_per_packet_shadowing(tmp_path: Path) -> None:
    ch = dict(CHANNEL, fading_per_attempt="correlated", coherence_time_s=0.01)
    ch["path_loss"] = dict(CHANNEL["path_loss"], shadowing="per-link")
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(dict(BASE, channel=ch)))
    r = CliRunner().invoke(main, ["analyze", str(path), "--no-simulate"])
    assert r.exit_code == 2 and "fading_per_attempt" in r.stderr
