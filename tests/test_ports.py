"""``xac1 ports``: the machine's serial ports, and which answer as an XA-C1.

The protocol side is always real: ``xac1 sim`` on a pty and on TCP answers the probe's 0RV through
``Client``; a plain pty from ``os.openpty`` answers nothing; a pty locked by another program is busy.
Only USB enumeration (no USB adapter exists here) is a test double: ``serial.tools.list_ports.comports``
returns pyserial's own ``ListPortInfo`` objects filled as the Linux backend fills them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator

import pytest
import serial
from serial.tools import list_ports, list_ports_common

from xac1_proto.cli import main, ports_cmd

pytestmark = pytest.mark.slow  # simulator processes


def xac1(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "xac1_proto", *args], capture_output=True, text=True,
                          timeout=60)


@pytest.fixture
def sim_pty_and_tcp() -> Iterator[tuple[str, str]]:
    """Two ``xac1 sim`` processes: one on a pty (firmware 123), one on TCP (firmware 100)."""
    procs = [subprocess.Popen([sys.executable, "-m", "xac1_proto", "sim", *mode], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
             for mode in (["--pty", "--version", "123"], ["--tcp", "127.0.0.1:0"])]
    try:
        urls = [p.stdout.readline().strip() for p in procs]  # type: ignore[union-attr]
        yield urls[0], urls[1]
    finally:
        for p in procs:
            p.stdin.close()  # type: ignore[union-attr]
            p.terminate()
            p.wait(timeout=10)
            p.stdout.close()  # type: ignore[union-attr]


@pytest.fixture
def plain_pty() -> Iterator[tuple[str, int]]:
    """A pty nobody answers on: (slave path, master fd)."""
    master, slave = os.openpty()
    try:
        yield os.ttyname(slave), master
    finally:
        os.close(master)
        os.close(slave)


def test_probe_finds_the_simulators_and_not_a_silent_pty(sim_pty_and_tcp, plain_pty, tmp_path):
    """--probe sends 0RV (and nothing else) to each port: the simulators on a pty and on TCP answer as
    XA-C1 with their firmware, a pty that answers nothing does not, a port that does not exist says why;
    jsonl carries the same per port."""
    pty, tcp = sim_pty_and_tcp
    silent, master = plain_pty
    r = xac1("ports", "--probe", "--format", "jsonl", "--timeout", "0.3", "--port", pty, "--port", tcp,
             "--port", silent, "--port", "/dev/ttyNOPE3")
    assert r.returncode == 0, r.stderr
    rows = {row["port"]: row for row in map(json.loads, r.stdout.splitlines())}
    assert rows[pty]["probe"] == {"result": "xac1", "firmware": "123",
                                  "detail": "XA-C1, firmware 123 (version 1.23)"}
    assert rows[tcp]["probe"]["result"] == "xac1" and rows[tcp]["probe"]["firmware"] == "100"
    assert rows[silent]["probe"]["result"] == "no-answer"
    assert rows["/dev/ttyNOPE3"]["probe"]["result"] == "error"
    assert "No such file" in rows["/dev/ttyNOPE3"]["probe"]["detail"]
    assert all(rows[p]["listed"] is False for p in (pty, tcp, silent))
    assert os.read(master, 100) == b"0RV\r\n"  # the one command the probe sent to the silent pty

    text = xac1("ports", "--probe", "--timeout", "0.3", "--port", pty, "--port", silent)
    assert text.returncode == 0
    lines = text.stdout.splitlines()
    heads = ["PORT", "DEVICE", "USB", "SERIAL", "LOCATION", "DESCRIPTION", "PROBE", "(0RV)"]
    assert lines[0].split() == heads
    assert any(line.startswith(pty) and line.endswith("XA-C1, firmware 123 (version 1.23)") for line in lines)
    assert any(line.startswith(silent) and "no answer to 0RV within 0.3 s" in line for line in lines)
    assert lines[-1].startswith("1 of ") and lines[-1].endswith("port(s) answered as an XA-C1")


def test_probe_skips_a_port_another_program_holds(sim_pty_and_tcp):
    """A port another program has opened exclusively is not probed: it is reported busy."""
    pty, _ = sim_pty_and_tcp
    with serial.Serial(pty, exclusive=True):
        r = xac1("ports", "--probe", "--format", "jsonl", "--port", pty)
    row = next(row for row in map(json.loads, r.stdout.splitlines()) if row["port"] == pty)
    assert row["probe"] == {"result": "busy", "firmware": None,
                            "detail": "another program holds this port; not probed"}


def _usb(device: str, serial_number: str, location: str) -> list_ports_common.ListPortInfo:
    info = list_ports_common.ListPortInfo(device, skip_link_detection=True)
    info.vid, info.pid, info.serial_number, info.location = 0x0403, 0x6001, serial_number, location
    info.manufacturer, info.product = "FTDI", "FT232R USB UART"
    info.description = "FT232R USB UART"
    info.hwid = info.usb_info()
    return info


def test_usb_adapters_listed_with_stable_names(monkeypatch, tmp_path, capsys):
    """USB enumeration (a test double for list_ports.comports only): each adapter with its
    /dev/serial/by-id name when udev made one, VID:PID, serial number, location, description; the
    hwid pyserial's hwgrep:// matches carries the serial number."""
    dev = tmp_path / "dev"
    dev.mkdir()
    (dev / "ttyUSB0").touch()
    (dev / "ttyUSB1").touch()
    by_id = tmp_path / "by-id"
    by_id.mkdir()
    (by_id / "usb-FTDI_FT232R_USB_UART_A1B2C3-if00-port0").symlink_to(dev / "ttyUSB0")
    fakes = [_usb(str(dev / "ttyUSB1"), "Z9Y8X7", "1-1.3:1.0"),
             _usb(str(dev / "ttyUSB0"), "A1B2C3", "1-1.2:1.0")]
    monkeypatch.setattr(list_ports, "comports", lambda include_links=False: fakes)
    monkeypatch.setattr(ports_cmd, "BY_ID_DIR", by_id)
    assert main(["ports", "--format", "jsonl"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["device"] for r in rows] == [str(dev / "ttyUSB0"), str(dev / "ttyUSB1")]
    first, second = rows
    assert first["port"] == first["by_id"] == str(by_id / "usb-FTDI_FT232R_USB_UART_A1B2C3-if00-port0")
    assert (first["usb"], first["serial_number"], first["location"]) == ("0403:6001", "A1B2C3", "1-1.2:1.0")
    assert "SER=A1B2C3" in first["hwid"] and first["description"] == "FT232R USB UART"
    assert second["port"] == second["device"] and second["by_id"] is None
    assert main(["ports"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split() == [first["port"], str(dev / "ttyUSB0"), "0403:6001", "A1B2C3", "1-1.2:1.0",
                                "FT232R", "USB", "UART"]
    assert lines[2].split()[:2] == [str(dev / "ttyUSB1"), "0403:6001"]  # no by-id: the device is the name


def test_no_ports_says_how_to_add_one(monkeypatch, capsys):
    """``xac1 ports`` with no serial port says so (exit 0); a zero timeout is refused (exit 2)."""
    monkeypatch.setattr(list_ports, "comports", lambda include_links=False: [])
    assert main(["ports"]) == 0
    assert "no serial ports found" in capsys.readouterr().out
    assert main(["ports", "--timeout", "0"]) == 2


def test_probe_reports_a_port_a_client_holds_as_busy(sim_pty_and_tcp):
    """A conformance run (or any ``Client``) on a device path holds it exclusively: ``--probe`` sends
    nothing into that conversation and says the port is busy; once the client closes, it is probed."""
    from xac1_proto.client import Client

    pty, _ = sim_pty_and_tcp
    with Client(pty, timeout=1) as held:
        assert held.read_version().version == "123"
        r = xac1("ports", "--probe", "--format", "jsonl", "--port", pty)
        row = next(row for row in map(json.loads, r.stdout.splitlines()) if row["port"] == pty)
        assert row["probe"]["result"] == "busy", row
        with pytest.raises(serial.SerialException, match="exclusively lock"):
            Client(pty, timeout=1)  # a second run on the same device is refused too
        assert held.read_version().version == "123"  # the holder's conversation goes on undisturbed
    r = xac1("ports", "--probe", "--format", "jsonl", "--port", pty)
    row = next(row for row in map(json.loads, r.stdout.splitlines()) if row["port"] == pty)
    assert row["probe"]["result"] == "xac1" and row["probe"]["firmware"] == "123", row
