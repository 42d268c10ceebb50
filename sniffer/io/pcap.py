"""Reader and writer for pcap and pcapng files of serial traffic (LINKTYPE_RTAC_SERIAL 250, USER0 147).

How this works: both link types carry, before the line's bytes, the 12-byte RTAC serial header of
Wireshark's ``rtacser`` dissector: arrival time as two big-endian 32-bit words (seconds since the
epoch, microseconds), an event type byte, a control-line bitmap byte (CTS 0x01, DCD 0x02, DSR 0x04,
RTS 0x08, DTR 0x10, RING 0x20, MBOK 0x40) and a 2-byte footer. Event types 0x01/0x03 (DATA_TX_START/
END) carry bytes the capturing port sent (``TX``), 0x02/0x04 (DATA_RX_START/END) bytes it received
(``RX``); 0x07 FRAMING_ERROR and 0x08 PARITY_ERROR mark their bytes as damaged (on the side of the
last data packet); other events carry no data. USER0 (147) is the older way such files were written
and is read the same. The reader walks pcap records or pcapng blocks (SHB, IDB, EPB, SPB, either byte
order, any if_tsresol) one at a time and checks each against the file and itself: a length past the
end of the file or implausible (pcapng: not repeated at the block's end), a body shorter than its fixed
fields, a captured length larger than its block, a time out of range. Each is reported as
``file:offset (record/block N): what was wrong`` and reading resumes at the next plausible record or
block (a bounded look-ahead), so the packets after damage are kept.

Two walks share that work (``_Walk`` holds what they carry from record to record: byte order,
interfaces, record count, last time and direction). The careful walk (``_pcap_record``,
``_pcapng_block``, ``_chunk``) reads one record at a time through ``_Buffer.peek``/``skip`` and knows
every case above. The fast walk runs over the bytes already read (``_Buffer.window``: one block of
``_READ`` or more bytes, no copy) with ``struct.unpack_from`` at an offset and locals only, and takes
the common record alone: for pcapng an EPB in the section's byte order, whole in the block with the
next block's header (one unpack reads its trailing length and that header), the length plausible and
repeated, on a serial interface; for pcap a record whose length and time fraction are sane and that is
whole in the block; then an RTAC TX/RX event with sane microseconds and a time ``Clock`` accepts. It
builds no ``where`` text (nothing is reported), counts the records as the careful walk does, hands its
state back when it stops, and leaves anything else, unchanged, to the careful walk for one record:
damage, SHB, IDB, SPB, other events, a bad time, a record cut by the end of the block (the careful walk
reads on). So both give the same chunks and problems, in the same order. Memory: one block of the
file plus at most one record's (or one ``_SCAN`` look-ahead's) bytes.

Host side default: ``TX`` (the capturing port sent the commands). The writer (``PcapngWriter``) writes
host bytes as TX and device bytes as RX, so its files read back with the default.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable, Iterator
from functools import partial
from typing import IO, Final

from xac1_proto.chunk import HOST, Chunk, Direction, new_chunk

from .base import MAX_TIME, Clock, FormatError, Sides, Source

FORMAT: Final = "pcap"
DESCRIPTION: Final = "pcap / pcapng with LINKTYPE_RTAC_SERIAL (250) or USER0 (147)"
HOST_DEFAULT: Final = "TX"
SUFFIXES: Final = (".pcap", ".pcapng", ".cap")
BINARY: Final = True

LINKTYPE_RTAC_SERIAL: Final = 250
LINKTYPE_USER0: Final = 147
SERIAL_LINKTYPES: Final = (LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0)
RTAC_HEADER: Final = struct.Struct(">IIBBH")  # seconds, microseconds, event, control lines, footer
TX_EVENTS: Final = frozenset({0x01, 0x03})
RX_EVENTS: Final = frozenset({0x02, 0x04})
ERROR_EVENTS: Final = {0x07: "UART framing error", 0x08: "UART parity error"}

_PCAP_MAGIC: Final = {b"\xd4\xc3\xb2\xa1": ("<", 1e-6), b"\xa1\xb2\xc3\xd4": (">", 1e-6),
                      b"\x4d\x3c\xb2\xa1": ("<", 1e-9), b"\xa1\xb2\x3c\x4d": (">", 1e-9)}
_SHB: Final = b"\x0a\x0d\x0d\x0a"
_BLOCK_EPB, _BLOCK_SPB, _BLOCK_IDB = 6, 3, 1
_MAX_RECORD: Final = 1 << 20
_RESYNC_MAX: Final = 1 << 16  # longest record or block taken as a resynchronisation point
_SCAN: Final = 1 << 18  # look-ahead searched for the next record after damage
_READ: Final = 1 << 17  # bytes read at once (at least): the fast walk's block

# the fast walk's fields, by byte order
_PCAP_HEAD: Final = {o: struct.Struct(o + "4xII").unpack_from for o in "<>"}  # time fraction, length
_EPB_HEAD: Final = {o: struct.Struct(o + "III8xI").unpack_from for o in "<>"}  # type, length, iface, cap
_EPB_TAIL: Final = {o: struct.Struct(o + "IIII8xI").unpack_from for o in "<>"}  # trailing length, next head
_EPB_TIME: Final = {o: struct.Struct(o + "II").unpack_from for o in "<>"}  # timestamp high, low
_U32: Final = {o: struct.Struct(o + "I").unpack_from for o in "<>"}  # pcap record seconds
_RTAC_FAST: Final = struct.Struct(">IIB").unpack_from  # seconds, microseconds, event

_Packet = tuple[str, float | None, bytes]  # where, time (None: none), RTAC header and data


def sniff_bytes(first: bytes) -> int:
    return 99 if first[:4] in _PCAP_MAGIC or first[:4] == _SHB else 0


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    buf = _Buffer(src)
    magic = buf.peek(4)
    if magic not in _PCAP_MAGIC and magic != _SHB:
        raise FormatError(f"{src.name}: not a pcap or pcapng file (first bytes {magic.hex(' ')})")
    walk = _Walk(src, buf, Sides("pcap", host_is, ("TX", "RX")))
    if magic == _SHB:
        yield from _pcapng_chunks(walk)
    elif _pcap_start(walk, magic):
        yield from _pcap_chunks(walk)


class _Buffer:
    """A look-ahead window over the file: ``peek`` without consuming, ``skip`` to consume; ``offset`` is
    the file offset of the window's first byte. The window is one immutable block read in large pieces
    and a position in it: a peek is one slice, a skip moves the position (no per-record copy of the
    rest); ``window`` gives the block itself to the fast walk. Memory: a read block plus the largest
    peek (about one record)."""

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
        """Read until ``n`` bytes from the position are in (or the file ends); the position becomes 0."""
        parts = [self._block[self._pos:]]
        have = len(parts[0])
        while have < n:
            more = self.src.read(max(n - have, _READ))
            if not more:
                break
            parts.append(more)
            have += len(more)
        self._block = b"".join(parts)
        self._pos = 0

    def skip(self, n: int) -> None:
        if self._pos + n > len(self._block):
            self._fill(n)
        n = min(n, len(self._block) - self._pos)
        self._pos += n
        self.offset += n

    def window(self) -> tuple[bytes, int]:
        """The block read and the position in it (the bytes ahead that are in, no copy, no read)."""
        return self._block, self._pos

    def advance(self, n: int) -> None:
        """Consume ``n`` bytes that ``window`` showed."""
        self._pos += n
        self.offset += n


class _Walk:
    """What reading one file carries from record to record, shared by the careful and the fast walk."""

    def __init__(self, src: Source, buf: _Buffer, sides: Sides) -> None:
        self.src = src
        self.buf = buf
        self.clock = Clock(src.report)
        tx, rx = sides.direction("TX"), sides.direction("RX")
        self.by_event: tuple[Direction | None, ...] = tuple(
            tx if e in TX_EVENTS else rx if e in RX_EVENTS else None for e in range(256))
        self.last: Direction | None = None  # the direction of the last data packet
        self.n = 0  # records or blocks read: the N of "(record N)", "(block N)"
        self.order = "<"  # byte order of the file (pcap) or section (pcapng)
        self.unit = 1e-6  # pcap: seconds per time fraction unit
        self.ticks = 1_000_000  # pcap: time fraction units per second
        self.last_sec: int | None = None  # pcap: seconds of the last good record
        self.interfaces: list[tuple[int, float]] = []  # pcapng: (link type, seconds per timestamp unit)
        self.units: list[float] = []  # pcapng: seconds per timestamp unit of a serial interface, else 0
        self.warned: set[int] = set()  # pcapng: interfaces said to be not serial

    def interface(self, linktype: int, unit: float) -> None:
        """A pcapng interface description read."""
        self.interfaces.append((linktype, unit))
        self.units.append(unit if linktype in SERIAL_LINKTYPES else 0.0)


def _chunk(w: _Walk, where: str, t: float | None, payload: bytes) -> Chunk | None:
    """The chunk of one packet's RTAC header and data (None: none, or a damaged packet: reported)."""
    report = w.src.report
    if len(payload) < RTAC_HEADER.size:
        report.problem(where, f"packet of {len(payload)} bytes is shorter than the 12-byte RTAC "
                              f"serial header", nbytes=len(payload))
        return None
    secs, usecs, event, _lines, _footer = RTAC_HEADER.unpack_from(payload)
    data = payload[RTAC_HEADER.size:]
    if usecs >= 1_000_000:
        report.problem(where, f"RTAC header microseconds {usecs} is not below 1000000; the "
                              f"packet's own time is used")
    elif secs or usecs:
        t = secs + usecs / 1e6
    t = w.clock.check(t, where)
    d = w.by_event[event]
    if d is not None:
        w.last = d
        return Chunk(t, d, data) if data else None
    if event in ERROR_EVENTS:
        return Chunk(t, w.last or HOST, data, ERROR_EVENTS[event])
    if data:
        report.problem(where, f"RTAC event 0x{event:02x} carries {len(data)} byte(s) that are "
                              f"not line data; skipped", nbytes=len(data))
    return None


