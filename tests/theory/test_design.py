"""Design inversion (kfcrit.theory.covariance.design): [p_S, p_V] for lim E[tr P] ≤ L, against closed forms.

Scalar plant x' = a x + w, y = c x + v (Q = q, R = r):

* S̄(p) = q / (1 − (1 − p) a²), so tr S̄(p_S) = L gives p_S = 1 − (1 − q/L)/a²;
* the MARE v = a² v + q − p a² c² v² / (c² v + r), multiplied out at v = L, is linear in p:
  p_V = [(a² − 1) c² L² + (a² r + q c² − r) L + q r] / (a² c² L²);
* the floor (p = 1) is the DARE root: c² v² + (r − a² r − q c²) v − q r = 0 (positive root).
"""
from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.theory.covariance import design


def scalar(a, c=1.0, q=1.0, r=1.0) -> System:
    return System(np.array([[a]]), np.array([[c]]), np.array([[q]]), np.array([[r]]))


def p_s_closed(a, q, L):
    return max(0.0, 1 - (1 - q / L) / a ** 2)


def p_v_closed(a, c, q, r, L):
    return ((a * a - 1) * c * c * L * L + (a * a * r + q * c * c - r) * L + q * r) \
        / (a * a * c * c * L * L)


def dare_closed(a, c, q, r):
    b = r - a * a * r - q * c * c
    return (-b + math.sqrt(b * b + 4 * c * c * q * r)) / (2 * c * c)


@pytest.mark.parametrize(("a", "c", "q", "r", "L"), [(2.0, 1.0, 1.0, 1.0, 10.0),
                                                     (2.0, 1.0, 1.0, 1.0, 4.5),
                                                     (1.5, 2.0, 3.0, 0.5, 20.0),
                                                     (0.5, 1.0, 1.0, 1.0, 1.2),
                                                     (1.0, 1.0, 1.0, 1.0, 5.0)])
def test_scalar_interval_matches_the_closed_forms(a, c, q, r, L):
    d = design.required_arrival(scalar(a, c, q, r), L)
    assert d.status == "interval"
    lo, hi = d.interval
    assert lo == pytest.approx(p_s_closed(a, q, L), abs=1e-8)
    assert hi == pytest.approx(p_v_closed(a, c, q, r, L), abs=1e-8)
    # certified ends are rounded outwards: never inside the exact interval
    assert lo <= p_s_closed(a, q, L) + 1e-15 and hi >= p_v_closed(a, c, q, r, L) - 1e-15
    assert d.p_s.certified and d.p_v.certified
    assert d.floor_trace == pytest.approx(dare_closed(a, c, q, r), rel=1e-9)
    json.dumps(d.to_dict(), allow_nan=False)


def test_stable_plant_with_a_loose_requirement_needs_nothing():
    # a = 1/2: S̄(0) = V̄(0) = q/(1 − a²) = 4/3 ≤ L = 2, so every p (even 0) meets L
    d = design.required_arrival(scalar(0.5), 2.0)
    assert d.status == "interval" and d.interval == (0.0, 0.0)
    assert d.p_v.certified


@pytest.mark.parametrize("L", [4.0, Fraction(1, 2)])
def test_requirement_below_the_floor_is_impossible(L):
    # a = 2, c = q = r = 1: the DARE root is 2 + √5 ≈ 4.236 > 4; L = 1/2 < tr Q = 1 (exact)
    d = design.required_arrival(scalar(2.0), L)
    assert d.status == "impossible" and d.interval is None
    assert d.floor_certified
    assert d.floor_trace is None or d.floor_trace == pytest.approx(2 + math.sqrt(5))


def _scalar_v(a, c, q, r, p):
    """Positive root of (a²c²(1−p) − c²) v² + (a² r + q c² − r) v + q r = 0."""
    A2 = a * a * c * c * (1 - p) - c * c
    B = a * a * r + q * c * c - r
    if abs(A2) < 1e-15:
        return -q * r / B
    disc = B * B - 4 * A2 * q * r
    roots = [(-B + s * math.sqrt(disc)) / (2 * A2) for s in (1, -1)]
    return min(v for v in roots if v > 0)


def test_decoupled_modes_against_independent_scalar_bisection():
    # A = diag(2, 1.5), C = I, Q = I, R = I: S̄ and V̄ are diagonal, each mode its own scalar
    s = System(np.diag([2.0, 1.5]), np.eye(2), np.eye(2), np.eye(2))
    L = 12.0
    d = design.required_arrival(s, L)

    def bisect(fn, lo, hi):
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if fn(mid) > L else (lo, mid)
        return hi

    p_s = bisect(lambda p: sum(1 / (1 - (1 - p) * a * a) if (1 - p) * a * a < 1 else math.inf
                               for a in (2.0, 1.5)), 0.75, 1.0)
    p_v = bisect(lambda p: sum(_scalar_v(a, 1, 1, 1, p) for a in (2.0, 1.5)), 0.75 + 1e-12, 1.0)
    lo, hi = d.interval
    assert lo == pytest.approx(p_s, abs=1e-8) and hi == pytest.approx(p_v, abs=1e-8)
    assert d.p_s.certified and d.p_v.certified


def test_bad_level_is_refused():
    with pytest.raises(ValueError, match="max_mean_error_trace"):
        design.required_arrival(scalar(2.0), -1.0)
    with pytest.raises(TypeError, match="max_mean_error_trace"):
        design.required_arrival(scalar(2.0), "10")
