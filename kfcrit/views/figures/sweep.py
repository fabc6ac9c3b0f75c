"""The sweep's margin figure: the arrival-probability margin p − p_req (and the link margin in
dB) against one parameter."""
from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

MAX_SERIES = 12
"""Most series (combinations of the other parameters) drawn in one figure."""

AXIS_LABELS = {
    "channel.distance_m": "distance (m)",
    "channel.tx_power_dbm": "transmit power (dBm)",
    "channel.packet_bytes": "payload (bytes)",
    "channel.arrival_probability": "arrival probability p",
    "channel.failure_rate": "failure rate f",
    "channel.recovery_rate": "recovery rate r",
    "channel.max_retries": "MAC retries",
    "channel.margin_db": "required link margin (dB)",
    "channel.path_loss.exponent": "path-loss exponent",
    "channel.path_loss.shadowing_sigma_db": "shadowing σ (dB)",
    "channel.noise.bandwidth_hz": "noise bandwidth (Hz)",
    "channel.noise.noise_figure_db": "noise figure (dB)",
    "channel.noise.interference_dbm": "interference (dBm)",
}


def axis_label(parameter: str) -> str:
    """Words and units for a swept parameter (the path itself when it has no known label)."""
    if parameter in AXIS_LABELS:
        return AXIS_LABELS[parameter]
    leaf = parameter.rsplit(".", 1)[-1]
    for suffix, unit in (("_m", "m"), ("_dbm", "dBm"), ("_db", "dB"), ("_hz", "Hz"), ("_s", "s")):
        if leaf.endswith(suffix):
            return f"{leaf[: -len(suffix)].replace('_', ' ')} ({unit})"
    return parameter


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


MARKERS = {"pass": "o", "fail": "x", "undetermined": "s"}
DECISION_WORDS = {"pass": "pass (filled dot)", "fail": "fail (cross)",
                  "undetermined": "undetermined (open square)"}


def series_label(others: Sequence[str], key: tuple) -> str | None:
    """``payload (bytes) = 20, …`` for one combination of the parameters not on the x axis."""
    return ", ".join(f"{axis_label(p)} = {v:g}" if _is_number(v) else f"{axis_label(p)} = {v}"
                     for p, v in zip(others, key)) or None


def _draw_series(axes: Any, group: list[dict[str, Any]], x_name: str, label: str | None,
                 color: str) -> None:
    """One series on both axes: a line through all its points and a marker at every point by
    its review decision (a point without a known decision: an open square)."""
    for ax, col in zip(axes, ("margin", "link_margin_db")):
        pts = [(float(r[x_name]), float(r[col]), r.get("decision")) for r in group
               if _is_number(r.get(col))]
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], linewidth=1, color=color,
                label=label if col == "margin" else None)
        for decision, marker in MARKERS.items():
            sel = [(x, y) for x, y, d in pts
                   if d == decision or (decision == "undetermined" and d not in MARKERS)]
            if sel:
                ax.plot(*zip(*sel), linestyle="none", marker=marker, markersize=4,
                        color=color, clip_on=False,
                        markerfacecolor=color if decision == "pass" else "none")


def _legend_handles(rows: Sequence[dict[str, Any]], has_db: bool, dmax_drawn: bool
                    ) -> tuple[list[Any], list[str]]:
    """Proxy entries for what the series entries do not explain: the decision markers, the
    zero line, the policy line and the largest-distance lines."""
    from matplotlib.lines import Line2D

    handles, labels = [], []
    present = {r.get("decision") if r.get("decision") in MARKERS else "undetermined"
               for r in rows}
    for decision, marker in MARKERS.items():
        if decision in present:
            handles.append(Line2D([], [], linestyle="none", marker=marker, markersize=4,
                                  color="0.2",
                                  markerfacecolor="0.2" if decision == "pass" else "none"))
            labels.append(f"review: {DECISION_WORDS[decision]}")
    handles.append(Line2D([], [], color="0.3", linewidth=0.8))
    labels.append("zero margin: p equals the required p")
    if has_db:
        handles.append(Line2D([], [], color="C3", linewidth=0.8, linestyle="--"))
        labels.append("link margin the policy requires")
    if dmax_drawn:
        handles.append(Line2D([], [], color="0.4", linewidth=1.0, linestyle=(0, (1, 1.5))))
        labels.append("largest distance meeting the policy\n(dotted, in its series' colour)")
    return handles, labels


