"""The accuracy requirement over a Gilbert–Elliott link is decided by bounds valid for that
channel (theory §10), never by the i.i.d. V̄ at the stationary arrival probability.

The Sinopoli general plant A = [[1.25, 0], [1, 1.1]], C = [1 1], Q = 20 I, R = 2.5 over the
chain f = 0.1, r = 0.5 (stationary arrival 5/6): the i.i.d. V̄ at p = 5/6 has trace 110.8, but
the losses-only lower bound, summed here by hand over the time since the last arrival, is
395.5 (M1 = A u(Q) A' + Q after an arrival, A^k M1 A'^k + Σ_{i<k} A^i Q A'^i after k losses,
each with stationary probability π_1 f (1 − r)^{k−1}); a joint Monte Carlo
(tests/theory/test_burstcov.py) puts lim E[tr P] between it and the fixed-gain bound 503.7.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from kfcrit.analysis.requirements import mean_assessment
from kfcrit.cli.main import main
from kfcrit.io.typed import ABSENT
from kfcrit.records.contract import Verdict
from kfcrit.records.covariance import (
    CovarianceBounds,
    CovarianceSummary,
    MarkovJumpLower,
    MarkovJumpRecord,
    MarkovJumpUpper,
)

PLANT = ("name: Sinopoli general over a bursty link\nA: [[1.25, 0], [1, 1.1]]\nC: [[1, 1]]\n"
         "Q: 20\nR: 2.5\nchannel: {model: gilbert-elliott, failure_rate: 0.1, "
         "recovery_rate: 0.5}\nrequirements: {max_mean_error_trace: %s}\n")


def _hand_lower() -> float:
    A, C, Q, R = np.array([[1.25, 0], [1, 1.1]]), np.array([[1.0, 1.0]]), 20 * np.eye(2), 2.5
    uQ = Q - Q @ C.T @ C @ Q / (C @ Q @ C.T + R)
    M1 = A @ uQ @ A.T + Q
    pi1, f, r = 5 / 6, 0.1, 0.5
    total, Ak, acc = pi1 * np.trace(M1), np.eye(2), np.zeros((2, 2))
    for k in range(1, 400):
        acc, Ak = acc + Ak @ Q @ Ak.T, A @ Ak
        total += pi1 * f * (1 - r) ** (k - 1) * np.trace(Ak @ M1 @ Ak.T + acc)
    return float(total)


def _run(tmp_path: Path, limit: float) -> tuple[int, dict]:
    p = tmp_path / "ge.yaml"
    p.write_text(PLANT % limit)
    r = CliRunner().invoke(main, ["analyze", str(p), "--json", "--quick", "--no-simulate"])
    return r.exit_code, json.loads(r.stdout)


def test_false_pass_is_now_a_fail(tmp_path):
    code, rec = _run(tmp_path, 150)
    lower = _hand_lower()
    assert abs(lower - 395.504) < 0.01
    assert rec["covariance_bounds"]["upper"]["trace"] < 150      # the i.i.d. V̄ would pass it
    (item,) = rec["requirements"]["assessments"]
    assert item["status"] == "not met"
    assert abs(item["interval"][0] - lower) < 1e-6 * lower
    assert rec["review"]["decision"] == "fail" and code == 5
    assert rec["operating_point"]["verdict"] == "mean-stable"


def test_met_only_above_the_markov_jump_upper_bound(tmp_path):
    code, rec = _run(tmp_path, 600)
    (item,) = rec["requirements"]["assessments"]
    assert item["status"] == "met" and rec["review"]["decision"] == "pass" and code == 0
    assert _hand_lower() <= item["interval"][1] <= 600


def _iid_bounds(markov_jump=ABSENT) -> CovarianceBounds:
    """The covariance bounds section with tr S̄ = 61, tr V̄ = 110 (i.i.d.) and the given
    Markov-jump bounds."""
    def summary(trace):
        return CovarianceSummary(exists=True, trace=trace, max_eig=None, matrix=None)

    return CovarianceBounds(p=0.6, lower=summary(61.0), upper=summary(110.0),
                            markov_jump=markov_jump)


def test_between_the_bounds_is_not_demonstrated():
    bounds = _iid_bounds(MarkovJumpRecord(
        failure_rate=0.1, recovery_rate=0.4, method="test",
        lower=MarkovJumpLower(trace=395.5, exists=True, basis="test"),
        upper=MarkovJumpUpper(trace=503.7, exists=True, basis="test", spectral_radius=None,
                              gains=None)))
    op = (Verdict.MEAN_STABLE, False)
    assert mean_assessment(450, bounds, *op).status == "not demonstrated"
    assert mean_assessment(150, bounds, *op).status == "not met"
    assert mean_assessment(600, bounds, *op).status == "met"


def test_channel_with_memory_without_a_chain_bound_is_never_met():
    # a measured trace: S̄, V̄ at the empirical rate decide nothing, in either direction
    bounds = _iid_bounds()
    op = (Verdict.MEAN_STABLE, False)
    assert mean_assessment(150, bounds, *op).status == "not demonstrated"
    assert mean_assessment(50, bounds, *op).status == "not demonstrated"
