r"""The typed ``channel_fit`` section of the record: a measured trace's fits, their confidence
region and what the theory proves on it (theory §13, §14).

Every field is typed (no free-form JSON): the record's JSON form, strict reader and schema are
generated from these dataclasses by :mod:`kfcrit.io.typed`. The section holds facts and
statistics; the verdict they support is ``operating_point.verdict`` (decided once, in
:mod:`kfcrit.analysis.verdict`).

Conventions: f = P(lost next | received now), r = P(received next | lost now); the
Bernoulli interval has level c, each Gilbert–Elliott interval 1 − (1 − c)/2 (Bonferroni)

.. math:: \hat p = k/n,\quad \hat f = \frac{n_{10}}{n_{1\cdot}},\quad
          \hat r = \frac{n_{01}}{n_{0\cdot}}.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt


@dataclass(frozen=True)
class BurstLengthHistogram:
    """Complete loss runs of the trace against the geometric law of the fitted r̂.

    ``expected[j]`` is runs·(1 − r̂)^{lengths[j]−1}·r̂; ``statistic`` the pooled Pearson X²
    with ``dof`` degrees of freedom and its ``p_value`` (None with fewer than three bins).
    """

    lengths: list[int]
    counts: list[int]
    expected: list[float]
    runs: int
    censored: int
    mean_length: float | None
    fitted_recovery_rate: float | None
    statistic: float | None
    dof: int | None
    p_value: float | None


@dataclass(frozen=True)
class RegionCorner:
    """One corner of the confidence region and what is proven there (facts, not verdicts).

    ``necessary``: the necessary condition holds (True), fails (False) or is undecided (None);
    ``sufficient``: a sufficient condition is proven at the corner.
    """

    arrival_probability: float | None
    failure_rate: float | None
    recovery_rate: float | None
    necessary: bool | None
    sufficient: bool
    basis: str


@dataclass(frozen=True)
class ConfidenceRegion:
    """The region the verdict is decided on: the interval of p (``bernoulli``) or the
    Bonferroni rectangle of (f, r) (``gilbert-elliott``), with its worst and best corners.

    ``outcome``: ``holds`` (mean stability proven at the worst corner, hence on the whole
    region), ``fails`` (the necessary condition fails at the best corner, hence everywhere) or
    ``neither``.
    """

    model: str
    confidence: float
    worst: RegionCorner
    best: RegionCorner
    outcome: str


@dataclass(frozen=True)
class StabilityBoundary:
    """The stability boundary in the (failure rate, recovery rate) plane (theory §7, §10).

    ``necessary_recovery`` = 1 − 1/ρ(A)² (below it (1 − r)ρ² ≥ 1: unstable for every f);
    ``sufficient_recovery[k]`` the least r at which the coupled certificate was found at
    ``failure_rates[k]`` (None: not found; equal to the necessary one for a scalar plant, where
    the condition is exact).
    """

    spectral_radius: float | None
    necessary_recovery: float | None
    failure_rates: list[float]
    sufficient_recovery: list[float | None]
    note: str


@dataclass(frozen=True)
class SensorTraceFit:
    """One sensor's own trace (its marginal law), in a network of measured links."""

    name: str
    n: int
    p_hat: float
    p_interval: list[float]
    failure_rate_hat: float | None
    recovery_rate_hat: float | None
    lrt_p_value: float


@dataclass(frozen=True)
class JointConstraintFit:
    r"""The necessary condition for one maximal sensor set T (theory §13):

    .. math:: P(S_t \subseteq T)\,\rho_T^2 < 1

    with P̂ the empirical frequency, ``interval`` its Clopper–Pearson interval at the
    simultaneous (Bonferroni) level, ``product`` what independent links with the same marginals
    would give.
    """

    unobservable: list[str]
    modulus2: float
    probability: float
    interval: list[float]
    product: float
    value: float
    value_low: float
    value_high: float
    product_value: float


@dataclass(frozen=True)
class JointLawFit:
    """The empirical joint law of the received set of time-aligned sensor traces.

    ``p_all_lost`` = π̂(∅) with its interval at ``confidence``, against
    ``p_all_lost_product`` = Π(1 − p̂_i) (independent links); ``law`` lists π̂(S) with bit i of
    the index = ``sensors[i]`` (empty above 8 sensors). ``necessary``/``sufficient``/
    ``exact_region`` are the facts under the point estimate; ``independent_necessary`` the
    necessary condition if the links were independent with these marginals (what a model of
    independent links would conclude); ``region_covered`` says whether the facts hold on the
    whole confidence region (see ``statement``).
    """

    sensors: list[str]
    n: int
    confidence: float
    p_all_lost: float
    p_all_lost_interval: list[float]
    p_all_lost_product: float
    all_lost_ratio: float | None
    law: list[float]
    constraints: list[JointConstraintFit]
    necessary: bool | None
    sufficient: bool
    exact_region: bool
    independent_necessary: bool | None
    region_covered: bool
    statement: str


@dataclass(frozen=True)
class ChannelFitSection:
    """Fits of a measured trace and the confidence region of the verdict (theory §14).

    For one trace channel the fits are of its trace; for a network of trace channels they are
    of the trace "at least one sensor received" (``subject``), with each sensor's own fit in
    ``sensors`` and the joint law of the received set in ``joint_law``.
    """

    subject: str
    model: str
    n: int
    p_hat: float
    p_interval: list[float]
    failure_rate_hat: float | None
    failure_rate_interval: list[float]
    recovery_rate_hat: float | None
    recovery_rate_interval: list[float]
    lrt_statistic: float
    lrt_p_value: float
    confidence: float
    length_to_decide: int | None
    length_to_decide_basis: str
    bursts: BurstLengthHistogram
    region: ConfidenceRegion | None = opt()
    boundary: StabilityBoundary | None = opt()
    sensors: list[SensorTraceFit] | None = opt()
    joint_law: JointLawFit | None = opt()
    notes: list[str] | None = opt()


__all__ = ["BurstLengthHistogram", "ChannelFitSection", "ConfidenceRegion", "JointConstraintFit",
           "JointLawFit", "RegionCorner", "SensorTraceFit", "StabilityBoundary"]
