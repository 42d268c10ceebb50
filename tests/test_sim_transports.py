"""The simulator's transports (pty, TCP, xac1sim://) driven by real clients: pyserial, raw termios, socat."""

from __future__ import annotations

import contextlib
import os
import select
import socket
import subprocess
import termios
import time
from collections.abc import Iterator

import pytest
import serial
from conftest import budget
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

import xac1_proto as x
from xac1_proto import spec
from xac1_proto.sim import SimConfig, serve_pty, serve_tcp

INSTANT = SimConfig(time_scale=0)
TIMEOUT = 3.0

MALFORMED = [b"0RP3\n", b"0RP3\r\r\n", b"0RPG\r\n", b"0XX\r\n", b"0RP1 \r\n", b"0WS1\r\n",
             b"ORV\r\n", b"0rv\r\n", b"0WP0930201234\r\n", b"0MV003001000\r\n", b"0CM2\r\n", b"\n"]


def transact(port: serial.SerialBase, data: bytes) -> bytes:
    port.write(data)
    answer = port.read_until(b"\n")
    assert answer.endswith(b"\n"), f"no answer to {data!r} within {TIMEOUT}s (got {answer!r})"
    return answer


@contextlib.contextmanager
def open_sim(kind: str, config: SimConfig = INSTANT) -> Iterator[serial.SerialBase]:
    """A pyserial port on a fresh simulator over ``kind``: pty, tcp or url."""
    if kind == "url":
        port = serial.serial_for_url("xac1sim://?time_scale=0", timeout=TIMEOUT)
        try:
            yield port
        finally:
            port.close()
        return
    serve = serve_pty if kind == "pty" else serve_tcp
    with serve(config) as sim:
        port = serial.serial_for_url(sim.url, baudrate=9600, timeout=TIMEOUT)
        try:
            yield port
        finally:
            port.close()


class DeviceRules(RuleBasedStateMachine):
    """Random valid and malformed commands over a real transport; every answer is checked against the
    rules docs/protocol.md states (byte counts, echoes, latching, reset, 0RC before homing, read-back after
    write, position after moves), with a reference that knows only those rules."""

    KIND = "pty"

    def __init__(self) -> None:
        super().__init__()
        self._stack = contextlib.ExitStack()
        self.port = self._stack.enter_context(open_sim(self.KIND))
        self.points: dict[int, tuple[int, int, int, int]] = {}
        self.outputs = 0
        self.homed = False
        self.pos: int | None = None
        self.latched: int | None = None

    def teardown(self) -> None:
        self._stack.close()

    def send(self, cmd: x.Frame | bytes) -> x.Frame:
        data = cmd if isinstance(cmd, bytes) else cmd.to_bytes()
        raw = transact(self.port, data)
        answer = x.parse(raw, "answer")  # byte count, CR LF, leading 0, the 2, field ranges
        if self.latched is not None and not isinstance(cmd, x.AlarmReset):
            assert answer == x.AlarmAnswer(code=self.latched), f"{data!r}: alarm not latched: {raw!r}"
        return answer

    def ok(self) -> bool:
        return self.latched is None

    @initialize()
    def power_on(self) -> None:
        """docs/protocol.md "Behaviour the vendor text states": 0RC before homing answers N, V, A 0 and Pos
        FFFFFF."""
        a = self.send(x.ReadCurrent())
        assert (a.n, a.v, a.a, a.pos) == (0, 0, 0, spec.UNKNOWN_POSITION)

    @rule(n=st.integers(1, 15), v=st.integers(1, 9), a=st.integers(1, 3), o=st.integers(0, 3),
          pos=st.integers(0, 0xFFFFFE))
    def write_point(self, n: int, v: int, a: int, o: int, pos: int) -> None:
        cmd = x.WritePoint(n=n, v=v, a=a, o=o, pos=pos)
        answer = self.send(cmd)
        if self.ok():
            assert answer.to_bytes() == cmd.to_bytes()  # echo
            self.points[n] = (v, a, o, pos)

    @rule(n=st.integers(1, 15))
    def read_point(self, n: int) -> None:
        answer = self.send(x.ReadPoint(n=n))
        if self.ok():
            assert isinstance(answer, x.ReadPointAnswer) and answer.n == n
            if n in self.points:
                assert (answer.v, answer.a, answer.o, answer.pos) == self.points[n]

    @rule()
    def read_current(self) -> None:
        answer = self.send(x.ReadCurrent())
        if self.ok():
            assert answer.o == self.outputs
            assert answer.pos == (self.pos if self.homed else spec.UNKNOWN_POSITION)

    @precondition(lambda self: bool(self.points))
    @rule(data=st.data())
    def move_point(self, data: st.DataObject) -> None:
        n = data.draw(st.sampled_from(sorted(self.points)))
        answer = self.send(x.MovePoint(n=n))
        if self.ok():
            v, a, o, pos = self.points[n]
            assert isinstance(answer, x.MovePointAnswer) and (answer.n, answer.pos) == (n, pos)
            self.homed, self.pos = True, pos
            self.outputs = o  # silent item 8: the simulator's default

    @rule()
    def home(self) -> None:
        answer = self.send(x.MovePoint(n=0))
        if self.ok():
            assert isinstance(answer, x.MovePointAnswer) and (answer.n, answer.pos) == (0, 0)
            self.homed, self.pos = True, 0

    @rule(vel=st.integers(1, 60), a=st.integers(1, 3), pos=st.integers(0, 0xFFFFFE))
    def move_direct(self, vel: int, a: int, pos: int) -> None:
        cmd = x.MoveDirect(vel=vel, a=a, pos=pos)
        answer = self.send(cmd)
        if self.ok():
            assert answer.to_bytes() == cmd.to_bytes()
            self.homed, self.pos = True, pos

    @rule(o=st.integers(0, 3))
    def write_outputs(self, o: int) -> None:
        cmd = x.WriteOutputs(o=o)
        answer = self.send(cmd)
        if self.ok():
            assert answer.to_bytes() == cmd.to_bytes()
            self.outputs = o

    @rule()
    def read_outputs(self) -> None:
        answer = self.send(x.ReadOutputs())
        if self.ok():
            assert answer == x.ReadOutputsAnswer(o=self.outputs)

    @rule()
    def read_version(self) -> None:
        answer = self.send(x.ReadVersion())
        if self.ok():
            assert answer == x.ReadVersionAnswer(version="100")

    @rule(mode=st.integers(0, 1))
    def switch_mode(self, mode: int) -> None:
        cmd = x.SwitchMode(mode=mode)
        answer = self.send(cmd)
        if self.ok():
            assert answer.to_bytes() == cmd.to_bytes()

    @rule(line=st.sampled_from(MALFORMED))
    def malformed(self, line: bytes) -> None:
        """Silent item 1: a malformed command latches 01 and is answered 0%%01."""
        answer = self.send(line)
        if self.ok():
            assert answer == x.AlarmAnswer(code=spec.ALARM_COMM)
            self.latched = spec.ALARM_COMM

    @rule()
    def reset(self) -> None:
        """docs/protocol.md "Frames": 0%C answers 0%C00 and clears the alarm."""
        assert self.send(x.AlarmReset()) == x.AlarmResetAnswer()
        self.latched = None

    @invariant()
    def nothing_left_over(self) -> None:
        assert self.port.in_waiting == 0


