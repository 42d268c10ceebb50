"""``xac1 replay`` run in this process against the built-in simulator (``xac1sim://``): the gallery's
faulty-device capture names exactly the differing answers (exit 1), the options are checked before
anything is sent (exit 2), an unreachable port is exit 3, ``--dry-run`` sends nothing, and the JSON
lines and the page say what the text says (docs/replay.md)."""

from __future__ import annotations

import json

import pytest
from conftest import CAPTURES

from xac1_proto.cli import main

RECORDING = str(CAPTURES / "recording.jsonl")  # the gallery session: a sloppy host and a faulty device
SIM = "xac1sim://?time_scale=0"

# The gallery's faulty device against a clean simulator: captured record number -> differences.
GALLERY_DIFFERENCES = {
    4: ["pos"],  # 0WP echoed with another position
    8: ["alarm-instead-of-answer"],  # 0RS answered normally while alarm 01 was latched
    12: ["bytes"],  # 0RP1 answered with a bare LF
    14: ["extra"],  # 0RV left unanswered
}


def run(capsys, *args: str) -> tuple[int, str, str]:
    status = main(["replay", *args])
    out, err = capsys.readouterr()
    return status, out, err


def replay(capsys, *args: str) -> tuple[int, list[dict], str]:
    status, out, err = run(capsys, *args)
    return status, [json.loads(line) for line in out.splitlines() if line.startswith("{")], err


def test_faulty_capture_against_a_clean_device_names_exactly_the_differing_answers(capsys, tmp_path):
    """Each answer of the faulty device differs from the clean simulator's in the one way the capture's
    fault makes, every other answer is the same, the new conversation's violations are named as the
    sniffer names them, and the exit status is 1; the page shows the same rows."""
    page = tmp_path / "replay.html"
    status, objs, err = replay(capsys, RECORDING, "--port", SIM, "--pace", "fast", "-f", "jsonl",
                               "--report", str(page))
    assert status == 1
    rows, summary = objs[:-1], objs[-1]
    assert {r["i"]: r["differences"] for r in rows if not r["same"]} == GALLERY_DIFFERENCES
    assert all(r["differences"] == [] for r in rows if r["same"])
    assert [r["i"] for r in rows] == [0, 2, 4, 6, 8, 10, 12, 14, 15]
    first = rows[0]
    assert set(first) == {"type", "i", "sent", "expected", "got", "same", "differences", "violations"}
    assert (first["sent"], first["expected"], first["got"]) == ("0RV\r\n", "0RV100\r\n", "0RV100\r\n")
    assert rows[-2]["expected"] is None and rows[-2]["got"] == "0RV100\r\n"
    assert {r["i"]: r["violations"] for r in rows if r["violations"]} == {6: ["letter-o"],
                                                                         8: ["alarm-ignored"]}
    assert summary == {**summary, "type": "summary", "lines": 9, "replayed": 9, "same": 5, "different": 4,
                       "skipped": 0, "missing": 0, "extra": 1, "exit": 1, "restored": True}
    html = page.read_text(encoding="utf-8")
    assert html.count('<tr class="different">') == 4 and html.count('<tr class="same">') == 5
    assert "alarm-instead-of-answer" in html and "report written to" in err


def test_text_output_marks_the_differences(capsys):
    """The text output: one line per replayed host line, ``same`` or ``DIFFERENT: <what>``, then the
    summary line."""
    status, out, _ = run(capsys, RECORDING, "--port", SIM, "--pace", "fast", "--no-color")
    lines = out.splitlines()
    assert status == 1 and len(lines) == 10
    assert sum("DIFFERENT" in line for line in lines) == 4
    assert "'0WP19302012345' CR LF" in lines[2] and lines[2].endswith("DIFFERENT: pos")
    assert "captured (silence)" in lines[7] and "DIFFERENT: extra" in lines[7]
    assert lines[3].endswith("same  [letter-o]")
    assert lines[-1].startswith("replayed 9 of 9 host lines: 5 same, 4 different (pos 1, "
                                "alarm-instead-of-answer 1, bytes 1, extra 1), 0 skipped")


@pytest.mark.parametrize(("args", "message"), [
    (["--port", SIM, "--allow-motion"], "--allow-motion needs --safe-range LO:HI"),
    (["--port", SIM, "--safe-range", "9:1"], "LO 0x000009 is above HI"),
    ([], "give the device with --port URL"),
])
def test_bad_options_end_with_a_message_before_anything_is_sent(capsys, args, message):
    """A bad option combination is exit 2 with a message naming it, before the capture is read."""
    status, objs, err = replay(capsys, RECORDING, *args)
    assert status == 2 and message in err and objs == []


