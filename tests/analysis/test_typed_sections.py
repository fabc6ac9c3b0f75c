"""Every section of the record is typed where it is made: ``analysis_sections`` hands the record
frozen dataclasses (or None, text, lists of them) that the theory, link, simulation and analysis
layers built as their classes, and no part of any section is read from plain data on the way
(the strict reader is for saved records only)."""
from __future__ import annotations

import dataclasses
import enum
import json
from pathlib import Path
from typing import Any

import pytest

from kfcrit.analysis import record as record_module
from kfcrit.analysis.record import (
    AnalysisOptions,
    analysis_data,
    analysis_sections,
    analyze_system,
    theory_sections,
)
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.analysis.spec import load_spec
from kfcrit.io import typed
from kfcrit.io.typed import ABSENT

REPORTS = Path(__file__).resolve().parents[2] / "reports"

FILES = ["network-redundant-gauges", "link-oqpsk-sensor", "ge-bursty-scalar",
         "loop-dc-motor", "trace-bursty-link", "mesh-pipeline-relaying",
         "continuous-cv-tracker", "requirements-tail"]
"""One file per kind of section: a network, a link budget, a Gilbert–Elliott link, a closed
loop, a measured trace, a mesh, a continuous-time plant, requirements."""

def typed_value(value: Any) -> bool:
    """A dataclass, an enum, text, None or a list of these (never a dict of plain data)."""
    if isinstance(value, list):
        return all(typed_value(v) for v in value)
    return (value is None or value is ABSENT or isinstance(value, (str, enum.Enum))
            or (dataclasses.is_dataclass(value) and not isinstance(value, type)))


@pytest.fixture
def no_reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Every dataclass the strict reader builds from plain data during the test (by path)."""
    paths: list[str] = []
    real = typed._dataclass_from_json

    def recording(cls: type, value: Any, path: str) -> Any:
        paths.append(path)
        return real(cls, value, path)

    monkeypatch.setattr(typed, "_dataclass_from_json", recording)
    return paths


def options() -> AnalysisOptions:
    return AnalysisOptions(simulate=False, quick=True)


@pytest.mark.parametrize("name", FILES)
def test_sections_are_typed_where_they_are_made(name: str, no_reads: list[str]) -> None:
    spec = load_spec(REPORTS / f"{name}.yaml")
    theory = theory_sections(spec.system, options(), channel=spec.channel)
    sec = analysis_sections(spec, options(), theory)
    plain = {k: type(v).__name__ for k, v in sec.items() if not typed_value(v)}
    assert plain == {}, f"plain sections of {name}: {plain}"
    assert no_reads == [], f"{name}: parts read from plain data: {sorted(set(no_reads))[:5]}"


@pytest.mark.parametrize("name", ["network-redundant-gauges", "link-oqpsk-sensor"])
def test_the_record_is_assembled_without_a_reader(name: str,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    refused: list[bool] = []
    real_sections = record_module.analysis_sections
    real_reader = typed.from_json

    def sections_then_refuse(*args: Any, **kwargs: Any) -> dict[str, Any]:
        out = real_sections(*args, **kwargs)
        refused.append(True)   # from here on, no section may be read from plain data
        return out

    def reader(*args: Any, **kwargs: Any) -> Any:
        assert not refused, "the record read a section from plain data"
        return real_reader(*args, **kwargs)

    monkeypatch.setattr(record_module, "analysis_sections", sections_then_refuse)
    monkeypatch.setattr(typed, "from_json", reader)
    rec = analyze_system(load_spec(REPORTS / f"{name}.yaml"), options())
    assert refused == [True]
    for f in dataclasses.fields(AnalysisRecord):
        if f.name != "timings":
            assert typed_value(getattr(rec, f.name)), f.name


@pytest.mark.parametrize("name", ["network-redundant-gauges", "link-oqpsk-sensor",
                                  "loop-dc-motor"])
def test_lean_rows_are_the_record_json(name: str) -> None:
    spec = load_spec(REPORTS / f"{name}.yaml")
    full = analyze_system(spec, options()).to_dict()
    lean, _ = analysis_data(spec, options(), lean=True)
    for key, value in lean.items():   # a section the record leaves out is null in a row
        assert json.dumps(value) == json.dumps(full.get(key)), key   # same keys, same order
