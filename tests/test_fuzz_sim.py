"""The simulator's robustness faults (xac1_proto.sim.config.ROBUSTNESS), which xac1 fuzz must find."""

from __future__ import annotations

import pytest

from xac1_proto.sim import DeviceModel, SimConfig, config_from_options
from xac1_proto.sim.config import LATE_AFTER_ERRORS_S, ROBUSTNESS


def _model(name: str, **options: str) -> DeviceModel:
    return DeviceModel(config_from_options({"time_scale": "0", "deviation": name, **options}))


def _answers(model: DeviceModel, data: bytes) -> list[bytes]:
    return [o.data for o in model.receive(data, 0.0)]


def test_hang_on_long_line():
    """hang-on-long-line: a line of hang_bytes is still answered; one byte more and nothing is answered
    again, not even 0RV."""
    m = _model("hang-on-long-line", hang_bytes="10")
    assert _answers(m, b"x" * 8 + b"\r\n") == [b"0%%01\r\n"]
    assert _answers(m, b"0%C\r\n") == [b"0%C00\r\n"]
    assert _answers(m, b"x" * 9 + b"\r\n") == []
    assert _answers(m, b"0RV\r\n") == []


def test_nul_corrupts_point():
    """nul-corrupts-point: a NUL in a line flips bit 8 of point 1's Pos (the line itself is answered as
    malformed); a line without NUL changes nothing."""
    m = _model("nul-corrupts-point")
    assert _answers(m, b"0RP\x001\r\n") == [b"0%%01\r\n"]
    _answers(m, b"0%C\r\n")
    assert _answers(m, b"0RP1\r\n") == [b"0RP10002000100\r\n"]
    clean = DeviceModel(SimConfig(time_scale=0))
    clean.receive(b"0RP\x001\r\n0%C\r\n", 0.0)
    assert [o.data for o in clean.receive(b"0RP1\r\n", 0.0)] == [b"0RP10002000000\r\n"]


def test_late_after_errors():
    """late-after-errors: flood_errors malformed lines in a row make every later answer late by
    LATE_AFTER_ERRORS_S, even at time_scale 0; fewer, or a good line between, do not."""
    m = _model("late-after-errors", flood_errors="3")
    m.receive(b"\n\n", 0.0)
    m.receive(b"0%C\r\n", 0.0)
    m.receive(b"\n\n", 0.0)
    assert all(o.due == 0.0 for o in m.receive(b"0%C\r\n", 0.0))
    outs = m.receive(b"\n\n\n0%C\r\n0RV\r\n", 0.0)
    assert [o.due for o in outs[2:]] == [LATE_AFTER_ERRORS_S] * 3


def test_a_power_cycle_clears_a_struck_robustness_fault():
    """A power cycle (``DeviceModel.power_cycle``, the control channel's ``power``) ends a hang and late
    answers, as switching a real controller off and on would; the fault stays switched on and strikes
    again on the next long line."""
    hung = _model("hang-on-long-line", hang_bytes="10")
    _answers(hung, b"x" * 11 + b"\r\n")
    assert _answers(hung, b"0RV\r\n") == []
    hung.power_cycle()
    assert _answers(hung, b"0%C\r\n") == [b"0%C00\r\n"]
    _answers(hung, b"x" * 11 + b"\r\n")
    assert _answers(hung, b"0%C\r\n") == []
    late = _model("late-after-errors", flood_errors="3")
    late.receive(b"\n\n\n", 0.0)
    assert [o.due for o in late.receive(b"0%C\r\n", 0.0)] == [LATE_AFTER_ERRORS_S]
    late.power_cycle()
    assert [o.due for o in late.receive(b"0%C\r\n", 0.0)] == [0.0]


@pytest.mark.parametrize("name", sorted(ROBUSTNESS))
def test_robustness_faults_are_off_by_default_and_named(name):
    """Each robustness fault is switched on by name (and documented); a default simulator has none."""
    assert ROBUSTNESS[name]
    assert name in _model(name).config.deviations
    assert not SimConfig().deviations


@pytest.mark.parametrize(("option", "value"), [("hang_bytes", "0"), ("hang_bytes", "64"), ("hang_bytes", "x"),
                                               ("flood_errors", "0"), ("flood_errors", "-1")])
def test_bad_robustness_options_are_named(option, value):
    """A bad hang_bytes or flood_errors is refused with an error naming the option."""
    with pytest.raises(ValueError, match=option):
        config_from_options({option: value})
