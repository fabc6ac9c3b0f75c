"""A network record names the stacked system's values as such (keys added, not renamed).

By hand: reports/network-redundant-gauges.yaml has a = 3 and three scalar gauges; stacked on
one link (all packets together) C = [1 1 1]' sees the state, so p_c = 1 − 1/a² = 8/9 — not any
gauge's own critical value (the pressure gauge's is 4/9: (1 − 0.6)(1 − 0.5)(1 − p)·9 < 1).
"""
from __future__ import annotations

import json

from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS


def test_stacked_values_are_named():
    path = str(REPORTS / "network-redundant-gauges.yaml")
    rec = json.loads(CliRunner().invoke(main, ["analyze", path, "--json", "--quick",
                                               "--no-simulate"]).stdout)
    net = rec["network"]
    assert abs(net["stacked_critical_value"]["value"] - 8 / 9) < 1e-12
    assert net["stacked_critical_value"]["value"] == rec["critical_value"]["value"]  # added
    assert net["stacked_upper_bound"]["interval"] == rec["upper_bound"]["interval"]
    pressure = next(s for s in net["sensors"] if s["name"] == "pressure")
    assert abs(pressure["critical_value"]["value"] - 4 / 9) < 1e-12
    text = CliRunner().invoke(main, ["analyze", path, "--quick", "--no-simulate"]).stdout
    assert "stacked system (all sensors on one link)" in text


def test_a_network_monte_carlo_scales_its_paths_by_the_stacked_step_cost():
    from kfcrit.analysis.network import stacked_paths

    # c(n, m) = n³ + m³ + n²m + nm²: c(1, 3) = 40 ≤ c(6, 6) = 864 keeps the budget;
    # c(6, 12) = 3240 is 3.75 × c(6, 6): 2000 → 533; c(1, 100) ≈ 1.01e6: the floor of 64
    assert stacked_paths(2000, 1, 3) == 2000
    assert stacked_paths(2000, 6, 12) == 533
    assert stacked_paths(2000, 1, 100) == 64
    assert stacked_paths(30, 1, 100) == 30  # never more than the budget
