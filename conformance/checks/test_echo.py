"""Echo answers: 0WP, 0MV, 0WS and 0CM answer with their command, field for field (the same header and
field values, as the rulebook judges an echo; framing flaws are the framing checks' to judge); 0%C
answers 0%C00."""

from __future__ import annotations

import pytest

from conformance.kit import reset_ok
from xac1_proto import spec
from xac1_proto.codec import diagnose, show_bytes
from xac1_proto.dut.evidence import describe_answer, differences, expect
from xac1_proto.frames import AlarmReset, SwitchMode, WriteOutputs, WritePoint


def _echoed(p, what):
    expect(not p.timed_out, f"{what}: no answer (silence)", p)
    expect(p.echoes(), f"{what}: expected the echo {show_bytes(p.sent)}, received {describe_answer(p)}"
           + (f"; {diff}" if (diff := _echo_difference(p)) else ""), p)


def _echo_difference(p):
    command, _ = diagnose(p.sent, spec.COMMAND)
    if command is None or p.frame is None or p.frame.header != command.header:
        return ""
    return differences(_named(command), _named(p.frame))


def _named(frame):
    return {spec.FIELDS[k].label: spec.FIELDS[k].show(v) if not spec.FIELDS[k].text else v
            for k, v in frame.fields().items()}


@pytest.mark.parametrize("v,a,o", [(1, 3, 0), (9, 1, 3)], ids=["V1A3O0", "V9A1O3"])
def test_write_point_echo(xac1_dut, xac1_kit, v, a, o):
    """0WP ({id}) answers with the command, field for field (docs/protocol.md "Frames", 0WP)."""
    p = xac1_dut.send(WritePoint(n=xac1_kit.point(1), v=v, a=a, o=o, pos=xac1_kit.safe_pos(1)))
    _echoed(p, "0WP")


@pytest.mark.parametrize("o", [0, 1, 2, 3])
def test_write_outputs_echo(xac1_dut, o):
    """0WS with O={id} answers with the command, field for field (docs/protocol.md "Frames", 0WS)."""
    _echoed(xac1_dut.send(WriteOutputs(o=o)), "0WS")


def test_switch_mode_echo(xac1_dut):
    """0CM0 and 0CM1 answer with the command, field for field (docs/protocol.md "Frames", 0CM)."""
    p0 = xac1_dut.send(SwitchMode(mode=0))
    p1 = xac1_dut.send(SwitchMode(mode=1))  # back to communication mode at once
    _echoed(p0, "0CM0")
    _echoed(p1, "0CM1")


@pytest.mark.xac1_motion
def test_direct_move_echo(xac1_dut, xac1_kit):
    """0MV answers with the command, field for field, once the move has ended
    (docs/protocol.md "Frames", 0MV)."""
    xac1_kit.require_homed()
    p = xac1_dut.send(xac1_kit.command("0MV"))
    _echoed(p, "0MV")


def test_reset_answer_without_alarm(xac1_dut):
    """0%C answers 0%C00, also when no alarm is latched (docs/protocol.md "Frames", alarm reset)."""
    p = xac1_dut.send(AlarmReset())
    expect(reset_ok(p), f"0%C: expected the reset answer 0%C00, received {describe_answer(p)}", p)
