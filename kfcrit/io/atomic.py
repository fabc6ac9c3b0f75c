"""Atomic file output: every file kfcrit writes goes through :func:`write_atomic`.

A reader (or a user who pressed Ctrl-C) sees the previous file or the complete new one, never a
partial file; this is the single implementation used by the report, sweep and simulate commands.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from kfcrit.errors import OutputError

__all__ = ["check_writable", "write_atomic"]


def _current_umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _output_error(target: Path, exc: OSError) -> OutputError:
    reason = exc.strerror or str(exc) or type(exc).__name__
    return OutputError(f"cannot write {str(target)[:120]!r}: {reason}", field="output")


def check_writable(path: str | Path) -> None:
    """Fail early (:class:`~kfcrit.errors.OutputError`) when ``path`` cannot be written.

    Creates and removes a temporary file in the target folder, exactly as
    :func:`write_atomic` will; nothing else is touched.
    """
    target = Path(path)
    try:
        folder = target.resolve().parent
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=str(folder))
    except OSError as exc:
        raise _output_error(target, exc) from None
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError:
        pass
    if target.is_dir():
        raise OutputError(f"{str(target)[:120]!r} is a folder", field="output")


def write_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temporary file in the same folder, fsync, rename.

    The new file gets the usual permissions ``0o666 & ~umask`` (``mkstemp`` alone would leave
    ``0o600``). On any error, including ``KeyboardInterrupt``, the temporary file is removed
    and an existing file at ``path`` is untouched.

    A file-system failure (missing or read-only folder, no permission, disk full, a path that is
    not a regular folder such as ``/proc``) raises :class:`~kfcrit.errors.OutputError` naming
    the path (exit code 2).

    Parameters
    ----------
    path : str or Path
        Destination; its folder must exist.
    data : bytes
        The complete file content.
    """
    target = Path(path)
    try:
        folder = target.resolve().parent
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=str(folder))
    except OSError as exc:
        raise _output_error(target, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_current_umask())
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise _output_error(target, exc) from None
        raise
    try:  # make the rename itself durable (best effort; not every filesystem allows it)
        dfd = os.open(str(folder), os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass
