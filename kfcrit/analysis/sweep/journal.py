"""The sweep journal: finished points, appended as they finish, read back on resuming.

A line is ``{"key": k, "check": h, "result": r}``: the point key :math:`k` (the SHA-256 of the
point's inputs, :func:`kfcrit.analysis.sweep.points.point_key`), the check :math:`h` binding the line
to the sweep file and to its own result (:func:`journal_check`), and the row's result columns.

Invariant: a line is reused only when its check matches *and* its result has exactly the shape
a computed row has (:func:`valid_result`); anything else — torn, edited, forged, copied from
another sweep or another kfcrit version — counts as not computed and the point is computed
again. Invariant: the journal is a regular file reached without following symbolic links.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any

from kfcrit.errors import ExitCode, KfcritError, OutputError
from kfcrit.io.safeio import read_text
from kfcrit.link.requirement import ACCURACY_BASIS, ACCURACY_IMPOSSIBLE_BASIS

MAX_POINTS = 100_000
"""Largest sweep (points): bounds the memory of the keyed grid (about 1 KiB per point) and the
journal read back; larger designs are several sweep files."""
MAX_JOURNAL_BYTES = 4096 * MAX_POINTS
"""Largest journal read back on resuming (4 KiB per point of the largest sweep)."""

JOURNAL_NAME = "sweep.journal.jsonl"
"""File name of the journal in the output folder."""
JOURNAL_FORMAT = 2
"""Version of the journal line format (``key``, ``check``, ``result``)."""
_STRING_COLUMNS = ("error", "classification", "critical_expression", "requirement_basis")
"""Result columns holding free text (or null)."""
_WORD_COLUMNS = {"status": ("ok", "error"),
                 "verdict": (None, "mean-stable", "mean-unstable", "undetermined"),
                 "decision": (None, "pass", "fail", "undetermined"),
                 "loop_verdict": (None, "mean-square-stable", "mean-square-unstable",
                                  "undetermined"),
                 "requirement_basis": (None, "robust critical value", "critical value",
                                       "upper bound (sufficient)",
                                       "lower bound (necessary only)", ACCURACY_BASIS,
                                       ACCURACY_IMPOSSIBLE_BASIS)}
POINT_ERROR_CODES = (int(ExitCode.VERIFICATION_FAILED), int(ExitCode.BAD_INPUT),
                      int(ExitCode.INCONCLUSIVE))
"""Exit codes a point's error row may carry (those of KfcritError and of numerical faults)."""
_SAFE_TEXT = re.compile("[^\x00-\x1f\x7f-\x9f<>&\u2028\u2029\u202a-\u202e\u2066-\u2069]"
                        "{0,300}")
"""A journalled string: at most 300 characters, no control or bidi characters, no markup."""
_KEY = re.compile("[0-9a-f]{64}")


def journal_check(binding: str, key: str, result: dict[str, Any]) -> str:
    """SHA-256 that binds one journal line to its sweep.

    .. math:: h = \\operatorname{SHA256}(\\text{format} \\,\\|\\, \\text{sweep file}
              \\,\\|\\, k \\,\\|\\, \\text{result})

    where the point key :math:`k` (:func:`point_key`) already covers the kfcrit version, the
    base system, the tolerance, ``max_states`` and the point's assignments, and ``binding`` is
    the SHA-256 of the sweep file's bytes. An edited result, a line copied from another sweep
    or another kfcrit version, or a line from an older format fails the check. This detects
    stale and edited lines; it is not a signature (anyone who can run kfcrit can compute it),
    so results are also validated by :func:`valid_result`.
    """
    return _check_of_text(binding, key, result_text(result))


def result_text(result: dict[str, Any]) -> str:
    """The canonical JSON text of a result (sorted keys, ASCII, no spaces, no NaN): what the
    check hashes and what a journal line holds."""
    return json.dumps(result, sort_keys=True, ensure_ascii=True, separators=(",", ":"),
                      allow_nan=False)


def _check_of_text(binding: str, key: str, text: str) -> str:
    """:func:`journal_check` of the result whose :func:`result_text` is ``text``: the blob is
    ``json.dumps({"journal", "key", "result", "sweep"}, sort_keys=True, …)`` assembled around
    the already encoded result (the keys in sorted order)."""
    blob = (f'{{"journal":{JOURNAL_FORMAT},"key":{json.dumps(key)},"result":{text},'
            f'"sweep":{json.dumps(binding)}}}')
    return hashlib.sha256(blob.encode()).hexdigest()


def _finite_number(value: Any) -> bool:
    return value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)
                             and math.isfinite(value))


def valid_result(result: Any, columns: tuple[str, ...]) -> bool:
    """Whether a journalled result has exactly the shape a sweep point's row has.

    Columns are ``columns`` (the sweep's ``RESULT_COLUMNS``), plus ``error_code`` on an error
    row; numbers finite or null; words from their vocabularies; free text bounded and free of
    control characters and markup; an error row carries an exit code a point can have (1, 2 or
    3) and an ok row none.
    Anything else is treated as not computed (the point is computed again), never reused.
    """
    if not isinstance(result, dict):
        return False
    status = result.get("status")
    expected = set(columns) | ({"error_code"} if status == "error" else set())
    if set(result) != expected:
        return False
    for column, words in _WORD_COLUMNS.items():
        if result[column] not in words:
            return False
    for column in _STRING_COLUMNS:
        text = result[column]
        if text is not None and not (isinstance(text, str) and _SAFE_TEXT.fullmatch(text)):
            return False
    if result["iid"] not in (None, True, False):
        return False
    numbers = [c for c in columns
               if c not in _STRING_COLUMNS and c not in _WORD_COLUMNS and c != "iid"]
    if not all(_finite_number(result[c]) for c in numbers):
        return False
    if status == "error":
        code = result["error_code"]
        return (isinstance(code, int) and not isinstance(code, bool)
                and code in POINT_ERROR_CODES and isinstance(result["error"], str))
    return result["error"] is None


class Journal:
    """Append-only JSON-lines file of finished points, fsynced after every batch.

    Each line is ``{"key": k, "check": h, "result": r}`` with ``h`` =
    :func:`journal_check` of the sweep; on reading, a line whose check or shape does not match
    (edited, copied from another sweep, torn, or forged) counts as not computed.

    The file is opened without following symbolic links (``O_NOFOLLOW``) and must be a regular
    file: a link, FIFO or device put in its place is refused with one line (exit 2), never
    written through. A torn last line (the process died mid-write) is ignored on reading and a
    newline is written before the next append, so the file stays parseable line by line. A
    failed append (disk full) truncates the file back to its previous length, and removes it
    when it was empty, before raising :class:`~kfcrit.errors.OutputError` naming the journal.
    """

    def __init__(self, path: Path, binding: str = "", columns: tuple[str, ...] = ()) -> None:
        self.path = path
        self.binding = binding
        self.columns = columns

    def load(self) -> dict[str, dict[str, Any]]:
        """Key → result columns of every complete line whose check and shape are valid."""
        out: dict[str, dict[str, Any]] = {}
        if not os.path.lexists(self.path):
            return out
        # a regular file only (a FIFO, a device or a symbolic link put in its place is
        # refused), bounded; kfcrit writes it in ASCII, so strict UTF-8 loses nothing
        text, _ = read_text(self.path, field="output", max_bytes=MAX_JOURNAL_BYTES,
                            what="the journal", follow_symlinks=False)
        for line in text.splitlines():
            try:
                entry = json.loads(line)
            except (json.JSONDecodeError, RecursionError):
                continue
            if not (isinstance(entry, dict) and set(entry) == {"key", "check", "result"}):
                continue
            key, check, result = entry["key"], entry["check"], entry["result"]
            if not (isinstance(key, str) and _KEY.fullmatch(key) and isinstance(check, str)
                    and valid_result(result, self.columns)):
                continue
            try:
                if check != journal_check(self.binding, key, result):
                    continue
            except (TypeError, ValueError):
                continue
            out[key] = result
        return out

    def _open(self) -> int:
        flags = (os.O_RDWR | os.O_APPEND | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0)
                 | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
                 | getattr(os, "O_NOCTTY", 0))
        shown = f"the journal {str(self.path)[:120]!r}"
        try:
            fd = os.open(self.path, flags, 0o666)
        except OSError as exc:
            reason = ("is a symbolic link, not a regular file" if os.path.islink(self.path)
                      else f"cannot be written ({exc.strerror or exc})")
            raise OutputError(f"{shown} {reason}", field="output") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise OutputError(f"{shown} is not a regular file", field="output")
        return fd

    def append(self, entries: list[tuple[str, dict[str, Any]]]) -> None:
        """Append ``(key, result)`` entries with their checks and fsync."""
        if not entries:
            return
        texts = [(k, result_text(r)) for k, r in entries]   # one encoding per line
        lines = "".join(f'{{"key":{json.dumps(k)},"check":"{_check_of_text(self.binding, k, t)}",'
                        f'"result":{t}}}\n' for k, t in texts)
        fd = self._open()
        size = 0
        try:
            size = os.fstat(fd).st_size
            needs_newline = size > 0 and os.pread(fd, 1, size - 1) != b"\n"
            data = (("\n" if needs_newline else "") + lines).encode("ascii")
            view = memoryview(data)
            while view:
                written = os.write(fd, view)
                view = view[written:]
            os.fsync(fd)
        except OSError as exc:
            self._undo(fd, size)
            raise OutputError(f"cannot write the journal {str(self.path)[:120]!r}: "
                              f"{exc.strerror or exc}", field="output") from None
        finally:
            os.close(fd)

    def _undo(self, fd: int, size: int) -> None:
        """Take a failed append back: truncate to ``size``, remove the file if it was empty."""
        try:
            os.ftruncate(fd, size)
            if size == 0 and os.path.samestat(os.fstat(fd), os.lstat(self.path)):
                os.unlink(self.path)
        except OSError:
            pass

    def count(self) -> int:
        """Lines whose check and shape are valid (for the interruption message)."""
        try:
            return len(self.load())
        except KfcritError:
            return 0


__all__ = ["JOURNAL_FORMAT", "JOURNAL_NAME", "MAX_JOURNAL_BYTES", "POINT_ERROR_CODES", "Journal",
           "journal_check", "result_text", "valid_result"]
