"""Monte Carlo of the Kalman filter over a mesh (theory §13): received sets from hop outcomes.

Every period each path draws the mesh's hop outcomes — without a slot budget one Bernoulli
variable per hop and period for an aggregating transmitter and one per (hop, packet) for a
forwarding one, each succeeding with s_h = 1 − (1 − q_h)^{k_h+1}; with a slot budget D each route
spends one slot per attempt, hops in order, at most k_h + 1 attempts on hop h — and a sensor's
packet arrives when one of its routes delivers. The filter then updates with the rows of the
received set S (theory §9):

.. math::

    P_{t+1} = A P_t A' + Q - A P_t C_S'(C_S P_t C_S' + R_S)^{-1} C_S P_t A'.

The summary holds E[tr P_T] with its 95 % band, the empirical P(all lost), and the Hill
estimate of the tail exponent α of tr P_T across paths: E[tr P] is finite only when α > 1, and
for the filter the tail exponent is

.. math:: \\alpha = \\min_T \\frac{\\log(1/P(S \\subseteq T))}{\\log \\rho_T^2}

(the necessary constraints), so the estimate is an independent check of the verdict.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kfcrit.model.mesh import Mesh
from kfcrit.model.network import Network
from kfcrit.theory.mesh.law import hop_outcome_variables

HILL_FRACTION = 0.05
"""Fraction of the paths (the largest tr P_T) the Hill estimator uses."""


@dataclass(frozen=True)
class MeshRun:
    """What :func:`simulate_mesh` measured (plain numbers)."""

    paths: int
    steps: int
    seed: int
    mean_trace: float
    mean_trace_band: tuple[float, float]
    empirical_all_lost: float
    tail_exponent: float | None
    tail_exponent_band: tuple[float, float] | None


def _hop_draws(mesh: Mesh, rng: np.random.Generator, paths: int) -> np.ndarray:
    """Received-set bit masks of one period (no slot budget)."""
    variables = hop_outcome_variables(mesh)
    ok = {v: rng.random(paths) < mesh.hops[v[0]].period_success() for v in variables}
    got = np.zeros(paths, dtype=np.int64)
    for r in mesh.routes:
        delivered = np.ones(paths, dtype=bool)
        for k in mesh.route_hops(r):
            shared = mesh.mode_of(mesh.hops[k].source) == "aggregate"
            delivered &= ok[(k, None if shared else r.sensor)]
        got |= delivered.astype(np.int64) << mesh.sensors.index(r.sensor)
    return got


def _slot_draws(mesh: Mesh, rng: np.random.Generator, paths: int) -> np.ndarray:
    """Received-set bit masks of one period under the slot budget (each route its D slots)."""
    D = int(mesh.slots_per_period or 0)
    got = np.zeros(paths, dtype=np.int64)
    for r in mesh.routes:
        hops = [mesh.hops[k] for k in mesh.route_hops(r)]
        q = np.array([h.q for h in hops] + [0.0])
        cap = np.array([h.retries + 1 if h.retries is not None else D for h in hops] + [0])
        stage = np.zeros(paths, dtype=np.int64)
        tries = np.zeros(paths, dtype=np.int64)
        for _ in range(D):
            on = (stage < len(hops)) & (tries < cap[stage])
            win = on & (rng.random(paths) < q[stage])
            tries[on] += 1
            stage[win] += 1
            tries[win] = 0
        got |= (stage == len(hops)).astype(np.int64) << mesh.sensors.index(r.sensor)
    return got


def received_masks(mesh: Mesh, rng: np.random.Generator, paths: int) -> np.ndarray:
    """One period's received sets of ``paths`` independent paths (bit i = ``mesh.sensors[i]``)."""
    if mesh.slots_per_period is not None:
        return _slot_draws(mesh, rng, paths)
    return _hop_draws(mesh, rng, paths)


def _riccati_step(P: np.ndarray, masks: np.ndarray, a: np.ndarray, q: np.ndarray,
                  c: np.ndarray, r: np.ndarray, rows_of: dict[int, np.ndarray]) -> np.ndarray:
    """One step of the random Riccati equation for every path, grouped by received set."""
    out = np.einsum("ij,pjk,lk->pil", a, P, a) + q
    for mask in np.unique(masks):
        rows = rows_of[int(mask)]
        if rows.size == 0:
            continue
        idx = np.nonzero(masks == mask)[0]
        Ps, Cs, Rs = P[idx], c[rows], r[np.ix_(rows, rows)]
        PC = Ps @ Cs.T
        S = Cs @ PC + Rs
        gain = a @ PC @ np.linalg.inv(S)
        out[idx] -= gain @ np.swapaxes(a @ PC, 1, 2)
    return 0.5 * (out + np.swapaxes(out, 1, 2))


def hill_exponent(values: np.ndarray, fraction: float = HILL_FRACTION
                  ) -> tuple[float | None, tuple[float, float] | None]:
    r"""Hill's estimate of the tail exponent α of P(X > x) ~ x^{−α} and a 3σ band.

    .. math:: \hat\alpha = \frac{k}{\sum_{i<k} \log(x_{(i)} / x_{(k)})},\qquad
              \sigma \approx \hat\alpha/\sqrt{k}
    """
    x = np.sort(values[np.isfinite(values)])[::-1]
    k = int(fraction * x.size)
    if k < 20 or x[k] <= 0:
        return None, None
    logs = np.log(x[:k] / x[k])
    total = float(logs.sum())
    if total <= 0:
        return None, None
    alpha = k / total
    spread = 3.0 * alpha / math.sqrt(k)
    return alpha, (alpha - spread, alpha + spread)


def simulate_mesh(network: Network, mesh: Mesh, paths: int, steps: int, seed: int) -> MeshRun:
    """Simulate the filter over the mesh (module docstring) from P_0 = Σ0.

    Parameters
    ----------
    network : Network
        The plant and the sensors (names equal to the mesh's sensors).
    mesh : Mesh
    paths, steps : int
        Independent paths and periods per path.
    seed : int
        NumPy ``default_rng`` seed (same seed, same result).
    """
    system = network.stacked_system()
    a, q, c, r = system.a, system.q, system.c, system.r
    slices = dict(zip(network.names, network.row_slices()))
    rows_of = {}
    for mask in range(2 ** len(mesh.sensors)):
        rows = [i for b, s in enumerate(mesh.sensors) if mask >> b & 1
                for i in range(slices[s].start, slices[s].stop)]
        rows_of[mask] = np.array(rows, dtype=np.int64)
    rng = np.random.default_rng(seed)
    P = np.broadcast_to(system.sigma0, (paths, system.n, system.n)).copy()
    lost = 0
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(steps):
            masks = received_masks(mesh, rng, paths)
            lost += int(np.count_nonzero(masks == 0))
            P = _riccati_step(P, masks, a, q, c, r, rows_of)
    tr = np.trace(P, axis1=1, axis2=2)
    finite = tr[np.isfinite(tr)]
    mean = float(finite.mean()) if finite.size else math.inf
    half = 1.96 * float(finite.std(ddof=1)) / math.sqrt(max(finite.size, 2)) if finite.size > 1 \
        else math.inf
    alpha, band = hill_exponent(tr)
    return MeshRun(paths, steps, seed, mean, (mean - half, mean + half),
                   lost / (paths * steps), alpha, band)
