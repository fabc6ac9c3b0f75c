"""Closed loops over lossy links (MATH §12): thresholds, costs and fixed designs.

Known answers are derived by hand in the comments; Hypothesis example counts are small (each
ν_c computation runs the certified p_up machinery).
"""
from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from kfcrit.theory.loop.curve import loop_critical_curve
from kfcrit.theory.loop.fixed import fixed_loop, mean_square_stability
from kfcrit.theory.loop.links import LossLink
from kfcrit.theory.loop.stack import fixed_design
from kfcrit.theory.loop.tcp import tcp_loop
from kfcrit.theory.loop.thresholds import actuation_threshold, sensing_threshold


def test_scalar_thresholds_are_9_over_25() -> None:
    # a = 5/4: ν_c = γ_c = 1 − 1/a² = 1 − 16/25 = 9/25
    nu_c = actuation_threshold([[F(5, 4)]], [[1]])
    gamma_c = sensing_threshold([[F(5, 4)]], [[1]])
    for th in (nu_c, gamma_c):
        assert th.exact and th.expression == "9/25" and th.certified
        assert th.interval[0] <= 0.36 <= th.interval[1]


def test_square_invertible_b_gives_p_low() -> None:
    # A = [[1, −1], [1, 1]] has eigenvalues 1 ± i, ρ² = 2: ν_c = 1 − 1/2; B = I (and any
    # invertible B) gives the dual of "C invertible"
    for B in ([[1, 0], [0, 1]], [[2, 1], [1, 1]]):
        th = actuation_threshold([[1, -1], [1, 1]], B)
        assert th.basis == "theorem" and sp.sympify(th.expression) == sp.Rational(1, 2)
    # upper-triangular A with ρ = 5/4: 9/25
    th = actuation_threshold([[F(5, 4), 1], [0, F(11, 10)]], [[1, 0], [0, 1]])
    assert sp.sympify(th.expression) == sp.Rational(9, 25)


def test_single_input_rotation_is_1_minus_r_to_the_minus_4() -> None:
    # A = r·rotation(θ), cos θ = 3/5 (θ/π irrational by Niven), r = 6/5, B = e1:
    # Π|λ_u|² = r⁴ so ν_c = 1 − (5/6)⁴ = 671/1296, while p_low = 1 − 1/r² = 11/36 is smaller
    r = F(6, 5)
    A = [[r * F(3, 5), -r * F(4, 5)], [r * F(4, 5), r * F(3, 5)]]
    th = actuation_threshold(A, [[1], [0]], tol=1e-8)
    assert sp.sympify(th.expression) == sp.Rational(671, 1296)
    assert th.certified and th.interval[0] - 1e-8 <= 671 / 1296 <= th.interval[1] + 1e-8
    assert th.interval[0] > 11 / 36 + 0.1


def test_perfect_state_feedback_bounded_iff_lost_fraction_times_a2_below_one() -> None:
    # C = 1, K = 1, R = 0, γ̄ = 1: x̂_{t|t} = x_t; u = −(a/b)x; x' = (1 − ν)a x + w, so
    # E[x²]' = (1 − ν̄)a² E[x²] + q: bounded iff (1 − ν̄)a² < 1, i.e. ν̄ > 9/25 for a = 5/4
    d = fixed_design(1.25, 1, 1, 1, 0, 1, 1, K=1, L=-1.25)
    assert mean_square_stability(d, 1, F(9, 25)).status == "fails (certified)"   # ρ = 1
    assert mean_square_stability(d, 1, F(9, 25) - F(1, 10**6)).holds is False
    assert mean_square_stability(d, 1, F(9, 25) + F(1, 10**6)).holds is True
    # cost at ν̄ = 1/2: E x² = 1/(1 − a²/2) = 32/7, J = E x² (1 + ν̄ a²) = (32/7)(57/32) = 57/7
    assert math.isclose(fixed_loop(d, 1, F(1, 2)).cost.value, 57 / 7, rel_tol=1e-12)


@settings(max_examples=8, deadline=None)
@given(st.fractions(F(-3), F(3)).filter(lambda a: a != 0),
       st.fractions(F(0), F(1)))
def test_perfect_state_feedback_rule_random(a: F, nu: F) -> None:
    a = F(round(float(a), 3)).limit_denominator(1000)
    d = fixed_design(float(a), 1, 1, 1, 0, 1, 1, K=1, L=-float(a))
    expect = (1 - nu) * F(float(a)) ** 2 < 1
    assert mean_square_stability(d, 1, nu).holds is expect


def test_gilbert_elliott_actuation_burst_rule() -> None:
    # Markov modes lost/received with Φ = a / 0: Z_lost' = (1 − r)a² Z_lost, so the MJLS is
    # mean-square stable iff (1 − r)a² < 1 (MATH §7's burst rule), whatever f is
    d = fixed_design(1.25, 1, 1, 1, 0, 1, 1, K=1, L=-1.25)
    for f in (F(1, 10), F(1, 2)):
        assert mean_square_stability(d, 1, LossLink(f, F(2, 5))).holds is True     # 0.9375
        assert mean_square_stability(d, 1, LossLink(f, F(3, 10))).holds is False   # 1.09375


