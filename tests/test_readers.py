"""Capture readers: each format's layout read into the same chunks; malformed and truncated files give
located problems and partial results (issue: offline decode)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.io import interceptty, jpnevulator, jsonl, pcap, saleae, sigrok, socat, spy
from sniffer.io.base import FormatError, Report, Source
from sniffer.io.registry import Capture, detect
from xac1_proto.chunk import Chunk
from xac1_proto.recording import DATA_PER_LINE, LONGEST_LINE, RecordingWriter


def read(module, path: Path, **kw) -> tuple[list[Chunk], Report]:
    report = Report()
    with Source(path, report) as src:
        return list(module.read(src, **kw)), report


def joined(chunks: list[Chunk]) -> dict[str, bytes]:
    out = {"host": b"", "device": b""}
    for c in chunks:
        out[c.dir] += c.data
    return out


def test_socat_nine_digit_fraction_holds_microseconds(tmp_path: Path) -> None:
    """socat 1.7.x prints ``08.000428215`` meaning 08.428215 s; a real nanosecond fraction switches
    the file to nanoseconds."""
    f = tmp_path / "s.log"
    f.write_text("> 2024/05/01 10:00:08.000428215  length=5 from=0 to=4\n 30 52 56 0d 0a\n"
                 "< 2024/05/01 10:00:08.000500000  length=8 from=0 to=7\n 30 52 56 31 30 30 0d 0a\n"
                 "> 2024/05/01 10:00:09.123456789  length=5 from=5 to=9\n 30 52 56 0d 0a\n")
    chunks, report = read(socat, f)
    assert [c.dir for c in chunks] == ["host", "device", "host"]
    assert chunks[1].t - chunks[0].t == pytest.approx(0.500000 - 0.428215, abs=1e-6)
    assert chunks[2].t - chunks[0].t == pytest.approx(1.123456789 - 0.428215, abs=1e-6)
    assert not report.problems


def test_socat_v_text_glued_header_and_escapes(tmp_path: Path) -> None:
    """-v text does not end with a newline: ``length=`` says where the data ends and the next header
    may follow on the same line; ``\\r`` and ``\\\\`` are escapes, a real newline is an LF byte."""
    f = tmp_path / "v.log"
    f.write_text("> 2024/05/01 10:00:00.100000  length=4 from=0 to=3\n0RP3"
                 "< 2024/05/01 10:00:00.200000  length=6 from=0 to=5\na\\\\b\\r\n"
                 "\n> 2024/05/01 10:00:00.300000  length=2 from=4 to=5\n\\r\n")
    chunks, report = read(socat, f)
    assert [(c.dir, c.data) for c in chunks] == [("host", b"0RP3"), ("device", b"a\\b\r\n\n"),
                                                 ("host", b"\r\n")]
    assert not report.problems


def test_socat_host_is_swaps_sides_and_refuses_unknown_names(tmp_path: Path) -> None:
    """--host-is names a side as socat does (``<``); anything else is a clear error."""
    f = tmp_path / "s.log"
    f.write_text("> 2024/05/01 10:00:00.100000  length=5 from=0 to=4\n 30 52 56 0d 0a\n")
    chunks, _ = read(socat, f, host_is="<")
    assert chunks[0].dir == "device"
    with pytest.raises(FormatError, match="'>' and '<'"):
        read(socat, f, host_is="TX")


def test_socat_truncated_transfer_is_reported_with_line(tmp_path: Path) -> None:
    """A dump cut short keeps the bytes it has and says which transfer lost how many bytes."""
    f = tmp_path / "s.log"
    f.write_text("> 2024/05/01 10:00:00.100000  length=16 from=0 to=15\n 30 52 50 33 39\n"
                 "garbage line here\n")
    chunks, report = read(socat, f)
    assert chunks[0].data == b"0RP39"
    assert report.unread_bytes == 11
    assert any(p.startswith(f"{f}:1:") and "length=16" in p for p in report.problems)
    assert any(f"{f}:3:" in p for p in report.problems)


def test_spy_rows_offsets_control_and_empty(tmp_path: Path) -> None:
    """spy:// rows: offset 0000 starts a chunk, 0010 continues it; control, Q- and <empty> rows carry
    no data; TX is the host by default."""
    f = tmp_path / "spy.log"
    row = "{t} {label:4} {off}  {cells:<49} {ascii}\n"
    text = "000000.000 Q-RX reset_input_buffer\n000000.001 RTS  inactive\n"
    text += row.format(t="000000.010", label="TX", off="0000", cells="30 52 56 0D 0A", ascii="0RV..")
    text += "000000.020 RX   <empty>\n"
    text += row.format(t="000000.030", label="RX", off="0000",
                       cells="30 52 50 31 39 33 30 32  30 31 32 33 34 35 0D 0A", ascii="0RP19302012345..")
    text += row.format(t="000000.030", label="RX", off="0010", cells="30 52 56 0D", ascii="0RV.")
    f.write_text(text + "not a row\n")
    chunks, report = read(spy, f)
    assert [(c.t, c.dir, c.data) for c in chunks] == [
        (0.01, "host", b"0RV\r\n"), (0.03, "device", b"0RP19302012345\r\n0RV\r")]
    assert report.unread_lines == 1 and f"{f}:7:" in report.problems[0]


def test_interceptty_original_and_fork_layouts(tmp_path: Path) -> None:
    """interceptty: ``<`` bytes the front-pty program (the host) wrote, ``>`` (with a tab) bytes the
    device answered on the back port; the fork's ``[HH:MM SS.uuuuuu]`` stamps, character names and
    joined lines read the same bytes."""
    plain = tmp_path / "a.log"
    plain.write_text("< 0x30 (0)\n< 0x52 (R)\n< 0x56 (V)\n< 0x0d\n< 0x0a\n> \t0x30 (0)\n"
                     "> \t0x52 (R)\n> \t0x56 (V)\n> \t0x31 (1)\n> \t0x30 (0)\n> \t0x30 (0)\n> \t0x0d\n"
                     "> \t0x0a\n")
    fork = tmp_path / "b.log"
    fork.write_text("[10:00 01.000000]< 30(0):52(R):56(V):0d([CR]):0a([LF])\n"
                    "[10:00 01.020000]> \t0x30 (0)\n                 > \t0x52 (R)\n"
                    "                 > \tV\n                 > \t1\n                 > \t0\n"
                    "                 > \t0\n                 > \t[CR]\n                 > \t[LF]\n")
    want = {"host": b"0RV\r\n", "device": b"0RV100\r\n"}
    a, ra = read(interceptty, plain)
    b, rb = read(interceptty, fork)
    assert joined(a) == joined(b) == want
    assert b[1].t - b[0].t == pytest.approx(0.02)
    assert not ra.problems and not rb.problems


def test_jpnevulator_byte_count_ascii_width_and_glued_line(tmp_path: Path) -> None:
    """--byte-count and --ascii columns are dropped, --width wraps data lines, and a partial last line
    glued to the next timing line (killed mid-write) is still read."""
    f = tmp_path / "j.txt"
    f.write_text("2024-05-01 10:00:00.100000: /dev/pts/3\n00000000\t30 52 50 33 0D 0A      \t0RP3..\n"
                 "2024-05-01 10:00:00.150000: /dev/pts/4\n00000000\t30 52 50 33 39 33 30 32\t0RP39302\n"
                 "00000008\t30 31 32 33 34 35 0D 0A2024-05-01 10:00:00.300000: /dev/pts/3\n30 52 56 0D 0A")
    chunks, report = read(jpnevulator, f)
    assert [(c.dir, c.data) for c in chunks] == [("host", b"0RP3\r\n"), ("device", b"0RP39302012345\r\n"),
                                                 ("host", b"0RV\r\n")]
    assert chunks[1].t - chunks[0].t == pytest.approx(0.05, abs=1e-5)
    chunks, report = read(jpnevulator, f, host_is="/dev/pts/4")
    assert chunks[0].dir == "device"
    _, report = read(jpnevulator, f, host_is="nope")
    assert any("matches no side" in p for p in report.problems)


def test_saleae_analyzer_pair_merged_by_time_with_framing_error(tmp_path: Path) -> None:
    """Saleae analyzer exports, one file per line (hex and ASCII radix), merge by time; a framing
    error marks its byte."""
    host = tmp_path / "host.csv"
    host.write_text("Time [s],Value,Parity Error,Framing Error\n0.10,0x30,,\n0.11,0x52,,\n0.12,0x56,,\n"
                    "0.13,0x0D,,\n0.14,0x0A,,\n")
    dev = tmp_path / "device.csv"
    dev.write_text("Time [s],Value,Parity Error,Framing Error\n0.20,'0',,\n0.21,R,,\n0.22,V,,\n"
                   "0.23,1,,Error\n0.24,0,,\n0.25,0,,\n0.26,\\r,,\n0.27,\\n,,\nbad,row\n")
    with Capture([str(dev), str(host)], "saleae") as cap:
        chunks = list(cap)
    assert joined(chunks) == {"host": b"0RV\r\n", "device": b"0RV100\r\n"}
    assert [c.data for c in chunks if c.error] == [b"1"]
    assert cap.report.unread_lines == 1 and f"{dev}:10:" in cap.report.problems[0]


def test_saleae_logic2_table_names_are_sides(tmp_path: Path) -> None:
    """Logic 2 data table: the analyzer's name is the side; --host-is takes that name."""
    f = tmp_path / "t.csv"
    f.write_text('name,type,start_time,duration,data\n"uart A","data",0.1,0.001,0x30\n'
                 '"uart A","data",0.101,0.001,0x0A\n"uart B","data",0.2,0.001,0x31\n'
                 '"uart B","framing error",0.201,0.001,\n')
    chunks, _ = read(saleae, f)
    assert joined(chunks) == {"host": b"0\n", "device": b"1"}
    assert chunks[-1].error
    chunks, _ = read(saleae, f, host_is="uart B")
    assert joined(chunks) == {"host": b"1", "device": b"0\n"}


