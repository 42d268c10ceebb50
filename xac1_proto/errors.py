"""The error tree: one root, ``XAC1Error``; framing and grammar errors carry a violation code and offset."""

from __future__ import annotations

from dataclasses import dataclass


class XAC1Error(Exception):
    """Root of every error this package raises on purpose."""


@dataclass(frozen=True)
class Violation:
    """One deviation from the protocol: a PROTOCOL.md violation code, where, and what was wrong."""

    code: str
    offset: int | None
    message: str

    def __str__(self) -> str:
        return self.message


class FrameError(XAC1Error, ValueError):
    """A frame that breaks the grammar. ``.code`` is a PROTOCOL.md violation code, ``.offset`` the
    byte offset of the first bad byte (None when the frame is built, not parsed)."""

    def __init__(self, code: str, offset: int | None, message: str, data: bytes | None = None):
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
