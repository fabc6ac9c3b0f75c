"""Trace file formats (kfcrit.io.traceformats): 0/1 per period, sequence numbers, receive logs.

Expected arrays are written out by hand; every bad file must raise the bad-input error (exit 2)
naming the field, the file and the line, without echoing the file's text.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kfcrit.errors import ExitCode, InputError
from kfcrit.io import traceformats as tf
from kfcrit.io.traceformats import (
    NO_SENSOR,
    parse_binary,
    parse_receive_log,
    parse_sequence_numbers,
    read_binary,
    read_receive_log,
    read_sequence_numbers,
    read_trace_file,
)


def bad(call, *args, **kwargs) -> InputError:  # noqa: ANN001
    with pytest.raises(InputError) as exc:
        call(*args, **kwargs)
    assert exc.value.exit_code == ExitCode.BAD_INPUT and "\n" not in str(exc.value)
    return exc.value


def ints(arr: np.ndarray) -> list[int]:
    return arr.astype(int).tolist()


# --- (a) one 0/1 per period -------------------------------------------------------------------

@pytest.mark.parametrize("text", ["1\n0\n1\n1\n", "1 0 1 1", "1,0,1,1\n", "1, 0\n1\t1",
                                  "# header\n1 0  # two\n\n1\n1\n", "1\r\n0\r\n1\r\n1\r\n"])
def test_binary_layouts(text: str) -> None:
    arr = parse_binary(text)
    assert ints(arr) == [1, 0, 1, 1] and arr.dtype == bool and not arr.flags.writeable


def test_binary_bad_token_names_file_and_line(tmp_path: Path) -> None:
    lines = ["1"] * 16 + ["x"] + ["0"] * 3
    path = tmp_path / "trace.txt"
    path.write_text("\n".join(lines) + "\n")
    err = bad(read_binary, path)
    assert str(err) == "channel.path: trace.txt line 17: 'x' is not 0 or 1"
    err = bad(parse_binary, "1 0\n1 1 2 0\n", source="t.txt", field="links[1].path")
    assert str(err) == "links[1].path: t.txt line 2: '2' (value 3 on the line) is not 0 or 1"


def test_binary_does_not_echo_a_foreign_file(tmp_path: Path) -> None:
    path = tmp_path / "passwd"
    path.write_text("root:x:0:0:root:/root:/bin/bash\n")
    err = bad(read_binary, path)
    assert "root:" not in str(err) and "passwd line 1" in str(err)


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n", " , \n"])
def test_binary_empty_is_an_error(text: str) -> None:
    err = bad(parse_binary, text, source="empty.txt")
    assert "empty.txt" in str(err) and "empty" in str(err)


# --- (b) received sequence numbers ------------------------------------------------------------

def test_sequence_numbers_missing_are_losses() -> None:
    assert ints(parse_sequence_numbers("10\n11\n13\n16\n")) == [1, 1, 0, 1, 0, 0, 1]
    assert ints(parse_sequence_numbers("3 4, 7", first=1, last=9)) == [0, 0, 1, 1, 0, 0, 1, 0, 0]
    assert ints(parse_sequence_numbers("5\n")) == [1]


@pytest.mark.parametrize(("text", "line", "words"), [
    ("1\n2\n5\n4\n", 4, "smaller than 5 on line 3"),
    ("1\n2\n2\n", 3, "repeated (also on line 2)"),
    ("1\n2\n-3\n", 3, "'-3' is not a sequence number"),
    ("1\n2.5\n", 2, "'2.5' is not a sequence number"),
    ("1\nabc\n", 2, "the value (not shown) is not a sequence number"),
])
def test_sequence_number_errors_name_the_line(text: str, line: int, words: str) -> None:
    err = bad(parse_sequence_numbers, text, source="seq.log")
    assert f"seq.log line {line}: " in str(err) and words in str(err)


def test_sequence_numbers_outside_first_last() -> None:
    assert "before first = 3" in str(bad(parse_sequence_numbers, "2\n4\n", first=3))
    assert "line 2: sequence number 9 is after last = 8" in \
        str(bad(parse_sequence_numbers, "2\n9\n", last=8))
    assert bad(parse_sequence_numbers, "2\n", first=5, last=4).field == "channel.first"
    assert bad(parse_sequence_numbers, "2\n", first=-1).field == "channel.first"
    assert "empty" in str(bad(parse_sequence_numbers, "# nothing\n"))


def test_sequence_numbers_span_is_capped(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tf, "MAX_PERIODS", 100)
    err = bad(parse_sequence_numbers, "0\n1000\n", source="s")
    assert "s line 2" in str(err) and "longer than 100 periods" in str(err)


# --- (c) timestamped receive log --------------------------------------------------------------

def test_receive_log_bins_arrivals_per_period() -> None:
    text = "0.00\n0.05\n0.3\n0.31\n0.75\n"  # periods 0, 0, 3, 3, 7 of T = 0.1
    out = parse_receive_log(text, period=0.1)
    assert list(out) == [NO_SENSOR]
    assert ints(out[NO_SENSOR]) == [1, 0, 0, 1, 0, 0, 0, 1]
    shifted = parse_receive_log(text, period="0.1", start=0.0, periods=10)[NO_SENSOR]
    assert ints(shifted) == [1, 0, 0, 1, 0, 0, 0, 1, 0, 0]
    late = parse_receive_log("2.05\n2.25\n", period=0.1, start=2)[NO_SENSOR]
    assert ints(late) == [1, 0, 1]


def test_receive_log_with_sensor_ids_gives_aligned_traces() -> None:
    text = "0.05 a\n0.12 b\n0.31,a\n0.52 b\n"
    out = parse_receive_log(text, period=0.1)
    assert list(out) == ["a", "b"]
    assert ints(out["a"]) == [1, 0, 0, 1, 0, 0]
    assert ints(out["b"]) == [0, 1, 0, 0, 0, 1]
    only_b = parse_receive_log(text, period=0.1, sensor="b")
    assert list(only_b) == ["b"] and ints(only_b["b"]) == [0, 1, 0, 0, 0, 1]
    only_a = parse_receive_log(text, period=0.1, sensor="a")  # as long as the whole log
    assert ints(only_a["a"]) == [1, 0, 0, 1, 0, 0]


@pytest.mark.parametrize(("text", "kwargs", "line", "words"), [
    ("0.1\n-0.5\n", {}, 2, "time -0.5 is negative"),
    ("0.5\n0.2\n", {}, 2, "earlier than the time on line 1"),
    ("0.5\n", {"start": 1}, 1, "before the start time"),
    ("0.1\n0.95\n", {"periods": 5}, 2, "after the last period"),
    ("0.1 a\n0.2\n", {}, 2, "has 1 column(s), but the first data line has 2"),
    ("0.1 a b\n", {}, 1, "has 3 columns"),
    ("nan\n", {}, 1, "is not a time in seconds"),
    ("0.1 a/b\n", {}, 1, "the sensor id must be"),
])
def test_receive_log_errors_name_the_line(text: str, kwargs: dict, line: int,
                                          words: str) -> None:
    err = bad(parse_receive_log, text, period=0.1, source="rx.log", **kwargs)
    assert f"rx.log line {line}: " in str(err) and words in str(err), str(err)


def test_receive_log_bad_options_and_empty_log() -> None:
    assert bad(parse_receive_log, "0.1\n", period=0).field == "channel.period"
    assert bad(parse_receive_log, "0.1\n", period="1/10").field == "channel.period"
    assert bad(parse_receive_log, "0.1\n", period=0.1, start=-1).field == "channel.start"
    assert bad(parse_receive_log, "0.1\n", period=0.1, sensor="a").field == "channel.sensor"
    assert bad(parse_receive_log, "0.1 a\n", period=0.1, sensor="b").field == "channel.sensor"
    assert "empty" in str(bad(parse_receive_log, "", period=0.1, source="rx.log"))


# --- files ------------------------------------------------------------------------------------

def test_reading_files_of_each_format(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("1 0 1\n")
    (tmp_path / "b.txt").write_text("7\n9\n")
    (tmp_path / "c.txt").write_text("0.0 s1\n0.25 s2\n")
    assert ints(read_binary(tmp_path / "a.txt")) == [1, 0, 1]
    assert ints(read_sequence_numbers(tmp_path / "b.txt", first=6)) == [0, 1, 0, 1]
    logs = read_receive_log(tmp_path / "c.txt", period=0.1)
    assert ints(logs["s1"]) == [1, 0, 0] and ints(logs["s2"]) == [0, 0, 1]
    assert ints(read_trace_file(tmp_path / "b.txt", "sequence-numbers")[NO_SENSOR]) == [1, 0, 1]
    assert bad(read_trace_file, tmp_path / "a.txt", "pcap").field == "channel.format"


def test_files_are_read_safely(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert "directory" in str(bad(read_binary, tmp_path))
    assert "cannot read" in str(bad(read_binary, tmp_path / "missing.txt"))
    (tmp_path / "big.txt").write_text("1 " * 100)
    monkeypatch.setattr(tf, "MAX_TRACE_BYTES", 50)
    assert "larger than 50 bytes" in str(bad(read_binary, tmp_path / "big.txt"))
    (tmp_path / "latin.txt").write_bytes(b"1\n\xff\n")
    assert "UTF-8" in str(bad(read_binary, tmp_path / "latin.txt"))
