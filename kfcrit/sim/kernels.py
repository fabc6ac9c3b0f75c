"""Compiled kernels (numba) of the random Riccati equation P_{t+1} = f_{γ_t}(P_t).

Lanes (paths) are the innermost, contiguous axis of every array (structure of arrays), so each
loop over lanes is a SIMD loop and the matrix loops are paid once per block of paths. A path's
arithmetic never depends on the block it runs in: results do not depend on the batch size.

Numerics. The arrival step is written in Joseph form, f_1(X) = F X F' + (AK) R (AK)' + Q with
AK = A X C' S^{-1}, S = C X C' + R, F = A − AK C, which equals φ(K_X, X) (Sinopoli Lemma 1(a)):
a sum of positive semidefinite terms, so the update preserves PSD up to rounding of each term;
only the upper triangle is computed and mirrored, so every iterate is exactly symmetric.
Divergence: a path whose trace crosses the divergence threshold is counted as diverged but not
stopped: it continues in the scaled form P = e^ℓ X, tr X = 1, with f_0: A X A' + e^{−ℓ}Q and
f_1: the Riccati map with e^{−ℓ}Q, e^{−ℓ}R (renormalised every step), so every statistic is a
true value. Only blocks holding a scaled lane take the scaled branch, so the non-divergent hot
path is unchanged. The long ergodic paths still stop at the threshold.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from kfcrit.sim.arrivals import channel_next, channel_start, next_uniform
from kfcrit.sim.stats import LOG_KEEP

LANES = 128
"""Paths advanced together by the kernel (the SIMD axis): a compile-time constant, so the
lane loops have a fixed trip count (no remainder loop) and every path runs the same vector code."""


# ---------------------------------------------------------------------------------------------
# The Riccati step (Joseph form) and the kernels
# ---------------------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", inline="always")
def riccati_lanes(A, C, Q, R, X, g, W, out, F, FX, XC, L, AK, T, scaled, cs, ld):
    """out[:, :, b] = f_{γ_b}(X[:, :, b]) for the lanes b < W; g[k, b] ∈ {0.0, 1.0} says whether
    output row k reached the estimator in lane b (one sensor: every row alike).

    Received set: with D = diag(g[:, b]) the step uses S̃ = D S D + (I − D) and AK = A X C' S̃⁻¹ D,
    i.e. the gain of the stacked rows of C that arrived (S̃ is S on those rows and the identity
    elsewhere, so its Cholesky factor and inverse split the same way) and 0 for the others.
    When every row arrived, S̃ = S exactly (products by 1.0, sums with 0.0).

    With ``scaled`` the noise of lane b is multiplied by ``cs[b]`` (Q → c Q, R → c R: the map
    of the scaled form P = e^ℓ X, c = e^{−ℓ}) and S = C X C' + c R is loaded on its diagonal by
    ``ld[b]`` · (S_kk + 1e-288) (a relative 1e-12 for scaled lanes, which keeps the Cholesky
    pivots positive when X is nearly singular; Joseph form: a slightly sub-optimal gain changes
    P only to second order). Lanes with cs = 1, ld = 0 give bit-identical results to the
    unscaled branch (multiplications by 1.0 and additions of 0.0 are exact).

    Lanes (paths) are the innermost, contiguous axis, so every loop over b is a SIMD loop and
    the matrix loops are paid once per block of paths. One formula serves losses and arrivals:
    AK = γ · A X C' S^{-1} (S = C X C' + R = L L', Cholesky), F = A − AK C and
    out = F X F' + (AK) R (AK)' + Q — the Joseph form φ(K_X, X) for γ = 1 and exactly
    A X A' + Q for γ = 0 (AK = 0). Upper triangle computed, then mirrored.
    """
    n = A.shape[0]
    m = C.shape[0]
    for i in range(n):
        for k in range(m):
            for b in range(W):
                XC[i, k, b] = 0.0
            for j in range(n):
                c = C[k, j]
                for b in range(W):
                    XC[i, k, b] += X[i, j, b] * c
    for k in range(m):
        for l in range(k + 1):
            r = R[k, l]
            if scaled:
                for b in range(W):
                    L[k, l, b] = r * cs[b]
            else:
                for b in range(W):
                    L[k, l, b] = r
            for j in range(n):
                c = C[k, j]
                for b in range(W):
                    L[k, l, b] += c * XC[j, l, b]
    if scaled:
        for k in range(m):
            for b in range(W):
                L[k, k, b] += ld[b] * (L[k, k, b] + 1e-288)
    for k in range(m):  # rows that did not arrive: identity rows of S̃
        for l in range(k):
            for b in range(W):
                L[k, l, b] = L[k, l, b] * (g[k, b] * g[l, b])
        for b in range(W):
            L[k, k, b] = L[k, k, b] * g[k, b] + (1.0 - g[k, b])
    for k in range(m):
        for l in range(k):
            for b in range(W):
                L[k, k, b] -= L[k, l, b] * L[k, l, b]
        for b in range(W):  # the diagonal holds 1/L_kk: one division per pivot, not per use
            L[k, k, b] = 1.0 / math.sqrt(L[k, k, b])
        for i in range(k + 1, m):
            for l in range(k):
                for b in range(W):
                    L[i, k, b] -= L[i, l, b] * L[k, l, b]
            for b in range(W):
                L[i, k, b] = L[i, k, b] * L[k, k, b]
    for i in range(n):
        for k in range(m):
            for b in range(W):
                T[i, k, b] = 0.0
            for j in range(n):
                a = A[i, j]
                for b in range(W):
                    T[i, k, b] += a * XC[j, k, b]
        for k in range(m):
            for b in range(W):
                AK[i, k, b] = T[i, k, b]
            for l in range(k):
                for b in range(W):
                    AK[i, k, b] -= L[k, l, b] * AK[i, l, b]
            for b in range(W):
                AK[i, k, b] = AK[i, k, b] * L[k, k, b]
        for k in range(m - 1, -1, -1):
            for l in range(k + 1, m):
                for b in range(W):
                    AK[i, k, b] -= L[l, k, b] * AK[i, l, b]
            for b in range(W):
                AK[i, k, b] = AK[i, k, b] * L[k, k, b] * g[k, b]
    for i in range(n):
        for j in range(n):
            a = A[i, j]
            for b in range(W):
                F[i, j, b] = a
            for k in range(m):
                c = C[k, j]
                for b in range(W):
                    F[i, j, b] -= AK[i, k, b] * c
        for k in range(m):
            for b in range(W):
                T[i, k, b] = 0.0
            for l in range(m):
                r = R[l, k]
                for b in range(W):
                    T[i, k, b] += AK[i, l, b] * r
            if scaled:
                for b in range(W):
                    T[i, k, b] *= cs[b]
    # F X and the upper triangle of F X F' + (AK R) AK' + Q: the n³ part of the step. Three
    # products per pass over the lanes (one load/store of the accumulator per three terms);
    # the grouping depends on n only, so every lane sums in the same order.
    for i in range(n):
        for j in range(n):
            k = n % 3
            if k == 0:
                for b in range(W):
                    FX[i, j, b] = 0.0
            elif k == 1:
                for b in range(W):
                    FX[i, j, b] = F[i, 0, b] * X[0, j, b]
            else:
                for b in range(W):
                    FX[i, j, b] = F[i, 0, b] * X[0, j, b] + F[i, 1, b] * X[1, j, b]
            while k < n:
                for b in range(W):
                    FX[i, j, b] += (F[i, k, b] * X[k, j, b] + F[i, k + 1, b] * X[k + 1, j, b]
                                    + F[i, k + 2, b] * X[k + 2, j, b])
                k += 3
    for i in range(n):
        for j in range(i, n):
            q = Q[i, j]
            if scaled:
                for b in range(W):
                    out[i, j, b] = q * cs[b]
            else:
                for b in range(W):
                    out[i, j, b] = q
            for k in range(m):
                for b in range(W):
                    out[i, j, b] += T[i, k, b] * AK[j, k, b]
            k = n % 3
            if k == 1:
                for b in range(W):
                    out[i, j, b] += FX[i, 0, b] * F[j, 0, b]
            elif k == 2:
                for b in range(W):
                    out[i, j, b] += FX[i, 0, b] * F[j, 0, b] + FX[i, 1, b] * F[j, 1, b]
            while k < n:
                for b in range(W):
                    out[i, j, b] += (FX[i, k, b] * F[j, k, b] + FX[i, k + 1, b] * F[j, k + 1, b]
                                     + FX[i, k + 2, b] * F[j, k + 2, b])
                k += 3
            if j > i:
                for b in range(W):
                    out[j, i, b] = out[i, j, b]


LMAX_BISECTIONS = 38
"""Bisection steps for λ_max: the bracket (⊂ [tr/n, tr]) shrinks below 3.7e-12 · tr."""


@njit(cache=True, error_model="numpy")
def lambda_max_lanes(X, W, out, N, lo, hi, mu, d, fail):
    """λ_max(X[:, :, b]) for the lanes b < W of symmetric PSD matrices, into ``out``.

    n ≤ 2: closed form. Otherwise bisection on [max(tr/n, max_i X_ii), min(tr, max_i Σ_j |X_ij|)]
    (λ_max of a PSD matrix lies there; Gershgorin): μ is above λ_max iff μI − X is positive
    definite, i.e. iff its Cholesky factorisation (backward stable, lane-parallel in ``N``) has
    only positive pivots.
    """
    n = X.shape[0]
    if n == 1:
        for b in range(W):
            out[b] = X[0, 0, b]
        return
    if n == 2:
        for b in range(W):
            h = 0.5 * (X[0, 0, b] + X[1, 1, b])
            e = 0.5 * (X[0, 0, b] - X[1, 1, b])
            out[b] = h + math.sqrt(e * e + X[0, 1, b] * X[0, 1, b])
        return
    for b in range(W):
        lo[b] = 0.0  # tr X
        hi[b] = 0.0  # max diagonal
        mu[b] = 0.0  # Gershgorin bound max_i Σ_j |X_ij|
    for i in range(n):
        for b in range(W):
            lo[b] += X[i, i, b]
            hi[b] = max(hi[b], X[i, i, b])
            d[b] = 0.0
        for j in range(n):
            for b in range(W):
                d[b] += abs(X[i, j, b])
        for b in range(W):
            mu[b] = max(mu[b], d[b])
    for b in range(W):
        tr = lo[b]
        lo[b] = max(tr / n, hi[b])
        hi[b] = min(tr, mu[b])
    for _ in range(LMAX_BISECTIONS):
        for b in range(W):
            mu[b] = 0.5 * (lo[b] + hi[b])
            fail[b] = 0.0
        for j in range(n):
            for b in range(W):
                d[b] = mu[b] - X[j, j, b]
            for k in range(j):
                for b in range(W):
                    d[b] -= N[j, k, b] * N[j, k, b]
            for b in range(W):  # N[j, j] holds the reciprocal of the pivot's square root
                if d[b] > 0.0:
                    N[j, j, b] = 1.0 / math.sqrt(d[b])
                else:
                    fail[b] = 1.0
                    N[j, j, b] = 1.0
            for i in range(j + 1, n):
                for b in range(W):
                    d[b] = -X[i, j, b]
                for k in range(j):
                    for b in range(W):
                        d[b] -= N[i, k, b] * N[j, k, b]
                for b in range(W):
                    N[i, j, b] = d[b] * N[j, j, b]
        for b in range(W):
            if fail[b] > 0.0:
                lo[b] = mu[b]
            else:
                hi[b] = mu[b]
    for b in range(W):
        out[b] = 0.5 * (lo[b] + hi[b])


@njit(cache=True)
def workspace(n: int, m: int, W: int):
    """Lane arrays of one block: X, out, F, FX (n×n×W), XC, AK, T (n×m×W), L (m×m×W)."""
    return (np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, n, W)),
            np.empty((n, m, W)), np.empty((m, m, W)), np.empty((n, m, W)), np.empty((n, m, W)))


@njit(cache=True)
def set_lane(X: np.ndarray, b: int, P0: np.ndarray) -> float:
    """X[:, :, b] = P0; return tr P0."""
    n = P0.shape[0]
    tr = 0.0
    for i in range(n):
        for j in range(n):
            X[i, j, b] = P0[i, j]
        tr += P0[i, i]
    return tr


LOAD = 1e-12
"""Relative diagonal loading of S = C X C' + c R for lanes in scaled form (see riccati_lanes)."""




