"""The Wireshark dissector reads a lower-case header as its command with the notice ``lowercase-hex``, as
``xac1 decode`` and docs/protocol.md "Framing" do (issue 23 item 11): generated from the same tables,
the same leniency. tshark for real."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_wireshark import T0, write_annotated
from wireshark_tshark import assert_frames_match, dissect

from sniffer.analyzer import analyze
from xac1_proto.chunk import DEVICE, HOST, Chunk

pytestmark = [pytest.mark.slow, pytest.mark.requires_tool("tshark")]  # tshark processes

LOWER = [(0.00, HOST, b"0rv\r\n"), (0.02, DEVICE, b"0rv100\r\n"),
         (0.10, HOST, b"0Rs\r\n"), (0.12, DEVICE, b"0rS02\r\n"),
         (0.20, HOST, b"Orp3\r\n"), (0.22, DEVICE, b"0%%01\r\n"),
         (0.30, HOST, b"0%c\r\n"), (0.32, DEVICE, b"0%c00\r\n"),
         (0.40, HOST, b"0wp19302012345\r\n"), (0.42, DEVICE, b"0WP19302012345\r\n")]


def test_a_lower_case_header_is_its_command_with_a_notice_in_the_dissector(tmp_path: Path):
    """0rv, 0Rs, 0%c, 0wp...: the dissector shows the upper-case header, decodes the fields and checks
    lowercase-hex, never unknown-command; packet by packet as xac1 decode does (a letter O before a
    lower-case tail, Orp3, is no frame start for either: garbage in both)."""
    chunks = [Chunk(T0 + t, d, data) for t, d, data in LOWER]
    path = tmp_path / "lower.pcapng"
    write_annotated(path, chunks)
    rows = dissect(path)
    records = analyze(chunks)
    assert assert_frames_match(path, rows) == 9
    headers = [h for row in rows for h in row["xac1.header"]]
    assert headers == ["0RV", "0RV", "0RS", "0RS", "0%%", "0%C", "0%C", "0WP", "0WP"]
    checks = [c for row in rows for c in row["xac1.check"]]
    assert "unknown-command" not in checks
    assert checks.count("lowercase-hex") == 7 and checks.count("garbage") == 1
    assert [int(v, 0) for row in rows for v in row["xac1.pos"]] == [0x12345, 0x12345]
    assert all("unknown-command" not in r.violations for r in records)
