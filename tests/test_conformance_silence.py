"""A device that stops answering in the middle of a conformance run (cable pulled, power lost).

The device is the simulator served over TCP, reached through ``Cable``: a relay in this test that
forwards every byte from the host and the device's answers to the first N commands, then swallows every
answer (the device goes silent for good), or, with ``come_back``, starts answering again once the suite
has tried its liveness check (0%C then 0RV, both unanswered). Which answers are lost depends only on
how many commands the host sent, never on timing, so the run is the same every time.
"""

from __future__ import annotations

import re
import selectors
import socket
import threading
from collections.abc import Iterator

import pytest
from conftest import conformance, read_table

from xac1_proto.frames import AlarmReset, ReadVersion
from xac1_proto.sim import DeviceModel, SimConfig, serve_tcp
from xac1_proto.sim.model import PointData

pytestmark = pytest.mark.slow  # whole conformance runs in a subprocess

HELD = {3: (5, 2, 1, 0x400), 7: (9, 3, 0, 0x800)}  # points holding data before the run (restorable)
MOTION = ["--allow-motion", "--safe-range", "0:0x1000"]
LIVENESS = (AlarmReset().to_bytes(), ReadVersion().to_bytes())  # what the suite sends to see if it is alive


class Cable:
    """A TCP relay host <-> simulator that loses the device's answers after ``answered`` commands.

    Every host byte is forwarded. A command counts when its LF passes; from command ``answered`` + 1 on
    the device's bytes are swallowed. With ``come_back``, answers flow again from the first command
    after the host has sent the suite's liveness pair (0%C then 0RV) into the silence."""

    def __init__(self, upstream: tuple[str, int], answered: int, come_back: bool = False) -> None:
        self.upstream, self.answered, self.come_back = upstream, answered, come_back
        self.commands = 0
        self.swallowed = 0  # device bytes lost
        self.lines: list[bytes] = []  # every host line, LF included
        self.muted_lines: list[bytes] = []  # host lines whose answers were lost
        self._muted = False
        self._back_next = False
        self._server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._server.getsockname()[1]}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self) -> Cable:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._server.close()
        assert not self._thread.is_alive()

    def _host_line(self, line: bytes) -> None:
        self.commands += 1
        self.lines.append(line)
        if self._back_next:
            self._muted = self._back_next = False
        elif self.commands > self.answered and not self.muted_lines:
            self._muted = True
        if self._muted:
            self.muted_lines.append(line)
            pair = tuple(self.muted_lines[-2:])
            self._back_next = self.come_back and pair == LIVENESS

    def _serve(self) -> None:
        self._server.settimeout(0.1)
        while not self._stop.is_set():
            try:
                host, _ = self._server.accept()
            except OSError:
                continue
            with host, socket.create_connection(self.upstream, timeout=5) as device:
                self._pump(host, device)

    def _pump(self, host: socket.socket, device: socket.socket) -> None:
        pending = b""
        with selectors.DefaultSelector() as sel:
            sel.register(host, selectors.EVENT_READ, "host")
            sel.register(device, selectors.EVENT_READ, "device")
            while not self._stop.is_set():
                for key, _ in sel.select(timeout=0.05):
                    data = key.fileobj.recv(4096)  # type: ignore[union-attr]
                    if not data:
                        return
                    if key.data == "host":
                        pending += data
                        while b"\n" in pending:  # the state changes before the command reaches the device
                            line, _, pending = pending.partition(b"\n")
                            self._host_line(line + b"\n")
                        device.sendall(data)
                    elif self._muted:
                        self.swallowed += len(data)
                    else:
                        host.sendall(data)


@pytest.fixture
def device() -> Iterator[tuple[str, tuple[str, int]]]:
    """The simulator (instant motion) holding HELD, served over TCP: (url, (host, port))."""
    model = DeviceModel(SimConfig(time_scale=0), {n: PointData(*d) for n, d in HELD.items()})
    with serve_tcp(model=model) as sim:
        yield sim.url, ("127.0.0.1", sim.port)


