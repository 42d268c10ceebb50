"""The simulator's mode (docs/protocol.md silent items 11 and 18, one reading): communicating switches the
controller to mode 1, and a refused or malformed line is communicating too; only a 0CM0 carried out sets
mode 0. The simulator and the rulebook say the same (issue 23 item 4)."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from xac1_proto.conversation import Conversation
from xac1_proto.sim.config import SimConfig
from xac1_proto.sim.model import DeviceModel

LINES = [b"0CM0\r\n", b"0CM1\r\n", b"0RV\r\n", b"0XY\r\n", b"0RP3\n", b"0MP5\r\n", b"0%C\r\n",
         b"0WS12\r\n", b"0RS\r\n"]


def run(lines: list[bytes]) -> tuple[DeviceModel, Conversation]:
    """Send each line to the simulator and feed both sides to the rulebook."""
    sim, conv = DeviceModel(SimConfig(time_scale=0)), Conversation()
    conv.power_on()
    t = 1.0
    for raw in lines:
        t += 0.01
        conv.host_frame(raw, t, t)
        for out in sim.receive(raw, t):
            conv.device_frame(out.data, out.due, out.due)
        sim.outbox.cancel()
    return sim, conv


@pytest.mark.parametrize("line", [b"0XY\r\n", b"0RP3\n", b"0MP5\r\n"],
                         ids=["unknown", "bad-length", "refused"])
def test_a_refused_or_malformed_line_after_0cm0_leaves_mode_1(line):
    """After 0CM0, a malformed line or a command refused with an alarm answer is communication: mode 1
    (silent items 11 and 18), in the simulator and in the rulebook alike."""
    sim, conv = run([b"0CM0\r\n", line])
    assert sim.mode == 1
    assert (conv.knowledge.mode.value, conv.knowledge.mode.judged) == (1, True)


def test_a_refused_0cm0_does_not_switch_to_mode_0():
    """A 0CM0 refused because an alarm is latched takes no effect of its own (silent item 18)."""
    sim, conv = run([b"0CM1\r\n", b"0MP5\r\n", b"0CM0\r\n"])
    assert sim.mode == 1 and conv.knowledge.mode.value == 1


@settings(max_examples=budget(80), deadline=None)
@given(st.lists(st.sampled_from(LINES), max_size=15))
def test_the_simulator_and_the_rulebook_agree_on_the_mode(lines):
    """Whatever lines come, the mode the rulebook holds (when it holds one) is the simulator's."""
    sim, conv = run(lines)
    mode = conv.knowledge.mode
    assert not mode.judged or mode.value == sim.mode
