"""The views write what the records say: ``JsonlView`` a record's line exactly as docs/output.md has it
(``json.dumps`` of the record's ``to_dict``, compact; ``record.to_json()`` the same without the newline),
``TextView`` without colour the plain text of the styled pieces that
``TextView.line`` and ``violation_parts`` give (rich's rendering where a tab is), the number helpers
(``fixed``, ``json_t``, ``json_ms``) and the text view's clock and latency exactly as ``json.dumps``,
``round`` and ``datetime`` give them. Each record on its own, and one view over a whole stream (as a
decode has: the part of a line made once per distinct frame, ``sniffer.frame_parts``, must never carry
over to a record with another frame, header or direction; the clock's second must never carry over).

Record streams: conversations through ``Analyzer`` (the generators of tests/test_decode_equivalence.py:
every violation, junk and timing edge, with and without time) and hand-built records with edge values
(no time, NaN, infinite, huge, negative and tiny times and latencies, ties of the rounding, no frame,
details holding tabs, ``%`` and markup, line errors, unknown codes, odd field values).
"""

from __future__ import annotations

import contextlib
import copy
import datetime as _dt
import io
import json
import math
import os
import time
from collections.abc import Iterator
from typing import Any

import pytest
from conftest import budget
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rich.console import Console
from rich.text import Text
from strategies import frames
from test_decode_equivalence import chunks_of, cuts, events, gaps, line_error_at

from sniffer import json_lines
from sniffer import view as view_mod
from sniffer.analyzer import Analyzer
from sniffer.records import CAPTURE_ENDED, FrameRecord, JunkRecord, Record, TimeoutRecord
from sniffer.view import BATCH_LINES, JsonlView, TextView
from xac1_proto import frames as fr
from xac1_proto import spec

T0 = 1_790_000_000.0
NAN, INF = float("nan"), float("inf")


