"""Files a command writes at a path the user names (``--report``, ``xac1 sim --state``): never anything
but a regular file, written whole or not at all.

How this works: ``check_output(path, option)`` is called before the command starts any work. It follows
a symbolic link to the file it names (a link is the user's way of pointing somewhere: the target is
written, the link stays) and refuses, with ``OutputFileError`` naming the option, the path and what is
there, anything that is not a regular file or a new name in a writable folder: a directory, a FIFO, a
device node (``--report /dev/null`` run as root would otherwise replace ``/dev/null``), a socket.
``write_output(path, data)`` writes beside that target a temporary file, renames it over the target
(atomic: a reader sees the old file or the new one) and keeps the target's permission bits; with
``durable`` it also fsyncs the file and the folder (the simulator's non-volatile memory).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

from .errors import XAC1Error

__all__ = ["OutputFileError", "check_output", "write_output"]

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


class OutputFileError(XAC1Error, ValueError):
    """The path cannot take the output file (the message says which option, which path, and why)."""


def _target(path: str | os.PathLike[str]) -> Path:
    """The file ``path`` names: the end of its chain of symbolic links (which may not exist yet)."""
    return Path(os.path.realpath(path))


def _not_regular(mode: int) -> str | None:
    for test, what in _KINDS:
        if test(mode):
            return what
    return None if stat.S_ISREG(mode) else "not a regular file"


def check_output(path: str | os.PathLike[str], option: str) -> Path:
    """The file to write for ``path`` (through its links), once sure it can be written as a regular
    file; else ``OutputFileError`` saying so (``option`` starts the message: ``--report``)."""
    target = _target(path)
    via = f" (a link to {target})" if os.path.islink(path) else ""
    where = f"{option} {path}{via}"
    try:
        mode: int | None = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise OutputFileError(f"{where}: cannot look at it ({exc.strerror or exc})") from None
    if mode is not None and stat.S_ISDIR(mode):
        raise OutputFileError(f"{where}: it is a directory; give the name of a file")
    if mode is not None and _not_regular(mode) is not None:
        raise OutputFileError(f"{where}: it is {_not_regular(mode)}, not a regular file: it is left alone; "
                              f"give the name of a file")
    if mode is not None and not os.access(target, os.W_OK):
        raise OutputFileError(f"{where}: permission denied")
    folder = target.parent
    if not folder.is_dir():
        raise OutputFileError(f"{where}: no such folder {folder}")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=f".{target.name}.", suffix=".tmp"):
            pass
    except OSError as exc:
        raise OutputFileError(f"{where}: {exc.strerror or exc}") from None
    return target


def write_output(path: str | os.PathLike[str], data: str | bytes, *, durable: bool = False) -> Path:
    """Write ``data`` (text as UTF-8) to the file ``path`` names, atomically; the file written.
    ``OutputFileError`` when ``path`` now names something that is not a regular file; ``OSError`` when
    the write fails (the old file is then untouched)."""
    target = _target(path)
    try:
        st: os.stat_result | None = os.stat(target)
    except FileNotFoundError:
        st = None
    if st is not None and _not_regular(st.st_mode) is not None:
        raise OutputFileError(f"{path}: it is {_not_regular(st.st_mode)}, not a regular file: it is left "
                              f"alone")
    if st is not None:
        mode = stat.S_IMODE(st.st_mode)
    else:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask  # as an ordinary new file (mkstemp makes it private)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if durable:
        dir_fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return target
