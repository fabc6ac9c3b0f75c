"""The ``simulation`` section: Monte Carlo of the random Riccati equation at the operating point
(means, horizon distribution, ergodic averages, bursts, divergence), the phase demo near p_c,
the checks, and the network simulation.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key
from kfcrit.records.channel import ChannelRecord
from kfcrit.records.contract import VerificationCheck


@dataclass(frozen=True, kw_only=True)
class SimulationBudget:
    """`simulation.budget`"""

    paths: int
    steps: int
    ergodic_steps: int
    replicas: int
    demo_paths: int
    demo_steps: int


@dataclass(frozen=True, kw_only=True)
class OperatingPointSeeds:
    """`simulation.seeds.operating_point`"""

    seed: int
    paths: str
    ergodic: str


@dataclass(frozen=True, kw_only=True)
class SimulationSeeds:
    """`simulation.seeds`"""

    operating_point: OperatingPointSeeds = opt_key()
    phase_demo: list[int] = opt_key()


@dataclass(frozen=True, kw_only=True)
class MeanTraceStatistics:
    """`simulation.operating_point.mean_trace`"""

    mean: list[float | None] | None
    lower: list[float | None] | None
    upper: list[float | None] | None
    std: list[float | None] | None
    confidence: float | None
    overflow: bool = opt_key()
    log10_mean: list[float | None] | None
    log10_lower: list[float | None] | None
    log10_upper: list[float | None] | None
    log10_std: list[float | None] = opt_key()
    exists: bool = opt_key()
    diverges: bool = opt_key()
    statement: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class MeanLambdaMaxStatistics:
    """`simulation.operating_point.mean_lambda_max`"""

    mean: list[float | None] | None
    lower: list[float | None] | None
    upper: list[float | None] | None
    std: list[float | None] | None
    confidence: float | None
    log10_mean: list[float | None] | None
    times: list[int] = opt_key()
    method: str = opt_key()
    exists: bool = opt_key()
    diverges: bool = opt_key()
    statement: str = opt_key()
    log10_lower: list[float | None] | None = opt_key()
    log10_upper: list[float | None] | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class HorizonCdf:
    """`simulation.operating_point.horizon.cdf`"""

    trace: list[float | None]
    probability: list[float | None]


@dataclass(frozen=True, kw_only=True)
class HorizonDistribution:
    """`simulation.operating_point.horizon`"""

    time: int
    levels: list[float | None]
    quantiles: list[float | None]
    log10_quantiles: list[float | None]
    mean: float | None
    log10_mean: float | None
    cdf: HorizonCdf
    sample_mean: float | None = opt_key()
    sample_log10_mean: float | None = opt_key()
    mean_diverges: bool = opt_key()


@dataclass(frozen=True, kw_only=True)
class Exceedance:
    """`simulation.operating_point.exceedance`"""

    level: float | None
    estimate: float | None
    lower: float | None
    upper: float | None
    count: int
    total: int


@dataclass(frozen=True, kw_only=True)
class TailLevel:
    """`simulation.operating_point.ergodic.time_averages.path.tail[]`"""

    level: float | None
    probability: float | None


@dataclass(frozen=True, kw_only=True)
class PathTimeAverages:
    """`simulation.operating_point.ergodic.time_averages.path`"""

    mean_trace: float | None
    second_moment: float | None
    tail: list[TailLevel]
    diverged: bool
    sample_mean_trace: float | None = opt_key()
    sample_second_moment: float | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class PooledMeanTrace:
    """`simulation.operating_point.ergodic.time_averages.pooled_mean_trace`"""

    mean: float | None
    lower: float | None
    upper: float | None
    batches: int
    diverges: bool = opt_key()
    sample_time_average: float | None = opt_key()
    statement: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class PooledTailLevel:
    """`simulation.operating_point.ergodic.time_averages.pooled_tail[]`"""

    level: float | None
    probability: float | None
    count: int
    steps: int
    replicas: int


@dataclass(frozen=True, kw_only=True)
class TimeAverages:
    """`simulation.operating_point.ergodic.time_averages`"""

    path: PathTimeAverages
    pooled_mean_trace: PooledMeanTrace
    pooled_tail: list[PooledTailLevel]
    replica_mean_trace: list[float | None]
    used_steps: list[int]


@dataclass(frozen=True, kw_only=True)
class ErgodicDivergence:
    """`simulation.operating_point.ergodic.divergence`"""

    threshold: float | None
    diverged_replicas: int
    times: list[int | None]


@dataclass(frozen=True, kw_only=True)
class ErgodicAverages:
    """`simulation.operating_point.ergodic`"""

    steps: int
    burn_in: int
    replicas: int
    seed: int
    streams: list[list[int]]
    time_averages: TimeAverages
    divergence: ErgodicDivergence


@dataclass(frozen=True, kw_only=True)
class BurstStatistics:
    """`simulation.operating_point.bursts`"""

    loss_fraction: float | None
    bursts: int
    mean_length: float | None
    expected_mean_length: float | None
    longest: int
    length: list[int]
    count: list[int]
    last_bin: int
    last_bin_collects_longer: bool
    mean_trace_after: list[float | None]


@dataclass(frozen=True, kw_only=True)
class AlmostSureSample:
    """`simulation.operating_point.almost_sure`"""

    block_start: list[int]
    block_max: list[float | None]
    block_min: list[float | None]
    running_max: float | None
    last_block_min: float | None
    last_block_max: float | None
    note: str


@dataclass(frozen=True, kw_only=True)
class SimulationDivergence:
    """`simulation.operating_point.divergence`"""

    threshold: float | None
    diverged_paths: int
    first_time: int | None
    diverged_fraction: list[float | None]
    above_threshold_fraction: list[float | None]
    continued: bool
    note: str
    failed_paths: int
    mean_is_lower_bound: bool


@dataclass(frozen=True, kw_only=True)
class SimulationReliability:
    """`simulation.operating_point.reliability`"""

    variance_condition: str | None
    variance_value: float | None
    heavy_tailed: bool | None
    variance_threshold_p2: float | None
    variance_critical_value: float | None
    variance_critical_source: str
    variance_basis: str | None
    lyapunov_trace_at_horizon: float | None
    lyapunov_trace_limit: float | None
    settled: bool | None


@dataclass(frozen=True, kw_only=True)
class MeanBasis:
    """`simulation.operating_point.mean_basis`"""

    exists: bool | None
    basis: str
    compared: str = opt_key()
    value: float | None = opt_key()
    critical_lower: float | None = opt_key()
    critical_upper: float | None = opt_key()
    critical_source: str


@dataclass(frozen=True, kw_only=True)
class SampleMeanTrace:
    """`simulation.operating_point.sample_mean_trace`"""

    label: str
    mean: list[float | None]
    std: list[float | None]
    log10_mean: list[float | None]
    log10_std: list[float | None]


@dataclass(frozen=True, kw_only=True)
class SampleMeanLambdaMax:
    """`simulation.operating_point.sample_mean_lambda_max`"""

    label: str
    mean: list[float | None]
    std: list[float | None]
    log10_mean: list[float | None]
    times: list[int]


@dataclass(frozen=True, kw_only=True)
class SimulationOperatingPoint:
    """`simulation.operating_point`"""

    channel: ChannelRecord | None
    arrival_probability: float | None
    iid: bool
    paths: int
    steps: int
    seed: int
    times: list[int]
    mean_trace: MeanTraceStatistics
    mean_lambda_max: MeanLambdaMaxStatistics
    horizon: HorizonDistribution
    exceedance: Exceedance | None
    ergodic: ErgodicAverages
    bursts: BurstStatistics
    almost_sure: AlmostSureSample
    divergence: SimulationDivergence
    reliability: SimulationReliability
    mean_exists: bool | None
    mean_basis: MeanBasis
    sample_mean_trace: SampleMeanTrace = opt_key()
    sample_mean_lambda_max: SampleMeanLambdaMax = opt_key()


@dataclass(frozen=True, kw_only=True)
class PhaseDemoCurve:
    """`simulation.phase_demo.curves[]`"""

    arrival_probability: float | None
    side: str
    seed: int
    times: list[int]
    mean_trace: list[float | None]
    lower: list[float | None]
    upper: list[float | None]
    diverged_fraction: list[float | None]
    mean_is_lower_bound: bool


@dataclass(frozen=True, kw_only=True)
class PhaseDemo:
    """`simulation.phase_demo`"""

    reference_value: float | None
    reference: str
    paths: int
    steps: int
    curves: list[PhaseDemoCurve]


@dataclass(frozen=True, kw_only=True)
class NetworkMeanTrace:
    """`simulation.network.mean_trace`"""

    mean: float | None
    lower: float | None
    upper: float | None


@dataclass(frozen=True, kw_only=True)
class NetworkSimulation:
    """`simulation.network`"""

    paths: int
    steps: int
    seed: int
    sensors: list[str]
    mean_exists: bool | None
    diverged_paths: int | None = opt_key()
    """Paths past the divergence threshold (not tracked by the mesh Monte Carlo)."""
    horizon_quantiles: list[float | None] = opt_key()
    horizon_levels: list[float | None] = opt_key()
    mean_trace: NetworkMeanTrace = opt_key()
    sample_mean_trace: float | None = opt_key()
    statement: str = opt_key()


@dataclass(frozen=True, kw_only=True)
class Simulation:
    """`simulation`"""

    seed: int = opt_key()
    quick: bool = opt_key()
    budget: SimulationBudget = opt_key()
    seeds: SimulationSeeds = opt_key()
    operating_point: SimulationOperatingPoint | None = opt_key()
    checks: list[VerificationCheck] = opt_key()
    warnings: list[str] = opt_key()
    phase_demo: PhaseDemo | None = opt_key()
    reason: str = opt_key()
    skipped: bool = opt_key()
    network: NetworkSimulation = opt_key()
