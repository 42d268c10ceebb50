"""Damaged captures: every gallery file (each format and layout) cut short and corrupted, decoded by
``xac1 decode`` as a user runs it. The rule (issue: offline decode): truncated and corrupted files give
clear messages and partial results, never a traceback; exit status 1 when something was decoded, 2
only when nothing could be (README "Decoding captures")."""

from __future__ import annotations

import json
import re
import shutil
import struct
import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import CAPTURES, xac1

from sniffer.analyzer import analyze
from sniffer.io.registry import Capture, detect

PARTNERS = {"saleae-host.csv": "saleae-device.csv", "saleae-ascii-host.csv": "saleae-ascii-device.csv",
            "raw-host.bin": "raw-device.bin"}
GALLERY = sorted(p.name for p in CAPTURES.iterdir() if p.is_file() and p.suffix != ".py"
                 and p.name != "README.md" and p.name not in PARTNERS.values())
BINARY = (".pcap", ".pcapng", ".bin")
# a change that keeps the layout valid is data, not damage: a byte of a raw file or a character of
# socat -v text (which prints bytes as themselves) can be changed into any other byte unseen
UNDETECTABLE = {("raw-host.bin", "flip"), ("raw-host.bin", "insert"), ("raw-host.bin", "delete"),
                ("socat-v.log", "flip"),
                # cut between two hex bytes: just how jpnevulator --ascii leaves a file at Ctrl-C
                ("jpnevulator-ascii.txt", "cut-line")}
_TOKEN = re.compile(rb"(?<![0-9A-Fa-f])[0-9A-Fa-f]{2}(?![0-9A-Fa-f])")


@dataclass(frozen=True)
class Damage:
    op: str
    data: bytes  # the damaged file
    clean: bytes  # the undamaged part before the damage, cut where the format allows


def _line_start(data: bytes, at: int) -> int:
    return data.rfind(b"\n", 0, at) + 1


def _records(data: bytes) -> list[int]:
    """Offsets where pcap records / pcapng blocks start (the file header counts as one)."""
    starts = []
    if data[:4] == b"\x0a\x0d\x0d\x0a":
        k = 0
        while k + 8 <= len(data):
            starts.append(k)
            k += struct.unpack_from("<I", data, k + 4)[0]
    else:
        starts.append(0)
        k = 24
        while k + 16 <= len(data):
            starts.append(k)
            k += 16 + struct.unpack_from("<I", data, k + 8)[0]
    return starts