@njit(cache=True)
def lane_scale(X: np.ndarray, b: int, s: float) -> None:
    """X[:, :, b] *= s."""
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            X[i, j, b] *= s


@njit(cache=True)
def lane_trace(X: np.ndarray, b: int) -> float:
    s = 0.0
    for i in range(X.shape[0]):
        s += X[i, i, b]
    return s


@njit(cache=True, error_model="numpy")
def scaled_step(A, C, Q, R, P, b, g, log_scale, ws, out):
    """One step of lane b of ``P`` (tr P_b = e^``log_scale`` · tr X) in scaled form, into ``out``.

    ``ws`` is a one-lane workspace. Returns the new log scale ℓ' (tr of the new X is 1), or NaN
    when the step is not finite (a numerical failure).
    """
    n = A.shape[0]
    X1, Y1, F1, FX1, XC1, L1, AK1, T1, g1, c1, d1 = ws
    tr = lane_trace(P, b)
    if not (tr > 0.0 and tr < math.inf):
        return math.nan
    for i in range(n):
        for j in range(n):
            X1[i, j, 0] = P[i, j, b] / tr
    ell = log_scale + math.log(tr)
    for k in range(g.shape[0]):
        g1[k, 0] = g[k, b]
    c1[0] = math.exp(-ell)
    d1[0] = LOAD
    riccati_lanes(A, C, Q, R, X1, g1, 1, Y1, F1, FX1, XC1, L1, AK1, T1, True, c1, d1)
    s = lane_trace(Y1, 0)
    if not (s > 0.0 and s < math.inf):
        return math.nan
    for i in range(n):
        for j in range(n):
            out[i, j, b] = Y1[i, j, 0] / s
    return ell + math.log(s)


