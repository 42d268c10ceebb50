"""The socat reader's one parser, by its behaviour: clean dumps give their transfers (times bit for bit as
``wallclock`` reads them), any dump (damaged anyhow) reads the same whatever the block size and line
limit, with located problems and bounded memory, and a log whose clock jumps back is reported (issue 22:
one parser for clean and damaged dumps; issue 24 item 5).

Dumps are generated as socat writes them (``_dump``): ``-x``, ``-x -v`` and ``-v`` transfers of any bytes
on both sides, styles mixed, 6-digit fractions, socat 1.7's 9-digit quirk and real nanoseconds, socat
restarting at ``from=0``, diagnostics between transfers, counters that slip; then damaged (``_damage``):
lines deleted, duplicated, joined, truncated at any character, characters overwritten or inserted, CRLF
line ends, no final newline, the file cut anywhere. Each is read with block sizes from one character to
the default (``read(block=...)``, ``socat.BLOCK``) so that block ends fall everywhere, with a line limit
small enough to cut lines into pieces (``Source(max_line=...)``), with ``--host-is``, and giving up after a
few problems as ``xac1 decode`` does.
"""

from __future__ import annotations

import dataclasses
import random
import re
import struct
import tempfile
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
from conftest import budget
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sniffer.io import base as base_mod
from sniffer.io import socat as socat_mod
from sniffer.io.base import Report, Source, WrongFormat, shown, wallclock

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



BLOCKS = [1, 2, 3, 5, 7, 16, 61, 64, 97, 128, 200, 333, 1000, 4096, socat_mod.BLOCK]
_TMP = tempfile.TemporaryDirectory(prefix="xac1-socatread-")


def _bits(t: float | None) -> str | None:
    return None if t is None else struct.pack("<d", t).hex()


def observe(path: Path, *, host_is: str | None = None, give_up: int | None = None,
            block: int = socat_mod.BLOCK,
            max_line: int = base_mod.MAX_LINE) -> tuple[list[Any], tuple[Any, ...], dict[str, Any]]:
    """What a consumer sees of the reader: each chunk (time as bits) with the report's counts when it came,
    how reading ended (the last line's state, bytes read, or giving up), and the whole report. The
    consumer clears ``give_up_after`` at the first chunk, as ``xac1 decode`` does. Any exception other
    than the reader's own (``WrongFormat``) fails the test."""
    report = Report(give_up_after=give_up)
    events: list[Any] = []
    with Source(path, report, max_line=max_line) as src:
        try:
            for c in socat_mod.read(src, host_is, block=block):
                events.append((_bits(c.t), c.dir, c.data, c.error, type(c), report.total_problems,
                               report.unread_bytes, report.unread_lines))
                report.give_up_after = None
            end: tuple[Any, ...] = ("end", src.unterminated, src.pos)
            src.check_end()
        except WrongFormat as exc:
            end = ("gave up", str(exc))
    return events, end, dataclasses.asdict(report)


def read_any_block(text: str, blocks: tuple[int, ...], *, max_line: int | None = None,
                   host_is: str | None = None, give_up: int | None = None) -> Any:
    """What reading ``text`` gives: the same with every block size (the block ends fall anywhere); every
    problem located at a line of the file."""
    path = Path(_TMP.name) / "dump.log"
    path.write_bytes(text.encode("latin-1"))
    limit = max_line or base_mod.MAX_LINE
    results = [observe(path, host_is=host_is, give_up=give_up, block=block, max_line=limit)
               for block in blocks]
    for block, result in zip(blocks[1:], results[1:], strict=True):
        assert result == results[0], f"BLOCK {block} differs from BLOCK {blocks[0]}"
    lines = text.count("\n") + 1
    for problem in results[0][2]["problems"]:
        m = re.match(re.escape(str(path)) + r":(\d+): ", problem)
        assert m is not None and 1 <= int(m.group(1)) <= lines, problem
    return results[0]


# hard cases: each once read wrongly by a version of this reader
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
@pytest.mark.parametrize("max_line", [None, 20, 257])
def test_hard_cases_read_the_same_at_every_block_size(text: str, max_line: int | None) -> None:
    """Each hard case (and its CRLF twin) reads the same whatever the block size and line limit."""
    read_any_block(text, (socat_mod.BLOCK, 1, 7, 64), max_line=max_line)
    read_any_block(text.replace("\n", "\r\n"), (socat_mod.BLOCK, 1, 7, 64), max_line=max_line)