def _pcap_start(w: _Walk, magic: bytes) -> bool:
    """Read a pcap file header: False when the file ends inside it (reported)."""
    src, buf = w.src, w.buf
    w.order, w.unit = _PCAP_MAGIC[magic]
    header = buf.peek(24)
    if len(header) < 24:
        src.report.problem(src.at(0), f"the file ends inside the 24-byte pcap file header "
                                      f"({len(header)} byte(s))", nbytes=len(header))
        return False
    linktype = struct.unpack(w.order + "HHiIII", header[4:])[5] & 0x0FFFFFFF
    if linktype not in SERIAL_LINKTYPES:
        raise FormatError(f"{src.at(20)}: pcap link type {linktype} is not serial (expected "
                          f"{LINKTYPE_RTAC_SERIAL} RTAC serial or {LINKTYPE_USER0} USER0)")
    buf.skip(24)
    w.ticks = round(1 / w.unit)
    return True


def _pcap_chunks(w: _Walk) -> Iterator[Chunk]:
    """The chunks of a pcap file's records: the fast walk over the block read while records are common
    (see the module docstring), one careful record where it stops."""
    buf = w.buf
    fast = hasattr(buf, "window")  # a buffer without a block (a test's reference) is walked carefully
    while True:
        if fast:
            block, start = buf.window()
            head, seconds, rtac, by_event = _PCAP_HEAD[w.order], _U32[w.order], _RTAC_FAST, w.by_event
            ticks, unit, max_record, max_time = w.ticks, w.unit, _MAX_RECORD, MAX_TIME
            n, t, d, good = w.n, 0.0, None, start
            p, size = start, len(block)
            while p + 16 <= size:
                frac, incl = head(block, p)
                b = p + 16  # the RTAC header
                q = b + incl
                if incl > max_record or frac >= ticks or q > size or incl < 12:
                    break
                secs, usecs, event = rtac(block, b)
                d2 = by_event[event]
                if d2 is None:
                    break
                if secs or usecs:  # the RTAC time: below 2**32 s when its microseconds are sane
                    if usecs >= 1_000_000:
                        break
                    t = secs + usecs / 1e6
                else:
                    t2 = seconds(block, p)[0] + frac * unit
                    if not t2 < max_time:  # >= 0
                        break
                    t = t2
                n, d, good = n + 1, d2, p
                if incl > 12:
                    yield new_chunk(t, d, block[b + 12:q])
                p = q
            if d is not None:
                w.n, w.last, w.clock.last, w.last_sec = n, d, t, seconds(block, good)[0]
            buf.advance(p - start)
        more, packet = _pcap_record(w)
        if not more:
            return
        if packet is not None and (chunk := _chunk(w, *packet)) is not None:
            yield chunk


