"""Replay end to end, with real parts (docs/replay.md): captures recorded by ``xac1 proxy`` from the
simulator (with and without deviations) over TCP, replayed by ``xac1 replay`` against simulators with
other deviations, and played back by ``xac1 sim --replay`` to a scripted host through ``xac1 proxy``;
motion refused without the options; the device restored after SIGINT or SIGTERM mid-replay."""

from __future__ import annotations

import contextlib
import json
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import ROOT, read_table, wait_until, xac1, xac1_sim

from xac1_proto.chunk import Chunk
from xac1_proto.client import Client
from xac1_proto.recording import RecordingWriter
from xac1_proto.sim import DeviceModel, PointData, SimConfig, serve_tcp

pytestmark = pytest.mark.slow

WAIT_S = 0.4  # the scripted host's wait for an answer
PROXY_TIMEOUT = "0.2"  # the proxies' and decodes' no-answer timeout: shorter than the host's wait

# A host session: each item is sent in one write, then the host waits for that many answer lines.
SESSION: list[tuple[bytes, int]] = [
    (b"0RV\r\n", 1),               # 0
    (b"0WP19302012345\r\n", 1),    # 1 echo
    (b"0RP1\r\n", 1),              # 2
    (b"0WS12\r\n", 1),             # 3 echo
    (b"0RS\r\n", 1),               # 4
    (b"0CM1\r\n", 1),              # 5 echo
    (b"0XX\r\n", 1),               # 6 malformed: alarm 01
    (b"0RS\r\n", 1),               # 7 alarm ignored: still 0%%01 while latched
    (b"0%C\r\n", 1),               # 8 reset
    (b"0RV\r\n", 1),               # 9
]

# A sloppy host: a letter O, lower case, two lines back to back (an overlap), line noise before a frame.
SLOPPY: list[tuple[bytes, int]] = [
    (b"ORV\r\n", 1),
    (b"0%C\r\n", 1),
    (b"0ws12\r\n", 1),
    (b"0%C\r\n", 1),
    (b"0RV\r\n0RS\r\n", 2),
    (b"\x00\xfe~0RV\r\n", 1),
    (b"0%C\r\n", 1),
    (b"0RV\r\n", 1),
]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def proxy(device_url: str, record: Path) -> Iterator[tuple[str, int]]:
    """``xac1 proxy --tcp`` in front of ``device_url``, recording to ``record``; yields the host address.
    Ended with SIGTERM (the recording is complete once it has exited)."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "proxy", "--device", device_url, "--tcp",
                             f"127.0.0.1:{port}", "--record", str(record), "--format", "jsonl",
                             "--timeout", PROXY_TIMEOUT],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert "host side on tcp" in line, line + proc.stderr.read()
        yield "127.0.0.1", port
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        finally:
            if proc.poll() is None:
                proc.kill()
            if proc.stderr is not None:
                proc.stderr.close()


def play(address: tuple[str, int], session: list[tuple[bytes, int]]) -> list[bytes]:
    """The scripted host: each item in one write, then its answers awaited (``WAIT_S`` at most)."""
    got = []
    with socket.create_connection(address, timeout=0.05) as sock:
        for data, answers in session:
            sock.sendall(data)
            received = b""
            deadline = time.monotonic() + WAIT_S
            while received.count(b"\n") < answers and time.monotonic() < deadline:
                with contextlib.suppress(TimeoutError):
                    received += sock.recv(4096)
            got.append(received)
    return got


def record(session: list[tuple[bytes, int]], path: Path, config: SimConfig) -> Path:
    """``session`` played through ``xac1 proxy`` to a simulator with ``config``, recorded to ``path``."""
    with serve_tcp(config) as sim, proxy(sim.url, path) as address:
        play(address, session)
    return path


def replay(capture: Path, port: str, *args: str) -> tuple[int, list[dict], str]:
    """``xac1 replay`` reading the capture with the proxies' no-answer timeout."""
    r = xac1("replay", str(capture), "--port", port, "--format", "jsonl", "--timeout", PROXY_TIMEOUT,
             *args, timeout=120)
    return r.returncode, [json.loads(line) for line in r.stdout.splitlines()], r.stderr


