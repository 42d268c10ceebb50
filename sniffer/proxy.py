"""A forwarding proxy between host software and the controller that decodes what passes.

The host opens the proxy's pseudo-terminal (``PtyHost``) or TCP port (``TcpHost``) instead of the real
port; the proxy holds the device port (a path or any pyserial URL). Bytes are forwarded unchanged and at
once in both directions: device bytes by a reader thread that writes them to the host side, host bytes
by the main loop that writes them to the device. Each piece is queued as a ``Chunk`` just before it is
forwarded (so the queue holds causes before their effects) and the main loop hands the queue to the
``Session`` (recording, analyzer, view): decoding never delays forwarding.
"""

from __future__ import annotations

import contextlib
import os
import queue
import select
import socket
import threading
from typing import IO, Protocol

import serial

import xac1_proto.urlhandler  # noqa: F401  (registers xac1sim:// for the controller port)
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.signals import StopRequest

from .live import TICK_S, Clock, Session
from .taps import PortGone, configure_raw


class HostSide(Protocol):
    def fds(self) -> list[int]: ...
    def on_readable(self, fd: int) -> bytes: ...
    def send(self, data: bytes) -> None: ...
    def close(self) -> None: ...


class PtyHost:
    """A pseudo-terminal for the host software; ``path`` (and ``link``, a symlink to it) is what it
    opens. The proxy keeps the slave open, so the host may open and close it any number of times."""

    def __init__(self, link: str | None = None, baud: int = spec.BAUD) -> None:
        self.master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        configure_raw(self._slave, baud)
        os.set_blocking(self.master, False)
        self.link = link
        if link is not None:
            if os.path.islink(link):
                os.unlink(link)
            os.symlink(self.path, link)
        self._lock = threading.Lock()
        self._closed = False

    def fds(self) -> list[int]:
        return [self.master]

    def on_readable(self, fd: int) -> bytes:
        try:
            return os.read(self.master, 4096)
        except (BlockingIOError, OSError):
            return b""

    def send(self, data: bytes) -> None:
        with self._lock:
            view = memoryview(data)
            while view and not self._closed:  # a host that does not read holds us here, until close
                try:
                    view = view[os.write(self.master, view):]
                except BlockingIOError:
                    select.select([], [self.master], [], 0.1)
                except OSError:
                    return

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True  # first: a send waiting for the host gives up
        with self._lock:
            if self.link is not None and os.path.islink(self.link):
                with contextlib.suppress(OSError):
                    os.unlink(self.link)
            for fd in (self.master, self._slave):
                with contextlib.suppress(OSError):
                    os.close(fd)


class TcpHost:
    """A TCP server for the host software: one client at a time (others are accepted and closed)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self.server = socket.create_server((host, port))
        self.server.setblocking(False)
        self.address = self.server.getsockname()[:2]
        self.client: socket.socket | None = None
        self._lock = threading.Lock()

    def fds(self) -> list[int]:
        return [self.server.fileno()] + ([self.client.fileno()] if self.client is not None else [])

    def on_readable(self, fd: int) -> bytes:
        if fd == self.server.fileno():
            try:
                conn, _ = self.server.accept()
            except BlockingIOError:
                return b""
            if self.client is not None:
                conn.close()
            else:
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.client = conn
            return b""
        assert self.client is not None
        try:
            data = self.client.recv(4096)
        except OSError:
            data = b""
        if not data:
            with self._lock:
                self.client.close()
                self.client = None
        return data

    def send(self, data: bytes) -> None:
        with self._lock:
            if self.client is not None:
                with contextlib.suppress(OSError):
                    self.client.sendall(data)

    def close(self) -> None:
        with self._lock:
            if self.client is not None:
                self.client.close()
                self.client = None
        self.server.close()


def open_device(port: str, baud: int = spec.BAUD) -> serial.SerialBase:
    """The controller's port: a path or a pyserial URL (``socket://``, ``xac1sim://``...)."""
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=TICK_S)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise PortGone("device", port, f"cannot open: {exc}") from None


