"""The decode speed-ups change no verdict, record, summary or chunk: each optimized piece against the code
it replaced, kept here as a small reference (``_reference_*``), on generated conversations.

Optimized pieces (issue 14) and their references below:
- ``Framer._frame_candidate``: one generated regex search for a cutting header (was a loop over every
  start byte); ``Framer.feed``: a chunk that is exactly one frame, with nothing held, goes straight out;
- ``sniffer.analyzer.to_record`` and ``Analyzer._line_errors``: no per-violation work on clean verdicts;
- ``Tally.add``: no counter updates for records without violations;
- ``FrameRecord.fields``: field names looked up once a frame class (was ``Frame.fields()``);
- ``sniffer.io.base.wallclock``: the whole local second cached (socat headers);
- ``codec.read_frame``: the last distinct lines' readings remembered (frames are immutable);
- ``TextView``: a line is built as styled pieces and, without colour, written as their plain text, in
  batches offline (was rich markup, parsed and printed by the console line by line); ``show_raw`` is one
  ``str.translate``, ``show_time`` formats the fields (was ``strftime``);
- ``Frame.__str__``: the last distinct frames' descriptions remembered (was ``describe`` every time).

Conversations: well-formed frames of every kind, the lines of docs/protocol.md's rule examples (every
violation code), letter O, lower case, bad lengths and terminators, junk, and timing edges around the
answer window, cut into chunks at arbitrary boundaries on both lines, with and without timestamps. The
library path (chunks -> ``Analyzer`` -> records, JSON lines, text lines, summary) and the readers (the same
chunks written as pcapng, possibly damaged, and as a socat log) must give exactly what the references give.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import io
import time
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

import pytest
from conftest import budget
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rich.markup import escape
from strategies import frames

from sniffer import analyzer as analyzer_mod
from sniffer import records as records_mod
from sniffer.analyzer import Analyzer
from sniffer.io import base as base_mod
from sniffer.io import pcap as pcap_mod
from sniffer.io import socat as socat_mod
from sniffer.io.base import Report, shown
from sniffer.io.registry import Capture
from sniffer.records import FrameRecord, JunkRecord, Record, TimeoutRecord, severities_of, sides_of
from sniffer.view import TextView
from xac1_proto import codec as codec_mod
from xac1_proto import conversation as conversation_mod
from xac1_proto import framer as framer_mod
from xac1_proto import frames as frames_mod
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.conversation import Verdict

CORPUS = Path(__file__).parent / "corpus" / "equivalence"

# ---------------------------------------------------------------- the references (the code on main) ----


def _reference_frame_candidate(self: framer_mod.Framer, final: bool) -> framer_mod.Event | None:
    buf = self._buf
    lf = buf.find(framer_mod._LF, 0, self.max_frame)
    limit = lf if lf >= 0 else min(len(buf), self.max_frame)
    for p in [m.start() for m in framer_mod._START_BYTE.finditer(buf, 1, limit)]:
        found = framer_mod._strong_start(buf, p)
        if found == 1:
            return self._emit(p, "truncated")
        if found == framer_mod._UNDECIDED and not final:
            return None
    if lf >= 0:
        return self._emit(lf + 1, None)
    if len(buf) >= self.max_frame:
        return self._emit(self.max_frame, "overflow")
    return self._emit(len(buf), "flushed") if final else None


def _reference_feed(self: framer_mod.Framer, data: bytes, t: float | None = None) -> list[framer_mod.Event]:
    if data:
        self._buf += data
        self._ends.append(self.bytes_in)
        self._times.append(t)
    return self._drain(final=False)


def _reference_to_record(v: Verdict, line_errors: tuple[str, ...] = (), reason: str = "") -> Record:
    details = tuple(x.message for x in v.violations)
    if v.kind == "no-answer":
        assert v.reply_to is not None
        return TimeoutRecord(command=v.reply_to, t=v.t, header=v.header, waited_s=v.waited_s,
                             details=details, sides=v.sides, severities=v.severities)
    assert v.i is not None
    if v.kind == "cut":  # issue 23 item 7: the data ended inside a frame, no violation
        return JunkRecord(i=v.i, t=v.t, dir=v.sender, raw=v.raw, reason=records_mod.CAPTURE_ENDED,
                          violations=(), line_errors=line_errors, reply_to=v.reply_to)
    if v.kind in ("host-junk", "device-junk"):
        return JunkRecord(i=v.i, t=v.t, dir=v.sender, raw=v.raw, reason=reason or "flushed",
                          violations=v.codes, details=details, line_errors=line_errors, sides=v.sides,
                          reply_to=v.reply_to, latency_s=v.latency_s, severities=v.severities)
    return FrameRecord(i=v.i, t=v.t, dir=v.sender, raw=v.raw, header=v.header, frame=v.frame,
                       violations=v.codes, details=details, reply_to=v.reply_to, latency_s=v.latency_s,
                       t_last=v.t_last, line_errors=line_errors, sides=v.sides,
                       window_s=v.waited_s if v.kind == "host-frame" else None, severities=v.severities)


def _reference_line_errors(self: Analyzer, direction: str, offset: int, length: int) -> tuple[str, ...]:
    ranges = self._errors[direction]
    while ranges and ranges[0][1] <= offset:
        ranges.pop(0)
    return tuple(e for start, end, e in ranges if start < offset + length and end > offset)


def _reference_tally_add(self: records_mod.Tally, record: Record) -> None:
    self.codes.update(record.violations)
    for code, side in zip(record.violations, sides_of(record), strict=True):
        self.by_side[side][code] += 1
    if isinstance(record, FrameRecord):
        self.frames[record.dir] += 1
        self.bytes[record.dir] += len(record.raw)
        header = record.header or "?"
        self.line_errors += bool(record.line_errors)
        if record.dir == "host":
            self.commands[header] = self.commands.get(header, 0) + 1  # (plain dicts now)
            self._headers[record.i] = header
            if len(self._headers) > records_mod._MAX_WAITING:
                del self._headers[next(iter(self._headers))]
        else:
            self.answers[header] = self.answers.get(header, 0) + 1
            command = self._headers.pop(record.reply_to, "?") if record.reply_to is not None else "?"
            if record.reply_to is not None and record.latency_s is not None:
                self.latencies.setdefault(command, records_mod.LatencyStats()).add(record.latency_s)
    elif isinstance(record, JunkRecord):
        self.junk_runs += record.reason != records_mod.CAPTURE_ENDED
        self.bytes[record.dir] += len(record.raw)
        self.line_errors += bool(record.line_errors)


def _reference_record_fields(self: FrameRecord) -> dict[str, object] | None:
    return None if self.frame is None else self.frame.fields()


def _reference_text_write(self: TextView, record: Record) -> None:
    """The text view as it was: each line built as rich markup and printed by the console. Three display
    fixes of the new code are applied here too, so the rest can be compared exactly: no emoji codes
    (``:smile:`` in the bytes was shown as an emoji), the raw column padded by the characters shown
    (it was padded with markup escapes counted), and a raw column of 22 characters or more that ends in
    ``\\`` (a backslash byte) keeps both characters (markup halved the backslashes before the closing
    tag)."""
    errors = getattr(record, "line_errors", ())
    for markup in [_reference_line(record), *_reference_violation_lines(record),
                   *(f"      [magenta]! line error: {escape(e)}[/]" for e in errors)]:
        self.console.print(markup, emoji=False)


def _reference_line(record: Record) -> str:
    when = _reference_show_time(record.t)
    if isinstance(record, TimeoutRecord):
        waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
        return (f"{when}       [bold red]device ✗ no answer to #{record.command} "
                f"({record.header or 'unknown'}){waited}[/]")
    arrow = "→" if record.dir == "host" else "←"
    colour = "cyan" if record.dir == "host" else "green"
    raw = escape(f"{_reference_show_raw(record.raw):<22}")
    raw += "\\" * (len(raw) - len(raw.rstrip("\\")))  # fix 3: see _reference_text_write
    head = f"{when} #{record.i:<4} [{colour}]{record.dir:<6} {arrow} {raw}[/]"
    if isinstance(record, JunkRecord) and record.reason == records_mod.CAPTURE_ENDED:
        cut = "" if record.reply_to is None else f", the answer to #{record.reply_to}"
        return f"{head} [yellow]cut: the capture ended inside this frame{cut} (no violation)[/]"
    if isinstance(record, JunkRecord):
        return f"{head} [red]junk ({record.reason})[/]"
    decoded = "?" if record.frame is None else str(record.frame)
    if record.frame is not None and record.header == spec.ALARM_HEADER:
        decoded += f" ({spec.alarm_meaning(record.frame.fields()['code'])})"
    if record.frame is None:
        decoded = f"{record.header or 'unknown'} (not decodable)"
    tail = ""
    if record.dir == "device" and record.reply_to is not None:
        tail = f"  re #{record.reply_to}"
        if record.latency_ms is not None:
            tail += f"  {record.latency_ms:.1f} ms"
    return f"{head} {escape(decoded)}[dim]{tail}[/]"


def _reference_violation_lines(record: Record) -> list[str]:
    out = []
    details = list(record.details)
    for code, side, severity in zip(record.violations, sides_of(record), severities_of(record), strict=True):
        meaning = spec.VIOLATIONS[code][1]  # the record's own severity (issue 35: a rule's, not the code's)
        colour = "yellow" if severity == spec.NOTICE else "red"
        suffix = f" ({code})"
        detail = "; ".join(d.removesuffix(suffix) for d in details if d.endswith(suffix))
        mark = "!" if severity == spec.NOTICE else "✗"
        out.append(f"      [{colour}]{side:<6} {mark} {code}[/]: {escape(meaning)}"
                   + (f" [dim]— {escape(detail)}[/]" if detail else ""))
    return out


def _reference_show_raw(raw: bytes) -> str:
    escapes = {0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}
    return "".join(escapes.get(b) or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}") for b in raw)


def _reference_show_time(t: float | None) -> str:
    if t is None:
        return "-" * 12
    try:
        return _dt.datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")[:-3]
    except (ValueError, OverflowError, OSError):
        return f"{'?' + repr(t):>12.12}"


def _reference_wallclock(date: str, clock: str) -> float:
    try:
        y, m, d = (int(x) for x in date.replace("/", "-").split("-"))
        hms, _, frac = clock.partition(".")
        hh, mm, ss = (int(x) for x in hms.split(":"))
        base = _dt.datetime(y, m, d, hh, mm, ss).timestamp()
        return base + (int(frac[:12]) / 10 ** len(frac[:12]) if frac else 0.0)
    except (ValueError, OverflowError, OSError) as exc:
        raise ValueError(f"impossible date or time {shown(date, 12)} {shown(clock, 24)} ({exc})") from None


_UNCACHED_READ = codec_mod.read_frame.__wrapped__


def _reference_read_frame(data: bytes, role: str) -> codec_mod.Reading:
    """``codec.read_frame`` with nothing remembered."""
    return _UNCACHED_READ(bytes(data), role)  # type: ignore[no-any-return]


@contextlib.contextmanager
def reference() -> Iterator[None]:
    """Every optimized piece swapped for the code it replaced."""
    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch.object(framer_mod.Framer, "_frame_candidate",
                                              _reference_frame_candidate))
        stack.enter_context(mock.patch.object(framer_mod.Framer, "feed", _reference_feed))
        stack.enter_context(mock.patch.object(analyzer_mod, "to_record", _reference_to_record))
        stack.enter_context(mock.patch.object(Analyzer, "_line_errors", _reference_line_errors))
        stack.enter_context(mock.patch.object(records_mod.Tally, "add", _reference_tally_add))
        stack.enter_context(mock.patch.object(FrameRecord, "fields", property(_reference_record_fields)))
        stack.enter_context(mock.patch.object(codec_mod, "read_frame", _reference_read_frame))
        stack.enter_context(mock.patch.object(conversation_mod, "read_frame", _reference_read_frame))
        stack.enter_context(mock.patch.object(socat_mod, "wallclock", _reference_wallclock))
        stack.enter_context(mock.patch.object(TextView, "write", _reference_text_write))
        stack.enter_context(mock.patch.object(frames_mod.Frame, "__str__", frames_mod.describe))
        yield


def test_reference_is_really_swapped_in():
    """The comparison below compares two different codes (else it could not fail)."""
    optimized = framer_mod.Framer._frame_candidate
    with reference():
        assert framer_mod.Framer._frame_candidate is not optimized
        assert socat_mod.wallclock is _reference_wallclock
        assert codec_mod.read_frame is _reference_read_frame
    assert framer_mod.Framer._frame_candidate is optimized


# ---------------------------------------------------------------- the conversations ----

# docs/protocol.md's rule examples: between them every violation code of the engine
HOST_LINES = [b"0RP3\r\n", b"0WP19302012345\r\n", b"0RV\r\n", b"ORV\r\n", b"0%C\r\n", b"0rv\r\n",
              b"0WP1930201abcd\r\n", b"0WS12\r\n", b"0RP3\n", b"0XX\r\n", b"0RP3\r\r\n", b"\x01\x02\r\n",
              b"0RS\r\n", b"0MV3C3001000\r\n", b"0MP5\r\n", b"0RC\r\n", b"0WS32\r\n", b"0CM1\r\n",
              b"0CM0\r\n", b"0WC01\r\n", b"ORP3\r\n", b"0R", b"\r\n", b"0RP30RP3\r\n", b"0" * 70,
              b"[bold]:smile:\t\\[x]\r\n", b"0RV:thumbs_up:\r\n"]
DEVICE_LINES = [b"0RP39302012345\r\n", b"0WP19302012345\r\n", b"0RV100\r\n", b"ORV100\r\n", b"0%%01\r\n",
                b"0%C00\r\n", b"0WS22\r\n", b"0RP49302012345\r\n", b"0%%08\r\n", b"0RC00002000000\r\n",
                b"\xb0RV1\r\n", b"0RS02\r\n", b"0MV3C3001000\r\n", b"0RV100 \r\n", b"0RP39302abcdef\r\n",
                b"0WS32\r\n", b"0CM1\r\n", b"0%%02\r\n", b"0%%0E\r\n", b"0RV1", b"0RV100\n", b"0RV10O"]
# gaps around the answer window (1 s), the device's idle flush (1 s) and move estimates
GAPS = [0.0, 0.001, 0.002, 0.0999, 0.5, 0.999999, 1.0, 1.000001, 1.5, 3.0, 30.0]

host_bytes = st.one_of(st.sampled_from(HOST_LINES), frames("command").map(lambda f: f.to_bytes()),
                       st.binary(max_size=18))
device_bytes = st.one_of(st.sampled_from(DEVICE_LINES), frames("answer").map(lambda f: f.to_bytes()),
                         st.binary(max_size=18))
events = st.lists(st.one_of(st.tuples(st.just(HOST), host_bytes), st.tuples(st.just(DEVICE), device_bytes)),
                  max_size=40)
gaps = st.lists(st.one_of(st.sampled_from(GAPS), st.floats(0, 3.0)), min_size=40, max_size=40)
cuts = st.lists(st.integers(1, 9), min_size=1, max_size=8)
line_error_at = st.sets(st.integers(0, 39), max_size=3)


def chunks_of(items: list[tuple[str, bytes]], dts: list[float], sizes: list[int], timed: bool,
              flagged: set[int] = frozenset()) -> list[Chunk]:  # type: ignore[assignment]
    """The conversation as chunks: each line's bytes cut into pieces (sizes cycled), times rising."""
    out: list[Chunk] = []
    t, k = 1_790_000_000.0, 0
    for n, ((who, data), dt) in enumerate(zip(items, dts, strict=False)):
        t += dt
        p = 0
        while p < len(data):
            size = sizes[k % len(sizes)]
            k += 1
            piece = data[p:p + size]
            p += size
            t += len(piece) / 960
            error = "UART framing error" if n in flagged else None
            out.append(Chunk(t if timed else None, who, piece, error))
    return out


