"""A scalar plant seen by three sensors at and within 10⁻⁴⁰ of the boundary: facts consistent
with each other and with the verdict, exact ties and exact orders of the margins, and a uniform
margin whose interval contains the true δ with the verdict's sign (docs/theory.md §9.4–§9.5).

By hand: x' = a x + w, independent arrivals p_i: mean-stable iff a²·Π(1 − p_i) < 1; sensor i's
critical value p_i* = max(0, 1 − 1/(a² Π_{j≠i}(1 − p_j))); δ solves a² Π(1 − p_i + δ) = 1. The
expected values are computed here with fractions and mpmath, never from kfcrit.
"""
from __future__ import annotations

from fractions import Fraction as F

import mpmath
import sympy as sp

from kfcrit.analysis.verdict import verdict_of
from kfcrit.model.network import Network, Sensor
from kfcrit.theory.links.network import network_analysis

R = sp.Rational
TINY = F(1, 10 ** 40)


def scalar(a: int, ps: list[F]):
    net = Network([[a]], 1, None, [Sensor(f"s{i}", [[1]], 1 + i) for i in range(len(ps))])
    return network_analysis(net, p=[sp.Rational(p.numerator, p.denominator) for p in ps])


def margins(a: int, ps: list[F]) -> list[F]:
    out = []
    for i, p in enumerate(ps):
        c = F(a * a)
        for j, q in enumerate(ps):
            if j != i:
                c *= 1 - q
        out.append(p - max(F(0), 1 - 1 / c))
    return out


def true_delta(a: int, ps: list[F]) -> mpmath.mpf:
    with mpmath.workdps(80):
        def f(d):
            out = mpmath.mpf(a * a)
            for p in ps:
                out *= 1 - mpmath.mpf(p.numerator) / p.denominator + d
            return out - 1
        return mpmath.findroot(f, mpmath.mpf(0))


def stable(a: int, ps: list[F]) -> bool:
    prod = F(a * a)
    for p in ps:
        prod *= 1 - p
    return prod < 1


def test_facts_agree_with_each_other_and_with_the_verdict_at_the_dead_links_boundary():
    # p = 2/3, 2/3, 1/2: with s2 dead (1/3)(1/3)·9 = 1, unstable
    ps = [F(2, 3), F(2, 3), F(1, 2)]
    res = scalar(3, ps)
    assert stable(3, ps) and verdict_of(res.facts)[0].value == "mean-stable"
    if res.certificate is not None and res.certificate.get("ok"):
        assert res.facts.sufficient
    for row in res.sensors:
        dead = row.n_minus_1
        assert dead.necessary is False
        assert dead.sufficient is False
        assert verdict_of(dead)[0].value == "mean-unstable"


def test_an_exact_tie_names_no_bottleneck():
    ps = [F(2, 3), F(2, 3), F(1, 2)]
    m = margins(3, ps)
    assert m[0] == m[1] < m[2]
    res = scalar(3, ps)
    assert res.bottleneck["name"] is None
    assert set(res.bottleneck["candidates"]) == {"s0", "s1"}


def test_margins_10e_minus_40_apart_are_ranked_exactly():
    for ps in ([F(2, 3) - TINY, F(2, 3), F(1, 2)],        # s1's margin is the least
               [F(1, 2), F(1, 2), F(5, 9) + TINY]):       # s2's margin is the least
        m = margins(3, ps)
        least = min(range(3), key=lambda i: m[i])
        assert all(m[least] < m[j] for j in range(3) if j != least)
        res = scalar(3, ps)
        assert res.bottleneck["name"] == f"s{least}"
        for row, mi in zip(res.sensors, m):
            # the record's margin is the exact one rounded, not a float difference
            assert abs(row.margin["value"] - float(mi)) <= 1e-15 * abs(float(mi))


