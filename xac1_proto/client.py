"""The host client: drive an XA-C1 over any pyserial port, one exchange at a time.

A thin I/O shell around sans-IO parts: ``Framer`` cuts the answer out of the byte stream, the client's
own ``conversation.Conversation`` (the one rulebook the sniffer and the conformance suite use too) judges
each exchange, keeps the host's duty to stop after communication errors in a row and prices how long
to wait for an answer: a move's window is the one the rulebook gives it (docs/protocol.md "Behaviour the
vendor text states": 0MP and 0MV answer when the move has ended; silent item 17), so the client waits
exactly as long as the sniffer and the conformance suite would judge the answer in time.

An exchange: bytes already waiting are read and reported as ``stale`` (a late answer to an earlier
exchange must not pass for this one's); the command is written; bytes are read until the framer
yields the first frame-shaped line, which is the answer, or until the timeout, after which late bytes
are drained until the line is quiet. Nothing is retried behind the caller's back.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import TypeVar, cast

import serial

from . import motion, rules, spec
from . import urlhandler as _urlhandler  # noqa: F401  (registers xac1sim:// for serial_for_url)
from .codec import diagnose, show_bytes
from .conversation import Conversation, Verdict
from .errors import CommunicationHalted, ResponseTimeout
from .exchange import Exchange, answer_or_raise
from .framer import FrameBytes, Framer, Junk
from .frames import (
    AlarmReset,
    AlarmResetAnswer,
    Frame,
    MoveDirect,
    MoveDirectAnswer,
    MovePoint,
    MovePointAnswer,
    ReadCurrent,
    ReadCurrentAnswer,
    ReadOutputs,
    ReadOutputsAnswer,
    ReadPoint,
    ReadPointAnswer,
    ReadVersion,
    ReadVersionAnswer,
    StoreCurrent,
    StoreCurrentAnswer,
    SwitchMode,
    SwitchModeAnswer,
    WriteOutputs,
    WriteOutputsAnswer,
    WritePoint,
    WritePointAnswer,
)

TrafficHook = Callable[[str, bytes, float], None]
A = TypeVar("A", bound=Frame)

POLL_S = 0.02  # longest a single read blocks; a deadline is overshot by at most this


def open_port(port: str | serial.Serial) -> tuple[serial.Serial, bool]:
    """The port at 9600 8N1 and whether we opened it (a URL or device path) or were handed it.

    A device path (or ``hwgrep://``, which names one) is opened exclusively where pyserial supports it
    (POSIX: an advisory lock), so that another program that asks for the port the same way, such as
    ``xac1 ports --probe`` or a second run, finds it busy instead of talking into our conversation."""
    settings = dict(baudrate=spec.BAUD, bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
                    stopbits=serial.STOPBITS_ONE, timeout=POLL_S)
    if isinstance(port, str):
        device = "://" not in port or port.lower().startswith("hwgrep://")
        if device and os.name == "posix":
            return serial.serial_for_url(port, exclusive=True, **settings), True
        return serial.serial_for_url(port, **settings), True
    for name, value in settings.items():
        if getattr(port, name) != value:
            setattr(port, name, value)
    return port, False


class Client:
    """An XA-C1 host. ``port``: a pyserial URL or device path (opened at 9600 8N1) or an open
    ``serial.Serial`` (set to 9600 8N1; left open by ``close()``).

    ``timeout``: turnaround timeout in seconds for immediate commands (default: the project's one
    answer-timeout, ``spec.NO_ANSWER_TIMEOUT_S``). Moves (0MP, 0MV) wait the conversation's answer
    window (``move_timeout``): the timeout plus the move's estimated time doubled, priced from ``speeds``
    and what the answers told, the unknown at its worst; ``time_scale`` scales the move's share, for a
    simulator run faster than real time. ``storm_limit``: communication-error
    answers in a row after which nothing is sent until ``rearm()`` (None: never halt).
    ``on_traffic(direction, data, t)`` sees every byte sent ("host") and received ("device"), ``t``
    from ``clock`` (default ``time.monotonic``). ``drain_quiet``: after a timeout, late bytes are read
    until the line has been quiet this long.
    """

    def __init__(self, port: str | serial.Serial, *, timeout: float = spec.NO_ANSWER_TIMEOUT_S,
                 storm_limit: int | None = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 on_traffic: TrafficHook | None = None, time_scale: float = 1.0, drain_quiet: float = 0.05,
                 clock: Callable[[], float] = time.monotonic,
                 readings: rules.Readings = rules.DEFAULT_READINGS) -> None:
        if timeout <= 0 or time_scale < 0 or drain_quiet < 0:
            raise ValueError("timeout must be > 0; time_scale and drain_quiet >= 0")
        if storm_limit is not None and storm_limit < 1:
            raise ValueError(f"storm_limit must be a positive count or None, got {storm_limit}")
        self.timeout = timeout
        self.time_scale = time_scale
        self.drain_quiet = drain_quiet
        self.on_traffic = on_traffic
        self.clock = clock
        self.storm_limit = storm_limit
        self.conversation = Conversation(no_answer_timeout=timeout,
                                         storm_limit=storm_limit or spec.STORM_LIMIT, speeds=speeds,
                                         readings=readings)
        self._read_t = 0.0
        self._lock = threading.RLock()
        self._serial, self._owned = open_port(port)

    # ---- state ----

    @property
    def port(self) -> serial.Serial:
        return self._serial

    @property
    def comm_errors_in_row(self) -> int:
        """``0%%01`` answers in a row (docs/protocol.md host duty; the rule is the conversation's)."""
        return self.conversation.knowledge.storm_run

    @property
    def halted(self) -> bool:
        """True once ``storm_limit`` communication errors came in a row; cleared by ``rearm()``."""
        return self.storm_limit is not None and self.conversation.halted

    @property
    def position(self) -> int | None:
        """The axis position as the conversation knows it from the answers (None: unknown)."""
        return self.conversation.knowledge.position.value

    def rearm(self) -> None:
        """Allow sending again after a communication-error storm (have the equipment checked first)."""
        with self._lock:
            self.conversation.rearm()

    def move_timeout(self, command: Frame) -> float:
        """Seconds to wait for ``command``'s answer: the timeout; for a move (``spec.MOVE_HEADERS``) the
        conversation's answer window, the move's estimated time doubled on top, that share scaled by
        ``time_scale``. The moves are picked as the conversation picks the lines it gives a move's window."""
        if command.header not in spec.MOVE_HEADERS:
            return self.timeout
        window = self.conversation.answer_window(command)
        return self.timeout + self.time_scale * (window - self.timeout)

    # ---- exchanges ----

    def request(self, command: Frame, timeout: float | None = None) -> Frame:
        """Send ``command`` and return its answer. Raises ``AlarmError`` for an alarm answer,
        ``ProtocolError`` for an answer that breaks the protocol, ``ResponseTimeout`` on silence,
        ``CommunicationHalted`` while halted."""
        if command.role != spec.COMMAND:
            raise ValueError(f"request() sends commands, got a {command.header} {command.role}")
        return answer_or_raise(self._exchange(command.to_bytes(), command, timeout))

    def transact(self, raw: bytes, timeout: float | None = None) -> Exchange:
        """Send any bytes (even a malformed command) and return the answer as the device sent it,
        decoded leniently with its violations. Raises only ``ResponseTimeout`` (no frame-shaped
        answer in time) and ``CommunicationHalted``; the answers still count for the storm guard."""
        command, violations = diagnose(raw, spec.COMMAND)
        if any(v.is_error for v in violations):
            command = None  # a malformed command is no move: it gets the plain timeout (e.g. 0MV vel 00)
        return self._exchange(bytes(raw), command, timeout)

    def _exchange(self, raw: bytes, command: Frame | None, timeout: float | None) -> Exchange:
        with self._lock:
            if self.halted:
                raise CommunicationHalted(
                    f"{self.comm_errors_in_row} communication-error answers (0%%01) in a row: the vendor "
                    f"says stop and have the equipment checked; call rearm() to send again")
            if timeout is None:
                timeout = self.move_timeout(command) if command is not None else self.timeout
            stale = self._read_waiting()
            self._judge(spec.DEVICE_SIDE, stale, None)
            self._serial.write(raw)
            self._serial.flush()
            t_sent = self.clock()
            self._traffic("host", raw, t_sent)
            self._judge(spec.HOST_SIDE, raw, t_sent, timeout)
            answer, junk, after, received = self._read_answer(t_sent + timeout)
            if answer is None:
                self._judge(spec.DEVICE_SIDE, junk, None)
                self.conversation.host_gave_up(self.clock())
                late = self._drain()
                what = f"{show_bytes(received)} (no complete frame)" if received else "nothing"
                raise ResponseTimeout(
                    f"no answer to {show_bytes(raw)} within {timeout:.3f} s; received {what}"
                    + (f"; {len(late)} late byte(s) drained" if late else ""), partial=received)
            verdicts = self._judge(spec.DEVICE_SIDE, junk, t_sent) if junk else []
            verdicts += self.conversation.device_frame(answer.raw, answer.t_first, answer.t_last)
            self.conversation.host_gave_up(self.clock())  # the client waits for no other answer
            self._judge(spec.DEVICE_SIDE, after, answer.t_last)  # unsolicited, reported as junk
            violations = [v for verdict in verdicts if verdict.sender == spec.DEVICE_SIDE
                          for v in verdict.violations]
            frame = verdicts[-1].frame
            exchange = Exchange(sent=raw, raw=answer.raw, frame=frame, violations=violations,
                                latency=None if answer.t_first is None else answer.t_first - t_sent,
                                junk=junk + after, stale=stale, t_sent=t_sent)
            return exchange

    def _judge(self, sender: str, data: bytes, t: float | None, window: float | None = None) -> list[Verdict]:
        """Bytes one side put on the line, through a framer into the client's conversation."""
        if not data:
            return []
        framer = Framer()
        out: list[Verdict] = []
        c = self.conversation
        for event in framer.feed(data, t) + framer.flush():
            if sender == spec.HOST_SIDE:
                judge = c.host_junk if isinstance(event, Junk) else c.host_frame
                out += judge(event.raw, event.t_first, event.t_last, window)
            elif isinstance(event, Junk):
                out += c.device_junk(event.raw, event.t_first, event.t_last)
            else:
                out += c.device_frame(event.raw, event.t_first, event.t_last)
        return out

    def _traffic(self, direction: str, data: bytes, t: float) -> None:
        if self.on_traffic is not None and data:
            self.on_traffic(direction, data, t)

    def _read_chunk(self) -> bytes:
        data = self._serial.read(max(1, self._serial.in_waiting))
        self._read_t = self.clock()  # one time for the traffic hook and the framer
        if data:
            self._traffic("device", data, self._read_t)
        return data

    def _read_waiting(self) -> bytes:
        """Bytes that arrived before a command was sent (never blocks)."""
        out = b""
        while self._serial.in_waiting:
            out += self._read_chunk()
        return out

    def _read_answer(self, deadline: float) -> tuple[FrameBytes | None, bytes, bytes, bytes]:
        """(answer frame, junk before it, bytes after it in the same read, every byte received) once the
        first frame-shaped line is in, or (None, junk, b"", received) at the deadline."""
        framer = Framer()
        junk, received = b"", b""
        while self.clock() < deadline:
            data = self._read_chunk()
            if not data:
                continue
            received += data
            for i, event in enumerate(events := framer.feed(data, self._read_t)):
                if isinstance(event, Junk):
                    junk += event.raw
                    continue
                rest = events[i + 1:] + framer.flush()  # bytes that came in the same read
                return event, junk, b"".join(e.raw for e in rest), received
        return None, junk, b"", received

    def _drain(self) -> bytes:
        """Read late bytes until the line has been quiet for ``drain_quiet`` (bounded by the timeout)."""
        out = b""
        start = quiet_since = self.clock()
        while self.clock() - quiet_since < self.drain_quiet and self.clock() - start < self.timeout:
            data = self._read_chunk()
            if data:
                out += data
                quiet_since = self.clock()
        return out

    # ---- one method a command (docs/protocol.md "Frames") ----

    def _ask(self, command: Frame, kind: type[A], timeout: float | None = None) -> A:
        return cast(A, self.request(command, timeout))

    def read_point(self, n: int) -> ReadPointAnswer:
        """0RP: movement data of point ``n`` (1-F)."""
        return self._ask(ReadPoint(n=n), ReadPointAnswer)

    def write_point(self, n: int, v: int, a: int, o: int, pos: int) -> WritePointAnswer:
        """0WP: store V, A, O and Pos as point ``n`` (1-F)."""
        return self._ask(WritePoint(n=n, v=v, a=a, o=o, pos=pos), WritePointAnswer)

    def read_current(self) -> ReadCurrentAnswer:
        """0RC: current point and position (Pos FFFFFF before homing)."""
        return self._ask(ReadCurrent(), ReadCurrentAnswer)

    def store_current(self, n: int) -> StoreCurrentAnswer:
        """0WC: store the current position into point ``n`` (1-F)."""
        return self._ask(StoreCurrent(n=n), StoreCurrentAnswer)

    def move_point(self, n: int, timeout: float | None = None) -> MovePointAnswer:
        """0MP: move to point ``n`` (0 homes); answers when the move has ended."""
        return self._ask(MovePoint(n=n), MovePointAnswer, timeout)

    def home(self, timeout: float | None = None) -> MovePointAnswer:
        """0MP 0: homing."""
        return self.move_point(0, timeout)

    def move_direct(self, vel: int, a: int, pos: int, timeout: float | None = None) -> MoveDirectAnswer:
        """0MV: move to ``pos`` at speed number ``vel`` (1-60) with acceleration ``a`` (1-3)."""
        return self._ask(MoveDirect(vel=vel, a=a, pos=pos), MoveDirectAnswer, timeout)

    def read_outputs(self) -> ReadOutputsAnswer:
        """0RS: the OUT ports."""
        return self._ask(ReadOutputs(), ReadOutputsAnswer)

    def write_outputs(self, o: int) -> WriteOutputsAnswer:
        """0WS: set the OUT ports (0 none, 1 OUT1, 2 OUT2, 3 both)."""
        return self._ask(WriteOutputs(o=o), WriteOutputsAnswer)

    def read_version(self) -> ReadVersionAnswer:
        """0RV: firmware version (``100`` = 1.00)."""
        return self._ask(ReadVersion(), ReadVersionAnswer)

    def switch_mode(self, mode: int) -> SwitchModeAnswer:
        """0CM: 0 external start, 1 communication."""
        return self._ask(SwitchMode(mode=mode), SwitchModeAnswer)

    def reset_alarm(self) -> AlarmResetAnswer:
        """0%C: clear every alarm but emergency stop."""
        return self._ask(AlarmReset(), AlarmResetAnswer)

    # ---- lifetime ----

    def close(self) -> None:
        """Close the port if this client opened it."""
        with self._lock:
            if self._owned and self._serial.is_open:
                self._serial.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
