"""JSON-safe conversion of analysis records (no NaN or inf ever reaches JSON, HTML or PDF)."""
from __future__ import annotations

import enum
import json
import math
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np
import sympy as sp

_PLAIN = frozenset({str, int, float, type(None)})
"""Item types a list holds as JSON already (floats when finite)."""


def jsonable(obj: Any) -> Any:
    """Convert a record to plain JSON types.

    NumPy scalars and arrays become Python numbers and lists, sympy numbers become floats,
    tuples become lists, and any non-finite float becomes ``None`` (the record carries a warning
    or a flag saying why; JSON never holds NaN or Infinity).
    """
    kind = type(obj)    # the plain types first, by exact type (most of a record)
    if kind is str or kind is int or kind is bool or obj is None:
        return obj
    if kind is float:
        return obj if math.isfinite(obj) else None
    if kind is dict:
        return {k if type(k) is str else str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, enum.Enum):
        return jsonable(obj.value)
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, bool):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, sp.Basic):
        if obj.is_Integer:
            return int(obj)
        return jsonable(float(sp.N(obj, 20))) if obj.is_number else sp.sstr(obj)
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        if all(type(v) in _PLAIN for v in obj) and all(
                math.isfinite(v) for v in obj if type(v) is float):
            return list(obj)  # what the items give one by one, in one pass (big matrices)
        return [jsonable(v) for v in obj]
    if hasattr(obj, "to_dict"):
        return jsonable(obj.to_dict())
    if is_dataclass(obj):
        return {f.name: jsonable(getattr(obj, f.name)) for f in fields(obj)}
    raise TypeError(f"cannot convert {type(obj).__name__} to JSON")


def native_number(x: Any) -> int | float | None:
    """``x`` as a native number of the record: an integer (NumPy's too) stays an integer (its
    JSON form is ``1``, not ``1.0``), any other real becomes a float, None stays None."""
    if x is None:
        return None
    if isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
        return int(x)
    return float(x)


def dumps(record: Any) -> str:
    """Deterministic JSON text of a record (sorted keys off: the contract order is kept)."""
    return json.dumps(jsonable(record), indent=2, allow_nan=False, ensure_ascii=False)
