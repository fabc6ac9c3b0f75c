"""Monte Carlo of the random Riccati equation (RRE) and of the filter itself.

The idea in ten lines. The prediction covariance follows P_{t+1} = f_{γ_t}(P_t) (MATH §1),
with f_0(X) = A X A' + Q (loss) and f_1 the Riccati map (arrival). Many paths are advanced by a
compiled kernel (numba) in blocks of ``LANES`` paths, the path index being the innermost (SIMD)
axis, and memory never depends on ``steps``: only the values at ≤ ``horizon_samples`` sample
times are kept (plus the full traces of the first few paths when asked). Every path draws its
arrivals from its own stream, a SplitMix64 sequence keyed by
``SeedSequence(seed, spawn_key=(0, i))`` — exactly the i-th child of
``SeedSequence(seed).spawn(1)[0].spawn(...)`` — so a path's result depends on (seed, i) only, and
statistics are accumulated in path order: the output is bit-identical for any batch size. The
full state/estimate simulation (x_t, x̂_t) of a few paths reuses those arrival streams and draws
its noise from NumPy generators keyed by ``spawn_key=(1, j)``; the long ergodic paths use
``spawn_key=(2, j)``.

Numerics. The arrival step is written in Joseph form, f_1(X) = F X F' + (AK) R (AK)' + Q with
AK = A X C' S^{-1}, S = C X C' + R, F = A − AK C, which equals φ(K_X, X) (Sinopoli Lemma 1(a)):
a sum of positive semidefinite terms, so the update preserves PSD up to rounding of each term;
only the upper triangle is computed and mirrored, so every iterate is exactly symmetric.
Divergence: a path whose trace crosses ``divergence_threshold`` (finite; default 1e10 × the
problem's scale) is counted as diverged but not stopped: it continues in the scaled form
P = e^ℓ X, tr X = 1, with f_0: A X A' + e^{−ℓ}Q and f_1: the Riccati map with e^{−ℓ}Q, e^{−ℓ}R
(renormalised every step), so every statistic is a true value — a diverged path that comes back
down after arrivals is followed back down. Means over values beyond float64 come from log-sum-exp
sums and are reported as log10 (``log10_*``); never a silent inf or NaN. Only blocks holding a
scaled lane take the scaled branch of the kernel, so the non-divergent hot path is unchanged.
The long ergodic paths still stop at the threshold (their time averages end there).
"""
from __future__ import annotations

import io
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from kfcrit.errors import InputError
from kfcrit.io.atomic import write_atomic
from kfcrit.model.channels import ArrivalProcess, Bernoulli, Channel, exact_probability
from kfcrit.model.system import System

DEFAULT_SAMPLES = 200
"""Largest number of sample times kept for E[tr P_t] curves."""
THRESHOLD_FACTOR = 1e10
"""Default divergence threshold relative to the problem's scale max(tr Σ0, tr Q, tr P*)."""
Z95 = 1.959963984540054
"""Two-sided 95 % normal quantile."""
QUANTILE_LEVELS = (0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99)
STREAM_PATHS, STREAM_FULL_STATE, STREAM_ERGODIC = 0, 1, 2
MAX_TRACE_VALUES = 250_000_000
"""Guard on requested full traces (2 GB of float64)."""
LANES = 256
"""Paths advanced together by the kernel (the SIMD axis)."""
_KIND_CODE = {"iid": 0, "markov": 1, "sequence": 2}
PROGRESS_WORK = 4_000_000
"""Lane-steps × n² per kernel call when progress is reported (a call then takes ~0.05 s)."""



class quiet_numerics:  # noqa: N801 - used like a function: ``with quiet_numerics():``
    """Silence floating-point ``RuntimeWarning``s and scipy's ``LinAlgWarning`` inside a block.

    Overflow and ill-conditioning are handled explicitly where they can occur (divergence
    thresholds, ``np.isfinite`` checks, warnings in the record); this keeps NumPy/scipy from
    also printing them on stderr, which carries only kfcrit's own messages.
    """

    def __enter__(self) -> quiet_numerics:
        import warnings

        from scipy.linalg import LinAlgWarning

        self._err = np.seterr(all="ignore")
        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.simplefilter("ignore", LinAlgWarning)
        return self

    def __exit__(self, *exc: object) -> None:
        self._ctx.__exit__(*exc)
        np.seterr(**self._err)


# ---------------------------------------------------------------------------------------------
# Random streams
# ---------------------------------------------------------------------------------------------


def path_keys(seed: int, start: int, stop: int, stream: int = STREAM_PATHS) -> np.ndarray:
    """64-bit keys of paths ``start … stop−1``: ``SeedSequence(seed, spawn_key=(stream, i))``.

    The same numbers as ``SeedSequence(seed).spawn(stream + 1)[stream].spawn(stop)[i]
    .generate_state(1, uint64)``; each key seeds that path's SplitMix64 stream. Computed by
    :func:`_seedsequence_keys`, NumPy's SeedSequence hash vectorised over i (the tests compare
    it with NumPy's own; the loop over SeedSequence objects is the fallback for i ≥ 2^32).
    """
    if stop <= start:
        return np.zeros(0, dtype=np.uint64)
    if stop > 2 ** 32:
        return np.array([np.random.SeedSequence(seed, spawn_key=(stream, i))
                         .generate_state(1, np.uint64)[0] for i in range(start, stop)],
                        dtype=np.uint64)
    return _seedsequence_keys(int(seed), int(stream), np.arange(start, stop, dtype=np.uint64))


_MASK32 = 0xFFFFFFFF
_SS_POOL, _SS_INIT_A, _SS_MULT_A = 4, 0x43B0D7E5, 0x931E8875
_SS_INIT_B, _SS_MULT_B = 0x8B51F9DD, 0x58F38DED
_SS_MIX_L, _SS_MIX_R, _SS_SHIFT = 0xCA01F9DD, 0x4973F715, 16


def _uint32_words(x: int) -> list[int]:
    """Little-endian 32-bit words of a non-negative integer (0 → [0]), as NumPy coerces it."""
    if x < 0:
        raise InputError("must be >= 0", field="seed")
    words = [x & _MASK32]
    x >>= 32
    while x:
        words.append(x & _MASK32)
        x >>= 32
    return words


def _seedsequence_keys(seed: int, stream: int, index: np.ndarray) -> np.ndarray:
    """NumPy's SeedSequence(seed, spawn_key=(stream, i)).generate_state(1, uint64), for all i.

    The algorithm of ``numpy.random.SeedSequence`` (pool of 4 words, hashmix/mix with its
    constants, all arithmetic mod 2^32); the hash constants do not depend on the data, so the
    computation runs on arrays of i at once.
    """
    run = _uint32_words(seed)
    run += [0] * max(0, _SS_POOL - len(run))  # zero-padded to the pool size (spawn key given)
    entropy: list[Any] = [np.full(index.size, w, dtype=np.uint64) for w in run]
    entropy += [np.full(index.size, w, dtype=np.uint64) for w in _uint32_words(stream)]
    entropy.append(index.astype(np.uint64))
    mask = np.uint64(_MASK32)
    shift = np.uint64(_SS_SHIFT)
    hc = _SS_INIT_A

    def hashmix(value: np.ndarray) -> np.ndarray:
        nonlocal hc
        value = value ^ np.uint64(hc)
        hc = (hc * _SS_MULT_A) & _MASK32
        value = (value * np.uint64(hc)) & mask
        return value ^ (value >> shift)

    def mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        result = (np.uint64(_SS_MIX_L) * x - np.uint64(_SS_MIX_R) * y) & mask
        return result ^ (result >> shift)

    pool = [hashmix(entropy[i]) for i in range(_SS_POOL)]
    for i_src in range(_SS_POOL):
        for i_dst in range(_SS_POOL):
            if i_src != i_dst:
                pool[i_dst] = mix(pool[i_dst], hashmix(pool[i_src]))
    for i_src in range(_SS_POOL, len(entropy)):
        for i_dst in range(_SS_POOL):
            pool[i_dst] = mix(pool[i_dst], hashmix(entropy[i_src]))
    hb = _SS_INIT_B
    words = []
    for i_dst in range(2):
        val = pool[i_dst % _SS_POOL] ^ np.uint64(hb)
        hb = (hb * _SS_MULT_B) & _MASK32
        val = (val * np.uint64(hb)) & mask
        words.append(val ^ (val >> shift))
    return words[0] | (words[1] << np.uint64(32))


@njit(cache=True, inline="always")
def _next_uniform(state: np.ndarray, b: int) -> float:
    """SplitMix64 step on ``state[b]``; return a uniform double in [0, 1) (53 random bits)."""
    s = state[b] + np.uint64(0x9E3779B97F4A7C15)
    state[b] = s
    z = s
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _channel_start(kind: int, f: float, r: float, seq_len: int, offset: int, state: np.ndarray,
                   b: int) -> int:
    """Initial channel state: Markov state drawn from its stationary law, or the trace index."""
    if kind == 1:
        return 1 if _next_uniform(state, b) < r / (f + r) else 0
    if kind == 2:
        return offset % seq_len
    return 0


@njit(cache=True, inline="always")
def _channel_next(kind: int, p: float, f: float, r: float, seq: np.ndarray, ch: np.ndarray,
                  state: np.ndarray, b: int) -> bool:
    """Return γ_t of lane b and advance its channel state ``ch[b]``.

    i.i.d.: γ = 1{u < p}. Markov: γ_t is the current state; the next one is lost with
    probability f after an arrival and recovers with probability r after a loss. Trace: the
    next value, cyclically.
    """
    if kind == 0:
        return _next_uniform(state, b) < p
    if kind == 1:
        u = _next_uniform(state, b)
        if ch[b] == 1:
            ch[b] = 0 if u < f else 1
            return True
        ch[b] = 1 if u < r else 0
        return False
    g = seq[ch[b]]
    ch[b] = (ch[b] + 1) % seq.shape[0]
    return g


@njit(cache=True)
def arrival_sequence(key: np.uint64, kind: int, p: float, f: float, r: float, seq: np.ndarray,
                     offset: int, steps: int) -> np.ndarray:
    """The arrivals γ_0 … γ_{steps−1} of the path keyed ``key`` (as the kernels draw them)."""
    state = np.empty(1, dtype=np.uint64)
    state[0] = key
    ch = np.empty(1, dtype=np.int64)
    ch[0] = _channel_start(kind, f, r, seq.shape[0], offset, state, 0)
    out = np.empty(steps, dtype=np.bool_)
    for t in range(steps):
        out[t] = _channel_next(kind, p, f, r, seq, ch, state, 0)
    return out


