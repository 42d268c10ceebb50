"""``xac1 proxy`` forwards every byte unchanged both ways (hypothesis over chunkings) and decodes the
exchange on the way (docs/protocol.md "Framing": answers pair first in, first out)."""

from __future__ import annotations

import contextlib
import socket
import threading
import time

import pytest
from conftest import budget
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer.analyzer import Analyzer
from sniffer.live import Clock, Session
from sniffer.proxy import Proxy, TcpHost
from xac1_proto.sim import SimConfig, serve_pty, serve_tcp

COMMANDS = [b"0RV\r\n", b"0RS\r\n", b"0WS12\r\n", b"0RP1\r\n", b"xx\r\n", b"0%C\r\n", b"ORC\r\n"]


class Collect:
    def __init__(self) -> None:
        self.records: list = []

    def write(self, record) -> None:
        self.records.append(record)

    def summary(self, summary) -> None:
        self.summary_line = summary


def _recv_until(sock: socket.socket, n_lf: int, timeout: float = 3.0) -> bytes:
    got = b""
    deadline = time.monotonic() + timeout
    while got.count(b"\n") < n_lf and time.monotonic() < deadline:
        with contextlib.suppress(TimeoutError):
            got += sock.recv(4096)
    return got


def test_proxy_forwards_byte_for_byte_and_decodes():
    """Whatever the host writes, cut anywhere, reaches the device unchanged, and the device's bytes reach
    the host unchanged; the decoded records hold exactly those bytes."""
    traffic: dict[str, bytearray] = {"host": bytearray(), "device": bytearray()}
    lock = threading.Lock()

    def on_traffic(direction: str, data: bytes) -> None:
        with lock:
            traffic[direction] += data

    with serve_pty(SimConfig(time_scale=0), on_traffic=on_traffic) as sim:
        view = Collect()
        session = Session(Analyzer(), view)
        clock = Clock()
        proxy = Proxy(TcpHost("127.0.0.1", 0), sim.path, session, clock)
        stop = threading.Event()
        thread = threading.Thread(target=proxy.run, args=(stop,), daemon=True)
        thread.start()
        sent, received = bytearray(), bytearray()
        try:
            with socket.create_connection(proxy.host.address, timeout=0.2) as sock:

                @settings(max_examples=budget(15), deadline=None,
                          suppress_health_check=[HealthCheck.function_scoped_fixture])
                @given(st.lists(st.sampled_from(COMMANDS), min_size=1, max_size=4),
                       st.lists(st.integers(1, 6), max_size=8))
                def exchange(commands, cuts):
                    data = b"".join(commands)
                    at = 0
                    for size in cuts + [len(data)]:
                        sock.sendall(data[at: at + size])
                        at += size
                        time.sleep(0.001)
                    sent.extend(data)
                    received.extend(_recv_until(sock, len(commands)))

                exchange()
        finally:
            deadline = time.monotonic() + 3
            while time.monotonic() < deadline and len(traffic["device"]) > len(received):
                time.sleep(0.02)
            stop.set()
            thread.join(5)
            session.close(clock.now())
        assert not thread.is_alive()
        assert bytes(traffic["host"]) == bytes(sent)
        assert bytes(traffic["device"]) == bytes(received)
        for d, fed in (("host", sent), ("device", received)):
            assert b"".join(r.raw for r in view.records if getattr(r, "raw", None) is not None
                            and r.dir == d) == bytes(fed)
        assert view.summary_line["frames"]["host"] > 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_device_port_swaps_while_the_host_writes():
    """With ``reconnect`` the device port goes away and comes back five times while the host keeps
    writing: each time the proxy says so, swaps the port under its lock and forwards again; closing it
    while it waits for the port stops the reader thread and leaves no port open."""
    import io

    port = _free_port()
    err = io.StringIO()
    session = Session(Analyzer(), Collect())
    clock = Clock()
    with serve_tcp(SimConfig(time_scale=0), port=port) as first:
        proxy = Proxy(TcpHost("127.0.0.1", 0), first.url, session, clock, reconnect=True, err=err)
        stop = threading.Event()
        runner = threading.Thread(target=proxy.run, args=(stop,), daemon=True)
        runner.start()
        with socket.create_connection(proxy.host.address, timeout=0.2) as sock:
            sock.sendall(b"0RV\r\n")
            assert _recv_until(sock, 1) == b"0RV100\r\n"
    for swap in range(1, 6):  # the device is gone here; the host goes on writing into the gap
        with socket.create_connection(proxy.host.address, timeout=0.2) as sock:
            sock.sendall(b"0RS\r\n")
        with serve_tcp(SimConfig(time_scale=0), port=port):
            deadline = time.monotonic() + 5
            while err.getvalue().count("back, resuming") < swap:
                assert time.monotonic() < deadline, err.getvalue()
                time.sleep(0.02)
            with socket.create_connection(proxy.host.address, timeout=0.2) as sock:
                sock.sendall(b"0RV\r\n")
                assert _recv_until(sock, 1).endswith(b"0RV100\r\n")
    # the device is gone again: close while the reader waits for it
    deadline = time.monotonic() + 5
    while err.getvalue().count("went away") < 6:
        assert time.monotonic() < deadline, err.getvalue()
        time.sleep(0.02)
    stop.set()
    runner.join(5)
    assert not runner.is_alive()
    assert [t for t in threading.enumerate() if t.name == "xac1-proxy-device"] == []  # its reader ended too
    assert proxy.device is None
    assert "Traceback" not in err.getvalue()
    session.close(clock.now())
