"""Multi-hop meshes (MATH §13): joint law, generalised network theory, estimate relaying.

Every expected value is derived by hand in the test (series routes, one aggregating relay,
path diversity, negative binomial slot budgets) or by brute force written here.
"""
from __future__ import annotations

import itertools
import math
from fractions import Fraction

import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from kfcrit.analysis.verdict import verdict_of
from kfcrit.model.mesh import build_mesh
from kfcrit.model.network import Network, Sensor
from kfcrit.model.system import System
from kfcrit.theory.links.network import network_analysis
from kfcrit.theory.mesh.law import mesh_law, product_law, route_arrival, slot_arrival
from kfcrit.theory.mesh.relaying import (
    estimate_relaying,
    max_drop_cut,
    sensor_cut,
    smart_sensor_critical_value,
)
from kfcrit.theory.mesh.stability import hop_headrooms, law_stability, mesh_analysis

R = sp.Rational
SMALL = settings(max_examples=12, deadline=None)


def V(stability) -> str:  # noqa: ANN001, N802 - the verdict the analysis layer reads
    facts = getattr(stability, "facts", stability)
    return verdict_of(facts)[0].value


def scalar_network(a, names):
    return Network([[a]], 1, None, [Sensor(n, [[1]], 1) for n in names])


def series(q="1/2", slots=None):
    return build_mesh([("s", "sensor"), ("r1", "relay"), ("r2", "relay"), ("g", "gateway")],
                      [("s", "r1", q), ("r1", "r2", q), ("r2", "g", q)], [("s", "r1", "r2", "g")],
                      slots_per_period=slots)


def one_relay(q1, q2, qR, mode="aggregate"):
    return build_mesh([("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")],
                      [("s1", "r", q1), ("s2", "r", q2), ("r", "g", qR)],
                      [("s1", "r", "g"), ("s2", "r", "g")], relay_mode=mode)


# ---------------------------------------------------------------------------------------------
# series route: raw forwarding against estimate relaying
# ---------------------------------------------------------------------------------------------

def test_series_route_raw_forwarding_is_unstable_and_relaying_is_stable():
    mesh = series()
    law = mesh_law(mesh)
    assert law.exact and law.probabilities == (R(7, 8), R(1, 8))
    net = scalar_network("5/4", ["s"])
    facts = law_stability(net, law)
    # 7/8 · 25/16 = 175/128 = 1.367 > 1
    assert V(facts) == "mean-unstable" and facts.exact
    assert facts.necessary.binding.value_exact == R(175, 128)
    assert facts.necessary.binding.value == pytest.approx(1.3671875)
    rel = estimate_relaying(net, mesh)
    cut = rel.sensors[0].cut
    assert cut.p_cut_exact == R(1, 2) and len(cut.hops) == 1
    assert rel.sensors[0].value_exact == R(25, 32)          # 0.781 < 1
    assert rel.sensors[0].stable is True and rel.network_stable is True


def test_series_route_p_cut_is_the_largest_hop_drop():
    mesh = build_mesh([("s", "sensor"), ("a", "relay"), ("b", "relay"), ("g", "gateway")],
                      [("s", "a", "9/10"), ("a", "b", "3/5"), ("b", "g", "4/5", 1)],
                      [("s", "a", "b", "g")])
    cut = sensor_cut(mesh, "s")
    assert cut.p_cut_exact == R(2, 5) and cut.hops == ("a->b",)
    # drop of b->g with one retry is (1/5)^2 = 1/25; arrival 9/10 · 3/5 · 24/25
    assert route_arrival(mesh, mesh.routes[0]) == Fraction(9, 10) * Fraction(3, 5) * Fraction(24, 25)


# ---------------------------------------------------------------------------------------------
# slot budgets
# ---------------------------------------------------------------------------------------------

def test_slot_budget_negative_binomial_values():
    got = [slot_arrival([Fraction(4, 5)] * 3, D) for D in (3, 4, 5, 6)]
    assert [float(g) for g in got] == pytest.approx([0.512, 0.8192, 0.94208, 0.98304])
    assert [round(float(g), 3) for g in got] == [0.512, 0.819, 0.942, 0.983]
    for D in range(3, 9):
        nb = sum(math.comb(t - 1, 2) * Fraction(4, 5) ** 3 * Fraction(1, 5) ** (t - 3)
                 for t in range(3, D + 1))
        assert slot_arrival([Fraction(4, 5)] * 3, D) == nb
    law = mesh_law(series("4/5", slots=5))
    assert law.probabilities[1] == R(11776, 12500)


