"""Networks without 2^N (issue 27 item 2, docs/theory.md §15): one-sensor maps.

Expected values are derived by hand in each test from the closed forms of docs/theory.md §9.4:
a scalar plant a seen by N sensors is mean-stable iff Π_i (1 − p_i)·a² < 1, and decoupled modes
(diagonal A, each sensor's rows unit vectors) are mean-stable iff, for every mode j,
Π_{i sees j}(1 − p_i)·a_j² < 1. Work is counted (certificates, received sets), never timed.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kfcrit.analysis.verdict import verdict_of
from kfcrit.model.network import Network, Sensor
from kfcrit.theory.links import netseq as ns
from kfcrit.theory.links.netsearch import SeqContext
from kfcrit.theory.links.network import modal_one_step, network_analysis

R = sp.Rational
WIDTH = 1e-6
"""Largest accepted width of a certified bracket where the closed form is exact."""


def V(facts) -> str:  # noqa: ANN001, N802
    return verdict_of(facts)[0].value


def scalar(a, N):
    return Network([[a]], 1, None, [Sensor(f"s{i}", [[1]], 1) for i in range(N)])


def decoupled(diag, seen):
    """diag(a_j); sensor i measures the modes in seen[i] (one unit row each)."""
    n = len(diag)
    A = [[diag[j] if j == k else 0 for k in range(n)] for j in range(n)]
    sensors = [Sensor(f"s{i}", [[1 if k == j else 0 for k in range(n)] for j in modes],
                      sp.eye(len(modes)))
               for i, modes in enumerate(seen)]
    return Network(A, sp.eye(n), None, sensors)


def _bracket_holds(row, expected: float) -> None:
    lo, hi = row["critical_value"]["interval"]
    assert lo <= expected + 1e-12 and expected <= hi + 1e-12
    assert hi - lo <= WIDTH
    suff = row["surfaces"]["sufficient"]
    assert suff is not None and suff["certificate"]["ok"]
    assert abs(suff["value"] - expected) <= WIDTH     # the certified end is tight


# ---------------------------------------------------------------------------------------------
# scalar plants
# ---------------------------------------------------------------------------------------------

def test_scalar_twelve_sensors_brackets_and_verdict():
    # a = 2, p_0 = 1/2, p_1..p_11 = 1/10: Π(1 − p_i)·a² = (1/2)(9/10)^11·4 ≈ 0.6276 < 1.
    # Sensor 0's critical value: 1 − 1/(4·(9/10)^11); every other one is 0, because
    # (1/2)(9/10)^10·4 ≈ 0.697 < 1 already with that link dead.
    net = scalar(2, 12)
    p = [R(1, 2)] + [R(1, 10)] * 11
    res = network_analysis(net, p).to_dict()
    assert res["method"]["decided_by"] == "sequential"
    assert res["method"]["received_sets"] == 0
    assert res["facts"]["necessary"] is True
    pc0 = 1 - 1 / (4 * 0.9 ** 11)
    _bracket_holds(res["sensors"][0], pc0)
    for row in res["sensors"][1:]:
        assert row["critical_value"]["interval"] == [0.0, 0.0]
    # uniform margin δ: (1/2 + δ)(9/10 + δ)^11·4 = 1, solved here by bisection
    lo, hi = 0.0, 0.1
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if (0.5 + mid) * (0.9 + mid) ** 11 * 4 < 1 else (lo, mid)
    um = res["uniform_margin"]["interval"]
    assert um[0] <= lo + 1e-12 and lo <= um[1] + 1e-12 and um[1] - um[0] <= WIDTH


def test_scalar_twelve_sensors_unstable():
    # (9/10)^12·4 ≈ 1.13 ≥ 1
    res = network_analysis(scalar(2, 12), [R(1, 10)] * 12)
    assert V(res.facts) == "mean-unstable"


def test_scalar_hundred_sensors_polynomial_work():
    # a = 10: (1 − p)^100·100 < 1 iff p > 1 − 100^(−1/100); at p = 1/20, 0.95^100·100 ≈ 0.59
    N = 100
    res = network_analysis(scalar(10, N), [R(1, 20)] * N).to_dict()
    assert res["method"]["decided_by"] == "sequential"
    assert V(network_analysis(scalar(10, N), [R(1, 20)] * N).facts) == "mean-stable"
    # every sensor: with its link dead, 0.95^99·100 ≈ 0.62 < 1, so its critical value is 0
    for row in res["sensors"]:
        assert row["critical_value"]["interval"] == [0.0, 0.0]
    # counted work: a bounded number of certificates per sensor, no received set enumerated
    assert res["method"]["certificates"] <= 10 * N
    assert res["method"]["received_sets"] == 0
    unstable = network_analysis(scalar(10, N), [R(1, 25)] * N)   # 0.96^100·100 ≈ 1.69
    assert V(unstable.facts) == "mean-unstable"


# ---------------------------------------------------------------------------------------------
# decoupled modes
# ---------------------------------------------------------------------------------------------

def test_decoupled_twelve_sensors():
    # A = diag(4, 3/2, 5/4); sensor i sees mode i mod 3, and sensor 11 also sees modes 0 and 1.
    # Mode 0 (a² = 16) is seen by sensors 0, 3, 6, 9 and 11. With p_0 = 3/5, p_11 = 0 (dead)
    # and the others 1/2: (2/5)(1/2)^3·16 = 0.8 < 1. Sensor 0 needs (1 − p_0)(1/2)^3·16 < 1,
    # p_0 > 1/2; sensor 3 needs (1 − p_3)(2/5)(1/2)^2·16 < 1, p_3 > 1 − 1/1.6 = 3/8.
    # Mode 1 (a² = 9/4): (1/2)^4·9/4 < 1 even with one of its links dead, so sensor 1's is 0.
    seen = [[k % 3] for k in range(11)] + [[0, 1]]
    net = decoupled([4, R(3, 2), R(5, 4)], seen)
    assert modal_one_step(net)[0] is True
    p = [R(3, 5)] + [R(1, 2)] * 10 + [0]
    res = network_analysis(net, p).to_dict()
    assert res["method"]["decided_by"] == "sequential"
    assert res["facts"]["necessary"] is True and res["certificate"]["ok"]
    _bracket_holds(res["sensors"][0], 0.5)
    _bracket_holds(res["sensors"][3], 0.375)
    assert res["sensors"][1]["critical_value"]["interval"] == [0.0, 0.0]


def test_decoupled_hundred_sensors():
    # A = diag(a_0..a_9), a_j = 1 + (j+1)/10; sensor i sees mode i mod 10 (ten sensors per
    # mode), all sensors of mode j at q_j: q = 1/10 for a_j ≤ 1.6, 1/5 for 1.7–1.9, 1/2 for 2.
    # Mode j is stable iff (1 − q_j)^10·a_j² < 1 (checked below by hand), and the critical value
    # of one of its sensors, the nine others at q_j, is max(0, 1 − 1/((1 − q_j)^9·a_j²)).
    n, N = 10, 100
    diag = [1 + R(j + 1, 10) for j in range(n)]
    q = [0.1] * 6 + [0.2] * 3 + [0.5]
    net = decoupled(diag, [[i % n] for i in range(N)])
    p = [R(q[i % n]).limit_denominator(10) for i in range(N)]
    for j in range(n):
        assert (1 - q[j]) ** 10 * float(diag[j]) ** 2 < 1
    res = network_analysis(net, p).to_dict()
    assert res["method"]["decided_by"] == "sequential"
    assert res["facts"]["necessary"] is True and res["certificate"]["ok"]
    for j in range(n):
        expected = max(0.0, 1 - 1 / ((1 - q[j]) ** 9 * float(diag[j]) ** 2))
        _bracket_holds(res["sensors"][j], expected)
    assert res["method"]["certificates"] <= 10 * N


# ---------------------------------------------------------------------------------------------
# the search alone (no modal seed): the generic gains are tight on the closed-form cases
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("net,p,i,expected", [
    (scalar(2, 6), np.array([0.5, 0.1, 0.1, 0.1, 0.1, 0.1]), 0, 1 - 1 / (4 * 0.9 ** 5)),
    (decoupled([3, 2], [[0], [1], [0], [1]]), np.array([0.5, 0.6, 0.6, 0.6]), 2,
     1 - 1 / (9 * 0.5)),
])
def test_generic_search_is_tight(net, p, i, expected):
    ctx = SeqContext(net, p, 1e-9, True, seed=None)
    b = ctx.coordinate_boundary(i, p, expected)
    assert b.s_cert is not None and b.check["ok"]
    assert expected <= b.s_cert <= expected + WIDTH


def test_certificate_is_rejected_below_the_threshold():
    # scalar a = 2, two sensors with gains 1 (F_i = 0): 𝓛 = 4(1 − p_1)(1 − p_2); at
    # p = (1/4, 1/4) it is 9/4 ≥ 1, so no X > 0 can pass the ball check
    net = scalar(2, 2)
    ctx = SeqContext(net, np.array([0.25, 0.25]), 1e-9, True)
    gains = [np.array([[1.0]]), np.array([[1.0]])]
    chk = ns.verify_sequential(ctx.exact, np.array([0.25, 0.25]), np.array([[1.0]]), gains)
    assert not chk.ok
    chk = ns.verify_sequential(ctx.exact, np.array([0.5, 0.75]), np.array([[1.0]]), gains)
    assert chk.ok       # 4·(1/2)(1/4) = 1/2 < 1


def test_sequential_never_beats_every_received_set():
    # docs/theory.md §15.5: product-form gains are a special case of one gain per received set
    net = Network([[R(5, 4), 0], [1, R(11, 10)]], sp.eye(2), None,
                  [Sensor("a", [[1, 1]], 1), Sensor("b", [[1, -1]], 1)])
    p = [R(9, 10), R(9, 10)]
    seq = network_analysis(net, p, method="sequential").to_dict()
    full = network_analysis(net, p, method="received-sets").to_dict()
    assert seq["method"]["decided_by"] == "sequential"
    assert full["method"]["decided_by"] == "received-sets"
    for a, b in zip(seq["sensors"], full["sensors"]):
        sa, sb = a["surfaces"]["sufficient"], b["surfaces"]["sufficient"]
        if sa is not None and sb is not None:
            assert sa["value"] >= sb["value"] - 1e-7


def test_repeated_eigenvalue_many_sensors_enumerates_row_spaces_not_sensors():
    # A = 2·I_3, sixty sensors, sensor i measures coordinate i mod 3 (twenty per coordinate).
    # The eigenspace is all of R³; its maximal unobservable sets are the sensors of two
    # coordinates (a coordinate plane), so there are exactly three constraints, each
    # (1 − p)^20·4 < 1 over the twenty sensors of the third coordinate. At p = 1/5:
    # (4/5)^20·4 ≈ 0.046 < 1; with one link dead (4/5)^19·4 ≈ 0.058 < 1, so every critical
    # value is 0. Sixty sensors in combinations of two would be 1,770 rank tests per flat size;
    # three distinct row spaces make it three.
    N = 60
    net = decoupled([2, 2, 2], [[i % 3] for i in range(N)])
    res = network_analysis(net, [R(1, 5)] * N).to_dict()
    assert len(res["necessary_constraints"]) == 3
    assert all(len(c["unobservable_without"]) == 20 for c in res["necessary_constraints"])
    assert res["facts"]["necessary"] is True
    for row in res["sensors"]:
        assert row["critical_value"]["interval"] == [0.0, 0.0]
    # at p = 1/20: (19/20)^20·4 ≈ 1.43 ≥ 1, unstable
    assert V(network_analysis(net, [R(1, 20)] * N).facts) == "mean-unstable"
