"""Reader for socat's ``-x``, ``-v`` and ``-x -v`` traffic dumps (written on stderr).

How this works: each transfer starts with a header ``> 2024/05/01 10:00:00.123456  length=6 from=0
to=5`` (``>``: data from socat's first address to its second, ``<``: back). Then the data, as one of:
- ``-x``: one line of hex bytes `` 30 52 56 0d 0a``;
- ``-x -v``: hex lines of up to 16 bytes with an ASCII column, split after each LF, ending with ``--``;
- ``-v``: the bytes as text (``\\r``, ``\\\\``, ``\\a\\b\\v\\f`` escaped, LF as a line end, other
  unprintable bytes as ``.``), not ended by a newline, so the next header may follow on the same line.
  ``length=`` says where the text ends. ``.`` stands for any unprintable byte, so ``-v`` alone is lossy.
Some socat releases (1.7.x) print the fraction of a second as nine digits of which the first three are
``000`` and the last six the microseconds (``08.000428215`` is 08.428215 s); a file whose fractions all
start with ``000`` is read that way, the first other nine-digit fraction switches to nanoseconds.
socat's own diagnostics (``2024/05/01 10:00:00 socat[123] N ...``) are skipped. socat counts each
direction's bytes (``from=``, ``to=``): a header whose counters disagree with ``length=``, or a
``from=`` past where that side's previous transfer ended (transfers lost), is reported. A restarted
socat appending to the same log starts again at ``from=0``, which is accepted. The reader is a line
tokenizer (``tokenize``: what a line is) and a chunk builder (``_Transfers``: one chunk per transfer,
handed on in bounded pieces; ``length=`` beyond 16 MiB is damage).

Host side default: ``>``; run ``socat -x -v <host's side> <device's side>``.
"""

from __future__ import annotations

import re
from collections.abc import Generator, Iterator
from typing import Final

from xac1_proto.chunk import Chunk

from .base import Clock, Report, Sides, Source, shown, wallclock

FORMAT: Final = "socat"
DESCRIPTION: Final = "socat -x / -v / -x -v dump"
HOST_DEFAULT: Final = ">"
SUFFIXES: Final = (".socat",)

_HEADER: Final = re.compile(
    r"([<>]) (?:(\d{4}/\d\d/\d\d) (\d\d:\d\d:\d\d)(?:\.(\d+))?\s+)?"
    r"length=(\d{1,18}) from=(\d{1,18}) to=(\d{1,18})")
_DIAG: Final = re.compile(r"\d{4}/\d\d/\d\d \d\d:\d\d:\d\d socat\[\d+\] [DINWEF] ")
_HEX: Final = re.compile(r" ((?:[0-9a-f]{2} )*[0-9a-f]{2})(?: {2,}.*)?\s*")
_MAX_TRANSFER: Final = 1 << 24  # socat -b sets the transfer size (8192 by default); more is damage
_SPILL: Final = 1 << 16  # bytes of one transfer held before they are handed on
_ESCAPES: Final = {"r": 0x0D, "n": 0x0A, "\\": 0x5C, "a": 0x07, "b": 0x08, "v": 0x0B, "f": 0x0C,
                   "t": 0x09, "e": 0x1B}


def sniff(head: list[str]) -> int:
    """Confidence 0-100 that these first lines are a socat dump."""
    hits = sum(1 for line in head if _HEADER.match(line))
    return 90 if hits else (20 if any(_DIAG.match(line) for line in head) else 0)


class _Clock:
    """Turns a header's date, time and fraction into unix seconds, handling the 9-digit quirk."""

    def __init__(self) -> None:
        self.nanoseconds = False

    def __call__(self, date: str | None, clock: str | None, frac: str | None) -> float | None:
        if date is None or clock is None:
            return None
        frac = frac or ""
        if len(frac) == 9 and not self.nanoseconds:
            if frac.startswith("000"):
                frac = frac[3:]
            else:
                self.nanoseconds = True
        return wallclock(date, f"{clock}.{frac}" if frac else clock)


