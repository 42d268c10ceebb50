"""The rulebook from the line alone against the clean simulator: events the line cannot show (the stop
input pressed and released, a power cycle in a silence, an alarm raised or a move failing) never give the
clean device a device-side verdict (issue 23 items 2 and 3). Plus the simulator's reset during an
emergency stop (vendor §6: 0%C clears every alarm but emergency stop)."""

from __future__ import annotations

from conftest import budget
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule
from strategies import frames
from test_conversation_sim import MALFORMED, Line

from xac1_proto import frames as fr
from xac1_proto import spec
from xac1_proto.conversation import Conversation
from xac1_proto.sim.config import SimConfig
from xac1_proto.sim.model import DeviceModel

RAISABLE = [spec.ALARM_COMM, spec.ALARM_MEMORY_RW, spec.ALARM_MEMORY_DATA, spec.ALARM_POSITION,
            spec.ALARM_LIMIT, spec.ALARM_PULSE, spec.ALARM_HOMING]


class LineAlone(Line):
    """A ``Line`` whose rulebook is told nothing the line cannot show."""

    def stop(self, pressed: bool, t: float | None = None) -> None:
        for out in self.sim.set_estop(pressed, self.t if t is None else t):
            self._feed("device", out.data, out.due)

    def power_cycle(self) -> None:
        """Off and on in a silence: the position table kept (non-volatile, silent item 16)."""
        self.sim = DeviceModel(self.sim.config, points=self.sim.points)


class CleanSimulatorFromTheLineAlone(RuleBasedStateMachine):
    """Anything a host sends, anything that happens off the line: no device-side verdict ever."""

    def __init__(self) -> None:
        super().__init__()
        self.line = LineAlone(SimConfig(time_scale=0))

    @rule(command=frames("command"))
    def command(self, command: fr.Frame) -> None:
        self.line.send(command.to_bytes())

    @rule(raw=st.sampled_from(MALFORMED))
    def malformed(self, raw: bytes) -> None:
        self.line.send(raw)

    @rule()
    def reset(self) -> None:
        self.line.send(fr.AlarmReset().to_bytes())

    @rule(header=st.sampled_from([b"0RV\r\n", b"0RC\r\n", b"0RS\r\n"]))
    def read(self, header: bytes) -> None:
        self.line.send(header)

    @rule(n=st.integers(1, 3), pos=st.integers(0, 0x2000))
    def write_then_move(self, n: int, pos: int) -> None:
        self.line.send(fr.WritePoint(n=n, v=9, a=3, o=n, pos=pos).to_bytes())
        self.line.send(fr.MovePoint(n=n).to_bytes())

    @rule(pressed=st.booleans())
    def stop_input(self, pressed: bool) -> None:
        self.line.stop(pressed)

    @precondition(lambda self: self.line.sim.latched is None)
    @rule(code=st.sampled_from(RAISABLE))
    def raise_alarm(self, code: int) -> None:
        self.line.sim.raise_alarm(code)

    @rule(code=st.sampled_from(sorted({spec.ALARM_LIMIT, spec.ALARM_HOMING, spec.ALARM_PULSE})))
    def fail_next_move(self, code: int) -> None:
        self.line.sim.fail_next_move(code)

    # a power cycle also clears the OUT ports and any latched alarm, which the line cannot show either
    # and nothing tells from a broken device: only the homing is at stake here
    @precondition(lambda self: self.line.sim.latched is None and self.line.sim.outputs == 0)
    @rule()
    def power_cycle(self) -> None:
        self.line.power_cycle()

    @invariant()
    def no_device_side_verdict(self) -> None:
        assert self.line.device_side() == []


CleanSimulatorFromTheLineAlone.TestCase.settings = settings(
    max_examples=budget(80), stateful_step_count=40, deadline=None, suppress_health_check=list(HealthCheck))
test_clean_simulator_from_the_line_alone_never_gets_a_device_side_verdict = \
    CleanSimulatorFromTheLineAlone.TestCase


def test_reset_during_emergency_stop_clears_the_other_alarms():
    """vendor §6: 0%C clears every alarm but emergency stop. With alarm 09 latched and the stop on, 0%C
    answers 0%%0E and clears 09: after the release the next command gets its normal answer, and the
    rulebook from the line alone finds nothing wrong."""
    line = LineAlone(SimConfig(time_scale=0))
    line.sim.raise_alarm(spec.ALARM_LIMIT)
    line.send(b"0RV\r\n")
    line.stop(True)
    line.send(b"0%C\r\n")
    assert line.sim.latched == spec.ALARM_ESTOP and line.sim.alarm is None
    line.stop(False)
    line.send(b"0RV\r\n")
    answers = [v.raw for v in line.verdicts if v.kind == "device-frame"]
    assert answers == [b"0%%09\r\n", b"0%%0E\r\n", b"0RV100\r\n"]
    assert line.device_side() == []


def test_an_alarm_held_under_the_stop_comes_back_after_the_release():
    """Without a reset, an alarm latched before the emergency stop is still latched after the release
    (vendor §6: held until a reset): the device repeating it is right, from the line alone too."""
    line = LineAlone(SimConfig(time_scale=0))
    line.sim.raise_alarm(spec.ALARM_LIMIT)
    line.send(b"0RV\r\n")
    line.stop(True)
    line.send(b"0RV\r\n")
    line.stop(False)
    line.send(b"0RV\r\n")
    answers = [v.raw for v in line.verdicts if v.kind == "device-frame"]
    assert answers == [b"0%%09\r\n", b"0%%0E\r\n", b"0%%09\r\n"]
    assert line.device_side() == []


