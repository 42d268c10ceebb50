"""Interrupted runs. Ctrl-C during the random command sequences (hypothesis) is an interrupted run
(INCOMPLETE, exit 2, the device restored), never a failure. The restore after an interruption resets a
latched alarm even when the interrupt landed between a malformed command and the bookkeeping of its
answer (the suite still believes nothing is latched): the restore treats the alarm state as unknown and
sends 0%C first. A real ``xac1 sim`` over TCP, the real client, real signals to real runs."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import xac1
from test_fleet import HELD, OUT_BEFORE, Sim

from xac1_proto.client import Client
from xac1_proto.dut.device import DeviceUnderTest
from xac1_proto.dut.safety import restore, take_snapshot
from xac1_proto.dut.settings import Settings
from xac1_proto.frames import AlarmAnswer, ReadVersion, WriteOutputs, WritePoint

pytestmark = pytest.mark.slow  # conformance runs interrupted

MALFORMED = b"0WPZ\r\n"  # a write-point command with a bad point number: answered with an alarm
UNKNOWN_HEADER = b"0XY\r\n"  # what the malformed check "unknown-header" sends: answered with an alarm
SLOW_MS = 300  # the simulator's extra turnaround: the window in which the signal lands


@pytest.fixture
def sim(tmp_path: Path):
    s = Sim(tmp_path, "latch")
    yield s
    s.close()


def _alarm_latched(client: Client) -> bool:
    """Whether the device answers 0RV with an alarm (sent on a raw client: the suite's bookkeeping
    sees nothing of it)."""
    return isinstance(client.transact(ReadVersion().to_bytes()).frame, AlarmAnswer)


def _control(sim: Sim, line: str) -> None:
    """A control command typed on the simulator's stdin (``slow MS``: extra turnaround before answers)."""
    assert sim.proc.stdin is not None
    sim.proc.stdin.write(line + "\n")
    sim.proc.stdin.flush()


def test_restore_resets_an_alarm_latched_unbeknown(sim):
    """Restoring after an interrupted run resets an alarm the run latched without knowing (its answer
    never reached the suite's bookkeeping), and puts the settings back."""
    dut = DeviceUnderTest.open(Settings.make(sim.url, False, False, None, timeout=0.5))
    dut.test = "t"
    try:
        snap = take_snapshot(dut)
        dut.send(WritePoint(n=1, v=9, a=2, o=0, pos=0x123))  # the run changed things...
        dut.send(WriteOutputs(o=1))
        assert dut.latched is False
        dut.client.transact(MALFORMED)  # ...and latched an alarm past the suite's bookkeeping
        assert dut.latched is False  # the bookkeeping never saw the alarm
        assert _alarm_latched(dut.client) is True  # but the device has it latched
        report = restore(dut, snap)
    finally:
        dut.close()
    assert report.ok, (report.problems, report.unverified)
    resets = [p for p in dut.log if p.raw and p.raw.startswith(b"0%C")]
    assert resets, "no 0%C sent by the restore"
    with Client(sim.url, timeout=1) as c:
        assert _alarm_latched(c) is False
    assert sim.points() == HELD and sim.outputs() == OUT_BEFORE


def test_sigint_while_an_alarm_answer_is_on_its_way_still_resets_it(sim, tmp_path, private_history):
    """SIGINT while the run waits for the answer to a malformed command (the device has latched its
    alarm, the run never files the answer): exit 2, INCOMPLETE with the check cut short (no verdict),
    the restore's first command is 0%C, and the device is left with no alarm latched, its points and
    OUT ports as before."""
    _control(sim, f"slow {SLOW_MS}")
    before = len(sim.host_bytes())
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "conformance", "--port", sim.url,
                             "--timeout", "5", "-k", "malformed_answered and unknown",
                             "--report", str(tmp_path / "r.md")], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 60
        while UNKNOWN_HEADER not in sim.host_bytes()[before:]:
            assert time.monotonic() < deadline and proc.poll() is None, "the malformed check never began"
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        _control(sim, "slow 0")  # the restore at full speed
        out, _ = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 2, out[-3000:]
    last = out.splitlines()[-1]
    assert last.startswith("xac1 conformance: INCOMPLETE") and "interrupted by SIGINT" in last, last
    assert "safety PROBLEM" not in out and "safety NOT RESTORED" not in out, out
    report = (tmp_path / "r.md").read_text()
    assert "malformed_answered_with_alarm[unknown-header] | interrupted" in report, report
    sent = sim.host_bytes()[before:]
    after = sent[sent.index(UNKNOWN_HEADER) + len(UNKNOWN_HEADER):]
    assert after.startswith(b"0%C"), after[:40]  # the alarm it never saw, reset before anything else
    with Client(sim.url, timeout=1) as c:
        assert _alarm_latched(c) is False
    assert sim.points() == HELD and sim.outputs() == OUT_BEFORE


@pytest.mark.parametrize("wait_for", [b"0WP", b"0MP"])
def test_ctrl_c_during_random_sequences_is_an_interrupted_run(tmp_path, wait_for, private_history):
    """SIGINT once the random sequences have written a point (or moved): exit 2, the verdict says
    INCOMPLETE and interrupted, no check FAILs or ERRORs, the device's points and OUT ports are back."""
    slow = Sim(tmp_path, "seq", "--time-scale", "0.05", "--turnaround", "200")  # 10 ms an answer
    try:
        before = len(slow.host_bytes())
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "conformance", "--port", slow.url,
                                 "--allow-motion", "--safe-range", "0:0x1000", "-k", "random_sequences",
                                 "--examples", "500", "--report", str(tmp_path / "r.md")], cwd=tmp_path,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        deadline = time.monotonic() + 60
        while wait_for not in slow.host_bytes()[before:]:
            assert time.monotonic() < deadline and proc.poll() is None, "the sequences never began"
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=90)
        assert proc.returncode == 2, out[-3000:]
        last = out.splitlines()[-1]
        assert last.startswith("xac1 conformance: INCOMPLETE") and "interrupted by SIGINT" in last, last
        assert not [line for line in out.splitlines() if line.startswith(("FAIL", "ERROR", "safety PROBLEM",
                                                                          "safety NOT RESTORED"))], out
        assert "xac1: restoring the device's points" in out
        report = (tmp_path / "r.md").read_text()
        assert "random_sequences | interrupted" in report and "FAIL" not in report.split("## Safety")[0]
        assert slow.points() == HELD and slow.outputs() == OUT_BEFORE
        # the history keeps the interrupted run: its verdict, exit status, signal, the check cut short
        shown = xac1("history", "show", "1", "-f", "json")
        run = json.loads(shown.stdout)
        assert (run["verdict"], run["exit_status"], run["interrupted"]) == ("INCOMPLETE", 2, "SIGINT"), run
        assert [c["outcome"] for c in run["checks"]] == ["INTERRUPTED"], run["checks"]
    finally:
        slow.close()
