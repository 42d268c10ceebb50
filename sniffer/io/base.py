"""What every capture reader shares: the source file, the problem report, side naming and time parsing.

How this works: a reader is a generator ``read(src, host_is) -> Iterator[Chunk]``. It pulls lines (or
bytes) from a ``Source``, which counts the bytes consumed (for a progress bar) and caps line length so a
binary file fed to a text reader cannot use unbounded memory. Anything it cannot read goes to the
``Report`` with the file name and line number, counting the bytes or lines lost, and reading goes on.
The report keeps the first ``MAX_KEPT`` messages and counts the rest, so memory stays constant whatever
the file size. ``Sides`` maps the names a format gives its two lines (``>``/``<``, ``TX``/``RX``, a tty
alias...) to ``host``/``device``, honouring ``--host-is``.
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Final

from xac1_proto.chunk import DEVICE, HOST, Direction

MAX_KEPT: Final = 50  # problem messages kept; the rest are only counted
MAX_LINE: Final = 1 << 16  # longest text line read at once (a longer one is read in pieces)


class FormatError(Exception):
    """The file cannot be read as the format asked for at all (wrong magic, bad option)."""


@dataclass
class Report:
    """What could not be read, across all files of one decode run."""

    problems: list[str] = field(default_factory=list)
    dropped: int = 0  # problem messages counted but not kept
    unread_bytes: int = 0
    unread_lines: int = 0
    notes: list[str] = field(default_factory=list)

    def problem(self, where: str, message: str, *, nbytes: int = 0, nlines: int = 0) -> None:
        """Record one unreadable spot: ``where`` is ``file:line`` (or ``file@offset``)."""
        self.unread_bytes += nbytes
        self.unread_lines += nlines
        if len(self.problems) < MAX_KEPT:
            self.problems.append(f"{where}: {message}")
        else:
            self.dropped += 1

    def note(self, message: str) -> None:
        """A remark about the whole capture (lossy format, missing sample rate...), said once."""
        if message not in self.notes:
            self.notes.append(message)

    @property
    def total_problems(self) -> int:
        return len(self.problems) + self.dropped

    def summary(self) -> str:
        """One line for the end of a run."""
        parts = []
        if self.unread_bytes:
            parts.append(f"{self.unread_bytes} byte(s)")
        if self.unread_lines:
            parts.append(f"{self.unread_lines} line(s)")
        if not parts:
            return f"{self.total_problems} problem(s) in the capture"
        return f"could not read {' and '.join(parts)} ({self.total_problems} problem(s))"


class Source:
    """One capture file opened for reading, with a byte counter for progress."""

    def __init__(self, path: str | os.PathLike[str], report: Report, *,
                 name: str | None = None) -> None:
        self.path = Path(path)
        self.name = name or str(path)
        self.report = report
        self.size = self.path.stat().st_size
        self._f: IO[bytes] = open(self.path, "rb")  # noqa: SIM115 - closed by close()/__exit__
        self.pos = 0
        self.unterminated: int | None = None  # number of a last line read that has no line end

    def lines(self) -> Iterator[tuple[int, str]]:
        """(line number, text without its line end) for each line; bytes read as latin-1 so no byte is
        ever a decoding error. A line longer than ``MAX_LINE`` comes in pieces with the same number."""
        number = 0
        continued = False
        while True:
            raw = self._f.readline(MAX_LINE)
            if not raw:
                return
            self.pos += len(raw)
            if not continued:
                number += 1
            continued = not raw.endswith(b"\n")
            self.unterminated = number if continued else None
            yield number, raw.decode("latin-1").rstrip("\r\n")

    def read(self, n: int) -> bytes:
        data = self._f.read(n)
        self.pos += len(data)
        return data

    def where(self, line: int) -> str:
        return f"{self.name}:{line}"

    def check_end(self) -> None:
        """After reading a text capture: a last line with no line end means the file was cut while
        being written (every supported tool ends its lines), so that line may be incomplete. A reader
        that can tell its last record is whole (socat's ``length=``) clears ``unterminated`` first."""
        if self.unterminated is not None:
            self.report.problem(self.where(self.unterminated), "the file ends in the middle of this line "
                                "(no line end): it was cut short, the line may be incomplete")
            self.unterminated = None

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def head_lines(path: str | os.PathLike[str], n: int = 20, max_bytes: int = 8192) -> list[str]:
    """The first lines of a file for content sniffing (latin-1, at most ``max_bytes`` read)."""
    with open(path, "rb") as f:
        data = f.read(max_bytes)
    return data.decode("latin-1").splitlines()[:n]


class Sides:
    """Maps a format's side names to host/device.

    ``fixed``: the two names the format always uses, host default first (e.g. ``(">", "<")``); then
    ``--host-is`` must be one of them. Without ``fixed`` the names come from the capture (tty aliases,
    decoder instances, analyzer names): the host is ``host_is`` if given, else a side whose name says
    ``host``, else the first side seen (the host speaks first in a request/answer protocol). A third
    name is refused (None) and reported by the reader.
    """

    def __init__(self, fmt: str, host_is: str | None, fixed: tuple[str, str] | None = None) -> None:
        self.fmt = fmt
        self.host_is = host_is
        self.fixed = fixed
        self.seen: dict[str, Direction] = {}
        if fixed is not None and host_is is not None and host_is not in fixed:
            lower = {name.lower(): name for name in fixed}
            if host_is.lower() not in lower:
                raise FormatError(f"--host-is {host_is!r}: {fmt} names its sides "
                                  f"{fixed[0]!r} and {fixed[1]!r}")
            self.host_is = lower[host_is.lower()]

    def direction(self, name: str) -> Direction | None:
        if name in self.seen:
            return self.seen[name]
        if self.fixed is not None:
            host = self.host_is or self.fixed[0]
            if name not in self.fixed:
                return None
            d: Direction = HOST if name == host else DEVICE
        else:
            if len(self.seen) >= 2:
                return None
            d = self._guess(name)
        self.seen[name] = d
        return d

    def _guess(self, name: str) -> Direction:
        taken = set(self.seen.values())
        if self.host_is is not None:
            return HOST if _matches(name, self.host_is) else DEVICE
        if HOST in taken:
            return DEVICE
        if DEVICE in taken:
            return HOST
        low = name.lower()
        if "device" in low or "answer" in low:
            return DEVICE
        return HOST  # "host", or simply the first side seen

    def check(self, report: Report, where: str) -> None:
        """After reading: say when ``--host-is`` named no side of the capture."""
        if self.fixed is None and self.host_is is not None and self.seen and \
                not any(_matches(n, self.host_is) for n in self.seen):
            report.problem(where, f"--host-is {self.host_is!r} matches no side of this capture "
                                  f"(sides seen: {', '.join(sorted(self.seen))}); every side was "
                                  f"read as the device")


def _matches(name: str, host_is: str) -> bool:
    return name == host_is or os.path.basename(name) == host_is


def wallclock(date: str, clock: str) -> float:
    """Unix seconds of a zone-less ``YYYY-MM-DD``/``YYYY/MM/DD`` date and ``HH:MM:SS[.ffffff]`` time,
    read as local time (the zone the tool printed in is not recorded; local time keeps the clock
    the log shows)."""
    y, m, d = (int(x) for x in date.replace("/", "-").split("-"))
    hms, _, frac = clock.partition(".")
    hh, mm, ss = (int(x) for x in hms.split(":"))
    base = _dt.datetime(y, m, d, hh, mm, ss).timestamp()
    return base + (int(frac) / 10 ** len(frac) if frac else 0.0)
