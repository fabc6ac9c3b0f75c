"""Command line: ``kfcrit analyze | report | simulate | sweep``.

stdout carries data only (the summary, or exactly the JSON record with ``--json``); progress and
errors go to stderr. Exit codes are :class:`kfcrit.errors.ExitCode`: 0 done, 1 a verification
failed, 2 bad usage or bad input file, 3 a numerical method was inconclusive, 4 internal error.
"""
from __future__ import annotations

import functools
import sys
import traceback
from collections.abc import Callable
from typing import Any

import click

from kfcrit.version import __version__
from kfcrit.errors import ExitCode, KfcritError

EXAMPLES = """\b
Examples:
  kfcrit analyze reports/sinopoli-scalar.yaml
  kfcrit analyze reports/rotation-third-turn.yaml --json
  kfcrit report reports/sinopoli-general.yaml -o review.html
  kfcrit report reports/sinopoli-general.yaml -o review.pdf --quick
  kfcrit simulate reports/kar-scalar-fractal.yaml --paths 2000 --steps 500 --seed 1

\b
Exit codes: 0 done, 1 a verification failed, 2 bad usage or bad input file,
3 a numerical method was inconclusive, 4 internal error (a bug: please report it),
130 interrupted, 141 the reader of stdout closed the pipe.
"""


def fail(message: str, code: int) -> None:
    """Print one line to stderr and exit with ``code``."""
    click.echo(f"kfcrit: error: {' '.join(str(message).split())}", err=True)
    sys.exit(int(code))


def interrupted_exit() -> None:
    """Report an interruption in one line and leave at once with exit code 130.

    By the time the ``KeyboardInterrupt`` reaches here every ``finally`` block has run (temporary
    files are removed), so the process ends with ``os._exit``: an interrupt may land inside a
    JIT compilation, whose half-built objects would otherwise print "Exception ignored"
    tracebacks from their finalizers at interpreter shutdown.
    """
    import os

    click.echo("kfcrit: error: interrupted; nothing was written", err=True)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(ExitCode.INTERRUPTED)


def broken_pipe_exit() -> None:
    """The reader of stdout went away (``kfcrit analyze … | head``): leave quietly with 141.

    Nobody is left to read the data, so nothing is printed; 141 = 128 + SIGPIPE is what a shell
    reports for a program killed by a broken pipe. stdout is pointed at /dev/null first so the
    interpreter's final flush cannot raise again.
    """
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    os._exit(ExitCode.BROKEN_PIPE)


def handle_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn kfcrit errors into one stderr line and the documented exit code."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        debug = kwargs.get("debug", False)
        try:
            return func(*args, **kwargs)
        except KfcritError as exc:
            if debug:
                traceback.print_exc()
            fail(str(exc), exc.exit_code)
        except KeyboardInterrupt:
            interrupted_exit()
        except (click.exceptions.Exit, click.ClickException, SystemExit):
            raise
        except BrokenPipeError:
            broken_pipe_exit()
        except OSError as exc:
            if exc.filename is None:  # not about a path the user gave: a bug
                if debug:
                    traceback.print_exc()
                fail(f"internal error (OSError: {str(exc)[:200]}); rerun with --debug for the "
                     "traceback", ExitCode.INTERNAL)
            if debug:
                traceback.print_exc()
            fail(f"{str(exc.filename)[:120]!r}: {exc.strerror or exc}", ExitCode.BAD_INPUT)
        except MemoryError:
            fail("out of memory (is the problem too large? see --max-states)", ExitCode.BAD_INPUT)
        except Exception as exc:  # noqa: BLE001 - last-resort guard, one line for the user
            if debug:
                traceback.print_exc()
            fail(f"internal error ({type(exc).__name__}: {str(exc)[:200]}); rerun with --debug "
                 "for the traceback", ExitCode.INTERNAL)

    return wrapper