@njit(cache=True, error_model="numpy", nogil=True)
def rre_paths(A, C, Q, R, P0, keys, offsets, kinds, ps, fs, rs, seqs, seq_len, row_sensor, t0,
              t1, sample_t, lmax_index, threshold, Xall, lg_all, sc_all, state_all, ch_all,
              out_tr, out_ltr, out_lm, out_llm, out_div, out_fail, traces):
    """Advance the paths of a batch from step ``t0`` to ``t1``; record tr P, λ_max at sample times.

    Paths run in blocks of ``LANES`` lanes (see :func:`riccati_lanes`); the last block of a batch
    is padded with spare lanes (P_0, always arrivals) whose values are never read, so every path
    runs through the same fixed-size vector loops: a path's arithmetic does not depend on its
    block, so results do not depend on the batch or the chunking in time. The state of every
    path (X, log scale, scaled flag, random and channel state) is kept in ``Xall`` (n×n×B),
    ``lg_all``, ``sc_all``, ``state_all``, ``ch_all`` between calls (``t0 = 0`` initialises it).
    ``traces`` (k, steps + 1): full traces of the first k paths (k may be 0).

    Sensors: output row k of C belongs to sensor ``row_sensor[k]``; sensor s has its own link
    (``kinds[s]``, ``ps[s]``, ``fs[s]``, ``rs[s]``, trace ``seqs[s, :seq_len[s]]``), random stream
    (``keys[s]``, trace offsets ``offsets[s]``) and channel state (``state_all[s]``,
    ``ch_all[s]``); a step uses the rows whose sensor's packet arrived (see
    :func:`riccati_lanes`). One sensor owning every row is the single-link filter.

    Sample times: ``out_tr[:, s]`` = tr P at ``sample_t[s]`` (inf beyond float64) and
    ``out_ltr[:, s]`` its natural log where tr P > e^``LOG_KEEP`` or the path is in scaled
    form, −inf elsewhere (see :func:`kfcrit.sim.stats.accumulate_log`: smaller values cannot
    change a log-sum-exp sum that is used). λ_max is computed only at the sample times s with
    ``lmax_index[s] = k ≥ 0``, into ``out_lm[:, k]`` / ``out_llm[:, k]`` (same conventions).

    Divergence: when tr P crosses ``threshold`` the path is *not* stopped; ``out_div`` records
    the first crossing time (−1 if never) and the path continues in the scaled form
    P = e^ℓ X, tr X = 1 (f_γ(P) = e^ℓ f_γ^{(e^{−ℓ}Q, e^{−ℓ}R)}(X), then renormalised), so its
    values stay true values whatever their size; it returns to the plain form when tr P falls
    back below the threshold. A non-finite step (even in scaled form) is a numerical failure:
    ``out_fail`` records its time and the path keeps its last finite value from then on.
    """
    n = A.shape[0]
    m = C.shape[0]
    B = keys.shape[1]
    N = kinds.shape[0]
    all_iid = True
    for s in range(N):
        all_iid &= kinds[s] == 0
    n_samples = sample_t.shape[0]
    n_traced = traces.shape[0]
    X, Y, F, FX, XC, L, AK, T = workspace(n, m, LANES)
    ws = workspace(n, m, 1) + (np.zeros((m, 1)), np.ones(1), np.zeros(1))
    g = np.ones((m, LANES))
    gs = np.ones((N, LANES))
    state = np.empty((N, LANES), dtype=np.uint64)
    ch = np.empty((N, LANES), dtype=np.int64)
    trn = np.empty(LANES)
    lm = np.empty(LANES)
    lg = np.zeros(LANES)
    sc = np.zeros(LANES, dtype=np.int64)
    cs = np.ones(LANES)
    ld = np.zeros(LANES)
    v1, v2, v3, v4, v5 = (np.empty(LANES), np.empty(LANES), np.empty(LANES), np.empty(LANES),
                          np.empty(LANES))
    lthr = math.log(threshold)
    keep = math.exp(LOG_KEEP)
    si0 = 0
    while si0 < n_samples and sample_t[si0] < t0:
        si0 += 1
    for start in range(0, B, LANES):
        W = min(LANES, B - start)
        nsc = 0
        for b in range(W, LANES):  # spare lanes: P_0 under arrivals, never read
            set_lane(X, b, P0)
            for k in range(m):
                g[k, b] = 1.0
            sc[b] = 0
            lg[b] = 0.0
        if t0 == 0:
            for s in range(N):
                for b in range(W):
                    state[s, b] = keys[s, start + b]
                    ch[s, b] = channel_start(kinds[s], fs[s], rs[s], seq_len[s],
                                             offsets[s, start + b], state[s], b)
            for b in range(W):
                trn[b] = set_lane(X, b, P0)
                lg[b] = 0.0
                sc[b] = 0
                out_div[start + b] = -1
                out_fail[start + b] = -1
                if start + b < n_traced:
                    traces[start + b, 0] = trn[b]
        else:
            for s in range(N):
                for b in range(W):
                    state[s, b] = state_all[s, start + b]
                    ch[s, b] = ch_all[s, start + b]
            for b in range(W):
                lg[b] = lg_all[start + b]
                sc[b] = sc_all[start + b]
                for i in range(n):
                    for j in range(n):
                        X[i, j, b] = Xall[i, j, start + b]
                trn[b] = lane_trace(X, b)
        for b in range(LANES):
            cs[b] = math.exp(-lg[b]) if sc[b] else 1.0
            ld[b] = LOAD if sc[b] else 0.0
            nsc += sc[b]
        si = si0
        if si < n_samples and sample_t[si] == t0:
            if t0 == 0:
                _record(X, W, start, si, lmax_index[si], trn, sc, lg, keep, lm, FX, v1, v2, v3,
                        v4, v5, out_tr, out_ltr, out_lm, out_llm)
            si += 1
        for t in range(t0, t1):
            for s in range(N):
                st = state[s]
                if all_iid:  # i.i.d.: a branch-free loop the compiler vectorises
                    p = ps[s]
                    for b in range(W):
                        gs[s, b] = 1.0 if next_uniform(st, b) < p else 0.0
                else:
                    seq = seqs[s, :seq_len[s]]
                    chs = ch[s]
                    for b in range(W):
                        gs[s, b] = 1.0 if channel_next(kinds[s], ps[s], fs[s], rs[s], seq, chs,
                                                       st, b) else 0.0
            for k in range(m):
                s = row_sensor[k]
                for b in range(W):
                    g[k, b] = gs[s, b]
            riccati_lanes(A, C, Q, R, X, g, LANES, Y, F, FX, XC, L, AK, T, nsc > 0, cs, ld)
            X, Y = Y, X  # Y now holds the previous state (needed by a rescue step)
            for b in range(LANES):
                trn[b] = 0.0
            for i in range(n):
                for b in range(LANES):
                    trn[b] += X[i, i, b]
            fix = nsc > 0
            if not fix:
                for b in range(W):
                    fix |= not trn[b] <= threshold  # also catches NaN
            if fix:
                nsc = _rescale(A, C, Q, R, X, Y, W, start, t, g, trn, sc, lg, cs, ld, nsc,
                               threshold, lthr, ws, out_div, out_fail)
            if start < n_traced:
                for b in range(min(W, n_traced - start)):
                    traces[start + b, t + 1] = trn[b]
            if si < n_samples and sample_t[si] == t + 1:
                _record(X, W, start, si, lmax_index[si], trn, sc, lg, keep, lm, FX, v1, v2, v3,
                        v4, v5, out_tr, out_ltr, out_lm, out_llm)
                si += 1
        for s in range(N):
            for b in range(W):
                state_all[s, start + b] = state[s, b]
                ch_all[s, start + b] = ch[s, b]
        for b in range(W):
            lg_all[start + b] = lg[b]
            sc_all[start + b] = sc[b]
            for i in range(n):
                for j in range(n):
                    Xall[i, j, start + b] = X[i, j, b]


