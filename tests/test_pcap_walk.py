"""The pcap/pcapng reader's one walk, by its behaviour: what any file gives (whatever the read size),
round trips through the writer, truncation and damage with exact byte accounting, bounded memory, clear
errors, and time running backwards reported (issue 22: one walk, fast and careful; issue 24 item 5).

Files, mostly good records with the odd bad one: pcapng sections in either byte order (SHB; IDBs of
serial and other link types, with if_tsresol of powers of 10 and of 2 or junk options; EPBs on declared
and undeclared interfaces with any times, RTAC events, microseconds and captured lengths, lengths not a
multiple of 4; SPBs; blocks of other types), sections written by ``PcapngWriter`` from arbitrary chunks,
and pcap files of all four magics; then damaged: cut at any offset, bytes overwritten, junk inserted,
bytes deleted, record and block lengths and other fields corrupted. Each is read with several block
sizes (``read(block=...)``, from 1 byte up, so the ends of the blocks read fall everywhere), some with the
smallest look-ahead (``read(look_ahead=1024)``), so resynchronisation slides.
"""

from __future__ import annotations

import dataclasses
import re
import struct
import tempfile
import tracemalloc
from pathlib import Path
from typing import Any, TypeVar

import pytest
from conftest import budget
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from sniffer.io import pcap as pcap_mod
from sniffer.io.base import FormatError, Report, Source, WrongFormat
from xac1_proto.chunk import DEVICE, HOST, Chunk

SMALL_LOOK_AHEAD = 1024  # the smallest look-ahead: resynchronisation slides in small files
PCAP_MAGICS = [b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d"]
MAGIC = {magic: (order, unit) for magic, order, unit in zip(PCAP_MAGICS, "<><>", (1e-6, 1e-6, 1e-9, 1e-9),
                                                            strict=True)}  # byte order, time unit


@dataclasses.dataclass
class LoggedReport(Report):
    """A report that also logs each problem, in order with the chunks, in ``events``."""

    events: list[tuple[Any, ...]] = dataclasses.field(default_factory=list)

    def problem(self, where: str, message: str, *, nbytes: int = 0, nlines: int = 0) -> None:
        self.events.append(("problem", where, message, nbytes, nlines))
        super().problem(where, message, nbytes=nbytes, nlines=nlines)


def outcome(path: Path, host_is: str | None = None, give_up_after: int | None = None, *,
            block: int = pcap_mod.BLOCK,
            look_ahead: int = pcap_mod.LOOK_AHEAD) -> tuple[list[tuple[Any, ...]], dict[str, Any], Any]:
    """Everything reading ``path`` does, in order (chunks and problems), the report, the exception."""
    report = LoggedReport(give_up_after=give_up_after)
    events = report.events
    error = None
    with Source(path, report) as src:
        try:
            for c in pcap_mod.read(src, host_is, block=block, look_ahead=look_ahead):
                report.give_up_after = None  # data came (as xac1 decode does)
                events.append(("chunk", type(c), c.t, c.dir, c.data, c.error))
        except (FormatError, WrongFormat) as exc:  # the reader's own errors; anything else fails the test
            error = (type(exc), str(exc))
    report.events = []
    return events, {**dataclasses.asdict(report), "total": report.total_problems}, error


def read_any_size(path: Path, reads: tuple[int, ...], small: bool = False, host_is: str | None = None,
                  give_up_after: int | None = None) -> Any:
    """What reading ``path`` gives, the same for every block size (the ends of the blocks read fall
    anywhere), with the smallest look-ahead when ``small``; every problem located in the file; no byte
    counted twice."""
    size = path.stat().st_size
    look_ahead = SMALL_LOOK_AHEAD if small else pcap_mod.LOOK_AHEAD
    results = [outcome(path, host_is, give_up_after, block=n, look_ahead=look_ahead) for n in reads]
    for n, result in zip(reads[1:], results[1:], strict=True):
        assert result == results[0], f"block {n} differs from block {reads[0]}"
    events, report, _ = results[0]
    for e in events:
        if e[0] == "problem":
            m = re.fullmatch(re.escape(str(path)) + r":(\d+)(?: \((record|block) \d+\))?", e[1])
            assert m is not None and 0 <= int(m.group(1)) <= size, e
            assert e[3] <= size
    chunk_bytes = sum(len(e[4]) for e in events if e[0] == "chunk")
    assert chunk_bytes + report["unread_bytes"] <= size  # no byte counted twice
    return results[0]


# ---------------------------------------------------------------- building files ----

def block(order: str, block_type: int, body: bytes, padded: bool = True) -> bytes:
    pad = b"\0" * (-len(body) % 4 if padded else 0)
    total = 12 + len(body) + len(pad)
    return struct.pack(order + "II", block_type, total) + body + pad + struct.pack(order + "I", total)


def shb(order: str = "<") -> bytes:
    return block(order, 0x0A0D0D0A, struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1))


