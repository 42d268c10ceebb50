"""``xac1 decode`` on the inputs that broke it (issue 13, "Found: Decode"): each finding is a test named
after it. The rule (docs/captures.md): every problem is reported as ``file:offset`` or
``file:line`` with what was wrong, the damaged part is skipped, the rest is decoded; exit 1 with the
count of problems, 0 only for a clean read, 2 when nothing could be decoded; never a traceback."""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from peak_rss import run_measuring_peak_rss

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"
SESSION_FRAMES = {"host": 9, "device": 8}  # the gallery session (captures/README.md)


def xac1(*args: str, stdin: bytes | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    result = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", *args], input=stdin,
                            capture_output=True, timeout=timeout, cwd=ROOT)
    out = subprocess.CompletedProcess(result.args, result.returncode, result.stdout.decode(),
                                      result.stderr.decode("utf-8", "replace"))
    assert "Traceback" not in out.stderr, out.stderr
    return out


def summary(result: subprocess.CompletedProcess[str], notes: bool = True) -> dict:
    """The last JSON lines record (``--format jsonl``): the summary (without its notes, which name the
    file, when ``notes`` is false)."""
    last = json.loads(result.stdout.splitlines()[-1])
    assert last["type"] == "summary"
    if not notes:
        last.pop("notes", None)
    return last


