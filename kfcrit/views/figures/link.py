"""Link figures: arrival probability against distance, PER against SINR, outage against distance.

Each function draws curves computed by :mod:`kfcrit.link.curves` and returns a matplotlib
``Figure`` (nothing is computed here beyond plotting). Save with ``fig.savefig(path)``.
"""
from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

from matplotlib import rc_context, ticker  # noqa: E402 - after choosing the backend
from matplotlib.figure import Figure  # noqa: E402

from kfcrit.link.curves import ArrivalCurve, OutageCurve, PerCurve  # noqa: E402
from kfcrit.views.figures.style import (  # noqa: E402
    COLORS,
    FIG_RC,
    HALF_HEIGHT_IN,
    HALF_WIDTH_IN,
    HEIGHT_IN,
    arrival_formula,
    fmt,
    legend_quantity,
    new_figure,
    percent,
)

LINE_COLORS = ("#1f5fa8", "#d9730d", "#15803d", "#7c3aed", "#6b7280")


REQUIREMENT_WORDS = {"p_c": "$p_c$", "p_up": "$p_{up}$", "p_low": "$p_{low}$",
                     "p_S": "$p_S$", "p_V": "$p_V$"}
"""Symbols (mathtext subscripts) for the requirement names of
:class:`kfcrit.link.curves.OutageCurve` (``kfcrit.analysis.links`` names them p_c, p_up, p_S,
p_V)."""


def requirement_words(name: str) -> str:
    """A requirement's name for a legend: the symbol with its subscript (``$p_c$``), other
    code names with spaces for underscores."""
    return REQUIREMENT_WORDS.get(name, name.replace("_", " "))


def _plain_log_x(ax: object) -> None:
    """Distances as plain numbers (20, 30, 50, 100 m) on a log axis."""
    ax.xaxis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 3.0, 5.0)))
    ax.xaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax.xaxis.set_minor_formatter(ticker.NullFormatter())