def brute_slots(q, D, caps):
    """P(success within D slots) by enumerating every attempt count per hop."""
    total = Fraction(0)
    ranges = [range(1, (c if c is not None else D) + 1) for c in caps]
    for a in itertools.product(*ranges):
        if sum(a) <= D:
            total += math.prod(qh * (1 - qh) ** (ah - 1) for qh, ah in zip(q, a))
    return total


@SMALL
@given(st.lists(st.fractions(min_value=0, max_value=1, max_denominator=7), min_size=1,
                max_size=3),
       st.integers(1, 6), st.data())
def test_slot_dp_matches_enumeration(q, D, data):
    caps = [data.draw(st.one_of(st.none(), st.integers(1, 3))) for _ in q]
    assert slot_arrival(q, D, caps) == brute_slots(q, D, caps)


@SMALL
@given(st.lists(st.fractions(min_value=0, max_value=1, max_denominator=9), min_size=1,
                max_size=3), st.integers(1, 7), st.integers(0, 2), st.fractions(0, 1, max_denominator=9))
def test_slot_arrival_is_monotone_in_budget_and_success(q, D, h, bump):
    h = h % len(q)
    assert slot_arrival(q, D + 1) >= slot_arrival(q, D)
    better = list(q)
    better[h] = max(q[h], bump)
    assert slot_arrival(better, D) >= slot_arrival(q, D)


# ---------------------------------------------------------------------------------------------
# one aggregating relay: correlated losses
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("q1, q2, qR", [("1/2", "1/2", "9/10"), ("9/10", "1/3", "3/4")])
def test_aggregating_relay_loses_both_together(q1, q2, qR):
    law = mesh_law(one_relay(q1, q2, qR))
    a, b, c = R(q1), R(q2), R(qR)
    assert law.exact and law.total() == 1
    assert law.all_lost() == (1 - c) + c * (1 - a) * (1 - b)
    assert law.as_dict()[frozenset({"s1", "s2"})] == c * a * b
    assert law.marginal("s1") == c * a
    # correlated: P(both lost) exceeds the product of the marginal losses
    assert law.all_lost() > (1 - c * a) * (1 - c * b)
    fwd = mesh_law(one_relay(q1, q2, qR, mode="forward"))
    assert fwd.all_lost() == (1 - c * a) * (1 - c * b)


@pytest.mark.parametrize("a, stable", [("3/2", True), ("7/4", True), ("9/5", False), (2, False)])
def test_aggregating_relay_stability_meets_at_the_closed_form(a, stable):
    # P(both lost) = 1/10 + 9/10 · 1/4 = 13/40; stable iff 13/40 · a² < 1 (a² < 40/13 = 3.077);
    # a = 7/4 gives 637/640, just inside
    mesh = one_relay("1/2", "1/2", "9/10")
    net = scalar_network(a, ["s1", "s2"])
    res = mesh_analysis(net, mesh, n_minus_1=False)
    assert res.all_lost_exact == R(13, 40)
    assert res.product_of_losses_exact == R(11, 20) ** 2
    assert res.facts.necessary.binding.value_exact == R(13, 40) * R(a) ** 2
    assert res.facts.exact
    assert V(res.facts) == ("mean-stable" if stable else "mean-unstable")
    if stable:
        assert res.facts.sufficient.certified and res.facts.sufficient.weights == "exact"


def test_two_disjoint_routes_for_one_sensor():
    mesh = build_mesh([("s", "sensor"), ("a", "relay"), ("b", "relay"), ("g", "gateway")],
                      [("s", "a", "1/2"), ("a", "g", "1/2"), ("s", "b", "2/3"), ("b", "g", "3/4")],
                      [("s", "a", "g"), ("s", "b", "g")])
    law = mesh_law(mesh)
    # lost iff both routes fail: (1 − 1/4)(1 − 1/2) = 3/8
    assert law.probabilities == (R(3, 8), R(5, 8))
    net = scalar_network("3/2", ["s"])       # 3/8 · 9/4 = 27/32 < 1
    assert V(law_stability(net, law)) == "mean-stable"
    # one route alone: 3/4 · 9/4 > 1
    res = mesh_analysis(net, mesh)
    by = {(c.kind, c.element): c for c in res.n_minus_1}
    assert V(by[("relay", "b")].facts) == "mean-unstable"
    assert by[("relay", "b")].lost_sensors == ()
    # route b alone: lost 1/2, 1/2 · 9/4 = 9/8 ≥ 1
    assert V(by[("hop", "s->a")].facts) == "mean-unstable"
    assert by[("relay", "a")].facts.necessary.binding.value_exact == R(9, 8)
    assert by[("relay", "b")].facts.necessary.binding.value_exact == R(27, 16)


