"""Reader for interceptty dumps, the original and its fork with ``-T`` timestamps.

How this works: the original prints one byte a line: ``< 0x30 (0)`` for a byte written by the program
on the front pty (its main loop dumps those with direction flag 0) and ``> \\t0x30 (0)`` for a byte read
from the back device, the real serial port (flag 1, printed with a tab); the character in parentheses
appears for printable bytes only. The fork may prefix the first line of each read with
``[HH:MM SS.uuuuuu]`` (``-T``; blanks on the following lines of the same read), may print the character
as a name (``[CR]``, ``[LF]``, ``' '``), and with an end-of-line character joins a read's
bytes on one line (``< 30(0):52(R):0d([CR]):0a([LF])``) or prints characters only. A ``-T`` time has no
date: it becomes seconds since midnight.

Host side default: ``<`` (the program on interceptty's front pty is the host software; the device is
on the back port, its bytes are ``>``). A ``-T`` time that is no time of day (hour 27) is reported.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Final

from xac1_proto.chunk import Chunk

from .base import Clock, Sides, Source, shown

FORMAT: Final = "interceptty"
DESCRIPTION: Final = "interceptty (and its -T fork) byte dump"
HOST_DEFAULT: Final = "<"
SUFFIXES: Final = (".interceptty",)

_LINE: Final = re.compile(r"(?:\[(\d\d):(\d\d) (\d\d(?:\.\d+)?)\]|\s*)([<>]) \t?(.*)")
_HEX_ITEM: Final = re.compile(r"(?:0x)?([0-9a-fA-F]{2})\s*(?:\((.*)\))?")
_NAMES: Final = ("NUL", "SOH", "STX", "ETX", "EOT", "ENQ", "ACK", "BEL", "BS", "TAB", "LF", "VT", "FF", "CR",
                 "SO", "SI", "DLE", "DC1", "DC2", "DC3", "DC4", "NAK", "SYN", "ETB", "CAN", "EM", "SUB",
                 "ESC", "FS", "GS", "RS", "US")
_CHAR_NAMES: Final = {f"[{n}]": i for i, n in enumerate(_NAMES)} | {"[DEL]": 0x7F, "' '": 0x20}


def sniff(head: list[str]) -> int:
    rows = [line for line in head if line.strip()]
    matches = [_LINE.fullmatch(r) for r in rows]
    good = [m for m in matches if m is not None and _items(m.group(5)) is not None]
    return 85 if good and len(good) >= max(1, len(rows) * 2 // 3) else 0


def _items(text: str) -> bytes | None:
    """The bytes of one line's value part, or None if it is not an interceptty value."""
    text = text.strip()
    if not text:
        return None
    parts = text.split(":") if ":" in text and not text.startswith("0x") else [text]
    if len(parts) > 1 and any(not p for p in parts):
        parts = [text]  # a lone ':' character
    out = bytearray()
    for part in parts:
        m = _HEX_ITEM.fullmatch(part.strip())
        if m and (part.strip().startswith("0x") or m.group(2) is not None or len(parts) > 1):
            out.append(int(m.group(1), 16))
        elif part in _CHAR_NAMES:
            out.append(_CHAR_NAMES[part])
        elif len(part) == 1:
            out.append(ord(part) & 0xFF)
        else:
            return None
    return bytes(out)


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    sides = Sides(FORMAT, host_is, ("<", ">"))
    report = src.report
    pending: Chunk | None = None
    t: float | None = None
    clock = Clock(report)
    for number, line in src.lines():
        if not line.strip():
            continue
        m = _LINE.fullmatch(line)
        data = _items(m.group(5)) if m else None
        if m is None or data is None:
            report.problem(src.where(number), f"not an interceptty byte line: {shown(line)}", nlines=1)
            continue
        stamped = m.group(1) is not None
        if stamped:
            hh, mm, ss = int(m.group(1)), int(m.group(2)), float(m.group(3))
            if hh > 23 or mm > 59 or ss >= 61:
                report.problem(src.where(number), f"-T time {hh:02d}:{mm:02d} {m.group(3)} is no time of "
                                                  f"day; the bytes are kept with the previous time")
            else:
                t = clock.check(hh * 3600 + mm * 60 + ss, src.where(number))
        d = sides.direction(m.group(4))
        assert d is not None
        if pending is not None and pending.dir == d and not stamped and len(pending.data) < 4096:
            pending = Chunk(pending.t, d, pending.data + data)
            continue
        if pending is not None:
            yield pending
        pending = Chunk(t, d, data)
    if pending is not None:
        yield pending
