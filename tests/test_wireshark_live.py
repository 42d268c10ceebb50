"""Wireshark, live: sloppy-host sessions recorded as pcapng by ``xac1 proxy`` and ``xac1 sim`` (real
processes, the simulator on a real pty or TCP port), opened by tshark through a profile made by
``xac1 wireshark install``; a proxy killed with kill -9; the extcap driven the way Wireshark drives it."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import wait_until
from wireshark_tshark import PLUGIN, assert_frames_match, dissect, dissected_verdicts, tshark, verdicts_of

from xac1_proto.sim import SimConfig, serve_pty, serve_tcp

pytestmark = [pytest.mark.slow, pytest.mark.requires_tool("tshark")]  # proxy, simulator, tshark

WAIT_S = 20.0

# The host's side of the session: a letter O, a command after the alarm answer without a reset (the
# simulator keeps answering the latched alarm), then a reset, lower-case hex, a reset and a clean read.
SLOPPY_HOST = (b"0RV\r\n", b"ORP1\r\n", b"0RS\r\n", b"0%C\r\n", b"0WP1930200abcd\r\n", b"0%C\r\n",
               b"0RP1\r\n")


def xac1(*args: str, env: dict[str, str] | None = None, **kw) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "xac1_proto", *args], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, **kw)


def wait_line(stream, pattern: str, seen: list[str]) -> re.Match[str]:
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        line = stream.readline()
        if not line:
            break
        seen.append(line)
        m = re.search(pattern, line)
        if m:
            return m
    raise AssertionError(f"no {pattern!r} in {seen}")


def connect(port: int) -> socket.socket:
    """A connection to ``port`` once something listens there."""
    def connected() -> socket.socket | None:
        try:
            return socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
        except OSError:
            return None

    return wait_until(connected, WAIT_S, f"a listener on 127.0.0.1:{port}", interval=0.05)


def records_until(stream, last: bytes, seen: list[dict]) -> list[dict]:
    """JSON lines records read from a live ``--format jsonl`` view until the device frame ``last`` (the
    answer the host just got): from then on the proxy has recorded and shown every byte before it."""
    while True:
        line = stream.readline()
        assert line, f"the view ended before {last!r}: {seen}"
        seen.append(json.loads(line))
        if seen[-1].get("dir") == "device" and bytes.fromhex(seen[-1].get("raw", "")) == last:
            return seen


def talk(sock: socket.socket, commands: tuple[bytes, ...] = SLOPPY_HOST) -> list[bytes]:
    """Send each command and wait for its answer line."""
    answers = []
    for command in commands:
        sock.sendall(command)
        buf = b""
        while not buf.endswith(b"\n"):
            data = sock.recv(64)
            assert data, f"connection closed after {answers}"
            buf += data
        answers.append(buf)
    return answers


def open_files(pid: int) -> set[str]:
    """Paths a process holds open (Linux /proc)."""
    out = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        with contextlib.suppress(OSError):  # closed meanwhile
            out.add(os.readlink(fd))
    return out


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def profile_env(tmp_path) -> dict[str, str]:
    """A Wireshark configuration made by ``xac1 wireshark install`` in temporary folders."""
    home = tmp_path / "home"
    home.mkdir()
    env = {**os.environ, "HOME": str(home), "WIRESHARK_CONFIG_DIR": str(tmp_path / "wscfg")}
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "wireshark", "install"], capture_output=True,
                          text=True, timeout=60, env=env)
    assert done.returncode == 0, done.stderr
    return env


def proxied_session(rec: Path, config: SimConfig) -> tuple[str, list[bytes], list[dict]]:
    """The sloppy host through ``xac1 proxy --record REC`` to a simulator on a pty, ended by SIGINT: the
    device's path, the answers the host got, and the records the live view showed (the summary last)."""
    with serve_pty(config) as sim:
        proxy = xac1("proxy", "--device", sim.path, "--tcp", "127.0.0.1:0", "--format", "jsonl",
                     "--record", str(rec))
        try:
            port = int(wait_line(proxy.stderr, r"tcp 127\.0\.0\.1:(\d+)", []).group(1))
            with connect(port) as sock:
                answers = talk(sock)
            live = records_until(proxy.stdout, answers[-1], [])
            proxy.send_signal(signal.SIGINT)
            out = proxy.stdout.read()  # the rest (not communicate: it would skip the text buffer)
            err = proxy.stderr.read()
            proxy.wait(WAIT_S)
        finally:
            proxy.kill()
    assert proxy.returncode == 0 and "Traceback" not in err, err
    live += [json.loads(line) for line in out.splitlines()]
    assert live[-1]["type"] == "summary"
    return sim.path, answers, live


