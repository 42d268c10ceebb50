"""jpnevulator ends its file without a line end when stopped with Ctrl-C, as it always is (issue 23 item
6): a last line that reads whole is whole, not "cut short"; only a last line that does not read (a hex
byte cut in two, a timing line cut) is a problem of the capture."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest
from conftest import CAPTURES, budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.io import jpnevulator
from sniffer.io.base import Report, Source
from sniffer.io.registry import Capture
from xac1_proto.cli import main

SESSION = ("2024-05-01 10:00:00.100000: host\n30 52 56 0D 0A\n"
           "2024-05-01 10:00:00.120000: device\n30 52 56 31 30 30 0D 0A")


def read(path: Path) -> tuple[list[tuple[str, bytes]], Report]:
    report = Report()
    with Source(path, report) as src:
        chunks = [(c.dir, c.data) for c in jpnevulator.read(src)]
        src.check_end()
    return chunks, report


@pytest.mark.parametrize("name", ["jpnevulator.txt", "jpnevulator-ascii.txt"])
def test_the_gallerys_jpnevulator_logs_are_not_cut_short(name: str):
    """The gallery's real jpnevulator logs (stopped with Ctrl-C, no last line end) read with no problem."""
    assert not (CAPTURES / name).read_bytes().endswith(b"\n")  # as jpnevulator leaves them
    with Capture([str(CAPTURES / name)], "jpnevulator") as cap:
        chunks = list(cap)
    assert chunks and cap.report.problems == []


def test_a_whole_last_data_line_without_a_line_end_is_whole(tmp_path: Path):
    """The last data line, whole hex bytes and no line end: its bytes are read, no problem."""
    f = tmp_path / "j.txt"
    f.write_text(SESSION)
    chunks, report = read(f)
    assert chunks == [("host", b"0RV\r\n"), ("device", b"0RV100\r\n")] and report.problems == []


def test_a_last_line_cut_inside_a_hex_byte_is_cut_short(tmp_path: Path):
    """A last line that does not read (``30 5``) is a problem located at its line."""
    f = tmp_path / "j.txt"
    f.write_text(SESSION[:-1])
    _, report = read(f)
    assert any("j.txt:4" in p for p in report.problems)


def test_decode_of_a_clean_jpnevulator_log_exits_0(tmp_path: Path):
    """``xac1 decode`` of a clean exchange logged by jpnevulator and stopped with Ctrl-C: exit 0."""
    f = tmp_path / "j.txt"
    f.write_text(SESSION)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
        status = main(["decode", str(f), "--format", "summary"])
    assert status == 0, err.getvalue()


lines = st.lists(st.binary(min_size=1, max_size=12), min_size=1, max_size=4)


@settings(max_examples=budget(60), deadline=None)
@given(lines, st.booleans(), st.booleans())
def test_with_or_without_the_last_line_end_the_same_bytes_and_no_problem(tmp_path_factory, bursts,
                                                                         ascii_column, line_end):
    """Any bursts, with ``--ascii`` or not, the file ending with a line end or without: the same bytes,
    no problem."""
    text = ""
    for k, data in enumerate(bursts):
        side = "host" if k % 2 == 0 else "device"
        text += f"2024-05-01 10:00:00.{100000 + k * 1000}: {side}\n" + " ".join(f"{b:02X}" for b in data)
        if ascii_column and k < len(bursts) - 1:  # Ctrl-C leaves the last line without it
            text += "\t" + "".join(chr(b) if 32 <= b < 127 else "." for b in data)
        text += "\n" if k < len(bursts) - 1 or line_end else ""
    f = tmp_path_factory.mktemp("j") / "j.txt"
    f.write_text(text, encoding="latin-1")
    chunks, report = read(f)
    assert b"".join(data for _, data in chunks) == b"".join(bursts)
    assert report.problems == []
