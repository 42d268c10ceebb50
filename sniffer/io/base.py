"""What every capture reader shares: the source file, the problem report, side naming and time parsing.

How this works: a reader is a generator ``read(src, host_is) -> Iterator[Chunk]``. It pulls lines (or
bytes) from a ``Source``, which opens the file once (a buffered head serves format sniffing, so ``-``,
pipes and FIFOs work), counts the bytes consumed (for a progress bar) and caps line length so a binary
file fed to a text reader cannot use unbounded memory. Times pass a ``Clock``: one that is not a number,
out of range or impossible (``wallclock``: hour 27, day 32) is reported and the bytes keep the previous
time. Anything it cannot read goes to the
``Report`` with the file name and line number, counting the bytes or lines lost, and reading goes on.
The report keeps the first ``MAX_KEPT`` messages and counts the rest, so memory stays constant whatever
the file size. ``Sides`` maps the names a format gives its two lines (``>``/``<``, ``TX``/``RX``, a tty
alias...) to ``host``/``device``, honouring ``--host-is``.
"""

from __future__ import annotations

import datetime as _dt
import functools
import math
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Final

from xac1_proto.chunk import DEVICE, HOST, Direction

MAX_KEPT: Final = 50  # problem messages kept; the rest are only counted
MAX_LINE: Final = 1 << 16  # longest text line read at once (a longer one is read in pieces)


class FormatError(Exception):
    """The file cannot be read as the format asked for at all (wrong magic, bad option)."""


class WrongFormat(FormatError):
    """Raised by ``Report.problem`` when ``give_up_after`` problems came before any data."""


@dataclass
class Report:
    """What could not be read, across all files of one decode run."""

    problems: list[str] = field(default_factory=list)
    dropped: int = 0  # problem messages counted but not kept
    unread_bytes: int = 0
    unread_lines: int = 0
    notes: list[str] = field(default_factory=list)
    give_up_after: int | None = None  # raise WrongFormat at this many problems (cleared once data comes)
    looks_like: str = ""  # what the files look like, for the WrongFormat message

    def problem(self, where: str, message: str, *, nbytes: int = 0, nlines: int = 0) -> None:
        """Record one unreadable spot: ``where`` is ``file:line`` (or ``file@offset``)."""
        self.unread_bytes += nbytes
        self.unread_lines += nlines
        if len(self.problems) < MAX_KEPT:
            self.problems.append(f"{where}: {message}")
        else:
            self.dropped += 1
        if self.give_up_after is not None and self.total_problems >= self.give_up_after:
            raise WrongFormat(f"{self.total_problems} problems before any data")

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


STDIN: Final = "-"  # the file name that means standard input
HEAD_BYTES: Final = 8192  # bytes sniffed for the format


