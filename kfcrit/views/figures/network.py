"""Sensor-network figures: the stability region of the two weakest links, and the node map.

Both read the typed record's ``network`` section
(:class:`~kfcrit.records.network.NetworkSection`) and ``system.sensors``; nothing is
computed beyond drawing record values. The region figure evaluates the record's closed-form
necessary constraints (theory §9)

.. math::

    \\lvert\\lambda\\rvert^2 \\prod_{k \\in S} (1 - p_k) < 1

on a grid of the two plotted arrival probabilities (the others at their operating values): that
is drawing a formula whose every constant is in the record. The sufficient surface is not in the
record as a curve; only its points on the lines through the operating point (the per-sensor
critical values' sufficient ends) are drawn.
"""
from __future__ import annotations

import math
from typing import Any

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.records.network import NetworkSensor
from kfcrit.views.figures.style import (
    COLORS,
    FIG_RC,
    finite,
    fmt,
    new_figure,
    present,
    readable_rc,
)
from kfcrit.views.text.netmargin import sensor_margin_bounds

REGION_GRID = 241
"""Points per axis of the grid on which the necessary constraints are drawn."""


def sensors_of(rec: AnalysisRecord) -> list[NetworkSensor]:
    """The ``network.sensors`` rows (record order; empty without a network)."""
    return list(rec.network.sensors) if present(rec.network) else []


def margin_bounds(sensor: NetworkSensor) -> tuple[float | None, float | None]:
    """(conservative, optimistic) ends of a sensor's margin p_i − p_c,i.

    ``margin.value`` when the critical value is known; else ``margin.interval``, whose lower
    end (p_i minus the sufficient end) is the margin that is certain.
    """
    return sensor_margin_bounds(sensor)


def weakest_pair(rec: AnalysisRecord) -> list[int]:
    """Indices (into :func:`sensors_of`) of the two weakest links, weakest first.

    The record's bottleneck comes first; the others follow by their certain margin (the
    conservative end of :func:`margin_bounds`), sensor order breaking ties. Fewer than two
    sensors: an empty list.
    """
    sensors = sensors_of(rec)
    if len(sensors) < 2:
        return []
    bottleneck = rec.network.bottleneck.name

    def key(i: int) -> tuple[int, float, int]:
        low, _ = margin_bounds(sensors[i])
        return (0 if sensors[i].name == bottleneck else 1,
                math.inf if low is None else low, i)

    return sorted(range(len(sensors)), key=key)[:2]


def constraint_values(rec: AnalysisRecord, pair: list[int], grid: np.ndarray
                      ) -> list[tuple[str, np.ndarray]]:
    """Each necessary constraint |λ|²·Π_{k∈S}(1 − p_k) over the grid of the pair's p.

    Returns (label, values) with values of shape (len(grid), len(grid)): rows follow the second
    sensor's p, columns the first's. Constraints that do not involve either plotted sensor are
    constant; they are kept (a constant ≥ 1 makes the whole plane unstable).
    """
    sensors = sensors_of(rec)
    names = [s.name for s in sensors]
    p_op = {s.name: finite(s.arrival_probability) for s in sensors}
    x_name, y_name = names[pair[0]], names[pair[1]]
    px, py = np.meshgrid(grid, grid)
    out = []
    raw = rec.network.necessary_constraints if present(rec.network) else []
    for c in raw:
        m2 = finite(c.modulus2)
        members = c.unobservable_without
        if m2 is None:
            continue
        value = np.full_like(px, m2)
        for name in members:
            if name == x_name:
                value = value * (1.0 - px)
            elif name == y_name:
                value = value * (1.0 - py)
            elif p_op.get(name) is not None:
                value = value * (1.0 - p_op[name])
            else:
                break
        else:
            out.append((f"|λ|² = {c.modulus2_expression or m2} mode, "
                        f"links {', '.join(members)}", value))
    return out


def draw_network_region(rec: AnalysisRecord) -> Figure | None:
    """The (p_i, p_j) plane of the two weakest links: where the necessary constraints fail
    (mean-unstable, proven), each constraint's boundary, the per-sensor critical intervals on
    the lines through the operating point, and the operating point."""
    pair = weakest_pair(rec)
    if not pair:
        return None
    sensors = sensors_of(rec)
    sx, sy = sensors[pair[0]], sensors[pair[1]]
    ox, oy = finite(sx.arrival_probability), finite(sy.arrival_probability)
    if ox is None or oy is None:
        return None
    grid = np.linspace(0.0, 1.0, REGION_GRID)
    constraints = constraint_values(rec, pair, grid)
    with matplotlib.rc_context(readable_rc()):
        # Full-width size: the print CSS caps the height, so a taller figure prints narrower
        # (and its text smaller); the legend right of the square axes uses the width.
        fig, ax = new_figure()
        ax.set_box_aspect(1)
        if constraints:
            worst = np.max(np.stack([v for _, v in constraints]), axis=0)
            ax.contourf(grid, grid, (worst >= 1.0).astype(float), levels=[0.5, 1.5],
                        colors=["#fde2e2"])
            ax.fill_between([], [], color="#fde2e2",
                            label="a necessary constraint fails: mean-unstable (proven)")
        palette = ["#b91c1c", "#7c3aed", "#d9730d", "#6b7280"]
        for k, (label, value) in enumerate(constraints):
            if np.nanmin(value) < 1.0 <= np.nanmax(value):
                ax.contour(grid, grid, value, levels=[1.0], colors=[palette[k % len(palette)]],
                           linewidths=1.3)
                ax.plot([], [], color=palette[k % len(palette)], linewidth=1.3,
                        label=f"necessary boundary: {label}")
        _critical_segment(ax, sx, oy, horizontal=True)
        _critical_segment(ax, sy, ox, horizontal=False)
        ax.plot([ox], [oy], marker="o", markersize=6, color=COLORS["operating"],
                linestyle="none", label=f"operating point ({fmt(ox)}, {fmt(oy)})", clip_on=False)
        ax.set_xlim(-0.02, 1.02)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel(f"arrival probability of {sx.name}")
        ax.set_ylabel(f"arrival probability of {sy.name}")
        # The square axes sit next to the legend (no gap opens between them).
        ax.set_anchor("E")
        fig.legend(loc="outside right center", frameon=False)
        return fig


