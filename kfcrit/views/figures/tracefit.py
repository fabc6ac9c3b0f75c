r"""Figures of a measured trace (theory §14): its loss-burst histogram against the fitted
geometric law, and its confidence region in the (failure rate, recovery rate) plane with the
stability boundary.

Reads ``channel_fit`` (:class:`kfcrit.analysis.measured.section.ChannelFitSection`). The
geometric law of loss-run lengths under the fitted Gilbert–Elliott chain is

.. math:: P(\text{length} = j) = (1 - \hat r)^{j-1}\,\hat r,

and the boundary is r = 1 − 1/ρ(A)² (below it (1 − r)ρ² ≥ 1: E[P_t] diverges for every f) with
the certificate's sufficient curve where the record has one. Nothing is computed here.
"""
from __future__ import annotations

from typing import Any

import matplotlib
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from kfcrit.views.figures.style import (
    COLORS,
    HALF_HEIGHT_IN,
    WIDTH_IN,
    finite,
    floats,
    fmt,
    new_figure,
    readable_rc,
    section,
)


def draw_burst_histogram(record: dict[str, Any]) -> Figure | None:
    """Observed complete loss-run lengths (bars) against the fitted geometric law (points)."""
    b = section(record, "channel_fit", "bursts")
    if not isinstance(b, dict):
        return None
    lengths, counts = floats(b.get("lengths")), floats(b.get("counts"))
    if not lengths or counts is None or len(lengths) != len(counts):
        return None
    expected = floats(b.get("expected"))
    r = finite(b.get("fitted_recovery_rate"))
    with matplotlib.rc_context(readable_rc(WIDTH_IN, HALF_HEIGHT_IN)):
        fig, ax = new_figure(HALF_HEIGHT_IN)
        ax.bar(lengths, counts, width=0.8, color=COLORS["lower"], alpha=0.55,
               label=f"observed complete loss runs ({int(sum(counts))})")
        if expected is not None and len(expected) == len(lengths):
            ax.plot(lengths, expected, marker="o", markersize=4, linestyle="none",
                    color=COLORS["p_c"],
                    label=f"geometric law of r̂ = {fmt(r)}: runs·(1 − r̂)^(j−1)·r̂")
        if b.get("p_value") is not None:
            ax.plot([], [], linestyle="none",
                    label=f"Pearson X² = {fmt(finite(b.get('statistic')))}, "
                          f"{b.get('dof')} dof, p-value {fmt(finite(b.get('p_value')))}")
        ax.set_yscale("log" if max(counts) > 50 * max(min(counts), 1) else "linear")
        ax.set_xlabel("loss-run length j (periods)")
        ax.set_ylabel("number of runs")
        fig.legend(loc="outside right center", frameon=False)
        return fig


def _corner(region: dict[str, Any], key: str) -> tuple[float, float] | None:
    c = region.get(key) if isinstance(region.get(key), dict) else {}
    f, r = finite(c.get("failure_rate")), finite(c.get("recovery_rate"))
    return None if f is None or r is None else (f, r)


def draw_fit_region(record: dict[str, Any]) -> Figure | None:
    """The Bonferroni rectangle of (f̂, r̂), the fitted point and the stability boundary."""
    fit = section(record, "channel_fit")
    if not isinstance(fit, dict):
        return None
    fi, ri = floats(fit.get("failure_rate_interval")), floats(fit.get("recovery_rate_interval"))
    f_hat, r_hat = finite(fit.get("failure_rate_hat")), finite(fit.get("recovery_rate_hat"))
    if fi is None or ri is None or len(fi) != 2 or len(ri) != 2:
        return None
    bound = fit.get("boundary") if isinstance(fit.get("boundary"), dict) else {}
    region = fit.get("region") if isinstance(fit.get("region"), dict) else {}
    nec = finite(bound.get("necessary_recovery"))
    with matplotlib.rc_context(readable_rc()):
        fig, ax = new_figure()
        if nec is not None:
            ax.axhspan(0, nec, color="#fde2e2", linewidth=0)
            ax.axhline(nec, color=COLORS["p_c"], linewidth=2.0,
                       label=f"(1 − r)ρ(A)² = 1: r = {fmt(nec)} (below: mean-unstable, proven)")
        fs, suf = floats(bound.get("failure_rates")), bound.get("sufficient_recovery")
        pts = [(f, finite(s)) for f, s in zip(fs or [], suf or []) if finite(s) is not None]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=COLORS["operating"],
                    marker="s", markersize=4, linestyle=(0, (5, 2.5)),
                    label="sufficient curve (coupled certificate; above: mean-stable)")
        elif nec is not None and "scalar" in str(bound.get("note") or ""):
            ax.axhspan(nec, 1, color="#dcfce7", linewidth=0)
            ax.plot([], [], color="#dcfce7", linewidth=6,
                    label="above: mean-stable (scalar plant, exact condition)")
        conf = finite(fit.get("confidence"))
        ax.add_patch(Rectangle((fi[0], ri[0]), fi[1] - fi[0], ri[1] - ri[0], fill=False,
                               edgecolor=COLORS["lower"], linewidth=1.4,
                               label=f"{fmt(100 * conf) if conf else '?'} % confidence "
                                     "rectangle (Bonferroni)"))
        if f_hat is not None and r_hat is not None:
            ax.plot([f_hat], [r_hat], marker="*", markersize=11, color=COLORS["sim"],
                    linestyle="none", label=f"fit f̂ = {fmt(f_hat)}, r̂ = {fmt(r_hat)}")
        for key, style in (("worst", "v"), ("best", "^")):
            corner = _corner(region, key) if region.get("model") == "gilbert-elliott" else None
            if corner is not None:
                ax.plot(*corner, marker=style, markersize=6, color=COLORS["lower"],
                        linestyle="none", label=f"{key} corner")
        ax.plot([0, 1], [1, 0], color=COLORS["p_low"], linestyle=":", linewidth=1,
                label="f + r = 1 (i.i.d. losses)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_xlabel("failure rate f = P(lost | received before)")
        ax.set_ylabel("recovery rate r")
        fig.legend(loc="outside right center", frameon=False)
        return fig


__all__ = ["draw_burst_histogram", "draw_fit_region"]
