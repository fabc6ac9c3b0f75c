"""The files of a finished sweep: its table (CSV, JSON), its run summary and margin plots.

Shared by the Python API (:func:`kfcrit.sweep`) and the ``kfcrit sweep`` command, so that the
API never imports the command line.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from kfcrit.analysis.sweep.points import (
    FORMAT_VERSION,
    JOURNAL_NAME,
    RESULT_COLUMNS,
    SweepSpec,
    table_csv,
)
from kfcrit.io.atomic import write_atomic
from kfcrit.io.jsonio import jsonable
from kfcrit.version import __version__
from kfcrit.views.figures.sweep import margin_images

SWEEP_OUTPUT_NAMES = ("sweep.csv", "sweep.json", "margin.svg", "margin.png", "run.json",
                      JOURNAL_NAME)
"""The files a sweep writes in its output folder."""


def sweep_output_files(out: Path) -> list[Path]:
    """Every file a sweep writes into the folder ``out``."""
    return [out / name for name in SWEEP_OUTPUT_NAMES]


def sweep_inputs(spec: SweepSpec, sweep_file: str | Path) -> list[Path]:
    """The files a sweep reads: the sweep file, its base system file and the base's trace."""
    out = [Path(sweep_file)]
    if spec.base_path:
        out.append(Path(spec.base_path))
    ch = spec.base_doc.get("channel") if isinstance(spec.base_doc, dict) else None
    if isinstance(ch, dict) and ch.get("model") == "trace" and isinstance(ch.get("path"), str):
        p = Path(ch["path"])
        out.append(p if p.is_absolute() else Path(spec.base_dir) / p)
    return out


def write_outputs(spec: SweepSpec, rows: list[dict[str, Any]], out: Path, *,
                  runner: str, workers: int, computed: int, reused: int) -> dict[str, str]:
    """Write sweep.csv, sweep.json and the margin plots atomically; return their paths."""
    meta = {"name": spec.name, "description": spec.description, "sweep_file": spec.path,
            "sweep_sha256": spec.sha256, "base_system": spec.base_path,
            "parameters": list(spec.parameters), "tolerance": spec.tolerance,
            "points": len(rows), "plot_x": spec.plot_x, "kfcrit": __version__,
            "format": FORMAT_VERSION, "columns": ["index", "key", *spec.parameters,
                                                 *RESULT_COLUMNS]}
    record = {"sweep": meta, "rows": rows}
    run = {"runner": runner, "workers": workers,
           "computed": computed, "reused": reused}
    files = {"csv": out / "sweep.csv", "json": out / "sweep.json",
             "svg": out / "margin.svg", "png": out / "margin.png",
             "run": out / "run.json"}
    # kfcrit names these files itself: a symbolic link planted in the folder is replaced,
    # never written through
    write_atomic(files["csv"], table_csv(spec, rows).encode(), follow_symlinks=False)
    write_atomic(files["json"], json.dumps(jsonable(record), indent=1, allow_nan=False,
                                           ensure_ascii=False).encode(), follow_symlinks=False)
    write_atomic(files["run"], json.dumps(run, indent=1).encode(), follow_symlinks=False)
    for fmt, data in margin_images(rows, spec.parameters, spec.plot_x).items():
        write_atomic(files[fmt], data, follow_symlinks=False)
    return {k: str(v) for k, v in files.items()}