def _critical_segment(ax: Any, sensor: NetworkSensor, other_p: float, *,
                      horizontal: bool) -> None:
    """A sensor's critical value with the other links at their operating values: a point
    (exact) or a segment from the necessary to the sufficient end, on the line through the
    operating point."""
    cv = sensor.critical_value
    iv = cv.interval
    lo = hi = finite(cv.value)
    if lo is None and isinstance(iv, (list, tuple)) and len(iv) == 2:
        lo, hi = finite(iv[0]), finite(iv[1])
    if lo is None or hi is None:
        return
    xs, ys = ([lo, hi], [other_p, other_p]) if horizontal else ([other_p, other_p], [lo, hi])
    name = sensor.name
    if hi - lo > 1e-9:
        ax.plot(xs, ys, color=COLORS["p_up"], linewidth=3.0, alpha=0.6, solid_capstyle="butt",
                label=f"critical interval of {name} [{fmt(lo)}, {fmt(hi)}]")
        ax.plot(xs[-1:], ys[-1:], marker="s", markersize=4.5, color=COLORS["p_up"],
                linestyle="none")
    else:
        ax.plot(xs[:1], ys[:1], marker="D", markersize=5, color=COLORS["p_c"],
                linestyle="none", clip_on=False, label=f"critical value of {name} = {fmt(lo)}")


def positions_of(rec: AnalysisRecord) -> dict[str, tuple[float, float]]:
    """Sensor positions ``system.sensors[k].position_m`` (planar), by name."""
    sensors = rec.system.sensors if present(rec.system.sensors) else []
    out: dict[str, tuple[float, float]] = {}
    for s in sensors:
        pos = s.position_m
        if isinstance(pos, (list, tuple)) and len(pos) == 2:
            x, y = finite(pos[0]), finite(pos[1])
            if x is not None and y is not None:
                out[s.name] = (x, y)
    return out


def sink_of(rec: AnalysisRecord) -> tuple[float, float] | None:
    """The sink's position ``system.sink_position_m`` (``None`` when the record has none)."""
    pos = rec.system.sink_position_m
    if isinstance(pos, (list, tuple)) and len(pos) == 2:
        x, y = finite(pos[0]), finite(pos[1])
        if x is not None and y is not None:
            return x, y
    return None


def draw_network_map(rec: AnalysisRecord) -> Figure | None:
    """The nodes at their positions (and the sink, when the record has it), coloured by the
    certain margin p_i − p_c,i of each link."""
    from matplotlib import colormaps
    from matplotlib.colors import TwoSlopeNorm

    sensors = sensors_of(rec)
    pos = positions_of(rec) if sensors else {}
    sensors = [s for s in sensors if s.name in pos]
    if not sensors:
        return None
    margins = [margin_bounds(s) for s in sensors]
    known = [abs(m[0]) for m in margins if m[0] is not None]
    span = max(known + [1e-3])
    norm = TwoSlopeNorm(vcenter=0.0, vmin=-span, vmax=span)
    cmap = colormaps["RdYlGn"]
    sink = sink_of(rec)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(3.3)
        ax.set_aspect("equal", adjustable="box")
        for s, (low, high) in zip(sensors, margins):
            x, y = pos[s.name]
            if sink is not None:
                ax.plot([x, sink[0]], [y, sink[1]], color="#9ca3af", linewidth=0.8,
                        linestyle="--", zorder=1)
            color = "#d1d5db" if low is None else cmap(norm(low))
            ax.scatter([x], [y], s=90, color=color, edgecolors="#111827", linewidths=0.8,
                       zorder=3)
            text = "margin ?" if low is None else (
                f"margin {low:+.3g}" if high is None or abs(high - low) < 1e-9
                else f"margin [{low:+.3g}, {high:+.3g}]")
            ax.annotate(f"{s.name}\n{text}", (x, y), xytext=(7, 5),
                        textcoords="offset points", fontsize=7.5, zorder=4)
        if sink is not None:
            ax.scatter([sink[0]], [sink[1]], marker="s", s=80, color="#111827", zorder=3)
            ax.annotate("sink", sink, xytext=(7, -11), textcoords="offset points",
                        fontsize=7.5, fontweight="bold")
        xs = [p[0] for p in pos.values()] + ([sink[0]] if sink else [])
        ys = [p[1] for p in pos.values()] + ([sink[1]] if sink else [])
        pad = 0.18 * max(max(xs) - min(xs), max(ys) - min(ys), 1.0)
        ax.set_xlim(min(xs) - pad, max(xs) + 2.2 * pad)
        ax.set_ylim(min(ys) - pad, max(ys) + pad)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        mappable = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        bar = fig.colorbar(mappable, ax=ax, shrink=0.85, pad=0.02)
        bar.set_label("certain margin p − p_c of the link")
        return fig