def margin_figure(rows: Sequence[dict[str, Any]], parameters: Sequence[str], x_name: str) -> Any:
    """A matplotlib figure of the sweep: every numeric point of every series is drawn.

    Top: the arrival-probability margin p − p_req (zero line: the stability requirement);
    bottom, for link budgets: the link margin in dB with the policy line (the margin the policy
    requires) and, per series in its colour, the largest distance the policy allows when the x
    axis is the distance. Points are marked by their review decision (filled: pass; cross:
    fail; open: undetermined). The legend sits right of the axes, so it hides no point.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    # matplotlib loads only when drawing
    from kfcrit.views.figures.style import WIDTH_IN

    others = [p for p in parameters if p != x_name]
    series: dict[tuple, list[dict]] = {}
    for row in rows:
        series.setdefault(tuple(row.get(p) for p in others), []).append(row)
    has_db = any(_is_number(r.get("link_margin_db")) for r in rows)
    fig = Figure(figsize=(WIDTH_IN, 5.2 if has_db else 3.0), layout="constrained")
    axes = fig.subplots(2 if has_db else 1, 1, sharex=True, squeeze=False)[:, 0]
    dmax_drawn = False
    for k, (key, group) in enumerate(list(series.items())[:MAX_SERIES]):
        color = f"C{k % 10}"
        group = sorted((r for r in group if _is_number(r.get(x_name))), key=lambda r: r[x_name])
        label = series_label(others, key) or "margin"
        _draw_series(axes, group, x_name, label, color)
        if has_db and x_name == "channel.distance_m":
            dmax = next((r.get("max_distance_m") for r in group
                         if _is_number(r.get("max_distance_m"))), None)
            if dmax is not None:
                axes[1].axvline(dmax, color=color, linestyle=(0, (1, 1.5)), linewidth=1.0)
                dmax_drawn = True
    axes[0].axhline(0.0, color="0.3", linewidth=0.8)
    axes[0].set_ylabel("arrival-probability margin\n(p minus required p)")
    if has_db:
        needed = next((r.get("required_margin_db") for r in rows
                       if _is_number(r.get("required_margin_db"))), None)
        axes[1].axhline(needed if needed is not None else 0.0, color="C3", linewidth=0.8,
                        linestyle="--")
        axes[1].set_ylabel("link margin (dB)")
    for ax in axes:
        ax.grid(True, linewidth=0.3)
        ax.margins(x=0.03, y=0.06)
    axes[-1].set_xlabel(axis_label(x_name))
    handles, labels = axes[0].get_legend_handles_labels()
    extra_h, extra_l = _legend_handles(rows, has_db, dmax_drawn)
    fig.legend(handles + extra_h, labels + extra_l, loc="outside right upper", frameon=False,
               fontsize=7.5)
    if len(series) > MAX_SERIES:
        axes[0].set_title(f"first {MAX_SERIES} of {len(series)} series", fontsize=8)
    return fig


def margin_images(rows: Sequence[dict[str, Any]], parameters: Sequence[str],
                  x_name: str) -> dict[str, bytes]:
    """SVG and PNG bytes of :func:`margin_figure` (SVG without a date: reproducible)."""
    import matplotlib

    with matplotlib.rc_context({"svg.hashsalt": "kfcrit", "font.size": 9}):
        fig = margin_figure(rows, parameters, x_name)
        out = {}
        for fmt in ("svg", "png"):
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg" else None,
                        dpi=120)
            out[fmt] = buf.getvalue()
    return out
