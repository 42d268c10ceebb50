"""The one ``PointData``: what a point frame carries, whether 0WP can write it back, and its text."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from xac1_proto import frames as fr
from xac1_proto import spec
from xac1_proto.errors import FrameError
from xac1_proto.points import PointData


def answer_values(name: str) -> st.SearchStrategy[int]:
    """Any value a point answer may carry in field ``name`` (0 included for V and A: never written)."""
    return st.integers(*spec.FIELDS[name].answer_range)


@given(n=st.integers(1, 15), v=answer_values("v"), a=answer_values("a"), o=answer_values("o"),
       pos=answer_values("pos"))
def test_restorable_exactly_when_0wp_takes_the_values(n, v, a, o, pos):
    """A point read back is restorable exactly when a 0WP with its values can be built (docs/protocol.md
    silent item 6: a point never written reads V 0 and A 0, which 0WP refuses); ``of`` keeps the values."""
    point = PointData.of(fr.ReadPointAnswer(n=n, v=v, a=a, o=o, pos=pos))
    assert (point.v, point.a, point.o, point.pos) == (v, a, o, pos)
    try:
        written = fr.WritePoint(n=n, v=v, a=a, o=o, pos=pos)
    except FrameError:
        assert not point.restorable
    else:
        assert point.restorable and PointData.of(written) == point


def test_show_writes_the_values_as_the_frames_do():
    """``show`` writes Pos as the frames carry it (six upper-case hex digits), so a snapshot's line reads as
    the evidence's."""
    assert PointData(9, 3, 0, 0x1ABCD).show() == "V=9 A=3 O=0 Pos=01ABCD"


def test_one_point_class_for_simulator_rulebook_and_snapshot():
    """The simulator's table, the rulebook's knowledge and the conformance snapshot hold the same class, so a
    point read from one compares equal with the same point from another."""
    from xac1_proto import conversation
    from xac1_proto.dut import safety
    from xac1_proto.sim import model

    assert model.PointData is conversation.PointData is safety.PointData is PointData
