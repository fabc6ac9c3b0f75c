"""Sensor networks (issue 15, MATH §9): model, parser, necessary and sufficient surfaces.

Expected values are derived by hand in each test (closed forms of the scalar plant seen by k
sensors and of decoupled modes), by the single-link theory (N = 1) and by an independent Monte
Carlo of E[P_t] written here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from kfcrit.analysis.spec import parse_channel as channel_from_mapping
from kfcrit.analysis.verdict import verdict_of
from kfcrit.errors import InputError
from kfcrit.model.network import Network, Sensor, euclidean_distance, network_from_mapping
from kfcrit.model.system import System
from kfcrit.theory.critical.section import critical_value
from kfcrit.theory.links import netkernels as nk
from kfcrit.theory.links.network import necessary_constraints, network_analysis
from kfcrit.theory.upper.bracket import upper_bound

R = sp.Rational


def V(facts) -> str:  # noqa: ANN001, N802 - the verdict the analysis layer reads from the facts
    return verdict_of(facts)[0].value


def scalar_network(a, rs):
    return Network([[a]], 1, None, [Sensor(f"s{i}", [[1]], r) for i, r in enumerate(rs)])


def parser(mapping, prefix):
    return channel_from_mapping(mapping, prefix)


# ---------------------------------------------------------------------------------------------
# model and parser
# ---------------------------------------------------------------------------------------------

def test_stacked_system_of_one_sensor_is_the_single_sensor_system():
    A, C, Q, Rm = [["1.25", 0], [1, "1.1"]], [[1, 1]], 20, "2.5"
    single = System(A, C, Q, Rm)
    net = Network(A, Q, None, [Sensor("only", C, Rm)])
    stacked = net.stacked_system()
    for key in ("A", "C", "Q", "R", "Sigma0"):
        assert getattr(stacked, key) == getattr(single, key)
    assert stacked.exact and single.exact


def test_stacked_and_received_systems():
    net = Network([[1, 0], [0, 2]], 1, None,
                  [Sensor("n", [[1, 0]], 1), Sensor("s", [[0, 1], [1, 1]], [[2, 0], [0, 3]])])
    st = net.stacked_system()
    assert st.C == sp.Matrix([[1, 0], [0, 1], [1, 1]])
    assert st.R == sp.diag(1, 2, 3)
    rs = net.received_system(["s"])
    assert rs.C == sp.Matrix([[0, 1], [1, 1]]) and rs.R == sp.diag(2, 3)


@pytest.mark.parametrize("bad, field", [
    ({"name": "b", "C": [[1, 2, 3]], "R": 1}, "sensors[1].C"),
    ({"name": "a", "C": [[1, 0]], "R": 1}, "sensors[1].name"),
    ({"name": "b", "C": [[1, 0]], "R": -1}, "sensors[1].R"),
    ({"name": "b", "C": [[1, 0]], "R": [[1, 0], [0, 1]]}, "sensors[1].R"),
    ({"name": "b", "C": [[1, 0]], "R": 1, "colour": 1}, "sensors[1].colour"),
    ({"name": "b.c", "C": [[1, 0]], "R": 1}, "sensors[1].name"),
    ({"name": "b", "R": 1}, "sensors[1].C"),
])
def test_parser_errors_name_the_field(bad, field):
    doc = {"A": [[1, 0], [0, 2]], "Q": 1,
           "sensors": [{"name": "a", "C": [[1, 0]], "R": 1}, bad]}
    with pytest.raises(InputError) as exc:
        network_from_mapping(doc, parser)
    assert exc.value.field == field
    assert "\n" not in str(exc.value)


def test_parser_refuses_both_forms():
    doc = {"A": [[2]], "Q": 1, "C": [[1]], "sensors": [{"name": "a", "C": [[1]], "R": 1}]}
    with pytest.raises(InputError) as exc:
        network_from_mapping(doc, parser)
    assert exc.value.field == "C"


def test_parser_positions_give_exact_distance_and_links_merge():
    seen = {}

    def spy(mapping, prefix):
        seen[prefix] = mapping
        return channel_from_mapping({"model": "bernoulli", "arrival_probability": "0.5"}, prefix)

    doc = {"A": [["1.5"]], "Q": 1, "sink_position_m": [0, 0],
           "links": {"radio": "r", "noise": {"noise_figure_db": 10, "bandwidth_hz": 1}},
           "sensors": [{"name": "a", "C": [[1]], "R": 1, "position_m": ["3", "4"],
                        "channel": {"noise": {"bandwidth_hz": 2}}},
                       {"name": "b", "C": [[1]], "R": 1, "position_m": [1, 1]}]}
    net = network_from_mapping(doc, spy)
    a = seen["sensors[0].channel"]
    assert a["model"] == "link-budget" and a["radio"] == "r"
    assert a["distance_m"] == 5                                    # 3-4-5, exactly
    assert a["noise"] == {"noise_figure_db": 10, "bandwidth_hz": 2}   # nested merge
    assert seen["sensors[1].channel"]["distance_m"] == sp.sqrt(2)
    assert net.sensors[0].position == (3, 4)
    assert euclidean_distance((R(1, 2), 0), (0, 0)) == R(1, 2)


def test_parser_position_needs_sink():
    doc = {"A": [[2]], "Q": 1, "links": {"radio": "r"},
           "sensors": [{"name": "a", "C": [[1]], "R": 1, "position_m": [1, 2]}]}
    with pytest.raises(InputError) as exc:
        network_from_mapping(doc, parser)
    assert exc.value.field == "sink_position_m"


# ---------------------------------------------------------------------------------------------
# kernels
# ---------------------------------------------------------------------------------------------

def test_weights_sum_to_one_and_derivative_matches_difference_quotient():
    col = nk.all_received_sets(4)
    p = np.array([0.3, 0.6, 0.9, 0.05])
    d = np.array([1.0, 0.0, -1.0, 0.5])
    w, dw = nk.weights(col, p, d)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    # π({1, 2}) by hand: (1 − 0.3)·0.6·0.9·(1 − 0.05)
    assert w[0b0110] == pytest.approx(0.7 * 0.6 * 0.9 * 0.95, rel=1e-14)
    h = 1e-7
    w2, _ = nk.weights(col, p + h * d)
    assert np.abs((w2 - w) / h - dw).max() < 1e-6


def test_sub_collection_puts_missing_mass_on_total_loss():
    p = np.array([0.9] * 14)
    col = nk.likely_received_sets(p, budget=50)
    assert not col.masks[0].any() and col.size == 50
    w, _ = nk.weights(col, p)
    assert w.sum() == pytest.approx(1.0, abs=1e-12)
    assert w[0] > 0.1 ** 14                       # more than π(∅): the rest of the mass


# ---------------------------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------------------------

def test_scalar_two_sensors_closed_forms():
    # a = 2, p = (1/2, 3/5): (1 − p1)(1 − p2)a² = (1/2)(2/5)·4 = 4/5 < 1: stable.
    # critical p1: (1 − p1)(2/5)·4 = 1 → p1 = 3/8; critical p2: (1/2)(1 − p2)·4 = 1 → p2 = 1/2.
    # uniform margin δ: (1/2 + δ)(2/5 + δ)·4 = 1 → δ² + (9/10)δ − 1/20 = 0,
    # δ = (−9/10 + √(81/100 + 1/5))/2.
    net = scalar_network(2, [1, 2])
    res = network_analysis(net, [R(1, 2), R(3, 5)])
    assert V(res.facts) == "mean-stable"
    a, b = res.sensors
    assert sp.sympify(a.critical["expression"]) == R(3, 8) and a.critical["exact"]
    assert sp.sympify(b.critical["expression"]) == R(1, 2) and b.critical["exact"]
    delta = (-0.9 + math.sqrt(0.81 + 0.2)) / 2
    assert res.uniform_margin["value"] == pytest.approx(delta, abs=1e-9)
    # N − 1: p1 = 0 → (2/5)·4 > 1; p2 = 0 → (1/2)·4 > 1: both unstable
    assert [V(s.n_minus_1) for s in res.sensors] == ["mean-unstable"] * 2
    # bottleneck: margins p_i − crit_i: 1/2 − 3/8 = 1/8, 3/5 − 1/2 = 1/10 → s1
    assert res.bottleneck["name"] == "s1"


def test_scalar_three_sensors_unstable_and_n_minus_1():
    # a = 3/2 (a² = 9/4), p = (1/10, 1/10, 1/10): (9/10)³·9/4 = 1.64 > 1: unstable.
    net = scalar_network(R(3, 2), [1, 1, 1])
    res = network_analysis(net, [R(1, 10)] * 3)
    assert V(res.facts) == "mean-unstable"
    # critical p1 with p2 = p3 = 1/10: 1 − 1/((81/100)(9/4)) = 1 − 400/729 = 329/729
    assert sp.sympify(res.sensors[0].critical["expression"]) == R(329, 729)
    # uniform: 1 − (p − δ) = 9/10 + δ, (9/10 + δ)³·9/4 = 1 → δ = (4/9)^(1/3) − 9/10 < 0
    assert res.uniform_margin["value"] == pytest.approx((4 / 9) ** (1 / 3) - 0.9, abs=1e-9)
    assert res.uniform_margin["value"] < 0


def test_scalar_stable_margin_clips_at_zero():
    # a = 3/2, p = (0.9, 0.2): (1/10)(4/5)(9/4) = 0.18 < 1. Degrading both: p1 hits 0 only
    # after p2 does; with p2 clipped at 0 (δ ≥ 0.2): (1/10 + δ)·(9/4) = 1 → δ = 4/9 − 1/10.
    # Before clipping, at δ = 0.2: (0.3)(1.0)(2.25) = 0.675 < 1, so the root is after.
    net = scalar_network(R(3, 2), [1, 1])
    res = network_analysis(net, [R(9, 10), R(1, 5)])
    assert V(res.facts) == "mean-stable"
    assert res.uniform_margin["value"] == pytest.approx(4 / 9 - 1 / 10, abs=1e-9)
    # p2 critical: (1/10)(1 − p2)(9/4) < 1 for every p2 → 0; N − 1 of s1 is stable
    assert res.sensors[1].critical["value"] == 0
    assert V(res.sensors[1].n_minus_1) == "mean-stable"
    assert V(res.sensors[0].n_minus_1) == "mean-unstable"   # (4/5)(9/4) = 1.8


def test_decoupled_modes():
    # A = diag(2, 3), sensor i sees mode i: stable iff (1 − p1)·4 < 1 and (1 − p2)·9 < 1.
    net = Network([[2, 0], [0, 3]], 1, None, [Sensor("a", [[1, 0]], 1), Sensor("b", [[0, 1]], 1)])
    res = network_analysis(net, [R(4, 5), R(9, 10)])
    assert V(res.facts) == "mean-stable"
    assert sp.sympify(res.sensor("a").critical["expression"]) == R(3, 4)
    assert sp.sympify(res.sensor("b").critical["expression"]) == R(8, 9)
    # uniform: min over modes of the δ that breaks it: 4/5 − 3/4 = 1/20, 9/10 − 8/9 = 1/90
    assert res.uniform_margin["value"] == pytest.approx(1 / 90, abs=1e-12)
    assert res.bottleneck["name"] == "b"
    assert [V(s.n_minus_1) for s in res.sensors] == ["mean-unstable"] * 2
    # p1 = 0.7 < 3/4: unstable whatever p2
    assert V(network_analysis(net, [R(7, 10), 1]).facts) == "mean-unstable"


def test_decoupled_with_stable_mode_survives_losing_its_sensor():
    net = Network([[2, 0], [0, R(1, 2)]], 1, None,
                  [Sensor("a", [[1, 0]], 1), Sensor("b", [[0, 1]], 1)])
    res = network_analysis(net, [R(9, 10), R(1, 2)])
    assert V(res.facts) == "mean-stable"
    assert res.sensor("b").critical["value"] == 0
    assert V(res.sensor("b").n_minus_1) == "mean-stable"
    assert V(res.sensor("a").n_minus_1) == "mean-unstable"


def test_necessary_constraints_of_a_two_dimensional_eigenspace():
    # A = 2·I₂ (g = 2); sensors see e1, e2 and e1 again: the hyperplanes of their row spaces
    # are {s0, s2} (the e1 line) and {s1} (the e2 line).
    net = Network([[2, 0], [0, 2]], 1, None,
                  [Sensor("s0", [[1, 0]], 1), Sensor("s1", [[0, 1]], 1),
                   Sensor("s2", [[3, 0]], 1)])
    blinds = {c.blind for c in necessary_constraints(net)}
    assert blinds == {frozenset({0, 2}), frozenset({1})}


def test_undetectable_network_has_no_critical_value():
    net = Network([[2, 0], [0, 3]], 1, None, [Sensor("a", [[1, 0]], 1), Sensor("b", [[1, 0]], 1)])
    res = network_analysis(net, [1, 1])
    assert V(res.facts) == "mean-unstable"
    assert all(s.critical["value"] is None for s in res.sensors)
    assert res.uniform_margin["unbounded"] == "negative"


def test_coupled_case_interval_contains_boundary_and_is_certified():
    # A = diag(2, 3); a sees [1, 1], b sees mode 2. Not modal one-step observable ({a} sees
    # two modes through one row): the critical value of a lies in [necessary, certified].
    net = Network([[2, 0], [0, 3]], 1, None, [Sensor("a", [[1, 1]], 1), Sensor("b", [[0, 1]], 1)])
    res = network_analysis(net, [R(19, 20), R(1, 2)])
    assert not res.exact_region["holds"]
    lo, hi = res.sensor("a").critical["interval"]
    # necessary end by hand: mode 2 needs (1 − p_a)(1/2)·9 < 1 → p_a > 7/9; mode 1 (blind b)
    # needs (1 − p_a)·4 < 1 → p_a > 3/4
    assert lo == pytest.approx(7 / 9, abs=1e-12)
    assert hi is not None and lo <= hi <= 1
    cert = res.sensor("a").surfaces["sufficient"]["certificate"]
    assert cert["ok"] and cert["reason"] == "proven"
    # above the certified end the verdict is stable, below the necessary end unstable
    assert V(network_analysis(net, [min(hi + 1e-3, 1.0), R(1, 2)]).facts) == "mean-stable"
    assert V(network_analysis(net, [lo - 1e-3, R(1, 2)]).facts) == "mean-unstable"


# ---------------------------------------------------------------------------------------------
# N = 1 reproduces the single-link theory
# ---------------------------------------------------------------------------------------------

entries = st.sampled_from([R(k, 4) for k in range(-8, 9)])


@settings(max_examples=15, deadline=None)
@given(a=st.lists(entries, min_size=4, max_size=4),
       c=st.lists(st.sampled_from([0, 1, 2, -1]), min_size=2, max_size=2),
       p=st.sampled_from([R(1, 10), R(1, 2), R(9, 10), R(99, 100)]))
def test_one_sensor_reduces_to_single_link(a, c, p):
    A = [[a[0], a[1]], [a[2], a[3]]]
    if c == [0, 0]:
        c = [1, 0]
    net = Network(A, 1, None, [Sensor("only", [c], 1)])
    system = System(A, [c], 1, 1)
    cv = critical_value(system).to_dict()
    res = network_analysis(net, [p])
    row = res.sensors[0]
    klass = cv["classification"]
    if klass == "not-detectable":
        assert V(res.facts) == "mean-unstable" and row.critical["value"] is None
        return
    # the necessary surface is p_low = max(1 − 1/ρ², 0)
    rho2 = max(abs(np.linalg.eigvals(system.a))) ** 2
    p_low = max(1 - 1 / rho2, 0.0) if rho2 >= 1 else 0.0
    assert row.surfaces["necessary"]["value"] == pytest.approx(p_low, abs=1e-9)
    # the sufficient surface is a certified point at or above the single-link p_up (it can
    # never lie below p_up's lower end); the network's path search stops within 1e-4 of it
    up = upper_bound(system)
    if up.certified and row.surfaces["sufficient"] is not None:
        assert up.interval[0] - 1e-9 <= row.surfaces["sufficient"]["value"] <= \
            up.interval[1] + 1e-4
    # the critical value and verdict are the single-link ones
    pc = cv["critical_value"]["value"]
    if klass == "stable":
        assert V(res.facts) == "mean-stable"
    elif pc is not None:
        assert row.critical["value"] == pc
        assert row.critical["expression"] == cv["critical_value"]["expression"]
        assert V(res.facts) == ("mean-stable" if float(p) > pc else "mean-unstable")
        assert res.uniform_margin["value"] == pytest.approx(float(p) - pc, abs=1e-15)


# ---------------------------------------------------------------------------------------------
# monotonicity of the region in each p_i
# ---------------------------------------------------------------------------------------------

small = st.sampled_from([R(k, 2) for k in range(-4, 5)])
probs = st.sampled_from([R(k, 10) for k in range(0, 11)])


@settings(max_examples=20, deadline=None)
@given(a=st.lists(small, min_size=4, max_size=4),
       c=st.lists(st.sampled_from([0, 1]), min_size=4, max_size=4),
       p=st.lists(probs, min_size=2, max_size=2), i=st.integers(0, 1),
       bump=st.sampled_from([R(1, 10), R(3, 10), R(1, 2)]))
def test_region_is_monotone_in_each_probability(a, c, p, i, bump):
    A = [[a[0], a[1]], [a[2], a[3]]]
    net = Network(A, 1, None, [Sensor("u", [c[:2]], 1), Sensor("v", [c[2:]], 1)])
    q = list(p)
    q[i] = min(q[i] + bump, 1)
    low, high = network_analysis(net, p), network_analysis(net, q)
    if V(low.facts) == "mean-stable":
        assert V(high.facts) == "mean-stable"
    if V(high.facts) == "mean-unstable":
        assert V(low.facts) == "mean-unstable"
    # critical values: the necessary end never exceeds the certified end
    for row in low.sensors:
        iv = row.critical["interval"]
        if iv is not None and iv[1] is not None:
            assert iv[0] <= iv[1] + 1e-12


# ---------------------------------------------------------------------------------------------
# simulation either side of the boundary
# ---------------------------------------------------------------------------------------------

def _mean_covariance(a, p, r, q, steps, paths, rng):
    """Independent Monte Carlo of E[P_t] for a scalar plant seen by several sensors: the
    received measurements combine in information form, 1/P⁺ = 1/P + Σ_{i∈S} 1/r_i."""
    P = np.ones(paths)
    out = {}
    for t in range(1, steps + 1):
        S = rng.random((paths, len(p))) < np.asarray(p)
        P = a * a / (1 / P + (S / np.asarray(r)).sum(axis=1)) + q
        out[t] = P.mean()
    return out


@pytest.mark.parametrize("p2, stable", [(0.35, True), (0.1, False)])
def test_simulation_either_side_of_the_boundary(p2, stable):
    # a = 1.2, p1 = 0.1: boundary (0.9)(1 − p2)·1.44 = 1 → p2 = 0.2284; 0.35 above, 0.1 below.
    net = scalar_network(R(6, 5), [1, 2])
    res = network_analysis(net, [0.1, p2])
    assert V(res.facts) == ("mean-stable" if stable else "mean-unstable")
    assert res.sensors[1].critical["value"] == pytest.approx(1 - 1 / (0.9 * 1.44), abs=1e-12)
    m = _mean_covariance(1.2, [0.1, p2], [1.0, 2.0], 1.0, 40, 100_000,
                         np.random.default_rng(20240515))
    growth = m[40] / m[20]
    # unstable: E[P_t] grows like ((0.9)(0.9)·1.44)^t, ≈ 21.6 over 20 steps; stable: flat
    assert (growth < 1.5) if stable else (growth > 5)