class Source:
    """One capture file opened once for reading, with a byte counter for progress.

    ``path`` may be a regular file, a FIFO, a character device such as ``/dev/stdin`` or ``-`` (standard
    input). The file is opened once: ``head()`` buffers its first bytes for format sniffing and reading
    starts over from them, so a pipe works. A reader that needs a second pass (sigrok's instances) calls
    ``reopen()``: a regular file is opened again, anything else is first spooled to a temporary file."""

    def __init__(self, path: str | os.PathLike[str], report: Report, *,
                 name: str | None = None, max_line: int = MAX_LINE) -> None:
        if max_line < 2:
            raise ValueError(f"max_line must be at least 2 bytes, not {max_line}")
        self.path = Path(path)
        self.max_line = max_line  # the longest line read at once (a longer one comes in pieces)
        self.name = name or ("<stdin>" if str(path) == STDIN else str(path))
        self.report = report
        if str(path) == STDIN:
            self._f: IO[bytes] = os.fdopen(os.dup(sys.stdin.fileno()), "rb")
        else:
            self._f = open(self.path, "rb")  # noqa: SIM115 - closed by close()/__exit__
        mode = os.fstat(self._f.fileno()).st_mode
        self.regular = stat.S_ISREG(mode)
        self.size = os.fstat(self._f.fileno()).st_size if self.regular else 0
        self._head = b""
        self._buffered = 0  # bytes of _head not yet consumed (they are at its end)
        self._spool: IO[bytes] | None = None
        self.pos = 0
        self.unterminated: int | None = None  # number of a last line read that has no line end

    def head(self, n: int = HEAD_BYTES) -> bytes:
        """The first ``n`` bytes (or fewer), without consuming them; only before reading starts."""
        if self.pos == 0 and len(self._head) < n:
            more = _read_full(self._f, n - len(self._head))
            self._head += more
            self._buffered += len(more)
        return self._head[:n]

    def _raw_read(self, n: int) -> bytes:
        if self._buffered:
            start = len(self._head) - self._buffered
            data = self._head[start:start + n]
            self._buffered -= len(data)
            if len(data) == n:
                return data
            return data + self._f.read(n - len(data))
        return self._f.read(n)

    def _raw_readline(self, limit: int, end: bytes = b"\n") -> bytes:
        if self._buffered:
            start = len(self._head) - self._buffered
            stop = self._head.find(end, start, start + limit)
            if stop >= 0:
                data = self._head[start:stop + 1]
                self._buffered -= len(data)
                return data
            data = self._head[start:start + limit]
            self._buffered -= len(data)
            if len(data) == limit:
                return data
            return data + _readline(self._f, limit - len(data), end)
        return _readline(self._f, limit, end)

    def line_end(self) -> bytes:
        """``b"\\r"`` when the file's first line ends with a CR alone (old Mac style, as some exports on
        other systems write), else ``b"\\n"`` (LF or CR LF)."""
        head = self.head()
        cr, lf = head.find(b"\r"), head.find(b"\n")
        alone = cr >= 0 and (lf < 0 or cr < lf) and head[cr + 1:cr + 2] not in (b"\n", b"")
        return b"\r" if alone else b"\n"

    def lines(self, end: bytes = b"\n") -> Iterator[tuple[int, str]]:
        """(line number, text without its line end) for each line ending with ``end`` (LF, which reads
        CR LF too; or CR, see ``line_end``); bytes read as latin-1 so no byte is ever a decoding error.
        A line longer than ``max_line`` comes in pieces with the same number."""
        number = 0
        continued = False
        while True:
            raw = self._raw_readline(self.max_line, end)
            if not raw:
                return
            self.pos += len(raw)
            if not continued:
                number += 1
            continued = not raw.endswith(end)
            self.unterminated = number if continued else None
            yield number, raw.decode("latin-1").rstrip("\r\n")

    def read(self, n: int) -> bytes:
        data = self._raw_read(n)
        self.pos += len(data)
        return data

    def reopen(self) -> IO[bytes]:
        """A new, independent reader of the whole file from its first byte (close it after use). A pipe
        or FIFO is spooled to a temporary file first (before anything was read from it)."""
        if self.regular:
            return open(self.path, "rb")
        if self._spool is None:
            if self.pos:
                raise RuntimeError("reopen() of a pipe must come before reading from it")
            spool = tempfile.NamedTemporaryFile(prefix="xac1-decode-")  # noqa: SIM115 - closed by close()
            spool.write(self._head)
            shutil.copyfileobj(self._f, spool)
            spool.flush()
            self.size = spool.tell()
            self._f.close()
            spool.seek(len(self._head))
            self._f = spool
            self._spool = spool
        return open(self._spool.name, "rb")

    def where(self, line: int) -> str:
        return f"{self.name}:{line}"

    def at(self, offset: int) -> str:
        """``file:offset`` of a byte offset (binary formats)."""
        return f"{self.name}:{offset}"

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


def _readline(f: IO[bytes], limit: int, end: bytes = b"\n") -> bytes:
    """One line of at most ``limit`` bytes ending with ``end`` (included), or what is left at the end."""
    if end == b"\n":
        return f.readline(limit)
    parts: list[bytes] = []
    while limit > 0:
        ahead = f.peek(1)[:limit]  # type: ignore[attr-defined]  # buffered readers (every Source file)
        if not ahead:
            break
        stop = ahead.find(end)
        data = f.read(stop + 1 if stop >= 0 else len(ahead))
        parts.append(data)
        limit -= len(data)
        if stop >= 0:
            break
    return b"".join(parts)