def damages(name: str, data: bytes) -> list[Damage]:
    """The deterministic damage set: cut in the first line (or file header), in the middle of a line
    (record), inside a byte token (record header); a byte flipped, a line (bytes) inserted, a byte
    deleted, all past the first frames."""
    n = len(data)
    out = []
    if name.endswith(BINARY):
        if name.endswith(".bin"):
            cut = n * 6 // 10
            at = n * 4 // 10
            return [Damage("cut-header", data[:3], b""), Damage("cut-line", data[:cut], data[:cut]),
                    Damage("flip", data[:at] + bytes([data[at] ^ 0xFF]) + data[at + 1:], data[:at]),
                    Damage("insert", data[:at] + b"@@junk@@" + data[at:], data[:at]),
                    Damage("delete", data[:at] + data[at + 1:], data[:at])]
        starts = _records(data)
        late = next(s for s in starts if s >= n * 6 // 10)
        early = next(s for s in starts if s >= n * 4 // 10)
        # the second byte of the record's (block's) length: it grows by 32 KB
        length_field = early + (5 if data[:4] == b"\x0a\x0d\x0d\x0a" else 9)
        return [Damage("cut-header", data[:10], b""),
                Damage("cut-record", data[:late + 20], data[:late]),
                Damage("cut-record-header", data[:late + 6], data[:late]),
                Damage("flip", data[:length_field] + bytes([data[length_field] ^ 0x7F])
                       + data[length_field + 1:], data[:early]),
                Damage("insert", data[:early] + b"@@junk@@\n" + data[early:], data[:early]),
                Damage("delete", data[:early] + data[early + 3:], data[:early])]
    first_end = data.index(b"\n")
    out.append(Damage("cut-header", data[: max(1, first_end // 2)], b""))
    late = _line_start(data, n * 6 // 10)
    late_end = data.index(b"\n", late)
    out.append(Damage("cut-line", data[: (late + late_end) // 2], data[:late]))
    token = _TOKEN.search(data, late)
    cut = token.start() + 1 if token else (late + late_end) // 2
    out.append(Damage("cut-token", data[:cut], data[: _line_start(data, cut)]))
    token = _TOKEN.search(data, n * 4 // 10)
    at = token.start() if token else n * 4 // 10
    line = _line_start(data, at)
    out.append(Damage("flip", data[:at] + b"Z" + data[at + 1:], data[:line]))
    out.append(Damage("insert", data[:line] + b"@@ not a capture line @@\n" + data[line:], data[:line]))
    out.append(Damage("delete", data[:at] + data[at + 1:], data[:line]))
    return out


def frames_by_side(records) -> dict[str, list[bytes]]:
    out: dict[str, list[bytes]] = {"host": [], "device": []}
    for r in records:
        if r["type"] == "frame":
            out[r["dir"]].append(bytes.fromhex(r["raw"]))
    return out


def decode_in_process(paths: list[Path]) -> dict[str, list[bytes]]:
    names = [str(p) for p in paths]
    fmt = detect(names).name
    # a cut sigrok file may hold one decoder instance only: keep the full file's sides
    with Capture(names, fmt, host_is="uart-1" if fmt == "sigrok" else None) as cap:
        return frames_by_side(r.to_dict() for r in analyze(list(cap)))


def run_decode(path: Path) -> subprocess.CompletedProcess[str]:
    return xac1("decode", str(path), "--format", "jsonl", cwd=path.parent)


@pytest.mark.slow
@pytest.mark.parametrize("name", GALLERY)
def test_damaged_gallery_file_gives_located_messages_and_partial_results(tmp_path: Path,
                                                                         name: str) -> None:
    """Each damage of this gallery file: exit 1 (2 only when nothing at all could be decoded), no
    traceback, a message naming the file and its line (byte offset, record or block for binary
    files), valid JSON lines, and every frame of the undamaged part before the damage still decoded,
    in order, on each side."""
    data = (CAPTURES / name).read_bytes()
    cases = damages(name, data)
    dirs = []
    for case in cases:
        folder = tmp_path / case.op
        folder.mkdir()
        (folder / name).write_bytes(case.data)
        (folder / f"clean-{name}").write_bytes(case.clean)
        if name in PARTNERS:
            shutil.copy(CAPTURES / PARTNERS[name], folder / PARTNERS[name])
            shutil.copy(CAPTURES / PARTNERS[name], folder / f"clean-{PARTNERS[name]}")
        dirs.append(folder)
    with ThreadPoolExecutor(max_workers=3) as pool:
        results = list(pool.map(lambda d: run_decode(d / name), dirs))
    located = re.compile(re.escape(name) + r"(:\d+|@\d+| record \d+| block \d+)")
    for case, folder, result in zip(cases, dirs, results, strict=True):
        what = f"{name} {case.op}: rc={result.returncode}\n{result.stderr}"
        assert "Traceback" not in result.stderr, what
        assert result.returncode in (1, 2), what
        if (name, case.op) not in UNDETECTABLE:
            assert name in result.stderr, what
            if case.op != "cut-header":
                assert located.search(result.stderr), what
        if result.returncode == 2:
            assert case.op == "cut-header", what
            continue
        got = frames_by_side(json.loads(line) for line in result.stdout.splitlines())
        if not case.clean:
            continue
        paths = [folder / f"clean-{name}"]
        if name in PARTNERS:
            paths.append(folder / f"clean-{PARTNERS[name]}")
        before = decode_in_process(paths)
        assert before["host"], what  # the damage is past the first frames
        for side in ("host", "device"):
            assert got[side][: len(before[side])] == before[side], f"{what}\n{side}: {got[side]}"