# ---------------------------------------------------------------- the library path ----

def library_outputs(chunks: list[Chunk], close_at: float | None = None) -> tuple:
    """Everything the library path gives: records, their JSON lines and text lines, the summary."""
    analyzer = Analyzer()
    records: list[Record] = []
    for chunk in chunks:
        records += analyzer.feed(chunk)
    records += analyzer.close(close_at)
    printed = []
    for color in (None, False, True):  # a file or pipe, --no-color (both plain), and colour forced
        stream = io.StringIO()
        text = TextView(stream, color=color)
        for r in records:
            text.write(r)
        text.summary(analyzer.summary())
        printed.append(stream.getvalue())
    counted = records_mod.Tally()  # the summary counted from the records (the analyzer counts verdicts)
    for record in records:
        counted.add(record)
    counted.unanswered = analyzer.tally.unanswered
    return records, [r.to_json() for r in records], printed, analyzer.summary(), counted.summary()


def assert_library_equal(chunks: list[Chunk], close_at: float | None = None) -> None:
    optimized = library_outputs(chunks, close_at)
    with reference():
        expected = library_outputs(chunks, close_at)
    assert optimized[0] == expected[0]  # records, field by field (frames included)
    assert optimized[1] == expected[1]  # JSON lines
    assert optimized[2] == expected[2]  # the text view as printed
    assert optimized[3] == optimized[4] == expected[4]  # summary: of the verdicts, of the records


