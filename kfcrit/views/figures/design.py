"""Design figures: the accuracy requirement against the covariance bounds, and the link curves.

* ``accuracy``: tr S̄(p) and tr V̄(p) (``phase_transition``) with the requirement
  lim E[tr P] ≤ L and the required interval [p_S, p_V] of ``design.required_arrival_probability``
  shaded (theory §11: p ≤ p_S fails since tr S̄(p) > L; p ≥ p_V meets it since tr V̄(p) ≤ L);
* ``arrival_distance``, ``per_sinr``, ``outage_distance``: the link layer's curves from
  ``link_budget.curves`` (:class:`~kfcrit.records.link.LinkCurves`, the record forms of
  :mod:`kfcrit.link.curves`), drawn by
  :mod:`kfcrit.views.figures.link` with p_c, the requirement and the design distance marked.

Nothing is computed here: record values are only read back into arrays and drawn.
"""
from __future__ import annotations

import math
from typing import Any

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.link.curves import ArrivalCurve, OutageCurve, PerCurve
from kfcrit.records.channel import RadioRecord
from kfcrit.records.link import LinkBudgetRecord, LinkCurves
from kfcrit.views.figures.link import arrival_distance_figure, outage_distance_figure, per_sinr_figure
from kfcrit.views.figures.style import (
    COLORS,
    FIG_RC,
    finite,
    floats,
    fmt,
    mark,
    new_figure,
    plain_log_labels,
    positive,
    present,
)


def required_interval(rec: AnalysisRecord) -> tuple[float, float] | None:
    """[p_S, p_V] of the accuracy requirement (``design.required_arrival_probability``)."""
    iv = rec.design.required_arrival_probability.interval if present(rec.design) else None
    if isinstance(iv, (list, tuple)) and len(iv) == 2:
        lo, hi = finite(iv[0]), finite(iv[1])
        if lo is not None and hi is not None:
            return lo, hi
    return None


def requirement_level(rec: AnalysisRecord) -> float | None:
    """L of lim E[tr P] ≤ L (``design.required_arrival_probability.level``, else the
    requirement's ``requirements.max_mean_error_trace``)."""
    level = (finite(rec.design.required_arrival_probability.level) if present(rec.design)
             else None)
    if level is not None or rec.requirements is None:
        return level
    return finite(rec.requirements.max_mean_error_trace)


def draw_accuracy(rec: AnalysisRecord) -> Figure | None:
    """tr S̄ and tr V̄ against p with the requirement line L and [p_S, p_V] shaded."""
    level = requirement_level(rec)
    pt = rec.phase_transition
    if level is None or pt is None or not present(rec.design):
        return None
    p = floats(pt.p)
    lower, upper = floats(pt.trace_lower), floats(pt.trace_upper)
    if p is None:
        return None
    interval = required_interval(rec)
    floor = finite(rec.design.required_arrival_probability.floor_trace)
    operating = finite(pt.markers.operating)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(3.1)
        drawn = False
        for seq, key, label in ((lower, "lower", r"tr $\bar S(p)$: lim E[tr P] ≥ it"),
                                (upper, "upper", r"tr $\bar V(p)$: lim E[tr P] ≤ it")):
            if seq is not None and len(seq) == len(p) and positive(seq):
                ax.plot(p, seq, color=COLORS[key], linewidth=1.6, label=label)
                drawn = True
        if not drawn:
            return None
        ax.axhline(level, color=COLORS["p_c"], linewidth=1.2, linestyle="--",
                   label=f"requirement L = {fmt(level)}")
        if floor is not None and floor > 0:
            ax.axhline(floor, color=COLORS["p_low"], linewidth=1, linestyle=":",
                       label=f"floor tr P∞ = {fmt(floor)} (every packet arrives)")
        if interval is not None:
            ax.axvspan(interval[0], interval[1], color=COLORS["operating"], alpha=0.18,
                       linewidth=0, label=f"[p_S, p_V] = [{fmt(interval[0])}, {fmt(interval[1])}]"
                       " (bounds do not decide)")
        ax.set_yscale("log")
        shown = [v for v in (lower or []) + (upper or []) if math.isfinite(v) and v > 0]
        top = max(level * 30, floor or 0)
        ax.set_ylim(max(min(shown + [level]) / 2, 1e-300), min(max(shown), top))
        left = [x for x, v in zip(p, upper or lower or []) if math.isfinite(v) and v <= top]
        marks = [v for v in (interval or ()) if v is not None]
        lo = min(left + marks) if left or marks else min(p)
        ax.set_xlim(max(min(p), lo - 0.08 * (max(p) - lo)), max(p))
        mark_operating(ax, operating)
        plain_log_labels(ax, "y")
        ax.set_xlabel("arrival probability p")
        ax.set_ylabel("trace of the bound")
        fig.legend(loc="outside lower center", frameon=False, ncols=2)
        return fig


