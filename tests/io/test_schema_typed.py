"""The record is typed all the way down: every property, array item and map value of the printed
record schema has a type, and every shipped example's record — as ``analyze`` builds it and as
``--json`` prints it — survives the strict reader unchanged and validates against the schema."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from click.testing import CliRunner

from kfcrit.analysis import record as record_module
from kfcrit.analysis.sections import record_from_json, record_schema
from kfcrit.cli.main import main

from ..conftest import example_files

TYPED = ("type", "$ref", "anyOf", "oneOf", "allOf", "enum", "const")


def untyped(schema: Any, path: str = "#") -> list[str]:
    """Paths of the schema's properties, array items and map values that accept any value."""
    out: list[str] = []
    if isinstance(schema, dict):
        for name, sub in (schema.get("properties") or {}).items():
            if isinstance(sub, dict) and not any(k in sub for k in TYPED):
                out.append(f"{path}/properties/{name}")
        for key in ("items", "additionalProperties"):
            sub = schema.get(key)
            if isinstance(sub, dict) and not any(k in sub for k in TYPED):
                out.append(f"{path}/{key}")
        for branch in ("anyOf", "oneOf", "allOf"):
            for i, sub in enumerate(schema.get(branch) or []):
                if isinstance(sub, dict) and not any(k in sub for k in TYPED):
                    out.append(f"{path}/{branch}/{i}")
        for key, sub in schema.items():
            out.extend(untyped(sub, f"{path}/{key}"))
    elif isinstance(schema, list):
        for i, sub in enumerate(schema):
            out.extend(untyped(sub, f"{path}/{i}"))
    return out


def test_no_property_item_or_map_value_of_the_record_schema_is_untyped() -> None:
    schema = record_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    assert untyped(schema) == []
    assert len(schema["$defs"]) > 100  # every payload has its own definition


def test_the_walk_finds_an_untyped_property() -> None:
    assert untyped({"properties": {"a": {}, "b": {"type": "string"}}}) == ["#/properties/a"]
    assert untyped({"type": "array", "items": {}}) == ["#/items"]
    assert untyped({"type": "object", "additionalProperties": {}}) == ["#/additionalProperties"]


def test_record_definitions_have_unique_names() -> None:
    """Two section classes of one name would share one ``$defs`` entry (and one schema)."""
    import dataclasses
    import typing

    from kfcrit.analysis.sections import AnalysisRecord

    seen: dict[str, type] = {}

    def visit(tp: Any) -> None:
        for arg in typing.get_args(tp):
            visit(arg)
        if isinstance(tp, type) and dataclasses.is_dataclass(tp):
            other = seen.setdefault(tp.__name__, tp)
            assert other is tp, f"two record classes named {tp.__name__}"
            if tp.__name__ in visited:
                return
            visited.add(tp.__name__)
            for hint in typing.get_type_hints(tp).values():
                visit(hint)

    visited: set[str] = set()
    visit(AnalysisRecord)
    assert len(visited) == len(record_schema()["$defs"])


def same(a: Any, b: Any, path: str = "record") -> None:
    """``a`` and ``b`` are the same JSON value, with the same int/float form of every number."""
    assert type(a) is type(b), f"{path}: {type(a).__name__} became {type(b).__name__}"
    if isinstance(a, dict):
        assert set(a) == set(b), f"{path}: keys {sorted(set(a) ^ set(b))} differ"
        for k in a:
            same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{path}: length"
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]")
    else:
        assert a == b, f"{path}: {a!r} became {b!r}"


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(record_schema())


def check_record(data: dict[str, Any], validator: jsonschema.Draft202012Validator,
                 name: str) -> None:
    errors = sorted(validator.iter_errors(data), key=str)
    assert not errors, f"{name}: {errors[0].message} at {list(errors[0].absolute_path)}"
    again = record_from_json(json.loads(json.dumps(data)))
    same(data, json.loads(json.dumps(again.to_dict())), name)


QUICK = ["sinopoli-scalar.yaml", "ge-bursty-scalar.yaml", "link-oqpsk-sensor.yaml",
         "network-redundant-gauges.yaml", "continuous-cv-tracker.yaml",
         "rotation-third-turn.yaml"]


@pytest.mark.parametrize("name", QUICK)
def test_json_of_an_example_round_trips_and_validates(name: str, validator: Any) -> None:
    """``kfcrit analyze FILE --json --quick --no-simulate``: read strictly, written back
    unchanged, valid against the schema."""
    path = next(p for p in example_files() if p.name == name)
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", "--quick", "--no-simulate"])
    assert r.exit_code in (0, 1, 3, 5), r.stderr
    check_record(json.loads(r.stdout), validator, name)


def test_every_example_as_analyze_builds_it_round_trips(validator: Any) -> None:
    """The typed record ``analyze`` builds (section by section, never parsed back) is read back
    equal by the strict reader from its JSON form, which validates against the schema, for
    every shipped example."""
    from kfcrit.analysis.sections import record_from_json
    from kfcrit.analysis.spec import load_spec

    for path in example_files():
        record = record_module.analyze_system(load_spec(path), quick=True, simulate=False)
        data = json.loads(json.dumps(record.to_dict()))
        back = record_from_json(data)
        assert back == record, path.name
        same(data, json.loads(json.dumps(back.to_dict())), path.name)
        check_record(data, validator, path.name)


def test_every_example_record_round_trips(example_records: dict, validator: Any) -> None:
    """The shared ``--quick`` records (with simulation) of every shipped example."""
    assert {Path(n).name for n in example_records} == {p.name for p in example_files()}
    for name, record in example_records.items():
        check_record(json.loads(json.dumps(record.to_dict())), validator, name)
