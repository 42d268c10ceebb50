"""The line to the unit under fuzzing: cases out, answers in, the liveness probe, the state read-back.

A thin shell around ``xac1_proto.dut`` (the device under test that conformance and replay drive): the
snapshot, the restore, the alarm reset and the reads go through ``DeviceUnderTest``; a case's writes
are checked by the fuzz motion guard (``xac1_proto.fuzz.guard.check``) here, the one place they are
written, then sent as they are (they are no command the client would send) and every byte both ways is
added to the run's ``Transcript``. ``power_cycle`` starts the built-in simulator afresh; a real unit is
power-cycled by its operator when a terminal can ask for it, else it cannot be.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Final

from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST
from xac1_proto.dut.device import DeviceAbort, DeviceUnderTest
from xac1_proto.dut.safety import POINTS
from xac1_proto.frames import (
    AlarmAnswer,
    AlarmReset,
    Frame,
    ReadOutputs,
    ReadOutputsAnswer,
    ReadPoint,
    ReadPointAnswer,
    ReadVersion,
)
from xac1_proto.fuzz import guard
from xac1_proto.fuzz.cases import LF, Case
from xac1_proto.fuzz.judge import ANSWER, Point, Transcript, answers_in, probe_finding

if TYPE_CHECKING:
    from xac1_proto.dut.settings import Settings

LATE_FACTOR: Final = 5  # after a silent probe, bytes are awaited this many answer windows more,
LATE_MIN_S: Final = 1.0  # and at least this long


class Unreadable(Exception):
    """A read-back got no proper answer; the message says which and what came."""


class Unit:
    """One unit (a port URL) for the fuzzer; see the module docstring."""

    def __init__(self, settings: Settings, transcript: Transcript,
                 ask: Callable[[str], bool] | None = None) -> None:
        self.settings = settings
        self.transcript = transcript
        self.ask = ask  # asks the operator (True: done); None: nobody to ask
        self.dut: DeviceUnderTest = self._open()

    def _open(self) -> DeviceUnderTest:
        from xac1_proto.client import Client

        client = Client(self.settings.port, timeout=self.settings.timeout, storm_limit=None,
                        time_scale=self.settings.time_scale, on_traffic=self.transcript.add)
        return DeviceUnderTest(self.settings, client)

    @property
    def window(self) -> float:
        return self.settings.timeout

    def close(self) -> None:
        self.dut.close()

    def power_cycle(self) -> bool:
        """A fresh start of the unit: the simulator anew; a real unit's operator asked (False: nobody to
        ask, or they declined)."""
        if self.settings.simulator:
            self.dut.close()
            self.dut = self._open()
            return True
        return self.ask is not None and self.ask("switch the unit off and on again, then press Enter "
                                                 "(q: stop shrinking)")

    def settle(self) -> None:
        """Whatever was known of the alarm state, reset it and check the unit answers (DeviceAbort if
        not): the start of every re-run and of the run after a finding."""
        self.dut.latched = None
        self.dut.settle()

    # ---- a case ----

    def _read(self, until: float) -> bytes:
        port = self.dut.client.port
        data = port.read(max(1, port.in_waiting)) if time.monotonic() < until else b""
        if data:
            self.transcript.add(DEVICE, data, time.monotonic())
        return data

    def send_case(self, case: Case) -> bytes:
        """Write the case's writes (the whole case checked by the motion guard first), waiting after each
        for its answers: one a LF sent, or an answer window of quiet (a write with no LF: a window of
        silence). The bytes the unit sent back."""
        guard.check(case.data)  # raises MotionLine: nothing of the case is sent
        port = self.dut.client.port
        while port.in_waiting:  # a late answer of the last probe: in the transcript, not in the case's
            self._read(float("inf"))
        got = b""
        for data in case.lines:
            port.write(data)
            port.flush()
            now = time.monotonic()
            self.transcript.add(HOST, data, now)
            want = got.count(LF) + data.count(LF)
            until = now + self.window
            silence = LF not in data  # a partial line: the window of silence it is followed by
            while (silence or got.count(LF) < want) and time.monotonic() < until:
                chunk = self._read(until)
                if chunk:
                    got += chunk
                    until = time.monotonic() + self.window
        self.transcript.tick(time.monotonic())
        return got

    def send_move(self, case: Case) -> bytes:
        """A move case, through the device under test's motion guard (MotionRefused: nothing sent)."""
        return self.dut.probe(case.lines[0]).raw

    # ---- the probes ----

    def _late(self, since: float) -> float | None:
        """Seconds from ``since`` to the first late byte, when one comes within LATE_FACTOR windows (at
        least LATE_MIN_S); the whole time is waited, so that every late answer (of the probe and of the
        lines before it) is in the transcript, and in a capture, where it came."""
        until = time.monotonic() + max(LATE_FACTOR * self.window, LATE_MIN_S)
        late = None
        while time.monotonic() < until:
            if self._read(until) and late is None:
                late = time.monotonic() - since
        return late

    def _send(self, frame: Frame) -> tuple[bytes, float]:
        t0 = time.monotonic()
        try:
            p = self.dut.send(frame)
        except DeviceAbort:
            return b"", t0
        return p.raw, t0

    def version(self) -> bytes:
        """0RV's answer now (b"" when silent)."""
        return self._send(ReadVersion())[0]

    def liveness(self, expected: bytes, latched: bool, *, wait_late: bool = True) -> tuple[str, str] | None:
        """The liveness probe: 0%C first when an alarm may be latched, then 0RV, answered ``expected``
        within the window; (kind, detail) when not."""
        if latched:
            raw, t0 = self._send(AlarmReset())
            if not raw:
                late = self._late(t0) if wait_late else None
                return probe_finding(None, b"", AlarmReset().to_bytes(), late_s=late, window_s=self.window)
        raw, t0 = self._send(ReadVersion())
        late = self._late(t0) if not raw and wait_late else None
        return probe_finding(expected, raw, ReadVersion().to_bytes(), late_s=late, window_s=self.window)

    def read_state(self) -> tuple[dict[int, Point], int]:
        """Every point and the OUT ports, read back (after an alarm reset); Unreadable when one is not."""
        self._send(AlarmReset())
        points: dict[int, Point] = {}
        for n in POINTS:
            raw, _ = self._send(ReadPoint(n=n))
            f = next(iter(answers_in(raw)), None)
            if not isinstance(f, ReadPointAnswer) or f.n != n:
                raise Unreadable(f"0RP{n:X} answered {_what(raw, f)}")
            points[n] = (f.v, f.a, f.o, f.pos)
        raw, _ = self._send(ReadOutputs())
        f = next(iter(answers_in(raw)), None)
        if not isinstance(f, ReadOutputsAnswer):
            raise Unreadable(f"0RS answered {_what(raw, f)}")
        return points, f.o


def _what(raw: bytes, frame: Frame | None) -> str:
    from xac1_proto.codec import show_bytes

    if not raw:
        return "nothing"
    if isinstance(frame, AlarmAnswer):
        return f"alarm {frame.code:02X} ({show_bytes(raw)})"
    return show_bytes(raw)


def latched_after(answered: bytes, case: Case) -> bool:
    """May an alarm be latched after the case: an alarm answer came, or a line got no answer?"""
    answers = answers_in(answered)
    return any(isinstance(f, AlarmAnswer) and f.code != spec.ALARM_NONE for f in answers) or \
        len(answers) < case.data.count(LF)


def ask_on_terminal(prompt: str) -> bool:
    """Ask the operator on the terminal; True when they pressed Enter (False: q, or end of input)."""
    print(f"xac1 fuzz: {prompt}", file=sys.stderr, flush=True)
    try:
        return input().strip().lower() != "q"
    except EOFError:
        return False


__all__ = ["ANSWER", "Unit", "Unreadable", "ask_on_terminal", "latched_after"]
