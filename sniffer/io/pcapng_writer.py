"""pcapng recordings that Wireshark opens: one packet per chunk (a device frame's pieces as one), our
verdicts as packet comments.

How this works. The file is a pcapng section (SHB, then one IDB with LINKTYPE_RTAC_SERIAL, 250) and
one Enhanced Packet Block per chunk, as it was read. Each packet's data is Wireshark's 12-byte RTAC
serial header (arrival time in seconds and microseconds, event type, control lines, footer) and then
the line's bytes. Directions: bytes the host sent (commands) are ``DATA_TX_START`` (0x01), bytes the
controller sent (answers) ``DATA_RX_START`` (0x02): the capture is seen from the host's port, which is
what ``sniffer.io.pcap`` reads back by default (``TX`` is the host). A chunk flagged by the capture tool
(``Chunk.error``: a UART framing or parity error) is a ``FRAMING_ERROR`` (0x07) or ``PARITY_ERROR``
(0x08) event holding those bytes; RTAC error events carry no direction, so when the previous data packet
was of the other direction an empty data event of the right direction goes first (readers take an error
event's bytes for the last data direction). Timestamps: microseconds (``if_tsresol`` 6) in the block
and in the RTAC header.

Verdicts (docs/protocol.md "Violation codes") travel as packet comments (``opt_comment``), one line
each, on the packet that completes the frame: ``xac1 #I CODE (SIDE): SENTENCE`` per violation of record
``I`` (``SIDE``: whose fault, ``host`` or ``device``) and ``xac1 #I reply_to=#J latency_ms=MS`` on an
answer. A verdict found later (``no-answer`` when its deadline passes) goes on the packet being written
with the chunk that revealed it, or on an empty ``STATUS_CHANGE`` (0x00) packet of its own
(``verdicts()``: it carries no direction and no data). The dissector
(``sniffer/wireshark``) turns the comments into ``xac1.violation``, ``xac1.reply_to``,
``xac1.latency_ms`` and expert info.

A device frame that arrived in pieces within its own wire time (the port was read while its bytes were
still coming: the first byte, then the rest) is one packet, as the decoder reads it: device bytes that
end no line are held, and the next device piece joins them when it comes within the wire time of all
the bytes held (``BYTE_TIME_S`` a byte, plus ``PIECE_SLACK_S`` for the reads' own delay). The packet has
the first piece's time and a comment with every piece's size and time (``xac1 arrived in 2 pieces: 1
byte at +0.000 ms, 7 bytes at +1.042 ms``). Anything else (host bytes, a piece after a longer pause, an
error, a verdict packet, the wire time running out at a ``verdicts`` call) writes the held bytes first.
Host pieces are kept as they came: how the host software wrote a command is its own behaviour.

Every block is written whole and flushed to the OS at once (fsynced at least once a second and on close),
so a recorder killed with ``kill -9`` leaves a file Wireshark opens up to its last packet (device bytes
held for the rest of their frame apart: at most one frame's wire time).

Why by hand: three fixed block layouts (SHB, IDB, EPB with options) are a few ``struct`` calls.
python-pcapng (``FileWriter``) and dpkt (``pcapng.Writer``) write the same blocks, but each would be a
new runtime dependency for those few lines, python-pcapng builds and validates an object per packet (its
option schema) on the live path, and neither would be used to read: the reader stays in
``sniffer.io.pcap``, so read speed is unaffected either way.
"""

from __future__ import annotations

import os
import struct
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import IO, Final, Protocol

from xac1_proto import __version__, spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.framer import MAX_FRAME
from xac1_proto.output_file import can_sync, close_stream, open_stream
from xac1_proto.recording import RecordingWriter

from ..records import FrameRecord, Record, TimeoutRecord