def decoded(recording: Path) -> list[dict]:
    """``xac1 decode -f jsonl`` of a recording, without times: the frames, violations and pairing."""
    r = xac1("decode", str(recording), "-f", "jsonl", "--timeout", PROXY_TIMEOUT)
    assert r.returncode in (0, 1), r.stderr
    timing = {"t", "latency_ms", "waited_ms", "details"}
    return [{k: v for k, v in json.loads(line).items() if k not in timing} for line in r.stdout.splitlines()]


@pytest.fixture(scope="module")
def captures(tmp_path_factory) -> dict[str, Path]:
    """The session recorded through the proxy from a clean simulator and from two faulty ones."""
    folder = tmp_path_factory.mktemp("captures")
    return {name: record(SESSION, folder / f"{name}.jsonl", SimConfig(time_scale=0, deviations=devs))
            for name, devs in (("clean", frozenset()), ("silent-on-malformed", {"silent-on-malformed"}),
                               ("alarm-not-latched", {"alarm-not-latched"}))}


# capture, the replaying simulator's deviations -> differences by session line (all others the same)
CASES = [
    ("clean", (), {}),
    ("clean", ("echo-differs",), {1: ["pos"], 3: ["o"], 5: ["mode"]}),
    ("clean", ("wrong-n",), {2: ["n"]}),
    ("clean", ("silent-on-malformed",), {6: ["missing"]}),
    ("clean", ("alarm-not-latched",), {7: ["answer-instead-of-alarm"]}),
    ("clean", ("lf-only",), {n: ["bytes"] for n in range(len(SESSION))}),
    ("clean", ("wrong-reset-answer",), {8: ["bytes"]}),
    ("silent-on-malformed", (), {6: ["extra"]}),
    ("alarm-not-latched", (), {7: ["alarm-instead-of-answer"]}),
]


@pytest.mark.parametrize(("capture", "deviations", "differences"), CASES,
                         ids=[f"{c}-vs-{'+'.join(d) or 'clean'}" for c, d, _ in CASES])
def test_every_difference_found_and_nothing_else(captures, capture, deviations, differences):
    """A capture recorded through the proxy, replayed against a simulator with other deviations: each
    line the deviation changes differs in exactly that way, every other line is the same; exit 0 when
    all are the same (a clean capture against the same clean simulator), else 1."""
    with serve_tcp(SimConfig(time_scale=0, deviations=frozenset(deviations))) as sim:
        status, objs, err = replay(captures[capture], sim.url, "--pace", "fast")
    rows, summary = objs[:-1], objs[-1]
    assert [r["sent"] for r in rows] == [data.decode("latin-1") for data, _ in SESSION], err
    assert {n: r["differences"] for n, r in enumerate(rows) if not r["same"]} == differences, err
    assert summary["same"] == len(SESSION) - len(differences)
    assert status == (1 if differences else 0), err


def test_sloppy_host_replayed_keeps_the_overlap_and_the_noise(tmp_path):
    """A sloppy host's capture (letter O, lower case, an overlap, line noise) replayed at its captured
    pace sends its host bytes unchanged (recorded by a proxy in front of the device) and the new
    conversation has the same host violations on the same lines as the captured one."""
    capture = record(SLOPPY, tmp_path / "sloppy.jsonl", SimConfig(time_scale=0))
    with serve_tcp(SimConfig(time_scale=0)) as sim, proxy(sim.url, tmp_path / "again.jsonl") as address:
        status, objs, err = replay(capture, f"socket://{address[0]}:{address[1]}")
    sent = b"".join(data for data, _ in SLOPPY)
    again = b"".join(bytes.fromhex(json.loads(line)["data"]) for line in
                     (tmp_path / "again.jsonl").read_text().splitlines()[1:]
                     if json.loads(line)["dir"] == "host")
    assert sent in again, err  # between the snapshot's and the restore's commands
    host_codes = {"letter-o", "lowercase-hex", "overlapping-command", "garbage"}
    captured = [r for r in decoded(capture) if r.get("dir") == "host"]
    expected = [sorted(set(r["violations"]) & host_codes) for r in captured]
    rows = objs[:-1]
    assert [sorted(set(r["violations"]) & host_codes) for r in rows] == expected
    assert ["overlapping-command"] in expected and ["garbage"] in expected and ["letter-o"] in expected
    assert status == 0, err


