"""A Y-cable made of real pseudo-terminals, for the sniffer's tests.

``YCable(device_path)``: the host opens ``host_path``; a forwarding thread copies the host's bytes to
the device port and the device's bytes back, and mirrors each direction onto its tap pty
(``tap_paths["host"]``, ``tap_paths["device"]``), as a Y-cable does. Whatever comes back out of a tap
(something wrote to it) is kept in ``tap_writes``: a receive-only sniffer leaves it empty.
``links={"host": PATH, ...}``: the taps are reached through symlinks, so that ``unplug(dir)`` (the tap's
pty goes away, as a USB adapter pulled out) and ``replug(dir)`` (a new pty, the link re-pointed) can
play an adapter replugged under the same name. ``seen[dir]``: every byte put on the line each way.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time

from sniffer.taps import configure_raw


def _raw_pty() -> tuple[int, int, str]:
    master, slave = os.openpty()
    configure_raw(slave, 9600)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    deadline = time.monotonic() + 2.0
    while view and time.monotonic() < deadline:
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            select.select([], [fd], [], 0.05)


class YCable:
    """See the module docstring. A context manager; ``mirrored[dir]`` counts bytes put on each tap."""

    def __init__(self, device_path: str, links: dict[str, str] | None = None) -> None:
        self.host_master, self._host_slave, self.host_path = _raw_pty()
        self.device = os.open(device_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        configure_raw(self.device, 9600)
        self._taps: dict[str, tuple[int, int, str]] = {d: _raw_pty() for d in ("host", "device")}
        self.links = links or {}
        for d in self.links:
            self._link(d)
        self.tap_paths = {d: self.links.get(d, t[2]) for d, t in self._taps.items()}
        self.tap_writes = {d: b"" for d in self._taps}
        self.mirrored = {d: 0 for d in self._taps}
        self.seen = {d: bytearray() for d in self._taps}
        self._requests: list[tuple[str, str, threading.Event]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="y-cable", daemon=True)
        self._thread.start()

    def _read(self, fd: int) -> bytes:
        try:
            return os.read(fd, 4096)
        except (BlockingIOError, OSError):
            return b""

    def _link(self, d: str) -> None:
        tmp = self.links[d] + ".new"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.symlink(self._taps[d][2], tmp)
        os.replace(tmp, self.links[d])

    def _change(self, what: str, d: str) -> None:
        """Runs in the forwarding thread, between two polls."""
        if what == "sync":
            return
        if what == "unplug":
            for fd in self._taps.pop(d)[:2]:
                os.close(fd)
            if d in self.links:
                os.unlink(self.links[d])
        else:
            self._taps[d] = _raw_pty()
            if d in self.links:
                self._link(d)

    def _request(self, what: str, d: str) -> None:
        done = threading.Event()
        self._requests.append((what, d, done))
        assert done.wait(5), f"y-cable: {what} {d} not done"

    def unplug(self, d: str) -> None:
        """The ``d`` tap's pty goes away (its link too); what passes meanwhile is not mirrored."""
        self._request("unplug", d)

    def sync(self) -> None:
        """Return once the forwarding thread has handled every byte that was readable when called:
        the first request is taken before a poll that sees those bytes, the second after it."""
        self._request("sync", "")
        self._request("sync", "")

    def replug(self, d: str) -> None:
        """A new pty for the ``d`` tap, its link re-pointed to it."""
        self._request("replug", d)

    def _mirror(self, d: str, data: bytes) -> None:
        """Counted first, so that once the far end has the bytes ``mirrored`` covers them too."""
        self.mirrored[d] += len(data)
        self.seen[d] += data
        if d in self._taps:
            _write_all(self._taps[d][0], data)

    def _run(self) -> None:
        while not self._stop.is_set():
            while self._requests:
                what, d, done = self._requests.pop(0)
                self._change(what, d)
                done.set()
            tap_masters = {t[0]: d for d, t in self._taps.items()}
            fds = [self.host_master, self.device, *tap_masters]
            for fd in select.select(fds, [], [], 0.05)[0]:
                data = self._read(fd)
                if not data:
                    continue
                if fd == self.host_master:
                    self._mirror("host", data)
                    _write_all(self.device, data)
                elif fd == self.device:
                    self._mirror("device", data)
                    _write_all(self.host_master, data)
                else:
                    self.tap_writes[tap_masters[fd]] += data

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        fds = [self.host_master, self._host_slave, self.device]
        fds += [fd for t in self._taps.values() for fd in t[:2]]
        for fd in fds:
            with contextlib.suppress(OSError):
                os.close(fd)
        for link in self.links.values():
            with contextlib.suppress(FileNotFoundError):
                os.unlink(link)

    def __enter__(self) -> YCable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ScriptedHost:
    """A sloppy host: writes exactly the bytes it is told to and reads what comes back."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        configure_raw(self.fd, 9600)

    def send(self, data: bytes) -> None:
        _write_all(self.fd, data)

    def read_lines(self, n: int, timeout: float = 3.0) -> bytes:
        """Read until ``n`` LFs came or ``timeout`` passed."""
        got = b""
        deadline = time.monotonic() + timeout
        while got.count(b"\n") < n and time.monotonic() < deadline:
            if select.select([self.fd], [], [], 0.02)[0]:
                with contextlib.suppress(BlockingIOError, OSError):
                    got += os.read(self.fd, 4096)
        return got

    def ask(self, data: bytes, answers: int = 1) -> bytes:
        self.send(data)
        return self.read_lines(answers)

    def close(self) -> None:
        os.close(self.fd)