def test_proxy_recording_of_a_sloppy_host_opens_in_wireshark(tmp_path, profile_env):
    """Done when: ``xac1 proxy --record s.pcapng`` of a sloppy host opens in tshark after one
    ``xac1 wireshark install``, every frame decoded as our decoder decodes it, every deviation the live
    view reported there and filterable (``xac1.violation == "alarm-ignored"``)."""
    rec = tmp_path / "s.pcapng"
    device, answers, live = proxied_session(rec, SimConfig(time_scale=0))
    assert answers[1] == b"0%%01\r\n" and answers[3] == b"0%C00\r\n"
    rows = dissect(rec, plugin=False, decode_as=False, env=profile_env)  # the installed profile only
    assert dissected_verdicts(rows) == verdicts_of(live[:-1])
    assert {"letter-o", "alarm-ignored", "lowercase-hex"} <= {c for _, c, _ in dissected_verdicts(rows)}
    assert assert_frames_match(rec, rows) == live[-1]["frames"]["host"] + live[-1]["frames"]["device"]
    done = tshark(rec, "-Y", 'xac1.violation == "alarm-ignored"', "-T", "fields", "-e", "xac1.header",
                  "-e", "xac1.side", plugin=False, decode_as=False, env=profile_env)
    assert done.stdout.split() == ["0RS", "host"], done.stderr
    comment = subprocess.run(["capinfos", str(rec)], capture_output=True, text=True, timeout=60).stdout
    assert f"xac1 proxy --device {device} --tcp 127.0.0.1:0 (baud 9600" in comment


def test_proxy_recording_has_one_packet_per_answer_read_in_pieces(tmp_path):
    """A controller that sends its answers at 9600 baud (the simulator with wire timing): the proxy reads
    each as it comes (its first byte, then the rest), and its pcapng has one packet per answer, never a
    "(part of a frame" packet, with the pieces' times in a comment (issue 40 item 6: each answer was two
    packets in Wireshark's list). tshark shows every answer whole; the decoder reads the recording as
    the live view read the pieces."""
    rec = tmp_path / "w.pcapng"
    _, answers, live = proxied_session(rec, SimConfig(time_scale=0, wire_timing=True))
    done = tshark(rec)  # the packet list, Info column last
    assert done.returncode == 0, done.stderr
    device = [line for line in done.stdout.splitlines() if "device > " in line]
    assert len(device) == len(answers) and not [line for line in device if "part of a frame" in line], \
        done.stdout
    pieces = [c for row in dissect(rec) for c in row["frame.comment"] if c.startswith("xac1 arrived in ")]
    assert len(pieces) >= len(answers) - 1, done.stdout  # (a read may take a whole answer at once)
    decoded = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(rec), "--format", "jsonl"],
                             capture_output=True, text=True, timeout=60)
    back = [json.loads(line) for line in decoded.stdout.splitlines()][:-1]
    timeless = ("t", "latency_ms")  # the recording keeps microseconds: compared apart, to a microsecond
    assert [{k: v for k, v in r.items() if k not in timeless} for r in back] == [
        {k: v for k, v in r.items() if k not in timeless} for r in live[:-1]]
    assert [r["t"] for r in back] == pytest.approx([r["t"] for r in live[:-1]], abs=2e-6)