# ---------------------------------------------------------------------------------------------
# The Riccati step (Joseph form) and the kernels
# ---------------------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _riccati_lanes(A, C, Q, R, X, g, W, out, F, FX, XC, L, AK, T, scaled, cs, ld):
    """out[:, :, b] = f_{γ_b}(X[:, :, b]) for the lanes b < W (γ_b = g[b] ∈ {0.0, 1.0}).

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
    for k in range(m):
        for l in range(k):
            for b in range(W):
                L[k, k, b] -= L[k, l, b] * L[k, l, b]
        for b in range(W):
            L[k, k, b] = math.sqrt(L[k, k, b])
        for i in range(k + 1, m):
            for l in range(k):
                for b in range(W):
                    L[i, k, b] -= L[i, l, b] * L[k, l, b]
            for b in range(W):
                L[i, k, b] = L[i, k, b] / L[k, k, b]
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
                AK[i, k, b] = AK[i, k, b] / L[k, k, b]
        for k in range(m - 1, -1, -1):
            for l in range(k + 1, m):
                for b in range(W):
                    AK[i, k, b] -= L[l, k, b] * AK[i, l, b]
            for b in range(W):
                AK[i, k, b] = AK[i, k, b] / L[k, k, b] * g[b]
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
    for i in range(n):
        for j in range(n):
            for b in range(W):
                FX[i, j, b] = 0.0
            for k in range(n):
                for b in range(W):
                    FX[i, j, b] += F[i, k, b] * X[k, j, b]
    for i in range(n):
        for j in range(i, n):
            q = Q[i, j]
            if scaled:
                for b in range(W):
                    out[i, j, b] = q * cs[b]
            else:
                for b in range(W):
                    out[i, j, b] = q
            for k in range(n):
                for b in range(W):
                    out[i, j, b] += FX[i, k, b] * F[j, k, b]
            for k in range(m):
                for b in range(W):
                    out[i, j, b] += T[i, k, b] * AK[j, k, b]
            if j > i:
                for b in range(W):
                    out[j, i, b] = out[i, j, b]


LMAX_BISECTIONS = 38
"""Bisection steps for λ_max: the bracket (⊂ [tr/n, tr]) shrinks below 3.7e-12 · tr."""


@njit(cache=True, error_model="numpy")
def _lambda_max_lanes(X, W, out, N, lo, hi, mu, d, fail):
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
def _workspace(n: int, m: int, W: int):
    """Lane arrays of one block: X, out, F, FX (n×n×W), XC, AK, T (n×m×W), L (m×m×W)."""
    return (np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, n, W)),
            np.empty((n, m, W)), np.empty((m, m, W)), np.empty((n, m, W)), np.empty((n, m, W)))


@njit(cache=True)
def _set_lane(X: np.ndarray, b: int, P0: np.ndarray) -> float:
    """X[:, :, b] = P0; return tr P0."""
    n = P0.shape[0]
    tr = 0.0
    for i in range(n):
        for j in range(n):
            X[i, j, b] = P0[i, j]
        tr += P0[i, i]
    return tr


LOAD = 1e-12
"""Relative diagonal loading of S = C X C' + c R for lanes in scaled form (see _riccati_lanes)."""
LOG_SAFE = 345.0
"""ln of ~1e150: above it, means and variances of a sample column come from log-sum-exp sums."""


@njit(cache=True)
def _lane_scale(X: np.ndarray, b: int, s: float) -> None:
    """X[:, :, b] *= s."""
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            X[i, j, b] *= s


@njit(cache=True)
def _lane_trace(X: np.ndarray, b: int) -> float:
    s = 0.0
    for i in range(X.shape[0]):
        s += X[i, i, b]
    return s


@njit(cache=True, error_model="numpy")
def _scaled_step(A, C, Q, R, P, b, g, log_scale, ws, out):
    """One step of lane b of ``P`` (tr P_b = e^``log_scale`` · tr X) in scaled form, into ``out``.

    ``ws`` is a one-lane workspace. Returns the new log scale ℓ' (tr of the new X is 1), or NaN
    when the step is not finite (a numerical failure).
    """
    n = A.shape[0]
    X1, Y1, F1, FX1, XC1, L1, AK1, T1, g1, c1, d1 = ws
    tr = _lane_trace(P, b)
    if not (tr > 0.0 and tr < math.inf):
        return math.nan
    for i in range(n):
        for j in range(n):
            X1[i, j, 0] = P[i, j, b] / tr
    ell = log_scale + math.log(tr)
    g1[0] = g
    c1[0] = math.exp(-ell)
    d1[0] = LOAD
    _riccati_lanes(A, C, Q, R, X1, g1, 1, Y1, F1, FX1, XC1, L1, AK1, T1, True, c1, d1)
    s = _lane_trace(Y1, 0)
    if not (s > 0.0 and s < math.inf):
        return math.nan
    for i in range(n):
        for j in range(n):
            out[i, j, b] = Y1[i, j, 0] / s
    return ell + math.log(s)


@njit(cache=True, error_model="numpy")
def _rre_paths(A, C, Q, R, P0, keys, offsets, kind, p, f, r, seq, t0, t1, sample_t, threshold,
               want_lmax, lanes, Xall, lg_all, sc_all, state_all, ch_all, out_tr, out_ltr,
               out_lm, out_llm, out_div, out_fail, traces):
    """Advance the paths of a batch from step ``t0`` to ``t1``; record tr P, λ_max at sample times.

    Paths run in blocks of ``lanes`` lanes (see :func:`_riccati_lanes`); a path's arithmetic
    does not depend on its block, so results do not depend on ``lanes``, the batch or the
    chunking in time. The state of every path (X, log scale, scaled flag, random and channel
    state) is kept in ``Xall`` (n×n×B), ``lg_all``, ``sc_all``, ``state_all``, ``ch_all``
    between calls (``t0 = 0`` initialises it). ``traces`` (k, steps + 1): full traces of the first
    k paths (k may be 0); ``out_ltr``/``out_llm`` hold natural logs.

    Divergence: when tr P crosses ``threshold`` the path is *not* stopped; ``out_div`` records
    the first crossing time (−1 if never) and the path continues in the scaled form
    P = e^ℓ X, tr X = 1 (f_γ(P) = e^ℓ f_γ^{(e^{−ℓ}Q, e^{−ℓ}R)}(X), then renormalised), so its
    values stay true values whatever their size; it returns to the plain form when tr P falls
    back below the threshold. A non-finite step (even in scaled form) is a numerical failure:
    ``out_fail`` records its time and the path keeps its last finite value from then on.
    """
    n = A.shape[0]
    m = C.shape[0]
    B = keys.shape[0]
    n_samples = sample_t.shape[0]
    n_traced = traces.shape[0]
    X, Y, F, FX, XC, L, AK, T = _workspace(n, m, lanes)
    ws = _workspace(n, m, 1) + (np.zeros(1), np.ones(1), np.zeros(1))
    g = np.zeros(lanes)
    state = np.empty(lanes, dtype=np.uint64)
    ch = np.empty(lanes, dtype=np.int64)
    trn = np.empty(lanes)
    lm = np.empty(lanes)
    lg = np.zeros(lanes)
    sc = np.zeros(lanes, dtype=np.int64)
    cs = np.ones(lanes)
    ld = np.zeros(lanes)
    v1, v2, v3, v4, v5 = (np.empty(lanes), np.empty(lanes), np.empty(lanes), np.empty(lanes),
                          np.empty(lanes))
    lthr = math.log(threshold)
    si0 = 0
    while si0 < n_samples and sample_t[si0] <= t0:
        si0 += 1
    for start in range(0, B, lanes):
        W = min(lanes, B - start)
        nsc = 0
        if t0 == 0:
            for b in range(W):
                state[b] = keys[start + b]
                ch[b] = _channel_start(kind, f, r, seq.shape[0], offsets[start + b], state, b)
                trn[b] = _set_lane(X, b, P0)
                lg[b] = 0.0
                sc[b] = 0
                out_div[start + b] = -1
                out_fail[start + b] = -1
                if start + b < n_traced:
                    traces[start + b, 0] = trn[b]
            if sample_t[0] == 0:
                if want_lmax:
                    _lambda_max_lanes(X, W, lm, FX, v1, v2, v3, v4, v5)
                for b in range(W):
                    out_tr[start + b, 0] = trn[b]
                    out_ltr[start + b, 0] = math.log(trn[b]) if trn[b] > 0.0 else -math.inf
                    if want_lmax:
                        out_lm[start + b, 0] = lm[b]
                        out_llm[start + b, 0] = math.log(lm[b]) if lm[b] > 0.0 else -math.inf
        else:
            for b in range(W):
                state[b] = state_all[start + b]
                ch[b] = ch_all[start + b]
                lg[b] = lg_all[start + b]
                sc[b] = sc_all[start + b]
                for i in range(n):
                    for j in range(n):
                        X[i, j, b] = Xall[i, j, start + b]
                trn[b] = _lane_trace(X, b)
        for b in range(W):
            cs[b] = math.exp(-lg[b]) if sc[b] else 1.0
            ld[b] = LOAD if sc[b] else 0.0
            nsc += sc[b]
        si = si0
        for t in range(t0, t1):
            if kind == 0:  # i.i.d.: a branch-free loop the compiler vectorises
                for b in range(W):
                    g[b] = 1.0 if _next_uniform(state, b) < p else 0.0
            else:
                for b in range(W):
                    g[b] = 1.0 if _channel_next(kind, p, f, r, seq, ch, state, b) else 0.0
            _riccati_lanes(A, C, Q, R, X, g, W, Y, F, FX, XC, L, AK, T, nsc > 0, cs, ld)
            X, Y = Y, X  # Y now holds the previous state (needed by a rescue step)
            for b in range(W):
                trn[b] = 0.0
            for i in range(n):
                for b in range(W):
                    trn[b] += X[i, i, b]
            fix = nsc > 0
            if not fix:
                for b in range(W):
                    fix |= not trn[b] <= threshold  # also catches NaN
            if fix:
                for b in range(W):
                    s = trn[b]
                    if sc[b] == 0 and s <= threshold:
                        continue
                    if sc[b] == 1 and s > 0.0 and s < math.inf:
                        ell = lg[b] + math.log(s)
                        _lane_scale(X, b, 1.0 / s)
                    elif sc[b] == 0 and s > threshold and s < math.inf:
                        ell = math.log(s)
                        _lane_scale(X, b, 1.0 / s)
                    else:  # overflow or NaN: redo the step from the previous state, scaled
                        ell = _scaled_step(A, C, Q, R, Y, b, g[b], lg[b] if sc[b] else 0.0,
                                           ws, X)
                        if not ell == ell:  # a numerical failure: keep the last finite value
                            if out_fail[start + b] < 0:
                                out_fail[start + b] = t + 1
                            for i in range(n):
                                for j in range(n):
                                    X[i, j, b] = Y[i, j, b]
                            ell = lg[b] + math.log(_lane_trace(X, b)) if sc[b] else \
                                math.log(_lane_trace(X, b))
                            if not sc[b]:  # back to its plain value
                                trn[b] = _lane_trace(X, b)
                                continue
                            _lane_scale(X, b, 1.0 / _lane_trace(X, b))
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
                        _lane_scale(X, b, math.exp(ell) / _lane_trace(X, b))
                        if sc[b] == 1:
                            sc[b] = 0
                            nsc -= 1
                        lg[b] = 0.0
                        cs[b] = 1.0
                        ld[b] = 0.0
                        trn[b] = _lane_trace(X, b)
            if start < n_traced:
                for b in range(min(W, n_traced - start)):
                    traces[start + b, t + 1] = trn[b]
            if si < n_samples and sample_t[si] == t + 1:
                if want_lmax:
                    _lambda_max_lanes(X, W, lm, FX, v1, v2, v3, v4, v5)
                for b in range(W):
                    if sc[b]:
                        out_tr[start + b, si] = trn[b]
                        out_ltr[start + b, si] = lg[b]
                        if want_lmax:
                            out_lm[start + b, si] = lm[b] * trn[b]
                            out_llm[start + b, si] = math.log(lm[b]) + lg[b]
                    else:
                        out_tr[start + b, si] = trn[b]
                        out_ltr[start + b, si] = (math.log(trn[b]) if trn[b] > 0.0
                                                  else -math.inf)
                        if want_lmax:
                            out_lm[start + b, si] = lm[b]
                            out_llm[start + b, si] = (math.log(lm[b]) if lm[b] > 0.0
                                                      else -math.inf)
                si += 1
        for b in range(W):
            state_all[start + b] = state[b]
            ch_all[start + b] = ch[b]
            lg_all[start + b] = lg[b]
            sc_all[start + b] = sc[b]
            for i in range(n):
                for j in range(n):
                    Xall[i, j, start + b] = X[i, j, b]


