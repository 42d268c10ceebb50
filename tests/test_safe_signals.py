"""Signals are acted upon at safe points only (issue 41 items 3 and 4; issue 40 item 2).

An ``Interrupted`` raised inside an import (a class being made turns it into ``RuntimeError: Error
calling __set_name__``), a garbage-collection callback or a finalizer (Python drops it, or prints it as
"unraisable") is lost or becomes another error; so the policies (``xac1_proto.signals``, the
conformance suite's ``StopPolicy``) send such a signal again a moment later and raise it where the
program is. A start-up signal that some code swallowed is sent again when the command's policy takes
over; once a command's policy is down again, the dispatcher ignores signals, so a finished command's
results and status stand.

The in-process tests send the signal from exactly the moment they check (``os.kill`` inside the import,
the finalizer, the callback); the loops at the end signal real commands at a few dozen moments each.
"""

from __future__ import annotations

import gc
import importlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import ROOT

from conformance.stopping import StopPolicy
from xac1_proto.chunk import Chunk
from xac1_proto.recording import RecordingWriter
from xac1_proto.signals import SIGNALS, Interrupted, OrderlyEnd, running, startup
from xac1_proto.sim import DeviceModel, LineFaults, PointData, SimConfig, serve_tcp

MODULE = '''
import dataclasses, functools, os, signal

os.kill(os.getpid(), signal.SIGTERM)  # its handler runs here, inside the import


@dataclasses.dataclass
class Made:
    x: int = 1

    @functools.cached_property
    def twice(self) -> int:  # a descriptor with __set_name__
        return 2 * self.x
'''


@pytest.fixture
def handlers() -> Iterator[None]:
    """The process's handlers for SIGINT, SIGTERM and SIGHUP put back after the test."""
    before = {sig: signal.getsignal(sig) for sig in SIGNALS}
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


@pytest.fixture
def signalling_module(tmp_path: Path, monkeypatch) -> str:
    """The name of a module that signals its own process while it is imported."""
    name = f"signals_while_imported_{tmp_path.name}"  # a new module each test
    (tmp_path / f"{name}.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    return name


def raised_soon() -> Interrupted:
    """The ``Interrupted`` a policy raises at a safe point within 2 s (fails if none comes)."""
    try:
        deadline = time.monotonic() + 2
        while time.monotonic() < deadline:
            time.sleep(0.001)
    except Interrupted as exc:
        return exc
    pytest.fail("no Interrupted was raised after the unsafe moment")


class Signalling:
    """Sends SIGTERM to its own process from its finalizer."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGTERM)


def in_gc_callback(phase: str, info: dict[str, int]) -> None:
    if phase == "start":  # once a collection
        os.kill(os.getpid(), signal.SIGTERM)


def unsafe_moment(kind: str, module: str) -> None:
    """Send SIGTERM from inside an import, a finalizer or a gc callback (and return normally)."""
    if kind == "import":
        importlib.import_module(module)
    elif kind == "finalizer":
        Signalling()  # freed at once: its __del__ runs
    else:
        gc.callbacks.append(in_gc_callback)
        try:
            gc.collect()
        finally:
            gc.callbacks.remove(in_gc_callback)


MOMENTS = ["import", "finalizer", "gc-callback"]


@pytest.mark.parametrize("kind", MOMENTS)
def test_orderly_end_raises_after_the_unsafe_moment(handlers, signalling_module, capfd, kind) -> None:
    """A signal before ``begin()`` landing in an import, a finalizer or a gc callback: that code ends
    normally (the module imported, its dataclass made), then ``Interrupted`` is raised where the command
    is, without a traceback (was: ``RuntimeError: Error calling __set_name__`` from the import, or the
    signal dropped with an "Exception ignored" line)."""
    with OrderlyEnd("xac1 test", "stopping") as end:
        unsafe_moment(kind, signalling_module)
        if kind == "import":
            assert sys.modules[signalling_module].Made().twice == 2
        assert raised_soon().name == "SIGTERM" and end.early
    assert "Exception ignored" not in capfd.readouterr().err


def test_begin_raises_a_signal_still_owed(handlers, signalling_module) -> None:
    """A signal that came in an import just before ``begin()`` is raised by ``begin()`` at the latest:
    the run never begins."""
    begun = False
    with OrderlyEnd("xac1 test", "stopping") as end, pytest.raises(Interrupted):
        importlib.import_module(signalling_module)
        end.begin()
        begun = True  # the run's first step: never reached
        time.sleep(1)
    assert not begun
    assert signalling_module in sys.modules  # the import itself went through


@pytest.mark.parametrize("kind", MOMENTS)
def test_dispatcher_raises_after_the_unsafe_moment(handlers, signalling_module, kind) -> None:
    """The dispatcher's start-up policy (before a command's): the same, a signal in an import, a
    finalizer or a gc callback is raised once that code has ended."""
    startup()
    running()  # the command runs (while loading, the process would end at once: exit 2)
    unsafe_moment(kind, signalling_module)
    assert raised_soon().name == "SIGTERM"


def test_a_start_up_signal_swallowed_is_sent_again_for_the_command(handlers) -> None:
    """A start-up signal whose ``Interrupted`` some code swallowed (an ``except BaseException``) is sent
    again when the command's policy takes over: the command ends early (was: lost, the whole run ran)."""
    startup()
    running()  # the command runs (while loading, the process would end at once: exit 2)
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)
    except BaseException:  # noqa: BLE001, S110 - library code that swallows everything
        pass
    with OrderlyEnd("xac1 test", "stopping") as end:
        assert raised_soon().name == "SIGTERM" and end.early


