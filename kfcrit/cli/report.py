"""``kfcrit report``: one analysis (or one saved ``--json`` record), every requested output.

``kfcrit report FILE -o a.html -o a.pdf`` analyses FILE once and writes both documents;
``kfcrit report record.json -o a.pdf`` renders a record saved with ``kfcrit analyze --json``
without analysing again (the figures are drawn from the record's own data). The input is a
saved record when its extension is ``.json`` or its first non-blank character is ``{`` (a
system file is YAML, whose top level is a mapping written as ``key: value`` lines).

The click declaration of the command lives in :mod:`kfcrit.cli.main`, which calls
:func:`report_command`; this module imports nothing from ``main`` (no import cycle).
"""
from __future__ import annotations

import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from kfcrit.defaults import DEFAULT_TOLERANCE, MAX_STATES_DEFAULT
from kfcrit.errors import InputError
from kfcrit.io.atomic import write_atomic
from kfcrit.io.safeio import read_text

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord

FORMATS = {".html": "html", ".htm": "html", ".pdf": "pdf"}
MAX_RECORD_BYTES = 200_000_000
RECORD_KEYS = ("critical_value", "operating_point", "system")
"""A saved record has these top-level keys (``kfcrit analyze --json``)."""
ANALYSIS_OPTIONS = ("quick", "seed", "tolerance")
"""Options that change an analysis: refused for a saved record, which is rendered as it is."""


def output_format(output: str | Path, fmt: str | None) -> str:
    """``html`` or ``pdf``: ``fmt`` if given, else from the extension (InputError otherwise)."""
    if fmt is not None:
        if fmt not in ("html", "pdf"):
            raise InputError("must be html or pdf", field="format")
        return fmt
    ext = Path(output).suffix.lower()
    if ext not in FORMATS:
        raise InputError(f"cannot tell the format from the extension {ext or '(none)'!r}; use "
                         ".html or .pdf, or give --format", field="output")
    return FORMATS[ext]


def check_output_path(source: str | Path, output: str | Path) -> Path:
    """The output path, refused if it is the input file, a folder, or in a missing folder."""
    out = Path(output)
    if out.exists() and out.is_dir():
        raise InputError(f"{str(out)[:80]!r} is a directory", field="output")
    src = Path(source)
    same = out.resolve() == src.resolve()
    if not same and out.exists() and src.exists():
        same = os.path.samefile(out, src)
    if same:
        raise InputError("refusing to overwrite the input file", field="output")
    if not out.resolve().parent.is_dir():
        raise InputError(f"folder {str(out.parent)[:80]!r} does not exist", field="output")
    return out


def plan_outputs(source: str | Path, outputs: Sequence[str | Path],
                 fmt: str | None) -> list[tuple[Path, str]]:
    """``(path, format)`` of every output, checked before any work is done.

    ``--format`` names the format of a single output whose extension does not; with several
    outputs each extension decides. The same path twice is refused (one would overwrite the
    other).
    """
    if not outputs:
        raise InputError("give at least one output file (-o report.html)", field="output")
    if fmt is not None and len(outputs) > 1:
        raise InputError("--format applies to a single output; with several, each output's "
                         "extension (.html, .pdf) gives its format", field="format")
    plan = [(check_output_path(source, out), output_format(out, fmt)) for out in outputs]
    seen: set[Path] = set()
    for path, _ in plan:
        key = path.resolve()
        if key in seen:
            raise InputError(f"{str(path)[:80]!r} is given twice", field="output")
        seen.add(key)
    return plan


def is_record_file(path: str | Path, text: str | None = None) -> bool:
    """A saved JSON record (extension ``.json``, or text whose first non-blank character is
    ``{``) rather than a YAML system file."""
    if Path(path).suffix.lower() == ".json":
        return True
    return text is not None and text.lstrip("\ufeff \t\r\n")[:1] == "{"