@njit(cache=True, error_model="numpy")
def _record(X, W, start, si, li, trn, sc, lg, keep, lm, N, v1, v2, v3, v4, v5, out_tr, out_ltr,
            out_lm, out_llm):
    """Write tr P (and λ_max when ``li`` ≥ 0) of the lanes b < W at sample column ``si``."""
    for b in range(W):
        out_tr[start + b, si] = trn[b]
        if sc[b]:
            out_ltr[start + b, si] = lg[b]
        else:
            out_ltr[start + b, si] = math.log(trn[b]) if trn[b] > keep else -math.inf
    if li < 0:
        return
    lambda_max_lanes(X, W, lm, N, v1, v2, v3, v4, v5)
    for b in range(W):
        if sc[b]:
            out_lm[start + b, li] = lm[b] * trn[b]
            out_llm[start + b, li] = math.log(lm[b]) + lg[b]
        else:
            out_lm[start + b, li] = lm[b]
            out_llm[start + b, li] = math.log(lm[b]) if lm[b] > keep else -math.inf


@njit(cache=True, error_model="numpy")
def _rescale(A, C, Q, R, X, Y, W, start, t, g, trn, sc, lg, cs, ld, nsc, threshold, lthr, ws,
             out_div, out_fail):
    """Move lanes across the divergence threshold (plain ↔ scaled form); return #scaled lanes.

    A lane in scaled form is renormalised to tr X = 1; a plain lane above the threshold enters
    the scaled form; a non-finite step is redone from the previous state ``Y`` in scaled form,
    and a lane whose step fails even so is frozen at its last finite value (``out_fail``).
    """
    n = X.shape[0]
    for b in range(W):
        s = trn[b]
        if sc[b] == 0 and s <= threshold:
            continue
        if sc[b] == 1 and s > 0.0 and s < math.inf:
            ell = lg[b] + math.log(s)
            lane_scale(X, b, 1.0 / s)
        elif sc[b] == 0 and s > threshold and s < math.inf:
            ell = math.log(s)
            lane_scale(X, b, 1.0 / s)
        else:  # overflow or NaN: redo the step from the previous state, scaled
            ell = scaled_step(A, C, Q, R, Y, b, g, lg[b] if sc[b] else 0.0, ws, X)
            if not ell == ell:  # a numerical failure: keep the last finite value
                if out_fail[start + b] < 0:
                    out_fail[start + b] = t + 1
                for i in range(n):
                    for j in range(n):
                        X[i, j, b] = Y[i, j, b]
                ell = lg[b] + math.log(lane_trace(X, b)) if sc[b] else \
                    math.log(lane_trace(X, b))
                if not sc[b]:  # back to its plain value
                    trn[b] = lane_trace(X, b)
                    continue
                lane_scale(X, b, 1.0 / lane_trace(X, b))
        if ell > lthr:
            if out_div[start + b] < 0:
                out_div[start + b] = t + 1
            if sc[b] == 0:
                sc[b] = 1
                nsc += 1
                ld[b] = LOAD
            lg[b] = ell
            cs[b] = math.exp(-ell)
            trn[b] = math.exp(ell)  # inf when it overflows: logs are recorded too
        else:  # back below the threshold: the plain form again
            lane_scale(X, b, math.exp(ell) / lane_trace(X, b))
            if sc[b] == 1:
                sc[b] = 0
                nsc -= 1
            lg[b] = 0.0
            cs[b] = 1.0
            ld[b] = 0.0
            trn[b] = lane_trace(X, b)
    return nsc


