"""Per-point overhead of sweeps (issue 27 item 4), checked by counting work, never by timing.

* a link-budget sweep parses its base system once and computes its theory once per process,
  however many chunks that process evaluates;
* the lean per-point path (memoised spec, the record's JSON form without the typed round trip)
  gives exactly the rows of ``kfcrit analyze`` on the same document;
* serial and local-process runs give byte-identical tables.
"""
from __future__ import annotations

import json
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


def test_tables_identical_across_runners_and_chunk_sizes(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # per-packet shadowing (the shadowing average decides p) and 116-byte packets, some of
    # which exceed the PHY limit: error rows must be as reproducible as the others
    (tmp_path / "system.yaml").write_text(BASE_SYSTEM.replace(
        "shadowing_sigma_db: 4}", "shadowing_sigma_db: 4, shadowing: per-packet}"))
    (tmp_path / "sweep.yaml").write_text(
        "name: chunks\nsystem: system.yaml\ngrid:\n  channel.packet_bytes: [20, 116, 120]\n"
        "  channel.distance_m: {start: 10, stop: 200, num: 7}\n")
    spec = sweep_mod.load_sweep(tmp_path / "sweep.yaml")
    tables = []
    for label, chunk_max, workers in (("one", 1, 1), ("five", 5, 1), ("all", 256, 1),
                                      ("procs", 3, 2)):
        monkeypatch.setattr(run_mod, "CHUNK_MAX", chunk_max)
        result = sweep_mod.run_sweep(spec, tmp_path / label, workers=workers)
        assert result.computed == 21
        tables.append((sweep_mod.table_csv(spec, result.rows),
                       json.dumps(result.rows, allow_nan=False)))
    assert sum(r["status"] == "error" for r in result.rows) == 7    # 120 bytes > 127 - 11
    assert sum(r["status"] == "ok" for r in result.rows) == 14
    assert all(t == tables[0] for t in tables[1:])


def test_chunks_are_bounded_and_cover_every_point() -> None:
    items: run_mod.Items = [(i, f"k{i}", []) for i in range(1000)]
    for workers in (1, 2, 8):
        parts = run_mod.chunks(items, workers)
        assert [it for part in parts for it in part] == items
        assert max(len(p) for p in parts) <= run_mod.CHUNK_MAX
    assert len(run_mod.chunks(items, 2)) == 8    # ⌈1000 / (4·2)⌉ = 125 points per chunk


def test_forked_and_spawned_workers_give_identical_tables(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    spec = _spec(tmp_path, 50)
    serial = sweep_mod.run_sweep(spec, tmp_path / "serial", workers=1)
    tables = []
    for method in ("fork", "spawn"):
        monkeypatch.setattr(run_mod, "start_method", lambda m=method: m)
        result = sweep_mod.run_sweep(spec, tmp_path / method, workers=2)
        assert result.computed == 50
        tables.append((sweep_mod.table_csv(spec, result.rows), json.dumps(result.rows)))
    assert tables[0] == tables[1] == (sweep_mod.table_csv(spec, serial.rows),
                                      json.dumps(serial.rows))


def test_workers_are_spawned_while_another_thread_runs() -> None:
    import sys
    import threading

    alone = threading.active_count() == 1
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:
        assert run_mod.start_method() == "spawn"
    finally:
        release.set()
        other.join()
    if alone and sys.platform.startswith("linux"):
        assert run_mod.start_method() == "fork"


def test_journal_lines_encode_each_result_once_with_the_documented_check(tmp_path: Path) -> None:
    import hashlib

    from kfcrit.analysis.sweep.journal import JOURNAL_FORMAT, Journal, journal_check

    ok = dict.fromkeys(sweep_mod.RESULT_COLUMNS)
    ok.update(status="ok", margin=-0.0, sinr_db=1e-300, arrival_probability=0.9999999999999999,
              requirement_basis="critical value")
    bad = dict.fromkeys(sweep_mod.RESULT_COLUMNS)
    bad.update(status="error", error="channel.distance_m: must be positive, got −5 (µ)",
               error_code=2)
    binding, keys = "f" * 64, ("a" * 64, "b" * 64)
    journal = Journal(tmp_path / "j.jsonl", binding, sweep_mod.RESULT_COLUMNS)
    journal.append(list(zip(keys, (ok, bad))))
    lines = [json.loads(line) for line in (tmp_path / "j.jsonl").read_text().splitlines()]
    for key, result, line in zip(keys, (ok, bad), lines):
        # the check as the journal format defines it: one JSON text of all four fields
        blob = json.dumps({"journal": JOURNAL_FORMAT, "sweep": binding, "key": key,
                           "result": result}, sort_keys=True, ensure_ascii=True,
                          separators=(",", ":"), allow_nan=False)
        expected = hashlib.sha256(blob.encode()).hexdigest()
        assert line == {"key": key, "check": expected, "result": result}
        assert journal_check(binding, key, result) == expected
    assert journal.load() == dict(zip(keys, (ok, bad)))


def test_shipped_sweep_is_byte_identical_one_point_at_a_time_and_in_chunks(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # chunks of one point compute every link alone; larger chunks warm their links together
    # (kfcrit.link.linkbudget.warm_links) and run on forked workers: the same bytes
    spec = sweep_mod.load_sweep(Path(__file__).parents[2] / "reports" / "sweep-link-distance.yaml")
    tables = []
    for label, chunk_max, workers in (("one", 1, 1), ("all", 256, 1), ("procs", 7, 2)):
        monkeypatch.setattr(run_mod, "CHUNK_MAX", chunk_max)
        result = sweep_mod.run_sweep(spec, tmp_path / label, workers=workers)
        assert result.computed == len(spec.points) == 51 and result.errors == 0
        tables.append((sweep_mod.table_csv(spec, result.rows),
                       json.dumps(result.rows, allow_nan=False)))
    assert tables[1] == tables[0] and tables[2] == tables[0]
