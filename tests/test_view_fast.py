"""The views' templates change no byte: ``JsonlView`` and ``TextView`` (sniffer/view.py: ``_Templates``,
``JsonlView.line``, ``TextView._write_plain``, ``_Clock``, ``_fixed``) write exactly what they wrote
before them, in the same ``write`` calls, raising where they raised.

The code before the templates is kept here as a small reference (``_reference_*``, ``_Reference*``):
the records' ``to_dict`` serialised by ``json.dumps`` (the README's JSON lines), the text view's lines
(plain, batched offline, and coloured by rich) and ``show_time``. The reference is also checked against
today's ``record.to_json()``, so a change to the schema that the templates do not follow fails here.

Record streams: conversations through ``Analyzer`` (the generators of tests/test_decode_equivalence.py,
every violation, junk and timing edge, with and without time; and of tests/test_fastlane_equivalence.py,
whose repeated clean exchanges give the fast lane's clones that share their frame, bytes and verdicts),
written twice (the same record objects again); and hand-built records with edge values (no time,
NaN, infinite, huge, negative and tiny times and latencies, ties of the rounding, no frame, frames
shared by records of other contents and frames equal but not the same, details holding tabs, ``%`` and
the template's own markers, line errors, unknown codes, fields that cannot be hashed). Each stream goes
through views with the default template bound and with bounds of 1 to 3 (templates evicted and made
again), live and offline, record by record and with ``write_many``.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import datetime as _dt
import io
import json
import math
import os
import time
from collections.abc import Iterator
from typing import IO, Any
from unittest import mock

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rich.console import Console
from rich.text import Text
from strategies import frames
from test_decode_equivalence import chunks_of, cuts, events, gaps, line_error_at
from test_fastlane_equivalence import end_of, ops_of, steps

from sniffer import view as view_mod
from sniffer.analyzer import Analyzer
from sniffer.records import CAPTURE_ENDED, FrameRecord, JunkRecord, Record, TimeoutRecord
from sniffer.view import BATCH_LINES, TEMPLATES, JsonlView, TextView
from xac1_proto import frames as fr
from xac1_proto import spec

T0 = 1_790_000_000.0
NAN, INF = float("nan"), float("inf")

# ---------------------------------------------------------------- the references (the code before) ----


def _reference_sides(record: Record) -> list[str]:
    if len(record.sides) == len(record.violations):
        return list(record.sides)
    sender = "device" if record.dir == "device" else "host"
    return [spec.VIOLATION_TABLE[c].side(sender) for c in record.violations]  # type: ignore[arg-type]


def _reference_ms(seconds: Any) -> Any:
    return None if seconds is None else round(seconds * 1000.0, 3)


def _reference_dict(record: Record) -> dict[str, Any]:
    """The records' ``to_dict``."""
    t = None if record.t is None else round(record.t, 6)
    if isinstance(record, TimeoutRecord):
        return {"type": "timeout", "t": t, "dir": record.dir, "command": record.command,
                "header": record.header, "waited_ms": _reference_ms(record.waited_s),
                "violations": list(record.violations), "sides": _reference_sides(record),
                "details": list(record.details)}
    if isinstance(record, JunkRecord):
        out: dict[str, Any] = {"type": "junk", "i": record.i, "t": t, "dir": record.dir,
                               "raw": record.raw.hex(), "violations": list(record.violations),
                               "sides": _reference_sides(record), "reason": record.reason}
        if record.reply_to is not None:
            out["reply_to"] = record.reply_to
            out["latency_ms"] = _reference_ms(record.latency_s)
    else:
        out = {"type": "frame", "i": record.i, "t": t, "dir": record.dir, "raw": record.raw.hex(),
               "header": record.header, "fields": None if record.frame is None else record.frame.fields(),
               "violations": list(record.violations), "sides": _reference_sides(record)}
        if record.dir == "device":
            out["reply_to"] = record.reply_to
            out["latency_ms"] = _reference_ms(record.latency_s)
    if record.details:
        out["details"] = list(record.details)
    if record.line_errors:
        out["line_errors"] = list(record.line_errors)
    return out


def _reference_json(record: Record) -> str:
    return json.dumps(_reference_dict(record), separators=(",", ":"))


_REFERENCE_ESCAPES = {0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}
_REFERENCE_SHOWN = {b: _REFERENCE_ESCAPES.get(b) or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}")
                    for b in range(256)}


