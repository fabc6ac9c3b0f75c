"""Shared look of the report figures: colours, rc settings, sizes and the small readers and
axis helpers every drawing module uses (record values to floats, plain tick labels).

Nothing here computes a result: the readers turn record values into floats (``None`` → NaN,
a gap in a line) and the helpers format axes.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402 - after choosing the backend

from kfcrit.io.typed import ABSENT  # noqa: E402
from kfcrit.views import formatting as jinja_filters  # noqa: E402

COLORS = {"lower": "#1f5fa8", "upper": "#d9730d", "p_low": "#6b7280", "p_c": "#b91c1c",
          "p_up": "#7c3aed", "operating": "#15803d", "sim": "#111827", "band": "#9ca3af"}
FIG_RC = {"font.size": 8.5, "axes.titlesize": 9, "axes.labelsize": 8.5, "legend.fontsize": 7.5,
          "xtick.labelsize": 7.5, "ytick.labelsize": 7.5, "svg.fonttype": "path",
          "svg.hashsalt": "kfcrit", "axes.spines.top": False, "axes.spines.right": False,
          "axes.grid": True, "grid.color": "#e5e7eb", "grid.linewidth": 0.6,
          "mathtext.fontset": "dejavuserif"}
# Full-width figures: the A4 text width (182 mm) at the height they print at (print CSS caps a
# figure at 58 mm), so that their text prints at about its nominal size.
WIDTH_IN = 7.0
HEIGHT_IN = 2.6
# Figures printed side by side (two per row of the A4 text width, 182 mm) are drawn at the size
# they print at, so that their text keeps the size of the full-width figures' text.
HALF_WIDTH_IN = 3.45
HALF_HEIGHT_IN = 2.55
PRINT_WIDTH_MM = 182.0
PRINT_MAX_HEIGHT_MM = 58.0
"""The A4 text width and the print CSS's cap on a figure's height (templates/report.css)."""
MIN_PRINT_PT = 7.0
"""Smallest text size a printed figure may show."""


def print_scale(width_in: float, height_in: float) -> float:
    r"""Factor by which a full-width figure of ``width_in`` × ``height_in`` inches prints.

    .. math:: s = \min(1, W / w, H_{max} / h)

    with W the text width and H_max the print CSS's height cap (both in inches).
    """
    return min(1.0, PRINT_WIDTH_MM / 25.4 / width_in, PRINT_MAX_HEIGHT_MM / 25.4 / height_in)


def readable_rc(width_in: float = WIDTH_IN, height_in: float = HEIGHT_IN) -> dict[str, Any]:
    """:data:`FIG_RC` with every text size raised so that it prints at ≥ :data:`MIN_PRINT_PT`
    once the figure is scaled by :func:`print_scale`."""
    least = math.ceil(2 * MIN_PRINT_PT / print_scale(width_in, height_in)) / 2
    rc = dict(FIG_RC)
    for key in ("font.size", "axes.titlesize", "axes.labelsize", "legend.fontsize",
                "xtick.labelsize", "ytick.labelsize"):
        rc[key] = max(float(rc[key]), least)
    return rc


def floats(values: Any) -> list[float] | None:
    """A list of floats (``None`` entries become NaN); ``None`` if ``values`` is not a list."""
    if not isinstance(values, (list, tuple)) or not values:
        return None
    out = []
    for v in values:
        if v is None:
            out.append(math.nan)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(float(v))
        else:
            return None
    return out


def finite(v: Any) -> float | None:
    """A finite float or ``None``."""
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        return float(v)
    return None


def present(value: Any) -> bool:
    """Whether a typed record field holds a value: not ``None`` and not an absent optional key
    (:data:`kfcrit.io.typed.ABSENT`)."""
    return value is not None and value is not ABSENT


def positive(values: Sequence[float]) -> bool:
    """True when at least one value is finite and positive (something to draw on a log axis)."""
    return any(math.isfinite(v) and v > 0 for v in values)


def new_figure(height: float = HEIGHT_IN, width: float = WIDTH_IN) -> tuple[Figure, Any]:
    """A figure with one axes, ``width`` × ``height`` inches, constrained layout."""
    fig = Figure(figsize=(width, height), layout="constrained")
    return fig, fig.add_subplot()


def mark(ax: Any, x: float | None, key: str, label: str, style: str = "--") -> None:
    if x is not None:
        ax.axvline(x, color=COLORS[key], linestyle=style, linewidth=1.1, label=label)


SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def decade_label(value: float, _pos: Any = None) -> str:
    """``10⁵`` for a power of ten (plain text with superscript digits: no mathtext to parse)."""
    if value <= 0 or not math.isfinite(value):
        return ""
    exp = math.log10(value)
    if abs(exp - round(exp)) > 1e-9:
        return ""
    k = int(round(exp))
    return {0: "1", 1: "10"}.get(k, "10" + str(k).translate(SUPERSCRIPT))


def plain_label(value: float) -> str:
    """A tick value as plain text: ``0.6``, ``2``, ``20``, ``300`` (typographic minus sign)."""
    if value == 0 or not math.isfinite(value):
        return ""
    text = f"{value:.3g}"
    if "e" in text:   # outside the plain range: the decade form
        return decade_label(value)
    return text.replace("-", "−")


def plain_log_labels(ax: Any, which: str = "x") -> None:
    """Readable tick labels on a log axis, set as plain text (no mathtext: faster, same look).

    Few decades: 0.6, 2, 5, 20, 100 (plain numbers, never ``6e−01``); wide or large ranges:
    1, 10, 10², 10³ on the decades only.
    """
    from matplotlib import ticker

    lo, hi = ax.get_xlim() if which == "x" else ax.get_ylim()
    axis = ax.xaxis if which == "x" else ax.yaxis
    if lo <= 0 or hi <= 0 or hi / lo > 1e4 or hi >= 1e5 or lo < 1e-3:
        axis.set_major_formatter(ticker.FuncFormatter(decade_label))
        axis.set_minor_formatter(ticker.NullFormatter())
        return
    decades = math.log10(hi / lo)
    # Minor ticks sit at m·10^k, m = 2..9: label all of them over half a decade or less, the
    # 2s and 5s up to 2 decades, none beyond.
    mantissas = set(range(2, 10)) if decades <= 0.5 else {2, 5} if decades <= 2 else set()

    def minor(value: float, _pos: Any = None) -> str:
        if value <= 0:
            return ""
        mant = value / 10 ** math.floor(math.log10(value) + 1e-9)
        return plain_label(value) if round(mant) in mantissas and \
            abs(mant - round(mant)) < 1e-6 else ""

    axis.set_major_formatter(ticker.FuncFormatter(lambda v, _p=None: plain_label(v)))
    axis.set_minor_formatter(ticker.FuncFormatter(minor))


def fmt(value: float | None) -> str:
    """A probability-like value with 4 significant digits, typographic minus (``?`` if None)."""
    return "?" if value is None else f"{value:.4g}".replace("-", "−")


def legend_quantity(value: float, unit: str) -> str:
    r"""``value`` with its unit exactly as the report's tables print it
    (:func:`kfcrit.views.formatting.unit`: ``0.13 dB``, ``−1.48 dB``, ``80.2 m``), except
    that a negative value rounded to zero prints without its sign in a legend."""
    text = jinja_filters.unit(value, unit)
    number = text.split(" ", 1)[0]
    return text[1:] if number.startswith("−") and number.strip("−0.") == "" else text


def percent(value: float) -> str:
    """A probability as a percentage, as the tables print it: ``0.1`` → ``10 %``."""
    return jinja_filters.pct(value)


def arrival_formula(max_retries: int) -> str:
    r"""The arrival probability of one packet with ``k`` MAC retries, in plain text.

    .. math:: p = 1 - \mathrm{PER}^{k+1}

    (``1 − PER`` without retries; the exponent as Unicode superscripts otherwise).
    """
    if max_retries <= 0:
        return "p = 1 − PER"
    return "p = 1 − PER" + str(max_retries + 1).translate(SUPERSCRIPT)


def draw_mean_band(ax: Any, t: Sequence[float], mean: Sequence[float],
                   lower: Sequence[float] | None, upper: Sequence[float] | None, *,
                   floor: float, mean_label: str,
                   band_label: str = "95 % band of the simulated mean") -> None:
    r"""The simulated mean :math:`\overline{\operatorname{tr} P_t}` and its 95 % band — the one
    drawing of this plot, for the report and for ``kfcrit simulate --plot``.

    A lower band end at or below ``floor`` (zero, or below the axis) is drawn at ``floor``: on a
    log axis the band then extends below the plot.
    """
    if lower is not None and upper is not None and len(lower) == len(t) == len(upper):
        lo = [max(v, floor) if math.isfinite(v) else v for v in lower]
        ax.fill_between(t, lo, upper, color=COLORS["band"], alpha=0.35, linewidth=0,
                        label=band_label)
    ax.plot(t, mean, color=COLORS["sim"], linewidth=1.3, label=mean_label)


def draw_ecdf(ax: Any, x: Sequence[float], f: Sequence[float], *,
              label: str = "empirical CDF of tr P") -> None:
    r"""The empirical CDF :math:`\hat F(x) = \#\{k : \operatorname{tr} P^{(k)} \le x\} / N` of
    the horizon traces as a right-continuous step — the one drawing of this plot, for the report
    and for ``kfcrit simulate --plot``."""
    ax.step(x, f, where="post", color=COLORS["sim"], linewidth=1.3, label=label)
    ax.set_ylim(0, 1.02)
