"""Hostile inputs: a corpus of files, generated monsters and fuzzing through loader and CLI.

Every input either works or is refused with exit code 2 and one stderr line naming the field;
nothing is executed, nothing is written, and each case finishes within seconds.
"""
from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
import sympy as sp
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kfcrit import System
from kfcrit.analysis.spec import load_spec, spec_from_mapping
from kfcrit.cli.main import main
from kfcrit.errors import InputError, KfcritError
from kfcrit.model.exprparse import parse_expression

from ..conftest import PROFILE

HOSTILE = Path(__file__).parent
CORPUS = sorted(HOSTILE.glob("*.yaml"))
CPU_BUDGET = 6
"""CPU seconds the kernel grants a ``kfcrit`` child refusing or analysing one hostile file
(interpreter start-up included; a child past it is stopped with SIGXCPU and fails the test by
its exit code, so no test reads a clock)."""
VALID = {"name": "fuzz", "A": [[1.25]], "C": [[1]], "Q": [[1]], "R": [[2.5]],
         "channel": {"model": "bernoulli", "arrival_probability": 0.5}}


def run_cli(args: list[str]) -> tuple[int, str, str, int]:
    """Run the CLI in-process; returns (exit code, stdout, stderr, analyses run).

    The work a refusal costs is counted, not timed: the number of analyses the call started
    (:func:`kfcrit.analysis.record.analysis_sections`). Bad input must be refused before any
    (0); the input layer's own work is bounded by the reader's limits (size, depth, digits),
    which the tests below exercise with their worst cases.
    """
    from kfcrit.analysis import record as record_module

    real = record_module.analysis_sections
    calls: list[int] = []

    def counted(*a, **k):  # noqa: ANN002, ANN003, ANN202
        calls.append(1)
        return real(*a, **k)

    with mock.patch.object(record_module, "analysis_sections", counted):
        r = CliRunner().invoke(main, args)
    return r.exit_code, r.stdout, r.stderr, len(calls)


def assert_refused(code: int, out: str, err: str) -> None:
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfcrit: error: "), err
    assert "Traceback" not in err and out == ""


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
def test_corpus_is_refused(path: Path, tmp_path: Path) -> None:
    before = set(tmp_path.iterdir())
    code, out, err, dt = run_cli(["analyze", str(path), "--no-simulate"])
    assert_refused(code, out, err)
    assert dt == 0   # refused before any analysis ran
    assert set(tmp_path.iterdir()) == before
    assert not Path("/tmp/kfcrit-pwned").exists()


def test_trace_errors_do_not_leak_file_contents() -> None:
    code, out, err, _ = run_cli(["analyze", str(HOSTILE / "trace-passwd.yaml")])
    assert_refused(code, out, err)
    assert "root" not in err


def test_corpus_in_a_real_subprocess() -> None:
    for name in ("inject-import", "alias-bomb", "deep-nesting", "binary-garbage"):
        proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze",
                               str(HOSTILE / f"{name}.yaml")], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and proc.stdout == ""


