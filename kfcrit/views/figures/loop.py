"""Closed-loop figures (theory §12): the (γ̄, ν̄) plane and the cost against each link.

Both draw the typed record's ``loop`` section (:class:`~kfcrit.analysis.loop.schema.LoopSection`)
only: the boundary points of each design's stable
region (``critical_curve``, ``alternative_curve``), the float spectral radius ρ on the scanned
grid (a fixed design's shading), the operating point, and the cost series of ``cost_curves``.
Nothing is computed beyond drawing record values.
"""
from __future__ import annotations

from typing import Any

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from kfcrit.analysis.loop.schema import LoopCurve
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.views.figures.style import COLORS, finite, floats, fmt, new_figure, present, readable_rc

CURVE_COLORS = {"TCP-like optimal": "#1d4ed8", "this design": "#b91c1c",
                "UDP-like (Kalman + LQR)": "#d9730d", "TCP-like (Kalman + LQR)": "#7c3aed"}


def _draw_curve(ax: Any, curve: LoopCurve | None, style: str) -> None:
    """One design's boundary: the TCP-like rectangle's corner, or a fixed design's ν*(γ̄)."""
    if curve is None:
        return
    pts = [p for p in curve.points if isinstance(p, list) and len(p) == 2]
    if not pts:
        return
    xs, ys = [float(p[0]) for p in pts], [float(p[1]) for p in pts]
    label = curve.design
    color = CURVE_COLORS.get(label, "#374151")
    ax.plot(xs, ys, style, color=color, linewidth=1.6,
            label=f"{label}: stable above/right" if curve.kind == "thresholds"
            else f"{label}: boundary ν*(γ̄)")


def _shade(ax: Any, curve: LoopCurve | None) -> None:
    """Where the scanned spectral radius of the judged design is ≥ 1 (unstable, i.i.d. links)."""
    if curve is None or not curve.rho:
        return
    g, v = floats(curve.gamma), floats(curve.nu_grid)
    rows = [floats(r) for r in curve.rho]
    if g is None or v is None or any(r is None for r in rows):
        return
    rho = np.array(rows, dtype=float).T          # (ν, γ)
    ax.contourf(g, v, (np.nan_to_num(rho, nan=np.inf) >= 1.0).astype(float),
                levels=[0.5, 1.5], colors=["#fde2e2"])
    ax.fill_between([], [], color="#fde2e2",
                    label=f"{curve.design}: ρ ≥ 1 on the scan (not mean-square stable)")


def draw_loop_plane(rec: AnalysisRecord) -> Figure | None:
    """The (γ̄, ν̄) plane: each design's stable region boundary and the operating point."""
    loop = rec.loop
    if not present(loop) or (loop.critical_curve is None and loop.alternative_curve is None):
        return None
    g0 = finite(loop.sensing_arrival_probability)
    v0 = finite(loop.actuation_arrival_probability)
    with matplotlib.rc_context(readable_rc()):
        fig, ax = new_figure()
        ax.set_box_aspect(1)
        judged = loop.critical_curve
        _shade(ax, judged if judged is not None and judged.rho else loop.alternative_curve)
        _draw_curve(ax, judged, "-")
        _draw_curve(ax, loop.alternative_curve, "--")
        if g0 is not None and v0 is not None:
            ax.plot([g0], [v0], marker="o", markersize=6, color=COLORS["operating"],
                    linestyle="none", label=f"operating point ({fmt(g0)}, {fmt(v0)}): "
                    f"{loop.verdict.value}", clip_on=False)
        ax.set_xlim(-0.02, 1.02)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("sensing arrival probability γ̄")
        ax.set_ylabel("actuation arrival probability ν̄")
        ax.set_anchor("E")
        fig.legend(loc="outside right center", frameon=False)
        return fig


def draw_loop_cost(rec: AnalysisRecord) -> Figure | None:
    """The cost J against each link's arrival probability (the other at its operating value),
    one line per design, log scale; missing points are infinite costs."""
    curves = list(rec.loop.cost_curves) if present(rec.loop) else []
    if not curves:
        return None
    with matplotlib.rc_context(readable_rc()):
        fig = Figure(figsize=(7.0, 3.2), layout="constrained")
        axes = fig.subplots(1, len(curves), sharey=True)
        axes = np.atleast_1d(axes)
        drawn = False
        for ax, curve in zip(axes, curves):
            p = floats(curve.probability)
            if p is None:
                continue
            # costs is a plain dict[str, list] field of the schema (one series per design)
            for name, series in curve.costs.items():
                y = floats(series)
                if y is None or not any(np.isfinite(y)):
                    continue
                ax.plot(p, y, marker=".", color=CURVE_COLORS.get(name, "#374151"),
                        label=name if ax is axes[0] else None)
                drawn = True
            op = finite(curve.operating)
            if op is not None:
                ax.axvline(op, color=COLORS["operating"], linestyle=":", linewidth=1.1)
            link = curve.link
            ax.set_xlabel("sensing γ̄ (ν̄ at its operating value)" if link == "sensing"
                          else "actuation ν̄ (γ̄ at its operating value)")
            ax.set_xlim(0, 1.02)
        if not drawn:
            return None
        axes[0].set_yscale("log")
        axes[0].set_ylabel("average cost J")
        fig.legend(loc="outside lower center", frameon=False, ncols=3)
        return fig