@settings(max_examples=budget(120), deadline=None)
@given(st.data(), _dump(), st.sampled_from(BLOCKS) | st.integers(1, 400),
       st.sampled_from([None, None, None, None, 300, 257, 64, 20]), st.sampled_from([None, None, ">", "<"]),
       st.sampled_from([None, None, None, 1, 2, 5]))
@example(None, HARD[0], 1, None, None, None)
@example(None, HARD[3], socat_mod.BLOCK, None, None, None)
@example(None, HARD[6], socat_mod.BLOCK, None, None, None)  # a header line inside -v text
@example(None, HARD[7], 61, None, "<", None)  # the 9-digit quirk switching to nanoseconds
@example(None, LONG, socat_mod.BLOCK, 257, None, None)  # a -x line longer than MAX_LINE
@example(None, HARD[0] + HARD[3], socat_mod.BLOCK, 20, None, 2)  # headers longer than MAX_LINE
def test_any_dump_reads_the_same_at_every_block_size(data: st.DataObject | None, dump: str, block: int,
                                                     max_line: int | None, host_is: str | None,
                                                     give_up: int | None) -> None:
    """Any dump, damaged anyhow, is read to its end (or given up on as asked) without an exception other
    than the reader's own; the same chunks, problems and counts whatever the block size; every problem
    located at a line of the file."""
    text = dump if data is None else data.draw(_damage(dump))
    read_any_block(text, (socat_mod.BLOCK, block), max_line=max_line, host_is=host_is, give_up=give_up)


# ---------------------------------------------------------------- clean dumps give their transfers ----

_V_BYTES = b"0123456789ABCDEF%\r\n\\ ."  # bytes socat -v shows exactly (and no header line)
_V_SAFE = st.binary(min_size=1, max_size=40).map(lambda b: bytes(_V_BYTES[x % len(_V_BYTES)] for x in b))


@st.composite
def clean_dumps(draw: st.DrawFn) -> tuple[str, list[tuple[str, bytes, float]], bool]:
    """(a socat log, the transfers it holds as (side, bytes, time), whether it has -v text): times in
    order, counters that go on; a log of hex rows (each transfer -x or -x -v), or of -v text (bytes -v
    shows exactly), as socat dumps a run in one style."""
    date = draw(st.sampled_from(["2024/05/01", "2026/11/22", "2038/01/19"]))
    second = draw(st.integers(0, 80000))
    count = {">": 0, "<": 0}
    out, want, v = [], [], False
    styles = draw(st.sampled_from([["x", "x", "xv"], ["x", "x", "xv"], ["v"]]))
    for _ in range(draw(st.integers(1, 12))):
        side = draw(st.sampled_from("><"))
        style = draw(st.sampled_from(styles))
        data = draw(_V_SAFE if style == "v" else st.one_of(st.sampled_from(FRAMES[:6]), st.binary(min_size=1,
                                                                                                  max_size=70)))
        second += draw(st.sampled_from([0, 0, 1, 59, 3600]))
        clock = f"{second // 3600 % 24:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
        if second >= 86400:
            break
        fraction = f"{draw(st.integers(0, 999999)):06d}"
        if want and want[-1][2] > wallclock(date, f"{clock}.{fraction}"):
            fraction = f"{999999:06d}"
        out.append(f"{side} {date} {clock}.{fraction}  length={len(data)} from={count[side]} "
                   f"to={count[side] + len(data) - 1}\n")
        count[side] += len(data)
        if style == "x":
            out.append(" " + data.hex(" ") + "\n")
        elif style == "xv":
            out.extend(_hex_rows(data))
            out.append("--\n")
        else:
            v = True
            out.append(_v_text(data) + ("" if data.endswith(b"\n") else "\n"))
        want.append((side, data, wallclock(date, f"{clock}.{fraction}")))
    return "".join(out), want, v


