"""Atomic file output: every file kfcrit writes goes through :func:`write_atomic`.

A reader (or a user who pressed Ctrl-C) sees the previous file or the complete new one, never a
partial file; this is the single implementation used by the report, sweep and simulate commands.

Invariant: only a *regular* file is ever replaced. A destination that exists and is anything
else — a character device such as ``/dev/null``, a FIFO, a socket, a block device, a folder — is
refused with one line naming the path, both by :func:`check_writable` before any work and by
:func:`write_atomic` immediately before the rename (a rename over a device node would replace
the node by a regular file).

Invariant: the temporary file is created in the folder of the file that is finally replaced.
A symbolic link named by the user is followed (the file it points to is rewritten, like
``open(path, "w")`` would, and the link stays), so the rename never crosses file systems and a
link into another file system cannot fail with ``EXDEV`` after the work was done. Files whose
names kfcrit chooses itself (the sweep tables) pass ``follow_symlinks=False``: a link planted
in their place is replaced, never written through.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path
from typing import Any

from kfcrit.errors import OutputError

__all__ = ["check_writable", "final_path", "write_atomic"]

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISSOCK, "a socket"))


def _current_umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _shown(target: Path) -> str:
    return repr(str(target)[:120])


def _output_error(target: Path, exc: OSError) -> OutputError:
    reason = exc.strerror or str(exc) or type(exc).__name__
    return OutputError(f"cannot write {_shown(target)}: {reason}", field="output")


def final_path(path: str | Path, *, follow_symlinks: bool = True) -> Path:
    """The absolute path of the file that a write to ``path`` replaces.

    With ``follow_symlinks`` every link is resolved (also the last component); without it only
    the folder is resolved and a link at ``path`` is itself the file replaced.
    """
    target = Path(path)
    try:
        if follow_symlinks:
            return target.resolve()
        return target.parent.resolve() / target.name
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python < 3.13)
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "symlink loop"
        raise OutputError(f"cannot write {_shown(target)}: {reason}", field="output") from None


def _refuse_non_regular(shown_as: Path, final: Path) -> None:
    """Raise :class:`OutputError` when ``final`` exists and is not a regular file (or a link,
    which ``final`` only is when links are not followed)."""
    try:
        mode = os.lstat(final).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise _output_error(shown_as, exc) from None
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    where = "" if final == Path(shown_as).absolute() else f" (it leads to {str(final)[:120]!r})"
    raise OutputError(f"{_shown(shown_as)} is {kind}{where}; refusing to replace it: give the "
                      "path of a regular file", field="output")


def check_writable(path: str | Path, *, follow_symlinks: bool = True) -> None:
    """Fail early (:class:`~kfcrit.errors.OutputError`) when ``path`` cannot be written.

    Refuses a destination that is not a regular file (a device, FIFO, socket or folder, also
    behind a symbolic link), then creates and removes a temporary file in the folder of the
    file finally replaced, exactly as :func:`write_atomic` will; nothing else is touched.
    """
    target = Path(path)
    final = final_path(target, follow_symlinks=follow_symlinks)
    _refuse_non_regular(target, final)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=str(final.parent))
    except OSError as exc:
        raise _output_error(target, exc) from None
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError:
        pass


def write_atomic(path: str | Path, data: bytes, *, follow_symlinks: bool = True) -> None:
    """Write ``data`` to ``path`` atomically: temporary file in the same folder, fsync, rename.

    The new file gets the usual permissions ``0o666 & ~umask`` (``mkstemp`` alone would leave
    ``0o600``). On any error, including ``KeyboardInterrupt``, the temporary file is removed
    and an existing file at ``path`` is untouched.

    A file-system failure (missing or read-only folder, no permission, disk full, a path that is
    not a regular folder such as ``/proc``) or a destination that is not a regular file (a
    device, FIFO, socket or folder) raises :class:`~kfcrit.errors.OutputError` naming the path
    (exit code 2).

    Parameters
    ----------
    path : str or Path
        Destination; its folder must exist.
    data : bytes
        The complete file content.
    follow_symlinks : bool
        Write through a symbolic link at ``path`` (default) or replace the link itself.
    """
    target = Path(path)
    final = final_path(target, follow_symlinks=follow_symlinks)
    _refuse_non_regular(target, final)
    folder = final.parent
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=str(folder))
    except OSError as exc:
        raise _output_error(target, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_current_umask())
        # checked again just before the rename: the node may have been swapped in meanwhile
        _refuse_non_regular(target, final)
        os.replace(tmp, final)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
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


def refuse_replacing_inputs(outputs: Any, inputs: Any, field: str) -> None:
    """Refuse (InputError naming ``field``) any output path that is, or points to, an input
    file of the same run: the system or sweep file, a sweep's base system, a trace.

    Paths are compared after following symbolic links (``os.path.realpath``) and, when both
    exist, by device and inode, so a link or a hard link to an input is caught as well.
    """
    import os
    from pathlib import Path

    from kfcrit.errors import InputError

    ins = [Path(p) for p in inputs if p]
    for out in outputs:
        if not out:
            continue
        o = Path(out)
        for i in ins:
            same = os.path.realpath(o) == os.path.realpath(i)
            if not same and o.exists() and i.exists():
                try:
                    same = os.path.samefile(o, i)
                except OSError:
                    same = False
            if same:
                raise InputError(f"{str(o)[:80]!r} would replace the input file "
                                 f"{str(i)[:80]!r} of this run", field=field)