def load_record(path: str | Path) -> AnalysisRecord:
    """A record saved by ``kfcrit analyze --json`` (InputError naming ``record`` otherwise)."""
    text, _ = read_text(path, field="record", max_bytes=MAX_RECORD_BYTES, what="record file")
    try:
        record = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})",
                         field="record") from None
    if not isinstance(record, dict) or not any(k in record for k in RECORD_KEYS):
        raise InputError("not a kfcrit analysis record (save one with 'kfcrit analyze FILE "
                         "--json > record.json')", field="record")
    from kfcrit.analysis.sections import SCHEMA_VERSION, record_from_json
    from kfcrit.io.typed import RecordError

    version = record["schema_version"] if "schema_version" in record else None
    if version is not None:
        major = str(version).split(".")[0] if isinstance(version, str) else None
        if major != SCHEMA_VERSION.split(".")[0]:
            raise InputError(f"{str(version)[:20]!r} is not supported: this kfcrit reads "
                             f"records of schema {SCHEMA_VERSION.split('.')[0]}.x (re-run "
                             "'kfcrit analyze FILE --json' with this version)",
                             field="schema_version")

    try:  # the typed record's strict reader: every view then reads a well-formed record
        return record_from_json(record)
    except RecordError as exc:
        raise InputError(f"not a record of this kfcrit version ({exc})", field="record") from None


def progress(message: str) -> None:
    """One progress line on stderr (stdout carries data only)."""
    print(f"kfcrit: {message}", file=sys.stderr, flush=True)


def source_kind(source: str | Path) -> str:
    """``record`` for a saved JSON record, ``system`` for a system file (by extension, then by
    the first characters of the file; an unreadable file is left to the loader's error)."""
    if is_record_file(source):
        return "record"
    try:
        with open(source, encoding="utf-8", errors="replace") as fh:
            head = fh.read(256)
    except OSError:
        return "system"
    return "record" if is_record_file(source, head) else "system"


def analysed_record(source: str | Path, *, quick: bool, seed: int, tolerance: float,
                    max_states: int) -> AnalysisRecord:
    """Analyse the system file ``source`` once and return its typed record."""
    from kfcrit.analysis.record import AnalysisOptions, analyze_system
    from kfcrit.analysis.spec import load_spec

    progress(f"reading {source}")
    spec = load_spec(source, max_states=max_states)
    progress("analysing" + (" (quick draft)" if quick else ""))
    return analyze_system(spec, AnalysisOptions(quick=quick, seed=seed, tolerance=tolerance))


def report_command(source: str, outputs: str | Sequence[str], *, fmt: str | None = None,
                   quick: bool = False, seed: int = 0, max_states: int = MAX_STATES_DEFAULT,
                   tolerance: float = DEFAULT_TOLERANCE, options_given: Sequence[str] = ()) -> int:
    """``kfcrit report``: write the report of ``source`` to every path in ``outputs``.

    Parameters
    ----------
    source : str
        A system file (analysed once) or a record saved with ``kfcrit analyze --json``
        (rendered as it is).
    outputs : str or sequence of str
        Output files; ``.html``/``.htm`` or ``.pdf`` (or ``fmt`` for a single output).
    options_given : sequence of str
        Names among :data:`ANALYSIS_OPTIONS` the user gave explicitly: refused for a saved
        record, whose analysis options are fixed.

    Returns
    -------
    int
        The record's exit code (:attr:`kfcrit.analysis.sections.AnalysisRecord.exit_code`).
        Bad paths, formats or records raise :class:`~kfcrit.errors.InputError` (exit code 2)
        before anything is written.
    """
    from kfcrit.views.report.render import render_documents

    plan = plan_outputs(source, [outputs] if isinstance(outputs, (str, Path)) else outputs, fmt)
    if source_kind(source) == "record":
        given = [name for name in ANALYSIS_OPTIONS if name in options_given]
        if given:
            raise InputError(f"--{given[0]} changes an analysis; a saved record is rendered as "
                             "it was analysed (rerun 'kfcrit analyze' to change it)",
                             field=given[0])
        progress(f"reading the saved record {source}")
        record = load_record(source)
    else:
        from kfcrit.analysis.spec import load_spec
        from kfcrit.cli.common import spec_inputs
        from kfcrit.io.atomic import refuse_replacing_inputs

        refuse_replacing_inputs([path for path, _ in plan],
                                spec_inputs(load_spec(source, max_states=max_states), source),
                                "output")
        record = analysed_record(source, quick=quick, seed=seed, tolerance=tolerance,
                                 max_states=max_states)
    kinds = [kind for _, kind in plan]
    progress("drawing figures and rendering " + " and ".join(
        k.upper() for k in dict.fromkeys(kinds)))
    documents = render_documents(record, kinds)
    for path, kind in plan:
        write_atomic(path, documents[kind])
        progress(f"wrote {path} ({len(documents[kind])} bytes)")
    return record.exit_code
