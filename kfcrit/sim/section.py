"""The ``simulation`` section of the analysis record: the operating point and a phase demo.

Streams: the operating point uses ``SeedSequence(seed, spawn_key=(0, i))`` for its paths and
``spawn_key=(2, j)`` for its long ergodic paths; phase-demo curve k uses seed + 1 + k.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from kfcrit.io.systemfile import SystemSpec
from kfcrit.io.typed import ABSENT
from kfcrit.model.system import System
from kfcrit.records.channel import channel_record
from kfcrit.records.contract import VerificationCheck
from kfcrit.records.simulation import (
    MeanBasis,
    MeanLambdaMaxStatistics,
    MeanTraceStatistics,
    OperatingPointSeeds,
    PhaseDemo,
    PhaseDemoCurve,
    PooledMeanTrace,
    SampleMeanLambdaMax,
    SampleMeanTrace,
    Simulation,
    SimulationBudget,
    SimulationOperatingPoint,
    SimulationSeeds,
)
from kfcrit.sim.checks import mean_regime, simulation_checks, tail_regime
from kfcrit.sim.engine import ergodic, simulate
from kfcrit.sim.results import DEFAULT_SAMPLES
from kfcrit.sim.stats import json_array, quiet_numerics

LARGE_STATES = 40
"""Above this many states the simulation has fixed, smaller sizes (:meth:`Budget.for_system`):
each path-step costs O(n³) (batched BLAS-3, :mod:`kfcrit.sim.batched`)."""


LARGE_LAMBDA_MAX_SAMPLES = 6
"""Sample times of E[λ_max(P_t)] above :data:`LARGE_STATES` states (first and last included)."""


def large_budget_note(n: int, budget: Budget) -> str | None:
    """The sentence stating the reduced sizes of a large system's simulation (None for small n)."""
    if n <= LARGE_STATES:
        return None
    return (f"n = {n} > {LARGE_STATES} states: the Monte Carlo runs at reduced sizes (each "
            f"path-step costs O(n³)): {budget.paths} paths × {budget.steps} steps at the "
            f"operating point, {budget.replicas} long paths × {budget.ergodic_steps} steps, "
            f"phase demo {budget.demo_paths} paths × {budget.demo_steps} steps, E[λ_max] at "
            f"{LARGE_LAMBDA_MAX_SAMPLES} sample times; the checks use "
            "these sizes (their 5-standard-error tolerances widen accordingly, and a horizon "
            "that has not settled makes the bound check inconclusive, never passed)")


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
        if n > LARGE_STATES:
            return cls(32, 60, 300, 2, 8, 30) if quick else cls(48, 80, 600, 2, 8, 40)
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
                       seed: int, quick: bool,
                       critical_bracket: tuple[float | None, float | None] | None = None,
                       mean_decision: tuple[bool | None, str] | None = None) -> Simulation:
    """The ``simulation`` section of the analysis record.

    Fields: ``seed``, ``quick``, ``budget``, ``seeds``, ``operating_point`` (None without a
    channel), ``checks``, ``warnings``, ``phase_demo`` (None when the reference value is unknown
    or 0). See the module docstring for the streams.

    ``critical_value`` is p_c when known exactly; otherwise ``critical_bracket`` = (lo, hi)
    brackets it (either end may be None) and ``upper_bound`` is p_up ≥ p_c. They decide whether
    the mean exists at the operating point (:func:`mean_regime`; when it does not, the
    operating point carries no E[tr P_t] and no interval, only the sample statistics labelled
    as such) and whether tr P has a finite variance (:func:`tail_regime`, the upper end of what
    is known about p_c: conservative). ``mean_decision`` = (exists, basis), when the caller
    has decided the mean's existence exactly (the analysis's verdict at the operating point),
    is the one that counts: the float comparison of :func:`mean_regime` then only describes.
    """
    if not isinstance(spec, SystemSpec):
        spec = SystemSpec(system=spec)
    system = spec.system
    budget = Budget.for_system(system.n, quick)
    warnings: list[str] = []
    checks: list[VerificationCheck] = []
    note = large_budget_note(system.n, budget)
    if note:
        warnings.append(note)
    op = op_seeds = None
    with quiet_numerics():
        if spec.channel is not None:
            known = {"critical_value": critical_value, "critical_bracket": critical_bracket,
                     "upper_bound": upper_bound}
            op = _operating_point(spec, budget, seed, known, warnings, checks, mean_decision)
            op_seeds = OperatingPointSeeds(seed=int(seed),
                                           paths="SeedSequence(seed, spawn_key=(0, i))",
                                           ergodic="SeedSequence(seed, spawn_key=(2, j))")
        demo = _phase_demo(system, critical_value, upper_bound, budget, seed, warnings)
    seeds = SimulationSeeds(
        operating_point=ABSENT if op_seeds is None else op_seeds,
        phase_demo=ABSENT if demo is None else [c.seed for c in demo.curves])
    return Simulation(
        seed=int(seed), quick=bool(quick),
        budget=SimulationBudget(paths=budget.paths, steps=budget.steps,
                                ergodic_steps=budget.ergodic_steps, replicas=budget.replicas,
                                demo_paths=budget.demo_paths, demo_steps=budget.demo_steps),
        seeds=seeds, operating_point=op, checks=checks, warnings=warnings, phase_demo=demo)


