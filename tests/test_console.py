"""``xac1 console``: its command language, a session driven through a pty (pexpect), and stdin piped."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pexpect
import pytest
from conftest import xac1

from xac1_proto import frames as fr
from xac1_proto.console.commands import UsageError, help_text, parse_line

SIM = "xac1sim://?time_scale=0"
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x08")


def shown(text: str) -> re.Pattern[str]:
    """``text`` as the terminal shows it: the console may repaint between any two of its characters (a
    completion typed before the tab was read shows ``vers``, then ``ion``), so escape sequences may come
    between them."""
    return re.compile(f"(?:{ANSI.pattern})*".join(re.escape(c) for c in text))


@pytest.mark.parametrize(("line", "frames", "moves"), [
    ("read 3", [fr.ReadPoint(n=3)], False),
    ("read F", [fr.ReadPoint(n=15)], False),
    ("write 1 v=9 a=3 o=0 pos=0x12345", [fr.WritePoint(n=1, v=9, a=3, o=0, pos=0x12345)], False),
    ("home", [fr.MovePoint(n=0)], True),
    ("move 1", [fr.MovePoint(n=1)], True),
    ("go vel=30 a=2 pos=5000", [fr.MoveDirect(vel=30, a=2, pos=5000)], True),
    ("outputs 3", [fr.WriteOutputs(o=3)], False),
    ("outputs", [fr.ReadOutputs()], False),
    ("reset", [fr.AlarmReset()], False),
    ("version", [fr.ReadVersion()], False),
    ("mode 1", [fr.SwitchMode(mode=1)], False),
    ("store 2", [fr.StoreCurrent(n=2)], False),
    ("status", [fr.ReadCurrent(), fr.ReadOutputs()], False),
])
def test_named_commands_build_their_frames(line, frames, moves):
    """Each named command builds the frames of docs/protocol.md "Frames"; moving ones are flagged."""
    plan = parse_line(line)
    assert plan is not None and list(plan.frames) == frames and plan.moves == moves


def test_raw_frames_and_bad_lines():
    """``!FRAME`` sends bytes as typed (CR LF added unless it ends with LF); a raw move is flagged;
    bad lines say what was expected, and nothing is built."""
    assert parse_line("!0RV").raw == b"0RV\r\n"
    assert parse_line(r"!0RP3\n").raw == b"0RP3\n"
    assert parse_line("raw 0MP1").moves
    for line, expected in [("write 1 v=9", "missing a=, o=, pos="), ("read 16", "N must be 1-F"),
                           ("read", "expected N"), ("fly 3", "unknown command"), ("home 3", "no arguments"),
                           ("go vel=0 a=1 pos=0", "vel must be 01-3C"), ("read x", "must be a number")]:
        with pytest.raises(UsageError, match=expected):
            parse_line(line)
    assert "write N v=V a=A o=O pos=POS" in help_text() and "0MV" in help_text("go")


def spawn_console(*args: str) -> pexpect.spawn:
    # pexpect is no terminal emulator: it cannot answer prompt_toolkit's cursor position requests.
    env = dict(os.environ, TERM="xterm", PROMPT_TOOLKIT_NO_CPR="1")
    return pexpect.spawn(sys.executable, ["-m", "xac1_proto", "console", "--port", SIM, *args],
                         timeout=10, encoding="utf-8", dimensions=(40, 200), env=env)


@pytest.mark.slow
def test_console_session_through_a_pty():
    """A short session as a person types it: help, tab completion, point data, a refused and a
    confirmed move, an alarm with its meaning, reset, history recall, a usage error, status, quit."""
    child = spawn_console()
    seen: list[str] = []

    def step(keys: str, *expect: str, prompt: bool = True) -> None:
        child.send(keys)
        for text in expect:
            child.expect(shown(text))
            seen.append(ANSI.sub("", child.before))
        if prompt:
            child.expect(shown("xac1>"))

    try:
        child.expect_exact("xac1>")
        step("help\r", "write N v=V a=A o=O pos=POS")
        step("vers\t", "version", prompt=False)  # tab completes the only match
        step("\r", "0RV answer")
        step("write 1 v=9 a=3 o=0 pos=0x12345\r", "0WP answer N=1 V=9 A=3 O=0 Pos=0x012345")
        step("read 1\r", "< '0RP19302012345' CR LF", "ms]", "0RP answer N=1 V=9 A=3 O=0")
        step("move 1\r", "go ahead? [y/N]", prompt=False)
        step("n\r", "not sent")
        step("home\r", "go ahead? [y/N]", prompt=False)
        step("y\r", "0MP answer N=0")
        step(r"!0RP3\n" + "\r", "ALARM 01: communication error", "type reset to clear it")
        step("reset\r", "0%C answer")
        step("\x1b[A\r", "0%C answer")  # up arrow: the previous line again
        step("read 99\r", "error: read:", "field-range")
        step("status\r", "0RC answer", "0RS answer", "communication errors in a row: 0")
        child.send("quit\r")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    assert child.exitstatus == 0
    transcript = "".join(seen)
    assert "> '0MP0' CR LF" in transcript and "> '0MP1'" not in transcript  # the refused move: not sent


@pytest.mark.slow
def test_console_reads_piped_stdin():
    """Without a terminal the console reads plain lines (a script can drive it); moves still ask, and
    the answer is read from the next line; --yes skips the question."""
    r = xac1("console", "--port", SIM, stdin="version\nhome\nn\ngo vel=30 a=2 pos=5000\ny\nread 1\n",
             timeout=30)
    assert r.returncode == 0, r.stderr
    assert "0RV answer" in r.stdout and "not sent" in r.stdout
    assert "0MV answer vel=1E (30) A=2 Pos=0x001388 (5000)" in r.stdout and "0RP answer N=1" in r.stdout
    assert "0MP answer" not in r.stdout
    r = xac1("console", "--port", SIM, "--yes", stdin="home\n", timeout=30)
    assert r.returncode == 0 and "go ahead" not in r.stdout and "0MP answer N=0" in r.stdout


@pytest.mark.slow
def test_console_bad_port_is_a_clear_error():
    """A port that cannot be opened: one line naming it, exit 4, no traceback."""
    r = xac1("console", "--port", "xac1sim://?bogus=1", timeout=30)
    assert r.returncode == 4 and "cannot open" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_history_file_survives_sessions_and_ctrl_c_clears_the_line(tmp_path):
    """--history FILE keeps typed lines across sessions (up arrow recalls them); Ctrl-C at the prompt
    drops the line being typed and keeps the console running; Ctrl-D leaves with status 0."""
    history = tmp_path / "history"
    child = spawn_console("--history", str(history))
    try:
        child.expect_exact("xac1>")
        child.send("version\r")
        child.expect_exact("0RV answer")
        child.expect_exact("xac1>")
        child.send("read 2")
        child.sendintr()  # Ctrl-C: the typed line is dropped, not sent
        child.expect_exact("xac1>")
        child.send("quit\r")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    assert child.exitstatus == 0
    assert "version" in history.read_text() and "read 2" not in history.read_text()
    child = spawn_console("--history", str(history))
    try:
        child.expect_exact("xac1>")
        child.send("\x1b[A\x1b[A\r")  # up arrow twice: 'quit', then 'version' of the previous session
        child.expect_exact("0RV answer")
        child.expect_exact("xac1>")
        child.sendeof()  # Ctrl-D
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    assert child.exitstatus == 0


@pytest.mark.slow  # starts a process
def test_scripted_console_exits_4_when_its_port_goes_away():
    """A console driven from stdin whose port goes away ends at once with one line naming the port and
    exit 4: the rest of the script is not run as if it had been sent."""
    from xac1_proto.sim import SimConfig, serve_pty

    with serve_pty(SimConfig(time_scale=0)) as sim:
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "console", "--port", sim.path],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write("version\n")
        proc.stdin.flush()
        while "0RV answer" not in proc.stdout.readline():
            pass
        sim.stop()  # the device port goes away
    out, err = proc.communicate("version\nread 1\n", timeout=30)
    assert proc.returncode == 4
    assert err.startswith(f"xac1 console: port {sim.path}: ") and err.endswith("; the console ends\n")
    assert "0RP" not in out and "Traceback" not in err
