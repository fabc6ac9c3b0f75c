"""Monte Carlo of the random Riccati equation: exactness, reproducibility, statistics, CLI.

Reference values come from independent computations: ``kfcrit.theory.covariance.riccati`` (the standard-form
Riccati maps, not the kernel's Joseph form), closed-form scalar recursions, scipy's
``solve_discrete_lyapunov`` for S̄ and a plain MARE iteration for V̄ (Sinopoli Thm 4/6), and the
Gilbert–Elliott condition (1 − r) a² < 1 of docs/theory.md §7.

Statistical tolerance. Sample means are compared with their bound using the standard error
estimated from the same sample: |mean − target| ≤ 5 · sd/√N (one-sided where the theorem is an
inequality). Where the variance is finite (checked by the moment condition stated next to each
test) the CLT makes a 5σ excursion a ~3e-7 event; the seeds are fixed, so the tests are
deterministic anyway and the tolerance documents how far from the bound a correct estimator can
plausibly be.
"""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st
from scipy.linalg import solve_discrete_lyapunov

from kfcrit.analysis.spec import load_spec
from kfcrit.cli.simulate import simulate_command, summary_text, with_progress
from kfcrit.errors import InputError
from kfcrit.io.jsonio import dumps
from kfcrit.io.systemfile import Requirements, SystemSpec
from kfcrit.io.typed import ABSENT, from_json, to_json
from kfcrit.model.channels import GilbertElliott, Trace
from kfcrit.model.system import System
from kfcrit.records.simulation import Simulation
from kfcrit.sim.kernels import LANES, lambda_max_lanes, riccati_lanes
from kfcrit.sim.montecarlo import ergodic, path_keys, simulate, simulation_section
from kfcrit.sim.stats import accumulate_log, column_stats
from kfcrit.theory.covariance.riccati import f_arrival, f_loss, g

from ..conftest import REPORTS

SCALAR = System([[-1.25]], [[1]], 1, 2.5, name="sinopoli scalar")  # p_c = 9/25
GENERAL = System([[1.25, 0], [1, 1.1]], [[1, 1]], 20, 2.5, name="sinopoli general")


def floats(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)


@st.composite
def small_systems(draw):
    """Random (A, C, Q, R) with n ≤ 3, m ≤ 2 built from bounded floats; Q, R = L L' + δ I."""
    n = draw(st.integers(1, 3))
    m = draw(st.integers(1, 2))

    def mat(r, c, k=130):  # entries in [-k/100, k/100], two decimals
        entries = st.integers(-k, k).map(lambda i: i / 100)
        return np.array(draw(st.lists(entries, min_size=r * c, max_size=r * c))).reshape(r, c)

    A, C = mat(n, n), mat(m, n)
    Lq, Lr = mat(n, n, 100), mat(m, m, 100)
    Q = Lq @ Lq.T + draw(st.integers(0, 100)) / 100 * np.eye(n)
    R = Lr @ Lr.T + draw(st.integers(5, 200)) / 100 * np.eye(m)
    return A, C, 0.5 * (Q + Q.T), 0.5 * (R + R.T)


def mare_fixed_point(A, C, Q, R, p, iters=5000):
    """V̄ = lim V_t, V_{t+1} = g_p(V_t), V_0 = 0 (Sinopoli Thm 1, converges for p > p_up)."""
    V = np.zeros_like(A, dtype=float)
    for _ in range(iters):
        V = g(A, C, Q, R, V, p)
    return V


# --------------------------------------------------------------------------------------------
# exactness of the kernel


def trace_offset(seed, i, length):
    """Start of path i in a trace of ``length`` values: its key (NumPy's own SeedSequence)
    modulo the length (documented in simulate)."""
    key = np.random.SeedSequence(seed, spawn_key=(0, i)).generate_state(1, np.uint64)[0]
    return int(key % np.uint64(length))


@given(small_systems(), st.lists(st.booleans(), min_size=1, max_size=25))
def test_kernel_follows_the_standard_riccati_maps(sysmats, arrivals):
    """Paths of a trace channel read the trace from offset key_i mod L: compare with
    kfcrit.theory.covariance.riccati on the rotated trace."""
    A, C, Q, R = sysmats
    system = System(A, C, Q, R)
    L = len(arrivals)
    res = simulate(system, 2, L, 0, Trace.from_arrivals(arrivals),
                   record_traces=True, divergence_threshold=1e300)
    for i in range(2):
        k = trace_offset(0, i, L)
        P = system.sigma0.copy()
        expected = [np.trace(P)]
        for t in range(L):
            P = f_arrival(A, C, Q, R, P) if arrivals[(k + t) % L] else f_loss(A, Q, P)
            expected.append(np.trace(P))
        np.testing.assert_allclose(res.traces[i], expected, rtol=1e-9, atol=1e-12)


@given(small_systems(), st.integers(0, 6), floats(0.0, 1.0), st.integers(1, 9))
def test_lane_step_is_symmetric_psd_and_equals_the_maps(sysmats, rank, scale, lanes):
    """One kernel step on rank-deficient PSD X: exactly symmetric, PSD, equal to f_γ(X)."""
    A, C, Q, R = sysmats
    n, m = A.shape[0], C.shape[0]
    rng_free = np.arange(1, n * n + 1, dtype=float).reshape(n, n)  # deterministic, no RNG
    L = np.cos(rng_free * (1 + scale))[:, : min(rank, n)]
    X = 10.0 ** (4 * scale) * (L @ L.T)
    Xs = np.repeat(X[:, :, None], lanes, axis=2).copy()
    gam = np.repeat((np.arange(lanes) % 2).astype(float)[None, :], m, axis=0)  # one sensor
    out = np.empty_like(Xs)
    ws = [np.empty((n, n, lanes)) for _ in range(2)]
    wm = [np.empty((n, m, lanes)), np.empty((m, m, lanes)), np.empty((n, m, lanes)),
          np.empty((n, m, lanes))]
    ones, zeros = np.ones(lanes), np.zeros(lanes)
    riccati_lanes(A, C, Q, R, Xs, gam, lanes, out, ws[0], ws[1], wm[0], wm[1], wm[2], wm[3],
                   False, ones, zeros)
    # the scaled branch with c = 1 and no loading is the same arithmetic, bit for bit
    out_scaled = np.empty_like(Xs)
    riccati_lanes(A, C, Q, R, Xs, gam, lanes, out_scaled, ws[0], ws[1], wm[0], wm[1], wm[2],
                   wm[3], True, ones, zeros)
    assert np.array_equal(out, out_scaled)
    for b in range(lanes):
        Y = out[:, :, b]
        assert np.array_equal(Y, Y.T)
        ref = f_arrival(A, C, Q, R, X) if gam[0, b] else f_loss(A, Q, X)
        tol = 1e-9 * max(1.0, np.abs(ref).max())
        np.testing.assert_allclose(Y, ref, rtol=1e-8, atol=tol)
        assert np.linalg.eigvalsh(Y).min() >= -tol


@given(st.integers(1, 6), st.integers(1, 6), st.lists(st.integers(-9, 9), min_size=36,
                                                       max_size=36), st.integers(-3, 3))
