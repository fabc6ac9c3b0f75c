"""Random streams and arrival sequences γ_t of the simulated links.

Every path draws its arrivals from its own stream, a SplitMix64 sequence keyed by
``SeedSequence(seed, spawn_key=(stream, i))`` — exactly the i-th child of
``SeedSequence(seed).spawn(stream + 1)[stream]`` — so a path's arrivals depend on (seed, i) only.
Channels are coded for the compiled kernels as ``kind`` (0 i.i.d., 1 Gilbert–Elliott Markov
chain, 2 a trace read cyclically) with the parameters (p, f, r, seq).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from kfcrit.errors import InputError
from kfcrit.model.channels import ArrivalProcess

STREAM_PATHS, STREAM_FULL_STATE, STREAM_ERGODIC = 0, 1, 2


KIND_CODE = {"iid": 0, "markov": 1, "sequence": 2}


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
def next_uniform(state: np.ndarray, b: int) -> float:
    """SplitMix64 step on ``state[b]``; return a uniform double in [0, 1) (53 random bits)."""
    s = state[b] + np.uint64(0x9E3779B97F4A7C15)
    state[b] = s
    z = s
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def channel_start(kind: int, f: float, r: float, seq_len: int, offset: int, state: np.ndarray,
                   b: int) -> int:
    """Initial channel state: Markov state drawn from its stationary law, or the trace index."""
    if kind == 1:
        return 1 if next_uniform(state, b) < r / (f + r) else 0
    if kind == 2:
        return offset % seq_len
    return 0


@njit(cache=True, inline="always")
def channel_next(kind: int, p: float, f: float, r: float, seq: np.ndarray, ch: np.ndarray,
                  state: np.ndarray, b: int) -> bool:
    """Return γ_t of lane b and advance its channel state ``ch[b]``.

    i.i.d.: γ = 1{u < p}. Markov: γ_t is the current state; the next one is lost with
    probability f after an arrival and recovers with probability r after a loss. Trace: the
    next value, cyclically.
    """
    if kind == 0:
        return next_uniform(state, b) < p
    if kind == 1:
        u = next_uniform(state, b)
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
    ch[0] = channel_start(kind, f, r, seq.shape[0], offset, state, 0)
    out = np.empty(steps, dtype=np.bool_)
    for t in range(steps):
        out[t] = channel_next(kind, p, f, r, seq, ch, state, 0)
    return out


def process_arrays(process: ArrivalProcess) -> tuple[int, float, float, float, np.ndarray]:
    seq = (np.ascontiguousarray(process.sequence, dtype=np.bool_)
           if process.kind == "sequence" else np.zeros(1, dtype=np.bool_))
    return (KIND_CODE[process.kind], float(process.p), float(process.failure_rate),
            float(process.recovery_rate), seq)


def trace_offsets(keys: np.ndarray, length: int) -> np.ndarray:
    """Start index of each path in a trace of ``length`` values: its 64-bit key mod length.

    Derived from the path's own key, so a path's arrivals depend on (seed, i) only — not on how
    many paths are run (prefix independence). Unused for other channels.
    """
    return (keys % np.uint64(max(int(length), 1))).astype(np.int64)