def test_sim_log_pcapng_carries_the_verdicts(tmp_path):
    """``xac1 sim --log s.pcapng``: the simulator's own recording opens in tshark with the verdicts
    ``xac1 decode`` finds in it, and frames checked as the decoder checks them."""
    rec = tmp_path / "sim.pcapng"
    sim = xac1("sim", "--tcp", "127.0.0.1:0", "--time-scale", "0", "--log", str(rec))
    try:
        url = sim.stdout.readline().strip()
        port = int(url.rsplit(":", 1)[1])
        with connect(port) as sock:
            answers = talk(sock)
        # the simulator logs an answer just after sending it: wait until the last one is in the file
        wait_until(lambda: answers[-1] in rec.read_bytes(), WAIT_S, f"{answers[-1]!r} in {rec}")
        sim.send_signal(signal.SIGTERM)
        _, err = sim.communicate(timeout=WAIT_S)
    finally:
        sim.kill()
    assert "Traceback" not in err, err
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "decode", str(rec), "--format", "jsonl"],
                          capture_output=True, text=True, timeout=60)
    decoded = [json.loads(line) for line in done.stdout.splitlines()]
    rows = dissect(rec)
    assert dissected_verdicts(rows) == verdicts_of(decoded[:-1])
    assert {"letter-o", "alarm-ignored"} <= {c for _, c, _ in dissected_verdicts(rows)}
    assert assert_frames_match(rec, rows) == 2 * len(SLOPPY_HOST)
    info = subprocess.run(["capinfos", str(rec)], capture_output=True, text=True, timeout=60).stdout
    assert "xac1 sim --tcp 127.0.0.1:0 (time scale 0.0, wire timing off)" in info


def test_kill_9_proxy_recording_opens_up_to_its_last_packet(tmp_path):
    """A proxy killed with kill -9 leaves a pcapng tshark opens with every packet written."""
    rec = tmp_path / "k.pcapng"
    with serve_pty(SimConfig(time_scale=0)) as sim:
        proxy = xac1("proxy", "--device", sim.path, "--tcp", "127.0.0.1:0", "--record", str(rec), "--format",
                     "jsonl")
        try:
            port = int(wait_line(proxy.stderr, r"tcp 127\.0\.0\.1:(\d+)", []).group(1))
            with connect(port) as sock:
                answers = talk(sock, (b"0RV\r\n",) * 5)
                shown: list[dict] = []
                while len([r for r in shown if r["type"] == "frame"]) < 10:  # a frame is shown once
                    records_until(proxy.stdout, answers[-1], shown)          # it is recorded
                proxy.send_signal(signal.SIGKILL)
                proxy.wait(WAIT_S)
        finally:
            proxy.kill()
    rows = dissect(rec)
    headers = [h for row in rows for h in row["xac1.header"]]
    assert headers == ["0RV"] * 10


def test_extcap_driven_as_wireshark_drives_it(tmp_path, profile_env):
    """The launcher ``xac1 wireshark install`` put in the extcap folder answers Wireshark's queries
    (interfaces, dlts, config), then captures the proxy's traffic into a FIFO that tshark reads while
    the simulator talks: frames decoded and our verdicts there, live."""
    launcher = Path(profile_env["HOME"]) / ".local/lib/wireshark/extcap/xac1-extcap"

    def ask(*args: str) -> str:
        done = subprocess.run([str(launcher), *args, "--extcap-version=4.0"], capture_output=True, text=True,
                              timeout=60, env=profile_env)
        assert done.returncode == 0, done.stderr
        return done.stdout

    interfaces = ask("--extcap-interfaces")
    assert re.search(r"^extcap \{version=[\d.]+\}", interfaces, re.M)
    assert "interface {value=xac1tap}{display=XA-C1 tap" in interfaces
    assert "interface {value=xac1proxy}{display=XA-C1 proxy" in interfaces
    assert ask("--extcap-interface", "xac1proxy", "--extcap-dlts").startswith("dlt {number=250}")
    config = ask("--extcap-interface", "xac1proxy", "--extcap-config")
    assert "{call=--device}" in config and "{call=--tcp}" in config and "{required=true}" in config
    assert "{call=--host-tap}" in ask("--extcap-interface", "xac1tap", "--extcap-config")

    fifo = tmp_path / "extcap.fifo"
    os.mkfifo(fifo)
    port = free_port()
    with serve_tcp(SimConfig(time_scale=0)) as sim:
        reader = subprocess.Popen(["tshark", "-r", str(fifo), "-l", "-T", "fields", "-e", "frame.number",
                                   "-e", "xac1.header", "-e", "xac1.violation"], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, env=profile_env)
        capture = subprocess.Popen([str(launcher), "--capture", "--extcap-interface", "xac1proxy", "--fifo",
                                    str(fifo), "--device", sim.url, "--tcp", str(port)],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=profile_env)
        try:
            with connect(port) as sock:
                talk(sock)
                seen: list[str] = []
                wait_line(reader.stdout, r"\t0RS\talarm-ignored", seen)  # while the capture runs
            while sum(line.split("\t")[1:2] == ["0RP"] for line in seen) < 2:  # the last answer, shown
                wait_line(reader.stdout, r"\t0RP\t", seen)
            capture.send_signal(signal.SIGTERM)
            _, err = capture.communicate(timeout=WAIT_S)
            out = reader.stdout.read()  # the rest, after the lines wait_line took (not communicate:
            reader.wait(WAIT_S)         # it would skip what the text buffer already holds)
        finally:
            capture.kill()
            reader.kill()
    assert capture.returncode == 0 and err == "", err
    lines = seen + out.splitlines()
    headers = [line.split("\t")[1] for line in lines if line.split("\t")[1:2] != [""]]
    assert headers.count("0RV") == 2 and headers.count("0%C") == 4
    assert any(line.rstrip("\n").endswith("\tletter-o") for line in lines)


