"""Reader for Saleae Logic async serial exports (CSV).

How this works: two layouts are read.
- Logic 1.x analyzer export, one file per line direction: header ``Time [s],Value,Parity Error,Framing
  Error``, then one row per byte: ``0.001052,0x30,,`` (hex radix) or ``0.001052,'0',,`` / ``0``
  (ASCII radix; ``\\r``, ``\\n``, ``\\t``, ``\\xNN``, ``[CR]``-style names and ``COMMA``/``SPACE`` are
  read too). A non-empty error column marks the byte (Chunk.error).
- Logic 2 data table export: header ``name,type,start_time,duration,data`` (any further columns; one
  whose name contains ``error`` marks the byte), one row per frame of an analyzer: ``"Async
  Serial","data",0.001052,0.00104,0x30``. Rows of other types with an error word (``framing error``)
  mark the last byte; other row types are skipped.
Times are seconds from the start of the capture. Hex values have two digits (``0x0D``), as Saleae
prints them. A row with another number of fields than the header is reported as damaged (and read).

Sides: the analyzer export names a side by its file; the data table by the analyzer's ``name`` (the
file when several files are given). Host side default: a file or analyzer whose name says ``host``
(``device`` marks the other), else the first file given (the first analyzer in the table).
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Final

from xac1_proto.chunk import Chunk, Direction

from .base import Clock, Sides, Source, shown

FORMAT: Final = "saleae"
DESCRIPTION: Final = "Saleae Logic async serial export (analyzer CSV or Logic 2 data table)"
HOST_DEFAULT: Final = "the file/analyzer named host, else the first file given"
SUFFIXES: Final = (".csv",)
MULTI_FILE: Final = True  # one file per direction, merged by time

_ANALYZER: Final = ("time [s]", "value")
_TABLE: Final = ("name", "type", "start_time")
_ESC: Final = {"\\r": 0x0D, "\\n": 0x0A, "\\t": 0x09, "\\0": 0x00, "\\\\": 0x5C, "COMMA": 0x2C,
               "SPACE": 0x20, "' '": 0x20, "[CR]": 0x0D, "[LF]": 0x0A, "[TAB]": 0x09, "[NUL]": 0x00}


def sniff(head: list[str]) -> int:
    if not head:
        return 0
    first = [c.strip().strip('"').lower() for c in head[0].split(",")]
    if tuple(first[:2]) == _ANALYZER or tuple(first[:3]) == _TABLE:
        return 95
    return 0


def one_direction(head: bytes) -> bool:
    """Does a file starting with these bytes hold one line direction (the analyzer export) rather than
    a data table naming its analyzers?"""
    first = head.decode("latin-1").split("\n", 1)[0]
    return tuple(c.strip().strip('"').lower() for c in first.split(",")[:2]) == _ANALYZER


def value_byte(text: str) -> int | None:
    """A byte in any radix Saleae exports: ``0x30``, ``'0'``, ``0``, ``\\r``, ``0b00110000``."""
    text = text.strip()
    if len(text) >= 3 and text[0] == text[-1] == "'":
        text = text[1:-1]
    if text in _ESC:
        return _ESC[text]
    if re.fullmatch(r"0x[0-9A-Fa-f]{2}", text):  # Saleae always prints two hex digits
        return int(text, 16)
    if re.fullmatch(r"\\x[0-9A-Fa-f]{2}", text):
        return int(text[2:], 16)
    if re.fullmatch(r"0b[01]{1,8}", text):
        return int(text, 2)
    if len(text) == 1:
        return ord(text) & 0xFF
    return None


def _error_text(column: str, value: str) -> str:
    """``Framing Error`` + ``Error`` -> ``framing error``; ``error`` + ``framing`` -> ``error: framing``."""
    value = value.strip()
    return column if value.lower() in ("error", "1", "true", "x") else f"{column}: {value}"


@dataclass(frozen=True)
class _Layout:
    """Which export a header names, and where its columns are: what a row of it says."""

    header: list[str]
    table: bool  # Logic 2 data table (else the Logic 1.x analyzer export)
    error_cols: list[int]
    time_col: int
    data_col: int | None

    def side(self, src: Source, row: list[str], multi_file: bool) -> str:
        """The name of a row's side: its file (the analyzer export, or several files), else its
        analyzer."""
        return src.name if not self.table or multi_file else row[0]

    def error(self, row: list[str]) -> str | None:
        """What the row's first non-empty error column says (None: no error)."""
        header = self.header
        return next((_error_text(header[i], row[i]) for i in self.error_cols
                     if i < len(row) and row[i].strip()), None)

    def is_data(self, row: list[str]) -> bool:
        """Does the row carry a byte (every row of the analyzer export; a table's ``data`` rows)?"""
        return not self.table or row[1].strip().lower() == "data"

    def value(self, row: list[str]) -> int | None:
        """The byte a data row carries (None: none that reads)."""
        col = self.data_col
        return value_byte(row[col]) if col is not None and col < len(row) else None


