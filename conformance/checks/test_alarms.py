"""Alarm latching: a malformed command latches an alarm; every other command then answers it; 0%C
answers 0%C00 and clears it; normal answers return.

At most four communication-error answers come in a row before the reset and a normal answer (the
vendor's host duty: stop after five).
"""

from __future__ import annotations

import pytest

from conformance.kit import COMMAND_HEADERS, MOTION_HEADERS, reset_ok
from conformance.results import ManualStep
from xac1_proto import spec
from xac1_proto.codec import show_bytes
from xac1_proto.dut.evidence import describe_answer, expect
from xac1_proto.frames import AlarmReset, ReadVersion

MALFORMED = b"0XY" + spec.TERMINATOR
LATCHED_KINDS = [h for h in COMMAND_HEADERS if h != spec.RESET_HEADER]


def _latch(dut):
    p = dut.probe(MALFORMED)
    expect(not p.timed_out, "no answer (silence) to a malformed command", p)
    expect(p.alarm is not None, f"a malformed command (0XY): expected an alarm answer 0%%Ec, received "
                                f"{describe_answer(p)}", p)
    return p


def _same_alarm(p, first) -> bool:
    """Is ``p`` an alarm answer with ``first``'s alarm code (fields, not bytes)?"""
    return p.alarm is not None and p.alarm.code == first.alarm.code


@pytest.mark.parametrize("header", [
    pytest.param(h, id=h, marks=pytest.mark.xac1_motion) if h in MOTION_HEADERS else pytest.param(h, id=h)
    for h in LATCHED_KINDS])
def test_alarm_latched(xac1_dut, xac1_kit, header):
    """After an alarm, {id} is answered with the same alarm until a reset (docs/protocol.md "Behaviour the
    vendor text states": an alarm is latched); the same alarm code, compared by fields as the rulebook
    does (a flaw in the answer's framing is the framing checks' to judge)."""
    if header in MOTION_HEADERS:
        xac1_kit.prepare(header)  # a safe point for 0MP: a broken latch could only move safely
    command = xac1_kit.command(header)
    first = _latch(xac1_dut)
    p = xac1_dut.send(command)
    expect(_same_alarm(p, first), f"with alarm {first.alarm.code:02X} latched, {header}: expected the alarm "
                               f"answer {show_bytes(first.raw)} again, received {describe_answer(p)}",
           first, p)
    again = xac1_dut.send(ReadVersion())
    expect(_same_alarm(again, first),
           f"the alarm was not latched: a second command (0RV): expected the alarm answer "
           f"{show_bytes(first.raw)}, received {describe_answer(again)}", first, p, again)


def test_reset_clears_alarm(xac1_dut):
    """With an alarm latched, 0%C answers 0%C00 and the next command gets its normal answer (docs/protocol.md
    "Behaviour the vendor text states": alarm reset)."""
    first = _latch(xac1_dut)
    r = xac1_dut.send(AlarmReset())
    expect(reset_ok(r), f"0%C: expected the reset answer 0%C00, received {describe_answer(r)}",
           first, r)
    n = xac1_dut.send(ReadVersion())
    expect(n.answered, f"after 0%C00 the next command got {describe_answer(n)}, not its normal answer",
           first, r, n)


def test_malformed_alarm_code(xac1_dut):
    """A malformed command is answered with an alarm answer (docs/protocol.md "Behaviour the vendor text
    states"); which code is information (silent item 1)."""
    p = _latch(xac1_dut)
    xac1_dut.info("alarm code for a malformed command", "silent item 1",
                  f"{p.alarm.code:02X} ({p.alarm.meaning})", p)


def test_estop_survives_reset(xac1_dut):
    """0%C does not clear an emergency stop: the next command still gets alarm 0E (docs/protocol.md "Behaviour
    the vendor text states": the reset clears every alarm except emergency stop)."""
    sim = getattr(xac1_dut.client.port, "model", None)
    if sim is None or not hasattr(sim, "set_estop"):
        raise ManualStep("press the emergency stop, then send 0%C and 0RV (e.g. with xac1 console)",
                         "0%C answers 0%%0E and 0RV answers 0%%0E too: the stop stays latched until the "
                         "stop input is released")
    sim.set_estop(True)
    xac1_dut.client.conversation.stop_input(True)  # the rulebook knows the stop input here
    try:
        first = xac1_dut.send(ReadVersion())
        expect(first.alarm is not None and first.alarm.code == spec.ALARM_ESTOP,
               f"with emergency stop on, 0RV got {describe_answer(first)}", first)
        r = xac1_dut.send(AlarmReset())
        after = xac1_dut.send(ReadVersion())
        xac1_dut.info("0%C during emergency stop", "silent item 3", describe_answer(r), r)
        expect(after.alarm is not None and after.alarm.code == spec.ALARM_ESTOP,
               f"0%C cleared the emergency stop: the next command (0RV): expected the alarm answer 0%%0E, "
               f"received {describe_answer(after)}",
               first, r, after)
    finally:
        sim.set_estop(False)
        xac1_dut.client.conversation.stop_input(False, unhomes=sim.config.estop_rehome)
        xac1_dut.latched = None  # the next check resets whatever is left
