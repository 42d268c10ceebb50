"""The position table: answers carry the command's N, read-back after write, 0WC stores the position."""

from __future__ import annotations

import pytest

from xac1_proto.dut.evidence import describe_answer, differences, expect
from xac1_proto.dut.safety import POINTS
from xac1_proto.frames import (
    MoveDirect,
    MovePoint,
    ReadPoint,
    ReadPointAnswer,
    StoreCurrent,
    StoreCurrentAnswer,
    WritePoint,
)

# V, A, O at their extremes (V and A always differ, so swapped fields show), over two points.
EXTREMES = [(1, 3, 0), (9, 1, 3), (2, 3, 1), (8, 1, 2)]


def test_read_point_carries_n(xac1_dut):
    """The 0RP answer carries the command's N, for every point 1-F (docs/protocol.md "Frames", 0RP)."""
    for n in POINTS:
        p = xac1_dut.send(ReadPoint(n=n))
        expect(isinstance(p.frame, ReadPointAnswer), f"0RP{n:X} got {describe_answer(p)}", p)
        expect(p.frame.n == n, f"0RP{n:X}: expected N={n:X} in the answer, received N={p.frame.n:X} "
                               f"({describe_answer(p)})", p)


@pytest.mark.parametrize("k,values", list(enumerate(EXTREMES)),
                         ids=[f"V{v}A{a}O{o}" for v, a, o in EXTREMES])
def test_read_back_after_write(xac1_dut, xac1_kit, k, values):
    """0RP after 0WP ({id}) answers exactly the values written (docs/protocol.md "Frames", 0WP and 0RP)."""
    v, a, o = values
    n, pos = xac1_kit.point(k % 2), xac1_kit.safe_pos(k)  # two points: a device mixing up N shows
    w = xac1_dut.send(WritePoint(n=n, v=v, a=a, o=o, pos=pos))
    expect(w.answered, f"0WP got {describe_answer(w)}", w)
    r = xac1_dut.send(ReadPoint(n=n))
    expect(isinstance(r.frame, ReadPointAnswer), f"0RP{n:X} got {describe_answer(r)}", w, r)
    want = {"N": f"{n:X}", "V": str(v), "A": str(a), "O": str(o), "Pos": f"{pos:06X}"}
    f = r.frame
    got = {"N": f"{f.n:X}", "V": str(f.v), "A": str(f.a), "O": str(f.o), "Pos": f"{f.pos:06X}"}
    expect(got == want, f"0RP{n:X} after 0WP: expected the values written, received {describe_answer(r)}; "
                        f"{differences(want, got)}", w, r)


@pytest.mark.xac1_motion
def test_store_current(xac1_dut, xac1_kit):
    """0WC N stores the current position into N: its answer carries N and that Pos, and 0RP N then reads
    the same data (docs/protocol.md "Frames", 0WC)."""
    xac1_kit.require_homed()
    n, target = xac1_kit.point(2), xac1_kit.other_target()
    m = xac1_dut.send(MoveDirect(vel=0x3C, a=3, pos=target))
    expect(m.answered, f"0MV (to prepare) got {describe_answer(m)}", m)
    s = xac1_dut.send(StoreCurrent(n=n))
    expect(isinstance(s.frame, StoreCurrentAnswer), f"0WC{n:X} got {describe_answer(s)}", m, s)
    expect(s.frame.n == n, f"0WC{n:X} answered N={s.frame.n:X}", m, s)
    expect(s.frame.pos == target, f"0WC answered Pos={s.frame.pos:06X}, the axis is at {target:06X}", m, s)
    r = xac1_dut.send(ReadPoint(n=n))
    expect(isinstance(r.frame, ReadPointAnswer), f"0RP{n:X} got {describe_answer(r)}", s, r)
    expect(r.frame.fields() == s.frame.fields(), "0RP after 0WC reads other data than 0WC answered", m, s, r)


@pytest.mark.xac1_motion
def test_point_move_carries_n(xac1_dut, xac1_kit):
    """The 0MP answer carries the command's N (docs/protocol.md "Frames", 0MP)."""
    xac1_kit.require_homed()
    xac1_kit.write_safe_point(3)
    n = xac1_kit.point(3)
    p = xac1_dut.send(MovePoint(n=n))
    expect(p.answered and p.frame.header == "0MP", f"0MP{n:X} got {describe_answer(p)}", p)
    expect(p.frame.n == n, f"0MP{n:X} answered N={p.frame.n:X}", p)