@settings(max_examples=budget(60), deadline=None)
@given(clean_dumps(), st.sampled_from(BLOCKS))
def test_clean_dumps_give_their_transfers(dump: tuple[str, list[tuple[str, bytes, float]], bool],
                                          block: int) -> None:
    """A clean log gives each transfer as one chunk: its side's direction (``>`` the host), its bytes, its
    header's time bit for bit as ``wallclock`` reads it; nothing reported; the same with CRLF line ends
    (-x and -x -v)."""
    text, want, v = dump
    for variant in (text, text if v else text.replace("\n", "\r\n")):
        events, end, report = read_any_block(variant, (block, socat_mod.BLOCK))
        assert [(e[1], e[2], e[0]) for e in events] == [
            ("host" if side == ">" else "device", data, _bits(t)) for side, data, t in want]
        assert report["problems"] == [] and report["unread_bytes"] == 0 and end[0] == "end"


def test_times_are_wallclock_s_bit_for_bit() -> None:
    """Times of every fraction width socat (or damage) writes, across many seconds and dates, the 9-digit
    quirk switching to nanoseconds halfway: each is wallclock's float for its header (the times jump about, so
    steps back are reported, and nothing else)."""
    rng = random.Random(7)
    out, want = [], []
    nano = False
    for i in range(3000):
        digits = rng.choice([1, 2, 3, 6, 6, 6, 9, 12])
        fraction = str(rng.randrange(10 ** digits)).zfill(digits)
        if digits == 9 and i < 1500:
            fraction = "000" + fraction[3:]  # socat 1.7's microseconds, until the first real nanoseconds
        date = rng.choice(["2024/05/01", "2024/12/31", "1970/01/01", "2038/01/19"])
        clock = f"{rng.randrange(24):02d}:{rng.randrange(60):02d}:{rng.randrange(60):02d}"
        out.append(f"> {date} {clock}.{fraction}  length=1 from={i} to={i}\n {rng.randrange(256):02x}\n")
        nano = nano or (digits == 9 and i >= 1500 and not fraction.startswith("000"))
        read_as = fraction[3:] if digits == 9 and not nano else fraction
        want.append(_bits(wallclock(date, f"{clock}.{read_as}")))
    events, _, report = read_any_block("".join(out), (socat_mod.BLOCK, 97))
    assert [e[0] for e in events] == want
    assert report["problems"] and all(": time runs backwards: " in p for p in report["problems"])


@settings(max_examples=budget(60), deadline=None)
@given(st.sampled_from(DATES[:3]), st.integers(0, 86000),
       st.lists(st.tuples(st.sampled_from([0, 0, 0, 0, 1, 1, 59, 60, 61, 3600]), st.integers(0, 999999),
                          st.booleans()), min_size=1, max_size=40),
       st.sampled_from(BLOCKS))
def test_times_in_one_second_and_across_minutes_are_wallclock_s(date: str, second: int,
                                                               steps: list[tuple[int, int, bool]],
                                                               block: int) -> None:
    """A header's time is wallclock's float for its text (bit for bit) whether its second is the one of the
    header before (its start remembered), a new second of the same minute, or in a new minute or hour;
    six-digit fractions and socat 1.7's nine digits behind ``000`` mixed; nothing reported; the same at
    every block size."""
    out, want = [], []
    for i, (step, micro, nine) in enumerate(steps):
        second += step
        if second >= 86400:
            break
        clock = f"{second // 3600:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
        fraction = f"000{micro:06d}" if nine else f"{micro:06d}"
        out.append(f"{'><'[i % 2]} {date} {clock}.{fraction}  length=1 from={i // 2} to={i // 2}\n"
                   f" {micro % 256:02x}\n")
        want.append(_bits(wallclock(date, f"{clock}.{micro:06d}")))
    events, end, report = read_any_block("".join(out), (socat_mod.BLOCK, block))
    assert [e[0] for e in events] == want
    assert report["problems"] == [] and end[0] == "end"


# ---------------------------------------------------------------- time, memory ----

def test_a_clock_set_back_is_a_problem_of_the_capture() -> None:
    """A log whose timestamps jump back a day (the clock was set back) is reported once, at the header
    where it happens, as time running backwards; the bytes keep their own times; a step back within a
    second is no problem (issue 24 item 5: it was accepted without a word)."""
    stamps = ["2026/11/22 10:00:00.000000", "2026/11/22 10:00:01.000000", "2026/11/22 10:00:00.500000",
              "2026/11/21 10:00:02.000000", "2026/11/21 10:00:03.000000"]
    text = "".join(f"{'><'[i % 2]} {s}  length=5 from={i // 2 * 5} to={i // 2 * 5 + 4}\n 30 52 56 0d 0a\n"
                   for i, s in enumerate(stamps))
    events, _, report = read_any_block(text, (socat_mod.BLOCK, 5))
    assert len(events) == 5 and report["unread_bytes"] == 0
    path = Path(_TMP.name) / "dump.log"
    assert len(report["problems"]) == 1
    assert report["problems"][0].startswith(f"{path}:7: time runs backwards: ")
    assert "is 86398.500000 s before" in report["problems"][0]
    assert [e[0] for e in events] == [_bits(wallclock(s[:10], s[11:])) for s in stamps]


