"""Networks with bursty links: the burst facts decide (theory §9, §10), for the whole network
and for each N − 1 case, and ``network.verdict`` equals ``operating_point.verdict``.

Hand derivations (scalar plant a = 3/2, a² = 9/4, every sensor sees the state):
* any useful arrival resets the error, and independent links are all lost for k steps with
  probability ~ Π c_j^k (c = 1 − r for Gilbert–Elliott, 1 − p for Bernoulli), so E[P] is
  bounded iff Π c_j · a² < 1;
* f = 0.2, r = 0.5 beside Bernoulli 0.5: 0.5 · 0.5 · 9/4 = 0.5625 < 1 → mean-stable; with
  either link dead: 0.5 · 9/4 = 1.125 ≥ 1 → mean-unstable;
* an anti-correlated link f = r = 0.9 beside Bernoulli 0.05: 0.1 · 0.95 · 9/4 = 0.21375 < 1 →
  mean-stable, although the i.i.d. surface at the stationary rate 1/2 says
  0.5 · 0.95 · 9/4 = 1.06875 ≥ 1 (the former false fail);
* r = 0.1 beside Bernoulli 0.5: 0.9 · 0.5 · 9/4 = 1.0125 ≥ 1 → mean-unstable.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kfcrit.cli.main import main

NET = ("name: scalar behind two links\nA: [[1.5]]\nQ: 1\nsensors:\n"
       "  - {name: a, C: 1, R: 1, channel: {model: gilbert-elliott, failure_rate: %s, "
       "recovery_rate: %s}}\n"
       "  - {name: b, C: 1, R: 1, channel: {model: bernoulli, arrival_probability: %s}}\n")


def _run(tmp_path: Path, f: float, r: float, p: float) -> tuple[int, dict]:
    path = tmp_path / "net.yaml"
    path.write_text(NET % (f, r, p))
    res = CliRunner().invoke(main, ["analyze", str(path), "--json", "--quick", "--no-simulate"])
    return res.exit_code, json.loads(res.stdout)


@pytest.mark.parametrize("f, r, p, verdict, code", [
    (0.2, 0.5, 0.5, "mean-stable", 0),
    (0.9, 0.9, 0.05, "mean-stable", 0),
    (0.2, 0.1, 0.5, "mean-unstable", 5),
])
def test_scalar_network_decided_by_the_burst_condition(tmp_path, f, r, p, verdict, code):
    product = (1 - r) * (1 - p) * 2.25
    assert (product < 1) == (verdict == "mean-stable")
    got, rec = _run(tmp_path, f, r, p)
    assert rec["operating_point"]["verdict"] == verdict
    assert rec["network"]["verdict"] == rec["operating_point"]["verdict"]
    assert got == code


def test_each_dead_link_uses_the_burst_condition(tmp_path):
    _, rec = _run(tmp_path, 0.2, 0.5, 0.5)
    dead = {row["name"]: row["n_minus_1"]["verdict"] for row in rec["network"]["sensors"]}
    # a dead: 0.5 · 9/4 = 1.125; b dead (the bursty link alone): (1 − 0.5) · 9/4 = 1.125
    assert dead == {"a": "mean-unstable", "b": "mean-unstable"}


def test_anti_correlated_link_is_stable_by_simulation():
    # independent check of the false fail: the simulated E[P_t] settles (it would grow like
    # 1.06875^t if the i.i.d. necessary surface applied)
    rng = np.random.default_rng(3)
    n, a2 = 20000, 2.25
    P = np.ones(n)
    ge = rng.random(n) < 0.5
    means = []
    for _ in range(240):
        u = rng.random(n)
        ge = np.where(ge, u >= 0.9, u < 0.9)
        got = ge | (rng.random(n) < 0.05)
        P = a2 * np.where(got, P / (P + 1.0), P) + 1.0
        means.append(P.mean())
    assert means[-1] < 20 and abs(means[-1] - means[119]) < 0.1 * means[119]
