"""The XA-C1 protocol's tables, as data (docs/protocol.md "Fields", "Frames", "Alarms", "Violation codes").

Everything else derives from these tables: the construct grammar (``grammar.py``) builds one struct per
frame layout, the frame classes take their field ranges from here, and the lenient decoder walks the
same layouts. A layout is a tuple of items: a field name (a key of ``FIELDS``) or a ``Literal`` that
must appear verbatim (the mandatory ``2``, the ``00`` of the reset answer).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final
from typing import Literal as TypingLiteral

Role = TypingLiteral["command", "answer"]
COMMAND: Final = "command"
ANSWER: Final = "answer"
ROLES: Final = (COMMAND, ANSWER)

LEAD: Final = b"0"  # docs/protocol.md "Framing": the digit zero starts every frame
LETTER_O: Final = b"O"  # the PDF artefact a sloppy host may really send
HEADER_WIDTH: Final = 3
TERMINATOR: Final = b"\r\n"
FRAME_END: Final = TERMINATOR[-1:]  # a frame ends at LF, whatever precedes it (docs/protocol.md "Framing")
LF: Final = 0x0A

BAUD: Final = 9600
BITS_PER_BYTE: Final = 10  # 8N1: start + 8 data + stop
BYTE_TIME_S: Final = BITS_PER_BYTE / BAUD  # 1.0417 ms a byte on the wire


@dataclass(frozen=True)
class FieldSpec:
    """One field of a frame: its width in characters, radix, and value ranges (inclusive)."""

    name: str
    label: str  # as the vendor text names it
    width: int
    radix: int  # 16: upper-case hex digits; 10: decimal digits
    command_range: tuple[int, int]
    answer_range: tuple[int, int]
    doc: str
    text: bool = False  # kept as a str (0RV's version), not an int

    def range_for(self, role: Role) -> tuple[int, int]:
        return self.command_range if role == COMMAND else self.answer_range

    def show(self, value: int) -> str:
        """The value as it appears on the wire."""
        return format(value, f"0{self.width}{'X' if self.radix == 16 else 'd'}")


@dataclass(frozen=True)
class Literal:
    """Characters that must appear verbatim; ``code`` is the violation when they do not."""

    text: str
    code: ViolationCode

    @property
    def width(self) -> int:
        return len(self.text)


FIELDS: Final[dict[str, FieldSpec]] = {
    f.name: f
    for f in (
        FieldSpec("n", "N", 1, 16, (1, 0xF), (0, 0xF), "position number (0 = home)"),
        FieldSpec("v", "V", 1, 10, (1, 9), (0, 9), "speed number (0 in answers: none)"),
        FieldSpec("a", "A", 1, 10, (1, 3), (0, 3), "acceleration: 1 low, 2 mid, 3 high"),
        FieldSpec("o", "O", 1, 10, (0, 3), (0, 3), "OUT ports: 0 none, 1 OUT1, 2 OUT2, 3 both"),
        FieldSpec("pos", "Pos", 6, 16, (0, 0xFFFFFF), (0, 0xFFFFFF), "position in pulses"),
        FieldSpec("vel", "vel", 2, 16, (1, 60), (1, 60), "direct-move speed number"),
        FieldSpec("mode", "m", 1, 10, (0, 1), (0, 1), "0 external start, 1 communication"),
        FieldSpec("version", "ver", 3, 10, (0, 999), (0, 999), "firmware version", text=True),
        FieldSpec("code", "Ec", 2, 16, (0, 0xFF), (0, 0xFF), "alarm code"),
    )
}

TWO: Final = Literal("2", "missing-2")  # docs/protocol.md "Fields": the mandatory literal 2
RESET_OK: Final = Literal("00", "field-range")  # the reset answer 0%C00

Item = str | Literal


@dataclass(frozen=True)
class FrameSpec:
    """One frame kind: header, role, layout after the header, and per-frame range overrides."""

    header: str
    role: Role
    layout: tuple[Item, ...]
    meaning: str
    ranges: dict[str, tuple[int, int]] = field(default_factory=dict)
    echo: bool = False  # the answer repeats the command: the same header and field values

    @property
    def key(self) -> tuple[str, Role]:
        return (self.header, self.role)

    @property
    def length(self) -> int:
        """Bytes on the wire, CR LF included."""
        return HEADER_WIDTH + sum(_width(i) for i in self.layout) + len(TERMINATOR)

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(i for i in self.layout if isinstance(i, str))

    def field_range(self, name: str) -> tuple[int, int]:
        return self.ranges.get(name) or FIELDS[name].range_for(self.role)

    def literal_offset(self, literal: Literal) -> int | None:
        """Byte offset of ``literal`` (e.g. the mandatory ``2``) in a well-formed frame, or None."""
        at = HEADER_WIDTH
        for item in self.layout:
            if item == literal:
                return at
            at += _width(item)
        return None

    def offsets(self) -> dict[str, int]:
        """Byte offset of each field in a well-formed frame."""
        out, at = {}, HEADER_WIDTH
        for item in self.layout:
            if isinstance(item, str):
                out[item] = at
            at += _width(item)
        return out


def _width(item: Item) -> int:
    return FIELDS[item].width if isinstance(item, str) else item.width


_POINT_DATA: Final = ("n", "v", "a", "o", TWO, "pos")

# docs/protocol.md "Frames". One row a frame kind; the byte counts follow from the layouts.
FRAME_SPECS: Final[tuple[FrameSpec, ...]] = (
    FrameSpec("0RP", COMMAND, ("n",), "read movement data of point N"),
    FrameSpec("0RP", ANSWER, _POINT_DATA, "movement data of point N"),
    FrameSpec("0WP", COMMAND, _POINT_DATA, "write movement data of point N"),
    FrameSpec("0WP", ANSWER, _POINT_DATA, "write result (echo)", echo=True),
    FrameSpec("0RC", COMMAND, (), "read current position"),
    FrameSpec("0RC", ANSWER, _POINT_DATA, "current position"),
    FrameSpec("0WC", COMMAND, ("n",), "store current position into point N"),
    FrameSpec("0WC", ANSWER, _POINT_DATA, "point N's data after the store"),
    FrameSpec("0MP", COMMAND, ("n",), "move to point N (0 = homing)", ranges={"n": (0, 0xF)}),
    FrameSpec("0MP", ANSWER, _POINT_DATA, "point move done"),
    FrameSpec("0MV", COMMAND, ("vel", "a", "pos"), "direct move"),
    FrameSpec("0MV", ANSWER, ("vel", "a", "pos"), "direct move done (echo)", echo=True),
    FrameSpec("0RS", COMMAND, (), "read OUT ports"),
    FrameSpec("0RS", ANSWER, ("o", TWO), "OUT ports"),
    FrameSpec("0WS", COMMAND, ("o", TWO), "write OUT ports"),
    FrameSpec("0WS", ANSWER, ("o", TWO), "OUT ports written (echo)", echo=True),
    FrameSpec("0RV", COMMAND, (), "read firmware version"),
    FrameSpec("0RV", ANSWER, ("version",), "firmware version"),
    FrameSpec("0CM", COMMAND, ("mode",), "switch mode"),
    FrameSpec("0CM", ANSWER, ("mode",), "mode switched (echo)", echo=True),
    FrameSpec("0%C", COMMAND, (), "alarm reset"),
    FrameSpec("0%C", ANSWER, (RESET_OK,), "alarm reset done"),
    FrameSpec("0%%", ANSWER, ("code",), "alarm answer (to any command)"),
)

SPECS: Final[dict[tuple[str, Role], FrameSpec]] = {s.key: s for s in FRAME_SPECS}
HEADERS: Final[dict[Role, frozenset[str]]] = {
    r: frozenset(s.header for s in FRAME_SPECS if s.role == r) for r in ROLES
}
ALARM_HEADER: Final = "0%%"
RESET_HEADER: Final = "0%C"
MOVE_HEADERS: Final = frozenset({"0MP", "0MV"})

# docs/protocol.md "Behaviour the vendor text states" and "Fields".
UNKNOWN_POSITION: Final = 0xFFFFFF
ACCEL_RAMP_S: Final[dict[int, float]] = {1: 0.400, 2: 0.200, 3: 0.100}
STORM_LIMIT: Final = 5  # communication-error answers in a row before the host must stop
# docs/protocol.md silent item 17: how long a host (the client) and a watcher (the sniffer) wait for an
# answer after a command's last byte, before moves are priced in. One default for every part.
NO_ANSWER_TIMEOUT_S: Final = 1.0

# docs/protocol.md "Alarms". None: listed by the vendor with no meaning.
ALARMS: Final[dict[int, str | None]] = {
    0x00: "no error",
    0x01: "communication error",
    0x02: None,
    0x03: None,
    0x04: "internal memory read/write error",
    0x05: None,
    0x06: "internal memory data error",
    0x07: None,
    0x08: "move position setting error",
    0x09: "limit switch ON at move completion",
    0x0A: "output pulse count calculation error",
    0x0B: "homing error",
    0x0E: "emergency stop",
}
RESERVED_ALARMS: Final = frozenset(c for c, m in ALARMS.items() if m is None)
ALARM_NONE: Final = 0x00
ALARM_COMM: Final = 0x01
ALARM_MEMORY_RW: Final = 0x04
ALARM_MEMORY_DATA: Final = 0x06
ALARM_POSITION: Final = 0x08
ALARM_LIMIT: Final = 0x09
ALARM_PULSE: Final = 0x0A
ALARM_HOMING: Final = 0x0B
ALARM_ESTOP: Final = 0x0E


def alarm_meaning(code: int) -> str:
    """The alarm code's meaning, or why it has none."""
    if code in RESERVED_ALARMS:
        return "reserved (no meaning in the vendor text)"
    return ALARMS.get(code) or "unknown alarm code"