def test_relay_failure_loses_its_sensors():
    # s1, s2 behind relay r (aggregating); s3 direct. Scalar a² = 2.
    mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("s3", "sensor"), ("r", "relay"),
                       ("g", "gateway")],
                      [("s1", "r", "1/2"), ("s2", "r", "1/2"), ("r", "g", "9/10"),
                       ("s3", "g", "1/2")],
                      [("s1", "r", "g"), ("s2", "r", "g"), ("s3", "g")])
    net = Network([[sp.sqrt(2)]], 1, None, [Sensor(n, [[1]], 1) for n in ("s1", "s2", "s3")])
    res = mesh_analysis(net, mesh)
    # all lost: 13/40 · 1/2 = 13/80; · 2 = 13/40 < 1
    assert res.all_lost_exact == R(13, 80)
    assert V(res.facts) == "mean-stable"
    relay = next(c for c in res.n_minus_1 if c.kind == "relay")
    assert relay.element == "r" and relay.lost_sensors == ("s1", "s2")
    # relay dead: 1 · 1/2 · 2 = 1, not < 1
    assert V(relay.facts) == "mean-unstable"
    assert relay.facts.necessary.binding.value_exact == 1
    hop = next(c for c in res.n_minus_1 if c.element == "s1->r")
    assert hop.lost_sensors == ("s1",) and V(hop.facts) == "mean-stable"


def test_bottleneck_hop_by_hand():
    # s1 → r → g (0.9, 0.6), s2 → g (0.5); scalar a² = 3; P(∅) = (1 − 0.54)·0.5 = 0.23
    mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")],
                      [("s1", "r", 0.9), ("r", "g", 0.6), ("s2", "g", 0.5)],
                      [("s1", "r", "g"), ("s2", "g")])
    net = Network([[sp.sqrt(3)]], 1, None, [Sensor(n, [[1]], 1) for n in ("s1", "s2")])
    rows = {h.hop: h for h in hop_headrooms(net, mesh)}
    # (1 − 0.6σ)·0.5·3 = 1; (1 − 0.9σ)·0.5·3 = 1; 0.46(1 − σ)·3 = 1
    assert rows["s1->r"].critical_q == pytest.approx(5 / 9, abs=1e-9)
    assert rows["r->g"].critical_q == pytest.approx(10 / 27, abs=1e-9)
    assert rows["s2->g"].critical_q == pytest.approx(1 - 1 / 1.38, abs=1e-9)
    assert rows["s2->g"].headroom == pytest.approx(0.5 - (1 - 1 / 1.38), abs=1e-9)
    res = mesh_analysis(net, mesh, n_minus_1=False)
    assert res.bottleneck == "s2->g"
    assert not res.law.exact and res.all_lost == pytest.approx(0.23)


# ---------------------------------------------------------------------------------------------
# properties
# ---------------------------------------------------------------------------------------------

@st.composite
def layered_meshes(draw):
    """Random meshes: sensors, relays in layers, hops forward only; routes from the hops."""
    ns = draw(st.integers(1, 3))
    nr = draw(st.integers(0, 3))
    sensors = [f"s{i}" for i in range(ns)]
    relays = [f"r{i}" for i in range(nr)]
    order = sensors + relays + ["g"]
    hops = {}
    for i, u in enumerate(order[:-1]):
        for v in order[i + 1:]:
            if v in sensors:
                continue
            if v == "g" or draw(st.booleans()):
                hops[(u, v)] = draw(st.fractions(0, 1, max_denominator=6))
    routes = []
    for s in sensors:
        paths = _paths(hops, s, "g")
        k = draw(st.integers(1, min(2, len(paths))))
        routes += [tuple(p) for p in draw(st.permutations(paths))[:k]]
    mode = draw(st.sampled_from(["aggregate", "forward"]))
    return build_mesh([(s, "sensor") for s in sensors] + [(r, "relay") for r in relays]
                      + [("g", "gateway")], [(u, v, q) for (u, v), q in hops.items()], routes,
                      relay_mode=mode)


def _paths(hops, u, t, seen=()):
    if u == t:
        return [list(seen) + [t]]
    out = []
    for (a, b) in hops:
        if a == u and b not in seen:
            out += _paths(hops, b, t, tuple(seen) + (u,))
    return out[:6]


@SMALL
@given(layered_meshes())
def test_law_sums_to_one_and_is_non_negative(mesh):
    law = mesh_law(mesh)
    assert law.exact and law.total() == 1
    assert all(v >= 0 for v in law.probabilities)


@SMALL
@given(st.lists(st.fractions(0, 1, max_denominator=8), min_size=1, max_size=4),
       st.lists(st.integers(0, 2), min_size=4, max_size=4))