def test_sigrok_one_instance_classes_and_errors(tmp_path: Path) -> None:
    """One UART decoder showing classes: tx-data is the host by default, rx-data the device; a frame
    error annotation marks the byte before it; --samplerate turns sample numbers into seconds."""
    f = tmp_path / "a.txt"
    f.write_text('100-180 uart-1: tx-data: "30"\n200-280 uart-1: tx-data: "0A"\n'
                 '300-380 uart-1: rx-data: "31"\n380-390 uart-1: rx-warnings: "Frame error"\n')
    chunks, _ = read(sigrok, f, samplerate=1000.0)
    assert [(c.t, c.dir, c.data, bool(c.error)) for c in chunks] == [
        (0.1, "host", b"0", False), (0.2, "host", b"\n", False), (0.3, "device", b"1", True)]
    chunks, _ = read(sigrok, f, host_is="rx-data", samplerate=1000.0)
    assert chunks[0].dir == "device"


def test_sigrok_instances_out_of_order_are_merged_by_time(tmp_path: Path) -> None:
    """sigrok-cli prints each decoder instance's annotations block by block; with times the reader
    still yields them in time order (sample rate inferred at 9600 baud when not given)."""
    f = tmp_path / "b.txt"
    f.write_text("10-90 uart-1: 30\n310-390 uart-1: 0A\n110-190 uart-2: 31\n410-490 uart-2: 0A\n")
    chunks, report = read(sigrok, f)
    assert [(c.dir, c.data) for c in chunks] == [("host", b"0"), ("device", b"1"), ("host", b"\n"),
                                                 ("device", b"\n")]
    assert chunks[0].t == pytest.approx(10 / 96000)
    assert any("96000 Hz inferred" in n for n in report.notes)


