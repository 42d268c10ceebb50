"""Reader and writer for pcap and pcapng files of serial traffic (LINKTYPE_RTAC_SERIAL 250, USER0 147).

How this works: both link types carry, before the line's bytes, the 12-byte RTAC serial header of
Wireshark's ``rtacser`` dissector: arrival time as two big-endian 32-bit words (seconds since the
epoch, microseconds), an event type byte, a control-line bitmap byte (CTS 0x01, DCD 0x02, DSR 0x04,
RTS 0x08, DTR 0x10, RING 0x20, MBOK 0x40) and a 2-byte footer. Event types 0x01/0x03 (DATA_TX_START/
END) carry bytes the capturing port sent (``TX``), 0x02/0x04 (DATA_RX_START/END) bytes it received
(``RX``); 0x07 FRAMING_ERROR and 0x08 PARITY_ERROR mark their bytes as damaged (on the side of the
last data packet); other events carry no data. USER0 (147) is the older way such files were written
and is read the same. The reader walks pcap records or pcapng blocks (SHB, IDB, EPB, SPB, either byte
order, any if_tsresol) one at a time; a truncated record or block ends the file with a message saying
how many bytes were lost.

Host side default: ``TX`` (the capturing port sent the commands). The writer (``PcapngWriter``) writes
host bytes as TX and device bytes as RX, so its files read back with the default.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from typing import IO, Final

from xac1_proto.chunk import HOST, Chunk, Direction

from .base import FormatError, Sides, Source

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


def sniff_bytes(first: bytes) -> int:
    return 99 if first[:4] in _PCAP_MAGIC or first[:4] == _SHB else 0


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    magic = src.read(4)
    if magic in _PCAP_MAGIC:
        packets = _pcap_packets(src, magic)
    elif magic == _SHB:
        packets = _pcapng_packets(src)
    else:
        raise FormatError(f"{src.name}: not a pcap or pcapng file (first bytes {magic.hex(' ')})")
    sides = Sides("pcap", host_is, ("TX", "RX"))
    last: Direction | None = None
    for where, t, payload in packets:
        if len(payload) < RTAC_HEADER.size:
            src.report.problem(where, f"packet of {len(payload)} bytes is shorter than the 12-byte RTAC "
                                      f"serial header", nbytes=len(payload))
            continue
        secs, usecs, event, _lines, _footer = RTAC_HEADER.unpack_from(payload)
        data = payload[RTAC_HEADER.size:]
        if secs or usecs:
            t = secs + usecs / 1e6
        if event in TX_EVENTS or event in RX_EVENTS:
            d = sides.direction("TX" if event in TX_EVENTS else "RX")
            assert d is not None
            last = d
            if data:
                yield Chunk(t, d, data)
        elif event in ERROR_EVENTS:
            yield Chunk(t, last or HOST, data, ERROR_EVENTS[event])
        elif data:
            src.report.problem(where, f"RTAC event 0x{event:02x} carries {len(data)} byte(s) that are "
                                      f"not line data; skipped", nbytes=len(data))


def _need(src: Source, n: int, what: str) -> bytes | None:
    data = src.read(n)
    if len(data) < n:
        if data:
            src.report.problem(f"{src.name}@{src.pos - len(data)}", f"file ends inside {what}: "
                                                                  f"{n - len(data)} byte(s) missing",
                               nbytes=len(data))
        return None
    return data


def _pcap_packets(src: Source, magic: bytes) -> Iterator[tuple[str, float | None, bytes]]:
    order, unit = _PCAP_MAGIC[magic]
    header = _need(src, 20, "the pcap file header")
    if header is None:
        return
    linktype = struct.unpack(order + "HHiIII", header)[5] & 0x0FFFFFFF
    if linktype not in SERIAL_LINKTYPES:
        raise FormatError(f"{src.name}: pcap link type {linktype} is not serial (expected "
                          f"{LINKTYPE_RTAC_SERIAL} RTAC serial or {LINKTYPE_USER0} USER0)")
    n = 0
    while True:
        rec = _need(src, 16, "a record header")
        if rec is None:
            return
        n += 1
        sec, frac, incl, _orig = struct.unpack(order + "IIII", rec)
        if incl > _MAX_RECORD:
            src.report.problem(f"{src.name} record {n}", f"record length {incl} is not plausible: the file "
                                                        f"is corrupt from here on",
                               nbytes=src.size - src.pos)
            return
        data = _need(src, incl, f"record {n}")
        if data is None:
            return
        yield f"{src.name} record {n}", sec + frac * unit, data


def _pcapng_packets(src: Source) -> Iterator[tuple[str, float | None, bytes]]:
    order = "<"
    interfaces: list[tuple[int, float]] = []  # (linktype, seconds per timestamp unit)
    n = 0
    warned: set[int] = set()
    type_raw: bytes | None = _SHB  # read() consumed the first block's type
    while True:
        if type_raw is None:
            type_raw = _need(src, 4, "a block header")
            if type_raw is None:
                return
        if type_raw == _SHB:
            head = _need(src, 8, "a section header")  # block length, byte-order magic
            if head is None:
                return
            order = {b"\x4d\x3c\x2b\x1a": "<", b"\x1a\x2b\x3c\x4d": ">"}.get(head[4:], "")
            if not order:
                raise FormatError(f"{src.name}: pcapng section header with an unknown byte-order magic "
                                  f"{head[4:].hex(' ')}")
            total = struct.unpack(order + "I", head[:4])[0]
            if total < 28 or total % 4 or total > _MAX_RECORD or _need(src, total - 12, "a section "
                                                                                    "header") is None:
                return
            interfaces, type_raw = [], None
            continue
        block_type = struct.unpack(order + "I", type_raw)[0]
        type_raw = None
        raw_total = _need(src, 4, "a block header")
        if raw_total is None:
            return
        total = struct.unpack(order + "I", raw_total)[0]
        if total < 12 or total % 4 or total > _MAX_RECORD:
            src.report.problem(f"{src.name}@{src.pos - 8}", f"block length {total} is not plausible: the "
                                                           f"file is corrupt from here on",
                               nbytes=src.size - src.pos + 8)
            return
        body = _need(src, total - 8, f"block {n + 1}")
        if body is None:
            return
        body = body[:-4]
        n += 1
        where = f"{src.name} block {n}"
        if block_type == _BLOCK_IDB:
            linktype = struct.unpack(order + "H", body[:2])[0]
            interfaces.append((linktype, _tsresol(body[8:], order)))
        elif block_type in (_BLOCK_EPB, _BLOCK_SPB):
            if block_type == _BLOCK_EPB:
                iface, hi, lo, cap, _orig = struct.unpack(order + "IIIII", body[:20])
                data = body[20:20 + cap]
            else:
                iface, hi, lo = 0, 0, 0
                data = body[4:]
            if iface >= len(interfaces):
                src.report.problem(where, f"packet on undeclared interface {iface}", nbytes=len(data))
                continue
            linktype, unit = interfaces[iface]
            if linktype not in SERIAL_LINKTYPES:
                if iface not in warned:
                    warned.add(iface)
                    src.report.problem(where, f"interface {iface} has link type {linktype}, not serial "
                                              f"(250/147): its packets are skipped")
                src.report.unread_bytes += len(data)
                continue
            t = ((hi << 32) | lo) * unit if block_type == _BLOCK_EPB else None
            yield where, t, data


def _tsresol(options: bytes, order: str) -> float:
    """Seconds per timestamp unit from an IDB's options (default microseconds)."""
    i = 0
    while i + 4 <= len(options):
        code, length = struct.unpack(order + "HH", options[i:i + 4])
        if code == 0:
            break
        if code == 9 and length >= 1:
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