def _pcap_record(w: _Walk) -> tuple[bool, _Packet | None]:
    """One pcap record read carefully: (False, None) at the end of the file, else (True, its packet, or
    None after damage: reported, and the walk moved to the next plausible record)."""
    src, buf = w.src, w.buf
    off = buf.offset
    rec = buf.peek(16)
    if not rec:
        return False, None
    w.n += 1
    where = f"{src.at(off)} (record {w.n})"
    if len(rec) < 16:
        src.report.problem(where, f"the file ends inside a record header: {16 - len(rec)} byte(s) "
                                  f"missing of 16", nbytes=len(rec))
        return False, None
    sec, frac, incl, orig = struct.unpack(w.order + "IIII", rec)
    resync = partial(_pcap_resync, order=w.order, ticks=w.ticks, last_sec=w.last_sec)
    why = None
    if incl > _MAX_RECORD:
        why = f"corrupt length {incl} (expected at most {_MAX_RECORD})"
    elif frac >= w.ticks:
        why = f"corrupt time: fraction {frac} (expected below {w.ticks})"
    else:
        whole = buf.peek(16 + incl)
        if len(whole) < 16 + incl:
            left = len(whole) - 16
            if resync(buf.offset, off + 1, buf.peek(_SCAN)) is None:
                src.report.problem(where, f"corrupt length {incl}: the record runs {incl - left} byte(s) "
                                          f"past the end of the file ({left} left; or the file was cut "
                                          f"short inside it)", nbytes=len(whole))
                buf.skip(len(whole))
                return False, None
            why = f"corrupt length {incl}: the record runs {incl - left} byte(s) past the end of the file"
    if why is not None:
        w.n -= 1
        return _skip_damage(src, buf, where, why, off + 1, resync, "record"), None
    w.last_sec = sec
    data = buf.peek(16 + incl)[16:]
    buf.skip(16 + incl)
    return True, (where, sec + frac * w.unit, data)