def _reference_show_time(t: Any) -> str:
    if t is None:
        return "-" * 12
    try:
        d = _dt.datetime.fromtimestamp(t)
    except (ValueError, OverflowError, OSError):
        return f"{'?' + repr(t):>12.12}"
    return f"{d.hour:02d}:{d.minute:02d}:{d.second:02d}.{d.microsecond // 1000:03d}"


def _reference_violation_parts(record: Record) -> list[list[tuple[str, str]]]:
    out = []
    details = list(record.details)
    for code, side in zip(record.violations, _reference_sides(record), strict=True):
        severity, meaning = spec.VIOLATIONS[code]
        colour = "yellow" if severity == spec.NOTICE else "red"
        suffix = f" ({code})"
        detail = "; ".join(d.removesuffix(suffix) for d in details if d.endswith(suffix))
        mark = "!" if severity == spec.NOTICE else "✗"
        parts = [("      ", ""), (f"{side:<6} {mark} {code}", colour), (f": {meaning}", "")]
        if detail:
            parts += [(" ", ""), (f"— {detail}", "dim")]
        out.append(parts)
    return out


class _ReferenceLines:
    def __init__(self, stream: IO[str], live: bool) -> None:
        self.stream = stream
        self.batched = not live and not stream.isatty()
        self._pending: list[str] = []

    def add(self, line: str) -> None:
        if not self.batched:
            self.stream.write(line)
            return
        self._pending.append(line)
        if len(self._pending) >= BATCH_LINES:
            self.write_pending()

    def write_pending(self) -> None:
        if self._pending:
            self.stream.write("".join(self._pending))
            self._pending.clear()


class _ReferenceJsonlView:
    def __init__(self, stream: IO[str], live: bool) -> None:
        self.stream, self.live, self._lines = stream, live, _ReferenceLines(stream, live)

    def write(self, record: Record) -> None:
        self._lines.add(_reference_json(record) + "\n")
        if self.live:
            self.stream.flush()

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


class _ReferenceTextView:
    def __init__(self, stream: IO[str], color: bool | None, live: bool) -> None:
        self.console = Console(file=stream, force_terminal=color, no_color=color is False,
                               highlight=False, soft_wrap=True, emoji=False)
        self.stream = stream
        self._plain = self.console.color_system is None
        self._lines = _ReferenceLines(stream, live)

    def _print(self, parts: list[tuple[str, str]]) -> None:
        if self._plain:
            plain = "".join(text for text, _ in parts)
            if "\t" not in plain:
                self._lines.add(plain + "\n")
                return
        self._lines.write_pending()
        self.console.print(Text.assemble(*parts))

    def write(self, record: Record) -> None:
        self._print(self.line(record))
        for parts in _reference_violation_parts(record):
            self._print(parts)
        for error in getattr(record, "line_errors", ()):
            self._print([("      ", ""), (f"! line error: {error}", "magenta")])

    def line(self, record: Record) -> list[tuple[str, str]]:
        when = _reference_show_time(record.t)
        if isinstance(record, TimeoutRecord):
            waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
            return [(f"{when}       ", ""),
                    (f"device ✗ no answer to #{record.command} ({record.header or 'unknown'}){waited}",
                     "bold red")]
        arrow = "→" if record.dir == "host" else "←"
        colour = "cyan" if record.dir == "host" else "green"
        raw = record.raw.decode("latin-1").translate(_REFERENCE_SHOWN)
        head = [(f"{when} #{record.i:<4} ", ""), (f"{record.dir:<6} {arrow} {raw:<22}", colour)]
        if isinstance(record, JunkRecord) and record.reason == CAPTURE_ENDED:  # issue 23 item 7
            cut = "" if record.reply_to is None else f", the answer to #{record.reply_to}"
            return [*head, (" ", ""), (f"cut: the capture ended inside this frame{cut} (no violation)",
                                       "yellow")]
        if isinstance(record, JunkRecord):
            return [*head, (" ", ""), (f"junk ({record.reason})", "red")]
        if record.frame is None:
            decoded = f"{record.header or 'unknown'} (not decodable)"
        else:
            decoded = str(record.frame)
            if record.header == spec.ALARM_HEADER:
                decoded += f" ({spec.alarm_meaning(record.frame.fields()['code'])})"
        tail = ""
        if record.dir == "device" and record.reply_to is not None:
            tail = f"  re #{record.reply_to}"
            latency_ms = _reference_ms(record.latency_s)
            if latency_ms is not None:
                tail += f"  {latency_ms:.1f} ms"
        return [*head, (f" {decoded}", ""), (tail, "dim")]

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