def _clean(n: int, seed: int = 1) -> str:
    """``n`` transfers of frames as socat ``-x`` writes them."""
    rng = random.Random(seed)
    count = {">": 0, "<": 0}
    out = []
    for i in range(n):
        side, data = "><"[i % 2], rng.choice(FRAMES[:6]) + bytes([rng.randrange(256)])
        clock = f"10:{i // 6000 % 60:02d}:{i // 100 % 60:02d}.{rng.randrange(10 ** 6):06d}"
        out.append(f"{side} 2024/05/01 {clock}  length={len(data)} from={count[side]} "
                   f"to={count[side] + len(data) - 1}\n")
        count[side] += len(data)
        out.append(" " + data.hex(" ") + "\n")
    return "".join(out)


def _peak_reading(text: str) -> tuple[int, int, list[str]]:
    """(chunks, peak bytes allocated, problems) of reading ``text`` 4096 characters at a time."""
    path = Path(_TMP.name) / "big.log"
    path.write_text(text, encoding="latin-1")
    report = Report()
    tracemalloc.start()
    try:
        with Source(path, report) as src:
            chunks = sum(1 for _ in socat_mod.read(src, block=4096))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return chunks, peak, report.problems


def test_memory_stays_bounded() -> None:
    """What reading holds stays bounded: a block and a line of the file (a line of 300 000 characters is
    read in pieces), and the hex rows and lengths it remembers: the peak memory of reading a dump of many
    distinct transfers does not grow when the dump has three times as many."""
    def dump(n: int) -> str:
        count, rows = 0, []
        for i in range(n):  # distinct rows (their first two bytes), lengths from 2 to 41
            length = 2 + i % 40
            rows.append(f"> 2024/05/01 11:00:00.000001  length={length} from={count} "
                        f"to={count + length - 1}\n {i >> 8:02x} {i & 255:02x}" + " 00" * (length - 2) + "\n")
            count += length
        return _clean(200) + "x" * 300_000 + "\n" + "".join(rows)

    chunks, peak, problems = _peak_reading(dump(6000))
    chunks3, peak3, problems3 = _peak_reading(dump(18000))
    path = Path(_TMP.name) / "big.log"
    assert (chunks, chunks3) == (200 + 6000, 200 + 18000)
    assert problems == problems3 and problems and all(p.startswith(f"{path}:401: ") for p in problems)
    assert peak < 4 * 1024 * 1024 and peak3 < peak * 1.25


# ---------------------------------------------------------------- the block matcher ----

def test_a_header_cut_by_a_line_end_is_not_joined_to_the_next_line() -> None:
    """A header whose line ends before ``length=`` is no header: that line and the next are each reported
    at their own line, and every line after keeps its number (a version joined the two lines into one
    header, and numbered every later line one too low)."""
    text = ("> 2024/05/01 10:00:00.000001  length=5 from=0 to=4\n 30 52 56 0d 0a\n"
            "> 2024/05/01 10:00:00.000002\n  length=1 from=5 to=5\n 30\n"
            "> 2024/05/01 10:00:00.000003  length=3 from=6 to=8\n 30 31\n")
    events, _, report = read_any_block(text, (socat_mod.BLOCK, 1, 7))
    path = Path(_TMP.name) / "dump.log"
    assert [e[2] for e in events] == [b"0RV\r\n0", b"01"]
    assert report["problems"] == [
        f"{path}:3: cannot read this dump line: '> 2024/05/01 10:00:00.000002'",
        f"{path}:4: cannot read this dump line: '  length=1 from=5 to=5'",
        f"{path}:1: transfer says length=5 but its dump holds 6 byte(s) (cut short before line 6)",
        f"{path}:6: 1 byte(s) of the '>' side are missing before this transfer (from=6, the previous one "
        f"ended at to=4)",
        f"{path}:6: transfer says length=3 but its dump holds 2 byte(s) (cut short before line 7)"]


