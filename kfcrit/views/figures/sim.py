"""Figures of a simulation: E[tr P_t] with its 95 % band and sample paths, the horizon CDF.

Used by ``kfcrit simulate --plot``; the numbers come from a :class:`SimulationResult` only.
"""
from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.atomic import write_atomic
from kfcrit.sim.results import SimulationResult
from kfcrit.sim.stats import quiet_numerics
from kfcrit.views.figures.style import draw_ecdf, draw_mean_band

BAND_FLOOR = 0.1
"""On the log axis the lower band end is floored at this fraction of the smallest positive
mean (a lower end at 0 — a confidence interval reaching 0 — cannot be drawn on a log axis)."""


def plot_series(result: SimulationResult) -> dict[str, Any]:
    """What :func:`write_plot` draws on its left panel, in plot units.

    ``log10`` False: values on a log axis — mean, band with its lower end floored at
    ``BAND_FLOOR`` × the smallest positive mean, traces, and y-limits from these data only.
    ``log10`` True (some value beyond float64): the same in log10 units on a linear axis.
    """
    t = result.times.astype(float)
    mean = result.mean_trace
    lo, hi = result.band()
    traces = result.traces
    finite = bool(np.all(np.isfinite(mean)) and np.all(np.isfinite(hi))
                  and (traces is None or np.all(np.isfinite(traces))))
    if finite:
        pos = mean[mean > 0]
        floor = BAND_FLOOR * float(pos.min()) if pos.size else 1.0
        y, y_lo, y_hi = mean.astype(float), np.maximum(lo, floor), np.maximum(hi, floor)
        tr = None if traces is None else np.where(traces > 0, traces, np.nan)
        data = [y[y > 0], y_lo, y_hi] + ([] if tr is None else [tr[np.isfinite(tr)]])
        bottom = min(float(np.min(d)) for d in data if d.size)
        top = max(float(np.max(d)) for d in data if d.size)
        bottom, top = bottom / 1.5, top * 1.5
        thr = result.divergence_threshold
    else:
        llo, lhi = result.log10_band()
        y = result.log10_mean_trace if result.log10_mean_trace is not None else np.log10(mean)
        ok = np.isfinite(y)
        low = float(np.min(y[ok])) if ok.any() else 0.0
        floor = low + math.log10(BAND_FLOOR)
        y_lo, y_hi = np.maximum(llo, floor), np.maximum(lhi, floor)
        tr = None
        if traces is not None:
            with quiet_numerics():
                tr = np.where(np.isfinite(traces) & (traces > 0), np.log10(traces), np.nan)
        data = [y[ok], y_lo[np.isfinite(y_lo)], y_hi[np.isfinite(y_hi)]]
        if tr is not None:
            data.append(tr[np.isfinite(tr)])
        bottom = min(float(np.min(d)) for d in data if d.size)
        top = max(float(np.max(d)) for d in data if d.size)
        pad = max(0.05 * (top - bottom), 0.5)
        bottom, top = bottom - pad, top + pad
        thr = math.log10(result.divergence_threshold)
    return {"log10": not finite, "t": t, "mean": y, "lower": y_lo, "upper": y_hi,
            "traces": tr, "ylim": (bottom, top), "threshold": thr, "floor": floor}


def plot_mean(ax: Any, result: SimulationResult) -> None:
    d = plot_series(result)
    if d["traces"] is not None:
        steps = np.arange(result.steps + 1)
        for k, row in enumerate(d["traces"]):
            ax.plot(steps, row, lw=0.6, alpha=0.5, color="0.5",
                    label="sample paths" if k == 0 else None)
    draw_mean_band(ax, d["t"], d["mean"], d["lower"], d["upper"], floor=-math.inf,
                   mean_label="simulated mean tr P_t")
    bottom, top = d["ylim"]
    if result.diverged_paths and bottom < d["threshold"] < top:
        ax.axhline(d["threshold"], ls=":", lw=1, color="#b91c1c",
                   label=f"divergence threshold ({result.diverged_paths} paths crossed)")
    if d["log10"]:
        ax.set_ylabel("log10 tr P_t (values beyond float64)")
    else:
        ax.set_yscale("log")
        ax.set_ylabel("tr P_t")
    ax.set_ylim(bottom, top)
    ax.set_xlim(0, max(result.steps, 1))
    ax.set_xlabel("t")
    ax.set_title(f"p = {result.arrival_probability:.4g}, {result.paths} paths")
    ax.legend(loc="best", fontsize=8)


def plot_cdf(ax: Any, result: SimulationResult) -> None:
    """Empirical CDF of tr P at the horizon over all paths (log10 units if beyond float64)."""
    x = np.sort(result.horizon_traces)
    F = np.arange(1, x.size + 1) / x.size
    if np.all(np.isfinite(x)) and x.size and x[0] > 0:
        draw_ecdf(ax, x, F)
        ax.set_xscale("log")
        ax.set_xlabel(f"tr P at t = {result.steps}")
    else:
        lx = np.sort(result.horizon_log10_traces if result.horizon_log10_traces is not None
                     else np.log10(result.horizon_traces))
        ok = np.isfinite(lx)
        draw_ecdf(ax, lx[ok], F[ok], label="empirical CDF of log10 tr P")
        ax.set_xlabel(f"log10 tr P at t = {result.steps}")
    ax.set_ylabel("CDF")


def write_plot(result: SimulationResult, path: str) -> None:
    """Write E[tr P_t] with its band, a few sample paths and the horizon CDF (SVG/PNG, atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    target = Path(path)
    folder = target.resolve().parent
    if not folder.is_dir():
        raise InputError(f"folder {str(folder)[:80]!r} does not exist", field="--plot")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    try:
        plot_mean(ax1, result)
        plot_cdf(ax2, result)
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format=target.suffix.lower().lstrip("."))
        write_atomic(target, buffer.getvalue())
    finally:
        plt.close(fig)
