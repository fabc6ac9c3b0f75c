"""The report's view model: one plain dict holding every value the templates read.

:func:`view_model` assembles the section views (``view_verdict``, ``view_theory``, ``view_link``,
``view_sim``). Missing sections become ``available: False`` with a "not computed" message, never
a missing key: the template environment uses ``StrictUndefined``.
"""
from __future__ import annotations

import datetime
from typing import TYPE_CHECKING, Any

from kfcrit.records.bursty import GilbertElliottSection
from kfcrit.version import __version__
from kfcrit.views.figures.burst import is_exact_curve
from kfcrit.views.mesh.meshreport import mesh_view
from kfcrit.views.report.design import design_view, link_figures
from kfcrit.views.report.link import channel_view
from kfcrit.views.report.network import is_network, network_view
from kfcrit.views.report.parts import figure_entry, prose, stated
from kfcrit.views.report.sim import appendix_view, figures_view, simulation_view
from kfcrit.views.report.theory import (
    bounds_view,
    classification_view,
    covariance_view,
    invariant_view,
    statements_view,
    structure_view,
    system_view,
)
from kfcrit.views.report.tracefit import measured_view
from kfcrit.views.report.verdict import requirement_view, verdict_view
from kfcrit.views.text.looptext import loop_view

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord

IID_CAVEAT = ("The channel is bursty (Gilbert–Elliott): p_c, p_up, S̄ and V̄ assume i.i.d. "
              "losses, so they do not decide stability at the operating point; the burst "
              "analysis and the critical curve in section 1 do.")
NETWORK_CAVEAT = ("Sensor network: p_c, p_up, S̄, V̄ and the bounds here treat all sensors as one "
                  "link that delivers every measurement or none (the stacked system); the "
                  "per-link critical values, margins and N−1 verdicts are in section 1.")
IID_FIGURES = ("phase_transition", "traces", "operating")


def report_date(today: datetime.date | None = None) -> str:
    """The date printed in the footer: the rendering date (``today``, default today's)."""
    return (today or datetime.date.today()).isoformat()


def meta_view(rec: AnalysisRecord, today: datetime.date | None = None) -> dict[str, Any]:
    """Title, description, draft flag and the footer's system name, date and version."""
    prov = rec.provenance
    name = rec.name or "unnamed system"
    return {"title": f"Design review: {name}", "name": name,
            "description": rec.description or "",
            "quick": bool(prov.options.quick),
            "input_path": prov.input_path, "version": __version__,
            "date": report_date(today),
            "link_review": rec.link_budget is not None and rec.link_budget.applicable is True}


def has_critical_curve(rec: AnalysisRecord) -> bool:
    """Whether the record's Gilbert–Elliott section carries a critical curve."""
    lb = rec.link_budget
    return isinstance(lb, GilbertElliottSection) and stated(lb.critical_curve) is not None


def critical_curve_figure(rec: AnalysisRecord, figures: dict[str, str | None],
                          bursty: bool) -> dict[str, Any] | None:
    """The critical-curve figure of a Gilbert–Elliott link (``None`` for i.i.d. channels)."""
    if not bursty and not has_critical_curve(rec):
        return None
    exact = has_critical_curve(rec) and is_exact_curve(rec.link_budget.critical_curve)
    return figure_entry(
        figures.get("critical_curve"), "Critical curve of the bursty link",
        "The (failure rate f, recovery rate r) plane of the Gilbert–Elliott channel (docs/theory.md §10): "
        "at or below the necessary recovery rate r_nec(f) E[P_t] diverges (proven); "
        + ("above it E[P_t] is bounded: for a scalar plant the necessary threshold is also "
           "sufficient (docs/theory.md §7), so the record's r_suf(f) equals r_nec(f) and no "
           "band is undetermined. " if exact else
           "at or above the sufficient one r_suf(f) the coupled fixed-gain certificate proves "
           "it bounded (found numerically, drawn at the record's grid of f only); between, "
           "undetermined. ")
        + "The dotted diagonal f + r = 1 is the i.i.d. channel.",
        "critical curve: not computed (the record has no critical curve: an analysis without "
        "details, a stable plant, or more than 12 states)")


