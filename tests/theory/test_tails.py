"""Tail exponent β = log(1 − p)/(−2 log|λ_1|) (Mo & Sinopoli 2012; a labelled claim)."""
from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

from kfcrit.io.typed import to_json
from kfcrit.model.system import System
from kfcrit.theory.covariance.tails import tail_exponent


def test_scalar_exponent_by_hand():
    # a = 5/4, p = 3/4: β = log 4 / log(25/16) = 2 log 2 / (2 log(5/4)) = log 2 / log(5/4)
    s = System(np.array([[1.25]]), np.array([[1.0]]), np.eye(1), np.eye(1))
    t = tail_exponent(s, Fraction(3, 4), classification="non-degenerate")
    assert t.value == pytest.approx(math.log(2) / math.log(1.25), rel=1e-14)
    assert t.expression is not None and "log" in t.expression
    assert t.finite_mean and t.finite_variance          # β ≈ 3.106
    assert "claim" in t.label and "Mo & Sinopoli" in t.source
    json.dumps(to_json(t), allow_nan=False)


def test_exponent_one_at_the_critical_value():
    # β = 1 exactly when p = 1 − 1/a²: a = 2, p = 3/4 → log 4 / log 4
    s = System(np.array([[2.0]]), np.array([[1.0]]), np.eye(1), np.eye(1))
    t = tail_exponent(s, 0.75, classification="non-degenerate")
    assert t.value == pytest.approx(1.0, abs=1e-15) and t.finite_variance is False


def test_degenerate_systems_are_not_given_the_formula():
    s = System(np.diag([2.0, -2.0]), np.array([[1.0, 1.0]]), np.eye(2), np.eye(1))
    t = tail_exponent(s, 0.9, classification="degenerate")
    assert not t.applicable and t.value is None and "non-degenerate" in t.statement


@pytest.mark.parametrize("A, C", [([[1]], [[1]]), ([[1, 0], [0, "1/2"]], [[1, 1]]),
                                  ([[-1, 0], [0, "1/2"]], [[1, 1]])])
def test_unit_spectral_radius_has_no_power_law_tail(A, C):
    """ρ(A) = 1 exactly (a random walk, a diagonalizable mode on the unit circle): log ρ = 0,
    no unstable mode, so no power-law tail — decided exactly, never a division by log 1."""
    n, m = len(A), len(C)
    s = System(A, C, np.eye(n).astype(int).tolist(), np.eye(m).astype(int).tolist())
    t = tail_exponent(s, Fraction(9, 10), "non-degenerate")
    assert t.value is None and t.expression == "oo" and t.finite_mean and t.finite_variance


def test_marginal_random_walk_is_analysed_end_to_end():
    from kfcrit.analysis.record import analyze_system
    from kfcrit.analysis.spec import spec_from_mapping

    spec = spec_from_mapping({"name": "walk", "A": 1, "C": 1, "Q": 1, "R": 1,
                              "channel": {"model": "bernoulli", "arrival_probability": "9/10"}})
    rec = analyze_system(spec, simulate=False).to_dict()
    assert rec["critical_value"]["value"] == 0 and rec["review"]["decision"] == "pass"
