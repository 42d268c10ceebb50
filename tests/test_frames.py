"""Frames are values: equal by kind and fields, hashed alike, immutable, always true, without an order,
and copied or unpickled as they were made (a lenient frame too); building one by its fields checks them."""

from __future__ import annotations

import copy
import operator
import pickle

import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import frames

from xac1_proto import frames as fr
from xac1_proto import spec
from xac1_proto.errors import FrameError


@given(frames(), frames())
def test_two_frames_are_equal_exactly_when_of_one_kind_with_the_same_fields(a: fr.Frame, b: fr.Frame) -> None:
    """Two frames are equal exactly when they are of one kind with the same fields, and then hash alike."""
    same = type(a) is type(b) and a.fields() == b.fields()
    assert (a == b) is same
    assert (a != b) is not same
    if same:
        assert hash(a) == hash(b)


@given(frames())
def test_a_frame_is_a_value_that_copies_and_pickles_as_itself(frame: fr.Frame) -> None:
    """A frame copies, deep-copies and pickles as an equal frame of its own kind."""
    assert frame  # even one without fields
    for other in (copy.copy(frame), copy.deepcopy(frame), pickle.loads(pickle.dumps(frame))):
        assert type(other) is type(frame) and other == frame and hash(other) == hash(frame)
    assert type(frame)(**frame.fields()) == frame
    assert type(frame)._make(tuple(frame)) == frame  # type: ignore[attr-defined]  # the NamedTuple's


@given(frames())
def test_a_frame_cannot_be_changed(frame: fr.Frame) -> None:
    """Frames are immutable: no field (nor a new attribute) can be set."""
    for name in [*frame.fields(), "extra"]:
        with pytest.raises(AttributeError):
            setattr(frame, name, 1)


def test_frames_of_different_kinds_with_the_same_values_differ_and_have_no_order() -> None:
    """Frames of different kinds with the same values are not equal (nor equal to a plain tuple) and have no
    order."""
    a, b = fr.ReadPoint(n=3), fr.MovePoint(n=3)
    assert a != b and not operator.eq(a, b) and a != (3,)
    assert operator.ne((3,), a) and not operator.eq((3,), a)  # a plain tuple on the left too
    assert fr.ReadCurrent() != fr.ReadOutputs() and fr.ReadCurrent() == fr.ReadCurrent()
    assert len({a, b, fr.ReadPoint(n=3)}) == 2
    with pytest.raises(TypeError):
        _ = a < fr.ReadPoint(n=4)


def test_every_kind_is_named_by_its_fields_and_shown_as_a_dataclass_was() -> None:
    """Each frame class's fields are its spec row's, and its repr names them."""
    for (header, role), cls in fr.FRAME_CLASSES.items():
        assert cls.field_names() == spec.SPECS[(header, role)].field_names
    assert repr(fr.ReadPoint(n=3)) == "ReadPoint(n=3)" and repr(fr.ReadCurrent()) == "ReadCurrent()"


def test_building_by_fields_checks_them_and_unchecked_keeps_what_it_is_given() -> None:
    """Building a frame checks its fields (range and type, with the violation code); the unchecked constructor
    keeps what it is given."""
    with pytest.raises(FrameError, match=r"0RP command: byte 3: N must be 1-F, got 0 \(field-range\)"):
        fr.ReadPoint(n=0)
    with pytest.raises(TypeError, match="must be an int"):
        fr.ReadPoint(n="3")
    with pytest.raises(TypeError):
        fr.ReadPoint(m=3)
    lenient = fr.ReadPoint.unchecked(n=0)
    assert lenient.n == 0 and copy.copy(lenient) == lenient and pickle.loads(pickle.dumps(lenient)) == lenient


@given(st.sampled_from(sorted(fr.FRAME_CLASSES.values(), key=lambda c: (c.HEADER, c.ROLE))))
def test_a_frame_kind_is_a_frame_and_its_header_and_role_are_its_rows(cls: type[fr.Frame]) -> None:
    """Each frame kind is a ``Frame`` whose spec row is the one of its header and role."""
    assert issubclass(cls, fr.Frame) and cls.frame_spec() is spec.SPECS[(cls.HEADER, cls.ROLE)]
