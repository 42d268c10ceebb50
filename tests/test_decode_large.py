"""Large captures: ``xac1 decode`` draws a progress bar on stderr only when stderr is a terminal, and
reads a file of any size in constant memory (issue: offline decode, "Every reader streams ... Large
files show a progress bar on stderr when it is a terminal")."""

from __future__ import annotations

import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ROOT, gallery
from peak_rss import run_measuring_peak_rss

from sniffer.decode_cli import PROGRESS_MIN_BYTES

DECODE = [sys.executable, "-m", "xac1_proto", "decode", "--format", "summary"]


@pytest.fixture(scope="module")
def large_log(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("large") / "large.log"
    gallery.write_large_socat(path, PROGRESS_MIN_BYTES + PROGRESS_MIN_BYTES // 4)
    return path


def _read_all(fd: int, proc: subprocess.Popen, timeout: float = 60.0) -> bytes:
    """Everything written on a pty master until the child exits (EIO when the slave side closes)."""
    out = b""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                block = os.read(fd, 65536)
            except OSError:
                break
            if not block:
                break
            out += block
        elif proc.poll() is not None:
            break
    return out


_CSI = re.compile(r"\x1b\[([0-9;?]*)([A-Za-z])")


def screen(text: str) -> list[str]:
    """What a terminal shows after ``text``: lines with CR, LF, and the CSI cursor moves and erases a
    progress bar uses (up/down, column, erase in line); other escape sequences change nothing shown."""
    lines, row, col, at = [""], 0, 0, 0
    while at < len(text):
        csi = _CSI.match(text, at)
        if csi:
            at = csi.end()
            args, op = csi.group(1).lstrip("?"), csi.group(2)
            n = int(args.split(";")[0] or 0)
            line = lines[row]
            if op == "A":
                row = max(0, row - max(n, 1))
            elif op == "B":
                row = min(len(lines) - 1, row + max(n, 1))
            elif op == "G":
                col = max(n, 1) - 1
            elif op == "K":
                lines[row] = {0: line[:col], 1: " " * col + line[col:], 2: ""}.get(n, line)
            continue
        ch, at = text[at], at + 1
        if ch == "\r":
            col = 0
        elif ch == "\n":
            row += 1
            if row == len(lines):
                lines.append("")
        elif ch >= " ":
            line = lines[row].ljust(col)
            lines[row] = line[:col] + ch + line[col + 1:]
            col += 1
    return lines


def test_screen_follows_cursor_moves_and_erases() -> None:
    """The terminal model the progress bar test relies on."""
    assert screen("abc\rX") == ["Xbc"]
    assert screen("bar 50%\r\x1b[2K") == [""]
    assert screen("one\r\ntwo\x1b[1A\rO") == ["One", "two"]
    assert screen("abcdef\r\x1b[3G\x1b[K") == ["ab"]
    assert screen("\x1b[?25lbar\r   \r\x1b[?25h") == ["   "]


@pytest.mark.slow
def test_progress_bar_only_when_stderr_is_a_terminal(large_log: Path) -> None:
    """A capture of more than PROGRESS_MIN_BYTES: with stderr on a pty the bar (rich.progress:
    ``decoding ━━━━  NN.N% 0.6/1.3 MB``) is drawn and then erased; with stderr on a pipe there is no
    trace of it."""
    master, slave = os.openpty()
    try:
        proc = subprocess.Popen([*DECODE, str(large_log)], stdout=subprocess.DEVNULL, stderr=slave,
                                stdin=subprocess.DEVNULL, cwd=ROOT)
        os.close(slave)
        slave = -1
        shown = _read_all(master, proc).decode("utf-8", "replace")
        assert proc.wait(timeout=60) == 0
    finally:
        os.close(master)
        if slave >= 0:
            os.close(slave)
    assert "decoding" in shown and "100.0%" in shown and "/1.3 MB" in shown, shown[:300]
    left = [line for line in screen(shown) if line.strip()]
    assert left == [], f"the bar is wiped at the end; the terminal still shows {left}"
    piped = subprocess.run([*DECODE, str(large_log)], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert piped.returncode == 0
    assert "decoding [" not in piped.stderr and "%" not in piped.stderr


@pytest.mark.slow
def test_memory_does_not_grow_with_the_file(tmp_path: Path, large_log: Path) -> None:
    """Decoding streams: a socat log four times as large (15,000 records) peaks at about the same
    resident memory: within 3 MB (streaming measured +0.1 MB; holding the chunks and records in lists
    measured +5.6 MB) and under 64 MB (it measured 27 MB). benchmarks/bench_decode_memory.py does it
    with 50 MB."""
    smaller = tmp_path / "smaller.log"
    gallery.write_large_socat(smaller, large_log.stat().st_size // 4)
    small_code, small = run_measuring_peak_rss([*DECODE, str(smaller)], cwd=ROOT)
    big_code, big = run_measuring_peak_rss([*DECODE, str(large_log)], cwd=ROOT)
    assert (small_code, big_code) == (0, 0)
    print(f"peak RSS {small:.1f} MB -> {big:.1f} MB")
    assert big < 64
    assert big - small < 3, (small, big)