def _pcap_file(path: Path, linktype: int, records: list[bytes], big: bool = False) -> None:
    o = ">" if big else "<"
    data = struct.pack(o + "IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, linktype)
    for k, rec in enumerate(records):
        data += struct.pack(o + "IIII", 100 + k, 0, len(rec), len(rec)) + rec
    path.write_bytes(data)


def _rtac(event: int, payload: bytes, t: int = 0) -> bytes:
    return struct.pack(">IIBBH", t, 0, event, 0, 0) + payload


@pytest.mark.parametrize("linktype", [pcap.LINKTYPE_RTAC_SERIAL, pcap.LINKTYPE_USER0])
@pytest.mark.parametrize("big", [False, True])
def test_pcap_rtac_events_directions_and_truncation(tmp_path: Path, linktype: int, big: bool) -> None:
    """RTAC serial header: TX events are the host by default, RX the device, framing-error events mark
    bytes; a record cut by the end of the file is reported and the rest kept."""
    f = tmp_path / "x.pcap"
    _pcap_file(f, linktype, [_rtac(1, b"0RV\r\n"), _rtac(2, b"0RV100\r\n"), _rtac(7, b"\xff"),
                             _rtac(0, b""), _rtac(1, b"0RC\r\n")], big)
    chunks, report = read(pcap, f)
    assert [(c.dir, c.data, c.error) for c in chunks] == [
        ("host", b"0RV\r\n", None), ("device", b"0RV100\r\n", None),
        ("device", b"\xff", "UART framing error"), ("host", b"0RC\r\n", None)]
    f.write_bytes(f.read_bytes()[:-3])
    chunks, report = read(pcap, f)
    assert len(chunks) == 3 and report.unread_bytes > 0 and "record 5" in report.problems[0]


def test_pcap_other_linktype_is_refused(tmp_path: Path) -> None:
    """A pcap of another link type (Ethernet) is not a serial capture: a clear error."""
    f = tmp_path / "e.pcap"
    _pcap_file(f, 1, [b"x" * 20])
    with pytest.raises(FormatError, match="link type 1 is not serial"):
        read(pcap, f)


@settings(max_examples=budget(25), deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["host", "device"]), st.binary(min_size=1, max_size=40),
                          st.floats(min_value=0, max_value=1e3)), max_size=8))
