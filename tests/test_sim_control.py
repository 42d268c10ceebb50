"""The simulator's control channel (``xac1_proto.sim.control``), in-process: each line typed on ``xac1 sim``'s
stdin changes the device model as its help says, and a bad line is refused naming what was wrong."""

from __future__ import annotations

import pytest

from xac1_proto.sim import control
from xac1_proto.sim.config import DEVIATIONS, ROBUSTNESS, ROBUSTNESS_MARK, SimConfig
from xac1_proto.sim.model import DeviceModel


def _answer(model: DeviceModel, command: bytes, t: float) -> bytes:
    """The bytes the model sends for ``command`` (instant time scale: due at once)."""
    model.receive(command, t)
    return model.outbox.pop(t + 1.0)


def test_estop_on_makes_every_answer_the_stop_alarm_and_off_releases_it():
    """``estop on``: every answer becomes 0%%0E (docs/protocol.md "Alarms"); after ``estop off`` the
    alarm stays latched until a reset (0%C), as on a real controller."""
    model = DeviceModel(SimConfig(time_scale=0))
    assert _answer(model, b"0RV\r\n", 0.0) == b"0RV100\r\n"
    text, _ = control.apply(model, "estop on", 1.0)
    assert text == "emergency stop ON"
    assert _answer(model, b"0RV\r\n", 2.0) == b"0%%0E\r\n"
    assert control.apply(model, "ESTOP off", 3.0)[0] == "emergency stop off"
    assert _answer(model, b"0%C\r\n", 4.0) == b"0%C00\r\n"
    assert _answer(model, b"0RV\r\n", 5.0) == b"0RV100\r\n"


def test_status_and_help_come_from_the_one_table():
    """``help`` lists every control command of ``CONTROLS`` with its usage; ``status`` shows the state."""
    model = DeviceModel(SimConfig(time_scale=0))
    text, outputs = control.apply(model, "help", 0.0)
    assert outputs == [] and all(c.usage in text for c in control.CONTROLS.values())
    assert "estop off" in control.apply(model, "status", 0.0)[0]
    assert control.apply(model, "   ", 0.0) == ("", [])


@pytest.mark.parametrize(("line", "message"), [
    ("launch", "unknown control command 'launch'; type help"),
    ("estop", "usage: estop on|off"),
    ("estop maybe", "estop on|off: "),
    ("noise 2", "noise P: "),
    ("delay -5", "delay MS [P]: "),
])
def test_a_bad_line_is_refused_naming_what_was_wrong(line, message):
    """An unknown command, a wrong number of words or a bad value raises ValueError naming the command
    and its usage; the model is unchanged."""
    model = DeviceModel(SimConfig(time_scale=0))
    with pytest.raises(ValueError) as caught:
        control.apply(model, line, 0.0)
    assert str(caught.value).startswith(message)
    assert _answer(model, b"0RV\r\n", 1.0) == b"0RV100\r\n"


def test_deviation_lists_the_robustness_faults_marked_and_stars_those_on():
    """``deviation`` alone lists every deviation, then every robustness fault (``config.ROBUSTNESS``)
    marked as one the conformance suite does not check; those switched on are starred, a robustness
    fault switched on through the channel too."""
    model = DeviceModel(SimConfig(time_scale=0, deviations=frozenset({"letter-o"})))
    control.apply(model, "deviation hang-on-long-line on", 0.0)
    rows = control.apply(model, "deviation", 0.0)[0].splitlines()
    assert [row[2:].split()[0] for row in rows] == [*DEVIATIONS, *ROBUSTNESS]
    assert {row[2:].split()[0] for row in rows if row.startswith("*")} == {"letter-o", "hang-on-long-line"}
    marked = {row[2:].split()[0] for row in rows if row.endswith(f"[{ROBUSTNESS_MARK}]")}
    assert marked == set(ROBUSTNESS)
    assert "conformance suite does not check" in ROBUSTNESS_MARK
