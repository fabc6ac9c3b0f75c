"""The stationary mean of the filtered covariance, lim E[P_{t|t}], and its bounds (theory §3, §12).

The TCP-like cost needs lim E[P_{t|t}] of the random Riccati equation

.. math::

    P_{t|t} = P_t - \\gamma_t P_t C'(C P_t C' + R)^{-1} C P_t, \\qquad
    P_{t+1} = A P_{t|t} A' + Q ,

which has no closed form. Bounds (concavity and monotonicity of the update, Jensen):

.. math::

    (1-\\bar\\gamma)\\,\\bar S \\preceq \\lim E[P_{t|t}] \\preceq
    \\bar V - \\bar\\gamma\\, \\bar V C'(C\\bar V C' + R)^{-1} C \\bar V ,

with S̄ = (1−γ̄) A S̄ A' + Q and V̄ = g_γ̄(V̄) (:mod:`kfcrit.theory.covariance.bounds`). The value itself:

* n = 1: the law of P_t is propagated exactly from P_0 = 0 as a finite set of atoms (each step
  maps an atom x to a²x + q with weight 1−γ̄ and to a²x/(1 + s x) + q with weight γ̄,
  s = c'R^{-1}c), atoms within a relative distance ``merge`` merged at their weighted mean,
  until the mean settles (E[P_t] increases monotonically to its limit from P_0 = 0);
* n > 1: a seeded, vectorised Monte Carlo of the RRE (time averages over many paths), with
  its standard error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kfcrit.model.system import System
from kfcrit.theory.covariance.bounds import lower_covariance, upper_covariance
from kfcrit.theory.covariance.riccati import symmetrize

__all__ = ["FilterMoments", "filter_moments", "filtered", "rre_mean_monte_carlo",
           "scalar_rre_mean"]


@dataclass(frozen=True)
class FilterMoments:
    """lim E[P_t], lim E[P_{t|t}] and the bounds on lim E[P_{t|t}] at arrival probability γ̄.

    Attributes
    ----------
    gamma : float
    mean_pred, mean_filt : ndarray or None
        Estimates of lim E[P_t] and lim E[P_{t|t}] (None when not computed).
    method : str
        How the value was computed (``"atoms"`` or ``"monte-carlo"``), with its parameters.
    error : float or None
        Accuracy of ``tr(mean_filt)``: the standard error (Monte Carlo) or the last change of
        the mean (atoms).
    lower_filt, upper_filt : ndarray or None
        (1 − γ̄) S̄ and V̄ − γ̄ V̄C'(CV̄C'+R)^{-1}CV̄ (None when S̄ resp. V̄ does not exist).
    """

    gamma: float
    mean_pred: np.ndarray | None
    mean_filt: np.ndarray | None
    method: str
    error: float | None
    lower_filt: np.ndarray | None
    upper_filt: np.ndarray | None


def filtered(P: np.ndarray, C: np.ndarray, R: np.ndarray, gamma: float = 1.0) -> np.ndarray:
    """The (expected) measurement update P − γ P C'(C P C' + R)^{-1} C P (batched over axis 0).

    .. math::

        h_\\gamma(P) = P - \\gamma\\, P C' (C P C' + R)^{-1} C P
    """
    PC = P @ C.T
    S = C @ PC + R if P.ndim == 2 else np.einsum("ij,njk,lk->nil", C, P, C) + R
    if P.ndim == 2:
        return symmetrize(P - gamma * PC @ np.linalg.solve(S, PC.T))
    gain = np.linalg.solve(S, np.swapaxes(PC, 1, 2))
    return symmetrize(P - gamma * PC @ gain)


def _merge(x: np.ndarray, w: np.ndarray, rel: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge atoms whose logarithms fall in the same bin of width ``rel`` (mean preserved)."""
    key = np.round(np.log(np.maximum(x, 1e-300)) / rel).astype(np.int64)
    _, inv = np.unique(key, return_inverse=True)
    wt = np.bincount(inv, w)
    xm = np.bincount(inv, w * x) / np.where(wt > 0, wt, 1.0)
    keep = (wt > 1e-300) & np.isfinite(xm)
    return xm[keep], wt[keep]


