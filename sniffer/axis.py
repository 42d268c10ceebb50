"""What the sniffer can tell about the axis from the line, to give a move a fair ``no-answer`` deadline.

docs/protocol.md silent item 17: a move's answer may take its estimated move time, doubled, plus the plain
timeout. The estimate uses ``xac1_proto.motion`` (silent item 15) with what the answers revealed: the
current position (0RC, 0MP and 0MV answers; ``FFFFFF`` means unknown) and the position table (0RP,
0WP, 0WC and 0MP answers). Whatever is unknown is assumed at its worst, so an estimate is never short
because the sniffer joined late: an unknown start homes from the far end of the stroke first, an
unknown point is as far away as the stroke allows at the slowest speed. An alarm answer to a move and
an emergency stop make the position unknown again.
"""

from __future__ import annotations

from xac1_proto import Frame, frames, motion, spec

STROKE_END = spec.UNKNOWN_POSITION - 1  # the farthest position a move can reach (silent item 5)


class AxisEstimate:
    """Position and position table as far as the answers tell; ``move_time`` estimates a move."""

    def __init__(self, speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS) -> None:
        self.speeds = speeds
        self.position: int | None = None
        self.points: dict[int, tuple[int, int, int]] = {}  # n -> (v, a, pos)

    def forget_position(self) -> None:
        self.position = None

    def learn(self, answer: Frame) -> None:
        """Update from a decoded normal answer."""
        if isinstance(answer, frames.PointAnswer):
            if answer.n >= 1 and not isinstance(answer, frames.ReadCurrentAnswer):
                self.points[answer.n] = (answer.v, answer.a, answer.pos)
            if isinstance(answer, (frames.MovePointAnswer, frames.ReadCurrentAnswer)):
                self.position = None if answer.pos == spec.UNKNOWN_POSITION else answer.pos
        elif isinstance(answer, frames.MoveDirectAnswer):
            self.position = answer.pos

    def move_time(self, command: Frame) -> float:
        """Seconds the move ``command`` (0MP or 0MV) may take, homing included, at worst."""
        s = self.speeds
        start = self.position
        t = 0.0
        if start is None:  # not homed, or unknown: home from the far end first
            t += motion.move_time(STROKE_END, s.homing_pps, s.homing_accel)
            start = 0
        if isinstance(command, frames.MoveDirect):
            return t + motion.move_time(command.pos - start, s.direct_speed(command.vel), command.a)
        if isinstance(command, frames.MovePoint):
            if command.n == 0:
                return t + motion.move_time(start, s.homing_pps, s.homing_accel)
            known = self.points.get(command.n)
            if known is None:
                far = max(start, STROKE_END - start)
                return t + motion.move_time(far, s.point_speed(1), 1)
            v, a, pos = known
            return t + motion.move_time(pos - start, s.point_speed(v), a)
        return t
