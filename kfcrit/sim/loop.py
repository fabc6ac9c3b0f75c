"""Closed-loop Monte Carlo over lossy sensing and actuation links (theory §12).

Seeded and vectorised: all paths advance together (numpy arrays of shape (paths, …)). Two
loops:

* :func:`simulate_tcp` — the TCP-like optimal loop: the time-varying Kalman filter with the
  known applied input (acknowledgements) and u_t = L x̂_{t|t}, L from the control MARE;
* :func:`simulate_fixed` — a fixed design (:class:`kfcrit.theory.loop.stack.FixedDesign`),
  written in plant/estimator form (independently of the jump-linear stacking used by the
  theory), zero or hold, acknowledged or not.

Both return a :class:`LoopSimulation`: the empirical average cost

.. math::

    \\hat J = \\frac{1}{P}\\sum_{p=1}^{P} \\frac{1}{T - T_0} \\sum_{t=T_0}^{T-1}
    \\bigl(x_t' W x_t + a_t' U a_t\\bigr)_p

with a normal confidence interval over the independent paths, and a second-moment growth
indicator: the per-step slope of log mean_p ‖z_t‖² between the third and the last quarter of the
run (≈ 0 for a mean-square stable loop with noise, ≈ log ρ for an unstable one).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.theory.loop.fixed import as_link
from kfcrit.theory.loop.stack import FixedDesign
from kfcrit.theory.loop.tcp import control_gain, control_mare

__all__ = ["LoopSimulation", "growth_rate", "simulate_fixed", "simulate_tcp"]

Z95 = 1.959963984540054


@dataclass(frozen=True)
class LoopSimulation:
    """Empirical facts of a closed-loop Monte Carlo.

    Attributes
    ----------
    cost : float
        Mean over paths of the per-path time-average stage cost after ``burn_in``.
    ci : tuple of float
        Normal confidence interval (``confidence``) of the cost over independent paths.
    std_error : float
    confidence : float
    growth_rate : float
        Per-step slope of log mean ‖z_t‖² between the third and last quarter of the run.
    second_moment : ndarray
        mean_p ‖z_t‖² for every step t (length ``steps``).
    finite : bool
        Every simulated value stayed finite.
    paths, steps, burn_in, seed : int
    loop : str
        Which loop was simulated.
    """

    cost: float
    ci: tuple[float, float]
    std_error: float
    confidence: float
    growth_rate: float
    second_moment: np.ndarray
    finite: bool
    paths: int
    steps: int
    burn_in: int
    seed: int
    loop: str


def growth_rate(m: np.ndarray) -> float:
    """Slope of log m_t per step between the windows [T/2, 3T/4) and [3T/4, T).

    .. math::

        \\hat r = \\frac{\\log \\overline{m}_{[3T/4, T)} - \\log \\overline{m}_{[T/2, 3T/4)}}{T/4}
    """
    T = len(m)
    q = max(T // 4, 1)
    with np.errstate(all="ignore"):
        a, b = float(np.mean(m[T - 2 * q:T - q])), float(np.mean(m[T - q:]))
        return float((np.log(b) - np.log(a)) / q)


def _arrays(*Ms: Any) -> list[np.ndarray]:
    return [np.atleast_2d(np.asarray(M, dtype=float)) for M in Ms]


def _summary(costs: np.ndarray, m: np.ndarray, burn: int, paths: int, steps: int, seed: int,
             loop: str, confidence: float) -> LoopSimulation:
    from statistics import NormalDist

    z = NormalDist().inv_cdf(0.5 + confidence / 2) if confidence != 0.95 else Z95
    per_path = costs / max(steps - burn, 1)
    finite = bool(np.all(np.isfinite(per_path)) and np.all(np.isfinite(m)))
    mean = float(np.mean(per_path))
    se = float(np.std(per_path, ddof=1) / np.sqrt(paths)) if paths > 1 else float("nan")
    return LoopSimulation(mean, (mean - z * se, mean + z * se), se, confidence,
                          growth_rate(m), m, finite, paths, steps, burn, seed, loop)


def simulate_tcp(A: Any, B: Any, C: Any, W: Any, U: Any, Q: Any, R: Any, sensing: Any,
                 actuation: Any, paths: int = 2000, steps: int = 2000, burn_in: int = 200,
                 seed: int = 0, L: np.ndarray | None = None,
                 confidence: float = 0.95) -> LoopSimulation:
    """Monte Carlo of the TCP-like optimal loop (time-varying Kalman filter, u = L x̂_{t|t}).

    .. math::

        x_{t+1} = A x_t + \\nu_t B u_t + w_t, \\quad
        \\hat x_{t+1|t} = A \\hat x_{t|t} + \\nu_t B u_t, \\quad
        P_{t+1} = A P_{t|t} A' + Q

    Parameters
    ----------
    A, B, C, W, U, Q, R : array_like
        Plant, weights and noises (Q, W, U, R as matrices of the right size).
    sensing, actuation : LossLink or float
        The links (floats: i.i.d. arrival probabilities γ̄, ν̄).
    paths, steps, burn_in, seed : int
    L : ndarray, optional
        Controller gain (default: from the control MARE at the actuation arrival probability).
    confidence : float

    Returns
    -------
    LoopSimulation
    """
    A, B, C, W, U, Q, R = _arrays(A, B, C, W, U, Q, R)
    n, mu = A.shape[0], B.shape[1]
    s_link, a_link = as_link(sensing), as_link(actuation)
    if L is None:
        S = control_mare(A, B, W, U, float(a_link.arrival()))
        if S is None:
            raise ValueError("the control MARE has no fixed point at this ν̄ (ν̄ ≤ ν_c)")
        L = control_gain(A, B, U, S)
    rng = np.random.default_rng(seed)
    gam = s_link.sample(rng, steps, paths)
    nus = a_link.sample(rng, steps, paths)
    cq, cr = np.linalg.cholesky(Q + 1e-300 * np.eye(n)), np.linalg.cholesky(R)
    x = rng.standard_normal((paths, n))          # x_0 ~ N(0, I), Σ_0 = I
    xh = np.zeros((paths, n))
    P = np.broadcast_to(np.eye(n), (paths, n, n)).copy()
    costs = np.zeros(paths)
    m = np.empty(steps)
    for t in range(steps):
        g = gam[t][:, None]
        v = nus[t][:, None].astype(float)
        y = x @ C.T + rng.standard_normal((paths, C.shape[0])) @ cr.T
        PC = P @ C.T
        Sinv = np.linalg.inv(C @ PC + R)
        K = PC @ Sinv
        innov = y - xh @ C.T
        xf = xh + g * np.einsum("pij,pj->pi", K, innov)
        Pf = P - g[:, :, None] * (K @ np.swapaxes(PC, 1, 2))
        u = xf @ L.T
        m[t] = float(np.mean(np.sum(x * x, axis=1)))
        if t >= burn_in:
            costs += np.einsum("pi,ij,pj->p", x, W, x) + v[:, 0] * np.einsum(
                "pi,ij,pj->p", u, U, u)
        applied = v * u
        x = x @ A.T + applied @ B.T + rng.standard_normal((paths, n)) @ cq.T
        xh = xf @ A.T + applied @ B.T
        P = A @ Pf @ A.T + Q
        P = 0.5 * (P + np.swapaxes(P, 1, 2))
    del mu
    return _summary(costs, m, burn_in, paths, steps, seed, "tcp-like optimal", confidence)


def simulate_fixed(design: FixedDesign, sensing: Any, actuation: Any, paths: int = 2000,
                   steps: int = 2000, burn_in: int = 200, seed: int = 0, noise: bool = True,
                   confidence: float = 0.95) -> LoopSimulation:
    """Monte Carlo of a fixed design (zero/hold, acknowledged or not).

    .. math::

        \\hat x_{t|t} = \\hat x_t + \\gamma_t K (y_t - C\\hat x_t), \\quad u_t = L \\hat x_{t|t},
        \\quad a_t = \\nu_t u_t\\ [+ (1-\\nu_t) a_{t-1}], \\quad
        x_{t+1} = A x_t + B a_t + w_t

    Parameters
    ----------
    design : FixedDesign
    sensing, actuation : LossLink or float
    paths, steps, burn_in, seed : int
    noise : bool
        Drive the loop with the noises (False: a noise-free run from x_0 ~ N(0, I), x̂_0 = 0,
        to watch the second moment grow or decay).
    confidence : float
    """
    d = design
    A, B, C, K, L, W, U = d.A, d.B, d.C, d.K, d.L, d.W, d.U
    n, mu, mo = A.shape[0], B.shape[1], C.shape[0]
    s_link, a_link = as_link(sensing), as_link(actuation)
    nu_bar = float(a_link.arrival())
    hold = d.on_loss == "hold"
    rng = np.random.default_rng(seed)
    gam = s_link.sample(rng, steps, paths)
    nus = a_link.sample(rng, steps, paths)
    scale = 1.0 if noise else 0.0
    cq = np.linalg.cholesky(d.Q + 1e-300 * np.eye(n)) * scale
    ev, V = np.linalg.eigh(d.R)
    cr = V * np.sqrt(np.clip(ev, 0, None)) * scale
    x = rng.standard_normal((paths, n))
    xh = np.zeros((paths, n))
    a = np.zeros((paths, mu))
    ah = np.zeros((paths, mu))
    costs = np.zeros(paths)
    m = np.empty(steps)
    for t in range(steps):
        g = gam[t][:, None].astype(float)
        v = nus[t][:, None].astype(float)
        y = x @ C.T + rng.standard_normal((paths, mo)) @ cr.T
        xf = xh + g * ((y - xh @ C.T) @ K.T)
        u = xf @ L.T
        a_new = v * u + ((1 - v) * a if hold else 0.0)
        if d.acked:
            ah_new = a_new
        else:
            ah_new = nu_bar * u + ((1 - nu_bar) * ah if hold else 0.0)
        m[t] = float(np.mean(np.sum(x * x, axis=1) + np.sum(xh * xh, axis=1)))
        if t >= burn_in:
            costs += np.einsum("pi,ij,pj->p", x, W, x) + np.einsum("pi,ij,pj->p", a_new, U,
                                                                   a_new)
        x = x @ A.T + a_new @ B.T + rng.standard_normal((paths, n)) @ cq.T
        xh = xf @ A.T + ah_new @ B.T
        a, ah = a_new, ah_new
    label = f"fixed design ({'acknowledged' if d.acked else 'not acknowledged'}, {d.on_loss})"
    return _summary(costs, m, burn_in, paths, steps, seed, label, confidence)