def _operating_point(spec: Any, budget: Budget, seed: int, known: dict[str, Any],
                     warnings: list[str], checks: list[VerificationCheck],
                     mean_decision: tuple[bool | None, str] | None = None
                     ) -> SimulationOperatingPoint:
    system, chan = spec.system, spec.channel
    samples = DEFAULT_SAMPLES if system.n <= 10 else 50  # λ_max costs ~n³ per sample
    # λ_max costs a dense eigenproblem per path and sample time: fewer times for large n
    lmax = {"lambda_max_samples": LARGE_LAMBDA_MAX_SAMPLES} if system.n > LARGE_STATES else {}
    res = simulate(system, budget.paths, budget.steps, seed, chan, horizon_samples=samples,
                   **lmax)
    level = spec.requirements.max_error_trace
    erg = ergodic(system, budget.ergodic_steps, seed, chan, replicas=budget.replicas,
                  levels=(level,) if level is not None else ())
    averages = erg.averages()
    warnings.extend(res.warnings)
    if averages.divergence.diverged_replicas:
        warnings.append(f"{averages.divergence.diverged_replicas} of {erg.replicas} long paths "
                        "exceeded the divergence threshold (time averages stop there)")
    regime = tail_regime(system, chan, res.steps, **known)
    mean = decided_mean(mean_regime(system, chan, **known), mean_decision)
    found = simulation_checks(system, chan, res, erg, regime)
    for c in found:
        if c.status == "inconclusive":
            warnings.append(f"Monte Carlo check inconclusive: {c.check} ({c.reason})")
    checks.extend(found)
    op = SimulationOperatingPoint(
        channel=channel_record(chan), arrival_probability=float(res.arrival_probability),
        iid=bool(chan.iid), paths=int(res.paths), steps=int(res.steps), seed=int(res.seed),
        times=res.times.tolist(), mean_trace=res.mean_trace_statistics(),
        mean_lambda_max=res.mean_lambda_max_statistics(), horizon=res.horizon_distribution(),
        exceedance=res.exceedance(level) if level is not None else None, ergodic=averages,
        bursts=erg.burst_statistics(), almost_sure=erg.almost_sure_sample(),
        divergence=res.divergence_record(), reliability=regime, mean_exists=mean.exists,
        mean_basis=mean)
    if mean.exists is False:
        op = _withhold_means(op, warnings)
    return op