def blocks(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, type, total length) of each block of a little-endian pcapng file."""
    out, i = [], 0
    while i + 8 <= len(data):
        kind, total = struct.unpack_from("<II", data, i)
        out.append((i, kind, total))
        i += total
    return out


def records(data: bytes) -> list[tuple[int, int]]:
    """(offset, captured length) of each record of a little-endian microsecond pcap file."""
    out, i = [], 24
    while i + 16 <= len(data):
        incl = struct.unpack_from("<I", data, i + 8)[0]
        out.append((i, incl))
        i += 16 + incl
    return out


PCAPNG = (CAPTURES / "session.pcapng").read_bytes()
PCAP = (CAPTURES / "session.pcap").read_bytes()
EPB = 6


def _epbs() -> list[tuple[int, int, int]]:
    return [b for b in blocks(PCAPNG) if b[1] == EPB]


# ---- pcapng ----

@pytest.mark.slow  # starts a process
def test_pcapng_packet_block_of_length_12_is_reported_and_the_rest_kept(tmp_path: Path) -> None:
    """An Enhanced Packet Block of total length 12 (legal, but no room for its 20 fixed bytes) was a
    ``struct.error`` traceback and lost the frames after it."""
    off = _epbs()[3][0]
    bad = tmp_path / "epb12.pcapng"
    bad.write_bytes(PCAPNG[:off] + struct.pack("<III", EPB, 12, 12) + PCAPNG[off:])
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1
    assert f"{bad}:{off} (block " in result.stderr and "shorter than its 20 fixed bytes" in result.stderr
    assert summary(result)["frames"] == SESSION_FRAMES
    assert summary(result)["problems"] == 1


@pytest.mark.slow  # starts a process
def test_pcapng_interface_block_shorter_than_its_fixed_fields(tmp_path: Path) -> None:
    """An Interface Description Block whose body is shorter than its 8 fixed bytes: reported, its
    packets then fall on an unusable interface (reported), no traceback."""
    idb = next(b for b in blocks(PCAPNG) if b[1] == 1)
    bad = tmp_path / "idb.pcapng"
    bad.write_bytes(PCAPNG[:idb[0]] + struct.pack("<IIII", 1, 16, 0x00FA, 16) + PCAPNG[idb[0] + idb[2]:])
    result = xac1(str(bad))
    assert result.returncode in (1, 2)
    assert f"{bad}:{idb[0]} (block 2): interface description block body of 4 byte(s)" in result.stderr


@pytest.mark.slow  # starts a process
def test_pcapng_later_section_header_with_implausible_length_does_not_end_the_file(tmp_path: Path) -> None:
    """A second Section Header Block whose length is 2^32-4 silently ended the file (exit 0, packets
    after it gone). Now: reported with its offset, skipped, every packet after it decoded."""
    off = _epbs()[4][0]
    shb = (b"\x0a\x0d\x0d\x0a" + struct.pack("<I", 2**32 - 4) + b"\x4d\x3c\x2b\x1a"
           + struct.pack("<HHq", 1, 0, -1))
    bad = tmp_path / "shb.pcapng"
    bad.write_bytes(PCAPNG[:off] + shb + PCAPNG[off:])
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1
    assert re.search(rf"{re.escape(str(bad))}:{off} \(block \d+\): block length 4294967292 is not "
                     rf"plausible.*{len(shb)} byte\(s\) skipped", result.stderr)
    assert summary(result)["frames"] == SESSION_FRAMES


@pytest.mark.slow  # starts a process
def test_pcapng_captured_length_larger_than_its_block(tmp_path: Path) -> None:
    """The captured length of a packet larger than the bytes in its block was not reported (the
    padding was decoded as line data)."""
    off, _kind, total = _epbs()[2]
    data = bytearray(PCAPNG)
    struct.pack_into("<I", data, off + 20, total)  # captured length past its block's data
    bad = tmp_path / "caplen.pcapng"
    bad.write_bytes(bytes(data))
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1
    assert f"captured length {total} is larger than the" in result.stderr
    assert summary(result)["frames"]["host"] + summary(result)["frames"]["device"] == 16


@pytest.mark.slow  # starts a process
def test_pcap_record_longer_than_the_file_is_a_corrupt_length(tmp_path: Path) -> None:
    """A pcap record whose length runs past the end of the file was reported as "file ends"; it is a
    corrupt length, and the records after it are found again."""
    off, _incl = records(PCAP)[2]
    data = bytearray(PCAP)
    struct.pack_into("<I", data, off + 8, len(PCAP) * 2)
    bad = tmp_path / "incl.pcap"
    bad.write_bytes(bytes(data))
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1
    assert f"{bad}:{off} (record 3): corrupt length {len(PCAP) * 2}" in result.stderr
    assert summary(result)["frames"]["host"] + summary(result)["frames"]["device"] == 16


# ---- times ----

@pytest.mark.slow  # starts a process
def test_socat_timestamp_with_hour_27_is_a_problem_not_a_traceback(tmp_path: Path) -> None:
    """One bad digit in a socat header (hour 27) was a ``ValueError`` traceback from ``wallclock``."""
    lines = (CAPTURES / "socat-x.log").read_text().splitlines(keepends=True)
    lines[2] = re.sub(r" \d\d:", " 27:", lines[2], count=1)
    bad = tmp_path / "h27.log"
    bad.write_text("".join(lines))
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1
    assert f"{bad}:3: impossible date or time" in result.stderr and "hour" in result.stderr
    assert summary(result)["frames"] == SESSION_FRAMES


@pytest.mark.slow  # starts a process
def test_jpnevulator_day_32_is_a_problem_not_a_traceback(tmp_path: Path) -> None:
    """An impossible date in a jpnevulator capture is reported as a problem naming the line, not a
    traceback."""
    lines = (CAPTURES / "jpnevulator.txt").read_text().splitlines(keepends=True)
    lines[0] = re.sub(r"^(\d{4}-\d\d)-\d\d", r"\1-32", lines[0])
    bad = tmp_path / "d32.txt"
    bad.write_text("".join(lines))
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1 and f"{bad}:1: impossible date or time" in result.stderr
    assert summary(result)["frames"] == SESSION_FRAMES


@pytest.mark.slow  # starts a process
def test_saleae_carriage_return_inside_a_row(tmp_path: Path) -> None:
    """A CR inside a Saleae row was a ``_csv.Error`` traceback."""
    host = (CAPTURES / "saleae-host.csv").read_text().splitlines(keepends=True)
    host[3] = host[3].replace(",", ",\r", 1)
    shutil.copy(CAPTURES / "saleae-device.csv", tmp_path / "saleae-device.csv")
    bad = tmp_path / "saleae-host.csv"
    bad.write_text("".join(host))
    result = xac1(str(bad), "--format", "jsonl")
    assert result.returncode == 1 and f"{bad}:4: not a Saleae row" in result.stderr


@pytest.mark.slow  # starts a process
@pytest.mark.parametrize("view", ["text", "jsonl", "summary"])
def test_nan_infinite_and_absurd_times_never_crash_a_view(tmp_path: Path, view: str) -> None:
    """A recording with ``"t": NaN`` or ``Infinity`` and a Saleae time of 1e14 crashed the latency
    statistics and the text view's time column; each is now a problem naming the time, the bytes kept."""
    rec = tmp_path / "nan.jsonl"
    rec.write_text('{"type":"recording","version":1}\n'
                   '{"type":"chunk","t":1714557600.0,"dir":"host","data":"3052560d0a"}\n'
                   '{"type":"chunk","t":NaN,"dir":"device","data":"305256313030"}\n'
                   '{"type":"chunk","t":Infinity,"dir":"device","data":"0d0a"}\n'
                   '{"type":"chunk","t":1e300,"dir":"host","data":"3052560d0a"}\n')
    result = xac1(str(rec), "--format", view)
    assert result.returncode == 1
    assert "time nan is not a number of seconds" in result.stderr
    assert "time 1e+300 s is out of range" in result.stderr
    host = (CAPTURES / "saleae-host.csv").read_text().splitlines(keepends=True)
    host[5] = "1e14" + host[5][host[5].index(","):]
    (tmp_path / "saleae-host.csv").write_text("".join(host))
    shutil.copy(CAPTURES / "saleae-device.csv", tmp_path / "saleae-device.csv")
    result = xac1(str(tmp_path / "saleae-host.csv"), "--format", view)
    assert result.returncode == 1 and ":6: time 100000000000000.0 s is out of range" in result.stderr


