"""A capture or a proxy that stops inside a frame (issue 23 item 7): the recording ended, not the device.
The analyzer says so with a record (a junk record with reason ``capture-ended`` and no violation, on
device bytes naming the command whose answer was cut), and the command is cut short, never
``no-answer``; neither side is charged (docs/protocol.md "Framing")."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.analyzer import Analyzer, analyze
from sniffer.records import CAPTURE_ENDED, JunkRecord
from sniffer.view import JsonlView, TextView
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.cli import main


def test_a_capture_ending_inside_an_answer_charges_no_one():
    """The answer 0RV100 cut after 0RV1: a capture-ended record for the answer to #0, no violation, no
    no-answer; the command counts as still waiting at the end."""
    analyzer = Analyzer()
    records = analyzer.feed(Chunk(0.0, HOST, b"0RV\r\n")) + analyzer.feed(Chunk(0.002, DEVICE, b"0RV1"))
    records += analyzer.close()
    assert [r.violations for r in records] == [(), ()]
    cut = records[-1]
    assert isinstance(cut, JunkRecord) and cut.reason == CAPTURE_ENDED and cut.reply_to == 0
    summary = analyzer.summary()
    assert summary["violations"] == {} and summary["junk"] == 0 and summary["unanswered"] == 1
    assert summary["bytes"] == {"host": 5, "device": 4}  # every byte accounted for


def test_a_capture_without_time_ending_inside_an_answer_charges_no_one():
    """Without time the end of the data would be no-answer for every waiting command: not for the one
    whose answer the end cut."""
    records = analyze([Chunk(None, HOST, b"0RV\r\n"), Chunk(None, DEVICE, b"0RV1")])
    assert [(r.type, r.violations) for r in records] == [("frame", ()), ("junk", ())]


def test_a_single_frame_start_byte_at_the_end_is_capture_ended():
    """The framer's no-frame-start for a lone ``0`` at the end is still a frame the data ended inside."""
    records = analyze([Chunk(0.0, HOST, b"0RC\r\n"), Chunk(0.003, DEVICE, b"0")])
    assert [(r.type, r.violations) for r in records] == [("frame", ()), ("junk", ())]
    assert records[-1].reason == CAPTURE_ENDED  # type: ignore[union-attr]


def test_a_host_line_cut_by_the_end_is_no_ones_fault():
    """The proxy stopped while the host was sending: its partial line is capture-ended, no violation."""
    records = analyze([Chunk(0.0, HOST, b"0RV\r\n"), Chunk(0.002, DEVICE, b"0RV100\r\n"),
                       Chunk(0.1, HOST, b"0WP1930")])
    assert [r.violations for r in records] == [(), (), ()]
    assert records[-1].reason == CAPTURE_ENDED and records[-1].dir == "host"  # type: ignore[union-attr]


def test_a_device_that_stopped_mid_answer_is_still_charged():
    """A device line left unfinished for the idle flush (1 s) before the end is garbage: the device, not
    the recording, stopped; only the bytes the end itself cut are capture-ended."""
    analyzer = Analyzer()
    records = analyzer.feed(Chunk(0.0, HOST, b"0RV\r\n")) + analyzer.feed(Chunk(0.002, DEVICE, b"0RV1"))
    records += analyzer.close(5.0)
    assert ("garbage",) in [r.violations for r in records]


def test_bytes_that_are_no_frame_at_the_end_stay_garbage():
    """Only a frame start with no LF is cut by the end; other trailing bytes are still garbage."""
    records = analyze([Chunk(0.0, HOST, b"0RV\r\n"), Chunk(0.002, DEVICE, b"0RV100\r\n"),
                       Chunk(0.1, DEVICE, b"\xff\xfe")])
    assert records[-1].violations == ("garbage",)


def test_the_views_say_the_capture_ended():
    """Text and JSON lines views print the record as what it is."""
    records = analyze([Chunk(0.0, HOST, b"0RV\r\n"), Chunk(0.002, DEVICE, b"0RV1")])
    text, lines = io.StringIO(), io.StringIO()
    for view in (TextView(text, False), JsonlView(lines)):
        for record in records:
            view.write(record)
        view.flush()
    assert "the capture ended inside this frame, the answer to #0 (no violation)" in text.getvalue()
    cut = json.loads(lines.getvalue().splitlines()[-1])
    assert (cut["type"], cut["reason"], cut["violations"], cut["reply_to"]) == ("junk", CAPTURE_ENDED, [], 0)


