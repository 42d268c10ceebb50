"""Strict and lenient decoding: check order, offsets, messages (docs/protocol.md "Framing")."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

import xac1_proto as x
from xac1_proto import spec

# (wire, role, expected code of the strict error, its offset)
STRICT_ERRORS = [
    (b"ORP3\r\n", "command", "letter-o", 0),
    (b"0XY3\r\n", "command", "unknown-command", 1),
    (b"0rp3\r\n", "command", "lowercase-hex", 1),  # read as 0RP with the notice; strict rejects it
    (b"0xp3\r\n", "command", "unknown-command", 1),
    (b"0%%\r\n", "command", "unknown-command", 2),
    (b"0RP33\r\n", "command", "bad-length", 6),
    (b"0RP\r\n", "command", "bad-length", 5),
    (b"0RP3\n", "command", "bad-length", 5),
    (b"0RP3\r\r\n", "command", "bad-length", 6),
    (b"0RP3X\n", "command", "bad-terminator", 4),
    (b"0RS13\r\n", "answer", "missing-2", 4),
    (b"0WS13\r\n", "command", "missing-2", 4),
    (b"0RPa\r\n", "command", "lowercase-hex", 3),
    (b"0RP0\r\n", "command", "field-range", 3),
    (b"0RPG\r\n", "command", "field-range", 3),
    (b"0MV3D1000000\r\n", "command", "field-range", 3),
    (b"0WP19402012345\r\n", "command", "field-range", 5),
    (b"0CM2\r\n", "command", "field-range", 3),
    (b"0%C01\r\n", "answer", "field-range", 3),
    (b"0RVA00\r\n", "answer", "field-range", 3),
    (b"ORS3\r\n", "answer", "letter-o", 0),  # letter O comes before the missing 2 and length
]


@pytest.mark.parametrize("wire,role,code,offset", STRICT_ERRORS)
def test_strict_parse_raises_the_first_violation(wire, role, code, offset):
    """parse raises FrameError with the code and byte offset of the first failing check."""
    with pytest.raises(x.FrameError) as info:
        x.parse(wire, role)
    err = info.value
    assert (err.code, err.offset) == (code, offset)
    assert isinstance(err, ValueError) and isinstance(err, x.XAC1Error)
    assert f"({code})" in str(err)


def test_missing_2_message_names_expected_and_seen():
    """The pinned example message of the foundation issue."""
    with pytest.raises(x.FrameError, match=r"^0RS answer: byte 4: expected '2', got '3' \(missing-2\)$"):
        x.parse(b"0RS13\r\n", "answer")


def test_letter_o_is_recognised_leniently():
    """The lenient decoder reads ``ORP1`` as 0RP and names the ``letter-o`` violation (docs/protocol.md)."""
    frame, violations = x.diagnose(b"ORP1\r\n", "command")
    assert frame == x.ReadPoint(n=1)
    assert [v.code for v in violations] == ["letter-o"]
    assert "letter O" in violations[0].message


def test_lowercase_hex_decodes_with_a_notice():
    """Lower-case hex digits decode, with a ``lowercase-hex`` violation at their offset."""
    frame, violations = x.diagnose(b"0RPa\r\n", "command")
    assert frame == x.ReadPoint(n=10)
    assert [(v.code, v.offset) for v in violations] == [("lowercase-hex", 3)]


def test_answer_without_its_2_decodes_with_missing_2_and_bad_length():
    """A 0RS answer missing its fixed ``2`` decodes leniently with ``missing-2`` and ``bad-length``."""
    frame, violations = x.diagnose(b"0RS1\r\n", "answer")
    assert frame == x.ReadOutputsAnswer(o=1)
    assert sorted(v.code for v in violations) == ["bad-length", "missing-2"]


def test_point_answer_with_omitted_2_keeps_its_position():
    """A 16-byte answer that lost its 2 still decodes Pos from the bytes that follow."""
    frame, violations = x.diagnose(b"0RP3930012345\r\n", "answer")
    assert frame == x.ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x012345)
    assert {v.code for v in violations} == {"bad-length", "missing-2"}


def test_out_of_range_values_are_kept_leniently():
    """Out-of-range field values are kept as read, each named with ``field-range`` at its offset."""
    frame, violations = x.diagnose(b"0WP10402012345\r\n", "command")
    assert frame is not None and frame.fields()["v"] == 0 and frame.fields()["a"] == 4
    assert [(v.code, v.offset) for v in violations] == [("field-range", 4), ("field-range", 5)]


@pytest.mark.parametrize("code,notice", [(2, "reserved-alarm"), (0x42, "unknown-alarm")])
def test_alarm_codes_outside_the_meaning_table_are_notices_not_errors(code, notice):
    """docs/protocol.md silent item 13: any alarm code decodes; unlisted ones carry a notice."""
    wire = x.AlarmAnswer(code=code).to_bytes()
    assert x.parse(wire, "answer").code == code
    assert [v.code for v in x.diagnose(wire, "answer")[1]] == [notice]


def test_role_must_be_command_or_answer():
    """A role other than command or answer is a ``ValueError``."""
    with pytest.raises(ValueError, match="role must be"):
        x.parse(b"0RV\r\n", "reply")


def test_every_violation_code_is_in_the_vocabulary():
    """Every violation the decoder names for the strict-error table is a code of ``spec.VIOLATIONS``."""
    for wire, role, _, _ in STRICT_ERRORS:
        for v in x.diagnose(wire, role)[1]:
            assert v.code in spec.VIOLATIONS


@given(frames())
def test_build_then_parse_round_trips(frame):
    """Every frame kind over its whole field ranges: parse(to_bytes()) gives the frame back."""
    wire = frame.to_bytes()
    assert len(wire) == frame.frame_spec().length
    assert x.parse(wire, frame.role) == frame
    back, violations = x.diagnose(wire, frame.role)
    assert back == frame
    assert all(v.code in spec.NOTICES for v in violations)


@given(frames(), st.data())
def test_every_single_byte_change_is_a_frame_or_a_frame_error(frame, data):
    """Change one byte of a valid frame: the result parses to a valid frame or raises FrameError."""
    wire = bytearray(frame.to_bytes())
    i = data.draw(st.integers(0, len(wire) - 1))
    wire[i] = data.draw(st.integers(0, 255).filter(lambda b: b != wire[i]))
    try:
        other = x.parse(bytes(wire), frame.role)
    except x.FrameError as exc:
        assert exc.code in spec.VIOLATIONS and exc.offset is not None
        assert 0 <= exc.offset <= len(wire)
    else:
        assert other.to_bytes() == bytes(wire)
        assert type(other)(**other.fields()) == other  # in range


@settings(max_examples=budget(500))
@given(st.binary(max_size=40), st.sampled_from(spec.ROLES))
def test_arbitrary_bytes_raise_only_frame_error_and_diagnose_never_raises(data, role):
    """Any bytes: ``diagnose`` never raises and names only known codes; ``parse`` returns a frame or raises
    ``FrameError`` only."""
    frame, violations = x.diagnose(data, role)
    assert all(v.code in spec.VIOLATIONS for v in violations)
    try:
        parsed = x.parse(data, role)
    except x.FrameError:
        assert any(v.code not in ("reserved-alarm", "unknown-alarm") for v in violations)
    else:
        assert parsed == frame


@given(st.sampled_from(sorted(spec.SPECS)), st.binary(max_size=20))
def test_header_plus_arbitrary_tail_never_escapes_frame_error(key, tail):
    """A known header with any tail: ``parse`` raises nothing but ``FrameError`` and ``diagnose`` never
    raises."""
    header, role = key
    data = header.encode() + tail
    frame, violations = x.diagnose(data, role)
    try:
        assert x.parse(data, role) == frame
    except x.FrameError as exc:
        assert exc.violation in violations


def test_lowercase_header_read_leniently_as_its_command():
    """A header in lower case (``0rv``) is read as its command with the ``lowercase-hex`` notice, as a
    letter O is read as the digit with ``letter-o`` (docs/protocol.md "Framing")."""
    frame, violations = x.diagnose(b"0rv\r\n", "command")
    assert frame == x.ReadVersion() and [v.code for v in violations] == ["lowercase-hex"]
    frame, violations = x.diagnose(b"Owp19302012345\r\n", "command")
    assert frame is not None and frame.header == "0WP"
    assert [v.code for v in violations] == ["letter-o", "lowercase-hex"]
    frame, violations = x.diagnose(b"0%c00\r\n", "answer")
    assert frame == x.AlarmResetAnswer() and [v.code for v in violations] == ["lowercase-hex"]
