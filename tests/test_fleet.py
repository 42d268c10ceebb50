"""The fleet: ``xac1 conformance`` with several ports runs one child process per device at once.

Every device here is a real ``xac1 sim`` process (``--tcp`` or ``--pty``) with a state file holding
points before the run (``HELD``) and its OUT ports set through the protocol; after the fleet, the points
are read back from the state file and the OUT ports from the simulator's own ``status`` control command.
Devices that go silent or are unplugged mid-run sit behind ``Relay``, a TCP relay that counts the host's
commands (never timing), so the run is the same every time.
"""

from __future__ import annotations

import json
import os
import re
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from markupsafe import escape

from conformance.fleet import (
    CONFORMS,
    INCOMPLETE,
    INTERRUPTED,
    NOT_CONFORM,
    NOT_TESTED,
    Device,
    Target,
    fleet_status,
    gather,
    slug,
)
from xac1_proto.client import Client
from xac1_proto.recording import read_recording

pytestmark = pytest.mark.slow  # several simulators and conformance processes

# Five points hold data: enough for every check to run on a real device without --scratch-points,
# and every one of them must be back as it was after the run.
HELD = {n: (n % 60 + 1, n % 3 + 1, n % 4, 0x100 * n) for n in range(1, 6)}
OUT_BEFORE = 2
MOTION = ["--allow-motion", "--safe-range", "0:0x1000", "--fresh"]
FLEET_TIMEOUT = 180


