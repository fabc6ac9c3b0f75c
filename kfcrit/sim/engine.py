"""simulate() and ergodic(): Monte Carlo of the random Riccati equation and of the filter.

The prediction covariance follows P_{t+1} = f_{γ_t}(P_t) (theory §1), with f_0(X) = A X A' + Q
(loss) and f_1 the Riccati map (arrival). Many paths are advanced by the compiled kernels of
:mod:`kfcrit.sim.kernels` in blocks of ``LANES`` paths, and memory never depends on ``steps``:
only the values at ≤ ``horizon_samples`` sample times are kept (plus the full traces of the
first few paths when asked). Path i draws its arrivals from the stream keyed
``SeedSequence(seed, spawn_key=(0, i))`` (:mod:`kfcrit.sim.arrivals`) and statistics are
accumulated in path order, so the output is bit-identical for any batch size. The full
state/estimate simulation (x_t, x̂_t) of a few paths reuses those arrival streams and draws its
noise from NumPy generators keyed by ``spawn_key=(1, j)``; the long ergodic paths use
``spawn_key=(2, j)``. Means over values beyond float64 come from log-sum-exp sums and are
reported as log10 (``log10_*``); never a silent inf or NaN.
"""
from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.systemfile import SystemSpec
from kfcrit.model.channels import Bernoulli, Channel, exact_probability
from kfcrit.model.system import System
from kfcrit.sim.arrivals import (
    STREAM_ERGODIC,
    STREAM_FULL_STATE,
    STREAM_PATHS,
    arrival_sequence,
    path_keys,
    process_arrays,
    trace_offsets,
)
from kfcrit.sim.batched import (
    BATCHED_MIN_STATES,
    arrivals_of,
    batched_ergodic,
    batched_paths,
)
from kfcrit.sim.kernels import LANES, ergodic_paths, rre_paths
from kfcrit.sim.results import DEFAULT_SAMPLES, ErgodicResult, FullStateResult, SimulationResult
from kfcrit.sim.stats import LN10, accumulate, accumulate_log, column_stats, quiet_numerics
from kfcrit.theory.covariance.riccati import single_blas_thread

THRESHOLD_FACTOR = 1e10
MAX_THRESHOLD = 1e300
"""Largest default divergence threshold (a finite float64 with room for P_t's growth)."""
"""Default divergence threshold relative to the problem's scale max(tr Σ0, tr Q, tr P*)."""


MAX_TRACE_VALUES = 250_000_000
"""Guard on requested full traces (2 GB of float64)."""


PROGRESS_WORK = 4_000_000
"""Lane-steps × n² per kernel call when progress is reported (a call then takes ~0.05 s)."""


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


def kernel_array(x: Any, dtype: Any = None) -> np.ndarray:
    """``x`` as a C-contiguous, aligned, writable array (a copy only where it is not one).

    numba compiles one specialization per combination of array flags: passing the system's
    read-only matrices in one call and computed (writable) arrays in another would compile the
    kernels (tens of seconds) once per combination.
    """
    return np.require(np.asarray(x, dtype=dtype), requirements=("C", "A", "W"))


def sample_times(steps: int, samples: int) -> np.ndarray:
    """At most ``samples`` sample times in 0 … steps, evenly spread, always with 0 and steps."""
    if samples < 2:
        raise InputError("must be >= 2", field="horizon_samples")
    return np.unique(np.round(np.linspace(0, steps, min(samples, steps + 1))).astype(np.int64))


def problem_scale(system: System, P0: np.ndarray) -> float:
    """Problem scale: max(tr P0, tr Q, tr P*), P* the stabilising DARE solution when it exists.

    P* by the structured doubling algorithm (:func:`steady_covariance`); when it does not
    converge (no stabilising solution, or ill-conditioned) P* is only left out of the maximum.
    """
    scale = max(float(np.trace(P0)), float(np.trace(system.q)), 1e-300)
    P = steady_covariance(system.a, system.c, system.q, system.r)
    if P is not None:
        scale = max(scale, float(np.trace(P)))
    return scale


