"""System files: exact numbers, shorthand, channels, and every bad input of the foundation issue."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from kfcrit import System, load_spec, load_system
from kfcrit.cli.main import main
from kfcrit.errors import InputError

from ..conftest import REPORTS, SHARED_CASES, example_files

GOOD = """\
name: test
A: [[-1.25]]
C: [[1]]
Q: [[1]]
R: [[2.5]]
"""


def write(tmp_path: Path, text: str | bytes, name: str = "sys.yaml") -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


def test_numbers_are_exact_rationals(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD.replace("[[-1.25]]", "[[1.1, 1e-3], [0.1, '2*cos(pi/5)']]")
              .replace("C: [[1]]", "C: [[1, 0]]").replace("Q: [[1]]", "Q: 0.5"))
    s = load_system(p)
    assert s.A[0, 0] == sp.Rational(11, 10)
    assert s.A[0, 1] == sp.Rational(1, 1000)
    assert s.A[1, 0] == sp.Rational(1, 10)
    assert sp.simplify(s.A[1, 1] - (1 + sp.sqrt(5)) / 2) == 0
    assert s.exact
    # the scalar Q is 0.5 times the identity
    assert s.Q == sp.ImmutableMatrix([[sp.Rational(1, 2), 0], [0, sp.Rational(1, 2)]])
    assert s.R == sp.ImmutableMatrix([[sp.Rational(5, 2)]])


def test_scalar_shorthand_for_A_and_C(tmp_path: Path) -> None:
    s = load_system(write(tmp_path, "name: s\nA: 2\nC: 1\nQ: 1\nR: 1\nSigma0: 3\n"))
    assert s.A.shape == (1, 1) and s.A[0, 0] == 2
    assert s.Sigma0[0, 0] == 3


@pytest.mark.parametrize("path", example_files(), ids=lambda p: p.name)
def test_examples_load(path: Path) -> None:
    spec = load_spec(path)
    assert spec.system.n >= 1
    assert spec.channel is not None or spec.mesh is not None or (spec.network is not None and all(
        s.channel is not None for s in spec.network.sensors))
    assert spec.sha256 is not None and len(spec.sha256) == 64


def test_channels(tmp_path: Path) -> None:
    ge = load_spec(write(tmp_path, GOOD + "channel: {model: gilbert-elliott, failure_rate: 0.1, "
                         "recovery_rate: 0.4}\n")).channel
    # stationary arrival probability r/(f+r) = 0.4/0.5
    assert ge.arrival_probability == sp.Rational(4, 5)
    b = load_spec(write(tmp_path, GOOD + "channel: {model: bernoulli, arrival_probability: "
                        "0.7}\n")).channel
    assert b.arrival_probability == sp.Rational(7, 10) and b.iid


def test_system_api_accepts_arrays_and_sympy() -> None:
    s1 = System(np.array([[1.25, 0.0], [1.0, 1.1]]), np.array([[1.0, 1.0]]), 20 * np.eye(2), 2.5)
    assert not s1.exact  # binary floats as entered
    assert s1.A[0, 0] == sp.Rational(5, 4)  # 1.25 is a binary float exactly
    s2 = System(sp.Matrix([[sp.Rational(5, 4)]]), [[1]], [[Fraction(1, 3)]], [[2]])
    assert s2.exact and s2.Q[0, 0] == sp.Rational(1, 3)
    with pytest.raises(InputError, match="^Q: must be 1x1"):
        System([[1]], [[1]], [[1, 0], [0, 1]], [[1]])


def test_from_statespace() -> None:
    control = pytest.importorskip("control")
    ss = control.ss([[1.25, 0], [1, 1.1]], [[1], [0]], [[1, 1]], [[0]], True)
    s = System.from_statespace(ss, Q=20, R=2.5, name="cs")
    assert s.n == 2 and s.m == 1 and s.A[1, 1] == sp.Float(1.1) or float(s.A[1, 1]) == 1.1
    with pytest.raises(InputError, match="discrete-time"):
        System.from_statespace(control.ss([[1]], [[1]], [[1]], [[0]]), Q=1, R=1)


BAD_INPUTS = {
    "missing-file": (None, "file"),
    "empty": ("", "file"),
    "whitespace": ("   \n\n", "file"),
    "not-yaml": ("name: [unclosed\nA: {{\n", "file"),
    "not-mapping": ("- 1\n- 2\n", "file"),
    "scalar-doc": ("42\n", "file"),
    "missing-A": ("name: x\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n", "A"),
    "missing-name": ("A: [[1]]\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n", "name"),
    "A-not-square": (GOOD.replace("[[-1.25]]", "[[1, 2]]"), "A"),
    "A-ragged": (GOOD.replace("[[-1.25]]", "[[1, 2], [3]]"), "A"),
    "C-wrong-columns": (GOOD.replace("C: [[1]]", "C: [[1, 2]]"), "C"),
    "Q-not-symmetric": ("name: x\nA: [[1, 0], [0, 1]]\nC: [[1, 0]]\nQ: [[1, 2], [0, 1]]\n"
                        "R: [[1]]\n", "Q"),
    "Q-indefinite": (GOOD.replace("Q: [[1]]", "Q: [[-1]]"), "Q"),
    "R-singular": (GOOD.replace("R: [[2.5]]", "R: [[0]]"), "R"),
    "R-indefinite": (GOOD.replace("R: [[2.5]]", "R: [[-2.5]]"), "R"),
    "nan": (GOOD.replace("[[-1.25]]", "[[.nan]]"), "A[0][0]"),
    "inf": (GOOD.replace("[[-1.25]]", "[[.inf]]"), "A[0][0]"),
    "minus-inf": (GOOD.replace("[[-1.25]]", "[[-.inf]]"), "A[0][0]"),
    "1e400": (GOOD.replace("[[-1.25]]", "[[1e400]]"), "A[0][0]"),
    "1.0e400": (GOOD.replace("[[-1.25]]", "[[1.0e+400]]"), "A[0][0]"),
    "import": (GOOD.replace("[[-1.25]]", "[[\"__import__('os').system('id')\"]]"), "A[0][0]"),
    "class": (GOOD.replace("[[-1.25]]", "[[\"().__class__\"]]"), "A[0][0]"),
    "open": (GOOD.replace("[[-1.25]]", "[[\"open('x')\"]]"), "A[0][0]"),
    "tower": (GOOD.replace("[[-1.25]]", "[[\"9**9**9**9\"]]"), "A[0][0]"),
    "long-expression": (GOOD.replace("[[-1.25]]", "[[\"" + "1+" * 50_000 + "1\"]]"), "A[0][0]"),
    "alias-bomb": ("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a]\n"
                   "c: &c [*b, *b, *b, *b, *b, *b, *b, *b]\nname: x\nA: [[1]]\nC: [[1]]\n"
                   "Q: [[1]]\nR: [[1]]\n", "file"),
    "unknown-channel": (GOOD + "channel: {model: carrier-pigeon}\n", "channel.model"),
    "p-too-large": (GOOD + "channel: {model: bernoulli, arrival_probability: 1.5}\n",
                    "channel.arrival_probability"),
    "p-negative": (GOOD + "channel: {model: bernoulli, arrival_probability: -0.1}\n",
                   "channel.arrival_probability"),
    "typo-key": (GOOD + "channel: {model: bernoulli, arival_probability: 0.5}\n",
                 "channel.arival_probability"),
    "unknown-top-key": (GOOD + "Qq: 1\n", "Qq"),
    "duplicate-key": (GOOD + "A: [[2]]\n", "A"),
    "boolean-entry": (GOOD.replace("[[-1.25]]", "[[yes]]"), "A[0][0]"),
    "python-tag": (GOOD.replace("[[-1.25]]", "[[!!python/object/apply:os.system ['id']]]"),
                   "file"),
    "ge-zero-rate": (GOOD + "channel: {model: gilbert-elliott, failure_rate: 0, "
                     "recovery_rate: 0.5}\n", "channel.failure_rate"),
    "binary": (b"\xff\xfe\x00garbage\x80", "file"),
    "deep-nesting": ("name: x\nA: " + "[" * 5000 + "]" * 5000 + "\nC: 1\nQ: 1\nR: 1\n", None),
    "requirements-negative": (GOOD + "requirements: {max_error_trace: -1}\n",
                              "requirements.max_error_trace"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_one_line_exit_2(case: str, tmp_path: Path) -> None:
    text, field = BAD_INPUTS[case]
    path = tmp_path / "missing.yaml" if text is None else write(tmp_path, text)
    before = sorted(tmp_path.iterdir())
    result = CliRunner().invoke(main, ["analyze", str(path)])
    assert result.exit_code == 2, result.output
    err = result.stderr.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("kfcrit: error: ")
    assert "Traceback" not in err
    if field is not None:
        assert f"error: {field}:" in err, err
    assert result.stdout == ""
    assert sorted(tmp_path.iterdir()) == before  # nothing written


def test_injection_executes_nothing(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    text = GOOD.replace("[[-1.25]]", f"[[\"__import__('os').system('touch {marker}')\"]]")
    result = CliRunner().invoke(main, ["analyze", str(write(tmp_path, text))])
    assert result.exit_code == 2
    assert not marker.exists()


def test_real_subprocess_bad_input(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD.replace("R: [[2.5]]", "R: [[0]]"))
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(p)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "kfcrit: error: R: must be symmetric positive definite"
    assert proc.stdout == ""


def test_debug_shows_traceback(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD.replace("R: [[2.5]]", "R: [[0]]"))
    result = CliRunner().invoke(main, ["analyze", str(p), "--debug"])
    assert result.exit_code == 2
    assert "Traceback" in result.stderr


def test_lower_bounds_of_the_examples_match_expected_json() -> None:
    expected = json.loads((SHARED_CASES / "expected.json").read_text())
    for name, case in expected.items():
        if name.startswith("_"):
            continue
        result = CliRunner().invoke(main, ["analyze", str(REPORTS / name), "--json",
                                           "--no-simulate"])
        assert result.exit_code == 0, result.stderr
        rec = json.loads(result.stdout)
        want = sp.Rational(case["lower_bound"])
        got = rec["lower_bound"]
        assert sp.simplify(sp.sympify(got["expression"]) - want) == 0, (name, got)
        assert abs(got["value"] - float(want)) < 1e-12


def test_duplicate_keys_are_named_by_their_full_field(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD + "channel:\n  model: bernoulli\n  arrival_probability: 0.5\n"
                               "  arrival_probability: 0.7\n")
    with pytest.raises(InputError,
                       match=r"^channel\.arrival_probability: duplicate key \(line 9\)"):
        load_spec(p)
    p = write(tmp_path, GOOD + "A: [[2]]\n")
    with pytest.raises(InputError, match=r"^A: duplicate key \(line 6\)"):
        load_spec(p)
    # quoted and plain spellings of one key are the same key
    p = write(tmp_path, GOOD.replace("name: test", "name: test\n'name': again"))
    with pytest.raises(InputError, match=r"^name: duplicate key"):
        load_spec(p)


def test_merge_keys_are_refused_with_or_without_aliases(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD + "channel: {<<: {arrival_probability: 0.9}, model: bernoulli,"
                               " arrival_probability: 0.5}\n")
    with pytest.raises(InputError, match=r"^channel\.<<: YAML merge keys \(<<\) are not allowed"):
        load_spec(p)
    # a quoted "<<" is an ordinary (unknown) key, not a merge
    p = write(tmp_path, GOOD + "channel: {'<<': 1, model: bernoulli, arrival_probability: 0.5}\n")
    with pytest.raises(InputError, match=r"^channel\.<<: unknown key"):
        load_spec(p)


def test_loader_refuses_merge_keys_even_without_the_scan() -> None:
    import yaml

    from kfcrit.io.systemfile import ExactLoader

    with pytest.raises(InputError, match="merge keys"):
        yaml.load("a: {<<: {b: 1}, c: 2}\n", Loader=ExactLoader)  # noqa: S506 - safe subclass


def test_structure_scan_limits(tmp_path: Path) -> None:
    from kfcrit.io.systemfile import scan_yaml

    scan_yaml("a: " + "[" * 63 + "]" * 63)  # 64 levels with the top mapping: at the limit
    with pytest.raises(InputError, match="deeper than 64 levels"):
        scan_yaml("a: " + "[" * 64 + "]" * 64)
    with pytest.raises(InputError, match="more than 10 YAML values"):
        scan_yaml("[" + ",".join(["1"] * 20) + "]", max_nodes=10)
    with pytest.raises(InputError, match=r"^A: has more than 3 rows"):
        scan_yaml("A: [[1, 2], [3, 4], [5, 6], [7, 8]]\nB: [1, 2, 3, 4, 5]\n",
                  matrix_keys=frozenset({"A"}), max_items=3)
    scan_yaml("A: [[1, 2]]\nB: [1, 2, 3, 4, 5]\n", matrix_keys=frozenset({"A"}), max_items=3)
    with pytest.raises(InputError, match="aliases"):
        scan_yaml("a: &x 1\nb: *x\n")
    scan_yaml("a: [unclosed\n")  # syntax errors are left to the loader, which gives the line


def _analyze_in_subprocess(path: Path | str, timeout: float = 60) -> subprocess.CompletedProcess:
    """``kfcrit analyze`` in a real subprocess under a 2 GB address-space limit (an unbounded
    read fails fast instead of eating the machine) and a timeout (a hang fails the test)."""
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2_000_000_000, 2_000_000_000))

    return subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(path), "--no-simulate"],
                          capture_output=True, text=True, timeout=timeout, preexec_fn=limit)


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfcrit: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_dev_zero_is_refused_without_reading_it() -> None:
    # st_size is 0 for /dev/zero: the old size check passed and read_bytes() ate 24 GB
    proc = _analyze_in_subprocess("/dev/zero")
    assert proc.returncode == 2 and proc.stdout == ""
    line = _one_error_line(proc.stderr)
    assert line.startswith("kfcrit: error: file: ") and "character device" in line


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_is_refused_without_hanging(tmp_path: Path) -> None:
    fifo = tmp_path / "system.yaml"
    os.mkfifo(fifo)
    # no writer: a blocking open() would hang; the subprocess timeout only kills (and fails)
    proc = _analyze_in_subprocess(fifo, timeout=60)
    assert proc.returncode == 2
    line = _one_error_line(proc.stderr)
    assert "file: " in line and "FIFO" in line


def test_directory_is_refused_by_the_loader(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"^file: .* is a directory, not a regular file"):
        load_spec(tmp_path)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_trace_path_to_dev_zero_is_refused(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD + "channel: {model: trace, path: /dev/zero}\n")
    with pytest.raises(InputError, match=r"^channel\.path: trace file '/dev/zero' is a "
                                         r"character device"):
        load_spec(p)
    proc = _analyze_in_subprocess(p)
    assert proc.returncode == 2
    assert _one_error_line(proc.stderr).startswith("kfcrit: error: channel.path: ")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_trace_path_to_a_fifo_is_refused_without_hanging(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "trace.txt")
    p = write(tmp_path, GOOD + "channel: {model: trace, path: trace.txt}\n")
    proc = _analyze_in_subprocess(p)
    assert proc.returncode == 2 and "FIFO" in _one_error_line(proc.stderr)


def test_read_text_limits(tmp_path: Path) -> None:
    from kfcrit.io.safeio import read_text

    p = tmp_path / "f.txt"
    p.write_bytes(b"x" * 100)
    assert read_text(p, field="f", max_bytes=100) == ("x" * 100, b"x" * 100)
    with pytest.raises(InputError, match=r"^f: '.*' is larger than 99 bytes$"):
        read_text(p, field="f", max_bytes=99)
    p.write_bytes(b"ok \xff\xfe")
    with pytest.raises(InputError, match=r"^f: .* is not valid UTF-8 text$"):
        read_text(p, field="f", max_bytes=100)
    with pytest.raises(InputError, match=r"^trace: cannot read trace file '.*missing'"):
        read_text(tmp_path / "missing", field="trace", max_bytes=10, what="trace file")
    with pytest.raises(InputError, match=r"^f: cannot read"):
        read_text("bad\0path", field="f", max_bytes=10)
    # a symbolic link is followed, and judged by what it opens
    link = tmp_path / "link.yaml"
    if Path("/dev/zero").exists():
        link.symlink_to("/dev/zero")
        with pytest.raises(InputError, match="character device"):
            read_text(link, field="f", max_bytes=10)


def test_read_text_decides_on_the_opened_descriptor(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    # a path that is a regular file at the first look but not when opened (a swap in between)
    # is still refused: the binding check is fstat of the descriptor
    import stat as stat_mod

    import kfcrit.io.safeio as safeio

    p = tmp_path / "f.yaml"
    p.write_text("name: x\n")
    real_fstat = os.fstat

    class FakeStat:
        st_mode = stat_mod.S_IFIFO | 0o644

    monkeypatch.setattr(safeio.os, "fstat", lambda fd: FakeStat())
    with pytest.raises(InputError, match="FIFO"):
        safeio.read_text(p, field="file", max_bytes=100)
    monkeypatch.setattr(safeio.os, "fstat", real_fstat)
    assert safeio.read_text(p, field="file", max_bytes=100)[0] == "name: x\n"


def test_read_text_reads_at_most_max_bytes_plus_one(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import kfcrit.io.safeio as safeio

    p = tmp_path / "big.txt"
    p.write_bytes(b"1" * (3 * safeio.CHUNK_BYTES))
    asked: list[int] = []
    real_read = os.read

    def counting_read(fd: int, n: int) -> bytes:
        asked.append(n)
        return real_read(fd, n)

    monkeypatch.setattr(safeio.os, "read", counting_read)
    with pytest.raises(InputError, match="larger than"):
        safeio.read_text(p, field="file", max_bytes=1000)
    assert sum(asked) == 1001


# ---- definiteness: exact for exact input, scale-aware for floats -------------------------------

def test_positive_definiteness_is_exact_or_scale_aware() -> None:
    from kfcrit.model.system import is_definite

    tiny = System(3, 1, "1e-250", 1)
    assert tiny.exact and tiny.is_positive_definite("Q")
    assert System(3, 1, np.array([[1e-250]]), 1).is_positive_definite("Q")  # float input
    exact = System([[1, 0], [0, 1]], [[1, 1]], [["1", "0"], ["0", "1e-20"]], 1)
    assert exact.is_positive_definite("Q")  # exactly PD, however badly scaled
    assert not System([[1, 0], [0, 1]], [[1, 1]], [[1, 0], [0, 0]], 1).is_positive_definite("Q")
    # float: the answer does not depend on the scale of the matrix
    for scale in (1e-250, 1e-100, 1.0, 1e100, 1e250):
        M = scale * np.array([[2.0, 1.0], [1.0, 2.0]])
        assert is_definite(sp.ImmutableMatrix(M.tolist()), M, exact=False)
        S = scale * np.array([[1.0, 1.0], [1.0, 1.0]])  # singular, PSD
        assert not is_definite(sp.ImmutableMatrix(S.tolist()), S, exact=False)
        assert is_definite(sp.ImmutableMatrix(S.tolist()), S, exact=False, strict=False)
    with pytest.raises(InputError, match="^name: must be Q, R or Sigma0"):
        tiny.is_positive_definite("A")
