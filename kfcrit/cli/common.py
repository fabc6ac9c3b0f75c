"""Shared pieces of the command line: one-line errors, exit handling, common options.

stdout carries data only (the summary, or exactly the JSON record with ``--json``); progress and
errors go to stderr. Exit codes are :class:`kfcrit.errors.ExitCode`: 0 done (review pass), 1 a
verification failed, 2 bad usage or bad input file, 3 undetermined, 4 internal error, 5 the review
failed.
"""
from __future__ import annotations

import errno
import functools
import sys
import traceback
import warnings
from collections.abc import Callable
from typing import Any

import click

from kfcrit.defaults import MAX_STATES_DEFAULT
from kfcrit.errors import ExitCode, KfcritError
from kfcrit.io.safeio import printable

EXAMPLES = """\b
Examples:
  kfcrit analyze reports/sinopoli-scalar.yaml
  kfcrit analyze reports/rotation-third-turn.yaml --json
  kfcrit report reports/sinopoli-general.yaml -o review.html
  kfcrit report reports/sinopoli-general.yaml -o review.pdf --quick
  kfcrit report reports/link-oqpsk-sensor.yaml -o review.html -o review.pdf
  kfcrit analyze FILE --json > record.json && kfcrit report record.json -o review.pdf
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
    flush_std_streams()
    os._exit(ExitCode.INTERRUPTED)


def flush_std_streams() -> None:
    """Flush stdout and stderr before ``os._exit`` (which skips the interpreter's own flush);
    a stream that is already closed or broken is left alone."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass


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


ENVIRONMENT_ERRNOS = frozenset(getattr(errno, name) for name in
                               ("ENOSPC", "EDQUOT", "EIO", "EFBIG", "EROFS", "ENXIO")
                               if hasattr(errno, name))
"""``errno`` values that describe the machine (disk full, quota, I/O error, read-only file
system), not a bug: reported as one line with exit code 2 even when no path is attached."""


def _about_stdout(exc: BaseException) -> bool:
    """Whether ``exc`` was raised writing stdout: the innermost Python frame (``click.echo``,
    ``print``'s caller) holds stdout, or flushing stdout fails again."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    streams = [s for s in (sys.stdout, sys.__stdout__) if s is not None]
    streams += [getattr(s, "buffer", None) for s in streams]
    if tb is not None and any(v is s for v in tb.tb_frame.f_locals.values()
                              for s in streams if s is not None):
        return True
    try:
        sys.stdout.flush()
    except (OSError, ValueError):
        return True
    return False


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so the interpreter's final flush of data that could not be
    written cannot print an "Exception ignored" traceback after the one error line."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


def environment_exit(exc: OSError) -> None:
    """One line for a full disk, an I/O error or a read-only file system; exit code 2."""
    reason = exc.strerror or str(exc)
    if exc.filename is not None:
        fail(f"cannot write {str(exc.filename)[:120]!r}: {reason}", ExitCode.BAD_INPUT)
    if _about_stdout(exc):
        _silence_stdout()
        fail(f"cannot write to standard output: {reason}", ExitCode.BAD_INPUT)
    fail(f"cannot write the output: {reason}", ExitCode.BAD_INPUT)


def _flush_stdout() -> None:
    """Flush stdout now, inside the error handling (not at interpreter exit, where a failure
    would be an ignored traceback and exit code 120)."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        broken_pipe_exit()
    except OSError as exc:
        _silence_stdout()
        fail(f"cannot write to standard output: {exc.strerror or exc}", ExitCode.BAD_INPUT)
    except ValueError:  # stdout closed by the caller: nothing left to flush
        pass


def handle_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn kfcrit errors into one stderr line and the documented exit code."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        debug = kwargs.get("debug", False)
        try:
            result = func(*args, **kwargs)
            _flush_stdout()
            return result
        except KfcritError as exc:
            if debug:
                traceback.print_exc()
            fail(str(exc), exc.exit_code)
        except KeyboardInterrupt:
            interrupted_exit()
        except (click.exceptions.Exit, click.ClickException, SystemExit):
            _flush_stdout()
            raise
        except BrokenPipeError:
            broken_pipe_exit()
        except OSError as exc:
            if debug:
                traceback.print_exc()
            if exc.errno in ENVIRONMENT_ERRNOS:
                environment_exit(exc)
            if exc.filename is None:  # not about a path the user gave: a bug
                fail(f"internal error (OSError: {str(exc)[:200]}); rerun with --debug for the "
                     "traceback", ExitCode.INTERNAL)
            fail(f"{str(exc.filename)[:120]!r}: {exc.strerror or exc}", ExitCode.BAD_INPUT)
        except MemoryError:
            fail("out of memory (is the problem too large? see --max-states)", ExitCode.BAD_INPUT)
        except OverflowError as exc:
            # valid input whose numbers leave the float64 range somewhere a method did not
            # expect: the analysis is undetermined, not a crash
            if debug:
                traceback.print_exc()
            fail(f"undetermined: a floating-point computation overflowed ({str(exc)[:120]}); "
                 "the system's numbers are too large for float64 arithmetic", ExitCode.INCONCLUSIVE)
        except Exception as exc:  # noqa: BLE001 - last-resort guard, one line for the user
            if debug:
                traceback.print_exc()
            fail(f"internal error ({type(exc).__name__}: {str(exc)[:200]}); rerun with --debug "
                 "for the traceback", ExitCode.INTERNAL)

    return wrapper


class WarningTally:
    """Collects the warnings NumPy/SciPy print during a command (``warnings.showwarning``).

    An ill-conditioned system can make SciPy repeat the same ``RuntimeWarning`` dozens of times;
    they are counted here and summarised in one stderr line (:meth:`summary`) instead. The
    number of distinct messages kept is bounded.
    """

    MAX_DISTINCT = 20

    def __init__(self) -> None:
        self.total = 0
        self.messages: dict[str, int] = {}

    def show(self, message: Warning | str, category: type[Warning], filename: str,
             lineno: int, file: Any = None, line: str | None = None) -> None:
        self.total += 1
        text = f"{category.__name__}: {' '.join(str(message).split())[:160]}"
        if text in self.messages or len(self.messages) < self.MAX_DISTINCT:
            self.messages[text] = self.messages.get(text, 0) + 1

    def summary(self) -> str | None:
        """One line, or None when nothing was reported."""
        if not self.total:
            return None
        first = max(self.messages, key=self.messages.get) if self.messages else ""
        more = len(self.messages) - 1
        return (f"kfcrit: warning: the numerical libraries reported {self.total} floating-point "
                f"warning{'s' if self.total != 1 else ''} (most often {printable(first)}"
                f"{f'; {more} other kinds' if more > 0 else ''}); rerun with --debug to print "
                "them")


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
        tally = WarningTally()
        with warnings.catch_warnings():
            argv = list(args) if isinstance(args, (list, tuple)) else sys.argv[1:]
            if "--debug" not in argv:  # --debug shows every warning as it comes
                warnings.showwarning = tally.show
            try:
                rv = self._run(args, prog_name, complete_var, **extra)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
                self._summarise(tally, code)
                raise
            self._summarise(tally, rv if isinstance(rv, int) else 0)
        sys.exit(rv if isinstance(rv, int) else 0)

    @staticmethod
    def _summarise(tally: WarningTally, code: int) -> None:
        """The warnings line, after a result (exit 0, 1, 3 or 5); an error line stays alone."""
        line = tally.summary()
        if line and code in (ExitCode.OK, ExitCode.VERIFICATION_FAILED, ExitCode.INCONCLUSIVE,
                             ExitCode.REVIEW_FAILED):
            try:
                click.echo(line, err=True)
            except (OSError, ValueError):
                pass

    def _run(self, args: Any, prog_name: str | None, complete_var: str | None,
             **extra: Any) -> Any:
        try:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
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
        return None


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
max_states_option = click.option("--max-states", type=click.IntRange(1, 100_000), default=MAX_STATES_DEFAULT,
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


def spec_inputs(spec: Any, source: Any = None) -> list[Any]:
    """The files a loaded system file reads: the file itself and a trace channel's path (also
    each network sensor's trace)."""
    from pathlib import Path

    out = [source] if source else []
    channels = [getattr(spec, "channel", None)]
    net = getattr(spec, "network", None)
    if net is not None:
        channels += [s.channel for s in net.sensors]
    base = Path(source).resolve().parent if source else Path.cwd()
    for ch in channels:
        if ch is not None and getattr(ch, "model", None) == "trace" and getattr(ch, "path", None):
            out.append(base / ch.path if not Path(ch.path).is_absolute() else Path(ch.path))
    return out
