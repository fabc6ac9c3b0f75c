"""Report sections for sensor networks, bursty links and the accuracy design.

Expected values are hand computations from the example files (closed forms of MATH §9–§11),
never values copied from the analysis: the figures and tables must show what the record holds,
and the record's numbers are checked against the closed forms where one exists.
"""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from kfcrit.analysis.record import AnalysisOptions, analyze_system
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.analysis.spec import load_spec, spec_from_mapping
from kfcrit.io.typed import ABSENT
from kfcrit.views.figures import network as netplots
from kfcrit.views.figures import record as figures
from kfcrit.views.report import render as report
from kfcrit.views.report.viewmodel import IID_CAVEAT, view_model
from tests.views.test_report import REPORTS, edited, visible_text

_CACHE: dict[str, AnalysisRecord] = {}


def record(stem: str) -> AnalysisRecord:
    """A quick analysis of an example system (made once; typed records are frozen)."""
    if stem not in _CACHE:
        spec = load_spec(REPORTS / f"{stem}.yaml")
        _CACHE[stem] = analyze_system(spec, AnalysisOptions(quick=True, seed=0))
    return _CACHE[stem]


def record_of(doc: dict, key: str) -> AnalysisRecord:
    if key not in _CACHE:
        _CACHE[key] = analyze_system(spec_from_mapping(doc), AnalysisOptions(quick=True, seed=0))
    return _CACHE[key]


def html_of(rec: AnalysisRecord) -> str:
    return report.render_html(rec, figures.build_figures(rec))


# ----------------------------------------------------------------------------- network

# reports/network-redundant-gauges.yaml: a = 3, p = (0.6, 0.5, 3/4) for radar, float, pressure.
# One constraint 9·(1 − p_r)(1 − p_f)(1 − p_p) < 1, so with the others at their values:
#   radar    : 9·0.5·0.25·(1 − p) < 1  ⇔  p > 1 − 1/1.125 = 1/9
#   float    : 9·0.4·0.25·(1 − p) = 0.9(1 − p) < 1 for every p  ⇒  0
#   pressure : 9·0.4·0.5·(1 − p) < 1  ⇔  p > 1 − 1/1.8 = 4/9
GAUGES = {"radar": (0.6, 1 / 9), "float": (0.5, 0.0), "pressure": (0.75, 4 / 9)}


def test_network_table_shows_each_node_with_its_critical_value():
    rec = record("network-redundant-gauges")
    model = view_model(rec, figures.build_figures(rec))
    nodes = {n["name"]: n for n in model["network"]["nodes"]}
    assert set(nodes) == set(GAUGES)
    for name, (p, crit) in GAUGES.items():
        assert float(nodes[name]["critical"]) == pytest.approx(crit, abs=1e-6), name
        assert float(nodes[name]["margin"].replace("−", "-")) == pytest.approx(p - crit, abs=1e-4)
    # losing the float gauge: 9·0.4·0.25 = 0.9 < 1 survives; the other two do not
    assert nodes["float"]["n1_verdict"] == "mean-stable"
    assert nodes["radar"]["n1_verdict"] == nodes["pressure"]["n1_verdict"] == "mean-unstable"
    html = html_of(rec)
    assert 'id="network-nodes"' in html and 'id="fig-network-region"' in html
    text = visible_text(html)
    assert "a network of 3 sensors" in text and "(bottleneck)" in text


def test_weakest_pair_and_the_drawn_constraint_follow_the_closed_form():
    rec = record("network-redundant-gauges")
    names = [s.name for s in netplots.sensors_of(rec)]
    pair = netplots.weakest_pair(rec)
    # bottleneck pressure (its loss breaks stability, least certain margin 0.75 − 4/9), then
    # radar (margin 0.6 − 1/9 ≈ 0.489 < float's 0.5)
    assert [names[i] for i in pair] == ["pressure", "radar"]
    grid = np.array([0.0, 4 / 9, 0.75, 1.0])
    (_, values), = netplots.constraint_values(rec, pair, grid)
    px, py = np.meshgrid(grid, grid)
    np.testing.assert_allclose(values, 9 * (1 - px) * (1 - 0.5) * (1 - py))
    # on the line through the operating point (radar at 0.6) the boundary is pressure = 4/9
    assert values[list(grid).index(0.0), 1] == pytest.approx(9 * (5 / 9) * 0.5)   # radar 0
    fig = netplots.draw_network_region(rec)
    ax = fig.axes[0]
    op = [ln for ln in ax.get_lines() if ln.get_label().startswith("operating point")]
    assert op and tuple(op[0].get_xydata()[0]) == pytest.approx((0.75, 0.6))