ERROR: Final = "error"
NOTICE: Final = "notice"

Severity = TypingLiteral["error", "notice"]
# Whose duty a violation checks: the host's, the device's, or whoever sent the bytes (a framing fault).
Side = TypingLiteral["host", "device"]
HOST_SIDE: Final = "host"
DEVICE_SIDE: Final = "device"
SENDER: Final = "sender"
Duty = TypingLiteral["host", "device", "sender"]

ViolationCode = TypingLiteral[
    "bad-length", "bad-terminator", "letter-o", "lowercase-hex", "missing-2", "field-range",
    "unknown-command", "garbage", "echo-mismatch", "answer-mismatch", "unsolicited-answer", "no-answer",
    "overlapping-command", "command-during-motion", "alarm-ignored", "comm-error-storm", "storm-recovery",
    "error-accepted", "latch-broken", "estop-cleared", "readback-mismatch", "reserved-alarm",
    "unknown-alarm",
]


@dataclass(frozen=True)
class ViolationSpec:
    """One violation code of docs/protocol.md "Violation codes": severity, whose duty, meaning."""

    code: ViolationCode
    severity: Severity
    duty: Duty
    meaning: str
    section: str  # the docs/protocol.md section that states the rule

    def side(self, sender: Side) -> Side:
        """Whose fault it is when found in bytes sent by ``sender``."""
        return sender if self.duty == SENDER else self.duty


