"""The critical value's record sections, built as their classes by the theory layer.

Expected values are hand derivations (docs/theory.md §4): for A = 5/4, p_c = p_low =
1 − (4/5)² = 9/25 and the moment thresholds 1 − |λ|^(−2q) are 9/25 (q = 1) and
1 − (4/5)⁴ = 369/625 (q = 2).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from kfcrit.io.typed import ABSENT, from_json, to_json
from kfcrit.model.system import System
from kfcrit.records.contract import (
    BlockLowerBound,
    Classification,
    LowerBound,
    NearbyCase,
    RobustCriticalValue,
)
from kfcrit.records.structure import MomentThreshold, StructureRecord, Theory
from kfcrit.theory.critical.section import critical_value

SECTION_TYPES = {"classification": Classification, "robust_critical_value": RobustCriticalValue,
                 "lower_bound": LowerBound, "block_lower_bound": BlockLowerBound,
                 "structure": StructureRecord, "theory": Theory}


def _native(value: object) -> bool:
    """Every leaf of ``value`` is a plain Python value (no NumPy or sympy number)."""
    if dataclasses.is_dataclass(value):
        return all(_native(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, (list, tuple)):
        return all(_native(v) for v in value)
    return value is None or value is ABSENT or type(value) in (bool, int, float, str) \
        or isinstance(value, Classification)


def test_scalar_sections_are_their_classes():
    cv = critical_value(System(A=[["5/4"]], C=[[1]], Q=1, R=1))
    sec = cv.sections()
    assert sec["classification"] is Classification.NON_DEGENERATE
    assert (sec["critical_value"].value, sec["critical_value"].exact,
            sec["critical_value"].expression) == (0.36, True, "9/25")
    assert sec["lower_bound"] == LowerBound(value=0.36, expression="9/25")
    assert (sec["block_lower_bound"].value, sec["block_lower_bound"].expression) == (0.36, "9/25")
    assert sec["robust_critical_value"] is None
    assert sec["theory"].moment_thresholds == [
        MomentThreshold(q=1, value=0.36, expression="9/25", applies=True),
        MomentThreshold(q=2, value=369 / 625, expression="369/625", applies=True)]
    assert sec["structure"].eigenvalues[0].modulus_expression == "5/4"
    for key, cls in SECTION_TYPES.items():
        assert sec[key] is None or isinstance(sec[key], cls), key
    assert all(_native(v) for v in sec.values())


def test_sections_are_the_plain_form_read_strictly():
    # the numeric path with a nearby degenerate pair: robust value, alternatives, no low case
    s = System(np.diag([2.0, -(2 - 1e-12), 0.1, 0.2]), np.ones((1, 4)), np.eye(4), np.eye(1))
    cv = critical_value(s)
    sec, plain = cv.sections(), cv.to_dict()
    rob = sec["robust_critical_value"]
    assert isinstance(rob, RobustCriticalValue) and rob.low is ABSENT
    assert all(isinstance(a, NearbyCase) for a in rob.alternatives)
    assert all(_native(v) for v in sec.values())
    timing = plain["structure"].pop("seconds")
    assert isinstance(timing, float)
    for key, value in sec.items():
        assert to_json(value) == plain[key], key
        assert from_json(type(value), plain[key], key) == value, key
    assert plain["warnings"] == list(cv.warnings)
