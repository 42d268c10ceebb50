"""tshark with the generated XA-C1 plugin, and our decoder over the same pcapng, packet by packet.

``dissect(path)``: one dict a packet of every ``xac1.*`` field tshark shows (lists of strings).
``replay(path)``: our reader and ``Analyzer`` over the same file: for each packet holding line data, the
records its chunk completed (the packets with no line data carry only comments), then the records of
the end of the data. ``frame_view`` / ``expected_frame_view`` put both in the same shape, so a test
compares what the dissector computed in Lua with what ``xac1 decode`` computed, packet by packet.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from sniffer.analyzer import Analyzer
from sniffer.io.registry import Capture
from sniffer.records import FrameRecord, JunkRecord, Record
from sniffer.wireshark.luagen import shipped_path
from xac1_proto import spec

PLUGIN = shipped_path()
RTAC_HEADER_LEN = 12
SEP = "\x1f"
FIELDS = ("frame.number", "frame.len", "rtacser.eventtype", "xac1.header", "xac1.role", "xac1.n", "xac1.pos",
          "xac1.alarm", "xac1.check", "xac1.violation", "xac1.record", "xac1.side", "xac1.reply_to",
          "xac1.latency_ms", "_ws.expert.message", "frame.comment")
FRAME_CODES = frozenset(spec.CHECK_ORDER) | {"garbage"}
WAIT_S = 60.0


def tshark(path: Path | str, *args: str, plugin: bool = True, env: dict[str, str] | None = None,
           decode_as: bool = True) -> subprocess.CompletedProcess[str]:
    cmd = ["tshark", "-r", str(path)]
    if plugin:
        cmd += ["-X", f"lua_script:{PLUGIN}"]
    if decode_as:
        cmd += ["-d", "rtacser.data,xac1"]
    if env is None:  # the user's own Wireshark settings stay out of the tests
        env = {**os.environ, "WIRESHARK_CONFIG_DIR": "/nonexistent"}
    return subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=WAIT_S, env=env)


def lua_errors(done: subprocess.CompletedProcess[str]) -> list[str]:
    return [line for line in done.stderr.splitlines() if "Lua" in line or "lua" in line]


def dissect(path: Path | str, two_pass: bool = False, **kw) -> list[dict[str, list[str]]]:
    """``two_pass``: tshark -2, a first pass with no tree, as Wireshark's GUI reads a file."""
    args = ["-2"] if two_pass else []
    args += ["-T", "fields", "-E", "separator=\t", "-E", "occurrence=a", "-E", f"aggregator={SEP}"]
    for f in FIELDS:
        args += ["-e", f]
    done = tshark(path, *args, **kw)
    assert done.returncode == 0, done.stderr
    assert not lua_errors(done), done.stderr
    rows = []
    for line in done.stdout.splitlines():
        cells = line.split("\t")
        rows.append({f: (c.split(SEP) if c else []) for f, c in zip(FIELDS, cells, strict=True)})
    return rows


def has_data(row: dict[str, list[str]]) -> bool:
    return int(row["frame.len"][0]) > RTAC_HEADER_LEN


def replay(path: Path | str) -> tuple[list[list[Record]], list[Record]]:
    analyzer = Analyzer()
    with Capture([str(path)], "pcap") as capture:
        per_chunk = [analyzer.feed(chunk) for chunk in capture]
    return per_chunk, analyzer.close()


def frame_view(row: dict[str, list[str]]) -> dict[str, list]:
    """What the dissector decoded and checked in one packet."""
    return {"header": row["xac1.header"], "role": row["xac1.role"],
            "n": [int(v, 0) for v in row["xac1.n"]], "pos": [int(v, 0) for v in row["xac1.pos"]],
            "alarm": [int(v, 0) for v in row["xac1.alarm"]], "check": sorted(row["xac1.check"])}


def expected_frame_view(records: list[Record]) -> dict[str, list]:
    """The same, from our decoder's records of that packet."""
    frames = [r for r in records if isinstance(r, FrameRecord)]
    checks = [c for r in records if isinstance(r, FrameRecord | JunkRecord) for c in r.violations
              if c in FRAME_CODES]
    return {"header": [r.header for r in frames if r.header is not None],
            "role": ["command" if r.dir == "host" else "answer" for r in frames],
            "n": [r.fields["n"] for r in frames if r.fields and "n" in r.fields],
            "pos": [r.fields["pos"] for r in frames if r.fields and "pos" in r.fields],
            "alarm": [r.fields["code"] for r in frames if r.fields and "code" in r.fields],
            "check": sorted(checks)}


def assert_frames_match(path: Path | str, rows: list[dict[str, list[str]]] | None = None) -> int:
    """Every data packet: the dissector's frames and frame checks equal the decoder's; returns how many
    frames were compared."""
    rows = dissect(path) if rows is None else rows
    per_chunk, _ = replay(path)
    data_rows = [r for r in rows if has_data(r)]
    assert len(data_rows) == len(per_chunk), "one packet per chunk"
    compared = 0
    for row, records in zip(data_rows, per_chunk, strict=True):
        got, want = frame_view(row), expected_frame_view(records)
        assert got == want, f"{path} packet {row['frame.number'][0]}: tshark {got} != decoder {want}"
        compared += len(want["role"])
    return compared


def verdicts_of(records: list[dict]) -> list[tuple[int, str, str]]:
    """(record, code, side) of every violation in xac1 decode's JSON lines output."""
    out = []
    for r in records:
        if r["type"] not in ("frame", "junk", "timeout"):
            continue
        i = r["command"] if r["type"] == "timeout" else r["i"]
        for code in r["violations"]:
            out.append((i, code, spec.VIOLATION_TABLE[code].side(r["dir"])))
    return out


def dissected_verdicts(rows: list[dict[str, list[str]]]) -> list[tuple[int, str, str]]:
    """(record, code, side) of every verdict as the dissector's fields show them, in packet order."""
    out = []
    for row in rows:
        records, violations, sides = row["xac1.record"], row["xac1.violation"], row["xac1.side"]
        assert len(records) == len(violations) == len(sides), row
        out += [(int(i), v, s) for i, v, s in zip(records, violations, sides, strict=True)]
    return out