def test_network_map_draws_positions_and_the_sink_when_given():
    rec = record("network-planar-tracker")
    pos = netplots.positions_of(rec)
    assert pos == {"north": (0.0, 118.0), "east": (124.0, 0.0), "corner": (90.0, 92.0)}
    html = html_of(rec)
    assert 'id="fig-network-map"' in html
    # the planar tracker's file puts the sink at the origin: it is drawn there, with one
    # segment from each node to it
    assert rec.system.sink_position_m == [0.0, 0.0]
    model = view_model(rec, figures.build_figures(rec))
    assert "no sink position" not in model["network"]["map"]["caption"]
    fig = netplots.draw_network_map(rec)
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert "sink" in texts and any(t.startswith("corner") for t in texts)
    sink_marks = [c for c in ax.collections
                  if np.allclose(np.asarray(c.get_offsets(), dtype=float), [[0.0, 0.0]])]
    assert len(sink_marks) == 1
    to_sink = [ln for ln in ax.lines if list(ln.get_xdata())[-1:] == [0.0]
               and list(ln.get_ydata())[-1:] == [0.0]]
    assert len(to_sink) == len(pos)
    # without a sink position the map says so and draws no sink
    rec = dataclasses.replace(rec, system=dataclasses.replace(rec.system,
                                                              sink_position_m=ABSENT))
    assert "no sink position" in view_model(rec, figures.build_figures(rec))[
        "network"]["map"]["caption"]
    fig = netplots.draw_network_map(rec)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "sink" not in texts
    # a margin that is an interval is printed as one ([+lo, +hi] dB; its ends move with the
    # PER convention, per_over, so only the form is checked here)
    assert any(re.search(r"\[\+\d+\.\d+", t) for t in texts)


def test_single_link_record_has_no_network_section():
    rec = record("sinopoli-scalar")
    assert figures.build_figures(rec)["network_region"] is None
    assert 'id="network"' not in html_of(rec)


# ----------------------------------------------------------------------------- bursty links

def test_bursty_report_draws_the_critical_curve_and_carries_the_caveat():
    rec = record("ge-bursty-scalar")
    curve = rec.link_budget.critical_curve
    # scalar a = −5/4: r_nec = 1 − 1/a² = 9/25 for every f (MATH §7)
    assert curve.necessary_recovery == pytest.approx([9 / 25] * len(curve.failure_rates))
    fig = figures.figure(rec, "critical_curve")
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    nec = lines[r"necessary recovery rate $r_{\mathrm{nec}}(f)$"]
    np.testing.assert_array_equal(nec.get_xdata(), curve.failure_rates)
    np.testing.assert_array_equal(nec.get_ydata(), curve.necessary_recovery)
    star = next(ln for k, ln in lines.items() if k.startswith("operating point"))
    assert tuple(star.get_xydata()[0]) == pytest.approx((0.05, 0.1))
    html = html_of(rec)
    assert 'id="fig-critical-curve"' in html and 'id="iid-caveat"' in html
    text = visible_text(html)
    assert text.count("Caveat:") >= 1 and "burst verdict" in text


def test_iid_report_has_no_bursty_caveat():
    rec = record("sinopoli-scalar")
    html = html_of(rec)
    assert 'id="iid-caveat"' not in html and IID_CAVEAT not in html
    assert 'id="fig-critical-curve"' not in html


# ----------------------------------------------------------------------------- accuracy design

SCALAR_DESIGN = {"name": "scalar accuracy requirement", "A": [[-1.25]], "C": [[1]], "Q": [[1]],
                 "R": [[2.5]], "channel": {"model": "bernoulli", "arrival_probability": 0.8},
                 "requirements": {"max_mean_error_trace": 10}}


