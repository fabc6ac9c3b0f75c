"""A sensor network's design review says one thing once: what the record holds is shown, what it
lacks is "not computed" with the same reason everywhere, and the terminal view agrees.

Expected values are hand computations from the example files (MATH §9):

* reports/network-redundant-gauges.yaml: a = 3, q = 1, p = (0.6, 0.5, 0.75). Every packet is
  lost with probability Π(1 − p_i) = 0.4·0.5·0.25 = 1/20, so the covariance bounds' p is
  1 − 1/20 = 0.95 and S̄ = q / (1 − a²/20) = 1 / 0.55 = 20/11.
* reports/network-planar-tracker.yaml: the corner sensor's critical value is only bracketed,
  so its margin is an interval: [p − sufficient end, p − necessary end].
"""
from __future__ import annotations

import dataclasses
import re

import pytest

from kfcrit.records.network import SensorMargin
from kfcrit.views.figures import record as figures
from kfcrit.views.report import render as report
from kfcrit.views.report.theory import covariance_view, static_gain_view
from kfcrit.views.report.viewmodel import view_model
from kfcrit.views.text import netmargin
from kfcrit.views.text import terminal as text
from tests.views.test_report import edited, visible_text
from tests.views.test_report_sections import record

GAUGES_P = (0.6, 0.5, 0.75)
GAUGES_LOST = 0.4 * 0.5 * 0.25            # Π(1 − p_i)
GAUGES_S_BAR = 1.0 / (1.0 - 9.0 * GAUGES_LOST)   # 20/11


@pytest.fixture(scope="module")
def gauges():
    rec = record("network-redundant-gauges")
    html = report.render_html(rec, figures.build_figures(rec))
    return rec, html, visible_text(html)


def _v_bar_row(html: str) -> str:
    row = re.search(r"<tr><th scope=\"row\">V̄ = g.*?</tr>", html, re.S)
    assert row, "the covariance table has no V̄ row"
    return row.group(0)


def test_covariance_p_is_the_at_least_one_arrival_probability(gauges):
    rec, html, words = gauges
    cb = rec["covariance_bounds"]
    assert cb["p"] == pytest.approx(1 - GAUGES_LOST, abs=1e-12)
    assert cb["lower"]["trace"] == pytest.approx(GAUGES_S_BAR, rel=1e-9)
    # the report states that p and what it means, next to the table that uses it
    assert "bound (p = 0.95)" in words
    flat = words.replace("\n", " ")
    assert "p = 0.95 is 1 − Π(1 − pᵢ), the probability that at least one sensor's packet " \
           "arrives" in flat


def test_uncomputed_upper_bound_is_grey_not_a_red_no(gauges):
    rec, html, _ = gauges
    assert rec["covariance_bounds"]["upper"]["computed"] is False
    row = _v_bar_row(html)
    assert "badge-none" in row and "not computed" in row
    assert "badge-no\"" not in row and "badge badge-no\"" not in row


def test_a_bound_that_does_not_exist_stays_a_red_no():
    # a single link below p_up: V̄ does not exist (Sinopoli Thm 3), which is a computed "no"
    def below_p_up(data: dict) -> None:
        cb = data["covariance_bounds"]
        cb["p"] = 0.5
        cb["lower"].update(exists=True, trace=1.0)
        cb["upper"].update(exists=False, method="none: p <= p_up (Thm 3)")
        cb["upper"].pop("computed", None)

    rec = edited(record("sinopoli-scalar"), below_p_up)
    view = covariance_view(rec)
    assert view["upper"]["exists"] is False and view["upper"]["computed"] is True
    assert view["p_meaning"] is None


def test_simulation_numbers_the_record_has_are_shown_not_called_missing(gauges):
    rec, html, words = gauges
    net = rec["simulation"]["network"]
    mean = net["mean_trace"]["mean"]
    # S̄ ⪯ lim E[P_t] (Sinopoli Thm 4 with the all-lost probability): a mean-stable network's
    # simulated mean lies above tr S̄ = 20/11, beyond its sampling band
    assert net["mean_trace"]["lower"] > GAUGES_S_BAR
    flat = words.replace("\n", " ")
    assert "the simulation produced no data" not in flat
    assert "no operating point" not in flat and "has no channel" not in flat
    shown = f"E[tr Pₜ] at t = {net['steps']} is {mean:.6g}"
    assert shown in flat
    # the figure shells that would say "not computed" are replaced by one sentence each
    for fig in ("fig-phase-transition", "fig-traces", "fig-operating", "fig-cdf",
                "fig-almost-sure"):
        assert f'id="{fig}"' not in html, fig
    assert 'id="phase-transition-scope"' in html and 'id="simulation-scope"' in html


def test_block_maxima_are_said_missing_once_and_nowhere_promised(gauges):
    _, _, words = gauges
    flat = words.replace("\n", " ")
    assert "are in the appendix" not in flat
    assert flat.count("block maxima along one long path are computed for single-link systems "
                      "only") == 2    # section 7 and the appendix, the same words


def test_fixed_gain_reason_is_the_network_not_a_missing_channel(gauges):
    rec, _, words = gauges
    assert rec["static_gain"] is None
    why = static_gain_view(rec)["missing"]
    assert "single-link systems only" in why and "channel" not in why
    assert why in words.replace("\n", " ")
    # a single link without a channel keeps its own reason
    no_channel = dataclasses.replace(record("sinopoli-scalar"), operating_point=None,
                                     static_gain=None)
    assert "no channel" in static_gain_view(no_channel)["missing"]


def test_terminal_view_of_the_bounds_agrees_with_the_report(gauges):
    rec, _, words = gauges
    lines = text.summary(rec)
    assert "tr V̄ = ∞" not in lines and "tr V̄ not computed" in lines
    assert "at p = 0.95;" in lines
    assert "the probability that at least one sensor's packet arrives" in lines


@pytest.mark.parametrize("margin, expected", [
    (SensorMargin(value=0.25, interval=[0.25, 0.25]), "+0.25"),
    (SensorMargin(value=None, interval=[0.5388594, 0.7765047]), "[+0.5389, +0.7765]"),
    (SensorMargin(value=-0.125, interval=[None, None]), "−0.125"),
    (SensorMargin(value=None, interval=[None, None]), "—"),
])
def test_margin_text_by_hand(margin, expected):
    row = record("network-planar-tracker").network.sensors[0]
    assert netmargin.margin_text(dataclasses.replace(row, margin=margin)) == expected


def test_cli_and_report_show_the_same_margins():
    rec = record("network-planar-tracker")
    model = view_model(rec, {})
    cli = text.summary(rec)
    rows = {n["name"]: n for n in model["network"]["nodes"]}
    for s in rec["network"]["sensors"]:
        shown = rows[s["name"]]["margin"]
        line = next(ln for ln in cli.splitlines() if ln.strip().startswith(s["name"] + " "))
        assert shown in line, (s["name"], shown, line)
        # margin = p − critical value: with a bracketed critical value both ends follow
        cv = s["critical_value"]
        if cv["value"] is None:
            lo, hi = cv["interval"]
            p = s["arrival_probability"]
            assert shown == f"[{p - hi:+.4f}, {p - lo:+.4f}]".replace("-", "−")
        else:
            assert float(shown.replace("−", "-")) == pytest.approx(
                s["arrival_probability"] - cv["value"], abs=5e-5)
    corner = rows["corner"]["margin"]
    assert corner.startswith("[") and corner != "—"
    assert model["network"]["bottleneck_margin"] == corner
    assert f"(margin {corner})" in cli

