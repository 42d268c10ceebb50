"""Outputs at odd paths (issue 41 items 1, 2 and 6; issue 40 item 4): a stream written as it comes
(``--log``, ``--record``, ``--annotate``) onto ``/dev/null`` is written without syncing; onto a FIFO
nobody reads, or over an existing file that is not a recording, it is refused at once, naming the path
and why; ``--report ''`` is refused; a 250-character report name is written; ``xac1 replay`` names its
own ``--safe-range``; ``xac1 sniff`` refuses one tap for both directions.
"""

from __future__ import annotations

import errno
import os
import signal
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import ROOT, xac1_sim

from sniffer.io.pcapng_writer import PcapngRecorder
from xac1_proto.chunk import Chunk
from xac1_proto.cli import main
from xac1_proto.client import Client
from xac1_proto.output_file import check_output, write_output
from xac1_proto.recording import RecordingWriter
from xac1_proto.sim import DeviceModel, SimConfig, serve_tcp

WRITERS: dict[str, Callable[[Path], object]] = {
    "jsonl": lambda p: RecordingWriter(p, source="test"),
    "pcapng": lambda p: PcapngRecorder(p, source="test"),
}


def opening(path: Path, make: Callable[[Path], object]) -> BaseException | object:
    """What ``make(path)`` gives (the writer, or the exception), within 5 s: a writer that waits for a
    FIFO's reader is freed by opening that reader, and the test fails."""
    got: list[object] = []

    def attempt() -> None:
        try:
            got.append(make(path))
        except BaseException as exc:  # noqa: BLE001 - the test looks at it
            got.append(exc)

    thread = threading.Thread(target=attempt, daemon=True)
    thread.start()
    thread.join(5)
    if thread.is_alive():
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # free the waiting open
        thread.join(5)
        os.close(fd)
        pytest.fail(f"opening {path} waited for a reader")
    return got[0]


@pytest.mark.parametrize("kind", WRITERS)
def test_dev_null_is_written_without_syncing(kind: str) -> None:
    """A recording onto /dev/null takes chunks and closes without error (was: ``os.fsync`` EINVAL, a
    traceback and exit 1 for ``--record /dev/null``; the simulator's log died at its first byte), written
    in place: /dev/null is still the character device afterwards, never replaced by a file."""
    writer = WRITERS[kind](Path(os.devnull))
    for k in range(3):
        writer.write(Chunk(1000.0 + k, "host", b"0RV\r\n"))  # type: ignore[attr-defined]
    writer.close()  # type: ignore[attr-defined]
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


@pytest.mark.parametrize("kind", WRITERS)
def test_fifo_nobody_reads_is_refused_at_once(tmp_path: Path, kind: str) -> None:
    """A FIFO with no reader: OSError at once (ENXIO) saying nobody reads it (was: a silent wait)."""
    fifo = tmp_path / "out.fifo"
    os.mkfifo(fifo)
    got = opening(fifo, WRITERS[kind])
    assert isinstance(got, OSError) and got.errno == errno.ENXIO, got
    assert "nobody reads" in (got.strerror or "")


@pytest.mark.parametrize("kind", WRITERS)
def test_fifo_with_a_reader_is_written(tmp_path: Path, kind: str) -> None:
    """A FIFO whose reader is there (Wireshark's extcap pipe) is written as before."""
    fifo = tmp_path / "out.fifo"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    try:
        writer = opening(fifo, WRITERS[kind])
        assert not isinstance(writer, BaseException), writer
        writer.write(Chunk(1000.0, "host", b"0RV\r\n"))  # type: ignore[attr-defined]
        writer.close()  # type: ignore[attr-defined]
        assert len(os.read(reader, 65536)) > 0
    finally:
        os.close(reader)


def test_extcap_fifo_waits_for_wiresharks_end(tmp_path: Path) -> None:
    """The extcap pipe (the format named: ``fmt="pcapng"``) waits for its reader, which Wireshark opens
    perhaps a moment after starting us, instead of being refused."""
    from sniffer.io.pcapng_writer import open_recording

    fifo = tmp_path / "extcap.fifo"
    os.mkfifo(fifo)
    got: list[object] = []
    thread = threading.Thread(target=lambda: got.append(open_recording(fifo, "test", fmt="pcapng")),
                              daemon=True)
    thread.start()
    time.sleep(0.2)
    assert not got  # still waiting: not refused
    reader = os.open(fifo, os.O_RDONLY)
    try:
        thread.join(5)
        assert got, "the writer never opened"
        got[0].close()  # type: ignore[attr-defined]
        assert os.read(reader, 4) == b"\n\r\r\n"  # a pcapng section header
    finally:
        os.close(reader)


@pytest.mark.parametrize("kind", WRITERS)
def test_existing_file_that_is_not_a_recording_is_left_alone(tmp_path: Path, kind: str) -> None:
    """An existing file holding something else is refused, untouched (was: replaced without a word)."""
    other = tmp_path / "notes.txt"
    other.write_text("my notes\n")
    with pytest.raises(OSError, match="not a recording: it is left alone") as caught:
        WRITERS[kind](other)
    assert caught.value.errno == errno.EEXIST and other.read_text() == "my notes\n"


@pytest.mark.parametrize("earlier", WRITERS)
@pytest.mark.parametrize("kind", WRITERS)
def test_earlier_recording_and_empty_file_are_replaced(tmp_path: Path, kind: str, earlier: str) -> None:
    """A recording of ours (either format) or an empty file is replaced, as a run again expects."""
    old = tmp_path / "rec"
    WRITERS[earlier](old).close()  # type: ignore[attr-defined]
    WRITERS[kind](old).close()  # type: ignore[attr-defined]
    empty = tmp_path / "empty"
    empty.touch()
    WRITERS[kind](empty).close()  # type: ignore[attr-defined]
    assert empty.stat().st_size > 0