def _skip_damage(src: Source, buf: _Buffer, where: str, why: str, start: int,
                 scan: Callable[[int, int, bytes], int | None], unit: str) -> bool:
    """Report damage found at ``where`` and move to the next plausible record or block at or after
    ``start`` (True), or to the end of the file when there is none (False). ``scan(base, start,
    window)`` finds one in a look-ahead window; the window slides on, so memory stays bounded."""
    off = buf.offset
    while True:
        window = buf.peek(_SCAN)
        found = scan(buf.offset, start, window)
        if found is not None:
            lost = found - off
            src.report.problem(where, f"{why}; {lost} byte(s) skipped to the next plausible {unit}",
                               nbytes=lost)
            buf.skip(found - buf.offset)
            return True
        if len(window) < _SCAN:  # the end of the file is in the window
            buf.skip(len(window))
            lost = buf.offset - off
            src.report.problem(where, f"{why}; nothing plausible follows: the rest of the file ({lost} "
                                      f"byte(s)) is skipped", nbytes=lost)
            return False
        buf.skip(len(window) - _RESYNC_MAX - 32)
        start = buf.offset


def _pcap_resync(base: int, start: int, window: bytes, *, order: str, ticks: int,
                 last_sec: int | None) -> int | None:
    """The file offset of the next plausible pcap record at or after ``start`` in ``window`` (which
    starts at file offset ``base``): a sane fraction and length, a time near the last good one, and
    either the end of the window or another sane record header right after it."""
    for p in range(start - base, len(window) - 15):
        sec, frac, incl, orig = struct.unpack_from(order + "IIII", window, p)
        if frac >= ticks or incl > _RESYNC_MAX or incl > orig or incl < RTAC_HEADER.size:
            continue
        if last_sec is not None and abs(sec - last_sec) > 86400:
            continue
        nxt = p + 16 + incl
        if nxt > len(window):
            continue
        if nxt == len(window) or (nxt + 16 <= len(window) and
                                  _sane_pcap_header(window[nxt:nxt + 16], order, ticks, sec)):
            return base + p
    return None


def _sane_pcap_header(rec: bytes, order: str, ticks: int, near: int) -> bool:
    sec, frac, incl, orig = struct.unpack(order + "IIII", rec)
    return frac < ticks and incl <= min(orig, _RESYNC_MAX) and abs(sec - near) <= 86400


