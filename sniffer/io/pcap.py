"""Reader and writer for pcap and pcapng files of serial traffic (LINKTYPE_RTAC_SERIAL 250, USER0 147).

How this works: both link types carry, before the line's bytes, the 12-byte RTAC serial header of
Wireshark's ``rtacser`` dissector: arrival time as two big-endian 32-bit words (seconds since the
epoch, microseconds), an event type byte, a control-line bitmap byte (CTS 0x01, DCD 0x02, DSR 0x04,
RTS 0x08, DTR 0x10, RING 0x20, MBOK 0x40) and a 2-byte footer. Event types 0x01/0x03 (DATA_TX_START/
END) carry bytes the capturing port sent (``TX``), 0x02/0x04 (DATA_RX_START/END) bytes it received
(``RX``); 0x07 FRAMING_ERROR and 0x08 PARITY_ERROR mark their bytes as damaged (on the side of the
last data packet); other events carry no data. USER0 (147) is the older way such files were written
and is read the same. The reader walks pcap records or pcapng blocks (SHB, IDB, EPB, SPB, either byte
order, any if_tsresol) once, in order, and checks each against the file and itself: a length past the
end of the file or implausible (pcapng: not repeated at the block's end), a body shorter than its fixed
fields, a captured length larger than its block, a time out of range or running backwards
(``timeline``). Each is reported as ``file:offset (record/block N): what was wrong`` and reading resumes
at the next plausible record or block (a bounded look-ahead), so the packets after damage are kept.
Every byte is line data in a chunk, structure of a record read, or counted unread by a problem.

One walk (``_pcap_chunks``, ``_pcapng_chunks``): a loop over the block of the file read so far
(``_Buffer.window``: one block of ``block`` (``BLOCK``) or more bytes, no copy) with
``struct.unpack_from`` at an offset and locals. It takes, in a row, the records (pcap) or enhanced packet
blocks (pcapng) that are whole in the block and carry the common packet (a TX/RX event, sane microseconds,
a time in range and not running backwards), and stops at the first other one; the loop hands its locals to
``_Walk`` (``settle``) and ``_pcap_stop`` / ``_pcapng_stop`` say what is there: a record or block not yet
all read (the loop reads on, ``_Buffer.peek``), else ``_pcap_record`` / ``_pcapng_block`` read it: any
other packet (by ``_chunk``, which says what is wrong with it), any other block (SHB, IDB, SPB, other
types), and damage (an implausible or unrepeated length, the file ending inside), which they report and
resynchronise after. Memory: one block of the file plus at most one record's (or one ``look_ahead``'s)
bytes.

Host side default: ``TX`` (the capturing port sent the commands). The writer (``PcapngWriter``) writes
host bytes as TX and device bytes as RX, so its files read back with the default.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable, Iterator
from functools import partial
from typing import IO, Final

from xac1_proto.chunk import HOST, Chunk, Direction

from .base import MAX_TIME, Clock, FormatError, Sides, Source
from .timeline import TOLERANCE_S, Timeline

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
# the block types of the pcapng specification (SHB apart): IDB, packet (obsolete), SPB, name resolution,
# interface statistics, EPB, IRIG timestamp, ARINC 429, systemd journal export, decryption secrets, custom
_BLOCK_TYPES: Final = frozenset({*range(1, 11), 0x00000BAD, 0x40000BAD})
_MAX_RECORD: Final = 1 << 20
LOOK_AHEAD: Final = 1 << 18  # bytes searched at once by default for the next record after damage (a
# quarter of them: the longest record or block taken as a resynchronisation point)
BLOCK: Final = 1 << 17  # bytes read at once (at least) by default: the walk's block

# the walk's fields, by byte order
_PCAP_HEAD: Final = {o: struct.Struct(o + "4xII").unpack_from for o in "<>"}  # time fraction, length
# an EPB's type, length, interface, time high and low words, captured length; the same after the
# trailing length of the block before
_EPB_HEAD: Final = {o: struct.Struct(o + "6I").unpack_from for o in "<>"}
_EPB_TAIL: Final = {o: struct.Struct(o + "7I").unpack_from for o in "<>"}
_U32: Final = {o: struct.Struct(o + "I").unpack_from for o in "<>"}  # record seconds, trailing length
_RTAC_FAST: Final = struct.Struct(">IIB").unpack_from  # seconds, microseconds, event

_Packet = tuple[str, float | None, bytes]  # where, time (None: none), RTAC header and data


def sniff_bytes(first: bytes) -> int:
    return 99 if first[:4] in _PCAP_MAGIC or first[:4] == _SHB else 0


def read(src: Source, host_is: str | None = None, *, block: int = BLOCK,
         look_ahead: int = LOOK_AHEAD) -> Iterator[Chunk]:
    """The chunks of a pcap or pcapng file, read ``block`` bytes at a time (at least one): any block size
    gives the same chunks and problems. After damage the next plausible record is searched for
    ``look_ahead`` bytes at a time (at least 1024; records or blocks of up to a quarter of it are taken
    as that)."""
    if block < 1 or look_ahead < 1024:
        raise ValueError(f"block must be at least 1 byte and look_ahead 1024, not {block} and {look_ahead}")
    buf = _Buffer(src, block, look_ahead)
    magic = buf.peek(4)
    if magic not in _PCAP_MAGIC and magic != _SHB:
        raise FormatError(f"{src.name}: not a pcap or pcapng file (first bytes {magic.hex(' ')})")
    walk = _Walk(src, buf, Sides("pcap", host_is, ("TX", "RX")))
    if magic == _SHB:  # (the walk itself is the iterator: no generator hands its chunks on)
        return _pcapng_chunks(walk)
    if _pcap_start(walk, magic):
        return _pcap_chunks(walk)
    return iter(())


class _Buffer:
    """A look-ahead window over the file: ``peek`` without consuming, ``skip`` to consume; ``offset`` is
    the file offset of the window's first byte. The window is one immutable block read in large pieces
    and a position in it: a peek is one slice, a skip moves the position (no per-record copy of the
    rest); ``window`` gives the block itself to the walk's loop. Memory: a read block plus the largest
    peek (about one record)."""

    def __init__(self, src: Source, block: int, look_ahead: int) -> None:
        self.src = src
        self.block = block  # bytes read at once (at least)
        self.look_ahead = look_ahead  # bytes searched at once after damage
        self.longest = look_ahead // 4  # the longest record or block taken as a resynchronisation point
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
            more = self.src.read(max(n - have, self.block))
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
    """What reading one file carries from record to record (the walk's loop holds it in locals between
    the records it takes itself)."""

    def __init__(self, src: Source, buf: _Buffer, sides: Sides) -> None:
        self.src = src
        self.buf = buf
        self.clock = Clock(src.report)
        self.timeline = Timeline(src.report)
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

    def settle(self, n: int, last: Direction | None, t: float | None, latest: float) -> None:
        """What the walk's loop held in locals, handed back: records or blocks read, the last data
        packet's direction, the last good time (the clock's and the timeline's)."""
        self.n, self.last, self.clock.last, self.timeline.last = n, last, t, latest

    def interface(self, linktype: int, unit: float) -> None:
        """A pcapng interface description read."""
        self.interfaces.append((linktype, unit))
        self.units.append(unit if linktype in SERIAL_LINKTYPES else 0.0)


