"""Errors and exit codes of kfcrit.

Every failure a user can cause is a :class:`KfcritError` whose message is one line naming the
offending field; the command line turns it into that line on stderr and the documented exit code.
"""
from __future__ import annotations

from enum import IntEnum


class ExitCode(IntEnum):
    """Exit codes of the ``kfcrit`` command (documented in README.md).

    The review decision of an analysis fixes the code: ``pass`` gives 0, ``undetermined`` 3 and
    ``fail`` 5; a failed verification check gives 1 whatever the decision.

    Attributes
    ----------
    OK, VERIFICATION_FAILED, BAD_INPUT, INCONCLUSIVE, INTERNAL, REVIEW_FAILED : int
        0, 1, 2, 3, 4 and 5 (each member is documented below).
    INTERRUPTED, BROKEN_PIPE : int
        130 and 141 (128 + SIGINT, 128 + SIGPIPE).

    Raises
    ------
    ValueError
        ``ExitCode(n)`` for a number that is not one of the codes.

    References
    ----------
    docs/theory.md §16.3 (the review decision) and §16.4 (the table of exit codes).

    Examples
    --------
    >>> from kfcrit import ExitCode
    >>> int(ExitCode.REVIEW_FAILED), ExitCode(3).name
    (5, 'INCONCLUSIVE')
    >>> ExitCode(7)
    Traceback (most recent call last):
        ...
    ValueError: 7 is not a valid ExitCode
    """

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
    """Base class of errors reported to the user as one line.

    Every failure a user can cause (a bad matrix, file, argument or an inconclusive numerical
    method) is a subclass; the command line prints the message and exits with ``exit_code``.

    Parameters
    ----------
    message : str
        What is wrong; whitespace runs (newlines included) are collapsed to one space.
    field : str, optional
        The offending field (``"A"``, ``"channel.arrival_probability"``); it prefixes the
        message as ``"field: message"``.

    Attributes
    ----------
    field : str or None
        The ``field`` given.
    exit_code : ExitCode
        ``BAD_INPUT`` (2) here and for input errors, ``INCONCLUSIVE`` (3) for numerical
        errors, ``VERIFICATION_FAILED`` (1) for failed certificates.

    Raises
    ------
    KfcritError
        Nothing is raised by the constructor; the instance is what kfcrit raises, e.g.
        :class:`~kfcrit.System` raises its subclass ``InputError`` for a non-square ``A``.

    References
    ----------
    docs/theory.md §16.4 (exit codes).

    Examples
    --------
    >>> from kfcrit import KfcritError, System
    >>> err = KfcritError("must be positive", field="R")
    >>> str(err), err.field, int(err.exit_code)
    ('R: must be positive', 'R', 2)
    >>> try:
    ...     System(A=[[1, 2]], C=[[1]], Q=1, R=1)
    ... except KfcritError as exc:
    ...     print(exc.field, "|", exc)
    A | A: must be square, got 1x2
    """

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