def test_sim_log_onto_a_fifo_nobody_reads_is_refused(tmp_path: Path, capsys) -> None:
    """``xac1 sim --log FIFO``: exit 2, one line naming the log and why, nothing served (was: a hang)."""
    fifo = tmp_path / "log.fifo"
    os.mkfifo(fifo)
    got = opening(fifo, lambda p: main(["sim", "--tcp", "127.0.0.1:0", "--log", str(p)]))
    err = capsys.readouterr().err
    assert got == 2 and f"cannot write the log {fifo}: it is a FIFO (named pipe) that nobody reads" in err


def test_decode_annotate_onto_a_fifo_or_a_foreign_file(tmp_path: Path, capsys) -> None:
    """``xac1 decode --annotate``: a FIFO nobody reads or someone's file is refused, exit 2, the option
    and path named."""
    capture = tmp_path / "c.raw"
    capture.write_bytes(b"0RV\r\n")
    fifo = tmp_path / "a.fifo"
    os.mkfifo(fifo)
    other = tmp_path / "other.pcapng"
    other.write_text("not a capture")
    got = opening(fifo, lambda p: main(["decode", str(capture), "--annotate", str(p)]))
    assert got == 2 and f"--annotate {fifo}: it is a FIFO" in capsys.readouterr().err
    assert main(["decode", str(capture), "--annotate", str(other)]) == 2
    assert f"--annotate {other}: it is an existing file" in capsys.readouterr().err
    assert other.read_text() == "not a capture"


# ---- --report names ----

def test_a_250_character_report_name_is_written(tmp_path: Path) -> None:
    """A file name the folder takes is written, whatever its length (was: "File name too long": the
    temporary file beside it was longer)."""
    target = tmp_path / ("r" * 245 + ".html")
    assert check_output(target, "--report") == target
    write_output(target, "<p>report</p>")
    assert target.read_text() == "<p>report</p>" and os.listdir(tmp_path) == [target.name]


@pytest.mark.parametrize("argv", [
    ["decode", "{capture}", "--report", ""],
    ["replay", "{capture}", "--dry-run", "--report", ""],
    ["conformance", "--report", ""],
    ["sniff", "--host-tap", "{a}", "--device-tap", "{b}", "--report", ""],
    ["sniff", "--host-tap", "{a}", "--device-tap", "{b}", "--record", ""],
], ids=["decode", "replay", "conformance", "sniff-report", "sniff-record"])
def test_an_empty_output_name_is_refused(tmp_path: Path, capsys, argv: list[str]) -> None:
    """``--report ''`` (and ``--record ''``): exit 2 and one line saying a file name is needed, nothing
    done (was: ignored without a word)."""
    capture = tmp_path / "c.raw"
    capture.write_bytes(b"0RV\r\n")
    names = {"capture": str(capture), "a": str(tmp_path / "a"), "b": str(tmp_path / "b")}
    assert main([a.format(**names) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("give the name of a file" in err[0]), err


# ---- options named as the command names them ----

def test_replay_names_its_own_safe_range_option(tmp_path: Path, capsys) -> None:
    """``xac1 replay --safe-range 5:1``: the error names ``--safe-range`` (was: the pytest plugin's
    ``--xac1-safe-range``)."""
    capture = tmp_path / "c.raw"
    capture.write_bytes(b"0RV\r\n")
    assert main(["replay", str(capture), "--dry-run", "--safe-range", "5:1"]) == 2
    err = capsys.readouterr().err
    assert "xac1 replay: --safe-range: LO 0x000005 is above HI 0x000001" in err and "--xac1-" not in err


@pytest.mark.parametrize("same", ["same", "link"])
def test_sniff_refuses_one_tap_for_both_directions(tmp_path: Path, capsys, same: str) -> None:
    """``xac1 sniff`` with the same port (or a link to it) as both taps: exit 2, said, nothing opened
    (was: accepted, every byte shown twice)."""
    tap = tmp_path / "tap"
    other = tap
    if same == "link":
        other = tmp_path / "link"
        other.symlink_to(tap)
    assert main(["sniff", "--host-tap", str(tap), "--device-tap", str(other)]) == 2
    assert "--host-tap and --device-tap name the same port" in capsys.readouterr().err


# ---- the real commands onto /dev/null ----

@pytest.mark.slow
def test_proxy_recording_onto_dev_null_ends_in_order(tmp_path: Path) -> None:
    """``xac1 proxy --record /dev/null`` forwarding, then SIGTERM: exit 0, no traceback (was: an
    ``os.fsync`` EINVAL traceback and exit 1)."""
    with serve_tcp(model=DeviceModel(SimConfig(time_scale=0))) as sim:
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "proxy", "--device", sim.url, "--tcp",
                                 "127.0.0.1:0", "--record", os.devnull], cwd=ROOT, text=True,
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            assert proc.stderr is not None
            first = proc.stderr.readline()
            assert "Ctrl-C to stop" in first, first
            proc.send_signal(signal.SIGTERM)
            out, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    assert proc.returncode == 0 and "Traceback" not in err, err


@pytest.mark.slow
def test_sim_log_onto_dev_null_serves_past_its_first_sync(tmp_path: Path) -> None:
    """``xac1 sim --log /dev/null`` answers after the log's once-a-second sync is due, and ends with
    exit 0 (was: the simulator died at its first byte)."""
    with xac1_sim("--tcp", "127.0.0.1:0", "--time-scale", "0", "--log", os.devnull) as (proc, url):
        time.sleep(1.2)  # the log's sync is due at the next byte
        with Client(url, timeout=2) as client:
            for _ in range(2):
                assert client.read_version()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=15) == 0
