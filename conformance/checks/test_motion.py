"""Moves: 0MP and 0MV reach their target (0RC agrees), 0MP 0 homes."""

from __future__ import annotations

import pytest

from xac1_proto import spec
from xac1_proto.dut.evidence import describe_answer, expect
from xac1_proto.frames import MoveDirect, MovePoint, ReadCurrentAnswer, WritePoint

pytestmark = pytest.mark.xac1_motion


def _position(dut, *evidence):
    r = dut.current_position()
    expect(isinstance(r.frame, ReadCurrentAnswer), f"0RC got {describe_answer(r)}",
           *evidence, r)
    return r


def test_point_move_reaches_target(xac1_dut, xac1_kit):
    """After 0MP N has answered, 0RC reads point N's Pos (docs/protocol.md "Frames", 0MP; "Behaviour the
    vendor text states": the answer comes after the move)."""
    xac1_kit.require_homed()
    n, target = xac1_kit.point(1), xac1_kit.other_target()
    w = xac1_dut.send(WritePoint(n=n, v=9, a=3, o=xac1_kit.snapshot.outputs, pos=target))
    expect(w.answered, f"0WP (to prepare) got {describe_answer(w)}", w)
    m = xac1_dut.send(MovePoint(n=n))
    expect(m.answered, f"0MP{n:X} got {describe_answer(m)}", w, m)
    r = _position(xac1_dut, w, m)
    expect(r.frame.pos == target, f"0RC after 0MP{n:X}: expected Pos={target:06X} (point {n:X}'s Pos), "
                                  f"received Pos={r.frame.pos:06X}", w, m, r)


def test_direct_move_reaches_target(xac1_dut, xac1_kit):
    """After 0MV has answered, 0RC reads the move's Pos (docs/protocol.md "Frames", 0MV)."""
    xac1_kit.require_homed()
    target = xac1_kit.other_target()
    m = xac1_dut.send(MoveDirect(vel=0x3C, a=2, pos=target))
    expect(m.answered, f"0MV got {describe_answer(m)}", m)
    r = _position(xac1_dut, m)
    expect(r.frame.pos == target, f"0RC after 0MV: expected Pos={target:06X} (the move's target), received "
                                  f"Pos={r.frame.pos:06X}", m, r)


def test_homing(xac1_dut, xac1_kit):
    """0MP 0 homes: it answers as 0MP with N 0, and 0RC no longer reads the unknown position FFFFFF
    (docs/protocol.md "Frames", 0MP; "Behaviour the vendor text states")."""
    m = xac1_dut.send(MovePoint(n=0))
    expect(m.answered and m.frame.header == "0MP", f"0MP0 got {describe_answer(m)}", m)
    expect(m.frame.n == 0, f"0MP0 answered N={m.frame.n:X}", m)
    r = _position(xac1_dut, m)
    expect(r.frame.pos != spec.UNKNOWN_POSITION, "0RC after homing still reads Pos FFFFFF", m, r)
