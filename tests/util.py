"""Small assertions shared by the end-to-end tests."""
from __future__ import annotations

import math


def assert_all_finite(obj: object) -> None:
    """Every float anywhere in a nested record is finite (no NaN, no inf)."""
    if isinstance(obj, float):
        assert math.isfinite(obj), obj
    elif isinstance(obj, dict):
        for v in obj.values():
            assert_all_finite(v)
    elif isinstance(obj, list):
        for v in obj:
            assert_all_finite(v)