# ---- pipes, FIFOs, standard input ----

@pytest.mark.slow  # a decode process per way in
@pytest.mark.parametrize("name", ["socat-xv.log", "session.pcapng", "sigrok-uart.txt", "recording.jsonl"])
def test_pipe_fifo_and_dash_decode_a_valid_capture(tmp_path: Path, name: str) -> None:
    """The reader opened the file twice to sniff its format: a FIFO hung, ``cat f | xac1 decode
    /dev/stdin`` said "nothing to decode" and ``-`` was refused. Each now decodes as the file does."""
    data = (CAPTURES / name).read_bytes()
    direct = summary(xac1(str(CAPTURES / name), "--format", "jsonl"), notes=False)
    piped = subprocess.run(f"cat {CAPTURES / name} | {sys.executable} -m xac1_proto decode /dev/stdin "
                           f"--format jsonl", shell=True, capture_output=True, text=True, timeout=60,
                           cwd=ROOT)
    assert piped.returncode == 1 and summary(piped, notes=False) == direct, piped.stderr
    dash = xac1("-", "--format", "jsonl", stdin=data)
    assert dash.returncode == 1 and summary(dash, notes=False) == direct
    fifo = tmp_path / "capture.fifo"
    os.mkfifo(fifo)
    writer = threading.Thread(target=fifo.write_bytes, args=(data,), daemon=True)
    writer.start()
    through = xac1(str(fifo), "--format", "jsonl", timeout=30)
    writer.join(5)
    assert through.returncode == 1 and summary(through, notes=False) == direct


# ---- misleading results ----