LINKTYPE_RTAC_SERIAL: Final = 250
RTAC_HEADER: Final = struct.Struct(">IIBBH")  # seconds, microseconds, event, control lines, footer
EVENT_TX: Final = 0x01  # DATA_TX_START: the host's bytes
EVENT_RX: Final = 0x02  # DATA_RX_START: the controller's bytes
EVENT_STATUS: Final = 0x00  # STATUS_CHANGE: an empty packet carrying verdicts found later
EVENT_FRAMING_ERROR: Final = 0x07
EVENT_PARITY_ERROR: Final = 0x08
TSRESOL_US: Final = 6  # if_tsresol: 10^-6 s
FSYNC_EVERY_S: Final = 1.0
COMMENT_PREFIX: Final = "xac1 "
PIECES_PREFIX: Final = COMMENT_PREFIX + "arrived in "  # the comment of a frame written from its pieces
PIECE_SLACK_S: Final = 0.005  # beyond the wire time: how late a read may see the bytes that came

_SHB, _IDB, _EPB = 0x0A0D0D0A, 1, 6
_OPT_END, _OPT_COMMENT = 0, 1
_SHB_HARDWARE, _SHB_OS, _SHB_USERAPPL = 2, 3, 4
_IF_NAME, _IF_DESCRIPTION, _IF_TSRESOL = 2, 3, 9


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def _options(items: Iterable[tuple[int, bytes]]) -> bytes:
    body = b"".join(_option(code, value) for code, value in items)
    return body + _option(_OPT_END, b"") if body else b""


def _sentence(code: str, details: Sequence[str]) -> str:
    """The record's sentence for ``code`` (details end with ``(code)``), else the code's meaning."""
    for d in details:
        if d.endswith(f"({code})"):
            return d
    spec_row = spec.VIOLATION_TABLE.get(code)  # type: ignore[call-overload]
    return spec_row.meaning if spec_row is not None else code


def comments(record: Record) -> list[str]:
    """The packet comments that carry one record's verdicts (see the module docstring)."""
    out: list[str] = []
    i = record.command if isinstance(record, TimeoutRecord) else record.i
    for code in record.violations:
        row = spec.VIOLATION_TABLE.get(code)
        side = row.side(record.dir) if row is not None else record.dir
        text = " ".join(_sentence(code, record.details).split())  # one line
        out.append(f"{COMMENT_PREFIX}#{i} {code} ({side}): {text}")
    if isinstance(record, FrameRecord) and record.dir != HOST and record.reply_to is not None:
        line = f"{COMMENT_PREFIX}#{i} reply_to=#{record.reply_to}"
        if record.latency_ms is not None:
            line += f" latency_ms={record.latency_ms:.3f}"
        out.append(line)
    return out


class _Held:
    """Device bytes that end no line, waiting for the rest of their frame: the pieces, their times and
    the comments of the records they completed."""

    def __init__(self, chunk: Chunk, notes: list[str]) -> None:
        self.t = chunk.t
        self.pieces = [(chunk.t, chunk.data)]
        self.notes = notes

    def takes(self, chunk: Chunk) -> bool:
        """Is ``chunk`` the rest of the held bytes' frame: device bytes, unflagged, within the wire time
        of every byte held and its own?"""
        if chunk.dir == HOST or chunk.error or chunk.t is None or self.t is None:
            return False
        size = sum(len(data) for _, data in self.pieces) + len(chunk.data)
        return 0 <= chunk.t - self.t <= size * spec.BYTE_TIME_S + PIECE_SLACK_S

    def add(self, chunk: Chunk, notes: list[str]) -> None:
        self.pieces.append((chunk.t, chunk.data))
        self.notes += notes

    def expired(self, now: float | None) -> bool:
        """Has the wire time of a whole frame passed since the first piece (nothing more can join)?"""
        return now is None or self.t is None or now - self.t > MAX_FRAME * spec.BYTE_TIME_S + PIECE_SLACK_S

    @property
    def data(self) -> bytes:
        return b"".join(data for _, data in self.pieces)

    def comment(self) -> str:
        """Every piece's size and time after the first (``PIECES_PREFIX``)."""
        t0 = self.t or 0.0
        parts = [f"{len(data)} byte{'s' if len(data) != 1 else ''} at +{((t or t0) - t0) * 1e3:.3f} ms"
                 for t, data in self.pieces]
        return f"{PIECES_PREFIX}{len(self.pieces)} pieces: {', '.join(parts)}"


