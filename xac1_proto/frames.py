"""Frames as inert data: one immutable class per frame kind of docs/protocol.md "Frames".

A frame knows its header, role and fields, checks its field ranges when built, and turns itself into
wire bytes through the construct grammar. Behaviour (the device model, the conversation checker) lives
elsewhere. ``FRAME_CLASSES`` maps (header, role) to the class.
"""

from __future__ import annotations

import functools
from typing import Any, ClassVar, Final, NamedTuple, TypeVar

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


class Frame(tuple[Any, ...]):
    """A decoded frame: its field values in wire order, as a tuple (each kind is ``Frame`` first, then a
    ``NamedTuple`` of its fields, so a frame is immutable and quick to build). Two frames are equal when
    they are of the same kind with the same values; a frame is always true, even one without fields.

    Building a frame by its fields' names (``ReadPoint(n=3)``) checks each field's type and range;
    ``unchecked`` does not (the lenient decoder keeps what it saw), nor does ``_make`` (the NamedTuple's
    constructor from the values in wire order; the fast decoder's, whose pattern has checked them).
    ``to_bytes()`` gives the exact wire bytes."""

    __slots__ = ()
    HEADER: ClassVar[str]
    ROLE: ClassVar[spec.Role]

    def __new__(cls: type[F], *args: Any, check: bool = True, **values: Any) -> F:
        frame = super().__new__(cls, *args, **values)  # the NamedTuple base's
        if check:
            frame._check()
        return frame

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):  # another kind, or a plain tuple of the same values: not equal
            return False if isinstance(other, tuple) else NotImplemented
        return tuple.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        if type(other) is not type(self):
            return True if isinstance(other, tuple) else NotImplemented
        return tuple.__ne__(self, other)

    __hash__ = tuple.__hash__

    def __bool__(self) -> bool:
        return True

    def __getnewargs_ex__(self) -> tuple[tuple[Any, ...], dict[str, Any]]:
        """A copy or an unpickled frame is the frame it was, unchecked as it may have been made."""
        return tuple(self), {"check": False}

    def _unordered(self, other: object) -> bool:
        return NotImplemented

    __lt__ = __le__ = __gt__ = __ge__ = _unordered  # frames have no order (values of different kinds)

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

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The field names in wire order."""
        names: tuple[str, ...] = cls._fields  # type: ignore[attr-defined]  # the NamedTuple base's
        return names

    def fields(self) -> dict[str, Any]:
        """The field values by name, in wire order."""
        return dict(zip(self.field_names(), self, strict=True))

    def to_bytes(self) -> bytes:
        return bytes(grammar.STRUCTS[(self.HEADER, self.ROLE)].build(self.fields()))

    def _check(self) -> None:
        """Each field's type and range."""
        for value, (field, lo, hi, where) in zip(self, _field_checks(type(self)), strict=True):
            if field.text:
                if not (isinstance(value, str) and len(value) == field.width and value.isdigit()
                        and value.isascii()):
                    raise FrameError("field-range", None,
                                     f"{where}: {field.label} must be {field.width} digits, "
                                     f"got {value!r} (field-range)")
                continue
            if not isinstance(value, int) or isinstance(value, bool):
                raise TypeError(f"{self.HEADER} {self.ROLE}: {field.label} must be an int, got {value!r}")
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


@functools.cache
def _field_checks(cls: type[Frame]) -> tuple[tuple[spec.FieldSpec, int, int, str], ...]:
    """Each field of a frame kind, in wire order: its spec, its range (0, 0 for text) and where it is in
    the frame (``Frame._check``'s, worked out once a kind)."""
    fs = cls.frame_spec()
    offsets = fs.offsets()
    return tuple((spec.FIELDS[name], *((0, 0) if spec.FIELDS[name].text else fs.field_range(name)),
                  f"{fs.header} {fs.role}: byte {offsets[name]}") for name in cls.field_names())


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


# ---- the field shapes (the NamedTuple half of each frame kind) ----

class _Nothing(NamedTuple):
    pass


class _N(NamedTuple):
    n: int


class _Point(NamedTuple):
    n: int
    v: int
    a: int
    o: int
    pos: int


class _Direct(NamedTuple):
    vel: int
    a: int
    pos: int


class _O(NamedTuple):
    o: int


class _Mode(NamedTuple):
    mode: int


class _Version(NamedTuple):
    version: str


class _Code(NamedTuple):
    code: int


# ---- commands (docs/protocol.md "Frames", rows 1-10 and the alarm reset) ----