def _chunk(w: _Walk, where: str, t: float | None, payload: bytes) -> Chunk | None:
    """The chunk of one packet's RTAC header and data (None: none, or a damaged packet: reported): every
    case, where the walk's loop takes only the common one."""
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
    w.timeline.check(t, where)
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
    """The chunks of a pcap file's records, in one walk (see the module docstring). Each turn takes the
    common packets (TX/RX events, sane microseconds, a time in range and not running backwards) of the
    records in a row whole in the block read, then the record where that stopped (``_pcap_stop``: not all
    read yet, an uncommon packet, damage, the end)."""
    buf, new, rtac, max_time, max_record, tol = w.buf, Chunk, _RTAC_FAST, MAX_TIME, _MAX_RECORD, TOLERANCE_S
    head, seconds, by_event, ticks, unit = _PCAP_HEAD[w.order], _U32[w.order], w.by_event, w.ticks, w.unit
    more = True
    while more:
        block, start = buf.window()
        p, size = start, len(block)
        n, d, t, last = w.n, w.last, w.clock.last, w.timeline.last
        good = -1  # the offset of the last record taken (its seconds are the resynchronisation's hint)
        need = 0  # the record at p is read by _pcap_record (damage, an uncommon packet), else the bytes
        while True:  # from p that must be in the block to go on
            if p + 16 > size:
                need = 16
                break
            frac, incl = head(block, p)
            if incl > max_record or frac >= ticks or incl < 12:
                break
            q = p + 16 + incl
            if q > size:
                need = 16 + incl
                break
            secs, usecs, event = rtac(block, p + 16)
            d2 = by_event[event]
            t2 = secs + usecs / 1e6 if secs or usecs else seconds(block, p)[0] + frac * unit
            if d2 is None or usecs >= 1_000_000 or t2 >= max_time or t2 + tol < last:
                break
            n += 1
            d, good = d2, p
            t = last = t2
            if incl > 12:
                yield new(t, d, block[p + 28:q])
            p = q
        w.settle(n, d, t, last)
        if good >= 0:
            w.last_sec = seconds(block, good)[0]
        buf.advance(p - start)
        more, chunk = _pcap_stop(w, need)
        if chunk is not None:
            yield chunk