def test_pcapng_writer_round_trip(tmp_path_factory, items) -> None:
    """Whatever the writer writes, the reader reads back: directions, bytes, microsecond times (in time
    order: a time running backwards is a problem of the capture)."""
    path = tmp_path_factory.mktemp("p") / "r.pcapng"
    chunks = [Chunk(1.7e9 + t, d, data) for (d, data, _), t in zip(items, sorted(t for *_, t in items),
                                                                     strict=True)]
    with pcap.PcapngWriter(path) as w:
        for c in chunks:
            w.write(c)
    back, report = read(pcap, path)
    assert [(c.dir, c.data) for c in back] == [(c.dir, c.data) for c in chunks]
    assert all(abs(a.t - b.t) < 2e-6 for a, b in zip(back, chunks, strict=True))
    assert not report.problems


def test_jsonl_reads_decoded_output_and_recordings(tmp_path: Path) -> None:
    """Our decoded JSON lines give back the bytes of frame and junk records; a bad line is located."""
    f = tmp_path / "d.jsonl"
    f.write_text('{"type":"frame","i":0,"t":1.5,"dir":"host","raw":"3052560d0a","header":"0RV",'
                 '"fields":{},"violations":[]}\n{"type":"junk","i":1,"t":2.0,"dir":"device","raw":"41",'
                 '"violations":["garbage"],"reason":"flushed","line_errors":["UART framing error"]}\n'
                 '{"type":"timeout","t":3.0}\n{oops\n{"type":"summary"}\n')
    chunks, report = read(jsonl, f)
    assert chunks == [Chunk(1.5, "host", b"0RV\r\n"), Chunk(2.0, "device", b"A", "UART framing error")]
    assert report.unread_lines == 1 and f"{f}:4:" in report.problems[0]


