"""Mesh model (MATH §13): validation names the offending field; most reliable routes."""
from __future__ import annotations

from fractions import Fraction

import pytest
import sympy as sp

from kfcrit.errors import ExitCode, InputError
from kfcrit.model.mesh import (
    ROUTING_GIVEN,
    ROUTING_RELIABLE,
    Hop,
    Mesh,
    Node,
    Route,
    build_mesh,
)

NODES = [("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")]
HOPS = [("s1", "r", "9/10"), ("s2", "r", "4/5"), ("r", "g", "1/2", 2), ("s2", "g", 0.3)]


def test_exact_and_float_probabilities():
    m = build_mesh(NODES, HOPS, [("s1", "r", "g"), ("s2", "r", "g"), ("s2", "g")])
    assert m.hops[0].q_exact == sp.Rational(9, 10) and m.hops[0].q == 0.9
    assert m.hops[3].q_exact is None and m.hops[3].q == 0.3
    assert m.hops[2].period_success_exact() == 1 - sp.Rational(1, 8)
    assert m.sensors == ("s1", "s2") and m.relays == ("r",) and m.gateway == "g"
    assert not m.exact and m.routing == ROUTING_GIVEN
    assert m.route_hops(m.routes[0]) == (0, 2)
    assert len(m.routes_of("s2")) == 2


def test_fraction_and_int_are_exact():
    m = build_mesh([("s", "sensor"), ("g", "gateway")], [("s", "g", Fraction(1, 3))], [("s", "g")])
    assert m.exact and m.hops[0].q_exact == sp.Rational(1, 3)
    m = build_mesh([("s", "sensor"), ("g", "gateway")], [{"source": "s", "target": "g", "q": 1}],
                   [("s", "g")])
    assert m.hops[0].q_exact == 1


@pytest.mark.parametrize("routes, field, words", [
    ([("s1", "x", "g"), ("s2", "g")], "mesh.routes[0]", "unknown node 'x'"),
    ([("s1", "r", "s1", "g"), ("s2", "g")], "mesh.routes[0]", "cycle"),
    ([("s1", "r", "g")], "mesh.nodes[1]", "no route"),
    ([("s1", "r", "g"), ("s2", "r")], "mesh.routes[1]", "gateway"),
    ([("s1", "g"), ("s2", "g")], "mesh.routes[0]", "s1->g"),
    ([("r", "g"), ("s1", "r", "g"), ("s2", "g")], "mesh.routes[0].sensor", "not a sensor"),
    ([("s1", "r", "g"), ("s2", "g"), ("s2", "g")], "mesh.routes[2]", "repeats"),
])
def test_route_errors_name_the_field(routes, field, words):
    with pytest.raises(InputError) as exc:
        build_mesh(NODES, HOPS, routes)
    assert exc.value.field == field
    assert words in str(exc.value)
    assert exc.value.exit_code == ExitCode.BAD_INPUT == 2
    assert "\n" not in str(exc.value)


def test_slot_budget_below_a_route_length():
    with pytest.raises(InputError) as exc:
        build_mesh(NODES, HOPS, [("s1", "r", "g"), ("s2", "g")], slots_per_period=1)
    assert exc.value.field == "mesh.slots_per_period"
    assert "2 hops" in str(exc.value)
    for bad in (0, -3, 2.5, True):
        with pytest.raises(InputError):
            build_mesh(NODES, HOPS, [("s1", "r", "g"), ("s2", "g")], slots_per_period=bad)


@pytest.mark.parametrize("hops, field", [
    ([("s1", "r", "11/10")], "mesh.hops[0].q"),
    ([("s1", "r", -0.1)], "mesh.hops[0].q"),
    ([("s1", "r", float("nan"))], "mesh.hops[0].q"),
    ([("s1", "r", "abc")], "mesh.hops[0].q"),
    ([("s1", "r", True)], "mesh.hops[0].q"),
    ([("s1", "r", 0.5, -1)], "mesh.hops[0].retries"),
    ([("s1", "zz", 0.5)], "mesh.hops[0].target"),
    ([("s1", "s1", 0.5)], "mesh.hops[0]"),
    ([("g", "r", 0.5)], "mesh.hops[0].source"),
    ([("s1", "r", 0.5), ("s1", "r", 0.6)], "mesh.hops[1]"),
    ([{"source": "s1", "target": "r", "q": 0.5, "colour": 1}], "mesh.hops[0].colour"),
])
def test_hop_errors_name_the_field(hops, field):
    with pytest.raises(InputError) as exc:
        build_mesh(NODES, hops, [])
    assert exc.value.field == field


