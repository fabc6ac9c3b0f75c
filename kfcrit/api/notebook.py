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

    Parameters
    ----------
    **fields
        The fields of :class:`~kfcrit.analysis.sections.AnalysisRecord`; build it with
        :func:`kfcrit.analyze` (or :meth:`Analysis.of`), not by hand.

    Attributes
    ----------
    decision : str
        The review decision: ``pass``, ``undetermined`` or ``fail``.
    verdict : str or None
        ``mean-stable``, ``mean-unstable`` or ``undetermined`` at the operating point (None with
        no channel).
    critical_value, upper_bound, covariance_bounds, review, …
        The typed sections; ``record["name"]`` gives a section's JSON form.

    Raises
    ------
    KeyError
        ``record[name]`` for a name that is not a section; :meth:`figure` for an unknown figure.

    References
    ----------
    docs/theory.md §16 (verdicts, the review decision and exit codes).

    Examples
    --------
    >>> from kfcrit import Analysis, Bernoulli, System, SystemSpec, analyze
    >>> record = analyze(SystemSpec(System(A=[[1.25]], C=[[1]], Q=1, R=1), Bernoulli("1/2")),
    ...                  simulate=False, quick=True)
    >>> isinstance(record, Analysis), record["critical_value"]["value"]
    (True, 0.36)
    """

    def _repr_html_(self) -> str:
        from kfcrit.views.report.summary import html_summary

        return html_summary(self)

    def _repr_markdown_(self) -> str:
        from kfcrit.views.report.summary import markdown_summary

        return markdown_summary(self)

    def figure_names(self) -> list[str]:
        """The figures this record has data for (the report's figures, in report order)."""
        from kfcrit.views.figures.record import figure_names

        return figure_names(self)

    def figure(self, name: str) -> Any:
        """One report figure as a :class:`matplotlib.figure.Figure` (see :meth:`figure_names`)."""
        from kfcrit.views.figures.record import figure

        return figure(self, name)

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

    Parameters
    ----------
    system : str, pathlib.Path, System or SystemSpec
        What to analyse; a path is loaded with :func:`kfcrit.load_spec`.
    options : AnalysisOptions, optional
        Tolerances, simulation size and seed.
    max_states : int
        Largest state dimension accepted when loading a path.
    **kwargs
        Overrides of ``options`` fields (``simulate=False``, ``quick=True``, …).

    Returns
    -------
    Analysis
        The typed record: ``decision`` (``pass``, ``undetermined``, ``fail``), ``verdict`` at the
        operating point, the critical value, bounds, covariance bounds and the review.

    Raises
    ------
    TypeError
        ``system`` of another type, or an unknown option name.
    kfcrit.errors.InputError
        An invalid system file.

    References
    ----------
    Sinopoli et al. (2004), Theorems 2–6; Mo & Sinopoli, Theorem 4; docs/theory.md §3, §4 and §16
    (verdicts and the review decision).

    Examples
    --------
    >>> from kfcrit import Bernoulli, System, SystemSpec, analyze
    >>> system = System(A=[["5/4"]], C=[[1]], Q=1, R=1)
    >>> record = analyze(SystemSpec(system, Bernoulli("1/2")), simulate=False, quick=True)
    >>> record.decision, record.verdict, record.critical_value.expression
    ('pass', 'mean-stable', '9/25')
    >>> analyze(SystemSpec(system, Bernoulli("3/10")), simulate=False, quick=True).decision
    'fail'
    """
    return Analysis.of(record_analyze(as_spec(system, max_states=max_states), options, **kwargs))


@dataclass(frozen=True)
class SweepTable:
    r"""A sweep's table: one row per point (parameters, then the result columns).

    Parameters
    ----------
    rows : tuple of dict
        One mapping per point.
    parameters : tuple of str
        The swept parameters (dotted system-file paths).
    columns : tuple of str
        Column order of :meth:`to_pandas` and the CSV.
    computed, reused : int
        Points computed in this run and taken from the journal of an earlier one.

    Attributes
    ----------
    rows, parameters, columns, computed, reused
        As given.

    Raises
    ------
    ImportError
        :meth:`to_pandas` without pandas installed.

    References
    ----------
    docs/theory.md §16.4 (the exit codes of ``kfcrit sweep``).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "s.yaml").write_text(
    ...     "name: s\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
    ...     "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    >>> _ = (folder / "sweep.yaml").write_text(
    ...     "system: s.yaml\ngrid:\n  channel.arrival_probability: [0.3, 0.5]\n")
    >>> from kfcrit import SweepTable, sweep
    >>> table = sweep(folder / "sweep.yaml", write=False)
    >>> isinstance(table, SweepTable), len(table), table.parameters
    (True, 2, ('channel.arrival_probability',))
    """

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
          max_states: int = MAX_STATES_DEFAULT, write: bool = True, scheduler: str | None = None
          ) -> SweepTable:
    r"""Run (or resume) the sweep of ``sweep_file`` from Python and return its table.

    ``output`` is the results folder (default: beside the sweep file, as for ``kfcrit sweep``);
    with ``write`` the CSV, JSON and figures are written there too, and the journal that lets
    a sweep resume; with ``write=False`` nothing is written (no folder, no journal) and every
    point is computed. ``workers`` must be a whole number ≥ 1.

    Parameters
    ----------
    sweep_file : str or pathlib.Path
        The sweep file (a system file and a grid of its fields).
    output : str or pathlib.Path, optional
        Results folder.
    workers : int
        Parallel workers.
    max_states : int
        Largest state dimension accepted.
    write : bool
        Write the results and the journal.
    scheduler : str, optional
        A dask scheduler address (default: local processes).

    Returns
    -------
    SweepTable
        One row per grid point with its verdict and review decision.

    Raises
    ------
    kfcrit.errors.InputError
        An invalid sweep or system file, ``workers`` < 1, or an output that would replace an
        input.

    References
    ----------
    docs/theory.md §16 (each point's verdict and review decision).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "s.yaml").write_text(
    ...     "name: s\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
    ...     "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    >>> _ = (folder / "sweep.yaml").write_text(
    ...     "system: s.yaml\ngrid:\n  channel.arrival_probability: [0.3, 0.5]\n")
    >>> from kfcrit import sweep
    >>> table = sweep(folder / "sweep.yaml", write=False)
    >>> [(r["channel.arrival_probability"], r["verdict"], r["decision"]) for r in table.rows]
    [(0.3, 'mean-unstable', 'fail'), (0.5, 'mean-stable', 'pass')]
    >>> sweep(folder / "sweep.yaml", workers=0)
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: workers: must be a whole number ≥ 1, got 0
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
