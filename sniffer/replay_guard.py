"""The motion guard of ``xac1 replay``: which captured move lines may be sent to this device.

The conformance suite's rules (``xac1_proto.dut.settings.Settings``: motion only with ``--allow-motion`` and
a safe range ``LO:HI``; homing only when the origin is inside it; the built-in simulator may always
move): a move line (0MP, 0MV, also read through a letter O or lower case) whose target is outside the
range, or cannot be told, is not sent. 0MP N's target is point N's position as the conversation
established it (the engine's knowledge: a 0WP or 0RP answered before), else as the snapshot read it
before the replay; whether the axis is homed likewise.
"""

from __future__ import annotations

from collections.abc import Callable

from xac1_proto import spec
from xac1_proto.codec import diagnose, show_bytes
from xac1_proto.conversation import Knowledge
from xac1_proto.dut.settings import Settings
from xac1_proto.frames import MoveDirect, MovePoint


class MotionGuard:
    """``check(raw)``: None when the line may be sent, else why not. ``knowledge``: the live
    conversation's knowledge (read at each check); ``points``/``homed``: what the snapshot found."""

    def __init__(self, settings: Settings, knowledge: Callable[[], Knowledge],
                 points: dict[int, int] | None = None, homed: bool | None = None) -> None:
        self.settings = settings
        self.knowledge = knowledge
        self.points = points or {}
        self.homed = homed

    def check(self, raw: bytes) -> str | None:
        header = raw[: spec.HEADER_WIDTH].upper().replace(spec.LETTER_O, spec.LEAD, 1)
        if header.decode("ascii", "replace") not in spec.MOVE_HEADERS:
            return None
        s = self.settings
        if not s.motion:
            return "motion not allowed: pass --allow-motion and --safe-range LO:HI"
        if s.simulator:
            return None  # nothing to damage
        command, _ = diagnose(raw, spec.COMMAND)
        if not isinstance(command, (MovePoint, MoveDirect)):
            return f"a move line that does not decode ({show_bytes(raw)}): its target cannot be told"
        k = self.knowledge()
        homed = k.homed.value if k.homed.judged else self.homed
        homing = isinstance(command, MovePoint) and command.n == 0
        if (homing or homed is not True) and not s.may_home:
            what = "homing" if homing else "the axis may not be homed and would home first"
            return f"{what}: the origin is outside the safe range {s.describe_range()}"
        if homing:
            return None
        if isinstance(command, MoveDirect):
            target: int | None = command.pos
        else:
            fact = k.point(command.n)
            target = fact.value.pos if fact.judged and fact.value is not None else self.points.get(command.n)
            if target is None:
                return f"point {command.n:X}'s position is not known"
        assert target is not None
        if not s.in_range(target):
            return f"target 0x{target:06X} is outside the safe range {s.describe_range()}"
        return None
