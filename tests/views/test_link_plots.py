"""Link figures draw exactly the arrays the link layer computes."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from kfcrit.link import curves
from kfcrit.link.linkbudget import LinkBudget
from kfcrit.views.figures.link import (
    arrival_distance_figure,
    outage_distance_figure,
    per_sinr_figure,
)

LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "100", "packet_bytes": "40", "max_outage": "0.1", "max_retries": 1,
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2", "shadowing_sigma_db": "4"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def lines_of(fig: Figure) -> dict[str, np.ndarray]:
    ax = fig.axes[0]
    return {ln.get_label(): np.asarray(ln.get_ydata(), dtype=float) for ln in ax.get_lines()}


def test_arrival_figure_draws_the_curve_and_marks() -> None:
    link = LinkBudget.from_mapping(LINK, "channel")
    c = curves.arrival_vs_distance(link, np.array([20.0, 50.0, 100.0, 400.0]))
    # at the configured distance the curve is the link's own arrival probability (median link)
    assert c.arrival[2] == link.arrival_value
    assert c.mean_arrival[2] == link.mean_arrival(link.sinr_db)
    assert np.all(np.diff(c.arrival) <= 0) and c.arrival[0] > 0.999 > 1e-6 > c.arrival[-1]
    fig = arrival_distance_figure(c, critical_value=0.36, requirement=(0.6, 0.9),
                                  design_distance_m=80.0)
    lines = lines_of(fig)
    median = next(v for k, v in lines.items() if k.startswith("median link"))
    np.testing.assert_array_equal(median, c.arrival)
    assert any(k.startswith("critical arrival probability $p_c$ = 0.36") for k in lines)
    assert any("largest distance meeting the margin policy = 80.0 m" in k for k in lines)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("[0.6, 0.9]" in t for t in labels)


def test_per_and_outage_figures() -> None:
    link = LinkBudget.from_mapping(LINK, "channel")
    pc = curves.per_vs_sinr(link.radio, (20, 127), np.linspace(-4, 4, 9))
    np.testing.assert_allclose(pc.per[1], link.radio.per(np.linspace(-4, 4, 9), 127))
    fig = per_sinr_figure(pc, marks=[("configured SINR", link.sinr_db)])
    assert {"PSDU 20 bytes", "PSDU 127 bytes"} <= set(lines_of(fig))
    oc = curves.outage_vs_distance(link, {"p_c": 0.36}, np.array([50.0, 100.0, 200.0]))
    # the outage at the configured distance is the link's own
    assert oc.outage[0, 1] == link.outage_probability(0.36)
    assert np.all(np.diff(oc.outage[0]) > 0)  # farther links fail more often
    fig = outage_distance_figure(oc)
    assert any(k == "allowed outage 10 %" for k in lines_of(fig))


def test_per_figure_of_a_calibrated_radio_spans_its_transition() -> None:
    """reports/link-cc2420-retries.yaml: the CC2420 is calibrated to 1 % PER at −95 dBm for a
    20-byte PSDU; the thermal floor of 2 MHz at 290 K is −174 + 10·log10(2e6) = −110.99 dBm, so
    PER(20 bytes) = 0.01 at SINR 15.99 dB, far from an uncalibrated O-QPSK's 0 dB."""
    from pathlib import Path

    from kfcrit.analysis.record import AnalysisOptions, analyze_system
    from kfcrit.analysis.spec import load_spec
    from kfcrit.views.figures.design import draw_per_sinr

    path = Path(__file__).resolve().parents[2] / "reports" / "link-cc2420-retries.yaml"
    rec = analyze_system(load_spec(path), AnalysisOptions(quick=True, seed=0))
    fig = draw_per_sinr(rec)
    assert fig is not None
    ax = fig.axes[0]
    configured = rec.link_budget.link.sinr_db
    drawn = [ln for ln in ax.get_lines() if ln.get_label().startswith("PSDU")]
    assert {ln.get_label() for ln in drawn} == {"PSDU 20 bytes", "PSDU 41 bytes",
                                                "PSDU 127 bytes"}
    for ln in drawn:
        x = np.asarray(ln.get_xdata(), dtype=float)
        y = np.asarray(ln.get_ydata(), dtype=float)
        assert y.max() > 0.9 and y.min() < 0.01, ln.get_label()
        assert x.min() < configured < x.max()
        assert x.min() < rec.link_budget.required_sinr_db < x.max()
    short = next(ln for ln in drawn if ln.get_label() == "PSDU 20 bytes")
    sensitivity_sinr = -95.0 - (-174.0 + 10 * np.log10(2e6))
    per_there = np.interp(sensitivity_sinr, short.get_xdata(), short.get_ydata())
    assert abs(np.log10(per_there) - np.log10(0.01)) < 0.05
