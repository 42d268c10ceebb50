"""Power-on behaviour (fresh device only; these run before anything moves or stores a position)."""

from __future__ import annotations

import pytest

from xac1_proto import spec
from xac1_proto.dut.evidence import describe_answer, differences, expect
from xac1_proto.frames import MoveDirect, ReadCurrentAnswer, StoreCurrent

pytestmark = pytest.mark.xac1_fresh


def test_rc_before_homing(xac1_dut):
    """0RC before homing and before any move answers N, V, A = 0 and Pos = FFFFFF (docs/protocol.md "Behaviour
    the vendor text states")."""
    p = xac1_dut.current_position()
    expect(isinstance(p.frame, ReadCurrentAnswer), f"0RC got {describe_answer(p)}", p)
    f = p.frame
    hint = ""
    if f.pos != spec.UNKNOWN_POSITION:  # a position: most likely homed since power-on, not a wrong answer
        hint = (f"; 0RC answers a position, so the unit has most likely been homed since it was powered on: "
                f"power-cycle the unit and run again, or drop {xac1_dut.settings.flag('fresh')}")
    expect((f.n, f.v, f.a, f.pos) == (0, 0, 0, spec.UNKNOWN_POSITION),
           f"0RC before homing: expected N=0 V=0 A=0 Pos=FFFFFF, received {describe_answer(p)}; "
           + differences({"N": "0", "V": "0", "A": "0", "Pos": "FFFFFF"},
                         {"N": f"{f.n:X}", "V": str(f.v), "A": str(f.a), "Pos": f"{f.pos:06X}"}) + hint, p)
    xac1_dut.info("0RC O before homing", "silent item 8", f"O={f.o} (the current OUT ports)", p)


@pytest.mark.xac1_info
def test_store_before_homing(xac1_dut, xac1_kit):
    """0WC before homing, when the current position is unknown (docs/protocol.md silent item 4)."""
    p = xac1_dut.send(StoreCurrent(n=xac1_kit.point(0)))
    xac1_dut.info("0WC before homing", "silent item 4", describe_answer(p), p)


@pytest.mark.xac1_motion
def test_first_move_homes_first(xac1_dut, xac1_kit):
    """A first 0MV on a never-homed axis homes, then moves, then answers: 0RC then reads the move's Pos
    (docs/protocol.md "Behaviour the vendor text states")."""
    if not xac1_dut.settings.may_home:
        pytest.skip("homing goes to the origin, outside the safe range")
    target = xac1_kit.other_target()
    m = xac1_dut.send(MoveDirect(vel=0x3C, a=3, pos=target))
    expect(m.echoes(), f"0MV before homing got {describe_answer(m)}, expected its echo", m)
    r = xac1_dut.current_position()
    expect(isinstance(r.frame, ReadCurrentAnswer) and r.frame.pos == target,
           f"after the first 0MV to {target:06X}, 0RC answered {describe_answer(r)}", m, r)
