"""The pcap reader's fast walk changes no chunk and no problem: ``sniffer.io.pcap.read`` against the reader
as it was before the fast walk, kept here as a small reference (``_reference_*``: its buffer, its record
and block loops and its packet code; the resynchronisation and damage helpers it called are unchanged
and shared), on generated files.

What is compared, for every file: the whole stream of what reading does, in order: each chunk (type,
fields, repr) and each problem (where, message, bytes and lines counted), so a problem said before
instead of after a chunk is a difference; then the report (kept messages, counters) and the exception
that ended reading, if any (a non-serial pcap link type, a wrong ``--host-is``, ``WrongFormat`` from
``give_up_after``, which is cleared at the first chunk as ``xac1 decode`` does).

Files, mostly good records with the odd bad one: pcapng sections in either byte order (SHB; IDBs of
serial and other link types, with if_tsresol of powers of 10 and of 2 or junk options; EPBs on declared
and undeclared interfaces with any times, RTAC events, microseconds and captured lengths, lengths not a
multiple of 4; SPBs; blocks of other types), sections written by ``PcapngWriter`` from arbitrary chunks,
and pcap files of all four magics; then damaged: cut at any offset, bytes overwritten, junk inserted,
bytes deleted, record and block lengths and other fields corrupted. Each is read by the reference once
and by the reader with two read sizes (``_READ``, from 1 byte up, so the ends of the blocks read fall
everywhere) and with a buffer that has no block (the careful walk alone); some with small look-ahead
limits (``_SCAN``, ``_RESYNC_MAX``, ``_MAX_RECORD``), so resynchronisation slides. The ``@example``s are
the cases a wrong fast walk gets wrong first (each check it makes, the state it hands back). Then: the
bytes are accounted exactly (line data in chunks, the rest counted unread), the fast walk really reads
(few careful records on a clean file), memory stays one block and a look-ahead, and ``new_chunk``
builds a ``Chunk``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import pickle
import struct
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar
from unittest import mock

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from sniffer.io import pcap as pcap_mod
from sniffer.io.base import Clock, FormatError, Report, Sides, Source
from xac1_proto.chunk import DEVICE, HOST, Chunk, Direction, new_chunk

# ---------------------------------------------------------------- the reference (the reader before) ----

_REFERENCE_READ = 1 << 16


class _ReferenceBuffer:
    """The buffer as it was (it has no ``window``: given to the reader, it walks carefully only)."""

    def __init__(self, src: Source) -> None:
        self.src = src
        self._block = b""
        self._pos = 0
        self.offset = 0

    def peek(self, n: int) -> bytes:
        end = self._pos + n
        if end > len(self._block):
            self._fill(n)
            end = n
        return self._block[self._pos:end]

    def _fill(self, n: int) -> None:
        parts = [self._block[self._pos:]]
        have = len(parts[0])
        while have < n:
            more = self.src.read(max(n - have, _REFERENCE_READ))
            if not more:
                break
            parts.append(more)
            have += len(more)
        self._block = b"".join(parts)
        self._pos = 0

    def skip(self, n: int) -> None:
        self.peek(n)
        n = min(n, len(self._block) - self._pos)
        self._pos += n
        self.offset += n


def _reference_read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    p = pcap_mod
    buf = _ReferenceBuffer(src)
    magic = buf.peek(4)
    if magic in p._PCAP_MAGIC:
        packets = _reference_pcap_packets(src, buf, magic)
    elif magic == p._SHB:
        packets = _reference_pcapng_packets(src, buf)
    else:
        raise FormatError(f"{src.name}: not a pcap or pcapng file (first bytes {magic.hex(' ')})")
    sides = Sides("pcap", host_is, ("TX", "RX"))
    clock = Clock(src.report)
    last: Direction | None = None
    for where, t, payload in packets:
        if len(payload) < p.RTAC_HEADER.size:
            src.report.problem(where, f"packet of {len(payload)} bytes is shorter than the 12-byte RTAC "
                                      f"serial header", nbytes=len(payload))
            continue
        secs, usecs, event, _lines, _footer = p.RTAC_HEADER.unpack_from(payload)
        data = payload[p.RTAC_HEADER.size:]
        if usecs >= 1_000_000:
            src.report.problem(where, f"RTAC header microseconds {usecs} is not below 1000000; the "
                                      f"packet's own time is used")
        elif secs or usecs:
            t = secs + usecs / 1e6
        t = clock.check(t, where)
        if event in p.TX_EVENTS or event in p.RX_EVENTS:
            d = sides.direction("TX" if event in p.TX_EVENTS else "RX")
            assert d is not None
            last = d
            if data:
                yield Chunk(t, d, data)
        elif event in p.ERROR_EVENTS:
            yield Chunk(t, last or HOST, data, p.ERROR_EVENTS[event])
        elif data:
            src.report.problem(where, f"RTAC event 0x{event:02x} carries {len(data)} byte(s) that are "
                                      f"not line data; skipped", nbytes=len(data))


def _reference_pcap_packets(src: Source, buf: Any, magic: bytes) -> Iterator[tuple[str, float | None, bytes]]:
    p = pcap_mod
    order, unit = p._PCAP_MAGIC[magic]
    header = buf.peek(24)
    if len(header) < 24:
        src.report.problem(src.at(0), f"the file ends inside the 24-byte pcap file header "
                                      f"({len(header)} byte(s))", nbytes=len(header))
        return
    linktype = struct.unpack(order + "HHiIII", header[4:])[5] & 0x0FFFFFFF
    if linktype not in p.SERIAL_LINKTYPES:
        raise FormatError(f"{src.at(20)}: pcap link type {linktype} is not serial (expected "
                          f"{p.LINKTYPE_RTAC_SERIAL} RTAC serial or {p.LINKTYPE_USER0} USER0)")
    buf.skip(24)
    ticks = round(1 / unit)
    n = 0
    last_sec: int | None = None
    while True:
        off = buf.offset
        rec = buf.peek(16)
        if not rec:
            return
        n += 1
        where = f"{src.at(off)} (record {n})"
        if len(rec) < 16:
            src.report.problem(where, f"the file ends inside a record header: {16 - len(rec)} byte(s) "
                                      f"missing of 16", nbytes=len(rec))
            return
        sec, frac, incl, orig = struct.unpack(order + "IIII", rec)
        why = None
        if incl > p._MAX_RECORD:
            why = f"corrupt length {incl} (expected at most {p._MAX_RECORD})"
        elif frac >= ticks:
            why = f"corrupt time: fraction {frac} (expected below {ticks})"
        else:
            whole = buf.peek(16 + incl)
            if len(whole) < 16 + incl:
                left = len(whole) - 16
                if p._pcap_resync(buf.offset, off + 1, buf.peek(p._SCAN), order=order, ticks=ticks,
                                  last_sec=last_sec) is None:
                    src.report.problem(where, f"corrupt length {incl}: the record runs "
                                              f"{incl - left} byte(s) past the end of the file ({left} "
                                              f"left; or the file was cut short inside it)",
                                       nbytes=len(whole))
                    buf.skip(len(whole))
                    return
                why = (f"corrupt length {incl}: the record runs {incl - left} byte(s) past the end of "
                       f"the file")
        if why is not None:
            scan = lambda base, start, window, s=last_sec: p._pcap_resync(  # noqa: E731
                base, start, window, order=order, ticks=ticks, last_sec=s)
            if not p._skip_damage(src, buf, where, why, off + 1, scan, "record"):
                return
            n -= 1
            continue
        last_sec = sec
        data = buf.peek(16 + incl)[16:]
        buf.skip(16 + incl)
        yield where, sec + frac * unit, data


def _reference_pcapng_packets(src: Source, buf: Any) -> Iterator[tuple[str, float | None, bytes]]:
    p = pcap_mod
    order = "<"
    interfaces: list[tuple[int, float]] = []
    n = 0
    warned: set[int] = set()
    while True:
        off = buf.offset
        head = buf.peek(12)
        if not head:
            return
        n += 1
        where = f"{src.at(off)} (block {n})"
        if len(head) < 12:
            src.report.problem(where, f"the file ends inside a block header: {12 - len(head)} byte(s) "
                                      f"missing of 12", nbytes=len(head))
            return
        is_shb = head[:4] == p._SHB
        why = None
        if is_shb:
            bom = {b"\x4d\x3c\x2b\x1a": "<", b"\x1a\x2b\x3c\x4d": ">"}.get(head[8:12])
            if bom is None:
                why = f"section header with an unknown byte-order magic {head[8:12].hex(' ')}"
            else:
                order = bom
        block_type, total = struct.unpack(order + "II", head[:8])
        if why is None:
            why = p._bad_block_length(total, 28 if is_shb else 12)
        block = b""
        if why is None:
            block = buf.peek(total)
            if len(block) < total:
                if p._pcapng_resync(buf.offset, off + 4, buf.peek(p._SCAN), order=order) is None:
                    src.report.problem(where, f"the file ends inside block {n}: its length {total} runs "
                                              f"{total - len(block)} byte(s) past the end (the file was "
                                              f"cut short, or the length is corrupt)", nbytes=len(block))
                    buf.skip(len(block))
                    return
                why = (f"corrupt block length {total}: the block runs {total - len(block)} byte(s) past "
                       f"the end of the file")
            elif struct.unpack(order + "I", block[-4:])[0] != total:
                why = (f"block length {total} at its start but {struct.unpack(order + 'I', block[-4:])[0]} "
                       f"at its end: a corrupt length or a damaged block")
        if why is not None:
            scan = lambda base, start, window, o=order: p._pcapng_resync(  # noqa: E731
                base, start, window, order=o)
            if not p._skip_damage(src, buf, where, why, off + 4, scan, "block"):
                return
            n -= 1
            continue
        buf.skip(total)
        body = block[8:-4]
        if is_shb:
            interfaces = []
            continue
        packet = _reference_packet(src, where, order, block_type, body, interfaces, warned)
        if packet is not None:
            yield packet


def _reference_packet(src: Source, where: str, order: str, block_type: int, body: bytes,
                      interfaces: list[tuple[int, float]],
                      warned: set[int]) -> tuple[str, float | None, bytes] | None:
    p = pcap_mod
    report = src.report
    if block_type == p._BLOCK_IDB:
        if len(body) < 8:
            report.problem(where, f"interface description block body of {len(body)} byte(s), shorter than "
                                  f"its 8 fixed bytes: interface {len(interfaces)} is unusable")
            interfaces.append((-1, 1e-6))
            return None
        linktype = struct.unpack(order + "H", body[:2])[0]
        interfaces.append((linktype, p._tsresol(body[8:], order)))
        return None
    if block_type not in (p._BLOCK_EPB, p._BLOCK_SPB):
        return None
    if block_type == p._BLOCK_EPB:
        if len(body) < 20:
            report.problem(where, f"enhanced packet block body of {len(body)} byte(s), shorter than its 20 "
                                  f"fixed bytes: skipped", nbytes=len(body))
            return None
        iface, hi, lo, cap, _orig = struct.unpack(order + "IIIII", body[:20])
        if cap > len(body) - 20:
            report.problem(where, f"captured length {cap} is larger than the {len(body) - 20} byte(s) of "
                                  f"packet data in its block: skipped", nbytes=len(body) - 20)
            return None
        data = body[20:20 + cap]
    else:
        if len(body) < 4:
            report.problem(where, f"simple packet block body of {len(body)} byte(s), shorter than its 4 "
                                  f"fixed bytes: skipped", nbytes=len(body))
            return None
        iface, hi, lo = 0, 0, 0
        data = body[4:4 + struct.unpack(order + "I", body[:4])[0]]
    if iface >= len(interfaces):
        report.problem(where, f"packet on undeclared interface {iface}", nbytes=len(data))
        return None
    linktype, unit = interfaces[iface]
    if linktype not in p.SERIAL_LINKTYPES:
        if iface not in warned:
            warned.add(iface)
            report.problem(where, f"interface {iface} has link type {linktype}, not serial "
                                  f"(250/147): its packets are skipped")
        report.unread_bytes += len(data)
        return None
    t = ((hi << 32) | lo) * unit if block_type == p._BLOCK_EPB else None
    return where, t, data


# ---------------------------------------------------------------- reading and comparing ----

Reader = Callable[[Source, "str | None"], Iterator[Chunk]]
SMALL_LIMITS = (1024, 256, 512)  # _SCAN, _RESYNC_MAX, _MAX_RECORD: resynchronisation slides in small files


def outcome(reader: Reader, path: Path, host_is: str | None = None,
            give_up_after: int | None = None) -> tuple[list[tuple[Any, ...]], dict[str, Any], Any]:
    """Everything reading ``path`` does, in order (chunks and problems), the report, the exception."""
    report = Report(give_up_after=give_up_after)
    events: list[tuple[Any, ...]] = []
    problem = report.problem

    def logged(where: str, message: str, *, nbytes: int = 0, nlines: int = 0) -> None:
        events.append(("problem", where, message, nbytes, nlines))
        problem(where, message, nbytes=nbytes, nlines=nlines)

    report.problem = logged  # type: ignore[method-assign]
    error = None
    with Source(path, report) as src:
        try:
            for c in reader(src, host_is):
                report.give_up_after = None  # data came (as xac1 decode does)
                events.append(("chunk", type(c), repr(c), c.t, c.dir, c.data, c.error))
        except Exception as exc:
            error = (type(exc), str(exc))
    del report.problem
    return events, {**dataclasses.asdict(report), "total": report.total_problems}, error


@contextlib.contextmanager
def limits(small: bool) -> Iterator[None]:
    """The look-ahead limits, small or as they are (the reference reads the same module constants)."""
    if not small:
        yield
        return
    scan, resync, record = SMALL_LIMITS
    with mock.patch.object(pcap_mod, "_SCAN", scan), mock.patch.object(pcap_mod, "_RESYNC_MAX", resync), \
            mock.patch.object(pcap_mod, "_MAX_RECORD", record):
        yield


def assert_reads_as_reference(path: Path, reads: tuple[int, int], small: bool = False,
                              host_is: str | None = None, give_up_after: int | None = None) -> Any:
    """The reader with both read sizes, and walking carefully only, does what the reference does."""
    with limits(small):
        expected = outcome(_reference_read, path, host_is, give_up_after)
        for size in reads:
            with mock.patch.object(pcap_mod, "_READ", size):
                assert outcome(pcap_mod.read, path, host_is, give_up_after) == expected, f"_READ {size}"
        with mock.patch.object(pcap_mod, "_Buffer", _ReferenceBuffer):
            assert outcome(pcap_mod.read, path, host_is, give_up_after) == expected, "careful walk"
    events, report, _ = expected
    chunk_bytes = sum(len(e[5]) for e in events if e[0] == "chunk")
    assert chunk_bytes + report["unread_bytes"] <= path.stat().st_size  # no byte counted twice
    return expected


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


PCAP_MAGICS = list(pcap_mod._PCAP_MAGIC)


def pcap_header(magic: bytes, linktype: int = 250) -> bytes:
    order = pcap_mod._PCAP_MAGIC[magic][0]
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
    order, unit = pcap_mod._PCAP_MAGIC[magic]
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
reads = st.tuples(st.sampled_from(READS[-3:]), st.sampled_from(READS))  # one large enough for a fast walk
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
    return tmp_path_factory.mktemp("pcapfast")


def save(folder: Path, data: bytes, suffix: str) -> Path:
    path = folder / f"f{suffix}"
    path.write_bytes(data)
    return path


SLOW_OK = [HealthCheck.too_slow, HealthCheck.data_too_large]


# ---------------------------------------------------------------- the properties ----

def ng(order: str, *blocks: bytes) -> list[Piece]:
    return [(raw, 4, order) for raw in blocks]


def pc(magic: bytes, *records: bytes) -> list[Piece]:
    order = pcap_mod._PCAP_MAGIC[magic][0]
    return [(pcap_header(magic), None, order), *((raw, 8, order) for raw in records)]


NS_LE = b"\x4d\x3c\xb2\xa1"
TSRESOL_2_20 = option(">", 9, bytes([0x80 | 20])) + option(">", 0, b"")
LATE = 1_790_000_000_000_000  # microseconds


@settings(max_examples=300, deadline=None, suppress_health_check=SLOW_OK)
@given(pcapng_files(), damages, reads, st.booleans(), host_sides, give_ups)
@example(  # an EPB's length at its end corrupted between good ones
    pieces=ng("<", shb(), idb(), *(epb("<", rtac(k % 2 + 1, b"0RV\r\n", usecs=k)) for k in range(4))),
    damage=[("field", 3, -4, 99)], sizes=(1 << 17, 1), small=False, host_is=None, give_up=None)
@example(  # fast packets, then one whose time is out of range: it takes the last fast packet's time
    pieces=ng("<", shb(), idb(), epb("<", rtac(1, b"a")), epb("<", rtac(2, b"b", 0, 0), ts=2**64 - 1),
              epb("<", rtac(1, b"c", 0, 0), ts=LATE)),
    damage=[], sizes=(4096, 4096), small=False, host_is="RX", give_up=None)
@example(  # the latest time an RTAC header says, microseconds 1000000, a packet of another link type, a
    # big-endian section with a 2^-20 s timestamp unit, a length not a multiple of 4 (the rest is lost)
    pieces=ng("<", shb(), idb("<", 1), idb(), epb("<", rtac(1, b"x", 2**32 - 1, 999_999), iface=1),
              epb("<", rtac(2, b"y", 5, 10**6), iface=1, ts=LATE), epb("<", rtac(1, b"n")),
              epb("<", rtac(1, b"zz"), iface=1))
    + ng(">", shb(">"), idb(">", 147, TSRESOL_2_20), epb(">", rtac(1, b"z", 0, 0), ts=LATE),
         epb(">", rtac(2, b"odd"), padded=False), epb(">", rtac(1, b"lost"))),
    damage=[], sizes=(1 << 17, 509), small=True, host_is=None, give_up=None)
@example(  # an IDB's if_tsresol option without its value byte (it crashed both): microseconds
    pieces=ng("<", shb(), idb("<", 250, struct.pack("<HH", 9, 1)), epb("<", rtac(1, b"a"))),
    damage=[], sizes=(4096, 1), small=False, host_is=None, give_up=None)
def test_pcapng_files_read_as_the_reference_reads_them(folder, pieces, damage, sizes, small, host_is,
                                                        give_up) -> None:
    path = save(folder, assemble(pieces, damage), ".pcapng")
    assert_reads_as_reference(path, sizes, small, host_is, give_up)


@settings(max_examples=200, deadline=None, suppress_health_check=SLOW_OK)
@given(pcap_files(), damages, reads, st.booleans(), host_sides, give_ups)
@example(  # nanoseconds: the last second of 2^32 with the largest fraction is 2^32 s as a float: out of
    # range, the packet takes the last good time
    pieces=pc(NS_LE, pcap_record("<", rtac(1, b"a", 0, 0)),
              pcap_record("<", rtac(2, b"b", 0, 0), 2**32 - 1, 999_999_999)),
    damage=[], sizes=(4096, 4096), small=False, host_is=None, give_up=None)
@example(  # records (37 bytes) that end where the blocks read (61 bytes) end, then a corrupt length
    pieces=pc(PCAP_MAGICS[0], *(pcap_record("<", rtac(1, b"0RV\r\n0RV")) for _ in range(6))),
    damage=[("length", 4, 2**20 + 4)], sizes=(61, 61), small=False, host_is=None, give_up=3)
@example(  # a whole record longer than the longest taken (small limits), big-endian
    pieces=pc(PCAP_MAGICS[1], *(pcap_record(">", rtac(2, b"0" * n)) for n in (5, 600, 7))),
    damage=[], sizes=(4096, 100), small=True, host_is=None, give_up=None)
@example(  # a damaged record: the search for the next one wants a time near the last good record's
    pieces=pc(PCAP_MAGICS[0], *(pcap_record("<", rtac(1, b"ab", 0, 0), sec, frac) for sec, frac in (
        (1_790_000_000, 0), (100, 0), (100, 10**6), (1_790_000_000, 0), (150, 0), (160, 0)))),
    damage=[], sizes=(4096, 4096), small=False, host_is=None, give_up=None)
def test_pcap_files_read_as_the_reference_reads_them(folder, pieces, damage, sizes, small, host_is,
                                                      give_up) -> None:
    path = save(folder, assemble(pieces, damage), ".pcap")
    assert_reads_as_reference(path, sizes, small, host_is, give_up)


@settings(max_examples=80, deadline=None, suppress_health_check=SLOW_OK)
@given(writer_chunks, st.integers(0, 10**5), reads)
def test_writer_files_read_back_and_as_the_reference_reads_them(folder, chunks, cut, sizes) -> None:
    """Undamaged, every chunk comes back with its bytes and error; cut anywhere, the reference's chunks
    and problems."""
    data = written(chunks)
    path = save(folder, data, ".pcapng")
    events, report, error = assert_reads_as_reference(path, sizes)
    back = [e for e in events if e[0] == "chunk"]
    assert error is None and not report["problems"]
    assert [(e[4], e[5], e[6]) for e in back] == [(c.dir if not c.error else e[4], c.data, c.error)
                                                  for c, e in zip([c for c in chunks if c.data or c.error],
                                                                  back, strict=True)]
    assert_reads_as_reference(save(folder, data[:cut % (len(data) + 1)], ".pcapng"), sizes)


# ---------------------------------------------------------------- exact accounting, the walk, memory ----

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
def test_bytes_are_accounted_exactly(folder: Path, order: str, size: int) -> None:
    """Every byte of line data is in a chunk or counted as unread, as the reference counts them."""
    data, line, unread = _accounting_pcapng(order)
    events, report, error = assert_reads_as_reference(save(folder, data, ".pcapng"), (size, size))
    assert sum(len(e[5]) for e in events if e[0] == "chunk") == line
    assert report["unread_bytes"] == unread and error is None
    magic = next(m for m in PCAP_MAGICS if pcap_mod._PCAP_MAGIC[m] == (order, 1e-6))
    records = [pcap_header(magic), pcap_record(order, rtac(1, b"0RV\r\n")), pcap_record(order, b"tiny"),
               pcap_record(order, rtac(9, b"zz")), pcap_record(order, rtac(2, b"0RV1\r\n")),
               pcap_record(order, rtac(1, b"cut"))[:-2], ]
    events, report, error = assert_reads_as_reference(save(folder, b"".join(records), ".pcap"), (size, size))
    assert sum(len(e[5]) for e in events if e[0] == "chunk") == 11
    assert report["unread_bytes"] == 4 + 2 + 29 and error is None


@pytest.mark.parametrize("suffix", [".pcapng", ".pcap"])
def test_the_fast_walk_reads_common_records(folder: Path, suffix: str) -> None:
    """The comparisons above compare the fast walk: on a clean file it takes every packet but one or two
    at the end of each block read (and the section's header blocks), which the careful walk (counted)
    reads."""
    chunks = [Chunk(1.79e9 + k / 100, HOST if k % 2 else DEVICE, b"0RP3\r\n" * (k % 5 + 1))
              for k in range(3000)]
    data = written(chunks)
    if suffix == ".pcap":  # the same packets as pcap records
        records, k = [pcap_header(PCAP_MAGICS[0])], 0
        while k < len(data):
            block_type, total = struct.unpack_from("<II", data, k)
            if block_type == 6:
                cap = struct.unpack_from("<I", data, k + 20)[0]
                records.append(pcap_record("<", data[k + 28:k + 28 + cap]))
            k += total
        data = b"".join(records)
    path = save(folder, data, suffix)
    careful = pcap_mod._pcapng_block if suffix == ".pcapng" else pcap_mod._pcap_record
    with mock.patch.object(pcap_mod, careful.__name__, side_effect=careful) as counted, \
            mock.patch.object(pcap_mod, "_READ", 4096):
        events, report, error = outcome(pcap_mod.read, path)
    assert [e[2] for e in events] == [repr(c) for c in chunks] and error is None
    assert counted.call_count <= 2 * (len(data) // 4096 + 1) + 3


def test_memory_is_one_block_and_a_look_ahead(folder: Path) -> None:
    """The reader never holds the file: one block read, plus a record or a damage look-ahead."""
    chunks = [Chunk(1.79e9 + k, HOST, b"0RV\r\n" * (k % 7 + 1)) for k in range(2000)]
    data = bytearray(written(chunks))
    k = 0
    while k < len(data) // 2:  # to the block boundary after the middle
        k += struct.unpack_from("<I", data, k + 4)[0]
    data[k:k] = b"junk" * 100
    path = save(folder, bytes(data), ".pcapng")
    largest = 0
    fill = pcap_mod._Buffer._fill

    def watched(self: Any, n: int) -> None:
        nonlocal largest
        fill(self, n)
        largest = max(largest, len(self._block))

    with limits(True), mock.patch.object(pcap_mod, "_READ", 4096), \
            mock.patch.object(pcap_mod._Buffer, "_fill", watched):
        events, report, error = outcome(pcap_mod.read, path)
    assert len([e for e in events if e[0] == "chunk"]) == 2000 and report["total"] == 1
    assert 4096 < largest <= 4096 + SMALL_LIMITS[0] < len(data) // 10


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.none(), st.floats()), st.sampled_from([HOST, DEVICE]), st.binary(max_size=8),
       st.one_of(st.none(), st.text(max_size=8)))
def test_new_chunk_is_a_chunk(t, d, data, error) -> None:
    """``new_chunk`` builds what ``Chunk(...)`` builds: same class, fields, equality, hash, repr; frozen."""
    fast, slow = new_chunk(t, d, data, error), Chunk(t, d, data, error)
    assert type(fast) is Chunk and fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.astuple(fast) == dataclasses.astuple(slow)
    assert new_chunk(t, d, data) == Chunk(t, d, data)
    if t == t:  # a NaN read back is another NaN object: not equal
        assert pickle.loads(pickle.dumps(fast)) == fast
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.t = 0.0  # type: ignore[misc]


def test_an_if_tsresol_option_cut_before_its_value_is_the_default() -> None:
    """An IDB whose if_tsresol option has no value byte left (it raised IndexError: a traceback from
    ``xac1 decode``): the default unit, microseconds."""
    assert pcap_mod._tsresol(struct.pack("<HH", 9, 1), "<") == 1e-6
    assert pcap_mod._tsresol(struct.pack("<HHB3x", 9, 1, 3), "<") == 1e-3
