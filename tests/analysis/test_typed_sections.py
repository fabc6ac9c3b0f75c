"""Every section of the record is typed where it is made: ``analysis_sections`` hands the record
frozen dataclasses (or None, text, lists of them), the record is assembled from them without a
strict reader, and the sections the analysis builds itself are never read whole from plain
data (a lower layer's plain result is read only for the part it states)."""
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
from kfcrit.io.typed import ABSENT, RecordError
from kfcrit.records import read
from kfcrit.records.bursty import BurstCondition, StabilityFactsRecord
from kfcrit.records.network import DeadLinkBurst

REPORTS = Path(__file__).resolve().parents[2] / "reports"

FILES = ["network-redundant-gauges", "link-oqpsk-sensor", "ge-bursty-scalar",
         "loop-dc-motor", "trace-bursty-link", "mesh-pipeline-relaying",
         "continuous-cv-tracker", "requirements-tail"]
"""One file per kind of section: a network, a link budget, a Gilbert–Elliott link, a closed
loop, a measured trace, a mesh, a continuous-time plant, requirements."""

BUILT_TYPED = frozenset({"system", "network", "link_budget", "channel_fit", "loop", "design",
                         "tail", "requirements", "verification", "provenance", "review",
                         "operating_point", "mesh"})
"""Sections the analysis builds as their classes (a lower layer's plain parts inside them are
read by field, ``record.KEY.FIELD``, never the whole section ``record.KEY``)."""


def typed_value(value: Any) -> bool:
    """A dataclass, an enum, text, None or a list of these (never a dict of plain data)."""
    if isinstance(value, list):
        return all(typed_value(v) for v in value)
    return (value is None or value is ABSENT or isinstance(value, (str, enum.Enum))
            or (dataclasses.is_dataclass(value) and not isinstance(value, type)))


@pytest.fixture
def whole_reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The record paths read whole by the strict reader during the test."""
    paths: list[str] = []
    real = typed.from_json

    def recording(tp: Any, value: Any, path: str = "record") -> Any:
        paths.append(path)
        return real(tp, value, path)

    monkeypatch.setattr(read, "from_json", recording)
    return paths


def options() -> AnalysisOptions:
    return AnalysisOptions(simulate=False, quick=True)


@pytest.mark.parametrize("name", FILES)
def test_sections_are_typed_where_they_are_made(name: str, whole_reads: list[str]) -> None:
    spec = load_spec(REPORTS / f"{name}.yaml")
    theory = theory_sections(spec.system, options(), channel=spec.channel)
    before = len(whole_reads)
    sec = analysis_sections(spec, options(), theory)
    plain = {k: type(v).__name__ for k, v in sec.items() if not typed_value(v)}
    assert plain == {}, f"plain sections of {name}: {plain}"
    built_whole = sorted({p for p in whole_reads[before:]
                          if p.startswith("record.") and p[len("record."):] in BUILT_TYPED})
    assert built_whole == [], f"{name}: sections read whole from plain data: {built_whole}"


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
    monkeypatch.setattr(read, "from_json", reader)
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


def test_a_lower_layers_result_is_read_strictly_and_its_seconds_kept_apart() -> None:
    plain = {"expression": "(1 - r) a^2 < 1", "value": 0.5, "holds": True, "status": "theorem",
             "decides": True, "seconds": 0.25}
    found: dict[str, float] = {}
    cond = read.read_plain(BurstCondition, plain, "link_budget.condition", found)
    assert cond == BurstCondition(expression="(1 - r) a^2 < 1", value=0.5, holds=True,
                                  status="theorem", decides=True)
    assert found == {"link_budget.condition.seconds": 0.25}
    with pytest.raises(RecordError, match=r"record\.link_budget\.condition: unknown key 'extra'"):
        read.read_plain(BurstCondition, {**plain, "extra": 1}, "link_budget.condition")
    with pytest.raises(RecordError, match=r"record\.x\.holds: must be true or false"):
        read.read_plain(BurstCondition, {**plain, "holds": "yes"}, "x")


def test_fields_the_analysis_built_join_the_lower_layers_fields() -> None:
    facts = StabilityFactsRecord(necessary=True, sufficient=False, exact_region=False,
                                 necessary_basis="n", sufficient_basis="")
    dead = read.read_fields(DeadLinkBurst, {"holds": True}, "network.burst", facts=facts)
    assert dead == DeadLinkBurst(holds=True, facts=facts)
    with pytest.raises(RecordError, match=r"record\.network\.burst: unknown key 'other'"):
        read.read_fields(DeadLinkBurst, {"holds": True, "other": 1}, "network.burst",
                         facts=facts)
    with pytest.raises(RecordError, match=r"record\.network\.burst: .*facts"):
        read.read_fields(DeadLinkBurst, {"holds": True}, "network.burst")
