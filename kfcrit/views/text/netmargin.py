"""Text of a sensor network's margins and bracketed values (theory §9), shared by the terminal
view and the report so that both render the record's numbers the same way.

Pure functions of the typed ``network`` section's rows; no plotting imports (the terminal view
uses them).
"""
from __future__ import annotations

import math
from typing import Any

from kfcrit.io.typed import ABSENT
from kfcrit.records.network import NetworkBottleneck, NetworkSensor
from kfcrit.views import formatting as filters

NETWORK_P_MEANING = ("1 − Π(1 − p_i), the probability that at least one sensor's packet "
                     "arrives (S̄ takes the filter as only predicting when every packet is lost)")
"""The ``p`` of a network's covariance bounds (``covariance_bounds.reason``: S̄ solves
S = Π(1 − p_i) A S A' + Q)."""

SAME = 1e-12
"""Ends of an interval closer than this are shown as one number."""


def _finite(v: Any) -> float | None:
    """A finite real number, else ``None`` (booleans are not numbers here)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(v) else None


def margin_range(value: float | None, interval: list[float | None] | None
                 ) -> tuple[float | None, float | None]:
    """(conservative, optimistic) ends of a margin given as a value or an interval: the value
    (both ends) when it is finite, else the interval's ends (``None`` where unknown)."""
    v = _finite(value)
    if v is not None:
        return v, v
    if isinstance(interval, (list, tuple)) and len(interval) == 2:
        return _finite(interval[0]), _finite(interval[1])
    return None, None


def sensor_margin_bounds(sensor: NetworkSensor) -> tuple[float | None, float | None]:
    r"""(conservative, optimistic) ends of a sensor's margin

    .. math:: p_i - p_{c,i} \in [p_i - p_{c,i}^{\mathrm{suf}},\; p_i - p_{c,i}^{\mathrm{nec}}]

    ``margin.value`` (both ends) when the critical value is known, else ``margin.interval``.
    """
    return margin_range(sensor.margin.value, sensor.margin.interval)


def signed_range_text(low: float | None, high: float | None) -> str:
    """A margin with its sign: one number, or ``[+a, +b]`` for two distinct ends (— when the
    conservative end is unknown)."""
    if low is None:
        return "—"
    if high is None or abs(high - low) < SAME:
        return filters.signed(low, 4)
    return f"[{filters.signed(low, 4)}, {filters.signed(high, 4)}]"


def margin_text(sensor: NetworkSensor) -> str:
    """The margin p_i − p_c,i with its sign: one number, or ``[+a, +b]`` when p_c,i is only
    bracketed (— when the record has neither)."""
    if has_no_critical_value(sensor):
        return "none"
    return signed_range_text(*sensor_margin_bounds(sensor))


def _real(v: Any) -> float | None:
    """A real number, infinite ones included (shown as ∞), else ``None``."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return v


def margin_value_text(value: Any, interval: Any, digits: int = 6) -> str:
    """A number, or an interval [a, b] when only bounds are known (— when neither)."""
    v = _real(value)
    if v is not None:
        return filters.num(v, digits)
    iv = interval if isinstance(interval, (list, tuple)) else []
    if len(iv) == 2 and _real(iv[0]) is not None and _real(iv[1]) is not None:
        if abs(iv[1] - iv[0]) < SAME:
            return filters.num(iv[0], digits)
        return filters.interval(list(iv), digits)
    return "—"


NO_CRITICAL_VALUE = "none (no p_i suffices)"
"""A sensor's critical value when the record has neither a value nor an interval: a necessary
constraint without that sensor fails, whatever its link does."""


def has_no_critical_value(sensor: NetworkSensor) -> bool:
    """Whether the record states that no arrival probability of this sensor gives mean
    stability (``critical_value`` with neither value nor interval)."""
    cv = sensor.critical_value
    # exact False with neither: undecided at float precision, not "none"
    return _real(cv.value) is None and cv.interval is None and cv.exact is True


def bottleneck_margin_text(bottleneck: NetworkBottleneck) -> str:
    """The bottleneck's margin (``network.bottleneck.margin`` or ``margin_interval``), signed
    like the sensor rows (:func:`margin_text`)."""
    interval = bottleneck.margin_interval or None   # an absent key: no interval
    return signed_range_text(*margin_range(bottleneck.margin, interval))


def burst_margin_of(rec: Any, net: Any) -> bool:
    """Whether the network's margin is a recovery-rate margin r − r_nec: one sensor on a
    Markov (bursty) link, analysed as that link (theory §10), not a uniform δ on arrival
    probabilities."""
    op = rec.operating_point
    return len(net.sensors) == 1 and op is not None and \
        op.recovery_threshold not in (None, ABSENT)
