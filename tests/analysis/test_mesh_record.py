"""The ``mesh`` record section of mesh files (theory §13), end to end through ``analyze``.

Every expected value is derived here by hand: series routes (products of hop successes),
negative binomial slot budgets, P(both lost) = (1 − q_R) + q_R(1 − q_1)(1 − q_2) behind one
aggregating relay, 1 − (1 − a)² for two disjoint routes, and the scalar rule "mean-stable iff
P(all lost)·a² < 1" (theory §9, §13); the relaying min-cut of a series path is its largest hop
drop (Gupta et al. 2009).
"""
from __future__ import annotations

from fractions import Fraction
from math import comb
from pathlib import Path

import pytest

import kfcrit
from kfcrit.analysis.spec import spec_from_mapping
from kfcrit.errors import InputError

F = Fraction


def analyze(doc: dict, **kw) -> dict:
    spec = spec_from_mapping(doc, base_dir=Path("."))
    opts = {"simulate": False, "quick": True, **kw}
    return kfcrit.analyze(spec, **opts).to_dict()


def mesh_doc(a, nodes, hops, routes=None, **mesh) -> dict:
    body = {"nodes": nodes, "hops": hops, **mesh}
    if routes is not None:
        body["routes"] = routes
    return {"name": "probe", "A": a, "Q": 1, "mesh": body}


def sensor(name, C=1, R=1):
    return {"name": name, "role": "sensor", "C": C, "R": R}


def relay(name, **kw):
    return {"name": name, "role": "relay", **kw}


GW = {"name": "g", "role": "gateway"}


def hop(a, b, q, **kw):
    return {"from": a, "to": b, "attempt_success": q, **kw}


def series(q, a="5/4", **mesh):
    return mesh_doc(a, [sensor("s"), relay("r1"), relay("r2"), GW],
                    [hop("s", "r1", q), hop("r1", "r2", q), hop("r2", "g", q)],
                    [["s", "r1", "r2", "g"]], **mesh)


def as_fraction(text: str) -> Fraction:
    return Fraction(text)


# ---------------------------------------------------------------------------------------------
# 3-hop series route, drop 1/2 per hop, ρ(A) = 5/4
# ---------------------------------------------------------------------------------------------

def test_series_raw_forwarding_unstable_estimate_relaying_stable():
    rec = analyze(series("1/2"))
    mesh = rec["mesh"]
    # raw: arrival (1/2)^3 = 1/8; all lost 7/8; 7/8·25/16 = 175/128 > 1
    assert as_fraction(mesh["arrival_expression"]["s"]) == F(1, 8)
    assert as_fraction(mesh["all_lost"]["expression"]) == F(7, 8)
    assert mesh["verdict"] == "mean-unstable" == rec["operating_point"]["verdict"]
    assert as_fraction(mesh["facts"]["binding"]["value_expression"]) == F(175, 128)
    # relaying: p_cut = max hop drop = 1/2; 1/2·25/16 = 25/32 < 1
    assert mesh["relaying"]["p_cut"] == pytest.approx(0.5)
    assert mesh["relaying"]["verdict"] == "mean-stable"
    assert as_fraction(mesh["relaying"]["sensors"][0]["value_expression"]) == F(25, 32)
    # smart sensor: 1/8 < 1 − 16/25 = 9/25
    assert mesh["smart_sensor"]["verdict"] == "mean-unstable"
    assert as_fraction(mesh["smart_sensor"]["expression"]) == F(9, 25)
    assert "relay estimates, not measurements" in mesh["recommendation"]
    assert rec["review"]["decision"] == "fail"
    assert kfcrit.analysis.verdict.exit_code(rec) == 5


def test_series_route_row_lists_hops_and_their_success():
    mesh = analyze(series("1/2"))["mesh"]
    (route,) = mesh["routes"]
    assert route["hops"] == ["s->r1", "r1->r2", "r2->g"]
    assert route["hop_success"] == [0.5, 0.5, 0.5]
    assert as_fraction(route["arrival_expression"]) == F(1, 8)


# ---------------------------------------------------------------------------------------------
# slot budgets: 3 hops at q = 0.8 within D slots (negative binomial)
# ---------------------------------------------------------------------------------------------

def negative_binomial(q: Fraction, hops: int, slots: int) -> Fraction:
    return sum((comb(t - 1, hops - 1) * q ** hops * (1 - q) ** (t - hops)
                for t in range(hops, slots + 1)), Fraction(0))


