"""What ``xac1 decode`` prints, as a person reads it: bytes are shown as they came (nothing in them is
taken for rich markup or an emoji code), and an offline decode, which writes its lines in batches, still
prints every record it decoded when it is stopped part way (Ctrl-C, a crash)."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from sniffer.analyzer import Analyzer
from sniffer.records import FrameRecord
from sniffer.view import BATCH_LINES, JsonlView, TextView, show_raw
from xac1_proto.chunk import HOST, Chunk
from xac1_proto.cli import main

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow  # starts a process
def test_bytes_that_look_like_markup_or_emoji_codes_are_shown_as_typed(tmp_path: Path) -> None:
    """``:smile:`` in a frame was shown as an emoji and ``[bold]`` vanished into styling: the decoder
    must show the bytes on the line, whatever they look like."""
    capture = tmp_path / "host.bin"
    capture.write_bytes(b"0RV:smile:[bold]x\\\r\n0RV\r\n")
    for color in ("--no-color", "--color"):
        out = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(capture), "--input-format",
                              "raw", color], capture_output=True, text=True, timeout=60, cwd=ROOT).stdout
        assert "0RV:smile:[bold]x\\\\\\r\\n" in out.replace("\x1b[0m", "").replace("\x1b[36m", ""), out
        assert "\N{SMILING FACE WITH OPEN MOUTH AND SMILING EYES}" not in out


def test_show_raw_escapes_every_byte_the_same_way() -> None:
    """Printable ASCII as is, CR LF and backslash escaped, every other byte as ``\\xNN``."""
    every = bytes(range(256))
    shown = show_raw(every)
    expected = "".join({0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}.get(b)
                       or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}") for b in every)
    assert shown == expected


@pytest.mark.parametrize("fmt", ["text", "jsonl"])
def test_an_offline_view_writes_in_batches_and_loses_nothing_on_flush(fmt: str) -> None:
    """Offline (``live=False``) into a file: lines wait for a batch, then come out in order; ``flush``
    writes the rest. Live (the sniffer): every record is out as soon as it is written."""
    records = Analyzer().feed(Chunk(None, HOST, b"0RV\r\n" * (BATCH_LINES + 3)))
    assert len(records) == BATCH_LINES + 3 and all(isinstance(r, FrameRecord) for r in records)
    offline, live = io.StringIO(), io.StringIO()
    views = [(TextView(offline, False, live=False) if fmt == "text" else JsonlView(offline, live=False)),
             (TextView(live, False, live=True) if fmt == "text" else JsonlView(live, live=True))]
    lines = 0
    for record in records:
        for view in views:
            view.write(record)
        assert live.getvalue().count("\n") > lines  # out at once
        lines = live.getvalue().count("\n")
        assert offline.getvalue().count("\n") == (lines // BATCH_LINES) * BATCH_LINES
    assert lines > BATCH_LINES and offline.getvalue() != live.getvalue()  # a batch out, the rest held
    views[0].flush()
    assert offline.getvalue() == live.getvalue()


@pytest.mark.parametrize("fmt", ["text", "jsonl"])
@pytest.mark.parametrize("stop_after", [6, 151, 300])
def test_an_interrupted_decode_prints_every_record_decoded_so_far(fmt: str, stop_after: int, monkeypatch,
                                                                  capsys, tmp_path: Path) -> None:
    """Ctrl-C (or any exception) in the reader after some chunks, inside a stretch of exchanges the fast
    lane takes in bulk or not: the records of every chunk read before it are printed, not held back in
    an unwritten batch: exactly those ``feed`` gives for those chunks one at a time."""
    from sniffer.io.pcap import PcapngWriter
    from sniffer.io.registry import Capture
    from xac1_proto.chunk import DEVICE

    chunks = []
    for n in range(200):  # a clean exchange over and over (the lane's stretches), one late answer
        chunks += [Chunk(1.79e9 + n, HOST, b"0RV\r\n"), Chunk(1.79e9 + n + (2.0 if n == 120 else 0.002),
                                                               DEVICE, b"0RV100\r\n")]
    capture = tmp_path / "capture.pcapng"
    with PcapngWriter(capture) as writer:
        for chunk in chunks:
            writer.write(chunk)
    assert main(["decode", str(capture), "--format", fmt, "--no-color"]) == 1
    whole = capsys.readouterr().out.splitlines()
    analyzer = Analyzer()
    expected = [r for chunk in chunks[:stop_after] for r in analyzer.feed(chunk)]
    read = Capture.__iter__

    def read_then_stop(self: Capture):  # type: ignore[no-untyped-def]
        for n, chunk in enumerate(read(self)):
            if n == stop_after:
                raise KeyboardInterrupt
            yield chunk

    monkeypatch.setattr(Capture, "__iter__", read_then_stop)
    assert main(["decode", str(capture), "--format", fmt, "--no-color"]) == 130
    printed = capsys.readouterr().out.splitlines()
    if fmt == "jsonl":
        assert printed == [r.to_json() for r in expected]
    assert printed and printed == whole[:len(printed)]
    assert len(printed) >= len(expected)  # text: a record may take more than one line (its violations)
    if fmt == "text":  # every frame record's line, by its number
        numbers = [f"#{r.i}" for r in expected if isinstance(r, FrameRecord)]
        assert [line.split()[1] for line in printed if " #" in line[:20]][:len(numbers)] == numbers
