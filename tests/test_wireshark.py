"""Wireshark, offline: the pcapng writer, the generated dissector run in tshark against our decoder,
``xac1 decode --annotate`` over the whole gallery, ``xac1 wireshark install``, and bad input.

tshark is real (Debian's 4.0); every comparison is tshark's ``xac1.*`` fields against our decoder's
records over the same file, packet by packet."""

from __future__ import annotations

import json
import os
import re
import stat
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from wireshark_tshark import (
    PLUGIN,
    assert_frames_match,
    dissect,
    dissected_verdicts,
    lua_errors,
    replay,
    tshark,
    verdicts_of,
)

from sniffer.io.pcapng_writer import PcapngRecorder, comments, open_recording
from sniffer.io.registry import Capture
from sniffer.records import FrameRecord, TimeoutRecord
from sniffer.wireshark import install as inst
from sniffer.wireshark.luagen import generate, shipped_path
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk

pytestmark = [pytest.mark.slow, pytest.mark.requires_tool("tshark")]  # tshark processes

GALLERY = Path(__file__).resolve().parent.parent / "captures"
CAPTURES = sorted(p for p in GALLERY.iterdir()
                  if p.is_file() and p.suffix not in (".md", ".py") and "device" not in p.name)
T0 = 1_700_000_000.0

# A sloppy host and a faulty device (docs/protocol.md "Violation codes"): letter O, an alarm ignored,
# a latch broken, an echo that differs, a bare LF, a frame split over three chunks, two frames in one
# chunk, junk, a lower-case field, an unknown command, a missing 2, a field out of range, an alarm of
# no meaning, and a command left unanswered.
SESSION: list[tuple[float, str, bytes]] = [
    (0.00, HOST, b"0RV\r\n"), (0.02, DEVICE, b"0RV100\r\n"),
    (0.10, HOST, b"ORP1\r\n"), (0.12, DEVICE, b"0%%01\r\n"),
    (0.20, HOST, b"0RS\r\n"), (0.22, DEVICE, b"0RS02\r\n"),
    (0.30, HOST, b"0%C\r\n"), (0.32, DEVICE, b"0%C00\r\n"),
    (0.40, HOST, b"0WP1"), (0.41, HOST, b"93020123"), (0.42, HOST, b"45\r\n"),
    (0.44, DEVICE, b"0WP19302012344\r\n"),
    (0.50, HOST, b"0RP2\r\n"), (0.52, DEVICE, b"0RP29302000100\n"),
    (0.60, HOST, b"xx\r\n0RC\r\n"), (0.62, DEVICE, b"0RC0000200abcd\r\n"),
    (0.70, HOST, b"0QQ\r\n"), (0.72, DEVICE, b"0%%03\r\n"),
    (0.80, HOST, b"0%C\r\n"), (0.82, DEVICE, b"0%C00\r\n"),
    (0.90, HOST, b"0WS0\r\n"), (0.92, DEVICE, b"0%%01\r\n"),
    (1.00, HOST, b"0%C\r\n"), (1.02, DEVICE, b"0%C00\r\n"),
    (1.10, HOST, b"0CM7\r\n"), (1.12, DEVICE, b"0%%01\r\n"),
    (1.20, HOST, b"0%C\r\n"), (1.22, DEVICE, b"0%C00\r\n"),
    (1.30, HOST, b"0RV\r\n"),
    (3.00, HOST, b"0RC\r\n"), (3.02, DEVICE, b"0RC0000200000\r\n"),
]


def session_chunks() -> list[Chunk]:
    return [Chunk(T0 + t, d, data) for t, d, data in SESSION]


def write_annotated(path: Path, chunks: list[Chunk]) -> None:
    """What ``xac1 decode --annotate`` and the live shells do: each chunk with the records it completed."""
    from sniffer.analyzer import Analyzer

    analyzer = Analyzer()
    with PcapngRecorder(path, source="test session") as rec:
        for chunk in chunks:
            rec.write(chunk, analyzer.feed(chunk))
        rec.verdicts(analyzer.close())


