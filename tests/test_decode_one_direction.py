"""A one-direction capture (one file of a format that keeps a direction a file, its partner missing) is
told to the engine (``Conversation(directions=...)``, issue 35 item 4), which judges only what one line's
bytes show: the sender's duties (docs/protocol.md "Violation codes"). Nothing waits for an answer the file
cannot hold: the lines owed one are counted, not kept, so memory stays flat (issue 40 item 1)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from conftest import ROOT, budget
from hypothesis import given, settings
from hypothesis import strategies as st
from peak_rss import run_measuring_peak_rss
from strategies import frames

from sniffer.analyzer import Analyzer, analyze
from sniffer.records import CAPTURE_ENDED, FrameRecord, JunkRecord, Record, TimeoutRecord
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.cli import main
from xac1_proto.conversation import Conversation
from xac1_proto.frames import MoveDirect, ReadVersion, ReadVersionAnswer

DECODE = [sys.executable, "-m", "xac1_proto", "decode", "--format", "summary"]


def lines_of(role: str) -> st.SearchStrategy[bytes]:
    """Lines one side may send: well-formed frames, frames with a host's usual faults, and noise."""
    whole = frames(role).map(lambda f: f.to_bytes())
    return st.one_of(whole, whole.map(bytes.lower), whole.map(lambda b: b"O" + b[1:]),
                     whole.map(lambda b: b[:-2] + b"\n"), st.binary(max_size=24))


def sender_duties(record: Record) -> tuple[str, ...]:
    """The violations of ``record`` that one frame's bytes show (whoever sent them is at fault)."""
    return tuple(c for c in record.violations if spec.VIOLATION_TABLE[c].duty == spec.SENDER)


def owed_an_answer(records: list[Record]) -> int:
    """Host lines the device must answer: frame-shaped lines, and junk runs ending in LF."""
    return sum(1 for r in records if r.dir == HOST and (
        isinstance(r, FrameRecord) or (isinstance(r, JunkRecord) and r.reason != CAPTURE_ENDED
                                       and r.raw.endswith(b"\n"))))


@settings(max_examples=budget(300), deadline=None)
@given(st.sampled_from([HOST, DEVICE]).flatmap(
    lambda side: st.tuples(st.just(side), st.lists(lines_of(spec.COMMAND if side == HOST else spec.ANSWER),
                                                   max_size=20))), st.booleans())
def test_one_way_engine_judges_only_the_senders_duties(side_lines: tuple[str, list[bytes]],
                                                       timed: bool) -> None:
    """Fed one direction's lines, the engine told so finds on each frame and junk run exactly the
    sender-duty violations the two-direction engine finds there, pairs nothing (no answer, no latency, no
    ``no-answer``), keeps nothing waiting, and counts the host lines owed an answer."""
    side, lines = side_lines
    chunks = [Chunk(0.5 * k if timed else None, side, line) for k, line in enumerate(lines)]
    one = Analyzer(directions=side)  # type: ignore[arg-type]
    records: list[Record] = []
    for chunk in chunks:
        records += one.feed(chunk)
        assert not one.waiting
    records += one.close()
    both = {r.i: r for r in analyze(chunks) if not isinstance(r, TimeoutRecord)}
    assert not any(isinstance(r, TimeoutRecord) for r in records)
    assert [r.i for r in records] == sorted(both)
    for r in records:
        assert r.violations == sender_duties(both[r.i]), (r, both[r.i])
        assert r.reply_to is None and r.latency_s is None
    assert one.summary()["unanswered"] == owed_an_answer(records)


def test_directions_must_be_named() -> None:
    """``directions`` is ``both``, ``host`` or ``device``; anything else is refused, naming the choices."""
    with pytest.raises(ValueError, match="both, host, device"):
        Conversation(directions="sideways")  # type: ignore[arg-type]


def test_a_host_line_is_counted_not_queued() -> None:
    """One way, a command (even a move) never waits: the next line is neither overlapping nor sent during
    motion, no window ever closes, and ``cut_short`` gives the count once."""
    c = Conversation(directions=HOST)
    move = MoveDirect(vel=5, a=3, pos=0x1000).to_bytes()
    verdicts = c.host_frame(move, 0.0, 0.0) + c.host_frame(ReadVersion().to_bytes(), 0.01, 0.01)
    verdicts += c.tick(1e6) + c.close()
    assert [v.kind for v in verdicts] == ["host-frame", "host-frame"]
    assert all(v.violations == () for v in verdicts)
    assert not c.waiting and not c.moving
    assert c.cut_short() == 2 and c.cut_short() == 0