@pytest.mark.parametrize("nodes, field", [
    ([("s", "sensor"), ("g", "gateway"), ("h", "gateway")], "mesh.nodes"),
    ([("s", "sensor")], "mesh.nodes"),
    ([("g", "gateway")], "mesh.nodes"),
    ([("s", "sensor"), ("s", "relay"), ("g", "gateway")], "mesh.nodes[1].name"),
    ([("s", "boss"), ("g", "gateway")], "mesh.nodes[0].role"),
    ([("1s", "sensor"), ("g", "gateway")], "mesh.nodes[0].name"),
    ([("s", "sensor", "broadcast"), ("g", "gateway")], "mesh.nodes[0].mode"),
])
def test_node_errors_name_the_field(nodes, field):
    with pytest.raises(InputError) as exc:
        build_mesh(nodes, [], [])
    assert exc.value.field == field


def test_relay_mode_is_checked():
    with pytest.raises(InputError) as exc:
        build_mesh(NODES, HOPS, [("s1", "r", "g"), ("s2", "g")], relay_mode="flood")
    assert exc.value.field == "mesh.relay_mode"


def test_direct_construction_is_validated():
    nodes = (Node("s", "sensor"), Node("g", "gateway"))
    hops = (Hop("s", "g", 0.5, sp.Rational(1, 2)),)
    Mesh(nodes, hops, (Route("s", ("s", "g")),))
    with pytest.raises(InputError) as exc:
        Mesh(nodes, (Hop("s", "g", 0.5, sp.Rational(1, 3)),), (Route("s", ("s", "g")),))
    assert exc.value.field == "mesh.hops[0].q"


# ---------------------------------------------------------------------------------------------
# most reliable paths
# ---------------------------------------------------------------------------------------------

def test_most_reliable_path_prefers_two_good_hops_to_one_weak_hop():
    nodes = [("s", "sensor"), ("r", "relay"), ("g", "gateway")]
    # direct 0.5 versus 0.9·0.9 = 0.81 through r
    m = build_mesh(nodes, [("s", "g", "1/2"), ("s", "r", "9/10"), ("r", "g", "9/10")])
    assert m.routes[0].nodes == ("s", "r", "g") and m.routes[0].origin == "most-reliable"
    assert m.routing == ROUTING_RELIABLE and "Dijkstra" in m.routing
    # retries on the direct hop: 1 − (1/2)^3 = 7/8 > 0.81
    m = build_mesh(nodes, [("s", "g", "1/2", 2), ("s", "r", "9/10"), ("r", "g", "9/10")])
    assert m.routes[0].nodes == ("s", "g")


def test_most_reliable_path_goes_through_several_relays_and_skips_dead_hops():
    nodes = [("s", "sensor"), ("a", "relay"), ("b", "relay"), ("g", "gateway")]
    hops = [("s", "a", 0.9), ("a", "b", 0.9), ("b", "g", 0.9), ("a", "g", 0.0), ("s", "g", 0.6)]
    m = build_mesh(nodes, hops)
    assert m.routes[0].nodes == ("s", "a", "b", "g")        # 0.729 > 0.6


def test_no_path_is_an_input_error():
    nodes = [("s", "sensor"), ("t", "sensor"), ("g", "gateway")]
    with pytest.raises(InputError) as exc:
        build_mesh(nodes, [("s", "g", 0.5), ("t", "s", 0.0)])
    assert exc.value.field == "mesh.nodes[1]"
    assert "no route" in str(exc.value)
