"""``xac1 send`` as a user runs it (a real subprocess), against ``xac1sim://`` and a simulator on a pty."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import xac1

from xac1_proto.sim import SimConfig, serve_pty

pytestmark = pytest.mark.slow  # xac1 send as a subprocess

SIM = "xac1sim://?time_scale=0"


def send(port: str, *commands: str) -> subprocess.CompletedProcess[str]:
    return xac1("send", "--port", port, *commands, timeout=30)


def test_send_over_a_pty_prints_both_directions_decoded():
    """Each command is shown as sent and its answer as received, decoded, with the latency; CR LF is
    added to a command typed without it (docs/protocol.md "Framing")."""
    with serve_pty(SimConfig(time_scale=0)) as sim:
        r = send(sim.path, "0RV", "0WP19302012345", r"0RP1\r\n")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "> '0RV' CR LF   0RV command"
    assert lines[1].startswith("< '0RV100' CR LF   [") and lines[1].endswith(" ms]")
    assert "0WP answer N=1 V=9 A=3 O=0 Pos=0x012345 (74565)" in r.stdout
    assert "0RP answer N=1 V=9 A=3 O=0 Pos=0x012345 (74565)" in r.stdout


def test_send_alarm_exits_1_with_meaning_and_stops():
    """An alarm answer: its code and meaning, exit 1, later commands not sent (0WC before homing is
    alarm 08, docs/protocol.md silent item 4)."""
    r = send(SIM, "0WC1", "0RV")
    assert r.returncode == 1
    assert "ALARM 08: move position setting error" in r.stdout and "alarm 08" in r.stderr
    assert "'0RV'" not in r.stdout


def test_send_protocol_error_exits_2():
    """An answer that breaks the protocol: the violation code named, exit 2."""
    r = send(SIM + "&deviation=wrong-length", "0RV")
    assert r.returncode == 2 and "(bad-length)" in r.stderr and "protocol error" in r.stderr


def test_send_malformed_probe_shows_the_alarm():
    """A malformed command is sent as typed (bare LF kept) and the device's 0%%01 shown (silent item 1)."""
    r = send(SIM, r"0RP3\n")
    assert r.returncode == 1
    assert ("> '0RP3' LF   (malformed command: bad-length, bad-terminator; read as 0RP command N=3)"
            in r.stdout)
    assert "ALARM 01: communication error" in r.stdout


def test_send_timeout_exits_3():
    """Silence: a clear timeout message, exit 3."""
    r = send(SIM + "&drop=1", "--timeout", "0.1", "0RV")
    assert r.returncode == 3 and "timeout: no answer to '0RV' CR LF within" in r.stderr


def test_send_bad_port_and_bad_text_are_clear_errors():
    """User errors: one line saying what is wrong, no traceback."""
    r = send("xac1sim://?nonsense=1", "0RV")
    assert r.returncode == 4 and "cannot open" in r.stderr and "Traceback" not in r.stderr
    r = send(SIM, "0RV\u00e9")
    assert r.returncode == 5 and "ASCII" in r.stderr and "Traceback" not in r.stderr


def test_send_missing_device_is_one_clear_line():
    """A device path that does not exist: one line in the system's words, once (no ``[Errno 2]`` twice,
    no pyserial wording), exit 4."""
    r = send("/dev/nonexistent-xac1", "0RV")
    assert r.returncode == 4
    assert r.stderr == "xac1 send: cannot open /dev/nonexistent-xac1: No such file or directory\n"
    assert r.stdout == ""


def test_send_refused_tcp_port_is_one_clear_line():
    """A TCP port nobody listens on: the system's reason, once."""
    import socket

    with socket.socket() as s:  # a port that was free a moment ago
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = send(f"socket://127.0.0.1:{port}", "0RV")
    assert r.returncode == 4
    assert r.stderr == f"xac1 send: cannot open socket://127.0.0.1:{port}: Connection refused\n"


def test_send_bad_escapes_get_our_message():
    """A bad escape names itself and where it is, and lists the escapes there are (not Python's codec
    message); exit 5 (bad input), nothing sent."""
    r = send(SIM, r"0R\xZZ")
    assert r.returncode == 5 and r.stdout == ""
    assert r.stderr == ("xac1 send: bad escape \\xZZ at character 3 of 0R\\xZZ "
                        "(escapes: \\r \\n \\xNN, \\\\ for a backslash)\n")
    r = send(SIM, "0RV", r"0R\q")
    assert r.returncode == 5 and r.stdout == "" and "bad escape \\q at character 3" in r.stderr


def test_send_without_a_command_exits_5_as_documented():
    """No command given is bad input: exit 5, as docs/commands.md says (not argparse's 2, which would read
    as "protocol error")."""
    r = send(SIM)
    assert r.returncode == 5
    assert r.stderr == "xac1 send: no command given; e.g. xac1 send --port URL 0RV 0RP3\n"
    r = subprocess.run([sys.executable, "-m", "xac1_proto", "send", "0RV"], capture_output=True, text=True,
                       timeout=30)
    assert r.returncode == 5 and "--port" in r.stderr and "Traceback" not in r.stderr


def test_escapes_build_the_bytes_meant():
    """``\\r \\n \\xNN \\\\`` give the bytes they name; CR LF is added unless the text ends with LF."""
    from xac1_proto.console.show import command_bytes

    assert command_bytes("0RV") == b"0RV\r\n"
    assert command_bytes(r"0RP3\r\n") == b"0RP3\r\n"
    assert command_bytes(r"0R\x50\x33\n") == b"0RP3\n"
    assert command_bytes(r"0\\") == b"0\\\r\n"
