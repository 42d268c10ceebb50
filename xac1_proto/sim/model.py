"""The XA-C1 device model: bytes and a timestamp in, answers with the time they are due out (sans-IO).

How it works: ``receive(data, t)`` appends bytes to a line buffer; each LF ends a command line
(docs/protocol.md silent item 1: bytes with no LF yet wait, they are never answered early). A line is decoded
strictly with ``xac1_proto.parse``; a malformed line latches alarm 01 and is answered ``0%%01``. A good
command is dispatched on its header through ``_HANDLERS`` to a method that changes the device state and
returns the answer frame (built with the frame classes, sent with ``to_bytes()``) and how long the axis
moves first. While an alarm is latched every command but ``0%C`` is answered with the alarm; ``0%C``
clears all but emergency stop (docs/protocol.md "Behaviour the vendor text states"). Answers go into an
``Outbox`` due ``turnaround + motion`` later (both scaled by ``time_scale``; 0 = instant); bytes that
arrive before a move's answer is due are discarded (silent item 10). Moves take the time
``xac1_proto.motion`` gives (silent item 15); a move to a point or direct position homes first when the
axis has not been homed. Nothing here reads a clock, a port or a socket: shells feed the bytes, ask
``outbox.next_due`` when to wake, and ``outbox.pop(t)`` what to write.

Where docs/protocol.md is silent, ``SimConfig`` fields name the choice (defaults: docs/protocol.md's).
Beyond the silent items: 0WC keeps the point's V, A, O (unwritten: the silent item 6 values) and stores the
current position; a homing move of an axis whose position is unknown travels ``homing_distance``.

Fault injection (the spec-allowed faults a real device may show): ``raise_alarm``, ``set_estop``,
``fail_next_move`` (09 limit switch at completion, 0B homing error, 0A pulse calculation),
``fail_next_memory`` (04 on the next 0WP/0WC, 06 on the next 0RP/0MP N), ``set_line_faults`` (see
``outbox``), ``slow_turnaround_s``. Deviations (rule breakers, ``config.DEVIATIONS``) are switched with
``set_deviation``; so are the robustness faults (``config.ROBUSTNESS``: a hang on a long line, a NUL
that corrupts a point, lateness after a flood of errors), which last until the model is made anew.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from .. import frames as fr
from .. import motion, spec
from ..codec import diagnose, parse
from ..errors import FrameError
from ..framer import MAX_FRAME
from ..points import PointData
from .config import DEVIATIONS, LATE_AFTER_ERRORS_S, ROBUSTNESS, LineFaults, SimConfig
from .deviations import spoil
from .outbox import Outbox, Output

MAX_LINE: Final = MAX_FRAME  # longer lines are kept truncated: they are malformed anyway
MOVE_FAULTS: Final = frozenset({spec.ALARM_LIMIT, spec.ALARM_HOMING, spec.ALARM_PULSE})
MEMORY_FAULTS: Final = frozenset({spec.ALARM_MEMORY_RW, spec.ALARM_MEMORY_DATA})
RAISABLE: Final = frozenset(c for c in spec.ALARMS if c != spec.ALARM_NONE)


@dataclass(frozen=True, slots=True)
class _Segment:
    """One leg of a move, for the position during the move (status, emergency stop)."""

    t0: float
    t1: float
    start: int
    target: int
    speed: float
    a: int


class DeviceModel:
    """One simulated XA-C1; see the module docstring."""

    def __init__(self, config: SimConfig | None = None,
                 points: Mapping[int, PointData] | None = None) -> None:
        self.config = config or SimConfig()
        self.points: dict[int, PointData] = dict(points or {})
        self.homed = False
        self.position: int | None = None  # None: unknown until homed
        self.last_move: tuple[int, int, int] = (0, 0, 0)  # N, V, A of the last move
        self.outputs = 0
        self.mode = 0  # power-on: external start
        self.alarm: int | None = None  # latched alarm other than emergency stop
        self.estop = False
        self.busy_until = float("-inf")  # the pending move answer's due time
        self.slow_turnaround_s = 0.0
        self.table_changes = 0  # bumps whenever the position table changes (for state files)
        self.commands = 0
        self.discarded = 0  # bytes thrown away during moves
        self.power_cycles = 0  # times ``power_cycle`` switched it off and on
        self.outbox = Outbox(self.config.faults)
        self._line = bytearray()
        self._line_overflow = False
        self._move_fault: int | None = None
        self._memory_fault: int | None = None
        self._segments: list[_Segment] = []
        self.hung = False  # hang-on-long-line struck: nothing is answered any more
        self.late_s = 0.0  # late-after-errors struck: every answer this much later
        self._errors_in_row = 0

    # ---- bytes in ----

    def receive(self, data: bytes, t: float) -> list[Output]:
        """Take bytes the host sent at time ``t``; the answers they caused, as scheduled."""
        outs: list[Output] = []
        data = bytes(data)
        while data:
            if t < self.busy_until and self.config.discard_during_move:
                self.discarded += len(data)
                break
            lf = data.find(b"\n")
            if lf < 0:
                self._buffer(data)
                break
            self._buffer(data[: lf + 1])
            line = bytes(self._line)
            overflow = self._line_overflow
            self._line.clear()
            self._line_overflow = False
            data = data[lf + 1:]
            outs += self._command(line, max(t, self.busy_until), overflow)
        return outs

    def _buffer(self, data: bytes) -> None:
        room = MAX_LINE - len(self._line)
        if len(data) > room:
            self._line_overflow = True
            self._line += data[: max(room - 1, 0)] + data[-1:]  # keep the LF when it comes
        else:
            self._line += data

    def reset_line(self) -> None:
        """Forget a partial line and unsent answers (a TCP client went away)."""
        self._line.clear()
        self._line_overflow = False
        self.outbox.cancel()

    # ---- one command ----

    def _decode(self, line: bytes, overflow: bool) -> fr.Frame | None:
        if overflow:
            return None
        frame, code = _parse_command(line)
        if code != "lowercase-hex" or not self.config.accept_lowercase:
            return frame
        frame, violations = diagnose(line, spec.COMMAND)
        return frame if all(v.code == "lowercase-hex" for v in violations) else None

    def _robustness(self, line: bytes, overflow: bool, malformed: bool) -> None:
        """The robustness faults (``config.ROBUSTNESS``) a line sets off, when switched on."""
        devs = self.config.deviations
        if "hang-on-long-line" in devs and (overflow or len(line) > self.config.hang_bytes):
            self.hung = True
        if "nul-corrupts-point" in devs and b"\x00" in line:
            p = self._point(1)
            self.points[1] = PointData(p.v, p.a, p.o, p.pos ^ 0x100)
            self.table_changes += 1
        self._errors_in_row = self._errors_in_row + 1 if malformed else 0
        if "late-after-errors" in devs and self._errors_in_row >= self.config.flood_errors:
            self.late_s = LATE_AFTER_ERRORS_S

    def _command(self, line: bytes, t: float, overflow: bool) -> list[Output]:
        self.commands += 1
        frame = self._decode(line, overflow)
        self._robustness(line, overflow, frame is None)
        if self.hung:
            return []
        if frame is None:
            self._update_mode(None)  # silent item 11: a malformed line is communication too
            code = self.latched or self.config.malformed_alarm
            answer: fr.Frame = self._alarm(code)
            if "silent-on-malformed" in self.config.deviations:
                return []
            return [self._send(answer, t)]
        if self.latched is not None and frame.header != spec.RESET_HEADER:
            self._update_mode(None)
            return [self._send(fr.AlarmAnswer(code=self.latched), t)]
        answer, moving = _HANDLERS[frame.header](self, frame, t)
        # silent item 18: a refused command takes no effect (a refused 0CM0 switches nothing), but it is
        # communication: item 11, mode 1
        self._update_mode(None if isinstance(answer, fr.AlarmAnswer) else frame)
        out = self._send(answer, t, moving)
        if frame.header in spec.MOVE_HEADERS:
            self.busy_until = out.due
        return [out]

    def _update_mode(self, frame: fr.Frame | None) -> None:
        """Silent item 11: any line leaves mode 1 (``frame`` None: malformed or refused), except a 0CM0
        carried out (and, sticky, until 0CM1)."""
        if isinstance(frame, fr.SwitchMode):
            self.mode = frame.mode
        elif not (self.config.cm0_sticky and self.mode == 0 and self.commands > 1):
            self.mode = 1

    @property
    def latched(self) -> int | None:
        """The alarm every command is answered with, or None."""
        return spec.ALARM_ESTOP if self.estop else self.alarm

    def _alarm(self, code: int) -> fr.AlarmAnswer:
        if code == spec.ALARM_ESTOP:
            self.estop = True
        elif code != spec.ALARM_NONE:
            self.alarm = code
        return fr.AlarmAnswer(code=code)

    def _send(self, frame: fr.Frame, t: float, moving: float = 0.0) -> Output:
        cfg = self.config
        if isinstance(frame, fr.AlarmAnswer) and "alarm-not-latched" in cfg.deviations and not self.estop:
            self.alarm = None  # the deviation: answered once, then forgotten
        raw = spoil(frame, _wire(frame), cfg.deviations)
        due = t + (cfg.turnaround_s + moving) * cfg.time_scale + self.slow_turnaround_s + self.late_s
        return self.outbox.put(raw, due, cfg.wire_timing)

    def _echo(self, frame: fr.Frame, **changed: int) -> fr.Frame:
        """The echo answer of ``frame``; with ``echo-differs``, one field changed."""
        cls = fr.FRAME_CLASSES[(frame.header, spec.ANSWER)]
        fields = frame.fields()
        if "echo-differs" in self.config.deviations:
            fields.update(changed)
        return cls(**fields)

    # ---- handlers: (device, command, t) -> (answer, seconds of motion before it) ----

    def _point(self, n: int) -> PointData:
        return self.points.get(n) or PointData(*self.config.unwritten_point)

    def _store(self, n: int, data: PointData) -> None:
        if "write-not-stored" in self.config.deviations:
            return
        self.points[n] = data
        self.table_changes += 1

    def _take_memory_fault(self, code: int) -> bool:
        if self._memory_fault == code:
            self._memory_fault = None
            return True
        return False

    def _read_point(self, cmd: fr.ReadPoint, t: float) -> tuple[fr.Frame, float]:
        if self._take_memory_fault(spec.ALARM_MEMORY_DATA):
            return self._alarm(spec.ALARM_MEMORY_DATA), 0.0
        p = self._point(cmd.n)
        n = (cmd.n + 1) & 0xF if "wrong-n" in self.config.deviations else cmd.n
        return fr.ReadPointAnswer(n=n, v=p.v, a=p.a, o=p.o, pos=p.pos), 0.0

    def _write_point(self, cmd: fr.WritePoint, t: float) -> tuple[fr.Frame, float]:
        if self._take_memory_fault(spec.ALARM_MEMORY_RW):
            return self._alarm(spec.ALARM_MEMORY_RW), 0.0
        self._store(cmd.n, PointData(cmd.v, cmd.a, cmd.o, cmd.pos))
        return self._echo(cmd, pos=cmd.pos ^ 1), 0.0

    def _read_current(self, cmd: fr.ReadCurrent, t: float) -> tuple[fr.Frame, float]:
        if not self.homed or self.position is None:
            pos = 0 if "rc-before-homing-not-ffffff" in self.config.deviations else spec.UNKNOWN_POSITION
            return fr.ReadCurrentAnswer(n=0, v=0, a=0, o=self.outputs, pos=pos), 0.0
        n, v, a = self.last_move
        return fr.ReadCurrentAnswer(n=n, v=v, a=a, o=self.outputs, pos=self.position), 0.0

    def _store_current(self, cmd: fr.StoreCurrent, t: float) -> tuple[fr.Frame, float]:
        if not self.homed or self.position is None:
            return self._alarm(self.config.store_before_homing_alarm), 0.0
        if self._take_memory_fault(spec.ALARM_MEMORY_RW):
            return self._alarm(spec.ALARM_MEMORY_RW), 0.0
        old = self._point(cmd.n)
        new = PointData(old.v, old.a, old.o, self.position)
        self._store(cmd.n, new)
        p = self._point(cmd.n)
        n = (cmd.n + 1) & 0xF if "wrong-n" in self.config.deviations else cmd.n
        return fr.StoreCurrentAnswer(n=n, v=p.v, a=p.a, o=p.o, pos=p.pos), 0.0

    def _move_point(self, cmd: fr.MovePoint, t: float) -> tuple[fr.Frame, float]:
        if cmd.n == 0:
            moving, fault = self._home(t)
            if fault is not None:
                return fault, moving
            self.last_move = (0, 0, 0)
            return fr.MovePointAnswer(n=0, v=0, a=0, o=self.outputs, pos=0), moving
        if cmd.n not in self.points:
            return self._alarm(self.config.position_alarm), 0.0
        if self._take_memory_fault(spec.ALARM_MEMORY_DATA):
            return self._alarm(spec.ALARM_MEMORY_DATA), 0.0
        p = self.points[cmd.n]
        moving, fault = self._move(p.pos, self.config.speeds.point_speed(p.v), p.a, t)
        if fault is not None:
            return fault, moving
        self.last_move = (cmd.n, p.v, p.a)
        if self.config.point_move_sets_outputs:
            self.outputs = p.o
        n = (cmd.n + 1) & 0xF if "wrong-n" in self.config.deviations else cmd.n
        return fr.MovePointAnswer(n=n, v=p.v, a=p.a, o=p.o, pos=p.pos), moving

    def _move_direct(self, cmd: fr.MoveDirect, t: float) -> tuple[fr.Frame, float]:
        moving, fault = self._move(cmd.pos, self.config.speeds.direct_speed(cmd.vel), cmd.a, t)
        if fault is not None:
            return fault, moving
        self.last_move = (0, 0, cmd.a)
        return self._echo(cmd, pos=cmd.pos ^ 1), moving

    def _read_outputs(self, cmd: fr.ReadOutputs, t: float) -> tuple[fr.Frame, float]:
        return fr.ReadOutputsAnswer(o=self.outputs), 0.0

    def _write_outputs(self, cmd: fr.WriteOutputs, t: float) -> tuple[fr.Frame, float]:
        if "outputs-not-stored" not in self.config.deviations:
            self.outputs = cmd.o
        return self._echo(cmd, o=cmd.o ^ 1), 0.0

    def _read_version(self, cmd: fr.ReadVersion, t: float) -> tuple[fr.Frame, float]:
        return fr.ReadVersionAnswer(version=self.config.version), 0.0

    def _switch_mode(self, cmd: fr.SwitchMode, t: float) -> tuple[fr.Frame, float]:
        return self._echo(cmd, mode=cmd.mode ^ 1), 0.0

    def _alarm_reset(self, cmd: fr.AlarmReset, t: float) -> tuple[fr.Frame, float]:
        if self.estop and "estop-cleared" not in self.config.deviations:
            self.alarm = None  # vendor §6: the reset clears every alarm but emergency stop
            return fr.AlarmAnswer(code=spec.ALARM_ESTOP), 0.0  # silent item 3
        self.estop = False
        self.alarm = None
        return fr.AlarmResetAnswer(), 0.0

    # ---- motion ----

    def _scaled(self, seconds: float) -> float:
        return seconds * self.config.time_scale

    def _home(self, t: float) -> tuple[float, fr.AlarmAnswer | None]:
        """Home the axis; seconds of motion, and the alarm answer when homing fails."""
        speeds = self.config.speeds
        start = self.position if self.position is not None else self.config.homing_distance
        moving = motion.move_time(start, speeds.homing_pps, speeds.homing_accel)
        self._segments = [_Segment(t, t + self._scaled(moving), start, 0, speeds.homing_pps,
                                   speeds.homing_accel)]
        if self._move_fault == spec.ALARM_HOMING:
            self._move_fault = None
            self.homed, self.position = False, None
            return moving, self._alarm(spec.ALARM_HOMING)
        self.homed, self.position = True, 0
        return moving, None

    def _move(self, target: int, speed: float, a: int, t: float) -> tuple[float, fr.AlarmAnswer | None]:
        """Home if needed, then move to ``target``; seconds of motion, and an alarm answer if any."""
        lo, hi = self.config.stroke
        if not lo <= target <= hi:
            return 0.0, self._alarm(self.config.position_alarm)
        if self._move_fault == spec.ALARM_PULSE:
            self._move_fault = None
            return 0.0, self._alarm(spec.ALARM_PULSE)
        moving = 0.0
        if not self.homed or self.position is None or self._move_fault == spec.ALARM_HOMING:
            moving, fault = self._home(t)
            if fault is not None:
                return moving, fault
        else:
            self._segments = []
        start = self.position if self.position is not None else 0
        if "move-not-performed" in self.config.deviations:
            target = start
        leg = motion.move_time(target - start, speed, a)
        t0 = t + self._scaled(moving)
        self._segments.append(_Segment(t0, t0 + self._scaled(leg), start, target, speed, a))
        self.position = target
        moving += leg
        if self._move_fault == spec.ALARM_LIMIT:
            self._move_fault = None
            return moving, self._alarm(spec.ALARM_LIMIT)
        return moving, None

    def position_now(self, t: float) -> int | None:
        """Where the axis is at ``t`` (during a move: on its way), None when unknown."""
        for seg in self._segments:
            if seg.t0 <= t < seg.t1:
                scale = self.config.time_scale or 1.0
                return motion.position_at(seg.start, seg.target, seg.speed, seg.a, (t - seg.t0) / scale)
        return self.position if self.homed else None

    # ---- fault injection (docs/protocol.md "Alarms") ----

    def raise_alarm(self, code: int, t: float | None = None) -> list[Output]:
        """Latch alarm ``code`` now (0E: emergency stop on); the device sends nothing by itself."""
        if code not in RAISABLE:
            raise ValueError(f"alarm code must be one of {_codes(RAISABLE)}, got {code:02X}")
        if code == spec.ALARM_ESTOP:
            return self.set_estop(True, t)
        self.alarm = code
        return []

    def set_estop(self, on: bool, t: float | None = None) -> list[Output]:
        """Emergency stop input on or off. On during a move: the move stops where it is and its
        answer becomes ``0%%0E``. Off: the stop clears; the axis must home again (silent item 3)."""
        if not on:
            if self.estop and self.config.estop_rehome:
                self.homed = False
                self.position = None
            self.estop = False
            return []
        self.estop = True
        if t is not None and t < self.busy_until:
            self.position = self.position_now(t)
            self.outbox.cancel()
            self.busy_until = t
            self._segments = []
            return [self._send(fr.AlarmAnswer(code=spec.ALARM_ESTOP), t)]
        return []

    def power_cycle(self) -> list[Output]:
        """Switch the unit off and on: the power-on state (not homed, position unknown, mode 0, OUT ports
        off, nothing latched but a pressed stop input); a move, a partial line and unsent answers are
        lost, and a robustness fault that struck (a hang, late answers) clears. The position table is kept
        (it is the controller's memory), and so is what the bench set: the stop input, line faults, pending
        faults, deviations."""
        self.homed, self.position, self.mode, self.outputs, self.alarm = False, None, 0, 0, None
        self.hung, self.late_s, self._errors_in_row = False, 0.0, 0  # a struck robustness fault clears
        self.busy_until = float("-inf")
        self._segments = []
        self.reset_line()
        self.power_cycles += 1
        return []

    def fail_next_move(self, code: int) -> None:
        """The next move fails: 09 limit switch at completion, 0B homing error, 0A pulse calculation."""
        if code not in MOVE_FAULTS:
            raise ValueError(f"move fault must be one of {_codes(MOVE_FAULTS)}, got {code:02X}")
        self._move_fault = code

    def fail_next_memory(self, code: int) -> None:
        """04: the next 0WP/0WC fails; 06: the next 0RP/0MP N reads bad data."""
        if code not in MEMORY_FAULTS:
            raise ValueError(f"memory fault must be one of {_codes(MEMORY_FAULTS)}, got {code:02X}")
        self._memory_fault = code

    def set_line_faults(self, faults: LineFaults) -> None:
        self.config = dataclasses.replace(self.config, faults=faults)
        self.outbox.set_faults(faults)

    def set_deviation(self, name: str, on: bool = True) -> None:
        if name not in DEVIATIONS and name not in ROBUSTNESS:
            raise ValueError(f"unknown deviation {name!r}; known: {', '.join([*DEVIATIONS, *ROBUSTNESS])}")
        devs = set(self.config.deviations)
        (devs.add if on else devs.discard)(name)
        self.config = dataclasses.replace(self.config, deviations=frozenset(devs))

    def status(self, t: float | None = None) -> dict[str, Any]:
        """The device state as plain data (for ``status`` and tests)."""
        pos = self.position_now(t) if t is not None else (self.position if self.homed else None)
        return {
            "mode": self.mode,
            "homed": self.homed,
            "position": pos,
            "moving": t is not None and t < self.busy_until,
            "last_move": self.last_move,
            "outputs": self.outputs,
            "alarm": self.latched,
            "estop": self.estop,
            "version": self.config.version,
            "points": {n: dataclasses.astuple(p) for n, p in sorted(self.points.items())},
            "pending_faults": {"move": self._move_fault, "memory": self._memory_fault},
            "line_faults": self.config.faults,
            "slow_turnaround_s": self.slow_turnaround_s,
            "deviations": sorted(self.config.deviations),
            "commands": self.commands,
            "discarded": self.discarded,
        }


@functools.lru_cache(maxsize=512)
def _parse_command(line: bytes) -> tuple[fr.Frame | None, str | None]:
    """``parse`` a command line, remembered (hosts repeat their commands): (frame, None) or
    (None, violation code)."""
    try:
        return parse(line, spec.COMMAND), None
    except FrameError as exc:
        return None, exc.code


@functools.lru_cache(maxsize=512)
def _wire(frame: fr.Frame) -> bytes:
    """``frame.to_bytes()``, remembered (frames are frozen, so equal frames have equal bytes)."""
    return frame.to_bytes()


def _codes(codes: frozenset[int]) -> str:
    return ", ".join(f"{c:02X}" for c in sorted(codes))


Handler = Callable[[DeviceModel, Any, float], tuple[fr.Frame, float]]

# Dispatch by header (docs/protocol.md "Frames").
_HANDLERS: Final[dict[str, Handler]] = {
    fr.ReadPoint.HEADER: DeviceModel._read_point,
    fr.WritePoint.HEADER: DeviceModel._write_point,
    fr.ReadCurrent.HEADER: DeviceModel._read_current,
    fr.StoreCurrent.HEADER: DeviceModel._store_current,
    fr.MovePoint.HEADER: DeviceModel._move_point,
    fr.MoveDirect.HEADER: DeviceModel._move_direct,
    fr.ReadOutputs.HEADER: DeviceModel._read_outputs,
    fr.WriteOutputs.HEADER: DeviceModel._write_outputs,
    fr.ReadVersion.HEADER: DeviceModel._read_version,
    fr.SwitchMode.HEADER: DeviceModel._switch_mode,
    fr.AlarmReset.HEADER: DeviceModel._alarm_reset,
}
