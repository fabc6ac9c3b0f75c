"""Every analysis path yields a well-formed typed record: random small systems, channels and
requirements go through ``analyze`` and the strict typed reader, and validate against the
printed schema (a key no section declares would fail here, not in a user's run)."""
from __future__ import annotations

import json
from fractions import Fraction

import jsonschema
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kfcrit
from kfcrit.analysis.sections import record_from_json, record_schema
from kfcrit.analysis.spec import spec_from_mapping

from ..conftest import PROFILE

VALIDATOR = jsonschema.Draft202012Validator(record_schema())
EXAMPLES = 200 if PROFILE == "thorough" else 12

entry = st.fractions(min_value=-3, max_value=3, max_denominator=4).map(
    lambda f: f"{f.numerator}/{f.denominator}")
probability = st.fractions(min_value=0, max_value=1, max_denominator=20)
rate = st.fractions(min_value=Fraction(1, 20), max_value=1, max_denominator=20)


def text(f: Fraction) -> str:
    return f"{f.numerator}/{f.denominator}"


@st.composite
def documents(draw: st.DrawFn) -> dict:
    n = draw(st.integers(1, 3))
    m = draw(st.integers(1, 2))
    doc: dict = {"name": "random", "A": [[draw(entry) for _ in range(n)] for _ in range(n)],
                 "C": [[draw(entry) for _ in range(n)] for _ in range(m)], "Q": 1, "R": 1}
    kind = draw(st.sampled_from(["none", "bernoulli", "gilbert-elliott"]))
    if kind == "bernoulli":
        doc["channel"] = {"model": "bernoulli", "arrival_probability": text(draw(probability))}
    elif kind == "gilbert-elliott":
        doc["channel"] = {"model": "gilbert-elliott", "failure_rate": text(draw(rate)),
                          "recovery_rate": text(draw(rate))}
    if draw(st.booleans()):
        doc["requirements"] = {"max_mean_error_trace": draw(st.integers(1, 200))}
    return doc


@settings(max_examples=EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(doc=documents())
def test_any_small_system_gives_a_valid_record(doc: dict) -> None:
    record = kfcrit.analyze(spec_from_mapping(doc), quick=True, simulate=False)
    data = json.loads(json.dumps(record.to_dict()))
    errors = list(VALIDATOR.iter_errors(data))
    assert not errors, errors[0].message
    assert record_from_json(data).to_dict() == data
    assert data["review"]["decision"] in ("pass", "fail", "undetermined")
