"""The grammar against the vendor's examples and byte counts (docs/protocol.md "Frames", "Fields")."""

from __future__ import annotations

import pytest

import xac1_proto as x
from xac1_proto import grammar, spec

# docs/protocol.md "Frames", vendor examples (CR LF added): (wire, role, class, fields)
VENDOR_EXAMPLES = [
    (b"0RP3\r\n", "command", x.ReadPoint, {"n": 3}),
    (b"0RP39302012345\r\n", "answer", x.ReadPointAnswer,
     {"n": 3, "v": 9, "a": 3, "o": 0, "pos": 0x012345}),
    (b"0WP19302012345\r\n", "command", x.WritePoint,
     {"n": 1, "v": 9, "a": 3, "o": 0, "pos": 0x012345}),
    (b"0WP19302012345\r\n", "answer", x.WritePointAnswer,
     {"n": 1, "v": 9, "a": 3, "o": 0, "pos": 0x012345}),
    (b"0RV\r\n", "command", x.ReadVersion, {}),
    (b"0RV100\r\n", "answer", x.ReadVersionAnswer, {"version": "100"}),
    (b"0MV0F1001388\r\n", "command", x.MoveDirect, {"vel": 15, "a": 1, "pos": 5000}),
    (b"0MV1E2003A98\r\n", "command", x.MoveDirect, {"vel": 30, "a": 2, "pos": 15000}),
    (b"0MV3C3007530\r\n", "answer", x.MoveDirectAnswer, {"vel": 60, "a": 3, "pos": 30000}),
    (b"0%C\r\n", "command", x.AlarmReset, {}),
    (b"0%C00\r\n", "answer", x.AlarmResetAnswer, {}),
    (b"0%%01\r\n", "answer", x.AlarmAnswer, {"code": 1}),
    (b"0%%0E\r\n", "answer", x.AlarmAnswer, {"code": 0x0E}),
    (b"0RC\r\n", "command", x.ReadCurrent, {}),
    (b"0RC00002FFFFFF\r\n", "answer", x.ReadCurrentAnswer,
     {"n": 0, "v": 0, "a": 0, "o": 0, "pos": 0xFFFFFF}),
    (b"0WC5\r\n", "command", x.StoreCurrent, {"n": 5}),
    (b"0MP0\r\n", "command", x.MovePoint, {"n": 0}),
    (b"0RS\r\n", "command", x.ReadOutputs, {}),
    (b"0RS32\r\n", "answer", x.ReadOutputsAnswer, {"o": 3}),
    (b"0WS12\r\n", "command", x.WriteOutputs, {"o": 1}),
    (b"0CM1\r\n", "command", x.SwitchMode, {"mode": 1}),
    (b"0CM0\r\n", "answer", x.SwitchModeAnswer, {"mode": 0}),
]

# An independent literal copy of the vendor's byte-count table (spec section 5 and 6).
BYTE_COUNTS = {
    "0RP": (6, 16), "0WP": (16, 16), "0RC": (5, 16), "0WC": (6, 16), "0MP": (6, 16),
    "0MV": (14, 14), "0RS": (5, 7), "0WS": (7, 7), "0RV": (5, 8), "0CM": (6, 6),
    "0%C": (5, 7), "0%%": (None, 7),
}


@pytest.mark.parametrize("wire,role,cls,fields", VENDOR_EXAMPLES)
def test_vendor_example_parses(wire, role, cls, fields):
    """Each vendor example decodes to its frame kind and field values."""
    frame = x.parse(wire, role)
    assert type(frame) is cls
    assert frame.fields() == fields
    assert frame.role == role and frame.header == wire[:3].decode()


@pytest.mark.parametrize("wire,role,cls,fields", VENDOR_EXAMPLES)
def test_vendor_example_builds(wire, role, cls, fields):
    """Each vendor example is built back to the exact wire bytes, by the frame and by construct."""
    assert cls(**fields).to_bytes() == wire
    parsed = grammar.STRUCTS[(cls.HEADER, cls.ROLE)].parse(wire)
    assert {k: v for k, v in parsed.items() if not k.startswith("_")} == fields