def steady_covariance(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                      iterations: int = 60) -> np.ndarray | None:
    r"""P* = A P* A' + Q − A P* C'(C P* C' + R)^{-1} C P* A' by structured doubling, or None.

    .. math::

        W_k = (I + G_k H_k)^{-1},\quad \mathcal{A}_{k+1} = \mathcal{A}_k W_k \mathcal{A}_k,\quad
        G_{k+1} = G_k + \mathcal{A}_k W_k G_k \mathcal{A}_k',\quad
        H_{k+1} = H_k + \mathcal{A}_k' H_k W_k \mathcal{A}_k

    from 𝒜_0 = A', G_0 = C' R^{-1} C, H_0 = Q (Chu et al. 2004); H_k → P* quadratically when a
    stabilising solution exists. None when it has not converged to a relative 1e-10 within
    ``iterations`` doublings or is not finite. Cheap (a few n×n products per doubling), where
    scipy's QZ-based ``solve_discrete_are`` costs tens of milliseconds on a loaded machine.
    """
    n = A.shape[0]
    with quiet_numerics():
        try:
            Ak = np.array(A, dtype=float).T.copy()
            G = C.T @ np.linalg.solve(R, C)
            H = np.array(Q, dtype=float)
            eye = np.eye(n)
            for _ in range(iterations):
                W = np.linalg.inv(eye + G @ H)
                AW = Ak @ W
                H_new = H + Ak.T @ H @ W @ Ak
                G = G + AW @ G @ Ak.T
                Ak = AW @ Ak
                H_new = 0.5 * (H_new + H_new.T)
                G = 0.5 * (G + G.T)
                if not np.all(np.isfinite(H_new)):
                    return None
                done = np.abs(H_new - H).max() <= 1e-10 * max(np.abs(H_new).max(), 1e-300)
                H = H_new
                if done:
                    return H
        except np.linalg.LinAlgError:
            return None
    return None


LAMBDA_MAX_SAMPLES = 20
"""Default number of sample times at which E[λ_max(P_t)] is computed (exactly)."""
MAX_THREADS = 8
THREAD_WORK = 10_000_000
"""Below this many n² · path-steps a run stays on one thread (starting threads costs more)."""


def resolve_threads(threads: int | None, work: float = math.inf) -> int:
    """Worker threads: ``threads`` (≥ 1), or the CPUs this process may use (at most 8) when the
    run's ``work`` (n² · path-steps) is at least ``THREAD_WORK``, else 1."""
    if threads is None:
        if work < THREAD_WORK:
            return 1
        try:
            usable = len(os.sched_getaffinity(0))
        except (AttributeError, OSError):
            usable = os.cpu_count() or 1
        return max(1, min(usable, MAX_THREADS))
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise InputError("must be an integer >= 1", field="threads")
    return int(threads)


