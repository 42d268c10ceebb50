"""Where docs/protocol.md is silent: record what the device does, never fail it.

Each check here sends its probes, describes the answers in the report's information section and
passes whatever came back (silence included). Moves go only where the safety rules allow; a probe
they forbid is skipped with the reason.
"""

from __future__ import annotations

import pytest

from xac1_proto import spec
from xac1_proto.dut.evidence import describe_answer
from xac1_proto.dut.safety import POINTS
from xac1_proto.frames import (
    MoveDirect,
    MovePoint,
    ReadCurrent,
    ReadOutputs,
    ReadPoint,
    StoreCurrent,
    WriteOutputs,
    WritePoint,
)

pytestmark = pytest.mark.xac1_info


@pytest.mark.xac1_motion
def test_homing_answer(xac1_dut):
    """The fields of the 0MP 0 answer and of 0RC after homing (docs/protocol.md silent item 7)."""
    m = xac1_dut.send(MovePoint(n=0))
    r = xac1_dut.send(ReadCurrent())
    xac1_dut.info("0MP 0 answer", "silent item 7", describe_answer(m), m)
    xac1_dut.info("0RC after homing", "silent item 7", describe_answer(r), r)


@pytest.mark.xac1_motion
def test_rc_after_direct_move(xac1_dut, xac1_kit):
    """0RC's N, V, A and O after a direct move (docs/protocol.md silent item 9)."""
    xac1_kit.require_homed()
    m = xac1_dut.send(MoveDirect(vel=0x3C, a=2, pos=xac1_kit.other_target()))
    r = xac1_dut.send(ReadCurrent())
    xac1_dut.info("0RC after 0MV", "silent item 9", describe_answer(r), m, r)


@pytest.mark.xac1_motion
def test_point_move_answer_and_outputs(xac1_dut, xac1_kit):
    """The 0MP N answer's V, A, O, Pos, and the OUT ports after the move (docs/protocol.md silent item 8)."""
    xac1_kit.require_homed()
    n = xac1_kit.point(2)
    w = xac1_dut.send(WritePoint(n=n, v=9, a=3, o=2, pos=xac1_kit.other_target()))
    s = xac1_dut.send(WriteOutputs(o=1))
    m = xac1_dut.send(MovePoint(n=n))
    r = xac1_dut.send(ReadOutputs())
    xac1_dut.info("0MP N answer", "silent item 8", f"after 0WP wrote V=9 A=3 O=2: {describe_answer(m)}", w, m)
    xac1_dut.info("OUT ports after 0MP N", "silent item 8",
                  f"OUT was 1, the point's O is 2; after the move 0RS gives {describe_answer(r)}", s, m, r)


@pytest.mark.xac1_motion
def test_move_beyond_stroke(xac1_dut):
    """The alarm code for a move to a position beyond the stroke (FFFFFF) (docs/protocol.md silent item 5)."""
    m = xac1_dut.send(MoveDirect(vel=0x3C, a=3, pos=spec.UNKNOWN_POSITION))
    xac1_dut.info("0MV to FFFFFF (beyond the stroke)", "silent item 5", describe_answer(m), m)


def test_unwritten_points(xac1_dut, xac1_kit):
    """What points never written read back as (docs/protocol.md silent item 6), and 0MP to one (item 5)."""
    never = [n for n in POINTS if not xac1_kit.snapshot.points[n].restorable]
    untouched = [n for n in never if n not in xac1_kit.scratch[:6]]
    if not never:
        xac1_dut.info("points never written", "silent item 6", "every point held data before the run")
        return
    n = (untouched or never)[-1]
    r = xac1_dut.send(ReadPoint(n=n))
    xac1_dut.info("a point never written", "silent item 6",
                  f"{len(never)} point(s) read as never written; point {n:X}: {describe_answer(r)}", r)
    if untouched and xac1_dut.settings.motion:
        try:
            xac1_kit.require_homed()
            m = xac1_dut.send(MovePoint(n=n))
        except Exception as exc:  # noqa: BLE001 - information only: say why it was not probed
            xac1_dut.info("0MP to a point never written", "silent item 5", f"not probed: {exc}")
        else:
            xac1_dut.info("0MP to a point never written", "silent item 5", describe_answer(m), m)


def test_lowercase_hex(xac1_dut, xac1_kit):
    """A command with lower-case hex digits (0RP with N = a) (docs/protocol.md silent item 2)."""
    p = xac1_dut.probe(ReadPoint(n=0xA).to_bytes().lower())
    xac1_dut.info("lower-case hex from the host (0rpa)", "silent item 2", describe_answer(p), p)
    q = xac1_dut.probe(b"0RP" + b"a" + spec.TERMINATOR)
    xac1_dut.info("lower-case hex digit in a field (0RPa)", "silent item 2", describe_answer(q), q)


def test_store_into_point_0(xac1_dut):
    """0WC 0 (point 0 is home, not a stored point) (docs/protocol.md silent item 4)."""
    p = xac1_dut.probe(StoreCurrent.unchecked(n=0).to_bytes())
    xac1_dut.info("0WC 0", "silent item 4", describe_answer(p), p)


def test_extreme_positions(xac1_dut, xac1_kit):
    """0WP with Pos 000000 and FFFFFF, read back (docs/protocol.md silent item 5: 0WP stores any Pos); the
    point then gets a safe Pos again."""
    n = xac1_kit.point(0)
    seen = []
    for pos in (0, spec.UNKNOWN_POSITION):
        w = xac1_dut.send(WritePoint(n=n, v=5, a=2, o=0, pos=pos))
        r = xac1_dut.send(ReadPoint(n=n))
        xac1_dut.info(f"0WP with Pos {pos:06X}, read back", "silent item 5", describe_answer(r), w, r)
        seen.append(r)
    xac1_dut.send(WritePoint(n=n, v=5, a=2, o=0, pos=xac1_kit.safe_pos(0)))
