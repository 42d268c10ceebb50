"""Framing of every answer: byte counts, CR LF, the leading digit 0, the mandatory 2.

One sample exchange per command kind (shared by the four checks, cited as their evidence); moves and
0WC are sampled only when the run may move (0WC needs a homed axis). The alarm answer is sampled with
an unknown header.
"""

from __future__ import annotations

import pytest

from conformance.kit import COMMAND_HEADERS, MOTION_HEADERS, TWO_ANSWERS, two_offset
from xac1_proto import spec
from xac1_proto.codec import show_bytes
from xac1_proto.dut.evidence import describe_answer, expect
from xac1_proto.frames import StoreCurrent

NEEDS_MOTION = {*MOTION_HEADERS, StoreCurrent.HEADER}  # 0WC needs a homed axis
KINDS = [pytest.param(h, marks=pytest.mark.xac1_motion, id=h) if h in NEEDS_MOTION else pytest.param(h, id=h)
         for h in COMMAND_HEADERS]


def _normal_sample(kit, header):
    p = kit.sample(header)
    expect(not p.timed_out, f"{header}: no answer (silence) to a valid command", p)
    expect(p.alarm is None, f"{header}: a valid command got {describe_answer(p)} instead of its answer", p)
    return p


@pytest.mark.parametrize("header", KINDS)
def test_answer_length(xac1_dut, xac1_kit, header):
    """The answer to {id} has the spec's byte count, CR LF included (docs/protocol.md "Frames")."""
    p = _normal_sample(xac1_kit, header)
    want = spec.SPECS[(header, spec.ANSWER)].length
    expect(len(p.raw) == want, f"{header} answer: expected {want} bytes (CR LF included), received "
                               f"{len(p.raw)}: {show_bytes(p.raw)}", p)


@pytest.mark.parametrize("header", KINDS)
def test_crlf(xac1_dut, xac1_kit, header):
    """The answer to {id} ends with CR LF (docs/protocol.md "Framing")."""
    p = _normal_sample(xac1_kit, header)
    expect(p.raw.endswith(spec.TERMINATOR),
           f"{header} answer: expected CR LF as the last two bytes, received {show_bytes(p.raw[-2:])} "
           f"(the answer: {show_bytes(p.raw)})", p)


@pytest.mark.parametrize("header", KINDS)
def test_leading_zero(xac1_dut, xac1_kit, header):
    """The answer to {id} starts with the digit 0, not the letter O (docs/protocol.md "Framing")."""
    p = _normal_sample(xac1_kit, header)
    expect(p.raw[:1] == spec.LEAD, f"{header} answer: expected the digit 0 as the first byte, "
                                   f"received {show_bytes(p.raw[:1])} (the answer: {show_bytes(p.raw)})", p)


@pytest.mark.parametrize("header", [pytest.param(h, marks=pytest.mark.xac1_motion, id=h) if h in NEEDS_MOTION
                                    else pytest.param(h, id=h) for h in TWO_ANSWERS])
def test_mandatory_2(xac1_dut, xac1_kit, header):
    """The answer to {id} carries the mandatory character 2 where the layout has it
    (docs/protocol.md "Fields")."""
    p = _normal_sample(xac1_kit, header)
    at = two_offset(header)
    expect(p.raw[at:at + 1] == spec.TWO.text.encode(),
           f"{header} answer: expected the mandatory 2 at byte {at}, received {show_bytes(p.raw[at:at + 1])} "
           f"(the answer: {show_bytes(p.raw)}, {len(p.raw)} bytes)", p)


def test_alarm_answer_framing(xac1_dut):
    """The alarm answer to a malformed command is 7 bytes: 0%%, two hex digits, CR LF (docs/protocol.md
    "Frames")."""
    from xac1_proto.frames import AlarmAnswer

    p = xac1_dut.probe(b"0XY" + spec.TERMINATOR)
    expect(not p.timed_out, "no answer (silence) to a malformed command", p)
    want = AlarmAnswer.frame_spec().length
    expect(p.raw.startswith(spec.ALARM_HEADER.encode()), f"expected an alarm answer 0%%Ec, got "
                                                           f"{describe_answer(p)}", p)
    expect(len(p.raw) == want and p.raw.endswith(spec.TERMINATOR),
           f"alarm answer: expected {want} bytes ending CR LF, received {len(p.raw)} bytes ending "
           f"{show_bytes(p.raw[-2:])}", p)
