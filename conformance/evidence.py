"""Evidence: what one probe put on the line and got back, and how a check states a broken rule.

Every byte the suite sends goes through ``DeviceUnderTest.probe`` and becomes a ``Probe``, judged by the
client's conversation engine (the one rulebook: ``Probe.violations`` are its verdict); a check that
finds a rule broken raises ``RuleBroken`` with the probes that show it, so the report can print the
exact bytes sent and received next to the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.errors import Violation
from xac1_proto.exchange import Exchange
from xac1_proto.frames import AlarmAnswer, Frame

_ESCAPES = {0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}


def wire(data: bytes) -> str:
    """Bytes as they read on the wire: printable ASCII as is, ``\\r``, ``\\n``, ``\\xNN``."""
    return "".join(chr(b) if 0x20 <= b < 0x7F and b != 0x5C else _ESCAPES.get(b, f"\\x{b:02X}")
                   for b in data)


@dataclass(eq=False)
class Probe:
    """One command and its answer: the client's ``Exchange`` plus what the suite adds (the check that
    sent it, silence, notes). A probe that timed out holds an exchange with ``raw`` b"" and no frame,
    and keeps the bytes that did come in ``partial``. Probes compare by identity: two identical
    exchanges are two pieces of evidence."""

    test: str | None
    exchange: Exchange
    timed_out: bool = False
    partial: bytes = b""
    notes: list[str] = field(default_factory=list)

    @classmethod
    def silence(cls, test: str | None, sent: bytes, partial: bytes = b"") -> Probe:
        """A command that got no frame-shaped answer within the timeout."""
        return cls(test, Exchange(sent=sent, raw=b"", frame=None, violations=[], latency=None),
                   timed_out=True, partial=partial)

    @property
    def silent(self) -> bool:
        """Not a single byte came back (a timeout with nothing partial)."""
        return self.timed_out and not self.partial

    @property
    def sent(self) -> bytes:
        return self.exchange.sent

    @property
    def raw(self) -> bytes:
        return self.exchange.raw

    @property
    def frame(self) -> Frame | None:
        return self.exchange.frame

    @property
    def violations(self) -> list[Violation]:
        return self.exchange.violations

    @property
    def latency(self) -> float | None:
        return self.exchange.latency

    @property
    def junk(self) -> bytes:
        return self.exchange.junk

    @property
    def errors(self) -> list[Violation]:
        """Violations that break a stated rule (notices such as ``lowercase-hex`` left out)."""
        return self.exchange.errors

    @property
    def alarm(self) -> AlarmAnswer | None:
        return self.exchange.alarm

    @property
    def normal(self) -> bool:
        """A decoded, rule-abiding answer that is not an alarm."""
        return self.frame is not None and self.alarm is None and not self.errors

    @property
    def answered(self) -> bool:
        """A decoded answer that is not an alarm (framing flaws aside: the framing checks judge those)."""
        return self.frame is not None and self.alarm is None

    def echoes(self) -> bool:
        """The answer is its command's echo, as the rulebook judges it (``xac1_proto.conversation``: the
        same header and field values; framing flaws aside, the framing checks judge those)."""
        mismatch = {"echo-mismatch", "answer-mismatch", "error-accepted"}
        return self.answered and not any(v.code in mismatch for v in self.violations) \
            and self.frame is not None and self.frame.header == self.command_header

    @property
    def command_header(self) -> str:
        return self.sent[: spec.HEADER_WIDTH].decode("ascii", "replace")

    def show(self) -> str:
        got = wire(self.raw) if self.raw else f"no answer{self._partial()}"
        return f"{wire(self.sent)} -> {got}"

    def _partial(self) -> str:
        return f" (partial: {wire(self.partial)})" if self.partial else ""


class RuleBroken(AssertionError):
    """A stated rule the device broke; ``probes`` are the evidence."""

    def __init__(self, message: str, probes: list[Probe] | tuple[Probe, ...] = ()):
        super().__init__(message)
        self.probes = list(probes)


def expect(condition: object, message: str, *probes: Probe) -> None:
    """Raise ``RuleBroken(message, probes)`` unless ``condition`` holds."""
    if not condition:
        raise RuleBroken(message, probes)


def describe_answer(p: Probe) -> str:
    """A person's summary of what came back."""
    if p.timed_out:
        return "no answer (silence)" + p._partial()
    if p.frame is None:
        return f"an undecodable answer {wire(p.raw)!r}"
    if p.alarm is not None:
        return f"alarm {p.alarm.code:02X} ({p.alarm.meaning})"
    return str(p.frame)