def test_a_length_beyond_16_mib_is_reported_at_every_header_that_says_it() -> None:
    """``length=`` beyond 16 MiB is no transfer socat writes: reported at each header that says it (the
    same text again included: such a length is not remembered as a known one), read as 16 MiB, so the
    transfer is then cut short; its bytes are kept; the same at every block size."""
    text = ("> 2024/05/01 10:00:00.000001  length=20000000 from=0 to=19999999\n 30 31\n"
            "> 2024/05/01 10:00:00.000002  length=20000000 from=20000000 to=39999999\n 30\n")
    events, _, report = read_any_block(text, (socat_mod.BLOCK, 1, 7))
    path = Path(_TMP.name) / "dump.log"
    implausible = ("length=20000000 is not plausible for one transfer (expected at most 16777216); read as "
                   "that")
    assert [e[2] for e in events] == [b"01", b"0"]
    assert report["problems"] == [
        f"{path}:1: {implausible}",
        f"{path}:1: transfer says length=16777216 but its dump holds 2 byte(s) (cut short before line 3)",
        f"{path}:3: {implausible}",
        f"{path}:3: transfer says length=16777216 but its dump holds 1 byte(s) (cut short before line 4)"]


def test_a_second_past_59_is_reported_in_any_minute() -> None:
    """Second 60 to 99 is no time, whether its minute is new or was seen on the header before: reported
    at its header, the bytes kept with the previous time (a version said so only of a minute's first
    header and read a later one as the next minute's time)."""
    text = ("> 2024/05/01 10:00:08.000001  length=1 from=0 to=0\n 30\n"
            "> 2024/05/01 10:00:75.000001  length=1 from=1 to=1\n 31\n"
            "> 2024/05/01 10:01:75.000001  length=1 from=2 to=2\n 32\n")
    events, _, report = read_any_block(text, (socat_mod.BLOCK, 5))
    path = Path(_TMP.name) / "dump.log"
    first = _bits(wallclock("2024/05/01", "10:00:08.000001"))
    assert [(e[0], e[2]) for e in events] == [(first, b"0"), (first, b"1"), (first, b"2")]
    assert [p.split(": impossible")[0] for p in report["problems"]] == [f"{path}:3", f"{path}:5"]
    assert all("second must be in 0..59" in p for p in report["problems"])