@settings(max_examples=budget(300), deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at)
@example([(HOST, b"0RP3\r\n"), (DEVICE, b"0RP39302012345\r\n")], [0.0] * 40, [1], True, set())
@example([(HOST, b"0RP30RP3\r\n"), (DEVICE, b"0RV1"), (DEVICE, b"00\r\n")], [1.0] * 40, [2, 3], True, {1})
@example([(HOST, b"\x00" * 5), (HOST, b"\\")], [0.0] * 40, [64], False, set())  # raw ending in a backslash
def test_library_path_gives_the_references_records_and_summary(items, dts, sizes, timed, flagged):
    assert_library_equal(chunks_of(items, dts, sizes, timed, flagged))


@settings(max_examples=budget(60), deadline=None)
@given(events, gaps, st.booleans())
def test_close_with_a_time_gives_the_references_records(items, dts, timed):
    chunks = chunks_of(items, dts, [64], timed)
    assert_library_equal(chunks, close_at=(chunks[-1].t or 0) + 5.0 if chunks and timed else None)


def corpus_cases() -> list[Path]:
    return sorted(CORPUS.glob("*.txt"))


def read_corpus_case(path: Path) -> tuple[list[tuple[str, bytes]], list[float]]:
    """A corpus file's ``<H|D> <gap s> <hex>`` lines (``#`` comments) as (direction, bytes) and gaps."""
    items, dts = [], []
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            who, gap, data = line.split(maxsplit=2)
            items.append((HOST if who == "H" else DEVICE, bytes.fromhex(data)))
            dts.append(float(gap))
    assert items, f"{path}: no lines"
    return items, dts