# line kinds of the tokenizer
HEADER, END, DIAG, BLANK, HEXROW, OTHER = "header", "end", "diag", "blank", "hex", "other"


def tokenize(text: str) -> tuple[str, re.Match[str] | None]:
    """What one dump line (or the rest of one) is: a transfer header, the ``--`` end of an ``-x -v``
    transfer, a socat diagnostic, a blank line, a row of hex bytes, or anything else (text or junk),
    with the regular-expression match that read it."""
    m = _HEADER.match(text)
    if m:
        return HEADER, m
    if text.strip() == "--":
        return END, None
    if _DIAG.match(text):
        return DIAG, None
    if not text.strip():
        return BLANK, None
    hm = _HEX.fullmatch(text)
    return (HEXROW, hm) if hm else (OTHER, None)


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    builder = _Transfers(src, Sides(FORMAT, host_is, (">", "<")))
    number = 0
    for number, line in src.lines():
        rest: str | None = line
        while rest is not None:
            rest = yield from builder.step(number, rest)
    yield from builder.end(number)


class _Transfers:
    """The chunk builder: turns the tokenized lines into one chunk per transfer (long transfers in
    bounded pieces), checking ``length=`` and the counters."""

    def __init__(self, src: Source, sides: Sides) -> None:
        self.src = src
        self.report = src.report
        self.sides = sides
        self.clock = _Clock()
        self.times = Clock(src.report)
        # the transfer being read: line, direction, t, length, data, sent, mode "hex"/"text"/None
        self.cur: dict | None = None
        self.text_bytes = 0
        self.following: dict[str, int] = {}  # side name -> the from= its next transfer should have

    def finish(self, line: int) -> Iterator[Chunk]:
        rec, self.cur = self.cur, None
        if rec is None:
            return
        if _got(rec) != rec["length"]:
            self.report.problem(self.src.where(rec["line"]),
                                f"transfer says length={rec['length']} but its dump holds {_got(rec)} "
                                f"byte(s) (cut short before line {line})",
                                nbytes=max(0, rec["length"] - _got(rec)))
        if rec["data"]:
            yield Chunk(rec["t"], rec["dir"], bytes(rec["data"]))

    def step(self, number: int, text: str) -> Generator[Chunk, None, str | None]:
        """Read one line or the rest of one; returns (as the generator's value) a rest still to read."""
        cur = self.cur
        if cur is not None and cur["mode"] == "text" and _got(cur) < cur["length"] and \
                not (_got(cur) == 0 and _HEADER.match(text)):  # else an empty-looking transfer
            return (yield from self._text(number, text))
        kind, m = tokenize(text)
        if kind == HEADER:
            assert m is not None
            yield from self.finish(number)
            self._header(number, m, text)
        elif kind in (END, DIAG):
            if kind == END or cur is None or cur["mode"] != "text":
                yield from self.finish(number)
        elif kind == BLANK:
            if cur is not None and cur["mode"] is None:
                cur["mode"] = "text"
                return text
        elif cur is None:
            self.report.problem(self.src.where(number), f"not a socat header, data or log line: "
                                                        f"{shown(text)}", nlines=1)
        elif kind == HEXROW and cur["mode"] in (None, "hex"):
            assert m is not None
            cur["mode"] = "hex"
            cur["data"].extend(bytes.fromhex(m.group(1)))
            yield from _spill(cur)
        elif cur["mode"] is None:
            cur["mode"] = "text"
            return text
        else:
            self.report.problem(self.src.where(number), f"cannot read this dump line: {shown(text)}",
                                nlines=1)
        return None

    def _text(self, number: int, text: str) -> Generator[Chunk, None, str | None]:
        """-v text of the current transfer; returns what follows its last byte on the line."""
        cur = self.cur
        assert cur is not None
        consumed, cut = _take_text(text, cur)
        self.text_bytes += consumed
        yield from _spill(cur)
        if _got(cur) < cur["length"]:
            cur["data"].append(0x0A)  # the line end was an LF byte
            if _got(cur) == cur["length"]:
                yield from self.finish(number)
            return None
        yield from self.finish(number)
        return text[cut:] or None

    def _header(self, number: int, m: re.Match[str], text: str) -> None:
        report, where = self.report, self.src.where(number)
        d = self.sides.direction(m.group(1))
        assert d is not None
        length, start, end = int(m.group(5)), int(m.group(6)), int(m.group(7))
        _check_counters(m.group(1), length, start, end, self.following, report, where)
        if length > _MAX_TRANSFER:
            report.problem(where, f"length={length} is not plausible for one transfer (expected at "
                                  f"most {_MAX_TRANSFER}); read as that")
            length = _MAX_TRANSFER
        try:
            t = self.times.check(self.clock(m.group(2), m.group(3), m.group(4)), where)
        except ValueError as exc:
            report.problem(where, f"{exc}; the bytes are kept with the previous time")
            t = self.times.last
        self.cur = {"line": number, "dir": d, "t": t, "length": length, "data": bytearray(), "sent": 0,
                    "mode": None}
        tail = text[m.end():].strip()
        if tail:
            report.problem(where, f"unexpected text after the header: {shown(tail)}")

    def end(self, number: int) -> Iterator[Chunk]:
        cur = self.cur
        if cur is not None and cur["mode"] == "text" and _got(cur) == cur["length"]:
            self.src.unterminated = None  # -v text need not end with a newline: length= says it is whole
        yield from self.finish(number)
        if self.text_bytes:
            self.report.note(f"{self.src.name}: socat -v text dump: an unprintable byte shows as '.', so "
                             f"a '.' may stand for another byte (use socat -x -v for exact bytes)")