# ---- the generated plugin ----

def test_shipped_plugin_is_generated_from_spec():
    """The shipped xac1.lua is exactly what luagen makes from spec.py now (regenerate with
    ``python -m sniffer.wireshark.luagen --write``); the check command says so too."""
    assert shipped_path().read_text(encoding="utf-8") == generate()
    done = subprocess.run([sys.executable, "-m", "sniffer.wireshark.luagen", "--check"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr


def test_generated_tables_follow_spec(monkeypatch):
    """A change in spec.py's tables changes the plugin: every header with its byte count, every alarm
    name and every violation code comes from spec.py."""
    text = generate()
    for fs in spec.FRAME_SPECS:
        assert f'SPECS.{fs.role}["{fs.header}"] = {{ header = "{fs.header}", role = "{fs.role}", ' \
               f"length = {fs.length}," in text
    for code in spec.ALARMS:
        assert f'[0x{code:02X}] = "{spec.alarm_meaning(code)}"' in text
    for v in spec.VIOLATION_SPECS:
        assert f'code = "{v.code}", severity = "{v.severity}"' in text
    monkeypatch.setitem(spec.ALARMS, 0x0B, "homing error (changed)")
    assert "homing error (changed)" in generate()


# ---- pcapng writer ----

chunk_st = st.builds(Chunk, st.floats(min_value=1.0e9, max_value=2.0e9, allow_nan=False),
                     st.sampled_from([HOST, DEVICE]), st.binary(min_size=1, max_size=40),
                     st.sampled_from([None, None, None, "UART framing error", "UART parity error"]))


def _spread(chunks: list[Chunk]) -> list[Chunk]:
    """In time order, each at least 0.1 s after the one before: more than any frame's wire time, so no
    device pieces are joined into one packet (that is tests/test_pcapng_pieces.py)."""
    ordered = sorted(chunks, key=lambda c: c.t)
    return [Chunk(c.t + 0.1 * k, c.dir, c.data, c.error) for k, c in enumerate(ordered)]


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(chunk_st, max_size=25).map(_spread))
def test_pcapng_round_trip(tmp_path_factory, chunks):
    """Every chunk comes back from our pcap reader as written: direction (TX host, RX device), bytes,
    the UART error, the time to the microsecond (times in the order a recording has them: time running
    backwards is a problem of the capture, tests/test_pcap_walk.py)."""
    path = tmp_path_factory.mktemp("rt") / "r.pcapng"
    with PcapngRecorder(path, source="round trip") as rec:
        for c in chunks:
            rec.write(c)
    with Capture([str(path)], "pcap") as capture:
        back = list(capture)
        assert not capture.report.total_problems
    assert [(c.dir, c.data, c.error) for c in back] == [(c.dir, c.data, c.error) for c in chunks]
    for a, b in zip(back, chunks, strict=True):
        assert a.t == pytest.approx(b.t, abs=1e-6)


def test_pcapng_header_tshark_sees(tmp_path):
    """tshark reads the link type, the microsecond resolution, the section comment naming the tool and
    the ports, TX for the host and RX for the device, an error event for flagged bytes."""
    path = tmp_path / "h.pcapng"
    with PcapngRecorder(path, source="xac1 proxy --device /dev/ttyUSB0 (baud 9600)") as rec:
        rec.write(Chunk(T0, HOST, b"0RV\r\n"))
        rec.write(Chunk(T0 + 0.01, DEVICE, b"0RV1"))
        rec.write(Chunk(T0 + 0.0115, DEVICE, b"00\r\n", "UART framing error"))
    info = subprocess.run(["capinfos", str(path)], capture_output=True, text=True, timeout=60).stdout
    assert "RTAC serial-line" in info
    assert "xac1 0.1.0: xac1 proxy --device /dev/ttyUSB0 (baud 9600)" in info
    rows = dissect(path)
    assert [r["rtacser.eventtype"] for r in rows] == [["0x01"], ["0x02"], ["0x07"]]
    assert rows[2]["xac1.header"] == ["0RV"] and rows[2]["xac1.role"] == ["answer"]
    done = tshark(path, "-T", "fields", "-e", "frame.time_epoch")
    assert [float(x) for x in done.stdout.split()] == pytest.approx([T0, T0 + 0.01, T0 + 0.0115], abs=1e-6)


def test_open_recording_picks_the_format_by_suffix(tmp_path):
    """``.pcapng`` is pcapng, anything else our JSON lines recording; both read back the same."""
    for name in ("a.pcapng", "a.jsonl"):
        rec = open_recording(tmp_path / name, "test")
        for c in session_chunks():
            rec.write(c, [])
        rec.close()
        with Capture([str(tmp_path / name)], "pcap" if name.endswith("pcapng") else "jsonl") as capture:
            assert b"".join(c.data for c in capture if c.dir == HOST) == \
                b"".join(c.data for c in session_chunks() if c.dir == HOST)
    assert (tmp_path / "a.pcapng").read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"
    assert json.loads((tmp_path / "a.jsonl").read_text().splitlines()[0])["type"] == "recording"


def test_comments_carry_code_side_sentence_reply_and_latency():
    """A packet comment per violation (code, whose fault, the record's sentence) and one per answer."""
    r = FrameRecord(i=5, t=T0, dir="device", raw=b"0RS02\r\n", header="0RS", frame=None,
                    violations=("latch-broken",),
                    details=("a normal answer while alarm 01 ... (latch-broken)",),
                    reply_to=4, latency_s=0.0024)
    assert comments(r) == ["xac1 #5 latch-broken (device): a normal answer while alarm 01 ... (latch-broken)",
                           "xac1 #5 reply_to=#4 latency_ms=2.400"]
    t = TimeoutRecord(command=7, t=T0, header="0RV", waited_s=1.0,
                      details=("0RV #7 got no answer (no-answer)",))
    assert comments(t) == ["xac1 #7 no-answer (device): 0RV #7 got no answer (no-answer)"]


# ---- the dissector against our decoder ----

def test_dissector_equals_decoder_frame_by_frame(tmp_path):
    """Every frame of the sloppy session, reassembled across packets and several to a packet, has in
    tshark the header, role, N, Pos, alarm code and frame checks our decoder found, and every verdict of
    the decoder is an ``xac1.violation`` with its side on the packet that completed the frame."""
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    rows = dissect(path)
    from sniffer.analyzer import analyze

    records = analyze(session_chunks())
    assert assert_frames_match(path, rows) == sum(isinstance(r, FrameRecord) for r in records) == 29
    per_chunk, _ = replay(path)
    want = verdicts_of([r.to_dict() for r in records])
    assert dissected_verdicts(rows) == want
    assert dissect(path, two_pass=True) == rows  # a first pass without a tree finds the same
    codes = {c for _, c, _ in want}
    assert {"letter-o", "alarm-ignored", "latch-broken", "echo-mismatch", "bad-terminator", "garbage",
            "lowercase-hex", "unknown-command", "missing-2", "field-range", "reserved-alarm",
            "no-answer"} <= codes
    # reply_to and latency_ms on the answers, as the decoder paired them
    answers = [r for recs in per_chunk for r in recs if isinstance(r, FrameRecord) and r.reply_to is not None]
    assert [int(v) for row in rows for v in row["xac1.reply_to"]] == [r.reply_to for r in answers]
    got_ms = [float(v) for row in rows for v in row["xac1.latency_ms"]]
    assert got_ms == pytest.approx([r.latency_ms for r in answers], abs=1e-3)
    # the split 0WP shows in the packet of its last byte, reassembled
    split = next(r for r in rows if "0WP" in r["xac1.header"] and "command" in r["xac1.role"])
    assert split["xac1.n"] == ["0x01"] and int(split["xac1.pos"][0], 0) == 0x012345
    # expert info for frame checks and for verdicts
    experts = [m for row in rows for m in row["_ws.expert.message"]]
    assert any(m.startswith("letter-o: ") for m in experts)
    assert any(m.startswith("alarm-ignored (host): ") for m in experts)
    # filterable
    done = tshark(path, "-Y", 'xac1.violation == "alarm-ignored"', "-T", "fields", "-e", "xac1.header")
    assert done.stdout.split() == ["0RS"]
    done = tshark(path, "-Y", "xac1.alarm == 0x03", "-T", "fields", "-e", "xac1.alarm")
    assert done.stdout.split() == ["0x03"]


def test_recorded_verdicts_show_in_the_info_column(tmp_path):
    """The verdicts a recording carries (packet comments) show in tshark's Info column, each code once a
    packet, as ``{recorded: alarm-ignored, ...}`` after the dissector's own checks, in a one-pass and a
    two-pass read; a packet with no recorded verdict has none (issue 40 item 7: they were only in the
    detail tree, so ``alarm-ignored`` or ``overlapping-command`` never showed in the packet list)."""
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    want = {}
    for row in dissect(path):
        codes = list(dict.fromkeys(row["xac1.violation"]))
        want[int(row["frame.number"][0])] = codes
    assert "alarm-ignored" in want[5] and "overlapping-command" in want[15]
    for args in ((), ("-2",)):
        done = tshark(path, *args)
        assert done.returncode == 0 and not lua_errors(done), done.stderr
        got = {}
        for line in done.stdout.splitlines():
            m = re.match(r"\s*(\d+)\s.*?(?:\{recorded: ([^}]*)\})?$", line)
            assert m, line
            got[int(m[1])] = m[2].split(", ") if m[2] else []
        assert got == want


@settings(max_examples=budget(15), deadline=None)
@given(cuts=st.lists(st.integers(min_value=1, max_value=15), min_size=1, max_size=40),
       noise=st.lists(st.binary(min_size=1, max_size=6), max_size=3),
       flagged=st.sets(st.integers(min_value=0, max_value=60), max_size=6))
def test_dissector_framing_equals_the_framer_whatever_the_chunking(tmp_path_factory, cuts, noise, flagged):
    """The Lua framer (a port of xac1_proto/framer.py) cuts any chunking of the session's bytes, with
    noise in between, into the frames and junk our decoder finds, in the same packets; chunks flagged
    with a UART error (RTAC error events) keep their direction."""
    streams = {HOST: b"".join(d for _, side, d in SESSION if side == HOST) + b"".join(noise),
               DEVICE: b"".join(d for _, side, d in SESSION if side == DEVICE)}
    at = {HOST: 0, DEVICE: 0}
    chunks, t, k = [], T0, 0
    while any(at[d] < len(streams[d]) for d in at):
        side = (HOST, DEVICE)[(k // 2) % 2] if at[HOST] < len(streams[HOST]) else DEVICE
        if at[side] >= len(streams[side]):
            side = HOST
        n = cuts[k % len(cuts)]
        error = "UART framing error" if k in flagged else None
        chunks.append(Chunk(t, side, streams[side][at[side]:at[side] + n], error))
        at[side], k, t = at[side] + n, k + 1, t + 0.001
    path = tmp_path_factory.mktemp("chunking") / "c.pcapng"
    write_annotated(path, chunks)
    assert assert_frames_match(path) >= 29


def test_user0_files_dissect_the_same(tmp_path):
    """A file whose link type is USER0 (147) with the RTAC serial header (editcap -T user0) dissects
    exactly as the RTAC serial original."""
    path, user0 = tmp_path / "s.pcapng", tmp_path / "u0.pcapng"
    write_annotated(path, session_chunks())
    subprocess.run(["editcap", "-T", "user0", str(path), str(user0)], check=True, capture_output=True,
                   timeout=60)
    assert "USER 0" in subprocess.run(["capinfos", str(user0)], capture_output=True, text=True,
                                      timeout=60).stdout
    assert dissect(user0) == dissect(path)


def test_alarm_name_and_field_meanings_in_the_tree(tmp_path):
    """The tree names the alarm and gives each field's meaning."""
    path = tmp_path / "a.pcapng"
    write_annotated(path, session_chunks()[:4])
    text = tshark(path, "-V").stdout
    assert "communication error" in text
    assert "position number (0 = home)" in text and "read movement data of point N" in text


@pytest.mark.parametrize("capture", CAPTURES, ids=lambda p: p.name)
def test_annotate_every_gallery_capture(tmp_path, capture):
    """``xac1 decode FILE --annotate OUT.pcapng`` of every gallery capture opens in tshark with the very
    verdicts ``xac1 decode`` prints, and frames the dissector checks as the decoder does."""
    out = tmp_path / "annotated.pcapng"
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(capture), "--format", "jsonl",
                           "--annotate", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr  # the gallery session has violations
    records = [json.loads(line) for line in done.stdout.splitlines()]
    rows = dissect(out)
    assert dissected_verdicts(rows) == verdicts_of(records)
    assert {"letter-o", "alarm-ignored", "latch-broken"} <= {c for _, c, _ in dissected_verdicts(rows)}
    assert assert_frames_match(out, rows) > 10


def test_annotate_refuses_to_overwrite_its_input(tmp_path):
    """``--annotate`` naming the capture being read: a clear message, the capture untouched."""
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    before = path.read_bytes()
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(path), "--annotate", str(path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "that is an input file" in done.stderr
    assert path.read_bytes() == before


def test_recording_cut_mid_block_still_opens(tmp_path):
    """A recording cut anywhere (a process killed while writing) opens in tshark up to its last whole
    packet, and our reader says how many bytes were lost."""
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    data = path.read_bytes()
    whole = len(dissect(path))
    last_start = data.rfind(struct.pack("<I", 6), 0, len(data) - 12)
    for cut in (last_start + 2, last_start + 20, len(data) - 3):
        cut_path = tmp_path / f"cut{cut}.pcapng"
        cut_path.write_bytes(data[:cut])
        done = tshark(cut_path, "-T", "fields", "-e", "frame.number", "-e", "xac1.header")
        assert len(done.stdout.splitlines()) == whole - 1, done.stderr
        assert "cut short in the middle of a packet" in done.stderr or "appears to have been cut short" in \
            done.stderr
        assert not lua_errors(done)
        with Capture([str(cut_path)], "pcap") as capture:
            list(capture)
            assert capture.report.total_problems == 1


# ---- bad input ----

def test_pcapng_we_did_not_write(tmp_path):
    """A pcapng of another link type (Ethernet): our reader says which interface and link type and
    reads nothing; tshark with the plugin shows no XA-C1 and no Lua error."""
    path = tmp_path / "eth.pcapng"

    def block(t: int, body: bytes) -> bytes:
        body += b"\0" * (-len(body) % 4)
        return struct.pack("<II", t, 12 + len(body)) + body + struct.pack("<I", 12 + len(body))

    frame = bytes(12) + b"\x08\x00" + bytes(46)
    path.write_bytes(block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
                     + block(1, struct.pack("<HHI", 1, 0, 0))
                     + block(6, struct.pack("<IIIII", 0, 0, 0, len(frame), len(frame)) + frame))
    with Capture([str(path)], "pcap") as capture:
        assert list(capture) == []
        assert any("link type 1, not serial" in p for p in capture.report.problems)
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(path)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2 and "link type 1, not serial" in done.stderr
    tsh = tshark(path, "-T", "fields", "-e", "xac1.header")
    assert tsh.returncode == 0 and tsh.stdout.strip() == "" and not lua_errors(tsh)


def test_unknown_rtac_events_and_foreign_rtac_file(tmp_path):
    """An RTAC serial file with events we never write (status changes, data lost) still dissects: the
    data events are framed, the others ignored."""
    path = tmp_path / "foreign.pcapng"
    with PcapngRecorder(path) as rec:
        rec.write(Chunk(T0, HOST, b"0RV\r\n"))
    data = path.read_bytes()
    payload = struct.pack(">IIBBH", int(T0), 0, 0x05, 0, 0) + b"zz"  # CAPTURE_DATA_LOST with bytes
    epb = struct.pack("<IIIII", 0, 0, 0, len(payload), len(payload)) + payload + b"\0" * (-len(payload) % 4)
    path.write_bytes(data + struct.pack("<II", 6, 12 + len(epb)) + epb + struct.pack("<I", 12 + len(epb)))
    rows = dissect(path)
    assert rows[0]["xac1.header"] == ["0RV"]
    with Capture([str(path)], "pcap") as capture:
        assert [c.data for c in capture] == [b"0RV\r\n"]
        assert any("0x05" in p for p in capture.report.problems)


# ---- xac1 wireshark install ----

def xac1(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "xac1_proto", *args], capture_output=True, text=True,
                          timeout=60, env=env)


@pytest.fixture
def wsenv(tmp_path) -> dict[str, str]:
    home = tmp_path / "home"
    home.mkdir()
    return {**os.environ, "HOME": str(home), "WIRESHARK_CONFIG_DIR": str(tmp_path / "wscfg"),
            "XDG_CONFIG_HOME": str(tmp_path / "xdg")}


def test_install_profile_opens_recordings(tmp_path, wsenv):
    """After one ``xac1 wireshark install`` into a config dir, plain tshark (no -X, no -d) decodes a
    recording and filters on a verdict; the user's Decode As entries stay; a second install changes
    nothing; ``--uninstall`` removes only ours."""
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    cfg.mkdir()
    user_entry = "decode_as_entry: udp.port,5000,(none),RTP\n"
    (cfg / "decode_as_entries").write_text("# mine\n" + user_entry)
    done = xac1("wireshark", "install", env=wsenv)
    assert done.returncode == 0, done.stderr
    entries = (cfg / "decode_as_entries").read_text()
    assert entries.startswith("# mine\n" + user_entry) and inst.DECODE_AS_ENTRY in entries
    assert (cfg / "plugins" / "xac1.lua").read_text() == PLUGIN.read_text()
    launcher = Path(wsenv["HOME"]) / ".local/lib/wireshark/extcap/xac1-extcap"
    assert launcher.stat().st_mode & stat.S_IXUSR
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    plain = tshark(path, "-Y", 'xac1.violation == "alarm-ignored"', "-T", "fields", "-e", "xac1.header",
                   plugin=False, decode_as=False, env=wsenv)
    assert plain.stdout.split() == ["0RS"], plain.stderr
    assert xac1("wireshark", "install", env=wsenv).returncode == 0
    assert (cfg / "decode_as_entries").read_text() == entries
    paths = xac1("wireshark", "path", env=wsenv).stdout
    assert str(cfg / "plugins") in paths and str(launcher.parent) in paths
    done = xac1("wireshark", "install", "--uninstall", env=wsenv)
    assert done.returncode == 0, done.stderr
    assert (cfg / "decode_as_entries").read_text() == "# mine\n" + user_entry
    assert not (cfg / "plugins" / "xac1.lua").exists() and not launcher.exists()


def test_install_without_wireshark_config_dir_uses_home_and_xdg(tmp_path):
    """Without WIRESHARK_CONFIG_DIR: the Decode As entry in $XDG_CONFIG_HOME/wireshark and the plugin in
    ~/.local/lib/wireshark/plugins, which tshark loads by itself; a named profile gets the entry."""
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "WIRESHARK_CONFIG_DIR"}
    env.update(HOME=str(home), XDG_CONFIG_HOME=str(tmp_path / "xdg"))
    done = xac1("wireshark", "install", env=env)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "xdg/wireshark/decode_as_entries").read_text().endswith(inst.DECODE_AS_ENTRY + "\n")
    assert (home / ".local/lib/wireshark/plugins/xac1.lua").exists()
    path = tmp_path / "s.pcapng"
    write_annotated(path, session_chunks())
    plain = tshark(path, "-T", "fields", "-e", "xac1.header", plugin=False, decode_as=False, env=env)
    assert plain.stdout.split()[:2] == ["0RV", "0RV"], plain.stderr
    assert xac1("wireshark", "install", "--profile", "field", env=env).returncode == 0
    assert inst.DECODE_AS_ENTRY in (tmp_path / "xdg/wireshark/profiles/field/decode_as_entries").read_text()
    in_profile = tshark(path, "-C", "field", "-T", "fields", "-e", "xac1.header", plugin=False,
                        decode_as=False, env=env)
    assert in_profile.stdout.split()[:2] == ["0RV", "0RV"], in_profile.stderr


def test_install_refuses_a_malformed_decode_as_file(wsenv):
    """A decode_as_entries that does not parse: a message naming file and line; nothing changed."""
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    cfg.mkdir()
    bad = "decode_as_entry: udp.port,5000,(none),RTP\nthis is not an entry\n"
    (cfg / "decode_as_entries").write_text(bad)
    done = xac1("wireshark", "install", env=wsenv)
    assert done.returncode == 1
    assert f"{cfg / 'decode_as_entries'}:2: not a Decode As entry" in done.stderr
    assert "Traceback" not in done.stderr
    assert (cfg / "decode_as_entries").read_text() == bad
    assert not (cfg / "plugins").exists()


def test_install_keeps_an_entry_of_the_user_for_rtac_serial(wsenv):
    """The user already decodes RTAC serial payloads as something else: we say so and change nothing."""
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    cfg.mkdir()
    theirs = "decode_as_entry: rtacser.data,0,(none),Modbus/RTU\n"
    (cfg / "decode_as_entries").write_text(theirs)
    done = xac1("wireshark", "install", env=wsenv)
    assert done.returncode == 1 and "already decoded as something else" in done.stderr
    assert (cfg / "decode_as_entries").read_text() == theirs


def test_install_into_a_read_only_profile_dir(wsenv):
    """A profile folder we cannot write: a clear message, nothing of the user's touched. Root writes
    into read-only folders, so where the tests run as root the folder is made immutable (chattr +i),
    which root cannot write into either."""
    _read_only_case(wsenv)


def test_install_into_a_read_only_profile_dir_as_any_user(wsenv, monkeypatch):
    """The same refusal when the folder cannot be written (simulated where the tests run as root)."""
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    cfg.mkdir()
    original = "decode_as_entry: udp.port,5000,(none),RTP\n"
    (cfg / "decode_as_entries").write_text(original)
    import tempfile

    real = tempfile.mkstemp

    def refuse(*a, dir=None, **kw):  # noqa: A002 - tempfile's own keyword
        if dir is not None and Path(dir) == cfg:
            raise PermissionError(13, "Permission denied")
        return real(*a, dir=dir, **kw)

    monkeypatch.setattr(inst.tempfile, "mkstemp", refuse)
    with pytest.raises(inst.InstallError, match=f"cannot write in {cfg}: Permission denied"):
        inst.install(inst.folders(wsenv))
    assert (cfg / "decode_as_entries").read_text() == original


def _read_only_case(wsenv: dict[str, str]) -> None:
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    cfg.mkdir()
    original = "decode_as_entry: udp.port,5000,(none),RTP\n"
    (cfg / "decode_as_entries").write_text(original)
    cfg.chmod(0o555)
    immutable = os.geteuid() == 0
    if immutable:
        made = subprocess.run(["chattr", "+i", str(cfg)], capture_output=True, text=True)
        assert made.returncode == 0, f"chattr +i (e2fsprogs) is needed when the tests run as root: {made}"
    try:
        done = xac1("wireshark", "install", env=wsenv)
        assert done.returncode == 1 and "cannot write in" in done.stderr and "Traceback" not in done.stderr
        assert (cfg / "decode_as_entries").read_text() == original
        assert not (cfg / "plugins").exists()
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(cfg)], check=True)
        cfg.chmod(0o755)


