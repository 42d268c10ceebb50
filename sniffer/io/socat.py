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

Speed: the file is read in blocks of ``BLOCK`` characters (``_Lines``: never the whole file), cut into
the very lines ``Source.lines`` gives. At the start of a line, when no transfer or a hex one is being
read, a fast path (``_Transfers.run``) reads whole clean transfers, one match of one regular expression
each (``_FAST``, ``_FAST_CRLF``: a header with a time, then one -x hex line or the -x -v rows and
``--``), doing what ``step`` would do with their lines: the body's bytes by ``bytes.fromhex`` checked
against ``bytes.hex`` (lower case, single spaces: what ``_HEX`` reads), -x -v rows by ``_HEX`` itself,
short bodies remembered (a conversation repeats itself); the time as the last header's whole second
(``wallclock``) plus the fraction, computed as ``wallclock`` computes it, the 9-digit quirk included;
the counters. It stops, before changing anything, at the first transfer that is not plainly clean (a
count other than ``length=``, counters that do not go on, a time that is not a socat one, impossible
or near the end of the range, a line longer than ``MAX_LINE``, a transfer a block end cuts: it reads
ahead and goes on) and the line-by-line code reads that line, so chunks, times (bit for bit), messages
and line numbers are the same. A fast run that reads nothing makes the next wait (-v dumps). -v text is
decoded a run of characters at a time.

