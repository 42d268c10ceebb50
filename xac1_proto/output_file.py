"""Files a command writes at a path the user names (``--report``, ``xac1 sim --state``): never anything
but a regular file, written whole or not at all.

How this works: ``check_output(path, option)`` is called before the command starts any work. It follows
a symbolic link to the file it names (a link is the user's way of pointing somewhere: the target is
written, the link stays) and refuses, with ``OutputFileError`` naming the option, the path and what is
there, anything that is not a regular file or a new name in a writable folder: a directory, a FIFO, a
device node (``--report /dev/null`` run as root would otherwise replace ``/dev/null``), a socket.
``write_output(path, data)`` writes beside that target a temporary file, renames it over the target
(atomic: a reader sees the old file or the new one) and keeps the target's permission bits; with
``durable`` it also fsyncs the file and the folder (the simulator's non-volatile memory). The temporary
file's name keeps at most the first 32 characters of the target's, so any name the folder takes works.

Streams written as they come (``--log``, ``--record``, ``--annotate``) are opened by ``open_stream``: a
new file, one of our own recordings (replaced), a FIFO that has a reader, or a character device such as
``/dev/null``; never a directory, a FIFO nobody reads (opening it would wait without end) or an existing
file that holds something else (it is left alone). ``can_sync`` says whether fsync applies (a regular
file; a FIFO or ``/dev/null`` is written without syncing).
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from pathlib import Path
from typing import IO, Any

from .errors import XAC1Error

__all__ = ["OutputFileError", "can_sync", "check_output", "close_stream", "open_stream", "write_output"]

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))
# the first bytes of our two recording formats: a pcapng section header block, a JSON lines recording
RECORDING_HEADS = (b"\n\r\r\n", b'{"type":"recording"')
_TEMP_NAME_KEPT = 32  # characters of the target's name in its temporary file's name (a name may be 255)


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


def _temp_prefix(target: Path) -> str:
    """The start of the temporary file's name beside ``target``: short whatever the target's length."""
    return f".{target.name[:_TEMP_NAME_KEPT]}."


def check_output(path: str | os.PathLike[str], option: str) -> Path:
    """The file to write for ``path`` (through its links), once sure it can be written as a regular
    file; else ``OutputFileError`` saying so (``option`` starts the message: ``--report``)."""
    if not str(path):
        raise OutputFileError(f"{option} '': give the name of a file")
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
        with tempfile.NamedTemporaryFile(dir=folder, prefix=_temp_prefix(target), suffix=".tmp"):
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
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(target), suffix=".tmp", dir=target.parent)
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


def _holds_other(path: str | os.PathLike[str], size: int) -> bool:
    """Does the regular file at ``path`` hold something other than one of our recordings?"""
    if size == 0:
        return False
    with open(path, "rb") as f:
        head = f.read(max(len(h) for h in RECORDING_HEADS))
    return not head.startswith(RECORDING_HEADS)


def open_stream(path: str | os.PathLike[str], mode: str = "wb", *, wait_for_reader: bool = False,
                **kwargs: object) -> IO[Any]:
    """The file ``path`` names opened for writing as it comes (``open``'s ``mode`` and keywords), once
    sure the write cannot wait without end nor lose someone's file; ``OSError`` (its ``strerror`` says
    why, for people) otherwise. ``wait_for_reader``: a FIFO whose reader is on its way (Wireshark's
    extcap pipe) is waited for instead of refused."""
    if not str(path):
        raise OSError(errno.ENOENT, "give the name of a file", str(path))
    try:
        st: os.stat_result | None = os.stat(path)
    except FileNotFoundError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode) and _holds_other(path, st.st_size):
        raise OSError(errno.EEXIST, f"it is an existing file of {st.st_size} bytes that is not a recording: "
                                    f"it is left alone; give another name, or remove it first", str(path))
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OSError(errno.EISDIR, "it is a directory; give the name of a file", str(path))
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | (0 if wait_for_reader else os.O_NONBLOCK)
    try:  # non-blocking: a FIFO with no reader fails at once (ENXIO) instead of waiting for one
        fd = os.open(path, flags, 0o666)
    except OSError as exc:
        if exc.errno == errno.ENXIO:
            raise OSError(errno.ENXIO, "it is a FIFO (named pipe) that nobody reads: writing to it would "
                                       "wait without end; start its reader first", str(path)) from None
        raise
    os.set_blocking(fd, True)
    return os.fdopen(fd, mode, **kwargs)  # type: ignore[call-overload]


def can_sync(f: IO[Any]) -> bool:
    """Does ``os.fsync`` apply to the open file ``f`` (a regular file; not a FIFO, a terminal or
    ``/dev/null``, where it fails)?"""
    return stat.S_ISREG(os.fstat(f.fileno()).st_mode)


def close_stream(f: IO[Any]) -> None:
    """Flush ``f``, fsync it where that applies (``can_sync``), and close it, even when that fails."""
    if f.closed:
        return
    try:
        f.flush()
        if can_sync(f):
            os.fsync(f.fileno())
    finally:
        f.close()