def option(order: str, code: int, value: bytes) -> bytes:
    return struct.pack(order + "HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def idb(order: str = "<", linktype: int = 250, options: bytes = b"") -> bytes:
    return block(order, 1, struct.pack(order + "HHI", linktype, 0, 0) + options)


def rtac(event: int, data: bytes = b"", secs: int = 1_790_000_000, usecs: int = 0, lines: int = 0,
         footer: int = 0) -> bytes:
    return struct.pack(">IIBBH", secs, usecs, event, lines, footer) + data


def epb(order: str, payload: bytes, iface: int = 0, ts: int = 0, cap: int | None = None,
        orig: int | None = None, options: bytes = b"", padded: bool = True) -> bytes:
    """An EPB; not ``padded``: its length is not a multiple of 4 (said at both ends all the same)."""
    cap = len(payload) if cap is None else cap
    orig = len(payload) if orig is None else orig
    fields = struct.pack(order + "IIIII", iface, ts >> 32, ts & 0xFFFFFFFF, cap, orig)
    if not padded:
        return block(order, 6, fields + payload + options, padded=False)
    return block(order, 6, fields + payload + b"\0" * (-len(payload) % 4) + options)


def spb(order: str, payload: bytes, orig: int | None = None) -> bytes:
    return block(order, 3, struct.pack(order + "I", len(payload) if orig is None else orig) + payload)




def pcap_header(magic: bytes, linktype: int = 250) -> bytes:
    order = MAGIC[magic][0]
    return magic + struct.pack(order + "HHiIII", 2, 4, 0, 0, 65535, linktype)


def pcap_record(order: str, payload: bytes, sec: int = 1_790_000_000, frac: int = 0, incl: int | None = None,
                orig: int | None = None) -> bytes:
    incl = len(payload) if incl is None else incl
    return struct.pack(order + "IIII", sec, frac, incl, incl if orig is None else orig) + payload


def written(chunks: list[Chunk]) -> bytes:
    """A file of ``PcapngWriter``'s."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "w.pcapng"
        with pcap_mod.PcapngWriter(path) as w:
            for c in chunks:
                w.write(c)
        return path.read_bytes()


# A file is pieces: (bytes, offset of its length field or None, byte order)
Piece = tuple[bytes, "int | None", str]
T = TypeVar("T")


def rarely(common: st.SearchStrategy[T], *rare: st.SearchStrategy[T]) -> st.SearchStrategy[T]:
    """Mostly ``common``, one time in four one of ``rare``: files are mostly good records (the fast
    walk's), with the odd one that is not."""
    return st.integers(0, 3).flatmap(lambda k: st.one_of(*rare) if k == 3 else common)


orders = st.sampled_from("<>")
u32 = st.integers(0, 2**32 - 1)
events_ = rarely(st.sampled_from([1, 2, 3, 4]), st.sampled_from([0, 5, 7, 8]), st.integers(0, 255))
line_data = rarely(st.binary(max_size=24), st.binary(min_size=200, max_size=600))
rtac_times = rarely(st.tuples(st.integers(1_790_000_000, 1_790_000_100), st.integers(0, 999_999)),
                    st.just((0, 0)),  # none: the packet's own time
                    st.tuples(st.sampled_from([0, 2**32 - 1]), st.sampled_from([0, 999_999, 1_000_000])),
                    st.tuples(u32, u32))
timestamps = rarely(st.integers(1_790_000_000_000_000, 1_790_000_100_000_000), st.just(0),
                    st.integers(0, 2**64 - 1))
payloads = rarely(st.builds(lambda event, data, time, lines, footer: rtac(event, data, *time, lines, footer),
                            events_, line_data, rtac_times, st.integers(0, 255), st.integers(0, 0xFFFF)),
                  st.binary(max_size=14))  # shorter than the RTAC header, or just that


@st.composite
def idbs(draw: st.DrawFn, order: str, serial: bool = False) -> Piece:
    if not serial and draw(st.integers(0, 15)) == 0:
        return block(order, 1, draw(st.binary(max_size=7))), 4, order
    kinds = st.sampled_from([250, 147])
    linktype = draw(kinds if serial else rarely(kinds, st.sampled_from([1, 0, 65535]), st.integers(0, 65535)))
    resol = draw(st.one_of(st.sampled_from([6, 9, 0, 3, 0x80 | 10, 0x80 | 20, 0x80]), st.integers(0, 255)))
    options = draw(st.one_of(st.just(b""), st.just(option(order, 9, bytes([resol])) + option(order, 0, b"")),
                             st.just(option(order, 2, b"ttyS0") + option(order, 9, bytes([resol]))),
                             st.binary(max_size=12)))
    return idb(order, linktype, options), 4, order


@st.composite
def epbs(draw: st.DrawFn, order: str) -> Piece:
    payload = draw(payloads)
    iface = draw(rarely(st.just(0), st.integers(0, 3), u32))
    cap = draw(rarely(st.none(), st.integers(0, 600), u32))
    orig = draw(st.one_of(st.none(), u32))
    options = draw(rarely(st.just(b""), st.just(option(order, 1, b"note") + option(order, 0, b""))))
    padded = draw(st.integers(0, 15)) > 0
    return epb(order, payload, iface, draw(timestamps), cap, orig, options, padded), 4, order


@st.composite
def other_blocks(draw: st.DrawFn, order: str) -> Piece:
    if draw(st.booleans()):
        payload = draw(payloads)
        return spb(order, payload, draw(st.one_of(st.none(), st.integers(0, 64), u32))), 4, order
    block_type = draw(st.one_of(st.sampled_from([2, 4, 5, 0x80000001]), u32))
    return block(order, block_type, draw(st.binary(max_size=40))), 4, order


@st.composite
def sections(draw: st.DrawFn) -> list[Piece]:
    """A section header, mostly a serial interface, then mostly packets."""
    order = draw(orders)
    pieces: list[Piece] = [(shb(order), 4, order)]
    if draw(rarely(st.just(True), st.just(False))):
        pieces.append(draw(idbs(order, serial=True)))
    pieces += draw(st.lists(rarely(epbs(order), idbs(order), other_blocks(order)), max_size=10))
    return pieces


chunk_times = st.one_of(st.none(), st.just(0.0), st.floats(1.79e9, 1.8e9), st.floats(0, 1.8e13))
line_errors = st.sampled_from([None, None, "UART framing error", "UART parity error"])
sides = st.sampled_from([HOST, DEVICE])
writer_chunks = st.lists(st.builds(Chunk, chunk_times, sides, st.binary(max_size=30), line_errors),
                         max_size=8)


@st.composite
def pcapng_files(draw: st.DrawFn) -> list[Piece]:
    """Sections: generated ones and ``PcapngWriter``'s (its blocks split at their lengths)."""
    pieces: list[Piece] = []
    for _ in range(draw(st.integers(1, 3))):
        if draw(st.integers(0, 3)) == 0:
            data = written(draw(writer_chunks))
            k = 0
            while k < len(data):
                total = struct.unpack_from("<I", data, k + 4)[0]
                pieces.append((data[k:k + total], 4, "<"))
                k += total
        else:
            pieces += draw(sections())
    return pieces


@st.composite
def pcap_files(draw: st.DrawFn) -> list[Piece]:
    magic = draw(st.sampled_from(PCAP_MAGICS))
    order, unit = MAGIC[magic]
    ticks = round(1 / unit)
    linktype = draw(rarely(st.sampled_from([250, 147, 250 | 0x10000000]), st.sampled_from([1, 0])))
    pieces: list[Piece] = [(pcap_header(magic, linktype), None, order)]
    for _ in range(draw(st.integers(0, 12))):
        sec = draw(rarely(st.integers(1_790_000_000, 1_790_000_100), st.sampled_from([0, 2**32 - 1]), u32))
        frac = draw(rarely(st.integers(0, ticks - 1), st.sampled_from([0, ticks - 1, ticks]), u32))
        incl = draw(rarely(st.none(), st.integers(0, 600), u32))
        orig = draw(rarely(st.none(), u32))
        pieces.append((pcap_record(order, draw(payloads), sec, frac, incl, orig), 8, order))
    return pieces


offsets = st.integers(0, 10**5)
values = st.one_of(st.sampled_from([0, 1, 3, 4, 6, 12, 13, 16, 28, 32, 44, 2**16, 999_999, 1_000_000,
                                    2**20 + 4, 2**32 - 4]), u32)
field_offsets = st.one_of(st.sampled_from([-8, -4, 8, 12, 16, 20, 24, 28, 32, 36]), st.integers(-64, 64))
damages = st.lists(st.one_of(
    st.tuples(st.just("cut"), offsets),
    st.tuples(st.just("set"), offsets, st.binary(min_size=1, max_size=4)),
    st.tuples(st.just("insert"), offsets, st.binary(min_size=1, max_size=16)),
    st.tuples(st.just("delete"), offsets, st.integers(1, 16)),
    st.tuples(st.just("length"), st.integers(0, 100), values),
    st.tuples(st.just("field"), st.integers(0, 100), field_offsets, values)),
    max_size=3)
READS = [1, 2, 5, 16, 61, 100, 509, 4096, 1 << 17]
reads = st.tuples(st.sampled_from(READS[-3:]), st.sampled_from(READS))  # a large read size, and any
host_sides = st.sampled_from([None, None, None, "TX", "RX", "rx", "nobody"])
give_ups = st.sampled_from([None, None, None, 1, 3])


def assemble(pieces: list[Piece], damage: list[tuple[Any, ...]]) -> bytes:
    """The file of ``pieces``, damaged: offsets past its end wrap around; "length" sets the length field
    of a piece's record or block, "field" four bytes at an offset in a piece (from its end if negative),
    in the piece's byte order."""
    data = bytearray(b"".join(p[0] for p in pieces))
    starts = [0]
    for raw, _, _ in pieces:
        starts.append(starts[-1] + len(raw))
    for op, at, *arg in damage:
        if op in ("length", "field"):
            i = at % len(pieces)
            raw, field, order = pieces[i]
            off = field if op == "length" else arg[0] % len(raw) if arg[0] < 0 else arg[0]
            where = starts[i] + (off if off is not None else 0)
            if off is not None and where + 4 <= len(data):
                data[where:where + 4] = struct.pack(order + "I", arg[-1])
            continue
        at %= len(data) + 1
        if op == "cut":
            del data[at:]
        elif op == "set":
            data[at:at + len(arg[0])] = arg[0]
        elif op == "insert":
            data[at:at] = arg[0]
        else:
            del data[at:at + arg[0]]
    return bytes(data)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("pcapwalk")


def save(folder: Path, data: bytes, suffix: str) -> Path:
    path = folder / f"f{suffix}"
    path.write_bytes(data)
    return path


SLOW_OK = [HealthCheck.too_slow, HealthCheck.data_too_large]


def ng(order: str, *blocks: bytes) -> list[Piece]:
    return [(raw, 4, order) for raw in blocks]


def pc(magic: bytes, *records: bytes) -> list[Piece]:
    order = MAGIC[magic][0]
    return [(pcap_header(magic), None, order), *((raw, 8, order) for raw in records)]


NS_LE = b"\x4d\x3c\xb2\xa1"
TSRESOL_2_20 = option(">", 9, bytes([0x80 | 20])) + option(">", 0, b"")
LATE = 1_790_000_000_000_000  # microseconds


# ---------------------------------------------------------------- any file, any read size ----

@settings(max_examples=budget(40), deadline=None, suppress_health_check=SLOW_OK)
@given(pcapng_files(), damages, reads, st.booleans(), host_sides, give_ups)
@example(  # an EPB's length at its end corrupted between good ones
    pieces=ng("<", shb(), idb(), *(epb("<", rtac(k % 2 + 1, b"0RV\r\n", usecs=k)) for k in range(4))),
    damage=[("field", 3, -4, 99)], sizes=(1 << 17, 1), small=False, host_is=None, give_up=None)
@example(  # the latest time an RTAC header says, microseconds 1000000, a packet of another link type, a
    # big-endian section with a 2^-20 s timestamp unit, a length not a multiple of 4 (the rest is lost)
    pieces=ng("<", shb(), idb("<", 1), idb(), epb("<", rtac(1, b"x", 2**32 - 1, 999_999), iface=1),
              epb("<", rtac(2, b"y", 5, 10**6), iface=1, ts=LATE), epb("<", rtac(1, b"n")),
              epb("<", rtac(1, b"zz"), iface=1))
    + ng(">", shb(">"), idb(">", 147, TSRESOL_2_20), epb(">", rtac(1, b"z", 0, 0), ts=LATE),
         epb(">", rtac(2, b"odd"), padded=False), epb(">", rtac(1, b"lost"))),
    damage=[], sizes=(1 << 17, 509), small=True, host_is=None, give_up=None)
@example(  # an IDB's if_tsresol option without its value byte: microseconds
    pieces=ng("<", shb(), idb("<", 250, struct.pack("<HH", 9, 1)), epb("<", rtac(1, b"a"))),
    damage=[], sizes=(4096, 1), small=False, host_is=None, give_up=None)
def test_any_pcapng_file_reads_the_same_whatever_the_read_size(folder, pieces, damage, sizes, small,
                                                                 host_is, give_up) -> None:
    """Any pcapng file, damaged or not, is read to its end without an exception other than the reader's
    own (FormatError, WrongFormat); the same chunks and problems, in the same order, whatever the read
    size; every problem located at an offset in the file; no byte both in a chunk and counted unread."""
    read_any_size(save(folder, assemble(pieces, damage), ".pcapng"), sizes, small, host_is, give_up)


@settings(max_examples=budget(30), deadline=None, suppress_health_check=SLOW_OK)
@given(pcap_files(), damages, reads, st.booleans(), host_sides, give_ups)
@example(  # nanoseconds: the last second of 2^32 with the largest fraction is 2^32 s as a float: out of
    # range, the packet takes the last good time
    pieces=pc(NS_LE, pcap_record("<", rtac(1, b"a", 0, 0)),
              pcap_record("<", rtac(2, b"b", 0, 0), 2**32 - 1, 999_999_999)),
    damage=[], sizes=(4096, 4096), small=False, host_is=None, give_up=None)
@example(  # records (37 bytes) that end where the blocks read (61 bytes) end, then a corrupt length
    pieces=pc(PCAP_MAGICS[0], *(pcap_record("<", rtac(1, b"0RV\r\n0RV")) for _ in range(6))),
    damage=[("length", 4, 2**20 + 4)], sizes=(61, 1), small=False, host_is=None, give_up=3)
@example(  # a whole record longer than the longest taken (small limits), big-endian
    pieces=pc(PCAP_MAGICS[1], *(pcap_record(">", rtac(2, b"0" * n)) for n in (5, 600, 7))),
    damage=[], sizes=(4096, 100), small=True, host_is=None, give_up=None)
def test_any_pcap_file_reads_the_same_whatever_the_read_size(folder, pieces, damage, sizes, small, host_is,
                                                              give_up) -> None:
    """The same for pcap files of the four magics."""
    read_any_size(save(folder, assemble(pieces, damage), ".pcap"), sizes, small, host_is, give_up)


# ---------------------------------------------------------------- round trips and exact accounting ----

# line data as a conversation has it (printable, CR, LF): no run of it looks like a record or a block
line_bytes = st.binary(max_size=30).map(lambda b: bytes(0x20 + x % 0x5F if x % 7 else 0x0A for x in b))
ordered_chunks = st.lists(st.tuples(st.floats(0, 1000), sides, line_bytes, line_errors), max_size=10).map(
    lambda items: [Chunk(1.79e9 + t, d, data, error)
                   for t, (_, d, data, error) in zip(sorted(i[0] for i in items), items, strict=True)])


def expected_back(chunks: list[Chunk]) -> list[tuple[str, bytes, str | None]]:
    """What the writer's file of ``chunks`` reads back as: chunks with bytes, errors on the last data
    direction (RTAC error events carry none)."""
    out, last = [], HOST
    for c in chunks:
        if not c.error:
            last = c.dir
        if c.data or c.error:
            out.append((c.dir if not c.error else last, c.data, c.error))
    return out


def layout(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each pcapng block of a writer's file."""
    spans, k = [], 0
    while k < len(data):
        total = struct.unpack_from("<I", data, k + 4)[0]
        spans.append((k, k + total))
        k += total
    return spans


def as_pcap(data: bytes) -> tuple[bytes, list[tuple[int, int]]]:
    """The packets of a writer's pcapng file as a pcap file, and its records' spans (the header first)."""
    records, spans = [pcap_header(PCAP_MAGICS[0])], [(0, 24)]
    for start, _ in layout(data):
        if struct.unpack_from("<I", data, start)[0] == 6:
            cap = struct.unpack_from("<I", data, start + 20)[0]
            sec, usec = struct.unpack_from(">II", data, start + 28)
            records.append(pcap_record("<", data[start + 28:start + 28 + cap], sec, usec))
            spans.append((spans[-1][1], spans[-1][1] + len(records[-1])))
    return b"".join(records), spans


@settings(max_examples=budget(25), deadline=None, suppress_health_check=SLOW_OK)
@given(ordered_chunks, reads)
def test_writer_files_read_back_as_written(folder, chunks, sizes) -> None:
    """What PcapngWriter writes reads back: every chunk with its bytes, direction and error, its time to
    the microsecond, no problem; the same packets as a pcap file too."""
    data = written(chunks)
    for raw, suffix in ((data, ".pcapng"), (as_pcap(data)[0], ".pcap")):
        events, report, error = read_any_size(save(folder, raw, suffix), sizes)
        back = [e for e in events if e[0] == "chunk"]
        assert error is None and report["total"] == 0 and report["unread_bytes"] == 0
        assert [(e[3], e[4], e[5]) for e in back] == expected_back(chunks)
        kept = [c for c in chunks if c.data or c.error]
        assert all(abs(e[2] - c.t) < 1.5e-6 for e, c in zip(back, kept, strict=True))


@settings(max_examples=budget(30), deadline=None, suppress_health_check=SLOW_OK)
@given(ordered_chunks.filter(bool), st.integers(0, 10**6), st.booleans(), reads)
def test_a_cut_file_gives_every_whole_record_and_counts_the_cut_one(folder, chunks, cut, pcapng, sizes):
    """A file cut at any offset (a capture still being written, a copy cut short): the packets of every
    record or block wholly before the cut come back; the one the cut falls in is one problem located at
    its start, every byte of it that is there counted unread: bytes in chunks, structure of whole records
    and unread bytes add up to the file."""
    data = written(chunks)
    raw, spans = (data, layout(data)) if pcapng else as_pcap(data)
    k = 4 + cut % (len(raw) - 3)  # the magic is there (else it is not a capture at all)
    whole = sum(1 for _, end in spans if end <= k)
    events, report, error = read_any_size(save(folder, raw[:k], ".pcapng" if pcapng else ".pcap"), sizes)
    assert error is None
    packets = whole - (2 if pcapng else 1)  # the SHB and IDB, or the file header, carry none
    chunks_before = [c for c in chunks][:max(packets, 0)]
    assert [(e[3], e[4], e[5]) for e in events if e[0] == "chunk"] == expected_back(chunks_before)
    problems = [e for e in events if e[0] == "problem"]
    if whole == len(spans) or spans[whole][0] == k:
        assert problems == [] and report["unread_bytes"] == 0
    else:
        start = spans[whole][0]
        assert len(problems) == 1 and problems[0][1].split(" ")[0].endswith(f":{start}")
        assert report["unread_bytes"] == k - start
        assert "ends inside" in problems[0][2] or "past the end of the file" in problems[0][2]


@settings(max_examples=budget(25), deadline=None, suppress_health_check=SLOW_OK)
@given(ordered_chunks.filter(lambda c: len(c) >= 2), st.integers(0, 10**6),
       st.lists(st.integers(0xC0, 0xFF), min_size=1, max_size=120), st.booleans(), reads)
def test_junk_between_records_is_counted_exactly_and_reading_goes_on(folder, chunks, at, junk, pcapng, sizes):
    """Junk inside a file (a disk error, two captures glued badly): one problem at its first byte that
    counts exactly its bytes unread; every packet before and after it comes back."""
    data = written(chunks)
    raw, spans = (data, layout(data)) if pcapng else as_pcap(data)
    first = 2 if pcapng else 1
    start = spans[first + at % (len(spans) - first)][0]  # before a packet's record or block
    garbage = bytes(junk)
    if pcapng:
        garbage += bytes(-len(garbage) % 4 * [0xFF])  # pcapng blocks are 4-byte aligned
    path = save(folder, raw[:start] + garbage + raw[start:], ".pcapng" if pcapng else ".pcap")
    events, report, error = read_any_size(path, sizes)
    problems = [e for e in events if e[0] == "problem"]
    assert error is None and len(problems) == 1
    assert problems[0][1].split(" ")[0] == f"{path}:{start}" and problems[0][3] == len(garbage)
    assert report["unread_bytes"] == len(garbage)
    assert [(e[3], e[4], e[5]) for e in events if e[0] == "chunk"] == expected_back(chunks)


def _accounting_pcapng(order: str) -> tuple[bytes, int, int]:
    """A pcapng file with each kind of skipped packet, the last block cut: (file, line bytes, unread)."""
    blocks = [shb(order), idb(order, 250), idb(order, 1),
              epb(order, rtac(1, b"0RV\r\n"), ts=1_790_000_000_000_000),
              epb(order, b"e" * 20, iface=1),  # not serial: 20 unread
              epb(order, rtac(2, b"0RV"), iface=7),  # undeclared: 15
              epb(order, rtac(5, b"abc")),  # not line data: 3
              epb(order, b"short"),  # shorter than the RTAC header: 5
              epb(order, rtac(2, b"x" * 4), cap=99),  # captured length past its block: 16
              spb(order, rtac(2, b"0RV100\r\n")),
              epb(order, rtac(1, b"\xff" * 40))]
    data = b"".join(blocks)[:-30]  # the last block (84 bytes) cut: its first 54 bytes unread
    return data, len(b"0RV\r\n0RV100\r\n"), 20 + 15 + 3 + 5 + 16 + 54


@pytest.mark.parametrize("order", "<>")
@pytest.mark.parametrize("size", [1, 13, 1 << 17])
def test_every_byte_is_line_data_or_counted_unread(folder: Path, order: str, size: int) -> None:
    """Every byte of a packet that is not line data is counted unread, by the problem that says why:
    another link type, an undeclared interface, another event, a packet shorter than the RTAC header, a
    captured length past its block, a block cut by the file's end."""
    data, line, unread = _accounting_pcapng(order)
    events, report, error = read_any_size(save(folder, data, ".pcapng"), (size, 4096))
    assert sum(len(e[4]) for e in events if e[0] == "chunk") == line
    assert report["unread_bytes"] == unread and error is None
    magic = next(m for m in PCAP_MAGICS if MAGIC[m] == (order, 1e-6))
    records = [pcap_header(magic), pcap_record(order, rtac(1, b"0RV\r\n")), pcap_record(order, b"tiny"),
               pcap_record(order, rtac(9, b"zz")), pcap_record(order, rtac(2, b"0RV1\r\n")),
               pcap_record(order, rtac(1, b"cut"))[:-2], ]
    events, report, error = read_any_size(save(folder, b"".join(records), ".pcap"), (size, 4096))
    assert sum(len(e[4]) for e in events if e[0] == "chunk") == 11
    assert report["unread_bytes"] == 4 + 2 + 29 and error is None


# ---------------------------------------------------------------- memory, errors, time ----

def test_memory_is_one_block_and_a_look_ahead(folder: Path) -> None:
    """The reader never holds the file: what it allocates at once is one block read plus a record or a
    damage look-ahead, whatever the file's size."""
    chunks = [Chunk(1.79e9 + k, HOST, b"0RV\r\n" * (k % 7 + 1)) for k in range(3000)]
    data = bytearray(written(chunks))
    k = 0
    while k < len(data) // 2:  # to the block boundary after the middle
        k += struct.unpack_from("<I", data, k + 4)[0]
    data[k:k] = b"junk" * 100
    path = save(folder, bytes(data), ".pcapng")
    report = Report()
    tracemalloc.start()
    try:
        with Source(path, report) as src:
            n = sum(1 for _ in pcap_mod.read(src, block=4096, look_ahead=SMALL_LOOK_AHEAD))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert n == 3000 and report.total_problems == 1
    assert peak < 4096 + SMALL_LOOK_AHEAD + 48 * 1024 < len(data) // 3


def test_errors_say_what_and_where(folder: Path) -> None:
    """A file that is no capture, a capture of another link type, and damage each say what was wrong and
    where (offset, record or block number, expected against seen)."""
    path = save(folder, b"Nope, text", ".pcap")
    assert outcome(path)[2] == (FormatError, f"{path}: not a pcap or pcapng file (first bytes 4e 6f 70 65)")
    events, _, error = outcome(save(folder, pcap_header(PCAP_MAGICS[0], linktype=1), ".pcap"))
    assert error is not None and "pcap link type 1 is not serial (expected 250 RTAC serial or 147 USER0)" \
        in error[1] and ":20:" in error[1]
    good = epb("<", rtac(1, b"0RV\r\n"))
    bad = bytearray(good)
    bad[-4:] = struct.pack("<I", len(good) + 8)
    path = save(folder, shb() + idb() + good + bytes(bad) + good, ".pcapng")
    events, report, _ = outcome(path)
    problems = [e for e in events if e[0] == "problem"]
    offset = len(shb() + idb() + good)
    n = len(good)
    assert [(p[1], p[2]) for p in problems] == [
        (f"{path}:{offset} (block 4)", f"block length {n} at its start but {n + 8} at its end: a corrupt "
                                       f"length or a damaged block; {n} byte(s) skipped to the next "
                                       f"plausible block")]
    assert [e[4] for e in events if e[0] == "chunk"] == [b"0RV\r\n", b"0RV\r\n"]


@pytest.mark.parametrize("pcapng", [True, False])
def test_time_running_backwards_is_a_problem_of_the_capture(folder: Path, pcapng: bool) -> None:
    """A capture whose time jumps back (a day, the clock set back) is reported once, at the record where
    it happens, and its packets are kept with their own times; a step back within a second (two taps'
    delivery order) is no problem (issue 24 item 5, for pcap as for socat)."""
    t0 = 1.79e9
    times = [t0, t0 + 1, t0 + 0.5, t0 + 2, t0 + 2 - 86400, t0 + 3 - 86400, t0 + 4 - 86400]
    chunks = [Chunk(t, HOST if k % 2 == 0 else DEVICE, b"0RV\r\n") for k, t in enumerate(times)]
    data = written(chunks)
    raw, spans = (data, layout(data)) if pcapng else as_pcap(data)
    path = save(folder, raw, ".pcapng" if pcapng else ".pcap")
    events, report, error = outcome(path)
    problems = [e for e in events if e[0] == "problem"]
    assert error is None and len(problems) == 1
    at = spans[(2 if pcapng else 1) + 4][0]
    assert problems[0][1] == f"{path}:{at} ({'block 7' if pcapng else 'record 5'})"
    assert problems[0][2].startswith("time runs backwards: ") and "86400.000000 s before" in problems[0][2]
    assert problems[0][3] == 0  # no byte is lost: the packet is kept
    assert [e[2] for e in events if e[0] == "chunk"] == pytest.approx(times, abs=1e-6)


def test_an_if_tsresol_option_cut_before_its_value_is_the_default(folder: Path) -> None:
    """An IDB whose if_tsresol option has no value byte left (it raised IndexError: a traceback from
    ``xac1 decode``): its packets' times are read in the default unit, microseconds; with the value byte
    (10^-3), in milliseconds."""
    ts = 1_790_000_000_123
    for options, t in ((struct.pack("<HH", 9, 1), ts * 1e-6), (struct.pack("<HHB3x", 9, 1, 3), ts * 1e-3)):
        path = save(folder, shb() + idb("<", 250, options) + epb("<", rtac(1, b"a", 0, 0), ts=ts), ".pcapng")
        events, report, error = outcome(path)
        assert [e[2:5] for e in events] == [(t, HOST, b"a")] and report["total"] == 0 and error is None
