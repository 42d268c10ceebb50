"""Reader for socat's ``-x``, ``-v`` and ``-x -v`` traffic dumps (written on stderr).

How this works: each transfer starts with a header ``> 2024/05/01 10:00:00.123456  length=6 from=0
to=5`` (``>``: data from socat's first address to its second, ``<``: back). Then the data, as one of:
- ``-x``: one line of hex bytes `` 30 52 56 0d 0a``;
- ``-x -v``: hex lines of up to 16 bytes with an ASCII column, split after each LF, ending with ``--``;
- ``-v``: the bytes as text (``\\r``, ``\\\\``, ``\\a\\b\\v\\f`` escaped, LF as a line end, other
  unprintable bytes as ``.``), not ended by a newline, so the next header may follow on the same line.
  ``length=`` says where the text ends, so the file's last line may have no line end. ``.`` stands for
  any unprintable byte, so ``-v`` alone is lossy. Text may look like hex rows (`` 00`` is three bytes as
  text, one as hex): rows too short for ``length=`` whose text reading fits it are text, in a log that
  has not shown a transfer of hex rows (socat dumps a run in one style; there a short row is damage).
Some socat releases (1.7.x) print the fraction of a second as nine digits of which the first three are
``000`` and the last six the microseconds (``08.000428215`` is 08.428215 s); a file whose fractions all
start with ``000`` is read that way, the first other nine-digit fraction switches to nanoseconds.
socat's own diagnostics (``2024/05/01 10:00:00 socat[123] N ...``) are skipped. socat counts each
direction's bytes (``from=``, ``to=``): a header whose counters disagree with ``length=``, or a
``from=`` past where that side's previous transfer ended (transfers lost), is reported. A restarted
socat appending to the same log starts again at ``from=0``, which is accepted. A header whose time is
more than a second before the one before it is reported too (``timeline``: the clock was set back).

One parser: the file is read in blocks of ``block`` characters (``_Blocks``: never the whole file), handed on
as regions of whole lines, which one ``findall`` of ``_block_matcher`` cuts into lines at once (numbered, line
end stripped; a line longer than the source's ``max_line`` in pieces of the same number), every character
accounted for: the lines that make up almost every dump, a header as socat writes it (its date and time
digits) and the line after it when that starts with a space (its hex row), as one match with their fields; any
other line as itself. The transfer builder (``_Transfers``: one chunk per transfer, handed on in bounded
pieces; ``length=`` beyond 16 MiB is damage) reads each by its kind (``read``): a header and its row
(``_header_match``; a row holding the transfer whole makes its chunk at once, held until the next line shows
that no more rows follow), a further hex row (``_further_row``), the ``--`` that ends a ``-x -v`` transfer
held whole. The counters are checked by writing the two numbers expected (``from=`` where the side's last
transfer ended, ``to=`` where ``length=`` ends) and comparing them with the text (read and checked in full,
``_counters``, when they differ); the time is computed as ``wallclock`` computes it (``_HeaderClock``: the
start of the header's second remembered, found from the minute's start when the second changes, plus the
fraction). A hex row's bytes come from ``bytes.fromhex`` checked against ``bytes.hex`` (lower case, single
spaces, as ``_HEX`` reads them), else from ``_HEX`` itself; short rows and lengths are remembered (a
conversation repeats itself). Every other line, any line while -v text is being read, and a header the match
does not take (another spelling, a date that is none) are queued for ``step``: each line classified
(``tokenize``: what a line is) and acted on by its kind's handler (``on_kind``), the same way whatever the
dump's style and state. -v text is decoded a run of characters at a time.

Host side default: ``>``; run ``socat -x -v <host's side> <device's side>``.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Generator, Iterator
from typing import Final

from xac1_proto.chunk import Chunk, Direction

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
_LONGEST_HEADER: Final = 110  # characters of the longest header line the block matcher takes (CR too)
_SECONDS: Final = {f"{ss:02d}": ss for ss in range(60)}  # a clean header's seconds
_POWERS: Final = tuple(10 ** n for n in range(13))
_DIAG: Final = re.compile(r"\d{4}/\d\d/\d\d \d\d:\d\d:\d\d socat\[\d+\] [DINWEF] ")
_HEX: Final = re.compile(r" ((?:[0-9a-f]{2} )*[0-9a-f]{2})(?: {2,}.*)?\s*")
_MAX_TRANSFER: Final = 1 << 24  # socat -b sets the transfer size (8192 by default); more is damage
_SPILL: Final = 1 << 16  # bytes of one transfer held before they are handed on
_ESCAPES: Final = {"r": 0x0D, "n": 0x0A, "\\": 0x5C, "a": 0x07, "b": 0x08, "v": 0x0B, "f": 0x0C,
                   "t": 0x09, "e": 0x1B}
_KNOWN: Final = 4096  # hex rows remembered (their text -> their bytes)
_KNOWN_TEXT: Final = 160  # characters of the longest row remembered
_TEXT_ROWS: Final = 256  # the longest transfer whose hex rows are kept in case they were -v text
_TEXT: Final = "text"  # a transfer's mode: -v text (None: not known yet; "hex": hex rows)
_HEXMODE: Final = "hex"
_Stepped = tuple[Chunk | None, str | None]  # what ``step`` makes of a line: a chunk, a rest to read

BLOCK: Final = 1 << 14  # characters read at once by default: a region, and the list findall makes of it,
# stay small


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


@functools.lru_cache(maxsize=8)
def _block_matcher(max_line: int, crlf: bool) -> re.Pattern[str]:
    """What ``findall`` cuts a region of whole lines into, each line accounted for (no character skipped):
    a header as socat writes it (a date and time of digits, ``[0-5]`` seconds, six or nine digits of
    fraction, two spaces; a CR after it when ``crlf``) with the line after it when that starts with a
    space (a hex row, its line end excluded); any other line (up to ``max_line`` characters with its line
    end); or ``max_line`` characters of a longer line (a piece). Groups: mark, ``YYYY/MM/DD HH:MM:SS``
    (one string: compared with the header before's), fraction (with its point), length, from, to, row;
    the other line; the piece (each group costs ``findall`` a string). The date's and time's digits are
    each written ``[0-9]``: cheaper to match than a repeat ``[0-9]{4}``, and than a Python call checking
    them a header (a header whose date is not all digits is another line, read by ``step``). A line
    limit shorter than a header turns the first kind off. (A CR that may end a line costs a tenth of the
    matching: a file whose first lines end with LF alone is matched without, and its rows up to the LF,
    ``[^\n]`` being counted much faster than ``[^\r\n]``; a line ending CR LF in it is then another
    line, read by ``step``, or a row whose CR ``read`` strips where it is not read as hex, as ``_HEX``
    reads it with the CR.)"""
    d = "[0-9]"
    header = (rf"([<>]) ({d}{d}{d}{d}/{d}{d}/{d}{d} {d}{d}:{d}{d}:[0-5]{d})(\.[0-9]{{6}}|\.[0-9]{{9}})  "
              rf"length=([0-9]{{1,18}}) from=([0-9]{{1,18}}) to=([0-9]{{1,18}})\r?\n"
              rf"(?:( [^\r\n]{{0,{max_line - 2}}})\r?\n)?")
    if not crlf:
        header = header.replace(r"\r?", "").replace(r"[^\r\n]", r"[^\n]")
    return re.compile(("" if max_line > _LONGEST_HEADER else "(?!)") + header
                      + rf"|([^\n]{{0,{max_line - 1}}})\n|([^\n]{{{max_line}}})")


def read(src: Source, host_is: str | None = None, *, block: int = BLOCK) -> Iterator[Chunk]:
    """The chunks of a socat dump, read ``block`` characters at a time (at least one): any block size gives
    the same chunks and problems."""
    if block < 1:
        raise ValueError(f"block must be at least 1 character, not {block}")
    return _Transfers(src, Sides(FORMAT, host_is, (">", "<"))).read(_Blocks(src, block))


class _Blocks:
    """The file read in blocks of ``block`` characters (latin-1), handed on as regions of whole lines
    (never the whole file): ``regions`` gives ``(text, start, end)``, ``text[start:end]`` ending with a
    line end, or made of ``max_line`` pieces of a line longer than that. What follows the last line end
    of the file is ``tail``, once the regions are all read."""

    def __init__(self, src: Source, block: int) -> None:
        self.src = src
        self.block = block
        self.tail = ""

    def regions(self) -> Iterator[tuple[str, int, int]]:
        read, max_line, block = self.src.read, self.src.max_line, self.block
        buf, pos = "", 0
        while True:
            cut = buf.rfind("\n", pos) + 1
            if cut <= pos:  # no whole line left: pieces of a long one, or another block
                if len(buf) - pos >= max_line:
                    cut = pos + (len(buf) - pos) // max_line * max_line
                elif data := read(block):
                    buf, pos = buf[pos:] + data.decode("latin-1"), 0
                    continue
                else:
                    self.tail = buf[pos:]
                    return
            yield buf, pos, cut
            pos = cut


class _Transfer:
    """The transfer being read: its header's line, direction, time and ``length=``, its bytes held (not
    handed on yet), how many were handed on, and its mode (None until its first data line)."""

    __slots__ = ("line", "dir", "t", "length", "data", "sent", "mode", "rows")

    def __init__(self, line: int, d: Direction, t: float | None, length: int) -> None:
        self.line = line
        self.dir = d
        self.t = t
        self.length = length
        self.data = bytearray()
        self.sent = 0
        self.mode: str | None = None
        self.rows: list[str] | None = None  # its hex rows' text, while they may be -v text instead

    def add_hex_row(self, text: str, data: bytes) -> None:
        """A hex row's bytes. Its text is kept while every line of the transfer has been one and the
        transfer is short: -v text may look like hex rows (`` 00`` is three bytes as text, one as hex),
        and ``length=`` decides at its end (``_text_reading``)."""
        if self.mode is None and self.length <= _TEXT_ROWS:
            self.rows = [text]
        elif self.rows is not None:
            self.rows.append(text)
        self.mode = _HEXMODE
        self.data += data

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


class _HeaderClock:
    """The times of a log's headers, as ``wallclock`` computes them: a header's whole second plus its
    fraction, the 9-digit quirk read (``_Clock``). The start of the last header's minute is remembered
    (seconds in a minute are linear: time zones change their offset on whole minutes), and of its
    second, so a header of the same second or minute costs one addition. A time that cannot be one is
    reported (``times``) and the last good time (``last``) kept; one that runs backwards is reported
    (``timeline``)."""

    __slots__ = ("where", "quirk", "times", "timeline", "last", "minute", "base", "second", "second_base")

    def __init__(self, src: Source) -> None:
        self.where = src.where
        self.quirk = _Clock()
        self.times = Clock(src.report)
        self.timeline = Timeline(src.report)
        self.last = -math.inf  # the last good time (-inf: none yet)
        self.minute = ""  # the last header's ``YYYY/MM/DD HH:MM`` (when all its seconds are in range)
        self.base = 0.0  # and the start of that minute
        self.second = ""  # the last header's ``YYYY/MM/DD HH:MM:SS`` that ``at`` read, and its start
        self.second_base = 0.0

    def at(self, number: int, second: str, frac: str) -> float | None:
        """The time of a header as socat writes it (``second`` as ``_block_matcher`` takes it, digits,
        ``frac`` with its point) on line ``number``."""
        if second != self.second:
            if second[:16] != self.minute:  # a new minute
                return self.time(number, second[:10], second[11:], frac[1:])
            self.second, self.second_base = second, self.base + _SECONDS[second[17:]]
        t = self.second_base + float(frac if len(frac) == 7 else "." + self.quirk.fraction(frac[1:]))
        if t + TOLERANCE_S < self.last:
            self._backwards(number, t)
        self.last = t
        return t

    def time(self, number: int, date: str, clock: str, frac: str | None) -> float | None:
        """The time of any header (``clock``: ``HH:MM:SS``): a time that cannot be one is reported and the
        previous one kept. The minute's start is remembered when all its seconds are in range."""
        frac = self.quirk.fraction(frac or "")
        ss = int(clock[6:])
        base = self.base if f"{date} {clock[:5]}" == self.minute and ss < 60 else \
            self._minute_start(number, date, clock, frac)
        previous = None if self.last == -math.inf else self.last
        if base is None:
            return previous
        digits = frac[:12]
        t = base + ss + (int(digits) / _POWERS[len(digits)] if digits else 0.0)
        if not MIN_TIME <= t < MAX_TIME:
            self.times.last = previous
            return self.times.check(t, self.where(number))  # said; the previous time
        if t + TOLERANCE_S < self.last:
            self._backwards(number, t)
        self.last = t
        return t

    def _backwards(self, number: int, t: float) -> None:
        """A time more than ``TOLERANCE_S`` before the last good one: reported by the timeline."""
        self.timeline.last = self.last
        self.timeline.check(t, self.where(number))

    def _minute_start(self, number: int, date: str, clock: str, frac: str) -> float | None:
        """The start of a header's minute, remembered when all its seconds are in range; None for a time
        that cannot be one (reported as ``wallclock`` says it of the whole time)."""
        try:
            if int(clock[6:]) >= 60:
                raise ValueError(clock)
            base = wallclock(date, f"{clock[:5]}:00")
        except ValueError:
            try:
                wallclock(date, f"{clock}.{frac}" if frac else clock)
            except ValueError as exc:
                self.times.report.problem(self.where(number), f"{exc}; the bytes are kept with the "
                                                              f"previous time")
            return None
        in_range = MIN_TIME <= base < MAX_TIME - 61
        self.minute, self.base = (f"{date} {clock[:5]}", base) if in_range else ("", 0.0)
        return base


