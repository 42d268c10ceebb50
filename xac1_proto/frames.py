"""Frames as inert data: one frozen dataclass per frame kind of docs/protocol.md "Frames".

A frame knows its header, role and fields, checks its field ranges when built, and turns itself into
wire bytes through the construct grammar. Behaviour (the device model, the conversation checker) lives
elsewhere. ``FRAME_CLASSES`` maps (header, role) to the class.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any, ClassVar, Final, TypeVar

from . import grammar, spec
from .errors import FrameError

F = TypeVar("F", bound="Frame")

__all__ = [
    "FRAME_CLASSES",
    "ReadPoint",
    "WritePoint",
    "ReadCurrent",
    "StoreCurrent",
    "MovePoint",
    "MoveDirect",
    "ReadOutputs",
    "WriteOutputs",
    "ReadVersion",
    "SwitchMode",
    "AlarmReset",
    "PointAnswer",
    "ReadPointAnswer",
    "WritePointAnswer",
    "ReadCurrentAnswer",
    "StoreCurrentAnswer",
    "MovePointAnswer",
    "MoveDirectAnswer",
    "ReadOutputsAnswer",
    "WriteOutputsAnswer",
    "ReadVersionAnswer",
    "SwitchModeAnswer",
    "AlarmResetAnswer",
    "AlarmAnswer",
]


def range_text(field: spec.FieldSpec, lo: int, hi: int) -> str:
    """A field's range as the spec writes it (``1-F``, ``01-3C (1-60)``)."""
    if field.radix == 16 and field.width > 1:
        return f"{field.show(lo)}-{field.show(hi)} ({lo}-{hi})"
    return f"{field.show(lo)}-{field.show(hi)}"


@dataclass(frozen=True, kw_only=True, slots=True)
class Frame:
    """A decoded frame. Subclasses add the fields; ``to_bytes()`` gives the exact wire bytes."""

    HEADER: ClassVar[str]
    ROLE: ClassVar[spec.Role]
    check: dataclasses.InitVar[bool] = True  # False: the lenient decoder keeps what it saw (``unchecked``)

    @property
    def header(self) -> str:
        return self.HEADER

    @property
    def role(self) -> spec.Role:
        return self.ROLE

    @classmethod
    def frame_spec(cls) -> spec.FrameSpec:
        """This frame kind's row of ``spec.FRAME_SPECS``."""
        return spec.SPECS[(cls.HEADER, cls.ROLE)]

    def fields(self) -> dict[str, Any]:
        """The field values by name, in wire order."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_bytes(self) -> bytes:
        return bytes(grammar.STRUCTS[(self.HEADER, self.ROLE)].build(self.fields()))

    def __post_init__(self, check: bool = True) -> None:
        """Each field's type and range (``check`` False: none; a lenient decode keeps out-of-range values)."""
        if not check:
            return
        fs = self.frame_spec()
        offsets = fs.offsets()
        for name, value in self.fields().items():
            field = spec.FIELDS[name]
            where = f"{fs.header} {fs.role}: byte {offsets[name]}"
            if field.text:
                if not (isinstance(value, str) and len(value) == field.width and value.isdigit()
                        and value.isascii()):
                    raise FrameError("field-range", None,
                                     f"{where}: {field.label} must be {field.width} digits, "
                                     f"got {value!r} (field-range)")
                continue
            if not isinstance(value, int) or isinstance(value, bool):
                raise TypeError(f"{fs.header} {fs.role}: {field.label} must be an int, got {value!r}")
            lo, hi = fs.field_range(name)
            if not lo <= value <= hi:
                raise FrameError("field-range", None,
                                 f"{where}: {field.label} must be {range_text(field, lo, hi)}, "
                                 f"got {value} (field-range)")

    @classmethod
    def unchecked(cls: type[F], **values: Any) -> F:
        """A frame whose fields are not range-checked: the lenient decoder's way to keep what it saw."""
        return cls(**values, check=False)

    def __str__(self) -> str:
        """``0RP answer N=3 V=9 ...``: the header, the role, each field as on the wire (remembered for
        the last distinct frames: a decode shows the same few frames over and over)."""
        try:
            return _described(self)
        except TypeError:  # a lenient frame holding a value that cannot be hashed
            return describe(self)


def describe(frame: Frame) -> str:
    """What ``str(frame)`` says, worked out."""
    parts = [frame.HEADER, frame.ROLE]
    for name, value in frame.fields().items():
        field = spec.FIELDS[name]
        shown = value if field.text else field.show(value)
        extra = f" ({value})" if field.width > 1 and not field.text else ""
        parts.append(f"{field.label}={'0x' if field.width > 2 and not field.text else ''}{shown}{extra}")
    return " ".join(parts)


_described = functools.lru_cache(maxsize=4096)(describe)


# ---- commands (docs/protocol.md "Frames", rows 1-10 and the alarm reset) ----

@dataclass(frozen=True, kw_only=True, slots=True)
class ReadPoint(Frame):
    """0RP: read movement data of point N."""
    HEADER = "0RP"
    ROLE = spec.COMMAND
    n: int