# ---------------------------------------------------------------- the comparison ----

class Writes(io.StringIO):
    """A stream (not a terminal) that keeps each ``write`` call."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[str] = []

    def write(self, s: str) -> int:
        self.calls.append(s)
        return super().write(s)


def drive(view: Any, records: list[Record], many: bool) -> tuple[list[str], list[str]]:
    """The records through a view (``write_many``: stopping at the first exception, as a loop of
    ``write`` does); the stream's write calls and the exceptions raised, by type."""
    errors = []
    if many:
        try:
            view.write_many(records)
        except Exception as exc:
            errors.append(type(exc).__name__)
    else:
        for record in records:
            try:
                view.write(record)
            except Exception as exc:
                errors.append(type(exc).__name__)
    view.flush()
    return view.stream.calls, errors


def drive_reference(view: Any, records: list[Record], many: bool) -> tuple[list[str], list[str]]:
    errors = []
    for record in records:
        try:
            view.write(record)
        except Exception as exc:
            errors.append(type(exc).__name__)
            if many:
                break
    view.flush()
    return view.stream.calls, errors


def assert_reference_is_today(records: list[Record]) -> None:
    """The reference JSON is what the records' own ``to_json`` gives (raising where it raises)."""
    for record in records:
        try:
            want = _reference_json(record)
        except Exception as exc:
            with pytest.raises(type(exc)):
                record.to_json()
            continue
        assert record.to_json() == want


def assert_same_output(records: list[Record], size: int = TEMPLATES, live: bool = False,
                       many: bool = False, colour: bool = True) -> None:
    """JSON lines, plain text and (``colour``) coloured text: the same write calls and exceptions as the
    reference, with templates bounded by ``size``."""
    assert_reference_is_today(records)
    json_view = JsonlView(Writes(), live=live)
    json_view._templates.size = size
    assert drive(json_view, records, many) == drive_reference(_ReferenceJsonlView(Writes(), live), records,
                                                                many)
    assert len(json_view._templates) <= size
    kinds: list[bool | None] = [False, True] if colour else [False]
    for color in kinds:
        text_view = TextView(Writes(), color=color, live=live)
        text_view._templates.size = size
        assert drive(text_view, records, many) == drive_reference(
            _ReferenceTextView(Writes(), color, live), records, many), color
        assert len(text_view._templates) <= size


sizes = st.sampled_from([TEMPLATES, TEMPLATES, 1, 2, 3])
modes = st.tuples(sizes, st.booleans(), st.booleans())  # size, live, write_many


# ---------------------------------------------------------------- conversations ----

@settings(max_examples=150, deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at, modes, st.booleans())
@example([], [0.0] * 40, [1], True, set(), (TEMPLATES, False, False), True)
def test_views_on_generated_conversations(items, dts, sizes_, timed, flagged, mode, close_late):
    """Every violation, junk, line errors, timing edges, with and without time; the records written twice
    (the same objects again: the second time from templates)."""
    chunks = chunks_of(items, dts, sizes_, timed, flagged)
    analyzer = Analyzer()
    records: list[Record] = []
    for chunk in chunks:
        records += analyzer.feed(chunk)
    records += analyzer.close((chunks[-1].t or 0.0) + 5.0 if close_late and timed and chunks else None)
    size, live, many = mode
    assert_same_output(records * 2, size, live, many, colour=len(records) < 40)


@settings(max_examples=150, deadline=None)
@given(steps, st.booleans(), st.sampled_from([None, 0.0, 1.0, 5.0]), modes)
def test_views_on_fast_lane_conversations(items, timed, close_after, mode):
    """Clean exchanges repeated (the fast lane's clones share a template's frame and fields) with every
    anomaly the fast lane knows between them, ticks included."""
    ops = ops_of(items, timed)
    analyzer = Analyzer()
    records: list[Record] = []
    for what, arg in ops:
        if what == "feed":
            records += analyzer.feed(arg)
        elif what == "tick":
            records += analyzer.tick(arg)
    records += analyzer.close(None if close_after is None else end_of(ops) + close_after)
    assert analyzer.lane is not None
    size, live, many = mode
    assert_same_output(records, size, live, many, colour=len(records) < 40)


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


STATIC = ["frame", "dir", "raw", "header", "violations", "details", "line_errors", "sides"]


