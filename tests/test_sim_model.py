"""The sans-IO device model: stated rules, silent-point defaults, faults, deviations, fuzz."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

import xac1_proto as x
from xac1_proto import spec
from xac1_proto.sim import DEVIATIONS, DeviceModel, LineFaults, SimConfig, config_from_options

INSTANT = SimConfig(time_scale=0)
ALARM_01 = x.AlarmAnswer(code=spec.ALARM_COMM).to_bytes()


def talk(model: DeviceModel, data: bytes, t: float = 0.0) -> bytes:
    """Feed ``data`` at ``t`` and take every answer byte (however late it is due)."""
    model.receive(data, t)
    return model.outbox.pop(float("inf"))


def frame(cmd: x.Frame) -> bytes:
    return cmd.to_bytes()


def test_vendor_examples() -> None:
    """docs/protocol.md "Frames" vendor examples: 0WP echoes, 0RP reads back, 0RV answers 0RV100."""
    m = DeviceModel(INSTANT)
    assert talk(m, b"0WP39302012345\r\n") == b"0WP39302012345\r\n"
    assert talk(m, b"0RP3\r\n") == b"0RP39302012345\r\n"
    assert talk(m, b"0RV\r\n") == b"0RV100\r\n"


def test_rc_before_homing_then_moves() -> None:
    """docs/protocol.md "Behaviour the vendor text states": 0RC before homing is N/V/A 0, Pos FFFFFF; 0MP
    homes first; silent items 7, 8, 9 for 0RC after homing, a point move and a direct move."""
    m = DeviceModel(INSTANT)
    assert talk(m, b"0WS22\r\n") == b"0WS22\r\n"
    assert talk(m, b"0RC\r\n") == b"0RC00022FFFFFF\r\n"
    assert talk(m, b"0MP0\r\n") == b"0MP00022000000\r\n"
    assert talk(m, b"0RC\r\n") == b"0RC00022000000\r\n"
    talk(m, b"0WP57212001000\r\n")
    assert talk(m, b"0MP5\r\n") == b"0MP57212001000\r\n"
    assert talk(m, b"0RC\r\n") == b"0RC57212001000\r\n"  # O: current outputs, set by the move
    assert talk(m, b"0MV1E3003A98\r\n") == b"0MV1E3003A98\r\n"
    assert talk(m, b"0RC\r\n") == b"0RC00312003A98\r\n"


def test_move_homes_first_when_not_homed() -> None:
    """docs/protocol.md "Behaviour the vendor text states": 0MP/0MV home first when the axis has not been
    homed, then move."""
    m = DeviceModel(SimConfig(time_scale=1.0, turnaround_s=0.0))
    m.receive(b"0MV3C3001388\r\n", 0.0)
    (out,) = [o for o in [m.outbox] if o.next_due is not None]
    speeds = m.config.speeds
    homing = x.motion.move_time(m.config.homing_distance, speeds.homing_pps, speeds.homing_accel)
    leg = x.motion.move_time(5000, speeds.direct_speed(60), 3)
    assert out.next_due == pytest.approx(homing + leg)


def test_alarm_latch_and_reset() -> None:
    """docs/protocol.md "Behaviour the vendor text states" + silent item 1: a malformed command latches 01;
    every command is then answered 0%%01; 0%C answers 0%C00 and normal answers return."""
    m = DeviceModel(INSTANT)
    assert talk(m, b"0RP3\n") == ALARM_01
    for cmd in (b"0RV\r\n", b"0RS\r\n", b"0WP19302012345\r\n", b"0MP0\r\n", b"0CM1\r\n"):
        assert talk(m, cmd) == ALARM_01
    assert talk(m, b"0%C\r\n") == b"0%C00\r\n"
    assert talk(m, b"0RV\r\n") == b"0RV100\r\n"
    assert talk(m, b"0RP1\r\n") == b"0RP10002000000\r\n"  # the 0WP during the alarm was not stored


def test_estop_survives_reset() -> None:
    """docs/protocol.md "Behaviour the vendor text states": 0%C clears every alarm but emergency stop; silent
    item 3: 0%C answers 0%%0E, and after release the axis must home again (0RC answers FFFFFF)."""
    m = DeviceModel(INSTANT)
    talk(m, b"0MP0\r\n")
    m.set_estop(True)
    estop = x.AlarmAnswer(code=spec.ALARM_ESTOP).to_bytes()
    assert talk(m, b"0RV\r\n") == estop
    assert talk(m, b"0%C\r\n") == estop
    assert talk(m, b"0%C\r\n") == estop
    assert talk(m, b"0RC\r\n") == estop
    m.set_estop(False)
    assert talk(m, b"0RC\r\n") == b"0RC00002FFFFFF\r\n"


def test_estop_during_move_answers_0E() -> None:
    """Emergency stop during a move: the move's answer becomes 0%%0E and the axis stops on its way."""
    m = DeviceModel(SimConfig(time_scale=1.0))
    m.receive(b"0MP0\r\n", 0.0)
    m.set_estop(True, 0.5)
    assert m.outbox.pop(10.0) == x.AlarmAnswer(code=spec.ALARM_ESTOP).to_bytes()
    assert 0 < (m.status()["position"] or 0) < m.config.homing_distance


