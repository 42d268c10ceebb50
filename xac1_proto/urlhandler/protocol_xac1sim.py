"""``xac1sim://``: an in-process XA-C1 simulator opened exactly like a serial port.

URL: ``xac1sim://[?OPTION=VALUE&...]``, e.g. ``xac1sim://?time_scale=0&version=102&deviation=no-2``.
The options are those of ``xac1_proto.sim.config.OPTIONS`` (the one list, shared with ``xac1 sim``):
time_scale, wire_timing, version, turnaround (ms), stroke (LO:HI), deviation (repeat or comma-separate),
seed, noise, drop, delay (ms), delay_p, and the silent-point switches; and those of ``xac1 sim
--replay``: ``replay=CAPTURE`` (repeat it for formats with one file per direction), ``replay_strict=1``,
``replay_format=FORMAT``, ``replay_host_is=SIDE`` (docs/replay.md). An unknown option or a bad value
raises ``serial.SerialException`` naming it and the known options.

No thread: ``write`` feeds the model with the current monotonic time; ``read`` waits (sleeping until the
next answer byte is due, never past the timeout) and takes what the model's outbox says is due. Each
open starts a fresh device (power-on state). ``.model`` is the ``DeviceModel``, for fault injection:
``port.model.set_estop(True)``.
"""

from __future__ import annotations

import threading
import time
import urllib.parse
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from ..sim.config import SimConfig, config_from_options
from ..sim.model import DeviceModel

SCHEME = "xac1sim"
_IDLE_STEP_S = 0.05  # how long a blocking read sleeps when nothing at all is due


def parse_url(url: str) -> dict[str, list[str]]:
    """The options of a ``xac1sim://`` URL; raises SerialException for a foreign or bad URL."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != SCHEME:
        raise SerialException(f"expected a URL starting with {SCHEME}://, got {url!r}")
    if parts.netloc or parts.path not in ("", "/"):
        raise SerialException(f"{url!r}: options go in the query string, as in "
                              f"{SCHEME}://?time_scale=0&version=102")
    try:
        return urllib.parse.parse_qs(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError as exc:
        raise SerialException(f"{url!r}: bad query string ({exc})") from None


# The replay options (``xac1 sim --replay``): the capture file(s), strict, its format, its host side.
REPLAY_OPTIONS = ("replay", "replay_strict", "replay_format", "replay_host_is")


def _replaying(options: dict[str, list[str]], config: SimConfig) -> DeviceModel:
    """A device answering as the captured one did (``xac1_proto.sim.replaying``); ValueError naming a
    bad option or capture."""
    from ..sim.replaying import ReplayingDevice, load_script

    files = options.get("replay")
    if not files:
        raise ValueError("replay_strict, replay_format and replay_host_is go with replay=CAPTURE")
    strict = options.get("replay_strict", ["0"])[-1]
    if strict not in ("0", "1"):
        raise ValueError(f"replay_strict: expected 0 or 1, got {strict!r}")
    fmt = options.get("replay_format", ["auto"])[-1]
    host_is = options.get("replay_host_is", [None])[-1]
    return ReplayingDevice(load_script(files, fmt, host_is), config, strict=strict == "1")


class Serial(SerialBase):
    """pyserial port whose other end is a simulated XA-C1 (see the module docstring)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.model: DeviceModel | None = None
        self._rx = bytearray()
        self._lock = threading.Lock()
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:  # type: ignore[has-type]  # set by SerialBase
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        options = parse_url(self.portstr)
        replay = {key: options.pop(key) for key in REPLAY_OPTIONS if key in options}
        try:
            config = config_from_options(options)
            self.model = _replaying(replay, config) if replay else DeviceModel(config)
        except ValueError as exc:
            raise SerialException(f"{self.portstr}: {exc}") from None
        self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False
        super().close()

    def _reconfigure_port(self) -> None:
        pass  # a simulated line: every setting is accepted

    def _take_due(self) -> None:
        assert self.model is not None
        with self._lock:
            self._rx += self.model.outbox.pop(time.monotonic())

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        self._take_due()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise PortNotOpenError()
        assert self.model is not None
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while True:
            self._take_due()
            if len(self._rx) >= size:
                break
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                break
            with self._lock:
                due = self.model.outbox.next_due
            wake = now + _IDLE_STEP_S if due is None else due
            if deadline is not None:
                wake = min(wake, deadline)
            time.sleep(max(0.0, wake - now))
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        assert self.model is not None
        data = bytes(data)
        with self._lock:
            self.model.receive(data, time.monotonic())
        return len(data)

    def reset_input_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        self._take_due()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self) -> int:
        return 0

    # modem lines: a simulated line has none worth reporting
    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
