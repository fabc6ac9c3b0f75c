"""Report figures: matplotlib drawings of record data (Figure objects, inline SVG or PNG).

Every function here reads only the typed analysis record
(:class:`~kfcrit.analysis.sections.AnalysisRecord`, from :func:`kfcrit.analyze` or read back from
``--json`` by :func:`~kfcrit.analysis.sections.record_from_json`) and draws; nothing is computed
beyond unit conversions. :func:`figure` returns one figure as a
:class:`matplotlib.figure.Figure` (for notebooks), :func:`figure_names` lists those the record has
data for, and :func:`build_figures` returns every figure as markup for the report. A figure whose
data is missing or malformed is ``None`` and the report says "not computed" in its place.
``None`` inside a data list is a non-finite value in the record (a divergent trace, a bound that
does not exist at that p) and is drawn as a gap.

Figures (names for :func:`figure`, keys of :func:`build_figures`):

* ``phase_transition``: tr S̄ and tr V̄ against p (log scale) with p_low, p_c, p_up and the
  operating point marked (Sinopoli et al. 2004, Fig. 1-style);
* ``traces``: simulated mean tr P_t just below and just above the critical value;
* ``operating``: simulated mean tr P_t at the operating point with its band, against tr S̄, tr V̄;
* ``cdf``: empirical CDF of tr P at the operating point, with the requirement's limit;
* ``almost_sure``: block maxima and minima of tr P_t along one long path (theory §6);
* ``invariant``: support of the invariant distribution of a scalar system (Kar et al. Thm 10);
* ``network_region``, ``network_map``: a sensor network's stability region in the plane of its
  two weakest links, and the map of its nodes (:mod:`kfcrit.views.figures.network`);
* ``critical_curve``: a Gilbert–Elliott link's critical curve (:mod:`kfcrit.views.figures.burst`);
* ``accuracy``, ``arrival_distance``, ``per_sinr``, ``outage_distance``: the accuracy
  requirement against the covariance bounds and the link curves
  (:mod:`kfcrit.views.figures.design`);
* ``burst_histogram``, ``fit_region``: a measured trace's loss runs against the fitted geometric
  law and its confidence region in the (f, r) plane (:mod:`kfcrit.views.figures.tracefit`).
"""
from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Callable, Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402 - after choosing the backend

from kfcrit.analysis.sections import AnalysisRecord  # noqa: E402
from kfcrit.records.covariance import Invariant  # noqa: E402
from kfcrit.records.simulation import (  # noqa: E402
    MeanTraceStatistics,
    PhaseDemoCurve,
    SimulationOperatingPoint,
)
from kfcrit.views.figures.burst import draw_critical_curve  # noqa: E402
from kfcrit.views.figures.design import (  # noqa: E402
    draw_accuracy,
    draw_arrival_distance,
    draw_outage_distance,
    draw_per_sinr,
)
from kfcrit.views.figures.loop import draw_loop_cost, draw_loop_plane  # noqa: E402
from kfcrit.views.figures.mathsvg import clean_svg  # noqa: E402
from kfcrit.views.figures.network import draw_network_map, draw_network_region  # noqa: E402
from kfcrit.views.figures.style import (  # noqa: E402,F401
    COLORS,
    FIG_RC,
    HALF_HEIGHT_IN,
    HALF_WIDTH_IN,
    HEIGHT_IN,
    WIDTH_IN,
    draw_ecdf,
    draw_mean_band,
    finite,
    floats,
    fmt,
    mark,
    new_figure,
    plain_label,
    plain_log_labels,
    positive,
    present,
)
from kfcrit.views.figures.tracefit import draw_burst_histogram, draw_fit_region  # noqa: E402
from kfcrit.views.mesh.meshfigure import draw_mesh_topology  # noqa: E402

FIGURE_KEYS = ("phase_transition", "traces", "operating", "cdf", "almost_sure", "invariant",
               "network_region", "network_map", "critical_curve", "accuracy",
               "arrival_distance", "per_sinr", "outage_distance", "mesh_topology",
               "loop_plane", "loop_cost", "burst_histogram", "fit_region")