class PcapngRecorder:
    """Write chunks (and the verdicts they complete) as a pcapng file; see the module docstring.

    ``source`` names the ports and settings (the section comment); a context manager."""

    def __init__(self, path: str | os.PathLike[str], source: str = "", started: float | None = None, *,
                 wait_for_reader: bool = False) -> None:
        self.path = Path(path)
        # never a FIFO nobody reads (unless its reader is on its way: extcap), nor someone's file
        self._f: IO[bytes] = open_stream(path, wait_for_reader=wait_for_reader)
        self._syncable = can_sync(self._f)  # not a FIFO (extcap), not /dev/null
        self._last_sync = time.monotonic()
        self._last_t = time.time() if started is None else started
        self._last_dir: str | None = None
        self._held: _Held | None = None  # device bytes waiting for the rest of their frame
        self.packets = 0
        section = [(_SHB_USERAPPL, f"xac1 {__version__}".encode()),
                   (_SHB_OS, os.uname().sysname.encode())]
        if source:
            section.append((_OPT_COMMENT, f"xac1 {__version__}: {source}".encode()))
        self._block(_SHB, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1) + _options(section))
        idb_opts = [(_IF_NAME, b"xac1"), (_IF_DESCRIPTION, b"XA-C1 serial line (RTAC serial: TX host, RX "
                                                            b"controller)"),
                    (_IF_TSRESOL, bytes([TSRESOL_US]))]
        self._block(_IDB, struct.pack("<HHI", LINKTYPE_RTAC_SERIAL, 0, 0) + _options(idb_opts))
        self._flush()

    def _block(self, block_type: int, body: bytes) -> None:
        body += b"\0" * (-len(body) % 4)
        total = 12 + len(body)
        self._f.write(struct.pack("<II", block_type, total) + body + struct.pack("<I", total))

    def _flush(self) -> None:
        self._f.flush()
        now = time.monotonic()
        if self._syncable and now - self._last_sync >= FSYNC_EVERY_S:
            os.fsync(self._f.fileno())
            self._last_sync = now

    def _packet(self, t: float | None, event: int, data: bytes, notes: Sequence[str]) -> None:
        if t is None:
            t = self._last_t
        self._last_t = t
        usec_total = max(0, round(t * 1e6))
        secs, usecs = divmod(usec_total, 1_000_000)
        payload = RTAC_HEADER.pack(secs & 0xFFFFFFFF, usecs, event, 0, 0) + data
        body = struct.pack("<IIIII", 0, usec_total >> 32, usec_total & 0xFFFFFFFF, len(payload),
                           len(payload)) + payload + b"\0" * (-len(payload) % 4)
        body += _options((_OPT_COMMENT, n.encode("utf-8")) for n in notes)
        self._block(_EPB, body)
        self.packets += 1

    def write(self, chunk: Chunk, records: Sequence[Record] = ()) -> None:
        """One chunk as one packet, carrying the comments of the records it completed; device pieces of
        one frame within its wire time as one packet (module docstring)."""
        notes = [c for r in records for c in comments(r)]
        held = self._held
        if held is not None:
            if held.takes(chunk):
                held.add(chunk, notes)
                if chunk.data.endswith(spec.FRAME_END):
                    self._write_held()
                return
            self._write_held()
        if chunk.dir != HOST and not chunk.error and chunk.data and chunk.t is not None and \
                not chunk.data.endswith(spec.FRAME_END):
            self._held = _Held(chunk, notes)
            return
        data_event = EVENT_TX if chunk.dir == HOST else EVENT_RX
        if chunk.error:
            if self._last_dir != chunk.dir:
                self._packet(chunk.t, data_event, b"", ())
            event = EVENT_PARITY_ERROR if "parity" in chunk.error.lower() else EVENT_FRAMING_ERROR
        else:
            event = data_event
        self._last_dir = chunk.dir
        self._packet(chunk.t, event, chunk.data, notes)
        self._flush()

    def _write_held(self) -> None:
        held, self._held = self._held, None
        if held is None:
            return
        notes = held.notes if len(held.pieces) == 1 else [*held.notes, held.comment()]
        self._last_dir = DEVICE
        self._packet(held.t, EVENT_RX, held.data, notes)
        self._flush()

    def verdicts(self, records: Sequence[Record], t: float | None = None) -> None:
        """Verdicts found with no new bytes (time passed, or the end): an empty packet of their own. Also
        the moment held device bytes are written once their frame's wire time has passed (``t``)."""
        notes = [c for r in records for c in comments(r)]
        if self._held is not None and (notes or self._held.expired(t)):
            self._write_held()
        if notes:
            when = t if t is not None else next((r.t for r in records if r.t is not None), None)
            self._packet(when, EVENT_STATUS, b"", notes)
            self._flush()

    def note(self, text: str, t: float | None = None) -> None:
        """A note of the shell's (``xac1 sim --replay``: a line not in the capture): an empty packet with
        the text as its comment, as verdicts found with no new bytes are written."""
        self._write_held()
        self._packet(t, EVENT_STATUS, b"", [text])
        self._flush()

    def close(self) -> None:
        if not self._f.closed:
            try:
                self._write_held()
            finally:
                close_stream(self._f)

    def __enter__(self) -> PcapngRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Recorder(Protocol):
    """What the live shells write to: chunks with the records they completed, later verdicts, close."""

    def write(self, chunk: Chunk, records: Sequence[Record] = ()) -> None: ...

    def verdicts(self, records: Sequence[Record], t: float | None = None) -> None: ...

    def note(self, text: str, t: float | None = None) -> None: ...

    def close(self) -> None: ...


