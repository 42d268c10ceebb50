"""The decoder's answer does not depend on how the bytes came: the same records, JSON lines, text lines and
summary for any chunking of a capture (whole lines, any cuts, byte by byte) and any batch size
(``Analyzer.feed_many``'s ``limit``); and the readers give back the chunks written.

Conversations: well-formed frames of every kind, the lines of docs/protocol.md's rule examples (every
violation code), letter O, lower case, bad lengths and terminators, junk, and timing edges around the
answer window, on both lines, with and without timestamps; plus a corpus of hard cases
(``tests/corpus/equivalence``). A line's pieces arrive at the line's time, so only the cutting differs
between the runs compared: the usual chunk (one whole frame) and any other cut must give the same.
"""

from __future__ import annotations

import io
import itertools
import time
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import example, given, settings
from hypothesis import strategies as st
from strategies import frames

from sniffer import records as records_mod
from sniffer.analyzer import Analyzer
from sniffer.io import pcap as pcap_mod
from sniffer.io.base import Report
from sniffer.io.registry import Capture
from sniffer.records import Record
from sniffer.view import TextView
from xac1_proto.chunk import DEVICE, HOST, Chunk

CORPUS = Path(__file__).parent / "corpus" / "equivalence"

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
              flagged: set[int] = frozenset(), spread: bool = True) -> list[Chunk]:  # type: ignore[assignment]
    """The conversation as chunks: each line's bytes cut into pieces (sizes cycled), times rising (with
    ``spread`` False every piece of a line has the line's time and a flagged line, the tool's note on one
    chunk, comes whole: only the cutting differs)."""
    out: list[Chunk] = []
    t, k = 1_790_000_000.0, 0
    for n, ((who, data), dt) in enumerate(zip(items, dts, strict=False)):
        t += dt
        p = 0
        while p < len(data):
            size = sizes[k % len(sizes)] if spread or n not in flagged else len(data)
            k += 1
            piece = data[p:p + size]
            p += size
            t += len(piece) / 960 if spread else 0.0
            error = "UART framing error" if n in flagged else None
            out.append(Chunk(t if timed else None, who, piece, error))
    return out


# ---------------------------------------------------------------- the library path ----

def library_outputs(chunks: list[Chunk], close_at: float | None = None, limit: int | None = None) -> tuple:
    """Everything the library path gives: records, their JSON lines and text lines, the summary (of the
    verdicts, and counted again from the records). ``limit``: chunks fed through ``feed_many`` in
    batches of that many; None: one ``feed`` a chunk."""
    analyzer = Analyzer()
    records: list[Record] = []
    if limit is None:
        for chunk in chunks:
            records += analyzer.feed(chunk)
    else:
        it = iter(chunks)
        while analyzer.feed_many(it, records, limit=limit):
            pass
    records += analyzer.close(close_at)
    printed = []
    for color in (None, False, True):  # a file or pipe, --no-color (both plain), and colour forced
        stream = io.StringIO()
        text = TextView(stream, color=color)
        text.write_many(records)
        text.summary(analyzer.summary())
        printed.append(stream.getvalue())
    counted = records_mod.Tally()  # the summary counted from the records (the analyzer counts verdicts)
    for record in records:
        counted.add(record)
    counted.unanswered = analyzer.tally.unanswered
    assert analyzer.summary() == counted.summary()
    return records, [r.to_json() for r in records], printed, analyzer.summary()


def assert_same_for_any_cut(items: list[tuple[str, bytes]], dts: list[float], sizes: list[int], timed: bool,
                            flagged: set[int] = frozenset(), close_late: bool = False) -> None:  # type: ignore[assignment]
    """Whole lines, the given cuts and byte by byte give the same records, lines and summary."""
    runs = [chunks_of(items, dts, cut, timed, flagged, spread=False) for cut in ([64], sizes, [1])]
    last = max((c.t for c in runs[0] if c.t is not None), default=None)
    close_at = last + 5.0 if close_late and last is not None else None
    whole = library_outputs(runs[0], close_at)
    for chunks in runs[1:]:
        got = library_outputs(chunks, close_at)
        assert got[0] == whole[0]  # records, field by field (frames included)
        assert got[1] == whole[1]  # JSON lines
        assert got[2] == whole[2]  # the text view as printed
        assert got[3] == whole[3]  # the summary