def test_a_device_only_alarm_history_is_not_judged_as_a_latch() -> None:
    """One way (device): an answer is judged by its own bytes; alarms latch nothing, so a later normal
    answer is not ``latch-broken`` and none is ``unsolicited-answer``."""
    c = Conversation(directions=DEVICE)
    out = c.device_frame(b"0%%01\r\n", 0.0) + c.device_frame(b"0%%08\r\n", 1.0)
    out += c.device_frame(ReadVersionAnswer(version="100").to_bytes(), 2.0)
    out += c.device_frame(b"0RV10\r\n", 3.0)
    assert [v.codes for v in out] == [(), (), (), ("bad-length",)]
    assert c.knowledge.latched.value is None


def decode_json(tmp_path: Path, name: str, data: bytes, capsys: pytest.CaptureFixture[str],
                *options: str) -> tuple[int, list[dict]]:
    """``xac1 decode -f jsonl`` of one file written in ``tmp_path``, in this process."""
    path = tmp_path / name
    path.write_bytes(data)
    status = main(["decode", "-f", "jsonl", str(path), *options])
    out = capsys.readouterr()
    return status, [json.loads(line) for line in out.out.splitlines()]


def test_decode_of_a_host_file_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``xac1 decode host.bin`` (its device file missing): the host's own faults are found (letter O,
    garbage), no ``no-answer`` nor ``overlapping-command``; the lines owed an answer are ``unanswered``."""
    data = ReadVersion().to_bytes() * 3 + b"ORV\r\n" + b"xx\r\n"
    status, lines = decode_json(tmp_path, "host.bin", data, capsys)
    summary = lines[-1]
    assert status == 1
    assert summary["violations"] == {"letter-o": 1, "garbage": 1}
    assert summary["frames"] == {"host": 4, "device": 0} and summary["unanswered"] == 5
    assert not any(line["type"] == "timeout" for line in lines)
    assert any("other direction is missing" in note for note in summary["notes"])


def test_decode_of_a_device_file_alone_with_a_report(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """``xac1 decode device.bin`` alone, with ``--report``: answers are never ``unsolicited-answer``; the
    report is written from the same records."""
    pytest.importorskip("plotly", reason="the report extra (plotly)")
    data = ReadVersionAnswer(version="100").to_bytes() * 2 + b"0%%01\r\n" + b"0RV100\n"
    status, lines = decode_json(tmp_path, "device.bin", data, capsys, "--report", str(tmp_path / "r.html"))
    assert status == 1
    assert lines[-1]["violations"] == {"bad-length": 1, "bad-terminator": 1}
    assert lines[-1]["unanswered"] == 0
    assert all(line.get("reply_to") is None for line in lines[:-1])
    assert (tmp_path / "r.html").stat().st_size > 0


@pytest.mark.slow  # decode processes on files of a few hundred kB
@pytest.mark.parametrize(("what", "unit", "count"), [
    ("host lines, each owed an answer", b"0RV\r\n", 60_000),
    ("a run with no line end, a junk run every 3 bytes", b"0RV", 32_000),
])
def test_one_direction_memory_stays_flat(tmp_path: Path, what: str, unit: bytes, count: int) -> None:
    """A one-direction raw file four times as large peaks at about the same memory, under 64 MiB. Before,
    every host line waited in the engine's queue for an answer the file cannot hold (600,000 lines: 116
    MiB), and a run of 3-byte junk runs was held a 256 KiB batch of verdicts at a time (900 kB: 110 MiB)."""
    peaks = []
    for n in (count // 4, count):
        path = tmp_path / f"host-{n}.bin"
        path.write_bytes(unit * n)
        code, peak = run_measuring_peak_rss([*DECODE, str(path)], cwd=ROOT)
        assert code in (0, 1)
        peaks.append(peak)
    print(f"{what}: peak RSS {peaks[0]:.1f} MiB -> {peaks[1]:.1f} MiB")
    assert peaks[1] < 64
    assert peaks[1] - peaks[0] < 3, peaks