@st.composite
def record_streams(draw: Any) -> list[Record]:
    """Frame records of a few contents (frames shared between contents) with any numbers, junk and
    timeouts among them, and earlier record objects written again."""
    pool = draw(st.lists(st.one_of(st.none(), frames()), min_size=1, max_size=4)) + ODD_FRAMES
    kinds = draw(st.lists(contents(pool), min_size=1, max_size=5))
    probes = []  # a content that differs from another in one field only, each written twice after it
    for k, name in draw(st.lists(st.tuples(st.integers(0, 4), st.sampled_from(STATIC)), max_size=4)):
        k %= len(kinds)
        base = kinds[k]
        if name == "frame" and draw(st.booleans()):
            value: Any = copy.copy(base["frame"])
        elif name == "dir":
            value = "host" if base["dir"] == "device" else "device"
        else:
            value = draw(contents(pool))[name]
        kinds.append({**base, name: value})
        probes += [k, k, len(kinds) - 1, len(kinds) - 1]
    records: list[Record] = []
    which = draw(st.lists(st.integers(0, len(kinds) - 1), min_size=1, max_size=24)) + probes
    for k, (i, t, reply_to, latency, window) in zip(which, draw(st.lists(
            st.tuples(numbers, times, replies, latencies, st.one_of(st.none(), st.floats(0, 2))),
            min_size=len(which), max_size=len(which))), strict=True):
        records.append(FrameRecord(i=i, t=t, reply_to=reply_to, latency_s=latency, t_last=t, window_s=window,
                                   **kinds[k]))
    for at, t, reply_to, latency in draw(st.lists(st.tuples(st.integers(0, 30), times, replies, latencies),
                                                  max_size=3)):
        records.insert(at, JunkRecord(i=at, t=t, dir=draw(st.sampled_from(["host", "device"])),
                                      raw=draw(st.binary(max_size=8)), reason="truncated",
                                      details=("x (garbage)",), reply_to=reply_to, latency_s=latency))
    for at, t, waited in draw(st.lists(st.tuples(st.integers(0, 30), times, latencies), max_size=2)):
        records.insert(at, TimeoutRecord(command=at, t=t, header=draw(st.sampled_from([None, "0RV"])),
                                         waited_s=waited, details=("no answer (no-answer)",)))
    again = draw(st.lists(st.integers(0, len(records) - 1), max_size=10))
    return records + [records[k] for k in again]


@settings(max_examples=300, deadline=None)
@given(record_streams(), modes)
def test_views_on_hand_built_records(records, mode):
    size, live, many = mode
    assert_same_output(records, size, live, many)


# ---------------------------------------------------------------- the pieces ----

def _ties(scale: int, digits: int, count: int) -> list[float]:
    """Floats exactly halfway between two numbers of ``digits`` decimals, from ``scale`` up: the odd
    multiples of ``2**-(digits + 1)`` (``0.0078125`` for 6 digits, ``0.0625`` for 3)."""
    out = [scale + (2 * q + 1) * 2.0 ** -(digits + 1) for q in range(count)]
    assert all((x - math.floor(x)) * 10**digits % 1 == 0.5 for x in out)
    return out


@settings(max_examples=1500, deadline=None)
@given(st.one_of(st.floats(0.001, 2.0**32), st.floats(0.001, 1.0), st.floats(8192, 2.0**32),
                 st.sampled_from([0.001, 2.0**32 - 2**-21, 4294967295.9999995, *_ties(1 << 30, 6, 20),
                                  *_ties(1, 6, 20), *_ties(8192, 6, 20)])))
def test_fixed_is_repr_of_round_to_6_digits(x):
    assert view_mod._fixed(x, 6) == repr(round(x, 6))
    assert view_mod._json_t(x) == json.dumps(round(x, 6))


@settings(max_examples=1500, deadline=None)
@given(st.one_of(st.floats(0.001, 1e12, exclude_max=True), st.floats(0.001, 100), st.floats(1e9, 1e12),
                 st.sampled_from([0.001, 1.2345, 1.0005, 2.5e-3, 999999999999.9995, 999999999999.9996,
                                  *_ties(1, 3, 20), *_ties(1000, 3, 20)])))
def test_fixed_is_repr_of_round_to_3_digits(x):
    if x < 1e12:
        assert view_mod._fixed(x, 3) == repr(round(x, 3))
    assert view_mod._json_ms(x / 1000.0) == json.dumps(round(x / 1000.0 * 1000.0, 3))


@settings(max_examples=1000, deadline=None)
@given(st.one_of(st.none(), st.floats(), st.sampled_from(EDGE_TIMES + EDGE_LATENCIES), st.integers(),
                 st.booleans()))
