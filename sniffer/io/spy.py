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

from xac1_proto.chunk import Chunk, Direction

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
_SPILL: Final = 4096  # bytes of one read or write held before they are handed on
_CONTROL: Final = frozenset({"RTS", "DTR", "BRK", "BREAK", "CTS", "DSR", "RI", "CD", "Q-RX", "Q-TX"})


def sniff(head: list[str]) -> int:
    rows = [_ROW.fullmatch(_ANSI.sub("", line)) for line in head if line.strip()]
    good = [m for m in rows if m and (m.group(2) in ("TX", "RX") or m.group(2) in _CONTROL)]
    return 90 if good and len(good) >= len(rows) // 2 else 0


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    """The chunks of a spy:// log: each TX/RX row's bytes (``_data_row``) added to the read or write they
    belong to (``_Burst``)."""
    sides = Sides(FORMAT, host_is, ("TX", "RX"))
    clock = Clock(src.report)
    burst = _Burst(src)
    for number, raw in src.lines():
        row = _data_row(src, clock, number, raw)
        if row is None:
            continue
        t, label, offset, data = row
        d = sides.direction(label)
        assert d is not None
        if (chunk := burst.add(number, t, d, offset, data)) is not None:
            yield chunk
    if burst.pending is not None and burst.pending.data:
        yield burst.pending
    src.report.note(f"{src.name}: spy:// times are seconds since the port was opened, not wall-clock")


def _data_row(src: Source, clock: Clock, number: int,
              raw: str) -> tuple[float | None, str, int, bytes] | None:
    """(time, ``TX``/``RX``, hexdump offset, bytes) of a data row; None for any other line: a blank line,
    a control-line row, a read that timed out (``<empty>``), or a line that does not read (reported)."""
    line = _ANSI.sub("", raw)
    if not line.strip():
        return None
    m = _ROW.fullmatch(line)
    if not m:
        src.report.problem(src.where(number), f"not a spy row: {shown(line)}", nlines=1)
        return None
    label, value = m.group(2), m.group(3)
    t = clock.check(float(m.group(1)), src.where(number))
    if label not in ("TX", "RX"):
        if label not in _CONTROL:
            src.report.problem(src.where(number), f"unknown row label {shown(label)}", nlines=1)
        return None
    if value.strip() == "<empty>":
        return None
    dump = _hexdump(label, value)
    if isinstance(dump, str):
        src.report.problem(src.where(number), dump, nlines=1)
        return None
    return (t, label, *dump)


def _hexdump(label: str, value: str) -> tuple[int, bytes] | str:
    """The offset and bytes of a ``label`` row's hexdump ``OOOO  XX XX .. ASCII``, or what is wrong."""
    dm = _DATA.fullmatch(value)
    if not dm:
        return f"{label} row without a hexdump: {shown(value)}"
    area = dm.group(2)[:_HEX_AREA]
    cells = area.split()
    if not cells or not all(_BYTE.fullmatch(c) for c in cells) or len(cells) > 16:
        return f"bad hexdump cells: {shown(area.strip())}"
    return int(dm.group(1), 16), bytes.fromhex("".join(cells))


class _Burst:
    """The read or write being assembled from its hexdump rows: a row at offset 0000, of the other
    direction, or at another offset than the next expected (rows missing: reported) starts a new one;
    a huge one is handed on in pieces (memory stays bounded)."""

    def __init__(self, src: Source) -> None:
        self.src = src
        self.pending: Chunk | None = None
        self.expect = 0  # the offset of the next row of the pending burst

    def add(self, number: int, t: float | None, d: Direction, offset: int, data: bytes) -> Chunk | None:
        """One row's bytes; the burst before it or a full piece, when one is done."""
        pending, done = self.pending, None
        if offset == 0 or pending is None or pending.dir != d or offset != self.expect:
            if offset not in (0, self.expect):
                self.src.report.problem(self.src.where(number), f"hexdump offset {offset:04X}, expected "
                                                                f"{self.expect:04X}: rows are missing")
            done, pending = pending, Chunk(t, d, data)
        else:
            pending = Chunk(pending.t, d, pending.data + data)
        self.expect = offset + 16
        if len(pending.data) >= _SPILL:
            done, pending = pending, Chunk(t, d, b"")
        self.pending = pending
        return done