def test_after_the_commands_policy_signals_are_ignored(handlers, capfd) -> None:
    """Once a command's policy is down again (its results being said), the dispatcher ignores a signal
    and says so (was: ``Interrupted``: "stopped by", exit 2 for a finished command)."""
    startup()
    running()  # the command runs (while loading, the process would end at once: exit 2)
    with OrderlyEnd("xac1 test", "stopping") as end:
        end.begin()
        end.ending()
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.05)
    assert "xac1: SIGTERM ignored: the command has ended" in capfd.readouterr().err


@pytest.mark.parametrize("kind", MOMENTS)
def test_conformance_policy_raises_after_the_unsafe_moment(handlers, signalling_module, capfd, kind) -> None:
    """The conformance suite's ``StopPolicy`` too: a signal in an import, a finalizer or a gc callback
    is raised where the run is, once; no traceback."""
    policy = StopPolicy("xac1 conformance").install()
    try:
        unsafe_moment(kind, signalling_module)
        assert raised_soon().name == "SIGTERM"
    finally:
        policy.uninstall()
    err = capfd.readouterr().err
    assert "Exception ignored" not in err and "Traceback" not in err


# ---- real commands signalled at many moments ----
# moments counted from the process's first handler (xac1_proto.entry), the first a program can have

ATTEMPTS = 20
BAD = re.compile(r"Traceback|RuntimeError|Exception ignored|unraisable", re.IGNORECASE)


def moments(first: float, last: float, n: int = ATTEMPTS) -> list[float]:
    return [first + (last - first) * k / (n - 1) for k in range(n)]


def catches(pid: int, sig: int) -> bool:
    """Has process ``pid`` a handler for ``sig`` yet (``SigCgt`` in /proc: before the interpreter runs
    ``xac1``'s entry, any signal kills it, as it does any program)?"""
    with open(f"/proc/{pid}/status") as f:
        mask = next(line.split()[1] for line in f if line.startswith("SigCgt:"))
    return bool(int(mask, 16) >> (sig - 1) & 1)


def signalled(command: list[str], delay: float, sig: int, cwd: Path,
              timeout: float = 30) -> subprocess.CompletedProcess[str]:
    """Run ``xac1 COMMAND``, send ``sig`` ``delay`` s after its entry installed its first handler, wait
    for its end (at most ``timeout``)."""
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", *command], cwd=cwd, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 10
    while not catches(proc.pid, signal.SIGHUP) and time.monotonic() < deadline:  # SIGINT: Python has one
        time.sleep(0.0005)
    time.sleep(delay)
    proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"xac1 {' '.join(command)} still ran {timeout} s after a signal at {delay:.3f} s: {err}")
    return subprocess.CompletedProcess(command, proc.returncode, out, err)


@pytest.mark.slow
def test_proxy_signalled_at_many_moments(tmp_path: Path) -> None:
    """``xac1 proxy --record /dev/null`` sent SIGTERM at 20 moments from 0 to 1.2 s (loading,
    opening, forwarding): each ends in order, exit 0 (it was forwarding) or 2 (before), no traceback
    (was: ``RuntimeError: Error calling __set_name__`` at ~0.19 s, an fsync traceback at the end)."""
    with serve_tcp(model=DeviceModel(SimConfig(time_scale=0))) as sim:
        for delay in moments(0.0, 1.2):
            done = signalled(["proxy", "--device", sim.url, "--tcp", "127.0.0.1:0", "--record", os.devnull],
                             delay, signal.SIGTERM, tmp_path)
            assert done.returncode in (0, 2) and not BAD.search(done.stderr), (delay, done.stderr)


@pytest.mark.slow
def test_sim_signalled_at_many_moments(tmp_path: Path) -> None:
    """``xac1 sim --tcp`` sent SIGINT at 20 moments from 0 to 0.5 s: each ends (was: once kept
    serving after a SIGINT at ~33 ms), exit 0 or 2, no traceback."""
    for delay in moments(0.0, 0.5):
        done = signalled(["sim", "--tcp", "127.0.0.1:0", "--log", os.devnull], delay, signal.SIGINT, tmp_path,
                         timeout=15)
        assert done.returncode in (0, 2) and not BAD.search(done.stderr), (delay, done.stderr)