def test_independent_one_hop_links_give_the_product_law(q, retries):
    names = [f"s{i}" for i in range(len(q))]
    mesh = build_mesh([(n, "sensor") for n in names] + [("g", "gateway")],
                      [(n, "g", qi, k) for n, qi, k in zip(names, q, retries)],
                      [(n, "g") for n in names])
    s = [1 - (1 - qi) ** (k + 1) for qi, k in zip(q, retries)]
    assert mesh_law(mesh).probabilities == product_law(names, s).probabilities


@SMALL
@given(layered_meshes(), st.data())
def test_arrival_is_monotone_in_each_hop(mesh, data):
    k = data.draw(st.integers(0, len(mesh.hops) - 1))
    hi = data.draw(st.fractions(0, 1, max_denominator=6))
    lo = data.draw(st.fractions(0, hi, max_denominator=6))
    a, b = mesh_law(mesh, override={k: lo}), mesh_law(mesh, override={k: hi})
    for s in mesh.sensors:
        assert b.marginal(s) >= a.marginal(s)
    assert b.all_lost() <= a.all_lost()


def brute_cut(nodes, edges, s, t):
    inner = [n for n in nodes if n not in (s, t)]
    best = -1.0
    for bits in itertools.product((0, 1), repeat=len(inner)):
        side = {s} | {n for n, b in zip(inner, bits) if b}
        best = max(best, math.prod(d for u, v, d in edges if u in side and v not in side))
    return best


@SMALL
@given(st.integers(2, 6), st.data())
def test_max_cut_matches_brute_force(n, data):
    nodes = [f"n{i}" for i in range(n)]
    edges = []
    for u in nodes:
        for v in nodes:
            if u != v and data.draw(st.booleans()):
                edges.append((u, v, data.draw(st.sampled_from([0.0, 0.1, 0.25, 0.5, 0.8, 1.0]))))
    value, side, crossing = max_drop_cut(nodes, edges, "n0", nodes[-1])
    assert value == pytest.approx(brute_cut(nodes, edges, "n0", nodes[-1]), abs=1e-12)
    assert "n0" in side and nodes[-1] not in side
    assert value == pytest.approx(math.prod(edges[k][2] for k in crossing), abs=1e-12)


@pytest.mark.parametrize("A, C, p", [
    ([["3/2"]], [[[1]], [[1]]], ("1/2", "1/3")),
    ([[2]], [[[1]], [[1]]], ("1/2", "1/3")),
    ([[2, 0], [0, "3/2"]], [[[1, 0]], [[0, 1]]], ("4/5", "2/3")),
    ([[2, 0], [0, "3/2"]], [[[1, 0]], [[0, 1]]], ("4/5", "1/3")),
    ([["6/5", 1], [0, "11/10"]], [[[1, 0]], [[1, 1]]], ("1/2", "1/2")),
])
def test_product_law_reproduces_the_network_verdict(A, C, p):
    net = Network(A, 1, None, [Sensor(f"s{i}", c, 1) for i, c in enumerate(C)])
    law = product_law(net.names, [R(v) for v in p])
    ours = law_stability(net, law)
    ref = network_analysis(net, [R(v) for v in p])
    assert V(ours) == V(ref.facts)
    assert V(ours) != "undetermined"


def test_smart_sensor_critical_value():
    # degenerate for raw measurements (equal moduli), not for a smart sensor
    sys_ = System([[2, 0], [0, -2]], [[1, 1]], 1, 1)
    v = smart_sensor_critical_value(sys_)
    assert v.exact == R(3, 4) and v.value == pytest.approx(0.75)
    assert smart_sensor_critical_value(System([[2, 0], [0, 3]], [[1, 0]], 1, 1)).value is None
    assert smart_sensor_critical_value(System([["1/2"]], [[1]], 1, 1)).value == 0.0


def test_relaying_with_several_sensors_is_sufficient_only():
    mesh = one_relay("1/2", "1/2", "1/2")
    net = Network([[2, 0], [0, 2]], 1, None, [Sensor("s1", [[1, 0]], 1), Sensor("s2", [[0, 1]], 1)])
    rel = estimate_relaying(net, mesh)
    assert all(not r.detectable and r.stable is False for r in rel.sensors)
    assert rel.network_stable is None and "outside" in rel.basis
    net2 = scalar_network("5/4", ["s1", "s2"])
    rel2 = estimate_relaying(net2, mesh)
    assert rel2.network_stable is True and "sufficient" in rel2.basis
    assert rel2.sensors[0].cut.p_cut_exact == R(1, 2)
