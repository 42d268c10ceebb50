"""The simulator answering as a captured device did (``xac1_proto.sim.replaying``; docs/replay.md
"The device side"): captured bytes with the captured turnaround, captured silences, the fallback to the
model or to silence, and the ``xac1sim://?replay=`` URL."""

from __future__ import annotations

import pytest
import serial
from conftest import CAPTURES, budget
from hypothesis import given, settings
from hypothesis import strategies as st

import xac1_proto.client  # noqa: F401  (registers xac1sim://)
from xac1_proto.replay import Answer, ScriptBuilder
from xac1_proto.sim import SimConfig
from xac1_proto.sim.control import apply
from xac1_proto.sim.replaying import ReplayError, ReplayingDevice, load_script

RECORDING = CAPTURES / "recording.jsonl"  # the gallery session: a sloppy host and a faulty device


def script_of(*exchanges: tuple[bytes, list[tuple[bytes, float]]]):
    """A script from (host line, [(answer bytes, delay after the line's last byte)])."""
    builder = ScriptBuilder()
    t = 0.0
    for i, (raw, answers) in enumerate(exchanges):
        builder.host(i * 10, raw, t, t + 0.005)
        for a, delay in answers:
            builder.device(Answer(a, None, None, t + 0.005 + delay, t + 0.005 + delay + 0.007), i * 10)
        t += 1.0
    return builder.build()


def pop_all(device: ReplayingDevice, until: float) -> list[tuple[float, bytes]]:
    """Every answer byte run the outbox lets out, with when it was due, up to ``until``."""
    out = []
    while (due := device.outbox.next_due) is not None and due <= until:
        out.append((due, device.outbox.pop(due)))
    return out


@settings(max_examples=budget(40))
@given(st.lists(st.floats(0.0, 0.5), min_size=1, max_size=6), st.sampled_from([0.0, 0.5, 1.0, 2.0]))
def test_captured_answers_come_after_the_captured_turnaround_scaled(delays, scale):
    """Each matched line is answered with the captured bytes, due its captured delay (times
    ``time_scale``) after the line came in."""
    answers = [(f"0RV{100 + k}\r\n".encode(), d) for k, d in enumerate(delays)]
    device = ReplayingDevice(script_of(*[(b"0RV\r\n", [a]) for a in answers]),
                             SimConfig(time_scale=scale))
    for k, (raw, delay) in enumerate(answers):
        t = 10.0 * k
        device.receive(b"0RV\r\n", t)
        got = pop_all(device, t + 5)
        assert got == [(pytest.approx(t + delay * scale), raw)]


def test_captured_silence_stays_silent_and_faults_come_back():
    """A line the captured device left unanswered gets no answer; a garbled or faulty captured answer
    comes back byte for byte."""
    device = ReplayingDevice(script_of((b"0RV\r\n", []), (b"0RS\r\n", [(b"0R\xd302\n", 0.01)])),
                             SimConfig(time_scale=1))
    device.receive(b"0RV\r\n", 0.0)
    assert pop_all(device, 10.0) == []
    device.receive(b"0RS\r\n", 20.0)
    assert [raw for _, raw in pop_all(device, 30.0)] == [b"0R\xd302\n"]


# the model answers 0RS with O=0 and the literal 2: 0RS02
@pytest.mark.parametrize(("strict", "answer"), [(False, b"0RS02\r\n"), (True, b"")])
def test_a_line_not_in_the_capture_falls_back_to_the_model_or_to_silence(strict, answer):
    """A line the capture does not hold next is answered by the model, or not at all when strict; either
    way a note says so, with where the replay stands."""
    said = []
    device = ReplayingDevice(script_of((b"0RV\r\n", [(b"0RV100\r\n", 0.0)])), SimConfig(time_scale=0),
                             strict=strict, on_note=said.append)
    device.receive(b"0RS\r\n", 1.0)
    assert b"".join(raw for _, raw in pop_all(device, 5.0)) == answer
    assert len(said) == 1 and "'0RS' CR LF is not in the rest of the capture" in said[0]
    assert ("not answered" in said[0]) == strict and "0 of 1 captured host lines passed" in said[0]
    assert device.notes == said


def test_bytes_cut_anywhere_are_matched_as_whole_lines():
    """The host's bytes may come in any pieces: a line is matched when its LF has come."""
    device = ReplayingDevice(script_of((b"0RV\r\n", [(b"0RV123\r\n", 0.0)])), SimConfig(time_scale=0))
    for k, byte in enumerate(b"0RV\r\n"):
        device.receive(bytes([byte]), float(k))
    assert [raw for _, raw in pop_all(device, 10.0)] == [b"0RV123\r\n"]