def test_lambda_max_bisection_matches_eigvalsh(n, rank, entries, exponent):
    """λ_max by Cholesky bisection (n ≥ 3) or closed form (n ≤ 2) against LAPACK's eigvalsh."""
    L = np.array(entries[: n * n], dtype=float).reshape(n, n)[:, : min(rank, n)]
    X = 10.0 ** exponent * (L @ L.T)
    W = 3
    Xs = np.repeat(X[:, :, None], W, axis=2).copy()
    Xs[:, :, 1] *= 2.0
    out = np.empty(W)
    work = [np.empty(W) for _ in range(5)]
    lambda_max_lanes(Xs, W, out, np.empty_like(Xs), *work)
    for b in range(W):
        ref = np.linalg.eigvalsh(Xs[:, :, b])[-1]
        assert abs(out[b] - ref) <= 1e-10 * max(np.trace(Xs[:, :, b]), 1e-300)


def test_p_one_and_p_zero_follow_the_deterministic_recursions():
    a2, q, r = 1.5625, 1.0, 2.5
    res = simulate(SCALAR, 5, 30, 1, arrival_probability=1, horizon_samples=31)
    x, xs = 1.0, [1.0]
    for _ in range(30):
        x = a2 * r * x / (x + r) + q  # f_1 for c = 1
        xs.append(x)
    np.testing.assert_allclose(res.mean_trace, xs, rtol=1e-12)
    assert np.all(res.std_trace <= 1e-9 * np.asarray(xs))
    res0 = simulate(SCALAR, 3, 20, 1, arrival_probability=0, horizon_samples=21)
    lyap = [a2 ** t + q * (a2 ** t - 1) / (a2 - 1) for t in range(21)]
    np.testing.assert_allclose(res0.mean_trace, lyap, rtol=1e-12)


# --------------------------------------------------------------------------------------------
# reproducibility and records


@pytest.mark.parametrize("seed", [0, 1, 42, 2 ** 32 + 7, 2 ** 63 - 1, 3 ** 80])
def test_path_keys_are_seedsequence_spawn_children(seed):
    children = np.random.SeedSequence(seed).spawn(3)
    for stream in (0, 2):
        grand = children[stream].spawn(10)
        expected = [c.generate_state(1, np.uint64)[0] for c in grand]
        np.testing.assert_array_equal(path_keys(seed, 0, 10, stream), expected)
        np.testing.assert_array_equal(path_keys(seed, 4, 7, stream), expected[4:7])
    big = 70_000
    ref = np.random.SeedSequence(seed, spawn_key=(0, big)).generate_state(1, np.uint64)[0]
    assert path_keys(seed, big, big + 1)[0] == ref


@pytest.mark.parametrize("channel", [None, GilbertElliott(sp.Rational(1, 5), sp.Rational(1, 2))])
def test_bit_identical_for_any_batch_size(channel):
    kw = {"arrival_probability": 0.6} if channel is None else {"channel": channel}
    paths = LANES + 37
    ref = simulate(GENERAL, paths, 60, 5, **kw)
    for bs in (1, 7, 1000):
        other = simulate(GENERAL, paths, 60, 5, batch_size=bs, **kw)
        for name in ("mean_trace", "std_trace", "mean_lambda_max", "horizon_traces"):
            assert np.array_equal(getattr(ref, name), getattr(other, name)), (bs, name)
    again = simulate(GENERAL, paths, 60, 5, **kw).to_dict()
    first = ref.to_dict()
    first.pop("runtime_seconds")
    again.pop("runtime_seconds")
    assert first == again
    assert not np.array_equal(simulate(GENERAL, paths, 60, 6, **kw).horizon_traces,
                              ref.horizon_traces)


def test_paths_are_independent_of_how_many_are_run():
    few = simulate(GENERAL, 3, 40, 9, arrival_probability=0.5, record_traces=True)
    many = simulate(GENERAL, 300, 40, 9, arrival_probability=0.5, record_traces=3)
    np.testing.assert_array_equal(few.traces, many.traces)


def test_memory_does_not_grow_with_steps():
    res = simulate(SCALAR, 10, 20_000, 0, arrival_probability=0.7)
    assert res.times.size <= 200 and res.traces is None and res.horizon_traces.size == 10
    assert res.times[0] == 0 and res.times[-1] == 20_000


def test_divergence_is_detected_reported_and_json_safe():
    # p = 0, a = 2, c = q = r = 1, P0 = 1: tr P_t = 4^t + (4^t − 1)/3 by hand; first > 1e6 at t = 10
    system = System([[2]], [[1]], 1, 1)
    res = simulate(system, 4, 30, 0, arrival_probability=0, divergence_threshold=1e6,
                   horizon_samples=31)
    assert res.diverged_paths == 4 and not res.mean_is_lower_bound
    assert list(res.divergence_times) == [10] * 4
    assert np.all(res.diverged_fraction[res.times >= 10] == 1)
    assert np.all(res.diverged_fraction[res.times < 10] == 0)
    assert np.all(res.above_threshold_fraction == res.diverged_fraction)  # never comes back
    exact = np.array([4.0 ** t + (4.0 ** t - 1) / 3 for t in res.times])
    np.testing.assert_allclose(res.mean_trace, exact, rtol=1e-12)   # continued, not censored
    assert res.warnings and "scaled form" in res.warnings[0]
    d = res.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["divergence"]["first_time"] == 10 and not d["divergence"]["mean_is_lower_bound"]
    assert d["horizon"]["quantiles"][-1] == pytest.approx(exact[-1], rel=1e-12)


def test_a_path_that_crossed_the_threshold_comes_back_down():
    """The auditor's repro: a = 1.25, c = q = 1, r = 2.5, p = 0.8, threshold 5. Arrivals pull
    P back below 5 (the Riccati fixed point is < 5), so stopping a crossed path at 5 overstated
    the mean. Independent reference: the scalar recursions f0(P) = a²P + q,
    f1(P) = a²P + q − a²P²/(P + r) in plain Python on the same 0/1 trace (rotated by key mod L),
    with no threshold at all."""
    a, q, r = 1.25, 1.0, 2.5
    system = System([[a]], [[1]], q, r)
    arrivals = [bool(x) for x in np.random.default_rng(3).random(101) < 0.8]
    paths, steps = 40, 150
    res = simulate(system, paths, steps, 4, Trace.from_arrivals(arrivals),
                   divergence_threshold=5.0, horizon_samples=steps + 1, initial=[[1.0]])
    ref = np.empty((paths, steps + 1))
    for i in range(paths):
        k, P = trace_offset(4, i, len(arrivals)), 1.0
        ref[i, 0] = P
        for t in range(steps):
            P = a * a * P + q - (a * a * P * P / (P + r) if arrivals[(k + t) % 101] else 0.0)
            ref[i, t + 1] = P
    assert res.diverged_paths > 0 and not res.mean_is_lower_bound
    np.testing.assert_allclose(res.mean_trace, ref.mean(axis=0), rtol=1e-10)
    np.testing.assert_allclose(np.sort(res.horizon_traces), np.sort(ref[:, -1]), rtol=1e-10)
    # crossing is still reported, and the fraction above the threshold now falls again
    assert res.diverged_fraction[-1] == np.mean((ref > 5.0).any(axis=1))
    np.testing.assert_array_equal(res.above_threshold_fraction, (ref > 5.0).mean(axis=0))
    assert res.above_threshold_fraction[-1] < res.diverged_fraction[-1]


