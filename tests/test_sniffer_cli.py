"""``xac1 sniff`` and ``xac1 proxy`` run as real processes on real ptys and TCP, the simulator and the
client making the traffic: the output comes live, Ctrl-C prints the summary and closes the recording
(which decodes to the same frames), an unplugged port gives a message and keeps what was seen, with
``--reconnect`` the sniffer resumes on a replugged port, and kill -9 keeps the recording readable."""

from __future__ import annotations

import contextlib
import json
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from conftest import xac1
from sniffer_wire import ScriptedHost, YCable

from xac1_proto.client import Client
from xac1_proto.recording import read_recording
from xac1_proto.sim import SimConfig, serve_pty

pytestmark = pytest.mark.slow  # xac1 sniff and xac1 proxy as subprocesses

WAIT_S = 10.0  # an upper bound for anything to happen; never reached unless something is broken


class Cli:
    """``python -m xac1_proto ARGS`` with its stdout and stderr read line by line as they come."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", *args], stdin=subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.out: queue.Queue[str | None] = queue.Queue()
        self.err: queue.Queue[str | None] = queue.Queue()
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._threads = [threading.Thread(target=self._pump, args=(s, q), daemon=True)
                         for s, q in ((self.proc.stdout, self.out), (self.proc.stderr, self.err))]
        for t in self._threads:
            t.start()

    @staticmethod
    def _pump(stream, q: queue.Queue) -> None:
        for line in stream:
            q.put(line)
        q.put(None)

    def _next(self, q: queue.Queue, seen: list[str], what: str, deadline: float) -> str:
        try:
            line = q.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            raise AssertionError(f"nothing more on {what} after {WAIT_S} s; stderr: {self.stderr}") from None
        if line is None:
            q.put(None)
            raise AssertionError(f"{what} ended; stdout {self.stdout}, stderr {self.stderr}")
        seen.append(line)
        return line

    def wait_err(self, pattern: str) -> re.Match[str]:
        """The first coming stderr line matching ``pattern``."""
        deadline = time.monotonic() + WAIT_S
        while True:
            match = re.search(pattern, self._next(self.err, self.stderr, "stderr", deadline))
            if match:
                return match

    def records(self, n: int) -> list[dict]:
        """The next ``n`` JSON lines of stdout (as they come: the process is still running)."""
        deadline = time.monotonic() + WAIT_S
        return [json.loads(self._next(self.out, self.stdout, "stdout", deadline)) for _ in range(n)]

    def finish(self, sig: int | None = signal.SIGINT) -> int:
        """Send ``sig`` (None: wait for the exit) and return the exit code; all output read."""
        if sig is not None:
            self.proc.send_signal(sig)
        code = self.proc.wait(WAIT_S)
        for t in self._threads:
            t.join(WAIT_S)
        for q, seen in ((self.out, self.stdout), (self.err, self.stderr)):
            while (line := q.get_nowait()) is not None:
                seen.append(line)
        return code

    def all_records(self) -> list[dict]:
        return [json.loads(line) for line in self.stdout]

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(WAIT_S)
        for stream in (self.proc.stdout, self.proc.stderr):
            stream.close()

    def __enter__(self) -> Cli:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def decode(path: Path) -> list[dict]:
    """``xac1 decode FILE --format jsonl`` as the user runs it (exit 1: it found violations)."""
    done = xac1("decode", str(path), "--format", "jsonl", timeout=WAIT_S)
    assert done.returncode in (0, 1) and not done.stderr, done.stderr
    return [json.loads(line) for line in done.stdout.splitlines()]


def recorded(path: Path) -> dict[str, bytes]:
    with open(path, encoding="ascii") as f:
        chunks = list(read_recording(f, str(path)))
    return {d: b"".join(c.data for c in chunks if c.dir == d) for d in ("host", "device")}


def frames(records: list[dict]) -> list[dict]:
    return [r for r in records if r["type"] in ("frame", "junk")]


def no_traceback(cli: Cli) -> None:
    assert not any("Traceback" in line for line in cli.stderr), "".join(cli.stderr)


def test_sniff_live_jsonl_then_ctrl_c(tmp_path):
    """``xac1 sniff`` prints each exchange as it happens (JSON lines schema), Ctrl-C prints the summary
    and exits 0, and the recording decodes to the very same records (docs/protocol.md "Framing")."""
    rec = tmp_path / "line.jsonl"
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path) as cable, \
            Cli("sniff", "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"],
                "--format", "jsonl", "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        with Client(cable.host_path) as client:
            client.read_version()
            command, answer = cli.records(2)  # seen while the sniffer still runs
            assert (command["dir"], command["header"], answer["dir"], answer["header"]) == \
                ("host", "0RV", "device", "0RV")
            assert answer["reply_to"] == command["i"] and answer["latency_ms"] >= 0
            client.write_point(1, 5, 2, 1, 0x1000)
            client.read_point(1)
            client.write_outputs(2)
            assert [r["header"] for r in cli.records(6)] == ["0WP", "0WP", "0RP", "0RP", "0WS", "0WS"]
        assert cli.finish() == 0
        no_traceback(cli)
    live = cli.all_records()
    assert live[-1]["type"] == "summary"
    assert live[-1]["frames"] == {"host": 4, "device": 4} and live[-1]["violations"] == {}
    assert recorded(rec) == {d: bytes(cable.seen[d]) for d in ("host", "device")}
    replay = decode(rec)
    assert frames(replay) == frames(live)
    assert replay[-1]["frames"] == live[-1]["frames"]


def test_proxy_pty_link_live_then_ctrl_c(tmp_path):
    """``xac1 proxy --pty --link PATH``: the host opens the link, every exchange is forwarded and shown
    as it happens, a deviation is named; Ctrl-C prints the summary, exits 0 and the recording decodes to
    the same records."""
    rec, link = tmp_path / "proxy.jsonl", tmp_path / "xac1.tty"
    with serve_pty(SimConfig(time_scale=0)) as sim, \
            Cli("proxy", "--device", sim.path, "--pty", "--link", str(link), "--format", "jsonl",
                "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        assert link.is_symlink()
        with Client(str(link)) as client:
            assert client.read_version().version == "100"
            assert [r["header"] for r in cli.records(2)] == ["0RV", "0RV"]
        host = ScriptedHost(str(link))
        try:
            # lower-case hex is forwarded as it is; this simulator answers it with alarm 01
            assert host.ask(b"0WP1930200abcd\r\n") == b"0%%01\r\n"
            command, answer = cli.records(2)
        finally:
            host.close()
        assert command["violations"] == ["lowercase-hex"] and answer["reply_to"] == command["i"]
        assert cli.finish() == 0
        no_traceback(cli)
    live = cli.all_records()
    assert live[-1]["type"] == "summary" and live[-1]["violations"] == {"lowercase-hex": 1}
    assert not link.exists(), "the link is removed at the end"
    assert frames(decode(rec)) == frames(live)


def test_proxy_tcp_text_view(tmp_path):
    """``xac1 proxy --tcp 127.0.0.1:0`` names the port it took; a host on that port gets its answers, and
    the text view shows each exchange decoded with its latency and every violation with its meaning."""
    with serve_pty(SimConfig(time_scale=0)) as sim, \
            Cli("proxy", "--device", sim.path, "--tcp", "127.0.0.1:0", "--no-color") as cli:
        port = int(cli.wait_err(r"tcp 127\.0\.0\.1:(\d+)").group(1))
        with Client(f"socket://127.0.0.1:{port}") as client:
            client.read_version()
            client.transact(b"ORV\r\n")  # letter O for zero
        assert cli.finish() == 0
        no_traceback(cli)
    text = "".join(cli.stdout)
    assert re.search(r"host\s+→ 0RV\\r\\n", text)
    assert re.search(r"device\s+← 0RV100\\r\\n .*re #0\s+\d+\.\d ms", text)
    assert "letter-o: " in text and "summary" in text


def test_sniff_unplugged_tap_stops_with_a_message(tmp_path):
    """A tap that goes away stops ``xac1 sniff`` (exit 1) with a message naming the port, not a
    traceback; what was seen is kept: printed, summed up and recorded."""
    rec = tmp_path / "line.jsonl"
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path) as cable, \
            Cli("sniff", "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"],
                "--format", "jsonl", "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        host = ScriptedHost(cable.host_path)
        try:
            host.ask(b"0RV\r\n")
            cli.records(2)
            cable.unplug("device")
            message = cli.wait_err("error: ")
        finally:
            host.close()
        assert cli.finish(None) == 1
        no_traceback(cli)
    assert cable.tap_paths["device"] in message.string and "everything seen so far is kept" in message.string
    live = cli.all_records()
    assert live[-1]["type"] == "summary" and live[-1]["frames"] == {"host": 1, "device": 1}
    assert recorded(rec) == {"host": b"0RV\r\n", "device": b"0RV100\r\n"}


def test_sniff_reconnect_resumes_on_a_replugged_tap(tmp_path):
    """With ``--reconnect`` an unplugged tap is waited for; when a port comes back under the same name
    (a USB adapter replugged: the link now points at a new pty) decoding resumes there."""
    links = {d: str(tmp_path / f"{d}.tty") for d in ("host", "device")}
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path, links) as cable, \
            Cli("sniff", "--host-tap", links["host"], "--device-tap", links["device"], "--reconnect",
                "--format", "jsonl") as cli:
        cli.wait_err("Ctrl-C to stop")
        host = ScriptedHost(cable.host_path)
        try:
            host.ask(b"0RV\r\n")
            cli.records(2)
            cable.unplug("host")
            assert "waiting for it to come back" in cli.wait_err("error: ").string
            cable.replug("host")
            cli.wait_err("host tap .* back, resuming")
            host.ask(b"0RS\r\n")
            command, answer = cli.records(2)
        finally:
            host.close()
        assert (command["header"], answer["header"], answer["reply_to"]) == ("0RS", "0RS", command["i"])
        assert command["violations"] == answer["violations"] == []
        assert cli.finish() == 0
        no_traceback(cli)
    assert cli.all_records()[-1]["frames"] == {"host": 2, "device": 2}


def test_proxy_unplugged_device_port(tmp_path):
    """``xac1 proxy``: a device port that goes away gives a message and exit 1 (recording kept); with
    ``--reconnect`` the proxy waits and forwards again once the port is back under the same name."""
    dev = str(tmp_path / "device.tty")
    rec, link = tmp_path / "proxy.jsonl", str(tmp_path / "xac1.tty")
    with serve_pty(SimConfig(time_scale=0), link=dev) as sim, \
            Cli("proxy", "--device", dev, "--pty", "--format", "jsonl", "--record", str(rec)) as plain:
        path = plain.wait_err(r"pty ([^ ;]+)").group(1)
        with Client(path) as client:
            client.read_version()
        plain.records(2)
        sim.stop()  # the device port goes away
        message = plain.wait_err("error: ")
        assert plain.finish(None) == 1
        no_traceback(plain)
    assert dev in message.string and "everything seen so far is kept" in message.string
    assert recorded(rec) == {"host": b"0RV\r\n", "device": b"0RV100\r\n"}

    with contextlib.ExitStack() as stack:
        sim = stack.enter_context(serve_pty(SimConfig(time_scale=0), link=dev))
        cli = stack.enter_context(Cli("proxy", "--device", dev, "--pty", "--link", link, "--reconnect",
                                      "--format", "jsonl"))
        cli.wait_err("Ctrl-C to stop")
        with Client(link) as client:
            client.read_version()
        sim.stop()
        assert "waiting for it to come back" in cli.wait_err("error: ").string
        stack.enter_context(serve_pty(SimConfig(time_scale=0), link=dev))
        cli.wait_err("back, resuming")
        with Client(link) as client:
            assert client.read_outputs().o == 0  # a fresh device, reached through the same pty
        assert cli.finish() == 0
        no_traceback(cli)
    assert [r["header"] for r in frames(cli.all_records())] == ["0RV", "0RV", "0RS", "0RS"]


def test_kill_9_keeps_the_recording(tmp_path):
    """A sniffer killed with kill -9 while traffic flows keeps every chunk it had shown: each chunk goes
    to the recording before its records are printed, so every frame printed before the kill is in the
    recording, and the recording still decodes to those same frames."""
    rec = tmp_path / "line.jsonl"
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path) as cable, \
            Cli("sniff", "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"],
                "--format", "jsonl", "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        stop = threading.Event()

        def traffic() -> None:
            with Client(cable.host_path) as client:
                while not stop.is_set():
                    client.read_version()

        thread = threading.Thread(target=traffic, daemon=True)
        thread.start()
        try:
            shown = cli.records(10)  # five exchanges printed live; the traffic goes on
            assert cli.finish(signal.SIGKILL) == -signal.SIGKILL
        finally:
            stop.set()
            thread.join(WAIT_S)
        assert not thread.is_alive()
        seen = {d: bytes(cable.seen[d]) for d in ("host", "device")}
    kept = recorded(rec)
    for d in ("host", "device"):
        printed = b"".join(bytes.fromhex(r["raw"]) for r in shown if r["dir"] == d)
        assert printed.count(b"\n") == 5 and kept[d].startswith(printed) and seen[d].startswith(kept[d])
    assert frames(decode(rec))[:len(shown)] == shown


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_sniff_every_signal_ends_in_order(tmp_path, sig):
    """SIGINT, SIGTERM and SIGHUP all end ``xac1 sniff`` the same orderly way: one line says so, the
    summary is printed, the recording holds every byte seen, exit 0."""
    rec = tmp_path / "line.jsonl"
    with serve_pty(SimConfig(time_scale=0, wire_timing=True)) as sim, YCable(sim.path) as cable, \
            Cli("sniff", "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"],
                "--format", "jsonl", "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        host = ScriptedHost(cable.host_path)
        try:
            assert host.ask(b"0RV\r\n") == b"0RV100\r\n"
            cli.records(2)
        finally:
            host.close()
        assert cli.finish(sig) == 0
        no_traceback(cli)
    assert f"xac1 sniff: {signal.Signals(sig).name}: stopping: the summary follows\n" in cli.stderr
    live = cli.all_records()
    assert live[-1]["type"] == "summary" and live[-1]["frames"] == {"host": 1, "device": 1}
    assert recorded(rec) == {"host": b"0RV\r\n", "device": b"0RV100\r\n"}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_proxy_every_signal_ends_in_order(tmp_path, sig):
    """SIGINT, SIGTERM and SIGHUP all end ``xac1 proxy`` in order: what was forwarded is decoded and
    recorded, the summary printed, the link removed, exit 0."""
    rec, link = tmp_path / "proxy.jsonl", tmp_path / "xac1.tty"
    with serve_pty(SimConfig(time_scale=0)) as sim, \
            Cli("proxy", "--device", sim.path, "--pty", "--link", str(link), "--format", "jsonl",
                "--record", str(rec)) as cli:
        cli.wait_err("Ctrl-C to stop")
        with Client(str(link)) as client:
            client.read_version()
            client.read_outputs()
        assert cli.finish(sig) == 0
        no_traceback(cli)
    assert f"xac1 proxy: {signal.Signals(sig).name}: stopping: the summary follows\n" in cli.stderr
    live = cli.all_records()
    assert live[-1]["type"] == "summary" and live[-1]["frames"] == {"host": 2, "device": 2}
    assert recorded(rec) == {"host": b"0RV\r\n0RS\r\n", "device": b"0RV100\r\n0RS02\r\n"}
    assert not link.exists()


def test_sniff_tap_that_is_a_directory(tmp_path):
    """``--host-tap DIRECTORY``: one clear line naming the path, exit 1, no traceback."""
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "sniff", "--host-tap", str(tmp_path),
                           "--device-tap", str(tmp_path / "nope")], capture_output=True, text=True,
                          timeout=WAIT_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 1
    assert done.stderr == f"error: host port {tmp_path}: is a directory, not a serial port\n"
    assert done.stdout == ""


SIGNAL_IN_IMPORT = """
import importlib.metadata, os, signal, sys
package, name = sys.argv[1].rsplit("/", 1)
files = (f"/{package}/{name}.", f"/{package}/__pycache__/{name}.")  # its source, or its cached bytecode
fired = []
def hook(event, args):  # the module's file being opened to import it: the signal lands in the import
    if event == "open" and any(f in str(args[0]) for f in files) and not fired:
        fired.append(1)
        os.kill(os.getpid(), signal.SIGTERM)
sys.addaudithook(hook)
(entry,) = tuple(importlib.metadata.entry_points(group="console_scripts", name="xac1"))
sys.argv = ["xac1", *sys.argv[2:]]
sys.exit(entry.load()())
"""


def test_sniff_signal_before_the_taps_are_open_ends_quietly(tmp_path):
    """A signal during start-up (here: while the session report's package is imported, before the taps
    are open) ends ``xac1 sniff`` quietly once that import is done: one line, no summary, exit 2, no
    ``RuntimeError``. (The moment used to be a ``--record`` FIFO nobody reads; that is refused now.)"""
    done = subprocess.run([sys.executable, "-c", SIGNAL_IN_IMPORT, "report/__init__", "sniff", "--host-tap",
                           "/dev/null", "--device-tap", "/dev/zero", "--report", str(tmp_path / "r.html")],
                          capture_output=True, text=True, timeout=WAIT_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 2, done.stderr
    assert done.stderr == "xac1 sniff: stopped by SIGTERM before the taps were open\n", done.stderr
    assert done.stdout == ""
