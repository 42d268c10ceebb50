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
    """The chunks of a jpnevulator capture: each line a timing line (a burst begins) or a data line (its
    bytes), a timing line glued to a partial data line split from it (``_Bursts`` holds the burst)."""
    sides = Sides(FORMAT, host_is)
    bursts = _Bursts(src, sides)
    whole = False  # did the last line read whole (a timing line, or a data line of whole bytes)?
    for number, line in src.lines():
        m = _TIMING.search(line)
        if m and m.start() > 0:  # a timing line glued to a partial data line
            bursts.glued(number, line[:m.start()])
            line = line[m.start():]
        if m:  # the burst before ends (handed on before anything of this line is said)
            if (chunk := bursts.end()) is not None:
                yield chunk
            bursts.begin(number, m)
            whole = _TIMING.fullmatch(line) is not None
        elif line:
            data = _data_bytes(line)
            if (chunk := bursts.data(number, line, data)) is not None:
                yield chunk
            whole = data is not None
        else:
            whole = False
    if bursts.pending is not None and bursts.pending.data:
        yield bursts.pending
    if whole:
        src.unterminated = None  # the last line is whole, line end or not (jpnevulator's Ctrl-C)
    sides.check(src.report, src.name)


class _Bursts:
    """The burst being read: the tty that spoke (its side), its time and the bytes so far (``pending``;
    None while a skipped tty speaks), handed on at the next timing line or in pieces when huge."""

    def __init__(self, src: Source, sides: Sides) -> None:
        self.src = src
        self.report = src.report
        self.sides = sides
        self.clock = Clock(src.report)
        self.pending: Chunk | None = None
        self.side: str | None = None  # the tty of the last timing line (None: none yet)

    def end(self) -> Chunk | None:
        """The burst ends (at a timing line): its chunk, if it has bytes."""
        done = self.pending if self.pending is not None and self.pending.data else None
        self.pending = None
        return done

    def begin(self, number: int, m: re.Match[str]) -> None:
        """A timing line: a burst of its tty begins (a third tty's is skipped, reported)."""
        name = m.group(3)
        self.side = name.strip() if name and name.strip() else _SINGLE
        where = self.src.where(number)
        try:
            t = self.clock.check(wallclock(m.group(1), m.group(2)), where)
        except ValueError as exc:
            self.report.problem(where, f"{exc}; the bytes are kept with the previous time")
            t = self.clock.last
        d = self.sides.direction(self.side)
        if d is None:
            self.report.problem(where, f"a third tty {self.side!r} (this reader takes two lines: host and "
                                       f"device); its bytes are skipped")
        else:
            self.pending = Chunk(t, d, b"")

    def data(self, number: int, line: str, data: bytes | None) -> Chunk | None:
        """A data line's bytes (``data``; None: the line is none), added to the burst; the burst so far
        when it is huge (memory stays bounded)."""
        pending, where = self.pending, self.src.where(number)
        if data is None:
            self.report.problem(where, f"not a jpnevulator timing or data line: {shown(line)}", nlines=1)
        elif self.side is None:
            self.report.problem(where, "data before any timing line (run jpnevulator with --timing-print)",
                                nbytes=len(data))
        elif pending is None:
            self.report.problem(where, f"bytes of skipped tty {self.side!r}", nbytes=len(data))
        else:
            self.pending = Chunk(pending.t, pending.dir, pending.data + data)
            if len(self.pending.data) >= _SPILL:
                done, self.pending = self.pending, Chunk(pending.t, pending.dir, b"")
                return done
        return None

    def glued(self, number: int, head: str) -> None:
        """The partial data line before a timing line glued to it: its whole bytes added to the burst,
        else reported."""
        data = _data_bytes(head)
        if data is not None and self.side is not None and self.pending is not None:
            self.pending = Chunk(self.pending.t, self.pending.dir, self.pending.data + data)
        elif head.strip():
            self.report.problem(self.src.where(number), f"cannot read {shown(head)}", nlines=1)