class PtyRules(DeviceRules):
    KIND = "pty"


class TcpRules(DeviceRules):
    KIND = "tcp"


_MACHINE = settings(max_examples=budget(12), stateful_step_count=25, deadline=None)
TestPtyRules = _MACHINE(PtyRules).TestCase
TestTcpRules = pytest.mark.slow(_MACHINE(TcpRules).TestCase)  # seconds: every step over TCP
TestPtyRules.__doc__ = "Rule machine over the pty: " + (DeviceRules.__doc__ or "")
TestTcpRules.__doc__ = "Rule machine over TCP: " + (DeviceRules.__doc__ or "")

SCRIPT = [b"0RC\r\n", b"0RV\r\n", b"0WP19302012345\r\n", b"0RP1\r\n", b"0MP1\r\n", b"0RC\r\n",
          b"0RP3\n", b"0RV\r\n", b"0%C\r\n", b"0WS12\r\n", b"0RS\r\n", b"0MV0F3001388\r\n", b"0RC\r\n",
          b"0WC2\r\n", b"0RP2\r\n", b"0CM0\r\n", b"0MP0\r\n", b"0MP7\r\n", b"0%C\r\n", b"0RP\r\n",
          b"0%C\r\n", b"0RP", b"3\r\n"]


def run_script(port: serial.SerialBase) -> list[bytes]:
    out = []
    for chunk in SCRIPT:
        port.write(chunk)
        if chunk.endswith(b"\n"):
            out.append(port.read_until(b"\n"))
    return out


def test_same_answers_on_every_transport() -> None:
    """A pyserial program gets the same answers from xac1sim://, the pty and TCP (issue 3 "Done when")."""
    answers = {}
    for kind in ("url", "pty", "tcp"):
        with open_sim(kind) as port:
            answers[kind] = run_script(port)
    assert answers["url"] == answers["pty"] == answers["tcp"]
    assert answers["url"][1] == b"0RV100\r\n" and answers["url"][6] == b"0%%01\r\n"


