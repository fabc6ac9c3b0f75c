"""Batched BLAS-3 Monte Carlo of large systems (kfcrit.sim.batched).

References are independent: a plain per-path loop of the standard-form Riccati maps written
here (f_0(X) = A X A' + Q, f_1(X) = f_0(X) − A X C'(C X C' + R)⁻¹ C X A'), the lane kernels of
kfcrit.sim.kernels (scalar loops, another summation order) and a closed-form loss recursion.
"""
from __future__ import annotations

import math

import numpy as np

import kfcrit.sim.engine as engine
from kfcrit.model.system import System
from kfcrit.sim.arrivals import arrival_sequence, path_keys, trace_offsets
from kfcrit.sim.batched import BATCHED_MIN_STATES
from kfcrit.sim.section import LARGE_STATES, Budget, large_budget_note


def _system(n: int = 26, m: int = 5, radius: float = 1.2, seed: int = 1) -> System:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= radius / max(abs(np.linalg.eigvals(A)))
    return System(A=A, C=rng.normal(size=(m, n)), Q=np.eye(n), R=np.eye(m))


def _reference_traces(s: System, p: float, paths: int, steps: int, seed: int) -> np.ndarray:
    """tr P_t of each path by a plain loop of the standard-form maps, same arrival streams."""
    A, C, Q, R = s.a, s.c, s.q, s.r
    keys = path_keys(seed, 0, paths)
    offs = trace_offsets(keys, 1)
    out = np.empty((paths, steps + 1))
    for i in range(paths):
        gam = arrival_sequence(keys[i], 0, p, 0.0, 0.0, np.zeros(1, dtype=np.bool_), offs[i],
                               steps)
        X = s.sigma0.copy()
        out[i, 0] = np.trace(X)
        for t in range(steps):
            Y = A @ X @ A.T + Q
            if gam[t]:
                AXC = A @ X @ C.T
                Y = Y - AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T)
            X = 0.5 * (Y + Y.T)
            out[i, t + 1] = np.trace(X)
    return out


def test_batched_paths_match_a_plain_standard_form_loop():
    s = _system()
    assert s.n >= BATCHED_MIN_STATES
    res = engine.simulate(s, 12, 40, 3, arrival_probability=0.7, record_traces=True)
    ref = _reference_traces(s, 0.7, 12, 40, 3)
    np.testing.assert_allclose(res.traces, ref, rtol=1e-9)
    np.testing.assert_allclose(res.mean_trace, ref[:, res.times].mean(axis=0), rtol=1e-10)


def test_batched_and_lane_kernels_agree(monkeypatch):
    s = _system()
    a = engine.simulate(s, 40, 50, 5, arrival_probability=0.6, record_traces=2)
    ea = engine.ergodic(s, 300, 5, arrival_probability=0.6, replicas=3, levels=(40.0,))
    monkeypatch.setattr(engine, "BATCHED_MIN_STATES", 10**9)
    b = engine.simulate(s, 40, 50, 5, arrival_probability=0.6, record_traces=2)
    eb = engine.ergodic(s, 300, 5, arrival_probability=0.6, replicas=3, levels=(40.0,))
    np.testing.assert_allclose(a.mean_trace, b.mean_trace, rtol=1e-12)
    np.testing.assert_allclose(a.std_trace, b.std_trace, rtol=1e-8)
    np.testing.assert_allclose(a.traces, b.traces, rtol=1e-12)
    # the lane kernel bisects λ_max to 3.7e-12 · tr P; the batched one is LAPACK's syevd
    np.testing.assert_allclose(a.mean_lambda_max, b.mean_lambda_max, rtol=1e-10)
    np.testing.assert_allclose(ea.sums, eb.sums, rtol=1e-12)
    assert np.array_equal(ea.burst_count, eb.burst_count)
    assert np.array_equal(ea.exceed, eb.exceed)
    assert np.array_equal(ea.losses, eb.losses)


def test_a_path_does_not_depend_on_its_batch():
    s = _system()
    one = engine.simulate(s, 5, 30, 9, arrival_probability=0.5, record_traces=True)
    many = engine.simulate(s, 300, 30, 9, arrival_probability=0.5, record_traces=5)
    assert np.array_equal(one.traces, many.traces)


def test_divergent_paths_continue_in_scaled_form_with_true_values():
    # losses only (p = 0): P_t = 9^t P_0 + Σ_{k<t} 9^k Q for A = 3 I, beyond float64 at t ≈ 320
    n, steps = BATCHED_MIN_STATES, 400
    s = System(A=3 * np.eye(n), C=np.ones((1, n)), Q=np.eye(n), R=np.eye(1))
    res = engine.simulate(s, 3, steps, 0, arrival_probability=0)
    t = res.times.astype(float)
    expected = t * math.log10(9) + np.log10(n + n * (1 - 9.0 ** -t) / 8)
    np.testing.assert_allclose(res.log10_mean_trace, expected, rtol=1e-10)
    assert res.diverged_paths == 3 and res.failed_paths == 0


def test_large_budget_is_fixed_and_stated():
    small = Budget.for_system(LARGE_STATES, quick=False)
    large = Budget.for_system(LARGE_STATES + 1, quick=False)
    assert large.paths * large.steps < small.paths * small.steps
    assert large_budget_note(LARGE_STATES, small) is None
    note = large_budget_note(200, large)
    assert f"{large.paths} paths × {large.steps} steps" in note
