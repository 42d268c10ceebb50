"""Thin I/O shells around the device model: a pseudo-terminal or a TCP server, run in a thread.

How it works: one loop (``SimServer.run``) waits with ``select`` on the transport's file descriptors and
a wake-up pipe, with a timeout set by the model's ``outbox.next_due``. Bytes read go to
``model.receive(data, monotonic time)``; bytes the outbox says are due are written out (buffered when
the other side does not read). Every change to the model happens under ``RunningSim.lock``, so fault
injection from another thread (``RunningSim.call``) is safe; it wakes the loop so new answers go out.

- pty: ``os.openpty``; the slave end is set raw at 9600 baud and kept open by the simulator, so a client
  may open and close ``path`` any number of times (the device keeps its state, like a serial line).
- TCP: binds 127.0.0.1 unless told otherwise; one client at a time (a second connection is accepted and
  closed at once); the device state survives reconnections; when a client goes, its partial line and
  unsent answers are forgotten. A client's end of file is always served before a new connection is
  looked at, so a client that connects just as the previous one closes is served, not turned away.
- Back-pressure: answers the other side does not read wait in a buffer of at most ``MAX_PENDING_OUT``
  bytes (plus what one read can cause); while it is full the simulator stops reading that side, so a
  client that writes but never reads is slowed down by its own socket, and memory stays bounded.
- A loop that dies (an exception: a log that cannot be written, a bug) sets ``SimServer.failed`` and
  keeps the exception in ``SimServer.error``; ``xac1 sim`` watches it and stops at once.

``serve_pty`` and ``serve_tcp`` are context managers for tests and tools: they start the loop in a
daemon thread and stop it (joined, every descriptor closed) on exit.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator
from typing import Any, Protocol

from .config import SimConfig
from .model import DeviceModel

Traffic = Callable[[str, bytes], None]  # (direction "host"|"device", bytes)

READ_SIZE = 4096  # bytes read at a time from the other side
MAX_PENDING_OUT = 65536  # answer bytes held for a side that does not read before it is no longer read
MAX_SLEEP_S = 60.0  # the loop wakes at least this often, whatever the outbox says


class Transport(Protocol):
    def read_fds(self) -> list[int]: ...
    def write_fds(self) -> list[int]: ...
    def on_readable(self, fd: int) -> bytes | None: ...  # None: nothing for the model
    def on_writable(self, fd: int) -> None: ...
    def send(self, data: bytes) -> None: ...
    def close(self) -> None: ...


class PtyTransport:
    """A pseudo-terminal: the simulator holds the master; ``path`` is the slave a client opens."""

    def __init__(self, link: str | os.PathLike[str] | None = None) -> None:
        self.master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[4] = attrs[5] = termios.B9600
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        os.set_blocking(self.master, False)
        self._out = bytearray()
        self.link = os.fspath(link) if link is not None else None
        if self.link is not None:
            with contextlib.suppress(FileNotFoundError):
                if os.path.islink(self.link):
                    os.unlink(self.link)
            os.symlink(self.path, self.link)

    def read_fds(self) -> list[int]:
        return [self.master] if len(self._out) < MAX_PENDING_OUT else []  # back-pressure

    def write_fds(self) -> list[int]:
        return [self.master] if self._out else []

    def on_readable(self, fd: int) -> bytes | None:
        try:
            return os.read(self.master, READ_SIZE) or None
        except (BlockingIOError, InterruptedError):
            return None
        except OSError as exc:  # EIO: no client has the slave open (cannot happen while we hold it)
            if exc.errno == errno.EIO:
                return None
            raise

    def send(self, data: bytes) -> None:
        self._out += data
        self.on_writable(self.master)

    def on_writable(self, fd: int) -> None:
        while self._out:
            try:
                n = os.write(self.master, self._out)
            except (BlockingIOError, InterruptedError):
                return
            del self._out[:n]

    def close(self) -> None:
        if self.link is not None:
            with contextlib.suppress(OSError):
                if os.path.islink(self.link) and os.readlink(self.link) == self.path:
                    os.unlink(self.link)
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class TcpTransport:
    """A TCP server with at most one client; the model outlives connections."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0,
                 on_disconnect: Callable[[], None] | None = None) -> None:
        self.server = socket.create_server((host, port), reuse_port=False)
        self.server.setblocking(False)
        self.host, self.port = self.server.getsockname()[:2]
        self.client: socket.socket | None = None
        self._out = bytearray()
        self._on_disconnect = on_disconnect

    def read_fds(self) -> list[int]:
        fds = []
        if self.client is not None and len(self._out) < MAX_PENDING_OUT:  # else: back-pressure
            fds.append(self.client.fileno())  # before the server: an end of file before a new client
        fds.append(self.server.fileno())
        return fds

    def write_fds(self) -> list[int]:
        return [self.client.fileno()] if self.client is not None and self._out else []

    def on_readable(self, fd: int) -> bytes | None:
        if fd != self.server.fileno():
            data = self._recv()
            return data or None
        if self.client is not None:
            # Serve what the present client still has (its last bytes, its end of file) before looking
            # at the new connection: it may be the next client, come just as this one closed.
            data = self._recv()
            if data:
                return data  # the new connection waits in the backlog until the next round
            if self.client is not None:  # alive with nothing to say: one client at a time
                with contextlib.suppress(BlockingIOError, InterruptedError, OSError):
                    self.server.accept()[0].close()
                return None
        try:
            conn, _ = self.server.accept()
        except (BlockingIOError, InterruptedError):
            return None
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.client = conn
        return None

    def _recv(self) -> bytes:
        """What the client sent (b"" when nothing waits); its end of file or an error drops it. While
        its answers are not being read, only an end of file is looked for (back-pressure)."""
        if self.client is None:
            return b""
        paused = len(self._out) >= MAX_PENDING_OUT
        try:
            data = self.client.recv(1, socket.MSG_PEEK) if paused else self.client.recv(READ_SIZE)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:
            data = b""
        if not data:
            self._drop_client()
            return b""
        return b"" if paused else data

    def _drop_client(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
            self._out.clear()
            if self._on_disconnect is not None:
                self._on_disconnect()

    def send(self, data: bytes) -> None:
        if self.client is None:
            return  # nobody to hear it: a real line would lose it too
        self._out += data
        self.on_writable(self.client.fileno())

    def on_writable(self, fd: int) -> None:
        while self._out and self.client is not None:
            try:
                n = self.client.send(self._out)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self._drop_client()
                return
            del self._out[:n]

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        self.server.close()


class SimServer:
    """The loop that joins a transport to a model (see the module docstring)."""

    def __init__(self, model: DeviceModel, transport: Transport, on_traffic: Traffic | None = None,
                 on_table_change: Callable[[DeviceModel], None] | None = None) -> None:
        self.model = model
        self.transport = transport
        self.lock = threading.RLock()
        self.on_traffic = on_traffic
        self.on_table_change = on_table_change
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        self._stopping = False
        self._closed = False
        self._changes = model.table_changes
        self.error: BaseException | None = None
        self.failed = threading.Event()  # set when the loop died of ``error``

    def wake(self) -> None:
        if self._closed:
            return
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def stop(self) -> None:
        self._stopping = True
        self.wake()

    def run(self) -> None:
        try:
            while not self._stopping:
                self._step()
        except BaseException as exc:  # reported by the owner (RunningSim / the CLI)
            self.error = exc
            self.failed.set()
        finally:
            self._closed = True
            self.transport.close()
            for fd in (self._wake_r, self._wake_w):
                with contextlib.suppress(OSError):
                    os.close(fd)

    def _step(self) -> None:
        with self.lock:
            due = self.model.outbox.next_due
        timeout = MAX_SLEEP_S if due is None else min(MAX_SLEEP_S, max(0.0, due - time.monotonic()))
        with self.lock:
            rfds = [*self.transport.read_fds(), self._wake_r]
            wfds = self.transport.write_fds()
        readable, writable, _ = select.select(rfds, wfds, [], timeout)
        for fd in writable:
            with self.lock:  # a TCP disconnect resets the model's line
                self.transport.on_writable(fd)
        for fd in readable:  # in read_fds order: a client's end of file before a new connection
            if fd == self._wake_r:
                with contextlib.suppress(OSError):
                    os.read(self._wake_r, 512)
                continue
            with self.lock:
                data = self.transport.on_readable(fd)
            if data:
                self._received(data)
        self._send_due()

    def _received(self, data: bytes) -> None:
        if self.on_traffic is not None:
            self.on_traffic("host", data)
        with self.lock:
            self.model.receive(data, time.monotonic())
            if self.model.table_changes != self._changes:
                self._changes = self.model.table_changes
                if self.on_table_change is not None:
                    self.on_table_change(self.model)

    def _send_due(self) -> None:
        with self.lock:
            out = self.model.outbox.pop(time.monotonic())
            if out:
                self.transport.send(out)
        if out and self.on_traffic is not None:
            self.on_traffic("device", out)


class RunningSim:
    """A simulator running in a thread: ``.model``, ``.lock``, ``.url`` (for pyserial), and ``.path``
    (pty) or ``.host``/``.port`` (TCP). Use as a context manager, or call ``stop()``."""

    def __init__(self, server: SimServer) -> None:
        self.server = server
        self.model = server.model
        self.lock = server.lock
        transport: Any = server.transport
        self.path: str | None = getattr(transport, "path", None)
        self.link: str | None = getattr(transport, "link", None)
        self.host: str | None = getattr(transport, "host", None)
        self.port: int | None = getattr(transport, "port", None)
        self.url = self.path if self.path is not None else f"socket://{self.host}:{self.port}"
        self.failed = server.failed  # set when the loop died; ``server.error`` says of what
        self._thread = threading.Thread(target=server.run, name="xac1-sim", daemon=True)
        self._thread.start()

    def call(self, fn: Callable[[DeviceModel, float], Any]) -> Any:
        """Run ``fn(model, now)`` under the lock (fault injection), then let the loop send answers."""
        with self.lock:
            result = fn(self.model, time.monotonic())
        self.server.wake()
        return result

    def stop(self, timeout: float = 5.0) -> None:
        self.server.stop()
        self._thread.join(timeout)
        if self._thread.is_alive():
            raise RuntimeError("simulator thread did not stop")
        if self.server.error is not None:
            raise RuntimeError(f"simulator loop failed: {self.server.error!r}") from self.server.error

    def __enter__(self) -> RunningSim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _model(config: SimConfig | None, model: DeviceModel | None) -> DeviceModel:
    if model is not None and config is not None:
        raise ValueError("give a config or a model, not both")
    return model or DeviceModel(config)


@contextlib.contextmanager
def serve_pty(config: SimConfig | None = None, *, model: DeviceModel | None = None,
              link: str | os.PathLike[str] | None = None, on_traffic: Traffic | None = None,
              on_table_change: Callable[[DeviceModel], None] | None = None) -> Iterator[RunningSim]:
    """Run a simulator on a new pseudo-terminal; yields the ``RunningSim`` (``.path``, ``.url``)."""
    transport = PtyTransport(link)
    sim = RunningSim(SimServer(_model(config, model), transport, on_traffic, on_table_change))
    try:
        yield sim
    finally:
        sim.stop()


@contextlib.contextmanager
def serve_tcp(config: SimConfig | None = None, *, model: DeviceModel | None = None,
              host: str = "127.0.0.1", port: int = 0, on_traffic: Traffic | None = None,
              on_table_change: Callable[[DeviceModel], None] | None = None) -> Iterator[RunningSim]:
    """Run a simulator as a TCP server (port 0: any free port); yields the ``RunningSim``
    (``.port``, ``.url`` = ``socket://HOST:PORT``)."""
    the_model = _model(config, model)
    transport = TcpTransport(host, port, on_disconnect=the_model.reset_line)
    sim = RunningSim(SimServer(the_model, transport, on_traffic, on_table_change))
    try:
        yield sim
    finally:
        sim.stop()