@settings(max_examples=budget(300), deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at)
@example([(HOST, b"0RP3\r\n"), (DEVICE, b"0RP39302012345\r\n")], [0.0] * 40, [1], True, set())
@example([(HOST, b"0RP30RP3\r\n"), (DEVICE, b"0RV1"), (DEVICE, b"00\r\n")], [1.0] * 40, [2, 3], True, {1})
@example([(HOST, b"\x00" * 5), (HOST, b"\\")], [0.0] * 40, [64], False, set())  # raw ending in a backslash
def test_any_chunking_gives_the_same_records_lines_and_summary(items, dts, sizes, timed, flagged):
    """A capture's records, JSON lines, text lines and summary are the same whether each line comes as
    one chunk (the usual whole frame), cut anywhere, or byte by byte; line errors stay with their bytes."""
    assert_same_for_any_cut(items, dts, sizes, timed, flagged)


@settings(max_examples=budget(60), deadline=None)
@given(events, gaps, cuts, st.booleans())
def test_any_chunking_closed_late_gives_the_same_records(items, dts, sizes, timed):
    """Closed at a time after the last byte (missed answers expire then): still the same for any cut."""
    assert_same_for_any_cut(items, dts, sizes, timed, close_late=True)


@settings(max_examples=budget(100), deadline=None)
@given(events, gaps, cuts, st.booleans(), st.integers(1, 50))
def test_any_batch_size_gives_what_feed_gives(items, dts, sizes, timed, limit):
    """``feed_many(chunks, out, limit=N)`` for any N gives the records, lines and summary that one
    ``feed`` a chunk gives."""
    chunks = chunks_of(items, dts, sizes, timed)
    assert library_outputs(chunks, limit=limit) == library_outputs(chunks)


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
    """Derandomized hard cases, one per file: the same records whole, cut in twos and fives, byte by byte,
    timed or not, closed at the end or later, and in batches of any size."""
    items, dts = read_corpus_case(path)
    for timed, late in itertools.product((True, False), (False, True)):
        assert_same_for_any_cut(items, dts, [2, 5], timed, close_late=late)
    chunks = chunks_of(items, dts, [3], True)
    assert library_outputs(chunks, limit=7) == library_outputs(chunks)


def test_corpus_is_there():
    """The corpus of hard cases has not gone missing (the test above would then pass on nothing)."""
    assert len(corpus_cases()) >= 5


# ---------------------------------------------------------------- the readers ----

def read_all(path: Path, fmt: str) -> tuple[list[Chunk], list[str]]:
    """Every chunk a reader gives of a file, and the problems it reported."""
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
@given(events, gaps, cuts, st.one_of(st.none(), st.integers(29, 10_000)))
def test_pcapng_reader_gives_back_the_chunks_written(tmp_path_factory, items, dts, sizes, cut):
    """A pcapng file read back gives the chunks written, direction, bytes and time; a file cut short gives
    a first part of them and says that something was lost, unless it was cut between two blocks (then it
    is a whole, shorter file)."""
    chunks = chunks_of(items, dts, sizes, timed=True)
    path = tmp_path_factory.mktemp("pcapng") / "c.pcapng"
    with pcap_mod.PcapngWriter(path) as w:
        for ch in chunks:
            w.write(ch)
    data = path.read_bytes()
    if cut is not None:
        path.write_bytes(data[:cut])
    got, problems = read_all(path, "pcap")
    written = [(c.dir, c.data) for c in chunks]
    read = [(c.dir, c.data) for c in got]
    assert read == written[:len(read)]
    assert all(abs(a.t - b.t) < 2e-6 for a, b in zip(got, chunks, strict=False))  # type: ignore[operator]
    if cut is None or cut >= len(data):
        assert read == written and problems == []
    elif len(read) < len(written) and cut not in _block_ends(data):
        assert problems != []


def _block_ends(data: bytes) -> set[int]:
    """The offsets just past each block of a (little-endian, as the writer writes) pcapng file."""
    ends, offset = set(), 0
    while offset + 8 <= len(data):
        offset += int.from_bytes(data[offset + 4:offset + 8], "little")
        ends.add(offset)
    return ends


@settings(max_examples=budget(60), deadline=None)
@given(events, gaps, cuts)
def test_socat_reader_gives_back_the_chunks_written(tmp_path_factory, items, dts, sizes):
    """A socat ``-x`` log read back gives the chunks written: direction, bytes and time (to the
    microsecond the log keeps), and no problem."""
    chunks = chunks_of(items, dts, sizes, timed=True)
    path = tmp_path_factory.mktemp("socat") / "c.log"
    write_socat(chunks, path)
    got, problems = read_all(path, "socat")
    assert [(c.dir, c.data) for c in got] == [(c.dir, c.data) for c in chunks]
    assert all(abs(a.t - b.t) < 2e-6 for a, b in zip(got, chunks, strict=True))  # type: ignore[operator]
    assert problems == []
