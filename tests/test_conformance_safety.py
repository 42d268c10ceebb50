"""The suite leaves a real device as it found it: it writes only points it can write back (unless told
otherwise), puts the axis back, and a device that never answers ends the run at once with a clear verdict.

The device here is never the in-process ``xac1sim://``: it is ``xac1 sim --tcp`` in a subprocess with a
state file (points written before the run), or the simulator served over TCP by ``serve_tcp``, or a
plain listening socket that never answers.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import conformance, read_table

from xac1_proto import spec
from xac1_proto.client import Client
from xac1_proto.dut.evidence import Probe
from xac1_proto.dut.settings import SettingsError, parse_points
from xac1_proto.exchange import Exchange
from xac1_proto.frames import ReadVersion
from xac1_proto.recording import read_recording
from xac1_proto.sim import DeviceModel, SimConfig, serve_tcp
from xac1_proto.sim.model import PointData

# Points holding data before the run (the state file): the only ones the suite may write back.
HELD = {3: (5, 2, 1, 0x400), 7: (9, 3, 0, 0x800)}
MOTION = ["--allow-motion", "--safe-range", "0:0x1000"]


@pytest.fixture
def sim_process(tmp_path: Path) -> Iterator[tuple[str, Path, Path]]:
    """`xac1 sim --tcp` with a state file holding HELD and a traffic log: (url, state file, log)."""
    state, log = tmp_path / "state.json", tmp_path / "traffic.jsonl"
    points = {f"{n:X}": dict(zip(("v", "a", "o", "pos"), d, strict=True)) for n, d in HELD.items()}
    state.write_text(json.dumps({"format": "xac1sim-state", "version": 1, "points": points}))
    command = [sys.executable, "-m", "xac1_proto", "sim", "--tcp", "127.0.0.1:0", "--time-scale", "0",
               "--state", str(state), "--log", str(log)]
    proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("socket://"), url
        yield url, state, log
    finally:
        proc.stdin.close()
        proc.terminate()
        proc.wait(timeout=10)
        proc.stdout.close()


def written_points(log: Path) -> set[int]:
    """N of every 0WP and 0WC the host sent for a stored point (1-F), from the simulator's traffic log (the
    malformed 0WC 0 probe names no stored point)."""
    with log.open() as f:
        host = b"".join(c.data for c in read_recording(f) if c.dir == "host")
    heads = {h.encode() for h in ("0WP", "0WC")}
    at = spec.HEADER_WIDTH
    found = {int(line[at:at + 1], 16) for line in host.split(b"\n") if line[:at] in heads and len(line) > at}
    return found - {0}


@pytest.mark.slow
def test_writes_only_points_it_can_restore(sim_process, tmp_path):
    """On a real device (not xac1sim://) the suite writes only points that held data, restores them
    exactly, leaves never-written points never written (docs/protocol.md silent item 6), and skips the checks
    that need a third point with a reason naming the option to pass, in the terminal and the report."""
    url, state, log = sim_process
    before = read_table(url)
    report = tmp_path / "r.md"
    r = conformance(["--port", url, *MOTION, "--examples", "5", "--report", str(report)], tmp_path)
    after = read_table(url)
    assert r.returncode == 4, r.stdout[-4000:]  # INCOMPLETE: the checks that need more points did not run
    last = r.stdout.splitlines()[-1]
    assert "INCOMPLETE: 4 of 97 checks not run; to run them: --fresh, --scratch-points 1,2" in last, last
    assert after == before
    assert {n for n, (v, a, _o, _p) in after.points.items() if v and a} == set(HELD)
    assert written_points(log) == set(HELD)  # and nothing else was ever written, even for a moment
    text = report.read_text()
    for where in (r.stdout, text):
        assert "needs 3 points the suite may overwrite" in where
        assert "--scratch-points 1" in where
    assert "| store_current | needs 3 points" in text and "**Verdict: INCOMPLETE: 4 of 97" in text
    assert "point 3 restored" in text and "point 7 restored" in text
    saved = json.loads(state.read_text())["points"]
    assert {int(k, 16): (p["v"], p["a"], p["o"], p["pos"]) for k, p in saved.items()} == HELD


@pytest.mark.slow
def test_scratch_points_lets_the_checks_run(sim_process, tmp_path):
    """With --scratch-points the named points are used first, so the checks that need more points run;
    points that held data are still restored and the report names the never-written ones it changed."""
    url, _state, log = sim_process
    before = read_table(url)
    report = tmp_path / "r.md"
    r = conformance(["--port", url, *MOTION, "--scratch-points", "1,2", "--report", str(report),
                     "-k", "store_current or point_move_carries_n or read_back", "--allow-incomplete"],
                    tmp_path)
    after = read_table(url)
    assert r.returncode == 0, r.stdout[-4000:]  # only -k left checks out: deliberately partial
    last = r.stdout.splitlines()[-1]
    assert "INCOMPLETE: 88 of 98 checks not run; to run them: no -k (10 passed, 0 failed" in last, last
    text = report.read_text()
    assert "| store_current |" in text and "| point_move_carries_n |" in text and "SKIP" not in text
    assert written_points(log) <= {1, 2, *HELD} and {1, 2} <= written_points(log)
    assert {n: after.points[n] for n in HELD} == {n: before.points[n] for n in HELD}
    assert all(after.points[n] == before.points[n] for n in range(4, 16) if n != 7)
    assert "point 1 was never written before the run" in text


def test_scratch_points_option_errors():
    """--xac1-scratch-points takes hex point numbers 1-F separated by commas."""
    assert parse_points("1,2,F") == (1, 2, 15)
    assert parse_points("a, 3,a") == (10, 3)
    for bad in ("0", "1,,2", "10", "G", ""):
        with pytest.raises(SettingsError, match="scratch-points"):
            parse_points(bad)


def _held_model() -> DeviceModel:
    return DeviceModel(SimConfig(time_scale=0), {n: PointData(*d) for n, d in HELD.items()})


@pytest.mark.slow
def test_position_restored(tmp_path):
    """An axis homed and inside the safe range at the start is moved back there at the end (0MV at a
    gentle speed) and 0RC confirms it; the report says so and that mode 1 is left on purpose."""
    start = 0x0700
    with serve_tcp(model=_held_model()) as sim:
        with Client(sim.url, timeout=2) as c:
            c.home()
            c.move_direct(0x3C, 3, start)
        report = tmp_path / "r.md"
        r = conformance(["--port", sim.url, *MOTION, "--report", str(report), "-k", "reaches_target",
                         "--allow-incomplete"], tmp_path)
        with Client(sim.url, timeout=2) as c:
            now = c.read_current().pos
    assert r.returncode == 0, r.stdout[-4000:]
    assert now == start
    text = report.read_text()
    assert f"axis moved back to its starting position 0x{start:06X}" in text
    assert "does not send 0CM0" in text and "--restore-mode0" in text


@pytest.mark.slow
def test_position_not_known_is_reported(tmp_path):
    """An axis not homed at the start (0RC answers FFFFFF) cannot be put back: the safety section says the
    position was not restored and why."""
    with serve_tcp(model=_held_model()) as sim:
        report = tmp_path / "r.md"
        r = conformance(["--port", sim.url, *MOTION, "--report", str(report), "-k", "direct_move_reaches",
                         "--allow-incomplete"], tmp_path)
    assert r.returncode == 0, r.stdout[-4000:]
    text = report.read_text()
    assert "axis position not restored: it was not known at the start (0RC answered FFFFFF" in text
    assert "axis position not restored" in r.stdout


@pytest.mark.slow
def test_restore_mode0_sends_0cm0_last(tmp_path):
    """--restore-mode0 sends 0CM0 as the run's last command: the controller ends in mode 0."""
    with serve_tcp(model=_held_model()) as sim:
        r = conformance(["--port", sim.url, "--restore-mode0", "-k", "version_format", "--allow-incomplete"],
                        tmp_path)
        with sim.lock:
            mode = sim.model.status()["mode"]
    assert r.returncode == 0, r.stdout[-4000:]
    assert mode == 0
    assert "mode set to 0 (external start) by 0CM0" in r.stdout


@pytest.fixture
def silent_port() -> Iterator[str]:
    """A TCP port that accepts connections and reads everything, but never answers."""
    srv = socket.create_server(("127.0.0.1", 0))
    srv.settimeout(0.2)
    stop = threading.Event()
    conns: list[socket.socket] = []

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            conn.settimeout(0.2)
            conns.append(conn)
        for conn in conns:
            conn.close()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield f"socket://127.0.0.1:{srv.getsockname()[1]}"
    finally:
        stop.set()
        t.join(timeout=5)
        srv.close()


@pytest.mark.slow
def test_no_answer_ends_quickly_with_a_verdict(silent_port, tmp_path):
    """A device that answers nothing ends the run after the first probes with "no answer from the device"
    (exit status 3), a summary on the terminal and the report: no list of failures, nothing written."""
    report = tmp_path / "r.html"
    r = conformance(["--port", silent_port, "--timeout", "0.2", "--report", str(report)], tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 3, out[-3000:]
    assert "NO ANSWER FROM THE DEVICE" in r.stdout.splitlines()[-1]
    assert "no answer from the device on" in r.stdout and "9600 baud" in r.stdout
    assert "FAIL" not in r.stdout and "Traceback" not in out
    page = report.read_text()
    assert "NO ANSWER FROM THE DEVICE" in page and "nothing was written" in page


def test_probe_holds_the_exchange():
    """A probe is the client's Exchange plus the suite's bookkeeping: it reads the exchange's fields."""
    ex = Exchange(sent=ReadVersion().to_bytes(), raw=b"0RV100\r\n", frame=None, violations=[], latency=0.01)
    p = Probe("t", ex)
    assert (p.sent, p.raw, p.latency, p.junk, p.errors) == (ex.sent, ex.raw, 0.01, b"", [])
    q = Probe.silence("t", ex.sent, b"0R")
    assert q.timed_out and q.raw == b"" and q.frame is None and "partial: '0R'" in q.show()
    assert Probe("t", ex) != p  # two identical exchanges are two pieces of evidence
