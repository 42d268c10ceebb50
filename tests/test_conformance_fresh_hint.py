"""``--fresh`` on a unit homed since power-on: rc_before_homing fails (0RC answers a position, not
FFFFFF) and says what to do: power-cycle the unit and run again, or drop --fresh (issue 23 item 10)."""

from __future__ import annotations

import pytest
from conftest import conformance

from xac1_proto.client import Client
from xac1_proto.frames import MovePoint
from xac1_proto.sim import DeviceModel, SimConfig, serve_tcp

pytestmark = pytest.mark.slow  # a whole conformance run in a subprocess


def test_fresh_on_a_homed_unit_says_power_cycle_or_drop_fresh(tmp_path):
    """The simulator homed before the run: rc_before_homing fails with the hint; one that was not homed
    passes it (the hint is no excuse for a device answering FFFFFF wrongly)."""
    with serve_tcp(model=DeviceModel(SimConfig(time_scale=0))) as sim:
        with Client(sim.url, timeout=1.0) as client:
            client.request(MovePoint(n=0))  # homed since power-on
        r = conformance(["--port", sim.url, "--fresh", "-k", "rc_before_homing"], tmp_path)
    assert r.returncode == 1, r.stdout[-3000:]
    assert "FAIL rc_before_homing" in r.stdout
    assert "power-cycle the unit and run again, or drop --fresh" in r.stdout
    with serve_tcp(model=DeviceModel(SimConfig(time_scale=0))) as sim:
        r = conformance(["--port", sim.url, "--fresh", "-k", "rc_before_homing"], tmp_path)
    assert "FAIL" not in r.stdout and "power-cycle" not in r.stdout, r.stdout[-3000:]
