"""The suite's model of the device IS the one rulebook, ``xac1_proto.conversation`` (sans-IO).

How it works: every probe goes through the client, and the client judges each exchange with its own
``Conversation`` (docs/protocol.md, all of it: pairing, echoes by fields, latch, reset, storm, read-back,
errors answered with an alarm answer). ``Model`` is a view of that engine for the checks: ``judge``
gives the device-side violations of a probe as sentences (silence is ``no-answer``), and the
engine's knowledge (latched alarm, storm run, homed, position, points) answers what the random-sequence
check may send next. No rule is written here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.conversation import Conversation, Knowledge, PointData
from xac1_proto.dut.evidence import Probe


@dataclass
class Model:
    """What the conversation established about the device, and the verdict on each probe."""

    conversation: Conversation
    written: set[int] = field(default_factory=set)  # points stored during a sequence: safe to move to

    @property
    def knowledge(self) -> Knowledge:
        return self.conversation.knowledge

    @property
    def latched(self) -> int | None:
        """The latched alarm code, when one is known latched."""
        return self.knowledge.latched.value

    @property
    def comm_errors_in_row(self) -> int:
        return self.knowledge.storm_run

    @property
    def homed(self) -> bool | None:
        return self.knowledge.homed.value

    @property
    def position(self) -> int | None:
        return self.knowledge.position.value

    def point(self, n: int) -> PointData | None:
        return self.knowledge.point(n).value

    def judge(self, p: Probe) -> list[str]:
        """The device-side violations of one probe (the engine's verdict), as sentences."""
        problems = [str(v) for v, side in zip(p.violations, p.exchange.sides, strict=True)
                    if side == spec.DEVICE_SIDE and v.is_error]
        if p.timed_out:
            problems.append(f"{spec.VIOLATION_TABLE['no-answer'].meaning}: silence after "
                            f"{p.command_header} (no-answer)")
        return problems
