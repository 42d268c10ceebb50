"""The socat reader's fast path changes nothing: every dump gives the very chunks (``t`` bit for bit) and
the very report, with problems in the same order, at the same line, between the same chunks, as the
line-by-line reader it speeds up, kept here as a small reference: ``_reference_read`` (the ``read`` of
``sniffer/io/socat.py`` before the fast path: ``Source.lines`` through the same ``step``) and
``_reference_take_text`` (-v text decoded a character at a time, before runs were copied at once).

Dumps are generated as socat writes them (``_dump``): ``-x``, ``-x -v`` and ``-v`` transfers of any bytes
on both sides, styles mixed, 6-digit fractions, socat 1.7's 9-digit quirk and real nanoseconds, socat
restarting at ``from=0``, diagnostics between transfers, counters that slip; then damaged (``_damage``):
lines deleted, duplicated, joined, truncated at any character, characters overwritten or inserted, CRLF
line ends, no final newline, the file cut anywhere. Each is read with block sizes from one character to
the default (``socat.BLOCK``) so that block ends fall everywhere, with ``MAX_LINE`` small enough to cut
lines into pieces, with ``--host-is``, and giving up after a few problems as ``xac1 decode`` does.
Equal outputs alone would also come from a fast path that never runs, so tests show it reads clean
dumps by itself, keeps its memory bounded and builds chunks equal to ``Chunk(...)``.
"""

from __future__ import annotations

import dataclasses
import random
import struct
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sniffer.io import base as base_mod
from sniffer.io import socat as socat_mod
from sniffer.io.base import Report, Sides, Source, WrongFormat
from xac1_proto.chunk import Chunk

# ---------------------------------------------------------------- the reference (the code it replaced) ----


def _reference_read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    builder = socat_mod._Transfers(src, Sides(socat_mod.FORMAT, host_is, (">", "<")))
    number = 0
    for number, line in src.lines():
        rest: str | None = line
        while rest is not None:
            rest = yield from builder.step(number, rest)
    yield from builder.end(number)


def _reference_take_text(text: str, rec: dict) -> tuple[int, int]:
    data: bytearray = rec["data"]
    i = 0
    start = len(data)
    while i < len(text) and rec["sent"] + len(data) < rec["length"]:
        c = text[i]
        if c == "\\" and i + 1 < len(text) and text[i + 1] in socat_mod._ESCAPES:
            data.append(socat_mod._ESCAPES[text[i + 1]])
            i += 2
            continue
        data.append(ord(c) & 0xFF)
        i += 1
    return len(data) - start, i


