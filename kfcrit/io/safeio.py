"""Bounded reading of the files a user names (system, sweep and trace files, the sweep journal).

:func:`read_text` is the only way kfcrit reads such a file. It refuses anything that is not a
regular file — a directory, a FIFO (which would block), a character device such as
``/dev/zero`` or ``/dev/urandom`` (endless), a socket — and decides that on ``fstat`` of the
descriptor it actually opened, so a path swapped between a check and the open cannot slip
through. The open itself never blocks (``O_NONBLOCK``: opening a FIFO with no writer returns at
once), at most ``max_bytes + 1`` bytes are ever read (``st_size`` is not trusted: it is 0 for
``/dev/zero`` and for files in ``/proc``), and the bytes must be valid UTF-8. Every failure is
one :class:`~kfcrit.errors.InputError` naming the field; the file's contents are never echoed.
"""
from __future__ import annotations

import os
import re
import stat

from kfcrit.errors import InputError

CHUNK_BYTES = 1 << 20
"""Bytes requested per ``read`` call (the buffer never grows beyond what the file holds)."""

_KINDS = ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a directory"),
          (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def read_text(path: str | os.PathLike[str], *, field: str, max_bytes: int,
              what: str = "file", follow_symlinks: bool = True) -> tuple[str, bytes]:
    """The UTF-8 text of the regular file ``path`` and its bytes, at most ``max_bytes`` long.

    Parameters
    ----------
    path : str or path-like
        The file to read.
    field : str
        The field named by every error (``file``, ``channel.path``, ``output``, …).
    max_bytes : int
        Largest accepted size; a longer file is refused after reading ``max_bytes + 1`` bytes.
    what : str
        How the file is called in messages (``file``, ``trace file``, ``journal``).
    follow_symlinks : bool
        With ``False`` a symbolic link at ``path`` is refused (``lstat`` first, then
        ``O_NOFOLLOW`` on the open), for files kfcrit itself names such as the sweep journal.

    Raises
    ------
    InputError
        Missing or unreadable, not a regular file, larger than ``max_bytes``, or not UTF-8.
    """
    shown = repr(str(path)[:80]) if what == "file" else f"{what} {str(path)[:80]!r}"
    try:
        # a first look without opening: devices and FIFOs are refused before open() touches
        # them (opening some devices has effects); the fstat below is the binding check
        mode = (os.stat if follow_symlinks else os.lstat)(path).st_mode
        if not stat.S_ISREG(mode):
            raise InputError(f"{shown} is {_kind(mode)}, not a regular file", field=field)
        flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) \
            | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
        if not follow_symlinks:
            flags |= getattr(os, "O_NOFOLLOW", 0)
        fd = os.open(path, flags)
    except InputError:
        raise
    except (OSError, ValueError):  # ValueError: a NUL byte in the path
        raise InputError(f"cannot read {shown} (no such file or not readable)",
                         field=field) from None
    try:
        try:
            mode = os.fstat(fd).st_mode
            if not stat.S_ISREG(mode):
                raise InputError(f"{shown} is {_kind(mode)}, not a regular file",
                                 field=field)
            chunks: list[bytes] = []
            total = 0
            while total <= max_bytes:
                block = os.read(fd, min(CHUNK_BYTES, max_bytes + 1 - total))
                if not block:
                    break
                chunks.append(block)
                total += len(block)
        except InputError:
            raise
        except OSError:
            raise InputError(f"cannot read {shown}", field=field) from None
    finally:
        os.close(fd)
    if total > max_bytes:
        raise InputError(f"{shown} is larger than {max_bytes} bytes", field=field)
    data = b"".join(chunks)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{shown} is not valid UTF-8 text", field=field) from None
    return text, data


_CONTROLS = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """``text`` with every control, line-separator and bidi-override character escaped
    (``\\x1b``, ``\\u202e``), so user text echoed in a message cannot move the cursor, erase a
    line or reorder what the terminal shows. Tabs and newlines are kept (callers that need one
    line fold whitespace themselves)."""
    return _CONTROLS.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)


__all__ = ["CHUNK_BYTES", "printable", "read_text"]
