r"""Bounds on lim E[P_t] over a Gilbert–Elliott link (theory §10): numbers, never verdicts.

The i.i.d. bounds S̄ ⪯ lim E[P_t] ⪯ V̄ (Sinopoli Thm 4, 6) at the stationary arrival probability
do not bound E[P_t] when losses come in bursts. This module gives bounds valid for the chain
γ_t ∈ {0 (lost), 1 (received)} with T = [[1 − r, r], [f, 1 − f]] and stationary law
π = (f, r)/(f + r). P_t is the one-step prediction covariance (``P_{t+1} = A P_t^+ A' + Q``).

**Upper bound (fixed gains).** The Kalman filter is no worse than a filter that, on a
reception at time t, uses the gain K_i chosen by the previous arrival γ_{t−1} = i (predictor
form, F = A + K_i C). Its covariance Π_t ⪰ P_t pathwise (the Riccati map is monotone and below
every fixed-gain map), and with X_j = E[Π_t 1{γ_{t−1} = j}] the Markov property gives the
positive affine recursion

.. math::

    X_0 \leftarrow \sum_i T_{i0}\,(A X_i A' + \pi_i Q), \qquad
    X_1 \leftarrow \sum_i T_{i1}\,\big((A + K_i C) X_i (A + K_i C)' + \pi_i (Q + K_i R K_i')\big).

(The constants carry π_i: E[1{γ_{t−1} = i, γ_t = j}] = π_i T_ij in stationarity.) When its
linear part has spectral radius < 1, lim sup E[P_t] ⪯ X_0* + X_1* (fixed point). The gains are
chosen by the coupled Riccati iteration K_i = −A X_i C'(C X_i C' + π_i R)⁻¹ from X = 0; the
bound is then the fixed point of the affine recursion for those fixed gains (solved linearly,
checked as a float supersolution).

**Lower bound (losses only).** For t ≥ 1, P_t ⪰ Q; a reception gives P_{t+1} ⪰
M_1 = A·u(Q)·A' + Q with u(X) = X − XC'(CXC' + R)⁻¹CX (monotone), a loss P_{t+1} = A P_t A' + Q.
So with Z_j = E[Λ_t 1{γ_{t−1} = j}] of this pathwise lower recursion,

.. math::

    Z_1 = \pi_1 M_1, \qquad Z_0 = (1 - r) A Z_0 A' + f A Z_1 A' + \pi_0 Q,

finite iff (1 − r)ρ(A)² < 1, and lim inf E[P_t] ⪰ Z_0 + Z_1.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.io.typed import to_json
from kfcrit.model.system import System
from kfcrit.records.covariance import MarkovJumpLower, MarkovJumpRecord, MarkovJumpUpper
from kfcrit.theory.covariance.riccati import congruence_matrix, symmetrize, unvech, vech

RICCATI_MAX_ITERATIONS = 20000
"""Iterations of the coupled Riccati recursion that chooses the gains."""
RICCATI_TOLERANCE = 1e-12
"""Relative change of tr(X_0 + X_1) at which the gain iteration stops."""
SUPERSOLUTION_SCALE = 1.0 + 1e-8
"""The upper bound is s·X* with this s, checked to satisfy M(sX) + c ⪯ sX in floats."""
LINEAR_MAX_STATES = 40
"""Largest n for the linear (vech) solve of the fixed point; above it the fixed point is the
limit of the iteration."""


@dataclass(frozen=True)
class MarkovJumpBounds:
    """tr Z ≤ lim E[tr P_t] ≤ tr X over a Gilbert–Elliott link (module docstring).

    ``upper_trace`` / ``lower_trace`` are None when the bound does not exist (spectral radius
    ≥ 1, or (1 − r)ρ(A)² ≥ 1), with the reason in ``upper_reason`` / ``lower_reason``.
    """

    failure_rate: float
    recovery_rate: float
    lower_trace: float | None
    upper_trace: float | None
    lower_reason: str
    upper_reason: str
    spectral_radius: float | None
    gains: tuple[tuple[float, ...], ...] | None
    lower_exists: bool | None = None
    """Whether the lower bound exists when that is decided beyond its float trace (exactly:
    (1 − r)ρ(A)² < 1 with a float that rounds onto 1); None: it exists iff it has a trace."""

    def record(self) -> MarkovJumpRecord:
        """The bounds as their record class (``covariance_bounds.markov_jump``)."""
        return MarkovJumpRecord(
            failure_rate=self.failure_rate, recovery_rate=self.recovery_rate,
            lower=MarkovJumpLower(
                trace=self.lower_trace,
                exists=(self.lower_trace is not None if self.lower_exists is None
                        else bool(self.lower_exists)),
                basis=self.lower_reason),
            upper=MarkovJumpUpper(
                trace=self.upper_trace, exists=self.upper_trace is not None,
                basis=self.upper_reason, spectral_radius=self.spectral_radius,
                gains=None if self.gains is None else [list(g) for g in self.gains]),
            method="Markov-jump bounds for the Gilbert-Elliott chain (theory §10): "
                   "upper = fixed point of the fixed-gain second-moment recursion, "
                   "lower = losses-only recursion with the reception floor A u(Q) A' + Q")

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data (``covariance_bounds.markov_jump`` of the record)."""
        return to_json(self.record())