@njit(cache=True)
def _accumulate_log(lvalues, lmax, s1, s2):
    """Streaming log-sum-exp per column: Σ e^{x − M} and Σ e^{2(x − M)}, M the running max.

    Rows in order (bit-identical for any batch size); −inf entries (a zero trace) add nothing.
    """
    for b in range(lvalues.shape[0]):
        for s in range(lvalues.shape[1]):
            x = lvalues[b, s]
            if x == -math.inf:
                continue
            if x > lmax[s]:
                if lmax[s] > -math.inf:
                    e = math.exp(lmax[s] - x)
                    s1[s] *= e
                    s2[s] *= e * e
                lmax[s] = x
            d = math.exp(x - lmax[s])
            s1[s] += d
            s2[s] += d * d


@njit(cache=True)
def _accumulate(values, count, mean, m2):
    """Welford update of per-column mean and M2 with the rows of ``values``, in row order."""
    for b in range(values.shape[0]):
        count += 1
        for s in range(values.shape[1]):
            x = values[b, s]
            d = x - mean[s]
            mean[s] += d / count
            m2[s] += d * (x - mean[s])
    return count


@njit(cache=True, error_model="numpy")
def _ergodic_paths(A, C, Q, R, P0, keys, offsets, kind, p, f, r, seq, steps, burn_in, levels,
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
    X, Y, F, FX, XC, L, AK, T = _workspace(n, m, W)
    g = np.zeros(W)
    state = np.empty(W, dtype=np.uint64)
    ch = np.empty(W, dtype=np.int64)
    tr = np.empty(W)
    run = np.zeros(W, dtype=np.int64)
    span = max(steps - burn_in, 1)
    for b in range(W):
        state[b] = keys[b]
        ch[b] = _channel_start(kind, f, r, seq.shape[0], offsets[b], state, b)
        tr[b] = _set_lane(X, b, P0)
        div[b] = -1
    for t in range(steps):
        for b in range(W):
            arrived = _channel_next(kind, p, f, r, seq, ch, state, b)
            g[b] = 1.0 if arrived else 0.0
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
        _riccati_lanes(A, C, Q, R, X, g, W, Y, F, FX, XC, L, AK, T, False, g, g)
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
                _set_lane(X, b, P0)
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


# ---------------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------------


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True, eq=False)
class FullStateResult:
    """State x_t, prediction x̂_{t|t−1} and error e_t = x_t − x̂_{t|t−1} of a few paths.

    ``states`` and ``estimates`` have shape (paths, steps + 1, n); ``error_sq`` = |e_t|² and
    ``trace`` = tr P_t (the error covariance the filter believes, E[e_t e_t' | γ] = P_t) have
    shape (paths, steps + 1); ``arrivals`` has shape (paths, steps).
    """

    states: np.ndarray = field(repr=False)
    estimates: np.ndarray = field(repr=False)
    error_sq: np.ndarray = field(repr=False)
    trace: np.ndarray = field(repr=False)
    arrivals: np.ndarray = field(repr=False)
    seeds: tuple[tuple[int, int, int], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        ok = np.isfinite(self.error_sq) & np.isfinite(self.trace) & (self.trace > 0)
        ratio = float(np.mean(self.error_sq[ok] / self.trace[ok])) if ok.any() else None
        return {"paths": int(self.states.shape[0]), "steps": int(self.arrivals.shape[1]),
                "stream_keys": [list(s) for s in self.seeds],
                "mean_error_sq_over_trace": ratio,
                "states": _json_array(self.states), "estimates": _json_array(self.estimates),
                "error_sq": _json_array(self.error_sq), "trace": _json_array(self.trace),
                "arrivals": self.arrivals.astype(int).tolist()}


def _json_array(a: np.ndarray) -> list:
    """Nested lists with non-finite values (an overflowing unstable state) as None."""
    if np.isfinite(a).all():
        return a.tolist()
    out = a.astype(object)
    out[~np.isfinite(a)] = None
    return out.tolist()


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Result of :func:`simulate`: curves at sample times, the horizon distribution, flags.

    ``mean_trace`` etc. are indexed like ``times`` (the sample times, 0 … steps). A path that
    crosses ``divergence_threshold`` is counted as diverged (``divergence_times``, the fraction
    ``diverged_fraction`` that has crossed by each time, ``above_threshold_fraction`` that is
    above it at that time) and continued in scaled form, so every statistic is a true value.
    Values beyond float64 are ``inf`` in the plain arrays and finite in the ``log10_*`` ones
    (the record then gives None and the log10). Only a path frozen after a numerical failure
    (``failure_times``) makes later statistics approximate (``mean_is_lower_bound``).
    """

    system_name: str
    n: int
    m: int
    paths: int
    steps: int
    seed: int
    channel: dict[str, Any]
    arrival_probability: float
    times: np.ndarray = field(repr=False)
    mean_trace: np.ndarray = field(repr=False)
    std_trace: np.ndarray = field(repr=False)
    mean_lambda_max: np.ndarray | None = field(repr=False)
    std_lambda_max: np.ndarray | None = field(repr=False)
    diverged_fraction: np.ndarray = field(repr=False)
    horizon_traces: np.ndarray = field(repr=False)
    divergence_threshold: float = math.inf
    divergence_times: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    traces: np.ndarray | None = field(repr=False, default=None)
    full_state: FullStateResult | None = None
    runtime_seconds: float = 0.0
    warnings: tuple[str, ...] = ()
    log10_mean_trace: np.ndarray | None = field(repr=False, default=None)
    log10_std_trace: np.ndarray | None = field(repr=False, default=None)
    log10_mean_lambda_max: np.ndarray | None = field(repr=False, default=None)
    log10_std_lambda_max: np.ndarray | None = field(repr=False, default=None)
    horizon_log10_traces: np.ndarray | None = field(repr=False, default=None)
    above_threshold_fraction: np.ndarray | None = field(repr=False, default=None)
    failure_times: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    @property
    def diverged_paths(self) -> int:
        """Number of paths that crossed the divergence threshold (they were continued)."""
        return int(np.count_nonzero(self.divergence_times >= 0))

    @property
    def failed_paths(self) -> int:
        """Number of paths frozen after a non-finite step (normally 0)."""
        return int(np.count_nonzero(self.failure_times >= 0))

    @property
    def mean_is_lower_bound(self) -> bool:
        """True only when some path was frozen after a numerical failure.

        Paths that crossed the divergence threshold are continued in scaled form (their values
        are true values), so crossing alone never makes the means bounds.
        """
        return self.failed_paths > 0

    def _log10(self, which: str) -> tuple[np.ndarray, np.ndarray]:
        mean = self.mean_trace if which == "trace" else self.mean_lambda_max
        std = self.std_trace if which == "trace" else self.std_lambda_max
        lm = self.log10_mean_trace if which == "trace" else self.log10_mean_lambda_max
        ls = self.log10_std_trace if which == "trace" else self.log10_std_lambda_max
        with quiet_numerics():
            return (np.log10(mean) if lm is None else lm), (np.log10(std) if ls is None else ls)

    def band(self, which: str = "trace") -> tuple[np.ndarray, np.ndarray]:
        """95 % normal confidence band of the mean: mean ± 1.96 · sd / √paths, clipped at 0.

        (tr P and λ_max are non-negative, so is their mean.) Near p_c the variance may be
        infinite and the band is then only indicative. Ends beyond float64 are inf (see
        :meth:`log10_band`).
        """
        mean = self.mean_trace if which == "trace" else self.mean_lambda_max
        std = self.std_trace if which == "trace" else self.std_lambda_max
        half = Z95 * std / math.sqrt(max(self.paths, 1))
        with quiet_numerics():
            lo, hi = np.maximum(mean - half, 0.0), mean + half
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(half))):
            llo, lhi = self.log10_band(which)
            with quiet_numerics():
                bad = ~np.isfinite(lo) | ~np.isfinite(hi)
                lo = np.where(bad, 10.0 ** llo, lo)
                hi = np.where(bad, 10.0 ** lhi, hi)
        return lo, hi

    def log10_band(self, which: str = "trace") -> tuple[np.ndarray, np.ndarray]:
        """log10 of the band ends (−inf where the lower end is 0), finite where the mean
        overflows float64."""
        lm, ls = self._log10(which)
        lh = ls + math.log10(Z95 / math.sqrt(max(self.paths, 1)))
        with quiet_numerics():
            d = lh - lm                                  # log10(half / mean)
            hi = lm + np.log10(1.0 + 10.0 ** np.minimum(d, 300.0))
            hi = np.where(d > 300.0, lh, hi)
            lo = np.where(d < 0, lm + np.log10(np.maximum(-np.expm1(d * LN10), 0.0)), -np.inf)
        return lo, hi

    def horizon_quantiles(self, levels: tuple[float, ...] = QUANTILE_LEVELS) -> list[float | None]:
        """Quantiles of tr P_steps (true values; None where beyond float64: see
        :meth:`horizon_log10_quantiles`)."""
        x = np.sort(self.horizon_traces)
        out: list[float | None] = []
        for q in levels:
            v = float(np.quantile(x, q, method="inverted_cdf"))
            out.append(v if math.isfinite(v) else None)
        return out

    def horizon_log10_quantiles(self, levels: tuple[float, ...] = QUANTILE_LEVELS
                                ) -> list[float | None]:
        """log10 of the quantiles of tr P_steps (finite even where tr P overflows float64)."""
        x = self.horizon_log10_traces
        if x is None:
            with quiet_numerics():
                x = np.log10(self.horizon_traces)
        x = np.sort(x)
        return [_finite_or_none(float(np.quantile(x, q, method="inverted_cdf")))
                for q in levels]

    def exceedance(self, level: float) -> dict[str, Any]:
        """P(tr P_steps > level) with a 95 % Wilson interval."""
        k = int(np.count_nonzero(self.horizon_traces > level))
        return {"level": float(level), **_proportion(k, self.paths)}

    def cdf_points(self, points: int = DEFAULT_SAMPLES) -> dict[str, list]:
        """The empirical CDF of tr P at the horizon: points (x_(k), k/N) of the sorted traces.

        Up to ``max(points, 2000)`` paths it is the exact ECDF (every order statistic). Beyond,
        ``points`` evenly spaced ranks plus ranks spaced geometrically from both ends, so the
        minimum, the maximum and the tails (where a requirement's limit sits) keep their
        resolution. Paths at or above the divergence threshold (or not finite) are left out of
        the points: the curve then ends below 1, as they lie beyond every x drawn.
        """
        x = np.sort(self.horizon_traces)
        n = x.size
        if n == 0:
            return {"trace": [], "probability": []}
        if n <= max(points, 2000):
            ranks = np.arange(n)
        else:
            geo = np.unique(np.round(np.geomspace(1, n, 2 * points)).astype(np.int64)) - 1
            ranks = np.unique(np.concatenate([
                np.round(np.linspace(0, n - 1, points)).astype(np.int64), geo, n - 1 - geo]))
        xs, u = x[ranks], (ranks + 1) / n
        keep = xs < self.divergence_threshold
        return {"trace": xs[keep].tolist(), "probability": u[keep].tolist()}

    def to_dict(self) -> dict[str, Any]:
        lo, hi = self.band("trace")
        llm, lls = self._log10("trace")
        llo, lhi = self.log10_band("trace")
        out: dict[str, Any] = {
            "system": self.system_name, "n": self.n, "m": self.m, "paths": self.paths,
            "steps": self.steps, "seed": self.seed, "channel": self.channel,
            "arrival_probability": self.arrival_probability,
            "times": self.times.tolist(),
            "mean_trace": {"mean": _json_array(self.mean_trace), "lower": _json_array(lo),
                           "upper": _json_array(hi), "std": _json_array(self.std_trace),
                           "confidence": 0.95,
                           "overflow": bool(not np.all(np.isfinite(self.mean_trace))),
                           "log10_mean": _json_array(llm), "log10_lower": _json_array(llo),
                           "log10_upper": _json_array(lhi), "log10_std": _json_array(lls)},
            "mean_lambda_max": None,
            "horizon": {"time": self.steps, "levels": list(QUANTILE_LEVELS),
                        "quantiles": self.horizon_quantiles(),
                        "log10_quantiles": self.horizon_log10_quantiles(),
                        "mean": _finite_or_none(float(self.mean_trace[-1])),
                        "log10_mean": _finite_or_none(float(llm[-1])),
                        "cdf": self.cdf_points()},
            "divergence": {"threshold": _finite_or_none(self.divergence_threshold),
                           "diverged_paths": self.diverged_paths,
                           "first_time": (int(self.divergence_times[
                               self.divergence_times >= 0].min())
                               if self.diverged_paths else None),
                           "diverged_fraction": self.diverged_fraction.tolist(),
                           "above_threshold_fraction": (
                               None if self.above_threshold_fraction is None
                               else self.above_threshold_fraction.tolist()),
                           "continued": True,
                           "note": ("diverged = crossed the threshold at least once; such "
                                    "paths are continued in scaled form P = e^l X, so the "
                                    "statistics are true values"),
                           "failed_paths": self.failed_paths,
                           "mean_is_lower_bound": self.mean_is_lower_bound},
            "traces": None if self.traces is None else _json_array(self.traces),
            "full_state": None if self.full_state is None else self.full_state.to_dict(),
            "runtime_seconds": self.runtime_seconds,
            "warnings": list(self.warnings),
        }
        if self.mean_lambda_max is not None:
            lm_lo, lm_hi = self.band("lambda_max")
            l10, _ = self._log10("lambda_max")
            out["mean_lambda_max"] = {"mean": _json_array(self.mean_lambda_max),
                                      "lower": _json_array(lm_lo), "upper": _json_array(lm_hi),
                                      "std": _json_array(self.std_lambda_max), "confidence": 0.95,
                                      "log10_mean": _json_array(l10)}
        return out


def _proportion(k: int, n: int) -> dict[str, Any]:
    """Estimate k/n with its 95 % Wilson score interval."""
    if n == 0:
        return {"estimate": None, "lower": None, "upper": None, "count": 0, "total": 0}
    ph = k / n
    z2 = Z95 * Z95
    centre = (ph + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(ph * (1 - ph) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    lower = 0.0 if k == 0 else max(0.0, centre - half)   # exact ends (no 1e-19 round-off)
    upper = 1.0 if k == n else min(1.0, centre + half)
    return {"estimate": ph, "lower": lower, "upper": upper,
            "count": k, "total": n}


# ---------------------------------------------------------------------------------------------
# simulate()
# ---------------------------------------------------------------------------------------------


def resolve_channel(channel: Channel | None, arrival_probability: Any) -> Channel:
    """The channel to simulate: ``channel``, or Bernoulli(``arrival_probability``)."""
    if channel is not None and arrival_probability is not None:
        raise InputError("give a channel or an arrival probability, not both",
                         field="arrival_probability")
    if channel is not None:
        if not isinstance(channel, Channel):
            raise InputError(f"must be a Channel, got {type(channel).__name__}", field="channel")
        return channel
    if arrival_probability is None:
        raise InputError("a channel or an arrival probability is required", field="channel")
    return Bernoulli(exact_probability(arrival_probability, "arrival_probability"))


def sample_times(steps: int, samples: int) -> np.ndarray:
    """At most ``samples`` sample times in 0 … steps, evenly spread, always with 0 and steps."""
    if samples < 2:
        raise InputError("must be >= 2", field="horizon_samples")
    return np.unique(np.round(np.linspace(0, steps, min(samples, steps + 1))).astype(np.int64))


def _scale(system: System, P0: np.ndarray) -> float:
    """Problem scale: max(tr P0, tr Q, tr P*) (P* by scipy's DARE when it exists).

    An ill-conditioned DARE (scipy's ``LinAlgWarning``) or one without a stabilising solution
    only drops P* from the maximum; nothing is printed.
    """
    scale = max(float(np.trace(P0)), float(np.trace(system.q)), 1e-300)
    try:
        from scipy.linalg import solve_discrete_are

        with quiet_numerics():
            P = solve_discrete_are(system.a.T, system.c.T, system.q, system.r)
        if np.all(np.isfinite(P)):
            scale = max(scale, float(np.trace(P)))
    except (ValueError, np.linalg.LinAlgError):
        pass
    return scale


def _process_arrays(process: ArrivalProcess) -> tuple[int, float, float, float, np.ndarray]:
    seq = (np.ascontiguousarray(process.sequence, dtype=np.bool_)
           if process.kind == "sequence" else np.zeros(1, dtype=np.bool_))
    return (_KIND_CODE[process.kind], float(process.p), float(process.failure_rate),
            float(process.recovery_rate), seq)


def _check_sizes(paths: int, steps: int, seed: int) -> None:
    for name, v, lo in (("paths", paths, 1), ("steps", steps, 1), ("seed", seed, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise InputError(f"must be an integer >= {lo}", field=name)


def simulate(system: Any, paths: int, steps: int, seed: int, channel: Channel | None = None,
             arrival_probability: Any = None, *, record_traces: bool | int = False,
             full_state_paths: int = 0, horizon_samples: int = DEFAULT_SAMPLES,
             initial: np.ndarray | None = None, divergence_threshold: float | None = None,
             track_lambda_max: bool = True, batch_size: int = 1024,
             progress: Callable[[int, int], None] | None = None) -> SimulationResult:
    """Monte Carlo of the random Riccati equation P_{t+1} = f_{γ_t}(P_t), P_0 = Σ0.

    Parameters
    ----------
    system : System or SystemSpec
        The system (a ``SystemSpec`` also supplies its channel when none is given).
    paths, steps, seed : int
        Number of independent paths, horizon, root seed.
    channel : Channel, optional
        Arrival process (Bernoulli, Gilbert–Elliott, trace, or any model with a stationary
        arrival probability). Trace channels are read cyclically, path i from offset
        key_i mod L (key_i its 64-bit stream key, L the trace length): a path's arrivals do
        not depend on how many paths are run.
    arrival_probability : number, optional
        Shorthand for ``Bernoulli(p)``.
    record_traces : bool or int
        Keep tr P_t for every t of all paths (True) or of the first k paths (memory k·steps).
    full_state_paths : int
        Also simulate x_t, x̂_{t|t−1} for this many paths (same arrivals as paths 0 … k−1).
    horizon_samples : int
        At most this many sample times for the mean curves (memory independent of ``steps``).
    initial : array, optional
        P_0 (default Σ0 of the system).
    divergence_threshold : float, optional
        Finite and positive (default 1e10 × max(tr P0, tr Q, tr P*)). A path whose trace
        crosses it is counted as diverged and continued in scaled form (true values).
    track_lambda_max : bool
        Also estimate E[λ_max(P_t)] at the sample times.
    batch_size : int
        Paths per kernel call (results do not depend on it).
    progress : callable, optional
        Called as ``progress(path_steps_done, paths × steps)`` after every chunk of steps
        (the run is then cut into chunks of ``PROGRESS_WORK`` / n² lane-steps; the results do
        not change).

    Returns
    -------
    SimulationResult
    """
    from kfcrit.io.systemfile import SystemSpec

    t_start = time.perf_counter()
    if isinstance(system, SystemSpec):
        if channel is None and arrival_probability is None:
            channel = system.channel
        system = system.system
    if not isinstance(system, System):
        raise InputError(f"must be a System, got {type(system).__name__}", field="system")
    _check_sizes(paths, steps, seed)
    chan = resolve_channel(channel, arrival_probability)
    process = chan.arrival_process()
    kind, p, f, r, seq = _process_arrays(process)
    n, m = system.n, system.m
    A, C, Q, R = (np.ascontiguousarray(x, dtype=float) for x in
                  (system.a, system.c, system.q, system.r))
    P0 = _initial(system, initial)
    threshold = _threshold(system, P0, divergence_threshold)
    times = sample_times(steps, horizon_samples)
    S = times.size
    n_traced = paths if record_traces is True else int(record_traces or 0)
    n_traced = min(max(n_traced, 0), paths)
    if n_traced * (steps + 1) > MAX_TRACE_VALUES:
        raise InputError(f"keeping {n_traced} full traces of {steps} steps needs "
                         f"{n_traced * (steps + 1) * 8 / 1e9:.1f} GB; record fewer paths "
                         "(record_traces=k) or rely on the streaming statistics",
                         field="record_traces")
    traces = np.empty((n_traced, steps + 1))
    count_t = 0
    mean_t, m2_t = np.zeros(S), np.zeros(S)
    mean_l, m2_l = np.zeros(S), np.zeros(S)
    lsum_t = (np.full(S, -np.inf), np.zeros(S), np.zeros(S))   # (max log, Σe^{x−M}, Σe^{2(x−M)})
    lsum_l = (np.full(S, -np.inf), np.zeros(S), np.zeros(S))
    div_frac = np.zeros(S)
    above = np.zeros(S)
    lthr = math.log(threshold)
    horizon = np.empty(paths)
    horizon_log = np.empty(paths)
    div_times = np.empty(paths, dtype=np.int64)
    fail_times = np.empty(paths, dtype=np.int64)
    batch_size = max(int(batch_size), 1)
    total = paths * steps
    for start in range(0, paths, batch_size):
        stop = min(start + batch_size, paths)
        B = stop - start
        keys = path_keys(seed, start, stop)
        offsets = _trace_offsets(keys, seq.size)
        out_tr, out_lm = np.empty((B, S)), np.empty((B, S))
        out_ltr, out_llm = np.empty((B, S)), np.empty((B, S))
        out_div, out_fail = np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64)
        Xall, lg_all = np.empty((n, n, B)), np.zeros(B)
        sc_all, st_all, ch_all = (np.zeros(B, dtype=np.int64), np.zeros(B, dtype=np.uint64),
                                  np.zeros(B, dtype=np.int64))
        k_tr = max(0, min(n_traced - start, B))
        tr_view = traces[start:start + k_tr] if k_tr else np.empty((0, steps + 1))
        # in time chunks when progress is reported (the chunking does not change the numbers)
        chunk = steps if progress is None else max(1, int(PROGRESS_WORK // max(B * n * n, 1)))
        for t0 in range(0, steps, chunk):
            t1 = min(t0 + chunk, steps)
            _rre_paths(A, C, Q, R, P0, keys, offsets, kind, p, f, r, seq, t0, t1, times,
                       threshold, track_lambda_max, LANES, Xall, lg_all, sc_all, st_all, ch_all,
                       out_tr, out_ltr, out_lm, out_llm, out_div, out_fail, tr_view)
            if progress is not None:
                progress(start * steps + B * t1, total)
        c0 = count_t
        count_t = _accumulate(out_tr, c0, mean_t, m2_t)
        _accumulate_log(out_ltr, *lsum_t)
        if track_lambda_max:
            _accumulate(out_lm, c0, mean_l, m2_l)
            _accumulate_log(out_llm, *lsum_l)
        dv = out_div[out_div >= 0]
        for d in dv:
            div_frac[times >= d] += 1
        above += np.count_nonzero(out_ltr > lthr, axis=0)
        horizon[start:stop] = out_tr[:, -1]
        horizon_log[start:stop] = out_ltr[:, -1]
        div_times[start:stop] = out_div
        fail_times[start:stop] = out_fail
    mean_t, std_t, lmean_t, lstd_t = _column_stats(count_t, mean_t, m2_t, *lsum_t)
    if track_lambda_max:
        mean_l, std_l, lmean_l, lstd_l = _column_stats(count_t, mean_l, m2_l, *lsum_l)
    warnings: list[str] = []
    if process.kind == "sequence" and steps > process.sequence.size:
        warnings.append(f"the arrival trace has {process.sequence.size} values, fewer than the "
                        f"{steps} steps: it is read cyclically")
    n_div = int(np.count_nonzero(div_times >= 0))
    if n_div:
        warnings.append(f"{n_div} of {paths} paths crossed the divergence threshold tr P > "
                        f"{threshold:.3g} (diverged); they were continued in scaled form, so "
                        "the statistics are true values"
                        + ("; means too large for float64 are given as log10" if
                           not np.all(np.isfinite(mean_t)) else ""))
    n_fail = int(np.count_nonzero(fail_times >= 0))
    if n_fail:
        warnings.append(f"{n_fail} of {paths} paths had a non-finite Riccati step even in scaled "
                        "form and were frozen at their last finite value; later statistics are "
                        "approximate")
    full = (_full_state(system, A, C, Q, R, P0, seed, kind, p, f, r, seq, paths, steps,
                        min(int(full_state_paths), paths))
            if full_state_paths and full_state_paths > 0 else None)
    return SimulationResult(
        system_name=system.name, n=n, m=m, paths=paths, steps=steps, seed=int(seed),
        channel=chan.to_dict(), arrival_probability=float(chan.arrival_probability),
        times=times, mean_trace=mean_t, std_trace=std_t,
        mean_lambda_max=mean_l if track_lambda_max else None,
        std_lambda_max=std_l if track_lambda_max else None,
        diverged_fraction=div_frac / paths, horizon_traces=horizon,
        divergence_threshold=threshold, divergence_times=div_times,
        traces=traces if n_traced else None, full_state=full,
        runtime_seconds=time.perf_counter() - t_start, warnings=tuple(warnings),
        log10_mean_trace=lmean_t, log10_std_trace=lstd_t,
        log10_mean_lambda_max=lmean_l if track_lambda_max else None,
        log10_std_lambda_max=lstd_l if track_lambda_max else None,
        horizon_log10_traces=horizon_log / LN10, above_threshold_fraction=above / paths,
        failure_times=fail_times)


LN10 = math.log(10.0)


def _threshold(system: System, P0: np.ndarray, given: Any) -> float:
    """The divergence threshold: ``given`` (finite, positive) or 1e10 × the problem's scale."""
    if given is None:
        value = THRESHOLD_FACTOR * _scale(system, P0)
    else:
        if isinstance(given, bool):
            raise InputError("must be a finite positive number", field="divergence_threshold")
        try:
            value = float(given)
        except (TypeError, ValueError):
            raise InputError("must be a finite positive number",
                             field="divergence_threshold") from None
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"must be a finite positive number, got {value!r}",
                         field="divergence_threshold")
    return value


def _trace_offsets(keys: np.ndarray, length: int) -> np.ndarray:
    """Start index of each path in a trace of ``length`` values: its 64-bit key mod length.

    Derived from the path's own key, so a path's arrivals depend on (seed, i) only — not on how
    many paths are run (prefix independence). Unused for other channels.
    """
    return (keys % np.uint64(max(int(length), 1))).astype(np.int64)


def _column_stats(count: int, mean_w: np.ndarray, m2_w: np.ndarray, lmax: np.ndarray,
                  s1: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, ...]:
    """Mean, sample sd and their log10 per sample time.

    Columns whose largest value stays below e^LOG_SAFE (~1e150) use the Welford sums (the
    ordinary path, bit-identical for any batch size); larger ones use the log-sum-exp sums:
    ln mean = M + ln(Σe^{x−M}/N), ln E[x²] = 2M + ln(Σe^{2(x−M)}/N), var = N/(N−1)·(E[x²] − mean²).
    Values beyond float64 are then inf in the plain arrays and finite in the log10 ones.
    """
    N = max(count, 1)
    denom = max(count - 1, 1)
    with quiet_numerics():
        mean = mean_w.copy()
        std = np.sqrt(m2_w / denom)
        lmean = np.log10(mean)
        lstd = np.log10(std)
        big = lmax > LOG_SAFE
        if big.any():
            ln_mean = lmax[big] + np.log(s1[big] / N)
            ln_m2 = 2 * lmax[big] + np.log(s2[big] / N)
            gap = np.minimum(2 * ln_mean - ln_m2, 0.0)   # ln(mean²/E[x²]) ≤ 0
            ln_var = ln_m2 + np.log1p(-np.exp(gap)) + math.log(N / denom)
            lmean[big] = ln_mean / LN10
            lstd[big] = 0.5 * ln_var / LN10
            mean[big] = np.exp(ln_mean)
            std[big] = np.exp(0.5 * ln_var)
    return mean, std, lmean, lstd


def _initial(system: System, initial: Any) -> np.ndarray:
    if initial is None:
        return np.ascontiguousarray(system.sigma0, dtype=float)
    P0 = np.atleast_2d(np.asarray(initial, dtype=float))
    n = system.n
    if P0.shape != (n, n) or not np.all(np.isfinite(P0)):
        raise InputError(f"must be a finite {n}x{n} matrix", field="initial")
    P0 = 0.5 * (P0 + P0.T)
    if np.linalg.eigvalsh(P0).min() < -1e-12 * max(1.0, np.abs(P0).max()):
        raise InputError("must be positive semidefinite", field="initial")
    return np.ascontiguousarray(P0)


def _full_state(system: System, A, C, Q, R, P0, seed, kind, p, f, r, seq, paths, steps,
                k) -> FullStateResult:
    """x_{t+1} = A x_t + w_t, y_t = C x_t + v_t, and the intermittent Kalman filter.

    x̂_{t+1|t} = A x̂_{t|t−1} + γ_t A K_t (y_t − C x̂_{t|t−1}), K_t = P_t C' (C P_t C' + R)^{-1}, with
    P_t from the RRE; x_0 ~ N(0, P_0), x̂_{0|−1} = 0. Arrivals are those of RRE paths 0 … k−1.
    """
    n, m = A.shape[0], C.shape[0]
    keys = path_keys(seed, 0, k)
    offsets = _trace_offsets(keys, seq.size)
    Lq = _psd_sqrt(Q)
    Lr = _psd_sqrt(R)
    L0 = _psd_sqrt(P0)
    xs = np.empty((k, steps + 1, n))
    xh = np.empty((k, steps + 1, n))
    trs = np.empty((k, steps + 1))
    gam = np.empty((k, steps), dtype=bool)
    for j in range(k):
        rng = np.random.Generator(np.random.PCG64(
            np.random.SeedSequence(seed, spawn_key=(STREAM_FULL_STATE, j))))
        g = arrival_sequence(keys[j], kind, p, f, r, seq, int(offsets[j]), steps)
        gam[j] = g
        x = L0 @ rng.standard_normal(n)
        est = np.zeros(n)
        P = P0.copy()
        xs[j, 0], xh[j, 0], trs[j, 0] = x, est, np.trace(P)
        for t in range(steps):
            w = Lq @ rng.standard_normal(n)
            v = Lr @ rng.standard_normal(m)
            if g[t]:
                y = C @ x + v
                Smat = C @ P @ C.T + R
                K = np.linalg.solve(Smat, C @ P).T
                est = est + K @ (y - C @ est)
                F = np.eye(n) - K @ C
                P = F @ P @ F.T + K @ R @ K.T
            x = A @ x + w
            est = A @ est
            P = A @ P @ A.T + Q
            P = 0.5 * (P + P.T)
            xs[j, t + 1], xh[j, t + 1], trs[j, t + 1] = x, est, np.trace(P)
    err = np.sum((xs - xh) ** 2, axis=2)
    return FullStateResult(states=xs, estimates=xh, error_sq=err, trace=trs, arrivals=gam,
                           seeds=tuple((int(seed), STREAM_FULL_STATE, j) for j in range(k)))


def _psd_sqrt(M: np.ndarray) -> np.ndarray:
    """A square root L with L L' = M for a PSD matrix (eigen-decomposition, clipped at 0)."""
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


# ---------------------------------------------------------------------------------------------
# Ergodic averages along long paths (Kar–Sinopoli–Moura Prop. 25), bursts, almost-sure indicators
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ErgodicResult:
    """Time averages along ``replicas`` independent long paths (replica 0 is "the" long path).

    By Kar et al. Prop. 25, (1/T) Σ_t h(P_t) → ∫ h dμ_p a.s. for h ∈ L¹(μ_p): the time mean of
    tr P (finite iff p > p_c), its second moment and the tail P_μ(tr P > M). The batch-means
    interval treats the ``n_batches`` consecutive time batches of every replica as independent.
    """

    steps: int
    burn_in: int
    seed: int
    levels: tuple[float, ...]
    used_steps: np.ndarray = field(repr=False)
    sums: np.ndarray = field(repr=False)
    exceed: np.ndarray = field(repr=False)
    batch_sums: np.ndarray = field(repr=False)
    burst_count: np.ndarray = field(repr=False)
    burst_trace: np.ndarray = field(repr=False)
    block_max: np.ndarray = field(repr=False)
    block_min: np.ndarray = field(repr=False)
    divergence_times: np.ndarray = field(repr=False)
    losses: np.ndarray = field(repr=False)
    longest: np.ndarray = field(repr=False)
    observed_steps: np.ndarray = field(repr=False)
    expected_mean_burst: float | None = None
    divergence_threshold: float = math.inf

    @property
    def replicas(self) -> int:
        return int(self.sums.shape[0])

    def time_mean(self) -> np.ndarray:
        """(1/T) Σ tr P_t per replica (NaN where nothing was averaged)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sums[:, 0] / self.used_steps

    def pooled(self) -> dict[str, Any]:
        """Pooled time mean over all replicas with a 95 % batch-means interval."""
        ok = (self.divergence_times < 0) & (self.used_steps > 0)
        if not ok.any():
            return {"mean": None, "lower": None, "upper": None, "batches": 0}
        nb = self.batch_sums.shape[1]
        per_batch = self.used_steps[ok, None] / nb
        bm = (self.batch_sums[ok] / per_batch).ravel()
        mean = float(self.sums[ok, 0].sum() / self.used_steps[ok].sum())
        half = Z95 * float(bm.std(ddof=1)) / math.sqrt(bm.size) if bm.size > 1 else math.inf
        return {"mean": mean, "lower": _finite_or_none(mean - half),
                "upper": _finite_or_none(mean + half), "batches": int(bm.size)}

    def tail_probabilities(self) -> list[dict[str, Any]]:
        """P_μ(tr P > M) for every level, pooled over the replicas that never crossed the
        divergence threshold (a crossed path's counts stop at the crossing)."""
        ok = (self.divergence_times < 0) & (self.used_steps > 0)
        total = int(self.used_steps[ok].sum())
        out = []
        for q, lv in enumerate(self.levels):
            k = int(self.exceed[ok, q].sum())
            out.append({"level": float(lv), "probability": k / total if total else None,
                        "count": k, "steps": total, "replicas": int(ok.sum())})
        return out

    def to_dict(self) -> dict[str, Any]:
        used = self.used_steps
        tm = self.time_mean()
        with np.errstate(invalid="ignore", divide="ignore"):
            second = self.sums[:, 1] / used
            tails = self.exceed / used[:, None]
        diverged = self.divergence_times >= 0
        path0 = {"mean_trace": None if diverged[0] else _finite_or_none(tm[0]),
                 "second_moment": None if diverged[0] else _finite_or_none(second[0]),
                 "tail": [{"level": float(lv), "probability": _finite_or_none(tails[0, q])}
                          for q, lv in enumerate(self.levels)],
                 "diverged": bool(diverged[0])}
        counts = self.burst_count.sum(axis=0)
        trace_sum = self.burst_trace.sum(axis=0)
        lengths = np.arange(counts.size)
        total_bursts = int(counts[1:].sum())
        mean_burst = (float(self.losses.sum() / total_bursts) if total_bursts else None)
        obs = int(self.observed_steps.sum())
        top = int(np.flatnonzero(counts)[-1]) if counts[1:].any() else 0
        bursts = {
            "loss_fraction": float(self.losses.sum() / obs) if obs else None,
            "bursts": total_bursts, "mean_length": mean_burst,
            "expected_mean_length": self.expected_mean_burst,
            "longest": int(self.longest.max()) if self.longest.size else 0,
            "length": lengths[1:top + 1].tolist(),
            "count": counts[1:top + 1].astype(int).tolist(),
            "last_bin": counts.size - 1, "last_bin_collects_longer": True,
            "mean_trace_after": [(float(trace_sum[j] / counts[j]) if counts[j] else None)
                                 for j in range(1, top + 1)],
        }
        k_full = int(math.floor(math.log2(self.steps + 1)))  # blocks [2^k, 2^{k+1}) inside 1..steps
        bmax = self.block_max[0, :k_full]
        bmin = self.block_min[0, :k_full]
        valid = np.isfinite(bmax) & np.isfinite(bmin)
        almost = {
            "block_start": [int(2 ** k) for k in range(k_full)],
            "block_max": [float(x) if v else None for x, v in zip(bmax, valid, strict=True)],
            "block_min": [float(x) if v else None for x, v in zip(bmin, valid, strict=True)],
            "running_max": _finite_or_none(float(np.nanmax(np.where(valid, bmax, np.nan))))
            if valid.any() else None,
            "last_block_min": float(bmin[valid][-1]) if valid.any() else None,
            "last_block_max": float(bmax[valid][-1]) if valid.any() else None,
            "note": ("block k covers t in [2^k, 2^(k+1)) of replica 0; growing block maxima "
                     "indicate limsup tr P = inf (upper a.s. unstable), bounded block minima "
                     "indicate liminf tr P < inf (lower a.s. stable), MATH.md section 6"),
        }
        return {
            "steps": self.steps, "burn_in": self.burn_in, "replicas": self.replicas,
            "seed": self.seed,
            "streams": [[self.seed, STREAM_ERGODIC, j] for j in range(self.replicas)],
            "time_averages": {"path": path0, "pooled_mean_trace": self.pooled(),
                              "pooled_tail": self.tail_probabilities(),
                              "replica_mean_trace": [None if d else _finite_or_none(x)
                                                     for x, d in zip(tm, diverged, strict=True)],
                              "used_steps": used.astype(int).tolist()},
            "bursts": bursts, "almost_sure": almost,
            "divergence": {"threshold": _finite_or_none(self.divergence_threshold),
                           "diverged_replicas": int(diverged.sum()),
                           "times": [int(t) if t >= 0 else None
                                     for t in self.divergence_times]},
        }


def ergodic(system: Any, steps: int, seed: int, channel: Channel | None = None,
            arrival_probability: Any = None, *, replicas: int = 4, burn_in: int | None = None,
            levels: tuple[float, ...] | list[float] = (), max_burst: int = 32,
            n_batches: int = 20, initial: np.ndarray | None = None,
            divergence_threshold: float | None = None) -> ErgodicResult:
    """Time averages of tr P along ``replicas`` long paths (streams ``spawn_key=(2, j)``).

    Parameters
    ----------
    steps : int
        Length of each path.
    burn_in : int, optional
        Steps discarded before averaging (default steps // 10).
    levels : sequence of float
        Levels M of the tail estimates (1/T) #{t : tr P_t > M}.
    max_burst : int
        Loss-burst histogram bins 1 … max_burst (the last collects longer bursts).
    """
    from kfcrit.io.systemfile import SystemSpec

    if isinstance(system, SystemSpec):
        if channel is None and arrival_probability is None:
            channel = system.channel
        system = system.system
    _check_sizes(replicas, steps, seed)
    chan = resolve_channel(channel, arrival_probability)
    process = chan.arrival_process()
    kind, p, f, r, seq = _process_arrays(process)
    A, C, Q, R = (np.ascontiguousarray(x, dtype=float) for x in
                  (system.a, system.c, system.q, system.r))
    P0 = _initial(system, initial)
    threshold = _threshold(system, P0, divergence_threshold)
    burn = steps // 10 if burn_in is None else int(burn_in)
    if not 0 <= burn < steps:
        raise InputError("must be in [0, steps)", field="burn_in")
    lv = np.asarray(sorted(float(x) for x in levels), dtype=float)
    keys = path_keys(seed, 0, replicas, STREAM_ERGODIC)
    K = int(math.log2(steps)) + 1
    sums = np.zeros((replicas, 2))
    exceed = np.zeros((replicas, lv.size))
    batch_sums = np.zeros((replicas, n_batches))
    burst_count = np.zeros((replicas, max_burst + 1))
    burst_trace = np.zeros((replicas, max_burst + 1))
    block_max = np.full((replicas, K), -np.inf)
    block_min = np.full((replicas, K), np.inf)
    div = np.empty(replicas, dtype=np.int64)
    losses = np.zeros(replicas, dtype=np.int64)
    longest = np.zeros(replicas, dtype=np.int64)
    _ergodic_paths(A, C, Q, R, P0, keys, _trace_offsets(keys, seq.size), kind, p, f, r, seq,
                   steps, burn, lv, max_burst,
                   n_batches, threshold, sums, exceed, batch_sums, burst_count, burst_trace,
                   block_max, block_min, div, losses, longest)
    end = np.where(div >= 0, div - 1, steps)
    used = np.maximum(end - burn, 0).astype(float)
    expected = None
    if process.kind == "markov":
        expected = 1.0 / process.recovery_rate
    elif process.kind == "iid" and process.p > 0:
        expected = 1.0 / process.p
    return ErgodicResult(steps=steps, burn_in=burn, seed=int(seed), levels=tuple(lv.tolist()),
                         used_steps=used, sums=sums, exceed=exceed, batch_sums=batch_sums,
                         burst_count=burst_count, burst_trace=burst_trace, block_max=block_max,
                         block_min=block_min, divergence_times=div, losses=losses,
                         longest=longest, observed_steps=used.copy(),
                         expected_mean_burst=expected, divergence_threshold=threshold)


# ---------------------------------------------------------------------------------------------
# The simulation section of the analysis record
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Budget:
    """Sizes of the simulations of one analysis (scaled down for large n)."""

    paths: int
    steps: int
    ergodic_steps: int
    replicas: int
    demo_paths: int
    demo_steps: int

    @classmethod
    def for_system(cls, n: int, quick: bool) -> Budget:
        base = (cls(300, 200, 10_000, 4, 200, 150) if quick
                else cls(2000, 500, 50_000, 4, 500, 300))
        factor = max(1.0, (n / 6.0) ** 3)
        if factor == 1.0:
            return base
        return cls(max(50, int(base.paths / factor)), base.steps,
                   max(2000, int(base.ergodic_steps / factor)), base.replicas,
                   max(30, int(base.demo_paths / factor)), base.demo_steps)


def phase_probabilities(reference: float) -> list[tuple[str, float]]:
    """Arrival probabilities around ``reference``: p ∓ 0.5·d and p ∓ 0.2·d, d = min(p, 1 − p)."""
    d = min(reference, 1.0 - reference)
    out = [("below", reference - 0.5 * d), ("below", reference - 0.2 * d),
           ("above", reference + 0.2 * d), ("above", reference + 0.5 * d)]
    return [(side, float(p)) for side, p in out if 0.0 < p < 1.0]


def simulation_section(spec: Any, *, critical_value: float | None, upper_bound: float | None,
                       seed: int, quick: bool) -> dict[str, Any]:
    """The ``simulation`` section of the analysis record.

    Keys: ``seed``, ``quick``, ``budget``, ``seeds``, ``operating_point`` (None without a
    channel), ``phase_demo`` (None when the reference value is unknown or 0),
    ``runtime_seconds``, ``warnings``. See the module docstring for the streams.
    """
    from kfcrit.io.systemfile import SystemSpec

    t0 = time.perf_counter()
    if not isinstance(spec, SystemSpec):
        spec = SystemSpec(system=spec)
    system = spec.system
    budget = Budget.for_system(system.n, quick)
    warnings: list[str] = []
    out: dict[str, Any] = {"seed": int(seed), "quick": bool(quick),
                           "budget": dict(budget.__dict__), "seeds": {},
                           "operating_point": None, "phase_demo": None}
    checks: list[dict[str, Any]] = []
    with quiet_numerics():
        _simulation_parts(spec, system, budget, seed, critical_value, upper_bound, out,
                          warnings, checks)
    out["checks"] = checks
    out["runtime_seconds"] = time.perf_counter() - t0
    out["warnings"] = warnings
    return out


def _simulation_parts(spec: Any, system: System, budget: Budget, seed: int,
                      critical_value: float | None, upper_bound: float | None,
                      out: dict[str, Any], warnings: list[str],
                      checks: list[dict[str, Any]]) -> None:
    if spec.channel is not None:
        out["operating_point"] = _operating_point(spec, budget, seed, warnings, checks)
        out["seeds"]["operating_point"] = {
            "seed": int(seed), "paths": "SeedSequence(seed, spawn_key=(0, i))",
            "ergodic": "SeedSequence(seed, spawn_key=(2, j))"}
    out["phase_demo"] = _phase_demo(system, critical_value, upper_bound, budget, seed, warnings)
    if out["phase_demo"] is not None:
        out["seeds"]["phase_demo"] = [c["seed"] for c in out["phase_demo"]["curves"]]


def _operating_point(spec: Any, budget: Budget, seed: int, warnings: list[str],
                     checks: list[dict[str, Any]]) -> dict:
    system, chan = spec.system, spec.channel
    samples = DEFAULT_SAMPLES if system.n <= 10 else 50  # λ_max costs ~n³ per sample
    res = simulate(system, budget.paths, budget.steps, seed, chan, horizon_samples=samples)
    level = spec.requirements.max_error_trace
    erg = ergodic(system, budget.ergodic_steps, seed, chan, replicas=budget.replicas,
                  levels=(level,) if level is not None else ())
    d = res.to_dict()
    e = erg.to_dict()
    warnings.extend(d["warnings"])
    if e["divergence"]["diverged_replicas"]:
        warnings.append(f"{e['divergence']['diverged_replicas']} of {erg.replicas} long paths "
                        "exceeded the divergence threshold (time averages stop there)")
    regime = tail_regime(system, chan, res.steps)
    found = simulation_checks(system, chan, res, erg, regime)
    for c in found:
        if c.get("status") == "inconclusive":
            warnings.append(f"Monte Carlo check inconclusive: {c['check']} ({c['reason']})")
    checks.extend(found)
    return {
        "channel": d["channel"], "arrival_probability": d["arrival_probability"],
        "iid": bool(chan.iid), "paths": res.paths, "steps": res.steps, "seed": res.seed,
        "times": d["times"], "mean_trace": d["mean_trace"],
        "mean_lambda_max": d["mean_lambda_max"], "horizon": d["horizon"],
        "exceedance": res.exceedance(level) if level is not None else None,
        "ergodic": {k: e[k] for k in ("steps", "burn_in", "replicas", "seed", "streams",
                                      "time_averages", "divergence")},
        "bursts": e["bursts"], "almost_sure": e["almost_sure"],
        "divergence": d["divergence"], "runtime_seconds": res.runtime_seconds,
        "reliability": regime,
    }


def tail_regime(system: System, channel: Channel, steps: int) -> dict[str, Any]:
    """How far sample means of tr P_t can be trusted at this operating point.

    * ``heavy_tailed``: a loss burst of length k has probability ∝ q^k (q = 1 − p for i.i.d.
      losses, q = 1 − r for Gilbert–Elliott) and multiplies P by about ρ(A)^{2k}, so
      E[(tr P)²] ≥ c Σ_k (q ρ⁴)^k: when q ρ(A)⁴ ≥ 1 the variance of tr P diverges (Mo–Sinopoli
      Cor. 2 with exponent 2 gives the same threshold for non-degenerate systems). The sample
      standard deviation then underestimates the spread, the ±5 se tolerance is no test, and
      the sample mean sits below the true mean most of the time. This happens for every p just
      above p_c (q ρ² < 1 ≤ q ρ⁴). ``None`` for a measured trace (no model).
    * ``settled``: tr S_T ≥ 0.95 tr S̄ for the Lyapunov recursion S_{t+1} = (1 − p) A S_t A' + Q
      from Σ0 (i.i.d. only): near p_c, (1 − p) ρ² → 1 and the mean needs far more than the
      horizon T to approach its limit, so limit bounds say nothing about E[tr P_T] yet.
    """
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    proc = channel.arrival_process()
    if proc.kind == "iid":
        q, basis = 1.0 - float(proc.p), "(1 - p) rho(A)^4"
    elif proc.kind == "markov":
        q, basis = 1.0 - float(proc.recovery_rate), "(1 - r) rho(A)^4"
    else:
        q, basis = None, None
    with quiet_numerics():
        # numpy power: ρ⁴ beyond float64 is inf (the heavy tail is then certain), not an error
        value = None if q is None else float(q * np.float64(rho) ** 4)
    out: dict[str, Any] = {
        "variance_condition": basis,
        "variance_value": _finite_or_none(value) if value is not None else None,
        "heavy_tailed": None if value is None else bool(not value < 1),
        "lyapunov_trace_at_horizon": None, "lyapunov_trace_limit": None, "settled": None}
    if proc.kind == "iid" and q * rho * rho < 1:
        from kfcrit.theory.bounds import lower_covariance

        S_T = _lyapunov_traces(system, 1.0 - q, np.array([steps]))[0]
        with quiet_numerics():
            Sbar = lower_covariance(system.a, system.q, 1.0 - q)
        lim = float(np.trace(Sbar)) if Sbar is not None else None
        if S_T is not None and lim is not None and math.isfinite(lim):
            out.update(lyapunov_trace_at_horizon=S_T, lyapunov_trace_limit=lim,
                       settled=bool(S_T >= 0.95 * lim))
    return out


def _lyapunov_traces(system: System, p: float, times: np.ndarray) -> list[float | None]:
    """tr S_t at the given (sorted) times, S_{t+1} = (1 − p) A S_t A' + Q, S_0 = Σ0.

    Overflow is handled explicitly: once S_t is no longer finite the remaining entries are
    None (the caller then has no lower bound to compare with).
    """
    A, Q = system.a, system.q
    S = _initial(system, None)
    out: list[float | None] = []
    k, last = 0, int(times[-1]) if times.size else -1
    with quiet_numerics():
        for t in range(last + 1):
            while k < times.size and times[k] == t:
                tr = float(np.trace(S))
                out.append(tr if math.isfinite(tr) else None)
                k += 1
            if not np.all(np.isfinite(S)):
                out.extend([None] * (times.size - len(out)))
                break
            S = (1 - p) * A @ S @ A.T + Q
    return out


def _check(check: str, passed: bool | None, detail: str, *, reason: str | None = None,
           status: str | None = None) -> dict[str, Any]:
    """One verification entry; ``status`` is passed / failed / inconclusive / not applicable."""
    st = status or {True: "passed", False: "failed", None: "not applicable"}[passed]
    out = {"check": check, "passed": passed, "status": st, "detail": detail}
    if reason:
        out["reason"] = reason
    return out


def simulation_checks(system: System, channel: Channel, res: SimulationResult,
                      erg: ErgodicResult, regime: dict[str, Any] | None = None
                      ) -> list[dict[str, Any]]:
    """Self-checks of the operating-point simulation: ``{check, passed, status, detail}``.

    * every statistic is finite (divergence is flagged, never NaN/inf);
    * the mean loss-burst length matches the channel (1/r Gilbert–Elliott, 1/p i.i.d.) within
      5 standard errors of a geometric law (variance (1 − q)/q²);
    * i.i.d. channels with (1 − p) ρ(A)² < 1: E[tr P_t] ≥ tr S_t − 5 se at every sample time,
      S_{t+1} = (1 − p) A S_t A' + Q, S_0 = Σ0 (Sinopoli Lemma 1(f), by induction).

    A statistical check that misses its tolerance where the tolerance is not valid — heavy
    tails (see :func:`tail_regime`: just above p_c the variance of tr P is infinite) or paths
    censored at the divergence threshold (the means are then lower bounds) — is
    ``inconclusive`` (``passed`` None, with the reason), not failed: near p_c the simulated mean
    need not settle within any affordable horizon.
    """
    regime = regime if regime is not None else tail_regime(system, channel, res.steps)
    out: list[dict[str, Any]] = []
    # plain values may exceed float64 (then inf, with a finite log10 beside them); never NaN
    plain = [res.mean_trace, res.std_trace, res.horizon_traces]
    logs = [a for a in (res.log10_mean_trace, res.horizon_log10_traces) if a is not None]
    ok = (all(not np.isnan(a).any() for a in plain) and all(np.isfinite(a).all() for a in logs)
          and all(np.isfinite(a).all() for a in (erg.sums, erg.burst_trace)))
    out.append(_check("simulation: all statistics finite or given as log10 (divergence "
                      "flagged, not propagated)", bool(ok),
                      f"{res.diverged_paths} of {res.paths} paths crossed the divergence "
                      "threshold (continued in scaled form)"))
    bursts = int(erg.burst_count[:, 1:].sum())
    if erg.expected_mean_burst is not None and bursts >= 30:
        q = 1.0 / erg.expected_mean_burst
        mean = float(erg.losses.sum() / bursts)
        se = math.sqrt((1 - q) / (q * q) / bursts)
        out.append(_check("simulation: mean loss-burst length matches the channel",
                          bool(abs(mean - erg.expected_mean_burst) <= 5 * se + 1e-12),
                          f"{mean:.4g} vs {erg.expected_mean_burst:.4g} "
                          f"(5 se = {5 * se:.2g}, {bursts} bursts)"))
    p = float(channel.arrival_probability)
    rho = float(max(abs(np.linalg.eigvals(system.a))))
    if channel.iid and (1 - p) * rho * rho < 1:
        name = "simulation: E[tr P_t] >= Lyapunov lower bound tr S_t (Lemma 1)"
        lower = _lyapunov_traces(system, p, res.times)
        later = [k for k in range(res.times.size) if res.times[k] > 0]  # t = 0: equal
        if any(lower[k] is None for k in later):
            out.append(_check(name, None, "the Lyapunov recursion overflowed float64",
                              reason="tr S_t is not representable", status="inconclusive"))
            return out
        lo = np.array([lower[k] for k in later], dtype=float)
        se = res.std_trace[later] / math.sqrt(res.paths)
        with quiet_numerics():
            z = (res.mean_trace[later] - lo) / np.maximum(se, 1e-300)
        zmin = float(np.min(z)) if z.size else 0.0
        detail = (f"min over t of (mean − bound)/se = {max(min(zmin, 1e6), -1e6):.3g} "
                  "(>= −5 required)")
        if zmin >= -5:
            out.append(_check(name, True, detail))
        elif regime.get("heavy_tailed") or res.failed_paths:
            why = (f"{res.failed_paths} paths were frozen after a numerical failure, so "
                   "the simulated means are approximate" if res.failed_paths else
                   f"{regime['variance_condition']} = {regime['variance_value']:.4g} >= 1: the "
                   "variance of tr P diverges (heavy tails just above p_c), so the sample mean "
                   "and its standard error are unreliable at this horizon")
            out.append(_check(name, None, detail, reason=why, status="inconclusive"))
        else:
            out.append(_check(name, False, detail))
    return out


def _phase_demo(system: System, critical_value: float | None, upper_bound: float | None,
                budget: Budget, seed: int, warnings: list[str]) -> dict | None:
    if critical_value is not None:
        ref, source = float(critical_value), "critical_value"
    elif upper_bound is not None:
        ref, source = float(upper_bound), "upper_bound"
    else:
        return None
    if not 0.0 < ref < 1.0:
        return None
    curves = []
    for k, (side, p) in enumerate(phase_probabilities(ref)):
        s = int(seed) + 1 + k
        res = simulate(system, budget.demo_paths, budget.demo_steps, s, arrival_probability=p,
                       track_lambda_max=False, horizon_samples=100)
        lo, hi = res.band()
        curves.append({"arrival_probability": p, "side": side, "seed": s,
                       "times": res.times.tolist(), "mean_trace": res.mean_trace.tolist(),
                       "lower": lo.tolist(), "upper": hi.tolist(),
                       "diverged_fraction": res.diverged_fraction.tolist(),
                       "mean_is_lower_bound": res.mean_is_lower_bound})
    return {"reference_value": ref, "reference": source, "paths": budget.demo_paths,
            "steps": budget.demo_steps, "curves": curves}


# ---------------------------------------------------------------------------------------------
# Command line: kfcrit simulate
# ---------------------------------------------------------------------------------------------


def simulate_command(system_file: str, *, paths: int, steps: int, seed: int, as_json: bool,
                     plot: str | None, max_states: int, ergodic_steps: int | None = None,
                     tail: tuple[float, ...] | list[float] = ()) -> int:
    """Run the ``kfcrit simulate`` subcommand; return the exit code.

    Data (the summary or ``--json``) goes to stdout; a progress bar goes to stderr only when it
    is a terminal; ``--plot`` writes an SVG or PNG atomically. With ``ergodic_steps`` (or any
    ``tail`` level, default length max(10 · steps, 10 000)) the time averages along
    ``ERGODIC_REPLICAS`` long paths (Kar et al. Prop. 25, :func:`ergodic`) are added: time mean
    of tr P, tail probabilities (1/T) #{t : tr P_t > M} for every level M (and the system
    file's ``max_error_trace``), loss bursts and the almost-sure indicators; under ``ergodic``
    in ``--json``.
    """
    from kfcrit.io.jsonio import dumps
    from kfcrit.io.systemfile import load_spec

    _check_sizes(paths, steps, seed)
    levels = [_tail_level(x) for x in tail]
    if ergodic_steps is not None:
        if (isinstance(ergodic_steps, bool) or not isinstance(ergodic_steps, (int, np.integer))
                or ergodic_steps < 1):
            raise InputError("must be an integer >= 1", field="--ergodic-steps")
    elif levels:
        ergodic_steps = max(10 * steps, 10_000)
    if plot is not None:
        if Path(plot).suffix.lower() not in (".svg", ".png"):
            raise InputError("must end in .svg or .png", field="--plot")
        if not Path(plot).resolve().parent.is_dir():
            raise InputError(f"folder {str(Path(plot).resolve().parent)[:80]!r} does not exist",
                             field="--plot")
    spec = load_spec(system_file, max_states=max_states)
    if spec.channel is None:
        raise InputError("the system file has no channel (add channel: {model: bernoulli, "
                         "arrival_probability: ...})", field="channel")
    keep = min(paths, 5) if plot is not None and steps <= 1_000_000 else False
    if sys.stderr.isatty() and paths * steps * spec.system.n ** 2 > 5e7:
        result = _with_progress(spec, paths, steps, seed, keep)
    else:
        result = simulate(spec.system, paths, steps, seed, spec.channel, record_traces=keep)
    erg = None
    if ergodic_steps is not None:
        req = spec.requirements.max_error_trace
        lv = sorted(set(levels + ([float(req)] if req is not None else [])))
        erg = ergodic(spec.system, int(ergodic_steps), seed, spec.channel,
                      replicas=ERGODIC_REPLICAS, levels=lv)
    if as_json:
        record = result.to_dict()
        record["ergodic"] = None if erg is None else erg.to_dict()
        print(dumps(record))
    else:
        text = summary_text(result, spec.requirements.max_error_trace)
        if erg is not None:
            text += "\n" + ergodic_text(erg)
        print(text)
    if plot is not None:
        write_plot(result, plot)
    return 0


ERGODIC_REPLICAS = 4
"""Independent long paths of ``kfcrit simulate --ergodic-steps`` (replica 0 is "the" path)."""


def _tail_level(x: Any) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {str(x)[:40]!r}", field="--tail") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"must be a finite positive level, got {v!r}", field="--tail")
    return v


def ergodic_text(erg: ErgodicResult) -> str:
    """Terminal lines for the ergodic time averages (``kfcrit simulate --ergodic-steps``)."""
    d = erg.to_dict()
    ta = d["time_averages"]
    pooled = ta["pooled_mean_trace"]
    lines = [f"ergodic averages: {erg.replicas} paths x {erg.steps} steps, burn-in "
             f"{erg.burn_in}, streams SeedSequence({erg.seed}, spawn_key=(2, j))"]
    if pooled["mean"] is not None:
        lines.append(f"time average of tr P: {pooled['mean']:.6g} (95% batch-means interval "
                     f"{_fmt(pooled['lower'])} .. {_fmt(pooled['upper'])})")
    else:
        lines.append("time average of tr P: none (every long path crossed the divergence "
                     "threshold)")
    for t in erg.tail_probabilities():
        lines.append(f"P(tr P > {t['level']:g}) by time average: {_fmt(t['probability'])} "
                     f"({t['count']} of {t['steps']} path-steps of {t['replicas']} long paths "
                     "that stayed below the divergence threshold; steps are correlated, no "
                     "interval)")
    div = d["divergence"]
    if div["diverged_replicas"]:
        lines.append(f"warning: {div['diverged_replicas']} of {erg.replicas} long paths crossed "
                     f"tr P > {erg.divergence_threshold:.3g}; their averages stop there (the "
                     "mean of the invariant law is infinite below p_c)")
    b = d["bursts"]
    if b["mean_length"] is not None:
        lines.append(f"loss bursts: mean length {b['mean_length']:.4g} (channel "
                     f"{_fmt(b['expected_mean_length'])}), longest {b['longest']}")
    return "\n".join(lines)


def _with_progress(spec: Any, paths: int, steps: int, seed: int,
                   keep: int | bool) -> SimulationResult:
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("simulating", total=paths * steps)
        return simulate(spec.system, paths, steps, seed, spec.channel, record_traces=keep,
                        progress=lambda done, total: bar.update(task, completed=done))


def _fmt(x: float | None) -> str:
    return "—" if x is None else f"{x:.4g}"


def summary_text(result: SimulationResult, level: float | None = None) -> str:
    """A readable summary of a simulation (the default output of ``kfcrit simulate``)."""
    lo, hi = result.band()
    q = dict(zip(QUANTILE_LEVELS, result.horizon_quantiles(), strict=True))
    lines = [
        f"{result.system_name}: {result.paths} paths x {result.steps} steps, seed {result.seed}",
        f"channel: {result.channel.get('model')}, arrival probability "
        f"{result.arrival_probability:.6g}",
        f"E[tr P_t] at t = {result.steps}: {result.mean_trace[-1]:.6g} "
        f"(95% CI {lo[-1]:.6g} .. {hi[-1]:.6g})"
        + (" [approximate: paths frozen after a numerical failure]"
           if result.mean_is_lower_bound else ""),
    ]
    if not math.isfinite(result.mean_trace[-1]):
        llo, lhi = result.log10_band()
        low = "0" if not math.isfinite(llo[-1]) else f"10^{llo[-1]:.4g}"
        lines[-1] = (f"E[tr P_t] at t = {result.steps}: 10^{result.log10_mean_trace[-1]:.6g} "
                     f"(95% CI {low} .. 10^{lhi[-1]:.4g}; beyond float64, shown as powers of "
                     "ten)")
    if result.mean_lambda_max is not None:
        v = result.mean_lambda_max[-1]
        text = (f"{v:.6g}" if math.isfinite(v) or result.log10_mean_lambda_max is None
                else f"10^{result.log10_mean_lambda_max[-1]:.6g}")
        lines.append(f"E[lambda_max P_t] at t = {result.steps}: {text}")
    lq = dict(zip(QUANTILE_LEVELS, result.horizon_log10_quantiles(), strict=True))
    lines.append("tr P at the horizon: " + ", ".join(
        f"q{int(round(100 * k))} "
        + (_fmt(q[k]) if q[k] is not None or lq[k] is None else f"10^{lq[k]:.5g}")
        for k in (0.05, 0.5, 0.95, 0.99)))
    if level is not None:
        e = result.exceedance(level)
        lines.append(f"P(tr P > {level:g}) at the horizon: {e['estimate']:.4g} "
                     f"(95% CI {e['lower']:.4g} .. {e['upper']:.4g})")
    lines.append(f"diverged paths: {result.diverged_paths} (crossed tr P > "
                 f"{result.divergence_threshold:.3g}; continued in scaled form)")
    lines.extend(f"warning: {w}" for w in result.warnings)
    lines.append(f"runtime: {result.runtime_seconds:.2f} s")
    return "\n".join(lines)


BAND_FLOOR = 0.1
"""On the log axis the lower band end is floored at this fraction of the smallest positive
mean (a lower end at 0 — a confidence interval reaching 0 — cannot be drawn on a log axis)."""


def plot_series(result: SimulationResult) -> dict[str, Any]:
    """What :func:`write_plot` draws on its left panel, in plot units.

    ``log10`` False: values on a log axis — mean, band with its lower end floored at
    ``BAND_FLOOR`` × the smallest positive mean, traces, and y-limits from these data only.
    ``log10`` True (some value beyond float64): the same in log10 units on a linear axis.
    """
    t = result.times.astype(float)
    mean = result.mean_trace
    lo, hi = result.band()
    traces = result.traces
    finite = bool(np.all(np.isfinite(mean)) and np.all(np.isfinite(hi))
                  and (traces is None or np.all(np.isfinite(traces))))
    if finite:
        pos = mean[mean > 0]
        floor = BAND_FLOOR * float(pos.min()) if pos.size else 1.0
        y, y_lo, y_hi = mean.astype(float), np.maximum(lo, floor), np.maximum(hi, floor)
        tr = None if traces is None else np.where(traces > 0, traces, np.nan)
        data = [y[y > 0], y_lo, y_hi] + ([] if tr is None else [tr[np.isfinite(tr)]])
        bottom = min(float(np.min(d)) for d in data if d.size)
        top = max(float(np.max(d)) for d in data if d.size)
        bottom, top = bottom / 1.5, top * 1.5
        thr = result.divergence_threshold
    else:
        llo, lhi = result.log10_band()
        y = result.log10_mean_trace if result.log10_mean_trace is not None else np.log10(mean)
        ok = np.isfinite(y)
        low = float(np.min(y[ok])) if ok.any() else 0.0
        floor = low + math.log10(BAND_FLOOR)
        y_lo, y_hi = np.maximum(llo, floor), np.maximum(lhi, floor)
        tr = None
        if traces is not None:
            with quiet_numerics():
                tr = np.where(np.isfinite(traces) & (traces > 0), np.log10(traces), np.nan)
        data = [y[ok], y_lo[np.isfinite(y_lo)], y_hi[np.isfinite(y_hi)]]
        if tr is not None:
            data.append(tr[np.isfinite(tr)])
        bottom = min(float(np.min(d)) for d in data if d.size)
        top = max(float(np.max(d)) for d in data if d.size)
        pad = max(0.05 * (top - bottom), 0.5)
        bottom, top = bottom - pad, top + pad
        thr = math.log10(result.divergence_threshold)
    return {"log10": not finite, "t": t, "mean": y, "lower": y_lo, "upper": y_hi,
            "traces": tr, "ylim": (bottom, top), "threshold": thr, "floor": floor}


def _plot_mean(ax: Any, result: SimulationResult) -> None:
    d = plot_series(result)
    if d["traces"] is not None:
        steps = np.arange(result.steps + 1)
        for k, row in enumerate(d["traces"]):
            ax.plot(steps, row, lw=0.6, alpha=0.5, color="0.5",
                    label="sample paths" if k == 0 else None)
    ax.fill_between(d["t"], d["lower"], d["upper"], alpha=0.3, label="95% band of the mean")
    ax.plot(d["t"], d["mean"], lw=1.5, label="E[tr P_t]")
    bottom, top = d["ylim"]
    if result.diverged_paths and bottom < d["threshold"] < top:
        ax.axhline(d["threshold"], ls=":", lw=1, color="#b91c1c",
                   label=f"divergence threshold ({result.diverged_paths} paths crossed)")
    if d["log10"]:
        ax.set_ylabel("log10 tr P_t (values beyond float64)")
    else:
        ax.set_yscale("log")
        ax.set_ylabel("tr P_t")
    ax.set_ylim(bottom, top)
    ax.set_xlim(0, max(result.steps, 1))
    ax.set_xlabel("t")
    ax.set_title(f"p = {result.arrival_probability:.4g}, {result.paths} paths")
    ax.legend(loc="best", fontsize=8)


def _plot_cdf(ax: Any, result: SimulationResult) -> None:
    """Empirical CDF of tr P at the horizon over all paths (log10 units if beyond float64)."""
    x = np.sort(result.horizon_traces)
    F = np.arange(1, x.size + 1) / x.size
    if np.all(np.isfinite(x)) and x.size and x[0] > 0:
        ax.step(x, F, where="post")
        ax.set_xscale("log")
        ax.set_xlabel(f"tr P at t = {result.steps}")
    else:
        lx = np.sort(result.horizon_log10_traces if result.horizon_log10_traces is not None
                     else np.log10(result.horizon_traces))
        ok = np.isfinite(lx)
        ax.step(lx[ok], F[ok], where="post")
        ax.set_xlabel(f"log10 tr P at t = {result.steps}")
    ax.set_ylim(0, 1.02)
    ax.set_ylabel("CDF")


def write_plot(result: SimulationResult, path: str) -> None:
    """Write E[tr P_t] with its band, a few sample paths and the horizon CDF (SVG/PNG, atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    target = Path(path)
    folder = target.resolve().parent
    if not folder.is_dir():
        raise InputError(f"folder {str(folder)[:80]!r} does not exist", field="--plot")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    try:
        _plot_mean(ax1, result)
        _plot_cdf(ax2, result)
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format=target.suffix.lower().lstrip("."))
        write_atomic(target, buffer.getvalue())
    finally:
        plt.close(fig)