def _pcap_stop(w: _Walk, need: int) -> tuple[bool, Chunk | None]:
    """Where the walk's loop stopped: read on when the next ``need`` bytes are only not all read yet (True,
    None), else the record there, read by ``_pcap_record``."""
    if need and len(w.buf.peek(need)) >= need:
        return True, None
    return _pcap_record(w)


def _pcap_record(w: _Walk) -> tuple[bool, Chunk | None]:
    """One pcap record where the walk's loop stops (damage, the file's end): (False, None) at the end of
    the file, else (True, its chunk, or None after damage: reported, and the walk moved to the next
    plausible record)."""
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
    resync = partial(_pcap_resync, order=w.order, ticks=w.ticks, last_sec=w.last_sec, longest=buf.longest)
    why = None
    if incl > _MAX_RECORD:
        why = f"corrupt length {incl} (expected at most {_MAX_RECORD})"
    elif frac >= w.ticks:
        why = f"corrupt time: fraction {frac} (expected below {w.ticks})"
    else:
        whole = buf.peek(16 + incl)
        if len(whole) < 16 + incl:
            left = len(whole) - 16
            if resync(buf.offset, off + 1, buf.peek(buf.look_ahead)) is None:
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
    return True, _chunk(w, where, sec + frac * w.unit, data)


def _skip_damage(src: Source, buf: _Buffer, where: str, why: str, start: int,
                 scan: Callable[[int, int, bytes], int | None], unit: str) -> bool:
    """Report damage found at ``where`` and move to the next plausible record or block at or after
    ``start`` (True), or to the end of the file when there is none (False). ``scan(base, start,
    window)`` finds one in a look-ahead window; the window slides on, so memory stays bounded."""
    off = buf.offset
    while True:
        window = buf.peek(buf.look_ahead)
        found = scan(buf.offset, start, window)
        if found is not None:
            lost = found - off
            src.report.problem(where, f"{why}; {lost} byte(s) skipped to the next plausible {unit}",
                               nbytes=lost)
            buf.skip(found - buf.offset)
            return True
        if len(window) < buf.look_ahead:  # the end of the file is in the window
            buf.skip(len(window))
            lost = buf.offset - off
            src.report.problem(where, f"{why}; nothing plausible follows: the rest of the file ({lost} "
                                      f"byte(s)) is skipped", nbytes=lost)
            return False
        buf.skip(len(window) - buf.longest - 32)
        start = buf.offset


def _pcap_resync(base: int, start: int, window: bytes, *, order: str, ticks: int,
                 last_sec: int | None, longest: int) -> int | None:
    """The file offset of the next plausible pcap record at or after ``start`` in ``window`` (which
    starts at file offset ``base``): a sane fraction and length (at most ``longest``), a time near the last
    good one, and either the end of the window or another sane record header right after it."""
    for p in range(start - base, len(window) - 15):
        sec, frac, incl, orig = struct.unpack_from(order + "IIII", window, p)
        if frac >= ticks or incl > longest or incl > orig or incl < RTAC_HEADER.size:
            continue
        if last_sec is not None and abs(sec - last_sec) > 86400:
            continue
        nxt = p + 16 + incl
        if nxt > len(window):
            continue
        if nxt == len(window) or (nxt + 16 <= len(window) and
                                  _sane_pcap_header(window[nxt:nxt + 16], order, ticks, sec, longest)):
            return base + p
    return None