def _to_svg(fig: Figure, label: str) -> str:
    buf = io.BytesIO()
    with matplotlib.rc_context(FIG_RC):   # svg.fonttype and svg.hashsalt are read when saving
        fig.savefig(buf, format="svg", bbox_inches="tight", pad_inches=0.04,
                    metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    return clean_svg(buf.getvalue().decode("utf-8"), label=label, css_class="figure-svg")


def markers_of(rec: AnalysisRecord) -> dict[str, float | None]:
    """p_low, p_c, p_up and the operating p (``phase_transition.markers``; ``None`` if absent)."""
    pt = rec.phase_transition
    if pt is None:
        return dict.fromkeys(("p_low", "p_c", "p_up", "operating"))
    m = pt.markers
    return {"p_low": finite(m.p_low), "p_c": finite(m.p_c), "p_up": finite(m.p_up),
            "operating": finite(m.operating)}


def phase_window(p: Sequence[float], lower: Sequence[float] | None,
                 upper: Sequence[float] | None,
                 marks: dict[str, float | None]) -> tuple[float, float]:
    """The p-range of the phase-transition figure: where a bound exists, plus a margin.

    Both bounds are infinite below p_low, so the window starts a tenth of the remaining range
    below the first present point (and includes the operating point and the p markers).
    """
    present = [x for i, x in enumerate(p)
              if any(seq is not None and i < len(seq) and math.isfinite(seq[i])
                     for seq in (lower, upper))]
    first = min(present) if present else min(p)
    right = max(p)
    shown = [first] + [v for v in marks.values() if v is not None and min(p) <= v <= right]
    left = min(shown)
    left = max(min(p), left - 0.1 * (right - left))
    if right - left < 1e-9:
        left = max(min(p), right - 0.05)
    return left, right


def draw_phase_transition(rec: AnalysisRecord) -> Figure | None:
    """tr S̄(p) and tr V̄(p) on a log axis with p_low, p_c, p_up and the operating point."""
    pt = rec.phase_transition
    if pt is None:
        return None
    p = floats(pt.p)
    lower = floats(pt.trace_lower)
    upper = floats(pt.trace_upper)
    if p is None or (lower is None and upper is None):
        return None
    marks = markers_of(rec)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure()
        drawn = False
        if lower is not None and len(lower) == len(p) and positive(lower):
            ax.plot(p, lower, color=COLORS["lower"], linewidth=1.6,
                    label=r"tr $\bar S$ (lower bound of lim E[P])")
            drawn = True
        if upper is not None and len(upper) == len(p) and positive(upper):
            ax.plot(p, upper, color=COLORS["upper"], linewidth=1.6,
                    label=r"tr $\bar V$ (upper bound of lim E[P])")
            drawn = True
        if not drawn:
            return None
        ax.set_yscale("log")
        plain_log_labels(ax, "y")
        mark(ax, marks["p_low"], "p_low", rf"$p_{{low}}$ = {fmt(marks['p_low'])}", ":")
        mark(ax, marks["p_c"], "p_c", rf"$p_c$ = {fmt(marks['p_c'])}", "-")
        mark(ax, marks["p_up"], "p_up", rf"$p_{{up}}$ = {fmt(marks['p_up'])}", "--")
        mark(ax, marks["operating"], "operating", f"operating p = {fmt(marks['operating'])}",
              "-.")
        ax.set_xlabel("arrival probability p")
        ax.set_ylabel("trace of the bound")
        ax.set_xlim(*phase_window(p, lower, upper, marks))
        fig.legend(loc="outside lower center", frameon=False, ncols=3)
        return fig


def draw_traces(rec: AnalysisRecord) -> Figure | None:
    """Simulated mean tr P_t for arrival probabilities just below and above the critical value."""
    sim = rec.simulation
    phase_demo = sim.phase_demo if sim is not None else None
    if not present(phase_demo) or not phase_demo.curves:
        return None
    demo = phase_demo.curves
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(HALF_HEIGHT_IN, HALF_WIDTH_IN)
        palette = ["#b91c1c", "#d9730d", "#1f5fa8", "#15803d", "#7c3aed"]
        drawn = 0
        for i, run in enumerate(demo):
            t, y, _, _ = series_of(run)
            if t is None or y is None or len(t) != len(y) or not positive(y):
                continue
            p = finite(run.arrival_probability)
            label = run.side or ""
            text = f"p = {p:.4g}" if p is not None else "p = ?"
            if run.mean_is_lower_bound:
                label = (label + ", " if label else "") + "paths diverged: a lower bound"
            ax.plot(t, y, color=palette[i % len(palette)], linewidth=1.2,
                    label=f"{text} ({label})" if label else text)
            drawn += 1
        if not drawn:
            return None
        ax.set_yscale("log")
        plain_log_labels(ax, "y")
        ax.set_xlabel("time step t")
        ax.set_ylabel("mean tr $P_t$ over paths")
        fig.legend(loc="outside lower center", frameon=False, ncols=2)
        return fig


SimulatedRun = SimulationOperatingPoint | PhaseDemoCurve
"""A simulated run with a mean trace over time: the operating point's, or a phase-demo curve."""


def series_of(run: SimulatedRun) -> tuple[Any, Any, Any, Any]:
    """(times, mean, band lower end, band upper end) of a simulated run.

    The operating-point run has ``times`` and ``mean_trace = {mean, lower, upper}``; a curve of
    ``phase_demo`` has ``times``, ``mean_trace`` (a list) and ``lower``/``upper`` beside it.
    """
    t = floats(run.times)
    mt = run.mean_trace
    if mean_diverges(run):
        # E[tr P_t] does not exist: the record keeps only the sample mean over the paths, which
        # is drawn as what it is (no confidence band: it estimates nothing).
        smt = run.sample_mean_trace if isinstance(run, SimulationOperatingPoint) else None
        return t, floats(smt.mean) if present(smt) else None, None, None
    if isinstance(mt, MeanTraceStatistics):
        return t, floats(mt.mean), floats(mt.lower), floats(mt.upper)
    return t, floats(mt), floats(run.lower), floats(run.upper)


def mean_diverges(run: SimulatedRun | None) -> bool:
    """Whether the record says E[tr P_t] diverges at this run (``mean_trace.diverges``; False
    without a run)."""
    mt = run.mean_trace if run is not None else None
    return isinstance(mt, MeanTraceStatistics) and bool(mt.diverges)


def operating_of(rec: AnalysisRecord) -> SimulationOperatingPoint | None:
    """``simulation.operating_point`` (``None`` without a simulation or an operating point)."""
    sim = rec.simulation
    op = sim.operating_point if sim is not None else None
    return op if present(op) else None


def cdf_of(rec: AnalysisRecord) -> tuple[Any, Any]:
    """(trace, probability) of the empirical CDF of tr P at the operating point
    (``simulation.operating_point.horizon.cdf``)."""
    op = operating_of(rec)
    if op is None:
        return None, None
    cdf = op.horizon.cdf
    return floats(cdf.trace), floats(cdf.probability)


def tail_of(rec: AnalysisRecord) -> float | None:
    """Simulated P(tr P > limit) at the operating point
    (``simulation.operating_point.exceedance.estimate``)."""
    op = operating_of(rec)
    if op is None or op.exceedance is None:
        return None
    return finite(op.exceedance.estimate)


def draw_operating(rec: AnalysisRecord) -> Figure | None:
    """Mean tr P_t at the operating point (with its band) against tr S̄ and tr V̄."""
    op = operating_of(rec)
    if op is None:
        return None
    t, y, lo, hi = series_of(op)
    if t is None or y is None or len(t) != len(y) or not positive(y):
        return None
    cb = rec.covariance_bounds
    s_tr = finite(cb.lower.trace) if cb is not None else None
    v_tr = finite(cb.upper.trace) if cb is not None else None
    shown = [v for v in list(y) + [s_tr or 0.0, v_tr or 0.0] if math.isfinite(v) and v > 0]
    floor = 0.5 * min(shown)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(HALF_HEIGHT_IN, HALF_WIDTH_IN)
        label = ("sample mean of tr $P_t$ (E[tr $P_t$] diverges)" if mean_diverges(op)
                 else "simulated mean tr $P_t$")
        draw_mean_band(ax, t, y, lo, hi, floor=floor, mean_label=label)
        if s_tr is not None and s_tr > 0:
            ax.axhline(s_tr, color=COLORS["lower"], linestyle="--", linewidth=1.2,
                       label=r"tr $\bar S$")
        if v_tr is not None and v_tr > 0:
            ax.axhline(v_tr, color=COLORS["upper"], linestyle="--", linewidth=1.2,
                       label=r"tr $\bar V$")
        ax.set_yscale("log")
        # headroom above the highest curve, so that the settled mean and tr V̄ are read
        # against a labelled tick rather than against the frame
        top = 2.5 * max(shown)
        ax.set_ylim(floor, top if math.isfinite(top) else max(shown))
        plain_log_labels(ax, "y")
        ax.set_xlabel("time step t")
        ax.set_ylabel("tr $P_t$")
        fig.legend(loc="outside lower center", frameon=False, ncols=2)
        return fig


def cdf_window(x: Sequence[float], limit: float | None) -> tuple[float, float] | None:
    """The x range of the CDF figure: from below the smallest trace to past both the largest
    trace and the requirement's limit (so the paths beyond the limit are visible)."""
    present = [v for v in x if math.isfinite(v) and v > 0]
    if limit is not None and limit > 0:
        present.append(limit)
    if not present:
        return None
    return min(present) / 1.15, max(present) * 1.6


def draw_cdf(rec: AnalysisRecord) -> Figure | None:
    """Empirical CDF of tr P at the operating point, with the requirement's limit if given."""
    x, f = cdf_of(rec)
    if x is None or f is None or len(x) != len(f) or not positive(x):
        return None
    limit = finite(rec.requirements.max_error_trace) if rec.requirements is not None else None
    tail = tail_of(rec)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure()
        draw_ecdf(ax, x, f)
        if limit is not None and limit > 0:
            text = f"limit M = {limit:.4g}"
            if tail is not None:
                text += f"; P(tr P > M) = {tail:.3g}"
            ax.axvline(limit, color=COLORS["p_c"], linestyle="--", linewidth=1.1, label=text)
        ax.set_xscale("log")
        window = cdf_window(x, limit)
        if window is not None:
            left, right = window
            ax.set_xlim(left, right)
            if math.isfinite(x[-1]) and math.isfinite(f[-1]) and x[-1] < right:
                ax.plot([x[-1], right], [f[-1], f[-1]], color=COLORS["sim"], linewidth=1.3)
        plain_log_labels(ax, "x")
        ax.set_xlabel("tr P at the simulation horizon")
        ax.set_ylabel("P(tr P ≤ x)")
        # Below the axes, as in the other figures: it can never cover the curve or the limit.
        fig.legend(loc="outside lower center", frameon=False, ncols=2)
        return fig


def invariant_gaps(inv: Invariant) -> list[list[float]]:
    """Empty intervals of the invariant support: ``holes`` (pairs), ``gap_levels``
    [{lower, upper}] and ``support_points.largest_gaps`` (pairs), sorted.

    Intervals found twice (an exact hole and its numerical estimate from finitely many support
    points share the upper end) are kept once, as the narrower one: the numerical estimate
    starts at the largest support point found, below the true end of the support piece.
    """
    raw: list[Any] = list(inv.holes or [])
    raw += [[g.lower, g.upper] for g in inv.gap_levels or []]
    raw += list(inv.support_points.largest_gaps or [])
    pairs = sorted({(float(g[0]), float(g[1])) for g in raw
                    if isinstance(g, (list, tuple)) and len(g) == 2
                    and finite(g[0]) is not None and finite(g[1]) is not None
                    and g[1] > g[0]})
    by_upper: dict[float, tuple[float, float]] = {}
    for lo, hi in pairs:
        key = round(hi, 9)
        if key not in by_upper or lo > by_upper[key][0]:
            by_upper[key] = (lo, hi)
    return [list(g) for g in sorted(by_upper.values())]


def draw_invariant(rec: AnalysisRecord) -> Figure | None:
    """Support of the invariant distribution of a scalar system: the support from P* on, with
    its empty intervals cut out."""
    inv = rec.invariant
    if inv is None:
        return None
    gaps = invariant_gaps(inv)
    fixed = finite(inv.fixed_point.value)
    if not gaps:
        return None
    ends = [v for g in gaps for v in g]
    left = fixed if fixed is not None and fixed > 0 else min(ends)
    right = max(ends) * 1.15
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(height=1.55)
        ax.axvspan(left, right, ymin=0.25, ymax=0.75, color=COLORS["lower"], alpha=0.75,
                   linewidth=0, label="no gap found (support lies here)")
        for i, (a, b) in enumerate(gaps):
            ax.axvspan(float(a), float(b), ymin=0.2, ymax=0.8, color="#fde7cf", linewidth=0,
                       label="empty interval (no mass)" if i == 0 else None)
        if fixed is not None:
            ax.axvline(fixed, color=COLORS["p_c"], linewidth=1.4,
                       label=f"P* = {fixed:.4g} (Riccati fixed point)")
        ax.set_xscale("log")
        ax.set_xlim(left / 1.08, right)
        plain_log_labels(ax, "x")
        ax.set_ylim(0, 1)
        ax.set_yticks([])
        ax.grid(False, axis="y")
        ax.spines["left"].set_visible(False)
        ax.set_xlabel("P (scalar error covariance)")
        fig.legend(loc="outside lower center", frameon=False, ncols=3)
        return fig


def draw_almost_sure(rec: AnalysisRecord) -> Figure | None:
    """Block maxima and minima of tr P_t over dyadic time blocks of one long path (theory §6)."""
    op = operating_of(rec)
    if op is None:
        return None
    blk = op.almost_sure
    start = floats(blk.block_start)
    bmax = floats(blk.block_max)
    bmin = floats(blk.block_min)
    if start is None or bmax is None or len(start) != len(bmax) or not positive(bmax):
        return None
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(height=2.4)
        ax.plot(start, bmax, marker="^", markersize=3.5, color=COLORS["p_c"], linewidth=1.2,
                label="max of tr $P_t$ over the block")
        if bmin is not None and len(bmin) == len(start) and positive(bmin):
            ax.plot(start, bmin, marker="v", markersize=3.5, color=COLORS["lower"],
                    linewidth=1.2, label="min of tr $P_t$ over the block")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        plain_log_labels(ax, "y")
        ax.set_xlabel("block start $2^k$ (time step)")
        ax.set_ylabel("tr $P_t$")
        fig.legend(loc="outside lower center", frameon=False, ncols=2)
        return fig


DRAWERS: dict[str, Callable[[AnalysisRecord], Figure | None]] = {
    "phase_transition": draw_phase_transition, "traces": draw_traces,
    "operating": draw_operating, "cdf": draw_cdf, "almost_sure": draw_almost_sure,
    "invariant": draw_invariant, "network_region": draw_network_region,
    "network_map": draw_network_map, "critical_curve": draw_critical_curve,
    "accuracy": draw_accuracy, "arrival_distance": draw_arrival_distance,
    "per_sinr": draw_per_sinr, "outage_distance": draw_outage_distance,
    "mesh_topology": draw_mesh_topology,
    "loop_plane": draw_loop_plane, "loop_cost": draw_loop_cost,
    "burst_histogram": draw_burst_histogram,
    "fit_region": draw_fit_region}
LABELS = {
    "phase_transition": "Phase transition: trace of the lower and upper covariance bounds "
                        "against the arrival probability",
    "traces": "Simulated mean error covariance trace below and above the critical value",
    "operating": "Simulated mean error covariance trace at the operating point against the "
                 "covariance bounds",
    "cdf": "Distribution of the error covariance trace at the operating point",
    "almost_sure": "Block maxima and minima of the error covariance trace along one path",
    "invariant": "Support of the invariant distribution",
    "network_region": "Stability region of the two weakest links with the operating point",
    "network_map": "Map of the sensor nodes coloured by link margin",
    "critical_curve": "Critical curve of the bursty link in the failure-rate, recovery-rate "
                      "plane",
    "accuracy": "Covariance bounds against the arrival probability with the accuracy "
                "requirement",
    "arrival_distance": "Arrival probability against distance",
    "per_sinr": "Packet error rate against SINR",
    "outage_distance": "Shadowing outage against distance",
    "mesh_topology": "Mesh topology: nodes, routes and hops coloured by their success",
    "loop_plane": "Closed loop: stable regions in the sensing, actuation arrival-probability "
                  "plane with the operating point",
    "loop_cost": "Closed loop: average cost against each link's arrival probability",
    "burst_histogram": "Loss-burst lengths of the measured trace against the fitted geometric "
                       "law",
    "fit_region": "Confidence region of the trace fit in the failure-rate, recovery-rate plane "
                  "with the stability boundary"}
# Figures printed as PNG (see :func:`build_figures`): all of them, since WeasyPrint's SVG painter
# costs more per figure than the rest of a page's layout.
DENSE = frozenset(FIGURE_KEYS)
PRINT_DPI = 170
MALFORMED = (TypeError, ValueError, KeyError, IndexError, OverflowError)


def _draw(rec: AnalysisRecord, name: str) -> Figure | None:
    """The drawer's figure, or ``None`` when the record lacks the data or it is malformed."""
    try:
        return DRAWERS[name](rec)
    except MALFORMED:
        return None


def figure(rec: AnalysisRecord, name: str) -> Figure:
    """One report figure as a matplotlib :class:`~matplotlib.figure.Figure` (for notebooks).

    Parameters
    ----------
    rec : AnalysisRecord
        The typed analysis record (:func:`kfcrit.analyze`).
    name : str
        One of :data:`FIGURE_KEYS`; :func:`figure_names` lists those the record has data for.

    Raises
    ------
    KeyError
        ``name`` is not a figure of the report.
    ValueError
        The record has no data for this figure (e.g. no simulation, or not a scalar system).
    """
    if name not in DRAWERS:
        raise KeyError(f"unknown figure {name!r}; the figures are {', '.join(FIGURE_KEYS)}")
    fig = _draw(rec, name)
    if fig is None:
        raise ValueError(f"figure {name!r}: the record has no data for it")
    return fig


def figure_names(rec: AnalysisRecord) -> list[str]:
    """Names of the figures that :func:`figure` can draw from this record, in report order."""
    return [name for name in FIGURE_KEYS if _draw(rec, name) is not None]


def _to_png_img(fig: Figure, label: str) -> str:
    """An ``<img>`` element holding the figure as a PNG data URI (``label`` as its alt text)."""
    buf = io.BytesIO()
    with matplotlib.rc_context(FIG_RC):
        fig.savefig(buf, format="png", dpi=PRINT_DPI, bbox_inches="tight", pad_inches=0.04,
                    metadata={"Software": None})
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return (f'<img class="figure-img" alt="{html.escape(label)}" '
            f'src="data:image/png;base64,{data}">')


def draw_figures(rec: AnalysisRecord) -> dict[str, Figure | None]:
    """Every report figure as a matplotlib Figure (``None`` where the record lacks the data)."""
    return {key: _draw(rec, key) for key in FIGURE_KEYS}


def figure_markup(drawn: dict[str, Figure | None], medium: str = "screen") -> dict[str, str | None]:
    """HTML markup of drawn figures: inline SVG on screen; in print (``medium="print"``) the
    figures of :data:`DENSE` as PNG data URIs at :data:`PRINT_DPI` (WeasyPrint's layout and
    painting time grows with the number of SVG elements; a PNG prints as sharply on paper)."""
    out: dict[str, str | None] = {}
    for key, fig in drawn.items():
        if fig is None:
            out[key] = None
        elif medium == "print" and key in DENSE:
            out[key] = _to_png_img(fig, LABELS[key])
        else:
            out[key] = _to_svg(fig, LABELS[key])
    return out


def build_figures(rec: AnalysisRecord, medium: str = "screen") -> dict[str, str | None]:
    """Every report figure as HTML markup (``None`` where the record lacks the data).

    ``medium`` is ``"screen"`` (inline SVG) or ``"print"`` (see :func:`figure_markup`). A
    malformed section (wrong types or lengths) gives ``None`` rather than an exception: a report
    with one figure missing is more useful to a reviewer than no report.
    """
    return figure_markup(draw_figures(rec), medium)
