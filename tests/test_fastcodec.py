"""The fast path for clean frames gives exactly what the full lenient decode gives (docs/protocol.md
"Framing"): hypothesis over well-formed frames, their mutations and arbitrary bytes."""

from __future__ import annotations

import re

from hypothesis import given
from hypothesis import strategies as st

from xac1_proto import spec
from xac1_proto.codec import diagnose
from xac1_proto.fastcodec import decode_clean, digits_in_range
from xac1_proto.frames import FRAME_CLASSES, AlarmAnswer, ReadPointAnswer

ROLES = st.sampled_from(spec.ROLES)


@st.composite
def wire_frames(draw: st.DrawFn) -> tuple[bytes, str]:
    """A frame's wire bytes with arbitrary field values (in range or not), and its role."""
    fs = draw(st.sampled_from(spec.FRAME_SPECS))
    out = fs.header
    for item in fs.layout:
        if isinstance(item, str):
            field = spec.FIELDS[item]
            alphabet = "0123456789ABCDEFabcdef" if field.radix == 16 else "0123456789"
            out += draw(st.text(alphabet, min_size=field.width, max_size=field.width))
        else:
            out += item.text
    return out.encode("ascii") + spec.TERMINATOR, fs.role


def mutated(data: bytes, at: int, byte: int, how: str) -> bytes:
    at %= len(data) + 1
    if how == "replace" and at < len(data):
        return data[:at] + bytes([byte]) + data[at + 1:]
    if how == "insert":
        return data[:at] + bytes([byte]) + data[at:]
    return data[:at] + data[at + 1:]


def agrees(data: bytes, role: str) -> None:
    fast = decode_clean(data, role)
    frame, violations = diagnose(data, role)
    if fast is not None:
        assert violations == [] and fast == frame and type(fast) is type(frame)
    elif not violations:
        raise AssertionError(f"the fast path refused a clean frame: {data!r}")


@given(wire_frames())
def test_every_frame_kind_agrees(case: tuple[bytes, str]) -> None:
    """For every frame kind, the quick decode of well-formed frames reads what the grammar reads."""
    agrees(*case)


@given(wire_frames(), st.integers(0, 20), st.integers(0, 255), st.sampled_from(["replace", "insert", "drop"]))
def test_mutated_frames_agree(case: tuple[bytes, str], at: int, byte: int, how: str) -> None:
    """A frame with a byte changed, inserted or removed: the quick decode agrees with the grammar (or leaves
    it to the grammar)."""
    data, role = case
    agrees(mutated(data, at, byte, how), role)


@given(st.binary(max_size=24), ROLES)
def test_arbitrary_bytes_agree(data: bytes, role: str) -> None:
    """Any bytes: the quick decode agrees with the grammar."""
    agrees(data, role)


def test_vendor_examples_take_the_fast_path() -> None:
    """The vendor's examples decode on the fast path to the frames the spec gives."""
    assert decode_clean(b"0RP39302012345\r\n", "answer") == ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x012345)
    assert decode_clean(b"0%%0E\r\n", "answer") == AlarmAnswer(code=0x0E)
    assert decode_clean(b"0%%03\r\n", "answer") is None  # reserved alarm: the full path adds its notice
    assert decode_clean(b"0rp3\r\n", "command") is None
    assert len({cls for cls in FRAME_CLASSES.values()}) == len(spec.FRAME_SPECS)


@given(st.sampled_from([10, 16]), st.integers(1, 4), st.data())
def test_a_field_pattern_matches_exactly_the_values_in_its_range(radix: int, width: int,
                                                                   data: st.DataObject) -> None:
    """A field's digits match the frame's pattern exactly when their value is in the field's range (the
    range is checked by the pattern alone: ``decode_clean`` checks nothing after a match)."""
    top = radix ** width - 1
    lo = data.draw(st.integers(0, top))
    hi = data.draw(st.integers(lo, top))
    pattern = re.compile(digits_in_range(lo, hi, width, radix))
    for value in {0, lo, hi, top, max(lo - 1, 0), min(hi + 1, top), data.draw(st.integers(0, top))}:
        digits = (f"{value:0{width}X}" if radix == 16 else f"{value:0{width}d}").encode("ascii")
        assert (pattern.fullmatch(digits) is not None) == (lo <= value <= hi), (digits, lo, hi)
        assert pattern.fullmatch(digits + b"0") is None and pattern.fullmatch(digits[1:]) is None
        if digits.lower() != digits:  # lower-case hex is never clean
            assert pattern.fullmatch(digits.lower()) is None
