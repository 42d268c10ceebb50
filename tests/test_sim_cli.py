"""``xac1 sim`` as a user runs it: a subprocess on a pty or TCP port, control commands on stdin,
state and log files; and the state file's atomic writes under kill -9."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial
from conftest import xac1, xac1_sim

from xac1_proto.recording import read_recording
from xac1_proto.sim.model import PointData
from xac1_proto.sim.state import StateFileError, load_state, save_state

TIMEOUT = 5.0


def transact(port: serial.SerialBase, data: bytes) -> bytes:
    port.write(data)
    return port.read_until(b"\n")


def control(proc: subprocess.Popen[str], line: str) -> str:
    assert proc.stdin is not None and proc.stdout is not None
    proc.stdin.write(line + "\n")
    proc.stdin.flush()
    return proc.stdout.readline()


@pytest.mark.slow
def test_cli_pty_estop_and_log(tmp_path: Path) -> None:
    """Issue 3 "Done when": `xac1 sim --pty` prints the device path first; 0RV answers 0RV100; `estop on`
    on stdin turns the next answer into 0%%0E; --log records every byte both ways."""
    log = tmp_path / "traffic.jsonl"
    with xac1_sim("--pty", "--time-scale", "0", "--log", str(log)) as (proc, path):
        assert path.startswith("/dev/")
        with serial.Serial(path, 9600, timeout=TIMEOUT) as port:
            assert transact(port, b"0RV\r\n") == b"0RV100\r\n"
            assert "emergency stop ON" in control(proc, "estop on")
            assert transact(port, b"0RV\r\n") == b"0%%0E\r\n"
            assert transact(port, b"0%C\r\n") == b"0%%0E\r\n"
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(TIMEOUT) == 0
    chunks = list(read_recording(iter(log.read_text().splitlines())))
    host = b"".join(c.data for c in chunks if c.dir == "host")
    device = b"".join(c.data for c in chunks if c.dir == "device")
    assert host == b"0RV\r\n0RV\r\n0%C\r\n"
    assert device == b"0RV100\r\n0%%0E\r\n0%%0E\r\n"


@pytest.mark.slow
def test_cli_tcp_and_state_across_runs(tmp_path: Path) -> None:
    """--tcp serves socket:// clients; --state keeps the position table across runs (silent item 16)."""
    state = tmp_path / "table.json"
    with xac1_sim("--tcp", "0", "--time-scale", "0", "--state", str(state)) as (proc, url):
        assert url.startswith("socket://127.0.0.1:")
        with serial.serial_for_url(url, timeout=TIMEOUT) as port:
            assert transact(port, b"0WP59302012345\r\n") == b"0WP59302012345\r\n"
    assert load_state(state) == {5: PointData(9, 3, 0, 0x12345)}
    with xac1_sim("--tcp", "127.0.0.1:0", "--time-scale", "0", "--state", str(state)) as (proc, url), \
            serial.serial_for_url(url, timeout=TIMEOUT) as port:
        assert transact(port, b"0RP5\r\n") == b"0RP59302012345\r\n"


@pytest.mark.slow
@pytest.mark.parametrize("content", ["not json at all", '{"format": "something-else"}',
                                     '{"format": "xac1sim-state", "version": 1, "points": {"1": {"v": 12}}}'])
def test_cli_refuses_bad_state_file(tmp_path: Path, content: str) -> None:
    """A corrupt or foreign state file gives a clear error (exit 2, no traceback) and is left untouched."""
    state = tmp_path / "table.json"
    state.write_text(content)
    proc = xac1("sim", "--pty", "--state", str(state), timeout=30)
    assert proc.returncode == 2
    assert str(state) in proc.stderr and "Traceback" not in proc.stderr
    assert state.read_text() == content


@pytest.mark.slow
def test_cli_bad_options() -> None:
    """User errors in options are one clear line, never a traceback."""
    for args in (["--tcp", "nope"], ["--pty", "--deviation", "bogus"], ["--pty", "--version", "1.0"],
                 ["--pty", "--option", "colour=red"]):
        proc = xac1("sim", *args, timeout=30)
        assert proc.returncode == 2, args
        assert "error:" in proc.stderr and "Traceback" not in proc.stderr, args


_WRITER = """
import sys
from xac1_proto.sim.model import PointData
from xac1_proto.sim.state import save_state
path = sys.argv[1]
tables = [{n: PointData(9, 3, 1, n * 1000 + k) for n in range(1, 16)} for k in (1, 2)]
i = 0
print("ready", flush=True)
while True:
    save_state(path, tables[i % 2])
    i += 1
"""


@pytest.mark.slow
def test_state_file_survives_kill_9(tmp_path: Path) -> None:
    """Silent item 16 / issue 3: the state file is written atomically; a writer killed with kill -9 at
    any moment leaves the old or the new table, never a torn file."""
    path = tmp_path / "table.json"
    tables = [{n: PointData(9, 3, 1, n * 1000 + k) for n in range(1, 16)} for k in (1, 2)]
    save_state(path, tables[0])
    for delay in (0.01, 0.03, 0.05, 0.08, 0.13, 0.21):
        proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(path)], stdout=subprocess.PIPE,
                                text=True)
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(delay)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(TIMEOUT)
        proc.stdout.close()
        assert load_state(path) in tables
        for leftover in tmp_path.glob(".*.tmp"):  # a killed writer may leave its temporary file
            leftover.unlink()


def test_state_file_errors(tmp_path: Path) -> None:
    """load_state names the file and what is wrong; a missing file is an empty table."""
    assert load_state(tmp_path / "missing.json") == {}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "xac1sim-state", "version": 1,
                               "points": {"0": {"v": 1, "a": 1, "o": 0, "pos": 0}}}))
    with pytest.raises(StateFileError, match="point '0'"):
        load_state(bad)


@pytest.mark.slow
def test_miniterm_session() -> None:
    """Issue 3 "Done when": in pyserial's miniterm (--eol CRLF) a person types 0RV and sees 0RV100;
    `estop on` typed into the simulator turns the next answer into 0%%0E."""
    pexpect = pytest.importorskip("pexpect")
    sim = pexpect.spawn(sys.executable, ["-m", "xac1_proto", "sim", "--pty"], encoding="ascii",
                        timeout=TIMEOUT)
    term = None
    try:
        sim.expect(r"(/dev/\S+)")
        path = sim.match.group(1)
        term = pexpect.spawn(sys.executable, ["-m", "serial.tools.miniterm", "--eol", "CRLF", path, "9600"],
                             encoding="ascii", timeout=TIMEOUT)
        term.expect("Quit")
        term.send("0RV\r")
        term.expect("0RV100")
        sim.sendline("estop on")
        sim.expect("emergency stop ON")
        term.send("0RV\r")
        term.expect("0%%0E")
        term.sendcontrol("]")
        term.expect(pexpect.EOF)
        sim.sendintr()
        sim.expect(pexpect.EOF)
    finally:
        for child in (term, sim):
            if child is not None:
                child.close(force=True)
    assert sim.exitstatus == 0
