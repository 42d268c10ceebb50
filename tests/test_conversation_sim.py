"""The rulebook against the simulator's device model, sans-IO: the clean simulator never gets a device-side
verdict, whatever a host sends (a hypothesis rule machine, emergency stop presses and releases fed to both
as the out-of-band stop input); each deviation the line can show gets one. Plus the simulator's silent
items 18 and 19 (a refused 0CM0 leaves the mode; emergency stop during a move)."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule
from strategies import frames

from xac1_proto import Framer, Junk, spec
from xac1_proto import frames as fr
from xac1_proto.conversation import Conversation, Verdict
from xac1_proto.sim.config import DEVIATIONS, SimConfig
from xac1_proto.sim.model import DeviceModel


class Line:
    """A host, the simulator's model and the rulebook on one line; time passes 10 ms a command."""

    def __init__(self, config: SimConfig) -> None:
        self.sim = DeviceModel(config)
        self.conv = Conversation()
        self.conv.power_on()
        self.t = 1000.0
        self.verdicts: list[Verdict] = []
        self._framers = {"host": Framer(), "device": Framer()}

    def _feed(self, side: str, data: bytes, t: float) -> None:
        c = self.conv
        for e in self._framers[side].feed(data, t):
            junk = isinstance(e, Junk)
            if side == "host":
                self.verdicts += (c.host_junk if junk else c.host_frame)(e.raw, e.t_first, e.t_last)
            else:
                self.verdicts += (c.device_junk if junk else c.device_frame)(e.raw, e.t_first, e.t_last)

    def send(self, raw: bytes) -> None:
        self.t += 0.01
        self._feed("host", raw, self.t)
        for out in self.sim.receive(raw, self.t):
            self.t = max(self.t, out.due)
            self._feed("device", out.data, out.due)
        self.sim.outbox.cancel()  # delivered above

    def stop(self, pressed: bool, t: float | None = None) -> None:
        t = self.t if t is None else t
        outs = self.sim.set_estop(pressed, t)
        self.conv.stop_input(pressed, unhomes=self.sim.config.estop_rehome)
        for out in outs:
            self._feed("device", out.data, out.due)

    def close(self) -> None:
        self.verdicts += self.conv.close(self.t + 100)

    def device_side(self) -> list[tuple[str, str]]:
        return [(code, v.violations[0].message) for v in self.verdicts
                for code, side in zip(v.codes, v.sides, strict=True) if side == "device"]


MALFORMED = [b"0RP3\n", b"0RP3\r\r\n", b"0XX\r\n", b"0RS12\r\n", b"\x01\x02\r\n", b"ORV\r\n", b"0rv\r\n",
             b"0WP09302000100\r\n"]


class CleanSimulator(RuleBasedStateMachine):
    """Anything a host sends to the clean simulator: no device-side verdict ever."""

    def __init__(self) -> None:
        super().__init__()
        self.line = Line(SimConfig(time_scale=0))

    @rule(command=frames("command"))
    def command(self, command: fr.Frame) -> None:
        self.line.send(command.to_bytes())

    @rule(raw=st.sampled_from(MALFORMED))
    def malformed(self, raw: bytes) -> None:
        self.line.send(raw)

    @rule()
    def reset(self) -> None:
        self.line.send(fr.AlarmReset().to_bytes())

    @rule(n=st.integers(1, 3), pos=st.integers(0, 0x2000))
    def write_then_move(self, n: int, pos: int) -> None:
        self.line.send(fr.WritePoint(n=n, v=9, a=3, o=n, pos=pos).to_bytes())
        self.line.send(fr.MovePoint(n=n).to_bytes())

    @rule(pressed=st.booleans())
    def stop_input(self, pressed: bool) -> None:
        self.line.stop(pressed)

    @invariant()
    def no_device_side_verdict(self) -> None:
        assert self.line.device_side() == []


CleanSimulator.TestCase.settings = settings(max_examples=budget(60), stateful_step_count=40, deadline=None,
                                            suppress_health_check=list(HealthCheck))
test_clean_simulator_never_gets_a_device_side_verdict = CleanSimulator.TestCase


def _script(line: Line) -> None:
    """A conversation that touches every stated rule a deviation can break."""
    for raw in (b"0RC\r\n", b"0RV\r\n", b"0WP19302000100\r\n", b"0RP1\r\n", b"0WS12\r\n", b"0RS\r\n",
                b"0MV3C3000200\r\n", b"0RC\r\n", b"0MP1\r\n", b"0RC\r\n", b"0WC2\r\n", b"0RP2\r\n",
                b"0CM1\r\n", b"0MP5\r\n", b"0RV\r\n", b"0%C\r\n", b"0XX\r\n", b"0%C\r\n", b"0RV\r\n"):
        line.send(raw)
    line.stop(True)
    for raw in (b"0RV\r\n", b"0%C\r\n", b"0RV\r\n"):
        line.send(raw)
    line.stop(False)
    for raw in (b"0RC\r\n", b"0%C\r\n", b"0RV\r\n"):
        line.send(raw)
    line.close()


def test_clean_script_is_clean():
    """The script itself, on the clean simulator: no device-side verdict."""
    line = Line(SimConfig(time_scale=0))
    _script(line)
    assert line.device_side() == []


@pytest.mark.parametrize("deviation", sorted(DEVIATIONS))
def test_every_deviation_gets_a_device_side_verdict(deviation):
    """Each simulator deviation breaks a stated rule; where the rulebook knows what it needs (power-on,
    the stop input), it names a device-side violation for it."""
    line = Line(SimConfig(time_scale=0, deviations=frozenset({deviation})))
    _script(line)
    assert line.device_side(), f"{deviation}: no device-side verdict"


def test_refused_0cm0_leaves_the_mode():
    """Silent item 18: 0CM0 answered with an alarm (one is latched) takes no effect: the mode stays 1."""
    line = Line(SimConfig(time_scale=0))
    line.send(b"0CM1\r\n")
    line.send(b"0MP5\r\n")  # point 5 never written: alarm 08, latched
    line.send(b"0CM0\r\n")
    assert line.sim.mode == 1 and line.conv.knowledge.mode.value == 1
    assert line.device_side() == []


def test_estop_during_a_move_stops_there_and_answers_0e():
    """Silent item 19: the stop input pressed during a move stops the axis where it is and the move's
    answer is 0%%0E; the rulebook, told of the stop input, finds nothing wrong."""
    line = Line(SimConfig(time_scale=1))
    line.send(b"0MP0\r\n")  # homing from power-on
    start = line.t
    line.sim.outbox.cancel()
    outs = line.sim.receive(b"0MV01300FFFF\r\n", start + 0.01)
    line._feed("host", b"0MV01300FFFF\r\n", start + 0.01)
    assert outs and outs[0].due > start + 10  # a long move
    line.stop(True, start + 1.0)
    assert line.sim.position is not None and 0 < line.sim.position < 0xFFFF
    answers = [v for v in line.verdicts if v.kind == "device-frame"]
    assert answers[-1].frame == fr.AlarmAnswer(code=spec.ALARM_ESTOP) and answers[-1].reply_to is not None
    assert line.device_side() == [] and not line.conv.moving
