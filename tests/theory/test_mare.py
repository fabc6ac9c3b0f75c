"""The verified enclosure of the MARE fixed point V̄ (kfcrit.theory.covariance.mare) and the
iteration budgets of the large-n V̄ computations.

Independent references: the scalar MARE solved as a quadratic here, and a plain fixed-point
loop of g_p written here (Sinopoli eq. (16)).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.records.covariance import Markers
from kfcrit.theory.covariance import bounds
from kfcrit.theory.covariance.mare import mare_enclosure


def _scalar_vbar(a: float, p: float) -> float:
    # V = a² V + 1 − p a² V²/(V + 1), times (V + 1): (1 − a² + p a²) V² − a² V − 1 = 0
    qa, qb, qc = 1 - a * a + p * a * a, -a * a, -1.0
    return (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)


def _plain_vbar(A, C, Q, R, p, iterations=20000):
    V = np.zeros_like(Q)
    for _ in range(iterations):
        AXC = A @ V @ C.T
        Vn = A @ V @ A.T + Q - p * AXC @ np.linalg.inv(C @ V @ C.T + R) @ AXC.T
        Vn = 0.5 * (Vn + Vn.T)
        if np.max(np.abs(Vn - V)) <= 1e-15 * np.max(np.abs(Vn)):
            return Vn
        V = Vn
    return V


def test_scalar_enclosure_contains_the_closed_form():
    one = np.eye(1)
    v = _scalar_vbar(1.25, 0.5)
    enc = mare_enclosure(1.25 * one, one, one, one, 0.5, np.array([[v]]))
    lo, hi = enc["trace_interval"]
    assert lo <= v <= hi and (hi - lo) <= 3e-10 * v
    assert enc["proves_p_above_p_up"]


def test_enclosure_of_a_random_system_contains_the_plain_iteration():
    rng = np.random.default_rng(4)
    n, m, p = 6, 2, 0.8
    A = rng.normal(size=(n, n))
    A *= 1.2 / max(abs(np.linalg.eigvals(A)))
    C = rng.normal(size=(m, n))
    Q, R = np.eye(n), np.eye(m)
    ref = _plain_vbar(A, C, Q, R, p)
    V, _ = bounds.mare_iteration(A, C, Q, R, p)
    enc = mare_enclosure(A, C, Q, R, p, V)
    lo, hi = enc["trace_interval"]
    assert lo <= np.trace(ref) <= hi


def test_a_wrong_matrix_is_never_enclosed_wrongly():
    one = np.eye(1)
    v = _scalar_vbar(1.25, 0.5)
    for factor in (0.9, 0.99, 1.01, 1.1):
        enc = mare_enclosure(1.25 * one, one, one, one, 0.5, np.array([[factor * v]]))
        if enc is not None:
            lo, hi = enc["trace_interval"]
            assert lo <= v <= hi


def test_no_enclosure_where_vbar_does_not_exist():
    # a = 2, m = 1: p_up = 1 − 1/4 = 3/4 > 1/2, so the MARE has no PSD fixed point at p = 1/2
    one = np.eye(1)
    for guess in (1.0, 10.0, 1e6):
        assert mare_enclosure(2 * one, one, one, one, 0.5, np.array([[guess]])) is None


def test_covariance_bounds_state_the_certificate():
    s = System(A=[[1.25]], C=[[1]], Q=1, R=1)
    up = bounds.covariance_bounds(s, 0.5)["upper"]
    assert up["certified"] is True
    lo, hi = up["certificate"]["trace_interval"]
    assert lo <= _scalar_vbar(1.25, 0.5) <= hi


def _large_system(n: int = bounds.LARGE_STATES + 1) -> System:
    rng = np.random.default_rng(2)
    A = rng.normal(size=(n, n))
    A *= 1.3 / max(abs(np.linalg.eigvals(A)))
    return System(A=A, C=rng.normal(size=(5, n)), Q=np.eye(n), R=np.eye(5))


def test_large_phase_curve_stops_at_its_iteration_budget():
    s = _large_system()
    ticks = iter(range(10**9))  # a counting clock: never reaches the time budget
    pt = bounds.phase_transition(s, Markers(p_low=1 - 1 / 1.3**2, p_c=None, p_up=None,
                                            operating=None), points=12,
                                 clock=lambda: float(next(ticks)) * 1e-9, upper=_Upper(0.4, 0.45),
                                 iteration_budget=40)
    assert "budget of 40 fixed-point iterations" in (pt.limits.stopped or "")
    assert any(v is None for v in pt.trace_upper)


class _Upper:
    """A stand-in p_up bracket [lo, 1] (upper_of accepts any object with these attributes)."""

    def __init__(self, lo: float, value: float | None = None) -> None:
        self.value, self.interval, self.extras = value, (lo, 1.0), {}


@pytest.mark.parametrize("n", [bounds.LARGE_STATES + 1])
def test_large_operating_point_vbar_is_certified(n):
    s = _large_system(n)
    cb = bounds.covariance_bounds(s, 0.95, upper=_Upper(0.5))
    up = cb["upper"]
    assert up["exists"] and up["certified"]
    ref = _plain_vbar(s.a, s.c, s.q, s.r, 0.95)
    lo, hi = up["certificate"]["trace_interval"]
    assert lo <= np.trace(ref) <= hi


def test_single_blas_thread_restores_the_thread_counts():
    from kfcrit.theory.covariance.riccati import openblas_thread_controls, single_blas_thread

    before = [int(get()) for get, _ in openblas_thread_controls()]
    with single_blas_thread():
        assert all(int(get()) == 1 for get, _ in openblas_thread_controls())
    assert [int(get()) for get, _ in openblas_thread_controls()] == before
