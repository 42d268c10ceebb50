"""The error tree: one root, ``XAC1Error``; framing and grammar errors carry a violation code and offset."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final, NamedTuple

if TYPE_CHECKING:
    from .spec import Severity, ViolationCode


class XAC1Error(Exception):
    """Root of every error this package raises on purpose."""


class _ViolationFields(NamedTuple):
    code: ViolationCode
    offset: int | None
    rule: str
    severity: Severity
    text: str | None  # the sentence, when made at once (the decoder's); else made from the next two
    sentence: Callable[..., str] | None
    values: tuple[Any, ...]


class Violation(_ViolationFields):
    """One deviation from the protocol: a docs/protocol.md violation code, where, and what was wrong;
    ``rule``: the rulebook row it breaks (``xac1_proto.rules``; default: the code's plain rule);
    ``severity``: ``error`` or ``notice`` (default: the rule's, derived from its basis). ``message``, the
    sentence, is made when read: the engine records a function and the few values it needs (``said``),
    so a view that shows no sentence makes none (``xac1_proto.sentences``)."""

    __slots__ = ()

    def __new__(cls, code: ViolationCode, offset: int | None, message: str, rule: str = "",
                severity: Severity | None = None) -> Violation:
        from .rules import severity as rule_severity  # (rules imports spec, which may import this module)

        return tuple.__new__(cls, (code, offset, rule or code, severity or rule_severity(rule or code),
                                   message, None, ()))

    @classmethod
    def said(cls, code: ViolationCode, rule: str, severity: Severity, sentence: Callable[..., str],
             *values: Any, offset: int | None = None) -> Violation:
        """A violation whose sentence is ``sentence(*values)``, made only when ``message`` is read."""
        return _tuple_new(Violation, (code, offset, rule, severity, None, sentence, values))

    @property
    def message(self) -> str:
        """The sentence: what was wrong, the docs/protocol.md section and the code."""
        text = self.text
        if text is None:
            assert self.sentence is not None
            return self.sentence(*self.values)
        return text

    @property
    def is_error(self) -> bool:
        """Does it break a rule (not a notice)?"""
        return self.severity == "error"

    def graded(self, severity: Severity) -> Violation:
        """The same violation with another severity (``--readings``)."""
        return self._replace(severity=severity)

    def _key(self) -> tuple[object, ...]:
        return (self.code, self.offset, self.rule, self.severity, self.message)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Violation) and self._key() == other._key()

    def __ne__(self, other: object) -> bool:
        return not self == other

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(self) -> tuple[Any, ...]:
        return (tuple.__new__, (Violation, tuple(self)))

    def __repr__(self) -> str:
        return (f"Violation(code={self.code!r}, offset={self.offset!r}, message={self.message!r}, "
                f"rule={self.rule!r}, severity={self.severity!r})")

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


# a violation from its fields in order (code, offset, rule, severity, text, sentence, values), as ``said``
# makes it, with no Python frame of its own: ``_tuple_new(Violation, fields)``
_tuple_new: Final = tuple.__new__
