"""Markov-jump bounds on lim E[tr P_t] over a Gilbert–Elliott link (theory §10).

Expected values are derived here independently: the lower bound from its renewal series over
the time since the last arrival, the upper bound by iterating the conditional means forward in
time, and both against a joint Monte Carlo of the Kalman filter and the two bounding recursions
(pathwise order, and the sample mean of tr P below the upper bound)."""
from __future__ import annotations

import numpy as np
import pytest

import kfcrit
from kfcrit.theory.links.burstcov import markov_jump_bounds

A = np.array([[1.25, 0.0], [1.0, 1.1]])
C = np.array([[1.0, 1.0]])
Q = 20.0 * np.eye(2)
R = np.array([[2.5]])
F_RATE, R_RATE = 0.1, 0.5


@pytest.fixture(scope="module")
def sinopoli() -> kfcrit.System:
    return kfcrit.System([[1.25, 0], [1, 1.1]], [[1, 1]], Q=20, R=2.5)


def _update(P: np.ndarray) -> np.ndarray:
    return P - P @ C.T @ np.linalg.inv(C @ P @ C.T + R) @ C @ P


def test_lower_bound_equals_renewal_series(sinopoli):
    # Stationary: P(received at t-1) = pi_1; P(last arrival k + 1 steps back) = pi_1 f (1-r)^(k-1).
    # After an arrival the bound is M1 = A u(Q) A' + Q; k losses later A^k M1 A'^k + sum A^i Q A'^i.
    pi1 = R_RATE / (F_RATE + R_RATE)
    M1 = A @ _update(Q) @ A.T + Q
    total = pi1 * np.trace(M1)
    Ak, acc = np.eye(2), np.zeros((2, 2))
    for k in range(1, 400):
        acc = acc + Ak @ Q @ Ak.T
        Ak = A @ Ak
        total += pi1 * F_RATE * (1 - R_RATE) ** (k - 1) * np.trace(Ak @ M1 @ Ak.T + acc)
    got = markov_jump_bounds(sinopoli, F_RATE, R_RATE)
    assert got.lower_trace == pytest.approx(total, rel=1e-9)
    assert got.lower_trace == pytest.approx(395.5039, rel=1e-5)


def test_upper_bound_is_the_limit_of_the_forward_conditional_means(sinopoli):
    got = markov_jump_bounds(sinopoli, F_RATE, R_RATE)
    K = [np.array(g).reshape(2, 1) for g in got.gains]
    # forward in time from a stationary chain and Pi_0 = I: m_j = E[Pi_t | gamma_(t-1) = j]
    T = np.array([[1 - R_RATE, R_RATE], [F_RATE, 1 - F_RATE]])
    pi = np.array([F_RATE, R_RATE]) / (F_RATE + R_RATE)
    m = [np.eye(2), np.eye(2)]
    for _ in range(3000):
        new = []
        for j in range(2):
            acc = np.zeros((2, 2))
            for i in range(2):
                w = pi[i] * T[i, j] / pi[j]          # P(gamma_(t-1) = i | gamma_t = j)
                if j == 0:
                    acc += w * (A @ m[i] @ A.T + Q)
                else:
                    F = A + K[i] @ C
                    acc += w * (F @ m[i] @ F.T + Q + K[i] @ R @ K[i].T)
            new.append(acc)
        m = new
    expected = float(pi[0] * np.trace(m[0]) + pi[1] * np.trace(m[1]))
    assert got.upper_trace == pytest.approx(expected, rel=1e-6)
    assert got.spectral_radius < 1


def test_bounds_hold_against_a_joint_monte_carlo(sinopoli):
    got = markov_jump_bounds(sinopoli, F_RATE, R_RATE)
    K = [np.array(g) for g in got.gains]
    rng = np.random.default_rng(7)
    n_paths, steps, burn = 4000, 160, 60
    c = C[0]
    P = np.tile(np.eye(2), (n_paths, 1, 1))
    Pi, Lam = P.copy(), np.zeros_like(P)
    M1 = A @ _update(Q) @ A.T + Q
    g = rng.random(n_paths) < R_RATE / (F_RATE + R_RATE)
    means = []
    worst_upper = worst_lower = -np.inf
    for t in range(steps):
        prev = g.copy()
        u = rng.random(n_paths)
        g = np.where(g, u >= F_RATE, u < R_RATE)
        PC = P @ c
        Pu = P - np.einsum("ni,nj->nij", PC, PC) / (PC @ c + R[0, 0])[:, None, None]
        Pu = 0.5 * (Pu + Pu.transpose(0, 2, 1))
        P = A @ np.where(g[:, None, None], Pu, P) @ A.T + Q
        Kp = np.where(prev[:, None], K[1], K[0])
        F = A + np.einsum("ni,j->nij", Kp, c)
        Pi = np.where(g[:, None, None], F @ Pi @ F.transpose(0, 2, 1) + Q
                      + R[0, 0] * np.einsum("ni,nj->nij", Kp, Kp), A @ Pi @ A.T + Q)
        Lam = np.where(g[:, None, None], M1 if t > 0 else Q, A @ Lam @ A.T + Q)
        scale = np.trace(P, axis1=1, axis2=2).max()
        worst_upper = max(worst_upper, np.linalg.eigvalsh(P - Pi).max() / scale)
        worst_lower = max(worst_lower, np.linalg.eigvalsh(Lam - P).max() / scale)
        if t >= burn:
            means.append(np.trace(P, axis1=1, axis2=2).mean())
    assert worst_upper < 1e-12 and worst_lower < 1e-12     # Lambda_t <= P_t <= Pi_t pathwise
    simulated = float(np.mean(means))
    assert simulated > 150                                  # far above the i.i.d. V-bar (110.8)
    assert simulated <= got.upper_trace


def test_no_bound_when_the_necessary_burst_condition_fails(sinopoli):
    # (1 - r) rho(A)^2 = 0.7 * 1.5625 = 1.09 >= 1
    got = markov_jump_bounds(sinopoli, 0.1, 0.3)
    assert got.lower_trace is None and got.upper_trace is None


def test_memoryless_chain_reduces_to_the_iid_lyapunov_bound():
    # f + r = 1: i.i.d. with p = r. Scalar a, c = 1: the last arrival was k + 1 steps back with
    # probability p (1 - p)^k, so E[Lambda] = sum_k p (1-p)^k [a^(2k) M1 + q sum_(i<k) a^(2i)]
    a, q, rr, p = 1.2, 1.0, 1.0, 0.6
    s = kfcrit.System([[a]], [[1]], Q=q, R=rr)
    uq = q - q * q / (q + rr)
    M1 = a * a * uq + q
    expected = sum(p * (1 - p) ** k * (a ** (2 * k) * M1 + q * sum(a ** (2 * i) for i in range(k)))
                   for k in range(400))
    got = markov_jump_bounds(s, 1 - p, p)
    assert got.lower_trace == pytest.approx(expected, rel=1e-9)
    assert got.lower_trace <= got.upper_trace