def numbered_lines(f: IO[bytes], max_line: int = MAX_LINE) -> Iterator[tuple[int, str]]:
    """``Source.lines`` of a file opened apart (``Source.reopen``): pieces of at most ``max_line`` bytes,
    so a line without end (a binary file, a cut export) never has to fit in memory whole."""
    number = 0
    continued = False
    while raw := f.readline(max_line):
        if not continued:
            number += 1
        continued = not raw.endswith(b"\n")
        yield number, raw.decode("latin-1").rstrip("\r\n")


def _read_full(f: IO[bytes], n: int) -> bytes:
    """Up to ``n`` bytes, reading again after a short read (a pipe delivers in pieces) until end of file."""
    parts = []
    while n > 0:
        data = f.read(n)
        if not data:
            break
        parts.append(data)
        n -= len(data)
    return b"".join(parts)


def head_lines(path: str | os.PathLike[str], n: int = 20, max_bytes: int = HEAD_BYTES) -> list[str]:
    """The first lines of a regular file for content sniffing (latin-1, at most ``max_bytes`` read)."""
    with open(path, "rb") as f:
        data = f.read(max_bytes)
    return data.decode("latin-1").splitlines()[:n]


def shown(text: str | bytes, limit: int = 60) -> str:
    """A short printable quote of what was read (non-ASCII escaped): never raw binary on a terminal."""
    if isinstance(text, bytes):
        text = text.decode("latin-1")
    odd = sum(1 for c in text[:256] if not " " <= c <= "~" and c != "\t")
    if odd * 4 > min(len(text), 256):
        return f"{len(text)} byte(s) of binary data"
    cut = text[:limit]
    return ascii(cut) + ("..." if len(text) > limit else "")


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


# Plausible times: unix seconds up to 2106 (pcap's 32-bit seconds), and relative times (seconds since a
# capture or the day started, sample numbers over a rate) down to minus a year (a Saleae pre-trigger).
MIN_TIME: Final = -366 * 86400.0
MAX_TIME: Final = float(1 << 32)


def time_problem(t: float) -> str | None:
    """Why ``t`` (seconds) cannot be a capture time, or None when it can."""
    expected = f"expected {MIN_TIME:.0f} to {MAX_TIME:.0f} s"
    if isinstance(t, int) and not MIN_TIME <= t < MAX_TIME:  # an integer too large for a float, too
        return f"time {shown(str(t), 24)} s is out of range ({expected})"
    if not math.isfinite(t):
        return f"time {t!r} is not a number of seconds"
    if not MIN_TIME <= t < MAX_TIME:
        return f"time {t!r} s is out of range ({expected})"
    return None


class Clock:
    """Checks the times a reader reads: a bad one is reported and replaced by the last good one, so the
    bytes it stamps are kept in order."""

    def __init__(self, report: Report) -> None:
        self.report = report
        self.last: float | None = None

    def check(self, t: float | None, where: str) -> float | None:
        if t is None:
            return None
        why = time_problem(t)
        if why is not None:
            self.report.problem(where, f"{why}; the bytes are kept with the previous time")
            return self.last
        self.last = float(t)
        return self.last


def wallclock(date: str, clock: str) -> float:
    """Unix seconds of a zone-less ``YYYY-MM-DD``/``YYYY/MM/DD`` date and ``HH:MM:SS[.ffffff]`` time,
    read as local time (the zone the tool printed in is not recorded; local time keeps the clock
    the log shows). An impossible date or time (hour 27, day 32) is a ``ValueError`` saying so."""
    try:
        hms, _, frac = clock.partition(".")
        base = _local_seconds(date, hms)
        return base + (int(frac[:12]) / 10 ** len(frac[:12]) if frac else 0.0)
    except (ValueError, OverflowError, OSError) as exc:
        raise ValueError(f"impossible date or time {shown(date, 12)} {shown(clock, 24)} ({exc})") from None


@functools.lru_cache(maxsize=256)
def _local_seconds(date: str, hms: str) -> float:
    """Unix seconds of a whole local second (cached: consecutive log lines share their second)."""
    y, m, d = (int(x) for x in date.replace("/", "-").split("-"))
    hh, mm, ss = (int(x) for x in hms.split(":"))
    return _dt.datetime(y, m, d, hh, mm, ss).timestamp()
