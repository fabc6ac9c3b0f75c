"""Figure legends speak words in the tables' number style: no caret exponents, no code names
(``max_outage``, ``p_link``), the typographic minus U+2212, dB with 2 decimals and metres with
1 decimal as the report's tables print them (:func:`kfcrit.views.formatting.unit`)."""
from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.figure import Figure

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.link.curves import ArrivalCurve, OutageCurve, PerCurve
from kfcrit.views import formatting as jinja_filters
from kfcrit.views.figures.design import draw_accuracy, radio_title
from kfcrit.views.figures.link import (
    arrival_distance_figure,
    outage_distance_figure,
    per_sinr_figure,
)
from kfcrit.views.figures.style import arrival_formula, legend_quantity, percent
from tests.views.test_report_sections import SCALAR_DESIGN, record, record_of

CODE_NAME = re.compile(r"\b[a-z]+_[a-z_]+\b")
"""An identifier with an underscore (``max_outage``, ``p_link``) outside mathtext."""


def legend_texts(fig: Figure) -> list[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return [t.get_text() for leg in legends for t in leg.get_texts()]


def plain_words(text: str) -> str:
    """The text without its mathtext parts (``$p_c$`` renders as a subscript, not a name)."""
    return re.sub(r"\$[^$]*\$", "", text)


def assert_clean(texts: list[str]) -> None:
    assert texts
    for t in texts:
        assert "^" not in plain_words(t), t
        assert not CODE_NAME.search(plain_words(t)), t
        assert not re.search(r"(?<![\w])-\d", t), t   # hyphen-minus before a digit


def arrival_curve(retries: int) -> ArrivalCurve:
    d = np.array([20.0, 40.0, 55.0, 80.0, 200.0])
    return ArrivalCurve(d, np.array([1.0, 0.99, 0.9, 0.3, 0.0]),
                        np.array([0.99, 0.95, 0.8, 0.4, 0.05]), 55.0, retries, 41)


@pytest.mark.parametrize(("value", "unit", "text"), [
    (0.129, "dB", "0.13 dB"), (-1.4812, "dB", "−1.48 dB"), (80.17, "m", "80.2 m"),
    (55.34, "m", "55.3 m"), (-0.001, "dB", "0.00 dB")])
def test_quantities_print_as_in_the_tables(value: float, unit: str, text: str) -> None:
    assert legend_quantity(value, unit) == text
    if value != -0.001:   # the table filter keeps the sign of a rounded-away negative zero
        assert jinja_filters.unit(value, unit) == text


def test_arrival_formula_and_percent_by_hand() -> None:
    assert arrival_formula(0) == "p = 1 − PER"
    assert arrival_formula(3) == "p = 1 − PER⁴"       # k = 3 retries: k + 1 = 4 attempts
    assert arrival_formula(10) == "p = 1 − PER¹¹"
    assert percent(0.1) == "10 %" and percent(0.025) == "2.5 %"


@pytest.mark.parametrize("retries", [0, 3])
def test_arrival_legend_words(retries: int) -> None:
    fig = arrival_distance_figure(arrival_curve(retries), critical_value=0.36,
                                  requirement=(0.424, 0.53), design_distance_m=55.34)
    texts = legend_texts(fig)
    assert_clean(texts)
    median = next(t for t in texts if t.startswith("median link"))
    assert ("p = 1 − PER⁴" in median and "k = 3 retries" in median) if retries \
        else ("p = 1 − PER (" in median and "retries" not in median)
    assert "configured distance d = 55.0 m" in texts
    assert "largest distance meeting the margin policy = 55.3 m" in texts


def test_close_configured_and_largest_distance_are_both_visible() -> None:
    """55 m and 55.34 m: a wide light solid line under a thin dark dashed one."""
    fig = arrival_distance_figure(arrival_curve(3), critical_value=0.36,
                                  design_distance_m=55.34)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    conf = lines["configured distance d = 55.0 m"]
    far = lines["largest distance meeting the margin policy = 55.3 m"]
    assert conf.get_linewidth() >= 2 * far.get_linewidth()
    assert conf.get_linestyle() == "-" and far.get_linestyle() != "-"
    assert far.get_zorder() > conf.get_zorder() and conf.get_color() != far.get_color()


def test_per_legend_uses_the_typographic_minus_and_two_decimals() -> None:
    curve = PerCurve("ieee802154-oqpsk-2450", np.linspace(-4, 4, 5), (20,),
                     np.array([[0.9, 0.5, 0.1, 0.01, 0.001]]))
    fig = per_sinr_figure(curve, marks=[("configured SINR", 0.129),
                                        ("required SINR", -1.4812)])
    texts = legend_texts(fig)
    assert_clean(texts)
    assert "configured SINR = 0.13 dB" in texts and "required SINR = −1.48 dB" in texts
    assert fig.axes[0].get_title() == ""   # no code name as a title
    titled = per_sinr_figure(curve, title="IEEE 802.15.4 O-QPSK 2450 MHz radio")
    assert titled.axes[0].get_title() == "IEEE 802.15.4 O-QPSK 2450 MHz radio"


def test_radio_title_from_the_record() -> None:
    radio = record("link-oqpsk-sensor").link_budget.radio
    frame = replace(radio.frame, standard="IEEE 802.15.4 O-QPSK 2450 MHz")
    assert radio_title(replace(radio, model="cc2420", frame=frame)) \
        == "IEEE 802.15.4 O-QPSK 2450 MHz radio"
    assert radio_title(replace(radio, model="cc2420", frame=replace(frame, standard=" "))) is None


def test_outage_legend_words() -> None:
    d = np.array([50.0, 100.0, 200.0])
    curve = OutageCurve(d, (("p_c", 0.36), ("p_S", 0.424)),
                        np.array([[0.01, 0.3, 0.9], [0.02, 0.4, 0.95]]), 4.0, 0.1, 105.0)
    texts = legend_texts(outage_distance_figure(curve))
    assert_clean(texts)
    assert "allowed outage 10 %" in texts
    assert "P(arrival prob. < 0.36), $p_c$" in texts
    assert "P(arrival prob. < 0.424), $p_S$" in texts
    assert "configured distance d = 105.0 m" in texts


def accuracy_record(operating: float) -> AnalysisRecord:
    """tr S̄(p) = 1 / (1 − (1 − p)·25/16) and tr V̄ = 2·tr S̄ on p ∈ [0.4, 1] (a scalar-like
    shape; only the drawing is under test), requirement L = 10, no floor: a scalar design's
    record with these curves put in."""
    rec = record_of(SCALAR_DESIGN, "scalar-design")
    p = np.linspace(0.4, 1.0, 61)
    lower = 1.0 / (1.0 - (1.0 - p) * 25 / 16)
    pt = replace(rec.phase_transition, p=p.tolist(), trace_lower=lower.tolist(),
                 trace_upper=(2 * lower).tolist(),
                 markers=replace(rec.phase_transition.markers, operating=operating))
    required = replace(rec.design.required_arrival_probability, level=10.0,
                       interval=[0.424, 0.53], floor_trace=None)
    return replace(rec, phase_transition=pt,
                   design=replace(rec.design, required_arrival_probability=required))


def test_operating_point_outside_the_axis_is_an_arrow_at_its_edge() -> None:
    fig = draw_accuracy(accuracy_record(0.3))
    ax = fig.axes[0]
    assert ax.get_xlim()[0] > 0.3
    assert not [ln for ln in ax.get_lines() if ln.get_label().startswith("operating p")
                and len(ln.get_xdata())]
    notes = [t.get_text() for t in ax.texts]
    assert "operating p = 0.3 left of the axis" in notes
    assert any(t.startswith("operating p = 0.3 (off the axis") for t in legend_texts(fig))


def test_operating_point_inside_the_axis_is_a_line() -> None:
    fig = draw_accuracy(accuracy_record(0.8))
    ax = fig.axes[0]
    line = next(ln for ln in ax.get_lines() if ln.get_label() == "operating p = 0.8")
    assert list(line.get_xdata()) == [0.8, 0.8] and not ax.texts
