"""Every way a run can be interrupted leaves the device as it was found: SIGINT, a second SIGINT, SIGTERM
and SIGHUP, at start-up, during the checks and during the restore. The verdict is then `INCOMPLETE`,
the exit status 2, and the operator reads our words only (no traceback, no pytest banner).

The device is `xac1 sim --tcp` in a subprocess with a state file (points held before the run) and a
small answer delay, so each moment lasts long enough to be hit; each signal is sent when the run shows
the moment (a line it prints, or the state file changing), never after a guessed sleep.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from xac1_proto.client import Client

pytestmark = pytest.mark.slow  # conformance runs interrupted by signals

HELD = {3: (5, 2, 1, 0x400), 7: (9, 3, 0, 0x800)}
RUN = ["--allow-motion", "--safe-range", "0:0x1000", "--examples", "3",
       "-k", "read_back or outputs or echo or alarm"]
WAIT = 60


@pytest.fixture
def device(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """`xac1 sim --tcp` with HELD in its state file and a 15 ms answer delay: (url, state file)."""
    state = tmp_path / "state.json"
    points = {f"{n:X}": dict(zip(("v", "a", "o", "pos"), d, strict=True)) for n, d in HELD.items()}
    state.write_text(json.dumps({"format": "xac1sim-state", "version": 1, "points": points}))
    command = [sys.executable, "-m", "xac1_proto", "sim", "--tcp", "127.0.0.1:0", "--time-scale", "0",
               "--delay", "15", "--state", str(state)]
    proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("socket://"), url
        yield url, state
    finally:
        proc.stdin.close()
        proc.terminate()
        proc.wait(timeout=10)
        proc.stdout.close()


def saved_points(state: Path) -> dict:
    return json.loads(state.read_text())["points"]


def outputs(url: str) -> int:
    with Client(url, timeout=2) as c:
        return c.read_outputs().o


class Run:
    """`xac1 conformance` in a subprocess, its output read line by line (stdout and stderr merged)."""

    def __init__(self, url: str, cwd: Path) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "conformance", "--port", url, *RUN],
                                     cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line)
        self.lines.put(None)

    def wait_for(self, text: str) -> None:
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.5)
            except queue.Empty:
                continue
            if line is None:
                break
            self.seen.append(line)
            if text in line:
                return
        raise AssertionError(f"never saw {text!r}:\n{''.join(self.seen)[-3000:]}")

    def signal(self, sig: int) -> None:
        os.kill(self.proc.pid, sig)

    def finish(self) -> tuple[int, str]:
        try:
            rc = self.proc.wait(timeout=WAIT)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
        while (line := self.lines.get(timeout=10)) is not None:
            self.seen.append(line)
        return rc, "".join(self.seen)


def wait_for_change(state: Path, before: dict) -> None:
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        try:
            if saved_points(state) != before:
                return
        except (json.JSONDecodeError, FileNotFoundError):
            pass  # written atomically: a reader never sees half a file, but the rename may be under way
        time.sleep(0.02)
    raise AssertionError("the run never wrote to the device")


def assert_ended_in_order(rc: int, out: str) -> None:
    last = out.strip().splitlines()[-1]
    assert rc == 2, out[-3000:]
    assert "INCOMPLETE" in last and "interrupted" in last, out[-4000:]
    for noise in ("Traceback", "KeyboardInterrupt", "site-packages", "! Interrupted", "!!!"):
        assert noise not in out, (noise, out[-3000:])


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_signal_during_the_checks(device, tmp_path, sig):
    """A signal while the checks write to the device: the points and OUT ports are restored, INCOMPLETE,
    exit 2."""
    url, state = device
    before, outs = saved_points(state), outputs(url)
    run = Run(url, tmp_path)
    run.wait_for("testing")
    wait_for_change(state, before)
    run.signal(sig)
    rc, out = run.finish()
    assert_ended_in_order(rc, out)
    assert f"interrupted by {sig.name}" in out
    assert "restoring the device" in out
    assert saved_points(state) == before and outputs(url) == outs


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_signal_at_start_up(device, tmp_path, sig):
    """A signal while the suite starts (imports, collection, before or during the snapshot): a quiet end,
    nothing changed on the device."""
    url, state = device
    before, outs = saved_points(state), outputs(url)
    run = Run(url, tmp_path)
    run.wait_for("testing")
    run.signal(sig)
    rc, out = run.finish()
    assert_ended_in_order(rc, out)
    assert saved_points(state) == before and outputs(url) == outs


def test_second_sigint_during_the_restore_is_ignored(device, tmp_path):
    """Ctrl-C twice: the second, during the restore, is ignored and said so; the restore completes."""
    url, state = device
    before, outs = saved_points(state), outputs(url)
    run = Run(url, tmp_path)
    run.wait_for("testing")
    wait_for_change(state, before)
    run.signal(signal.SIGINT)
    run.wait_for("restoring the device")
    run.signal(signal.SIGINT)
    rc, out = run.finish()
    assert_ended_in_order(rc, out)
    assert "SIGINT ignored" in out
    assert saved_points(state) == before and outputs(url) == outs


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_signal_during_the_final_restore(device, tmp_path, sig):
    """A signal while a run that went through restores the device: ignored (said so), the restore
    completes, the run counts as interrupted."""
    url, state = device
    before, outs = saved_points(state), outputs(url)
    run = Run(url, tmp_path)
    run.wait_for("restoring the device")
    run.signal(sig)
    rc, out = run.finish()
    assert_ended_in_order(rc, out)
    assert f"{sig.name} ignored" in out
    assert saved_points(state) == before and outputs(url) == outs
