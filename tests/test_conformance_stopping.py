"""A signal at any moment of a conformance run ends it as documented (issue 24 items 9 and 10): one
stop policy a process (``xac1 conformance`` and its plugin share it), so the first signal wins and later
ones are ignored and said so, even after pytest has ended; a first signal whose ``Interrupted`` Python
swallowed (raised inside a garbage-collector callback such as hypothesis' own) is raised again where the
run is, and the verdict names it.

The moments are exact, not slept for: a small pytest plugin (``PYTEST_PLUGINS``) loaded into the run
sends the signals to its own process from a given hook, or from inside a gc callback."""

from __future__ import annotations

import gc
import io
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import ROOT

from conformance.stopping import Interrupted, StopPolicy

SELECT = ("-k", "answer_length")  # a few checks: a real run, quickly over


def test_the_plugin_and_the_cli_share_one_policy(capfd) -> None:
    """``StopPolicy.shared`` is the policy already in place: the first signal raises ``Interrupted``
    once; after the inner taker uninstalls, a second signal is still ignored and said so (was: a second
    policy took it as a first signal and its name replaced the first's in the verdict)."""
    before = signal.getsignal(signal.SIGTERM)
    outer = StopPolicy("xac1 conformance").install()
    try:
        installed = signal.getsignal(signal.SIGTERM)
        assert installed != before
        inner = StopPolicy.shared("xac1 conformance")
        assert inner is outer
        with pytest.raises(Interrupted):
            signal.raise_signal(signal.SIGINT)
        inner.uninstall()
        signal.raise_signal(signal.SIGTERM)  # no exception: ignored
        assert outer.stopped_by == "SIGINT" and signal.getsignal(signal.SIGTERM) == installed
    finally:
        outer.uninstall()
    assert signal.getsignal(signal.SIGTERM) == before
    err = capfd.readouterr().err
    assert "xac1 conformance: SIGINT: stopping" in err and "xac1 conformance: SIGTERM ignored" in err


def test_an_interrupt_swallowed_in_a_gc_callback_is_raised_again(capfd) -> None:
    """The first signal landing inside a garbage-collector callback: Python swallows the ``Interrupted``
    (an "Exception ignored" traceback); the policy prints no traceback and raises it again where the
    code runs, naming the same signal (was: the signal was lost)."""
    fired: list[int] = []

    def in_gc(phase: str, info: dict) -> None:
        if phase == "start" and not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGTERM)  # its handler runs inside this callback

    policy = StopPolicy("xac1 conformance").install()
    gc.callbacks.append(in_gc)
    try:
        with pytest.raises(Interrupted) as caught:
            gc.collect()
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:  # the signal comes again from a helper thread
                time.sleep(0.01)
        assert caught.value.name == "SIGTERM" and policy.stopped_by == "SIGTERM"
    finally:
        gc.callbacks.remove(in_gc)
        policy.uninstall()
    err = capfd.readouterr().err
    assert fired and "Exception ignored" not in err and "Traceback" not in err


class _Closer(io.RawIOBase):
    """An I/O object whose ``close`` (Python code) the collector runs: CPython drops any exception it
    raises there without a word (no ``sys.unraisablehook``)."""

    def __init__(self, action: Callable[[], None]) -> None:
        super().__init__()
        self.action = action
        self.me = self  # a cycle: only the collector frees it

    def close(self) -> None:
        if not self.closed:
            self.action()
        super().close()


@pytest.mark.parametrize("first", [True, False], ids=["first signal", "signal sent again"])
def test_an_interrupt_landing_in_a_finalizer_during_a_collection_is_raised_after_it(
    first: bool, capfd
) -> None:
    """A signal whose handler would run inside a finalizer of a garbage collection (the first one, or
    the one sent again after a gc callback swallowed the raise): it is raised once the collection has
    ended, where the code runs (was: ``io``'s finalizer dropped the ``Interrupted`` silently and the
    signal was lost)."""
    fired: list[int] = []

    def kill() -> None:
        if not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler runs here, inside the finalizer (or the helper's signal lands)

    def in_gc(phase: str, info: dict) -> None:
        if phase == "start" and not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGTERM)  # swallowed here: the policy sends it again

    callbacks = list(gc.callbacks)
    policy = StopPolicy("xac1 conformance").install()
    if not first:
        gc.callbacks.append(in_gc)
    try:
        with pytest.raises(Interrupted) as caught:
            for _ in range(50):
                _Closer(kill if first else lambda: time.sleep(0.002))
            gc.collect()
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:
                time.sleep(0.01)
        assert caught.value.name == "SIGTERM" and policy.stopped_by == "SIGTERM"
    finally:
        if not first:
            gc.callbacks.remove(in_gc)
        policy.uninstall()
    assert gc.callbacks == callbacks  # the policy's own callback went with it
    err = capfd.readouterr().err
    assert fired and "Exception ignored" not in err and "Traceback" not in err


# ---- the real command ----

GC_SIGNAL = '''
import gc, os, signal

def send_in_gc():
    fired = []

    def in_gc(phase, info):
        if phase == "start" and not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGTERM)  # its handler runs in this callback

    gc.callbacks.append(in_gc)
    try:
        gc.collect()
    finally:
        gc.callbacks.remove(in_gc)
'''