class KfcritGroup(click.Group):
    """The command group; usage errors become one line ``kfcrit: error: ...`` and exit code 2.

    Click's standalone mode prints a usage block and ``Error: ...``; here ``main`` runs click in
    non-standalone mode and reports :class:`click.UsageError` (unknown option, missing argument,
    bad option value) and other :class:`click.ClickException` in one line. ``--help`` and
    ``--version`` print as usual.
    """

    def main(self, args: Any = None, prog_name: str | None = None,  # type: ignore[override]
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        install_sigterm_handler()  # first: a SIGTERM from here on exits 130 with one line
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:  # bare ``kfcrit``: the help text
            exc.show()
            sys.exit(ExitCode.BAD_INPUT)
        except click.UsageError as exc:
            hint = ""
            if exc.ctx is not None:
                hint = f" (see '{exc.ctx.command_path} --help')"
            fail(f"{exc.format_message().rstrip('.')}{hint}", ExitCode.BAD_INPUT)
        except click.exceptions.Abort:
            interrupted_exit()
        except click.ClickException as exc:
            fail(exc.format_message(), exc.exit_code)
        except KeyboardInterrupt:
            interrupted_exit()
        sys.exit(rv if isinstance(rv, int) else 0)


class ToleranceType(click.ParamType):
    """A finite number in [0, 0.1] (``nan`` and ``inf`` are refused, unlike FloatRange)."""

    name = "float"

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> float:
        import math

        try:
            x = float(value)
        except (TypeError, ValueError):
            self.fail(f"must be a number in [0, 0.1], got {str(value)[:40]!r}", param, ctx)
        if not math.isfinite(x) or not 0 <= x <= 0.1:
            self.fail(f"must be a number in [0, 0.1], got {str(value)[:40]!r}", param, ctx)
        return x


debug_option = click.option("--debug", is_flag=True, help="Show tracebacks of errors.")
max_states_option = click.option("--max-states", type=click.IntRange(1, 100_000), default=400,
                                 show_default=True, help="Refuse systems with more states.")


@click.group(cls=KfcritGroup, epilog=EXAMPLES,
             context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kfcrit")
def main() -> None:
    """kfcrit: critical packet-arrival probability of a Kalman filter over a lossy link."""
    install_sigterm_handler()


def install_sigterm_handler() -> None:
    """Turn SIGTERM into ``KeyboardInterrupt`` so that ``finally`` blocks remove temporary files
    (atomic writes then leave the previous output or nothing, never a partial file)."""
    import signal

    def _raise(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    try:
        signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not the main thread (e.g. under a test runner's worker thread)
        pass


@main.command(epilog=EXAMPLES)
@click.argument("system_file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the analysis record as JSON.")
@click.option("--tolerance", type=ToleranceType(), default=1e-9, show_default=True,
              help="Relative perturbation size for the robust critical value, in [0, 0.1].")
@click.option("--no-simulate", is_flag=True, help="Skip the Monte Carlo simulation.")
@click.option("--quick", is_flag=True, help="Fewer simulations (a fast draft).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@max_states_option
@debug_option
@handle_errors
def analyze(system_file: str, as_json: bool, tolerance: float, no_simulate: bool, quick: bool,
            seed: int, max_states: int, debug: bool) -> None:
    """Analyse SYSTEM_FILE: critical value, bounds, simulation and verdict."""
    from kfcrit.analysis.record import AnalysisOptions
    from kfcrit.analysis.record import analyze as run
    from kfcrit.io.jsonio import dumps
    from kfcrit.io.systemfile import load_spec
    from kfcrit.views.text import summary

    spec = load_spec(system_file, max_states=max_states)
    record = run(spec, AnalysisOptions(tolerance=tolerance, simulate=not no_simulate,
                                       quick=quick, seed=seed))
    click.echo(dumps(record) if as_json else summary(record.to_dict()))
    sys.exit(exit_code_of(record.to_dict()))


def exit_code_of(record: dict[str, Any]) -> int:
    """The documented exit code of an analysis record: :func:`kfcrit.analysis.record.exit_code`."""
    from kfcrit.analysis.record import exit_code

    return exit_code(record)


@main.command(epilog=EXAMPLES)
@click.argument("system_file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output file (.html or .pdf).")
@click.option("--format", "fmt", type=click.Choice(["html", "pdf"]), default=None,
              help="Output format (default: from the output file's extension).")
@click.option("--quick", is_flag=True, help="A fast draft with fewer simulations.")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@click.option("--tolerance", type=ToleranceType(), default=1e-9, show_default=True,
              help="Relative perturbation size for the robust critical value, in [0, 0.1].")
@max_states_option
@debug_option
@handle_errors
def report(system_file: str, output: str, fmt: str | None, quick: bool, seed: int,
           tolerance: float, max_states: int, debug: bool) -> None:
    """Write a design-review report of SYSTEM_FILE to OUTPUT (HTML or PDF)."""
    from kfcrit.io.atomic import check_writable
    from kfcrit.views.report import report_command
    from kfcrit.io.systemfile import load_spec

    # refuse a bad output path or a bad system file before any progress line is printed (the
    # error is then the only line on stderr); load_spec remembers the file, so the report
    # does not parse it twice
    check_writable(output)
    load_spec(system_file, max_states=max_states)
    sys.exit(report_command(system_file, output, fmt=fmt, quick=quick, seed=seed,
                            max_states=max_states, tolerance=tolerance))


@main.command(epilog=EXAMPLES)
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
def simulate(system_file: str, paths: int, steps: int, seed: int, as_json: bool,
             plot: str | None, ergodic_steps: int | None, tail: tuple[float, ...],
             max_states: int, debug: bool) -> None:
    """Monte Carlo of the random Riccati equation for SYSTEM_FILE."""
    from kfcrit.io.atomic import check_writable
    from kfcrit.sim.montecarlo import simulate_command

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
missing points. Exit codes: 0 done, 2 bad sweep file or option (or a point with bad input),
3 a point was numerically inconclusive, 130 interrupted (finished points are kept).
"""


@main.command(epilog=SWEEP_EXAMPLES)
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
def sweep(sweep_file: str, output: str | None, scheduler: str | None, workers: int | None,
          max_states: int, debug: bool) -> None:
    """Sweep a grid of system/channel parameters described in SWEEP_FILE."""
    from kfcrit.analysis.sweep import sweep_command

    sys.exit(sweep_command(sweep_file, output=output, scheduler=scheduler, workers=workers,
                           max_states=max_states))
