"""Packet-trace file formats: 0/1 per period, received sequence numbers, timestamped receive logs.

Every reader turns a file into 0/1 arrays, one value per sampling period (1 = received):

* ``binary`` — one 0 or 1 per period, one per line or separated by whitespace or commas, or
  written together (``0010110``, as packet-trace tools and ns-3 scripts print them);
* ``sequence-numbers`` — the sequence numbers of the received packets, increasing (one per line
  or whitespace/comma separated); a number missing between ``first`` and ``last`` is a loss.
  ``first`` and ``last`` default to the first and last numbers in the file (so the trace starts
  and ends with a reception unless they are given). A repeated or decreasing number is an error:
  counters that wrap around must be unwrapped before (this reader assumes they never wrap);
* ``receive-log`` — one arrival per line, ``t_seconds`` or ``t_seconds sensor_id`` (whitespace or
  comma separated; the same number of columns on every line), times non-decreasing. With a
  sampling period T and start time t_0, period i is [t_0 + iT, t_0 + (i + 1)T); a period with at
  least one arrival is received. The number of periods is given or inferred (the period of the
  last arrival, plus one); with a sensor column every sensor gets an array of that common length,
  time-aligned. Times are read as exact decimals, so 0.3 s with T = 0.1 s falls in period 3.

Blank lines and ``#`` comments (to the end of the line) are ignored. Every error is one
:class:`~kfcrit.errors.InputError` naming the field, the file and the line
(``channel.path: trace.txt line 17: '2' is not 0 or 1``). The file's text is not echoed, except
an offending value that is a single character or looks like a number (at most 12 characters),
since a path pointed at the wrong file must not print that file. Files are read through
:func:`kfcrit.io.safeio.read_text` with the size cap of trace files; :data:`MAX_LOG_LINES` and
:data:`MAX_PERIODS` cap the lines parsed one by one and the arrays built. No file text is ever
evaluated: numbers are matched by regular expressions and converted by ``int``/``Decimal``.
"""
from __future__ import annotations

import decimal
import os
import re
from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.safeio import printable, read_text

MAX_TRACE_BYTES = 50_000_000
"""Largest trace file read (bytes)."""
MAX_LOG_LINES = 5_000_000
"""Most data lines of a sequence-number or receive-log file."""
MAX_PERIODS = 50_000_000
"""Most periods of a trace (all sensors together for a receive log)."""
MAX_SENSORS = 64
"""Most distinct sensor ids in one receive log."""
NO_SENSOR = ""
"""The key of the single trace of a receive log without a sensor column."""
TRACE_FORMATS = ("binary", "sequence-numbers", "receive-log")
"""The format names :func:`read_trace_file` accepts."""

_SPLIT = re.compile(r"[\s,]+")
_SHOWN = re.compile(r"[-+0-9.eE]{1,12}|[!-~]")
_SEQ = re.compile(r"[0-9]{1,18}")
_BITS = re.compile(r"[01]+")
_TIME = re.compile(r"[+-]?(?:[0-9]{1,30}(?:\.[0-9]{0,30})?|\.[0-9]{1,30})(?:[eE][+-]?[0-9]{1,3})?")
_SENSOR = re.compile(r"[A-Za-z0-9_.:-]{1,64}")


def _shown(token: str) -> str:
    """``'token'`` when it is safe to echo (a number-like token or one character), else a word."""
    return repr(token) if _SHOWN.fullmatch(token) else "the value (not shown)"


def _error(field: str, source: str, line: int | None, message: str) -> InputError:
    where = f"{source} line {line}" if line is not None else source
    return InputError(f"{where}: {message}", field=field)


def _data_lines(text: str, field: str, source: str,
                cap: int = MAX_LOG_LINES) -> Iterator[tuple[int, list[str]]]:
    """(line number, tokens) of every line with data, comments removed; at most ``cap`` lines."""
    seen = 0
    for number, line in enumerate(text.split("\n"), 1):
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        seen += 1
        if seen > cap:
            raise _error(field, source, number, f"more than {cap} data lines")
        yield number, [t for t in _SPLIT.split(body) if t]