def test_values_beyond_float64_are_reported_as_log10():
    # p = 0, a = 10, c = q = r = 1, P0 = 1: tr P_t = 100^t + (100^t − 1)/99, so at t = 400
    # log10 tr P = 800 + log10(1 + 1/99) (hand derivation); far beyond float64 (1.8e308)
    system = System([[10]], [[1]], 1, 1)
    res = simulate(system, 3, 400, 0, arrival_probability=0, initial=[[1.0]])
    expected = 800 + math.log10(1 + 1 / 99)
    assert res.mean_trace[-1] == math.inf and not np.isnan(res.mean_trace).any()
    assert res.log10_mean_trace[-1] == pytest.approx(expected, abs=1e-9)
    assert res.log10_mean_lambda_max[-1] == pytest.approx(expected, abs=1e-9)  # n = 1
    assert res.horizon_log10_quantiles()[4] == pytest.approx(expected, abs=1e-9)
    t50 = int(np.flatnonzero(res.times >= 50)[0])   # still a float: same value both ways
    tt = int(res.times[t50])
    assert res.mean_trace[t50] == pytest.approx(100.0 ** tt * (1 + 1 / 99), rel=1e-12)
    d = json.loads(dumps(res.to_dict()))
    assert d["mean_trace"]["overflow"] is True and d["mean_trace"]["mean"][-1] is None
    assert d["mean_trace"]["log10_mean"][-1] == pytest.approx(expected, abs=1e-9)
    assert d["horizon"]["log10_mean"] == pytest.approx(expected, abs=1e-9)
    assert "10^800.004" in simulate_summary(res)


def simulate_summary(res):
    return summary_text(res)


def test_log_sum_exp_moments_by_hand():
    """Values 1e400 and 1e401 (as logs): mean 5.5e400, sample sd 9e400/√2."""
    ln10 = math.log(10)
    lv = np.array([[400 * ln10], [401 * ln10]])
    lmax, s1, s2 = np.full(1, -np.inf), np.zeros(1), np.zeros(1)
    accumulate_log(lv[:1], lmax, s1, s2)   # in two batches: a new maximum rescales the sums
    accumulate_log(lv[1:], lmax, s1, s2)
    _, _, lmean, lstd = column_stats(2, np.full(1, np.inf), np.full(1, np.nan), lmax, s1, s2)
    assert lmean[0] == pytest.approx(400 + math.log10(5.5), abs=1e-12)
    assert lstd[0] == pytest.approx(400 + math.log10(9 / math.sqrt(2)), abs=1e-12)


def test_bit_identical_for_any_batch_size_with_diverging_paths():
    """Blocks holding scaled (crossed) lanes take the scaled kernel branch; the other lanes of
    such a block must not change by a bit."""
    kw = {"arrival_probability": 0.45, "divergence_threshold": 1e4}
    ref = simulate(GENERAL, 300, 120, 5, **kw)
    assert 0 < ref.diverged_paths < 300
    for bs in (1, 7, 1000):
        other = simulate(GENERAL, 300, 120, 5, batch_size=bs, **kw)
        for name in ("mean_trace", "std_trace", "mean_lambda_max", "horizon_traces",
                     "log10_mean_trace", "divergence_times"):
            assert np.array_equal(getattr(ref, name), getattr(other, name)), (bs, name)


def test_progress_is_reported_in_step_chunks(monkeypatch):
    """A run with fewer paths than one batch still reports progress as the steps advance,
    and the chunking changes no number (diverging lanes carry their scaled state across)."""
    import kfcrit.sim.engine as engine

    kw = {"arrival_probability": 0.45, "divergence_threshold": 1e4}
    ref = simulate(GENERAL, 50, 900, 2, record_traces=2, **kw)
    monkeypatch.setattr(engine, "PROGRESS_WORK", 50 * 4 * 100)   # 100 steps per kernel call
    calls = []
    res = simulate(GENERAL, 50, 900, 2, record_traces=2, progress=lambda d, t: calls.append((d, t)),
                   **kw)
    assert [d for d, _ in calls] == [50 * s for s in range(100, 1000, 100)]
    assert all(t == 50 * 900 for _, t in calls)
    for name in ("mean_trace", "std_trace", "mean_lambda_max", "horizon_traces", "traces",
                 "divergence_times"):
        assert np.array_equal(getattr(ref, name), getattr(res, name)), name


@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan, 0.0, -1.0, "x", True])
def test_divergence_threshold_must_be_finite_and_positive(bad):
    with pytest.raises(InputError, match="divergence_threshold"):
        simulate(SCALAR, 5, 10, 0, arrival_probability=0.5, divergence_threshold=bad)
    with pytest.raises(InputError, match="divergence_threshold"):
        ergodic(SCALAR, 50, 0, arrival_probability=0.5, divergence_threshold=bad)


def test_far_below_critical_long_horizon_stays_finite():
    # (1 − p) a² = 0.98 · 1.5625 > 1: E[tr P_t] grows without bound; loss runs of a few hundred
    # steps take single paths far beyond the threshold
    res = simulate(SCALAR, 300, 5000, 2, arrival_probability=0.02)
    assert not np.isnan(res.mean_trace).any() and not np.isnan(res.horizon_traces).any()
    assert np.all(np.isfinite(res.log10_mean_trace)) and np.all(np.isfinite(
        res.horizon_log10_traces))
    assert res.diverged_paths > 0 and res.failed_paths == 0
    # the crossed paths were continued: the mean is not held at the threshold
    assert res.mean_trace.max() > res.divergence_threshold
    json.dumps(res.to_dict(), allow_nan=False)
    json.loads(dumps(res.to_dict()))


def test_bad_arguments():
    with pytest.raises(InputError):
        simulate(SCALAR, 0, 10, 0, arrival_probability=0.5)
    with pytest.raises(InputError):
        simulate(SCALAR, 10, 10, 0)
    with pytest.raises(InputError):
        simulate(SCALAR, 10, 10, 0, arrival_probability=1.5)
    with pytest.raises(InputError):
        simulate(SCALAR, 10, 10, 0, channel=GilbertElliott(sp.Rational(1, 2), sp.Rational(1, 2)),
                 arrival_probability=0.5)
    with pytest.raises(InputError):
        simulate(SCALAR, 10, 10, 0, arrival_probability=0.5, initial=[[-1.0]])
    with pytest.raises(InputError, match="GB"):
        simulate(SCALAR, 10**6, 10**6, 0, arrival_probability=0.5, record_traces=True)


# --------------------------------------------------------------------------------------------
# statistics against the theory


def test_full_state_error_matches_the_riccati_covariance():
    """E[e_t e_t' | γ] = P_t: the mean of |e_t|² equals the mean of tr P_t (Kalman filter)."""
    res = simulate(GENERAL, 300, 40, 3, arrival_probability=0.7, full_state_paths=300)
    fs = res.full_state
    e = fs.error_sq[:, 20:].ravel()
    tr = fs.trace[:, 20:].ravel()
    # paths share arrivals with the RRE paths: the filter's P is the RRE's P
    np.testing.assert_allclose(fs.trace[:, -1], res.horizon_traces[:300], rtol=1e-9)
    # |e|² − tr P has mean 0; errors at one path are correlated in time, so use path totals
    per_path = (fs.error_sq[:, 20:] - fs.trace[:, 20:]).mean(axis=1)
    se = per_path.std(ddof=1) / math.sqrt(per_path.size)
    assert abs(per_path.mean()) < 5 * se
    assert 0.8 < e.mean() / tr.mean() < 1.25


