"""Mean stability over a Gilbert–Elliott link from gains chosen by the previous arrival
(docs/theory.md §10, "Gains chosen by the previous arrival").

The single-gain certificate of :mod:`kfcrit.theory.links.markov` uses one gain K on every
reception. A filter may instead use K_i when the previous packet's fate was i (0 lost,
1 received): that is still a causal linear estimator, so the Kalman filter's E[P_t] is below
its error covariance. With X_j = E[e_t e_t' 1{γ_{t−1} = j}] the error's second moment follows

.. math::

    X_j \\leftarrow \\sum_i T_{ij}\\, G_{ij} X_i G_{ij}' + \\text{const},\\qquad
    G_{i0} = A,\\; G_{i1} = A + K_i C,\\qquad T = \\begin{bmatrix}1-r & r\\\\ f & 1-f\\end{bmatrix},

a positive linear map M. Its spectral radius is below 1 iff the adjoint inequalities

.. math::

    Y_i \\succ 0,\\qquad Y_i - \\sum_j T_{ij}\\, G_{ij}' Y_j G_{ij} \\succ 0 \\quad (i = 0, 1)

have a solution; :func:`verify_previous_arrival_gains` proves them in ball arithmetic on the
exact A, C, f, r with the float K_i, Y_i taken exactly.
"""
from __future__ import annotations

from typing import Any

import flint
import numpy as np
import scipy.linalg as sla

from kfcrit.model.system import System
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.upper import certify

KIND = ("previous-arrival gains: Y_i > 0, Y_i - sum_j T_ij G_ij' Y_j G_ij > 0, G_i0 = A, "
        "G_i1 = A + K_i C, T = [[1-r, r], [f, 1-f]]")
"""The inequalities :func:`verify_previous_arrival_gains` proves (the record's ``kind``)."""


def transition_maps(A: np.ndarray, C: np.ndarray, gains: list[np.ndarray]
                    ) -> list[list[np.ndarray]]:
    """G[i][j]: the error's transition when the previous arrival was i and this one is j.

    .. math:: G_{i0} = A,\\qquad G_{i1} = A + K_i C
    """
    return [[A, A + gains[i] @ C] for i in range(2)]


def adjoint_solution(A: np.ndarray, C: np.ndarray, gains: list[np.ndarray], f: float,
                     r: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(Y_0, Y_1) solving Y_i − Σ_j T_ij G_ij' Y_j G_ij = I, or None when the float solution
    is not positive definite (then no certificate comes from these gains).

    .. math:: Y_i - \\sum_j T_{ij}\\, G_{ij}' Y_j G_{ij} = I
    """
    n = A.shape[0]
    T = np.array([[1.0 - r, r], [f, 1.0 - f]])
    G = transition_maps(A, C, gains)
    N = n * n
    # vec(G' Y G) = (G' ⊗ G') vec(Y) (column-major vec)
    big = np.eye(2 * N)
    for i in range(2):
        for j in range(2):
            big[i * N:(i + 1) * N, j * N:(j + 1) * N] -= T[i, j] * np.kron(G[i][j].T, G[i][j].T)
    rhs = np.concatenate([np.eye(n).reshape(-1, order="F")] * 2)
    try:
        y = sla.solve(big, rhs)
    except (np.linalg.LinAlgError, ValueError):
        return None
    Y = [symmetrize(y[k * N:(k + 1) * N].reshape((n, n), order="F")) for k in range(2)]
    if not all(np.all(np.isfinite(M)) for M in Y):
        return None
    if min(float(np.linalg.eigvalsh(M).min()) for M in Y) <= 0:
        return None
    return Y[0], Y[1]


def verify_previous_arrival_gains(system: System, failure_rate: Any, recovery_rate: Any,
                                  Y: tuple[np.ndarray, np.ndarray],
                                  gains: list[np.ndarray]) -> certify.CheckResult:
    """Prove mean-square stability of the previous-arrival-gain error system, in balls.

    .. math::

        Y_i \\succ 0,\\qquad Y_i - \\sum_j T_{ij}\\, G_{ij}' Y_j G_{ij} \\succ 0 \\quad (i = 0, 1)

    Parameters
    ----------
    system : System
        The plant; its exact A and C enter the check.
    failure_rate, recovery_rate : sympy number
        The chain's exact f and r.
    Y : tuple of ndarray
        The candidate (Y_0, Y_1), taken exactly.
    gains : list of ndarray
        K_0 (after a loss) and K_1 (after a reception), taken exactly.

    Returns
    -------
    CheckResult
        ``ok`` True only when every inequality is proven; ``margin`` the least proven
        eigenvalue of the equilibrated differences.

    References
    ----------
    docs/theory.md §10.
    """
    old = flint.ctx.prec
    flint.ctx.prec = certify.PRECISION_BITS
    try:
        return _verify(system, failure_rate, recovery_rate, Y, gains)
    finally:
        flint.ctx.prec = old


def _verify(system: System, failure_rate: Any, recovery_rate: Any,
            Y: tuple[np.ndarray, np.ndarray], gains: list[np.ndarray]) -> certify.CheckResult:
    n, m = system.n, system.m
    f_num, r_num = float(failure_rate), float(recovery_rate)
    p_stat = r_num / (f_num + r_num) if f_num + r_num > 0 else 0.0
    try:
        A = certify.arb_from_sympy(system.A)
        C = certify.arb_from_sympy(system.C)
        f = certify.arb_exact_number(failure_rate)
        r = certify.arb_exact_number(recovery_rate)
        Ya = [certify.arb_from_float(np.asarray(M, dtype=float)) for M in Y]
        Ka = [certify.arb_from_float(np.asarray(K, dtype=float).reshape(n, m)) for K in gains]
    except (ValueError, TypeError) as exc:
        return certify.CheckResult(False, KIND, p_stat, None, None, f"bad certificate: {exc}")
    if any(M.nrows() != n or M.ncols() != n for M in Ya):
        return certify.CheckResult(False, KIND, p_stat, None, None, "bad shape")
    one, half = flint.arb(1), flint.arb(0.5)
    Ys = [(M + M.transpose()) * half for M in Ya]
    margins_y = [certify.definite_margin(M) for M in Ys]
    if any(v is None for v in margins_y):
        return certify.CheckResult(False, KIND, p_stat, None, None,
                                   "Y_0 or Y_1 is not proven positive definite")
    T = [[one - r, r], [f, one - f]]
    G = [[A, A + Ka[i] * C] for i in range(2)]
    margins = []
    for i in range(2):
        D = Ys[i]
        for j in range(2):
            D = D - T[i][j] * (G[i][j].transpose() * Ys[j] * G[i][j])
        mm = certify.definite_margin(D)
        if mm is None:
            return certify.CheckResult(False, KIND, p_stat, min(margins_y), None,
                                       f"Y_{i} - sum_j T_{i}j G_{i}j' Y_j G_{i}j is not proven "
                                       "positive definite")
        margins.append(mm)
    return certify.CheckResult(True, KIND, p_stat, min(margins_y), min(margins), "proven")