class Sim:
    """``xac1 sim`` in a subprocess with a state file (HELD) and a traffic log."""

    def __init__(self, where: Path, name: str, *extra: str, pty: bool = False) -> None:
        self.state, self.log = where / f"{name}.state.json", where / f"{name}.log.jsonl"
        points = {f"{n:X}": dict(zip(("v", "a", "o", "pos"), d, strict=True)) for n, d in HELD.items()}
        self.state.write_text(json.dumps({"format": "xac1sim-state", "version": 1, "points": points}))
        mode = ["--pty"] if pty else ["--tcp", "127.0.0.1:0"]
        self.proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "sim", *mode, "--time-scale", "0",
                                      "--state", str(self.state), "--log", str(self.log), *extra],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     text=True)
        assert self.proc.stdout is not None and self.proc.stdin is not None
        self.url = self.proc.stdout.readline().strip()
        assert self.url, "the simulator printed no address"
        with Client(self.url, timeout=2) as c:
            c.write_outputs(OUT_BEFORE)

    @property
    def address(self) -> tuple[str, int]:
        host, _, port = self.url.removeprefix("socket://").rpartition(":")
        return host, int(port)

    def points(self) -> dict[int, tuple[int, int, int, int]]:
        saved = json.loads(self.state.read_text())["points"]
        return {int(k, 16): (p["v"], p["a"], p["o"], p["pos"]) for k, p in saved.items()}

    def outputs(self) -> int:
        """The OUT ports as the simulator holds them (its ``status`` control command, not the protocol)."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write("status\n")
        self.proc.stdin.flush()
        lines = []
        while not (line := self.proc.stdout.readline()).startswith("points:"):
            lines.append(line)
        m = re.search(r"\bOUT (\d+)", "".join(lines))
        assert m, lines
        return int(m.group(1))

    def host_bytes(self) -> bytes:
        if not self.log.exists():
            return b""
        with self.log.open() as f:
            return b"".join(c.data for c in read_recording(f) if c.dir == "host")

    def close(self) -> None:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.close()
        self.proc.terminate()
        self.proc.wait(timeout=10)
        self.proc.stdout.close()


@pytest.fixture
def sims(tmp_path: Path) -> Iterator[list[Sim]]:
    """Start simulators with ``start(name, *args, pty=...)``; all are stopped at the end."""
    started: list[Sim] = []

    def start(name: str, *extra: str, pty: bool = False) -> Sim:
        started.append(Sim(tmp_path, name, *extra, pty=pty))
        return started[-1]

    yield start  # type: ignore[misc]
    for s in started:
        s.close()


class Relay:
    """A TCP relay host <-> simulator that, from the host's command ``after`` + 1 on, either swallows
    every answer (``silent``: the device stopped answering) or closes the connection and listens no more
    (``unplug``: the cable was pulled)."""

    def __init__(self, upstream: tuple[str, int], after: int, mode: str) -> None:
        self.upstream, self.after, self.mode = upstream, after, mode
        self.commands = 0
        self._server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._server.getsockname()[1]}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._server.close()

    def _serve(self) -> None:
        self._server.settimeout(0.1)
        while not self._stop.is_set():
            try:
                host, _ = self._server.accept()
            except OSError:
                continue
            with host, socket.create_connection(self.upstream, timeout=5) as device:
                if self._pump(host, device) == "unplugged":
                    self._server.close()
                    return

    def _pump(self, host: socket.socket, device: socket.socket) -> str:
        with selectors.DefaultSelector() as sel:
            sel.register(host, selectors.EVENT_READ, "host")
            sel.register(device, selectors.EVENT_READ, "device")
            while not self._stop.is_set():
                for key, _ in sel.select(timeout=0.05):
                    data = key.fileobj.recv(4096)  # type: ignore[union-attr]
                    if not data:
                        return "closed"
                    if key.data == "host":
                        self.commands += data.count(b"\n")
                        if self.commands > self.after and self.mode == "unplug":
                            return "unplugged"
                        device.sendall(data)
                    elif self.commands <= self.after:
                        host.sendall(data)
        return "stopped"


def fleet(args: list[str], cwd: Path, timeout: float = FLEET_TIMEOUT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


def table_row(stdout: str, port: str) -> str:
    """The fleet table's row of ``port`` (rich draws it with │ between cells; a long cell wraps onto
    lines of its own, which may name the port too: the row is the line whose first cell is the port)."""
    rows = [line for line in stdout.splitlines() if line.startswith(f"│ {port} ")]
    assert len(rows) == 1, stdout[-3000:]
    return rows[0]


def assert_restored(sim: Sim) -> None:
    assert sim.points() == HELD
    assert sim.outputs() == OUT_BEFORE


@pytest.mark.slow
def test_three_devices_at_once(sims, tmp_path):
    """The issue's "Done when": three simulators (TCP, pty, and TCP with a deviation) in one command.
    Each gets its own report, JUnit file and log; the fleet table and DIR/fleet.html show two CONFORMS
    and one DOES NOT CONFORM with the failing rule; exit status 1; every device's points and OUT ports
    are as they were; the runs overlap, so the fleet takes about the time of the slowest single run."""
    tcp, pty = sims("tcp"), sims("pty", pty=True)
    bad = sims("bad", "--deviation", "wrong-reset-answer")
    alone = sims("alone", "--deviation", "wrong-reset-answer")
    t0 = time.monotonic()
    single = fleet(["--port", alone.url, *MOTION, "--report", str(tmp_path / "alone.md")], tmp_path)
    single_s = time.monotonic() - t0
    assert single.returncode == 1, single.stdout[-3000:]

    out = tmp_path / "out"
    t0 = time.monotonic()
    r = fleet(["--port", tcp.url, "--port", pty.url, "--port", bad.url, *MOTION, "--report-dir", str(out)],
              tmp_path)
    fleet_s = time.monotonic() - t0
    assert r.returncode == 1, r.stdout[-4000:] + r.stderr[-2000:]
    assert "Traceback" not in r.stdout + r.stderr
    assert r.stdout.splitlines()[-1] == ("xac1 conformance: fleet of 3: 2 CONFORMS, 1 DOES NOT CONFORM "
                                         "(exit status 1)")
    for sim, verdict in ((tcp, CONFORMS), (pty, CONFORMS), (bad, NOT_CONFORM)):
        row = table_row(r.stdout, sim.url)
        assert f" {verdict} " in row and " 100 " in row, row  # verdict and firmware
        stem = slug(sim.url)
        for suffix in (".html", ".xml", ".log"):
            assert (out / f"{stem}{suffix}").stat().st_size > 0, stem + suffix
        assert_restored(sim)
    assert "reset_clears_alarm" in table_row(r.stdout, bad.url)
    assert f"{bad.url}: FAIL reset_clears_alarm: With an alarm latched, 0%C answers 0%C00" in r.stdout
    page = (out / "fleet.html").read_text()
    assert page.count(">CONFORMS<") == 2 and page.count(">DOES NOT CONFORM<") == 1
    assert "<b>reset_clears_alarm</b>: With an alarm latched, 0%C answers 0%C00" in page
    assert f'href="{slug(bad.url)}.html"' in page
    md = (out / "fleet.md").read_text()
    assert md.count("| **CONFORMS** |") == 2 and "| **DOES NOT CONFORM** | reset_clears_alarm:" in md
    assert "DOES NOT CONFORM" in (out / f"{slug(bad.url)}.html").read_text()
    # At once: every child started before any ended, and the whole fleet about one run's time.
    durations = [float(m) for m in re.findall(r"│ ([\d.]+) s\s+│$", r.stdout, re.M)]
    assert len(durations) == 3, r.stdout[-2000:]
    assert fleet_s < sum(durations), (fleet_s, durations)
    assert fleet_s < 2.5 * single_s + 5, (fleet_s, single_s)


def _two_and_a_broken_one(sims, tmp_path: Path, mode: str) -> tuple[subprocess.CompletedProcess, Sim, Relay,
                                                                       Sim, float]:
    """A --ports file (comments, unit ids): a good device, one cut mid-run by ``mode``, another good one."""
    good, cut, other = sims("good"), sims("cut"), sims("other", pty=True)
    relay = Relay(cut.address, after=70, mode=mode)
    try:
        ports = tmp_path / "rack.txt"
        ports.write_text(f"# rack 7\n{good.url}  UNIT-A   # the good one\n\n{relay.url} UNIT-B\n"
                         f"{other.url}\n")
        t0 = time.monotonic()
        r = fleet(["--ports", str(ports), *MOTION, "--report-dir", str(tmp_path / "out")], tmp_path)
        took = time.monotonic() - t0
    finally:
        relay.close()
    assert relay.commands > 70  # it really was cut mid-run
    for sim in (good, other):
        assert f" {CONFORMS} " in table_row(r.stdout, sim.url)
        assert_restored(sim)
    assert " UNIT-A " in table_row(r.stdout, good.url)
    return r, good, relay, other, took


@pytest.mark.slow
def test_device_that_stops_answering_ends_its_own_run(sims, tmp_path):
    """A device that stops answering mid-run ends its own run (NOT TESTED, named, the child's reason in
    the table and fleet.html) while the two others go on to CONFORMS and are restored; the fleet exits
    3. Ports come from a --ports file with comments and unit ids, shown in the table."""
    r, _good, relay, _other, took = _two_and_a_broken_one(sims, tmp_path, "silent")
    assert r.returncode == 3, r.stdout[-4000:] + r.stderr[-2000:]
    assert took < 120, took
    assert "Traceback" not in r.stdout + r.stderr
    row = table_row(r.stdout, relay.url)
    assert f" {NOT_TESTED} " in row and " UNIT-B " in row and "STOPPED ANSWERING" in row
    assert r.stdout.splitlines()[-1] == ("xac1 conformance: fleet of 3: 2 CONFORMS, 1 NOT TESTED; "
                                         f"not tested: {relay.url} (exit status 3)")
    page = (tmp_path / "out" / "fleet.html").read_text()
    assert "THE DEVICE STOPPED ANSWERING" in page and "UNIT-B" in page


@pytest.mark.slow
def test_unplugged_device_ends_its_own_run(sims, tmp_path):
    """A device unplugged mid-run (its port closes) ends its own run as NOT TESTED; the others conform
    and are restored; the fleet exits 3."""
    r, _good, relay, _other, took = _two_and_a_broken_one(sims, tmp_path, "unplug")
    assert r.returncode == 3, r.stdout[-4000:] + r.stderr[-2000:]
    assert took < 120, took
    assert "Traceback" not in r.stdout + r.stderr
    row = table_row(r.stdout, relay.url)
    assert f" {NOT_TESTED} " in row and " UNIT-B " in row and "STOPPED ANSWERING" in row, row
    log = (tmp_path / "out" / f"{slug(relay.url)}.log").read_text()
    # the run ended at the port's failure: one stop, no check after it judged (no ERROR per later check)
    assert "failed while sending" in log and "ERROR " not in log, log[-3000:]
    assert r.stdout.splitlines()[-1] == ("xac1 conformance: fleet of 3: 2 CONFORMS, 1 NOT TESTED; "
                                         f"not tested: {relay.url} (exit status 3)")


@pytest.mark.slow
def test_ctrl_c_stops_every_device_and_each_restores(sims, tmp_path):
    """SIGINT to the fleet once the runs have written to the devices: it is forwarded once to each
    child, each restores its own device (points and OUT ports as before), the fleet says so and exits 2."""
    # Answers 20 ms late, so that the interrupt lands early in each run, far from the last check.
    a, b = sims("a", "--turnaround", "20"), sims("b", "--turnaround", "20", pty=True)
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "conformance", "--port", a.url, "--port",
                             b.url, *MOTION, "--report-dir", str(tmp_path / "out")], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 60
    while not all(b"0WP" in s.host_bytes() for s in (a, b)):  # both runs have written a point
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    stdout, _ = proc.communicate(timeout=90)
    assert proc.returncode == 2, stdout[-4000:]
    assert "stopping: each device finishes its restore" in stdout
    page = (tmp_path / "out" / "fleet.html").read_text()
    for sim in (a, b):
        row = table_row(stdout, sim.url)
        assert f" {INTERRUPTED} " in row
        log = (tmp_path / "out" / f"{slug(sim.url)}.log").read_text()
        assert "xac1: restoring the device's points" in log  # the child itself did the restore
        # Each child judges its own restore; the fleet never hides one it reports as failed. (Today a
        # single run interrupted while an alarm is latched can fail its restore: see the report.)
        problems = [line for line in log.splitlines() if line.startswith("safety PROBLEM")]
        if problems:
            assert str(escape(problems[0])) in page
            assert problems[0] in (tmp_path / "out" / "fleet.md").read_text()
        else:
            assert_restored(sim)
    assert stdout.splitlines()[-1] == "xac1 conformance: fleet of 2: 2 INTERRUPTED (exit status 2)"


# ---- bad input: clear errors, nothing sent ----

@pytest.fixture
def quiet_sim(sims) -> Sim:
    return sims("q")


@pytest.mark.parametrize("case", ["twice", "twice-symlink", "missing", "bad-url", "file-words", "file-empty",
                                  "file-missing-port", "report-dir", "one-report"])
def test_bad_input_stops_before_anything_is_sent(case, quiet_sim, tmp_path):
    """A port listed twice, a port that does not exist, a malformed ports file (its line named), an
    unwritable --report-dir, one --report for several ports: exit 2 with a message naming what is
    wrong, and not one byte reaches any device."""
    url = quiet_sim.url
    ports = tmp_path / "ports.txt"
    link = tmp_path / "tty-link"
    master, slave = os.openpty()
    pty_path = os.ttyname(slave)
    link.symlink_to(pty_path)
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    args, expected = {
        "twice": (["--port", url, "--port", url], f"port {url} is listed twice: --port and --port"),
        "twice-symlink": (["--port", pty_path, "--port", str(link), "--port", url],
                          f"port {link} is listed twice: --port (as {pty_path}) and --port"),
        "missing": (["--port", url, "--port", "/dev/ttyNOPE9"],
                    "port /dev/ttyNOPE9 (--port): no such device"),
        "bad-url": (["--port", url, "--port", "socket://127.0.0.1:notaport"],
                    "port socket://127.0.0.1:notaport (--port): expected HOST:PORT"),
        "file-words": (["--ports", str(ports)], f"--ports {ports} line 3: expected a port URL and optionally "
                                                f"a unit id, got 3 words"),
        "file-empty": (["--ports", str(ports)], f"--ports {ports}: the file names no port"),
        "file-missing-port": (["--port", url, "--ports", str(ports)],
                              f"port /dev/ttyNOPE7 ({ports} line 2): no such device"),
        "report-dir": (["--port", url, "--port", pty_path, "--report-dir", str(blocker / "out")],
                       f"--report-dir {blocker / 'out'}: cannot write there"),
        "one-report": (["--port", url, "--port", pty_path, "--report", str(tmp_path / "r.html")],
                       "--report names one file; with several ports use --report-dir DIR"),
    }[case]
    ports.write_text({"file-words": f"# rack\n{url}\n{pty_path} UNIT-1 extra\n",
                      "file-empty": "# nothing here\n\n",
                      "file-missing-port": f"{pty_path}\n/dev/ttyNOPE7 U2\n"}.get(case, ""))
    sent_before = quiet_sim.host_bytes()  # the setup's 0WS
    try:
        r = fleet([*args, *MOTION], tmp_path, timeout=60)
        os.set_blocking(master, False)
        try:
            on_pty = os.read(master, 4096)
        except BlockingIOError:
            on_pty = b""
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 2, r.stdout + r.stderr
    assert expected in r.stderr, r.stderr
    assert r.stdout == "" and "Traceback" not in r.stderr
    assert quiet_sim.host_bytes() == sent_before and on_pty == b""


def test_single_port_path_is_unchanged(tmp_path):
    """One --port (no --ports, no --report-dir) runs the suite in-process exactly as before: its own
    summary and verdict line, no fleet table."""
    r = fleet(["--port", "xac1sim://", "-k", "version", "--allow-incomplete"], tmp_path, timeout=60)
    assert r.returncode == 0, r.stdout[-3000:]  # -k leaves checks out: deliberately partial
    assert "xac1 conformance: testing xac1sim://" in r.stdout and "XA-C1 fleet" not in r.stdout
    assert r.stdout.splitlines()[-1].startswith("xac1 conformance: INCOMPLETE")


# ---- how a device's result is read, and the fleet's exit status ----

def _device(tmp_path: Path, output: str, status: int, junit: str | None = None) -> Device:
    path = tmp_path / "d.xml"
    path.unlink(missing_ok=True)
    if junit is not None:
        path.write_text(junit)
    d = Device(Target("socket://127.0.0.1:9", "--port"), "d", None, path, None, [])
    d.output += output.encode()
    d.status = status
    return d


def test_gather_reads_exit_status_verdict_line_and_junit(tmp_path):
    """The verdict comes from the exit status, confirmed by the verdict line (exit 1 without one is a
    crash, not a failed device); failed checks from the FAIL lines, else the JUnit file; the firmware
    from JUnit's properties, else the summary."""
    junit = ("<testsuites><testsuite><properties><property name='firmware' value='123'/></properties>"
             "<testcase name='test_crlf[0RV]'><failure message='no CR'/></testcase></testsuite></testsuites>")
    d = _device(tmp_path, "xac1 conformance: DOES NOT CONFORM: 1 failed (exit status 1)\n", 1, junit)
    gather(d, interrupted=False)
    assert (d.verdict, d.failed, d.firmware) == (NOT_CONFORM, [("crlf[0RV]", "no CR")], "123")
    crash = _device(tmp_path, "Traceback (most recent call last):\n", 1)
    gather(crash, interrupted=False)
    assert crash.verdict == NOT_TESTED and "without a verdict (exit status 1)" in crash.reason
    text = ("device 100 on x\nrun stopped: the device stopped answering: it answered 3 commands\n"
            "xac1 conformance: THE DEVICE STOPPED ANSWERING: x (exit status 3)\n")
    stopped = _device(tmp_path, text, 3)
    gather(stopped, interrupted=False)
    assert stopped.verdict == NOT_TESTED and stopped.firmware == "100"
    assert stopped.reason == ("THE DEVICE STOPPED ANSWERING: the device stopped answering: it answered 3 "
                              "commands")
    killed = _device(tmp_path, "", -9)
    gather(killed, interrupted=False)
    assert killed.verdict == NOT_TESTED and "killed by signal 9" in killed.reason


