"""The sweep's margin figure: margin p − p_req (and the link margin in dB) against one parameter."""
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


def margin_figure(rows: Sequence[dict[str, Any]], parameters: Sequence[str], x_name: str) -> Any:
    """A matplotlib figure of the sweep: every numeric point of every series is drawn.

    Top: the margin p − p_req (zero line: the stability requirement); bottom, for link budgets:
    the link margin in dB with the policy line (the margin the policy requires) and, per series,
    the largest distance the policy allows when the x axis is the distance. Points are marked by
    their review decision (filled: pass; cross: fail; open: undetermined).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    others = [p for p in parameters if p != x_name]
    series: dict[tuple, list[dict]] = {}
    for row in rows:
        series.setdefault(tuple(row.get(p) for p in others), []).append(row)
    has_db = any(r.get("link_margin_db") is not None for r in rows)
    fig, axes = plt.subplots(2 if has_db else 1, 1, figsize=(6.4, 6.4 if has_db else 3.8),
                             sharex=True, squeeze=False)
    markers = {"pass": "o", "fail": "x", "undetermined": "s"}
    for label_key, group in list(series.items())[:MAX_SERIES]:
        group = sorted((r for r in group if _is_number(r.get(x_name))), key=lambda r: r[x_name])
        label = ", ".join(f"{axis_label(p)} = {v:g}" if _is_number(v) else f"{p} = {v}"
                          for p, v in zip(others, label_key)) or None
        for ax, col in zip(axes[:, 0], ("margin", "link_margin_db")):
            pts = [(r[x_name], r[col], r.get("decision")) for r in group
                   if r.get(col) is not None]
            if not pts:
                continue
            (line,) = ax.plot([p[0] for p in pts], [p[1] for p in pts], linewidth=1,
                              label=label)
            for decision, marker in markers.items():
                sel = [(x, y) for x, y, d in pts if d == decision]
                if sel:
                    ax.plot(*zip(*sel), linestyle="none", marker=marker, markersize=4,
                            color=line.get_color(),
                            markerfacecolor=line.get_color() if decision == "pass" else "none")
        if has_db and x_name == "channel.distance_m":
            dmax = next((r.get("max_distance_m") for r in group
                         if r.get("max_distance_m") is not None), None)
            if dmax is not None:
                axes[1, 0].axvline(dmax, color="0.5", linestyle=":", linewidth=0.8)
    axes[0, 0].axhline(0.0, color="0.3", linewidth=0.8)
    axes[0, 0].set_ylabel("margin p − p_req")
    if has_db:
        needed = next((r.get("required_margin_db") for r in rows
                       if r.get("required_margin_db") is not None), None)
        axes[1, 0].axhline(needed if needed is not None else 0.0, color="C3", linewidth=0.8,
                           linestyle="--", label="policy margin")
        axes[1, 0].set_ylabel("link margin (dB)")
    for ax in axes[:, 0]:
        ax.grid(True, linewidth=0.3)
    axes[-1, 0].set_xlabel(axis_label(x_name))
    if axes[0, 0].get_legend_handles_labels()[0] and (len(series) > 1):
        axes[0, 0].legend(fontsize=7)
    if len(series) > MAX_SERIES:
        axes[0, 0].set_title(f"first {MAX_SERIES} of {len(series)} series", fontsize=8)
    fig.tight_layout()
    return fig


def margin_images(rows: Sequence[dict[str, Any]], parameters: Sequence[str],
                  x_name: str) -> dict[str, bytes]:
    """SVG and PNG bytes of :func:`margin_figure` (SVG without a date: reproducible)."""
    import matplotlib.pyplot as plt

    with plt.rc_context({"svg.hashsalt": "kfcrit", "font.size": 9}):
        fig = margin_figure(rows, parameters, x_name)
        out = {}
        for fmt in ("svg", "png"):
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg" else None,
                        dpi=120)
            out[fmt] = buf.getvalue()
        plt.close(fig)
    return out