def reference(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    """The reader as it was: the reference read, with the reference -v text decoder."""
    with mock.patch.object(socat_mod, "_take_text", _reference_take_text):
        yield from _reference_read(src, host_is)


# ---------------------------------------------------------------- dumps as socat writes them ----

Transfer = tuple[str, bytes, str]  # side (">"/"<"), bytes, style ("x", "xv", "v")
_V_ESCAPES = {0x0D: "\\r", 0x5C: "\\\\", 0x07: "\\a", 0x08: "\\b", 0x0B: "\\v", 0x0C: "\\f", 0x0A: "\n"}
DATES = ["2024/05/01", "2026/11/22", "1970/01/01", "2106/02/07", "2024/02/30", "2038/01/19", "1969/12/31"]
FRACTIONS = ["6", "9-quirk", "9-nano", "3", "12"]
FRAMES = [b"0RV\r\n", b"0RV100\r\n", b"0RP3\r\n", b"0RP39302012345\r\n", b"0%%01\r\n", b"0WP19302012345\r\n",
          # bytes whose -v text holds clean -x and -x -v transfers (header lines inside a transfer)
          b"a\n> 2024/05/01 10:00:00.000001  length=1 from=0 to=0\n 30\n",
          b"\n< 2024/05/01 10:00:00.000001  length=1 from=0 to=0\n 30  0\n--\n> 2024/05/01 10:00:00.0  len"]


def _hex_rows(data: bytes) -> list[str]:
    """socat -x -v: rows of up to 16 bytes, a row ends after an LF; hex padded, then the ASCII column."""
    rows, row = [], bytearray()
    for b in data:
        row.append(b)
        if b == 0x0A or len(row) == 16:
            rows.append(bytes(row))
            row.clear()
    if row:
        rows.append(bytes(row))
    return ["".join(f" {b:02x}" for b in r) + "   " * (16 - len(r)) + "  "
            + "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in r) + "\n" for r in rows]


def _v_text(data: bytes) -> str:
    """socat -v: printable bytes as themselves, a few escapes, LF as a line end, the rest as ``.``."""
    return "".join(_V_ESCAPES.get(b) or (chr(b) if 0x20 <= b < 0x7F else ".") for b in data)


def _fraction(kind: str, micro: int, nano: int) -> str:
    return {"6": f"{micro:06d}", "9-quirk": f"000{micro:06d}", "9-nano": f"{nano:09d}",
            "3": f"{micro // 1000:03d}", "12": f"{micro:06d}{nano % 1000000:06d}"}[kind]


@st.composite
def _dump(draw: st.DrawFn) -> str:
    """A socat log (text, latin-1) of generated transfers, diagnostics, restarts and counter slips."""
    style = draw(st.sampled_from(["x", "xv", "v", "mixed"]))
    fractions = draw(st.sampled_from([["6"], ["9-quirk"], ["9-quirk", "9-nano"], FRACTIONS]))
    date = draw(st.sampled_from(DATES))
    second = draw(st.sampled_from([0, 3599, 36000, 86399]))
    count = {">": 0, "<": 0}
    out: list[str] = []
    for _ in range(draw(st.integers(0, 14))):
        side = draw(st.sampled_from("><"))
        data = draw(st.one_of(st.sampled_from(FRAMES), st.binary(min_size=1, max_size=20),
                              st.binary(min_size=21, max_size=70), st.binary(min_size=71, max_size=150)))
        kind = style if style != "mixed" else draw(st.sampled_from(["x", "xv", "v"]))
        event = draw(st.sampled_from(["", "", "", "", "", "diag", "restart", "gap", "back", "bad-to",
                                      "bad-length"]))
        if event == "restart":
            count = {">": 0, "<": 0}
        if event == "diag":
            level = draw(st.sampled_from("DINWEF"))
            what = draw(st.sampled_from(["starting", "exiting", "read(5, ...): Input/output error"]))
            out.append(f"{date} 10:00:0{len(out) % 10} socat[{len(out)}] {level} {what}\n")
        second += draw(st.sampled_from([0, 0, 0, 1, 2, 3600]))
        start = count[side] + (3 if event == "gap" else -2 if event == "back" and count[side] >= 2 else 0)
        count[side] = start + len(data)
        end = count[side] - 1 + (1 if event == "bad-to" else 0)
        fraction = _fraction(draw(st.sampled_from(fractions)), draw(st.integers(0, 999999)),
                             draw(st.integers(0, 999999999)))
        stamp = f"{date} {second // 3600 % 24:02d}:{second // 60 % 60:02d}:{second % 60:02d}.{fraction}"
        length = len(data) + (draw(st.sampled_from([-1, 1])) if event == "bad-length" else 0)
        out.append(f"{side} {stamp}  length={length} from={start} to={end}\n")
        if kind == "x":
            out.append(" " + data.hex(" ") + "\n")
        elif kind == "xv":
            out.extend(_hex_rows(data))
            out.append("--\n")
        else:
            out.append(_v_text(data))
            if draw(st.booleans()) and not data.endswith(b"\n"):
                out.append("\n")
    return "".join(out)


_SNIPPETS = ["\n", "\r", " ", "--\n", "\n\n", "\r\n", "> ", "< ", "0", "9", "\\", ".", "a", "\x85", "\xff",
             " 30 52 56 0d 0a\n", "> 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n",
             "2024/05/01 10:00:00 socat[1] E oops\n", "length=", " from=0", "\t"]


@st.composite
def _damage(draw: st.DrawFn, text: str) -> str:
    """The dump damaged a few times over: line and character edits, line ends, a cut."""
    for _ in range(draw(st.integers(0, 4))):
        lines = [line + "\n" for line in text.split("\n")]  # as the readers cut them, LF ends kept
        lines[-1] = lines[-1][:-1]
        lines = [line for line in lines if line]
        at = draw(st.integers(0, 10 ** 6))
        how = draw(st.sampled_from(["delete", "duplicate", "join", "truncate", "overwrite", "insert",
                                    "crlf", "crlf-one", "cut", "header"]))
        if not lines:
            text = draw(st.sampled_from(_SNIPPETS))
        elif how == "delete":
            del lines[at % len(lines)]
            text = "".join(lines)
        elif how == "duplicate":
            lines.insert(at % len(lines), lines[at % len(lines)])
            text = "".join(lines)
        elif how == "join":
            i = at % len(lines)
            lines[i] = lines[i].rstrip("\n")
            text = "".join(lines)
        elif how == "truncate":
            i = at % len(lines)
            keep = draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:keep] + ("\n" if lines[i].endswith("\n") and draw(st.booleans()) else "")
            text = "".join(lines)
        elif how == "overwrite":
            i = at % len(text)
            char = draw(st.one_of(st.sampled_from("0123456789 \n\r><-x.:/=f"),
                                  st.characters(max_codepoint=255)))
            text = text[:i] + char + text[i + 1:]
        elif how == "insert":
            i = at % (len(text) + 1)
            text = text[:i] + draw(st.sampled_from(_SNIPPETS)) + text[i:]
        elif how == "header":  # a character of a header overwritten (time, counters)
            headers = [i for i, line in enumerate(lines) if line[:2] in ("> ", "< ")] or [at % len(lines)]
            i = headers[at % len(headers)]
            k = draw(st.integers(0, 30) | st.integers(0, len(lines[i])))  # the time, or anywhere
            lines[i] = lines[i][:k] + draw(st.sampled_from("0123456789/-: .=x\t")) + lines[i][k + 1:]
            text = "".join(lines)
        elif how == "crlf":
            text = text.replace("\n", "\r\n")
        elif how == "crlf-one":
            i = at % len(lines)
            lines[i] = lines[i].replace("\n", "\r\n")
            text = "".join(lines)
        else:
            text = text[:at % (len(text) + 1)]
    return text


# ---------------------------------------------------------------- reading and comparing ----

BLOCKS = [1, 2, 3, 5, 7, 16, 61, 64, 97, 128, 200, 333, 1000, 4096, socat_mod.BLOCK]
_TMP = tempfile.TemporaryDirectory(prefix="xac1-socatfast-")


def _bits(t: float | None) -> str | None:
    return None if t is None else struct.pack("<d", t).hex()


def observe(reader: Callable[..., Iterator[Chunk]], path: Path, *, host_is: str | None = None,
            give_up: int | None = None) -> tuple[list[Any], tuple[Any, ...], dict[str, Any]]:
    """What a consumer sees of a reader: each chunk (time as bits) with the report's counts when it came,
    how reading ended (the last line's state, bytes read, or giving up), and the whole report. The
    consumer clears ``give_up_after`` at the first chunk, as ``xac1 decode`` does."""
    report = Report(give_up_after=give_up)
    events: list[Any] = []
    with Source(path, report) as src:
        try:
            for c in reader(src, host_is):
                events.append((_bits(c.t), c.dir, c.data, c.error, type(c), report.total_problems,
                               report.unread_bytes, report.unread_lines))
                report.give_up_after = None
            end: tuple[Any, ...] = ("end", src.unterminated, src.pos)
            src.check_end()
        except WrongFormat as exc:
            end = ("gave up", str(exc))
    return events, end, dataclasses.asdict(report)


def assert_same(text: str, block: int, *, max_line: int | None = None, host_is: str | None = None,
                give_up: int | None = None) -> list[Any]:
    """The fast reader with this block size (and ``MAX_LINE``) sees exactly what the reference sees;
    returns what it saw (the chunks)."""
    path = Path(_TMP.name) / "dump.log"
    path.write_bytes(text.encode("latin-1"))
    with mock.patch.object(base_mod, "MAX_LINE", max_line or base_mod.MAX_LINE):
        expected = observe(reference, path, host_is=host_is, give_up=give_up)
        with mock.patch.object(socat_mod, "BLOCK", block):
            got = observe(socat_mod.read, path, host_is=host_is, give_up=give_up)
    assert got == expected
    return got[0]


# the hardest cases found while writing the fast path
HARD = [
    # a -x transfer whose hex line is followed by a second hex row: one transfer of both rows
    "> 2024/05/01 10:00:00.000001  length=4 from=0 to=3\n 30 31\n 32 33\n",
    # -x -v without its "--" at the end of the file, and with a diagnostic before it
    "> 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n 30 31" + " " * 45 + "01\n",
    "< 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n 30 31  01\n2024/05/01 10:00:00 socat[1] E x\n--\n",
    # a -x transfer whole on its first hex line, then more rows: too many bytes, said at its header's line
    "> 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n 30 31\n 32\n",
    # upper-case hex, a double space, a trailing space, after a clean transfer
    "> 2024/05/01 10:00:00.000001  length=1 from=0 to=0\n 30\n> 2024/05/01 10:00:00.000001  length=2 "
    "from=1 to=2\n 0D 0a\n> 2024/05/01 10:00:00.000001  length=2 from=3 to=4\n 0d  0a\n"
    "> 2024/05/01 10:00:00.000001  length=1 from=5 to=5\n 0d \n",
    # -x -v rows holding fewer or more bytes than length=
    "> 2024/05/01 10:00:00.000001  length=3 from=0 to=2\n 30 31  01\n--\n"
    "> 2024/05/01 10:00:00.000001  length=1 from=3 to=3\n 30 31  01\n--\n",
    # a -v transfer whose text holds a clean -x transfer
    "> 2024/05/01 10:00:00.000001  length=60 from=0 to=59\nab\n< 2024/05/01 10:00:00.000001  length=1 "
    "from=0 to=0\n 30\n",
    # the 9-digit quirk switching to nanoseconds mid-file, then 000-fractions read as nanoseconds
    "> 2024/05/01 10:00:00.000123456  length=1 from=0 to=0\n 30\n< 2024/05/01 10:00:00.123456789  length=1 "
    "from=0 to=0\n 31\n> 2024/05/01 10:00:01.000123456  length=1 from=1 to=1\n 32\n",
    # an impossible date, a time out of range, and a -v transfer right after a -x one
    "> 2024/02/30 10:00:00.000001  length=1 from=0 to=0\n 30\n> 2106/02/07 06:28:15.999999  length=1 "
    "from=1 to=1\n 30\n< 2024/05/01 10:00:00.5  length=3 from=0 to=2\nab\\r",
    # CRLF, and a header glued to -v text
    "> 2024/05/01 10:00:00.000001  length=1 from=0 to=0\r\n 30\r\n< 2024/05/01 10:00:00.000001  length=1 "
    "from=0 to=0\nx> 2024/05/01 10:00:01.000001  length=1 from=1 to=1\n 31",
    # length= other than the bytes, counters agreeing with the bytes; a leading zero
    "> 2024/05/01 10:00:00.000001  length=3 from=0 to=1\n 30 31\n< 2024/05/01 10:00:00.000001  length=02 "
    "from=0 to=1\n 30 31\n> 2024/05/01 10:00:00.000001  length=1 from=2 to=2\n 30\n",
    # times that wallclock reads but that are no socat header: dashes, a tab, one-digit fields
    "> 2024-05-01 10:00:00.000001  length=1 from=0 to=0\n 30\n> 2024/05/01\t10:00:00.000001  length=1 "
    "from=1 to=1\n 30\n> 2024/5/01 10:00:00.0000001  length=1 from=2 to=2\n 30\n< 2024/05/01 10:00:00.1  "
    "length=1 from=0 to=0\n 30\n",
    # a -x -v row longer than MAX_LINE when that is 257 (its ASCII column in pieces)
    "> 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n 30 31  " + "x" * 300 + "\n--\n"
    "> 2024/05/01 10:00:00.000001  length=1 from=2 to=2\n 30  0\n--\n",
    # -v text with backslashes that escape nothing, at a line end, and at the end of the transfer
    "> 2024/05/01 10:00:00.000001  length=6 from=0 to=5\na\\qb\\\n\\< 2024/05/01 10:00:00.000001  length=1 "
    "from=0 to=0\n 30\n> 2024/05/01 10:00:00.000001  length=2 from=6 to=7\n\\\\\\",
    # counters: a restart at from=0, a gap, a repeat, to= off
    "> 2024/05/01 10:00:00.000001  length=2 from=5 to=6\n 30 31\n> 2024/05/01 10:00:00.000002  length=2 "
    "from=0 to=1\n 30 31\n> 2024/05/01 10:00:00.000003  length=1 from=9 to=9\n 30\n> 2024/05/01 "
    "10:00:00.000004  length=1 from=9 to=9\n 30\n> 2024/05/01 10:00:00.000005  length=1 from=10 to=11\n 30\n",
]


# a -x transfer of 120 bytes: its hex line comes in pieces when MAX_LINE is 257
LONG = ("> 2024/05/01 10:00:00.000001  length=120 from=0 to=119\n " + bytes(range(120)).hex(" ") + "\n"
        "> 2024/05/01 10:00:00.000001  length=1 from=120 to=120\n 31\n")


@pytest.mark.parametrize("text", HARD)
@pytest.mark.parametrize("block", [1, 7, 64, socat_mod.BLOCK])
@pytest.mark.parametrize("max_line", [None, 20, 257])
def test_hard_cases_read_as_before(text: str, block: int, max_line: int | None) -> None:
    assert_same(text, block, max_line=max_line)
    assert_same(text.replace("\n", "\r\n"), block, max_line=max_line)


@settings(max_examples=1000, deadline=None)
@given(st.data(), _dump(), st.sampled_from(BLOCKS) | st.integers(1, 400),
       st.sampled_from([None, None, None, None, 300, 257, 64, 20]), st.sampled_from([None, None, ">", "<"]),
       st.sampled_from([None, None, None, 1, 2, 5]))
@example(None, HARD[0], 1, None, None, None)
@example(None, HARD[3], socat_mod.BLOCK, None, None, None)  # read whole by the fast path, then more rows
@example(None, HARD[4], socat_mod.BLOCK, None, None, None)  # hex that only looks like hex
@example(None, HARD[6], socat_mod.BLOCK, None, None, None)  # a header line inside -v text
@example(None, HARD[7], 61, None, "<", None)  # the 9-digit quirk switching to nanoseconds
@example(None, LONG, socat_mod.BLOCK, 257, None, None)  # a -x line longer than MAX_LINE
@example(None, HARD[0] + HARD[3], socat_mod.BLOCK, 20, None, 2)  # headers longer than MAX_LINE
def test_fast_reader_gives_what_the_line_reader_gives(data: st.DataObject | None, dump: str, block: int,
                                                      max_line: int | None, host_is: str | None,
                                                      give_up: int | None) -> None:
    text = dump if data is None else data.draw(_damage(dump))
    assert_same(text, block, max_line=max_line, host_is=host_is, give_up=give_up)


@settings(max_examples=200, deadline=None)
@given(_dump(), st.sampled_from(BLOCKS))
def test_clean_dumps_read_as_before_at_every_block_size(dump: str, block: int) -> None:
    for text in (dump, dump.replace("\n", "\r\n"), dump.rstrip("\n")):
        assert_same(text, block)


# ---------------------------------------------------------------- the fast path runs, and stays small ----


def _clean(n: int, style: str, seed: int = 1, crlf: bool = False) -> str:
    """``n`` transfers of frames as socat ``-x`` (``x``) or ``-x -v`` (``xv``) writes them."""
    rng = random.Random(seed)
    count = {">": 0, "<": 0}
    out = []
    for i in range(n):
        side, data = "><"[i % 2], rng.choice(FRAMES[:6]) + bytes([rng.randrange(256)])
        fraction = _fraction(rng.choice(["6", "9-quirk"]), rng.randrange(10 ** 6), 0)
        out.append(f"{side} 2024/05/01 10:{i // 6000 % 60:02d}:{i // 100 % 60:02d}.{fraction}  "
                   f"length={len(data)} from={count[side]} to={count[side] + len(data) - 1}\n")
        count[side] += len(data)
        out.append(" " + data.hex(" ") + "\n" if style == "x" else "".join(_hex_rows(data)) + "--\n")
    text = "".join(out)
    return text.replace("\n", "\r\n") if crlf else text


def _steps(text: str, block: int) -> tuple[int, int]:
    """(lines ``step`` read, lines in the dump) when the fast reader reads ``text`` (and gives what
    the reference gives)."""
    assert_same(text, block)
    calls = []
    step = socat_mod._Transfers.step

    def counted(self: Any, number: int, line: str) -> Any:
        calls.append(number)
        return (yield from step(self, number, line))

    with mock.patch.object(socat_mod._Transfers, "step", counted), \
            mock.patch.object(socat_mod, "BLOCK", block):
        _read_text(text)
    return len(set(calls)), text.count("\n")


@pytest.mark.parametrize(("style", "crlf"), [("x", False), ("xv", False), ("x", True), ("xv", True)])
def test_fast_path_reads_clean_dumps_by_itself(style: str, crlf: bool) -> None:
    """Clean ``-x`` and ``-x -v`` dumps (LF or CRLF) are read by the fast path, also where a block end
    cuts a transfer (it reads ahead and goes on): ``step`` reads at most the last -x transfer (the fast
    path reads a -x transfer once it sees the next line, which could have been another hex row)."""
    text = _clean(3000, style, crlf=crlf)
    last = 2 if style == "x" else 0
    assert _steps(text, socat_mod.BLOCK)[0] == last
    assert _steps(text, 4096)[0] == last


def test_fast_path_comes_back_after_text_and_damage() -> None:
    """After a -v section and after damage, the fast path reads again within a bounded number of
    lines (it waits longer and longer while it reads nothing, at most 2 ** _FAST_WAIT lines)."""
    v_part = "".join(f"> 2024/05/01 10:00:00.{i:06d}  length=5 from={5 * i} to={5 * i + 4}\n0RV\\r\n"
                     for i in range(3000))
    text = v_part + _clean(3000, "x", seed=2) + "junk\n" + _clean(3000, "xv", seed=3)
    stepped, _ = _steps(text, socat_mod.BLOCK)
    assert stepped < v_part.count("\n") + (1 << socat_mod._FAST_WAIT) + 3 * 16


def test_memory_stays_bounded() -> None:
    """The block buffer holds at most a block and a line; the bodies remembered are bounded in number
    and size, whatever the file (long lines, many distinct transfers)."""
    text = _clean(200, "x") + "x" * 300_000 + "\n" + "".join(
        f"> 2024/05/01 10:00:00.000001  length=2 from={2 * i} to={2 * i + 1}\n {i >> 8:02x} {i & 255:02x}\n"
        for i in range(socat_mod._KNOWN + 500))
    path = Path(_TMP.name) / "big.log"
    path.write_text(text, encoding="latin-1")
    largest, builders = [0], []
    fill, init = socat_mod._Lines._fill, socat_mod._Transfers.__init__

    def measured_fill(self: Any) -> bool:
        more = fill(self)
        largest[0] = max(largest[0], len(self.buf))
        return more

    def kept_init(self: Any, *args: Any) -> None:
        init(self, *args)
        builders.append(self)

    with mock.patch.object(socat_mod, "BLOCK", 4096), \
            mock.patch.object(socat_mod._Lines, "_fill", measured_fill), \
            mock.patch.object(socat_mod._Transfers, "__init__", kept_init), Source(path, Report()) as src:
        chunks = list(socat_mod.read(src))
    assert len(chunks) == 200 + socat_mod._KNOWN + 500
    assert 4096 < largest[0] <= 4096 + base_mod.MAX_LINE
    assert 0 < len(builders[0].known) <= socat_mod._KNOWN
    assert all(len(body) <= socat_mod._KNOWN_TEXT for body in builders[0].known)

def _read_text(text: str) -> list[Chunk]:
    path = Path(_TMP.name) / "plain.log"
    path.write_text(text, encoding="latin-1")
    with Source(path, Report()) as src:
        return list(socat_mod.read(src))


def test_times_are_the_line_readers_bit_for_bit() -> None:
    """Times of every fraction width socat (or damage) writes, across many seconds and dates, the 9-digit
    quirk switching to nanoseconds halfway: the fast path's arithmetic gives wallclock's floats."""
    rng = random.Random(7)
    out = []
    for i in range(3000):
        digits = rng.choice([1, 2, 3, 6, 6, 6, 9, 12])
        fraction = str(rng.randrange(10 ** digits)).zfill(digits)
        if digits == 9 and i < 1500:
            fraction = "000" + fraction[3:]  # socat 1.7's microseconds, until the first real nanoseconds
        date = rng.choice(["2024/05/01", "2024/12/31", "1970/01/01", "2038/01/19", "2106/02/07"])
        out.append(f"> {date} {rng.randrange(24):02d}:{rng.randrange(60):02d}:{rng.randrange(60):02d}."
                   f"{fraction}  length=1 from={i} to={i}\n {rng.randrange(256):02x}\n")
    chunks = assert_same("".join(out), socat_mod.BLOCK)
    assert len(chunks) > 2500