def split_lanes(start: int, stop: int, parts: int) -> list[tuple[int, int]]:
    """Cut paths ``start … stop−1`` into ≤ ``parts`` ranges of whole ``LANES`` blocks, in order."""
    blocks = -(-(stop - start) // LANES)
    per = -(-blocks // max(1, min(parts, blocks)))
    edges = list(range(start, stop, per * LANES)) + [stop]
    return list(zip(edges[:-1], edges[1:], strict=True))


def split_paths(start: int, stop: int, parts: int) -> list[tuple[int, int]]:
    """Cut paths ``start … stop−1`` into ≤ ``parts`` consecutive ranges of nearly equal size."""
    parts = max(1, min(parts, stop - start))
    edges = [start + (stop - start) * k // parts for k in range(parts + 1)]
    return list(zip(edges[:-1], edges[1:], strict=True))


def lambda_max_schedule(times: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample columns where λ_max is computed: (index per column or −1, the chosen times).

    At most ``samples`` columns, evenly spread over ``times`` and always with the first and
    the last (the horizon); none when ``samples`` is 0.
    """
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 0:
        raise InputError("must be an integer >= 0", field="lambda_max_samples")
    index = np.full(times.size, -1, dtype=np.int64)
    if samples == 0:
        return index, np.zeros(0, dtype=np.int64)
    cols = np.unique(np.round(np.linspace(0, times.size - 1, min(max(samples, 2), times.size)))
                     .astype(np.int64))
    index[cols] = np.arange(cols.size)
    return index, times[cols]


def sensor_stream(sensor: int) -> int:
    """Stream of sensor s's arrivals: the paths' own stream for s = 0, 2 + s beyond."""
    return STREAM_PATHS if sensor == 0 else STREAM_ERGODIC + sensor


def resolve_sensors(sensors: Sequence[tuple[Sequence[int], Channel]], m: int
                    ) -> list[tuple[list[int], Channel]]:
    """Check (rows, channel) pairs: channels, and rows that partition 0 … m−1."""
    out: list[tuple[list[int], Channel]] = []
    seen: list[int] = []
    for s, item in enumerate(sensors):
        try:
            rows, ch = item
            rows = [int(k) for k in rows]
        except (TypeError, ValueError):
            raise InputError(f"sensor {s}: must be (rows of C, channel)", field="sensors") from None
        if not isinstance(ch, Channel):
            raise InputError(f"sensor {s}: must have a Channel, got {type(ch).__name__}",
                             field="sensors")
        if not rows or any(not 0 <= k < m for k in rows):
            raise InputError(f"sensor {s}: rows must be indices of C's {m} rows", field="sensors")
        seen += rows
        out.append((rows, ch))
    if not out or sorted(seen) != list(range(m)):
        raise InputError(f"every row of C (0 … {m - 1}) must belong to exactly one sensor",
                         field="sensors")
    return out


@dataclass(frozen=True, eq=False)
class SensorLinks:
    """Per-sensor channel arrays for the kernel and the sensor of every output row."""

    kinds: np.ndarray
    ps: np.ndarray
    fs: np.ndarray
    rs: np.ndarray
    seqs: np.ndarray
    seq_len: np.ndarray
    row_sensor: np.ndarray

    @classmethod
    def of(cls, links: list[tuple[list[int], Channel]], m: int) -> SensorLinks:
        coded = [process_arrays(ch.arrival_process()) for _, ch in links]
        longest = max(c[4].size for c in coded)
        seqs = np.zeros((len(coded), longest), dtype=np.bool_)
        for s, c in enumerate(coded):
            seqs[s, :c[4].size] = c[4]
        row_sensor = np.empty(m, dtype=np.int64)
        for s, (rows, _) in enumerate(links):
            row_sensor[rows] = s
        return cls(np.array([c[0] for c in coded], dtype=np.int64),
                   np.array([c[1] for c in coded]), np.array([c[2] for c in coded]),
                   np.array([c[3] for c in coded]), seqs,
                   np.array([c[4].size for c in coded], dtype=np.int64), row_sensor)


@dataclass(eq=False)
class _Part:
    """Kernel state and outputs of paths ``start … stop−1`` of a batch (one worker's share)."""

    start: int
    stop: int
    keys: np.ndarray
    offsets: np.ndarray
    out_tr: np.ndarray
    out_ltr: np.ndarray
    out_lm: np.ndarray
    out_llm: np.ndarray
    out_div: np.ndarray
    out_fail: np.ndarray
    Xall: np.ndarray
    lg_all: np.ndarray
    sc_all: np.ndarray
    st_all: np.ndarray
    ch_all: np.ndarray
    traces: np.ndarray

    @classmethod
    def new(cls, seed: int, start: int, stop: int, seq_len: np.ndarray, n: int, S: int, SL: int,
            traces: np.ndarray, n_traced: int) -> _Part:
        B = stop - start
        N = seq_len.size
        keys = np.stack([path_keys(seed, start, stop, sensor_stream(s)) for s in range(N)])
        # every sensor's trace starts at the same index (the path key of sensor 0's stream):
        # traces recorded together stay time-aligned, so their joint law is replayed as
        # measured (independent starts would make simultaneous losses independent)
        offsets = np.stack([trace_offsets(keys[0], int(seq_len[s])) for s in range(N)])
        k_tr = max(0, min(n_traced - start, B))
        return cls(start, stop, keys, offsets,
                   np.empty((B, S)), np.empty((B, S)), np.empty((B, SL)), np.empty((B, SL)),
                   np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64),
                   np.empty((n, n, B)), np.zeros(B), np.zeros(B, dtype=np.int64),
                   np.zeros((N, B), dtype=np.uint64), np.zeros((N, B), dtype=np.int64),
                   traces[start:start + k_tr] if k_tr else np.empty((0, traces.shape[1])))


def _advance(fixed: tuple, chan_args: tuple, times: np.ndarray, lmax_index: np.ndarray,
             threshold: float, part: _Part, t0: int, t1: int) -> None:
    """Run the kernel on one part from step t0 to t1 (releases the GIL)."""
    rre_paths(*fixed, part.keys, part.offsets, *chan_args, t0, t1, times, lmax_index, threshold,
              part.Xall, part.lg_all, part.sc_all, part.st_all, part.ch_all, part.out_tr,
              part.out_ltr, part.out_lm, part.out_llm, part.out_div, part.out_fail, part.traces)


BATCHED_MEMORY = 256 * 2**20
"""Bytes of path state (about six n×n float64 arrays per path) one batched call may hold."""


def batched_width(n: int) -> int:
    """Paths advanced together by one batched BLAS-3 call at n states (memory-bounded)."""
    return max(1, int(BATCHED_MEMORY // (48 * n * n)))


def _advance_batched(fixed: tuple, process: tuple, times: np.ndarray, lmax_index: np.ndarray,
                     threshold: float, part: _Part, steps: int) -> None:
    """The paths of ``part`` over all ``steps`` by :func:`kfcrit.sim.batched.batched_paths`, in
    groups of :func:`batched_width` paths (a path's values do not depend on its group)."""
    A, C, Q, R, P0 = fixed
    kind, p, f, r, seq = process
    B = part.stop - part.start
    width = batched_width(A.shape[0])
    for a in range(0, B, width):
        b = min(a + width, B)
        gamma = arrivals_of(part.keys[0, a:b], part.offsets[0, a:b], kind, p, f, r, seq, steps)
        k_tr = max(0, min(part.traces.shape[0] - a, b - a))
        batched_paths(A, C, Q, R, P0, gamma, times, lmax_index, threshold, part.out_tr[a:b],
                      part.out_ltr[a:b], part.out_lm[a:b], part.out_llm[a:b], part.out_div[a:b],
                      part.out_fail[a:b], part.traces[a:a + k_tr])


def check_sizes(paths: int, steps: int, seed: int) -> None:
    for name, v, lo in (("paths", paths, 1), ("steps", steps, 1), ("seed", seed, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise InputError(f"must be an integer >= {lo}", field=name)


def simulate(system: Any, paths: int, steps: int, seed: int, channel: Channel | None = None,
             arrival_probability: Any = None, *, record_traces: bool | int = False,
             full_state_paths: int = 0, horizon_samples: int = DEFAULT_SAMPLES,
             initial: np.ndarray | None = None, divergence_threshold: float | None = None,
             track_lambda_max: bool = True, lambda_max_samples: int = LAMBDA_MAX_SAMPLES,
             batch_size: int = 1024, threads: int | None = None,
             progress: Callable[[int, int], None] | None = None,
             sensors: Sequence[tuple[Sequence[int], Channel]] | None = None) -> SimulationResult:
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
        Also estimate E[λ_max(P_t)], at ``lambda_max_samples`` of the sample times.
    lambda_max_samples : int
        At most this many sample times (evenly spread, with 0 and ``steps``) at which λ_max is
        computed — exactly: closed form for n ≤ 2, Cholesky bisection on μI − P to 3.7e-12 tr P
        for n ≥ 3 (each costs about three Riccati steps at n = 6, so λ_max at every sample
        time would cost more than the simulation). The result's ``lambda_max_times`` lists them.
    batch_size : int
        Paths per batch (results do not depend on it).
    threads : int, optional
        Threads that advance the blocks of a batch concurrently (default: the CPUs this process
        may use, at most 8, for runs of at least ``THREAD_WORK`` n² · path-steps; one below).
        Results do not depend on it: blocks are independent and the statistics are accumulated
        in path order.
    sensors : sequence of (rows, Channel), optional
        Several sensors, each over its own link (instead of ``channel``): sensor s owns the
        output rows ``rows`` of C (every row belongs to exactly one sensor) and its packets
        follow its channel, independently of the others; a step uses the stacked rows of C
        whose packets arrived (:func:`kfcrit.sim.kernels.riccati_lanes`). Sensor 0 draws from
        the path's stream ``spawn_key=(0, i)``, sensor s ≥ 1 from ``spawn_key=(2 + s, i)``, so
        one sensor owning every row gives exactly the single-link result. Trace channels of
        all sensors start at the same index (key of sensor 0's stream mod each length), so
        traces recorded together are replayed time-aligned (theory §13: their joint law).
    progress : callable, optional
        Called as ``progress(path_steps_done, paths × steps)`` after every chunk of steps
        (the run is then cut into chunks of ``PROGRESS_WORK`` / n² lane-steps; the results do
        not change).

    Returns
    -------
    SimulationResult

        Sample times ``times``, the mean and standard deviation of tr P_t and λ_max(P_t)
        (also in log10), the fraction of diverged paths, optional traces and warnings.

    Raises
    ------
    kfcrit.errors.InputError
        ``paths``, ``steps`` or ``seed`` out of range, no channel and no arrival probability,
        or an invalid ``initial`` or ``sensors``.

    References
    ----------
    Sinopoli et al. (2004), eq. (15) (the random Riccati equation); Kar, Sinopoli & Moura,
    Proposition 25 (ergodic averages); docs/theory.md §1 (the Joseph-form step) and §5.

    Examples
    --------
    >>> from kfcrit import System, simulate
    >>> system = System(A=[["5/4"]], C=[[1]], Q=1, R=1)
    >>> res = simulate(system, paths=200, steps=50, seed=1, arrival_probability="1/2")
    >>> res.paths, res.steps, float(res.diverged_fraction.max())
    (200, 50, 0.0)
    >>> bool(4 < res.mean_trace[-1] < 8)    # S̄ = 4.57 ⪯ lim E[P_t] ⪯ V̄ = 7.73 at p = 1/2
    True
    >>> simulate(system, paths=0, steps=50, seed=1, arrival_probability="1/2")
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: paths: must be an integer >= 1
    """
    t_start = time.perf_counter()
    if isinstance(system, SystemSpec):
        if channel is None and arrival_probability is None:
            channel = system.channel
        system = system.system
    if not isinstance(system, System):
        raise InputError(f"must be a System, got {type(system).__name__}", field="system")
    check_sizes(paths, steps, seed)
    n, m = system.n, system.m
    if sensors is None:
        chan = resolve_channel(channel, arrival_probability)
        links = [(list(range(m)), chan)]
    else:
        if channel is not None or arrival_probability is not None:
            raise InputError("give sensors or a channel, not both", field="sensors")
        links = resolve_sensors(sensors, m)
        chan = links[0][1]
        if full_state_paths:
            raise InputError("the full-state simulation has one link; leave it at 0 with "
                             "sensors", field="full_state_paths")
    link = SensorLinks.of(links, m)
    process = chan.arrival_process()
    kind, p, f, r, seq = process_arrays(process)
    A, C, Q, R = (kernel_array(x, float) for x in (system.a, system.c, system.q, system.r))
    P0 = kernel_array(initial_covariance(system, initial), float)
    threshold = resolve_threshold(system, P0, divergence_threshold)
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
    lmax_index, lmax_times = lambda_max_schedule(times, lambda_max_samples if track_lambda_max
                                                 else 0)
    S, SL = times.size, lmax_times.size
    count_t = 0
    mean_t, m2_t = np.zeros(S), np.zeros(S)
    mean_l, m2_l = np.zeros(SL), np.zeros(SL)
    lsum_t = (np.full(S, -np.inf), np.zeros(S), np.zeros(S))   # (max log, Σe^{x−M}, Σe^{2(x−M)})
    lsum_l = (np.full(SL, -np.inf), np.zeros(SL), np.zeros(SL))
    div_frac = np.zeros(S)
    above = np.zeros(S)
    lthr = math.log(threshold)
    horizon = np.empty(paths)
    horizon_log = np.empty(paths)
    div_times = np.empty(paths, dtype=np.int64)
    fail_times = np.empty(paths, dtype=np.int64)
    batch_size = max(int(batch_size), 1)
    # large n: batched BLAS-3 steps, the paths shared between the workers (one BLAS thread each)
    batched = n >= BATCHED_MIN_STATES and sensors is None and progress is None
    workers = resolve_threads(threads, float(n * n) * paths * steps)
    total = paths * steps
    fixed = (A, C, Q, R, P0)
    chan_args = tuple(kernel_array(a) for a in (link.kinds, link.ps, link.fs, link.rs, link.seqs,
                                                 link.seq_len, link.row_sensor))
    with ThreadPoolExecutor(workers) if workers > 1 else nullcontext() as pool:
        for start in range(0, paths, batch_size):
            stop = min(start + batch_size, paths)
            B = stop - start
            ranges = (split_paths(start, stop, workers) if batched
                      else split_lanes(start, stop, workers))
            parts = [_Part.new(seed, a, b, link.seq_len, 1 if batched else n, S, SL, traces,
                               n_traced) for a, b in ranges]
            # in time chunks when progress is reported (the chunking does not change the numbers)
            chunk = steps if progress is None else max(1, int(PROGRESS_WORK // max(B * n * n, 1)))
            for t0 in range(0, steps, chunk):
                t1 = min(t0 + chunk, steps)
                calls = [(part, t0, t1) for part in parts]
                if batched:
                    run = [(fixed, (kind, p, f, r, kernel_array(seq)), times, lmax_index,
                            threshold, part, steps) for part in parts]
                    with single_blas_thread():
                        if pool is None or len(parts) == 1:
                            for call in run:
                                _advance_batched(*call)
                        else:
                            for fut in [pool.submit(_advance_batched, *call) for call in run]:
                                fut.result()
                elif pool is None or len(parts) == 1:
                    for call in calls:
                        _advance(fixed, chan_args, times, lmax_index, threshold, *call)
                else:
                    for fut in [pool.submit(_advance, fixed, chan_args, times, lmax_index,
                                            threshold, *call) for call in calls]:
                        fut.result()
                if progress is not None:
                    progress(start * steps + B * t1, total)
            for part in parts:  # in path order: the sums do not depend on the split
                c0 = count_t
                count_t = accumulate(part.out_tr, c0, mean_t, m2_t)
                accumulate_log(part.out_ltr, *lsum_t)
                if SL:
                    accumulate(part.out_lm, c0, mean_l, m2_l)
                    accumulate_log(part.out_llm, *lsum_l)
                for d in part.out_div[part.out_div >= 0]:
                    div_frac[times >= d] += 1
                above += np.count_nonzero(part.out_ltr > lthr, axis=0)
                a, b = part.start, part.stop
                horizon[a:b] = part.out_tr[:, -1]
                last = part.out_ltr[:, -1]
                with quiet_numerics():   # plain values below e^LOG_KEEP carry no log: take it
                    horizon_log[a:b] = np.where(last > -np.inf, last, np.log(part.out_tr[:, -1]))
                div_times[a:b] = part.out_div
                fail_times[a:b] = part.out_fail
    mean_t, std_t, lmean_t, lstd_t = column_stats(count_t, mean_t, m2_t, *lsum_t)
    if track_lambda_max:
        mean_l, std_l, lmean_l, lstd_l = column_stats(count_t, mean_l, m2_l, *lsum_l)
    warnings: list[str] = []
    for _, ch in links:
        pr = ch.arrival_process()
        if pr.kind == "sequence" and steps > pr.sequence.size:
            warnings.append(f"the arrival trace has {pr.sequence.size} values, fewer than the "
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
    full = (simulate_full_state(system, A, C, Q, R, P0, seed, kind, p, f, r, seq, paths, steps,
                        min(int(full_state_paths), paths))
            if full_state_paths and full_state_paths > 0 else None)
    return SimulationResult(
        system_name=system.name, n=n, m=m, paths=paths, steps=steps, seed=int(seed),
        channel=(chan.to_dict() if sensors is None else
                 {"model": "sensors", "sensors": [{"rows": list(rows), "channel": ch.to_dict()}
                                                  for rows, ch in links]}),
        arrival_probability=(float(chan.arrival_probability) if sensors is None else
                             float(np.mean([float(ch.arrival_probability)
                                            for _, ch in links]))),
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
        lambda_max_times=lmax_times if track_lambda_max else None,
        horizon_log10_traces=horizon_log / LN10, above_threshold_fraction=above / paths,
        failure_times=fail_times)



def resolve_threshold(system: System, P0: np.ndarray, given: Any) -> float:
    """The divergence threshold: ``given`` (finite, positive) or 1e10 × the problem's scale,
    capped at :data:`MAX_THRESHOLD` (a scale near the top of float64 — Σ0 or Q of 1e300 — must
    not turn the default into ``inf``, a value the user never wrote)."""
    if given is None:
        value = THRESHOLD_FACTOR * problem_scale(system, P0)
        if not value < MAX_THRESHOLD:  # also catches NaN
            value = MAX_THRESHOLD
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



def initial_covariance(system: System, initial: Any) -> np.ndarray:
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


def simulate_full_state(system: System, A, C, Q, R, P0, seed, kind, p, f, r, seq, paths, steps,
                k) -> FullStateResult:
    """x_{t+1} = A x_t + w_t, y_t = C x_t + v_t, and the intermittent Kalman filter.

    x̂_{t+1|t} = A x̂_{t|t−1} + γ_t A K_t (y_t − C x̂_{t|t−1}), K_t = P_t C' (C P_t C' + R)^{-1}, with
    P_t from the RRE; x_0 ~ N(0, P_0), x̂_{0|−1} = 0. Arrivals are those of RRE paths 0 … k−1.
    """
    n, m = A.shape[0], C.shape[0]
    keys = path_keys(seed, 0, k)
    offsets = trace_offsets(keys, seq.size)
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
    if isinstance(system, SystemSpec):
        if channel is None and arrival_probability is None:
            channel = system.channel
        system = system.system
    check_sizes(replicas, steps, seed)
    chan = resolve_channel(channel, arrival_probability)
    process = chan.arrival_process()
    kind, p, f, r, seq = process_arrays(process)
    A, C, Q, R = (kernel_array(x, float) for x in (system.a, system.c, system.q, system.r))
    P0 = kernel_array(initial_covariance(system, initial), float)
    threshold = resolve_threshold(system, P0, divergence_threshold)
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
    seq = kernel_array(seq)
    if system.n >= BATCHED_MIN_STATES:
        gamma = arrivals_of(keys, trace_offsets(keys, seq.size), kind, p, f, r, seq, steps)
        outs = (sums, exceed, batch_sums, burst_count, burst_trace, block_max, block_min, div,
                losses, longest)
        ranges = split_paths(0, replicas, resolve_threads(None, float(system.n) ** 2 * steps
                                                          * replicas))

        def run(a: int, b: int) -> None:
            batched_ergodic(A, C, Q, R, P0, gamma[a:b], burn, lv, max_burst, n_batches,
                            threshold, *(o[a:b] for o in outs))
        with single_blas_thread(), ThreadPoolExecutor(len(ranges)) as pool:
            for fut in [pool.submit(run, a, b) for a, b in ranges]:
                fut.result()
    else:
        ergodic_paths(A, C, Q, R, P0, keys, trace_offsets(keys, seq.size), kind, p, f, r, seq,
                      steps, burn, lv, max_burst, n_batches, threshold, sums, exceed,
                      batch_sums, burst_count, burst_trace, block_max, block_min, div, losses,
                      longest)
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
