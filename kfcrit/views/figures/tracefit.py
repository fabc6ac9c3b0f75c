r"""Figures of a measured trace (theory §14): its loss-burst histogram against the fitted
geometric law, and its confidence region in the (failure rate, recovery rate) plane with the
stability boundary.

Reads the typed ``channel_fit`` (:class:`kfcrit.analysis.measured.section.ChannelFitSection`). The
geometric law of loss-run lengths under the fitted Gilbert–Elliott chain is

.. math:: P(\text{length} = j) = (1 - \hat r)^{j-1}\,\hat r,

and the boundary is r = 1 − 1/ρ(A)² (below it (1 − r)ρ² ≥ 1: E[P_t] diverges for every f) with
the certificate's sufficient curve where the record has one. Nothing is computed here.
"""
from __future__ import annotations

import matplotlib
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from kfcrit.analysis.measured.section import ConfidenceRegion, RegionCorner
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.views.figures.style import (
    COLORS,
    HALF_HEIGHT_IN,
    WIDTH_IN,
    finite,
    floats,
    fmt,
    new_figure,
    present,
    readable_rc,
)


def draw_burst_histogram(rec: AnalysisRecord) -> Figure | None:
    """Observed complete loss-run lengths (bars) against the fitted geometric law (points)."""
    if not present(rec.channel_fit):
        return None
    b = rec.channel_fit.bursts
    lengths, counts = floats(b.lengths), floats(b.counts)
    if not lengths or counts is None or len(lengths) != len(counts):
        return None
    expected = floats(b.expected)
    r = finite(b.fitted_recovery_rate)
    with matplotlib.rc_context(readable_rc(WIDTH_IN, HALF_HEIGHT_IN)):
        fig, ax = new_figure(HALF_HEIGHT_IN)
        ax.bar(lengths, counts, width=0.8, color=COLORS["lower"], alpha=0.55,
               label=f"observed complete loss runs ({int(sum(counts))})")
        if expected is not None and len(expected) == len(lengths):
            ax.plot(lengths, expected, marker="o", markersize=4, linestyle="none",
                    color=COLORS["p_c"],
                    label=f"geometric law of r̂ = {fmt(r)}: runs·(1 − r̂)^(j−1)·r̂")
        if b.p_value is not None:
            ax.plot([], [], linestyle="none",
                    label=f"Pearson X² = {fmt(finite(b.statistic))}, "
                          f"{b.dof} dof, p-value {fmt(finite(b.p_value))}")
        ax.set_yscale("log" if max(counts) > 50 * max(min(counts), 1) else "linear")
        ax.set_xlabel("loss-run length j (periods)")
        ax.set_ylabel("number of runs")
        fig.legend(loc="outside right center", frameon=False)
        return fig


def _corner(c: RegionCorner) -> tuple[float, float] | None:
    f, r = finite(c.failure_rate), finite(c.recovery_rate)
    return None if f is None or r is None else (f, r)


def _corners(region: ConfidenceRegion | None) -> list[tuple[str, RegionCorner]]:
    """The worst and best corners of a Gilbert–Elliott region (none for a Bernoulli one)."""
    if region is None or region.model != "gilbert-elliott":
        return []
    return [("worst", region.worst), ("best", region.best)]


def draw_fit_region(rec: AnalysisRecord) -> Figure | None:
    """The Bonferroni rectangle of (f̂, r̂), the fitted point and the stability boundary."""
    fit = rec.channel_fit
    if not present(fit):
        return None
    fi, ri = floats(fit.failure_rate_interval), floats(fit.recovery_rate_interval)
    f_hat, r_hat = finite(fit.failure_rate_hat), finite(fit.recovery_rate_hat)
    if fi is None or ri is None or len(fi) != 2 or len(ri) != 2:
        return None
    bound = fit.boundary
    nec = finite(bound.necessary_recovery) if bound is not None else None
    with matplotlib.rc_context(readable_rc()):
        fig, ax = new_figure()
        if nec is not None:
            ax.axhspan(0, nec, color="#fde2e2", linewidth=0)
            ax.axhline(nec, color=COLORS["p_c"], linewidth=2.0,
                       label=f"(1 − r)ρ(A)² = 1: r = {fmt(nec)} (below: mean-unstable, proven)")
        fs = floats(bound.failure_rates) if bound is not None else None
        suf = bound.sufficient_recovery if bound is not None else None
        pts = [(f, finite(s)) for f, s in zip(fs or [], suf or []) if finite(s) is not None]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=COLORS["operating"],
                    marker="s", markersize=4, linestyle=(0, (5, 2.5)),
                    label="sufficient curve (coupled certificate; above: mean-stable)")
        elif nec is not None and "scalar" in (bound.note or ""):
            ax.axhspan(nec, 1, color="#dcfce7", linewidth=0)
            ax.plot([], [], color="#dcfce7", linewidth=6,
                    label="above: mean-stable (scalar plant, exact condition)")
        conf = finite(fit.confidence)
        ax.add_patch(Rectangle((fi[0], ri[0]), fi[1] - fi[0], ri[1] - ri[0], fill=False,
                               edgecolor=COLORS["lower"], linewidth=1.4,
                               label=f"{fmt(100 * conf) if conf else '?'} % confidence "
                                     "rectangle (Bonferroni)"))
        if f_hat is not None and r_hat is not None:
            ax.plot([f_hat], [r_hat], marker="*", markersize=11, color=COLORS["sim"],
                    linestyle="none", label=f"fit f̂ = {fmt(f_hat)}, r̂ = {fmt(r_hat)}")
        for (key, c), style in zip(_corners(fit.region), ("v", "^")):
            corner = _corner(c)
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