@pytest.mark.parametrize("system,p", [(SCALAR, 0.8), (GENERAL, 0.8)])
def test_above_p_up_the_mean_settles_between_the_bounds(system, p):
    """S̄ ⪯ lim E[P_t] ⪯ V̄ (Sinopoli Thm 4, 6) for p > p_up (0.36 scalar, ≈0.471 general).

    Finite variance: (1 − p)·ρ(A)⁴ = 0.2·1.25⁴ ≈ 0.49 < 1, so the 5σ CLT tolerance applies.
    """
    A, C, Q, R = system.a, system.c, system.q, system.r
    S_bar = solve_discrete_lyapunov(math.sqrt(1 - p) * A, Q)
    V_bar = mare_fixed_point(A, C, Q, R, p)
    res = simulate(system, 4000, 150, 11, arrival_probability=p)
    mean, se = res.mean_trace[-1], res.std_trace[-1] / math.sqrt(res.paths)
    assert np.trace(S_bar) - 5 * se <= mean <= np.trace(V_bar) + 5 * se
    assert np.trace(S_bar) < np.trace(V_bar)


@pytest.mark.parametrize("system,p", [(SCALAR, 0.15), (GENERAL, 0.2)])
def test_below_p_low_the_mean_grows_at_least_like_the_lyapunov_bound(system, p):
    """E[P_t] ⪰ S_t, S_{t+1} = (1 − p) A S_t A' + Q, S_0 = Σ0 (Lemma 1(f)/(h) by induction).

    (1 − p)ρ(A)² > 1 here, so S_t grows geometrically. Heavy tails make the sample mean
    underestimate E[P_t] at large t; at t ≤ 40 the dominant event (a loss burst of length
    ~ t) still has ≳ 30 occurrences among the paths, and the check is one-sided with 5 se.
    """
    A, Q = system.a, system.q
    res = simulate(system, 20_000, 40, 4, arrival_probability=p, horizon_samples=41)
    S = system.sigma0.copy()
    lower = [np.trace(S)]
    for _ in range(40):
        S = (1 - p) * A @ S @ A.T + Q
        lower.append(np.trace(S))
    se = res.std_trace / math.sqrt(res.paths)
    assert np.all(res.mean_trace >= np.array(lower) - 5 * se)
    assert lower[-1] > 100 * lower[0]  # the bound itself explodes
    assert res.mean_trace[-1] > 100 * res.mean_trace[0]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sinopoli-single-unstable", "sinopoli-general",
                                  "mo-nondegenerate-four"])
def test_bounds_bracket_the_mean_on_the_examples_slow(name):
    """Thorough profile: S̄ − 5 se ≤ E[tr P_t] ≤ V̄ + 5 se at p = (1 + p_up)/2 on paper examples,
    p_up estimated independently as the least p on a 0.01 grid where the MARE iteration from 0
    stays bounded (MATH §3, equivalent characterisation)."""
    system = load_spec(REPORTS / f"{name}.yaml").system
    A, C, Q, R = system.a, system.c, system.q, system.r

    def bounded(p):
        V = np.zeros_like(A)
        for _ in range(3000):
            V = g(A, C, Q, R, V, p)
            if not np.isfinite(V).all() or np.trace(V) > 1e12:
                return False
        return True

    p_up = next(p for p in np.arange(0.01, 1.0, 0.01) if bounded(p))
    p = (1 + p_up) / 2
    rho = max(abs(np.linalg.eigvals(A)))
    if (1 - p) * rho ** 4 >= 1:
        pytest.skip("infinite variance at this p: the CLT tolerance does not apply")
    S_bar = solve_discrete_lyapunov(math.sqrt(1 - p) * A, Q)
    V_bar = mare_fixed_point(A, C, Q, R, p)
    res = simulate(system, 40_000, 300, 13, arrival_probability=p)
    mean, se = res.mean_trace[-1], res.std_trace[-1] / math.sqrt(res.paths)
    assert np.trace(S_bar) - 5 * se <= mean <= np.trace(V_bar) + 5 * se


A2 = System([[2]], [[1]], 1, 1, name="a = 2")  # GE condition: bounded iff (1 − r)·4 < 1


def burst_growth_factor(channel) -> float:
    """Estimate (1 − r)·a² from one long path: burst-length tail ratio × growth per lost step."""
    erg = ergodic(A2, 400_000, 1, channel, replicas=1, max_burst=12)
    d = erg.to_dict()["bursts"]
    count = np.array(d["count"], dtype=float)[:8]
    after = np.array([x if x is not None else np.nan for x in d["mean_trace_after"]])[:8]
    tail = np.nanmean(count[1:] / count[:-1])
    growth = np.nanmean(after[1:] / after[:-1])
    return tail * growth


@pytest.mark.parametrize("f,r,bounded", [(0.9, 0.95, True), (0.01, 0.5, False)])
def test_gilbert_elliott_mean_bounded_iff_condition(f, r, bounded):
    """MATH §7: E[P] bounded iff (1 − r) a² < 1. The two channels are chosen so that the
    stationary arrival probability says the opposite (0.51 < 0.75 = iid p_c but bounded;
    0.98 > 0.75 but unbounded): only r decides. The mechanism is measured: P(burst = j+1)/P(j)
    → 1 − r and E[tr P after a burst of j+1]/E[… j] → a², so Σ_j P(j)·E[P | j] converges iff
    their product is below 1."""
    ch = GilbertElliott(sp.nsimplify(f), sp.nsimplify(r))
    factor = burst_growth_factor(ch)
    expected = (1 - r) * 4
    assert abs(factor - expected) < 0.25 * expected
    assert (factor < 1) == bounded == ((1 - r) * 4 < 1)


def test_gilbert_elliott_direct_means():
    """Bounded (f, r) = (0.9, 0.95): E[tr P_t] at t = 100 and 200 agree ((1 − r)a⁴ = 0.8 < 1,
    finite variance); unbounded (0.5, 0.25), (1 − r) a² = 3: the mean keeps growing."""
    ok = simulate(A2, 8000, 200, 3, GilbertElliott(sp.Rational(9, 10), sp.Rational(19, 20)),
                  horizon_samples=201)
    se = ok.std_trace / math.sqrt(ok.paths)
    assert abs(ok.mean_trace[100] - ok.mean_trace[200]) < 5 * math.hypot(se[100], se[200])
    bad = simulate(A2, 8000, 30, 3, GilbertElliott(sp.Rational(1, 2), sp.Rational(1, 4)),
                   horizon_samples=31)
    assert bad.mean_trace[30] > 10 * bad.mean_trace[15] > 10 * bad.mean_trace[5]