def decided_mean(mean: MeanBasis, decision: tuple[bool | None, str] | None) -> MeanBasis:
    """:func:`mean_regime`'s answer, with ``exists`` (and, where it differs, the basis) taken
    from the caller's ``decision`` = (exists, basis) when there is one: the analysis's verdict
    at the operating point, exact; ``exists`` None when that verdict is undetermined (a float
    comparison here must not decide what the verdict could not)."""
    if decision is None or mean.exists is None and mean.basis == "a measured trace: no model":
        return mean
    exists, basis = decision
    if mean.exists is exists:
        return mean
    return replace(mean, exists=exists, basis=f"the verdict at the operating point: {basis}")


DIVERGES = ("E[tr P_t] diverges at this operating point (sup_t E[tr P_t] = ∞: {basis}); a "
            "sample mean over finitely many paths and steps is finite but estimates nothing, "
            "so no mean and no confidence interval is given")

SAMPLE_LABEL = ("sample mean and sd over the simulated paths (not an estimate: the mean "
                "diverges)")


def _withhold_means(op: SimulationOperatingPoint, warnings: list[str]
                    ) -> SimulationOperatingPoint:
    """The operating point of a divergent mean: every mean (and its interval) replaced by a
    statement; the raw sample statistics stay, under fields that say what they are."""
    statement = DIVERGES.format(basis=op.mean_basis.basis)
    mt, ml, hz = op.mean_trace, op.mean_lambda_max, op.horizon
    ta = op.ergodic.time_averages
    pooled, path = ta.pooled_mean_trace, ta.path
    warnings.append(statement)
    return replace(
        op,
        sample_mean_trace=SampleMeanTrace(label=SAMPLE_LABEL, mean=mt.mean, std=mt.std,
                                          log10_mean=mt.log10_mean, log10_std=mt.log10_std),
        mean_trace=MeanTraceStatistics(
            mean=None, lower=None, upper=None, std=None, confidence=None, log10_mean=None,
            log10_lower=None, log10_upper=None, exists=False, diverges=True,
            statement=statement),
        sample_mean_lambda_max=ABSENT if ml is None else SampleMeanLambdaMax(
            label=SAMPLE_LABEL, mean=ml.mean, std=ml.std, log10_mean=ml.log10_mean,
            times=ml.times),
        mean_lambda_max=None if ml is None else MeanLambdaMaxStatistics(
            mean=None, lower=None, upper=None, std=None, confidence=None, log10_mean=None,
            exists=False, diverges=True, statement=statement, log10_lower=None,
            log10_upper=None),
        horizon=replace(hz, sample_mean=hz.mean, sample_log10_mean=hz.log10_mean, mean=None,
                        log10_mean=None, mean_diverges=True),
        ergodic=replace(op.ergodic, time_averages=replace(
            ta,
            pooled_mean_trace=PooledMeanTrace(
                mean=None, lower=None, upper=None, batches=pooled.batches, diverges=True,
                sample_time_average=pooled.mean,
                statement="the invariant law has an infinite mean (p <= p_c): time averages "
                          "grow without bound"),
            path=replace(path, sample_mean_trace=path.mean_trace, mean_trace=None,
                         sample_second_moment=path.second_moment, second_moment=None))))


def _phase_demo(system: System, critical_value: float | None, upper_bound: float | None,
                budget: Budget, seed: int, warnings: list[str]) -> PhaseDemo | None:
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
        curves.append(PhaseDemoCurve(
            arrival_probability=p, side=side, seed=s, times=res.times.tolist(),
            mean_trace=json_array(res.mean_trace), lower=json_array(lo), upper=json_array(hi),
            diverged_fraction=json_array(res.diverged_fraction),
            mean_is_lower_bound=res.mean_is_lower_bound))
    return PhaseDemo(reference_value=ref, reference=source, paths=budget.demo_paths,
                     steps=budget.demo_steps, curves=curves)