def loop_figures(view: dict[str, Any], figures: dict[str, str | None]) -> dict[str, Any]:
    """The closed loop's section view with its two figures (theory §12)."""
    if not view["available"]:
        return view
    view["plane"] = figure_entry(
        figures.get("loop_plane"), "Stable region in the (γ̄, ν̄) plane",
        "Sensing arrival probability γ̄ against actuation arrival probability ν̄ (i.i.d. links). "
        "Solid: the judged design's boundary; dashed: the other acknowledgement mode's "
        "(TCP-like optimal: γ̄ > γ_c and ν̄ > ν_c; a fixed design: least ν̄ with "
        "ρ(Σ π_m Φ_m ⊗ Φ_m) < 1 at each γ̄ of the scan). Shaded: ρ ≥ 1 on the scanned grid.",
        "stable-region figure: not computed (an analysis without details)")
    view["cost_figure"] = figure_entry(
        figures.get("loop_cost"), "Average cost against each link",
        "J against γ̄ with ν̄ at its operating value (left) and against ν̄ with γ̄ at its "
        "operating value (right), one line per design; gaps are infinite costs. TCP-like "
        "values for n > 1 use a seeded Monte Carlo of lim E[P_t|t].",
        "cost figure: not computed (an analysis without details)")
    return view


def view_model(rec: AnalysisRecord, figures: dict[str, str | None],
               today: datetime.date | None = None) -> dict[str, Any]:
    """Every value the templates read, from the record and the figures (no computation left).

    Parameters
    ----------
    rec : AnalysisRecord
        The typed analysis record (optional sections ``None`` or absent).
    figures : dict
        Figure markup from :func:`kfcrit.views.figures.record.build_figures` (``None`` where missing).
    today : datetime.date, optional
        The rendering date for the footer (default: today).
    """
    bursty = rec.operating_point is not None and rec.operating_point.iid is False
    caveat = IID_CAVEAT if bursty else NETWORK_CAVEAT if is_network(rec) else ""
    figs = figures_view(figures, rec)
    if caveat:
        # the caveat in full once (section 4); figures and tables point to it
        short = ("i.i.d. losses assumed (see the caveat in section 4)." if bursty else
                 "all sensors treated as one link (see the note in section 4).")
        for key in IID_FIGURES:
            figs[key]["caption"] = f"Caveat: {short} {figs[key]['caption']}"
    channel = channel_view(rec)
    channel["critical_curve"] = critical_curve_figure(rec, figures, bursty)
    channel["link_figures"] = link_figures(rec, figures)
    return {
        "meta": meta_view(rec, today),
        "verdict": verdict_view(rec),
        "warnings": list(dict.fromkeys(prose(w) for w in rec.warnings)),
        "system": system_view(rec),
        "structure": structure_view(rec),
        "classification": classification_view(rec),
        "bounds": bounds_view(rec),
        "covariance": covariance_view(rec),
        "figures": figs,
        "iid_caveat": caveat,
        "iid_caveat_short": ("These bounds assume i.i.d. losses: see the caveat in section 4."
                             if bursty else "These bounds treat all sensors as one link: see "
                             "section 4." if caveat else ""),
        "simulation": simulation_view(rec),
        "requirement": requirement_view(rec),
        "statements": statements_view(rec),
        "invariant": invariant_view(rec, figures.get("invariant")),
        "channel": channel,
        "network": network_view(rec, figures),
        "mesh": mesh_view(rec, figures),
        "loop": loop_figures(loop_view(rec), figures),
        "channel_fit": measured_view(rec, figures),
        "design": design_view(rec, figures),
        "appendix": appendix_view(rec),
    }