def test_install_does_not_overwrite_a_plugin_of_the_same_name(wsenv):
    """A file named xac1.lua that we did not write stays; so does uninstall."""
    cfg = Path(wsenv["WIRESHARK_CONFIG_DIR"])
    (cfg / "plugins").mkdir(parents=True)
    (cfg / "plugins" / "xac1.lua").write_text("-- someone else's\n")
    done = xac1("wireshark", "install", env=wsenv)
    assert done.returncode == 1 and "was not written by xac1" in done.stderr
    assert not (cfg / "decode_as_entries").exists()
    assert xac1("wireshark", "install", "--uninstall", env=wsenv).returncode == 0
    assert (cfg / "plugins" / "xac1.lua").read_text() == "-- someone else's\n"


def test_folders_follow_wireshark():
    """WIRESHARK_CONFIG_DIR wins; else XDG_CONFIG_HOME/wireshark (or ~/.config/wireshark); profiles
    under profiles/NAME; Lua plugins and extcap under ~/.local/lib/wireshark."""
    f = inst.folders({"HOME": "/h", "WIRESHARK_CONFIG_DIR": "/c"}, profile="p")
    assert (f.config, f.profile, f.lua_plugins, f.extcap) == \
        (Path("/c"), Path("/c/profiles/p"), Path("/c/plugins"), Path("/h/.local/lib/wireshark/extcap"))
    f = inst.folders({"HOME": "/h", "XDG_CONFIG_HOME": "/x"})
    assert (f.config, f.lua_plugins) == (Path("/x/wireshark"), Path("/h/.local/lib/wireshark/plugins"))
    assert inst.folders({"HOME": "/h"}).config == Path("/h/.config/wireshark")