def test_extcap_tap_interface_captures_a_y_cable(tmp_path):
    """"XA-C1 tap": the two receive-only taps of a Y-cable captured into the FIFO, decoded by tshark."""
    from sniffer_wire import YCable

    from xac1_proto.client import Client

    fifo = tmp_path / "tap.fifo"
    os.mkfifo(fifo)
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path) as cable:
        reader = subprocess.Popen(["tshark", "-r", str(fifo), "-l", "-X", f"lua_script:{PLUGIN}",
                                   "-d", "rtacser.data,xac1", "-T", "fields", "-e", "xac1.header",
                                   "-e", "xac1.role"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        capture = xac1("extcap", "--capture", "--extcap-interface", "xac1tap", "--fifo", str(fifo),
                       "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"])
        try:
            taps = {os.path.realpath(p) for p in cable.tap_paths.values()}

            def taps_open() -> bool:  # the taps are open: the capture runs
                assert capture.poll() is None, capture.stderr
                return taps <= open_files(capture.pid)

            wait_until(taps_open, WAIT_S, "the extcap capture holding both taps", interval=0.05)
            with Client(cable.host_path) as client:
                client.read_version()
                client.read_outputs()
            seen: list[str] = []
            wait_line(reader.stdout, r"^0RS\tanswer", seen)  # the taps' last frame reached Wireshark
            capture.send_signal(signal.SIGTERM)
            _, err = capture.communicate(timeout=WAIT_S)
            out = "".join(seen) + reader.stdout.read()  # not communicate: it would skip the text buffer
            reader.wait(WAIT_S)
        finally:
            capture.kill()
            reader.kill()
    assert capture.returncode == 0 and err == "", err  # nothing on stderr: Wireshark would show it
    frames = [tuple(line.split("\t")) for line in out.splitlines() if line.split("\t")[0]]
    assert frames == [("0RV", "command"), ("0RV", "answer"), ("0RS", "command"), ("0RS", "answer")]


def test_extcap_capture_failure_is_said_on_stderr(tmp_path):
    """A tap that does not exist: the capture fails with the sniffer's message on stderr (which
    Wireshark shows), naming the port; missing options are named too."""
    out = tmp_path / "out.pcapng"
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "extcap", "--capture", "--extcap-interface",
                           "xac1tap", "--fifo", str(out), "--host-tap", str(tmp_path / "no-such-tty"),
                           "--device-tap", str(tmp_path / "no-such-tty-2")], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 1 and "no-such-tty" in done.stderr and "Traceback" not in done.stderr
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "extcap", "--capture", "--extcap-interface",
                           "xac1proxy", "--fifo", str(out)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "needs --device" in done.stderr
