"""Reader for ``jpnevulator --read --timing-print`` output (hexadecimal base).

How this works: before every burst of bytes jpnevulator prints a timing line
``2024-05-01 10:00:00.123456: NAME`` (NAME is the tty or its ``--tty NAME:ALIAS`` alias; with a single
tty the line ends at the colon). Data lines follow, ``--width`` bytes each (16 by default) as
``30 52 56 0D 0A``; ``--byte-count`` puts an 8-digit hex index and a tab before the bytes (it counts per
tty), ``--ascii`` a tab and an ASCII column after them. A file cut while jpnevulator was still running
may end in a partial line with no ASCII column; that is read too. jpnevulator ends its file without a
line end when stopped with Ctrl-C, as it always is: a last line that reads whole (a timing line, or a
data line of whole hex bytes) is whole, not cut short; only one that does not read is reported.

Host side default: a tty or alias whose name says ``host`` (``device`` marks the other), else the
first tty that speaks (the host speaks first); ``--host-is`` takes an alias or a tty name. A capture
of one tty has only one side: give ``--host-is`` a name it does not use (e.g. ``--host-is none``) to
read it as the device line.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Final

from xac1_proto.chunk import Chunk

from .base import Clock, Sides, Source, shown, wallclock

FORMAT: Final = "jpnevulator"
DESCRIPTION: Final = "jpnevulator --read --timing-print output"
HOST_DEFAULT: Final = "first tty that speaks (or the one named host)"
SUFFIXES: Final = (".jpnevulator", ".jpn")

_TIMING: Final = re.compile(r"(\d{4}-\d\d-\d\d) (\d\d:\d\d:\d\d\.\d+):(?: (.*))?")
_COUNT: Final = re.compile(r"[0-9A-Fa-f]{8}")
_HEX: Final = re.compile(r"(?:[0-9A-Fa-f]{2} ?)+")
_SINGLE: Final = "(the only tty)"
_SPILL: Final = 1 << 12  # bytes of one burst held before they are handed on


def sniff(head: list[str]) -> int:
    return 90 if any(_TIMING.fullmatch(line) for line in head[:3]) else 0


def _data_bytes(line: str) -> bytes | None:
    """The bytes of a data line (byte count and ASCII column dropped), None if it is not one."""
    fields = line.split("\t")
    if len(fields) > 1 and _COUNT.fullmatch(fields[0]):
        fields = fields[1:]
    hexpart = fields[0].rstrip()
    if not _HEX.fullmatch(hexpart + " ") or not hexpart:
        return None
    try:
        return bytes.fromhex(hexpart)
    except ValueError:
        return None


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    sides = Sides(FORMAT, host_is)
    report = src.report
    pending: Chunk | None = None
    side: str | None = None
    t: float | None = None
    clock = Clock(report)
    whole = False  # did the last line read whole (a timing line, or a data line of whole bytes)?
    for number, raw in src.lines():
        line = raw
        whole = False
        while line:
            m = _TIMING.search(line)
            if m and m.start() > 0:  # a timing line glued to a partial data line
                head, line = line[:m.start()], line[m.start():]
                data = _data_bytes(head)
                if data is not None and side is not None and pending is not None:
                    pending = Chunk(pending.t, pending.dir, pending.data + data)
                elif head.strip():
                    report.problem(src.where(number), f"cannot read {shown(head)}", nlines=1)
                continue
            if m:
                if pending is not None and pending.data:
                    yield pending
                pending = None
                side = m.group(3).strip() if m.group(3) and m.group(3).strip() else _SINGLE
                try:
                    t = clock.check(wallclock(m.group(1), m.group(2)), src.where(number))
                except ValueError as exc:
                    report.problem(src.where(number), f"{exc}; the bytes are kept with the previous time")
                    t = clock.last
                d = sides.direction(side)
                if d is None:
                    report.problem(src.where(number), f"a third tty {side!r} (this reader takes two "
                                                      f"lines: host and device); its bytes are skipped")
                else:
                    pending = Chunk(t, d, b"")
                whole = _TIMING.fullmatch(line) is not None
                break
            data = _data_bytes(line)
            whole = data is not None
            if data is None:
                report.problem(src.where(number), f"not a jpnevulator timing or data line: {shown(line)}",
                               nlines=1)
            elif side is None:
                report.problem(src.where(number), "data before any timing line (run jpnevulator with "
                                                  "--timing-print)", nbytes=len(data))
            elif pending is None:
                report.problem(src.where(number), f"bytes of skipped tty {side!r}", nbytes=len(data))
            else:
                pending = Chunk(pending.t, pending.dir, pending.data + data)
                if len(pending.data) >= _SPILL:  # bounded memory on a huge burst
                    yield pending
                    pending = Chunk(pending.t, pending.dir, b"")
            break
    if pending is not None and pending.data:
        yield pending
    if whole:
        src.unterminated = None  # the last line is whole, line end or not (jpnevulator's Ctrl-C)
    sides.check(report, src.name)