Host side default: ``>``; run ``socat -x -v <host's side> <device's side>``.
"""

from __future__ import annotations

import re
from collections.abc import Generator, Iterator
from typing import Final

from xac1_proto.chunk import Chunk, Direction

from . import base as _base
from .base import MAX_TIME, MIN_TIME, Clock, Report, Sides, Source, shown, wallclock

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

BLOCK = 1 << 16  # characters read at once (a test makes it tiny so that block ends fall everywhere)
_FAST_MAX: Final = 4096  # longest transfer the fast path reads (its -x hex line is shorter than MAX_LINE)
# A clean transfer at the start of a line: a header with a time and fraction, then its body (group 7):
# either one -x hex line, then a line that is no -x -v row nor ``--`` (group 8 None; a block end is no
# line: read on), or -x -v rows and the ``--`` that ends them (group 8); LF or CRLF line ends (a
# regular expression each: ``\r?`` costs). The time (group 2) is checked by _STAMP when it changes,
# the body by the caller.
_FAST_HEADER: Final = (r"([<>]) (.{19})\.([0-9]{1,12})  length=([0-9]{1,18}) from=([0-9]{1,18}) "
                       r"to=([0-9]{1,18})")
_FAST: Final = re.compile(_FAST_HEADER + r"\n( [^\n]*\n(?=[^ -])|(?: [^\n]*\n)+(--\n))")
_FAST_CRLF: Final = re.compile(_FAST_HEADER + r"\r\n( [^\n]*\n(?=[^ -])|(?: [^\n]*\n)+(--\r\n))")
_STAMP: Final = re.compile(r"[0-9]{4}/[0-9]{2}/[0-9]{2} [0-9]{2}:[0-9]{2}:[0-9]{2}")
_POWERS: Final = tuple(10 ** n for n in range(13))
# after this many fast runs in a row read nothing (a -v dump, damage), the next waits 2, 4... lines
_FAST_TRIES: Final = 16
_FAST_WAIT: Final = 10  # at most 2 ** this many lines
# what a fast run did: read nothing; read transfers up to one it leaves to ``step``; read all it matched
_READ_NONE: Final = 0
_READ_SOME: Final = 1
_READ_ALL: Final = 2
_KNOWN: Final = 4096  # transfer bodies remembered (their text -> their bytes)
_KNOWN_TEXT: Final = 160  # characters of the longest body remembered


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
    lines = _Lines(src)
    misses = wait = 0  # fast runs in a row that read nothing; lines to read before trying again
    while True:
        if wait:
            wait -= 1
        elif not lines.continued and builder.ready():
            ran = yield from builder.run(lines)
            if ran == _READ_NONE:
                misses += 1
                wait = 1 << min(misses - _FAST_TRIES, _FAST_WAIT) if misses > _FAST_TRIES else 0
            else:
                misses = 0
                if ran == _READ_ALL:
                    continue  # on from where it stopped, after reading ahead if it was the block end
        piece = lines.next()
        if piece is None:
            break
        number, text = piece
        rest: str | None = text
        while rest is not None:
            rest = yield from builder.step(number, rest)
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
        # the fast path's memory: the last whole second (header text, wallclock), the transfer bodies
        # read (text -> bytes), the length= of each byte count up to the longest read, each side's
        # direction
        self.stamp, self.base = "", 0.0
        self.known: dict[str, bytes] = {}
        self.decimal = [""]  # no length= says 0: an empty body is never read
        self.dirs: dict[str, Direction] = {}

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

    def ready(self) -> bool:
        """Whether the fast path may read on: no transfer is being read, or a hex one (a header then
        ends it; never -v text, which could hold a header line)."""
        cur = self.cur
        return cur is None or cur["mode"] == "hex"

    def run(self, lines: _Lines) -> Generator[Chunk, None, int]:
        """The fast path: read the clean transfers that start at ``lines.pos`` (matched by ``_FAST`` or
        ``_FAST_CRLF``) as ``step`` would read their lines; stop before the first that is not plainly
        clean, or where none matches. Returns what it did (``_READ_*``). A -x transfer's chunk is held
        until the next header (more hex rows could follow); when the run stops, it becomes ``cur``."""
        lines.ahead()
        m = _FAST.match(lines.buf, lines.pos) or _FAST_CRLF.match(lines.buf, lines.pos)
        if m is None or lines.max_line < 256:  # < 256: headers come in pieces
            return _READ_NONE
        new = Chunk
        buf, pos, match = lines.buf, lines.pos, m.re.match
        fast_max = min(_FAST_MAX, (lines.max_line - 3) // 3)
        following, known, decimal = self.following, self.known, self.decimal
        dirs = self.dirs or self._directions()
        nanoseconds, stamp0, base0, powers = self.clock.nanoseconds, self.stamp, self.base, _POWERS
        last: Chunk | None = None  # the last transfer read
        held = False  # it is a -x transfer, not handed on yet
        cur_open = self.cur is not None
        found: re.Match[str] | None = m
        while found is not None:
            mark, stamp, frac, length_s, start_s, end_s, body, rows = found.groups()
            data = known.get(body) or self._body(body, rows is not None, fast_max, lines.max_line)
            length, start = len(data), int(start_s)
            if decimal[length] != length_s or int(end_s) - start + 1 != length or \
                    start != following.get(mark, start) and start:
                break  # not hex as socat writes it, a count other than length=, counters that do not go on
            if stamp != stamp0:
                second = _second(stamp)
                if second is None:
                    break
                stamp0, base0 = stamp, second
            digits = len(frac)
            if digits == 9 and not nanoseconds:
                if frac.startswith("000"):
                    frac, digits = frac[3:], 6
                else:
                    nanoseconds = True  # no check follows: the transfer is read
            # clean: read as step would read it
            following[mark] = start + length
            if held:
                yield last  # type: ignore[misc]
            elif cur_open:
                cur_open = False
                yield from self.finish(lines.number + 1)
            last = new(base0 + int(frac) / powers[digits], dirs[mark], data)
            if rows is None:
                held = True
            else:  # -x -v: ``--`` ended it
                held = False
                yield last
            found = match(buf, pos := found.end())
        self.clock.nanoseconds, self.stamp, self.base = nanoseconds, stamp0, base0
        if last is None:
            return _READ_NONE
        self._stop(lines, pos, last, held)
        return _READ_ALL if found is None else _READ_SOME

    def _stop(self, lines: _Lines, pos: int, last: Chunk, held: bool) -> None:
        """The end of a fast run that read transfers: lines read, the last time, a held -x transfer
        made ``cur``."""
        lines.number += lines.buf.count("\n", lines.pos, pos)
        lines.pos = pos
        self.times.last = last.t
        if held:
            self.cur = {"line": lines.number - 1, "dir": last.dir, "t": last.t, "length": len(last.data),
                        "data": bytearray(last.data), "sent": 0, "mode": "hex"}

    def _directions(self) -> dict[str, Direction]:
        if not self.dirs:
            for mark in (">", "<"):
                d = self.sides.direction(mark)
                assert d is not None
                self.dirs[mark] = d
        return self.dirs

    def _body(self, body: str, rows: bool, fast_max: int, max_line: int) -> bytes:
        """The bytes of a transfer's body (the -x hex line or the -x -v rows, line ends included) if it
        is exactly what ``step`` reads as that many bytes (at most ``fast_max``), else empty; short
        bodies are remembered."""
        data = _rows(body, max_line) if rows else _hex_line(body, fast_max)
        if len(data) > fast_max:
            return b""
        decimal = self.decimal
        decimal.extend(str(n) for n in range(len(decimal), len(data) + 1))
        if len(body) <= _KNOWN_TEXT:
            if len(self.known) >= _KNOWN:
                self.known.clear()
            self.known[body] = data
        return data

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


def _hex_line(line: str, fast_max: int) -> bytes:
    """The bytes of a -x hex line (its first space and line end included) if it is what ``_HEX`` reads
    (lower case, single spaces; ``bytes.hex`` writes it back the same) and short enough for one piece
    of ``MAX_LINE``, else empty."""
    if len(line) > 3 * fast_max + 2:
        return b""
    text = line[1:].rstrip("\r\n")
    try:
        data = bytes.fromhex(text)
    except ValueError:
        return b""
    return data if data.hex(" ") == text else b""


def _rows(rows: str, max_line: int) -> bytes:
    """The bytes of -x -v hex rows (each ending with a line end, then the ``--`` line) as ``step`` reads
    them with ``_HEX``; empty when a row is not a hex row or they are longer than ``max_line`` (pieces)."""
    parts = []
    if len(rows) > max_line:
        return b""
    for row in rows.split("\n")[:-2]:
        hm = _HEX.fullmatch(row.rstrip("\r"))
        if hm is None:
            return b""
        parts.append(hm.group(1))
    return bytes.fromhex(" ".join(parts))


def _second(stamp: str) -> float | None:
    """Unix seconds of a header's whole second (``YYYY/MM/DD HH:MM:SS``) as ``wallclock`` gives them,
    or None when it is not plainly good: not that layout, impossible, or near the end of the range
    ``Clock`` accepts (any fraction added keeps a time of a good second in range)."""
    if _STAMP.fullmatch(stamp) is None:
        return None
    try:
        base = wallclock(stamp[:10], stamp[11:])
    except ValueError:
        return None
    return base if MIN_TIME <= base < MAX_TIME - 1 else None


def _take_text(text: str, rec: dict) -> tuple[int, int]:
    """Decode -v text into ``rec['data']`` until its length is reached; returns (bytes, chars used).
    A run of characters without a backslash is copied at once (each character is its latin-1 byte)."""
    data: bytearray = rec["data"]
    start, need = len(data), rec["length"] - rec["sent"] - len(data)
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