def mark_operating(ax: Any, operating: float | None) -> None:
    """The operating p: a vertical line inside the x range; outside it, an arrow at the axis
    edge pointing towards it (with its value), so that the legend never names an unseen line."""
    if operating is None:
        return
    lo, hi = ax.get_xlim()
    label = f"operating p = {fmt(operating)}"
    if lo <= operating <= hi:
        mark(ax, operating, "operating", label, "-.")
        return
    left = operating < lo
    ax.annotate(f"{label} {'left' if left else 'right'} of the axis",
                xy=(0.0 if left else 1.0, 0.92), xycoords="axes fraction",
                xytext=(16 if left else -16, 0), textcoords="offset points",
                ha="left" if left else "right", va="center", fontsize=7.5,
                color=COLORS["operating"], bbox={"fc": "white", "ec": "none", "pad": 1.0},
                arrowprops={"arrowstyle": "->", "color": COLORS["operating"], "lw": 1.2})
    ax.plot([], [], color=COLORS["operating"], marker="<" if left else ">", linestyle="none",
            label=f"{label} (off the axis: arrow at its {'left' if left else 'right'} edge)")


def _budget(rec: AnalysisRecord) -> LinkBudgetRecord | None:
    """The link budget's section (``None`` for no link budget, or a Gilbert–Elliott one)."""
    lb = rec.link_budget
    return lb if isinstance(lb, LinkBudgetRecord) else None


def _curves(rec: AnalysisRecord) -> LinkCurves | None:
    lb = _budget(rec)
    return lb.curves if lb is not None and present(lb.curves) else None


def _array(values: Any, ndim: int = 1) -> np.ndarray | None:
    """A float array of ``ndim`` dimensions from a record list (``None`` → NaN), or ``None``."""
    if not isinstance(values, list) or not values:
        return None
    try:
        arr = np.array([[math.nan if v is None else v for v in row] for row in values]
                       if ndim == 2 else [math.nan if v is None else v for v in values],
                       dtype=float)
    except (TypeError, ValueError):
        return None
    return arr if arr.ndim == ndim else None


def arrival_curve_of(rec: AnalysisRecord) -> ArrivalCurve | None:
    """``link_budget.curves.arrival_vs_distance`` read back (see
    :meth:`kfcrit.link.curves.ArrivalCurve.to_dict`)."""
    curves = _curves(rec)
    if curves is None:
        return None
    c = curves.arrival_vs_distance
    d, arr = _array(c.distance_m), _array(c.arrival)
    mean = _array(c.mean_arrival) if c.mean_arrival is not None else None
    conf = finite(c.configured_distance_m)
    if d is None or arr is None or len(d) != len(arr) or conf is None:
        return None
    if mean is not None and len(mean) != len(d):
        mean = None
    return ArrivalCurve(d, arr, mean, conf, int(c.max_retries or 0), int(c.psdu_bytes or 0))


def design_p_c(rec: AnalysisRecord) -> float | None:
    """p_c for the link figures: the critical value, else the link's design requirement."""
    value = finite(rec.critical_value.value) if rec.critical_value is not None else None
    lb = _budget(rec)
    if value is not None or lb is None:
        return value
    return finite(lb.required_arrival_probability.design_value)


def draw_arrival_distance(rec: AnalysisRecord) -> Figure | None:
    """p(d) with p_c, the required [p_S, p_V] and the largest distance of the margin policy."""
    curve = arrival_curve_of(rec)
    if curve is None:
        return None
    return arrival_distance_figure(
        curve, critical_value=design_p_c(rec), requirement=required_interval(rec),
        design_distance_m=finite(_budget(rec).max_distance_m))


def draw_per_sinr(rec: AnalysisRecord) -> Figure | None:
    """PER(SINR) for the record's PSDU lengths, with the configured and required SINR."""
    curves = _curves(rec)
    if curves is None:
        return None
    c = curves.per_vs_sinr
    s, per = _array(c.sinr_db), _array(c.per, 2)
    lengths = c.psdu_bytes
    if s is None or per is None or not isinstance(lengths, list) \
            or per.shape != (len(lengths), len(s)):
        return None
    curve = PerCurve(c.radio or "radio", s, tuple(int(v) for v in lengths), per,
                     int(c.header_bytes or 0))
    lb = _budget(rec)
    marks = [(label, v) for label, v in (
        ("configured SINR", finite(lb.link.sinr_db)),
        ("required SINR", finite(lb.required_sinr_db)))
        if v is not None]
    return per_sinr_figure(curve, marks=marks, title=radio_title(lb.radio))


def radio_title(radio: RadioRecord) -> str | None:
    """The radio in words for a figure title: its frame standard (``IEEE 802.15.4 O-QPSK
    2450 MHz radio``), else ``None`` (no title: the model key is a code name)."""
    standard = radio.frame.standard
    if isinstance(standard, str) and standard.strip():
        return f"{standard.strip()} radio"
    return None


def draw_outage_distance(rec: AnalysisRecord) -> Figure | None:
    """Per-link shadowing outage against distance for each requirement, with ``max_outage``."""
    curves = _curves(rec)
    if curves is None or not present(curves.outage_vs_distance):
        return None
    c = curves.outage_vs_distance
    d, out = _array(c.distance_m), _array(c.outage, 2)
    reqs = c.requirements
    conf, sigma = finite(c.configured_distance_m), finite(c.sigma_db)
    if d is None or out is None or not isinstance(reqs, list) or conf is None \
            or sigma is None or out.shape != (len(reqs), len(d)):
        return None
    pairs = tuple((str(r[0]), float(r[1])) for r in reqs
                  if isinstance(r, (list, tuple)) and len(r) == 2 and finite(r[1]) is not None)
    if len(pairs) != len(reqs):
        return None
    curve = OutageCurve(d, pairs, out, sigma, finite(c.max_outage), conf)
    return outage_distance_figure(curve)
