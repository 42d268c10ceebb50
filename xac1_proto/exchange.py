"""One command/answer exchange as data, and what the client raises for it (sans-IO).

The client sends a command, feeds what comes back through the ``Framer`` and stops at the first
``FrameBytes``: that is the answer. It is judged by the client's own ``conversation.Conversation`` (the
one rulebook: docs/protocol.md "Violation codes", echoes by fields, read-back, latch, the storm run of
the host duty); ``Exchange.violations`` holds that verdict's violations, with ``garbage`` first for bytes
that formed no frame. Nothing here touches a port or a clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import spec
from .codec import show_bytes
from .errors import AlarmError, ProtocolError, Violation
from .frames import AlarmAnswer, Frame


@dataclass(frozen=True)
class Exchange:
    """What one exchange put on the line and got back.

    ``sent``: the command bytes; ``raw``: the answer bytes as received (b"" when none); ``frame``: the
    answer decoded leniently (None when it does not decode); ``violations``: every deviation found in
    the answer; ``latency``: seconds from the command's last byte to the answer's first byte;
    ``junk``: bytes received during the exchange that formed no frame (before the answer, or after it
    in the same read); ``stale``: bytes that were waiting before the command was sent (a late answer
    to an earlier exchange, or noise), discarded and reported here; ``sides``: whose fault each of
    ``violations`` is (a ``conversation.side_of`` per violation).
    """

    sent: bytes
    raw: bytes
    frame: Frame | None
    violations: list[Violation]
    latency: float | None
    junk: bytes = b""
    stale: bytes = b""
    t_sent: float | None = field(default=None, compare=False)

    @property
    def sides(self) -> list[spec.Side]:
        return [spec.VIOLATION_TABLE[v.code].side(spec.DEVICE_SIDE) for v in self.violations]

    @property
    def errors(self) -> list[Violation]:
        """The violations that break a rule (notices left out)."""
        return [v for v in self.violations if v.is_error]

    @property
    def alarm(self) -> AlarmAnswer | None:
        return self.frame if isinstance(self.frame, AlarmAnswer) else None


def answer_or_raise(exchange: Exchange) -> Frame:
    """The answer frame of a clean exchange; ``ProtocolError`` for the first rule it breaks,
    ``AlarmError`` for an alarm answer (code and meaning from the spec's table)."""
    errors = exchange.errors
    if errors:
        first = errors[0]
        raise ProtocolError(first.code, f"{first.message}; answer received: {show_bytes(exchange.raw)}",
                            exchange.raw, exchange.violations)
    alarm = exchange.alarm
    if alarm is not None:
        raise AlarmError(alarm.code, alarm.meaning, alarm, exchange.raw)
    assert exchange.frame is not None  # diagnose reports a violation whenever nothing decodes
    return exchange.frame
