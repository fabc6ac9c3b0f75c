"""Gilbert–Elliott links for vector systems (kfcrit.theory.links.markov), against hand results.

Expected values are derived by hand (MATH.md §7, §10):

* necessary: a burst of j losses has probability (1 − r)^{j−1} r and multiplies the dominant
  mode's variance by ρ^{2j}, so bounded E[P_t] needs (1 − r)ρ(A)² < 1;
* C square and invertible: the gain K = −A C⁻¹ gives F_1 = A + K C = 0, and the coupled
  inequalities X_0 ≻ A'((1 − r) X_0 + r X_1) A, X_1 ≻ 0 are solvable iff (1 − r)ρ(A)² < 1
  (take X_1 small): the two conditions coincide, so the verdict is exact on both sides;
* f + r = 1 is an i.i.d. link with p = r, where the coupled condition is Sinopoli's
  jump-linear one: its threshold is p_up = 1 − 1/Π|λ_u|² for one output (closed form).
"""
from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest

from kfcrit.analysis.verdict import verdict_of
from kfcrit.model.system import System
from kfcrit.theory.links import markov


def make(A, C, Q=None, R=None) -> System:
    A, C = np.atleast_2d(np.asarray(A, float)), np.atleast_2d(np.asarray(C, float))
    Q = np.eye(A.shape[0]) if Q is None else np.asarray(Q, float)
    R = np.eye(C.shape[0]) if R is None else np.atleast_2d(np.asarray(R, float))
    return System(A, C, Q, R)


BURSTY = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]], 20 * np.eye(2), [[2.5]])


@pytest.mark.parametrize(("r", "stable"), [(0.8, True), (Fraction(3, 4), False), (0.7, False)])
def test_scalar_burst_condition_is_exact(r, stable):
    # a = 2: (1 − r)·4 = 0.8, 1, 1.2; C = 1 invertible, so stable exactly when < 1
    v = markov.burst_facts(make([[2.0]], [[1.0]]), 0.3, r)
    assert verdict_of(v.facts)[0].value == ("mean-stable" if stable else "mean-unstable")
    if stable:
        assert v.certificate.certified and v.certificate.check["ok"]
    else:
        assert v.necessary.holds is False and v.necessary.rigorous
    json.dumps(v.to_dict(), allow_nan=False)


def test_scalar_boundary_with_a_non_dyadic_modulus():
    # a = 3/2: r_nec = 1 − 4/9 = 5/9 exactly; at r = 5/9 (1 − r)a² = 1 (unstable, equality)
    s = make([[1.5]], [[1.0]])
    at = markov.burst_necessary(s, Fraction(5, 9))
    assert at.holds is False and "equality" in at.how
    above = markov.burst_necessary(s, Fraction(5, 9) + Fraction(1, 10 ** 12))
    assert above.holds is True
    r_nec, expr = markov.necessary_recovery_threshold(s)
    assert expr == "5/9" and r_nec == pytest.approx(5 / 9, abs=1e-15)


@pytest.mark.parametrize(("r", "stable"), [(0.8, True), (0.76, True), (0.75, False),
                                           (0.7, False)])
def test_diagonal_fully_observed(r, stable):
    # A = diag(2, 3/2), C = I: ρ² = 4, stable iff (1 − r)·4 < 1 iff r > 3/4 (C invertible)
    v = markov.burst_facts(make(np.diag([2.0, 1.5]), np.eye(2)), 0.2, r)
    assert verdict_of(v.facts)[0].value == ("mean-stable" if stable else "mean-unstable")


def test_diagonal_fully_observed_curve_closes():
    # C invertible: the sufficient curve equals the necessary line r = 3/4 for every f
    curve = markov.burst_critical_curve(make(np.diag([2.0, 1.5]), np.eye(2)),
                                  failure_rates=[0.1, 0.5, 0.9], tol=1e-3)
    assert curve.necessary_recovery == (0.75, 0.75, 0.75)
    assert curve.necessary_expression == "3/4"
    for r in curve.sufficient_recovery:
        assert r is not None and 0.75 <= r <= 0.75 + 2e-3
    json.dumps(curve.to_dict(), allow_nan=False)


def test_bursty_vector_link_unstable_by_bursts():
    # (1 − 0.2)·1.25² = 1.25 > 1, although r/(f + r) = 2/3 > p_up ≈ 0.471 (i.i.d. would be fine)
    v = markov.burst_facts(BURSTY, 0.1, 0.2)
    assert verdict_of(v.facts)[0].value == "mean-unstable" and v.certificate is None
    assert v.necessary.value == pytest.approx(1.25, abs=1e-12)
    assert v.stationary_arrival == pytest.approx(2 / 3)


def test_bursty_vector_link_proven_stable():
    v = markov.burst_facts(BURSTY, 0.1, 0.5)
    assert verdict_of(v.facts)[0].value == "mean-stable"
    cert = v.certificate
    assert cert.certified and cert.check["ok"] and cert.spectral_radius < 1
    # the proof is re-checkable from the record: the same matrices pass the ball check again
    from kfcrit.theory.upper import certify
    m = cert.matrices
    again = certify.verify_markov_jump(BURSTY, markov.exact_rate(0.1), markov.exact_rate(0.5),
                                       np.array(m["X0"]), np.array(m["X1"]), np.array(m["K"]))
    assert again.ok
    # a perturbed gain far from stabilising is refused by the same check
    bad = certify.verify_markov_jump(BURSTY, markov.exact_rate(0.1), markov.exact_rate(0.5),
                                     np.array(m["X0"]), np.array(m["X1"]), np.zeros((2, 1)))
    assert not bad.ok


