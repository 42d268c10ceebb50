"""The device under test: one client, one choke point for every byte sent, the motion guard.

Every probe goes through ``DeviceUnderTest.probe`` (the client's ``transact``), which records it as
evidence for the running check and keeps turnaround times per command; what is known of the axis (homed,
position, the points' stored targets) is the engine's (the client's ``conversation.knowledge``). Before
a move command is sent, whatever the alarm state, the guard checks that motion is allowed and that the
target (a point's stored Pos for 0MP) and any homing on the way stay inside the safe range; otherwise the
probe is refused with ``MotionRefused`` and nothing is sent.

Silence is told apart from a device that went away by the liveness check ``settle`` (0%C then 0RV),
run between checks, after a check whose last probe got no byte back, and as soon as ``SILENT_LIMIT``
probes in a row got none. When neither answers, the device is gone (``NoAnswer`` if it never answered,
else ``StoppedAnswering``) and every later probe fails at once without being sent, until ``settle``
(the restore's first step) finds it answering again.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from typing import Any

from serial import SerialException

from xac1_proto import spec
from xac1_proto.codec import diagnose, show_bytes
from xac1_proto.errors import CommunicationHalted, ResponseTimeout
from xac1_proto.frames import (
    AlarmAnswer,
    AlarmReset,
    Frame,
    MoveDirect,
    MovePoint,
    ReadCurrent,
    ReadOutputsAnswer,
    ReadVersion,
    ReadVersionAnswer,
    WriteOutputsAnswer,
)

from .evidence import Probe, describe_answer
from .settings import Settings


class DeviceAbort(Exception):
    """The run cannot go on safely (emergency stop, host duty halt, a device that stopped answering)."""


class NoAnswer(DeviceAbort):
    """The device gave no byte back to a reset and a version request: nothing else can be judged."""


class PortLost(DeviceAbort):
    """The port itself failed (adapter unplugged, socket closed, device file gone): nothing more can be sent
    on it, so the run stops at once (the restore is then reported as not done)."""


class StoppedAnswering(DeviceAbort):
    """The device answered earlier in the run, then neither a reset nor a version request got a byte back
    (cable pulled, power lost): the run stops and the restore cannot be verified unless it comes back."""


SILENT_LIMIT = 2  # probes in a row with not a byte back before the liveness check runs mid-check


class MotionRefused(Exception):
    """A move the safety rules forbid; nothing was sent. The message says why."""


@dataclass
class Info:
    """What the device did where docs/protocol.md is silent: information, never a verdict."""

    topic: str
    section: str
    observed: str
    probes: list[Probe] = field(default_factory=list)


class DeviceUnderTest:
    """A client plus the evidence log, timing, axis knowledge and the motion guard."""

    def __init__(self, settings: Settings, client: Any) -> None:
        self.settings = settings
        self.client = client
        self.log: list[Probe] = []
        self.infos: list[Info] = []
        self.latencies: dict[str, list[float]] = {}
        self.test: str | None = None
        self.version: str | None = None
        self.latched: bool | None = None  # None: not known (start, after silence)
        self.outputs: int | None = None
        self.cited: dict[str | None, list[Probe]] = {}
        self.gone: str | None = None  # why the device is taken for gone (StoppedAnswering), else None
        self.silent_in_row = 0  # probes in a row that got not a single byte back
        self.lost: str | None = None  # why the port failed (PortLost), else None
        self._checking = False  # inside the liveness check (no nested one)

    @classmethod
    def open(cls, settings: Settings) -> DeviceUnderTest:
        from xac1_proto.client import Client  # heavy: only when a run really starts

        return cls(settings, Client(settings.port, timeout=settings.timeout, time_scale=settings.time_scale,
                                    readings=settings.readings))

    def close(self) -> None:
        self.client.close()

    # ---- the choke point ----

    def probe(self, raw: bytes, *, timeout: float | None = None) -> Probe:
        """Send ``raw`` (always ending in LF) through ``transact`` and record what came back."""
        if not raw.endswith(b"\n"):
            raise ValueError(f"probe {show_bytes(raw)} does not end with LF (docs/protocol.md silent item 1)")
        if self.gone is not None:
            raise StoppedAnswering(self.gone)
        if self.lost is not None:
            raise PortLost(self.lost)
        command, problems = diagnose(raw, spec.COMMAND)
        self._guard(raw, command)
        if timeout is None and problems:
            # A malformed command is answered (an alarm) or not at once: no move to wait for, even when
            # its fields read as a move (vel 00 would make the wait endless).
            timeout = self.settings.timeout
        try:
            ex = self.client.transact(raw, timeout=timeout)
        except ResponseTimeout as exc:
            p = Probe.silence(self.test, raw, exc.partial)
            self.latched = None
        except CommunicationHalted as exc:
            raise DeviceAbort(f"the client stopped sending after repeated communication errors "
                              f"(the vendor's host duty): {exc}") from exc
        except (SerialException, OSError) as exc:  # after ResponseTimeout, itself a TimeoutError
            self.lost = (f"the port {self.settings.port} failed while sending {show_bytes(raw)}: {exc}. "
                         f"The adapter or device went away (unplugged, powered off, connection closed)")
            raise PortLost(self.lost) from None
        else:
            p = Probe(self.test, ex)
            self._learn(command, p)
        self.log.append(p)
        self.silent_in_row = self.silent_in_row + 1 if p.silent else 0
        if self.silent_in_row >= SILENT_LIMIT and not self._checking:
            self.settle()  # is anyone there? StoppedAnswering if not, so no check talks on into silence
        return p

    @property
    def homed(self) -> bool | None:
        """Is the axis homed, as the engine knows it from the answers (None: not known)?"""
        homed: bool | None = self.client.conversation.knowledge.homed.value
        return homed

    @property
    def position(self) -> int | None:
        """The axis position as the engine knows it from the answers (None: not known)."""
        position: int | None = self.client.conversation.knowledge.position.value
        return position

    def send(self, frame: Frame, *, timeout: float | None = None) -> Probe:
        return self.probe(frame.to_bytes(), timeout=timeout)

    def _learn(self, command: Frame | None, p: Probe) -> None:
        if p.latency is not None and command is not None:
            self.latencies.setdefault(command.header, []).append(p.latency)
        if p.alarm is not None:
            self.latched = p.alarm.code != spec.ALARM_NONE
        elif p.frame is not None:  # any other answer: nothing is latched now
            self.latched = False
        if isinstance(p.frame, ReadVersionAnswer) and not p.errors:
            self.version = self.version or p.frame.version
        if p.normal and isinstance(p.frame, (ReadOutputsAnswer, WriteOutputsAnswer)):
            self.outputs = p.frame.o

    def _guard(self, raw: bytes, command: Frame | None) -> None:
        header = raw[: spec.HEADER_WIDTH].decode("ascii", "replace")
        moving = header in spec.MOVE_HEADERS or "0" + header[1:] in spec.MOVE_HEADERS
        if not moving:
            return
        s = self.settings
        if not s.motion:
            raise MotionRefused(f"motion not allowed: pass {s.flag('allow-motion')} and "
                                f"{s.flag('safe-range')} LO:HI")
        if s.simulator:
            return  # nothing to damage: the suite may probe any target, even beyond the stroke
        if not isinstance(command, (MovePoint, MoveDirect)):
            raise MotionRefused(f"a malformed move command ({show_bytes(raw)}) is only sent to the simulator")
        homing = isinstance(command, MovePoint) and command.n == 0
        if self.homed is None and not self.latched:
            self.current_position()  # learn whether the move would home first
        if (homing or self.homed is not True) and not s.may_home:
            raise MotionRefused(f"{'homing' if homing else 'the axis may not be homed and would home'}"
                                f" first: the origin is outside the safe range {s.describe_range()}")
        if homing:
            return
        if isinstance(command, MoveDirect):
            target = command.pos
        else:
            point = self.client.conversation.knowledge.point(command.n).value
            if point is None:
                raise MotionRefused(f"point {command.n:X}'s position is not known: read it first")
            target = point.pos
        if not s.in_range(target):
            raise MotionRefused(f"target 0x{target:06X} is outside the safe range {s.describe_range()}")

    def drain(self, quiet: float) -> bytes:
        """Read and drop what comes until the line has been quiet for ``quiet`` seconds (at most ten
        times that): the late answer of a probe an interruption cut short must not pass for the answer
        to the next command."""
        port = self.client.port
        out = b""
        start = last = time.monotonic()
        try:
            while time.monotonic() - last < quiet and time.monotonic() - start < 10 * quiet:
                data = port.read(max(1, port.in_waiting))
                if data:
                    out += data
                    last = time.monotonic()
        except (SerialException, OSError) as exc:
            self.lost = f"the port {self.settings.port} failed: {exc}"
            raise PortLost(self.lost) from None
        return out

    # ---- alarms ----

    def settle(self) -> None:
        """Reset a latched alarm (or one that may be latched) and confirm normal answers are back.

        This is also the liveness check: when neither 0%C nor 0RV gets a byte back the device is gone
        (``NoAnswer``, or ``StoppedAnswering`` when it answered earlier). A reset that answers followed
        by a silent 0RV is tried once more, so a device that stops between the two is still told apart
        from one that ignores 0RV."""
        if self.latched is False:
            return
        self.gone, self._checking = None, True
        try:
            for attempt in (1, 2):
                reset = self.send(AlarmReset())
                if reset.alarm is not None and reset.alarm.code == spec.ALARM_ESTOP:
                    raise DeviceAbort("emergency stop is active (alarm 0E): 0%C cannot clear it. Release "
                                      "the emergency stop input, then run again")
                check = self.send(ReadVersion())
                if reset.silent and check.silent:
                    heard = any(p.raw or p.partial for p in self.log)
                    if not heard:
                        raise NoAnswer(self._silence(heard))
                    self.gone = self._silence(heard)
                    raise StoppedAnswering(self.gone)
                if not check.silent or attempt == 2:
                    break
        finally:
            self._checking = False
        if check.frame is None or check.alarm is not None:
            raise DeviceAbort(f"after an alarm reset the device still gives {describe_answer(check)} "
                              f"({check.show()}): the run cannot go on")
        # A non-alarm answer ends the run of communication errors (docs/protocol.md "Behaviour the vendor
        # text states", host duty), even when it breaks a framing rule: that is for the checks to judge,
        # not a reason to stop talking.
        self.client.rearm()

    def _silence(self, heard: bool) -> str:
        wait = f"{self.settings.timeout:g} s"
        if not heard:
            return (f"no answer from the device on {self.settings.port}: neither 0%C nor 0RV got a single "
                    f"byte back within {wait}. Check that the controller is powered, the cable is plugged "
                    f"in, the port is the right one and the line is 9600 baud 8N1 (a slow device may need "
                    f"{self.settings.flag('timeout')} S)")
        answers = sum(1 for p in self.log if p.raw or p.partial)
        last = next(p for p in reversed(self.log) if p.raw or p.partial)
        return (f"the device stopped answering: it answered {answers} commands (the last: {last.show()}), "
                f"then neither 0%C nor 0RV got a byte back within {wait}. Check the power, the cable and "
                f"the emergency stop")

    # ---- positions ----

    def current_position(self) -> Probe:
        return self.send(ReadCurrent())

    def home_if_needed(self) -> None:
        """Make sure the axis is homed (homing only when allowed); MotionRefused otherwise."""
        if self.homed is None:
            self.current_position()
        if self.homed is not True:
            p = self.send(MovePoint(n=0))
            if p.frame is None or p.alarm is not None:  # a flawed but real answer is for the checks
                raise DeviceAbort(f"homing failed: {describe_answer(p)} ({p.show()})")

    def safe_targets(self, count: int) -> list[int]:
        """``count`` distinct positions spread over the safe range, hex letters included where possible."""
        assert self.settings.safe_range is not None
        lo, hi = self.settings.safe_range
        span = hi - lo
        picks = [lo + span * k // max(count, 1) + (0xAB if span > 0x200 else 0) for k in range(1, count + 1)]
        out = []
        for t in picks:
            t = min(max(t, lo), hi)
            if t not in out:
                out.append(t)
        return out or [lo]

    # ---- evidence ----

    def probes_for(self, test: str) -> list[Probe]:
        """The evidence of one check: probes it cited (shared samples), then those it sent."""
        return self.cited.get(test, []) + [p for p in self.log if p.test == test]

    def cite(self, *probes: Probe) -> None:
        """File probes sent earlier (a shared sample) as evidence of the running check too."""
        mine = self.cited.setdefault(self.test, [])
        mine += [p for p in probes if p.test != self.test and p not in mine]

    def info(self, topic: str, section: str, observed: str, *probes: Probe) -> None:
        self.infos.append(Info(topic, section, observed, list(probes)))

    def timing_table(self) -> list[tuple[str, int, float, float, float]]:
        """(command, count, min, median, max) of answer turnaround in seconds, per command header."""
        return [(h, len(v), min(v), statistics.median(v), max(v))
                for h, v in sorted(self.latencies.items()) if v]



def is_alarm(p: Probe, code: int | None = None) -> bool:
    return isinstance(p.frame, AlarmAnswer) and (code is None or p.frame.code == code)
