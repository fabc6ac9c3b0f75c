"""Where a lower layer's plain result enters the record: read once, strictly, as its record type.

The theory, link, simulation and file layers sit below the analysis and cannot build the
record's classes; they state their results as plain data (``to_dict()``). The analysis reads
such a result here, at the place where it builds the section that holds it (a key the record
does not declare, or a value of the wrong type, is an error naming its path), and moves the
wall-clock seconds the lower layer reported out of the record. Everything the analysis computes
itself is built as the record's classes directly.
"""
from __future__ import annotations

import dataclasses
import enum
import functools
import math
import typing
from typing import Any

from kfcrit.io.jsonio import jsonable
from kfcrit.io.typed import RecordError, from_json

_PLAIN_SCALARS = frozenset({str, bool, int})
"""Types whose values are their own JSON form (a finite float is too)."""
TIMING_KEYS = frozenset({"seconds", "runtime_seconds"})
"""Keys of a lower layer's result that hold wall-clock seconds (kept out of the record)."""


def split_timings(obj: Any, path: str, found: dict[str, float]) -> Any:
    """Copy of ``obj`` without the keys in :data:`TIMING_KEYS`; those go into ``found``
    (keyed by their dotted path under ``path``)."""
    kind = type(obj)
    if kind is dict:
        out = {}
        for k, v in obj.items():
            if k in TIMING_KEYS and (v is None or isinstance(v, (int, float))):
                found[f"{path}.{k}".lstrip(".")] = v
            elif type(v) is dict or type(v) is list:
                out[k] = split_timings(v, f"{path}.{k}", found)
            else:
                out[k] = v
        return out
    if kind is list:
        if all(type(v) is not dict and type(v) is not list for v in obj):
            return list(obj)
        return [split_timings(v, f"{path}[{i}]", found) for i, v in enumerate(obj)]
    return obj


def read_plain(tp: Any, value: Any, path: str, timings: dict[str, float] | None = None) -> Any:
    """A lower layer's plain result ``value`` as the record type ``tp``.

    Parameters
    ----------
    tp : type
        The record type (a section class, or a field type such as ``list[X] | None``).
    value : Any
        The plain result (NumPy and sympy numbers allowed); a value that is already typed (a
        dataclass or an enum) is returned as is (None only where ``tp`` allows it).
    path : str
        The dotted place of the value in the record (``link_budget.curves``), for errors and
        for the keys of ``timings``.
    timings : dict, optional
        Receives the wall-clock seconds of :data:`TIMING_KEYS` found in ``value``.

    Raises
    ------
    kfcrit.io.typed.RecordError
        A key the record does not declare, a missing key or a mistyped value (names its path).
    """
    if type(value) in _PLAIN_SCALARS or value is None or \
            type(value) is float and math.isfinite(value):
        return from_json(tp, value, f"record.{path}")   # already its JSON form
    if dataclasses.is_dataclass(value) or isinstance(value, enum.Enum):
        return value
    plain = split_timings(jsonable(value), f".{path}", timings if timings is not None else {})
    return from_json(tp, plain, f"record.{path}")


def read_fields(cls: type, plain: typing.Mapping[str, Any], path: str,
                timings: dict[str, float] | None = None, **typed: Any) -> Any:
    """The record class ``cls`` from the fields the analysis built (``typed``, taken as they
    are) and a lower layer's plain fields (``plain``, each read by :func:`read_plain` as its
    field type).

    Raises
    ------
    kfcrit.io.typed.RecordError
        A plain key ``cls`` does not declare, a missing field, or a plain value of the wrong
        type (names its path).
    """
    hints = _field_types(cls)
    unknown = sorted(k for k in plain if k not in hints and k not in TIMING_KEYS)
    if unknown:
        raise RecordError(f"record.{path}: unknown key {unknown[0]!r} "
                          f"(expected one of {', '.join(hints)})")
    found = timings if timings is not None else {}
    fields = {}
    for k, v in plain.items():
        if k in typed:
            continue
        if k in TIMING_KEYS and k not in hints:
            found[f"{path}.{k}"] = v
            continue
        fields[k] = read_plain(hints[k], v, f"{path}.{k}", found)
    try:
        return cls(**fields, **typed)
    except TypeError as exc:   # a required field neither built nor stated
        raise RecordError(f"record.{path}: {exc}") from None


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    """The public fields' types of a record class, by name (resolved once per class)."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)
            if not f.metadata.get("internal")}