@st.composite
def _garbled(draw: st.DrawFn) -> tuple[str, list[tuple[str, bytes, float]], list[int]]:
    """A clean ``-x`` log with lines of junk put between its transfers: (text, its transfers, the junk's
    line numbers). Junk is any text that is no header, hex row, diagnostic, blank line or ``--``. (Right
    after a header, a line that is no hex row is -v text: the transfer's bytes.)"""
    date, count, second = "2024/05/01", {">": 0, "<": 0}, draw(st.integers(0, 80000))
    lines: list[str] = []
    want = []
    for _ in range(draw(st.integers(1, 30))):
        side = draw(st.sampled_from("><"))
        data = draw(st.one_of(st.sampled_from(FRAMES[:6]), st.binary(min_size=1, max_size=40)))
        second += draw(st.sampled_from([0, 0, 1, 59]))
        clock = f"{second // 3600 % 24:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
        fraction = draw(st.sampled_from(["000001", "999999", "500000", "000123456"]))
        lines.append(f"{side} {date} {clock}.{fraction}  length={len(data)} from={count[side]} "
                     f"to={count[side] + len(data) - 1}")
        lines.append(" " + data.hex(" "))
        count[side] += len(data)
        read_as = fraction[3:] if len(fraction) == 9 else fraction
        want.append((side, data, wallclock(date, f"{clock}.{read_as}")))
    junk = st.from_regex(r"[a-zA-Z#*][ -~]{0,70}", fullmatch=True)
    spots = sorted(draw(st.lists(st.integers(0, len(lines) // 2), max_size=6)), reverse=True)
    for at in spots:  # from the end, so that the earlier spots stay where they were drawn
        lines.insert(2 * at, draw(junk))
    numbers = [i + 1 for i, line in enumerate(lines) if line[:1] not in "<> "]
    return "".join(line + "\n" for line in lines), want, numbers


@settings(max_examples=budget(60), deadline=None)
@given(_garbled(), st.sampled_from(BLOCKS) | st.integers(1, 400))
def test_junk_between_lines_is_reported_at_its_line_and_the_transfers_read_whole(
        dump: tuple[str, list[tuple[str, bytes, float]], list[int]], block: int) -> None:
    """Lines of junk between the transfers of a ``-x`` log are each reported once, at their own line, as
    one line not read; every transfer still reads whole, its time wallclock's; the same at every block size
    (block ends falling inside transfers and junk alike)."""
    text, want, numbers = dump
    events, end, report = read_any_block(text, (socat_mod.BLOCK, block))
    path = Path(_TMP.name) / "dump.log"
    assert [(e[1], e[2], e[0]) for e in events] == [
        ("host" if side == ">" else "device", data, _bits(t)) for side, data, t in want]
    assert [p.split(": ")[0] for p in report["problems"]] == [f"{path}:{n}" for n in numbers]
    assert report["unread_lines"] == len(numbers) and report["unread_bytes"] == 0 and end[0] == "end"


@settings(max_examples=budget(40), deadline=None)
@given(clean_dumps(), st.data())
def test_line_ends_mixed_anyhow_read_the_same(dump: tuple[str, list[tuple[str, bytes, float]], bool],
                                              more: st.DataObject) -> None:
    """A clean -x / -x -v log whose lines end with LF or CR LF, mixed anyhow (the first lines deciding how
    the block matcher reads line ends), gives the same transfers as with LF alone, and nothing reported."""
    text, want, v = dump
    lines = text.split("\n")
    crlf = more.draw(st.lists(st.booleans(), min_size=len(lines), max_size=len(lines)))
    mixed = "\n".join(line + "\r" if cr and i < len(lines) - 1 and not v else line
                      for i, (line, cr) in enumerate(zip(lines, crlf, strict=True)))
    events, end, report = read_any_block(mixed, (socat_mod.BLOCK, 61))
    assert [(e[1], e[2], e[0]) for e in events] == [
        ("host" if side == ">" else "device", data, _bits(t)) for side, data, t in want]
    assert report["problems"] == [] and end[0] == "end"


# -v text that looks like hex rows: digits in pairs after a space, LF between lines
_HEXLIKE_LINE = st.lists(st.integers(0, 99), min_size=1, max_size=5).map(
    lambda ns: " " + " ".join(f"{n:02d}" for n in ns))
_HEXLIKE_TEXT = st.tuples(st.lists(st.one_of(_HEXLIKE_LINE, st.just(""), st.just("0RV")), min_size=1,
                                   max_size=4).filter(lambda rows: rows[0] != ""),
                          st.booleans()).map(lambda r: ("\n".join(r[0]) + ("\n" if r[1] else "")).encode())


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(st.tuples(st.sampled_from("><"), st.one_of(_HEXLIKE_TEXT, st.sampled_from(FRAMES[:4]))),
                min_size=1, max_size=5), st.booleans())
def test_v_text_that_looks_like_hex_rows_is_read_as_text(transfers: list[tuple[str, bytes]],
                                                         last_newline: bool) -> None:
    """A -v log whose text looks like hex rows (`` 00`` is three bytes as text, one as hex): the reading
    that fits ``length=`` is the text one, so each transfer is its bytes and nothing is reported, the
    file's last line ended or not (was: read as a short hex dump and reported cut short)."""
    count = {">": 0, "<": 0}
    out = []
    for k, (side, data) in enumerate(transfers):
        out.append(f"{side} 2024/05/01 10:00:{k:02d}.000001  length={len(data)} from={count[side]} "
                   f"to={count[side] + len(data) - 1}\n")
        out.append(_v_text(data) + ("" if data.endswith(b"\n") else "\n"))
        count[side] += len(data)
    text = "".join(out)
    if not last_newline and not transfers[-1][1].endswith(b"\n"):
        text = text[:-1]  # socat -v ends text without an LF with nothing
    events, end, report = read_any_block(text, (socat_mod.BLOCK, 61))
    assert [(e[1], e[2]) for e in events] == [("host" if side == ">" else "device", data)
                                              for side, data in transfers]
    assert report["problems"] == [] and end[0] == "end" and end[1] is None


@pytest.mark.parametrize("style", ["x", "xv"])
@pytest.mark.parametrize("then", ["a header", "the end of the file", "the end of a line at the end"])
def test_a_hex_row_cut_where_its_text_would_fit_is_reported_in_a_log_of_hex_rows(style: str,
                                                                                   then: str) -> None:
    """A log of hex rows whose row is cut where its text would be ``length=`` characters (`` 30 4d`` of
    the six bytes ``0MP0\\r\\n``, a crash in the middle of a line): the log has shown hex rows, so it is a
    dump cut short, reported with the bytes it holds, never read as -v text."""
    first = b"0RV\r\n"
    rows = [" " + first.hex(" ") + "\n"] if style == "x" else [*_hex_rows(first), "--\n"]
    text = ("> 2024/05/01 10:00:00.000001  length=5 from=0 to=4\n" + "".join(rows)
            + "> 2024/05/01 10:00:01.000001  length=6 from=5 to=10\n 30 4d")
    text += {"a header": "\n< 2024/05/01 10:00:02.000001  length=1 from=0 to=0\n 30\n",
             "the end of the file": "", "the end of a line at the end": "\n"}[then]
    events, end, report = read_any_block(text, (socat_mod.BLOCK, 61))
    assert [e[2] for e in events][:2] == [first, b"0M"]
    assert "transfer says length=6 but its dump holds 2 byte(s)" in report["problems"][0]
    assert len(report["problems"]) == (2 if then == "the end of the file" else 1)  # and the line cut


@pytest.mark.parametrize("last", ["0RV", "0RV100\\r", " 00"])
def test_a_v_log_whose_last_text_has_no_line_end_is_whole(last: str) -> None:
    """socat -v ends text that has no LF with nothing, so a whole log's last line may have no line end:
    ``length=`` says the text is whole, and nothing is reported (was: "the file ends in the middle of
    this line", a complete capture called cut short)."""
    data = last.replace("\\r", "\r").encode()
    text = ("> 2024/05/01 10:00:00.000001  length=5 from=0 to=4\n0RV\\r\n"
            f"< 2024/05/01 10:00:00.010001  length={len(data)} from=0 to={len(data) - 1}\n{last}")
    events, end, report = read_any_block(text, (socat_mod.BLOCK, 61))
    assert [e[2] for e in events] == [b"0RV\r\n", data]
    assert report["problems"] == [] and end == ("end", None, len(text))


@pytest.mark.parametrize("at", [8, 14, 16, 19, 21])  # a character of the year, the month, the day, the
# hour, the minute (the seconds' own two characters are covered by "second past 59")
@pytest.mark.parametrize("char", ["x", "/", " ", "\xb2"])
@pytest.mark.parametrize("line_end", ["\n", "\r\n"])
def test_a_header_whose_date_or_time_is_not_all_digits_is_no_header(at: int, char: str,
                                                                    line_end: str) -> None:
    """A header line's date and time are digits (``YYYY/MM/DD HH:MM:SS``); one with any other character
    there (a letter, a separator, a space, a superscript digit) is no header: it does not end the
    transfer before it, and is reported at its line as a line the dump cannot hold, whatever the block
    size and line end; the row after it is read as a further row of the transfer before, which is then
    longer than its ``length=`` (reported at that header), and the next clean header reads on."""
    bad = "> 2024/05/01 10:00:00.000002  length=2 from=2 to=3"
    bad = bad[:at] + char + bad[at + 1:]
    text = ("> 2024/05/01 10:00:00.000001  length=2 from=0 to=1\n 30 31\n" + bad + "\n 32 33\n"
            "< 2024/05/01 10:00:01.000001  length=1 from=0 to=0\n 30\n").replace("\n", line_end)
    events, end, report = read_any_block(text, (socat_mod.BLOCK, 1, 7, 61))
    path = Path(_TMP.name) / "dump.log"
    assert [(e[1], e[2]) for e in events] == [("host", b"0123"), ("device", b"0")]
    assert report["problems"] == [f"{path}:3: cannot read this dump line: {shown(bad)}",
                                  f"{path}:1: transfer says length=2 but its dump holds 4 byte(s) (cut "
                                  f"short before line 5)"]
    assert report["unread_lines"] == 1 and end == ("end", None, len(text))
