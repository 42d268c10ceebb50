"""Receive-only serial ports for a Y-cable tap: opened read-only, and nothing here can write to them.

A tap port is opened with ``O_RDONLY`` (so even a stray ``os.write`` on its descriptor fails with
EBADF) and set raw at the line's speed, with ``PARMRK`` on so that bytes received with a framing error
are marked by the kernel (``linemarks``); ``ReadOnlyPort.write`` raises ``TapWriteError``. ``read()``
returns what is there as ``(bytes, error or None)`` pieces (none when nothing is); an unplugged port
raises ``PortGone`` with a message for people.
"""

from __future__ import annotations

import errno
import os
import stat
import termios
import tty

from xac1_proto import XAC1Error, spec

from .linemarks import MarkDecoder

_BAUDS = {b: getattr(termios, f"B{b}") for b in (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)}


class TapWriteError(XAC1Error, PermissionError):
    """Something tried to write to a receive-only tap."""


class PortGone(XAC1Error):
    """A port could not be opened or went away (unplugged, closed by the other end)."""

    def __init__(self, name: str, path: str, reason: str) -> None:
        super().__init__(f"{name} port {path}: {reason}")
        self.name = name
        self.path = path
        self.reason = reason


def configure_raw(fd: int, baud: int, mark_errors: bool = False) -> bool:
    """Raw bytes at ``baud`` 8N1 with the receiver on (a terminal only: False for other files, which are
    left alone). ``mark_errors``: bytes with a framing error come marked (``PARMRK``, see linemarks)."""
    if not os.isatty(fd):
        return False
    if baud not in _BAUDS:
        raise ValueError(f"baud must be one of {', '.join(map(str, _BAUDS))}, got {baud}")
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    attrs[2] |= termios.CLOCAL | termios.CREAD
    attrs[4] = attrs[5] = _BAUDS[baud]
    if mark_errors:
        attrs[0] |= termios.INPCK | termios.PARMRK
        attrs[0] &= ~(termios.IGNPAR | termios.IGNBRK | termios.BRKINT | termios.ISTRIP)
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return True


class ReadOnlyPort:
    """One tap: ``name`` (``host``/``device``) says which line it listens to."""

    def __init__(self, path: str, name: str, baud: int = spec.BAUD) -> None:
        self.path = path
        self.name = name
        try:
            self.fd: int | None = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            raise PortGone(name, path, f"cannot open for reading: {exc.strerror}") from None
        if stat.S_ISDIR(os.fstat(self.fd).st_mode):
            self.close()
            raise PortGone(name, path, "is a directory, not a serial port")
        try:
            self._marks = MarkDecoder() if configure_raw(self.fd, baud, mark_errors=True) else None
        except (OSError, termios.error) as exc:
            self.close()
            raise PortGone(name, path, f"cannot set {baud} baud raw mode: {exc}") from None

    def fileno(self) -> int:
        if self.fd is None:
            raise ValueError(f"{self.name} tap {self.path} is closed")
        return self.fd

    def read(self, size: int = 4096) -> list[tuple[bytes, str | None]]:
        """The bytes waiting (maybe none) as ``(bytes, error or None)`` pieces, marks undone. Raises
        ``PortGone`` when the port went away."""
        try:
            data = os.read(self.fileno(), size)
        except BlockingIOError:
            return []
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.ENXIO, errno.ENODEV, errno.EBADF):
                raise PortGone(self.name, self.path, f"went away ({exc.strerror}): unplugged?") from None
            raise PortGone(self.name, self.path, f"cannot read: {exc.strerror or exc}") from None
        if not data:  # readable with nothing to read: end of file
            raise PortGone(self.name, self.path, "closed by the other end")
        return self._marks.feed(data) if self._marks is not None else [(data, None)]

    def write(self, data: bytes) -> int:
        raise TapWriteError(f"{self.name} tap {self.path} is receive-only: the sniffer never writes to a tap")

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
