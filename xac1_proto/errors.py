"""The error tree: one root, ``XAC1Error``; framing and grammar errors carry a violation code and offset."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .spec import Severity, ViolationCode


class XAC1Error(Exception):
    """Root of every error this package raises on purpose."""


@dataclass(frozen=True)
class Violation:
    """One deviation from the protocol: a docs/protocol.md violation code, where, and what was wrong;
    ``rule``: the rulebook row it breaks (``xac1_proto.rules``; default: the code's plain rule);
    ``severity``: ``error`` or ``notice`` (default: the rule's, derived from its basis)."""

    code: ViolationCode
    offset: int | None
    message: str
    rule: str = ""
    severity: Severity = "error"

    def __init__(self, code: ViolationCode, offset: int | None, message: str, rule: str = "",
                 severity: Severity | None = None) -> None:
        from .rules import severity as rule_severity  # (rules imports spec, which may import this module)

        object.__setattr__(self, "code", code)
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "message", message)
        object.__setattr__(self, "rule", rule or code)
        object.__setattr__(self, "severity", severity or rule_severity(rule or code))

    @property
    def is_error(self) -> bool:
        """Does it break a rule (not a notice)?"""
        return self.severity == "error"

    def __str__(self) -> str:
        return self.message


class FrameError(XAC1Error, ValueError):
    """A frame that breaks the grammar. ``.code`` is a docs/protocol.md violation code, ``.offset`` the
    byte offset of the first bad byte (None when the frame is built, not parsed)."""

    def __init__(self, code: ViolationCode, offset: int | None, message: str, data: bytes | None = None):
        super().__init__(message)
        self.code = code
        self.offset = offset
        self.data = data

    @classmethod
    def from_violation(cls, violation: Violation, data: bytes | None = None) -> FrameError:
        return cls(violation.code, violation.offset, violation.message, data)

    @property
    def violation(self) -> Violation:
        return Violation(self.code, self.offset, str(self))


class ProtocolError(XAC1Error):
    """The device's answer broke the protocol (wrong length, missing ``2``, echo differs, answer to
    another command...). ``.code`` is the violation code, ``.raw`` the bytes as received."""

    def __init__(self, code: ViolationCode, message: str, raw: bytes = b"",
                 violations: list[Violation] | None = None):
        super().__init__(message)
        self.code = code
        self.raw = raw
        self.violations = list(violations or [])


class AlarmError(XAC1Error):
    """The device answered with the alarm answer ``0%%Ec``. ``.code`` is the alarm code (int),
    ``.meaning`` its meaning from the spec table, ``.frame`` the AlarmAnswer."""

    def __init__(self, code: int, meaning: str, frame: object = None, raw: bytes = b""):
        super().__init__(f"alarm {code:02X}: {meaning}")
        self.code = code
        self.meaning = meaning
        self.frame = frame
        self.raw = raw


class ResponseTimeout(XAC1Error, TimeoutError):
    """No complete answer arrived in time. ``.partial`` holds the bytes that did arrive."""

    def __init__(self, message: str, partial: bytes = b""):
        super().__init__(message)
        self.partial = partial


class CommunicationHalted(XAC1Error):
    """The vendor's host duty: after too many communication-error answers in a row the client refuses
    to send until ``rearm()`` (docs/protocol.md "Behaviour the vendor text states")."""