@njit(cache=True, error_model="numpy")
def ergodic_paths(A, C, Q, R, P0, keys, offsets, kind, p, f, r, seq, steps, burn_in, levels,
                   max_burst, n_batches, threshold, sums, exceed, batch_sums, burst_count,
                   burst_trace, block_max, block_min, div, losses, longest):
    """Long independent paths (one per lane): time sums, loss bursts, dyadic block extremes.

    Per lane b, over t = burn_in+1 … steps: ``sums[b]`` = (Σ tr P_t, Σ (tr P_t)²),
    ``exceed[b, q]`` = #{t : tr P_t > levels[q]}, ``batch_sums[b, k]`` the sum over the k-th of
    ``n_batches`` consecutive time batches. ``burst_count[b, j]`` counts loss bursts of length j
    (j = max_burst collects longer ones) and ``burst_trace[b, j]`` sums tr P_t at the arrival
    that ends them (the covariance accumulated by the burst). Block k covers t ∈ [2^k, 2^{k+1})
    (all t ≥ 1). ``div[b]`` is the divergence time or −1.
    """
    n = A.shape[0]
    m = C.shape[0]
    W = keys.shape[0]
    X, Y, F, FX, XC, L, AK, T = workspace(n, m, W)
    g = np.zeros((m, W))
    state = np.empty(W, dtype=np.uint64)
    ch = np.empty(W, dtype=np.int64)
    tr = np.empty(W)
    run = np.zeros(W, dtype=np.int64)
    span = max(steps - burn_in, 1)
    for b in range(W):
        state[b] = keys[b]
        ch[b] = channel_start(kind, f, r, seq.shape[0], offsets[b], state, b)
        tr[b] = set_lane(X, b, P0)
        div[b] = -1
    for t in range(steps):
        for b in range(W):
            arrived = channel_next(kind, p, f, r, seq, ch, state, b)
            for k in range(m):
                g[k, b] = 1.0 if arrived else 0.0
            if t >= burn_in and div[b] < 0:
                if arrived:
                    if run[b] > 0:
                        j = min(run[b], max_burst)
                        burst_count[b, j] += 1
                        burst_trace[b, j] += tr[b]
                    run[b] = 0
                else:
                    run[b] += 1
                    losses[b] += 1
                    longest[b] = max(longest[b], run[b])
        riccati_lanes(A, C, Q, R, X, g, W, Y, F, FX, XC, L, AK, T, False, tr, tr)
        X, Y = Y, X
        k = int(math.log2(t + 1))
        for b in range(W):
            if div[b] >= 0:
                continue
            s = 0.0
            for i in range(n):
                s += X[i, i, b]
            if not s <= threshold:
                div[b] = t + 1
                set_lane(X, b, P0)
                continue
            tr[b] = s
            block_max[b, k] = max(block_max[b, k], s)
            block_min[b, k] = min(block_min[b, k], s)
            if t + 1 > burn_in:
                sums[b, 0] += s
                sums[b, 1] += s * s
                for q in range(levels.shape[0]):
                    if s > levels[q]:
                        exceed[b, q] += 1.0
                batch_sums[b, min((t - burn_in) * n_batches // span, n_batches - 1)] += s