@pytest.mark.parametrize("kind", ["recording", "decoded"])
def test_jsonl_an_overlong_line_is_one_problem_at_its_line(tmp_path: Path, kind: str) -> None:
    """A JSON line longer than ``LONGEST_LINE`` (here a 3 MB ``data`` string of digits) is one problem at
    its own line number, in our words, and the lines after it are read with their own numbers (issue 40
    item 5: it was reported as lines 3, 4, 5... with Python's "Exceeds the limit (4300 digits)" message)."""
    f = tmp_path / "big.jsonl"
    if kind == "recording":
        lines = ['{"type":"recording","version":1,"started":0,"source":"t"}',
                 '{"type":"chunk","t":1.0,"dir":"host","data":"3052560d0a"}',
                 '{"type":"chunk","t":1.1,"dir":"host","data":"' + "31" * 1_500_000 + '"}',
                 '{"type":"chunk","t":1.2,"dir":"device","data":"305256313030"}', "{oops"]
    else:
        lines = ['{"type":"frame","t":1.0,"dir":"host","raw":"3052560d0a"}',
                 '{"type":"junk","t":1.1,"dir":"host","raw":"' + "31" * 1_500_000 + '"}',
                 '{"type":"frame","t":1.2,"dir":"device","raw":"305256313030"}', "{oops"]
    f.write_text("\n".join(lines) + "\n")
    chunks, report = read(jsonl, f)
    assert [c.data for c in chunks] == [b"0RV\r\n", b"0RV100"]
    big = lines.index(max(lines, key=len)) + 1
    assert report.problems == [
        f"{f}:{big}: a line of {len(lines[big - 1]):,} characters, longer than any recording or record line "
        f"({LONGEST_LINE:,} at most); not read",
        f"{f}:{len(lines)}: " + ("malformed recording line (" if kind == "recording" else
                                 "malformed decoded record (") + "Expecting property name enclosed in double "
        "quotes: line 1 column 2 (char 1))"]
    assert report.unread_lines == 2


def test_jsonl_a_number_past_pythons_digit_limit_is_said_in_our_words(tmp_path: Path) -> None:
    """A number of 5,000 digits in a line (Python's ``int`` refuses past 4,300) is a malformed line
    named as such, never Python's advice to call ``sys.set_int_max_str_digits``."""
    f = tmp_path / "n.jsonl"
    f.write_text('{"type":"recording","version":1,"started":0,"source":"t"}\n'
                 '{"type":"chunk","t":' + "1" * 5000 + ',"dir":"host","data":"3052560d0a"}\n')
    chunks, report = read(jsonl, f)
    assert chunks == []
    assert report.problems == [f"{f}:2: malformed recording line (a number with more digits than any field "
                               f"has)"]


def test_recording_writer_splits_a_long_chunk_into_lines_a_reader_takes(tmp_path: Path) -> None:
    """A chunk longer than ``DATA_PER_LINE`` is written as several chunk lines of the same time and
    direction, each within ``LONGEST_LINE``; reading them back gives the same bytes."""
    data = bytes(range(256)) * (DATA_PER_LINE // 128 + 3)
    f = tmp_path / "r.jsonl"
    with RecordingWriter(f) as rec:
        rec.write(Chunk(5.0, "device", data, "UART framing error"))
        rec.write(Chunk(6.0, "host", b""))
    assert max(len(line) for line in f.read_text().splitlines()) <= LONGEST_LINE
    chunks, report = read(jsonl, f)
    assert not report.problems and len(chunks) == 4
    assert b"".join(c.data for c in chunks[:3]) == data and chunks[3] == Chunk(6.0, "host", b"")
    assert {(c.t, c.dir, c.error) for c in chunks[:3]} == {(5.0, "device", "UART framing error")}


def test_auto_detection_names_what_it_considered(tmp_path: Path) -> None:
    """Content sniffing picks the format from the first lines; when unsure it lists what it
    considered and asks for --input-format."""
    f = tmp_path / "j.txt"
    f.write_text("2024-05-01 10:00:00.100000: host\n30 52 56 0D 0A\n")
    assert detect([str(f)]).name == "jpnevulator"
    g = tmp_path / "what.txt"
    g.write_text("hello world\n")
    with pytest.raises(FormatError, match="considered: .*--input-format"):
        detect([str(g)])


def test_report_keeps_memory_bounded() -> None:
    """Millions of bad lines keep only the first messages and count the rest."""
    r = Report()
    for k in range(10_000):
        r.problem(f"f:{k}", "bad", nlines=1)
    assert len(r.problems) == 50 and r.total_problems == 10_000 and r.unread_lines == 10_000