def _pcapng_chunks(w: _Walk) -> Iterator[Chunk]:
    """The chunks of a pcapng file's blocks: the fast walk over the block read while blocks are common
    (see the module docstring), one careful block where it stops."""
    buf = w.buf
    fast = hasattr(buf, "window")  # a buffer without a block (a test's reference) is walked carefully
    while True:
        if fast:
            block, start = buf.window()
            head, tail, times = _EPB_HEAD[w.order], _EPB_TAIL[w.order], _EPB_TIME[w.order]
            rtac, units, by_event, max_record = _RTAC_FAST, w.units, w.by_event, _MAX_RECORD
            n, t, d, known, max_time = w.n, 0.0, None, len(w.units), MAX_TIME
            p, last = start, len(block) - 28  # the last offset of a whole EPB header
            if p <= last:
                block_type, total, iface, cap = head(block, p)
            while p <= last:  # and then p <= last stays true: each block is checked to end by then
                q = p + total  # the next block: its header comes with this one's trailing length
                if (block_type != _BLOCK_EPB or total & 3 or total > max_record or q > last
                        or not 12 <= cap <= total - 32 or iface >= known or not units[iface]):
                    break
                end, block_type, total_next, iface_next, cap_next = tail(block, q - 4)
                b = p + 28  # the RTAC header
                secs, usecs, event = rtac(block, b)
                d2 = by_event[event]
                if end != total or d2 is None:
                    break
                if secs or usecs:  # the RTAC time: below 2**32 s when its microseconds are sane
                    if usecs >= 1_000_000:
                        break
                    t = secs + usecs / 1e6
                else:
                    hi, lo = times(block, p + 12)
                    t2 = ((hi << 32) | lo) * units[iface]
                    if not t2 < max_time:  # >= 0
                        break
                    t = t2
                n, d = n + 1, d2
                if cap > 12:
                    yield new_chunk(t, d, block[b + 12:b + cap])
                p, total, iface, cap = q, total_next, iface_next, cap_next
            if d is not None:
                w.n, w.last, w.clock.last = n, d, t
            buf.advance(p - start)
        more, packet = _pcapng_block(w)
        if not more:
            return
        if packet is not None and (chunk := _chunk(w, *packet)) is not None:
            yield chunk


def _pcapng_block(w: _Walk) -> tuple[bool, _Packet | None]:
    """One pcapng block read carefully: (False, None) at the end of the file, else (True, its packet,
    or None: a block without one, or damage: reported, and the walk moved to the next plausible block)."""
    src, buf = w.src, w.buf
    off = buf.offset
    head = buf.peek(12)
    if not head:
        return False, None
    w.n += 1
    where = f"{src.at(off)} (block {w.n})"
    if len(head) < 12:
        src.report.problem(where, f"the file ends inside a block header: {12 - len(head)} byte(s) "
                                  f"missing of 12", nbytes=len(head))
        return False, None
    is_shb = head[:4] == _SHB
    why = None
    if is_shb:
        bom = {b"\x4d\x3c\x2b\x1a": "<", b"\x1a\x2b\x3c\x4d": ">"}.get(head[8:12])
        if bom is None:
            why = f"section header with an unknown byte-order magic {head[8:12].hex(' ')}"
        else:
            w.order = bom
    block_type, total = struct.unpack(w.order + "II", head[:8])
    if why is None:
        why = _bad_block_length(total, 28 if is_shb else 12)
    block = b""
    if why is None:
        block = buf.peek(total)
        if len(block) < total:
            if _pcapng_resync(buf.offset, off + 4, buf.peek(_SCAN), order=w.order) is None:
                src.report.problem(where, f"the file ends inside block {w.n}: its length {total} runs "
                                          f"{total - len(block)} byte(s) past the end (the file was "
                                          f"cut short, or the length is corrupt)", nbytes=len(block))
                buf.skip(len(block))
                return False, None
            why = (f"corrupt block length {total}: the block runs {total - len(block)} byte(s) past "
                   f"the end of the file")
        elif (end := struct.unpack(w.order + "I", block[-4:])[0]) != total:
            why = (f"block length {total} at its start but {end} at its end: a corrupt length or a "
                   f"damaged block")
    if why is not None:
        w.n -= 1
        return _skip_damage(src, buf, where, why, off + 4, partial(_pcapng_resync, order=w.order),
                            "block"), None
    buf.skip(total)
    if is_shb:
        w.interfaces, w.units = [], []
        return True, None
    return True, _packet(w, where, block_type, block[8:-4])


def _bad_block_length(total: int, least: int) -> str | None:
    if total < least or total % 4 or total > _MAX_RECORD:
        return (f"block length {total} is not plausible (expected a multiple of 4 from {least} to "
                f"{_MAX_RECORD})")
    return None


