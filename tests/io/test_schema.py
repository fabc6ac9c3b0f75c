"""The typed record and the printed JSON Schemas: every example's record and file validate,
records round-trip through their JSON form, and a renamed field is caught."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jsonschema
import pytest
import yaml
from click.testing import CliRunner

from kfcrit.analysis.sections import AnalysisRecord, record_from_json
from kfcrit.analysis.verdict import CheckStatus, Decision, Reason, Review, decide
from kfcrit.cli.main import main
from kfcrit.io.typed import RecordError

from ..conftest import REPORTS, example_files


def printed_schema(what: str) -> dict:
    r = CliRunner().invoke(main, ["schema", what])
    assert r.exit_code == 0, r.stderr
    schema = json.loads(r.stdout)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)
    return schema


def test_every_example_record_validates_against_the_printed_schema(example_records: dict
                                                                   ) -> None:
    validator = jsonschema.Draft202012Validator(printed_schema("record"))
    for name, record in example_records.items():
        errors = sorted(validator.iter_errors(record.to_dict()), key=str)
        assert not errors, f"{name}: {errors[0].message} at {list(errors[0].absolute_path)}"


def test_every_example_file_validates_against_the_printed_schema() -> None:
    validator = jsonschema.Draft202012Validator(printed_schema("system"))
    for path in example_files():
        doc = yaml.safe_load(path.read_text())
        errors = sorted(validator.iter_errors(doc), key=str)
        assert not errors, f"{path.name}: {errors[0].message} at {list(errors[0].absolute_path)}"


def test_every_sweep_file_validates_against_the_printed_schema() -> None:
    validator = jsonschema.Draft202012Validator(printed_schema("sweep"))
    files = sorted(REPORTS.glob("sweep-*.yaml"))
    assert files
    for path in files:
        errors = sorted(validator.iter_errors(yaml.safe_load(path.read_text())), key=str)
        assert not errors, f"{path.name}: {errors[0].message}"


def test_the_system_schema_refuses_what_the_reader_refuses() -> None:
    validator = jsonschema.Draft202012Validator(printed_schema("system"))
    good = {"name": "s", "A": [[2]], "C": [[1]], "Q": 1, "R": "1/2",
            "channel": {"model": "bernoulli", "arrival_probability": 0.9}}
    assert validator.is_valid(good)
    assert not validator.is_valid({**good, "Aa": 1})                     # unknown key
    assert not validator.is_valid({k: v for k, v in good.items() if k != "R"})   # missing R
    assert not validator.is_valid({**good, "channel": {"model": "bernoulli"}})
    assert not validator.is_valid({**good, "channel": {"model": "carrier-pigeon"}})


def test_records_round_trip_through_their_json_form(example_records: dict) -> None:
    for name, record in example_records.items():
        data = record.to_dict()
        again = record_from_json(json.loads(json.dumps(data)))
        assert again.to_dict() == data, name
        assert isinstance(again, AnalysisRecord) and again.review == record.review


def test_a_renamed_or_unknown_field_fails(example_records: dict) -> None:
    data = next(iter(example_records.values())).to_dict()
    renamed = dict(data)
    renamed["verdicts"] = renamed.pop("review")
    with pytest.raises(RecordError, match="unknown key 'verdicts'"):
        record_from_json(renamed)
    inner = json.loads(json.dumps(data))
    inner["critical_value"]["valeu"] = inner["critical_value"].pop("value")
    with pytest.raises(RecordError, match="critical_value"):
        record_from_json(inner)
    bad = json.loads(json.dumps(data))
    bad["review"]["decision"] = "maybe"
    with pytest.raises(RecordError, match="review.decision"):
        record_from_json(bad)


def test_review_is_the_worst_reason() -> None:
    def r(status: CheckStatus) -> Reason:
        return Reason("c", status, "d")

    assert decide([]) is Decision.PASS
    assert decide([r(CheckStatus.PASS), r(CheckStatus.NOT_APPLICABLE)]) is Decision.PASS
    assert decide([r(CheckStatus.PASS), r(CheckStatus.UNDETERMINED)]) is Decision.UNDETERMINED
    assert decide([r(CheckStatus.UNDETERMINED), r(CheckStatus.FAIL)]) is Decision.FAIL
    review = Review(Decision.FAIL, (r(CheckStatus.FAIL),))
    assert dataclasses.asdict(review)["decision"] is Decision.FAIL


def test_record_in_a_notebook_says_what_it_is(example_records: dict) -> None:
    record = example_records["sinopoli-scalar.yaml"]
    text = repr(record)
    assert "sinopoli" in text.lower() or "Sinopoli" in text
    assert "9/25" in text and "review" in text


def test_schema_command_rejects_unknown_subjects() -> None:
    r = CliRunner().invoke(main, ["schema", "nonsense"])
    assert r.exit_code == 2


def test_check_command(tmp_path: Path) -> None:
    ok = CliRunner().invoke(main, ["check", str(REPORTS / "link-oqpsk-sensor.yaml")])
    assert ok.exit_code == 0 and "valid system file" in ok.stdout
    sweep = CliRunner().invoke(main, ["check", str(REPORTS / "sweep-link-distance.yaml")])
    assert sweep.exit_code == 0 and "valid sweep file" in sweep.stdout
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: b\nA: [[1, 2]]\nC: [[1]]\nQ: 1\nR: 1\n")
    r = CliRunner().invoke(main, ["check", str(bad)])
    assert r.exit_code == 2 and "A" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_the_file_reference_is_generated_from_the_schemas() -> None:
    r = CliRunner().invoke(main, ["schema", "--markdown"])
    assert r.exit_code == 0
    assert (REPORTS / "REFERENCE.md").read_text() == r.stdout, \
        "reports/REFERENCE.md is stale: regenerate with `kfcrit schema --markdown`"
    for key in ("channel.max_retries", "channel.packet_bytes", "requirements.max_mean_error_trace",
                "grid", "channel.path_loss.shadowing"):
        assert f"`{key}`" in r.stdout