def test_device_side_replayed_gives_the_same_records(tmp_path):
    """A faulty device's capture played by ``xac1 sim --replay`` to the same scripted host through
    ``xac1 proxy``: the new recording decodes to the same records as the original (frames, violations,
    pairing): the host software meets the faulty device's violations again."""
    faulty = SimConfig(time_scale=0, deviations=frozenset({"echo-differs", "silent-on-malformed", "wrong-n",
                                                           "alarm-not-latched"}))
    original = record(SESSION, tmp_path / "faulty.jsonl", faulty)
    with xac1_sim("--tcp", "127.0.0.1:0", "--replay", str(original), "--replay-strict") as (sim, url), \
            proxy(url, tmp_path / "again.jsonl") as address:
        play(address, SESSION)
    first, again = decoded(original), decoded(tmp_path / "again.jsonl")
    assert again == first
    codes = {c for r in first for c in r.get("violations", [])}
    assert {"echo-mismatch", "answer-mismatch", "no-answer"} <= codes


def test_sim_replay_reports_lines_not_in_the_capture(tmp_path):
    """``xac1 sim --replay``: a line the capture does not hold next is answered by the model and said on
    stderr and in the sim's log (a note line the readers skip); the control channel's ``replay`` says
    where the replay stands."""
    original = record(SESSION[:2], tmp_path / "short.jsonl", SimConfig(time_scale=0))
    log = tmp_path / "sim.jsonl"
    with xac1_sim("--tcp", "127.0.0.1:0", "--replay", str(original), "--time-scale", "0", "--log",
                  str(log)) as (sim, url):
        port = int(url.rpartition(":")[2])
        got = play(("127.0.0.1", port), [(b"0RV\r\n", 1), (b"0RS\r\n", 1)])
        assert sim.stdin is not None and sim.stdout is not None
        sim.stdin.write("replay\n")
        sim.stdin.flush()
        where = sim.stdout.readline()
        sim.send_signal(signal.SIGTERM)
        sim.wait(10)
        err = sim.stderr.read() if sim.stderr else ""
    assert got == [b"0RV100\r\n", b"0RS02\r\n"]  # the second from the model
    assert where.startswith("replay: 1 of 2 captured host lines passed")
    assert "xac1 sim: replay: '0RS' CR LF is not in the rest of the capture: answered by the model" in err
    notes = [json.loads(line) for line in log.read_text().splitlines() if '"note"' in line]
    assert len(notes) == 1 and "'0RS' CR LF is not in the rest of the capture" in notes[0]["text"]
    r = xac1("decode", str(log))
    assert r.returncode == 0 and "problem" not in r.stderr, r.stderr


# ---- motion ----

MOVES: list[tuple[bytes, int]] = [
    (b"0MP0\r\n", 1),              # homing: the origin
    (b"0MV3C3000800\r\n", 1),      # inside 0:0x1000
    (b"0MV3C3002000\r\n", 1),      # outside
    (b"0WP19302000400\r\n", 1),
    (b"0MP1\r\n", 1),              # point 1: 0x400, inside
    (b"0RC\r\n", 1),
]


def test_motion_refused_without_the_options(tmp_path):
    """Against a device that is not the built-in simulator: no move is sent without --allow-motion and
    --safe-range (shown as skipped); with them, a move outside the range is skipped and the others go;
    --allow-motion alone is refused before anything is sent."""
    capture = record(MOVES, tmp_path / "moves.jsonl", SimConfig(time_scale=0))
    host: list[bytes] = []
    lock = threading.Lock()

    def seen(direction: str, data: bytes) -> None:
        if direction == "host":
            with lock:
                host.append(data)

    with serve_tcp(SimConfig(time_scale=0), on_traffic=seen) as sim:
        status, objs, err = replay(capture, sim.url, "--pace", "fast")
        skipped = [r["skipped"] for r in objs[:-1] if r.get("skipped")]
        assert status == 1 and len(skipped) == 4, err
        assert all("motion not allowed" in why for why in skipped)
        assert not any(b"0MP" in d or b"0MV" in d for d in host)
        assert sim.model.homed is False

        host.clear()
        status, objs, err = replay(capture, sim.url, "--pace", "fast", "--allow-motion", "--safe-range",
                                   "0:0x1000")
        rows = objs[:-1]
        assert [r.get("skipped") is not None for r in rows] == [False, False, True, False, False, False]
        assert "target 0x002000 is outside the safe range" in rows[2]["skipped"]
        sent = b"".join(host)
        assert b"0MP0\r\n" in sent and b"0MV3C3000800\r\n" in sent and b"0MP1\r\n" in sent
        assert b"0MV3C3002000" not in sent

        host.clear()
        status, objs, err = replay(capture, sim.url, "--allow-motion")
        assert status == 2 and "--allow-motion needs --safe-range" in err and host == [] and objs == []


