"""Per-point overhead of sweeps (issue 27 item 4), checked by counting work, never by timing.

* a link-budget sweep parses its base system once and computes its theory once per process,
  however many chunks that process evaluates;
* the lean per-point path (memoised spec, the record's JSON form without the typed round trip)
  gives exactly the rows of ``kfcrit analyze`` on the same document;
* serial and local-process runs give byte-identical tables.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import kfcrit.analysis.record as record_mod
import kfcrit.analysis.spec as spec_mod
import kfcrit.analysis.sweep.points as sweep_mod
import kfcrit.analysis.sweep.run as run_mod
from kfcrit.bench.bench_sweep import BASE_SYSTEM, sweep_text
from kfcrit.errors import InputError


def _spec(tmp_path: Path, points: int) -> sweep_mod.SweepSpec:
    (tmp_path / "system.yaml").write_text(BASE_SYSTEM)
    (tmp_path / "sweep.yaml").write_text(sweep_text(points))
    return sweep_mod.load_sweep(tmp_path / "sweep.yaml")


def _items(spec: sweep_mod.SweepSpec) -> run_mod.Items:
    return [(i, k, spec.assignments(i)) for i, k in enumerate(spec.keys)]


def test_system_parsed_and_theory_computed_once_per_process(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    spec = _spec(tmp_path, 40)
    parses: list[int] = []
    theories: list[int] = []
    real_parse, real_theory = spec_mod.spec_from_mapping, record_mod.theory_sections

    def parse(*args, **kwargs):  # noqa: ANN002, ANN003
        parses.append(1)
        return real_parse(*args, **kwargs)

    def theory(*args, **kwargs):  # noqa: ANN002, ANN003
        theories.append(1)
        return real_theory(*args, **kwargs)

    monkeypatch.setattr(spec_mod, "spec_from_mapping", parse)
    monkeypatch.setattr(record_mod, "theory_sections", theory)
    monkeypatch.setattr(run_mod, "_worker_memo", {})
    chunks = run_mod.chunks(_items(spec), 4)
    assert len(chunks) > 3
    rows = []
    for chunk in chunks:   # as a worker process evaluates them, one after the other
        rows += run_mod.evaluate_in_worker(sweep_mod.evaluate_chunk, spec.base_doc,
                                           str(spec.base_dir), spec.tolerance, 400, chunk)
    assert len(rows) == 40
    assert len(parses) == 1      # only channel.* varies: the system is parsed once
    assert len(theories) == 1    # and its theory computed once for every chunk


def test_lean_point_path_equals_analyze(tmp_path: Path) -> None:
    from kfcrit.analysis.record import analyze_system as analyze

    spec = _spec(tmp_path, 30)
    memo: dict = {}
    for index in (0, 7, 14, 21, 28, 29):
        lean = sweep_mod.evaluate_point(spec.base_doc, str(spec.base_dir), spec.tolerance, 400,
                                        spec.assignments(index), memo)
        doc = sweep_mod.apply_point(spec.base_doc, spec.assignments(index))
        try:
            full = spec_mod.spec_from_mapping(doc, base_dir=spec.base_dir, max_states=400)
        except InputError as exc:   # e.g. a packet too long for the PHY: an error row
            assert lean["status"] == "error" and lean["error"] == str(exc)[:300]
            continue
        record = analyze(full, sweep_mod.point_options(spec.tolerance)).to_dict()
        expected = dict.fromkeys(sweep_mod.RESULT_COLUMNS)
        expected.update(sweep_mod.row_of(record))
        assert lean == sweep_mod.jsonable(expected)


def test_serial_and_processes_give_identical_tables(tmp_path: Path) -> None:
    spec = _spec(tmp_path, 60)
    serial = sweep_mod.run_sweep(spec, tmp_path / "serial", workers=1)
    procs = sweep_mod.run_sweep(spec, tmp_path / "procs", workers=2)
    assert serial.computed == procs.computed == 60
    assert (tmp_path / "serial").is_dir() and (tmp_path / "procs").is_dir()
    assert sweep_mod.table_csv(spec, serial.rows) == sweep_mod.table_csv(spec, procs.rows)