def test_bytes_during_move_are_discarded() -> None:
    """Silent item 10: bytes that arrive while a move is under way are discarded; after the answer is
    due, commands are answered again."""
    m = DeviceModel(SimConfig(time_scale=1.0, turnaround_s=0.0))
    m.receive(b"0MP0\r\n", 0.0)
    end = m.busy_until
    assert end > 0.5
    m.receive(b"0RV\r\n", end / 2)
    assert m.outbox.pop(end + 1) == b"0MP00002000000\r\n"
    m.receive(b"0RV\r\n", end + 1)
    assert m.outbox.pop(end + 2) == b"0RV100\r\n"
    assert m.discarded == len(b"0RV\r\n")


def test_line_buffered_until_lf() -> None:
    """Silent item 1: bytes with no LF yet are buffered, not answered; a bare-LF line is malformed."""
    m = DeviceModel(INSTANT)
    assert talk(m, b"0RV\r") == b""
    assert talk(m, b"\n") == b"0RV100\r\n"
    assert talk(m, b"0RV") == b""
    assert talk(m, b"\n") == ALARM_01


def test_wire_timing_paces_bytes() -> None:
    """docs/protocol.md "Line" + silent item 17: with wire timing, the answer's first byte comes after the
    turnaround and each next byte one byte time (1.0417 ms) later."""
    m = DeviceModel(SimConfig(time_scale=1.0, wire_timing=True))
    m.receive(b"0RV\r\n", 0.0)
    answer = b"0RV100\r\n"
    assert m.outbox.next_due == pytest.approx(0.002)
    assert m.outbox.pop(0.0019) == b""
    assert m.outbox.pop(0.002 + 2.5 * spec.BYTE_TIME_S) == answer[:3]
    assert m.outbox.pop(1.0) == answer[3:]


def test_faults_on_next_move_and_memory() -> None:
    """docs/protocol.md "Alarms": injected faults answer 09 (limit, after the move), 0B (homing), 0A (pulse),
    04 (memory write), 06 (memory data), each latched until 0%C."""
    m = DeviceModel(INSTANT)
    talk(m, b"0WP19302012345\r\n")
    for code, cmd in ((0x09, b"0MP1\r\n"), (0x0B, b"0MP0\r\n"), (0x0A, b"0MV013000100\r\n")):
        m.fail_next_move(code)
        assert talk(m, cmd) == x.AlarmAnswer(code=code).to_bytes()
        assert talk(m, b"0RV\r\n") == x.AlarmAnswer(code=code).to_bytes()
        assert talk(m, b"0%C\r\n") == b"0%C00\r\n"
    m.fail_next_memory(0x04)
    assert talk(m, b"0WP29302000001\r\n") == b"0%%04\r\n"
    talk(m, b"0%C\r\n")
    m.fail_next_memory(0x06)
    assert talk(m, b"0RP1\r\n") == b"0%%06\r\n"
    m.raise_alarm(0x08)
    talk(m, b"0%C\r\n")
    assert talk(m, b"0RP1\r\n") == b"0RP19302012345\r\n"
    with pytest.raises(ValueError, match="move fault"):
        m.fail_next_move(0x04)


def test_silent_point_position_alarms() -> None:
    """Silent items 4 and 5: 0WC before homing, 0MP to an unwritten point and 0MV beyond the stroke
    answer alarm 08."""
    for cmd in (b"0WC1\r\n", b"0MP7\r\n", b"0MV013FFFFFF\r\n"):
        m = DeviceModel(INSTANT)
        assert talk(m, cmd) == b"0%%08\r\n"


@given(st.lists(st.one_of(frames("command").map(frame),
                          st.binary(max_size=20).map(lambda b: b.replace(b"\n", b"") + b"\n")),
                max_size=25),
       st.data())