def _sane_pcap_header(rec: bytes, order: str, ticks: int, near: int, longest: int) -> bool:
    sec, frac, incl, orig = struct.unpack(order + "IIII", rec)
    return frac < ticks and incl <= min(orig, longest) and abs(sec - near) <= 86400


def _pcapng_chunks(w: _Walk) -> Iterator[Chunk]:
    """The chunks of a pcapng file's blocks, in one walk (see the module docstring). Each turn takes the
    common packets (enhanced packet blocks of TX/RX events on a serial interface, sane microseconds, a
    time in range and not running backwards) in a row whole in the block read (a block's trailing length
    and the next block's fixed fields read with one unpack), then the block where that stopped
    (``_pcapng_stop``: not all read yet, another block type, an uncommon packet, damage, the end)."""
    buf, new, rtac, max_time, max_record, tol = w.buf, Chunk, _RTAC_FAST, MAX_TIME, _MAX_RECORD, TOLERANCE_S
    more = True
    while more:
        block, start = buf.window()
        p, size = start, len(block)
        need = 24  # bytes from p that must be in the block read to go on (0: the loop stops at p)
        if p + 24 <= size:
            head, tail, units, by_event = _EPB_HEAD[w.order], _EPB_TAIL[w.order], w.units, w.by_event
            known = len(units)
            n, d, t, last = w.n, w.last, w.clock.last, w.timeline.last
            block_type, total, iface, hi, lo, cap = head(block, p)
            need = 0
            while block_type == _BLOCK_EPB and not total & 3 and 32 <= total <= max_record:
                q = p + total
                if q + 24 > size:
                    need = total + 24  # this block and the next one's fixed fields are not all read
                    break
                end, next_type, next_total, next_iface, next_hi, next_lo, next_cap = tail(block, q - 4)
                if end != total or iface >= known or not (unit := units[iface]) or \
                        not 12 <= cap <= total - 32:
                    break
                secs, usecs, event = rtac(block, p + 28)
                d2 = by_event[event]
                t2 = secs + usecs / 1e6 if secs or usecs else ((hi << 32) | lo) * unit
                if d2 is None or usecs >= 1_000_000 or t2 >= max_time or t2 + tol < last:
                    break
                n += 1
                d = d2
                t = last = t2
                if cap > 12:
                    yield new(t, d, block[p + 40:p + 28 + cap], None)
                p = q
                block_type, total, iface, hi, lo, cap = (next_type, next_total, next_iface, next_hi, next_lo,
                                                         next_cap)
            w.settle(n, d, t, last)
            buf.advance(p - start)
        more, chunk = _pcapng_stop(w, need)
        if chunk is not None:
            yield chunk


def _pcapng_stop(w: _Walk, need: int) -> tuple[bool, Chunk | None]:
    """Where the walk's loop stopped: read on when the next ``need`` bytes are only not all read yet (True,
    None), else the block there, read by ``_pcapng_block``."""
    if need and len(w.buf.peek(need)) >= need:
        return True, None
    return _pcapng_block(w)


def _pcapng_block(w: _Walk) -> tuple[bool, Chunk | None]:
    """One pcapng block where the walk's loop stops (another block type, damage, the file's end):
    (False, None) at the end of the file, else (True, its chunk, or None: a block without one, or damage:
    reported, and the walk moved to the next plausible block)."""
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
            if _pcapng_resync(buf.offset, off + 4, buf.peek(buf.look_ahead), order=w.order,
                              longest=buf.longest) is None:
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
        return _skip_damage(src, buf, where, why, off + 4,
                            partial(_pcapng_resync, order=w.order, longest=buf.longest), "block"), None
    buf.skip(total)
    if is_shb:
        w.interfaces, w.units = [], []
        return True, None
    if block_type == _BLOCK_EPB:  # one too short for its fixed fields (the walk's loop takes the others)
        return True, _epb_chunk(w, where, block[8:-4])
    packet = _packet(w, where, block_type, block[8:-4])
    return True, None if packet is None else _chunk(w, *packet)