@pytest.mark.slow
def test_conformance_signalled_at_many_moments_keeps_its_word(tmp_path: Path) -> None:
    """``xac1 conformance --report r.md`` sent SIGTERM at 10 moments from 0 to 1.2 s: each ends,
    exit 2, no traceback; when it says the report follows, the report is written (was: "the report
    follows" and no report at ~0.16 s; once the signal lost and the whole suite run, exit 4)."""
    for delay in moments(0.0, 1.2, 10):
        report = tmp_path / "r.md"
        report.unlink(missing_ok=True)
        done = signalled(["conformance", "--report", str(report)], delay, signal.SIGTERM, tmp_path, 60)
        said = done.stdout + done.stderr
        assert done.returncode == 2 and not BAD.search(said), (delay, said[-2000:])
        assert "the report follows" not in done.stderr or report.exists(), (delay, said[-2000:])


# ---- the moments after a run: the results stand ----

def capture_with_writes(path: Path) -> Path:
    """A recording that writes point 1 and the OUT ports and reads them: the restore has work."""
    lines = [(b"0WP15212000321\r\n", b"0WP15212000321\r\n"), (b"0WS22\r\n", b"0WS22\r\n"),
             (b"0RV\r\n", b"0RV100\r\n")]
    with RecordingWriter(path, source="hand-made") as w:
        for n, (command, answer) in enumerate(lines):
            w.write(Chunk(1000.0 + n * 0.1, "host", command))
            w.write(Chunk(1000.02 + n * 0.1, "device", answer))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_replay_signalled_once_its_summary_is_out_keeps_report_and_status(tmp_path: Path, sig) -> None:
    """A signal as the replay's summary appears (the restore and the page still to come): ignored and
    said so, the restore done, the report written, the process's status the summary's (was: "stopped by
    SIGINT", exit 2, no report; the JSON summary said exit 1)."""
    capture = capture_with_writes(tmp_path / "c.jsonl")
    report = tmp_path / "r.html"
    slow = SimConfig(time_scale=0, faults=LineFaults(delay=1.0, delay_s=0.03, seed=1))  # restore ~0.2 s
    with serve_tcp(model=DeviceModel(slow, {1: PointData(4, 2, 1, 0x123)})) as sim:
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "replay", str(capture), "--port",
                                 sim.url, "-f", "jsonl", "--report", str(report)], cwd=ROOT, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
        lines: list[str] = []

        def read() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line)
                if '"type": "summary"' in line:
                    proc.send_signal(sig)

        reader = threading.Thread(target=read)
        reader.start()
        try:
            err = proc.stderr.read() if proc.stderr else ""
            proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
            reader.join(10)
    summary = json.loads(lines[-1])
    assert summary["type"] == "summary" and proc.returncode == summary["exit"], err
    assert f"{sig.name} ignored" in err and "stopped by" not in err, err
    assert report.exists() and "restore: point 1 restored" in err, err


AFTER_THE_VERDICT = '''
import os, signal

import pytest


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    os.kill(os.getpid(), signal.SIGTERM)  # the verdict is decided, the report written
'''


@pytest.mark.slow
def test_conformance_signal_once_the_verdict_is_decided_says_it_stands(tmp_path: Path) -> None:
    """A signal once the run's verdict is decided: ignored, and the words say the verdict stands (was:
    "ignored: the device is being restored; the report follows", after both were done); exit 4 (the run
    was deliberately partial, -k)."""
    (tmp_path / "sig_after_verdict.py").write_text(AFTER_THE_VERDICT)
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "PYTEST_PLUGINS": "sig_after_verdict"}
    done = subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", "-k", "answer_length"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 4, done.stdout[-2000:] + done.stderr[-2000:]
    assert "SIGTERM ignored: the verdict is decided" in done.stderr and "the verdict stands" in done.stderr
    assert not BAD.search(done.stdout + done.stderr)


INSIDE_A_MODULE_LOCK = """
import _thread, os, signal, sys, time
from xac1_proto.signals import Interrupted, OrderlyEnd
fired = []
def tracer(frame, event, arg):
    if frame.f_code.co_name != "acquire" or frame.f_code.co_filename != "<frozen importlib._bootstrap>":
        return None
    def local(f, ev, a):  # the import's module lock has marked this thread as blocked on it
        if ev == "line" and not fired and f.f_globals["_blocking_on"].get(_thread.get_ident()) is not None:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGTERM)
        return local
    return local
with OrderlyEnd("xac1 test", "stopping") as end:
    try:
        sys.settrace(tracer)
        import json.tool  # not imported yet
        sys.settrace(None)
        end.begin()
        time.sleep(2)
        print("not interrupted")
    except Interrupted as exc:
        print(f"interrupted by {exc.name}, early={end.early}, fired={len(fired)}")
"""


@pytest.mark.slow  # starts a process: the moment needs a fresh interpreter's imports
def test_a_signal_inside_an_imports_module_lock_is_raised_after_the_import() -> None:
    """A signal handled while an import holds this thread's place in importlib's module locks: the
    handler imports nothing (an import there took that place and the import it interrupted failed with
    ``KeyError`` in ``_ModuleLock.acquire``, as CI saw ``xac1 sim`` end with a traceback); the import
    completes and ``Interrupted`` is raised after it, before the run begins."""
    done = subprocess.run([sys.executable, "-c", INSIDE_A_MODULE_LOCK], cwd=ROOT, capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL)
    said = "interrupted by SIGTERM, early=True, fired=1\n"
    assert (done.returncode, done.stdout, done.stderr) == (0, said, "")