def test_json_numbers_of_any_value(x):
    """Whatever ``to_dict`` holds: NaN, infinities, ints, booleans, None."""
    assert view_mod._json_t(x) == json.dumps(None if x is None else round(x, 6))
    assert view_mod._json_ms(x) == json.dumps(None if x is None else round(x * 1000.0, 3))
    assert view_mod._json_number(x) == json.dumps(x)


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


@pytest.mark.parametrize("zone", ["UTC", "Europe/Berlin", "Australia/Lord_Howe", "America/St_Johns"])
@settings(max_examples=150, deadline=None)
@given(st.lists(clock_times, min_size=1, max_size=30))
def test_clock_shows_what_show_time_shows(zone, ts):
    """In and out of order, across DST changes (Lord Howe's is half an hour), seconds rounding over."""
    with time_zone(zone):
        clock = view_mod._Clock()
        for t in ts + sorted(t for t in ts if isinstance(t, float) and not math.isnan(t)):
            assert clock.show(t) == _reference_show_time(t) == view_mod.show_time(t), t


@pytest.mark.parametrize("zone", ["Europe/Berlin", "America/St_Johns"])
def test_views_across_a_dst_change(zone):
    """A conversation through the autumn change (the clock goes back an hour)."""
    with time_zone(zone):
        records = _repeated(400, t0=DST[1] - 100.0, step=0.5)
        assert_same_output(records, colour=False)


# ---------------------------------------------------------------- templates are used, bounded, right ----

def _repeated(n: int, t0: float = T0, step: float = 0.01) -> list[Record]:
    """``n`` clean exchanges of three kinds: records of the fast lane (clones sharing their fields)."""
    pairs = [(fr.ReadVersion(), fr.ReadVersionAnswer(version="100")),
             (fr.ReadPoint(n=3), fr.ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x12345)),
             (fr.ReadOutputs(), fr.ReadOutputsAnswer(o=2))]
    analyzer = Analyzer()
    records: list[Record] = []
    from xac1_proto.chunk import DEVICE, HOST, Chunk
    for k in range(n):
        command, answer = pairs[k % 3]
        t = t0 + k * step
        records += analyzer.feed(Chunk(t, HOST, command.to_bytes()))
        records += analyzer.feed(Chunk(t + 0.0021 + k * 1e-7, DEVICE, answer.to_bytes()))
    assert analyzer.lane is not None and analyzer.lane.hits > n // 2
    return records


def test_templates_are_used():
    """After the second record of a content, neither view works the content out again (so the
    comparisons above compare the templates, not the general path with itself)."""
    records = _repeated(300)
    to_dict = mock.patch.object(FrameRecord, "to_dict", autospec=True, side_effect=FrameRecord.to_dict)
    body = mock.patch.object(view_mod, "_body", side_effect=view_mod._body)
    with to_dict as to_dict_calls, body as body_calls:
        assert_same_output(records, colour=False)
    # 6 contents, each twice: its first record by the general path, its second to make the template;
    # to_dict once a record more: the check that the reference is today's to_json
    assert to_dict_calls.call_count == 6 * 2 + len(records)
    assert body_calls.call_count == 6 * 2


