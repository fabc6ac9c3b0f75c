"""Trace statistics (kfcrit.link.tracefit): exact intervals, Gilbert–Elliott counts, the LRT,
burst histograms, confidence-region facts, length to decide, joint laws.

Expected values come from elsewhere: hand counts, closed forms, and SciPy's own implementations
(``binomtest(...).proportion_ci(method='exact')`` for Clopper–Pearson, ``chi2_contingency`` with
the log-likelihood statistic for the G-test). Synthetic traces are drawn here with a plain
per-step Markov chain, not with the package's generators.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import binomtest, chi2_contingency

from kfcrit.errors import ExitCode, InputError
from kfcrit.link.tracefit import (
    ChannelFit,
    burst_histogram,
    clopper_pearson,
    decide_on_region,
    fit_trace,
    joint_law,
    length_to_decide,
    loss_runs,
    lrt_iid_vs_markov,
    rows_to_decide,
    transition_counts,
    with_length_to_decide,
)


def exact_ci(k: int, n: int, c: float) -> tuple[float, float]:
    ci = binomtest(k, n).proportion_ci(confidence_level=c, method="exact")
    return ci.low, ci.high


def markov_trace(f: float, r: float, n: int, seed: int) -> np.ndarray:
    """γ_0 … γ_{n−1} of the chain P(1→0) = f, P(0→1) = r, one uniform per step."""
    u = np.random.default_rng(seed).random(n)
    out = np.empty(n, dtype=bool)
    state = True
    for t in range(n):
        out[t] = state
        state = (u[t] >= f) if state else (u[t] < r)
    return out


# --- Clopper–Pearson --------------------------------------------------------------------------

@pytest.mark.parametrize(("k", "n", "c"), [(45, 50, 0.95), (0, 10, 0.95), (10, 10, 0.9),
                                           (1, 3, 0.99), (500, 1000, 0.5)])
def test_clopper_pearson_matches_scipy_exact(k: int, n: int, c: float) -> None:
    assert clopper_pearson(k, n, c) == pytest.approx(exact_ci(k, n, c), rel=1e-9, abs=1e-12)


def test_clopper_pearson_closed_forms_at_the_ends() -> None:
    # k = 0: upper = 1 − (α/2)^{1/n}; k = n: lower = (α/2)^{1/n}
    assert clopper_pearson(0, 10, 0.95) == pytest.approx((0.0, 1 - 0.025 ** 0.1))
    assert clopper_pearson(10, 10, 0.95) == pytest.approx((0.025 ** 0.1, 1.0))
    assert clopper_pearson(0, 0, 0.95) == (0.0, 1.0)


@pytest.mark.parametrize("c", [0.0, 1.0, -0.5, 2.0, float("nan")])
def test_confidence_outside_the_open_unit_interval_is_bad_input(c: float) -> None:
    with pytest.raises(InputError) as exc:
        clopper_pearson(1, 2, c)
    assert exc.value.field == "confidence" and exc.value.exit_code == ExitCode.BAD_INPUT


def test_bernoulli_fit_of_45_in_50() -> None:
    trace = np.r_[np.ones(45), np.zeros(5)][np.random.default_rng(3).permutation(50)]
    fit = fit_trace(trace, 0.95)
    assert fit.n == 50 and fit.p_hat == 0.9
    assert fit.p_interval == pytest.approx(exact_ci(45, 50, 0.95), rel=1e-9)
    assert fit.confidence == 0.95 and fit.length_to_decide is None


# --- Gilbert–Elliott counts on a hand-built trace ---------------------------------------------

HAND = [1, 1, 0, 0, 0, 1, 1, 1, 0, 1]
# transitions: 1→1 at (0,1) (5,6) (6,7); 1→0 at (1,2) (7,8); 0→0 at (2,3) (3,4); 0→1 at (4,5) (8,9)


def test_transition_counts_by_hand() -> None:
    assert transition_counts(HAND).tolist() == [[2, 2], [2, 3]]


def test_gilbert_elliott_fit_by_hand() -> None:
    fit = fit_trace(HAND, 0.9)
    assert fit.failure_rate_hat == pytest.approx(2 / 5)  # n_10 / (n_10 + n_11)
    assert fit.recovery_rate_hat == pytest.approx(2 / 4)  # n_01 / (n_01 + n_00)
    # Bonferroni: each interval at 1 − 0.1/2 = 0.95
    assert fit.failure_rate_interval == pytest.approx(exact_ci(2, 5, 0.95), rel=1e-9)
    assert fit.recovery_rate_interval == pytest.approx(exact_ci(2, 4, 0.95), rel=1e-9)
    assert fit.p_hat == 0.6 and fit.p_interval == pytest.approx(exact_ci(6, 10, 0.9), rel=1e-9)


def test_lrt_is_the_g_test_of_the_transition_table() -> None:
    table = np.array([[2, 2], [2, 3]])
    stat, p = lrt_iid_vs_markov(table)
    ref = chi2_contingency(table, correction=False, lambda_="log-likelihood")
    assert stat == pytest.approx(ref.statistic) and p == pytest.approx(ref.pvalue)
    # by hand: rows (4, 5), columns (4, 5), total 9
    hand = 2 * sum(o * math.log(o / e) for o, e in
                   [(2, 16 / 9), (2, 20 / 9), (2, 20 / 9), (3, 25 / 9)])
    assert stat == pytest.approx(hand)


def test_lrt_of_a_constant_trace_is_degenerate() -> None:
    assert lrt_iid_vs_markov(transition_counts([1] * 20)) == (0.0, 1.0)
    fit = fit_trace([1] * 20)
    assert fit.model == "bernoulli" and fit.recovery_rate_hat is None
    assert fit.recovery_rate_interval == (0.0, 1.0) and fit.failure_rate_hat == 0.0


def test_lrt_bursty_trace_has_tiny_p_value_and_iid_trace_a_large_one() -> None:
    bursty = fit_trace(markov_trace(0.05, 0.2, 4000, seed=11), 0.95)
    assert bursty.lrt_p_value < 1e-12 and bursty.model == "gilbert-elliott"
    assert bursty.failure_rate_interval[0] < 0.05 < bursty.failure_rate_interval[1]
    assert bursty.recovery_rate_interval[0] < 0.2 < bursty.recovery_rate_interval[1]
    iid = fit_trace(np.random.default_rng(12).random(4000) < 0.8, 0.95)
    assert iid.lrt_p_value > 0.05 and iid.model == "bernoulli"


# --- burst histogram --------------------------------------------------------------------------

def test_loss_runs_count_complete_runs_and_censored_ones() -> None:
    lengths, censored = loss_runs([0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 0])
    assert lengths.tolist() == [1, 3] and censored == 2
    hist = burst_histogram(HAND, 0.5)
    assert hist.lengths == (1, 3) and hist.counts == (1, 1) and hist.runs == 2
    assert hist.censored == 0 and hist.mean_length == 2.0
    assert hist.expected == pytest.approx((2 * 0.5, 2 * 0.25 * 0.5))  # m (1−r)^{j−1} r
    assert hist.statistic is None  # two runs: too few for any bin


def test_geometric_bursts_fit_and_constant_bursts_do_not() -> None:
    geo = fit_trace(markov_trace(0.05, 0.2, 20000, seed=5)).bursts
    assert geo.runs > 500 and geo.dof is not None and geo.dof >= 3
    assert geo.p_value is not None and geo.p_value > 0.001
    assert sum(geo.counts) == geo.runs
    fixed = fit_trace(np.tile([1] * 5 + [0] * 5, 300))  # every burst lasts exactly 5
    assert fixed.recovery_rate_hat == pytest.approx(299 / (299 + 4 * 300))
    assert fixed.bursts.lengths == (5,) and fixed.bursts.censored == 1
    assert fixed.bursts.p_value is not None and fixed.bursts.p_value < 1e-12


# --- confidence-region facts ------------------------------------------------------------------

def test_region_decision_bernoulli_corners() -> None:
    fit = fit_trace(np.r_[np.ones(90), np.zeros(10)], 0.95)
    low, high = fit.p_interval
    above = decide_on_region(fit, lambda p: p > low - 0.01, model="bernoulli")
    assert above.outcome == "holds" and above.worst == (low,) and above.best == (high,)
    below = decide_on_region(fit, lambda p: p > high + 0.01, model="bernoulli")
    assert below.outcome == "fails" and below.at_best == "unstable"
    inside = decide_on_region(fit, lambda p: "stable" if p > 0.9 else "unstable",
                              model="bernoulli")
    assert inside.outcome == "neither"
    unknown = decide_on_region(fit, lambda p: None, model="bernoulli")
    assert unknown.outcome == "neither" and unknown.at_worst == "unknown"


def test_region_decision_gilbert_elliott_uses_high_f_low_r_as_worst() -> None:
    fit = fit_trace(markov_trace(0.05, 0.3, 3000, seed=2), 0.9)
    seen: list[tuple[float, float]] = []

    def necessary(f: float, r: float) -> bool:  # (1 − r) a² < 1 with a² = 1.2
        seen.append((f, r))
        return (1 - r) * 1.2 < 1

    result = decide_on_region(fit, necessary, model="gilbert-elliott")
    (f_lo, f_hi), (r_lo, r_hi) = fit.failure_rate_interval, fit.recovery_rate_interval
    assert seen == [(f_hi, r_lo), (f_lo, r_hi)]
    assert result.outcome == ("holds" if (1 - r_lo) * 1.2 < 1 else
                              "fails" if (1 - r_hi) * 1.2 >= 1 else "neither")
    assert decide_on_region(fit, lambda f, r: (1 - r) * 50 < 1).outcome == "fails"


def test_a_predicate_stable_at_worst_and_unstable_at_best_is_rejected() -> None:
    fit = fit_trace(np.r_[np.ones(60), np.zeros(40)])
    with pytest.raises(InputError) as exc:
        decide_on_region(fit, lambda p: p < 0.6, model="bernoulli")
    assert exc.value.field == "predicate"


# --- length to decide -------------------------------------------------------------------------

def excludes(p_hat: float, m: int, thr: float, c: float) -> bool:
    k = math.floor(p_hat * m + 0.5)
    low, high = exact_ci(k, m, c)
    return low > thr if p_hat > thr else high < thr


@pytest.mark.parametrize(("p_hat", "thr"), [(0.9, 0.8), (0.9, 0.5), (0.3, 0.4), (0.0, 0.1),
                                            (1.0, 0.99), (0.75, 0.7)])
def test_rows_to_decide_is_a_crossing(p_hat: float, thr: float) -> None:
    m = rows_to_decide(p_hat, thr, 0.95)
    assert m is not None and excludes(p_hat, m, thr, 0.95)
    assert m == 1 or not excludes(p_hat, m - 1, thr, 0.95)


def test_length_to_decide_grows_as_the_threshold_nears_the_estimate() -> None:
    fit = fit_trace(np.r_[np.ones(90), np.zeros(10)], 0.95)
    lengths = [length_to_decide(fit, thr, parameter="p") for thr in (0.5, 0.7, 0.8, 0.85, 0.88)]
    assert all(isinstance(n, int) for n in lengths)
    assert lengths == sorted(lengths) and lengths[-1] > 10 * lengths[0]
    above = [length_to_decide(fit, thr, parameter="p") for thr in (0.99, 0.95, 0.92)]
    assert above == sorted(above)
    assert length_to_decide(fit, 0.9, parameter="p") is None
    # a higher confidence never needs a shorter trace here
    strict = fit_trace(np.r_[np.ones(90), np.zeros(10)], 0.99)
    assert length_to_decide(strict, 0.8, parameter="p") >= length_to_decide(fit, 0.8,
                                                                            parameter="p")


def test_length_to_decide_for_the_recovery_rate_scales_the_row_count() -> None:
    fit = fit_trace(markov_trace(0.1, 0.4, 2000, seed=8), 0.95)
    f, r = fit.failure_rate_hat, fit.recovery_rate_hat
    m = rows_to_decide(r, 0.25, 0.975)  # Bonferroni level
    assert length_to_decide(fit, 0.25, parameter="recovery_rate") == \
        1 + math.ceil(m * (f + r) / f)
    filled = with_length_to_decide(fit, 0.25)
    assert isinstance(filled, ChannelFit) and filled.length_to_decide == \
        (length_to_decide(fit, 0.25) if fit.model == "gilbert-elliott"
         else length_to_decide(fit, 0.25, parameter="p"))
    assert length_to_decide(fit_trace([1] * 30), 0.5, parameter="recovery_rate") is None


# --- joint traces -----------------------------------------------------------------------------

def test_joint_law_of_two_aligned_traces() -> None:
    a = [1, 1, 0, 0, 1, 0, 1, 1, 0, 1]
    b = [1, 0, 0, 1, 1, 0, 1, 0, 0, 1]
    law = joint_law([a, b], 0.95)
    # periods: both 1,4,6,9 → 4; only a: 1,7 → 2; only b: 3 → 1; none: 2,5,8 → 3
    assert law.counts.tolist() == [3, 2, 1, 4]
    assert law.law == {frozenset(): 0.3, frozenset({0}): 0.2, frozenset({1}): 0.1,
                       frozenset({0, 1}): 0.4}
    assert law.marginals == (0.6, 0.5)
    assert law.p_all_lost == 0.3 and law.p_all_lost_product == pytest.approx(0.4 * 0.5)
    assert law.all_lost_ratio == pytest.approx(1.5)
    assert law.p_all_lost_interval == pytest.approx(exact_ci(3, 10, 0.95), rel=1e-9)


def test_joint_law_rejects_unequal_lengths_and_non_binary() -> None:
    with pytest.raises(InputError) as exc:
        joint_law([[1, 0, 1], [1, 0]])
    assert exc.value.field == "traces[1]"
    with pytest.raises(InputError):
        joint_law([[1, 2, 1]])
    with pytest.raises(InputError):
        joint_law([])


# --- properties (small counts) ----------------------------------------------------------------

confidences = st.floats(min_value=0.5, max_value=0.999)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 400), frac=st.floats(0, 1), c=confidences)
def test_cp_interval_contains_the_estimate(n: int, frac: float, c: float) -> None:
    k = round(frac * n)
    low, high = clopper_pearson(k, n, c)
    assert 0.0 <= low <= k / n <= high <= 1.0


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 400), frac=st.floats(0, 1), c1=confidences, c2=confidences)
def test_cp_intervals_nest_as_confidence_rises(n: int, frac: float, c1: float,
                                               c2: float) -> None:
    k = round(frac * n)
    lo_c, hi_c = sorted((c1, c2))
    inner, outer = clopper_pearson(k, n, lo_c), clopper_pearson(k, n, hi_c)
    assert outer[0] <= inner[0] + 1e-15 and inner[1] <= outer[1] + 1e-15


@settings(max_examples=20, deadline=None)
@given(data=st.data(), sensors=st.integers(1, 4), n=st.integers(1, 60))
def test_joint_law_sums_to_one(data: st.DataObject, sensors: int, n: int) -> None:
    traces = [data.draw(st.lists(st.booleans(), min_size=n, max_size=n)) for _ in range(sensors)]
    law = joint_law(traces)
    assert len(law.law) == 2 ** sensors
    assert math.fsum(law.law.values()) == pytest.approx(1.0)
    assert int(law.counts.sum()) == n
    for i, traced in enumerate(traces):  # marginals from the joint law
        assert math.fsum(v for s, v in law.law.items() if i in s) == \
            pytest.approx(sum(traced) / n)