def test_fifty_megabyte_file_is_refused_quickly(tmp_path: Path) -> None:
    p = tmp_path / "huge.yaml"
    with p.open("w") as fh:
        fh.write("name: huge\nA: [[")
        fh.write("1, " * (50_000_000 // 3))
        fh.write("1]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "file:" in err


def test_million_digit_integer_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "digits.yaml"
    p.write_text("name: digits\nA: [[" + "9" * 1_000_000 + "]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "A[0][0]:" in err


def test_5000_by_5000_matrix_is_refused(tmp_path: Path) -> None:
    # through the API (no file-size guard in the way): the state-size guard answers at once
    with pytest.raises(InputError, match=r"^A: has more than 400 rows"):
        System(np.zeros((5000, 5000)), np.zeros((1, 5000)), 1, 1)
    # through a file with a compact flow sequence that stays under the size limit
    p = tmp_path / "wide.yaml"
    p.write_text("name: wide\nA: [[" + ",".join(["0"] * 5000) + "]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, _ = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "--max-states" in err


def test_max_states_guard_is_adjustable(tmp_path: Path) -> None:
    p = tmp_path / "three.yaml"
    p.write_text("name: three\nA: [[2,0,0],[0,0.5,0],[0,0,0.5]]\nC: [[1,1,1]]\nQ: 1\nR: 1\n")
    code, out, err, _ = run_cli(["analyze", str(p), "--max-states", "2", "--no-simulate"])
    assert_refused(code, out, err)
    assert "A:" in err


def test_memory_stays_bounded_for_hostile_corpus() -> None:
    # peak RSS of this process after running the whole corpus above stays far below 500 MB
    # plus what the interpreter and libraries already hold
    for path in CORPUS:
        run_cli(["analyze", str(path), "--no-simulate"])
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    assert peak_mb < 1500


# ---- fuzzing ----------------------------------------------------------------------------

_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30),
                     st.floats(allow_nan=True, allow_infinity=True),
                     st.text(max_size=40))
_yaml_values = st.recursive(_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=10), inner, max_size=4)),
    max_leaves=20)


def _fuzz_doc(field: str, value: object) -> str:
    doc = dict(VALID)
    if field.startswith("channel."):
        doc["channel"] = {**VALID["channel"], field.split(".", 1)[1]: value}
    else:
        doc[field] = value
    return yaml.safe_dump(doc)


FIELDS = ["name", "description", "A", "C", "Q", "R", "Sigma0", "channel", "requirements",
          "channel.model", "channel.arrival_probability", "unknown"]


@settings(max_examples=60, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), value=_yaml_values)
def test_fuzz_every_field_through_the_loader(field: str, value: object) -> None:
    text = _fuzz_doc(field, value)
    try:
        doc = yaml.safe_load(text)
        spec_from_mapping(doc)
    except KfcritError as exc:
        assert exc.exit_code == 2
        assert "\n" not in str(exc)


@settings(max_examples=40)
@given(text=st.text(max_size=300))
def test_fuzz_matrix_entry_strings(text: str) -> None:
    try:
        spec_from_mapping({**VALID, "A": [[text]]})
    except KfcritError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("A[0][0]:")


@settings(max_examples=40)
@given(data=st.binary(max_size=400))
def test_fuzz_raw_bytes_through_the_file_loader(data: bytes, tmp_path_factory) -> None:  # noqa: ANN001
    p = tmp_path_factory.mktemp("fuzz") / "f.yaml"
    p.write_bytes(data)
    try:
        load_spec(p)
    except KfcritError as exc:
        assert exc.exit_code == 2 and "\n" not in str(exc)


@settings(max_examples=15, deadline=None)
@given(field=st.sampled_from(FIELDS), value=_yaml_values)
def test_fuzz_through_the_cli(field: str, value: object, tmp_path_factory) -> None:  # noqa: ANN001
    p = tmp_path_factory.mktemp("cli") / "f.yaml"
    p.write_text(_fuzz_doc(field, value))
    code, out, err, dt = run_cli(["analyze", str(p), "--no-simulate", "--json"])
    assert code in (0, 2, 3), err
    assert "Traceback" not in err
    if code == 2:
        assert len(err.strip().splitlines()) == 1


# ---- audit "Hardening: hostile inputs" -------------------------------------------------------

def _one_line_error(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfcrit: error: "), err
    return lines[0]


@pytest.mark.parametrize("name", ["deep-flow-30000", "deep-mapping-30000", "deep-block-30000"])
def test_30000_deep_nesting_exits_2_in_a_real_subprocess(name: str) -> None:
    # PyYAML's C composer recursed into a segfault (exit 139) on these; the event scan refuses
    # them before any node is composed
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(HOSTILE / f"{name}.yaml"),
                           "--no-simulate"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-500:])
    line = _one_line_error(proc.stderr)
    # PyYAML ≥ 6.0.4's scanner may refuse a deep flow collection first, in its own words
    assert f"{name}.yaml" in line and proc.stdout == ""
    assert "deeper than 64 levels" in line or "maximum nesting depth" in line, line


