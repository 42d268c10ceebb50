"""Turn a terminal's parity/framing error marks back into bytes and ``Chunk.error`` text (sans-IO).

How it works. A live tap is read with ``PARMRK`` on (``taps.configure_raw(mark_errors=True)``): the
kernel then delivers a byte received with a framing (or parity) error as ``FF 00 X``, a break as
``FF 00 00``, and a real ``FF`` byte doubled as ``FF FF``. ``MarkDecoder.feed`` undoes that: clean runs
come out as ``(bytes, None)``, each marked byte on its own as ``(X, reason)``. A mark cut by a read is
held until the next read. The XA-C1 line has no parity bit (docs/protocol.md "Line": 8N1), so a
mark is a framing error, or a break when its byte is ``00`` (the kernel cannot tell those two apart).
"""

from __future__ import annotations

from typing import Final

MARK: Final = 0xFF
FRAMING_ERROR: Final = "framing error"
FRAMING_ERROR_OR_BREAK: Final = "framing error or break"


class MarkDecoder:
    """``feed(data) -> [(bytes, error or None)]``; ``flush()`` gives back a held partial mark as data."""

    def __init__(self) -> None:
        self._held = b""

    def feed(self, data: bytes) -> list[tuple[bytes, str | None]]:
        buf = self._held + data
        out: list[tuple[bytes, str | None]] = []
        clean = bytearray()
        i = 0
        while i < len(buf):
            if buf[i] != MARK:
                clean.append(buf[i])
                i += 1
                continue
            if i + 1 == len(buf) or (buf[i + 1] == 0 and i + 2 == len(buf)):
                break  # the rest of the mark comes with the next read
            if buf[i + 1] == MARK:  # an escaped FF
                clean.append(MARK)
                i += 2
            elif buf[i + 1] == 0:
                if clean:
                    out.append((bytes(clean), None))
                    clean = bytearray()
                byte = buf[i + 2]
                out.append((bytes([byte]), FRAMING_ERROR_OR_BREAK if byte == 0 else FRAMING_ERROR))
                i += 3
            else:  # not a mark PARMRK makes: keep the byte as it is
                clean.append(MARK)
                i += 1
        self._held = bytes(buf[i:])
        if clean:
            out.append((bytes(clean), None))
        return out

    def flush(self) -> bytes:
        held, self._held = self._held, b""
        return held
