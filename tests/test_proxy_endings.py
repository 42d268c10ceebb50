"""``xac1 proxy`` ends as documented (issue 24 items 11 and 13): when its standard output goes away
(``xac1 proxy ... | tee log`` and the Ctrl-C that ends both), the recording, the report and the summary
(on stderr) are still written and the exit status is the signal's; its errors start ``xac1 proxy:``."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ROOT, wait_until

from sniffer.analyzer import Analyzer
from sniffer.live import Session
from xac1_proto.chunk import Chunk
from xac1_proto.cli import main
from xac1_proto.client import Client
from xac1_proto.recording import read_recording
from xac1_proto.sim import SimConfig, serve_pty


class ClosedPipeView:
    """A view whose reader went away after ``keep`` records (as ``tee`` ended by Ctrl-C)."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self.written: list[object] = []

    def write(self, record: object) -> None:
        if len(self.written) >= self.keep:
            raise BrokenPipeError(32, "Broken pipe")
        self.written.append(record)

    def summary(self, summary: dict) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self) -> None:
        pass


def test_a_closed_output_stops_the_printing_not_the_session(tmp_path: Path, capsys) -> None:
    """A view that raises BrokenPipeError: the session goes on (every record still reaches the report
    hook), says once on ``err`` that standard output went away, and puts the summary there."""
    import io

    err = io.StringIO()
    seen: list[object] = []
    view = ClosedPipeView(keep=1)
    session = Session(Analyzer(), view, on_record=seen.append, err=err, program="xac1 proxy")
    for k, (d, data) in enumerate([("host", b"0RV\r\n"), ("device", b"0RV100\r\n"), ("host", b"0RS\r\n"),
                                   ("device", b"0RS02\r\n")]):
        session.chunk(Chunk(1.0 + k / 100, d, data))
    session.close(2.0)
    assert len(view.written) == 1 and len(seen) == 4
    text = err.getvalue()
    assert text.count("xac1 proxy: standard output went away") == 1
    assert "summary: 2 host frames, 2 device frames" in text


def test_proxy_errors_start_with_the_command(tmp_path: Path, capsys) -> None:
    """Every error of ``xac1 proxy`` starts ``xac1 proxy:``, as every other command's do (was
    ``error:``)."""
    assert main(["proxy", "--device", "x", "--tcp", "0", "--link", str(tmp_path / "l")]) == 2
    assert capsys.readouterr().err.startswith("xac1 proxy: error: --link goes with --pty")
    assert main(["proxy", "--device", str(tmp_path / "nope"), "--tcp", "127.0.0.1:0"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("xac1 proxy: error: ") and "nope" in err
    assert main(["proxy", "--device", "x", "--tcp", "0", "--timeout", "0"]) == 2
    assert capsys.readouterr().err.startswith("xac1 proxy: error: --timeout")


def _read_line(stream, pattern: str, timeout: float = 20.0) -> str:
    deadline = time.monotonic() + timeout
    seen = []
    while time.monotonic() < deadline:
        line = stream.readline()
        if not line:
            break
        seen.append(line)
        if re.search(pattern, line):
            return line
    raise AssertionError(f"no line matching {pattern!r}; saw: {''.join(seen)[-2000:]}")


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_proxy_piped_to_a_reader_that_dies_still_records_reports_and_summarises(tmp_path: Path, sig) -> None:
    """``xac1 proxy ... | tee``, and the signal that ends both: the reader of its standard output goes
    away first, then the proxy gets the signal. The recording holds every byte, the report is written,
    the summary is on stderr, no traceback, and the exit status is the signal's (0: ended in order)
    (was: exit 1, no summary, no report)."""
    rec, link, report = tmp_path / "p.jsonl", tmp_path / "xac1.tty", tmp_path / "r.html"
    with serve_pty(SimConfig(time_scale=0)) as sim:
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "proxy", "--device", sim.path, "--pty",
                                 "--link", str(link), "--format", "jsonl", "--record", str(rec),
                                 "--report", str(report)], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
        try:
            assert proc.stderr is not None and proc.stdout is not None
            _read_line(proc.stderr, "Ctrl-C to stop")
            with Client(str(link)) as client:
                client.read_version()
            assert json.loads(proc.stdout.readline())["header"] == "0RV"  # printing works
            proc.stdout.close()  # tee ended by the terminal's Ctrl-C
            with Client(str(link)) as client:
                client.read_outputs()  # the next record meets the closed pipe
            _read_line(proc.stderr, "standard output went away")
            proc.send_signal(sig)
            rest = proc.stderr.read()
            code = proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert code == 0, rest
    assert "Traceback" not in rest and "Exception ignored" not in rest, rest
    assert f"xac1 proxy: {signal.Signals(sig).name}: stopping: the summary follows" in rest
    assert "summary: 2 host frames, 2 device frames" in rest
    assert f"report written to {report}" in rest and report.stat().st_size > 0
    chunks = list(read_recording(rec.read_text().splitlines()))
    assert b"".join(c.data for c in chunks if c.dir == "host") == b"0RV\r\n0RS\r\n"
    wait_until(lambda: not link.exists(), 5, "the link removed")
    assert not os.path.lexists(link)