class ReadPoint(Frame, _N):
    """0RP: read movement data of point N."""
    __slots__ = ()
    HEADER = "0RP"
    ROLE = spec.COMMAND


class WritePoint(Frame, _Point):
    """0WP: write movement data of point N."""
    __slots__ = ()
    HEADER = "0WP"
    ROLE = spec.COMMAND


class ReadCurrent(Frame, _Nothing):
    """0RC: read the current position."""
    __slots__ = ()
    HEADER = "0RC"
    ROLE = spec.COMMAND


class StoreCurrent(Frame, _N):
    """0WC: store the current position into point N."""
    __slots__ = ()
    HEADER = "0WC"
    ROLE = spec.COMMAND


class MovePoint(Frame, _N):
    """0MP: move to point N; N = 0 homes."""
    __slots__ = ()
    HEADER = "0MP"
    ROLE = spec.COMMAND


class MoveDirect(Frame, _Direct):
    """0MV: direct move to Pos at speed vel with acceleration A."""
    __slots__ = ()
    HEADER = "0MV"
    ROLE = spec.COMMAND


class ReadOutputs(Frame, _Nothing):
    """0RS: read the OUT ports."""
    __slots__ = ()
    HEADER = "0RS"
    ROLE = spec.COMMAND


class WriteOutputs(Frame, _O):
    """0WS: write the OUT ports."""
    __slots__ = ()
    HEADER = "0WS"
    ROLE = spec.COMMAND


class ReadVersion(Frame, _Nothing):
    """0RV: read the firmware version."""
    __slots__ = ()
    HEADER = "0RV"
    ROLE = spec.COMMAND


class SwitchMode(Frame, _Mode):
    """0CM: switch mode (0 external start, 1 communication)."""
    __slots__ = ()
    HEADER = "0CM"
    ROLE = spec.COMMAND


class AlarmReset(Frame, _Nothing):
    """0%C: reset every alarm but emergency stop."""
    __slots__ = ()
    HEADER = "0%C"
    ROLE = spec.COMMAND


# ---- answers ----

class PointAnswer(Frame, _Point):
    """Shape shared by the 16-byte answers: N V A O 2 Pos."""
    __slots__ = ()


class ReadPointAnswer(PointAnswer):
    """0RP answer: the movement data of point N."""
    __slots__ = ()
    HEADER = "0RP"
    ROLE = spec.ANSWER


class WritePointAnswer(PointAnswer):
    """0WP answer: the write result, an echo of the command."""
    __slots__ = ()
    HEADER = "0WP"
    ROLE = spec.ANSWER


class ReadCurrentAnswer(PointAnswer):
    """0RC answer: the current position (FFFFFF before homing)."""
    __slots__ = ()
    HEADER = "0RC"
    ROLE = spec.ANSWER


class StoreCurrentAnswer(PointAnswer):
    """0WC answer: point N's data after the store."""
    __slots__ = ()
    HEADER = "0WC"
    ROLE = spec.ANSWER


class MovePointAnswer(PointAnswer):
    """0MP answer, sent when the move has ended."""
    __slots__ = ()
    HEADER = "0MP"
    ROLE = spec.ANSWER


class MoveDirectAnswer(Frame, _Direct):
    """0MV answer, an echo of the command sent when the move has ended."""
    __slots__ = ()
    HEADER = "0MV"
    ROLE = spec.ANSWER


class ReadOutputsAnswer(Frame, _O):
    """0RS answer: the OUT ports."""
    __slots__ = ()
    HEADER = "0RS"
    ROLE = spec.ANSWER


class WriteOutputsAnswer(Frame, _O):
    """0WS answer, an echo of the command."""
    __slots__ = ()
    HEADER = "0WS"
    ROLE = spec.ANSWER


class ReadVersionAnswer(Frame, _Version):
    """0RV answer: three digits, ``100`` = version 1.00."""
    __slots__ = ()
    HEADER = "0RV"
    ROLE = spec.ANSWER


class SwitchModeAnswer(Frame, _Mode):
    """0CM answer, an echo carrying the mode."""
    __slots__ = ()
    HEADER = "0CM"
    ROLE = spec.ANSWER


class AlarmResetAnswer(Frame, _Nothing):
    """0%C answer: ``0%C00``."""
    __slots__ = ()
    HEADER = "0%C"
    ROLE = spec.ANSWER


class AlarmAnswer(Frame, _Code):
    """0%% answer: the (latched) alarm code, sent in place of any answer."""
    __slots__ = ()
    HEADER = "0%%"
    ROLE = spec.ANSWER

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