def test_accuracy_figure_shades_the_required_interval():
    rec = record_of(SCALAR_DESIGN, "scalar-design")
    # tr S̄(p) = q / (1 − (1 − p) a²) = 10  ⇔  (1 − p)·25/16 = 0.9  ⇔  p_S = 0.424 (by hand)
    p_s, p_v = rec.design.required_arrival_probability.interval
    assert p_s == pytest.approx(0.424, abs=1e-6) and p_s < p_v < 0.8
    fig = figures.figure(rec, "accuracy")
    ax = fig.axes[0]
    spans = [p for p in ax.patches if "p_S, p_V" in p.get_label()]
    assert len(spans) == 1
    box = spans[0].get_bbox()   # an axvspan is a rectangle in data x, axes y
    assert box.x0 == pytest.approx(p_s) and box.x1 == pytest.approx(p_v)
    level = [ln for ln in ax.get_lines() if ln.get_label().startswith("requirement L")]
    assert level and level[0].get_ydata()[0] == 10
    html = html_of(rec)
    text = visible_text(html)
    assert 'id="design"' in html and 'id="fig-accuracy"' in html
    assert "lim E[tr P] ≤ 10: met" in text and "no requirement in the system file" not in text


def test_link_curves_from_the_record_are_drawn_as_given():
    from kfcrit.link import curves

    rec = record("link-oqpsk-sensor")
    link = load_spec(REPORTS / "link-oqpsk-sensor.yaml").channel
    arrival = curves.arrival_vs_distance(link, np.geomspace(30, 300, 25))
    per = curves.per_vs_sinr(link.radio, (20, 127), np.linspace(-4, 4, 17))
    outage = curves.outage_vs_distance(link, {"p_c": 0.36}, np.array([50.0, 105.0, 200.0]))
    rec = edited(rec, lambda d: d["link_budget"]["curves"].update(
        arrival_vs_distance=arrival.to_dict(), per_vs_sinr=per.to_dict(),
        outage_vs_distance=outage.to_dict()))
    fig = figures.figure(rec, "arrival_distance")
    median = next(ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("median"))
    np.testing.assert_array_equal(median.get_ydata(), arrival.arrival)
    assert any(ln.get_label() == "critical arrival probability $p_c$ = 0.36"
               for ln in fig.axes[0].get_lines())
    fig = figures.figure(rec, "per_sinr")
    psdu127 = next(ln for ln in fig.axes[0].get_lines() if ln.get_label() == "PSDU 127 bytes")
    np.testing.assert_allclose(psdu127.get_ydata(), link.radio.per(np.linspace(-4, 4, 17), 127))
    fig = figures.figure(rec, "outage_distance")
    out = next(ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("P(arrival prob."))
    assert out.get_ydata()[1] == link.outage_probability(0.36)
    html = html_of(rec)
    assert all(f'id="fig-link-{i}"' in html for i in (1, 2, 3))
    # malformed curves: no figure, no exception
    rec = edited(rec, lambda d: d["link_budget"]["curves"]["per_vs_sinr"].update(per=[[0.1]]))
    assert figures.build_figures(rec)["per_sinr"] is None


def test_tail_exponent_is_shown_with_its_label():
    rec = record("requirements-tail")
    ex = rec.tail.exponent
    # β = log(1 − p)/(−2 log|a|) = log(5)/log(25/16) at p = 0.8, a = −5/4 (by hand)
    assert ex.value == pytest.approx(math.log(5) / math.log(25 / 16))
    text = visible_text(html_of(rec))
    assert "Power-law tail exponent β = 3.60628" in text and "claim" in text


# ----------------------------------------------------------------------------- divergent mean

def test_divergent_mean_draws_the_sample_mean_without_a_band():
    """ge-bursty-scalar: a = −5/4 and recovery rate r = 1/10 give (1 − r)·a² = 45/32 ≥ 1, so
    E[P_t] is unbounded (MATH 7/10): the record has no mean and the figure shows the sample
    mean."""
    rec = record("ge-bursty-scalar")
    op = rec.simulation.operating_point
    assert op.mean_trace.diverges and op.mean_trace.mean is None
    sample = op.sample_mean_trace.mean
    fig = figures.draw_operating(rec)
    assert fig is not None
    ax = fig.axes[0]
    lines = [ln for ln in ax.lines if len(ln.get_xdata()) == len(op.times)]
    assert len(lines) == 1
    assert list(lines[0].get_ydata()) == pytest.approx(sample)
    assert "diverges" in lines[0].get_label() and "sample mean" in lines[0].get_label()
    assert not ax.collections  # no confidence band: the sample mean estimates nothing
    html = html_of(rec)
    chunk = html.split('id="fig-operating"')[1].split("</figure>")[0]
    assert "<svg" in chunk and "diverges" in visible_text(chunk)
    assert "sample mean of tr P_t at the horizon" in visible_text(html)