def test_pty_raw_termios_client(tmp_path) -> None:
    """The pty works for a non-Python-library client: plain os.open + termios raw 9600, as C would; the
    --link symlink points at it."""
    link = tmp_path / "xac1"
    with serve_pty(INSTANT, link=link) as sim:
        assert os.path.realpath(link) == sim.path
        fd = os.open(str(link), os.O_RDWR | os.O_NOCTTY)
        try:
            attrs = termios.tcgetattr(fd)  # cfmakeraw, by hand
            attrs[0] &= ~(termios.IGNBRK | termios.BRKINT | termios.PARMRK | termios.ISTRIP | termios.INLCR
                          | termios.IGNCR | termios.ICRNL | termios.IXON)
            attrs[1] &= ~termios.OPOST
            attrs[2] = (attrs[2] & ~(termios.CSIZE | termios.PARENB | termios.CSTOPB)) | termios.CS8 \
                | termios.CREAD | termios.CLOCAL
            attrs[3] &= ~(termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN)
            attrs[4] = attrs[5] = termios.B9600
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            for cmd, want in ((b"0RV\r\n", b"0RV100\r\n"), (b"0WP39302012345\r\n", b"0WP39302012345\r\n"),
                              (b"0RP3\r\n", b"0RP39302012345\r\n")):
                os.write(fd, cmd)
                got = b""
                deadline = time.monotonic() + TIMEOUT
                while not got.endswith(b"\n") and time.monotonic() < deadline:
                    ready, _, _ = select.select([fd], [], [], 0.2)
                    if ready:
                        got += os.read(fd, 64)
                assert got == want
        finally:
            os.close(fd)
    assert not link.exists()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow  # starts a process
@pytest.mark.requires_tool("socat")
def test_socat_bridges_pty_to_tcp() -> None:
    """socat (a real third-party tool) bridges the simulator's pty to a TCP port; a socket:// client
    gets the device's answers through it."""
    with serve_pty(INSTANT) as sim:
        port = _free_port()
        proc = subprocess.Popen(["socat", f"TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr",
                                 f"FILE:{sim.path},raw,echo=0,b9600"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            client = None
            deadline = time.monotonic() + 10
            while client is None:
                try:
                    client = serial.serial_for_url(f"socket://127.0.0.1:{port}", timeout=TIMEOUT)
                except serial.SerialException:
                    if time.monotonic() > deadline or proc.poll() is not None:
                        raise
                    time.sleep(0.05)
            with client:
                assert transact(client, b"0RV\r\n") == b"0RV100\r\n"
                assert transact(client, b"0RP3\n") == b"0%%01\r\n"
        finally:
            proc.terminate()
            proc.wait(5)
            assert proc.stderr is not None
            proc.stderr.close()


def test_tcp_one_client_and_state_across_reconnections() -> None:
    """TCP: one client at a time (a second connection is closed at once); the device state survives a
    reconnection."""
    with serve_tcp(INSTANT) as sim:
        assert sim.url == f"socket://127.0.0.1:{sim.port}"
        with serial.serial_for_url(sim.url, timeout=TIMEOUT) as first:
            assert transact(first, b"0WP19302012345\r\n") == b"0WP19302012345\r\n"
            with socket.create_connection(("127.0.0.1", sim.port), timeout=TIMEOUT) as second:
                assert second.recv(16) == b""  # closed by the simulator
            assert transact(first, b"0RV\r\n") == b"0RV100\r\n"
        with serial.serial_for_url(sim.url, timeout=TIMEOUT) as again:
            assert transact(again, b"0RP1\r\n") == b"0RP19302012345\r\n"


def test_pty_reopen_keeps_state() -> None:
    """The pty can be closed and reopened; the device keeps its state like a serial line."""
    with serve_pty(INSTANT) as sim:
        with serial.Serial(sim.path, 9600, timeout=TIMEOUT) as p:
            transact(p, b"0WS32\r\n")
        with serial.Serial(sim.path, 9600, timeout=TIMEOUT) as p:
            assert transact(p, b"0RS\r\n") == b"0RS32\r\n"


def test_fault_injection_from_another_thread() -> None:
    """Emergency stop switched on a running simulator turns the next answer into 0%%0E (issue 3)."""
    with serve_tcp(INSTANT) as sim, serial.serial_for_url(sim.url, timeout=TIMEOUT) as p:
        assert transact(p, b"0RV\r\n") == b"0RV100\r\n"
        sim.call(lambda model, now: model.set_estop(True, now))
        assert transact(p, b"0RV\r\n") == b"0%%0E\r\n"


def test_url_options_and_errors() -> None:
    """xac1sim:// takes its options from the query string; unknown options are clear errors."""
    with serial.serial_for_url("xac1sim://?time_scale=0&version=102&deviation=no-2", timeout=1) as p:
        assert transact(p, b"0RV\r\n") == b"0RV102\r\n"
        assert transact(p, b"0RS\r\n") == b"0RS0\r\n"
    with pytest.raises(serial.SerialException, match="unknown simulator option 'speed'"):
        serial.serial_for_url("xac1sim://?speed=3")
    with pytest.raises(serial.SerialException, match="time_scale"):
        serial.serial_for_url("xac1sim://?time_scale=fast")


def test_url_real_time_move_discards_bytes() -> None:
    """Silent item 10 through xac1sim:// in real time: a command sent during a move gets no answer."""
    with serial.serial_for_url("xac1sim://?time_scale=0.05", timeout=TIMEOUT) as p:
        p.write(b"0MP0\r\n")
        time.sleep(0.01)
        p.write(b"0RV\r\n")
        assert p.read_until(b"\n") == b"0MP00002000000\r\n"
        p.timeout = 0.2
        assert p.read(16) == b""