def scalar_rre_mean(a: float, c: np.ndarray, q: float, R: np.ndarray, gamma: float,
                    merge: float = 1e-6, rtol: float = 1e-13, max_steps: int = 4000,
                    ) -> tuple[float, float, float, int]:
    """lim E[P_t] and lim E[P_{t|t}] of a scalar state (any number of outputs) by atoms.

    .. math::

        P_{t+1} = \\begin{cases} a^2 P_t + q & (1-\\bar\\gamma) \\\\
        a^2 P_t / (1 + s P_t) + q & (\\bar\\gamma) \\end{cases}, \\qquad s = c' R^{-1} c

    Returns
    -------
    (mean_pred, mean_filt, last_change, steps)
    """
    c = np.atleast_1d(np.asarray(c, dtype=float)).reshape(-1)
    s = float(c @ np.linalg.solve(np.atleast_2d(R), c))
    a2 = a * a
    x, w = np.array([0.0]), np.array([1.0])
    prev, change, steps, settled = -1.0, np.inf, 0, 0
    while steps < max_steps and settled < 3:      # three consecutive small changes
        steps += 1
        with np.errstate(over="ignore", invalid="ignore"):
            x = np.concatenate([a2 * x + q, a2 * x / (1 + s * x) + q])
        w = np.concatenate([(1 - gamma) * w, gamma * w])
        x, w = _merge(x, w, merge)
        mean = float(w @ x)
        change = abs(mean - prev)
        settled = settled + 1 if change <= rtol * mean else 0
        prev = mean
    filt = float((1 - gamma) * mean + gamma * (w @ (x / (1 + s * x))))
    return mean, filt, change, steps


def rre_mean_monte_carlo(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                         gamma: float, paths: int = 1000, steps: int = 3000, burn: int = 300,
                         seed: int = 0, weight: np.ndarray | None = None,
                         ) -> tuple[np.ndarray, np.ndarray, float]:
    """Monte Carlo of the RRE: time averages of P_t and P_{t|t} over ``paths`` paths.

    Returns
    -------
    (mean_pred, mean_filt, se)
        ``se`` is the standard error (over paths) of tr(weight · mean_filt), weight = I
        by default.
    """
    rng = np.random.default_rng(seed)
    n = A.shape[0]
    Wt = np.eye(n) if weight is None else weight
    P = np.broadcast_to(Q, (paths, n, n)).copy()
    acc_p = np.zeros((paths, n, n))
    acc_f = np.zeros((paths, n, n))
    for t in range(steps):
        arrive = rng.random(paths) < gamma
        Pf = P.copy()
        if arrive.any():
            Pf[arrive] = filtered(P[arrive], C, R)
        if t >= burn:
            acc_p += P
            acc_f += Pf
        P = symmetrize(A @ Pf @ A.T + Q)
    k = steps - burn
    per_path = acc_f / k
    traces = np.einsum("ij,nji->n", Wt, per_path)
    se = float(traces.std(ddof=1) / np.sqrt(paths))
    return acc_p.mean(axis=0) / k, per_path.mean(axis=0), se


def filter_moments(system: System, gamma: float, mc_paths: int = 1000, mc_steps: int = 3000,
                   seed: int = 0, weight: np.ndarray | None = None,
                   value: bool = True) -> FilterMoments:
    """lim E[P_{t|t}] (value and bounds) of the intermittent Kalman filter at γ̄ = ``gamma``.

    Parameters
    ----------
    system : System
        (A, C, Q, R) of the sensing side.
    gamma : float
        Arrival probability of the sensing link.
    mc_paths, mc_steps, seed : int
        Monte Carlo size for n > 1.
    weight : ndarray, optional
        The matrix whose trace against the mean matters (its standard error is reported).
    value : bool
        Compute the value (False: only the bounds).
    """
    A, C, Q, R = system.a, system.c, system.q, system.r
    S = lower_covariance(A, Q, gamma)
    lower = None if S is None else (1 - gamma) * S
    upper = None
    if gamma > 0:
        V = upper_covariance(system, gamma)["V"]
        if V is not None and np.all(np.isfinite(V)):
            upper = filtered(V, C, R, gamma)
    if not value or S is None:
        return FilterMoments(gamma, None, None, "not computed" if not value else
                             "none: (1 − γ̄) ρ(A)² ≥ 1, lim E[P_t] is infinite", None,
                             lower, upper)
    if system.n == 1:
        mp, mf, change, steps = scalar_rre_mean(float(A[0, 0]), C[:, 0], float(Q[0, 0]), R,
                                                gamma)
        return FilterMoments(gamma, np.array([[mp]]), np.array([[mf]]),
                             f"atoms (law of P_t propagated from 0 for {steps} steps, "
                             "relative merge width 1e-6)", change, lower, upper)
    mp, mf, se = rre_mean_monte_carlo(A, C, Q, R, gamma, paths=mc_paths, steps=mc_steps,
                                      seed=seed, weight=weight)
    return FilterMoments(gamma, mp, mf, f"monte-carlo ({mc_paths} paths × {mc_steps} steps, "
                         f"seed {seed})", se, lower, upper)
