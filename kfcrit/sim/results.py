"""Result types of the Monte Carlo: curves at sample times, horizon law, ergodic averages."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kfcrit.io.typed import to_json
from kfcrit.records.simulation import (
    AlmostSureSample,
    BurstStatistics,
    ErgodicAverages,
    ErgodicDivergence,
    Exceedance,
    HorizonCdf,
    HorizonDistribution,
    MeanLambdaMaxStatistics,
    MeanTraceStatistics,
    PathTimeAverages,
    PooledMeanTrace,
    PooledTailLevel,
    SimulationDivergence,
    TailLevel,
    TimeAverages,
)
from kfcrit.sim.arrivals import STREAM_ERGODIC
from kfcrit.sim.stats import LN10, Z95, finite_or_none, json_array, proportion, quiet_numerics

DEFAULT_SAMPLES = 200
"""Largest number of sample times kept for E[tr P_t] curves."""


QUANTILE_LEVELS = (0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99)


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
                "states": json_array(self.states), "estimates": json_array(self.estimates),
                "error_sq": json_array(self.error_sq), "trace": json_array(self.trace),
                "arrivals": self.arrivals.astype(int).tolist()}



@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Result of :func:`simulate`: curves at sample times, the horizon distribution, flags.

    ``mean_trace`` etc. are indexed like ``times`` (the sample times, 0 … steps);
    ``mean_lambda_max`` etc. like ``lambda_max_times`` (a subset of them). A path that
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
    above_threshold_fraction: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    failure_times: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    lambda_max_times: np.ndarray | None = field(repr=False, default=None)

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

    def lambda_max_method(self) -> str:
        """How E[λ_max(P_t)] was computed (stated in the record)."""
        k = (self.times.size if self.lambda_max_times is None else self.lambda_max_times.size)
        how = ("closed form" if self.n <= 2 else
               "Cholesky bisection on mu I - P (backward-stable positive-definiteness test), "
               "to 3.7e-12 tr P")
        return (f"exact per path ({how}), at {k} of the {self.times.size} sample times "
                "(listed in times), averaged over all paths")

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
        return [finite_or_none(float(np.quantile(x, q, method="inverted_cdf")))
                for q in levels]

    def exceedance(self, level: float) -> Exceedance:
        """P(tr P_steps > level) with a 95 % Wilson interval."""
        k = int(np.count_nonzero(self.horizon_traces > level))
        p = proportion(k, int(self.paths))
        return Exceedance(level=float(level), estimate=p["estimate"], lower=p["lower"],
                          upper=p["upper"], count=p["count"], total=p["total"])

    def cdf_points(self, points: int = DEFAULT_SAMPLES) -> HorizonCdf:
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
            return HorizonCdf(trace=[], probability=[])
        if n <= max(points, 2000):
            ranks = np.arange(n)
        else:
            geo = np.unique(np.round(np.geomspace(1, n, 2 * points)).astype(np.int64)) - 1
            ranks = np.unique(np.concatenate([
                np.round(np.linspace(0, n - 1, points)).astype(np.int64), geo, n - 1 - geo]))
        xs, u = x[ranks], (ranks + 1) / n
        keep = xs < self.divergence_threshold
        return HorizonCdf(trace=xs[keep].tolist(), probability=u[keep].tolist())

    def mean_trace_statistics(self) -> MeanTraceStatistics:
        """E[tr P_t] at the sample times: mean, 95 % band (:meth:`band`), sd and their log10
        (finite where the plain values overflow float64, which are then None)."""
        lo, hi = self.band("trace")
        llm, lls = self._log10("trace")
        llo, lhi = self.log10_band("trace")
        return MeanTraceStatistics(
            mean=json_array(self.mean_trace), lower=json_array(lo), upper=json_array(hi),
            std=json_array(self.std_trace), confidence=0.95,
            overflow=bool(not np.all(np.isfinite(self.mean_trace))),
            log10_mean=json_array(llm), log10_lower=json_array(llo),
            log10_upper=json_array(lhi), log10_std=json_array(lls))

    def mean_lambda_max_statistics(self) -> MeanLambdaMaxStatistics | None:
        """E[λ_max(P_t)] at its sample times with its 95 % band (None when not tracked)."""
        if self.mean_lambda_max is None:
            return None
        lo, hi = self.band("lambda_max")
        l10, _ = self._log10("lambda_max")
        lt = self.times if self.lambda_max_times is None else self.lambda_max_times
        return MeanLambdaMaxStatistics(
            mean=json_array(self.mean_lambda_max), lower=json_array(lo), upper=json_array(hi),
            std=json_array(self.std_lambda_max), confidence=0.95, log10_mean=json_array(l10),
            times=[int(x) for x in lt], method=self.lambda_max_method())

    def horizon_distribution(self) -> HorizonDistribution:
        """The law of tr P at the horizon: quantiles (and their log10), mean, empirical CDF."""
        llm, _ = self._log10("trace")
        return HorizonDistribution(
            time=int(self.steps), levels=list(QUANTILE_LEVELS),
            quantiles=self.horizon_quantiles(), log10_quantiles=self.horizon_log10_quantiles(),
            mean=finite_or_none(float(self.mean_trace[-1])),
            log10_mean=finite_or_none(float(llm[-1])), cdf=self.cdf_points())

    def divergence_record(self) -> SimulationDivergence:
        """Which paths crossed the divergence threshold, when, and whether any was frozen."""
        crossed = self.divergence_times[self.divergence_times >= 0]
        return SimulationDivergence(
            threshold=finite_or_none(self.divergence_threshold),
            diverged_paths=self.diverged_paths,
            first_time=int(crossed.min()) if crossed.size else None,
            diverged_fraction=json_array(self.diverged_fraction),
            above_threshold_fraction=json_array(self.above_threshold_fraction),
            continued=True,
            note=("diverged = crossed the threshold at least once; such paths are continued in "
                  "scaled form P = e^l X, so the statistics are true values"),
            failed_paths=self.failed_paths, mean_is_lower_bound=self.mean_is_lower_bound)

    def to_dict(self) -> dict[str, Any]:
        """The plain JSON form (``kfcrit simulate --json``): the statistics of the record
        (:meth:`mean_trace_statistics` …) with the system, the kept traces and the timing."""
        lm = self.mean_lambda_max_statistics()
        return {
            "system": self.system_name, "n": self.n, "m": self.m, "paths": self.paths,
            "steps": self.steps, "seed": self.seed, "channel": self.channel,
            "arrival_probability": self.arrival_probability,
            "times": self.times.tolist(),
            "mean_trace": to_json(self.mean_trace_statistics()),
            "mean_lambda_max": None if lm is None else to_json(lm),
            "horizon": to_json(self.horizon_distribution()),
            "divergence": to_json(self.divergence_record()),
            "traces": None if self.traces is None else json_array(self.traces),
            "full_state": None if self.full_state is None else self.full_state.to_dict(),
            "runtime_seconds": self.runtime_seconds,
            "warnings": list(self.warnings),
        }


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

    def pooled(self) -> PooledMeanTrace:
        """Pooled time mean over all replicas with a 95 % batch-means interval."""
        ok = (self.divergence_times < 0) & (self.used_steps > 0)
        if not ok.any():
            return PooledMeanTrace(mean=None, lower=None, upper=None, batches=0)
        nb = self.batch_sums.shape[1]
        per_batch = self.used_steps[ok, None] / nb
        bm = (self.batch_sums[ok] / per_batch).ravel()
        mean = float(self.sums[ok, 0].sum() / self.used_steps[ok].sum())
        half = Z95 * float(bm.std(ddof=1)) / math.sqrt(bm.size) if bm.size > 1 else math.inf
        return PooledMeanTrace(mean=mean, lower=finite_or_none(mean - half),
                               upper=finite_or_none(mean + half), batches=int(bm.size))

    def tail_probabilities(self) -> list[PooledTailLevel]:
        """P_μ(tr P > M) for every level, pooled over the replicas that never crossed the
        divergence threshold (a crossed path's counts stop at the crossing)."""
        ok = (self.divergence_times < 0) & (self.used_steps > 0)
        total = int(self.used_steps[ok].sum())
        out = []
        for q, lv in enumerate(self.levels):
            k = int(self.exceed[ok, q].sum())
            out.append(PooledTailLevel(level=float(lv), probability=k / total if total else None,
                                       count=k, steps=total, replicas=int(ok.sum())))
        return out

    def path_averages(self) -> PathTimeAverages:
        """Time averages along replica 0 ("the" long path): tr P, its square, the tails (None
        once it crossed the divergence threshold)."""
        used = self.used_steps
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.sums[0, 0] / used[0]
            second = self.sums[0, 1] / used[0]
            tails = self.exceed[0] / used[0]
        diverged = bool(self.divergence_times[0] >= 0)
        return PathTimeAverages(
            mean_trace=None if diverged else finite_or_none(mean),
            second_moment=None if diverged else finite_or_none(second),
            tail=[TailLevel(level=float(lv), probability=finite_or_none(tails[q]))
                  for q, lv in enumerate(self.levels)],
            diverged=diverged)

    def averages(self) -> ErgodicAverages:
        """The time averages of every replica, pooled, and the replicas' divergence."""
        tm = self.time_mean()
        diverged = self.divergence_times >= 0
        return ErgodicAverages(
            steps=int(self.steps), burn_in=int(self.burn_in), replicas=self.replicas,
            seed=int(self.seed),
            streams=[[int(self.seed), STREAM_ERGODIC, j] for j in range(self.replicas)],
            time_averages=TimeAverages(
                path=self.path_averages(), pooled_mean_trace=self.pooled(),
                pooled_tail=self.tail_probabilities(),
                replica_mean_trace=[None if d else finite_or_none(x)
                                    for x, d in zip(tm, diverged, strict=True)],
                used_steps=self.used_steps.astype(int).tolist()),
            divergence=ErgodicDivergence(
                threshold=finite_or_none(self.divergence_threshold),
                diverged_replicas=int(diverged.sum()),
                times=[int(t) if t >= 0 else None for t in self.divergence_times]))

    def burst_statistics(self) -> BurstStatistics:
        """Loss bursts over all replicas: their lengths' histogram (the last bin collects the
        longer ones), mean length against the channel's, and the mean tr P after each length."""
        counts = self.burst_count.sum(axis=0)
        trace_sum = self.burst_trace.sum(axis=0)
        lengths = np.arange(counts.size)
        total_bursts = int(counts[1:].sum())
        obs = int(self.observed_steps.sum())
        top = int(np.flatnonzero(counts)[-1]) if counts[1:].any() else 0
        expected = self.expected_mean_burst
        return BurstStatistics(
            loss_fraction=float(self.losses.sum() / obs) if obs else None,
            bursts=total_bursts,
            mean_length=float(self.losses.sum() / total_bursts) if total_bursts else None,
            expected_mean_length=None if expected is None else float(expected),
            longest=int(self.longest.max()) if self.longest.size else 0,
            length=lengths[1:top + 1].tolist(),
            count=counts[1:top + 1].astype(int).tolist(),
            last_bin=int(counts.size - 1), last_bin_collects_longer=True,
            mean_trace_after=[(float(trace_sum[j] / counts[j]) if counts[j] else None)
                              for j in range(1, top + 1)])

    def almost_sure_sample(self) -> AlmostSureSample:
        """Maxima and minima of tr P over the blocks [2^k, 2^(k+1)) of replica 0 (theory §6)."""
        k_full = int(math.floor(math.log2(self.steps + 1)))  # blocks [2^k, 2^{k+1}) inside 1..steps
        bmax = self.block_max[0, :k_full]
        bmin = self.block_min[0, :k_full]
        valid = np.isfinite(bmax) & np.isfinite(bmin)
        return AlmostSureSample(
            block_start=[int(2 ** k) for k in range(k_full)],
            block_max=[float(x) if v else None for x, v in zip(bmax, valid, strict=True)],
            block_min=[float(x) if v else None for x, v in zip(bmin, valid, strict=True)],
            running_max=finite_or_none(float(np.nanmax(np.where(valid, bmax, np.nan))))
            if valid.any() else None,
            last_block_min=float(bmin[valid][-1]) if valid.any() else None,
            last_block_max=float(bmax[valid][-1]) if valid.any() else None,
            note=("block k covers t in [2^k, 2^(k+1)) of replica 0; growing block maxima "
                  "indicate limsup tr P = ∞ (upper a.s. unstable), bounded block minima "
                  "indicate liminf tr P < inf (lower a.s. stable), docs/theory.md §6"))

    def to_dict(self) -> dict[str, Any]:
        """The plain JSON form (``kfcrit simulate --ergodic-steps --json``): the record's
        :meth:`averages` with :meth:`burst_statistics` and :meth:`almost_sure_sample`."""
        avg = to_json(self.averages())
        div = avg.pop("divergence")
        return {**avg, "bursts": to_json(self.burst_statistics()),
                "almost_sure": to_json(self.almost_sure_sample()), "divergence": div}