class JsonlRecorder:
    """Our JSON lines recording (``xac1_proto.recording``) behind the ``Recorder`` shape: it keeps the
    raw chunks only (``xac1 decode`` recomputes the verdicts)."""

    def __init__(self, path: str | os.PathLike[str], source: str = "",
                 writer: RecordingWriter | None = None) -> None:
        self._writer = writer if writer is not None else RecordingWriter(path, source=source)
        self.path = self._writer.path

    @classmethod
    def around(cls, writer: RecordingWriter) -> JsonlRecorder:
        """An open ``RecordingWriter`` behind the ``Recorder`` shape."""
        return cls(writer.path, writer=writer)

    def write(self, chunk: Chunk, records: Sequence[Record] = ()) -> None:
        self._writer.write(chunk)

    def verdicts(self, records: Sequence[Record], t: float | None = None) -> None:
        pass

    def note(self, text: str, t: float | None = None) -> None:
        self._writer.note(text, t)

    def close(self) -> None:
        self._writer.close()


PCAPNG_SUFFIXES: Final = (".pcapng",)


class AnalyzingRecorder:
    """A recorder fed by a shell with no analyzer of its own (the simulator's log): it runs the
    sniffer's ``Analyzer`` over the chunks and writes each with the verdicts it completed."""

    def __init__(self, inner: Recorder) -> None:
        from ..analyzer import Analyzer

        self.inner = inner
        self.analyzer = Analyzer()

    def write(self, chunk: Chunk, records: Sequence[Record] = ()) -> None:
        found: list[Record] = []
        try:
            found = self.analyzer.feed(chunk)
        finally:
            self.inner.write(chunk, [*records, *found])

    def verdicts(self, records: Sequence[Record], t: float | None = None) -> None:
        self.inner.verdicts(records, t)

    def note(self, text: str, t: float | None = None) -> None:
        self.inner.note(text, t)

    def close(self) -> None:
        try:
            self.inner.verdicts(self.analyzer.close())
        finally:
            self.inner.close()


def is_pcapng(path: str | os.PathLike[str]) -> bool:
    return str(path).lower().endswith(PCAPNG_SUFFIXES)


def open_recording(path: str | os.PathLike[str], source: str = "", analyze: bool = False,
                   fmt: str | None = None) -> Recorder:
    """The recording for ``path``, by suffix: ``.pcapng`` -> pcapng (Wireshark), anything else -> our
    JSON lines recording (``fmt`` "pcapng" or "jsonl" overrides: a FIFO's name says nothing).
    ``source`` names the tool's ports and settings (the section comment). ``analyze``: the caller has
    no analyzer, so a pcapng recording runs one to carry the verdicts. Raises ``OSError``."""
    if fmt == "pcapng" or (fmt is None and is_pcapng(path)):
        # the format named (extcap): a FIFO Wireshark opens its end of, perhaps a moment later
        recorder = PcapngRecorder(path, source=source, wait_for_reader=fmt is not None)
        return AnalyzingRecorder(recorder) if analyze else recorder
    return JsonlRecorder(path, source=source)

