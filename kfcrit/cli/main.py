"""Command line: ``kfcrit analyze | report | simulate | sweep | check | schema``.

stdout carries data only (the summary, or exactly the JSON record with ``--json``); progress and
errors go to stderr. Exit codes are :class:`kfcrit.errors.ExitCode` (README, "Exit codes"):
0 review pass, 1 a verification failed, 2 bad usage or bad input file, 3 undetermined,
4 internal error, 5 review failed, 130 interrupted, 141 stdout closed.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from contextlib import AbstractContextManager, nullcontext

import click

from kfcrit.cli.common import (
    EXAMPLES,
    KfcritGroup,
    ToleranceType,
    debug_option,
    handle_errors,
    install_sigterm_handler,
    max_states_option,
)
from kfcrit.cli.inspect import check, radios, schema
from kfcrit.cli.link import link
from kfcrit.defaults import DEFAULT_TOLERANCE
from kfcrit.version import __version__


@click.group(cls=KfcritGroup, epilog=EXAMPLES,
             context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kfcrit")
def main() -> None:
    """kfcrit: critical packet-arrival probability of a Kalman filter over a lossy link."""
    install_sigterm_handler()


main.add_command(check)
main.add_command(schema)
main.add_command(radios)
main.add_command(link)


@main.command("analyze", epilog=EXAMPLES)
@click.argument("system_file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the analysis record as JSON.")
@click.option("--tolerance", type=ToleranceType(), default=DEFAULT_TOLERANCE, show_default=True,
              help="Relative perturbation size for the robust critical value, in [0, 0.1].")
@click.option("--no-simulate", is_flag=True, help="Skip the Monte Carlo simulation.")
@click.option("--quick", is_flag=True, help="Fewer simulations (a fast draft).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@max_states_option
@debug_option
@handle_errors
def analyze_cli(system_file: str, as_json: bool, tolerance: float, no_simulate: bool, quick: bool,
            seed: int, max_states: int, debug: bool) -> None:
    """Analyse SYSTEM_FILE: critical value, bounds, simulation, verdict and review decision."""
    from kfcrit.analysis.record import AnalysisOptions
    from kfcrit.analysis.record import analyze_system as run
    from kfcrit.analysis.spec import load_spec
    from kfcrit.io.jsonio import dumps
    from kfcrit.views.text.terminal import summary

    spec = load_spec(system_file, max_states=max_states)
    hint = long_run_hint(spec.system.n, quick=quick, simulate=not no_simulate)
    if hint:
        click.echo(hint, err=True)
    with blas_threads_for(spec.system.n):
        record = run(spec, AnalysisOptions(tolerance=tolerance, simulate=not no_simulate,
                                           quick=quick, seed=seed))
    click.echo(dumps(record.to_dict()) if as_json else summary(record))
    sys.exit(record.exit_code)


LONG_RUN_STATES = 50
"""Above this many states ``kfcrit analyze`` says on stderr that the run may take minutes."""


def blas_threads_for(n: int, environ: Mapping[str, str] | None = None) -> AbstractContextManager:
    """OpenBLAS on one thread for an analysis above :data:`LONG_RUN_STATES` states, unless
    ``OPENBLAS_NUM_THREADS`` is set (then the user's choice stands).

    Its products there are of a few hundred rows, and OpenBLAS threads that wait for a busy
    core spin: on the 2-core machine at load ≈ 2–3, ``analyze --quick`` of 200 states took
    15.7 s wall and 14.9 s CPU with the default threads against 4.2 s and 4.0 s on one
    (12-03); the Monte Carlo shares its paths between worker threads of its own.
    """
    environ = os.environ if environ is None else environ
    if n <= LONG_RUN_STATES or "OPENBLAS_NUM_THREADS" in environ:
        return nullcontext()
    from kfcrit.theory.covariance.riccati import single_blas_thread

    return single_blas_thread()


def long_run_hint(n: int, *, quick: bool, simulate: bool) -> str | None:
    """The stderr line announcing a long analysis (by the state count, never by a clock)."""
    if n <= LONG_RUN_STATES:
        return None
    if quick:
        return f"kfcrit: n = {n} states: this may take a while (--quick draft)"
    return f"kfcrit: n = {n} states: this may take minutes; --quick skips the Monte Carlo"


@main.command(epilog=EXAMPLES)
@click.argument("source", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outputs", required=True, multiple=True,
              type=click.Path(dir_okay=False),
              help="Output file (.html or .pdf); repeat for both: -o r.html -o r.pdf.")
@click.option("--format", "fmt", type=click.Choice(["html", "pdf"]), default=None,
              help="Format of a single output whose extension does not say it.")
@click.option("--quick", is_flag=True, help="A fast draft with fewer simulations.")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@click.option("--tolerance", type=ToleranceType(), default=DEFAULT_TOLERANCE, show_default=True,
              help="Relative perturbation size for the robust critical value, in [0, 0.1].")
@max_states_option
@debug_option
@click.pass_context
@handle_errors
def report(ctx: click.Context, source: str, outputs: tuple[str, ...], fmt: str | None,
           quick: bool, seed: int, tolerance: float, max_states: int, debug: bool) -> None:
    """Write a design-review report of FILE (a system file, or a record saved with
    'kfcrit analyze --json') to every OUTPUT, from one analysis."""
    from click.core import ParameterSource

    from kfcrit.analysis.spec import load_spec
    from kfcrit.cli.report import ANALYSIS_OPTIONS, report_command, source_kind
    from kfcrit.io.atomic import check_writable

    for out in outputs:
        check_writable(out)
    if source_kind(source) == "system":
        load_spec(source, max_states=max_states)
    given = [n for n in ANALYSIS_OPTIONS
             if ctx.get_parameter_source(n) is ParameterSource.COMMANDLINE]
    sys.exit(report_command(source, list(outputs), fmt=fmt, quick=quick, seed=seed,
                            max_states=max_states, tolerance=tolerance, options_given=given))


@main.command("simulate", epilog=EXAMPLES)
@click.argument("system_file", type=click.Path(dir_okay=False))
@click.option("--paths", type=click.IntRange(1, 10_000_000), default=1000, show_default=True)
@click.option("--steps", type=click.IntRange(1, 10_000_000), default=500, show_default=True)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="Print the simulation summary as JSON.")
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="Write a figure of the simulated traces (SVG or PNG).")
@click.option("--ergodic-steps", type=click.IntRange(1, 100_000_000), default=None,
              help="Also average along 4 long paths of N steps (Kar et al. Prop. 25): time "
                   "mean of tr P, tail probabilities, loss bursts, almost-sure indicators.")
@click.option("--tail", "tail", type=float, multiple=True, metavar="M",
              help="Tail probability P(tr P > M) by time average (repeatable; implies "
                   "--ergodic-steps max(10*steps, 10000) unless given).")
@max_states_option
@debug_option
@handle_errors
def simulate_cli(system_file: str, paths: int, steps: int, seed: int, as_json: bool,
             plot: str | None, ergodic_steps: int | None, tail: tuple[float, ...],
             max_states: int, debug: bool) -> None:
    """Monte Carlo of the random Riccati equation for SYSTEM_FILE."""
    from kfcrit.cli.simulate import simulate_command
    from kfcrit.io.atomic import check_writable

    if plot is not None:
        check_writable(plot)
    sys.exit(simulate_command(system_file, paths=paths, steps=steps, seed=seed, as_json=as_json,
                              plot=plot, max_states=max_states, ergodic_steps=ergodic_steps,
                              tail=tail))


SWEEP_EXAMPLES = """\b
Examples:
  kfcrit sweep reports/sweep-link-distance.yaml -o results/
  kfcrit sweep reports/sweep-link-distance.yaml -o results/ --scheduler tcp://10.0.0.5:8786

\b
Outputs in the folder: sweep.csv, sweep.json, margin.svg, margin.png, run.json and the journal
sweep.journal.jsonl; rerunning the same command after an interruption computes only the
missing points. Each point's review decision (pass / fail / undetermined) is a column of the
table. Exit codes: 0 done, 2 bad sweep file or option (or a point with bad input), 3 a point
was numerically inconclusive, 130 interrupted (finished points are kept).
"""


@main.command("sweep", epilog=SWEEP_EXAMPLES)
@click.argument("sweep_file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default=None, type=click.Path(),
              help="Output folder for the CSV, JSON and plots (default: next to the sweep file; "
                   "its parent folder must exist).")
@click.option("--scheduler", default=None,
              help="Address of an existing Dask scheduler (tcp://HOST:PORT); default local.")
@click.option("--workers", type=click.IntRange(1, 256), default=None,
              help="Local worker processes (default: number of cores).")
@max_states_option
@debug_option
@handle_errors
def sweep_cli(sweep_file: str, output: str | None, scheduler: str | None, workers: int | None,
          max_states: int, debug: bool) -> None:
    """Sweep a grid of system/channel parameters described in SWEEP_FILE."""
    from kfcrit.cli.sweep import sweep_command

    sys.exit(sweep_command(sweep_file, output=output, scheduler=scheduler, workers=workers,
                           max_states=max_states))
