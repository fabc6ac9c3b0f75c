"""Shared pieces of the command line: one-line errors, exit handling, common options.

stdout carries data only (the summary, or exactly the JSON record with ``--json``); progress and
errors go to stderr. Exit codes are :class:`kfcrit.errors.ExitCode`: 0 done (review pass), 1 a
verification failed, 2 bad usage or bad input file, 3 undetermined, 4 internal error, 5 the review
failed.
"""
from __future__ import annotations

import functools
import sys
import traceback
from collections.abc import Callable
from typing import Any

import click

from kfcrit.errors import ExitCode, KfcritError
from kfcrit.io.safeio import printable

EXAMPLES = """\b
Examples:
  kfcrit analyze reports/sinopoli-scalar.yaml
  kfcrit analyze reports/rotation-third-turn.yaml --json
  kfcrit report reports/sinopoli-general.yaml -o review.html
  kfcrit report reports/sinopoli-general.yaml -o review.pdf --quick
  kfcrit simulate reports/kar-scalar-fractal.yaml --paths 2000 --steps 500 --seed 1

\b
Exit codes: 0 done (review pass), 1 a verification failed, 2 bad usage or bad
input file, 3 undetermined (review undetermined, or a numerical method was
inconclusive), 4 internal error (a bug: please report it), 5 the review failed
(unstable at the operating point, a requirement not met, or the link policy
not met), 130 interrupted, 141 the reader of stdout closed the pipe.
"""


def fail(message: str, code: int) -> None:
    """Print one line to stderr and exit with ``code``.

    Whitespace (newlines, carriage returns) is folded to single spaces and any other control
    character is escaped (``\\x1b``): a message may echo text from the user's file, which
    must not move the cursor or rewrite what the terminal shows.
    """
    click.echo(f"kfcrit: error: {printable(' '.join(str(message).split()))}", err=True)
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