def _pcapng_resync(base: int, start: int, window: bytes, *, order: str) -> int | None:
    """The file offset of the next whole pcapng block at or after ``start`` in ``window`` (which starts
    at file offset ``base``; blocks are 4-byte aligned): a plausible length repeated at its end."""
    first = start - base
    first += -first % 4
    for p in range(first, len(window) - 11, 4):
        is_shb = window[p:p + 4] == _SHB
        orders = ("<", ">") if is_shb else (order,)
        for o in orders:
            total = struct.unpack_from(o + "I", window, p + 4)[0]
            if total > _RESYNC_MAX or _bad_block_length(total, 28 if is_shb else 12) is not None:
                continue
            if p + total <= len(window) and struct.unpack_from(o + "I", window, p + total - 4)[0] == total:
                return base + p
    return None


def _packet(w: _Walk, where: str, block_type: int, body: bytes) -> _Packet | None:
    """The packet of one pcapng block (None for a block that carries none, or a damaged one: reported)."""
    report, order, interfaces = w.src.report, w.order, w.interfaces
    if block_type == _BLOCK_IDB:
        if len(body) < 8:
            report.problem(where, f"interface description block body of {len(body)} byte(s), shorter than "
                                  f"its 8 fixed bytes: interface {len(interfaces)} is unusable")
            w.interface(-1, 1e-6)
            return None
        linktype = struct.unpack(order + "H", body[:2])[0]
        w.interface(linktype, _tsresol(body[8:], order))
        return None
    if block_type not in (_BLOCK_EPB, _BLOCK_SPB):
        return None
    if block_type == _BLOCK_EPB:
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
    if linktype not in SERIAL_LINKTYPES:
        if iface not in w.warned:
            w.warned.add(iface)
            report.problem(where, f"interface {iface} has link type {linktype}, not serial "
                                  f"(250/147): its packets are skipped")
        report.unread_bytes += len(data)
        return None
    t = ((hi << 32) | lo) * unit if block_type == _BLOCK_EPB else None
    return where, t, data


def _tsresol(options: bytes, order: str) -> float:
    """Seconds per timestamp unit from an IDB's options (default microseconds)."""
    i = 0
    while i + 4 <= len(options):
        code, length = struct.unpack(order + "HH", options[i:i + 4])
        if code == 0:
            break
        if code == 9 and length >= 1 and i + 4 < len(options):  # (its value byte cut off: the default)
            v = options[i + 4]
            return 2.0 ** -(v & 0x7F) if v & 0x80 else 10.0 ** -v
        i += 4 + (length + 3) // 4 * 4
    return 1e-6


class PcapngWriter:
    """Write chunks as a pcapng file with LINKTYPE_RTAC_SERIAL: host bytes as TX, device bytes as RX.

    A context manager; each chunk is flushed as it is written (a killed process keeps every packet)."""

    def __init__(self, path: str | os.PathLike[str], linktype: int = LINKTYPE_RTAC_SERIAL) -> None:
        self._f: IO[bytes] = open(path, "wb")  # noqa: SIM115 - closed by close()
        shb_body = struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)
        self._block(0x0A0D0D0A, shb_body)
        opts = struct.pack("<HHB3x", 9, 1, 6) + struct.pack("<HH", 0, 0)  # if_tsresol = 10^-6
        self._block(_BLOCK_IDB, struct.pack("<HHI", linktype, 0, 0) + opts)
        self._f.flush()

    def _block(self, block_type: int, body: bytes) -> None:
        pad = b"\0" * (-len(body) % 4)
        total = 12 + len(body) + len(pad)
        self._f.write(struct.pack("<II", block_type, total) + body + pad + struct.pack("<I", total))

    def write(self, chunk: Chunk) -> None:
        t = chunk.t or 0.0
        usec_total = round(t * 1e6)
        secs, usecs = divmod(usec_total, 1_000_000)
        if chunk.error:
            event = 0x08 if "parity" in chunk.error.lower() else 0x07
        else:
            event = 0x01 if chunk.dir == HOST else 0x02
        payload = RTAC_HEADER.pack(secs & 0xFFFFFFFF, usecs, event, 0, 0) + chunk.data
        epb = struct.pack("<IIIII", 0, usec_total >> 32, usec_total & 0xFFFFFFFF, len(payload),
                          len(payload)) + payload
        self._block(_BLOCK_EPB, epb)
        self._f.flush()

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()

    def __enter__(self) -> PcapngWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