@pytest.mark.parametrize("slots, rounded", [(3, 0.512), (4, 0.819), (5, 0.942), (6, 0.983)])
def test_slot_budget_arrival_is_negative_binomial(slots, rounded):
    mesh = analyze(series("0.8", slots_per_period=slots))["mesh"]
    expected = negative_binomial(F(4, 5), 3, slots)
    assert as_fraction(mesh["arrival_expression"]["s"]) == expected
    assert mesh["arrival_probability"]["s"] == pytest.approx(rounded, abs=5e-4)
    assert mesh["slots_per_period"] == slots


def test_retries_cap_attempts_within_the_slot_budget():
    # one retry (2 attempts) per hop, D = 6: P = Σ over a_h ∈ {1, 2} with Σ a_h ≤ 6, i.e.
    # (q + q(1−q))^3 = (1 − (1−q)^2)^3 since Σ a_h ≤ 6 always holds
    mesh = analyze(series("0.8", slots_per_period=6, retries=1))["mesh"]
    assert as_fraction(mesh["arrival_expression"]["s"]) == (1 - F(1, 5) ** 2) ** 3


# ---------------------------------------------------------------------------------------------
# two sensors behind one aggregating relay, against two independent links
# ---------------------------------------------------------------------------------------------

def one_relay(mode="aggregate", a="3/2"):
    return mesh_doc(a, [sensor("s1"), sensor("s2"), relay("r"), GW],
                    [hop("s1", "r", "9/10"), hop("s2", "r", "9/10"), hop("r", "g", "1/2")],
                    [["s1", "r", "g"], ["s2", "r", "g"]], relay_mode=mode)


def test_aggregating_relay_correlates_losses():
    rec = analyze(one_relay())
    mesh = rec["mesh"]
    both = (1 - F(1, 2)) + F(1, 2) * (1 - F(9, 10)) ** 2           # 101/200
    marginal = F(9, 10) * F(1, 2)                                    # 9/20 each
    assert as_fraction(mesh["all_lost"]["expression"]) == both
    assert as_fraction(mesh["all_lost"]["product_expression"]) == (1 - marginal) ** 2
    assert mesh["all_lost"]["ratio"] == pytest.approx(float(both / (1 - marginal) ** 2))
    # scalar plant: stable iff P(both lost)·a² < 1; 101/200 · 9/4 = 909/800 > 1
    assert both * F(9, 4) > 1
    assert mesh["verdict"] == "mean-unstable" == rec["operating_point"]["verdict"]


def test_same_marginals_over_independent_links_are_stable():
    # the product law: (11/20)^2 · 9/4 = 1089/1600 < 1
    doc = {"name": "independent", "A": "3/2", "Q": 1, "sensors": [
        {"name": n, "C": 1, "R": 1, "channel": {"model": "bernoulli",
                                                "arrival_probability": "9/20"}}
        for n in ("s1", "s2")]}
    assert (1 - F(9, 20)) ** 2 * F(9, 4) < 1
    assert analyze(doc)["operating_point"]["verdict"] == "mean-stable"


def test_forwarding_relay_makes_the_losses_independent():
    mesh = analyze(one_relay("forward"))["mesh"]
    # each packet gets its own attempts on r->g: P(both lost) = (1 − 9/20)^2
    assert as_fraction(mesh["all_lost"]["expression"]) == (1 - F(9, 20)) ** 2
    assert mesh["all_lost"]["ratio"] == pytest.approx(1.0)
    assert mesh["verdict"] == "mean-stable"


def test_relay_failure_cuts_off_both_sensors():
    mesh = analyze(one_relay())["mesh"]
    dead = {(f["kind"], f["element"]): f for f in mesh["failures"]}
    assert dead[("relay", "r")]["lost_sensors"] == ["s1", "s2"]
    assert dead[("relay", "r")]["verdict"] == "mean-unstable"
    # one sensor's hop dead: the other arrives w.p. 9/20; (11/20)·9/4 = 99/80 > 1
    assert dead[("hop", "s1->r")]["lost_sensors"] == ["s1"]
    assert dead[("hop", "s1->r")]["verdict"] == "mean-unstable"
    assert {(f["kind"], f["element"]) for f in mesh["failures"]} == {
        ("relay", "r"), ("hop", "s1->r"), ("hop", "s2->r"), ("hop", "r->g")}


# ---------------------------------------------------------------------------------------------
# path diversity: two disjoint routes
# ---------------------------------------------------------------------------------------------