def test_bad_capture_ends_with_a_message_nothing_sent(capsys, tmp_path):
    """A capture that is missing, or not a capture at all, is exit 2 with a message naming it; nothing
    is sent."""
    junk = tmp_path / "notes.txt"
    junk.write_text("hello\nthis is no capture\n")
    for path, message in ((tmp_path / "missing.jsonl", "no such file"), (junk, "cannot tell the capture "
                                                                               "format")):
        status, objs, err = replay(capsys, str(path), "--port", "socket://127.0.0.1:1")
        assert status == 2 and message in err and "nothing sent" in err and objs == []


def test_unreachable_port_is_exit_3(capsys):
    """A port that cannot be opened is exit 3 with a message; nothing is sent."""
    status, _, err = replay(capsys, RECORDING, "--port", "socket://127.0.0.1:1")
    assert status == 3 and "cannot open socket://127.0.0.1:1" in err and "nothing sent" in err


def test_dry_run_shows_what_would_be_sent_and_opens_no_port(capsys):
    """``--dry-run`` lists every captured host line as it would go (moves it would skip marked), opens
    no port (none is given) and sends nothing."""
    status, objs, _ = replay(capsys, RECORDING, "--dry-run", "-f", "jsonl")
    assert status == 0
    assert [o["line"] for o in objs[:-1]] == ["0RV\r\n", "0RC\r\n", "0WP19302012345\r\n", "ORP1\r\n",
                                              "0RS\r\n", "0%C\r\n", "0RP1\r\n", "0RV\r\n", "0RV\r\n"]
    assert objs[-1] == {"type": "summary", "dry_run": True, "lines": 9, "would_send": 9, "skipped": 0}


@pytest.mark.slow
def test_a_device_that_stops_answering_mid_replay_is_exit_3(capsys, tmp_path):
    """Lines answered in the capture that now get not a byte back, three in a row, and a 0RV that gets
    none either: the replay stops (exit 3), says so, and the restore is reported as not verified."""
    from xac1_proto.chunk import Chunk
    from xac1_proto.recording import RecordingWriter
    from xac1_proto.sim import LineFaults, SimConfig, serve_tcp

    capture = tmp_path / "cm1.jsonl"
    with RecordingWriter(capture) as w:
        for n, (line, answer) in enumerate([(b"0CM1\r\n", b"0CM1\r\n")] + [(b"0RV\r\n", b"0RV100\r\n")] * 6):
            w.write(Chunk(10.0 + n, "host", line))
            w.write(Chunk(10.0 + n + 0.01, "device", answer))

    def mute_after_0cm1(direction: str, data: bytes) -> None:
        if direction == "host" and b"0CM1" in data:
            sim.model.set_line_faults(LineFaults(drop=1.0))  # from now on every answer byte is lost

    with serve_tcp(SimConfig(time_scale=0), on_traffic=mute_after_0cm1) as sim:
        status, objs, err = replay(capsys, str(capture), "--port", sim.url, "--pace", "fast", "--timeout",
                                   "0.2", "-f", "jsonl")
    assert status == 3, err
    assert "the device stopped answering" in err
    assert "restore: the restore could not be done or verified" in err
    assert "restore: not verified: the mode, switched by the replay (0CM)" in err
    summary = objs[-1]
    assert summary["stopped"] is True and summary["restored"] is False and summary["replayed"] < 7


@pytest.mark.slow
def test_a_device_that_never_answers_is_exit_3_nothing_of_the_capture_sent(capsys):
    """A port that opens but gives not a byte back to the first reads (the snapshot): exit 3 with a
    message; none of the capture's lines is sent."""
    from xac1_proto.sim import LineFaults, SimConfig, serve_tcp

    host: list[bytes] = []
    with serve_tcp(SimConfig(time_scale=0, faults=LineFaults(drop=1.0)),
                   on_traffic=lambda d, data: host.append(data) if d == "host" else None) as sim:
        status, objs, err = replay(capsys, RECORDING, "--port", sim.url, "--timeout", "0.2")
    assert status == 3 and "cannot read the device's points, OUT ports and position first" in err
    assert "no answer from the device" in err and objs == []
    assert set(host) <= {b"0%C\r\n", b"0RV\r\n"}  # the liveness check only: 0WP1... never went out


def test_a_report_path_that_is_no_regular_file_is_exit_2_nothing_sent(capsys, tmp_path):
    """``--report`` naming a directory (or a FIFO, a device) is refused before the capture is read or a
    port opened: exit 2, a message naming the option and the path, nothing sent."""
    status, objs, err = replay(capsys, RECORDING, "--port", "socket://127.0.0.1:1", "--report",
                               str(tmp_path))
    assert status == 2 and "--report" in err and str(tmp_path) in err and "nothing sent" in err
    assert objs == []