@pytest.mark.parametrize("header", sorted(BYTE_COUNTS))
def test_byte_counts_match_the_vendor_table(header):
    """Every frame kind's length equals the vendor's byte-count table, CR LF included."""
    cmd, ans = BYTE_COUNTS[header]
    assert spec.SPECS.get((header, "command")) is None if cmd is None else \
        spec.SPECS[(header, "command")].length == cmd
    assert spec.SPECS[(header, "answer")].length == ans


def test_every_frame_kind_has_a_class_whose_fields_follow_the_layout():
    """One class per frame kind; its dataclass fields are the layout's fields in wire order."""
    assert set(x.FRAME_CLASSES) == set(spec.SPECS)
    for key, cls in x.FRAME_CLASSES.items():
        assert cls.field_names() == spec.SPECS[key].field_names


@pytest.mark.parametrize("cls,kw,label", [
    (x.ReadPoint, {"n": 0}, "N"),
    (x.ReadPoint, {"n": 16}, "N"),
    (x.WritePoint, {"n": 1, "v": 0, "a": 1, "o": 0, "pos": 0}, "V"),
    (x.WritePoint, {"n": 1, "v": 1, "a": 4, "o": 0, "pos": 0}, "A"),
    (x.WritePoint, {"n": 1, "v": 1, "a": 1, "o": 4, "pos": 0}, "O"),
    (x.WritePoint, {"n": 1, "v": 1, "a": 1, "o": 0, "pos": 0x1000000}, "Pos"),
    (x.MoveDirect, {"vel": 0, "a": 1, "pos": 0}, "vel"),
    (x.MoveDirect, {"vel": 61, "a": 1, "pos": 0}, "vel"),
    (x.SwitchMode, {"mode": 2}, "m"),
    (x.AlarmAnswer, {"code": 256}, "Ec"),
    (x.ReadVersionAnswer, {"version": "1.0"}, "ver"),
])
def test_building_out_of_range_fields_raises_field_range(cls, kw, label):
    """Building a frame from an out-of-range field raises FrameError(field-range) naming it."""
    with pytest.raises(x.FrameError) as info:
        cls(**kw)
    assert info.value.code == "field-range"
    assert f" {label} must be" in str(info.value)


def test_move_point_accepts_zero_for_homing_but_read_point_does_not():
    """0MP N is 0-F (0 = homing); 0RP, 0WP, 0WC take 1-F (docs/protocol.md "Fields")."""
    assert x.MovePoint(n=0).to_bytes() == b"0MP0\r\n"
    for cls in (x.ReadPoint, x.StoreCurrent):
        with pytest.raises(x.FrameError):
            cls(n=0)


def test_frames_are_frozen():
    """A frame's field cannot be assigned."""
    frame = x.ReadPoint(n=3)
    with pytest.raises(AttributeError):
        frame.n = 4  # type: ignore[misc]


def test_alarm_meanings_come_from_the_table():
    """An alarm's meaning comes from the alarm table: known, reserved and unknown codes."""
    assert x.AlarmAnswer(code=0x0E).meaning == "emergency stop"
    assert "reserved" in x.AlarmAnswer(code=2).meaning
    assert "unknown" in x.AlarmAnswer(code=0x42).meaning


def test_literal_offset_of_the_mandatory_2():
    """The 2 sits after N V A O in point answers (byte 7) and after O in 0RS/0WS (byte 4)."""
    assert spec.SPECS[("0RP", "answer")].literal_offset(spec.TWO) == 7
    assert spec.SPECS[("0WS", "command")].literal_offset(spec.TWO) == 4
    assert spec.SPECS[("0RV", "answer")].literal_offset(spec.TWO) is None
    for fs in spec.FRAME_SPECS:
        at = fs.literal_offset(spec.TWO)
        if at is not None:
            assert _example(fs).to_bytes()[at:at + 1] == b"2", fs.key


def _example(fs):
    lows = {n: (str(fs.field_range(n)[0]).zfill(3) if spec.FIELDS[n].text else fs.field_range(n)[0])
            for n in fs.field_names}
    return x.FRAME_CLASSES[fs.key](**lows)
