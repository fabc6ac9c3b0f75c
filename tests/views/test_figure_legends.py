"""The sweep, bursty and network-region figures: legends name every drawn element, every grid
point stays visible, coinciding curves stay distinguishable, text prints at ≥ 7 pt."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.records.bursty import RatesPoint
from kfcrit.records.network import SensorMargin
from kfcrit.views.figures.burst import draw_critical_curve
from kfcrit.views.figures.network import draw_network_region
from kfcrit.views.figures.style import HEIGHT_IN, MIN_PRINT_PT, WIDTH_IN, print_scale
from kfcrit.views.figures.sweep import margin_figure
from tests.views.test_report_sections import record


def legend_texts(fig: Figure) -> list[str]:
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


def sweep_rows(distances: list, sizes: list) -> list[dict]:
    """Rows of a distance × payload sweep: the link margin falls 0.1 dB per metre from 10 dB,
    less 1 dB per payload step; the policy needs 5 dB, so the largest distance of payload
    number j is 50 − 10·j m; points meeting the policy pass, the others fail."""
    rows = []
    for j, size in enumerate(sizes):
        for d in distances:
            db = 10.0 - 0.1 * d - j
            rows.append({"channel.packet_bytes": size, "channel.distance_m": d,
                         "margin": 0.5 if db >= 5 else -0.2, "link_margin_db": db,
                         "required_margin_db": 5.0, "max_distance_m": 50.0 - 10.0 * j,
                         "decision": "pass" if db >= 5 else "fail"})
    return rows


@pytest.mark.parametrize("distances", [[20, 40, 60, 80], [20.5, 40.25, 60.0, 79.75]],
                         ids=["integer grid", "float grid"])
def test_sweep_legend_and_every_point_visible(distances: list) -> None:
    sizes = [20, 40, 116]
    rows = sweep_rows(distances, sizes)
    fig = margin_figure(rows, ["channel.packet_bytes", "channel.distance_m"],
                        "channel.distance_m")
    texts = legend_texts(fig)
    assert "link margin the policy requires" in texts
    assert any(t.startswith("largest distance meeting the policy") for t in texts)
    assert "review: pass (filled dot)" in texts and "review: fail (cross)" in texts
    assert [t for t in texts if t.startswith("payload (bytes) = ")] == [
        f"payload (bytes) = {s}" for s in sizes]
    # the legend sits outside the axes: it overlaps none of them
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    box = fig.legends[0].get_window_extent(renderer)
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent(renderer))
    top, bottom = fig.axes
    assert "p" in top.get_ylabel() and "_" not in top.get_ylabel()
    assert bottom.get_ylabel() == "link margin (dB)"
    # every grid point is a marker inside the axis limits
    for ax, key in ((top, "margin"), (bottom, "link_margin_db")):
        marked = [(x, y) for ln in ax.get_lines() if ln.get_marker() not in ("None", "", None)
                  for x, y in zip(ln.get_xdata(), ln.get_ydata())]
        want = sorted((r["channel.distance_m"], r[key]) for r in rows)
        assert sorted(marked) == want
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert all(x0 < x < x1 and y0 < y < y1 for x, y in marked)
    # each largest-distance line in its series' colour, at 50 − 10·j m
    series = {ln.get_label(): ln.get_color() for ln in top.get_lines()
              if ln.get_label().startswith("payload")}
    vlines = [ln for ln in bottom.get_lines() if ln.get_linestyle() != "None"
              and len(set(ln.get_xdata())) == 1 and ln.get_xdata()[0] in (50.0, 40.0, 30.0)]
    for j, size in enumerate(sizes):
        line = next(ln for ln in vlines if ln.get_xdata()[0] == 50.0 - 10.0 * j)
        assert to_rgba(line.get_color()) == to_rgba(series[f"payload (bytes) = {size}"])


def critical_curve_record(gap: float) -> AnalysisRecord:
    """The bursty scalar link's record with its critical curve replaced: r_nec = 9/25 at every
    f, r_suf = 9/25 + gap, the operating point (0.05, 0.1)."""
    rec = record("ge-bursty-scalar")
    f = np.linspace(0.0, 1.0, 11).tolist()
    curve = rec.link_budget.critical_curve
    curve = replace(curve, failure_rates=f, necessary_recovery=[0.36] * 11,
                    sufficient_recovery=[0.36 + gap] * 11, necessary_expression="9/25",
                    operating_point=RatesPoint(failure_rate=0.05, recovery_rate=0.1))
    return replace(rec, link_budget=replace(rec.link_budget, critical_curve=curve))


def test_coinciding_critical_curves_are_distinguishable() -> None:
    fig = draw_critical_curve(critical_curve_record(6.25e-4))
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if len(ln.get_ydata()) and
             np.all(np.abs(np.asarray(ln.get_ydata(), dtype=float) - 0.36) < 1e-3)]
    styles = {(ln.get_linewidth(), str(ln.get_linestyle()), ln.get_marker()) for ln in lines}
    assert len(lines) == 3 and len(styles) == 3
    texts = legend_texts(fig)
    assert any("sufficient recovery rate" in t and "within 0.00062" in t for t in texts)
    assert any(t.startswith("r = 9/25") for t in texts)
    exact = legend_texts(draw_critical_curve(critical_curve_record(0.0)))
    assert any("the critical curve is exact" in t for t in exact)
    # r_suf = r_nec everywhere (the scalar theorem, theory §7): no band is left undetermined
    assert any("mean-stable (exact)" in t for t in exact)
    assert not any("(certificate)" in t for t in exact)
    apart = legend_texts(draw_critical_curve(critical_curve_record(0.2)))
    assert not any("within" in t or "exact" in t for t in apart)
    assert any("mean-stable (certificate)" in t for t in apart)


def region_record() -> AnalysisRecord:
    """Two sensors a, b with |λ|² = 36/25 unobservable without both: the necessary
    constraint 1.44·(1 − p_a)(1 − p_b) < 1 (the planar tracker's record, edited)."""
    rec = record("network-planar-tracker")
    one, two = rec.network.sensors[:2]
    a = replace(one, name="a", arrival_probability=0.9,
                critical_value=replace(one.critical_value, value=0.2, interval=[0.2, 0.2]),
                margin=SensorMargin(value=0.7, interval=[0.7, 0.7]))
    b = replace(two, name="b", arrival_probability=0.5,
                critical_value=replace(two.critical_value, value=None, interval=[0.2, 0.4]),
                margin=SensorMargin(value=None, interval=[0.1, 0.3]))
    constraint = replace(rec.network.necessary_constraints[0], modulus2=1.44,
                         modulus2_expression="36/25", unobservable_without=["a", "b"])
    network = replace(rec.network, sensors=[a, b],
                      bottleneck=replace(rec.network.bottleneck, name="b"),
                      necessary_constraints=[constraint])
    return replace(rec, network=network)


@pytest.mark.parametrize("fig_of", [lambda: draw_critical_curve(critical_curve_record(0.0)),
                                    lambda: draw_network_region(region_record())],
                         ids=["critical curve", "network region"])
def test_full_width_figures_print_text_of_at_least_7_pt(fig_of) -> None:
    fig = fig_of()
    w, h = fig.get_size_inches()
    assert (w, h) == (WIDTH_IN, HEIGHT_IN)
    # 182 mm text width, 58 mm print height cap: 2.283 in / 2.6 in = 0.878 (by hand)
    scale = print_scale(w, h)
    assert scale == pytest.approx(58 / 25.4 / 2.6)
    FigureCanvasAgg(fig).draw()
    sizes = [t.get_fontsize() for leg in fig.legends for t in leg.get_texts()]
    for ax in fig.axes:
        sizes += [t.get_fontsize() for t in ax.get_xticklabels() + ax.get_yticklabels()]
        sizes += [ax.xaxis.label.get_fontsize(), ax.yaxis.label.get_fontsize()]
    assert sizes and min(sizes) * scale >= MIN_PRINT_PT