# ---- restore after a signal ----

def slow_capture(path: Path) -> Path:
    """A capture that writes point 1 and the OUT ports, then waits long before its last lines."""
    lines = [(b"0WP15212000321\r\n", b"0WP15212000321\r\n"), (b"0WS22\r\n", b"0WS22\r\n"),
             (b"0RV\r\n", b"0RV100\r\n"), (b"0RV\r\n", b"0RV100\r\n")]
    with RecordingWriter(path, source="hand-made") as w:
        t = 1000.0
        for n, (command, answer) in enumerate(lines):
            w.write(Chunk(t, "host", command))
            w.write(Chunk(t + 0.02, "device", answer))
            t += 30.0 if n >= 1 else 0.1
    return path


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_device_restored_after_a_signal_mid_replay(tmp_path, signum):
    """A signal while the replay waits between lines ends it in order: the points and OUT ports it
    changed are written back (read back equal to before), the results so far are printed, exit 1."""
    capture = slow_capture(tmp_path / "slow.jsonl")
    points = {1: PointData(4, 2, 1, 0x123), 2: PointData(1, 1, 0, 0x10)}
    with serve_tcp(model=DeviceModel(SimConfig(time_scale=0), points)) as sim:
        with Client(sim.url, timeout=1) as c:
            c.write_outputs(1)
        before = read_table(sim.url)
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "replay", str(capture), "--port",
                                 sim.url, "-f", "jsonl"], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            wait_until(lambda: sim.model.outputs == 2, 30, "the replay's 0WS22 to reach the device")
            assert sim.model.points[1] != points[1]
            proc.send_signal(signum)
            out, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        after = read_table(sim.url)
    assert after == before, err
    summary = json.loads(out.splitlines()[-1])
    assert summary["interrupted"] == signal.Signals(signum).name and summary["restored"] is True
    assert summary["replayed"] == 2 and proc.returncode == 1, err
    assert "point 1 restored" in err and "OUT ports restored to 1" in err


@pytest.mark.requires_tool("chromium")
def test_replay_page_in_chromium(tmp_path):
    """The ``--report`` page opens in real headless Chromium with no console error and no request; its
    table holds one row per captured host line, the differing ones marked with what differs, as the
    JSON lines say."""
    from session_report_browser import Browser

    page_path = tmp_path / "replay.html"
    status, objs, err = replay(ROOT / "captures" / "recording.jsonl", "xac1sim://?time_scale=0", "--pace",
                               "fast", "--report", str(page_path))
    assert status == 1, err
    browser = Browser()
    try:
        page = browser.open(page_path)
        rows = page.evaluate("""[...document.querySelectorAll('#replay tr')].slice(1).map(
            tr => [tr.className, tr.cells[4].textContent.trim()])""")
        assert page.problems() == [] and page.requests() == []
        page.close()
    finally:
        browser.close()
    expected = [["same" if o["same"] else "different", "same" if o["same"] else ", ".join(o["differences"])]
                for o in objs[:-1]]
    assert rows == expected


def test_sim_replay_on_a_pty(tmp_path):
    """``xac1 sim --pty --replay``: host software opening the pseudo-terminal with pyserial meets the
    captured faulty device (the gallery's: the 0WP echo with another position, the bare-LF answer,
    the silent 0RV)."""
    import serial

    capture = str(ROOT / "captures" / "recording.jsonl")
    got = []
    with xac1_sim("--pty", "--replay", capture, "--time-scale", "0") as (_, path), \
            serial.Serial(path, 9600, timeout=0.5) as port:
        for line in (b"0RV\r\n", b"0RC\r\n", b"0WP19302012345\r\n", b"0RP1\r\n", b"0RV\r\n"):
            port.write(line)
            got.append(port.read_until(b"\n"))
    assert got == [b"0RV100\r\n", b"0RC00002FFFFFF\r\n", b"0WP19302012344\r\n", b"0RP19302012345\n", b""]