def test_decode_of_a_capture_ending_mid_answer_exits_0(tmp_path: Path):
    """``xac1 decode`` of a capture that ends inside an answer: exit status 0, nothing charged."""
    capture = tmp_path / "cut.jsonl"
    capture.write_text("\n".join(json.dumps(r) for r in [
        {"type": "frame", "i": 0, "t": 1.0, "dir": "host", "raw": b"0RV\r\n".hex()},
        {"type": "frame", "i": 1, "t": 1.002, "dir": "device", "raw": b"0RV100\r\n".hex()},
        {"type": "frame", "i": 2, "t": 1.1, "dir": "host", "raw": b"0RP3\r\n".hex()},
        {"type": "junk", "i": 3, "t": 1.102, "dir": "device", "raw": b"0RP3930".hex()}]) + "\n")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(["decode", str(capture), "--format", "jsonl"])
    lines = [json.loads(line) for line in out.getvalue().splitlines()]
    assert status == 0, out.getvalue()
    assert lines[-2]["reason"] == CAPTURE_ENDED and lines[-1]["violations"] == {}


answers = st.sampled_from([(b"0RV\r\n", b"0RV100\r\n"), (b"0RP3\r\n", b"0RP39302012345\r\n"),
                           (b"0WS12\r\n", b"0WS12\r\n"), (b"0%C\r\n", b"0%C00\r\n")])


@settings(max_examples=budget(80), deadline=None)
@given(st.lists(answers, min_size=1, max_size=5), st.integers(1, 15), st.booleans())
def test_wherever_the_end_cuts_the_last_answer_no_one_is_charged(exchanges, cut, timed):
    """Clean exchanges, the capture ending anywhere inside the last answer: no violation at all."""
    chunks = []
    for k, (cmd, ans) in enumerate(exchanges):
        t = 0.1 * k if timed else None
        chunks.append(Chunk(t, HOST, cmd))
        last = k == len(exchanges) - 1
        data = ans[:min(cut, len(ans) - 1)] if last else ans
        chunks.append(Chunk(None if t is None else t + 0.002, DEVICE, data))
    records = analyze(chunks)
    assert [r.violations for r in records if r.violations] == []
    assert records[-1].reason == CAPTURE_ENDED  # type: ignore[union-attr]


def test_a_proxy_stopped_inside_an_answer_charges_no_one():
    """``xac1 proxy`` stopped (Ctrl-C) while the device is half way through an answer: the record says
    the capture ended inside it, no violation on either side, the command still waiting at the end."""
    import os
    import socket
    import threading
    import time

    from sniffer.live import Clock, Session
    from sniffer.proxy import Proxy, TcpHost

    class Collect:
        def __init__(self) -> None:
            self.records: list = []

        def write(self, record) -> None:
            self.records.append(record)

        def summary(self, summary) -> None:
            self.summary = summary

    master, slave = os.openpty()
    view = Collect()
    session, clock = Session(Analyzer(), view), Clock()
    proxy = Proxy(TcpHost("127.0.0.1", 0), os.ttyname(slave), session, clock)
    stop = threading.Event()
    thread = threading.Thread(target=proxy.run, args=(stop,), daemon=True)
    thread.start()
    try:
        with socket.create_connection(proxy.host.address, timeout=2) as sock:
            sock.sendall(b"0RV\r\n")
            got = b""
            while not got.endswith(b"\n"):  # the device reads the command...
                got += os.read(master, 64)
            os.write(master, b"0RV1")  # ...and is half way through its answer
            deadline = time.monotonic() + 3
            seen = b""
            while seen != b"0RV1" and time.monotonic() < deadline:
                sock.settimeout(0.2)
                with contextlib.suppress(TimeoutError):
                    seen += sock.recv(16)
            assert seen == b"0RV1"
    finally:
        stop.set()  # what Ctrl-C does
        thread.join(5)
        session.close(clock.now())
        os.close(master)
        os.close(slave)
    assert [(r.type, r.violations) for r in view.records] == [("frame", ()), ("junk", ())]
    assert view.records[-1].reason == CAPTURE_ENDED and view.records[-1].reply_to == 0
    assert view.summary["violations"] == {} and view.summary["unanswered"] == 1