class Writes(io.StringIO):
    """A stream (not a terminal) that keeps each ``write`` call."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[str] = []

    def write(self, s: str) -> int:
        self.calls.append(s)
        return super().write(s)


def _outcome(make: Any) -> tuple[str, Any]:
    """("ok", value) or ("raises", the exception's type)."""
    try:
        return "ok", make()
    except Exception as exc:
        return "raises", type(exc)


def plain_text(record: Record) -> str:
    """A record's lines (its line, its violations, its line errors: ``TextView.lines``), each the plain
    text of its pieces; a line holding a tab as rich prints it (rich expands tabs)."""
    stream = io.StringIO()
    console = Console(file=stream, no_color=True, highlight=False, soft_wrap=True, emoji=False)
    for texts, styles in TextView(io.StringIO(), color=False).lines([record]):
        text = "".join(texts)
        if "\t" in text:
            console.print(Text.assemble(*zip(texts, styles, strict=True)))
        else:
            stream.write(text + "\n")
    return stream.getvalue()


def dumped(record: Record) -> str:
    """The record's ``to_dict`` as compact JSON: what docs/output.md says its line is."""
    return json.dumps(record.to_dict(), separators=(",", ":"))


def assert_views_say_what_records_say(records: list[Record]) -> None:
    """Each record: the JSON line (and ``to_json()``) is its ``to_dict`` as JSON (raising where that
    raises); the text the pieces'. Then ``assert_one_view_says_what_records_say``."""
    for record in records:
        expected = _outcome(lambda r=record: dumped(r) + "\n")
        assert _outcome(lambda r=record: JsonlView(io.StringIO()).line(r)) == expected
        assert _outcome(lambda r=record: r.to_json() + "\n") == expected
        text = TextView(io.StringIO(), color=False)
        got = _outcome(lambda r=record, v=text: (v.write(r), v.flush(), v.stream.getvalue())[2])
        assert got == _outcome(lambda r=record: plain_text(r)), record
    assert_one_view_says_what_records_say(records)


def assert_one_view_says_what_records_say(records: list[Record]) -> None:
    """One view of each kind over the whole stream (as a decode has), offline and live, in one batch and
    record by record: every line is its own record's, whatever the records before it held."""
    ok = [r for r in records if _outcome(lambda r=r: (dumped(r), plain_text(r)))[0] == "ok"]
    expected = {"jsonl": "".join(dumped(r) + "\n" for r in ok), "text": "".join(map(plain_text, ok))}
    for live in (False, True):
        for by_record in (False, True):
            views = {"jsonl": JsonlView(io.StringIO(), live=live),
                     "text": TextView(io.StringIO(), color=False, live=live)}
            for fmt, view in views.items():
                if by_record:
                    for record in ok:
                        view.write(record)
                else:
                    view.write_many(ok)
                view.flush()
                assert view.stream.getvalue() == expected[fmt], (fmt, live, by_record)


# ---------------------------------------------------------------- conversations ----

@settings(max_examples=budget(30), deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at, st.booleans())
@example([], [0.0] * 40, [1], True, set(), True)
def test_views_on_generated_conversations(items, dts, sizes_, timed, flagged, close_late):
    """Every violation, junk, line errors, timing edges, with and without time: the JSON lines are the
    records' ``to_dict`` as JSON, the plain text rich's rendering of the same pieces."""
    chunks = chunks_of(items, dts, sizes_, timed, flagged)
    analyzer = Analyzer()
    records: list[Record] = []
    for chunk in chunks:
        records += analyzer.feed(chunk)
    records += analyzer.close((chunks[-1].t or 0.0) + 5.0 if close_late and timed and chunks else None)
    assert_views_say_what_records_say(records)


def test_cell_exchanges_read_back_as_json():
    """The JSON lines of clean exchanges (the hand-written format) parse back to the records' dicts."""
    analyzer = Analyzer()
    records: list[Record] = []
    from xac1_proto.chunk import DEVICE, HOST, Chunk
    pairs = [(fr.ReadCurrent(), fr.ReadCurrentAnswer(n=3, v=9, a=3, o=1, pos=0x12345)),
             (fr.WriteOutputs(o=2), fr.WriteOutputsAnswer(o=2)),
             (fr.ReadVersion(), fr.ReadVersionAnswer(version="100"))]
    for k in range(30):
        command, answer = pairs[k % 3]
        t = T0 + k * 0.0137
        records += analyzer.feed(Chunk(t, HOST, command.to_bytes()))
        records += analyzer.feed(Chunk(t + 0.0021 + k * 1e-7, DEVICE, answer.to_bytes()))
    view = JsonlView(Writes(), live=False)
    view.write_many(records)
    view.flush()
    lines = view.stream.getvalue().splitlines()
    assert [json.loads(line) for line in lines] == [r.to_dict() for r in records]
    assert len(lines) == 60 and all(r.type == "frame" and not r.violations for r in records)


# ---------------------------------------------------------------- hand-built records ----

EDGE_TIMES = [0.0, -0.0, 5e-324, 1e-7, 0.0004999, 0.0005, 0.000999, 0.001, 0.0010005, 0.5, 1.5, -1.5,
              -0.0000004, -0.9999996, 8191.9999995, 8192.0, T0, T0 + 0.0078125, T0 + 0.0000005,
              T0 + 0.9999995, T0 + 0.99999949, T0 + 0.9995, 2.0**31 + 0.5, 2.0**32 - 1e-6, 2.0**32,
              2.0**32 + 0.25, 1e12 + 0.5, 1e15 + 0.5, 1e16, 1e17, 1e300, -1e300, 253402300799.9995,
              253402300800.0, -62135596800.0, -62135596801.0, 2.0**63, NAN, INF, -INF]
EDGE_LATENCIES = [0.0, -0.0, 1e-9, 5e-7, 9.999e-7, 1e-6, 1.0000005e-6, 0.0000015, 0.0012345, 0.0012355,
                  0.00125, 0.00135, 0.001, 0.0025, 0.999999, 1.0, 1e6, 1e9, 1e9 - 1e-6, 999999999.9999996,
                  1e9 + 0.1234567, 1234567890.1234567, 3e10 + 0.1, 1e12, 1e12 + 0.0625, 1e15, 1e300, -0.002,
                  NAN, INF, -INF]
times = st.one_of(st.none(), st.sampled_from(EDGE_TIMES), st.floats(), st.floats(T0, T0 + 100),
                  st.floats(-1e11, 1e11), st.integers(-10**11, 10**11))
latencies = st.one_of(st.none(), st.sampled_from(EDGE_LATENCIES), st.floats(), st.floats(0, 2),
                      st.floats(1e8, 1e14), st.integers(-5, 5))
numbers = st.one_of(st.integers(-5, 10**6), st.integers(), st.booleans())
replies = st.one_of(st.none(), st.integers(-5, 10**6), st.booleans())
CODES = list(spec.VIOLATIONS)
codes = st.one_of(st.sampled_from(CODES), st.sampled_from(CODES), st.just("bogus-code"))
HEADERS = sorted(spec.HEADERS[spec.COMMAND] | spec.HEADERS[spec.ANSWER])
# frames whose values print oddly: the same description for 1 and True, JSON 1 and true; a tab
ODD_FRAMES = [fr.ReadPoint.unchecked(n=1), fr.ReadPoint.unchecked(n=True), fr.AlarmAnswer(code=0x0E),
              fr.AlarmAnswer.unchecked(code=0x7F), fr.ReadVersionAnswer.unchecked(version="1\t0"),
              fr.ReadVersionAnswer.unchecked(version="%s%")]
notes = st.one_of(st.text(max_size=12), st.sampled_from(["\t", "50%", "%s", "%%", "\0i\0", "\0t\0", "\x00",
                                                          "\0latency_ms\0", '"', "\\u0000i\\u0000"]))


def _wire(frame: Any) -> bytes:
    try:
        return frame.to_bytes()  # type: ignore[no-any-return]
    except Exception:  # no frame, or one of the odd ones
        return b"0RP1\r\n"


@st.composite
def contents(draw: Any, pool: list[Any]) -> dict[str, Any]:
    """Everything of a frame record but its numbers; the frame from ``pool`` (shared objects), now and
    then a copy (equal, not the same object)."""
    frame = draw(st.sampled_from(pool))
    if frame is not None and draw(st.integers(0, 5)) == 0:
        frame = copy.copy(frame)
    direction = draw(st.sampled_from(["host", "device"]))
    raw = draw(st.one_of(st.just(_wire(frame)), st.binary(max_size=24)))
    header = draw(st.one_of(st.none(), st.sampled_from(HEADERS), st.text(max_size=4),
                            st.just(getattr(frame, "HEADER", None))))
    violations = tuple(draw(st.lists(codes, unique=True, max_size=3)))
    n = len(violations)
    aligned = st.lists(st.sampled_from(["host", "device"]), min_size=n, max_size=n)
    sides = draw(st.one_of(st.just(()), aligned.map(tuple)))
    sentences = st.tuples(notes, codes).map(lambda nc: f"{nc[0]} ({nc[1]})")  # a detail of a code
    details = tuple(draw(st.lists(st.one_of(notes, sentences), max_size=3)))
    line_errors = tuple(draw(st.lists(st.one_of(st.just("UART framing error"), notes), max_size=2)))
    return dict(dir=direction, raw=raw, header=header, frame=frame, violations=violations, details=details,
                line_errors=line_errors, sides=sides)





@st.composite
def record_streams(draw: Any) -> list[Record]:
    """Frame records of a few contents (frames shared between contents) with any numbers, junk and
    timeouts among them, and earlier record objects written again."""
    pool = draw(st.lists(st.one_of(st.none(), frames()), min_size=1, max_size=4)) + ODD_FRAMES
    kinds = draw(st.lists(contents(pool), min_size=1, max_size=5))
    records: list[Record] = []
    which = draw(st.lists(st.integers(0, len(kinds) - 1), min_size=1, max_size=24))
    for k, (i, t, reply_to, latency, window) in zip(which, draw(st.lists(
            st.tuples(numbers, times, replies, latencies, st.one_of(st.none(), st.floats(0, 2))),
            min_size=len(which), max_size=len(which))), strict=True):
        records.append(FrameRecord(i=i, t=t, reply_to=reply_to, latency_s=latency, t_last=t, window_s=window,
                                   **kinds[k]))
    for at, t, reply_to, latency in draw(st.lists(st.tuples(st.integers(0, 30), times, replies, latencies),
                                                  max_size=3)):
        records.insert(at, JunkRecord(i=at, t=t, dir=draw(st.sampled_from(["host", "device"])),
                                      raw=draw(st.binary(max_size=8)),
                                      reason=draw(st.sampled_from(["truncated", CAPTURE_ENDED])),
                                      details=("x (garbage)",), reply_to=reply_to, latency_s=latency))
    for at, t, waited in draw(st.lists(st.tuples(st.integers(0, 30), times, latencies), max_size=2)):
        records.insert(at, TimeoutRecord(command=at, t=t, header=draw(st.sampled_from([None, "0RV"])),
                                         waited_s=waited, details=("no answer (no-answer)",)))
    again = draw(st.lists(st.integers(0, len(records) - 1), max_size=10))
    return records + [records[k] for k in again]


@settings(max_examples=budget(60), deadline=None)
@given(record_streams())
def test_views_on_hand_built_records(records):
    """Edge values of every field: the views still say exactly what the records say."""
    assert_views_say_what_records_say(records)


# frames for bytes they may not hold: a command and its echo share their bytes (0WS), equal copies, a
# value that prints like another (True, 1), no frame
SHARED_FRAMES = [fr.WriteOutputs(o=3), fr.WriteOutputsAnswer(o=3), copy.copy(fr.WriteOutputsAnswer(o=3)),
                 fr.WriteOutputs(o=2), fr.ReadPoint(n=1), fr.ReadPoint.unchecked(n=True), fr.ReadPoint(n=2),
                 fr.AlarmAnswer(code=0x0E), fr.ReadVersionAnswer(version="100"), None]


@st.composite
def shared_bytes(draw: Any) -> list[Record]:
    """Clean frame records of two byte strings, each with any frame, header and direction."""
    records: list[Record] = []
    for k in range(draw(st.integers(1, 30))):
        records.append(FrameRecord(
            i=k, t=T0 + k * 0.01, dir=draw(st.sampled_from(["host", "device"])),
            raw=draw(st.sampled_from([b"0WS3\r\n", b"0RP1\r\n"])),
            header=draw(st.sampled_from([None, "0WS", "0RP", spec.ALARM_HEADER, "0RV"])),
            frame=draw(st.sampled_from(SHARED_FRAMES)), reply_to=draw(st.sampled_from([None, k - 1])),
            latency_s=draw(st.sampled_from([None, 0.0021, 0.5]))))
    return records


@settings(max_examples=budget(50), deadline=None)
@given(shared_bytes())
def test_records_sharing_bytes_each_get_their_own_line(records):
    """The views make a frame's part of a line once per distinct frame: a record whose bytes an earlier
    record had, with another frame (even an equal one), header or direction, still gets its own line."""
    assert_one_view_says_what_records_say(records)


def test_record_numbers_of_every_width():
    """The record number's column (``#`` and four wide, wider numbers as they are) for numbers of every
    width, negative ones too, on commands and answers."""
    frame = fr.ReadCurrentAnswer(n=3, v=9, a=3, o=1, pos=0x12345)
    records: list[Record] = [
        FrameRecord(i=i, t=T0 + k, dir=direction, raw=frame.to_bytes(), header=frame.HEADER, frame=frame,
                    reply_to=i - 1, latency_s=0.0021)
        for k, i in enumerate([0, 7, 99, 100, 999, 1000, 9999, 10000, 123456, -1, -999, -1000, -12345])
        for direction in ("host", "device")]
    assert_one_view_says_what_records_say(records)


# latencies (ms) at and around the ties of one-decimal rounding, k.k5, where rounding to 3 decimals first
# can move the digit: exactly on it, 0.0005 either side, and the limits of the text view's shortcut
NEAR_TIES = [0.0, 0.0005, -0.0005, 0.0004999, -0.0005001, 0.0006, -0.0006, 0.00061, -0.00061, 0.001]
latencies_near_ties = st.one_of(
    st.tuples(st.integers(0, 10**7), st.sampled_from(NEAR_TIES)).map(lambda kd: (kd[0] + 0.5) / 10 + kd[1]),
    st.tuples(st.integers(0, 10**7), st.floats(-0.002, 0.002)).map(lambda kd: (kd[0] + 0.5) / 10 + kd[1]),
    st.floats(0, 2e6), st.sampled_from([999999.95, 1e6, 1e6 + 0.05, 0.05, 0.0495, 0.0505]))


@settings(max_examples=budget(150), deadline=None)
@given(st.lists(latencies_near_ties, min_size=1, max_size=20))
def test_text_view_latency_is_round_to_3_then_1_digit(ms):
    """An answer's latency on its text line is ``latency_ms`` (rounded to 3 decimals) shown with one
    decimal, also where rounding twice differs from rounding once (near a tie of the one-decimal
    rounding)."""
    frame = fr.ReadCurrentAnswer(n=3, v=9, a=3, o=1, pos=0x12345)
    records: list[Record] = [
        FrameRecord(i=k, t=T0 + k, dir="device", raw=frame.to_bytes(), header=frame.HEADER, frame=frame,
                    reply_to=k - 1, latency_s=x / 1000.0) for k, x in enumerate(ms)]
    assert_one_view_says_what_records_say(records)


@pytest.mark.parametrize("live", [False, True])
def test_write_many_batches_like_write(live):
    """Offline, ``write_many`` gathers ``BATCH_LINES`` lines a write; live, a write (and flush) a line;
    the text is the same either way."""
    records = [FrameRecord(i=k, t=T0 + k, dir="host", raw=b"0RV\r\n", header="0RV", frame=fr.ReadVersion())
               for k in range(BATCH_LINES + 3)]
    one, many = JsonlView(Writes(), live=live), JsonlView(Writes(), live=live)
    for record in records:
        one.write(record)
    many.write_many(records)
    one.flush()
    many.flush()
    assert one.stream.getvalue() == many.stream.getvalue() == "".join(dumped(r) + "\n" for r in records)
    calls = [c for c in many.stream.calls if c]
    assert len(calls) == (len(records) if live else 2)


# ---------------------------------------------------------------- the pieces ----

def _ties(scale: int, digits: int, count: int) -> list[float]:
    """Floats exactly halfway between two numbers of ``digits`` decimals, from ``scale`` up: the odd
    multiples of ``2**-(digits + 1)`` (``0.0078125`` for 6 digits, ``0.0625`` for 3)."""
    out = [scale + (2 * q + 1) * 2.0 ** -(digits + 1) for q in range(count)]
    assert all((x - math.floor(x)) * 10**digits % 1 == 0.5 for x in out)
    return out


@settings(max_examples=budget(1500), deadline=None)
@given(st.one_of(st.floats(0.001, 2.0**32), st.floats(0.001, 1.0), st.floats(8192, 2.0**32),
                 st.sampled_from([0.001, 2.0**32 - 2**-21, 4294967295.9999995, *_ties(1 << 30, 6, 20),
                                  *_ties(1, 6, 20), *_ties(8192, 6, 20)])))
def test_fixed_is_repr_of_round_to_6_digits(x):
    """A time as ``json.dumps(round(t, 6))``, by the helper and in a record's line."""
    assert json_lines.fixed(x, 6) == repr(round(x, 6))
    assert json_lines.json_t(x) == json.dumps(round(x, 6))
    assert_line_is_dumped(t=x)


@settings(max_examples=budget(1500), deadline=None)
@given(st.one_of(st.floats(0.001, 1e12, exclude_max=True), st.floats(0.001, 100), st.floats(1e9, 1e12),
                 st.sampled_from([0.001, 1.2345, 1.0005, 2.5e-3, 999999999999.9995, 999999999999.9996,
                                  *_ties(1, 3, 20), *_ties(1000, 3, 20)])))
def test_fixed_is_repr_of_round_to_3_digits(x):
    """A latency in ms as ``json.dumps(round(ms, 3))``, by the helper and in a record's line."""
    if x < 1e12:
        assert json_lines.fixed(x, 3) == repr(round(x, 3))
    assert json_lines.json_ms(x / 1000.0) == json.dumps(round(x / 1000.0 * 1000.0, 3))
    assert_line_is_dumped(latency_s=x / 1000.0)


@settings(max_examples=budget(1000), deadline=None)
@given(st.one_of(st.none(), st.floats(), st.sampled_from(EDGE_TIMES + EDGE_LATENCIES), st.integers(),
                 st.booleans()))
def test_json_numbers_of_any_value(x):
    """Whatever ``to_dict`` holds: NaN, infinities, ints, booleans, None."""
    assert json_lines.json_t(x) == json.dumps(None if x is None else round(x, 6))
    assert json_lines.json_ms(x) == json.dumps(None if x is None else round(x * 1000.0, 3))
    assert json_lines.json_number(x) == json.dumps(x)
    assert_line_is_dumped(t=x, latency_s=x, i=x if type(x) is int else 7, reply_to=x)


def assert_line_is_dumped(**numbers: Any) -> None:
    """An answer's JSON line with these numbers is its ``to_dict`` as JSON."""
    frame = fr.ReadCurrentAnswer(n=3, v=9, a=3, o=1, pos=0x12345)
    values = dict(i=7, t=T0, dir="device", raw=frame.to_bytes(), header=frame.HEADER, frame=frame, reply_to=6,
                  latency_s=0.002)
    record = FrameRecord(**{**values, **numbers})
    assert json_lines.JsonLines().line(record) == dumped(record) + "\n"


def datetime_clock(t: Any) -> str:
    """The clock shown for ``t``, straight from ``datetime`` (``?`` and the value when it has none)."""
    if t is None:
        return "-" * 12
    try:
        d = _dt.datetime.fromtimestamp(t)
    except (ValueError, OverflowError, OSError):
        return f"{'?' + repr(t):>12.12}"
    return f"{d.hour:02d}:{d.minute:02d}:{d.second:02d}.{d.microsecond // 1000:03d}"


@contextlib.contextmanager
def time_zone(name: str) -> Iterator[None]:
    """The process's local time zone set to ``name`` (``TZ``), put back after."""
    old = os.environ.get("TZ")
    os.environ["TZ"] = name
    time.tzset()
    try:
        yield
    finally:
        if old is None:
            del os.environ["TZ"]
        else:
            os.environ["TZ"] = old
        time.tzset()


# around whole seconds, where the microseconds round into the next; and DST changes in 2026/2027
BOUNDARIES = [0.0, 0.9999995, 0.99999949999, 0.9999994, 0.0000005, 0.0000004999, 0.0005, 0.9995, 0.5]
DST = [1774746000.0, 1792890000.0, 1775314800.0, 1791043200.0, 1772949600.0, 1793509200.0]
clock_times = st.one_of(st.floats(), st.sampled_from(EDGE_TIMES), st.floats(-3e10, 3e10),
                        st.tuples(st.sampled_from(DST + [T0, -1.0, -3600.0]), st.integers(-7200, 7200),
                                  st.sampled_from(BOUNDARIES)).map(lambda x: x[0] + x[1] + x[2]),
                        st.sampled_from([-0.0, 1, -5, None]))


@st.composite
def runs_of_times(draw: Any) -> list[Any]:
    """Times as a capture has them, many in one second: a start (whole seconds and their boundaries, DST
    changes, small, negative, huge) and steps of up to a third of a second (or exactly onto a boundary)."""
    start = draw(st.one_of(clock_times.filter(lambda t: isinstance(t, float)),
                           st.sampled_from([0.0, 0.4, 5.0, 8191.9999995, 2.0**31 - 0.5, T0 + 0.9999994])))
    steps = draw(st.lists(st.one_of(st.floats(0, 0.34), st.sampled_from([0.0000005, 0.0000001, 0.0005])),
                          max_size=40))
    out = [start]
    for step in steps:
        out.append(out[-1] + step)
    return out


@pytest.mark.parametrize("zone", ["UTC", "Europe/Berlin", "Australia/Lord_Howe", "America/St_Johns"])
@settings(max_examples=budget(60), deadline=None)
@given(st.lists(clock_times, min_size=1, max_size=30), runs_of_times())
@example([T0 + 0.9999996, T0 + 0.5, 3.9999995, 3.25], [T0 + 0.9999995, T0 + 0.75])  # rounded into the next
def test_text_view_clock_is_datetimes(zone, ts, run):
    """The text view's clock column (the last whole second remembered) is ``datetime``'s for every time,
    whatever came before: in and out of order, many in a second, across DST changes (Lord Howe's is
    half an hour), microseconds rounding into the next second, no time, damaged times."""
    with time_zone(zone):
        times = ts + run + sorted(t for t in ts if isinstance(t, float) and not math.isnan(t)) + ts
        records = [FrameRecord(i=k, t=t, dir="host", raw=b"0RV\r\n", header="0RV", frame=fr.ReadVersion())
                   for k, t in enumerate(times)]
        view = TextView(io.StringIO(), color=False, live=False)
        half = len(records) // 2
        view.write_many(records[:half])
        for record in records[half:]:
            view.write(record)
        view.flush()
        shown = [line[:12] for line in view.stream.getvalue().splitlines()]
        assert shown == [datetime_clock(t) for t in times] == [view_mod.show_time(t) for t in times]