class _Transfers:
    """The chunk builder: turns the file's lines into one chunk per transfer (long transfers in bounded
    pieces), checking ``length=``, the counters and the times. ``read`` takes the lines of a dump as socat
    writes it (a header and its hex row, further rows, the ``--`` after a transfer held whole); ``step``
    every other line, and every line while -v text is being read."""

    __slots__ = ("src", "report", "dirs", "clock", "cur", "held", "held_line", "number", "continued", "here",
                 "queued", "text_bytes", "text_ended", "hex_seen", "following", "known", "sizes", "on_kind")

    def __init__(self, src: Source, sides: Sides) -> None:
        self.src = src
        self.report = src.report
        self.dirs: dict[str, Direction] = {}
        for mark in (">", "<"):
            d = sides.direction(mark)
            assert d is not None
            self.dirs[mark] = d
        self.clock = _HeaderClock(src)
        self.cur: _Transfer | None = None  # the transfer being read
        # a whole transfer read from its header and hex row (no _Transfer made), handed on when the next
        # line shows that no more rows follow; its header's line
        self.held: Chunk | None = None
        self.held_line = 0
        self.number = 0  # the number of the last line read
        self.continued = False  # whether that line's last piece had no line end
        self.here = True  # lines are read by ``read`` (no piece of a long line, no -v text going on)
        self.queued: list[tuple[int, str]] = []  # lines (numbered) that ``read`` hands to ``step``
        self.text_bytes = 0
        self.text_ended = 0  # the last line on which -v text ended a transfer with the line itself
        self.hex_seen = False  # a transfer's hex rows held its length= bytes: the log dumps hex rows
        self.following: dict[str, int] = {}  # side name -> the from= its next transfer should have
        self.known: dict[str, bytes] = {}  # hex rows read (text -> bytes)
        self.sizes: dict[str, int] = {}  # length= read (text -> number)
        self.on_kind = {HEADER: self._on_header, END: self._on_end, DIAG: self._on_diag,
                        BLANK: self._on_blank, HEXROW: self._on_hex_row, OTHER: self._on_other}

    def read(self, blocks: _Blocks) -> Iterator[Chunk]:
        """Every line of the file, a region of whole lines at a time: ``findall`` cuts it into lines, a
        header and its hex row as one (``_block_matcher``), and each is read by its kind: a header, a
        further hex row, the ``--`` after a transfer held whole, anything else (for ``step``: see the
        module docstring); then the file's last line if it has no line end."""
        findall = _block_matcher(self.src.max_line, b"\r\n" in self.src.head()).findall  # (nothing read yet)
        header, further_row, for_step = self._header_match, self._further_row, self._line_for_step
        queued = self.queued
        chunk: Chunk | None
        for region in blocks.regions():
            for match in findall(*region):
                if match[0]:
                    if self.here:  # the transfer before ends (held whole, or finished)
                        chunk, self.held = self.held or self.finish(self.number + 1), None
                        if chunk is not None:
                            yield chunk  # (before anything of the header is said)
                        header(match)
                    else:
                        self._header_for_step(match)
                else:
                    line, piece = match[7], match[8]
                    if line[:1] == " " and self.here and (self.held or self.cur) is not None:
                        chunk = further_row(line.rstrip("\r"))
                    elif line[:2] == "--":
                        chunk = self._dashes(line, piece)
                    else:
                        chunk = for_step(line, piece)
                    if chunk is not None:
                        yield chunk
                if queued:
                    yield from self._step_queued()
        yield from self._last_line(blocks.tail)

    def _header_match(self, match: tuple[str, ...]) -> None:
        """A header as socat writes it, with its first hex row when one follows (the transfer before it
        has ended): this transfer begins; one whose row holds it whole is held (no ``_Transfer``)."""
        mark, second, frac, length_s, from_s, to_s, row, _, _ = match
        number = self.number + 1
        # the counters compared as text with the two numbers expected (``from=`` where the side's last
        # transfer ended, ``to=`` where ``length=`` ends), read and checked in full when they differ
        length = self.sizes.get(length_s)  # (a length remembered is at most 16 MiB)
        first = self.following.get(mark, -1)
        if length is not None and from_s == str(first) and to_s == str(first + length - 1):
            self.following[mark] = first + length
        else:
            length = self._counters(number, mark, self._size(length_s), int(from_s), int(to_s))
        t = self.clock.at(number, second, frac)
        d = self.dirs[mark]
        if not row:
            self.number, self.cur = number, _Transfer(number, d, t, length)
            return
        self.number = number + 1
        data = self.known.get(row) or self._hex_row(row)
        if data and len(data) == length:
            self.held, self.held_line, self.hex_seen = Chunk(t, d, data), number, True
            return
        cur = self.cur = _Transfer(number, d, t, length)
        if data:
            cur.add_hex_row(row.rstrip("\r"), data)
        else:
            self.queued.append((number + 1, row.rstrip("\r")))  # no hex row: step reads it

    def _dashes(self, line: str, piece: str) -> Chunk | None:
        """A line starting with ``--``: the end of a -x -v transfer held whole (as step's END would end
        it), else a line for ``step``."""
        if self.held is None or line.strip() != "--":
            self._line_for_step(line, piece)
            return None
        self.number += 1
        chunk, self.held = self.held, None
        return chunk

    def _header_for_step(self, match: tuple[str, ...]) -> None:
        """A header while -v text is read or a line's pieces go on: queued for ``step`` with its row (a
        header whose date is not all digits is no header to ``_block_matcher``: another line for ``step``)."""
        mark, second, frac, length_s, from_s, to_s, row, _, _ = match
        self._line_for_step(f"{mark} {second}{frac}  length={length_s} from={from_s} to={to_s}", "")
        if row:
            self.number += 1
            self.queued.append((self.number, row.rstrip("\r")))

    def _further_row(self, text: str) -> Chunk | None:
        """A line starting with a space while a transfer is read: a further hex row of it (a long
        transfer's bytes handed on in pieces), else a line for ``step``."""
        self.number += 1
        if self.held is not None:
            self._hold()
        cur = self.cur
        assert cur is not None
        data = self.known.get(text) or self._hex_row(text)
        if not data:
            self.queued.append((self.number, text))
            return None
        cur.add_hex_row(text, data)
        return cur.spill() if len(cur.data) >= _SPILL else None

    def _line_for_step(self, line: str, piece: str) -> None:
        """Any other line, or a piece of a line longer than ``max_line`` (numbered as the piece before it
        when that went on; then the file so far ends inside it: ``unterminated``): queued for ``step``."""
        if not self.continued:
            self.number += 1
        self.continued = piece != ""
        self.src.unterminated = self.number if self.continued else None
        if self.held is not None:
            self._hold()
        self.queued.append((self.number, piece.rstrip("\r") if piece else line.rstrip("\r")))

    def _step_queued(self) -> Iterator[Chunk]:
        """The lines queued, read by ``step``; then whether ``read`` reads the next lines itself."""
        step = self.step
        for number, text in self.queued:
            rest: str | None = text
            while rest is not None:
                rest = yield from step(number, rest)
        self.queued.clear()
        cur = self.cur
        self.here = not self.continued and (cur is None or cur.mode is not _TEXT)

    def _last_line(self, tail: str) -> Iterator[Chunk]:
        """The file's end: the transfer held handed to ``step``'s state, the last line read when it has no
        line end, then the transfer being read ends."""
        if self.held is not None:
            self._hold()
        if tail:
            if not self.continued:
                self.number += 1
            self.src.unterminated = self.number
            rest: str | None = tail.rstrip("\r")
            while rest is not None:
                rest = yield from self.step(self.number, rest)
        yield from self.end(self.number)

    def _hold(self) -> None:
        """The whole transfer held becomes the transfer being read (a line after its row came)."""
        held = self.held
        assert held is not None
        self.held = None
        cur = self.cur = _Transfer(self.held_line, held.dir, held.t, len(held.data))
        cur.mode = _HEXMODE
        cur.data += held.data

    def _size(self, text: str) -> int:
        """``length=``'s number (remembered when it is plausible, at most 16 MiB: a conversation's transfers
        have few lengths)."""
        size = int(text)
        if size <= _MAX_TRANSFER:
            if len(self.sizes) >= _KNOWN:
                self.sizes.clear()
            self.sizes[text] = size
        return size

    def _counters(self, number: int, mark: str, length: int, start: int, end: int) -> int:
        """A header's counters and length checked (by ``_header``, or by ``_header_match`` when it found them
        other than it expected: the first transfer of a side, a restart, a leading zero, damage); the length
        read."""
        following = self.following
        if end - start + 1 != length or length > _MAX_TRANSFER or \
                mark in following and start != following[mark] and start != 0:
            return self._damaged_header(number, mark, length, start, end)
        following[mark] = start + length
        return length

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
            data = bytes.fromhex(text)  # (its leading space skipped as any space between bytes)
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
        self._rows_as_text(rec, whole=True)
        got = rec.sent + len(rec.data)
        if got == rec.length and rec.mode is _HEXMODE:
            self.hex_seen = True
        if got != rec.length:
            self.report.problem(self.src.where(rec.line),
                                f"transfer says length={rec.length} but its dump holds {got} "
                                f"byte(s) (cut short before line {line})",
                                nbytes=max(0, rec.length - got))
        return Chunk(rec.t, rec.dir, bytes(rec.data)) if rec.data else None

    def step(self, number: int, text: str) -> Generator[Chunk, None, str | None]:
        """Read one line or the rest of one by its kind (``tokenize``; -v text while a transfer of it
        wants bytes); returns (as the generator's value) a rest still to read."""
        cur = self.cur
        if cur is not None and cur.mode == _TEXT and cur.got < cur.length and \
                not (cur.got == 0 and _HEADER.match(text)):  # else an empty-looking transfer
            return (yield from self._text(number, text))
        kind, m = tokenize(text)
        chunk, rest = self.on_kind[kind](number, text, m)
        if chunk is not None:
            yield chunk
        return rest

    # what ``step`` does with each kind of line: (a chunk to hand on or None, a rest of the line to read)

    def _on_header(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """A transfer header: the transfer being read ends (handed on, and the header read again: nothing
        of it is said before), else this one begins."""
        if self.cur is not None:
            return self.finish(number), text
        m = _HEADER_LINE.match(text)
        assert m is not None
        self._header(number, m)
        return None, None

    def _on_end(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """The ``--`` after a -x -v transfer: it ends."""
        return self.finish(number), None

    def _on_diag(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """A socat diagnostic: the transfer being read ends, unless it is -v text (whose ``length=`` says
        where it ends)."""
        cur = self.cur
        return (self.finish(number) if cur is None or cur.mode != _TEXT else None), None

    def _on_blank(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """A blank line: -v text of the transfer being read when it can be (its line end a byte), else
        nothing."""
        cur = self.cur
        if cur is not None and (cur.mode is None or self._rows_as_text(cur, whole=False)):
            cur.mode = _TEXT
            return None, text
        return None, None

    def _on_hex_row(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """A row of hex bytes: the transfer's bytes when it is read as hex rows (a long one's handed on in
        pieces), else as any other line."""
        cur = self.cur
        if cur is None or cur.mode == _TEXT:
            return self._on_other(number, text, m)
        assert m is not None
        cur.add_hex_row(text, bytes.fromhex(m.group(1)))
        return cur.spill(), None

    def _on_other(self, number: int, text: str, m: re.Match[str] | None) -> _Stepped:
        """Any other line: -v text of the transfer being read when it can be, else reported."""
        cur = self.cur
        if cur is None:
            self.report.problem(self.src.where(number), f"not a socat header, data or log line: "
                                                        f"{shown(text)}", nlines=1)
        elif cur.mode is None or self._rows_as_text(cur, whole=False):
            cur.mode = _TEXT
            return None, text
        else:
            cur.rows = None  # (rows followed by a line that is neither a row nor their text: damage)
            self.report.problem(self.src.where(number), f"cannot read this dump line: {shown(text)}",
                                nlines=1)
        return None, None

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
        if cut == len(text):
            self.text_ended = number
        return text[cut:] or None

    def _rows_as_text(self, cur: _Transfer, whole: bool) -> bool:
        """Hex rows too short for ``length=`` that read as -v text fitting it (``whole``: exactly, the
        transfer has ended; else with bytes still to come, a line that is no hex row follows), in a log
        that has not shown a transfer of hex rows yet (socat dumps a run in one style): they were text,
        and the transfer is text from now on (True)."""
        if cur.rows is None or cur.mode is not _HEXMODE or cur.got >= cur.length or self.hex_seen:
            return False  # (in a log of hex rows a short one is damage: a row cut short)
        text = _text_reading(cur.rows, cur.length, whole)
        if text is None:
            return False
        self.text_bytes += len(text)
        cur.data[:], cur.rows, cur.mode = text, None, _TEXT
        return True

    def _header(self, number: int, m: re.Match[str]) -> None:
        """A transfer's header: its counters, length and time checked; it becomes the transfer read."""
        mark, date, clock, frac, length_s, start_s, end_s, tail = m.groups()
        length = self._counters(number, mark, int(length_s), int(start_s), int(end_s))
        t = None if date is None else self.clock.time(number, date, clock, frac)
        self.cur = _Transfer(number, self.dirs[mark], t, length)
        if tail and not tail.isspace():
            self.report.problem(self.src.where(number), f"unexpected text after the header: "
                                                        f"{shown(tail.strip())}")

    def end(self, number: int) -> Iterator[Chunk]:
        """The file's end: the transfer being read ends (-v text that ``length=`` says is whole need not
        end with a line end); a -v dump's loss noted."""
        cur = self.cur
        if cur is not None:
            self._rows_as_text(cur, whole=True)  # rows that are the text length= says is whole
        if self.text_ended == number or cur is not None and cur.mode == _TEXT and cur.got == cur.length:
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


def _text_reading(rows: list[str], length: int, whole: bool) -> bytearray | None:
    """Whole dump lines read as -v text (each line end an LF byte while bytes are missing, as ``_text``
    reads them), when that reading fits ``length=``: exactly (``whole``: the transfer ended), or with
    bytes still to come (another line of it follows). None when it does not fit."""
    probe = _Transfer(0, "host", None, length)
    for k, row in enumerate(rows):
        _, used = _take_text(row, probe)
        if used != len(row):
            return None
        if probe.got < length:
            probe.data.append(0x0A)  # the line end was an LF byte
        if probe.got == length:
            return probe.data if whole and k == len(rows) - 1 else None
    return None if whole else probe.data


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
