"""Batched BLAS-3 Riccati steps for large systems (the random Riccati equation, many paths).

The compiled lane kernels of :mod:`kfcrit.sim.kernels` advance blocks of ``LANES`` paths with
scalar loops: every step costs ``LANES`` · O(n³) whatever the number of paths, without BLAS.
From :data:`BATCHED_MIN_STATES` states on, the paths are advanced instead as a stack of n×n
matrices with NumPy's batched matrix products (one BLAS-3 ``gemm`` per path and product), in
the same Joseph form (docs/theory.md §1):

.. math::

    S = C X C' + c R,\\quad AK = \\gamma\\, A X C' S^{-1},\\quad F = A - AK\\, C,\\quad
    X' = F X F' + (AK) R (AK)' c + c Q ,

with c = e^{−ℓ} for a path in the scaled form P = e^ℓ X past the divergence threshold (c = 1
otherwise), as the lane kernel does. A path's arrivals are drawn from its own stream
(:func:`kfcrit.sim.arrivals.arrival_sequence`, the numbers the lane kernel draws), so both
kernels simulate the same paths; their results agree to rounding (the summation order of the
products differs), and a path's values do not depend on the other paths of its batch.
"""
from __future__ import annotations

import math

import numpy as np

from kfcrit.sim.arrivals import arrival_sequence
from kfcrit.sim.kernels import LOAD
from kfcrit.sim.stats import LOG_KEEP

BATCHED_MIN_STATES = 24
"""Smallest n advanced by :func:`batched_paths` (below it the lane kernels are faster)."""


class StepBuffers:
    """Work arrays of :func:`_step` for a stack of B paths, allocated once per run: a fresh
    B×n×n temporary per product costs page faults on every step (about 15 % of a step at
    n = 400, measured), and the products written into these are the same, bit for bit.

    Two result arrays alternate, so that a step never overwrites the state it starts from
    (a step that is redone in scaled form restarts from it).
    """

    def __init__(self, B: int, n: int, m: int) -> None:
        self.XC, self.AXC, self.KR = (np.empty((B, n, m)) for _ in range(3))
        self.S = np.empty((B, m, m))
        self.F, self.FX, self.out = (np.empty((B, n, n)) for _ in range(3))
        self.results = (np.empty((B, n, n)), np.empty((B, n, n)))

    def result_for(self, X: np.ndarray) -> np.ndarray:
        """The result array that is not ``X``."""
        first, second = self.results
        return second if np.shares_memory(first, X) else first


def _step(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, X: np.ndarray,
          gamma: np.ndarray, c: np.ndarray, load: np.ndarray,
          work: StepBuffers | None = None) -> np.ndarray:
    """One Joseph-form step of every path in the stack ``X`` (B×n×n), arrivals ``gamma`` (B),
    noise scale ``c`` (B) and relative diagonal loading ``load`` (B) of S; the products go
    into ``work`` when given (its shapes those of ``X``), else into new arrays."""
    B, n, _ = X.shape
    if work is None:
        work = StepBuffers(B, n, C.shape[0])
    XC = np.matmul(X, C.T, out=work.XC)                               # B×n×m
    S = np.matmul(C, XC, out=work.S)                                  # B×m×m
    S += c[:, None, None] * R
    if load.any():
        d = np.einsum("bii->bi", S)
        d += load[:, None] * (d + 1e-288)
    AXC = np.matmul(A, XC, out=work.AXC)
    # AK = γ · A X C' S^{-1}: S is symmetric, so solve S Z = (A X C')' and transpose
    AK = np.swapaxes(np.linalg.solve(S, np.swapaxes(AXC, 1, 2)), 1, 2) * gamma[:, None, None]
    F = np.matmul(AK, C, out=work.F)
    np.subtract(A, F, out=F)                                          # F = A − AK C
    out = np.matmul(np.matmul(F, X, out=work.FX), np.swapaxes(F, 1, 2), out=work.out)
    noise = np.matmul(np.matmul(AK, R, out=work.KR), np.swapaxes(AK, 1, 2), out=work.FX)
    noise *= c[:, None, None]
    noise += c[:, None, None] * Q
    out += noise                                   # F X F' + ((AK) R (AK)' c + c Q)
    result = np.add(out, np.swapaxes(out, 1, 2), out=work.result_for(X))
    result *= 0.5
    return result


