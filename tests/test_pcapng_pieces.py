"""pcapng recordings: a device frame read in pieces within its own wire time is one packet (issue 40
item 6: each answer the proxy read as its first byte, then the rest, was two packets in Wireshark), its
pieces' sizes and times in a packet comment, and the decoder reads the recording as it read the
pieces. The packet list as tshark shows it: tests/test_wireshark_live.py."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.analyzer import Analyzer
from sniffer.io.pcapng_writer import PIECES_PREFIX, PcapngRecorder
from sniffer.io.registry import Capture
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk

BYTE = spec.BYTE_TIME_S


def record(path: Path, chunks: list[Chunk], ticks: dict[int, float] | None = None) -> list[dict]:
    """Write ``chunks`` as the live shells do (each with the records it completed; ``ticks``: a tick at
    that time after chunk k), and return the decoder's records of them."""
    analyzer, out = Analyzer(), []
    with PcapngRecorder(path, source="pieces") as rec:
        for k, chunk in enumerate(chunks):
            records = analyzer.feed(chunk)
            rec.write(chunk, records)
            out += records
            if ticks and k in ticks:
                found = analyzer.tick(ticks[k])
                rec.verdicts(found, ticks[k])
                out += found
        found = analyzer.close()
        rec.verdicts(found)
        out += found
    return [r.to_dict() for r in out]


def read_back(path: Path) -> list[Chunk]:
    with Capture([str(path)], "pcap") as capture:
        chunks = list(capture)
        assert not capture.report.total_problems
    return chunks


def test_an_answer_read_as_its_first_byte_then_the_rest_is_one_packet(tmp_path):
    """``0RV100`` read as ``0`` and then ``RV100 CR LF`` 1 ms later is one packet at the first byte's
    time, with the comment ``xac1 arrived in 2 pieces: 1 byte at +0.000 ms, 7 bytes at +1.000 ms``; the
    host's own pieces stay as they came, and so do device pieces after a pause longer than the wire
    time, or flagged by the capture tool."""
    t = 1_700_000_000.0
    chunks = [Chunk(t, HOST, b"0R"), Chunk(t + 0.001, HOST, b"V\r\n"),
              Chunk(t + 0.010, DEVICE, b"0"), Chunk(t + 0.011, DEVICE, b"RV100\r\n"),
              Chunk(t + 0.100, HOST, b"0RS\r\n"),
              Chunk(t + 0.110, DEVICE, b"0RS"), Chunk(t + 0.300, DEVICE, b"02\r\n"),
              Chunk(t + 0.400, HOST, b"0RS\r\n"),
              Chunk(t + 0.410, DEVICE, b"0R"), Chunk(t + 0.411, DEVICE, b"S02\r\n", "UART framing error")]
    path = tmp_path / "p.pcapng"
    record(path, chunks)
    back = read_back(path)
    assert [(c.dir, c.data, c.error) for c in back] == [
        (HOST, b"0R", None), (HOST, b"V\r\n", None), (DEVICE, b"0RV100\r\n", None), (HOST, b"0RS\r\n", None),
        (DEVICE, b"0RS", None), (DEVICE, b"02\r\n", None), (HOST, b"0RS\r\n", None), (DEVICE, b"0R", None),
        (DEVICE, b"S02\r\n", "UART framing error")]
    assert back[2].t == pytest.approx(t + 0.010, abs=1e-6)
    assert f"{PIECES_PREFIX}2 pieces: 1 byte at +0.000 ms, 7 bytes at +1.000 ms".encode() in path.read_bytes()
    assert path.read_bytes().count(PIECES_PREFIX.encode()) == 1


def test_held_bytes_are_written_when_their_wire_time_has_passed(tmp_path):
    """A device piece that ends no line and gets no rest is written at the first ``verdicts`` call after
    a whole frame's wire time (the live shells tick), not only at the next chunk or the end: a recording
    killed then still holds it."""
    t = 1_700_000_000.0
    path = tmp_path / "h.pcapng"
    rec = PcapngRecorder(path)
    rec.write(Chunk(t, DEVICE, b"0RV1"))
    rec.verdicts([], t + 0.01)
    assert b"0RV1" not in path.read_bytes()
    rec.verdicts([], t + 1.0)
    assert b"0RV1" in path.read_bytes()
    rec.close()
    assert [c.data for c in read_back(path)] == [b"0RV1"]


_EXCHANGES = [(b"0RV\r\n", b"0RV100\r\n"), (b"0RS\r\n", b"0RS02\r\n"), (b"0RP1\r\n", b"0RP19302000ABC\r\n"),
              (b"0QQ\r\n", b"0%%03\r\n"), (b"0RC\r\n", b"0RC0000200123A\r\n"), (b"0RV\r\n", b"junk")]


@settings(max_examples=budget(100), deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_EXCHANGES), st.lists(st.integers(1, 15), max_size=3),
                          st.lists(st.sampled_from([0.0, BYTE, 3 * BYTE, 0.02, 0.2]), min_size=3, max_size=3),
                          st.sampled_from([0.004, 0.05, 1.5])),
                min_size=1, max_size=10))
def test_the_decoder_reads_joined_pieces_as_it_read_the_pieces(tmp_path_factory, exchanges):
    """Answers cut anywhere, their pieces within or beyond their wire time, late answers and missing
    ones: the recording's packets decode to the very records the pieces decoded to (times, latencies,
    pairing, every verdict), and hold the same bytes in the same order."""
    chunks, t = [], 1_700_000_000.0
    for (command, answer), cuts, pauses, gap in exchanges:
        chunks.append(Chunk(round(t, 6), HOST, command))  # the recording keeps microseconds
        t += len(command) * BYTE + 0.004
        at = 0
        for cut, pause in zip([*sorted(set(c for c in cuts if c < len(answer))), len(answer)], pauses,
                              strict=False):
            if cut > at:
                chunks.append(Chunk(round(t, 6), DEVICE, answer[at:cut]))
                t += (cut - at) * BYTE + pause
                at = cut
        if at < len(answer):
            chunks.append(Chunk(round(t, 6), DEVICE, answer[at:]))
        t += gap
    path = tmp_path_factory.mktemp("pieces") / "r.pcapng"
    live = record(path, chunks)
    back = read_back(path)
    assert [r.to_dict() for r in _analyze(back)] == live
    for side in (HOST, DEVICE):
        sent = b"".join(c.data for c in chunks if c.dir == side)
        assert b"".join(c.data for c in back if c.dir == side) == sent
    assert len(back) <= len(chunks)


def _analyze(chunks: list[Chunk]) -> list:
    analyzer = Analyzer()
    return [r for c in chunks for r in analyzer.feed(c)] + analyzer.close()