def _legend_below(fig: Figure, ax: object, ncols: int = 2) -> None:
    """The legend under the axes, so that it never hides a curve."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=ncols, frameon=False)


def _distance_lines(ax: object, configured_m: float, design_m: float | None) -> None:
    """The configured distance (thick, light, solid) and the largest distance of the margin
    policy (thin, dark, dashed, drawn on top): both stay visible when they nearly coincide."""
    ax.axvline(configured_m, color=COLORS["band"], ls="-", lw=3.2, alpha=0.8, zorder=1.5,
               label=f"configured distance d = {legend_quantity(configured_m, 'm')}")
    if design_m is not None:
        ax.axvline(design_m, color=COLORS["p_up"], ls=(0, (4, 2)), lw=1.1, zorder=2.5,
                   label=f"largest distance meeting the margin policy = "
                         f"{legend_quantity(design_m, 'm')}")


def arrival_distance_figure(curve: ArrivalCurve, *, critical_value: float | None = None,
                            requirement: Sequence[float] | None = None,
                            design_distance_m: float | None = None) -> Figure:
    """p(d) of the median link (and the shadowing average) with p_c and the requirement.

    Parameters
    ----------
    curve : ArrivalCurve
        From :func:`kfcrit.link.curves.arrival_vs_distance`.
    critical_value : float, optional
        p_c, drawn as a horizontal line.
    requirement : (p_S, p_V), optional
        The required arrival-probability interval, shaded (a single value: a line).
    design_distance_m : float, optional
        The largest distance meeting the requirement under the margin policy.
    """
    with rc_context(FIG_RC):
        fig, ax = new_figure(HEIGHT_IN + 0.5)
        retries = f", k = {curve.max_retries} retries" if curve.max_retries else ""
        ax.plot(curve.distance_m, curve.arrival, color=COLORS["lower"],
                label=f"median link, {arrival_formula(curve.max_retries)} "
                      f"(PSDU {curve.psdu_bytes} bytes{retries})")
        if curve.mean_arrival is not None:
            ax.plot(curve.distance_m, curve.mean_arrival, color=COLORS["upper"], ls="-.",
                    label="shadowing average (per-packet mean)")
        if critical_value is not None:
            ax.axhline(critical_value, color=COLORS["p_c"], ls="--", lw=1,
                       label=f"critical arrival probability $p_c$ = {fmt(critical_value)}")
        if requirement is not None and len(requirement) == 2 \
                and requirement[0] != requirement[1]:
            ax.axhspan(requirement[0], requirement[1], color=COLORS["operating"], alpha=0.15,
                       label=f"required interval [$p_S$, $p_V$] = [{fmt(requirement[0])}, "
                             f"{fmt(requirement[1])}]")
        elif requirement is not None:
            ax.axhline(requirement[-1], color=COLORS["operating"], ls=":", lw=1.2,
                       label=f"required p = {fmt(requirement[-1])}")
        _distance_lines(ax, curve.configured_distance_m, design_distance_m)
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("distance d (m)")
        ax.set_ylabel("arrival probability")
        ax.set_title("Arrival probability against distance")
        _plain_log_x(ax)
        _legend_below(fig, ax, ncols=2)
    return fig


def per_sinr_figure(curve: PerCurve, *, marks: Sequence[tuple[str, float]] = (),
                    title: str | None = None) -> Figure:
    """PER of one attempt against SINR (dB) for each PSDU length, log scale.

    ``marks``: (label, SINR dB) pairs drawn as vertical lines (e.g. the configured SINR).
    ``title``: the radio in words (e.g. its display name); ``None`` draws no title (the
    curve's radio is a code name, not a title).
    """
    with rc_context(FIG_RC):
        fig, ax = new_figure(HALF_HEIGHT_IN + 0.35, HALF_WIDTH_IN)
        for i, length in enumerate(curve.psdu_bytes):
            y = curve.per[i]
            ax.plot(curve.sinr_db, y, color=LINE_COLORS[i % len(LINE_COLORS)],
                    label=f"PSDU {length} bytes")
        for j, (label, x) in enumerate(marks):
            ax.axvline(x, color=COLORS["sim"], ls=(":" if j % 2 == 0 else "--"), lw=1,
                       label=f"{label} = {legend_quantity(x, 'dB')}")
        ax.set_yscale("log")
        ax.set_ylim(1e-8, 1.5)
        ax.set_xlabel("SINR (dB)")
        ax.set_ylabel("packet error rate" + (
            f" (+ {curve.header_bytes}-byte PHY header)" if curve.header_bytes else ""))
        if title:
            ax.set_title(title)
        _legend_below(fig, ax)
    return fig


def outage_distance_figure(curve: OutageCurve) -> Figure:
    """P(p_link < p) over per-link shadowing against distance, with the allowed outage.

    Legends in words: ``P(arrival prob. < 0.36), p_c`` and ``allowed outage 10 %``.
    """
    with rc_context(FIG_RC):
        fig, ax = new_figure(HALF_HEIGHT_IN + 0.35, HALF_WIDTH_IN)
        for i, (label, p) in enumerate(curve.requirements):
            ax.plot(curve.distance_m, curve.outage[i], color=LINE_COLORS[i % len(LINE_COLORS)],
                    label=f"P(arrival prob. < {fmt(p)}), {requirement_words(label)}")
        if curve.max_outage is not None:
            ax.axhline(curve.max_outage, color=COLORS["p_c"], ls="--", lw=1,
                       label=f"allowed outage {percent(curve.max_outage)}")
        _distance_lines(ax, curve.configured_distance_m, None)
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("distance d (m)")
        ax.set_ylabel("outage probability")
        ax.set_title(f"shadowing σ = {curve.sigma_db:g} dB, per link")
        _plain_log_x(ax)
        _legend_below(fig, ax, ncols=1)
    return fig


def ns3_arrival_figure(summary: dict, distances_m: Sequence[float],
                       curves: dict[str, Sequence[float]]) -> Figure:
    """Analytic against simulated arrival by distance (``kfcrit link simulate -o``).

    One line per sensor: its link budget's p(d) (``curves[name]`` on ``distances_m``); at the
    sensor's distance, the ns-3 arrival rate with its 95 % Clopper–Pearson interval (error bar)
    and the analytic value under the simulated shadowing draw and fading (open marker).
    """
    with rc_context(FIG_RC):
        fig, ax = new_figure(HEIGHT_IN + 0.5)
        palette = [COLORS["lower"], COLORS["upper"], COLORS["p_c"], COLORS["operating"],
                   COLORS["sim"]]
        for k, row in enumerate(summary["sensors"]):
            color = palette[k % len(palette)]
            name = row["name"]
            if name in curves:
                ax.plot(distances_m, curves[name], color=color, lw=1.1,
                        label=f"{name}: link budget p(d)")
            lo, hi = row["arrival_simulated_ci95"]
            p = row["arrival_simulated"]
            ax.errorbar([row["distance_m"]], [p], yerr=[[p - lo], [hi - p]], fmt="o",
                        color=color, ms=4, capsize=3,
                        label=f"{name}: ns-3 {p:.3f} [{lo:.3f}, {hi:.3f}]")
            ax.plot([row["distance_m"]], [row["arrival_analytic_simulated_conditions"]],
                    marker="D", mfc="none", color=color, ms=6, ls="none")
        ax.plot([], [], marker="D", mfc="none", color="0.3", ls="none",
                label="analytic at the simulated shadowing and fading")
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("distance d (m)")
        ax.set_ylabel("arrival probability")
        ax.set_title("Analytic against simulated (ns-3) arrival by distance")
        _plain_log_x(ax)
        _legend_below(fig, ax, ncols=2)
    return fig