def test_ergodic_time_average_matches_the_ensemble_mean():
    """Kar et al. Prop. 25: (1/T) Σ tr P_t → E_μ[tr P] = lim E[tr P_t] (p = 0.8 > p_c)."""
    erg = ergodic(SCALAR, 200_000, 5, arrival_probability=0.8, replicas=4)
    pooled = erg.pooled()
    ens = simulate(SCALAR, 20_000, 200, 5, arrival_probability=0.8)
    se_ens = ens.std_trace[-1] / math.sqrt(ens.paths)
    half = (pooled.upper - pooled.lower) / 2
    assert abs(pooled.mean - ens.mean_trace[-1]) < 2.5 * math.hypot(half, 1.96 * se_ens)
    d = erg.to_dict()
    json.dumps(d, allow_nan=False)
    b = d["bursts"]
    assert abs(b["loss_fraction"] - 0.2) < 0.01 and abs(b["mean_length"] - 1.25) < 0.05


def test_tail_levels_count_visits():
    """The tail estimate is the fraction of times above M: compare with a recorded trace.

    Both read the trace from their stream key mod L (ergodic replica j: key of
    SeedSequence(seed, spawn_key=(2, j))); the simulated path gets the trace rotated so that it
    starts where the ergodic replica does."""
    seq = [1, 0, 1, 1, 0, 0, 1, 1, 1, 0, 0, 0, 1]
    key = np.random.SeedSequence(0, spawn_key=(2, 0)).generate_state(1, np.uint64)[0]
    start = (int(key % np.uint64(13)) - trace_offset(0, 0, 13)) % 13
    res = simulate(SCALAR, 1, 3000, 0, Trace.from_arrivals(seq[start:] + seq[:start]),
                   record_traces=True)
    erg = ergodic(SCALAR, 3000, 0, Trace.from_arrivals(seq),
                  replicas=1, burn_in=0, levels=(5.0, 10.0))
    tr = res.traces[0, 1:]
    assert erg.exceed[0].tolist() == [float((tr > 5).sum()), float((tr > 10).sum())]
    assert erg.sums[0, 0] == pytest.approx(tr.sum(), rel=1e-12)


def test_almost_sure_indicators_below_critical():
    """Unstable A, i.i.d. 0 < p < 1: limsup tr P = ∞ and liminf bounded (MATH §6): the dyadic
    block maxima of one long path grow while the block minima stay near tr P* (arrivals pull
    the covariance down to f_1-images)."""
    erg = ergodic(SCALAR, 2 ** 17, 8, arrival_probability=0.5, replicas=1, burn_in=0)
    a = erg.to_dict()["almost_sure"]
    bmax = [x for x in a["block_max"] if x is not None]
    bmin = [x for x in a["block_min"] if x is not None]
    assert max(bmax[-4:]) > 20 * max(bmax[:4])
    assert max(bmin[-6:]) < 10


# --------------------------------------------------------------------------------------------
# the analysis section and the command line


def test_simulation_section_keys_and_json():
    spec = SystemSpec(system=SCALAR, channel=GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2)),
                      requirements=Requirements(max_error_trace=20.0))
    sim = simulation_section(spec, critical_value=0.36, upper_bound=0.36, seed=3, quick=True)
    assert isinstance(sim, Simulation)
    d = to_json(sim)
    # wall-clock seconds are no record field
    assert set(d) == {"seed", "quick", "budget", "seeds", "operating_point", "phase_demo",
                      "checks", "warnings"}
    assert sim.checks and all(c.passed for c in sim.checks)
    assert {"check", "passed", "status", "detail"} == set(d["checks"][0])
    # p_c = 9/25 is given: the variance condition is the general one, q / (1 - p_c)^2
    op = sim.operating_point
    assert op.reliability.variance_condition == "(1 - r) / (1 - p_c)^2"
    assert op.mean_exists is True   # r = 1/2 > p_c (burst claim)
    for key in ("channel", "arrival_probability", "iid", "times", "mean_trace",
                "mean_lambda_max", "horizon", "exceedance", "ergodic", "bursts", "almost_sure",
                "divergence"):
        assert key in d["operating_point"]
    assert "runtime_seconds" not in d["operating_point"]
    assert len(op.times) <= 200 and op.exceedance.level == 20.0
    assert op.ergodic.time_averages.path.tail[0].level == 20.0
    demo = sim.phase_demo
    assert demo.reference == "critical_value" and len(demo.curves) == 4
    below = [c for c in demo.curves if c.side == "below"]
    above = [c for c in demo.curves if c.side == "above"]
    assert min(c.mean_trace[-1] for c in below) > max(c.mean_trace[-1] for c in above)
    assert sim.seeds.phase_demo == [4, 5, 6, 7]
    text = dumps(d)
    assert "NaN" not in text and "Infinity" not in text


def _native_leaves(value, path="simulation"):
    """(path, type name) of every leaf of a typed record that is not a plain Python value."""
    if dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            yield from _native_leaves(getattr(value, f.name), f"{path}.{f.name}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            yield from _native_leaves(v, f"{path}[{i}]")
    elif value is not None and value is not ABSENT and type(value) not in (bool, int, float, str):
        yield path, type(value).__name__
    elif type(value) is float and not math.isfinite(value):
        yield path, repr(value)


@pytest.mark.parametrize("p", [sp.Rational(3, 10), sp.Rational(7, 10)])
def test_simulation_section_is_built_typed_with_plain_values(p):
    """Every leaf is a plain finite Python value (no NumPy or sympy number), so the section
    survives its JSON round trip unchanged: below p_c (means withheld) and above."""
    from kfcrit.model.channels import Bernoulli

    spec = SystemSpec(system=SCALAR, channel=Bernoulli(p),
                      requirements=Requirements(max_error_trace=20.0))
    sim = simulation_section(spec, critical_value=0.36, upper_bound=0.36, seed=2, quick=True)
    assert list(_native_leaves(sim)) == []
    assert from_json(Simulation, to_json(sim)) == sim


def test_simulation_section_without_channel_or_reference():
    d = simulation_section(SystemSpec(system=SCALAR), critical_value=None, upper_bound=None,
                           seed=0, quick=True)
    assert d.operating_point is None and d.phase_demo is None
    d0 = simulation_section(SystemSpec(system=SCALAR), critical_value=0.0, upper_bound=0.5,
                            seed=0, quick=True)
    assert d0.phase_demo is None
    du = simulation_section(SystemSpec(system=SCALAR), critical_value=None, upper_bound=0.36,
                            seed=0, quick=True)
    assert du.phase_demo.reference == "upper_bound"


def test_simulate_command_json_text_and_plot(tmp_path, capsys):
    f = str(REPORTS / "sinopoli-scalar.yaml")
    assert simulate_command(f, paths=50, steps=40, seed=1, as_json=True, plot=None,
                            max_states=400) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["paths"] == 50 and d["arrival_probability"] == 0.5
    out = tmp_path / "fig.svg"
    assert simulate_command(f, paths=50, steps=40, seed=1, as_json=False, plot=str(out),
                            max_states=400) == 0
    text = capsys.readouterr().out
    assert "E[tr P_t]" in text and "50 paths" in text
    assert out.read_text()[:200].lstrip().startswith(("<?xml", "<svg"))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".kfcrit-")]
    with pytest.raises(InputError, match="svg"):
        simulate_command(f, paths=5, steps=5, seed=1, as_json=False, plot=str(tmp_path / "x.gif"),
                         max_states=400)