class _Quiet:
    def write(self, record) -> None:
        pass

    def summary(self, summary) -> None:
        pass


def test_live_session_writes_verdicts_as_they_come(tmp_path):
    """The live Session writes each chunk with the verdicts it completed, and a no-answer found when
    time passes on a packet of its own; a hand-opened JSON lines writer still works in its place."""
    from sniffer.analyzer import Analyzer
    from sniffer.live import Session
    from xac1_proto.recording import RecordingWriter, read_recording

    path = tmp_path / "live.pcapng"
    session = Session(Analyzer(), _Quiet(), open_recording(path, "live"))  # type: ignore[arg-type]
    for c in session_chunks()[:8]:  # up to the alarm reset
        session.chunk(c)
    session.chunk(Chunk(T0 + 2.0, HOST, b"0RV\r\n"))
    session.tick(T0 + 4.0)  # its deadline passed: no-answer on an empty packet of its own
    session.close(T0 + 4.0)
    rows = dissect(path)
    assert rows[-1]["frame.len"] == ["12"] and rows[-1]["xac1.violation"] == ["no-answer"]
    assert [v for row in rows for v in row["xac1.violation"]] == ["letter-o", "alarm-ignored", "latch-broken",
                                                                   "no-answer"]
    jsonl = tmp_path / "live.jsonl"
    session = Session(Analyzer(), _Quiet(), RecordingWriter(jsonl, "hand"))  # type: ignore[arg-type]
    for c in session_chunks()[:2]:
        session.chunk(c)
    session.close(T0 + 1)
    with open(jsonl, encoding="ascii") as f:
        assert [c.data for c in read_recording(f)] == [b"0RV\r\n", b"0RV100\r\n"]