class Proxy:
    """Forward between ``host`` and the device port; decode through ``session``. ``run()`` until
    ``stop`` is set; returns 0, or 1 when the device port went away (without ``reconnect``).

    The device port is shared by two threads: the reader thread reads it and, when it goes away,
    closes it and (with ``reconnect``) opens it again; the main loop writes to it and closes it at the
    end. Every change of ``self.device`` and every write happens under ``_device_lock``; a read does not
    hold it (a serial port reads and writes at the same time), and a port found replaced or closed
    after a failed read is left to whoever replaced it."""

    def __init__(self, host: HostSide, device_port: str, session: Session, clock: Clock, *,
                 baud: int = spec.BAUD, reconnect: bool = False, err: IO[str] | None = None) -> None:
        self.host = host
        self.device_port = device_port
        self.session = session
        self.clock = clock
        self.baud = baud
        self.reconnect = reconnect
        self.err = err
        self.device: serial.SerialBase | None = open_device(device_port, baud)
        self._chunks: queue.Queue[Chunk | PortGone] = queue.Queue()
        self._stop = threading.Event()
        self._device_lock = threading.Lock()
        self._reader = threading.Thread(target=self._read_device, name="xac1-proxy-device", daemon=True)

    def _say(self, text: str) -> None:
        if self.err is not None:
            self.err.write(text + "\n")
            self.err.flush()

    def _reopen(self) -> None:
        """Try once to open the device port again (the reader thread, with ``reconnect``)."""
        self._stop.wait(0.5)
        try:
            dev = open_device(self.device_port, self.baud)
        except PortGone:
            return
        with self._device_lock:
            if self._stop.is_set():  # closing: the new port is not wanted
                with contextlib.suppress(Exception):
                    dev.close()
                return
            self.device = dev
        self._say(f"xac1 proxy: device port {self.device_port}: back, resuming")

    def _gone(self, dev: serial.SerialBase, exc: BaseException) -> None:
        """A read from ``dev`` failed: close it and say so, unless it was closed or replaced meanwhile."""
        with self._device_lock:
            mine = self.device is dev
            if mine:
                self.device = None  # from here on nobody else writes to it
        if not mine:
            return
        with contextlib.suppress(Exception):
            dev.close()
        if not self._stop.is_set():
            self._chunks.put(PortGone("device", self.device_port, f"went away ({exc})"))

    def _read_device(self) -> None:
        while not self._stop.is_set():
            with self._device_lock:
                dev = self.device
            if dev is None:
                self._reopen()
                continue
            try:
                data = dev.read(max(dev.in_waiting, 1))
            except (serial.SerialException, OSError, TypeError, AttributeError, ValueError) as exc:
                self._gone(dev, exc)
                if not self.reconnect:
                    return
                continue
            if data:  # queued before forwarding: the host cannot react before we have it in order
                self._chunks.put(Chunk(self.clock.now(), DEVICE, data))
                self.host.send(data)

    def _to_device(self, data: bytes) -> None:
        with self._device_lock:
            dev = self.device
            if dev is None:
                problem = "dropped: the device port is away"
            else:
                try:
                    dev.write(data)
                    return
                except (serial.SerialException, OSError) as exc:
                    problem = f"not delivered: {exc}"
        self._say(f"xac1 proxy: warning: {len(data)} host bytes {problem}")

    def run(self, stop: StopRequest | None = None) -> int:
        stop = stop or threading.Event()
        self._reader.start()
        try:
            while not stop.is_set():
                ready = select.select(self.host.fds(), [], [], TICK_S)[0]
                for fd in ready:
                    data = self.host.on_readable(fd)
                    if data:
                        self._chunks.put(Chunk(self.clock.now(), HOST, data))
                        self._to_device(data)
                while True:
                    try:
                        item = self._chunks.get_nowait()
                    except queue.Empty:
                        break
                    if isinstance(item, PortGone):
                        self._say(f"xac1 proxy: error: {item}; everything seen so far is kept"
                                  + ("; waiting for it to come back" if self.reconnect else ""))
                        if not self.reconnect:
                            return 1
                        continue
                    self.session.chunk(item)
                self.session.tick(self.clock.now())
            return 0
        finally:
            self.close()

    def drain(self) -> None:
        """Hand the chunks still queued (seen and forwarded, not yet decoded) to the session."""
        while True:
            try:
                item = self._chunks.get_nowait()
            except queue.Empty:
                return
            if isinstance(item, Chunk):
                self.session.chunk(item)

    def close(self) -> None:
        """Stop the reader thread, close the device port and the host side (idempotent)."""
        self._stop.set()
        if self._reader.is_alive():
            self._reader.join(timeout=2.0)
        with self._device_lock:
            dev, self.device = self.device, None
        if dev is not None:
            with contextlib.suppress(Exception):
                dev.close()
        self.host.close()