def test_literature_claim_is_labelled_not_the_verdict():
    v = markov.burst_facts(BURSTY, 0.1, 0.4, classification="non-degenerate")
    assert v.claim is not None and "claim" in v.claim["label"]
    assert "You, Fu & Xie" in v.claim["source"]


def test_iid_link_threshold_matches_p_up_closed_form():
    # f = 1 − r: the chain is i.i.d. with p = r; one output: p_up = 1 − 1/(1.25²·1.1²)
    p_up = 1 - 1 / (1.25 ** 2 * 1.1 ** 2)
    A, C = BURSTY.a, BURSTY.c
    assert markov.certificate_feasible(A, C, 1 - (p_up + 0.01), p_up + 0.01)
    assert not markov.certificate_feasible(A, C, 1 - (p_up - 0.01), p_up - 0.01)


def _fixed_gain_steady_trace(A, C, Q, R, K, f, r):
    """tr(Y_0 + Y_1) of the steady second moment, by iterating the recursion (not a solve)."""
    T = markov.transition_matrix(f, r)
    pi = np.array([f, r]) / (f + r)
    F = [A, A + K @ C]
    W = [Q, Q + K @ R @ K.T]
    Y = [np.zeros_like(A), np.zeros_like(A)]
    for _ in range(3000):
        Y = [sum(T[i, j] * (F[i] @ Y[i] @ F[i].T + pi[i] * W[i]) for i in (0, 1))
             for j in (0, 1)]
    return float(np.trace(Y[0] + Y[1]))


def test_stable_case_by_simulation_of_the_markov_jump_second_moment():
    # Monte Carlo over Markov loss paths (stationary start): the fixed-gain conditional
    # covariance Π_{t+1} = F_γ Π F_γ' + Q + γ K R K' averages to the recursion's steady value,
    # and the Kalman filter's P_t (Riccati with losses) stays below it on every path
    f, r = 0.1, 0.9
    v = markov.burst_facts(BURSTY, f, r)
    assert verdict_of(v.facts)[0].value == "mean-stable"
    K = np.array(v.certificate.matrices["K"])
    A, C, Q, R = BURSTY.a, BURSTY.c, BURSTY.q, BURSTY.r
    expected = _fixed_gain_steady_trace(A, C, Q, R, K, f, r)
    rng = np.random.default_rng(7)
    paths, steps = 4000, 120
    gamma = (rng.random(paths) < r / (f + r)).astype(int)
    Pi = np.zeros((paths, 2, 2))
    P = np.zeros((paths, 2, 2))
    F = [A, A + K @ C]
    for _ in range(steps):
        new_pi = np.empty_like(Pi)
        for g in (0, 1):
            idx = gamma == g
            new_pi[idx] = F[g] @ Pi[idx] @ F[g].T + Q + g * (K @ R @ K.T)
        S = C @ P @ C.T + R                                     # (paths, 1, 1)
        gain = A @ P @ C.T @ np.linalg.inv(S)
        upd = A @ P @ A.T + Q - gamma[:, None, None] * (gain @ C @ P @ A.T)
        Pi, P = new_pi, 0.5 * (upd + np.transpose(upd, (0, 2, 1)))
        u = rng.random(paths)
        gamma = np.where(gamma == 1, (u >= f).astype(int), (u < r).astype(int))
    tr_pi = np.trace(Pi, axis1=1, axis2=2)
    tr_p = np.trace(P, axis1=1, axis2=2)
    assert abs(tr_pi.mean() - expected) <= 0.1 * expected
    assert np.all(tr_p <= tr_pi * (1 + 1e-9))
    assert tr_p.mean() < expected


def test_bad_rates_are_refused():
    with pytest.raises(ValueError, match="recovery_rate"):
        markov.burst_necessary(BURSTY, 1.5)
    with pytest.raises(TypeError, match="failure_rate"):
        markov.burst_facts(BURSTY, "0.1", 0.5)


def test_compiled_lmi_reused_across_rates_equals_a_fresh_one() -> None:
    """The critical curve re-solves one compiled LMI (f, r as parameters): each solve must
    equal a problem built afresh at that (f, r), whatever was solved before it."""
    A = np.array([[1.25, 0.0], [1.0, 1.1]])
    C = np.array([[1.0, 1.0]])
    reused = markov.CoupledLmi(A, C)
    for f, r in [(0.3, 0.9), (0.05, 0.45), (0.6, 0.2), (0.1, 0.5)]:
        _, t_reused = reused.solve(f, r)
        _, t_fresh = markov.CoupledLmi(A, C).solve(f, r)
        assert t_reused == pytest.approx(t_fresh, rel=1e-6, abs=1e-9), (f, r)


def test_smallest_certified_finds_a_stretch_plain_bisection_misses():
    # Certified on [0.30, 0.40] and [0.80, 1]: a plain bisection on [0.1, 1] tests 0.55 (not
    # certified) and then never looks below it, ending at 0.80. The grid 0.1 + 0.075 k hits
    # 0.325 (certified) after 0.25 (not), so the bisection inside [0.25, 0.325] ends within
    # tol above 0.30.
    from kfcrit.theory.links.markov import smallest_certified

    calls = []

    def feasible(r: float) -> bool:
        calls.append(r)
        return 0.30 <= r <= 0.40 or r >= 0.80

    got = smallest_certified(feasible, 0.1, 1.0, 1e-4, points=12)
    assert 0.30 <= got <= 0.30 + 1e-4
    # every point the search tried below 0.30 was infeasible (no certified point was skipped)
    assert all(r >= 0.30 or not (0.30 <= r <= 0.40 or r >= 0.80) for r in list(calls))
    assert smallest_certified(lambda r: False, 0.1, 1.0, 1e-3) is None
    assert smallest_certified(lambda r: r >= 0.95, 0.1, 1.0, 1e-3) == pytest.approx(0.95, abs=1e-3)