def _runs(run: int, rounds: int) -> list[Record]:
    """Runs of ``run`` records of one content, the six contents of ``_repeated`` in turn, ``rounds``
    times (``replace`` keeps the field objects, as the fast lane's clones do)."""
    templates = _repeated(30)[:6]
    out: list[Record] = []
    for n in range(rounds * 6 * run):
        template = templates[n // run % 6]
        device = template.dir == "device"
        out.append(dataclasses.replace(template, i=n, t=T0 + n * 0.01, reply_to=n - 1 if device else None,
                                       latency_s=0.002 + n * 1e-6 if device else None))
    return out


@pytest.mark.parametrize("size", [1, 2, 5, 6, TEMPLATES])
def test_templates_are_evicted_and_made_again(size):
    """Fewer templates allowed than contents in use: the oldest dropped, made again when it comes back
    (on its second record), the output unchanged."""
    records = _runs(3, 4)
    for make_view in (lambda s: JsonlView(s, live=False), lambda s: TextView(s, color=False, live=False)):
        view = make_view(Writes())
        view._templates.size = size
        made: list[Record] = []
        make = view._templates.make
        view._templates.make = lambda record, make=make, made=made: made.append(record) or make(record)
        for record in records:
            view.write(record)
        assert len(view._templates) <= size
        assert len(made) == (6 if size >= 6 else 6 * 4)
        assert [r.i % 3 for r in made] == [1] * len(made)  # each made on the second record of a run
    for many in (False, True):
        assert_same_output(records, size=size, many=many, colour=False)


def test_records_sharing_a_frame_object_or_an_equal_frame():
    """One frame object in records of other bytes, verdicts and direction; frames equal but not the
    same (``N=1`` and ``N=True`` print the same line, not the same JSON)."""
    one, true = fr.ReadPoint.unchecked(n=1), fr.ReadPoint.unchecked(n=True)
    shared = fr.ReadPoint(n=3)
    base = dict(raw=b"0RP1\r\n", header="0RP", violations=(), details=(), line_errors=(), sides=())
    records: list[Record] = []
    for k in range(12):
        frame = (one, true, shared, copy.copy(shared))[k % 4]
        changes: dict[str, Any] = {"frame": frame, "dir": ("host", "device")[k // 4 % 2]}
        if k % 3 == 0:
            changes.update(violations=("letter-o",), details=("a letter O (letter-o)",))
        if k % 5 == 0:
            changes.update(raw=b"ORP3\r\n", line_errors=("UART framing error",))
        records.append(FrameRecord(i=k, t=T0 + k, reply_to=k - 1, latency_s=0.002, **{**base, **changes}))
    for size in (1, 2, TEMPLATES):
        assert_same_output(records * 3, size=size)
    lines = [json.loads(line) for line in drive(JsonlView(Writes(), live=False), records * 3, False)[0][0]
             .splitlines()]
    assert {str(line["fields"]) for line in lines} == {"{'n': 1}", "{'n': True}", "{'n': 3}"}


def test_odd_fields_take_the_general_path_and_raise_as_before():
    """A field that cannot be hashed (a list of codes), an unknown violation code (the text view raised
    after the record's line), an alarm header on a frame without a code, a time that is not a number,
    a tab in a number."""
    rv = fr.ReadVersionAnswer(version="100")
    base = dict(i=1, t=T0, dir="device", raw=b"0RV100\r\n", header="0RV", frame=rv, reply_to=0,
                latency_s=0.002)
    records: list[Record] = [
        FrameRecord(**{**base, "violations": ["echo-mismatch"]}),  # type: ignore[arg-type]
        FrameRecord(**{**base, "violations": ("bogus",), "sides": ("host",)}),  # type: ignore[arg-type]
        FrameRecord(**{**base, "header": "0%%"}),
        FrameRecord(**{**base, "t": "noon"}),  # type: ignore[arg-type]
        FrameRecord(**{**base, "i": None}),  # type: ignore[arg-type]
        FrameRecord(**{**base, "latency_s": "2 ms"}),  # type: ignore[arg-type]
        FrameRecord(**{**base, "reply_to": "1\t2"}),  # type: ignore[arg-type]
    ]
    for size in (1, TEMPLATES):
        for many in (False, True):
            assert_same_output(records * 3, size=size, many=many)
    _, errors = drive(TextView(Writes(), color=False, live=False), records * 3, False)
    assert errors == ["KeyError", "KeyError", "TypeError", "TypeError", "TypeError"] * 3


def test_tabs_are_left_to_the_console():
    """A tab in a detail, a line error or a decoded value: the console expands it, in order with the
    batched lines."""
    tab = fr.ReadVersionAnswer.unchecked(version="1\t0")
    records = [FrameRecord(i=k, t=T0 + k, dir="device", raw=b"0RV1\t0\r\n", header="0RV",
                           frame=(tab, None, fr.ReadVersionAnswer(version="100"))[k % 3], reply_to=k,
                           latency_s=0.001, details=("a\tb (bad-length)",) if k % 2 else (),
                           violations=("bad-length",) if k % 2 else (),
                           line_errors=("x\ty",) if k % 4 else ())
               for k in range(24)]
    for many in (False, True):
        assert_same_output(records * 2, many=many)


def test_write_many_batches_like_write():
    """Offline: the same write calls (batches of ``BATCH_LINES`` lines) from ``write_many`` as from a
    loop of ``write``, for more lines than a batch."""
    records = _repeated(BATCH_LINES // 2 + 100)
    for make in (lambda s: JsonlView(s, live=False), lambda s: TextView(s, color=False, live=False)):
        one, many = make(Writes()), make(Writes())
        for record in records:
            one.write(record)
        many.write_many(iter(records))
        one.flush()
        many.flush()
        assert one.stream.calls == many.stream.calls and len(one.stream.calls) == 2