def test_progress_bar_path_runs_and_reports(capsys):
    """The rich progress path (used only when stderr is a terminal) gives the same result."""
    spec = load_spec(REPORTS / "sinopoli-scalar.yaml")
    res = with_progress(spec, 600, 20, 3, False)
    ref = simulate(spec.system, 600, 20, 3, spec.channel)
    assert np.array_equal(res.mean_trace, ref.mean_trace)
    assert capsys.readouterr().out == ""  # nothing on stdout


def test_numpy_scalars_are_accepted_as_probabilities():
    a = simulate(SCALAR, 20, 10, 0, arrival_probability=np.float64(0.5))
    b = simulate(SCALAR, 20, 10, 0, arrival_probability=0.5)
    assert np.array_equal(a.horizon_traces, b.horizon_traces)


def test_simulate_command_needs_a_channel(tmp_path):
    spec_file = tmp_path / "nochan.yaml"
    spec_file.write_text("name: x\nA: [[2]]\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n")
    with pytest.raises(InputError, match="channel"):
        simulate_command(str(spec_file), paths=5, steps=5, seed=0, as_json=True, plot=None,
                         max_states=400)


# a mesh's received sets come from its hop outcomes: its Monte Carlo is tested in
# tests/analysis/test_mesh_record.py against the mesh verdict
EXAMPLE_FILES = [p for p in sorted(REPORTS.glob("*.yaml"))
                 if not p.name.startswith(("sweep", "mesh-"))]


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.stem)
def test_example_files_simulate(path):
    """Every example simulates to a finite, seeded, self-consistent record: the mean of tr P_t
    starts at tr Σ0 exactly and never falls below the deterministic lower bound tr S_t of
    Sinopoli Lemma 1(f) (i.i.d. channels) beyond 5 standard errors, nor above the censoring
    threshold; quantiles are ordered; diverged paths are counted, not propagated."""
    spec = load_spec(path)
    paths, steps = 64, 40
    if spec.network is not None:   # each sensor over its own link, rows of the stacked C
        sensors = [(list(range(sl.start, sl.stop)), s.channel)
                   for sl, s in zip(spec.network.row_slices(), spec.network.sensors)]
        res = simulate(spec.system, paths, steps, 5, sensors=sensors)
        model = "sensors"
    else:
        res = simulate(spec, paths, steps, 5)
        model = spec.channel.model
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["seed"] == 5 and d["paths"] == paths and d["steps"] == steps
    assert d["channel"]["model"] == model
    mean = np.array(d["mean_trace"]["mean"])
    assert np.all(np.isfinite(mean)) and np.all(mean >= 0)
    assert mean[0] == pytest.approx(float(np.trace(spec.system.sigma0)))
    lo, hi = np.array(d["mean_trace"]["lower"]), np.array(d["mean_trace"]["upper"])
    assert np.all(lo <= mean + 1e-9) and np.all(mean <= hi + 1e-9)
    assert d["divergence"]["failed_paths"] == 0
    q = [x for x in d["horizon"]["quantiles"] if x is not None]
    assert q == sorted(q)
    assert 0 <= d["divergence"]["diverged_paths"] <= paths
    if spec.channel is not None and spec.channel.iid:   # independent Lyapunov recursion
        p = float(spec.channel.arrival_probability)
        A, Q = spec.system.a, spec.system.q
        S, bound = np.array(spec.system.sigma0, dtype=float), []
        for _ in range(steps + 1):
            bound.append(float(np.trace(S)))
            S = (1 - p) * A @ S @ A.T + Q
        times = np.array(d["times"])
        se = np.array(d["mean_trace"]["std"]) / math.sqrt(paths)
        censored = d["divergence"]["failed_paths"] > 0   # crossed paths are continued
        if not censored:
            assert np.all(mean >= np.array(bound)[times] - 5 * se - 1e-9 * np.array(bound)[times])
    # the same seed gives the same numbers
    again = (simulate(spec.system, paths, steps, 5, sensors=sensors) if spec.network is not None
             else simulate(spec, paths, steps, 5))
    assert np.array_equal(again.mean_trace, res.mean_trace)


def _doctored(res, factor):
    """The same simulation with every mean scaled by ``factor`` (an estimator bug)."""
    import dataclasses

    return dataclasses.replace(res, mean_trace=res.mean_trace * factor)


def test_lyapunov_check_fails_when_valid_and_is_inconclusive_near_pc():
    from kfcrit.model.channels import Bernoulli
    from kfcrit.sim.checks import simulation_checks, tail_regime

    # scalar a = -1.25: p_c = 1 - 1/a^2 = 0.36; the variance of P is finite iff
    # (1 - p) a^4 < 1, i.e. p > 1 - 1/a^4 = 0.5904 (hand derivation, MATH §3 / Cor. 2)
    name = "simulation: E[tr P_t] >= Lyapunov lower bound tr S_t (Lemma 1)"
    for p, heavy in ((sp.Rational(7, 10), False), (sp.Rational(37, 100), True)):
        ch = Bernoulli(p)
        res = simulate(SCALAR, 400, 100, 1, ch)
        erg = ergodic(SCALAR, 2000, 1, ch, replicas=2)
        reg = tail_regime(SCALAR, ch, 100)
        assert reg.heavy_tailed is heavy
        assert reg.variance_value == pytest.approx((1 - float(p)) * 1.25**4)
        honest = {c.check: c for c in simulation_checks(SCALAR, ch, res, erg)}
        assert honest[name].passed in (True, None)   # never a false failure
        broken = {c.check: c for c in simulation_checks(SCALAR, ch, _doctored(res, 0.2), erg)}
        if heavy:   # below the tolerance, but the tolerance is not valid there
            assert broken[name].passed is None and broken[name].status == "inconclusive"
            assert "variance" in broken[name].reason
        else:       # finite variance: a mean 5x too small is a failure
            assert broken[name].passed is False and broken[name].status == "failed"


def test_lyapunov_settling_is_reported():
    from kfcrit.model.channels import Bernoulli
    from kfcrit.sim.checks import tail_regime

    # (1 - p) a^2 = 0.64 * 1.5625 = 1 - 1.5625e-10: S_t grows by ~1 per step for 500 steps while
    # its limit is 1/(1.5625e-10) ≈ 6.4e9, so the horizon is far from settled
    reg = tail_regime(SCALAR, Bernoulli(sp.Rational(3600000001, 10**10)), 500)
    assert reg.settled is False
    assert reg.lyapunov_trace_limit == pytest.approx(1 / (1 - 0.6399999999 * 1.5625),
                                                        rel=1e-4)
    reg = tail_regime(SCALAR, Bernoulli(sp.Rational(9, 10)), 500)
    assert reg.settled is True and reg.heavy_tailed is False


# --------------------------------------------------------------------------------------------
# threads, λ_max schedule, the threshold scale, heavy tails and divergent means


def test_bit_identical_for_any_number_of_threads():
    """Blocks of a batch run on several threads; the statistics are summed in path order."""
    kw = {"arrival_probability": 0.45, "divergence_threshold": 1e4, "record_traces": 3}
    paths = 3 * LANES + 5
    ref = simulate(GENERAL, paths, 80, 3, threads=1, **kw)
    for threads, bs in ((2, 1024), (3, 2 * LANES), (8, 100)):
        other = simulate(GENERAL, paths, 80, 3, threads=threads, batch_size=bs, **kw)
        for name in ("mean_trace", "std_trace", "mean_lambda_max", "horizon_traces", "traces",
                     "divergence_times", "log10_mean_trace"):
            assert np.array_equal(getattr(ref, name), getattr(other, name)), (threads, name)
    with pytest.raises(InputError, match="threads"):
        simulate(GENERAL, 5, 5, 0, arrival_probability=0.5, threads=0)


