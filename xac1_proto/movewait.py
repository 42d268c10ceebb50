"""How long a host must wait for a move's answer (sans-IO).

docs/protocol.md "Behaviour the vendor text states".

0MP and 0MV answer only when the move has ended, homing first when the axis is not homed, so their
timeout is the move's duration plus a margin, never the turnaround timeout. ``MoveBudget`` keeps what
the host has learnt from the answers it saw: the last known position, whether the axis is homed, and
each point's V, A and Pos (from 0RP, 0WP, 0WC and 0MP answers). It prices a move with
``motion.move_time`` and the speed table; whatever it does not know it takes at its worst: position
unknown means the far end of the stroke, an unknown point means the slowest speed and ramp over the
whole stroke, an axis that may not be homed means homing first. After a move that got no clean answer
(alarm, timeout, bad frame) the position is unknown again; an emergency stop also unhomes the axis.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import motion, spec
from .frames import (
    AlarmAnswer,
    Frame,
    MoveDirect,
    MoveDirectAnswer,
    MovePoint,
    MovePointAnswer,
    PointAnswer,
    ReadCurrentAnswer,
)

FULL_STROKE = spec.UNKNOWN_POSITION - 1  # docs/protocol.md silent item 5: the whole range but FFFFFF


@dataclass(frozen=True)
class PointData:
    v: int
    a: int
    pos: int


class MoveBudget:
    """Track position knowledge from answers and price moves in seconds of (unscaled) motion."""

    def __init__(self, speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS, stroke: int = FULL_STROKE) -> None:
        if not 0 < stroke <= FULL_STROKE:
            raise ValueError(f"stroke must be 1-{FULL_STROKE} pulses, got {stroke}")
        self.speeds = speeds
        self.stroke = stroke
        self.position: int | None = None  # last known position, None when unknown
        self.homed: bool | None = None  # None: not known
        self.points: dict[int, PointData] = {}

    def _homing_time(self) -> float:
        distance = self.position if self.position is not None else self.stroke
        return motion.move_time(distance, self.speeds.homing_pps, self.speeds.homing_accel)

    def _travel(self, start: int | None, target: int, speed_pps: float, a: int) -> float:
        # an unknown start is taken at the farther end of the stroke
        distance = max(target, self.stroke - target, 0) if start is None else abs(target - start)
        return motion.move_time(distance, speed_pps, a)

    def estimate(self, command: Frame) -> float | None:
        """Seconds the move ``command`` may take (homing included); None for a command that is no move."""
        if not isinstance(command, (MovePoint, MoveDirect)):
            return None
        if isinstance(command, MovePoint) and command.n == 0:
            return self._homing_time()
        if isinstance(command, MoveDirect):
            target, speed, a = command.pos, self.speeds.direct_speed(command.vel), command.a
        elif command.n in self.points:
            point = self.points[command.n]
            target, speed, a = point.pos, self.speeds.point_speed(point.v), point.a
        else:  # a point never seen: slowest speed and ramp over the whole stroke
            worst_a = max(spec.ACCEL_RAMP_S, key=lambda k: spec.ACCEL_RAMP_S[k])
            return self._homing_time() + motion.move_time(self.stroke, self.speeds.point_speed(1), worst_a)
        after_homing = self._homing_time() + self._travel(0, target, speed, a)
        if self.homed is False:
            return after_homing
        as_is = self._travel(self.position, target, speed, a)
        return as_is if self.homed else max(after_homing, as_is)

    def observe(self, command: Frame | None, answer: Frame | None, clean: bool) -> None:
        """Learn from one exchange: ``answer`` is None when none decoded; ``clean`` is False when it
        broke the protocol (then only a move's uncertainty is recorded)."""
        moving = isinstance(command, (MovePoint, MoveDirect))
        if isinstance(answer, AlarmAnswer):
            if answer.code == spec.ALARM_ESTOP:
                self.homed, self.position = False, None
            elif moving:
                self.position = None
            return
        if answer is None or not clean:
            if moving:
                self.position = None
                self.homed = None
            return
        if isinstance(answer, ReadCurrentAnswer):
            known = answer.pos != spec.UNKNOWN_POSITION
            self.homed, self.position = known, (answer.pos if known else None)
        elif isinstance(answer, (MovePointAnswer, MoveDirectAnswer)):
            self.homed, self.position = True, answer.pos
        if isinstance(answer, PointAnswer) and not isinstance(answer, ReadCurrentAnswer) and answer.n:
            self.points[answer.n] = PointData(answer.v, answer.a, answer.pos)
