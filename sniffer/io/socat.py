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
socat appending to the same log starts again at ``from=0``, which is accepted. A header whose time is
more than a second before the one before it is reported too (``timeline``: the clock was set back).

One parser: the file is read in blocks of ``BLOCK`` characters (``_Lines``: never the whole file), cut
into lines (numbered, line end stripped; a line longer than ``MAX_LINE`` in pieces of the same number).
Each line is classified (``tokenize``: what a line is) and acted on by the transfer builder
(``_Transfers``: one chunk per transfer, handed on in bounded pieces; ``length=`` beyond 16 MiB is
damage), whatever the dump's style and state. ``_Transfers.read`` takes the lines that make up almost
every dump itself, before any other classification: a header and the hex row after it, matched at once
(``_HEADER_ROW``; the match fails at once on any other line), then ``_header``'s checks (counters,
length, time) done in place; a further hex row (a leading space). A hex row's bytes come from
``bytes.fromhex`` checked against ``bytes.hex`` (lower case, single spaces, as ``_HEX`` reads them), else
from ``_HEX`` itself; short rows are remembered (a conversation repeats itself). Every other line, and
any line while -v text is being read, goes through ``step``, which does the same for every kind. A
header's time is its minute's start (``wallclock``, remembered) plus its seconds and fraction, computed
as ``wallclock`` computes it. -v text is decoded a run of characters at a time.

Host side default: ``>``; run ``socat -x -v <host's side> <device's side>``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Generator, Iterator
from typing import Final

from xac1_proto.chunk import Chunk, Direction

from . import base as _base
from .base import MAX_TIME, MIN_TIME, Clock, Report, Sides, Source, shown, wallclock
from .timeline import TOLERANCE_S, Timeline

FORMAT: Final = "socat"
DESCRIPTION: Final = "socat -x / -v / -x -v dump"
HOST_DEFAULT: Final = ">"
SUFFIXES: Final = (".socat",)

_HEADER: Final = re.compile(
    r"([<>]) (?:(\d{4}/\d\d/\d\d) (\d\d:\d\d:\d\d)(?:\.(\d+))?\s+)?"
    r"length=(\d{1,18}) from=(\d{1,18}) to=(\d{1,18})")
_HEADER_LINE: Final = re.compile(_HEADER.pattern + r"(.*)", re.DOTALL)  # and what follows on the line
# _HEADER with what follows on its line (CR included) and, when it starts with a space, the next line;
# the date and the minute are taken as any characters (a quicker match) and checked by _MINUTE when
# they change (in latin-1 text ``\\d`` is ``[0-9]``)
_HEADER_ROW: Final = re.compile(
    r"([<>]) (?:(.{10}) (.{5}):([0-9]{2})(?:\.([0-9]+))?\s+)?"
    r"length=([0-9]{1,18}) from=([0-9]{1,18}) to=([0-9]{1,18})([^\n]*)\n(?:( [^\n]*)\n)?")
_MINUTE: Final = re.compile(r"\d{4}/\d\d/\d\d \d\d:\d\d")
_POWERS: Final = tuple(10 ** n for n in range(13))
_DIAG: Final = re.compile(r"\d{4}/\d\d/\d\d \d\d:\d\d:\d\d socat\[\d+\] [DINWEF] ")
_HEX: Final = re.compile(r" ((?:[0-9a-f]{2} )*[0-9a-f]{2})(?: {2,}.*)?\s*")
_MAX_TRANSFER: Final = 1 << 24  # socat -b sets the transfer size (8192 by default); more is damage
_SPILL: Final = 1 << 16  # bytes of one transfer held before they are handed on
_ESCAPES: Final = {"r": 0x0D, "n": 0x0A, "\\": 0x5C, "a": 0x07, "b": 0x08, "v": 0x0B, "f": 0x0C,
                   "t": 0x09, "e": 0x1B}
_KNOWN: Final = 4096  # hex rows remembered (their text -> their bytes)
_KNOWN_TEXT: Final = 160  # characters of the longest row remembered
_TEXT: Final = "text"  # a transfer's mode: -v text (None: not known yet; "hex": hex rows)
_HEXMODE: Final = "hex"

BLOCK = 1 << 16  # characters read at once (a test makes it tiny so that block ends fall everywhere)


def sniff(head: list[str]) -> int:
    """Confidence 0-100 that these first lines are a socat dump."""
    hits = sum(1 for line in head if _HEADER.match(line))
    return 90 if hits else (20 if any(_DIAG.match(line) for line in head) else 0)