@dataclass(frozen=True, kw_only=True, slots=True)
class WritePoint(Frame):
    """0WP: write movement data of point N."""
    HEADER = "0WP"
    ROLE = spec.COMMAND
    n: int
    v: int
    a: int
    o: int
    pos: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadCurrent(Frame):
    """0RC: read the current position."""
    HEADER = "0RC"
    ROLE = spec.COMMAND


@dataclass(frozen=True, kw_only=True, slots=True)
class StoreCurrent(Frame):
    """0WC: store the current position into point N."""
    HEADER = "0WC"
    ROLE = spec.COMMAND
    n: int


@dataclass(frozen=True, kw_only=True, slots=True)
class MovePoint(Frame):
    """0MP: move to point N; N = 0 homes."""
    HEADER = "0MP"
    ROLE = spec.COMMAND
    n: int


@dataclass(frozen=True, kw_only=True, slots=True)
class MoveDirect(Frame):
    """0MV: direct move to Pos at speed vel with acceleration A."""
    HEADER = "0MV"
    ROLE = spec.COMMAND
    vel: int
    a: int
    pos: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadOutputs(Frame):
    """0RS: read the OUT ports."""
    HEADER = "0RS"
    ROLE = spec.COMMAND


@dataclass(frozen=True, kw_only=True, slots=True)
class WriteOutputs(Frame):
    """0WS: write the OUT ports."""
    HEADER = "0WS"
    ROLE = spec.COMMAND
    o: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadVersion(Frame):
    """0RV: read the firmware version."""
    HEADER = "0RV"
    ROLE = spec.COMMAND


@dataclass(frozen=True, kw_only=True, slots=True)
class SwitchMode(Frame):
    """0CM: switch mode (0 external start, 1 communication)."""
    HEADER = "0CM"
    ROLE = spec.COMMAND
    mode: int


@dataclass(frozen=True, kw_only=True, slots=True)
class AlarmReset(Frame):
    """0%C: reset every alarm but emergency stop."""
    HEADER = "0%C"
    ROLE = spec.COMMAND


# ---- answers ----

@dataclass(frozen=True, kw_only=True, slots=True)
class PointAnswer(Frame):
    """Shape shared by the 16-byte answers: N V A O 2 Pos."""
    n: int
    v: int
    a: int
    o: int
    pos: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadPointAnswer(PointAnswer):
    """0RP answer: the movement data of point N."""
    HEADER = "0RP"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class WritePointAnswer(PointAnswer):
    """0WP answer: the write result, an echo of the command."""
    HEADER = "0WP"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadCurrentAnswer(PointAnswer):
    """0RC answer: the current position (FFFFFF before homing)."""
    HEADER = "0RC"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class StoreCurrentAnswer(PointAnswer):
    """0WC answer: point N's data after the store."""
    HEADER = "0WC"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class MovePointAnswer(PointAnswer):
    """0MP answer, sent when the move has ended."""
    HEADER = "0MP"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class MoveDirectAnswer(Frame):
    """0MV answer, an echo of the command sent when the move has ended."""
    HEADER = "0MV"
    ROLE = spec.ANSWER
    vel: int
    a: int
    pos: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadOutputsAnswer(Frame):
    """0RS answer: the OUT ports."""
    HEADER = "0RS"
    ROLE = spec.ANSWER
    o: int


@dataclass(frozen=True, kw_only=True, slots=True)
class WriteOutputsAnswer(Frame):
    """0WS answer, an echo of the command."""
    HEADER = "0WS"
    ROLE = spec.ANSWER
    o: int


@dataclass(frozen=True, kw_only=True, slots=True)
class ReadVersionAnswer(Frame):
    """0RV answer: three digits, ``100`` = version 1.00."""
    HEADER = "0RV"
    ROLE = spec.ANSWER
    version: str


@dataclass(frozen=True, kw_only=True, slots=True)
class SwitchModeAnswer(Frame):
    """0CM answer, an echo carrying the mode."""
    HEADER = "0CM"
    ROLE = spec.ANSWER
    mode: int


@dataclass(frozen=True, kw_only=True, slots=True)
class AlarmResetAnswer(Frame):
    """0%C answer: ``0%C00``."""
    HEADER = "0%C"
    ROLE = spec.ANSWER


@dataclass(frozen=True, kw_only=True, slots=True)
class AlarmAnswer(Frame):
    """0%% answer: the (latched) alarm code, sent in place of any answer."""
    HEADER = "0%%"
    ROLE = spec.ANSWER
    code: int

    @property
    def meaning(self) -> str:
        return spec.alarm_meaning(self.code)


FRAME_CLASSES: Final[dict[tuple[str, spec.Role], type[Frame]]] = {
    (c.HEADER, c.ROLE): c
    for c in (
        ReadPoint, WritePoint, ReadCurrent, StoreCurrent, MovePoint, MoveDirect, ReadOutputs,
        WriteOutputs, ReadVersion, SwitchMode, AlarmReset,
        ReadPointAnswer, WritePointAnswer, ReadCurrentAnswer, StoreCurrentAnswer, MovePointAnswer,
        MoveDirectAnswer, ReadOutputsAnswer, WriteOutputsAnswer, ReadVersionAnswer,
        SwitchModeAnswer, AlarmResetAnswer, AlarmAnswer,
    )
}
