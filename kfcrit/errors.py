"""Errors and exit codes of kfcrit.

Every failure a user can cause is a :class:`KfcritError` whose message is one line naming the
offending field; the command line turns it into that line on stderr and the documented exit code.
"""
from __future__ import annotations

from enum import IntEnum


class ExitCode(IntEnum):
    """Exit codes of the ``kfcrit`` command (documented in README.md)."""

    OK = 0
    """The command did what was asked."""
    VERIFICATION_FAILED = 1
    """A verification (certificate, cross-check, requirement) failed."""
    BAD_INPUT = 2
    """Bad usage or a bad input file."""
    INCONCLUSIVE = 3
    """Undetermined: the review decision is ``undetermined`` (or a numerical method was
    inconclusive)."""
    INTERNAL = 4
    """An internal error (a bug): one line asking to rerun with ``--debug`` and report it."""
    REVIEW_FAILED = 5
    """The review decision is ``fail``: the design is unstable at its operating point, misses a
    requirement, or its link misses the margin or outage policy."""
    INTERRUPTED = 130
    """Interrupted by SIGINT or SIGTERM (128 + SIGINT, the shell's convention for Ctrl-C)."""
    BROKEN_PIPE = 141
    """The reader of stdout closed the pipe (128 + SIGPIPE); nothing more is printed."""


class KfcritError(Exception):
    """Base class of errors reported to the user as one line."""

    exit_code: ExitCode = ExitCode.BAD_INPUT

    def __init__(self, message: str, *, field: str | None = None) -> None:
        self.field = field
        text = f"{field}: {message}" if field else message
        super().__init__(" ".join(str(text).split()))


class InputError(KfcritError):
    """A system, sweep or trace file (or an argument) is invalid."""

    exit_code = ExitCode.BAD_INPUT


class OutputError(InputError, OSError):
    """An output file or folder cannot be written (exit code 2, naming the path).

    Also an :class:`OSError`, so callers that handle file-system errors still catch it.
    """


class ExpressionError(InputError):
    """An expression string is not in the allowed grammar or exceeds a limit."""


class NumericalError(KfcritError):
    """A numerical method could not reach a conclusion."""

    exit_code = ExitCode.INCONCLUSIVE


class VerificationError(KfcritError):
    """A certificate or cross-check failed."""

    exit_code = ExitCode.VERIFICATION_FAILED