class _Clock:
    """The 9-digit quirk: which fractions of a second are microseconds behind ``000``."""

    def __init__(self) -> None:
        self.nanoseconds = False

    def fraction(self, frac: str) -> str:
        """A header's fraction digits as read: ``000`` and six digits are microseconds until a file shows
        another nine-digit fraction (nanoseconds from then on)."""
        if len(frac) == 9 and not self.nanoseconds:
            if frac.startswith("000"):
                return frac[3:]
            self.nanoseconds = True
        return frac


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
    lines = _Lines(src)
    yield from builder.read(lines)
    yield from builder.end(lines.number)


class _Lines:
    """The file read in blocks of ``BLOCK`` characters (latin-1) and cut into the very lines
    ``Source.lines`` gives: numbered, line end stripped, a line longer than ``MAX_LINE`` in pieces of the
    same number. ``buf[pos:]`` is what is not read yet; the fast path reads it directly."""

    def __init__(self, src: Source) -> None:
        self.src = src
        self.buf = ""
        self.pos = 0
        self.eof = False
        self.number = 0  # of the last line (piece) read
        self.continued = False  # the last piece read had no line end: the next continues its line
        self.max_line = _base.MAX_LINE

    def _fill(self) -> bool:
        """Read another block after what is left; False at the end of the file."""
        data = self.src.read(BLOCK)
        if not data:
            self.eof = True
            return False
        self.buf = self.buf[self.pos:] + data.decode("latin-1")
        self.pos = 0
        return True

    def ahead(self) -> None:
        """Read another block when less than a long line is left (the fast path reads whole lines)."""
        if not self.eof and len(self.buf) - self.pos < self.max_line:
            self._fill()

    def next(self) -> tuple[int, str] | None:
        """(line number, text) of the next line or piece of one, None at the end of the file."""
        buf, pos = self.buf, self.pos
        nl = buf.find("\n", pos, pos + self.max_line)
        if nl < 0 or self.continued:
            return self._piece()
        self.pos = nl + 1
        self.number += 1  # src.unterminated is None already: the last piece read ended its line
        return self.number, buf[pos:nl].rstrip("\r")

    def _piece(self) -> tuple[int, str] | None:
        """``next`` for a line that is not whole in the block or continues a piece."""
        while True:
            buf, pos = self.buf, self.pos
            limit = pos + self.max_line
            nl = buf.find("\n", pos, limit)
            if nl >= 0:
                end = nl + 1
            elif len(buf) >= limit:
                end = limit
            elif not self.eof and self._fill():
                continue
            elif pos < len(buf):
                end = len(buf)
            else:
                return None
            self.pos = end
            if not self.continued:
                self.number += 1
            self.continued = nl < 0
            self.src.unterminated = self.number if self.continued else None
            return self.number, buf[pos:end].rstrip("\r\n")


class _Transfer:
    """The transfer being read: its header's line, direction, time and ``length=``, its bytes held (not
    handed on yet), how many were handed on, and its mode (None until its first data line)."""

    __slots__ = ("line", "dir", "t", "length", "data", "sent", "mode")

    def __init__(self, line: int, d: Direction, t: float | None, length: int) -> None:
        self.line = line
        self.dir = d
        self.t = t
        self.length = length
        self.data = bytearray()
        self.sent = 0
        self.mode: str | None = None

    @property
    def got(self) -> int:
        """Bytes read so far (handed on and held)."""
        return self.sent + len(self.data)

    def spill(self) -> Chunk | None:
        """The bytes held of a long transfer, handed on (memory stays bounded whatever ``length=``
        says), or None while they are few."""
        data = self.data
        if len(data) < _SPILL:
            return None
        self.sent += len(data)
        chunk = Chunk(self.t, self.dir, bytes(data))
        data.clear()
        return chunk