def test_the_uniform_margin_interval_contains_the_true_delta_with_the_verdicts_sign():
    for ps in ([F(1, 2), F(1, 2), F(5, 9) + TINY],
               [F(1, 2), F(1, 2), F(5, 9) - TINY],
               [F(2, 3), F(2, 3), F(1, 2)],
               [F(1, 10)] * 11 + [F(2, 5)]):
        res = scalar(3, ps)
        delta = true_delta(3, ps)
        lo, hi = res.uniform_margin["interval"]
        assert mpmath.mpf(lo) <= delta <= mpmath.mpf(hi)
        assert (res.uniform_margin["value"] > 0) == stable(3, ps)
        assert (lo > 0) == stable(3, ps) and (hi > 0) == stable(3, ps)


def diagonal_network(modes: list[str], sensor_modes: list[int]):
    n = len(modes)
    A = [[modes[i] if i == j else "0" for j in range(n)] for i in range(n)]
    return Network(A, 1, None, [Sensor(f"m{k}_{i}", [[1 if j == k else 0 for j in range(n)]], 1)
                                for i, k in enumerate(sensor_modes)])


def test_eight_diagonal_states_decide_the_boundary_exactly():
    # beyond the exact structure path (n > 6): the diagonal entries are the exact eigenvalues.
    # Mode 2 seen by u at p, mode 3/2 by v at 2/3: stable iff (1 − p)·4 < 1 and (1/3)·9/4 < 1
    net = diagonal_network(["2", "3/2"] + ["1/2"] * 6, [0, 1])
    for p_u, is_stable in ((R(3, 4) + R(1, 10 ** 40), True), (R(3, 4), False),
                           (R(3, 4) - R(1, 10 ** 40), False)):
        assert ((1 - F(p_u.p, p_u.q)) * 4 < 1) == is_stable
        res = network_analysis(net, p=[p_u, R(2, 3)])
        assert res.facts.necessary is is_stable
        assert verdict_of(res.facts)[0].value == ("mean-stable" if is_stable else "mean-unstable")
        u, v = res.sensors
        assert u.critical["exact"] and sp.sympify(u.critical["expression"]) == R(3, 4)
        if is_stable:
            # v alone: 1 − 1/(9/4) = 5/9
            assert v.critical["exact"] and sp.sympify(v.critical["expression"]) == R(5, 9)
        else:
            # mode 2 fails whatever v does: no critical value, never an "exact" 0
            assert v.critical["value"] is None and v.critical["interval"] is None
        lo, hi = res.uniform_margin["interval"]
        assert (lo > 0) == is_stable if p_u != R(3, 4) else lo <= 0 <= hi



def test_many_states_in_the_exact_region_are_decided_without_certificates():
    # 30 decoupled modes (one unstable, a = 3/2) seen by two sensors: (1 − p)²·9/4 < 1 at
    # p = 1/3 + 10⁻⁴⁰ fails at 1/3: the exact-region proof decides, no vech operator of
    # 465 × 465 per sensor is formed
    net = diagonal_network(["3/2"] + ["1/3"] * 29, [0, 0])
    for p, is_stable in ((R(1, 3) + R(1, 10 ** 40), True), (R(1, 3), False)):
        assert ((1 - F(p.p, p.q)) ** 2 * F(9, 4) < 1) == is_stable
        res = network_analysis(net, p=[p, p])
        assert verdict_of(res.facts)[0].value == ("mean-stable" if is_stable else "mean-unstable")
        assert res.method["certificates"] == 0


def test_a_congruence_batch_too_large_is_refused_naming_the_limit():
    import numpy as np
    import pytest

    from kfcrit.errors import NumericalError
    from kfcrit.theory.links import netkernels as nk

    # 100 operators on 100 states: 3·100·5050²·8 bytes ≈ 57 GiB > the limit
    with pytest.raises(NumericalError, match="limit"):
        nk.congruence_batch(np.zeros((100, 100, 100)))
    assert nk.congruence_batch(np.eye(2)[None]).shape == (1, 3, 3)
