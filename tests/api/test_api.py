"""``kfcrit.analyze`` takes what a new user passes first: a path."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

import kfcrit

from ..conftest import REPORTS


@pytest.mark.parametrize("as_path", [str, Path], ids=["str", "Path"])
def test_analyze_takes_a_system_file_path(as_path) -> None:
    record = kfcrit.analyze(as_path(REPORTS / "sinopoli-scalar.yaml"), simulate=False)
    assert isinstance(record, kfcrit.Analysis)
    # scalar a = 5/4 observed: p_c = 1 − 1/a² = 1 − 16/25 = 9/25 (Sinopoli et al. 2004)
    assert record.critical_value.expression == "9/25"
    assert record.name == "Sinopoli scalar example"     # the file's name: key, so it was loaded


def test_analyze_of_a_path_equals_analyze_of_the_loaded_file() -> None:
    path = REPORTS / "sinopoli-general.yaml"
    by_path = kfcrit.analyze(path, simulate=False).to_dict()
    by_spec = kfcrit.analyze(kfcrit.load_spec(path), simulate=False).to_dict()
    for key in ("critical_value", "operating_point", "review", "classification"):
        assert by_path[key] == by_spec[key]
    # the path's record carries the file's provenance, hashed here independently
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    assert by_path["provenance"]["input_sha256"] == digest
    assert by_path["provenance"]["input_path"] == str(path)


@pytest.mark.parametrize("wrong", [3, 0.5, {"A": [[1]]}, [[1.25]], None, b"reports/x.yaml"],
                         ids=["int", "float", "dict", "list", "None", "bytes"])
def test_analyze_of_anything_else_is_a_type_error_saying_what_it_takes(wrong) -> None:
    with pytest.raises(TypeError, match=r"system file path \(str or pathlib.Path\).*"
                                        + type(wrong).__name__):
        kfcrit.analyze(wrong)


def test_analyze_of_a_missing_or_wrong_file_is_the_cli_one_line_error(tmp_path: Path) -> None:
    with pytest.raises(kfcrit.KfcritError, match="cannot read"):
        kfcrit.analyze(tmp_path / "missing.yaml")
    rec = tmp_path / "rec.json"
    rec.write_text(json.dumps({"schema_version": "2.0", "review": {"decision": "pass"}}))
    with pytest.raises(kfcrit.KfcritError, match="saved analysis record.*kfcrit report"):
        kfcrit.analyze(rec)


def test_max_states_applies_to_a_path() -> None:
    with pytest.raises(kfcrit.KfcritError, match="more than 1 rows or columns"):
        kfcrit.analyze(REPORTS / "sinopoli-general.yaml", max_states=1)
