"""A reference model of the rules docs/protocol.md states, for the random-sequence check (sans-IO).

How it works: the model holds what the host can know for sure: every point's data (read before the
sequence starts, then updated by writes), the OUT ports, whether the axis is homed, its position, the
latched alarm and the firmware version. ``judge(command, answer)`` compares one decoded answer with the
stated rules and returns the broken ones as messages, then updates the model. Whatever docs/protocol.md
leaves open becomes "unknown" and is learnt from the next answer instead of checked: the alarm code of
a malformed command (silent item 1), the OUT ports after 0MP N (item 8), 0RC's N, V, A and O after a move
(items 7-9), the position right after homing (item 7), V, A and O of a 0WC answer. Moves go only to
points stored during the sequence: what a point never written does on 0MP is silent (item 5).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.frames import (
    AlarmAnswer,
    AlarmReset,
    AlarmResetAnswer,
    Frame,
    MoveDirect,
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
    WriteOutputs,
    WritePoint,
)


@dataclass(frozen=True)
class Point:
    v: int
    a: int
    o: int
    pos: int


@dataclass
class Model:
    """What the host knows for sure; ``None`` marks what a silent point left unknown."""

    points: dict[int, Point]
    outputs: int | None
    homed: bool | None = None
    position: int | None = None
    latched: int | None = None  # alarm code, while latched
    version: str | None = None
    comm_errors_in_row: int = 0
    written: set[int] = field(default_factory=set)  # points stored during the sequence: safe to move to

    def judge(self, command: Frame | bytes, answer: Frame | None, raw: bytes, errors: list[str]) -> list[str]:
        """Broken rules in this answer to ``command`` (a frame, or the bytes of a malformed command)."""
        problems = [f"the answer breaks the grammar: {e}" for e in errors]
        if answer is None:
            problems.append("no decodable answer")
            self._lost()
            return problems
        if isinstance(answer, AlarmAnswer):
            if answer.code == spec.ALARM_COMM:
                self.comm_errors_in_row += 1
        elif not isinstance(answer, AlarmResetAnswer):
            self.comm_errors_in_row = 0
        if isinstance(command, bytes):  # malformed: an alarm answer (any code, silent item 1)
            if not isinstance(answer, AlarmAnswer):
                problems.append(f"a malformed command got {answer} instead of an alarm answer")
            elif self.latched is not None and answer.code != self.latched:
                problems.append(f"alarm {self.latched:02X} is latched but the answer is alarm "
                                f"{answer.code:02X}")
            if isinstance(answer, AlarmAnswer) and self.latched is None:
                self.latched = answer.code
            return problems
        if isinstance(command, AlarmReset):
            if not isinstance(answer, AlarmResetAnswer) or raw != AlarmResetAnswer().to_bytes():
                problems.append(f"0%C answered {answer}, expected 0%C00")
            self.latched = None
            return problems
        if self.latched is not None:
            if not (isinstance(answer, AlarmAnswer) and answer.code == self.latched):
                problems.append(f"alarm {self.latched:02X} is latched, but {command.header} got {answer}")
            return problems
        if isinstance(answer, AlarmAnswer):
            problems.append(f"{command.header} got alarm {answer.code:02X} ({answer.meaning}) where the "
                            f"stated rules give a normal answer")
            self.latched = answer.code
            if isinstance(command, (MovePoint, MoveDirect)):
                self.position, self.homed = None, None
            return problems
        problems += self._normal(command, answer, raw)
        return problems

    def _lost(self) -> None:
        self.latched = None
        self.homed, self.position, self.outputs = None, None, None

    def _normal(self, c: Frame, a: Frame, raw: bytes) -> list[str]:
        out: list[str] = []
        if a.header != c.header:
            return [f"{c.header} got the answer of another command: {a}"]
        if spec.SPECS[(c.header, spec.ANSWER)].echo and raw != c.to_bytes():
            out.append(f"{c.header} echo differs: sent {c.to_bytes()!r}, got {raw!r}")
        if isinstance(c, ReadPoint):
            assert isinstance(a, ReadPointAnswer)
            known = self.points.get(c.n)
            got = Point(a.v, a.a, a.o, a.pos)
            if a.n != c.n:
                out.append(f"0RP{c.n:X} answered N={a.n:X}")
            elif known is not None and got != known:
                out.append(f"0RP{c.n:X} reads V={a.v} A={a.a} O={a.o} Pos={a.pos:06X}; the model holds "
                           f"V={known.v} A={known.a} O={known.o} Pos={known.pos:06X}")
            self.points[c.n] = got if known is None else known
        elif isinstance(c, WritePoint):
            self.points[c.n] = Point(c.v, c.a, c.o, c.pos)
            self.written.add(c.n)
        elif isinstance(c, ReadCurrent):
            assert isinstance(a, ReadCurrentAnswer)
            out += self._judge_position(a)
        elif isinstance(c, StoreCurrent):
            assert isinstance(a, StoreCurrentAnswer)
            if a.n != c.n:
                out.append(f"0WC{c.n:X} answered N={a.n:X}")
            if self.position is not None and a.pos != self.position:
                out.append(f"0WC{c.n:X} answered Pos={a.pos:06X}, the axis is at {self.position:06X}")
            self.points[c.n] = Point(a.v, a.a, a.o, a.pos)
            self.written.add(c.n)
        elif isinstance(c, MovePoint):
            assert isinstance(a, MovePointAnswer)
            if a.n != c.n:
                out.append(f"0MP{c.n:X} answered N={a.n:X}")
            self.homed = True
            self.position = None if c.n == 0 else self.points[c.n].pos
            if c.n != 0:
                self.outputs = None  # silent item 8
        elif isinstance(c, MoveDirect):
            self.homed, self.position = True, c.pos
        elif isinstance(c, ReadOutputs):
            assert isinstance(a, ReadOutputsAnswer)
            if self.outputs is not None and a.o != self.outputs:
                out.append(f"0RS reads O={a.o}, 0WS wrote O={self.outputs}")
            self.outputs = a.o
        elif isinstance(c, WriteOutputs):
            self.outputs = c.o
        elif isinstance(c, ReadVersion):
            assert isinstance(a, ReadVersionAnswer)
            if self.version is not None and a.version != self.version:
                out.append(f"0RV answered {a.version}, earlier {self.version}")
            self.version = a.version
        elif isinstance(c, SwitchMode):
            pass  # the echo is all that is stated
        return out

    def _judge_position(self, a: ReadCurrentAnswer) -> list[str]:
        if self.homed is False:
            if (a.n, a.v, a.a, a.pos) != (0, 0, 0, spec.UNKNOWN_POSITION):
                return [f"0RC before homing answered N={a.n:X} V={a.v} A={a.a} Pos={a.pos:06X}; expected "
                        f"N=0 V=0 A=0 Pos=FFFFFF"]
            return []
        if a.pos == spec.UNKNOWN_POSITION:
            if self.homed:
                return ["0RC after homing reads the unknown position FFFFFF"]
            self.homed = False  # learnt: FFFFFF is the never-homed answer
            return []
        if self.position is not None and a.pos != self.position:
            return [f"0RC reads Pos={a.pos:06X}; the last move went to {self.position:06X}"]
        self.homed, self.position = True, a.pos
        return []