class _Transfers:
    """The chunk builder: turns the classified lines into one chunk per transfer (long transfers in
    bounded pieces), checking ``length=``, the counters and the times."""

    def __init__(self, src: Source, sides: Sides) -> None:
        self.src = src
        self.report = src.report
        self.sides = sides
        self.dirs: dict[str, Direction] = {}
        for mark in (">", "<"):
            d = sides.direction(mark)
            assert d is not None
            self.dirs[mark] = d
        self.clock = _Clock()
        self.times = Clock(src.report)
        self.timeline = Timeline(src.report)
        self.cur: _Transfer | None = None  # the transfer being read
        self.text_bytes = 0
        self.following: dict[str, int] = {}  # side name -> the from= its next transfer should have
        # the last header's date and minute (HH:MM), and the minute's start (``wallclock``): seconds in a
        # minute are linear (time zones change their offset on whole minutes)
        self.minute: tuple[str, str, float] = ("", "", 0.0)
        self.known: dict[str, bytes] = {}  # hex rows read (text -> bytes)

    def read(self, lines: _Lines) -> Iterator[Chunk]:
        """Every line of the file: the common ones taken here, the others by ``step`` (see the module
        docstring). A header line and the line after it, when that starts with a space (a hex row), are
        matched at once (``_HEADER_ROW``). The transfer they make is
        held in locals (its bytes, not copied) until the next line shows whether more rows follow; it
        becomes ``cur`` before anything else reads the state. The position in the file, the line number
        and the last time are locals too, handed to ``lines`` and the clocks before anything else."""
        header_row, known, max_line, following = _HEADER_ROW.match, self.known, lines.max_line, self.following
        dirs, timeline, tol, powers = self.dirs, self.timeline, TOLERANCE_S, _POWERS
        new = Chunk
        day, minute, base = self.minute
        held: bytes | None = None  # the bytes of the transfer held (None: none is)
        h_line, h_dir, h_t, h_length = 0, dirs[">"], None, 0
        buf, pos, number, continued = lines.buf, lines.pos, lines.number, lines.continued
        last_t = timeline.last  # the time of the last header read here (times.last too, when it was one)
        while True:
            piece: tuple[int, str] | None = None
            m = header_row(buf, pos)  # the most common line: fails at once on any other
            if m is None:
                first = buf[pos:pos + 1]
            else:
                first = ""
                cur = self.cur
                if ((after := m.end()) - pos < max_line or m.end(9) - pos < max_line) and not continued \
                        and (held is not None or cur is None or cur.mode is not _TEXT):
                    mark, date, hhmm, ss, frac, length_s, start_s, end_s, tail, row = m.groups()
                    if date is not None and (hhmm != minute or date != day) and \
                            _MINUTE.fullmatch(f"{date} {hhmm}") is None:
                        m = None  # not a header as _HEADER reads one: step says what it is
                else:
                    m = None
                if m is not None:
                    number += 1
                    if after - pos < max_line or row is not None and len(row) < max_line:
                        pos = after  # (both lines shorter than MAX_LINE: pieces are read by step)
                    else:
                        row = None
                        pos = m.end(9) + 1
                    if held is not None:  # the transfer before ends
                        if len(held) == h_length:
                            yield new(h_t, h_dir, held)
                        else:
                            self._hold(h_line, h_dir, h_t, h_length, held)
                            if (chunk := self.finish(number)) is not None:
                                yield chunk
                        held = None
                    elif self.cur is not None and (chunk := self.finish(number)) is not None:
                        yield chunk
                    length, start, end = int(length_s), int(start_s), int(end_s)
                    if end - start + 1 != length or length > _MAX_TRANSFER or \
                            mark in following and start != following[mark] and start != 0:
                        length = self._damaged_header(number, mark, length, start, end)
                    else:
                        following[mark] = start + length
                    t = None
                    if date is not None:
                        if frac is None or len(frac) > 6 or hhmm != minute or date != day:
                            self._clocks(last_t)
                            t = self._time(number, date, f"{hhmm}:{ss}", frac)
                            day, minute, base = self.minute
                            last_t = timeline.last
                        else:  # as wallclock computes it: the whole second (in range), the fraction
                            t = base + int(ss) + int(frac) / powers[len(frac)]
                            if t + tol < last_t:
                                timeline.last = last_t
                                timeline.check(t, self.src.where(number))
                            last_t = t
                    if tail and not tail.isspace():
                        self.report.problem(self.src.where(number), f"unexpected text after the header: "
                                                                    f"{shown(tail.strip())}")
                    if row is not None:
                        number += 1
                        if row[-1:] == "\r":
                            row = row.rstrip("\r")
                        data = known.get(row)
                        if data is None:
                            data = self._hex_row(row)
                        if data:
                            held, h_line, h_dir, h_t, h_length = data, number - 1, dirs[mark], t, length
                            continue
                        piece = number, row  # no hex row: step reads it
                    self.cur = _Transfer(number - (row is not None), dirs[mark], t, length)
                    if piece is None:
                        continue
            if held is not None:  # another line: the transfer held becomes the state step reads
                self._hold(h_line, h_dir, h_t, h_length, held)
                held = None
            cur = self.cur
            if piece is None and first == " " and cur is not None and cur.mode is not _TEXT and not continued:
                nl = buf.find("\n", pos, pos + max_line)
                if nl >= 0:
                    text = buf[pos:nl]
                    if text[-1:] == "\r":
                        text = text.rstrip("\r")
                    data = known.get(text)
                    if data is None:
                        data = self._hex_row(text)
                    pos, number = nl + 1, number + 1
                    if data:
                        cur.mode = _HEXMODE
                        cur.data += data
                        if len(cur.data) >= _SPILL and (chunk := cur.spill()) is not None:
                            yield chunk
                        continue
                    piece = number, text
            # anything else: lines and the clocks as read so far, then step
            lines.pos, lines.number = pos, number
            self._clocks(last_t)
            if piece is None:
                piece = lines.next()
                if piece is None:
                    return
            line_number, line = piece
            rest: str | None = line
            while rest is not None:
                rest = yield from self.step(line_number, rest)
            day, minute, base = self.minute
            buf, pos, number, continued = lines.buf, lines.pos, lines.number, lines.continued
            last_t = timeline.last

    def _clocks(self, last: float) -> None:
        """The last good time (``read`` holds it), handed to the clocks (the same time for both: none yet
        is -inf to the timeline and None to ``times``)."""
        self.timeline.last = last
        self.times.last = None if last == -math.inf else last

    def _hold(self, line: int, d: Direction, t: float | None, length: int, data: bytes) -> None:
        """A transfer read by ``read`` (a header and a hex row) becomes the transfer being read."""
        cur = self.cur = _Transfer(line, d, t, length)
        cur.mode = _HEXMODE
        cur.data += data

    def _damaged_header(self, number: int, mark: str, length: int, start: int, end: int) -> int:
        """A header whose counters or length are wrong: reported; the length read (at most 16 MiB)."""
        where = self.src.where(number)
        _check_counters(mark, length, start, end, self.following, self.report, where)
        if length > _MAX_TRANSFER:
            self.report.problem(where, f"length={length} is not plausible for one transfer (expected at most "
                                       f"{_MAX_TRANSFER}); read as that")
            length = _MAX_TRANSFER
        return length

    def _hex_row(self, text: str) -> bytes:
        """The bytes of a hex row as ``_HEX`` reads them (empty: not a hex row); short rows remembered."""
        try:
            data = bytes.fromhex(text[1:])
        except ValueError:
            data = b""
        if not data or data.hex(" ") != text[1:]:  # not plain: as _HEX reads it, if it does
            hm = _HEX.fullmatch(text)
            data = bytes.fromhex(hm.group(1)) if hm else b""
        if len(text) <= _KNOWN_TEXT:
            if len(self.known) >= _KNOWN:
                self.known.clear()
            self.known[text] = data
        return data

    def finish(self, line: int) -> Chunk | None:
        """End the transfer being read: its last bytes as a chunk (None: none), a short dump reported."""
        rec, self.cur = self.cur, None
        if rec is None:
            return None
        got = rec.sent + len(rec.data)
        if got != rec.length:
            self.report.problem(self.src.where(rec.line),
                                f"transfer says length={rec.length} but its dump holds {got} "
                                f"byte(s) (cut short before line {line})",
                                nbytes=max(0, rec.length - got))
        return Chunk(rec.t, rec.dir, bytes(rec.data)) if rec.data else None

    def step(self, number: int, text: str) -> Generator[Chunk, None, str | None]:
        """Read one line or the rest of one; returns (as the generator's value) a rest still to read."""
        cur = self.cur
        if cur is not None and cur.mode == _TEXT and cur.got < cur.length and \
                not (cur.got == 0 and _HEADER.match(text)):  # else an empty-looking transfer
            return (yield from self._text(number, text))
        kind, m = tokenize(text)
        if kind == HEADER:
            if (chunk := self.finish(number)) is not None:
                yield chunk
            m = _HEADER_LINE.match(text)
            assert m is not None
            self._header(number, m)
        elif kind in (END, DIAG):
            chunk = self.finish(number) if kind == END or cur is None or cur.mode != _TEXT else None
            if chunk is not None:
                yield chunk
        elif kind == BLANK:
            if cur is not None and cur.mode is None:
                cur.mode = _TEXT
                return text
        elif cur is None:
            self.report.problem(self.src.where(number), f"not a socat header, data or log line: "
                                                        f"{shown(text)}", nlines=1)
        elif kind == HEXROW and cur.mode in (None, _HEXMODE):
            assert m is not None
            cur.mode = _HEXMODE
            cur.data.extend(bytes.fromhex(m.group(1)))
            if (chunk := cur.spill()) is not None:
                yield chunk
        elif cur.mode is None:
            cur.mode = _TEXT
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
        if (chunk := cur.spill()) is not None:
            yield chunk
        if cur.got < cur.length:
            cur.data.append(0x0A)  # the line end was an LF byte
            if cur.got == cur.length and (chunk := self.finish(number)) is not None:
                yield chunk
            return None
        if (chunk := self.finish(number)) is not None:
            yield chunk
        return text[cut:] or None

    def _header(self, number: int, m: re.Match[str]) -> None:
        """A transfer's header: its counters, length and time checked; it becomes the transfer read."""
        mark, date, clock, frac, length_s, start_s, end_s, tail = m.groups()
        length, start, end = int(length_s), int(start_s), int(end_s)
        following = self.following
        if end - start + 1 != length or length > _MAX_TRANSFER or \
                mark in following and start != following[mark] and start != 0:
            length = self._damaged_header(number, mark, length, start, end)
        else:
            following[mark] = start + length
        t = None if date is None else self._time(number, date, clock, frac)
        self.cur = _Transfer(number, self.dirs[mark], t, length)
        if tail and not tail.isspace():
            self.report.problem(self.src.where(number), f"unexpected text after the header: "
                                                        f"{shown(tail.strip())}")

    def _time(self, number: int, date: str, clock: str, frac: str | None) -> float | None:
        """A header's time (``clock``: ``HH:MM:SS``): its whole second plus the fraction, as ``wallclock``
        computes it, the 9-digit quirk read (``_Clock``); a time that cannot be one, or that runs
        backwards, is reported (the previous time is kept for the former). The minute's start is
        remembered when all its seconds are in range (``read`` then computes the next ones itself)."""
        times = self.times
        frac = self.clock.fraction(frac or "")
        hhmm, ss = clock[:5], int(clock[6:])
        day, minute, base = self.minute
        if date != day or hhmm != minute or ss >= 60:
            try:
                if ss >= 60:
                    raise ValueError(clock)
                base = wallclock(date, f"{hhmm}:00")
            except ValueError:  # said as wallclock says it of the whole time
                try:
                    wallclock(date, f"{clock}.{frac}" if frac else clock)
                except ValueError as exc:
                    self.report.problem(self.src.where(number), f"{exc}; the bytes are kept with the "
                                                                f"previous time")
                return times.last
            in_range = MIN_TIME <= base < MAX_TIME - 61
            self.minute = (date, hhmm, base) if in_range else ("", "", 0.0)
        if frac:
            digits = frac[:12]
            t = base + ss + int(digits) / _POWERS[len(digits)]
        else:
            t = base + ss + 0.0
        if not MIN_TIME <= t < MAX_TIME:
            return times.check(t, self.src.where(number))  # said; the previous time
        times.last = t
        timeline = self.timeline
        if t + TOLERANCE_S < timeline.last:
            timeline.check(t, self.src.where(number))
        else:
            timeline.last = t
        return t

    def end(self, number: int) -> Iterator[Chunk]:
        cur = self.cur
        if cur is not None and cur.mode == _TEXT and cur.got == cur.length:
            self.src.unterminated = None  # -v text need not end with a newline: length= says it is whole
        if (chunk := self.finish(number)) is not None:
            yield chunk
        if self.text_bytes:
            self.report.note(f"{self.src.name}: socat -v text dump: an unprintable byte shows as '.', so "
                             f"a '.' may stand for another byte (use socat -x -v for exact bytes)")


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


def _take_text(text: str, rec: _Transfer) -> tuple[int, int]:
    """Decode -v text into ``rec['data']`` until its length is reached; returns (bytes, chars used).
    A run of characters without a backslash is copied at once (each character is its latin-1 byte)."""
    data = rec.data
    start, need = len(data), rec.length - rec.sent - len(data)
    i, n = 0, len(text)
    while need > 0 and i < n:
        j = text.find("\\", i, i + need)
        if j < 0:
            j = min(n, i + need)
        data += text[i:j].encode("latin-1")
        need -= j - i
        i = j
        if need > 0 and i < n:  # a backslash: an escape, or itself
            if i + 1 < n and text[i + 1] in _ESCAPES:
                data.append(_ESCAPES[text[i + 1]])
                i += 2
            else:
                data.append(0x5C)
                i += 1
            need -= 1
    return len(data) - start, i