def _layout(src: Source, lines: Iterator[tuple[int, str]]) -> _Layout | None:
    """The layout the file's first line (its header) names; None for an empty file or another first
    line (reported)."""
    first = next(lines, None)
    if first is None:
        src.report.problem(src.name, "empty file")
        return None
    number, header_line = first
    try:
        header = [c.strip().lower() for c in next(csv.reader([header_line]))]
    except (csv.Error, StopIteration):
        header = []
    if tuple(header[:2]) == _ANALYZER:
        table = False
    elif tuple(header[:3]) == _TABLE:
        table = True
    else:
        src.report.problem(src.where(number), f"not a Saleae header: {shown(header_line)}", nlines=1)
        return None
    data_col = header.index("data") if table and "data" in header else (None if table else 1)
    return _Layout(header, table, [i for i, c in enumerate(header) if "error" in c], 2 if table else 0,
                   data_col)


def _rows(src: Source, lines: Iterator[tuple[int, str]], layout: _Layout) -> Iterator[tuple[int, float,
                                                                                             list[str]]]:
    """The tokenizer: (line number, time, fields) of each readable row, problems reported."""
    report = src.report
    clock = Clock(report)
    for number, line in lines:
        if not line.strip():
            continue
        try:
            row = next(csv.reader([line]))
            t = clock.check(float(row[layout.time_col]), src.where(number))
        except (ValueError, IndexError, StopIteration, csv.Error):
            report.problem(src.where(number), f"not a Saleae row: {shown(line)}", nlines=1)
            continue
        if t is None:  # no good time yet: the row cannot be placed
            report.problem(src.where(number), "row skipped: no usable time before it", nlines=1)
            continue
        if len(row) != len(layout.header):
            report.problem(src.where(number), f"row has {len(row)} field(s), the header "
                                              f"{len(layout.header)}: the row is damaged: {shown(line)}")
        yield number, t, row


def read(src: Source, host_is: str | None = None, sides: Sides | None = None,
         multi_file: bool = False) -> Iterator[Chunk]:
    """The chunk builder: one byte a chunk, held back one row so a following error row can mark it
    (``_Held``)."""
    own = sides is None
    sides = sides or Sides(FORMAT, host_is)
    lines = src.lines(src.line_end())  # CR-only line ends, as some exports on other systems write
    layout = _layout(src, lines)
    if layout is None:
        return
    held = _Held()
    for number, t, row in _rows(src, lines, layout):
        key = layout.side(src, row, multi_file)
        d = sides.direction(key)
        if d is None:
            src.report.problem(src.where(number), f"a third side {shown(key)}; its rows are skipped",
                               nlines=1)
            continue
        error = layout.error(row)
        if not layout.is_data(row):
            if "error" in " ".join(row[1:]).lower() and \
                    (chunk := held.mark(t, d, error or row[1].strip())) is not None:
                yield chunk
            continue
        value = layout.value(row)
        if value is None:
            src.report.problem(src.where(number), f"cannot read the byte value in {shown(','.join(row))}",
                               nlines=1)
        elif (chunk := held.hold(Chunk(t, d, bytes([value]), error))) is not None:
            yield chunk
    if held.byte is not None:
        yield held.byte
    if own:
        sides.check(src.report, src.name)


class _Held:
    """The last byte read, held back one row so that an error row after it can mark it."""

    def __init__(self) -> None:
        self.byte: Chunk | None = None

    def hold(self, byte: Chunk) -> Chunk | None:
        """Hold this byte; the one held before it, handed on."""
        done, self.byte = self.byte, byte
        return done

    def mark(self, t: float, d: Direction, mark: str) -> Chunk | None:
        """An error row of side ``d``: it marks the byte held when that is of its side, else it is a chunk
        of its own without bytes."""
        byte = self.byte
        if byte is not None and byte.dir == d:
            self.byte = Chunk(byte.t, d, byte.data, mark)
            return None
        return Chunk(t, d, b"", mark)
