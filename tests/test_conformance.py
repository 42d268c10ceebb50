"""The conformance kit's parts: options, the reference model, the plugin's inertness, CLI errors."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import conformance

from conformance.model import Model
from xac1_proto import spec
from xac1_proto.dut.evidence import Probe
from xac1_proto.dut.settings import Settings, SettingsError, parse_safe_range
from xac1_proto.frames import (
    AlarmReset,
    MoveDirect,
    ReadCurrent,
    ReadOutputs,
    ReadPoint,
    WriteOutputs,
)

RUN_TIMEOUT = 60


def test_safe_range_forms():
    """--xac1-safe-range takes LO:HI in decimal or 0x-hex, LO <= HI, never the FFFFFF marker."""
    assert parse_safe_range("0:0x1000") == (0, 0x1000)
    assert parse_safe_range("100:200") == (100, 200)
    for bad in ("0x1000", "5:1", "0:0xFFFFFF", "a:b", "-1:4"):
        with pytest.raises(SettingsError):
            parse_safe_range(bad)


def test_motion_on_hardware_needs_a_safe_range():
    """Motion on a real device needs a safe range; the simulator implies motion, a range and freshness."""
    with pytest.raises(SettingsError, match="safe-range"):
        Settings.make("socket://127.0.0.1:1", True, False, None)
    real = Settings.make("socket://127.0.0.1:1", False, False, None)
    assert (real.motion, real.fresh, real.safe_range) == (False, False, None)
    sim = Settings.make(None, False, False, None)
    assert sim.simulator and sim.motion and sim.fresh and sim.in_range(0)
    assert sim.time_scale == 0  # the default port runs motion instantly


def _probes(deviation: str | None = None):
    """A model on a client of the in-process simulator, and a way to probe it."""
    from xac1_proto import Client

    url = "xac1sim://?time_scale=0" + (f"&deviation={deviation}" if deviation else "")
    client = Client(url, timeout=0.5)
    model = Model(client.conversation)
    return client, model, lambda frame: Probe(None, client.transact(frame.to_bytes()))


def test_model_is_the_rulebook_and_accepts_the_stated_answers():
    """The model is the client's conversation engine: the simulator's stated answers (0RC before homing,
    an echo, a latched alarm and its reset) get no verdict (docs/protocol.md "Behaviour the vendor text
    states")."""
    client, m, probe = _probes()
    with client:
        for frame in (ReadCurrent(), WriteOutputs(o=2), ReadPoint(n=1), AlarmReset()):
            assert m.judge(probe(frame)) == []
        assert m.judge(Probe(None, client.transact(b"0XY\r\n"))) == []  # an alarm answer, as owed
        assert m.latched == spec.ALARM_COMM
        assert m.judge(probe(AlarmReset())) == [] and m.latched is None


@pytest.mark.parametrize("deviation, code", [("move-not-performed", "readback-mismatch"),
                                             ("outputs-not-stored", "readback-mismatch"),
                                             ("echo-differs", "echo-mismatch")])
def test_model_names_broken_rules(deviation, code):
    """A position a move did not reach, OUT ports not stored, a differing echo: the engine's verdict."""
    client, m, probe = _probes(deviation)
    with client:
        verdicts = []
        for frame in (MoveDirect(vel=0x3C, a=3, pos=0x100), ReadCurrent(), WriteOutputs(o=2), ReadOutputs()):
            verdicts += m.judge(probe(frame))
        assert verdicts and all(v.endswith(f"({code})") for v in verdicts)


@pytest.mark.slow
def test_plugin_is_inert(tmp_path):
    """With no --xac1 option and no checks collected, the plugin adds nothing to a pytest run (no device
    opened, no summary), yet its options are registered."""
    (tmp_path / "test_x.py").write_text("def test_ok():\n    assert True\n")
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
                       capture_output=True, text=True, timeout=RUN_TIMEOUT, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "XA-C1" not in r.stdout
    h = subprocess.run([sys.executable, "-m", "pytest", "--help"], capture_output=True, text=True,
                       timeout=RUN_TIMEOUT, cwd=tmp_path)
    assert "--xac1-port" in h.stdout and "--xac1-safe-range" in h.stdout


@pytest.mark.slow
@pytest.mark.parametrize("args,words", [
    (["--port", "socket://127.0.0.1:1", "--allow-motion"], "--safe-range"),
    (["--safe-range", "9:1"], "above"),
    (["--report", "out.txt"], ".md or .html"),
])
def test_cli_usage_errors(tmp_path, args, words):
    """Bad option values give exit status 2 and a one-line reason, never a traceback."""
    r = conformance(args, tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert words in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_cli_port_that_does_not_open(tmp_path):
    """A port that cannot be opened ends the run with the reason and the could-not-go-on verdict (exit 3),
    nothing written, and only our words: no pytest banner, counts or skipped-checks block."""
    r = subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", "--port",
                        str(tmp_path / "no-such-tty")], capture_output=True, text=True,
                       timeout=RUN_TIMEOUT, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 3, out
    assert "cannot open" in out and "NOT TESTED: 0 passed, 0 failed, 98 not run" in r.stdout.splitlines()[-1]
    for noise in ("Traceback", "! Interrupted", "1 error", "skipped", "checks not run (never a failure"):
        assert noise not in out, (noise, out)
