"""Evidence: what one probe put on the line and got back, and how a check states a broken rule.

Every byte the suite sends goes through ``DeviceUnderTest.probe`` and becomes a ``Probe``, judged by the
client's conversation engine (the one rulebook: ``Probe.violations`` are its verdict); a check that
finds a rule broken raises ``RuleBroken`` with the probes that show it, so the report can print the
exact bytes sent and received next to the verdict.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.codec import show_bytes
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
        got = show_bytes(self.raw) if self.raw else f"no answer{self._partial()}"
        return f"{show_bytes(self.sent)} -> {got}"

    def _partial(self) -> str:
        return f" (partial: {show_bytes(self.partial)})" if self.partial else ""


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
    """A person's summary of what came back: the bytes, then the fields by name."""
    if p.timed_out:
        return "no answer (silence)" + p._partial()
    if p.frame is None:
        return f"an undecodable answer {show_bytes(p.raw)}"
    if p.alarm is not None:
        return f"the alarm answer {show_bytes(p.raw)}: alarm {p.alarm.code:02X} ({p.alarm.meaning})"
    return f"{show_bytes(p.raw)} ({fields_text(p.frame)})"


def fields_text(frame: Frame) -> str:
    """``0RP answer: N=3 V=9 A=3 O=0 Pos=012345``: the header and each field by name, as on the wire."""
    shown = []
    for name, value in frame.fields().items():
        f = spec.FIELDS[name]
        shown.append(f"{f.label}={value if f.text else f.show(value)}")
    return f"{frame.header} {frame.role}" + (": " + " ".join(shown) if shown else "")


def differences(want: Mapping[str, object], got: Mapping[str, object]) -> str:
    """``A: expected 3, received 1; Pos: expected 001000, received 000000`` for the fields that differ."""
    return "; ".join(f"{k}: expected {want[k]}, received {got.get(k)}" for k in want if want[k] != got.get(k))