# ----------------------------------------------------------------------------- exact forms

IRRATIONAL_PLANT = {"name": "three states, cubic eigenvalues",
                    "A": [["1.1", "0.3", "0"], ["0.2", "0.9", "0.4"], ["0", "0.1", "1.05"]],
                    "C": [[1, 0, 0]], "Q": 1, "R": 1,
                    "channel": {"model": "bernoulli", "arrival_probability": "0.8"}}


def test_short_closed_forms_only():
    from kfcrit.views.report.parts import closed_form_text, numerical_text, short_closed_form
    assert short_closed_form("9/25") == "9/25"
    assert short_closed_form("1 - 2**(-3)") == "1 - 2**(-3)"
    assert short_closed_form("sqrt(3)/2") == "sqrt(3)/2"
    for not_a_form in ("0.96213", "1.4198034786194746e-5", "CRootOf(x**3 - 2*x - 1, 2)",
                       "0.4263521177043613", "1/(1 - 0.13996696020413057)", "",
                       "sqrt(" + "1 + " * 20 + "2)"):
        assert short_closed_form(not_a_form) is None, not_a_form
        assert closed_form_text(not_a_form) is None
    assert numerical_text(0.13996696020413057) == "0.139967 (numerical)"


def test_irrational_eigenvalues_are_shown_as_numbers_not_root_objects():
    """A has the characteristic polynomial of a cubic with three real irrational roots; the
    report shows them at 6 digits (numpy's eigvals, a second method) and p_c = 1 − 1/|λ₁|²
    as a number marked numerical, never a CRootOf or a 17-digit float."""
    rec = record_of(IRRATIONAL_PLANT, "irrational-plant")
    A = np.array([[1.1, 0.3, 0], [0.2, 0.9, 0.4], [0, 0.1, 1.05]])
    lam = sorted(abs(np.linalg.eigvals(A)), reverse=True)
    pc = 1 - 1 / lam[0] ** 2
    assert rec.critical_value.value == pytest.approx(pc, rel=1e-12)
    text = visible_text(html_of(rec))
    assert "RootOf(" not in text and "x^3" not in text
    assert f"p c ≈ {pc:.6g} · numerical" in text
    for mod in lam:
        # six significant digits with trailing zeros kept (1.06900, not a shorter 1.069)
        assert f"{mod:#.6g} (numerical)".replace("-", "−") in text
    table = text.split("exact form of |λ i |")[1].split("equi-block")[0]
    assert not re.search(r"\d\.\d{9,}", table), table
    assert "· exact" not in text.split("critical value p c")[1].split("margin")[0]


# ----------------------------------------------------------------------------- design wording

def _bound(quantity, unit, sense, suf, nec, suf_status="value", nec_status="value"):
    from kfcrit.records.link import LinkDesignBound, LinkDesignDistance

    return LinkDesignDistance(quantity=quantity, unit=unit, sense=sense, interval=[suf, nec],
                              sufficient=LinkDesignBound(value=suf, status=suf_status),
                              necessary=LinkDesignBound(value=nec, status=nec_status),
                              method="")


def test_radio_bounds_fail_on_the_side_their_sense_says():
    from kfcrit.views.report.design import bound_text
    # a transmit power must be at least its bound: below the necessary end it fails
    power = bound_text(_bound("transmit power", "dBm", "at least", -2.05, -2.28))
    assert "fails below −2.28 dBm" in power and "guaranteed at −2.05 dBm or more" in power
    assert "beyond" not in power and "above" not in power
    # a distance must be at most its bound: above the necessary end it fails
    dist = bound_text(_bound("distance", "m", "at most", 76.0, 77.3))
    assert "fails above 77.3 m" in dist and "or less" in dist
    # the PHY's largest payload meets it: nothing fails
    payload = bound_text(_bound("payload", "bytes", "at most", 116, 116, "phy-limit",
                                "phy-limit"))
    assert payload.startswith("every payload the PHY allows meets it") and "fail" not in payload
    assert bound_text(_bound("MAC retries", "retries", "at least", 0, 0)).startswith(
        "needed: 0")
    assert bound_text(_bound("MAC retries", "retries", "at least", 2, 2)).startswith(
        "needed: 2")
    assert bound_text(_bound("distance", "m", "at most", None, None, "unbounded",
                             "unbounded")) == "any distance meets it"
    assert bound_text(_bound("transmit power", "dBm", "at least", None, None, "unreachable",
                             "unreachable")) == "no transmit power meets it"