# The simulator answers 63 commands: the snapshot, the first checks (alarm_latched[0MP] writes point 3
# and homes the axis) and the first command of alarm_latched[0WP]; its next command meets the silence.
ANSWERED = 63
STOPPED = f"the device stopped answering: it answered {ANSWERED} commands"


def test_device_stops_answering_mid_run(device, tmp_path):
    """A device that stops answering in the middle of a run (cable pulled, power lost) ends it within a
    bounded time with exit status 3 and the verdict "the device stopped answering": the summary is
    printed, the check it stopped in has no verdict (interrupted, not failed), the report lists the
    checks that did not run, and the safety section says the restore could not be done or verified,
    naming what the run changed (never "restored"). The suite stops talking after the liveness check."""
    url, address = device
    report = tmp_path / "r.md"
    with Cable(address, ANSWERED) as cable:
        r = conformance(["--port", cable.url, *MOTION, "--report", str(report)], tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 3, out[-4000:]
    assert "Traceback" not in out and "FAIL" not in r.stdout
    last = r.stdout.splitlines()[-1]
    assert last.startswith("xac1 conformance: THE DEVICE STOPPED ANSWERING: the run did not complete"), last
    assert "by rule group:" in r.stdout and "alarm latching and reset: " in r.stdout  # the summary
    assert f"run stopped: {STOPPED}" in r.stdout and "safety NOT RESTORED" in r.stdout
    # Into the silence: one check command, then the restore found nobody: only liveness checks after it.
    assert cable.muted_lines == [cable.muted_lines[0], *LIVENESS, *LIVENESS], cable.muted_lines
    text = report.read_text()
    assert "**Verdict: THE DEVICE STOPPED ANSWERING: the run did not complete" in text
    assert f"**The run stopped early:** {STOPPED}" in text
    interrupted = re.findall(r"^\| (\S+) \| interrupted: the run stopped during this check \|$", text, re.M)
    assert len(interrupted) == 1, interrupted  # the one check the silence hit (today alarm_latched[0WP])
    assert f"| {interrupted[0]} | " not in text.split("## Verdicts")[1].split("\n## ")[0]  # no verdict
    assert "| random_sequences | not run |" in text and "| reset_clears_alarm | not run |" in text
    assert "| alarm_latched[0MP] |" in text and "**PASS**" in text  # verdicts given before the silence
    safety = text.split("## Safety")[1]
    assert f"**NOT RESTORED:** the restore could not be done or verified: {STOPPED}" in safety
    assert "not verified: point 3, written during the run; it held V=5 A=2 O=1 Pos=000400 before" in safety
    assert "not verified: the axis position, moved during the run" in safety
    assert "restored to" not in safety and "unchanged" not in safety
    assert read_table(url).points[3] != HELD[3]  # and indeed: the device was left as the run left it


def test_device_comes_back_before_the_end(device, tmp_path):
    """A device that stops answering, then answers again before the run ends: the run still stops
    (exit status 3, the device stopped answering), but the restore runs when it is back and is verified
    by reading again: points the run wrote are back as they were, and the report says "restored"."""
    url, address = device
    before = read_table(url)
    report = tmp_path / "r.html"
    with Cable(address, ANSWERED, come_back=True) as cable:
        r = conformance(["--port", cable.url, *MOTION, "--report", str(report)], tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 3, out[-4000:]
    assert "Traceback" not in out and "NOT RESTORED" not in out
    assert "THE DEVICE STOPPED ANSWERING: the run did not complete" in r.stdout.splitlines()[-1]
    assert cable.muted_lines == [cable.muted_lines[0], *LIVENESS]  # back right after the liveness check
    assert read_table(url) == before
    page = report.read_text()
    assert "THE DEVICE STOPPED ANSWERING" in page and "interrupted: the run stopped during this check" in page
    safety = page.split("<h2>Safety</h2>")[1]
    assert "point 3 restored to V=5 A=2 O=1 Pos=000400" in safety and "NOT RESTORED" not in safety
    assert "PROBLEM" not in safety