_F, _B, _C = "Framing", "Behaviour the vendor text states", "Violation codes"

# docs/protocol.md "Violation codes": one row a code; the order is the report order.
VIOLATION_SPECS: Final[tuple[ViolationSpec, ...]] = (
    ViolationSpec("bad-length", ERROR, SENDER, "the frame's byte count is not the spec's", _F),
    ViolationSpec("bad-terminator", ERROR, SENDER, "the frame does not end with CR LF", _F),
    ViolationSpec("letter-o", ERROR, SENDER, "the frame starts with the letter O, not the digit 0", _F),
    ViolationSpec("lowercase-hex", NOTICE, SENDER,
                  "hex digits or header in lower case (the vendor writes upper case)", _F),
    ViolationSpec("missing-2", ERROR, SENDER, "the mandatory character 2 is missing", "Fields"),
    ViolationSpec("field-range", ERROR, SENDER, "a field is out of its range", "Fields"),
    ViolationSpec("unknown-command", ERROR, SENDER, "the header is no command or answer of the spec",
                  "Frames"),
    ViolationSpec("garbage", ERROR, SENDER, "bytes that form no frame", _F),
    ViolationSpec("echo-mismatch", ERROR, DEVICE_SIDE, "an echo answer differs from its command", _B),
    ViolationSpec("answer-mismatch", ERROR, DEVICE_SIDE, "an answer of another command or another N",
                  _C),
    ViolationSpec("unsolicited-answer", ERROR, DEVICE_SIDE, "an answer with no command waiting for it",
                  _F),
    ViolationSpec("no-answer", ERROR, DEVICE_SIDE, "a command (or an error) got no answer in time", _B),
    ViolationSpec("overlapping-command", ERROR, HOST_SIDE, "a new command before the previous answer",
                  _F),
    ViolationSpec("command-during-motion", ERROR, HOST_SIDE, "a command sent while the axis moves", _B),
    ViolationSpec("alarm-ignored", NOTICE, HOST_SIDE,
                  "the host went on after an alarm answer without a reset (our reading: no stated duty)", _B),
    ViolationSpec("comm-error-storm", ERROR, HOST_SIDE,
                  "a command sent after too many communication errors in a row", _B),
    ViolationSpec("storm-recovery", NOTICE, HOST_SIDE,
                  "an alarm reset, or the first command after a successful one, sent after too many "
                  "communication errors in a row (our reading: no stated duty)", _B),
    ViolationSpec("error-accepted", ERROR, DEVICE_SIDE,
                  "a normal answer to a command that breaks a stated rule (errors get an alarm answer)",
                  _B),
    ViolationSpec("latch-broken", ERROR, DEVICE_SIDE,
                  "a normal answer while an alarm should still be latched", _B),
    ViolationSpec("estop-cleared", ERROR, DEVICE_SIDE, "emergency stop cleared by an alarm reset",
                  "Where the vendor text is silent"),
    ViolationSpec("readback-mismatch", ERROR, DEVICE_SIDE,
                  "a value read back differs from what the conversation established", _B),
    ViolationSpec("reserved-alarm", NOTICE, SENDER,
                  "alarm code 02, 03, 05 or 07 (no meaning in the vendor text)", "Alarms"),
    ViolationSpec("unknown-alarm", NOTICE, SENDER, "an alarm code the vendor does not list", "Alarms"),
)
VIOLATION_TABLE: Final[dict[ViolationCode, ViolationSpec]] = {v.code: v for v in VIOLATION_SPECS}
# code -> (severity, meaning), the shape the views use.
VIOLATIONS: Final[dict[ViolationCode, tuple[Severity, str]]] = {
    v.code: (v.severity, v.meaning) for v in VIOLATION_SPECS
}
NOTICES: Final[frozenset[ViolationCode]] = frozenset(v.code for v in VIOLATION_SPECS if v.severity == NOTICE)

# Order in which strict parsing checks a frame (docs/protocol.md "Framing"); the first failure is raised.
CHECK_ORDER: Final[dict[ViolationCode, int]] = {
    "letter-o": 0,
    "unknown-command": 0,
    "bad-length": 1,
    "bad-terminator": 2,
    "missing-2": 3,
    "lowercase-hex": 4,
    "field-range": 4,
    "reserved-alarm": 5,
    "unknown-alarm": 5,
}