@pytest.mark.parametrize("path", corpus_cases(), ids=lambda p: p.stem)
def test_corpus_of_hard_cases(path):
    """Derandomized hard cases, one per file: ``<dir> <gap s> <hex>`` lines, fed whole and byte by byte."""
    items, dts = read_corpus_case(path)
    for timed in (True, False):
        for sizes in ([64], [1], [2, 5]):
            assert_library_equal(chunks_of(items, dts, sizes, timed))


def test_corpus_is_there():
    assert len(corpus_cases()) >= 5


# ---------------------------------------------------------------- the readers ----

def read_all(path: Path, fmt: str) -> tuple[list[Chunk], list[str]]:
    report = Report()
    with Capture([str(path)], fmt, report=report) as capture:
        got = list(capture)
    return got, list(report.problems)


def write_socat(chunks: list[Chunk], path: Path) -> None:
    """A socat ``-x`` dump (host ``>``) with microsecond fractions."""
    count = {HOST: 0, DEVICE: 0}
    with open(path, "w", encoding="ascii") as f:
        for ch in chunks:
            t = ch.t or 0.0
            stamp = time.strftime("%Y/%m/%d %H:%M:%S", time.localtime(t)) + f".{int(t % 1 * 1e6):06d}"
            start = count[ch.dir]
            count[ch.dir] += len(ch.data)
            f.write(f"{'>' if ch.dir == HOST else '<'} {stamp}  length={len(ch.data)} from={start} "
                    f"to={count[ch.dir] - 1}\n {ch.data.hex(' ')}\n")