@pytest.mark.slow  # starts a process
def test_one_half_of_a_two_file_capture_says_the_other_direction_is_missing(tmp_path: Path) -> None:
    """``saleae-host.csv`` alone decoded silently as a dead controller plus a host sending back to back
    (a storm of no-answer/overlapping-command). Now a note says the device direction is missing and
    only what one frame shows is judged (the host's letter O)."""
    shutil.copy(CAPTURES / "saleae-host.csv", tmp_path / "saleae-host.csv")
    result = xac1(str(tmp_path / "saleae-host.csv"), "--format", "jsonl")
    assert "the other direction is missing" in result.stderr
    last = summary(result)
    assert last["frames"] == {"host": 9, "device": 0}
    assert last["violations"] == {"letter-o": 1}
    assert not any(json.loads(line)["type"] == "timeout" for line in result.stdout.splitlines())
    assert any("other direction is missing" in note for note in last["notes"])


@pytest.mark.slow  # starts a process
def test_wrong_input_format_stops_early_and_names_the_detected_one() -> None:
    """A pcap read as socat printed one error per line, in raw binary. Now: a few located problems
    with no raw bytes, the detected format named, exit 2."""
    result = xac1(str(CAPTURES / "session.pcapng"), "--input-format", "socat")
    assert result.returncode == 2
    problems = [line for line in result.stderr.splitlines() if "not a socat header" in line]
    assert 1 <= len(problems) <= 3
    assert "looks like a pcap capture" in result.stderr and "more problem(s)" in result.stderr
    assert all(ch.isprintable() for ch in result.stderr.replace("\n", ""))


@pytest.mark.parametrize(("option", "value", "words"), [
    ("--timeout", "-1", "above 0"), ("--timeout", "nan", "above 0"), ("--timeout", "inf", "above 0"),
    ("--timeout", "soon", "not a number"), ("--header", "0XX", "not a header of the protocol"),
    ("--samplerate", "nan", "above 0"), ("--samplerate", "-48000", "above 0"),
    ("--storm-limit", "0", "from 1")])
@pytest.mark.slow  # starts a process
def test_bad_option_values_are_rejected(option: str, value: str, words: str) -> None:
    """``--timeout -1`` and ``--header 0XX`` were accepted; non-finite numbers too."""
    result = xac1(str(CAPTURES / "socat-x.log"), f"{option}={value}")
    assert result.returncode == 2 and words in result.stderr and option in result.stderr


@pytest.mark.slow  # starts a process
def test_lower_case_header_option_is_read_as_the_header() -> None:
    """``--header 0wp`` selects the 0WP frames: the header option is read case-insensitively."""
    result = xac1(str(CAPTURES / "socat-x.log"), "--header", "0wp", "--format", "jsonl")
    assert {json.loads(line).get("header") for line in result.stdout.splitlines()[:-1]} == {"0WP"}


@pytest.mark.slow  # starts a process
def test_two_files_of_different_formats_say_which_format_each_is() -> None:
    """Two recognised files of different formats got "none matched"."""
    result = xac1(str(CAPTURES / "socat-x.log"), str(CAPTURES / "spy.log"))
    assert result.returncode == 2
    assert "socat-x.log is socat" in result.stderr and "spy.log is spy" in result.stderr
    assert "none matched" not in result.stderr


@pytest.mark.slow  # starts a process
def test_problems_reach_the_json_lines_summary(tmp_path: Path) -> None:
    """Damage reported on stderr was absent from the summary record: a pipeline saw only the exit
    status. Now the summary carries the count and the first messages; a clean read has neither."""
    lines = (CAPTURES / "socat-x.log").read_text().splitlines(keepends=True)
    lines[4] = "@@@ damaged @@@\n"
    bad = tmp_path / "bad.log"
    bad.write_text("".join(lines))
    result = xac1(str(bad), "--format", "jsonl")
    located = [line for line in result.stderr.splitlines() if line.startswith(f"xac1 decode: {bad}:")]
    last = summary(result)
    assert last["problems"] == len(located) >= 1
    assert last["problem_messages"][0].startswith(f"{bad}:5: ")
    clean = summary(xac1(str(CAPTURES / "socat-x.log"), "--format", "jsonl"))
    assert "problems" not in clean


