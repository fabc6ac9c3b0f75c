"""Records and sweep tables for notebooks: ``repr``, ``_repr_html_``, ``_repr_markdown_``,
``figure(name)`` and ``to_pandas()``."""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kfcrit.analysis import sections
from kfcrit.analysis.record import analyze_system as record_analyze
from kfcrit.analysis.spec import load_spec
from kfcrit.io.systemfile import SystemSpec
from kfcrit.model.system import MAX_STATES_DEFAULT, System


@dataclass(frozen=True, repr=False)
class Analysis(sections.AnalysisRecord):
    """The typed analysis record, displayed in notebooks by its verdict box and bounds table.

    Everything of :class:`kfcrit.analysis.sections.AnalysisRecord` (typed sections, ``to_dict()``,
    ``decision``, ``verdict``), plus :meth:`figure` and the rich displays.
    """

    def _repr_html_(self) -> str:
        from kfcrit.views.report.summary import html_summary

        return html_summary(self.to_dict())

    def _repr_markdown_(self) -> str:
        from kfcrit.views.report.summary import markdown_summary

        return markdown_summary(self.to_dict())

    def figure_names(self) -> list[str]:
        """The figures this record has data for (the report's figures, in report order)."""
        from kfcrit.views.figures.record import figure_names

        return figure_names(self.to_dict())

    def figure(self, name: str) -> Any:
        """One report figure as a :class:`matplotlib.figure.Figure` (see :meth:`figure_names`)."""
        from kfcrit.views.figures.record import figure

        return figure(self.to_dict(), name)

    @classmethod
    def of(cls, record: sections.AnalysisRecord) -> Analysis:
        """The notebook form of a record built by :func:`kfcrit.analysis.record.analyze_system`."""
        return cls(**{f.name: getattr(record, f.name) for f in dataclasses.fields(record)})


def as_spec(system: Any, *, max_states: int = MAX_STATES_DEFAULT) -> System | SystemSpec:
    """What :func:`kfcrit.analysis.record.analyze_system` takes, from what a notebook user passes.

    A path (``str`` or :class:`os.PathLike`) is a system file, loaded as ``kfcrit analyze``
    loads it (:func:`kfcrit.analysis.spec.load_spec`: channel, requirements and provenance
    included); a :class:`~kfcrit.model.system.System` or
    :class:`~kfcrit.io.systemfile.SystemSpec` is used as it is.

    Raises
    ------
    TypeError
        For anything else, naming the type received and the types accepted.
    kfcrit.errors.InputError
        For a path whose file is missing or invalid (one line naming the field).
    """
    if isinstance(system, (System, SystemSpec)):
        return system
    if isinstance(system, (str, os.PathLike)):
        return load_spec(os.fspath(system), max_states=max_states)
    raise TypeError("analyze() takes a system file path (str or pathlib.Path), a "
                    "kfcrit.System or a kfcrit.SystemSpec (from kfcrit.load_spec), not "
                    f"{type(system).__name__}")


def analyze(system: Any, options: Any = None, *, max_states: int = MAX_STATES_DEFAULT,
            **kwargs: Any) -> Analysis:
    """Analyse a system file (its path), a :class:`~kfcrit.model.system.System` or a loaded
    system file (:class:`~kfcrit.io.systemfile.SystemSpec`).

    See :func:`kfcrit.analysis.record.analyze_system` (same parameters; keyword arguments override
    fields of :class:`~kfcrit.analysis.record.AnalysisOptions`, e.g. ``simulate=False``);
    ``max_states`` is the size cap applied when loading a path, as ``--max-states`` on the
    command line. The record returned displays itself in notebooks.

    Examples
    --------
    >>> record = kfcrit.analyze("reports/link-oqpsk-sensor.yaml", quick=True)  # doctest: +SKIP
    >>> record.decision, record.figure_names()                                 # doctest: +SKIP
    """
    return Analysis.of(record_analyze(as_spec(system, max_states=max_states), options, **kwargs))


@dataclass(frozen=True)
class SweepTable:
    """A sweep's table: one row per point (parameters, then the result columns)."""

    rows: tuple[dict[str, Any], ...]
    parameters: tuple[str, ...]
    columns: tuple[str, ...]
    computed: int = 0
    reused: int = 0

    def to_pandas(self) -> Any:
        """The table as a :class:`pandas.DataFrame` (pandas is an optional extra:
        ``pip install 'kfcrit[notebook]'``)."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas() needs pandas: pip install 'kfcrit[notebook]'") from exc
        return pd.DataFrame([{c: r.get(c) for c in self.columns} for r in self.rows],
                            columns=list(self.columns))

    def __len__(self) -> int:
        return len(self.rows)

    def __repr__(self) -> str:
        decisions = [r.get("decision") for r in self.rows]
        counts = ", ".join(f"{d}: {decisions.count(d)}" for d in dict.fromkeys(decisions))
        return f"<kfcrit SweepTable: {len(self.rows)} points over {', '.join(self.parameters)}" \
               f" ({counts})>"


def sweep(sweep_file: str | Path, output: str | Path | None = None, *, workers: int = 1,
          max_states: int = 400, write: bool = True, scheduler: str | None = None
          ) -> SweepTable:
    """Run (or resume) the sweep of ``sweep_file`` from Python and return its table.

    ``output`` is the results folder (default: beside the sweep file, as for ``kfcrit sweep``);
    with ``write`` the CSV, JSON and figures are written there too, and the journal that lets
    a sweep resume; with ``write=False`` nothing is written (no folder, no journal) and every
    point is computed. ``workers`` must be a whole number ≥ 1.
    """
    from kfcrit.analysis.sweep.points import RESULT_COLUMNS, load_sweep, run_sweep
    from kfcrit.api.sweepfiles import write_outputs

    spec = load_sweep(sweep_file, max_states=max_states)
    out = Path(output) if output is not None else \
        Path(sweep_file).with_name(Path(sweep_file).stem + "-results")
    if write:
        from kfcrit.api.sweepfiles import sweep_inputs, sweep_output_files
        from kfcrit.io.atomic import refuse_replacing_inputs

        refuse_replacing_inputs(sweep_output_files(out), sweep_inputs(spec, sweep_file),
                                "output")
    result = run_sweep(spec, out, scheduler=scheduler, workers=workers, max_states=max_states,
                       journal=write)
    if write:
        write_outputs(spec, result.rows, Path(result.output), runner=result.runner,
                      workers=result.workers, computed=result.computed, reused=result.reused)
    columns: Sequence[str] = ("index", "key", *spec.parameters, *RESULT_COLUMNS)
    return SweepTable(rows=tuple(result.rows), parameters=tuple(spec.parameters),
                      columns=tuple(columns), computed=result.computed, reused=result.reused)
