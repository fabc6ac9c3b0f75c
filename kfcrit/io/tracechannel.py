"""The ``trace`` channel of system files: a measured packet log and how to read it (theory §14).

.. code-block:: yaml

    channel:
      model: trace
      path: log.txt                 # relative to the system file
      format: receive-log           # binary (default) | sequence-numbers | receive-log
      period_s: 0.1                 # receive-log: the sampling period T (required)
      start_s: 0                    # receive-log: start of period 0 (default 0)
      periods: 5000                 # receive-log: number of periods (default: inferred)
      sensor: s1                    # receive-log with a sensor column: whose arrivals
      first: 1                      # sequence-numbers: the first and last numbers sent
      last: 5000
      confidence: 0.95              # confidence of the verdict on the fit's region (default)

The file formats are those of :mod:`kfcrit.io.traceformats`; every error names the field and,
for the file's content, the line. Several sensors of one ``sensors:`` file that read the same
receive log get traces of one common length, period k of each being the same sampling period
(time-aligned), which is what keeps their joint law.
"""
from __future__ import annotations

import re
from decimal import Decimal
from pathlib import Path
from typing import Any

from kfcrit.errors import InputError
from kfcrit.io.traceformats import NO_SENSOR, TRACE_FORMATS, read_trace_file
from kfcrit.model.channels import Trace, check_keys

DEFAULT_CONFIDENCE = 0.95
"""Confidence of a trace channel's verdict when the file gives none."""
TRACE_KEYS = {"model", "path", "format", "period_s", "start_s", "periods", "sensor", "first",
              "last", "confidence"}
"""Every key a ``trace`` channel may have."""
FORMAT_KEYS = {"binary": set(), "sequence-numbers": {"first", "last"},
               "receive-log": {"period_s", "start_s", "periods", "sensor"}}
"""The keys each format takes beyond ``model``, ``path``, ``format`` and ``confidence``."""

_DECIMAL = re.compile(r"[+]?(?:[0-9]{1,30}(?:\.[0-9]{0,30})?|\.[0-9]{1,30})(?:[eE][+-]?[0-9]{1,3})?")
_INTEGER = re.compile(r"[+]?[0-9]{1,18}")


def _text(value: Any, field: str) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float, str, Decimal)):
        raise InputError(f"must be a number, got {type(value).__name__}", field=field)
    return value.strip() if isinstance(value, str) else repr(value) \
        if isinstance(value, float) else str(value)


def decimal_value(value: Any, field: str, *, positive: bool = False) -> Decimal:
    """A non-negative (or, with ``positive``, strictly positive) exact decimal from a number or
    its text (``0.1`` is 1/10 exactly, as written)."""
    text = _text(value, field)
    if not _DECIMAL.fullmatch(text):
        raise InputError(f"must be a finite non-negative number, got {text[:40]!r}", field=field)
    d = Decimal(text)
    if positive and d == 0:
        raise InputError("must be > 0", field=field)
    return d


def integer_value(value: Any, field: str) -> int:
    """A non-negative integer from an int or its text."""
    text = _text(value, field)
    if not _INTEGER.fullmatch(text):
        raise InputError(f"must be a non-negative integer, got {text[:40]!r}", field=field)
    return int(text)


def confidence_value(value: Any, field: str) -> float:
    r"""The confidence c of a verdict on a confidence region, strictly inside (0, 1).

    .. math:: 0 < c < 1
    """
    d = decimal_value(value, field)
    if not Decimal(0) < d < Decimal(1):
        raise InputError(f"must be strictly between 0 and 1, got {str(d)[:40]}", field=field)
    return float(d)


def _options(data: dict, fmt: str, prefix: str) -> dict[str, Any]:
    """The reader options of ``fmt`` from the channel mapping (values checked, fields named)."""
    for key in data:
        if key in TRACE_KEYS - {"model", "path", "format", "confidence"} \
                and key not in FORMAT_KEYS[fmt]:
            raise InputError(f"is not used by format {fmt!r} (it takes: "
                             f"{', '.join(sorted(FORMAT_KEYS[fmt])) or 'no options'})",
                             field=f"{prefix}.{key}")
    if fmt == "sequence-numbers":
        return {k: integer_value(data[k], f"{prefix}.{k}") for k in ("first", "last")
                if k in data}
    if fmt != "receive-log":
        return {}
    if "period_s" not in data:
        raise InputError("is required for a receive log (the sampling period in seconds)",
                         field=f"{prefix}.period_s")
    out: dict[str, Any] = {"period": decimal_value(data["period_s"], f"{prefix}.period_s",
                                                   positive=True)}
    if "start_s" in data:
        out["start"] = decimal_value(data["start_s"], f"{prefix}.start_s")
    if "periods" in data:
        out["periods"] = integer_value(data["periods"], f"{prefix}.periods")
    if "sensor" in data:
        sensor = data["sensor"]
        if not isinstance(sensor, (str, int)) or isinstance(sensor, bool) or not str(sensor):
            raise InputError("must be a sensor id (a string)", field=f"{prefix}.sensor")
        out["sensor"] = str(sensor)
    return out


def _one_trace(traces: dict[str, Any], fmt: str, prefix: str) -> tuple[Any, str | None]:
    """The single trace of a reader's result; a log with several sensors needs ``sensor``."""
    if len(traces) == 1:
        key, arr = next(iter(traces.items()))
        return arr, (None if key == NO_SENSOR else key)
    names = ", ".join(sorted(traces)[:8]) + (", …" if len(traces) > 8 else "")
    raise InputError(f"the {fmt} has {len(traces)} sensors ({names}): name one with "
                     f"{prefix}.sensor", field=f"{prefix}.sensor")


def measured_trace_from_mapping(data: dict, prefix: str, base_dir: Path | None = None) -> Trace:
    """A ``trace`` channel from its mapping (see the module docstring); the file is read
    relative to the system file's folder (``base_dir``)."""
    check_keys(data, TRACE_KEYS, {"path"}, prefix)
    raw = data["path"]
    if not isinstance(raw, str) or not raw.strip():
        raise InputError("must be a file path", field=f"{prefix}.path")
    fmt = data.get("format", "binary")
    if fmt not in TRACE_FORMATS:
        raise InputError(f"unknown trace format {str(fmt)[:40]!r} (known: "
                         f"{', '.join(TRACE_FORMATS)})", field=f"{prefix}.format")
    confidence = (confidence_value(data["confidence"], f"{prefix}.confidence")
                  if "confidence" in data else DEFAULT_CONFIDENCE)
    options = _options(data, fmt, prefix)
    path = Path(raw)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    if fmt == "receive-log":
        options["options_field"] = prefix
    elif fmt == "sequence-numbers":
        options["options_field"] = prefix
    traces = read_trace_file(path, fmt, field=f"{prefix}.path", **options)
    arrivals, sensor = _one_trace(traces, "receive log" if fmt == "receive-log" else fmt,
                                  prefix)
    period = options.get("period")
    return Trace(raw, arrivals, format=fmt, confidence=confidence,
                 sensor=options.get("sensor", sensor),
                 period_s=None if period is None else str(period))


__all__ = ["DEFAULT_CONFIDENCE", "FORMAT_KEYS", "TRACE_KEYS", "confidence_value",
           "decimal_value", "integer_value", "measured_trace_from_mapping"]