def test_network_margin_rows_are_labelled_as_the_uniform_margin():
    """A network's operating_point.margin is the uniform margin δ (every link degraded by δ),
    not p − p_c: every place that shows it says so."""
    from kfcrit.records.network import NetworkSection
    from kfcrit.views.report.summary import markdown_summary

    rec = record("network-redundant-gauges")
    assert isinstance(rec.network, NetworkSection)
    rec = dataclasses.replace(rec, operating_point=dataclasses.replace(rec.operating_point,
                                                                       bracket=[0.05, 0.15]))
    text = visible_text(html_of(rec))
    assert "p − p c" not in text.split("1. ")[0] and "bracket for" not in text
    assert "uniform margin δ in [0.05, 0.15]" in text
    assert "p − p_c" not in markdown_summary(rec)
    assert "uniform margin δ" in markdown_summary(rec)


# ----------------------------------------------------------------------------- notation

INTERNAL = re.compile(r"`|kfcrit\.[a-z]|LinAlgError|_bar\b|rho\(|>=|<=|\) a\^2")


def test_record_prose_reads_without_program_names():
    from kfcrit.views.formatting import pretty_text
    assert pretty_text("(1 - r) rho(A)^2 >= 1") == "(1 − r) ρ(A)² ≥ 1"
    assert pretty_text("(1 - r) a^2 < 1") == "(1 − r) a² < 1"
    assert pretty_text("tr S_bar > L, tr V_bar <= L") == "tr S̄ > L, tr V̄ ≤ L"
    assert pretty_text("proof in kfcrit.theory.links.network (claim)") == "kfcrit's own proof (claim)"
    assert pretty_text("failed (LinAlgError: Singular matrix)") == \
        "failed (a linear-algebra failure: Singular matrix)"
    assert pretty_text("the verdicts are in `network`") == "the verdicts are in the network section"


@pytest.mark.parametrize("stem", ["ge-bursty-scalar", "network-planar-tracker",
                                  "network-redundant-gauges"])
def test_reports_show_no_internal_names(stem):
    # the user's own words (the description) are printed as written
    rec = dataclasses.replace(record(stem), description=None)
    text = visible_text(report.render_html(rec, {}))
    assert not INTERNAL.search(text), INTERNAL.search(text)


def test_network_simulation_summary_is_shown() -> None:
    """A network's per-sensor-arrival simulation is a row of the simulation table (not
    "not computed"): its paths and the simulated mean with its band, read from the record."""
    from kfcrit.records.simulation import (
        NetworkMeanTrace,
        NetworkSimulation,
        Simulation,
    )
    from kfcrit.views.report.sim import simulation_view

    rec = dataclasses.replace(record("network-redundant-gauges"), covariance_bounds=None,
                              simulation=Simulation(seed=3, quick=True, network=NetworkSimulation(
                                  paths=300, steps=200, seed=3, sensors=["a", "b"],
                                  mean_exists=True,
                                  mean_trace=NetworkMeanTrace(mean=8.0, lower=6.0, upper=10.0))))
    rows = {r["label"]: r for r in simulation_view(rec)["rows"]}
    assert "each sensor over its own link" in rows["operating-point runs"]["note"]
    assert rows["simulated E[tr P_t] at the horizon"]["value"] == 8.0


def test_absent_keys_read_as_none_and_are_not_listed():
    """An opt_key field the record lacks reads as None (the JSON form has no such key); the
    fields listed for a generic table are the JSON form's keys, in its order."""
    from kfcrit.records.simulation import OperatingPointSeeds, SimulationSeeds
    from kfcrit.views.report.parts import stated, stated_fields

    seeds = SimulationSeeds(phase_demo=[4, 5])
    assert seeds.operating_point is ABSENT and stated(seeds.operating_point) is None
    assert stated(0) == 0 and stated(None) is None and stated("") == ""
    assert stated_fields(seeds) == [("phase_demo", [4, 5])]
    full = SimulationSeeds(operating_point=OperatingPointSeeds(seed=1, paths="a", ergodic="b"),
                           phase_demo=[])
    assert [k for k, _ in stated_fields(full)] == list(
        {"operating_point": 0, "phase_demo": 0})      # declaration order, empty list kept
    rec = record("sinopoli-scalar")
    assert [k for k, _ in stated_fields(rec)] == list(rec.to_dict())   # timings is internal
