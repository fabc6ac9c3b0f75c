"""N − 1 of a two-sensor network leaves one sensor alone: its single-link theory decides.

By hand: A = diag(6/5, −6/5), the sensor 'pair' sees C = [1 1]. C A^k = (6/5)^k [1, (−1)^k],
so the two modes are told apart only by measurements of both parities; losing every other
packet keeps the difference unobserved while it grows by a⁴ per two steps. Hence
p_c = 1 − a⁻⁴ = 1 − 625/1296 = 671/1296 ≈ 0.5177 (Mo–Sinopoli, degenerate second order), and at
p = 0.35 < p_c the filter with 'full' dead is mean-unstable, although the network's necessary
surface with that link dead, (1 − 0.35)·a² = 0.936 < 1, holds. The sensor 'full' (C = I)
alone has p_c = 1 − a⁻² = 11/36 < 0.9: mean-stable with 'pair' dead.
"""
from __future__ import annotations

import sympy as sp

from kfcrit.model.network import Network, Sensor
from kfcrit.theory.links.network import network_analysis


def _network() -> Network:
    ch = {"pair": sp.Rational(7, 20), "full": sp.Rational(9, 10)}
    from kfcrit.model.channels import Bernoulli

    return Network([["6/5", 0], [0, "-6/5"]], 1, sensors=[
        Sensor("pair", [[1, 1]], 1, Bernoulli(ch["pair"])),
        Sensor("full", [[1, 0], [0, 1]], 1, Bernoulli(ch["full"]))])


def test_lone_sensor_uses_its_exact_critical_value():
    res = network_analysis(_network()).to_dict()
    rows = {r["name"]: r["n_minus_1"] for r in res["sensors"]}
    a4 = sp.Rational(6, 5) ** 4
    assert 1 - 1 / a4 == sp.Rational(671, 1296)
    assert (1 - 0.35) * 1.44 < 1                         # the network's necessary surface holds
    assert rows["full"]["facts"]["necessary"] is False  # 'pair' alone: 0.35 ≤ 671/1296
    assert "671/1296" in rows["full"]["facts"]["necessary_basis"]
    assert rows["pair"]["facts"]["sufficient"] is True  # 'full' alone: 0.9 > 11/36
    assert "11/36" in rows["pair"]["facts"]["sufficient_basis"]