def diverse():
    return mesh_doc("5/4", [sensor("s"), relay("r1"), relay("r2"), GW],
                    [hop("s", "r1", "1/2"), hop("r1", "g", "1/2"), hop("s", "r2", "1/2"),
                     hop("r2", "g", "1/2")], [["s", "r1", "g"], ["s", "r2", "g"]])


def test_two_disjoint_routes():
    rec = analyze(diverse())
    mesh = rec["mesh"]
    # each route 1/4; arrival 1 − (3/4)^2 = 7/16; all lost 9/16; 9/16·25/16 = 225/256 < 1
    assert as_fraction(mesh["arrival_expression"]["s"]) == F(7, 16)
    assert [r["arrival_probability"] for r in mesh["routes"]] == [0.25, 0.25]
    assert F(9, 16) * F(25, 16) < 1
    assert mesh["verdict"] == "mean-stable" == rec["operating_point"]["verdict"]
    assert rec["review"]["decision"] == "pass"
    # with r1 dead only the route through r2 is left: 3/4 · 25/16 = 75/64 > 1
    dead = {f["element"]: f for f in mesh["failures"]}
    assert dead["r1"]["lost_sensors"] == [] and dead["r1"]["verdict"] == "mean-unstable"
    # relaying: the best cut crosses two hops of drop 1/2 each: 1/4
    assert mesh["relaying"]["p_cut"] == pytest.approx(0.25)


def test_computed_routes_take_the_most_reliable_path():
    doc = mesh_doc("5/4", [sensor("s"), relay("r1"), relay("r2"), GW],
                   [hop("s", "r1", "1/2"), hop("r1", "g", "1/2"), hop("s", "r2", "9/10"),
                    hop("r2", "g", "9/10")])
    mesh = analyze(doc)["mesh"]
    assert [r["nodes"] for r in mesh["routes"]] == [["s", "r2", "g"]]
    assert mesh["routes"][0]["origin"] == "most-reliable"
    assert "Dijkstra" in mesh["routing"]
    assert as_fraction(mesh["arrival_expression"]["s"]) == F(81, 100)


# ---------------------------------------------------------------------------------------------
# Monte Carlo over the hop outcomes against the verdict
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("q, verdict", [("1/2", "mean-unstable"), ("9/10", "mean-stable")])
def test_monte_carlo_agrees_with_the_verdict(q, verdict):
    rec = analyze(series(q), simulate=True, quick=False, seed=3)
    sim = rec["mesh"]["simulation"]
    assert rec["mesh"]["verdict"] == verdict
    loss = 1 - F(q) ** 3
    # the tail exponent of tr P: log(1/P(all lost)) / log(a²), independent of the library
    import math
    alpha = math.log(1 / float(loss)) / math.log(25 / 16)
    assert sim["tail_exponent_theory"] == pytest.approx(alpha, rel=1e-9)
    lo, hi = sim["tail_exponent_band"]
    assert (lo < 1 if verdict == "mean-unstable" else lo > 1)
    assert sim["consistent"] is True
    assert sim["empirical_all_lost"] == pytest.approx(float(loss), abs=0.01)
    check = next(c for c in rec["verification"] if c["check"].startswith("mesh Monte Carlo"))
    assert check["passed"] is True
    if verdict == "mean-stable":
        assert sim["mean_trace"] is not None and rec["simulation"]["network"]["mean_exists"]


# ---------------------------------------------------------------------------------------------
# bad meshes name the field
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("change, field", [
    (lambda d: d["mesh"].update(routes=[["s", "r1", "r9", "g"]]), "mesh.routes[0]"),
    (lambda d: d["mesh"].update(routes=[["s", "r1", "r2", "r1", "g"]]), "mesh.routes[0]"),
    (lambda d: d["mesh"]["nodes"].insert(1, sensor("lonely")), "mesh.nodes[1]"),
    (lambda d: d["mesh"].update(slots_per_period=2), "mesh.slots_per_period"),
    (lambda d: d["mesh"]["hops"][0].update(to="nowhere"), "mesh.hops[0].to"),
    (lambda d: d["mesh"]["hops"][0].update(attempt_success="3/2"), "mesh.hops[0].attempt_success"),
    (lambda d: d["mesh"].update(relay_mode="flood"), "mesh.relay_mode"),
    (lambda d: d["mesh"]["nodes"][0].pop("C"), "mesh.nodes[0].C"),
    (lambda d: d.update(C=1), "C"),
])
def test_bad_mesh_names_the_field(change, field):
    doc = series("1/2")
    change(doc)
    with pytest.raises(InputError) as err:
        spec_from_mapping(doc, base_dir=Path("."))
    assert err.value.field == field