def _empty(field: str, source: str, what: str) -> InputError:
    return _error(field, source, None, f"no {what} on any line (an empty trace)")


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def parse_binary(text: str, *, source: str = "<text>", field: str = "channel.path") -> np.ndarray:
    """A 0/1 trace from text with one 0 or 1 per period (see the module docstring).

    Raises
    ------
    InputError
        A value other than 0 or 1 (naming its line), no values, or more than
        :data:`MAX_PERIODS`.
    """
    if "#" not in text:  # the common case: one pass over the tokens, lines only for an error
        tokens = text.replace(",", " ").split()
        if all(_BITS.fullmatch(t) for t in tokens):
            joined = "".join(tokens)
            if not joined:
                raise _empty(field, source, "0/1 values")
            if len(joined) > MAX_PERIODS:
                raise _error(field, source, None, f"more than {MAX_PERIODS} values")
            return _frozen(np.frombuffer(joined.encode("ascii"), dtype=np.uint8) == ord("1"))
    values: list[bool] = []
    for number, tokens in _data_lines(text, field, source, cap=MAX_PERIODS):
        for position, token in enumerate(tokens, 1):
            if not _BITS.fullmatch(token):
                on = f" (value {position} on the line)" if len(tokens) > 1 else ""
                raise _error(field, source, number, f"{_shown(token)}{on} is not 0 or 1")
        values.extend(c == "1" for t in tokens for c in t)
        if len(values) > MAX_PERIODS:
            raise _error(field, source, number, f"more than {MAX_PERIODS} values")
    if not values:
        raise _empty(field, source, "0/1 values")
    return _frozen(np.asarray(values, dtype=bool))