@pytest.mark.parametrize(("verdicts", "status"), [
    ([CONFORMS, CONFORMS], 0),
    ([CONFORMS, INCOMPLETE], 4),
    ([INCOMPLETE, NOT_CONFORM, CONFORMS], 1),
    ([NOT_CONFORM, NOT_TESTED, INCOMPLETE], 3),
])
def test_worst_device_wins_3_1_4_0(verdicts, status, tmp_path):
    """Exit 0 only when every device conforms; otherwise the worst in the order 3 > 1 > 4."""
    devices = []
    for v in verdicts:
        d = _device(tmp_path, "", 0)
        d.verdict = v
        devices.append(d)
    assert fleet_status(devices, interrupted=False) == status
    assert fleet_status(devices, interrupted=True) == 2


def test_every_option_but_the_fleets_own_reaches_each_device():
    """Each child gets the options as given (built from the parser, so options added later pass too),
    never the fleet's own ports and files."""
    import argparse

    from conformance import cli
    from conformance.fleet import passthrough

    p = argparse.ArgumentParser()
    cli.add_arguments(p)
    args = p.parse_args(["--port", "A", "--port", "B", "--allow-motion", "--safe-range", "0:0x1000",
                         "--fresh", "--scratch-points", "1,2", "--seed", "7", "--timeout", "0.3", "-k",
                         "crlf or echo", "-v", "--report-dir", "out", "--report-format", "md"])
    assert passthrough(args) == ["--allow-motion", "--safe-range", "0:0x1000", "--fresh", "--scratch-points",
                                 "1,2", "--seed", "7", "--timeout", "0.3", "-k", "crlf or echo", "--verbose"]