def test_nesting_within_the_limit_is_only_a_schema_error(tmp_path: Path) -> None:
    p = tmp_path / "ok-depth.yaml"
    p.write_text("name: d\nA: " + "[" * 60 + "]" * 60 + "\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, _ = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "deeper than" not in err and "A" in err


def test_nine_million_entry_row_is_refused_within_seconds(tmp_path: Path) -> None:
    # 18 MB, one row of 9 000 000 entries: ran > 120 s and 2.3 GB before the scan
    p = tmp_path / "row.yaml"
    p.write_text("name: row\nA: [[" + "1," * 9_000_000 + "1]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "A: has more than 400 rows or columns" in err and "--max-states" in err
    assert dt == 0, dt


def test_1400_by_1400_matrix_is_refused_within_seconds(tmp_path: Path) -> None:
    # 118 s before the 400-row refusal: now refused while reading the first row
    row = "[" + ",".join(["0.5"] * 1400) + "]"
    p = tmp_path / "square.yaml"
    p.write_text("name: sq\nA: [" + ",".join([row] * 1400) + "]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "A: has more than 400 rows" in err, dt
    # the raised limit is honoured by the same guard (the row of 1400 passes, 1400 rows fail)
    code, out, err, dt = run_cli(["analyze", str(p), "--max-states", "1399"])
    assert_refused(code, out, err)
    assert "A: has more than 1399 rows" in err, dt


def test_tall_block_matrix_is_refused_by_rows(tmp_path: Path) -> None:
    p = tmp_path / "tall.yaml"
    p.write_text("name: t\nA:\n" + "- [1, 2, 3]\n" * 500 + "C: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "A: has more than 400 rows" in err


def test_yaml_value_budget_is_refused_within_seconds(tmp_path: Path) -> None:
    # lists within 400 entries, but 400 x 400 x 40 values: beyond 5*400^2 + 10000 in one file
    inner = "[" + ",".join(["1"] * 40) + "]"
    row = "[" + ",".join([inner] * 400) + "]"
    p = tmp_path / "many.yaml"
    p.write_text("name: many\nA: [" + ",".join([row] * 400) + "]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "file:" in err and "more than 810000 YAML values" in err, dt


def test_shapes_are_checked_before_any_exact_conversion(monkeypatch: pytest.MonkeyPatch) -> None:
    import kfcrit.io.systemfile as sf

    def no_conversion(*args: object, **kwargs: object) -> None:
        raise AssertionError("an entry was converted before the shapes were checked")

    monkeypatch.setattr(sf, "_exact_numbers", no_conversion)
    big = [["0.5"] * 1400 for _ in range(1400)]
    with pytest.raises(InputError, match=r"^A: has more than 400 rows"):
        spec_from_mapping({**VALID, "A": big})
    with pytest.raises(InputError, match=r"^C: must have 300 columns"):
        spec_from_mapping({**VALID, "A": [["0.5"] * 300 for _ in range(300)], "C": [[1, 2]]})
    with pytest.raises(InputError, match=r"^Q: must be 2x2, got 3x3"):
        spec_from_mapping({**VALID, "A": [[1, 0], [0, 1]], "C": [[1, 1]],
                           "Q": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]})
    with pytest.raises(InputError, match=r"^A: row 1 has 1 entries"):
        spec_from_mapping({**VALID, "A": [[1, 0], [0]]})
    with pytest.raises(InputError, match=r"^A: has more than 2 rows"):
        spec_from_mapping({**VALID, "A": [[1] * 3] * 3, "C": [[1] * 3]}, max_states=2)


def test_bounded_symmetry_check_refuses_a_near_miss_at_once() -> None:
    # sp.simplify of this difference ran for minutes; the entries agree to 58 digits
    code, out, err, dt = run_cli(["analyze", str(HOSTILE / "asymmetric-radicals.yaml"),
                                  "--no-simulate"])
    assert_refused(code, out, err)
    assert "Q: must be symmetric (Q[0][1] != Q[1][0])" in err


def test_symmetry_of_equal_entries_in_different_forms() -> None:
    # provably equal (expansion), and equal but beyond the bounded exact test: both accepted
    for q01, q10 in (("(1+sqrt(2))**2", "3+2*sqrt(2)"), ("(cos(1)**2+sin(1)**2)^64", "1")):
        s = System([[1, 0], [0, 1]], [[1, 1]], [[9, q01], [q10, 9]], 1)
        assert s.Q[0, 1] == s.Q[1, 0]  # symmetrised where equal but not provably so
        assert abs(float(s.Q[0, 1]) - float(sp.N(parse_expression(q01), 20))) < 1e-12
    # a difference far below the float tolerance but certain: refused
    with pytest.raises(InputError, match=r"^Q: must be symmetric"):
        System([[1, 0], [0, 1]], [[1, 1]], [[9, "sqrt(2)"], ["sqrt(2)+1e-80", 9]], 1)


def test_probability_equal_to_one_but_not_syntactically(tmp_path: Path) -> None:
    # exit 4 (TypeError from bool() of a sympy relational) before the fix
    p = tmp_path / "one.yaml"
    p.write_text("name: one\nA: [[2]]\nC: 1\nQ: 1\nR: 1\nchannel: {model: bernoulli, "
                 "arrival_probability: 'cos(1)**2+sin(1)**2'}\n"
                 "requirements: {max_error_trace: 10,\n"
                 "               max_tail_probability: 'sin(1)**2+cos(1)**2'}\n")
    spec = load_spec(p)
    assert spec.channel.arrival_probability == 1  # proven equal to the end point: exactly 1
    assert spec.requirements.max_tail_probability == 1.0
    code, out, err, _ = run_cli(["analyze", str(p), "--no-simulate", "--json"])
    assert code in (0, 1, 3) and "Traceback" not in err and "internal error" not in err, err


@pytest.mark.parametrize(("name", "field"), [
    ("undecidable-zero", "A[0][0]:"),
    ("undecidable-probability", "channel.arrival_probability:"),
    ("log-of-unprovable-one", "A[0][0]:"),
    ("tiny-product", "A[0][0]:"),
    ("tiny-exp", "A[0][0]:"),
    ("huge-product", "A[0][0]:"),
])
def test_undecidable_and_out_of_range_values_name_the_field(name: str, field: str) -> None:
    code, out, err, dt = run_cli(["analyze", str(HOSTILE / f"{name}.yaml"), "--no-simulate"])
    assert_refused(code, out, err)
    assert f"kfcrit: error: {field}" in err


def test_tiny_values_follow_the_literal_rule(tmp_path: Path) -> None:
    # the literal 1e-301 and the expressions 1e-200*1e-200, exp(-690)**2 are all refused;
    # 1e-300 as a literal and as an expression (1e-150*1e-150) are both accepted
    for text in ("1e-301", "'1e-200*1e-200'", "'exp(-690)**2'", "'1e-150*1e-151'"):
        with pytest.raises(InputError, match=r"out of range"):
            spec_from_mapping({**VALID, "A": [[yaml.safe_load(text) if text[0] == "'"
                                               else text]]})
    for text in ("1e-300", "1e-150*1e-150", "exp(-690)"):
        spec_from_mapping({**VALID, "A": [[text]]})


@pytest.mark.parametrize(("name", "field"), [
    ("merge-inline", "kfcrit: error: channel.<<: YAML merge keys (<<) are not allowed"),
    ("duplicate-channel-key", "kfcrit: error: channel.arrival_probability: duplicate key"),
    ("null-key", "kfcrit: error: <null key>: a null key (~, null or empty) at top level"),
    ("null-key-channel", "kfcrit: error: channel.<null key>: a null key"),
    ("complex-key", "kfcrit: error: file: mapping keys must be plain names"),
])
def test_key_problems_name_the_full_field(name: str, field: str) -> None:
    code, out, err, _ = run_cli(["analyze", str(HOSTILE / f"{name}.yaml"), "--no-simulate"])
    assert_refused(code, out, err)
    assert err.startswith(field), err


def test_null_key_through_the_api_is_named() -> None:
    with pytest.raises(InputError, match=r"^<null key>: unknown key"):
        spec_from_mapping({**VALID, None: 1})
    with pytest.raises(InputError, match=r"^channel\.<null key>: unknown key"):
        spec_from_mapping({**VALID, "channel": {**VALID["channel"], None: 1}})


def test_merge_key_in_a_sweep_file_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "sweep.yaml"
    p.write_text("system:\n  <<: {name: hidden}\n  name: merged\n  A: [[1.25]]\n  C: 1\n  Q: 1\n"
                 "  R: 1\n  channel: {model: bernoulli, arrival_probability: 0.5}\n"
                 "grid:\n  channel.arrival_probability: [0.5, 0.9]\n")
    code, out, err, _ = run_cli(["sweep", str(p), "-o", str(tmp_path / "out")])
    assert_refused(code, out, err)
    assert "system.<<: YAML merge keys" in err
    assert not (tmp_path / "out").exists()


# ---- outputs ---------------------------------------------------------------------------------

def test_unwritable_report_output_is_bad_input(tmp_path: Path) -> None:
    afile = tmp_path / "plain-file"
    afile.write_text("x")
    for target in ("/proc/kfcrit-x.html", str(afile / "x.html"), str(tmp_path / "no" / "x.html")):
        code, out, err, dt = run_cli(["report", str(HOSTILE.parent.parent / "reports" /
                                                    "sinopoli-scalar.yaml"), "-o", target,
                                      "--quick"])
        assert_refused(code, out, err)
        assert err.startswith("kfcrit: error: output: cannot write") and target in err, err
        assert dt == 0  # refused before the analysis runs


def test_bad_system_file_gives_only_the_error_line_for_report(tmp_path: Path) -> None:
    out_file = tmp_path / "x.html"
    for name in ("deep-flow-30000", "duplicate-channel-key", "tiny-product"):
        code, out, err, _ = run_cli(["report", str(HOSTILE / f"{name}.yaml"), "-o", str(out_file)])
        assert_refused(code, out, err)
        assert "reading" not in err
    assert not out_file.exists()


def test_write_atomic_turns_os_errors_into_output_errors(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    import errno
    import os

    from kfcrit.errors import OutputError
    from kfcrit.io.atomic import write_atomic

    target = tmp_path / "keep.txt"
    target.write_bytes(b"old")

    def full_disk(*args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(OutputError, match=r"^output: cannot write .*No space left") as info:
        write_atomic(target, b"new")
    assert info.value.exit_code == 2
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]  # no temporary left


def test_os_error_naming_a_path_maps_to_exit_2(monkeypatch: pytest.MonkeyPatch) -> None:
    import kfcrit.analysis.spec as sf  # the reader the CLI calls

    def denied(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", "/some/output/folder")

    monkeypatch.setattr(sf, "load_spec", denied)
    code, out, err, _ = run_cli(["analyze", str(HOSTILE / "nan.yaml")])
    assert_refused(code, out, err)
    assert "/some/output/folder" in err and "Permission denied" in err


# ---- usage errors ----------------------------------------------------------------------------

@pytest.mark.parametrize(("args", "expected"), [
    (["analyze", "x.yaml", "--bogus"], "No such option '--bogus'"),
    (["analyze"], "Missing argument 'SYSTEM_FILE'"),
    (["analyze", "x.yaml", "--seed", "minus"], "Invalid value for '--seed'"),
    (["analyze", "x.yaml", "--tolerance", "nan"], "must be a number in [0, 0.1], got 'nan'"),
    (["analyze", "x.yaml", "--tolerance", "0.5"], "must be a number in [0, 0.1], got '0.5'"),
    (["report", "x.yaml"], "Missing option '-o'"),
    (["frobnicate"], "No such command 'frobnicate'"),
])
def test_usage_errors_are_one_line(args: list[str], expected: str) -> None:
    code, out, err, _ = run_cli(args)
    assert code == 2, (code, err)
    line = _one_line_error(err)
    assert expected in line and "Usage:" not in err and out == ""


def test_usage_error_in_a_real_subprocess() -> None:
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze", "--nope"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert "No such option '--nope'" in _one_line_error(proc.stderr)


def test_help_and_version_still_work() -> None:
    for args in (["--help"], ["analyze", "--help"], ["sweep", "-h"]):
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 0 and r.stdout.startswith("Usage: ") and r.stderr == ""
    r = CliRunner().invoke(main, ["--version"])
    assert r.exit_code == 0 and "kfcrit, version" in r.stdout
    r = CliRunner().invoke(main, ["analyze", "--help"])
    assert "[0, 0.1]" in r.stdout


# ---- fuzzing: sweep files, channel subfields, requirements; real subprocesses ----------------

def _field_of(err: str) -> str:
    """The field named by a one-line CLI error ``kfcrit: error: FIELD: message``."""
    line = _one_line_error(err)
    return line[len("kfcrit: error: "):].split(": ", 1)[0]


def _names_the_field(named: str | None, fuzzed: str) -> bool:
    """The error names the fuzzed field, a part of it, or the mapping holding it (a check across
    the mapping's entries); ``file`` for YAML-level problems."""
    if not named:
        return False
    return named == "file" or named.startswith(fuzzed) or fuzzed.startswith(named)


SWEEP_BASE = {"name": "fuzz sweep", "system": "system.yaml",
              "grid": {"channel.arrival_probability": [0.6, 0.9]}}
SWEEP_FIELDS = {
    # fuzzed key: the field prefixes an error may name
    "name": ("sweep.name",), "description": ("sweep.description",), "system": ("system",),
    "tolerance": ("sweep.tolerance",), "grid": ("sweep.grid",), "plot": ("sweep.plot",),
    "points": ("sweep.points", "sweep.grid"), "unknown": ("sweep.unknown",),
    "grid.channel.arrival_probability": ("sweep.grid.channel.arrival_probability",),
    "grid.A[0][0]": ("sweep.grid.A[0][0]",),
    "system.A": ("system",), "system.channel": ("system",),
}
_BASE_SYSTEM = ("name: base\nA: [[1.25]]\nC: [[1]]\nQ: [[1]]\nR: [[2.5]]\n"
                "channel: {model: bernoulli, arrival_probability: 0.5}\n")


def _sweep_doc(field: str, value: object) -> dict:
    doc = {k: (dict(v) if isinstance(v, dict) else v) for k, v in SWEEP_BASE.items()}
    if field.startswith("grid."):
        doc["grid"] = {field[5:]: value}
    elif field.startswith("system."):
        base = yaml.safe_load(_BASE_SYSTEM)
        base[field[7:]] = value
        doc["system"] = base
    elif field == "points":
        doc.pop("grid")
        doc["points"] = value
    else:
        doc[field] = value
    return doc


def _sweep_case(folder: Path, field: str, value: object) -> Path:
    (folder / "system.yaml").write_text(_BASE_SYSTEM)
    p = folder / "sweep.yaml"
    p.write_text(yaml.safe_dump(_sweep_doc(field, value)))
    return p


@settings(max_examples=60, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(sorted(SWEEP_FIELDS)), value=_yaml_values)
def test_fuzz_sweep_fields_through_the_loader(field: str, value: object,
                                              tmp_path_factory) -> None:  # noqa: ANN001
    from kfcrit.analysis.sweep.points import load_sweep

    p = _sweep_case(tmp_path_factory.mktemp("sweep"), field, value)
    try:
        load_sweep(p)
    except KfcritError as exc:
        assert exc.exit_code == 2 and "\n" not in str(exc)
        assert any(_names_the_field(exc.field, f) for f in SWEEP_FIELDS[field]), (field, exc)


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(sorted(SWEEP_FIELDS)), value=_yaml_values)
def test_fuzz_sweep_files_through_the_cli(field: str, value: object,
                                          tmp_path_factory) -> None:  # noqa: ANN001
    folder = tmp_path_factory.mktemp("sweepcli")
    p = _sweep_case(folder, field, value)
    out_dir = folder / "out"
    before = sorted(x.name for x in folder.iterdir())
    code, out, err, dt = run_cli(["sweep", str(p), "-o", str(out_dir), "--workers", "1"])
    assert "Traceback" not in err and "internal error" not in err, err
    if code == 2 and not out_dir.exists():  # refused before anything ran
        named = _field_of(err)
        assert any(_names_the_field(named, f) for f in SWEEP_FIELDS[field]), (field, err)
        assert sorted(x.name for x in folder.iterdir()) == before  # nothing written
        assert dt == 0, dt
    else:  # it ran: done, or points that failed on their own (a row each) — never a crash
        assert code in (0, 2, 3), err
        assert (out_dir / "sweep.csv").exists()


LINK_CHANNEL = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": 0,
                "distance_m": 50, "packet_bytes": 40,
                "path_loss": {"model": "log-distance", "exponent": 3.0,
                              "reference_distance_m": 1, "reference_loss_db": 40.2,
                              "shadowing_sigma_db": 4},
                "noise": {"noise_figure_db": 10, "bandwidth_hz": 2.0e6, "temperature_k": 290},
                "margin_db": 2, "max_outage": 0.1}
CHANNELS = {"gilbert-elliott": {"model": "gilbert-elliott", "failure_rate": 0.1,
                                "recovery_rate": 0.5},
            "trace": {"model": "trace", "path": "trace.txt"},
            "link-budget": LINK_CHANNEL}
CHANNEL_FIELDS = [
    ("gilbert-elliott", "failure_rate"), ("gilbert-elliott", "recovery_rate"),
    ("gilbert-elliott", "unknown"), ("trace", "path"), ("trace", "unknown"),
    ("link-budget", "radio"), ("link-budget", "radio.model"), ("link-budget", "tx_power_dbm"),
    ("link-budget", "distance_m"), ("link-budget", "packet_bytes"),
    ("link-budget", "path_loss"), ("link-budget", "path_loss.model"),
    ("link-budget", "path_loss.exponent"), ("link-budget", "path_loss.shadowing_sigma_db"),
    ("link-budget", "noise"), ("link-budget", "noise.bandwidth_hz"),
    ("link-budget", "noise.temperature_k"), ("link-budget", "margin_db"),
    ("link-budget", "max_outage"), ("link-budget", "unknown"),
    ("requirements", "max_error_trace"), ("requirements", "max_tail_probability"),
    ("requirements", "unknown"), ("requirements", ""),
]


def _channel_doc(model: str, sub: str, value: object) -> dict:
    doc = {k: v for k, v in VALID.items() if k != "channel"}
    if model == "requirements":
        reqs: object = {"max_error_trace": 10, "max_tail_probability": 0.01}
        if sub:
            reqs[sub] = value  # type: ignore[index]
        else:
            reqs = value
        doc["channel"] = VALID["channel"]
        doc["requirements"] = reqs
        return doc
    channel = yaml.safe_load(yaml.safe_dump(CHANNELS[model]))  # a deep copy
    head, _, tail = sub.partition(".")
    if tail:
        inner = channel.get(head)
        channel[head] = {**inner, tail: value} if isinstance(inner, dict) else {tail: value}
    else:
        channel[head] = value
    doc["channel"] = channel
    return doc


@settings(max_examples=80, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=st.sampled_from(CHANNEL_FIELDS), value=_yaml_values)
def test_fuzz_channel_subfields_and_requirements(case: tuple[str, str], value: object,
                                                 tmp_path_factory) -> None:  # noqa: ANN001
    model, sub = case
    base_dir = tmp_path_factory.mktemp("chan")
    (base_dir / "trace.txt").write_text("1 0 1 1 0 1\n")
    root = "requirements" if model == "requirements" else "channel"
    fuzzed = f"{root}.{sub}" if sub else root
    # through YAML text, as a file would give it (numbers keep their text)
    text = yaml.safe_dump(_channel_doc(model, sub, value))
    p = base_dir / "f.yaml"
    p.write_text(text)
    try:
        load_spec(p)
    except KfcritError as exc:
        assert exc.exit_code == 2 and "\n" not in str(exc)
        assert _names_the_field(exc.field, fuzzed), (fuzzed, str(exc))
        assert "root:" not in str(exc)  # a trace path's contents are never echoed


def _run_measured(args: list[str]) -> tuple[int, str, str, float, float, float]:
    """A real ``kfcrit`` subprocess: (exit code, stdout, stderr, CPU s, peak RSS MB).

    The timer only kills a hang; nothing here reads the wall clock.

    Peak RSS and CPU time are the kernel's accounting for that child alone (``os.wait4``: the
    per-child form of ``resource.getrusage(RUSAGE_CHILDREN)``, which would mix in every child
    of the test session); a 2 GB address-space limit keeps a runaway case from eating the
    machine, and a timer kills a hang.
    """
    import os
    import tempfile
    import threading

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2_000_000_000, 2_000_000_000))
        # the kernel stops a child past its CPU budget (SIGXCPU): exit code -24, not 0/2/3
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_BUDGET, CPU_BUDGET))

    with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe:
        proc = subprocess.Popen([sys.executable, "-m", "kfcrit", *args], stdout=fo, stderr=fe,
                                stdin=subprocess.DEVNULL, preexec_fn=limit)
        timer = threading.Timer(120, proc.kill)
        timer.start()
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        finally:
            timer.cancel()
        proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
        fo.seek(0)
        fe.seek(0)
        out, err = fo.read().decode(errors="replace"), fe.read().decode(errors="replace")
    return (proc.returncode, out, err, usage.ru_utime + usage.ru_stime,
            usage.ru_maxrss / 1024)


