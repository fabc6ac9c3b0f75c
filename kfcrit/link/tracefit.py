r"""Statistics of a measured packet trace (theory §7, §10, §14): fits, tests and decision facts.

A trace is a 0/1 sequence γ_0 … γ_{n−1}, one value per sampling period (1 = received, 0 = lost).
This module fits the two channel models of :mod:`kfcrit.model.channels` to it, with exact
confidence intervals, tests one against the other, and states *facts* a verdict can rest on:
whether a monotone stability property holds on the whole confidence region, fails on all of it,
or neither, and how long a trace would decide it at the fitted values. It gives no verdict.

Conventions (those of :class:`~kfcrit.model.channels.GilbertElliott`): n_{ab} counts the
transitions γ_t = a → γ_{t+1} = b, the failure rate is f = P(lost next | received now) and the
recovery rate r = P(received next | lost now),

.. math::

    \hat p = \frac{k}{n}, \qquad
    \hat f = \frac{n_{10}}{n_{10} + n_{11}}, \qquad
    \hat r = \frac{n_{01}}{n_{01} + n_{00}}.

Intervals are exact (Clopper–Pearson). At confidence c = 1 − α the interval for p̂ has level c;
the two Gilbert–Elliott intervals have level 1 − α/2 each, so that their rectangle (Bonferroni)
covers (f, r) with probability at least c. Model choice: Gilbert–Elliott when the
likelihood-ratio test rejects i.i.d. losses at level α = 1 − c (p-value < 1 − c), else Bernoulli.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from kfcrit.errors import InputError

Model = Literal["bernoulli", "gilbert-elliott"]
Outcome = Literal["holds", "fails", "neither"]
PointVerdict = Literal["stable", "unstable", "unknown"]

MAX_SENSORS = 16
"""Largest number of sensors of a joint trace (the joint law has 2^N entries)."""
MAX_LENGTH_TO_DECIDE = 10**15
"""Largest trace length :func:`length_to_decide` searches; beyond it the answer is None."""
MIN_EXPECTED = 5.0
"""Least expected count of a bin of the burst-length goodness-of-fit test (bins are pooled)."""


def _check_confidence(confidence: float) -> float:
    c = float(confidence)
    if not (0.0 < c < 1.0):
        raise InputError(f"must be strictly between 0 and 1, got {confidence!r}"[:80],
                         field="confidence")
    return c


def as_trace(arrivals: object, field: str = "arrivals") -> np.ndarray:
    """A non-empty 1-D boolean array from a 0/1 sequence (anything else is an InputError)."""
    arr = np.asarray(arrivals)
    if arr.ndim != 1 or arr.size == 0:
        raise InputError("must be a non-empty 1-D sequence of 0 and 1", field=field)
    if arr.dtype != bool and not np.isin(arr, (0, 1)).all():
        raise InputError("only 0 and 1 are allowed", field=field)
    return arr.astype(bool)


def clopper_pearson(k: int, n: int, confidence: float) -> tuple[float, float]:
    r"""The exact (Clopper–Pearson) interval for a binomial proportion.

    .. math::

        \bigl[\,B^{-1}_{k,\,n-k+1}(\alpha/2),\ B^{-1}_{k+1,\,n-k}(1-\alpha/2)\,\bigr],
        \qquad \alpha = 1 - c,

    with B^{-1}_{a,b} the quantile function of the Beta(a, b) law; the lower end is 0 when
    k = 0 and the upper end 1 when k = n.

    Parameters
    ----------
    k : int
        Successes, 0 ≤ k ≤ n.
    n : int
        Trials; n = 0 gives the uninformative interval (0, 1).
    confidence : float
        Coverage c in (0, 1).

    Returns
    -------
    tuple of float
        (lower, upper), with lower ≤ k/n ≤ upper.
    """
    c = _check_confidence(confidence)
    k, n = int(k), int(n)
    if n < 0 or not 0 <= k <= n:
        raise InputError(f"need 0 <= k <= n, got k={k}, n={n}", field="counts")
    if n == 0:
        return 0.0, 1.0
    from scipy import stats  # imported on use: a sweep worker never needs scipy.stats

    alpha = 1.0 - c
    low = 0.0 if k == 0 else float(stats.beta.ppf(alpha / 2, k, n - k + 1))
    high = 1.0 if k == n else float(stats.beta.ppf(1 - alpha / 2, k + 1, n - k))
    return low, high


def transition_counts(arrivals: object) -> np.ndarray:
    """The 2×2 integer array ``N`` with ``N[a, b]`` = n_{ab}, the number of t with
    γ_t = a and γ_{t+1} = b (n − 1 transitions in all)."""
    x = as_trace(arrivals).astype(np.int64)
    codes = 2 * x[:-1] + x[1:]
    return np.bincount(codes, minlength=4).reshape(2, 2)


def lrt_iid_vs_markov(counts: np.ndarray) -> tuple[float, float]:
    r"""Likelihood-ratio test of i.i.d. losses against the two-state Markov chain.

    Conditioning on γ_0, the Markov log-likelihood is Σ n_{ab} log p̂_{ab} with
    p̂_{ab} = n_{ab}/n_{a·}; under i.i.d. losses both rows equal q̂_b = n_{·b}/(n − 1). The
    statistic

    .. math:: \Lambda = 2 \sum_{a,b} n_{ab} \log\frac{\hat p_{ab}}{\hat q_b}

    is asymptotically χ² with 1 degree of freedom under i.i.d. losses (the G-test of
    independence of the 2×2 transition table). A degenerate table (an empty row or column:
    a constant trace, or a single transition) gives Λ = 0 and p-value 1.

    Returns
    -------
    tuple of float
        (Λ, p-value).
    """
    n = np.asarray(counts, dtype=float)
    rows, cols, total = n.sum(axis=1), n.sum(axis=0), n.sum()
    if total == 0 or (rows == 0).any() or (cols == 0).any():
        return 0.0, 1.0
    expected = np.outer(rows, cols) / total
    mask = n > 0
    stat = max(0.0, float(2.0 * np.sum(n[mask] * np.log(n[mask] / expected[mask]))))
    from scipy import stats

    return stat, float(stats.chi2.sf(stat, 1))


@dataclass(frozen=True)
class BurstHistogram:
    r"""Loss runs (maximal runs of 0) of a trace against the fitted geometric law.

    Only *complete* runs (a 1 on both sides) are counted: a run touching either end of the trace
    is censored (its true length is at least the observed one) and only counted in
    ``censored``. The fitted law is P(length = j) = (1 − r̂)^{j−1} r̂ with r̂ of the
    Gilbert–Elliott fit. The Pearson statistic

    .. math:: X^2 = \sum_{\text{bins}} \frac{(O - E)^2}{E}

    runs over bins j = 1, 2, … and a final tail bin {j ≥ J}, pooled so that every expected
    count is at least :data:`MIN_EXPECTED`; its degrees of freedom are bins − 2 (the total and
    r̂ are fitted — r̂ from the transition counts, close to but not exactly the histogram's own
    maximum-likelihood value). With fewer than 3 bins (too few runs, or r̂ ∈ {None, 1}) the
    statistic, its degrees of freedom and p-value are None.

    Attributes
    ----------
    lengths, counts : tuple of int
        The observed complete-run lengths (increasing) and how many runs had each.
    expected : tuple of float
        Expected counts at those lengths under the fitted law (empty when r̂ is None).
    runs, censored : int
        Number of complete runs; number of runs touching an end of the trace.
    mean_length : float or None
        Mean complete-run length (1/r̂ is its fitted value).
    statistic, p_value : float or None
        Pearson X² and its χ² upper-tail probability.
    dof : int or None
        Degrees of freedom of the test.
    """

    lengths: tuple[int, ...]
    counts: tuple[int, ...]
    expected: tuple[float, ...]
    runs: int
    censored: int
    mean_length: float | None
    statistic: float | None
    dof: int | None
    p_value: float | None


def loss_runs(arrivals: object) -> tuple[np.ndarray, int]:
    """Lengths of the complete loss runs of a trace (in order) and the number of censored ones."""
    x = as_trace(arrivals)
    lost = np.concatenate(([False], ~x, [False])).astype(np.int8)
    edges = np.diff(lost)
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    complete = (starts > 0) & (ends < x.size)
    return (ends - starts)[complete], int((~complete).sum())


def burst_histogram(arrivals: object, recovery_rate: float | None) -> BurstHistogram:
    """The loss-run histogram of ``arrivals`` tested against Geometric(``recovery_rate``)."""
    lengths, censored = loss_runs(arrivals)
    values, counts = np.unique(lengths, return_counts=True)
    m = int(lengths.size)
    mean = float(lengths.mean()) if m else None
    r = recovery_rate
    if r is None or m == 0:
        return BurstHistogram(tuple(int(v) for v in values), tuple(int(c) for c in counts), (),
                              m, censored, mean, None, None, None)
    expected = tuple(float(m * (1 - r) ** (int(j) - 1) * r) for j in values)
    observed, predicted = [], []  # bins 1 … J−1, then the tail {j ≥ J}
    j, tail = 1, float(m)  # tail = expected count of {length ≥ j}
    while True:
        e_j = m * (1 - r) ** (j - 1) * r
        if e_j < MIN_EXPECTED or tail - e_j < MIN_EXPECTED:
            break
        observed.append(int((lengths == j).sum()))
        predicted.append(e_j)
        tail -= e_j
        j += 1
    observed.append(int((lengths >= j).sum()))
    predicted.append(tail)
    if len(observed) < 3:
        return BurstHistogram(tuple(int(v) for v in values), tuple(int(c) for c in counts),
                              expected, m, censored, mean, None, None, None)
    o, e = np.asarray(observed, float), np.asarray(predicted, float)
    stat = float(np.sum((o - e) ** 2 / e))
    dof = len(observed) - 2
    from scipy import stats

    return BurstHistogram(tuple(int(v) for v in values), tuple(int(c) for c in counts),
                          expected, m, censored, mean, stat, dof, float(stats.chi2.sf(stat, dof)))


@dataclass(frozen=True)
class ChannelFit:
    """Both channel models fitted to one trace, the test between them and the chosen model.

    Attributes
    ----------
    model : {"bernoulli", "gilbert-elliott"}
        Gilbert–Elliott when ``lrt_p_value < 1 - confidence``, else Bernoulli.
    n : int
        Trace length.
    p_hat, p_interval
        k/n and its Clopper–Pearson interval at ``confidence``.
    failure_rate_hat, recovery_rate_hat : float or None
        f̂ and r̂ (None when the row count n_{1·} resp. n_{0·} is zero).
    failure_rate_interval, recovery_rate_interval : tuple of float
        Clopper–Pearson intervals at 1 − (1 − confidence)/2 each (Bonferroni: their rectangle
        is a joint region at ``confidence``); (0, 1) when the row count is zero.
    lrt_p_value : float
        p-value of :func:`lrt_iid_vs_markov`.
    confidence : float
        The confidence c of the intervals and of the model choice.
    length_to_decide : int or None
        None from :func:`fit_trace`; :func:`with_length_to_decide` fills it.
    bursts : BurstHistogram
        Loss runs against the geometric law of r̂.
    """

    model: Model
    n: int
    p_hat: float
    p_interval: tuple[float, float]
    failure_rate_hat: float | None
    failure_rate_interval: tuple[float, float]
    recovery_rate_hat: float | None
    recovery_rate_interval: tuple[float, float]
    lrt_p_value: float
    confidence: float
    length_to_decide: int | None
    bursts: BurstHistogram


def fit_trace(arrivals: object, confidence: float = 0.95) -> ChannelFit:
    """Fit Bernoulli and Gilbert–Elliott models to a 0/1 trace (see the module docstring).

    Parameters
    ----------
    arrivals : sequence of 0/1 or bool
        The trace, one value per sampling period (1 = received).
    confidence : float
        Confidence c of the intervals; the LRT's level is 1 − c.
    """
    c = _check_confidence(confidence)
    x = as_trace(arrivals)
    n, k = int(x.size), int(x.sum())
    counts = transition_counts(x)
    half = 1.0 - (1.0 - c) / 2.0
    n1, n0 = int(counts[1].sum()), int(counts[0].sum())
    f_hat = counts[1, 0] / n1 if n1 else None
    r_hat = counts[0, 1] / n0 if n0 else None
    _, p_value = lrt_iid_vs_markov(counts)
    return ChannelFit(
        model="gilbert-elliott" if p_value < 1.0 - c else "bernoulli",
        n=n, p_hat=k / n, p_interval=clopper_pearson(k, n, c),
        failure_rate_hat=None if f_hat is None else float(f_hat),
        failure_rate_interval=clopper_pearson(int(counts[1, 0]), n1, half),
        recovery_rate_hat=None if r_hat is None else float(r_hat),
        recovery_rate_interval=clopper_pearson(int(counts[0, 1]), n0, half),
        lrt_p_value=p_value, confidence=c, length_to_decide=None,
        bursts=burst_histogram(x, None if r_hat is None else float(r_hat)))


# --- decision facts -------------------------------------------------------------------------

@dataclass(frozen=True)
class RegionDecision:
    """Where a monotone stability property stands on a fit's confidence region (a fact).

    ``outcome`` is ``"holds"`` (stable at the worst corner, hence on the whole region),
    ``"fails"`` (unstable at the best corner, hence nowhere on the region) or ``"neither"``.
    The corners are points ``(p,)`` for Bernoulli and ``(f, r)`` for Gilbert–Elliott.
    """

    outcome: Outcome
    model: Model
    confidence: float
    worst: tuple[float, ...]
    best: tuple[float, ...]
    at_worst: PointVerdict
    at_best: PointVerdict


def _verdict(value: object) -> PointVerdict:
    if value is True or value == "stable":
        return "stable"
    if value is False or value == "unstable":
        return "unstable"
    if value is None or value == "unknown":
        return "unknown"
    raise InputError(f"must return 'stable', 'unstable', 'unknown', True, False or None, "
                     f"got {str(value)[:40]!r}", field="predicate")


def decide_on_region(fit: ChannelFit, predicate: Callable[..., object], *,
                     model: Model | None = None) -> RegionDecision:
    r"""Evaluate a monotone stability predicate at the worst and best corners of the region.

    Bernoulli: ``predicate(p)``; the stable set is an up-set in p, so the worst corner is the
    lower end of ``p_interval`` and the best its upper end. Gilbert–Elliott:
    ``predicate(f, r)``; the stable set is assumed to be an up-set in r and a down-set in f
    (Wu, Shi, Anderson & Johansson, TAC 63(4) 2018: the critical curve splits the (f, r) plane
    monotonically; the necessary condition (1 − r) ρ² < 1 of theory §10 involves r alone), so

    .. math:: \text{worst} = (f_{\mathrm{hi}}, r_{\mathrm{lo}}), \qquad
              \text{best} = (f_{\mathrm{lo}}, r_{\mathrm{hi}}).

    The monotonicity is the caller's claim about its predicate; nothing here checks it. The
    predicate returns ``"stable"``/``"unstable"``/``"unknown"`` (or True/False/None); an
    ``"unknown"`` corner decides nothing. A corner may lie on the boundary (r = 0 when no loss
    run ended, p = 0 or 1): the predicate must accept it. A predicate stable at the worst
    corner and unstable at the best one contradicts its claimed monotonicity: an InputError.

    Parameters
    ----------
    fit : ChannelFit
        The fit whose region is used (at its ``confidence``).
    predicate : callable
        Decides stability at one point of the region.
    model : {"bernoulli", "gilbert-elliott"}, optional
        Which region to use (default: ``fit.model``).
    """
    model = model or fit.model
    if model == "bernoulli":
        worst: tuple[float, ...] = (fit.p_interval[0],)
        best: tuple[float, ...] = (fit.p_interval[1],)
    elif model == "gilbert-elliott":
        worst = (fit.failure_rate_interval[1], fit.recovery_rate_interval[0])
        best = (fit.failure_rate_interval[0], fit.recovery_rate_interval[1])
    else:
        raise InputError(f"unknown model {str(model)[:40]!r}", field="model")
    at_worst = _verdict(predicate(*worst))
    at_best = at_worst if worst == best else _verdict(predicate(*best))
    if at_worst == "stable" and at_best == "unstable":
        raise InputError(f"is not monotone: stable at the worst corner {worst} but unstable at "
                         f"the best corner {best}", field="predicate")
    outcome: Outcome = ("holds" if at_worst == "stable" else
                        "fails" if at_best == "unstable" else "neither")
    return RegionDecision(outcome, model, fit.confidence, worst, best, at_worst, at_best)


def _excludes(p_hat: float, m: int, threshold: float, level: float) -> bool:
    k = min(m, max(0, math.floor(p_hat * m + 0.5)))
    low, high = clopper_pearson(k, m, level)
    return low > threshold if p_hat > threshold else high < threshold


def rows_to_decide(p_hat: float, threshold: float, level: float, *,
                   max_rows: int = MAX_LENGTH_TO_DECIDE) -> int | None:
    """Number of binomial trials m at which the Clopper–Pearson interval at (round(p̂ m), m),
    level ``level``, lies strictly on p̂'s side of ``threshold``; None if p̂ = threshold or no
    m ≤ ``max_rows`` does.

    Search: m = 1, 2, 4, … until the interval excludes the threshold, then bisection between
    the last power of two that did not and the first that did. Because k = round(p̂ m) moves in
    steps, exclusion is not monotone in m (it may hold at m and fail at m + 1). Guaranteed: the
    interval at the returned m excludes the threshold, and at m − 1 it does not (when m > 1).
    Not guaranteed: that m is the least such m, or that every larger m excludes it (for large m
    the width shrinks like m^{-1/2} while the rounding error is at most 1/(2m), so exclusion
    becomes permanent soon after).
    """
    p_hat, threshold = float(p_hat), float(threshold)
    if not (0.0 <= p_hat <= 1.0) or not math.isfinite(threshold):
        raise InputError("need 0 <= p_hat <= 1 and a finite threshold", field="threshold")
    if p_hat == threshold:
        return None
    if _excludes(p_hat, 1, threshold, level):
        return 1
    low, high = 1, 2
    while not _excludes(p_hat, high, threshold, level):
        if high >= max_rows:
            return None
        low, high = high, min(2 * high, max_rows)
    while high - low > 1:  # invariant: excludes at high, not at low
        mid = (low + high) // 2
        if _excludes(p_hat, mid, threshold, level):
            high = mid
        else:
            low = mid
    return high


Parameter = Literal["p", "failure_rate", "recovery_rate"]


def length_to_decide(fit: ChannelFit, threshold: float, *,
                     parameter: Parameter | None = None,
                     max_length: int = MAX_LENGTH_TO_DECIDE) -> int | None:
    r"""The trace length at which the interval at the fitted value would exclude ``threshold``.

    ``parameter`` ``"p"`` (default for a Bernoulli fit): the least trace length n found by
    :func:`rows_to_decide` for p̂ at ``fit.confidence``. ``"recovery_rate"`` (default for a
    Gilbert–Elliott fit; the threshold is then the critical recovery rate at fixed f) or
    ``"failure_rate"``: the row count m from :func:`rows_to_decide` for r̂ (resp. f̂) at the
    Bonferroni level 1 − α/2, turned into the trace length whose *expected* row count is m
    under the fitted chain (a fraction f̂/(f̂ + r̂) of periods are losses, r̂/(f̂ + r̂)
    receptions):

    .. math:: n = 1 + \left\lceil m\,\frac{\hat f + \hat r}{\hat f} \right\rceil
              \quad\text{(recovery rate; } \hat r \text{ for failure rate).}

    Returns None when the fitted value equals the threshold, when a needed estimate is None or
    the chain never visits the needed state (f̂ = 0 for r, r̂ = 0 for f), or beyond
    ``max_length``. The guarantees are those of :func:`rows_to_decide` (a crossing point of the
    search, not certified to be the least length).
    """
    parameter = parameter or ("p" if fit.model == "bernoulli" else "recovery_rate")
    if parameter == "p":
        return rows_to_decide(fit.p_hat, threshold, fit.confidence, max_rows=max_length)
    f, r = fit.failure_rate_hat, fit.recovery_rate_hat
    if parameter not in ("failure_rate", "recovery_rate"):
        raise InputError(f"unknown parameter {str(parameter)[:40]!r}", field="parameter")
    if f is None or r is None:
        return None
    value, visits = (r, f) if parameter == "recovery_rate" else (f, r)
    if visits == 0:
        return None
    level = 1.0 - (1.0 - fit.confidence) / 2.0
    m = rows_to_decide(value, threshold, level, max_rows=max_length)
    if m is None:
        return None
    n = 1 + math.ceil(m * (f + r) / visits)
    return n if n <= max_length else None


def with_length_to_decide(fit: ChannelFit, threshold: float, *,
                          parameter: Parameter | None = None) -> ChannelFit:
    """``fit`` with its ``length_to_decide`` field filled by :func:`length_to_decide`."""
    return replace(fit, length_to_decide=length_to_decide(fit, threshold, parameter=parameter))


# --- joint traces of several sensors --------------------------------------------------------

@dataclass(frozen=True)
class EmpiricalJointLaw:
    r"""Empirical joint law π̂(S) of the received set S_t of N sensors (theory §13).

    Attributes
    ----------
    sensors : int
        N.
    n : int
        Common trace length.
    counts : numpy.ndarray
        Length 2^N; entry s counts the periods whose received set is {i : bit i of s is 1}.
    law : dict of frozenset of int to float
        π̂(S) = counts/n for every one of the 2^N sets S (sensor indices from 0).
    marginals : tuple of float
        p̂_i, the fraction of periods sensor i was received.
    p_all_lost : float
        π̂(∅).
    p_all_lost_interval : tuple of float
        Its Clopper–Pearson interval at ``confidence``.
    p_all_lost_product : float
        Π_i (1 − p̂_i), what independent links with these marginals would give.
    confidence : float
        Confidence of the interval.
    """

    sensors: int
    n: int
    counts: np.ndarray
    law: dict[frozenset[int], float]
    marginals: tuple[float, ...]
    p_all_lost: float
    p_all_lost_interval: tuple[float, float]
    p_all_lost_product: float
    confidence: float

    @property
    def all_lost_ratio(self) -> float:
        """π̂(∅) / Π(1 − p̂_i) (inf when the product is 0 and π̂(∅) > 0, nan when both are 0)."""
        if self.p_all_lost_product == 0.0:
            return math.inf if self.p_all_lost > 0 else math.nan
        return self.p_all_lost / self.p_all_lost_product


def joint_law(traces: Sequence[object], confidence: float = 0.95) -> EmpiricalJointLaw:
    """The empirical joint law of time-aligned traces of equal length (one per sensor).

    Raises
    ------
    InputError
        No traces, more than :data:`MAX_SENSORS`, a trace that is not 0/1, or unequal lengths.
    """
    c = _check_confidence(confidence)
    if isinstance(traces, np.ndarray) and traces.ndim == 2:
        traces = list(traces)
    if not isinstance(traces, Sequence) or isinstance(traces, (str, bytes)) or not traces:
        raise InputError("must be a non-empty list of 0/1 traces", field="traces")
    if len(traces) > MAX_SENSORS:
        raise InputError(f"at most {MAX_SENSORS} sensors, got {len(traces)}", field="traces")
    arrays = [as_trace(t, f"traces[{i}]") for i, t in enumerate(traces)]
    n = arrays[0].size
    for i, a in enumerate(arrays):
        if a.size != n:
            raise InputError(f"has length {a.size}, but traces[0] has length {n}; joint traces "
                             "must be time-aligned and of equal length", field=f"traces[{i}]")
    big_n = len(arrays)
    codes = np.zeros(n, dtype=np.int64)
    for i, a in enumerate(arrays):
        codes |= a.astype(np.int64) << i
    counts = np.bincount(codes, minlength=1 << big_n)
    counts.setflags(write=False)
    law = {frozenset(i for i in range(big_n) if s >> i & 1): float(counts[s] / n)
           for s in range(1 << big_n)}
    marginals = tuple(float(a.mean()) for a in arrays)
    return EmpiricalJointLaw(big_n, int(n), counts, law, marginals, float(counts[0] / n),
                    clopper_pearson(int(counts[0]), int(n), c),
                    float(np.prod([1.0 - m for m in marginals])), c)


__all__ = ["BurstHistogram", "ChannelFit", "EmpiricalJointLaw", "RegionDecision", "as_trace",
           "burst_histogram", "clopper_pearson", "decide_on_region", "fit_trace", "joint_law",
           "length_to_decide", "loss_runs", "lrt_iid_vs_markov", "rows_to_decide",
           "transition_counts", "with_length_to_decide"]