def arrivals_of(keys: np.ndarray, offsets: np.ndarray, kind: int, p: float, f: float, r: float,
                seq: np.ndarray, steps: int) -> np.ndarray:
    """γ_t (paths × steps, float 0/1) of the paths keyed ``keys``, as the lane kernels draw
    them."""
    return np.array([arrival_sequence(np.uint64(k), kind, p, f, r, seq, int(o), steps)
                     for k, o in zip(keys, offsets)], dtype=float).reshape(len(keys), steps)


def lambda_max_stack(X: np.ndarray) -> np.ndarray:
    """λ_max of each symmetric matrix of the stack (LAPACK ``syevd``, to rounding)."""
    return np.linalg.eigvalsh(X)[:, -1]


def batched_paths(A, C, Q, R, P0, gamma, sample_t, lmax_index, threshold, out_tr, out_ltr,
                  out_lm, out_llm, out_div, out_fail, traces) -> None:
    """Advance B paths from P_0 for ``gamma.shape[1]`` steps; fill the outputs of
    :func:`kfcrit.sim.kernels.rre_paths` (same conventions: tr P and its log at the sample
    times, λ_max where ``lmax_index`` ≥ 0, divergence and failure times, full traces of the
    first ``traces.shape[0]`` paths).

    Divergence: past ``threshold`` a path continues in the scaled form P = e^ℓ X, tr X = 1
    (noise scaled by e^{−ℓ}, S loaded by the relative ``LOAD``), back to the plain form below
    it. A step that is not finite is redone in scaled form; a path whose step fails even so is
    frozen at its last finite value (``out_fail``).
    """
    B, steps = gamma.shape
    n = A.shape[0]
    X = np.broadcast_to(P0, (B, n, n)).copy()
    lg = np.zeros(B)
    sc = np.zeros(B, dtype=bool)
    out_div[:] = -1
    out_fail[:] = -1
    keep = math.exp(LOG_KEEP)
    lthr = math.log(threshold)
    trn = np.trace(X, axis1=1, axis2=2).copy()
    k_tr = traces.shape[0]
    if k_tr:
        traces[:, 0] = trn[:k_tr]
    si = 0

    def record(si: int) -> None:
        out_tr[:, si] = trn
        with np.errstate(divide="ignore"):
            out_ltr[:, si] = np.where(sc, lg, np.where(trn > keep, np.log(np.maximum(trn, 1e-300)),
                                                       -np.inf))
        li = lmax_index[si]
        if li < 0:
            return
        lm = lambda_max_stack(X)
        with np.errstate(divide="ignore", over="ignore"):
            out_lm[:, li] = np.where(sc, lm * trn, lm)
            out_llm[:, li] = np.where(sc, np.log(np.maximum(lm, 1e-300)) + lg,
                                      np.where(lm > keep, np.log(np.maximum(lm, 1e-300)),
                                               -np.inf))

    if sample_t.size and sample_t[0] == 0:
        record(0)
        si = 1
    work = StepBuffers(B, n, C.shape[0])
    for t in range(steps):
        c = np.where(sc, np.exp(-lg), 1.0)
        load = np.where(sc, LOAD, 0.0)
        with np.errstate(all="ignore"):
            Y = _step(A, C, Q, R, X, gamma[:, t], c, load, work)
            tr = np.trace(Y, axis1=1, axis2=2)
        bad = ~np.isfinite(tr)
        for b in np.flatnonzero(bad):
            # redo from the previous state in scaled form (tr X = 1), as the lane kernel does
            s0 = float(np.trace(X[b]))
            ell0 = (lg[b] if sc[b] else 0.0) + math.log(s0) if 0 < s0 < math.inf else math.nan
            with np.errstate(all="ignore"):
                y = _step(A, C, Q, R, X[b:b + 1] / s0, gamma[b:b + 1, t],
                          np.array([math.exp(-ell0)]), np.array([LOAD]))[0]
            s1 = float(np.trace(y))
            if ell0 == ell0 and 0 < s1 < math.inf:
                Y[b] = y / s1
                lg[b], sc[b] = ell0 + math.log(s1), True
                tr[b] = 1.0
            else:
                if out_fail[b] < 0:
                    out_fail[b] = t + 1
                Y[b] = X[b]
                tr[b] = float(np.trace(X[b]))
        X = Y
        # scaled paths: renormalise; plain paths past the threshold: enter the scaled form
        ell = np.where(sc, lg + np.log(np.maximum(tr, 1e-300)),
                       np.log(np.maximum(tr, 1e-300)))
        move = sc | (tr > threshold)
        above = move & (ell > lthr)
        first = above & (out_div < 0)
        out_div[first] = t + 1
        if move.any():
            X[move] /= tr[move][:, None, None]
            back = move & ~above
            if back.any():   # back below the threshold: the plain form again
                X[back] *= np.exp(ell[back])[:, None, None]
            lg = np.where(above, ell, 0.0)
            sc = above.copy()
        with np.errstate(over="ignore"):
            trn = np.where(sc, np.exp(lg), np.trace(X, axis1=1, axis2=2))
        if k_tr:
            traces[:, t + 1] = trn[:k_tr]
        if si < sample_t.size and sample_t[si] == t + 1:
            record(si)
            si += 1