@settings(max_examples=budget(120), deadline=None)
@given(events, gaps, cuts, st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255)), max_size=3),
       st.one_of(st.none(), st.integers(0, 10_000)))
def test_pcapng_reader_gives_the_references_chunks_and_problems(tmp_path_factory, items, dts, sizes,
                                                                  damage, cut):
    """Same chunks and the same problems (damaged and cut-short files included), and the records the
    library path makes of them are the reference's."""
    chunks = chunks_of(items, dts, sizes, timed=True)
    path = tmp_path_factory.mktemp("pcapng") / "c.pcapng"
    with pcap_mod.PcapngWriter(path) as w:
        for ch in chunks:
            w.write(ch)
    data = bytearray(path.read_bytes())
    for at, value in damage:
        if 28 < at < len(data):  # the section header stays: damage inside the blocks
            data[at] = value
    path.write_bytes(bytes(data[:cut]) if cut is not None and cut > 28 else bytes(data))
    optimized = read_all(path, "pcap")
    with reference():
        expected = read_all(path, "pcap")
    assert optimized == expected
    if not damage and cut is None:
        assert [(c.dir, c.data) for c in optimized[0]] == [(c.dir, c.data) for c in chunks]
    assert_library_equal(optimized[0])


@settings(max_examples=budget(60), deadline=None)
@given(events, gaps, cuts)
def test_socat_reader_gives_the_references_chunks(tmp_path_factory, items, dts, sizes):
    chunks = chunks_of(items, dts, sizes, timed=True)
    path = tmp_path_factory.mktemp("socat") / "c.log"
    write_socat(chunks, path)
    optimized = read_all(path, "socat")
    with reference():
        expected = read_all(path, "socat")
    assert optimized == expected
    assert [(c.dir, c.data) for c in optimized[0]] == [(c.dir, c.data) for c in chunks]


def test_pcap_buffer_reads_large_blocks_and_peeks_across_them(tmp_path):
    """The block buffer: peeks spanning reads, skips past the end, offsets counted."""
    path = tmp_path / "b.bin"
    data = bytes(range(256)) * 1024  # 256 KiB: several reads
    path.write_bytes(data)
    src = base_mod.Source(str(path), Report())
    try:
        buf = pcap_mod._Buffer(src)
        assert buf.peek(4) == data[:4]
        buf.skip(pcap_mod._READ - 2)
        assert buf.peek(8) == data[pcap_mod._READ - 2:pcap_mod._READ + 6]  # across two reads
        assert buf.offset == pcap_mod._READ - 2
        buf.skip(len(data))
        assert buf.offset == len(data) and buf.peek(4) == b""
    finally:
        src.close()

