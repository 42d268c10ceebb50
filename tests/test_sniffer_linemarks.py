"""Framing-error marks of a live tap (termios PARMRK) become ``Chunk.error`` on exactly the marked bytes,
and a real FF byte, which the kernel doubles, is kept once (docs/protocol.md "Line": 8N1, no parity)."""

from __future__ import annotations

import os
import select
import termios

from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.linemarks import FRAMING_ERROR, FRAMING_ERROR_OR_BREAK, MarkDecoder
from sniffer.taps import ReadOnlyPort


def kernel_marks(line: list[tuple[int, bool]]) -> bytes:
    """What a terminal with PARMRK (and INPCK, no ISTRIP) delivers for ``(byte, framing error)`` pairs."""
    out = bytearray()
    for byte, bad in line:
        out += bytes([0xFF, 0x00, byte]) if bad else (b"\xff\xff" if byte == 0xFF else bytes([byte]))
    return bytes(out)


@settings(max_examples=budget(150))
@given(st.lists(st.tuples(st.sampled_from([0x00, 0x0A, 0x30, 0xFF, 0x7F]) | st.integers(0, 255),
                          st.booleans()), max_size=40),
       st.lists(st.integers(1, 7), max_size=20))
def test_marks_undone_whatever_the_reads(line, cuts):
    """However the marked stream is cut into reads, every byte comes back once, in order, and a piece
    carries an error exactly when it is one marked byte (a 00 byte: maybe a break)."""
    stream, at, decoder, pieces = kernel_marks(line), 0, MarkDecoder(), []
    for size in cuts + [len(kernel_marks(line))]:
        pieces += decoder.feed(stream[at: at + size])
        at += size
    assert decoder.flush() == b""
    assert b"".join(data for data, _ in pieces) == bytes(b for b, _ in line)
    flagged = [(data, error) for data, error in pieces if error is not None]
    assert flagged == [(bytes([b]), FRAMING_ERROR_OR_BREAK if b == 0 else FRAMING_ERROR)
                       for b, bad in line if bad]
    assert all(data for data, _ in pieces)


def test_held_partial_mark_flushes_as_data():
    """A mark cut at the end of the data is held, and given back as plain bytes at the end."""
    decoder = MarkDecoder()
    assert decoder.feed(b"0R\xff") == [(b"0R", None)]
    assert decoder.feed(b"\x00") == []
    assert decoder.flush() == b"\xff\x00"


def test_tap_port_marks_errors_and_keeps_ff_once():
    """A tap is opened with PARMRK and INPCK on (so a UART's framing errors come marked) and ISTRIP
    off; the kernel then doubles a real FF byte on the way in, and the tap gives it back once."""
    master, slave = os.openpty()
    port = ReadOnlyPort(os.ttyname(slave), "host")
    try:
        iflag = termios.tcgetattr(port.fileno())[0]
        assert iflag & termios.PARMRK and iflag & termios.INPCK and not iflag & termios.ISTRIP
        os.write(master, b"\x000RV\xff\r\n")
        got = []
        while b"".join(d for d, _ in got) != b"\x000RV\xff\r\n":
            assert select.select([port.fileno()], [], [], 5)[0], f"only {got} came"
            got += port.read()
        assert all(error is None for _, error in got)
    finally:
        port.close()
        os.close(master)
        os.close(slave)