def batched_ergodic(A, C, Q, R, P0, gamma, burn_in, levels, max_burst, n_batches, threshold,
                    sums, exceed, batch_sums, burst_count, burst_trace, block_max, block_min, div,
                    losses, longest) -> None:
    """:func:`kfcrit.sim.kernels.ergodic_paths` with batched BLAS-3 steps (same outputs and
    conventions; ``gamma`` holds the arrivals, replicas × steps)."""
    W, steps = gamma.shape
    n = A.shape[0]
    X = np.broadcast_to(P0, (W, n, n)).copy()
    tr = np.full(W, float(np.trace(P0)))
    run = np.zeros(W, dtype=np.int64)
    span = max(steps - burn_in, 1)
    div[:] = -1
    ones, zeros = np.ones(W), np.zeros(W)
    work = StepBuffers(W, n, C.shape[0])
    for t in range(steps):
        arrived = gamma[:, t] > 0
        if t >= burn_in:
            for b in np.flatnonzero(div < 0):
                if arrived[b]:
                    if run[b] > 0:
                        j = min(run[b], max_burst)
                        burst_count[b, j] += 1
                        burst_trace[b, j] += tr[b]
                    run[b] = 0
                else:
                    run[b] += 1
                    losses[b] += 1
                    longest[b] = max(longest[b], run[b])
        with np.errstate(all="ignore"):
            X = _step(A, C, Q, R, X, gamma[:, t], ones, zeros, work)
            s = np.trace(X, axis1=1, axis2=2)
        k = int(math.log2(t + 1))
        for b in np.flatnonzero(div < 0):
            if not s[b] <= threshold:
                div[b] = t + 1
                X[b] = P0
                continue
            tr[b] = s[b]
            block_max[b, k] = max(block_max[b, k], s[b])
            block_min[b, k] = min(block_min[b, k], s[b])
            if t + 1 > burn_in:
                sums[b, 0] += s[b]
                sums[b, 1] += s[b] * s[b]
                exceed[b] += s[b] > levels
                batch_sums[b, min((t - burn_in) * n_batches // span, n_batches - 1)] += s[b]