_SUBPROCESS_EXAMPLES = {"ci": 4, "dev": 10, "thorough": 60}.get(PROFILE, 4)
MEGABYTES = 500


@settings(max_examples=_SUBPROCESS_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS + ["channel.failure_rate", "requirements.max_error_trace"]),
       value=_yaml_values)
def test_fuzz_in_a_real_subprocess_bounded_time_and_memory(field: str, value: object,
                                                           tmp_path_factory) -> None:  # noqa: ANN001
    folder = tmp_path_factory.mktemp("proc")
    p = folder / "f.yaml"
    if field.startswith("requirements."):
        p.write_text(yaml.safe_dump({**VALID, "requirements": {field.split(".", 1)[1]: value}}))
    else:
        p.write_text(_fuzz_doc(field, value))
    before = sorted(x.name for x in folder.iterdir())
    code, out, err, cpu, peak_mb = _run_measured(["analyze", str(p), "--no-simulate",
                                                        "--json"])
    assert code in (0, 2, 3), (code, err[-2000:])
    assert "Traceback" not in err
    assert peak_mb < MEGABYTES, peak_mb
    assert sorted(x.name for x in folder.iterdir()) == before
    if code == 2:
        named = _field_of(err)
        root = field.split(".", 1)[0] if field != "unknown" else "unknown"
        assert _names_the_field(named, field) or named.startswith(root), (field, err)
        assert out == ""


def test_hostile_corpus_in_subprocesses_within_500_mb() -> None:
    for name in ("alias-bomb", "deep-flow-30000", "huge-product", "exponent-tower"):
        code, out, err, cpu, peak_mb = _run_measured(["analyze", str(HOSTILE / f"{name}.yaml"),
                                                         "--no-simulate"])
        assert code == 2 and out == "", (name, err)
        _one_line_error(err)
        assert peak_mb < MEGABYTES, (name, peak_mb, cpu)


@pytest.mark.parametrize("name", ["fstring", "walrus", "starred"])
def test_corpus_messages_use_plain_words(name: str) -> None:
    code, out, err, _ = run_cli(["analyze", str(HOSTILE / f"{name}.yaml"), "--no-simulate"])
    assert_refused(code, out, err)
    for ast_name in ("JoinedStr", "FormattedValue", "NamedExpr", "Starred"):
        assert ast_name not in err, err
