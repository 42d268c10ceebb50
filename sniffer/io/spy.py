"""Reader for pyserial ``spy://`` hexdump logs (``spy://PORT?file=LOG``, the default formatter).

How this works: each row is ``SSSSSS.mmm LABEL VALUE``: seconds since the port was opened (three
decimals), a label padded to four characters, then the value. ``TX``/``RX`` rows carry a hexdump row
``OOOO  XX XX .. (16 bytes, a gap after 8) ASCII``; a read or write longer than 16 bytes takes several
rows with offsets 0000, 0010, ..., so offset 0000 starts a new chunk. ``RX <empty>`` is a read that
timed out. Other labels are control-line rows (``RTS``, ``DTR``, ``BRK``, ``CTS``, ``DSR``, ``RI``,
``CD``, ``BREAK``) and buffer resets (``Q-RX``, ``Q-TX``): noted, carry no data. ``?color`` adds ANSI
colour codes, which are removed. Times are relative to the port's opening, not wall-clock.

Host side default: ``TX`` (the program that opened ``spy://`` is usually the host).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Final

from xac1_proto.chunk import Chunk

from .base import Clock, Sides, Source, shown

FORMAT: Final = "spy"
DESCRIPTION: Final = "pyserial spy:// hexdump log"
HOST_DEFAULT: Final = "TX"
SUFFIXES: Final = (".spy",)

_ROW: Final = re.compile(r"(\d+\.\d{3}) (\S+)\s*(.*)")
_DATA: Final = re.compile(r"([0-9A-F]{4})  (.*)")
_BYTE: Final = re.compile(r"[0-9A-F]{2}")
_ANSI: Final = re.compile(r"\x1b\[[0-9;]*m")
_HEX_AREA: Final = 16 * 3 + 1  # 16 "XX " cells and the gap after the 8th
_CONTROL: Final = frozenset({"RTS", "DTR", "BRK", "BREAK", "CTS", "DSR", "RI", "CD", "Q-RX", "Q-TX"})


def sniff(head: list[str]) -> int:
    rows = [_ROW.fullmatch(_ANSI.sub("", line)) for line in head if line.strip()]
    good = [m for m in rows if m and (m.group(2) in ("TX", "RX") or m.group(2) in _CONTROL)]
    return 90 if good and len(good) >= len(rows) // 2 else 0


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    sides = Sides(FORMAT, host_is, ("TX", "RX"))
    report = src.report
    pending: Chunk | None = None
    expect_offset = 0
    clock = Clock(report)
    for number, raw in src.lines():
        line = _ANSI.sub("", raw)
        if not line.strip():
            continue
        m = _ROW.fullmatch(line)
        if not m:
            report.problem(src.where(number), f"not a spy row: {shown(line)}", nlines=1)
            continue
        label, value = m.group(2), m.group(3)
        t = clock.check(float(m.group(1)), src.where(number))
        if label not in ("TX", "RX"):
            if label not in _CONTROL:
                report.problem(src.where(number), f"unknown row label {shown(label)}", nlines=1)
            continue
        if value.strip() == "<empty>":
            continue
        dm = _DATA.fullmatch(value)
        if not dm:
            report.problem(src.where(number), f"{label} row without a hexdump: {shown(value)}", nlines=1)
            continue
        offset = int(dm.group(1), 16)
        area = dm.group(2)[:_HEX_AREA]
        cells = area.split()
        if not cells or not all(_BYTE.fullmatch(c) for c in cells) or len(cells) > 16:
            report.problem(src.where(number), f"bad hexdump cells: {shown(area.strip())}", nlines=1)
            continue
        data = bytes.fromhex("".join(cells))
        d = sides.direction(label)
        assert d is not None
        if offset == 0 or pending is None or pending.dir != d or offset != expect_offset:
            if offset not in (0, expect_offset):
                report.problem(src.where(number), f"hexdump offset {offset:04X}, expected "
                                                  f"{expect_offset:04X}: rows are missing")
            if pending is not None:
                yield pending
            pending = Chunk(t, d, data)
        else:
            pending = Chunk(pending.t, d, pending.data + data)
        expect_offset = offset + 16
        if len(pending.data) >= 4096:  # keep memory bounded on a huge single write
            yield pending
            pending = Chunk(t, d, b"")
    if pending is not None and pending.data:
        yield pending
    report.note(f"{src.name}: spy:// times are seconds since the port was opened, not wall-clock")