def _bound(value: Any, name: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InputError(f"must be a non-negative integer, got {str(value)[:40]!r}", field=name)
    return int(value)


def parse_sequence_numbers(text: str, *, source: str = "<text>", field: str = "channel.path",
                           first: int | None = None, last: int | None = None,
                           options_field: str = "channel") -> np.ndarray:
    """A 0/1 trace from the increasing sequence numbers of the received packets.

    Period i of the trace is sequence number ``first + i``, for ``first`` … ``last`` (defaults:
    the first and last numbers of the file); it is 1 when that number was received.

    Raises
    ------
    InputError
        A token that is not a non-negative integer, a repeated or decreasing number, a number
        outside [first, last] (each naming its line), no numbers, first > last (naming
        ``<options_field>.first``), or more than :data:`MAX_PERIODS` periods.
    """
    lo = _bound(first, f"{options_field}.first")
    hi = _bound(last, f"{options_field}.last")
    if lo is not None and hi is not None and lo > hi:
        raise InputError(f"must be <= last ({hi}), got {lo}", field=f"{options_field}.first")
    numbers: list[int] = []
    previous, previous_line = -1, 0
    for number, tokens in _data_lines(text, field, source):
        for token in tokens:
            if not _SEQ.fullmatch(token):
                raise _error(field, source, number,
                             f"{_shown(token)} is not a sequence number (a non-negative integer)")
            value = int(token)
            if value == previous:
                raise _error(field, source, number, f"sequence number {value} is repeated "
                             f"(also on line {previous_line})")
            if value < previous:
                raise _error(field, source, number, f"sequence number {value} is smaller than "
                             f"{previous} on line {previous_line}: numbers must increase "
                             "(wrapped-around counters are not supported)")
            if lo is not None and value < lo:
                raise _error(field, source, number,
                             f"sequence number {value} is before first = {lo}")
            if hi is not None and value > hi:
                raise _error(field, source, number,
                             f"sequence number {value} is after last = {hi}")
            start = numbers[0] if lo is None and numbers else (value if lo is None else lo)
            if value - start >= MAX_PERIODS:
                raise _error(field, source, number, f"sequence number {value} makes the trace "
                             f"longer than {MAX_PERIODS} periods")
            numbers.append(value)
            previous, previous_line = value, number
    if not numbers:
        raise _empty(field, source, "sequence numbers")
    lo = numbers[0] if lo is None else lo
    hi = numbers[-1] if hi is None else hi
    if hi - lo + 1 > MAX_PERIODS:
        raise InputError(f"first..last spans more than {MAX_PERIODS} periods",
                         field=f"{options_field}.last")
    out = np.zeros(hi - lo + 1, dtype=bool)
    out[np.asarray(numbers, dtype=np.int64) - lo] = True
    return _frozen(out)


def _decimal(value: Any, name: str, *, positive: bool = False) -> Decimal:
    """An exact decimal from an int, float (its shortest repr) or numeric string."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str, Decimal, np.number)):
        raise InputError(f"must be a number, got {type(value).__name__}", field=name)
    text = value if isinstance(value, str) else repr(float(value)) \
        if isinstance(value, (float, np.floating)) else str(value)
    if not _TIME.fullmatch(text.strip()):
        raise InputError(f"must be a finite number, got {str(value)[:40]!r}", field=name)
    d = Decimal(text.strip())
    if d < 0 or (positive and d == 0):
        raise InputError(f"must be {'> 0' if positive else '>= 0'}, got {str(value)[:40]}",
                         field=name)
    return d


def parse_receive_log(text: str, *, period: Any, start: Any = 0, periods: int | None = None,
                      sensor: str | None = None, source: str = "<text>",
                      field: str = "channel.path",
                      options_field: str = "channel") -> dict[str, np.ndarray]:
    """0/1 traces from a timestamped receive log, binned per sampling period.

    Parameters
    ----------
    text : str
        One arrival per line: ``t_seconds`` or ``t_seconds sensor_id``.
    period : number
        Sampling period T > 0 in seconds (``<options_field>.period`` in errors).
    start : number
        Start time t_0 ≥ 0 of period 0 (``<options_field>.start``).
    periods : int, optional
        Number of periods; default: the period of the log's last arrival (of any sensor, also
        when ``sensor`` selects one), plus one.
    sensor : str, optional
        Keep only this sensor's lines (the log must have a sensor column and the id must occur).

    Returns
    -------
    dict of str to numpy.ndarray
        One read-only boolean array per sensor id (sorted), all of the same length; the key is
        :data:`NO_SENSOR` for a log without a sensor column.

    Raises
    ------
    InputError
        A bad time or sensor id, a negative time, a time before ``start`` or after the last
        period, decreasing times, a changing number of columns (each naming its line), an empty
        log, or too many sensors or periods.
    """
    step = _decimal(period, f"{options_field}.period", positive=True)
    t0 = _decimal(start, f"{options_field}.start")
    total = _bound(periods, f"{options_field}.periods")
    if total is not None and not 0 < total <= MAX_PERIODS:
        raise InputError(f"must be in 1..{MAX_PERIODS}, got {total}", field=f"{options_field}.periods")
    bins: dict[str, list[int]] = {}
    columns: int | None = None
    previous, previous_line, last_index = None, 0, 0
    with decimal.localcontext() as ctx:
        ctx.prec = 80
        for number, tokens in _data_lines(text, field, source):
            if len(tokens) not in (1, 2):
                raise _error(field, source, number, f"has {len(tokens)} columns, expected "
                             "'t_seconds' or 't_seconds sensor_id'")
            if columns is None:
                columns = len(tokens)
            elif len(tokens) != columns:
                raise _error(field, source, number, f"has {len(tokens)} column(s), but the first "
                             f"data line has {columns}")
            token = tokens[0]
            if not _TIME.fullmatch(token):
                raise _error(field, source, number, f"{_shown(token)} is not a time in seconds")
            t = Decimal(token)
            if t < 0:
                raise _error(field, source, number, f"time {token} is negative")
            if previous is not None and t < previous:
                raise _error(field, source, number, f"time {token} is earlier than the time on "
                             f"line {previous_line}: times must not decrease")
            previous, previous_line = t, number
            if t < t0:
                raise _error(field, source, number, f"time {token} is before the start time "
                             f"{t0} s")
            index = (t - t0) // step
            if index >= (total if total is not None else MAX_PERIODS):
                raise _error(field, source, number, f"time {token} is after the last period "
                             f"({total if total is not None else MAX_PERIODS} periods of "
                             f"{step} s from {t0} s)")
            last_index = max(last_index, int(index))
            key = NO_SENSOR
            if columns == 2:
                key = tokens[1]
                if not _SENSOR.fullmatch(key):
                    raise _error(field, source, number, "the sensor id must be 1 to 64 letters, "
                                 "digits or _.:-")
                if sensor is not None and key != sensor:
                    continue
            if key not in bins:
                if len(bins) >= MAX_SENSORS:
                    raise _error(field, source, number, f"more than {MAX_SENSORS} sensor ids")
                bins[key] = []
            bins[key].append(int(index))
    if columns is None:
        raise _empty(field, source, "arrivals")
    if sensor is not None:
        if columns == 1:
            raise InputError(f"{source} has no sensor column", field=f"{options_field}.sensor")
        if not bins:
            raise InputError(f"{printable(sensor)[:64]!r} does not occur in {source}",
                             field=f"{options_field}.sensor")
    length = total if total is not None else 1 + last_index
    if length * len(bins) > MAX_PERIODS:
        raise _error(field, source, None, f"{len(bins)} sensors × {length} periods exceed "
                     f"{MAX_PERIODS}")
    out: dict[str, np.ndarray] = {}
    for key in sorted(bins):
        arr = np.zeros(length, dtype=bool)
        arr[np.asarray(bins[key], dtype=np.int64)] = True
        out[key] = _frozen(arr)
    return out


def _source(path: str | os.PathLike[str]) -> str:
    return printable(Path(path).name)[:80] or "trace file"


def _read(path: str | os.PathLike[str], field: str) -> str:
    text, _ = read_text(path, field=field, max_bytes=MAX_TRACE_BYTES, what="trace file")
    return text


def read_binary(path: str | os.PathLike[str], *, field: str = "channel.path") -> np.ndarray:
    """:func:`parse_binary` of a file (read with the trace-file size cap)."""
    return parse_binary(_read(path, field), source=_source(path), field=field)


def read_sequence_numbers(path: str | os.PathLike[str], *, field: str = "channel.path",
                          **options: Any) -> np.ndarray:
    """:func:`parse_sequence_numbers` of a file (options: first, last, options_field)."""
    return parse_sequence_numbers(_read(path, field), source=_source(path), field=field,
                                  **options)


def read_receive_log(path: str | os.PathLike[str], *, field: str = "channel.path",
                     **options: Any) -> dict[str, np.ndarray]:
    """:func:`parse_receive_log` of a file (options: period, start, periods, sensor,
    options_field)."""
    return parse_receive_log(_read(path, field), source=_source(path), field=field, **options)


def read_trace_file(path: str | os.PathLike[str], format: str = "binary", *,
                    field: str = "channel.path", **options: Any) -> dict[str, np.ndarray]:
    """Read a trace file of any of :data:`TRACE_FORMATS`, as ``{sensor id: array}`` (the key is
    :data:`NO_SENSOR` for the single trace of a binary or sequence-number file)."""
    if format == "binary":
        if options:
            raise InputError(f"the binary format takes no options, got {sorted(options)}",
                             field=field)
        return {NO_SENSOR: read_binary(path, field=field)}
    if format == "sequence-numbers":
        return {NO_SENSOR: read_sequence_numbers(path, field=field, **options)}
    if format == "receive-log":
        return read_receive_log(path, field=field, **options)
    raise InputError(f"unknown trace format {str(format)[:40]!r} (known: "
                     f"{', '.join(TRACE_FORMATS)})", field=field.rpartition(".")[0] + ".format"
                     if "." in field else "format")


__all__ = ["MAX_LOG_LINES", "MAX_TRACE_BYTES", "MAX_PERIODS", "MAX_SENSORS", "NO_SENSOR", "TRACE_FORMATS",
           "parse_binary", "parse_receive_log", "parse_sequence_numbers", "read_binary",
           "read_receive_log", "read_sequence_numbers", "read_trace_file"]