def test_lambda_max_is_exact_at_its_sample_times():
    """p = 1: every path follows the same deterministic Riccati recursion, so E[λ_max(P_t)] is
    λ_max of that recursion (kfcrit.theory.covariance.riccati.f_arrival, numpy's eigvalsh) at the chosen
    times; n = 3 takes the Cholesky-bisection branch."""
    A = np.array([[1.2, 0.3, 0.0], [0.0, 0.9, 0.5], [0.1, 0.0, 1.1]])
    C = np.array([[1.0, 0.0, 1.0]])
    system = System(A, C, np.eye(3), [[2.0]])
    res = simulate(system, 7, 60, 0, arrival_probability=1, lambda_max_samples=9)
    lt = res.lambda_max_times
    assert lt.size == 9 and lt[0] == 0 and lt[-1] == 60 and set(lt) <= set(res.times)
    P, lam = np.eye(3), {0: 1.0}
    for t in range(1, 61):
        P = f_arrival(A, C, np.eye(3), np.array([[2.0]]), P)
        lam[t] = np.linalg.eigvalsh(P)[-1]
    np.testing.assert_allclose(res.mean_lambda_max, [lam[int(t)] for t in lt], rtol=1e-10)
    d = res.to_dict()["mean_lambda_max"]
    assert d["times"] == [int(t) for t in lt] and "9 of the" in d["method"]
    assert "bisection" in d["method"]
    none = simulate(system, 3, 10, 0, arrival_probability=1, track_lambda_max=False)
    assert none.mean_lambda_max is None and none.to_dict()["mean_lambda_max"] is None


@pytest.mark.parametrize("n,m,seed", [(1, 1, 0), (2, 1, 1), (4, 2, 2), (6, 2, 3)])
def test_threshold_scale_dare_matches_scipy(n, m, seed):
    """P* by structured doubling against scipy's QZ-based solve_discrete_are (a second
    method), on systems with unstable modes and a stabilising solution."""
    from scipy.linalg import solve_discrete_are

    from kfcrit.sim.engine import steady_covariance

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 1.2 / max(abs(np.linalg.eigvals(A)))
    C = rng.normal(size=(m, n))
    P = steady_covariance(A, C, np.eye(n), np.eye(m))
    ref = solve_discrete_are(A.T, C.T, np.eye(n), np.eye(m))
    np.testing.assert_allclose(P, ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())


def test_threshold_scale_without_stabilising_solution():
    """An undetectable unstable mode (2 with C = [0 1]) has no stabilising DARE solution."""
    from kfcrit.sim.engine import steady_covariance

    assert steady_covariance(np.diag([2.0, 0.5]), np.array([[0.0, 1.0]]), np.eye(2),
                             np.eye(1)) is None


def test_variance_condition_uses_the_critical_value_degenerate_case():
    """A = diag(2, −2), C = [1 1]: degenerate, q = 2, p_c = 1 − 2^{−4} = 15/16 (MATH §4).
    Hand value of the variance threshold: 1 − p₂ = (1 − p_c)² = 2^{−8}, p₂ = 255/256 — the
    same as 1 − ρ^{−4q/(q−1)} = 1 − 2^{−8}. At p = 0.99 (between p_c and p₂) the variance is
    infinite although (1 − p) ρ⁴ = 0.16 < 1 (the non-degenerate formula)."""
    from kfcrit.model.channels import Bernoulli
    from kfcrit.sim.checks import tail_regime

    system = System(np.diag([2.0, -2.0]), [[1.0, 1.0]], 1, 1)
    ch = Bernoulli(sp.Rational(99, 100))
    plain = tail_regime(system, ch, 100)
    assert plain.heavy_tailed is False and plain.variance_value == pytest.approx(0.16)
    reg = tail_regime(system, ch, 100, critical_value=15 / 16)
    assert reg.heavy_tailed is True
    assert reg.variance_threshold_p2 == pytest.approx(255 / 256, abs=1e-15)
    assert reg.variance_value == pytest.approx(0.01 * 256)
    assert reg.variance_basis.startswith("claim")
    above = tail_regime(system, Bernoulli(sp.Rational(997, 1000)), 100, critical_value=15 / 16)
    assert above.heavy_tailed is False        # 0.003 · 256 = 0.768 < 1


def test_variance_condition_takes_the_upper_end_of_a_bracket():
    """Only a bracket [0.3, 0.4] of p_c, p = 0.6: the upper end gives 1 − p₂ = (1 − 0.4)² = 0.36
    and (1 − p)/0.36 = 1.11 ≥ 1 (infinite variance flagged); the lower end would give
    0.4/0.49 = 0.82 < 1. The upper end is the conservative one and is used; p_up alone is an
    upper end too (p_c ≤ p_up)."""
    from kfcrit.model.channels import Bernoulli
    from kfcrit.sim.checks import tail_regime

    reg = tail_regime(SCALAR, Bernoulli(sp.Rational(3, 5)), 50, critical_bracket=(0.3, 0.4))
    assert reg.heavy_tailed is True and reg.variance_threshold_p2 == pytest.approx(0.64)
    assert reg.variance_critical_source == "critical_bracket"
    up = tail_regime(SCALAR, Bernoulli(sp.Rational(3, 5)), 50, upper_bound=0.4)
    assert up.heavy_tailed is True and up.variance_critical_value == 0.4


def test_below_critical_the_section_gives_no_mean():
    """p = 3/10 < p_c = 9/25: E[tr P_t] grows without bound; the operating point must not
    present a finite mean with an interval. The raw sample statistics stay, labelled."""
    from kfcrit.model.channels import Bernoulli

    spec = SystemSpec(system=SCALAR, channel=Bernoulli(sp.Rational(3, 10)))
    d = simulation_section(spec, critical_value=0.36, upper_bound=0.36, seed=2, quick=True)
    op = d.operating_point
    assert op.mean_exists is False
    assert op.mean_trace.mean is None and op.mean_trace.lower is None
    assert op.mean_trace.diverges is True and "diverges" in op.mean_trace.statement
    assert op.mean_lambda_max.mean is None
    assert op.horizon.mean is None and op.horizon.mean_diverges is True
    sample = op.sample_mean_trace
    assert "not an estimate" in sample.label and len(sample.mean) == len(op.times)
    assert sample.mean[0] == pytest.approx(float(np.trace(SCALAR.sigma0)))
    pooled = op.ergodic.time_averages.pooled_mean_trace
    assert pooled.mean is None and pooled.diverges is True
    assert any("diverges" in w for w in d.warnings)
    json.loads(dumps(to_json(d)))
    # the same operating point with only a bracket above p: still divergent
    d2 = simulation_section(spec, critical_value=None, upper_bound=0.5, seed=2, quick=True,
                            critical_bracket=(0.32, 0.4))
    assert d2.operating_point.mean_exists is False
    # inside the bracket: unknown, the mean is given (with the flag)
    d3 = simulation_section(spec, critical_value=None, upper_bound=0.5, seed=2, quick=True,
                            critical_bracket=(0.2, 0.4))
    assert d3.operating_point.mean_exists is None
    assert d3.operating_point.mean_trace.mean is not None