def device_codes(steps: list[tuple[bytes, bytes] | bool]) -> list[str]:
    """The device-side codes the rulebook gives a script of (command, answer) exchanges, 0.1 s apart; a
    bool in it is the stop input told to the engine (pressed or released)."""
    c = Conversation()
    out = []
    for k, step in enumerate(steps):
        if isinstance(step, bool):
            c.stop_input(step)
            continue
        cmd, ans = step
        out += c.host_frame(cmd, k * 0.1, k * 0.1) + c.device_frame(ans, k * 0.1 + 0.002, k * 0.1 + 0.002)
    return [code for v in out for code, side in zip(v.codes, v.sides, strict=True) if side == "device"]


def test_an_alarm_cleared_during_the_stop_coming_back_is_judged_only_where_the_release_is_known():
    """A reset during the emergency stop clears alarm 09 (vendor §6). Told of the stop input, the rulebook
    calls 09 answering a plain 0RV right after the release latch-broken (stop-alarm-back, a reading). From
    the line alone the release is unseen, and the same bytes come from a clean device on which a new 09
    arose after it (the CleanSimulatorFromTheLineAlone machine found one): nothing is judged."""
    script: list[tuple[bytes, bytes] | bool] = [
        (b"0RV\r\n", b"0%%09\r\n"), True, (b"0RV\r\n", b"0%%0E\r\n"), (b"0%C\r\n", b"0%%0E\r\n"), False,
        (b"0RV\r\n", b"0%%09\r\n")]
    assert device_codes(script) == ["latch-broken"]
    assert device_codes([step for step in script if not isinstance(step, bool)]) == []


def test_after_the_stop_a_new_alarm_is_no_latch_broken():
    """From the line alone the release is unseen: after 0%%0E, a move refused with 0%%08 is a new alarm,
    not a latched code changing."""
    c = Conversation()
    out = []
    for k, (cmd, ans) in enumerate([(b"0RV\r\n", b"0%%0E\r\n"), (b"0MP5\r\n", b"0%%08\r\n")]):
        out += c.host_frame(cmd, k * 0.1, k * 0.1) + c.device_frame(ans, k * 0.1 + 0.002, k * 0.1 + 0.002)
    assert [side for v in out for side in v.sides if side == "device"] == []


def test_a_reset_that_meets_the_stop_first_still_clears_the_other_alarm():
    """Alarm 09 latched; the stop pressed; 0%C answered 0%%0E has cleared 09 (vendor §6): after a release
    the rulebook is told of, 09 coming back to 0RV is latch-broken, and the clean simulator's normal answer
    is not; from the line alone (release unseen) neither is judged."""
    def run(last: bytes, told: bool) -> list[str]:
        script: list[tuple[bytes, bytes] | bool] = [
            (b"0RV\r\n", b"0%%09\r\n"), True, (b"0%C\r\n", b"0%%0E\r\n"), False, (b"0RV\r\n", last)]
        return device_codes(script if told else [step for step in script if not isinstance(step, bool)])

    assert run(b"0%%09\r\n", told=True) == ["latch-broken"]
    assert run(b"0RV100\r\n", told=True) == []
    assert run(b"0%%09\r\n", told=False) == run(b"0RV100\r\n", told=False) == []


def test_a_new_alarm_after_the_release_is_the_latched_one_not_the_cleared_one():
    """Alarm 01 latched; the stop pressed; 0%C during it clears 01 (vendor §6); the stop released; a
    malformed line raises 01 anew: the clean simulator's 01 to the next 0RC is that new latched alarm,
    never the cleared one coming back (no latch-broken). Found by the CleanSimulator rule machine."""
    line = Line(SimConfig(time_scale=0))
    line.send(b"0RP3\n")
    line.stop(True)
    line.send(fr.AlarmReset().to_bytes())
    line.send(fr.WritePoint(n=1, v=1, a=1, o=0, pos=0).to_bytes())
    line.stop(False)
    line.send(b"0RP3\n")
    line.send(fr.ReadCurrent().to_bytes())
    answers = [v.raw for v in line.verdicts if v.kind == "device-frame"]
    assert answers[-2:] == [b"0%%01\r\n", b"0%%01\r\n"]
    assert line.device_side() == []


def test_a_lower_case_command_refused_after_the_release_is_a_new_alarm_not_the_cleared_one():
    """Alarm 01 latched; the stop pressed; 0%C during it clears 01 (vendor §6); the stop released; then
    ``0rv``: the simulator refuses lower case with alarm 01 of its own (silent item 2), so that 01 is a
    new alarm, never the cleared one coming back (no latch-broken). The same 01 answering a plain 0RV is
    latch-broken where the rulebook is told of the stop input. Found by the CleanSimulator rule machine."""
    line = Line(SimConfig(time_scale=0))
    line.send(b"0RP3\n")
    line.stop(True)
    line.send(fr.AlarmReset().to_bytes())
    line.stop(False)
    line.send(b"0rv\r\n")
    answers = [v.raw for v in line.verdicts if v.kind == "device-frame"]
    assert answers[-1] == b"0%%01\r\n"
    assert line.device_side() == []

    def judged(command: bytes) -> list[str]:  # the stop input told to the rulebook
        return device_codes([(b"0RP3\n", b"0%%01\r\n"), True, (b"0%C\r\n", b"0%%0E\r\n"), False,
                             (command, b"0%%01\r\n")])

    assert judged(b"0rv\r\n") == []
    assert judged(b"0RV\r\n") == ["latch-broken"]