PLUGINS = {
    # during the last check's teardown, inside a gc callback
    "last_check": GC_SIGNAL + '''
def pytest_runtest_teardown(item, nextitem):
    if nextitem is None:
        send_in_gc()
''',
    # during the first check, inside a gc callback; the check goes on for 30 s unless interrupted
    "first_check": GC_SIGNAL + '''
import time

def pytest_runtest_call(item):
    if not getattr(pytest_runtest_call, "done", False):
        pytest_runtest_call.done = True
        send_in_gc()
        time.sleep(30)
''',
    # during the first check, inside an I/O object's close that its reference count runs as a finalizer
    # (CPython drops an exception raised there without a word: no hook sees it)
    "finalizer_in_check": '''
import io, os, signal

class Closer(io.RawIOBase):
    def close(self):
        if not self.closed:
            os.kill(os.getpid(), signal.SIGTERM)  # its handler runs here
        super().close()

def pytest_runtest_call(item):
    if not getattr(pytest_runtest_call, "done", False):
        pytest_runtest_call.done = True
        Closer()  # freed at once
''',
    # once pytest has ended (after every unconfigure hook), inside a gc callback
    "after_pytest": GC_SIGNAL + '''
def pytest_configure(config):
    config.add_cleanup(send_in_gc)
''',
    # SIGINT during collection; SIGTERM once pytest has ended
    "two_signals": '''
import os, signal

def pytest_collection_modifyitems(session, config, items):
    config.add_cleanup(lambda: os.kill(os.getpid(), signal.SIGTERM))
    os.kill(os.getpid(), signal.SIGINT)
''',
}


def run_with(plugin: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    (tmp_path / f"sig_{plugin}.py").write_text(PLUGINS[plugin])
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "PYTEST_PLUGINS": f"sig_{plugin}"}
    return subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", *SELECT], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)


def verdict(done: subprocess.CompletedProcess[str]) -> str:
    return done.stdout.splitlines()[-1]


@pytest.mark.slow
def test_signal_in_a_gc_callback_during_the_last_check_interrupts_the_run(tmp_path: Path) -> None:
    """SIGTERM raised inside a gc callback while the last check ends: the run is interrupted (exit 2),
    the verdict names SIGTERM, the device is restored, no traceback."""
    done = run_with("last_check", tmp_path)
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert "interrupted by SIGTERM" in verdict(done) and verdict(done).endswith("(exit status 2)")
    assert "Traceback" not in done.stderr + done.stdout and "restoring the device" in done.stdout


@pytest.mark.slow
def test_signal_in_a_gc_callback_during_a_check_stops_the_run_in_it(tmp_path: Path) -> None:
    """SIGTERM raised inside a gc callback during the first check: it is raised again once the
    collection has ended, in that check (which would go on for 30 s): no check passes, exit 2, the
    verdict names SIGTERM, no second signal is reported (was: the check ran to its end)."""
    started = time.monotonic()
    done = run_with("first_check", tmp_path)
    assert time.monotonic() - started < 25, "the check was not interrupted"
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert "INCOMPLETE: 98 of 98 checks not run" in verdict(done) and "passed" not in done.stdout
    assert "interrupted by SIGTERM" in verdict(done) and "Traceback" not in done.stderr
    assert "ignored" not in done.stderr and "Exception ignored" not in done.stdout


@pytest.mark.slow
def test_signal_whose_raise_a_finalizer_dropped_stops_the_run_before_the_next_check(tmp_path: Path) -> None:
    """SIGTERM whose ``Interrupted`` an I/O object's finalizer drops without a word during the first
    check: that check ends, the run stops before the next one, exit 2, the verdict names SIGTERM (was:
    every other check still ran)."""
    done = run_with("finalizer_in_check", tmp_path)
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert "framing of answers: 1 passed, 10 not run" in done.stdout
    assert "interrupted by SIGTERM" in verdict(done) and "Traceback" not in done.stderr


@pytest.mark.slow
def test_signal_in_a_gc_callback_after_pytest_ended_is_ignored_and_said(tmp_path: Path) -> None:
    """SIGTERM inside a gc callback once pytest has ended (the run's last ~0.1 s): the ending goes on,
    the signal is ignored and said so, no traceback (was: a second policy raised it inside the callback,
    a traceback, and the signal lost)."""
    done = run_with("after_pytest", tmp_path)
    assert "xac1 conformance: SIGTERM ignored" in done.stderr, done.stderr[-2000:]
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr, done.stderr[-2000:]
    assert done.returncode == 4 and verdict(done).startswith("xac1 conformance: INCOMPLETE")  # -k


@pytest.mark.slow
def test_first_signal_wins_and_the_second_is_ignored(tmp_path: Path) -> None:
    """SIGINT during collection, then SIGTERM once pytest has ended: the verdict names SIGINT (the first)
    and SIGTERM is ignored and said so (was: the verdict named none, or the second)."""
    done = run_with("two_signals", tmp_path)
    assert done.returncode == 2
    assert verdict(done) == ("xac1 conformance: INCOMPLETE: nothing was checked (the run was interrupted by "
                             "SIGINT before it began) (exit status 2)")
    assert "xac1 conformance: SIGINT: stopping" in done.stderr
    assert "xac1 conformance: SIGTERM ignored" in done.stderr and "Traceback" not in done.stderr