def test_scalar_tcp_cost() -> None:
    # S solves 11S² − 25S − 16 = 0 (control MARE at ν̄ = 4/5), and ν̄L²(S + 1) = ν̄a²S²/(S + 1);
    # lim E[P_{t|t}] from an independent depth-20 tree over arrival histories (P_0 = 0)
    S = (25 + math.sqrt(1329)) / 22
    P, w = np.array([0.0]), np.array([1.0])
    for _ in range(20):
        P = np.concatenate([1.5625 * P + 1, 1.5625 * P / (P + 1) + 1])
        w = np.concatenate([0.2 * w, 0.8 * w])
    Ptt = 0.2 * (w @ P) + 0.8 * (w @ (P / (P + 1)))
    J_hand = S + 0.8 * 1.5625 * S * S / (S + 1) * Ptt
    res = tcp_loop([[F(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.8, 0.8)
    assert math.isclose(res.S[0, 0], S, rel_tol=1e-10)
    assert math.isclose(res.cost.value, J_hand, rel_tol=2e-4)
    assert abs(res.cost.value - 5.6605) < 5e-3          # MATH §12 quotes 5.6605
    assert res.cost.finite is True and res.cost.lower <= res.cost.value <= res.cost.upper
    # below the thresholds the cost is infinite
    assert tcp_loop([[F(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.3, 0.8).cost.finite is False
    assert tcp_loop([[F(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.8, 0.3).cost.value == math.inf


def _control_iteration_bounded(A: np.ndarray, B: np.ndarray, nu: float, steps: int = 4000
                               ) -> bool:
    """S_{k+1} = A'S A + I − ν A'SB(B'SB + I)^{-1}B'SA from 0, written in control form."""
    S = np.zeros_like(A)
    for _ in range(steps):
        M = B.T @ S @ B + np.eye(B.shape[1])
        S = A.T @ S @ A + np.eye(A.shape[0]) - nu * A.T @ S @ B @ np.linalg.solve(M, B.T @ S @ A)
        if not np.isfinite(S).all() or np.abs(S).max() > 1e12:
            return False
    return True


entries = st.sampled_from([F(k, 4) for k in range(-6, 7)])


@settings(max_examples=5, deadline=None)
@given(st.lists(entries, min_size=4, max_size=4), st.lists(entries, min_size=2, max_size=2))
def test_nu_c_is_p_up_of_the_dual_and_above_p_low(a: list, b: list) -> None:
    A = [[a[0] + F(5, 4), a[1]], [a[2], a[3]]]
    B = [[b[0]], [b[1] + 1]]
    An, Bn = np.array(A, dtype=float), np.array(B, dtype=float)
    ctrb = np.linalg.matrix_rank(np.hstack([Bn, An @ Bn]))
    th = actuation_threshold(A, B, tol=1e-6)
    if ctrb < 2:
        return
    rho = max(abs(np.linalg.eigvals(An)))
    p_low = max(0.0, 1 - 1 / rho**2) if rho > 1 else 0.0
    assert th.interval[1] >= p_low - 1e-12 and th.interval[0] >= p_low - 1e-9
    lo, hi = th.interval
    if hi + 0.02 < 1:
        assert _control_iteration_bounded(An, Bn, hi + 0.02)
    if lo - 0.02 > 0:
        assert not _control_iteration_bounded(An, Bn, lo - 0.02)


@settings(max_examples=6, deadline=None)
@given(st.fractions(F(11, 10), F(3)), st.fractions(F(-1, 2), F(1, 2)))
def test_state_feedback_stable_region_is_an_up_set(a: F, ratio: F) -> None:
    # scalar state feedback, a + b·l = ratio·a with |ratio| < 1: the second-moment factor is
    # (1 − ν̄)a² + ν̄ (ratio·a)², affine and decreasing in ν̄: the stable set is {ν̄ > ν*}
    a_f = float(a)
    d = fixed_design(a_f, 1, 1, 1, 0, 1, 1, K=1, L=(float(ratio) - 1) * a_f)
    grid = [F(k, 20) for k in range(21)]
    holds = [mean_square_stability(d, 1, v).holds for v in grid]
    first = holds.index(True) if True in holds else len(holds)
    assert all(h is False for h in holds[:first]) and all(h is True for h in holds[first:])


def test_critical_curve_of_state_feedback() -> None:
    d = fixed_design(1.25, 1, 1, 1, 0, 1, 1, K=1, L=-1.25)
    curve = loop_critical_curve(d, [1.0], tol=1e-6, certify_ends=True)
    assert curve.monotone_at_grid == [True]
    assert abs(curve.nu_star[0] - 0.36) < 1e-6 and curve.certified == [True]


def test_fixed_design_defaults_and_exact_vs_float_radius() -> None:
    d = fixed_design([[1.25, 1], [0, 1.1]], [[0], [1]], [[1, 0]], 1, 1, 1, 1)
    for acked in (True, False):
        for on_loss in ("zero", "hold"):
            dd = fixed_design(d.A, d.B, d.C, 1, 1, 1, 1, acked=acked, on_loss=on_loss)
            for g, v in ((0.95, 0.95), (0.5, 0.5)):
                fact = mean_square_stability(dd, g, v)
                assert fact.holds is not None
                assert fact.holds == (fact.rho < 1) or abs(fact.rho - 1) < 1e-9
