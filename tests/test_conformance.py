"""The conformance kit's parts: options, the reference model, the plugin's inertness, CLI errors."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import conformance

from conformance.model import Model, Point
from conformance.settings import Settings, SettingsError, parse_safe_range
from xac1_proto import parse, spec
from xac1_proto.frames import (
    AlarmReset,
    MoveDirect,
    ReadCurrent,
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


def _model() -> Model:
    return Model(points={n: Point(0, 0, 0, 0) for n in range(1, 16)}, outputs=0, homed=False)


def _answer(raw: bytes):
    return parse(raw, spec.ANSWER)


def test_model_accepts_the_stated_answers():
    """The reference model accepts 0RC before homing, an echo, a latched alarm and its reset
    (docs/protocol.md "Behaviour the vendor text states")."""
    m = _model()
    assert m.judge(ReadCurrent(), _answer(b"0RC00002FFFFFF\r\n"), b"0RC00002FFFFFF\r\n", []) == []
    assert m.judge(WriteOutputs(o=2), _answer(b"0WS22\r\n"), b"0WS22\r\n", []) == []
    assert m.judge(b"0XY\r\n", _answer(b"0%%01\r\n"), b"0%%01\r\n", []) == []
    assert m.judge(ReadPoint(n=1), _answer(b"0%%01\r\n"), b"0%%01\r\n", []) == []
    assert m.judge(AlarmReset(), _answer(b"0%C00\r\n"), b"0%C00\r\n", []) == []
    assert m.latched is None


def one_problem(problems: list[str], *words: str) -> str:
    """The single broken rule reported, checked to name it by these words."""
    assert len(problems) == 1, problems
    assert all(w in problems[0] for w in words), (words, problems[0])
    return problems[0]


def test_model_names_broken_rules():
    """The reference model reports a broken latch, a wrong 0RC before homing, a position that a move did
    not reach and a differing echo, each as exactly one problem naming that rule; silent points (0RC's
    O) are not judged."""
    m = _model()
    one_problem(m.judge(ReadCurrent(), _answer(b"0RC00002000000\r\n"), b"", []),
                "0RC before homing", "FFFFFF")
    assert m.judge(b"0XY\r\n", _answer(b"0%%01\r\n"), b"", []) == []  # malformed: alarm 01 latched
    one_problem(m.judge(ReadPoint(n=1), _answer(b"0RP10002000000\r\n"), b"", []),
                "alarm 01 is latched", "0RP")
    m = _model()
    move = MoveDirect(vel=0x3C, a=3, pos=0x100)
    assert m.judge(move, _answer(move.to_bytes()), move.to_bytes(), []) == []
    assert m.judge(ReadCurrent(), _answer(b"0RC00332000100\r\n"), b"", []) == []  # N/V/A/O: silent
    one_problem(m.judge(ReadCurrent(), _answer(b"0RC00002000200\r\n"), b"", []), "000200", "000100")
    wrong = b"0WS32\r\n"
    one_problem(m.judge(WriteOutputs(o=2), _answer(wrong), wrong, []), "0WS echo differs")


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