def _stationary(f: float, r: float) -> np.ndarray:
    return np.array([f, r]) / (f + r)


def _update(P: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    S = C @ P @ C.T + R
    return symmetrize(P - P @ C.T @ np.linalg.solve(S, C @ P))


def burst_lower_covariance(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                           f: float, r: float) -> np.ndarray | None:
    """Z_0 + Z_1 of the losses-only recursion (module docstring), or None when
    (1 − r)ρ(A)² ≥ 1 (the series diverges)."""
    rho = float(max(abs(np.linalg.eigvals(A)))) if A.size else 0.0
    if (1.0 - r) * rho * rho >= 1.0:
        return None
    pi = _stationary(f, r)
    M1 = A @ _update(Q, C, R) @ A.T + Q
    Z1 = pi[1] * M1
    rhs = symmetrize(f * A @ Z1 @ A.T + pi[0] * Q)
    Z0 = sla.solve_discrete_lyapunov(np.sqrt(1.0 - r) * A, rhs)
    return symmetrize(Z0 + Z1)


def _affine(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, T: np.ndarray,
            pi: np.ndarray, K: list[np.ndarray], X: list[np.ndarray]) -> list[np.ndarray]:
    F = [A + K[0] @ C, A + K[1] @ C]
    X0 = sum(T[i, 0] * (A @ X[i] @ A.T + pi[i] * Q) for i in range(2))
    X1 = sum(T[i, 1] * (F[i] @ X[i] @ F[i].T + pi[i] * (Q + K[i] @ R @ K[i].T))
             for i in range(2))
    return [symmetrize(X0), symmetrize(X1)]


def previous_arrival_gains(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                           T: np.ndarray, pi: np.ndarray,
                           max_iterations: int = RICCATI_MAX_ITERATIONS
                           ) -> list[np.ndarray] | None:
    """Gains (K_0, K_1) chosen by the previous arrival, from the coupled Riccati iteration
    (None when it diverges or an inverse below does not exist).

    .. math:: K_i = -A X_i C'(C X_i C' + \\pi_i R)^{-1}

    with (X_0, X_1) iterated by the fixed-gain recursion of the module docstring.
    """
    n, m = A.shape[0], C.shape[0]
    X = [np.zeros((n, n)), np.zeros((n, n))]
    K = [np.zeros((n, m)), np.zeros((n, m))]
    last = 0.0
    with np.errstate(all="ignore"):
        for _ in range(max_iterations):
            try:
                K = [-A @ X[i] @ C.T @ np.linalg.inv(C @ X[i] @ C.T + pi[i] * R)
                     for i in range(2)]
            except np.linalg.LinAlgError:
                # C X_i C' + π_i R singular (π_i = 0 with C X_i C' singular): no gain of this
                # form, so no certificate by this route
                return None
            X = _affine(A, C, Q, R, T, pi, K, X)
            tr = float(np.trace(X[0] + X[1]))
            if not np.isfinite(tr) or tr > 1e200:
                return None
            if abs(tr - last) <= RICCATI_TOLERANCE * max(tr, 1.0):
                break
            last = tr
    return K if all(np.all(np.isfinite(k)) for k in K) else None


def _fixed_gain_operator(A: np.ndarray, C: np.ndarray, T: np.ndarray,
                         K: list[np.ndarray]) -> np.ndarray:
    F = [A + K[0] @ C, A + K[1] @ C]
    L0 = [congruence_matrix(A), congruence_matrix(A)]
    L1 = [congruence_matrix(F[0]), congruence_matrix(F[1])]
    return np.block([[T[0, 0] * L0[0], T[1, 0] * L0[1]], [T[0, 1] * L1[0], T[1, 1] * L1[1]]])


def burst_upper_covariance(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                           f: float, r: float, gains: list[np.ndarray] | None = None
                           ) -> tuple[np.ndarray | None, float | None, list[np.ndarray] | None,
                                      str]:
    """(X_0* + X_1* scaled to a checked supersolution, spectral radius, gains, reason) of the
    fixed-gain recursion (module docstring); the matrix is None when no bound was found.

    ``gains`` (K_0, K_1) overrides the coupled Riccati choice (e.g. one certificate gain for
    both)."""
    n = A.shape[0]
    T = np.array([[1.0 - r, r], [f, 1.0 - f]])
    pi = _stationary(f, r)
    K = gains if gains is not None else previous_arrival_gains(A, C, Q, R, T, pi)
    if K is None:
        return None, None, None, ("the coupled Riccati recursion that chooses the gains "
                                  "diverges: no fixed-gain bound exists")
    if n > LINEAR_MAX_STATES:
        return None, None, K, f"not attempted for n = {n} > {LINEAR_MAX_STATES} states"
    M = _fixed_gain_operator(A, C, T, K)
    rho = float(max(abs(np.linalg.eigvals(M))))
    if not rho < 1.0:
        return None, rho, K, (f"the fixed-gain second-moment recursion has spectral radius "
                              f"{rho:.6g} >= 1: no bound from these gains")
    N = n * (n + 1) // 2
    c0 = sum(T[i, 0] * pi[i] * Q for i in range(2))
    c1 = sum(T[i, 1] * pi[i] * (Q + K[i] @ R @ K[i].T) for i in range(2))
    rhs = np.concatenate([vech(symmetrize(c0)), vech(symmetrize(c1))])
    try:
        x = sla.solve(np.eye(2 * N) - M, rhs)
    except (np.linalg.LinAlgError, ValueError):
        return None, rho, K, "the fixed-point system is singular in floats"
    X = [SUPERSOLUTION_SCALE * unvech(x[:N], n), SUPERSOLUTION_SCALE * unvech(x[N:], n)]
    image = _affine(A, C, Q, R, T, pi, K, X)
    gap = max(float(np.linalg.eigvalsh(image[j] - X[j]).max()) for j in range(2))
    if gap > 0.0:
        return None, rho, K, (f"the scaled fixed point is not a float supersolution (excess "
                              f"{gap:.3g}): not used as a bound")
    return symmetrize(X[0] + X[1]), rho, K, (
        f"fixed point of the fixed-gain second-moment recursion (gains chosen by the previous "
        f"arrival, spectral radius {rho:.6g} < 1), scaled by {SUPERSOLUTION_SCALE} and checked "
        "as a supersolution: lim sup E[P_t] is below it (theory §10)")


def markov_jump_bounds(system: System, failure_rate: float, recovery_rate: float,
                       gains: list[np.ndarray] | None = None, *,
                       necessary_holds: bool | None = None) -> MarkovJumpBounds:
    """Lower and upper bounds on lim E[tr P_t] over a Gilbert–Elliott link (theory §10).

    Parameters
    ----------
    system : System
        The plant (A, C, Q, R); the float view is used.
    failure_rate, recovery_rate : float
        f = P(lost next | received now), r = P(received next | lost now), in (0, 1].
    gains : list of ndarray, optional
        Fixed gains (K_0, K_1) for the upper bound (predictor form, F = A + K C); by default
        the coupled Riccati choice.
    necessary_holds : bool, optional
        (1 − r)ρ(A)² < 1 decided exactly by the caller
        (:func:`kfcrit.theory.links.markov.burst_necessary`): when it holds but the float
        recursion finds no bounded lower bound, the bound exists beyond float64.

    Returns
    -------
    MarkovJumpBounds
        The traces of the bounds, or None with the reason when a bound does not exist.
    """
    f, r = float(failure_rate), float(recovery_rate)
    A, C, Q, R = system.a, system.c, system.q, system.r
    low = burst_lower_covariance(A, C, Q, R, f, r)
    lower_reason = ("losses-only recursion: (1 - r) rho(A)^2 >= 1, the series diverges"
                    if low is None else
                    "losses-only recursion Z_1 = pi_1 (A u(Q) A' + Q), Z_0 = (1 - r) A Z_0 A' + "
                    "f A Z_1 A' + pi_0 Q: lim inf E[P_t] is above Z_0 + Z_1 (theory §10)")
    lower_exists = None
    if low is None and necessary_holds:
        lower_exists = True
        lower_reason = ("(1 - r) rho(A)^2 < 1 exactly: the losses-only lower bound exists, but "
                        "(1 - r) rho(A)^2 rounds to 1 in float64 and its series is beyond float64")
    up, rho, K, upper_reason = burst_upper_covariance(A, C, Q, R, f, r, gains)
    return MarkovJumpBounds(
        f, r, None if low is None else float(np.trace(low)),
        None if up is None else float(np.trace(up)), lower_reason, upper_reason, rho,
        None if K is None else tuple(tuple(float(v) for v in k.ravel()) for k in K),
        lower_exists)
