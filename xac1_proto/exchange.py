"""One command/answer exchange as data, how its answer is judged, and the host's storm guard (sans-IO).

The client sends a command, feeds what comes back through the ``Framer`` and stops at the first
``FrameBytes``: that is the answer. ``judge_answer`` decodes it leniently (``diagnose``) and adds the
checks that need the command (docs/protocol.md "Violation codes"): an answer to another command or another
N is ``answer-mismatch``; an echo answer (0WP, 0MV, 0WS, 0CM) that differs from its command byte for
byte is ``echo-mismatch``. The alarm answer may answer any command. Bytes that formed no frame before
the answer are ``garbage``. Nothing here touches a port or a clock: times are passed in.

``StormGuard`` is the vendor's host duty (docs/protocol.md "Behaviour the vendor text states"): it counts
``0%%01`` answers since the last normal answer (latched repeats count; the reset answer ``0%C00`` and
other alarm answers neither count nor end the run) and halts once the count reaches the limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import spec
from .codec import diagnose, show_bytes
from .errors import AlarmError, ProtocolError, Violation
from .frames import AlarmAnswer, Frame

# Non-echo commands whose answer carries the N asked for (0RP, 0WC, 0MP); echoes are checked whole.
_N_ANSWERED = frozenset(
    h for (h, role), fs in spec.SPECS.items()
    if role == spec.COMMAND and "n" in fs.layout and (h, spec.ANSWER) in spec.SPECS
    and not spec.SPECS[(h, spec.ANSWER)].echo
)


@dataclass(frozen=True)
class Exchange:
    """What one exchange put on the line and got back.

    ``sent``: the command bytes; ``raw``: the answer bytes as received (b"" when none); ``frame``: the
    answer decoded leniently (None when it does not decode); ``violations``: every deviation found in
    the answer; ``latency``: seconds from the command's last byte to the answer's first byte;
    ``junk``: bytes received during the exchange that formed no frame (before the answer, or after it
    in the same read); ``stale``: bytes that were waiting before the command was sent (a late answer
    to an earlier exchange, or noise), discarded and reported here.
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
    def errors(self) -> list[Violation]:
        """The violations that break a rule (notices left out)."""
        return [v for v in self.violations if v.code not in spec.NOTICES]

    @property
    def alarm(self) -> AlarmAnswer | None:
        return self.frame if isinstance(self.frame, AlarmAnswer) else None


def judge_answer(sent: bytes, raw: bytes, junk: bytes = b"") -> tuple[Frame | None, list[Violation]]:
    """Decode the answer ``raw`` to the command ``sent`` and list every deviation (never raises)."""
    frame, violations = diagnose(raw, spec.ANSWER)
    out = list(violations)
    if junk:
        out.insert(0, Violation("garbage", None, f"{len(junk)} byte(s) received with the answer formed "
                                                 f"no frame: {show_bytes(junk)} (garbage)"))
    command, _ = diagnose(sent, spec.COMMAND)
    if command is None or frame is None or isinstance(frame, AlarmAnswer):
        return frame, out
    if frame.header != command.header:
        out.append(Violation("answer-mismatch", 0, f"answer to {command.header}: byte 0: expected the "
                                                   f"{command.header} answer, got {frame.header} "
                                                   f"(answer-mismatch)"))
        return frame, out
    if command.header in _N_ANSWERED and getattr(frame, "n", None) != getattr(command, "n", None):
        at = command.frame_spec().offsets()["n"]
        out.append(Violation("answer-mismatch", at, f"{frame.header} answer: byte {at}: expected N="
                                                    f"{getattr(command, 'n', 0):X} (the command's), got N="
                                                    f"{getattr(frame, 'n', 0):X} "
                                                    f"(answer-mismatch)"))
    if frame.frame_spec().echo and raw != sent:
        at = next((i for i, (a, b) in enumerate(zip(raw, sent, strict=False)) if a != b),
                  min(len(raw), len(sent)))
        out.append(Violation("echo-mismatch", at, f"{frame.header} answer: byte {at}: expected the echo "
                                                  f"{show_bytes(sent)}, got {show_bytes(raw)} "
                                                  f"(echo-mismatch)"))
    return frame, out


class StormGuard:
    """Count communication-error answers in a row; ``halted`` once ``limit`` is reached (None: never)."""

    def __init__(self, limit: int | None = spec.STORM_LIMIT) -> None:
        if limit is not None and limit < 1:
            raise ValueError(f"storm_limit must be a positive count or None, got {limit}")
        self.limit = limit
        self.in_row = 0

    @property
    def halted(self) -> bool:
        return self.limit is not None and self.in_row >= self.limit

    def observe(self, frame: Frame | None, clean: bool = True) -> None:
        """Account for one answer (None: nothing decoded, which changes nothing). An answer that broke
        the protocol (``clean`` False) never ends a run; a ``0%%01`` in it still counts."""
        if isinstance(frame, AlarmAnswer):
            if frame.code == spec.ALARM_COMM:
                self.in_row += 1
        elif frame is not None and clean and frame.header != spec.RESET_HEADER:
            self.in_row = 0

    def rearm(self) -> None:
        self.in_row = 0


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