def test_the_control_channel_says_where_the_replay_stands():
    """``replay`` on the control channel: lines passed, the next captured line, matched and not."""
    device = ReplayingDevice(script_of((b"0RV\r\n", []), (b"0RS\r\n", [])), SimConfig(time_scale=0))
    device.receive(b"0RV\r\n", 0.0)
    text, _ = apply(device, "replay", 0.0)
    assert text.startswith("replay: 1 of 2 captured host lines passed, next captured line 2 (record 10)")
    with pytest.raises(ValueError, match="not replaying a capture"):
        from xac1_proto.sim.model import DeviceModel

        apply(DeviceModel(SimConfig()), "replay", 0.0)


def test_load_script_reads_a_gallery_capture_through_the_plug_in():
    """The core finds the capture reader through its entry point (it names no sniffer); a file that is
    no capture is a ReplayError naming it."""
    script = load_script([str(RECORDING)])
    assert [line.raw for line in script.lines][:2] == [b"0RV\r\n", b"0RC\r\n"]
    with pytest.raises(ReplayError, match="no such file"):
        load_script([str(CAPTURES / "no-such-capture.jsonl")])


def test_xac1sim_url_replays_the_faulty_device():
    """``xac1sim://?replay=FILE``: pyserial opens a device that answers as the captured faulty one (the
    0WP echo with another position, the bare-LF answer, the silence); a bad replay option is a
    SerialException naming it."""
    url = f"xac1sim://?time_scale=0&replay={RECORDING}"
    with serial.serial_for_url(url, timeout=0.3) as port:
        got = []
        for line in (b"0RV\r\n", b"0RC\r\n", b"0WP19302012345\r\n", b"0RP1\r\n", b"0RV\r\n", b"0RV\r\n"):
            port.write(line)
            got.append(port.read_until(b"\n"))
    assert got == [b"0RV100\r\n", b"0RC00002FFFFFF\r\n", b"0WP19302012344\r\n", b"0RP19302012345\n", b"",
                   b"0RV100\r\n"]
    with pytest.raises(serial.SerialException, match="replay_strict: expected 0 or 1"):
        serial.serial_for_url(url + "&replay_strict=yes")
    with pytest.raises(serial.SerialException, match="go with replay=CAPTURE"):
        serial.serial_for_url("xac1sim://?replay_strict=1")


def test_a_note_in_a_recording_is_skipped_by_its_readers(tmp_path):
    """The sim's log takes replay notes as ``{"type":"note"}`` lines; reading the recording gives its
    chunks only, with no problem."""
    from xac1_proto.chunk import Chunk
    from xac1_proto.recording import RecordingWriter, read_recording

    path = tmp_path / "log.jsonl"
    with RecordingWriter(path) as w:
        w.write(Chunk(1.0, "host", b"0RV\r\n"))
        w.note("replay: '0RS' CR LF is not in the rest of the capture", 1.5)
        w.write(Chunk(2.0, "device", b"0RV100\r\n"))
    problems: list[str] = []
    lines = path.read_text().splitlines()
    assert '"type":"note"' in lines[2]
    chunks = list(read_recording(iter(lines), str(path), problems))
    assert [c.data for c in chunks] == [b"0RV\r\n", b"0RV100\r\n"] and problems == []


@pytest.mark.slow
def test_a_note_in_a_pcapng_log_is_a_packet_comment(tmp_path):
    """``xac1 sim --replay --log FILE.pcapng``: a replay note is an empty status packet whose comment is
    the note (Wireshark shows it); our reader gives the chunks only, with no problem."""
    from wireshark_tshark import tshark

    from sniffer.io.pcapng_writer import open_recording
    from sniffer.io.registry import Capture
    from xac1_proto.chunk import Chunk

    path = tmp_path / "log.pcapng"
    log = open_recording(path, "sim", analyze=True)
    log.write(Chunk(1.0, "host", b"0RV\r\n"))
    log.note("replay: '0RS' CR LF is not in the rest of the capture", 1.5)
    log.write(Chunk(2.0, "device", b"0RV100\r\n"))
    log.close()
    done = tshark(path, "-T", "fields", "-e", "frame.comment", plugin=False, decode_as=False)
    assert done.returncode == 0, done.stderr
    assert "replay: '0RS' CR LF is not in the rest of the capture" in done.stdout
    with Capture([str(path)], "pcap") as capture:
        assert [c.data for c in capture] == [b"0RV\r\n", b"0RV100\r\n"]
        assert not capture.report.total_problems