@pytest.mark.slow  # starts a process
def test_interceptty_less_than_sign_is_the_host() -> None:
    """interceptty prints ``<`` for what the program on its front pty (the host software) wrote and
    ``>`` (and a tab) for what the device answered; the reader had them the other way round."""
    result = xac1(str(CAPTURES / "interceptty.log"), "--format", "jsonl")
    first = json.loads(result.stdout.splitlines()[0])
    assert (first["dir"], bytes.fromhex(first["raw"])) == ("host", b"0RV\r\n")
    assert (CAPTURES / "interceptty.log").read_text().startswith("< 0x30 (0)\n")
    swapped = xac1(str(CAPTURES / "interceptty.log"), "--host-is", ">", "--format", "jsonl")
    assert json.loads(swapped.stdout.splitlines()[0])["dir"] == "device"


# ---- memory ----

@pytest.mark.slow  # a 100 MB file
@pytest.mark.parametrize("layout", ["socat", "jsonl"])
def test_a_100_mb_line_without_a_newline_stays_under_64_mib(tmp_path: Path, layout: str) -> None:
    """A 100 MB line with no newline (a socat hex dump, a recording line) is read in bounded pieces."""
    big = tmp_path / f"big.{layout}"
    with open(big, "wb") as f:
        if layout == "socat":
            f.write(b"> 2024/05/01 10:00:00.000000  length=99999999 from=0 to=99999998\n")
            piece = b" 30" * (1 << 16)
        else:
            f.write(b'{"type":"recording","version":1}\n{"type":"chunk","t":1.0,"dir":"host","data":"')
            piece = b"30" * (1 << 16)
        for _ in range((100 << 20) // len(piece)):
            f.write(piece)
    code, peak = run_measuring_peak_rss([sys.executable, "-m", "xac1_proto", "decode", str(big),
                                         "--format", "summary"], cwd=ROOT)
    assert code in (1, 2)
    assert peak < 64, f"peak RSS {peak:.1f} MiB"


# ---- statistics and views on damaged times (records.py, view.py) ----

@pytest.mark.parametrize("t", [float("nan"), float("inf"), -float("inf"), 1e300, -1e300])
def test_time_column_and_latency_statistics_survive_any_float(t: float) -> None:
    """``show_time`` and the latency statistics raised ``ValueError``/``OverflowError`` on NaN,
    infinite and absurd times; a damaged time is shown as such and never counted as a latency."""
    from sniffer.records import LatencyStats, Tally
    from sniffer.view import show_time

    assert show_time(t).strip().startswith("?") and len(show_time(t)) == 12
    stats = LatencyStats()
    stats.add(t)
    stats.add(0.002)
    assert stats.stats_ms() == {"n": 1, "min": 2.0, "median": 2.0, "max": 2.0}
    tally = Tally()
    tally.latencies["0RV"] = LatencyStats()
    tally.latencies["0RV"].add(t)
    assert tally.latency_stats() == {}


def test_sniffing_a_pipe_does_not_consume_it() -> None:
    """Format detection reads a buffered head of the one open file; reading then starts from byte 0."""
    from sniffer.io.base import Report, Source
    from sniffer.io.registry import Capture, detect

    data = (CAPTURES / "socat-x.log").read_bytes()
    read_fd, write_fd = os.pipe()
    writer = threading.Thread(target=lambda: (os.write(write_fd, data), os.close(write_fd)), daemon=True)
    writer.start()
    report = Report()
    src = Source(f"/dev/fd/{read_fd}", report, name="pipe")
    assert not src.regular and detect([src]).name == "socat"
    with Capture([src], "socat", report=report) as capture:
        chunks = list(capture)
    writer.join(5)
    os.close(read_fd)
    with Capture([str(CAPTURES / "socat-x.log")], "socat") as direct:
        assert [(c.t, c.dir, c.data) for c in chunks] == [(c.t, c.dir, c.data) for c in direct]
    assert chunks[0].data == b"0RV\r\n" and not report.problems
