"""Gains chosen by the previous arrival (kfcrit.theory.links.pairgain, theory §10).

Two 2-state plants over Gilbert–Elliott links whose single-gain certificate fails but whose
previous-arrival-gain certificate is proven. Checked independently of the ball arithmetic:
the inequalities Y_i − Σ_j T_ij G_ij' Y_j G_ij ≻ 0 are re-checked in exact rationals (sympy,
leading principal minors of the 2×2 matrices, the float certificate converted exactly), and the
forward second-moment recursion with those gains, iterated here, decays geometrically.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import sympy as sp

from kfcrit.analysis.verdict import verdict_of
from kfcrit.model.system import System
from kfcrit.theory.links import markov, pairgain

CASES = [
    # (A, C, f, r): found by a search over small rational plants; the coupled single-gain LMI
    # and the candidate gains do not certify them
    ([["-9/10", "11/10"], ["1/2", "11/10"]], [["7/10", "4/5"]], "3/10", "1/2"),
    ([["1/10", "-13/10"], ["6/5", "7/5"]], [["-3/10", "1/10"]], "1/2", "7/10"),
]


def plant(A, C) -> System:
    As = sp.Matrix([[sp.Rational(v) for v in row] for row in A])
    Cs = sp.Matrix([[sp.Rational(v) for v in row] for row in C])
    return System(A=As, C=Cs, Q=sp.eye(2), R=sp.eye(1), name="pair")


def exact(M) -> sp.Matrix:
    return sp.Matrix([[sp.Rational(*Fraction(float(v)).as_integer_ratio()) for v in row]
                      for row in np.atleast_2d(M)])


@pytest.mark.parametrize(("A", "C", "f", "r"), CASES)
def test_previous_arrival_certificate_proves_what_one_gain_does_not(A, C, f, r):
    s = plant(A, C)
    fe, re_ = sp.Rational(f), sp.Rational(r)
    cert = markov.burst_certificate(s, fe, re_)
    assert cert.certified
    assert cert.gain_origin == markov.PREVIOUS_ARRIVAL_ORIGIN
    mats = cert.matrices
    K0, K1 = exact(mats["K"]), exact(mats["K1"])
    Y = [exact(mats["X0"]), exact(mats["X1"])]
    As, Cs = s.A, s.C
    T = [[1 - re_, re_], [fe, 1 - fe]]
    G = [[As, As + K0 * Cs], [As, As + K1 * Cs]]
    for i in range(2):
        D = Y[i] - sum((T[i][j] * G[i][j].T * Y[j] * G[i][j] for j in range(2)), sp.zeros(2))
        for M in (Y[i], D):
            M = (M + M.T) / 2
            assert M[0, 0] > 0 and M.det() > 0  # exact: both leading minors positive


@pytest.mark.parametrize(("A", "C", "f", "r"), CASES)
def test_forward_recursion_with_those_gains_decays(A, C, f, r):
    s = plant(A, C)
    cert = markov.burst_certificate(s, sp.Rational(f), sp.Rational(r))
    K = [np.array(cert.matrices["K"]), np.array(cert.matrices["K1"])]
    a, c = np.array(s.a), np.array(s.c)
    fv, rv = float(sp.Rational(f)), float(sp.Rational(r))
    T = np.array([[1 - rv, rv], [fv, 1 - fv]])
    X = [np.eye(2), np.eye(2)]
    norms = []
    for _ in range(3000):
        G = [[a, a + K[i] @ c] for i in range(2)]
        X = [sum(T[i, j] * G[i][j] @ X[i] @ G[i][j].T for i in range(2)) for j in range(2)]
        norms.append(float(np.trace(X[0] + X[1])))
    assert norms[-1] < 1e-6 * norms[0]


def test_single_gain_certificate_alone_fails_on_the_first_case():
    A, C, f, r = CASES[0]
    s = plant(A, C)
    fv, rv = float(sp.Rational(f)), float(sp.Rational(r))
    K_lmi, _ = markov.lmi_gain(s.a, s.c, fv, rv)
    gains = [K for _, K in markov.candidate_gains(s.a, s.c)] + ([K_lmi] if K_lmi is not None
                                                                 else [])
    outcomes = []
    for K in gains:
        rho = markov.coupled_radius(s.a, s.c, K, fv, rv)
        sol = markov.adjoint_stein(s.a, s.c, K, fv, rv) if rho < 1 else None
        outcomes.append(sol is not None and markov.certify.verify_markov_jump(
            s, sp.Rational(f), sp.Rational(r), sol[0], sol[1], K).ok)
    assert len(outcomes) >= 2 and not any(outcomes)


def test_a_bogus_certificate_is_rejected():
    A, C, f, r = CASES[0]
    s = plant(A, C)
    cert = markov.burst_certificate(s, sp.Rational(f), sp.Rational(r))
    gains = [np.array(cert.matrices["K"]), np.array(cert.matrices["K1"])]
    Y = (np.array(cert.matrices["X0"]), 1e-3 * np.eye(2))
    check = pairgain.verify_previous_arrival_gains(s, sp.Rational(f), sp.Rational(r), Y, gains)
    assert not check.ok
    assert "not proven positive definite" in check.reason


@pytest.mark.parametrize(("A", "C", "f", "r"), CASES)
def test_the_verdict_is_mean_stable(A, C, f, r):
    facts = markov.burst_facts(plant(A, C), sp.Rational(f), sp.Rational(r))
    assert verdict_of(facts.facts)[0].value == "mean-stable"


def test_the_sufficient_curve_uses_the_same_gains():
    # the operating point (f, r) = (3/10, 1/2) is certified, so the curve's r_suf(3/10) —
    # the smallest r found certifiable — may not lie above r = 1/2
    A, C, f, r = CASES[0]
    curve = markov.burst_critical_curve(plant(A, C), failure_rates=[0.3], tol=1e-3)
    assert curve.to_dict()["sufficient_recovery"][0] <= 0.5


def test_previous_arrival_gains_without_an_inverse_give_no_certificate_not_an_error():
    """π_1 = 0 (recovery rate 0) and C X C' singular at X = 0: the gain formula has no
    inverse; the route gives no gains (None), the caller no certificate — never LinAlgError."""
    import numpy as np

    from kfcrit.theory.links.burstcov import previous_arrival_gains
    from kfcrit.theory.links.markov import previous_arrival_radius

    A = np.array([[0.0, 2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    C = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    T = np.array([[1.0, 0.0], [0.05, 0.95]])
    assert previous_arrival_gains(A, C, np.eye(3), np.eye(2), T, np.array([1.0, 0.0])) is None
    assert previous_arrival_radius(A, C, np.eye(3), np.eye(2), 0.05, 0.0) is None