def _got(rec: dict) -> int:
    """Bytes of a transfer read so far (handed on and held)."""
    return int(rec["sent"]) + len(rec["data"])


def _spill(rec: dict) -> Iterator[Chunk]:
    """Hand on the bytes held of a long transfer (memory stays bounded whatever ``length=`` says)."""
    data: bytearray = rec["data"]
    if len(data) >= _SPILL:
        yield Chunk(rec["t"], rec["dir"], bytes(data))
        rec["sent"] += len(data)
        data.clear()


def _check_counters(side: str, length: int, start: int, end: int, following: dict[str, int],
                    report: object, where: str) -> None:
    """socat counts each direction's bytes: ``from=`` is the count before the transfer, ``to=`` the
    count of its last byte. A header whose counters disagree with ``length=`` is damaged; a ``from=``
    past the previous transfer's end means transfers of that side are missing from the log."""
    assert isinstance(report, Report)
    if end - start + 1 != length:
        report.problem(where, f"damaged header: length={length} but from={start} to={end} span "
                              f"{end - start + 1} byte(s); read as length={length}")
    elif side in following and start != following[side] and start != 0:
        gap = start - following[side]
        if gap > 0:
            report.problem(where, f"{gap} byte(s) of the {side!r} side are missing before this transfer "
                                  f"(from={start}, the previous one ended at to={following[side] - 1})",
                           nbytes=gap)
        else:
            report.problem(where, f"from={start} repeats bytes of the {side!r} side (the previous "
                                  f"transfer ended at to={following[side] - 1}): the log is damaged")
    following[side] = start + length


def _take_text(text: str, rec: dict) -> tuple[int, int]:
    """Decode -v text into ``rec['data']`` until its length is reached; returns (bytes, chars used)."""
    data: bytearray = rec["data"]
    i = 0
    start = len(data)
    while i < len(text) and rec["sent"] + len(data) < rec["length"]:
        c = text[i]
        if c == "\\" and i + 1 < len(text) and text[i + 1] in _ESCAPES:
            data.append(_ESCAPES[text[i + 1]])
            i += 2
            continue
        data.append(ord(c) & 0xFF)
        i += 1
    return len(data) - start, i
