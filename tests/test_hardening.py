"""Hostile inputs: a corpus of files, generated monsters and fuzzing through loader and CLI.

Every input either works or is refused with exit code 2 and one stderr line naming the field;
nothing is executed, nothing is written, and each case finishes within seconds.
"""
from __future__ import annotations

import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kfcrit import System
from kfcrit.cli import main
from kfcrit.errors import InputError, KfcritError
from kfcrit.systemfile import load_spec, spec_from_mapping

HOSTILE = Path(__file__).parent / "hostile"
CORPUS = sorted(HOSTILE.glob("*.yaml"))
SECONDS = 5.0
VALID = {"name": "fuzz", "A": [[1.25]], "C": [[1]], "Q": [[1]], "R": [[2.5]],
         "channel": {"model": "bernoulli", "arrival_probability": 0.5}}


def run_cli(args: list[str]) -> tuple[int, str, str, float]:
    t0 = time.perf_counter()
    r = CliRunner().invoke(main, args)
    return r.exit_code, r.stdout, r.stderr, time.perf_counter() - t0


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
    assert dt < SECONDS
    assert set(tmp_path.iterdir()) == before
    assert not Path("/tmp/kfcrit-pwned").exists()


def test_trace_errors_do_not_leak_file_contents() -> None:
    code, out, err, _ = run_cli(["analyze", str(HOSTILE / "trace-passwd.yaml")])
    assert_refused(code, out, err)
    assert "root" not in err


def test_corpus_in_a_real_subprocess() -> None:
    for name in ("inject-import", "alias-bomb", "deep-nesting", "binary-garbage"):
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze",
                               str(HOSTILE / f"{name}.yaml")], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and proc.stdout == ""
        assert time.perf_counter() - t0 < 30  # includes interpreter start-up


def test_fifty_megabyte_file_is_refused_quickly(tmp_path: Path) -> None:
    p = tmp_path / "huge.yaml"
    with p.open("w") as fh:
        fh.write("name: huge\nA: [[")
        fh.write("1, " * (50_000_000 // 3))
        fh.write("1]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "file:" in err and dt < SECONDS


def test_million_digit_integer_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "digits.yaml"
    p.write_text("name: digits\nA: [[" + "9" * 1_000_000 + "]]\nC: 1\nQ: 1\nR: 1\n")
    code, out, err, dt = run_cli(["analyze", str(p)])
    assert_refused(code, out, err)
    assert "A[0][0]:" in err and dt < SECONDS


def test_5000_by_5000_matrix_is_refused(tmp_path: Path) -> None:
    # through the API (no file-size guard in the way): the state-size guard answers at once
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"^A: has more than 400 rows"):
        System(np.zeros((5000, 5000)), np.zeros((1, 5000)), 1, 1)
    assert time.perf_counter() - t0 < SECONDS
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
    assert dt < 30