def _bad_block_length(total: int, least: int) -> str | None:
    if total < least or total % 4 or total > _MAX_RECORD:
        return (f"block length {total} is not plausible (expected a multiple of 4 from {least} to "
                f"{_MAX_RECORD})")
    return None


def _pcapng_resync(base: int, start: int, window: bytes, *, order: str, longest: int) -> int | None:
    """The file offset of the next whole pcapng block at or after ``start`` in ``window`` (which starts
    at file offset ``base``; blocks are 4-byte aligned): a block type the format defines and a plausible
    length (at most ``longest``) repeated at its end (an EPB's captured and original lengths of 12 would
    otherwise read as a 12-byte block inside it)."""
    first = start - base
    first += -first % 4
    for p in range(first, len(window) - 11, 4):
        is_shb = window[p:p + 4] == _SHB
        orders = ("<", ">") if is_shb else (order,)
        if not is_shb and struct.unpack_from(order + "I", window, p)[0] not in _BLOCK_TYPES:
            continue
        for o in orders:
            total = struct.unpack_from(o + "I", window, p + 4)[0]
            if total > longest or _bad_block_length(total, 28 if is_shb else 12) is not None:
                continue
            if p + total <= len(window) and struct.unpack_from(o + "I", window, p + total - 4)[0] == total:
                return base + p
    return None


def _packet(w: _Walk, where: str, block_type: int, body: bytes) -> _Packet | None:
    """The packet of one pcapng block other than an EPB (None for a block that carries none, or a damaged
    one: reported)."""
    report, order = w.src.report, w.order
    if block_type == _BLOCK_IDB:
        if len(body) < 8:
            report.problem(where, f"interface description block body of {len(body)} byte(s), shorter than "
                                  f"its 8 fixed bytes: interface {len(w.interfaces)} is unusable")
            w.interface(-1, 1e-6)
            return None
        linktype = struct.unpack(order + "H", body[:2])[0]
        w.interface(linktype, _tsresol(body[8:], order))
        return None
    if block_type != _BLOCK_SPB:
        return None
    if len(body) < 4:
        report.problem(where, f"simple packet block body of {len(body)} byte(s), shorter than its 4 "
                              f"fixed bytes: skipped", nbytes=len(body))
        return None
    data = body[4:4 + struct.unpack(order + "I", body[:4])[0]]
    return (where, None, data) if _serial(w, where, 0, data) else None


def _epb_chunk(w: _Walk, where: str, body: bytes) -> Chunk | None:
    """The chunk of one enhanced packet block's body (None: none, or damage: reported)."""
    report = w.src.report
    if len(body) < 20:
        report.problem(where, f"enhanced packet block body of {len(body)} byte(s), shorter than its 20 "
                              f"fixed bytes: skipped", nbytes=len(body))
        return None
    iface, hi, lo, cap, _orig = struct.unpack(w.order + "IIIII", body[:20])
    if cap > len(body) - 20:
        report.problem(where, f"captured length {cap} is larger than the {len(body) - 20} byte(s) of "
                              f"packet data in its block: skipped", nbytes=len(body) - 20)
        return None
    data = body[20:20 + cap]
    if not _serial(w, where, iface, data):
        return None
    return _chunk(w, where, ((hi << 32) | lo) * w.interfaces[iface][1], data)


def _serial(w: _Walk, where: str, iface: int, data: bytes) -> bool:
    """Is ``iface`` a declared serial interface? (Else its packet is reported or counted unread.)"""
    report = w.src.report
    if iface >= len(w.interfaces):
        report.problem(where, f"packet on undeclared interface {iface}", nbytes=len(data))
        return False
    linktype = w.interfaces[iface][0]
    if linktype not in SERIAL_LINKTYPES:
        if iface not in w.warned:
            w.warned.add(iface)
            report.problem(where, f"interface {iface} has link type {linktype}, not serial "
                                  f"(250/147): its packets are skipped")
        report.unread_bytes += len(data)
        return False
    return True


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
