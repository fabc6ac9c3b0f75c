"""``kfcrit sweep``: run a sweep file, write its table and figures, report in one line."""
from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

from kfcrit.analysis.sweep.points import (
    JOURNAL_NAME,
    Journal,
    load_sweep,
    run_sweep,
)
from kfcrit.api.sweepfiles import sweep_inputs, sweep_output_files, write_outputs
from kfcrit.cli.common import flush_std_streams
from kfcrit.errors import ExitCode
from kfcrit.io.atomic import refuse_replacing_inputs
from kfcrit.io.safeio import printable
from kfcrit.views.formatting import counted


def _progress(total: int, done: int) -> tuple[Callable[[int], None], Callable[[], None]]:
    """A rich progress bar on stderr when stderr is a terminal; otherwise no-ops."""
    if not sys.stderr.isatty() or total == 0:
        return (lambda n: None), (lambda: None)
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    prog = Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TextColumn("points"),
                    TimeRemainingColumn(), console=Console(stderr=True), transient=True)
    task = prog.add_task("sweep", total=total, completed=done)
    prog.start()
    return (lambda n: prog.advance(task, n)), prog.stop


def _interrupted(journal: Journal) -> None:
    """One line on stderr, then leave with exit code 130 (as ``cli.interrupted_exit`` does).

    Unlike the other commands, an interrupted sweep keeps what it finished: the journal.
    """
    print(f"kfcrit: error: interrupted; {journal.count()} finished points are kept in "
          f"{printable(str(journal.path))} (run the same command again to resume); the table "
          "and plots were not updated", file=sys.stderr)
    flush_std_streams()
    os._exit(ExitCode.INTERRUPTED)


def _quiet_dask_logs() -> None:
    """Keep ``distributed``'s log records ("Failed to reconnect to scheduler …") off stderr: a
    lost or unreachable scheduler is reported in kfcrit's one line, with the resume hint."""
    import logging

    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)


def sweep_command(sweep_file: str, *, output: str | None, scheduler: str | None,
                  workers: int | None, max_states: int) -> int:
    """Run the ``kfcrit sweep`` subcommand; return the exit code.

    Errors in the sweep file are :class:`InputError` (exit 2). Points that fail (for example a
    swept value outside its allowed range) are rows with ``status = error`` and their message;
    the outputs are still written and the exit code is the worst point's (2 input, 3 numerical).
    Each point's review decision is a column of the table; the exit code does not summarise
    decisions (a sweep explores where a design passes and fails).
    """
    spec = load_sweep(sweep_file, max_states=max_states)
    if scheduler is not None:
        _quiet_dask_logs()
    if output is None:
        output = str(Path(sweep_file).with_name(Path(sweep_file).stem + "-results"))
    refuse_replacing_inputs(sweep_output_files(Path(output)), sweep_inputs(spec, sweep_file),
                            "--output")
    try:
        result = run_sweep(spec, output, scheduler=scheduler, workers=workers,
                           max_states=max_states, progress=_progress)
        write_outputs(spec, result.rows, Path(result.output), runner=result.runner,
                      workers=result.workers, computed=result.computed, reused=result.reused)
    except KeyboardInterrupt:
        _interrupted(Journal(Path(output) / JOURNAL_NAME, spec.sha256 or ""))
    print(f"kfcrit: sweep {spec.name!r}: {len(result.rows)} points ({result.computed} computed, "
          f"{result.reused} from the journal), {counted(result.errors, 'error')}; outputs in "
          f"{printable(result.output)}", file=sys.stderr)
    if result.errors:
        first = next(r for r in result.rows if r["status"] != "ok")
        print(f"kfcrit: first failing point {first['index']}: {printable(str(first['error']))}",
              file=sys.stderr)
    return result.exit_code