def test_gilbert_elliott_burst_condition_decides_divergence():
    """(1 − r) a² = 0.75 · 1.5625 ≥ 1: E[P] unbounded for any system (MATH §10)."""
    from kfcrit.sim.checks import mean_regime

    bad = mean_regime(SCALAR, GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 4)))
    assert bad.exists is False and bad.value == pytest.approx(0.75 * 1.5625)
    ok = mean_regime(SCALAR, GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2)),
                     critical_value=0.36)
    assert ok.exists is True and ok.basis.startswith("claim")


# --------------------------------------------------------------------------------------------
# several sensors, each over its own link


@pytest.mark.parametrize("channel", [None, GilbertElliott(sp.Rational(1, 5), sp.Rational(1, 2))])
def test_one_sensor_owning_every_row_is_the_single_link_filter(channel):
    """Sensors API with one sensor owning every row: bit for bit the single-link simulation."""
    from kfcrit.model.channels import Bernoulli

    ch = channel if channel is not None else Bernoulli(sp.Rational(11, 20))
    two = System([[1.2, 0.3], [0.0, 0.9]], [[1.0, 0.0], [0.5, 1.0]], 1, [[1.0, 0.2], [0.2, 2.0]])
    ref = simulate(two, LANES + 9, 70, 4, ch, record_traces=3)
    net = simulate(two, LANES + 9, 70, 4, sensors=[([0, 1], ch)], record_traces=3)
    for name in ("mean_trace", "std_trace", "mean_lambda_max", "horizon_traces", "traces"):
        assert np.array_equal(getattr(ref, name), getattr(net, name)), name
    assert net.channel["model"] == "sensors"


def test_sensor_arrivals_follow_the_received_set_update():
    """Two sensors (rows 0 and 1 of C, R with a cross term) over two different traces. Each
    path reads every sensor's trace from the same start, key mod L_s, key = SeedSequence(seed,
    spawn_key=(0, i)) (numpy's own SeedSequence): traces recorded together stay time-aligned.
    Independent reference: kfcrit.theory.covariance.riccati.f_arrival with the stacked rows of C (and the
    block of R) that arrived, f_loss when none did."""
    A = np.array([[1.1, 0.4], [0.0, 0.8]])
    C = np.array([[1.0, 0.0], [0.3, 1.0]])
    Q, R = np.eye(2), np.array([[1.0, 0.3], [0.3, 2.0]])
    seqs = [[1, 0, 0, 1, 1, 0, 1], [0, 1, 1, 0, 0]]
    res = simulate(System(A, C, Q, R), 3, 30, 7,
                   sensors=[([0], Trace.from_arrivals(seqs[0])),
                            ([1], Trace.from_arrivals(seqs[1]))],
                   record_traces=True, divergence_threshold=1e300)
    for i in range(3):
        offs = []
        for seq in seqs:
            key = np.random.SeedSequence(7, spawn_key=(0, i)).generate_state(1, np.uint64)[0]
            offs.append(int(key % np.uint64(len(seq))))
        P, expected = np.eye(2), [2.0]
        for t in range(30):
            rows = [s for s in range(2) if seqs[s][(offs[s] + t) % len(seqs[s])]]
            if rows:
                P = f_arrival(A, C[rows], Q, R[np.ix_(rows, rows)], P)
            else:
                P = f_loss(A, Q, P)
            expected.append(np.trace(P))
        np.testing.assert_allclose(res.traces[i], expected, rtol=1e-10)


def test_redundant_sensors_scalar_plant():
    """A scalar plant a = 1.25 seen by two sensors with independent Bernoulli links: E[P]
    bounded iff (1 − p_1)(1 − p_2) a² < 1 (the all-lost event is the only loss). With
    p_1 = p_2 = 0.3: 0.49 · 1.5625 = 0.77 < 1 bounded; each link alone (0.7 · 1.5625 = 1.09)
    would not be. The Lyapunov recursion of the all-lost probability, s_{t+1} = 0.49 a² s_t + 1,
    is a lower bound of E[P_t] (Sinopoli Lemma 1 with p = 1 − 0.49), and the mean settles."""
    from kfcrit.model.channels import Bernoulli

    sys2 = System([[1.25]], [[1.0], [1.0]], 1, np.eye(2))
    links = [([0], Bernoulli(sp.Rational(3, 10))), ([1], Bernoulli(sp.Rational(3, 10)))]
    res = simulate(sys2, 20_000, 120, 3, sensors=links, horizon_samples=121)
    s, lower = 1.0, [1.0]
    for _ in range(120):
        s = 0.49 * 1.5625 * s + 1
        lower.append(s)
    se = res.std_trace / math.sqrt(res.paths)
    assert np.all(res.mean_trace >= np.array(lower)[res.times] - 5 * se)
    assert abs(res.mean_trace[60] - res.mean_trace[120]) < 5 * math.hypot(se[60], se[120])
    single = simulate(System([[1.25]], [[1.0]], 1, 1), 20_000, 120, 3,
                      arrival_probability=sp.Rational(3, 10), horizon_samples=121)
    assert single.mean_trace[120] > 3 * res.mean_trace[120]


def test_sensor_arguments_are_checked():
    from kfcrit.model.channels import Bernoulli

    b = Bernoulli(sp.Rational(1, 2))
    two = System([[1.2, 0.0], [0.0, 0.9]], np.eye(2), 1, 1)
    with pytest.raises(InputError, match="sensors"):
        simulate(two, 5, 5, 0, sensors=[([0], b)])                 # row 1 has no sensor
    with pytest.raises(InputError, match="sensors"):
        simulate(two, 5, 5, 0, sensors=[([0, 1], b), ([1], b)])    # row 1 twice
    with pytest.raises(InputError, match="sensors"):
        simulate(two, 5, 5, 0, b, sensors=[([0, 1], b)])


@pytest.mark.parametrize("gap", [0.5, 0.99, 1.0 - 1e-9, 1.0])
def test_lambda_max_bisection_any_spectral_gap(gap):
    """λ_max by Cholesky bisection with spectral gaps λ₂/λ₁ = ``gap`` from 0.5 to a double
    eigenvalue, against LAPACK's eigvalsh on Q diag(3, 3·gap, 1, 0.2) Q' (Q a fixed rotation,
    no RNG)."""
    c, s = math.cos(0.7), math.sin(0.7)
    Q1 = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    Q2 = np.array([[1, 0, 0, 0], [0, c, 0, -s], [0, 0, 1, 0], [0, s, 0, c]])
    Qm = Q1 @ Q2 @ Q1.T
    X = Qm @ np.diag([3.0, 3.0 * gap, 1.0, 0.2]) @ Qm.T
    X = 0.5 * (X + X.T)
    W = 4
    Xs = np.repeat(X[:, :, None], W, axis=2).copy()
    Xs[:, :, 1] *= 1e-3
    out = np.empty(W)
    lambda_max_lanes(Xs, W, out, np.empty_like(Xs), *[np.empty(W) for _ in range(5)])
    for b in range(W):
        ref = np.linalg.eigvalsh(Xs[:, :, b])[-1]
        assert abs(out[b] - ref) <= 1e-10 * np.trace(Xs[:, :, b])