@settings(max_examples=budget(150), deadline=None)
def test_fuzz_one_answer_per_line(lines: list[bytes], data: st.DataObject) -> None:
    """Silent item 1: every LF-terminated line gets exactly one answer, a malformed one the alarm answer
    (01 unless another alarm is latched), whatever the chunking; the model never raises."""
    m = DeviceModel(INSTANT)
    answers = []
    for line in lines:
        latched = m.latched
        out = talk(m, line)
        assert out.count(b"\n") == 1
        answers.append(out)
        try:
            x.parse(line, "command")
        except x.FrameError:
            assert out == x.AlarmAnswer(code=latched or spec.ALARM_COMM).to_bytes()
    stream = b"".join(lines)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    m2 = DeviceModel(INSTANT)
    got = b""
    for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True):
        got += talk(m2, stream[a:b])
    assert got == b"".join(answers)


@given(st.binary(max_size=300))
@settings(max_examples=budget(200), deadline=None)
def test_fuzz_arbitrary_bytes(stream: bytes) -> None:
    """Arbitrary byte streams never crash the model; answers are whole frames, one per LF."""
    m = DeviceModel(INSTANT)
    out = talk(m, stream)
    assert out.count(b"\n") == stream.count(b"\n")
    for ev in x.Framer().feed(out) + x.Framer().flush():
        assert isinstance(ev, x.FrameBytes)
        x.parse(ev.raw, "answer")


def test_line_faults_reproducible_by_seed() -> None:
    """Line faults are reproducible: the same seed spoils the same bytes; another seed differs."""
    script = b"".join([b"0RV\r\n", b"0WP19302012345\r\n", b"0RP1\r\n"] * 20)

    def run(seed: int) -> bytes:
        m = DeviceModel(SimConfig(time_scale=0, faults=LineFaults(corrupt=0.05, drop=0.05, seed=seed)))
        return talk(m, script)

    clean = talk(DeviceModel(INSTANT), script)
    assert run(7) == run(7)
    assert run(7) != run(8)
    assert run(7) != clean


def test_deviation_table_is_documented() -> None:
    """Every deviation names the rule it breaks and the docs/protocol.md section."""
    for name, (rule, section) in DEVIATIONS.items():
        assert rule and section, name


# one script a deviation must change, and what the faithful answers look like
_SCRIPT = [b"0RP3\n", b"0RV\r\n", b"0%C\r\n", b"0RC\r\n", b"0WP17202001000\r\n", b"0RP1\r\n",
           b"0WS12\r\n", b"0RS\r\n", b"0CM1\r\n", b"0MP1\r\n", b"0RC\r\n", b"0MV0F3001388\r\n",
           b"0RC\r\n", b"0WC2\r\n", b"0RP2\r\n"]


@pytest.mark.parametrize("name", sorted(DEVIATIONS))
def test_each_deviation_breaks_its_rule(name: str) -> None:
    """Each deviation changes the answers to a script that exercises every stated rule (issue 5 item 8)."""
    faithful = DeviceModel(INSTANT)
    deviant = DeviceModel(INSTANT.replace(deviations=frozenset({name})))
    if name == "estop-cleared":
        faithful.set_estop(True)
        deviant.set_estop(True)
    assert [talk(faithful, c) for c in _SCRIPT] != [talk(deviant, c) for c in _SCRIPT]


def test_deviation_details() -> None:
    """Spot checks of deviations against the rule each breaks (docs/protocol.md "Framing", "Frames")."""
    def first(dev: str, cmd: bytes) -> bytes:
        return talk(DeviceModel(INSTANT.replace(deviations=frozenset({dev}))), cmd)

    assert x.diagnose(first("no-2", b"0RS\r\n"), "answer")[1][0].code == "bad-length"
    assert first("lf-only", b"0RV\r\n") == b"0RV100\n"
    assert first("letter-o", b"0RV\r\n") == b"ORV100\r\n"
    assert first("wrong-reset-answer", b"0%C\r\n") == b"0%C01\r\n"
    assert first("silent-on-malformed", b"0RV\n") == b""
    assert first("echo-differs", b"0WS12\r\n") == b"0WS02\r\n"


def test_config_options() -> None:
    """The option strings (xac1sim:// query, CLI) map onto SimConfig; unknown names are clear errors."""
    cfg = config_from_options({"time_scale": "0", "version": "102", "deviation": ["no-2,lf-only"],
                               "stroke": "0:0x1000", "noise": "0.1", "seed": "3"})
    assert cfg.version == "102" and cfg.stroke == (0, 0x1000) and cfg.time_scale == 0
    assert cfg.deviations == {"no-2", "lf-only"} and cfg.faults.corrupt == 0.1 and cfg.faults.seed == 3
    with pytest.raises(ValueError, match="unknown simulator option 'colour'"):
        config_from_options({"colour": "red"})
    with pytest.raises(ValueError, match="unknown deviation"):
        config_from_options({"deviation": "nope"})
    with pytest.raises(ValueError, match="version"):
        config_from_options({"version": "1.0"})
