"""The one signal policy (``xac1_proto.signals``), in this process with real signals: SIGINT, SIGTERM
and SIGHUP end a run the same way; a signal before the run began aborts it quietly; later signals and
signals during the ending are ignored and said so; the previous handlers come back."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from xac1_proto.signals import EXIT_EARLY, SIGNALS, Interrupted, OrderlyEnd, signal_name

ALL = pytest.mark.parametrize("sig", SIGNALS, ids=signal_name)


def messages(path: Path) -> list[str]:
    return path.read_text().splitlines()


@ALL
def test_signal_before_begin_aborts_quietly(tmp_path: Path, sig: int) -> None:
    """Before ``begin()`` a signal raises ``Interrupted`` (the command then ends with EXIT_EARLY) and
    prints nothing."""
    with open(tmp_path / "err", "w") as err, OrderlyEnd("xac1 test", "ending", err=err) as end:
        with pytest.raises(Interrupted) as caught:
            signal.raise_signal(sig)
        assert caught.value.signum == sig and caught.value.name == signal_name(sig)
        assert end.early and end.stop.is_set() and end.signum == sig
    assert messages(tmp_path / "err") == []
    assert EXIT_EARLY == 2


@ALL
def test_first_signal_after_begin_sets_stop_and_says_so(tmp_path: Path, sig: int) -> None:
    """After ``begin()`` the first signal sets ``stop`` (no exception: a loop polls it) and says what
    the ending does."""
    with open(tmp_path / "err", "w") as err, \
            OrderlyEnd("xac1 test", "stopping: the summary follows", err=err) as end:
        end.begin()
        signal.raise_signal(sig)
        assert end.stop.is_set() and not end.early and end.signal_name == signal_name(sig)
    assert messages(tmp_path / "err") == [f"xac1 test: {signal_name(sig)}: stopping: the summary follows"]


def test_interrupt_mode_raises_once_then_ignores(tmp_path: Path) -> None:
    """With ``interrupt=True`` the first signal also raises ``Interrupted`` (code that blocks); a second
    one (a double Ctrl-C) is ignored and said so, without raising into the ending."""
    with open(tmp_path / "err", "w") as err, \
            OrderlyEnd("xac1 test", "restoring the device", interrupt=True, err=err) as end:
        end.begin()
        with pytest.raises(Interrupted):
            signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGINT)  # no exception
        signal.raise_signal(signal.SIGTERM)
        assert end.signum == signal.SIGINT
    assert messages(tmp_path / "err") == ["xac1 test: SIGINT: restoring the device",
                                          "xac1 test: SIGINT ignored: restoring the device",
                                          "xac1 test: SIGTERM ignored: restoring the device"]


@ALL
def test_signal_during_the_ending_is_ignored(tmp_path: Path, sig: int) -> None:
    """Once ``ending()`` was called (the run ended on its own: a port went away), every signal is
    ignored and said so; ``stop`` stays as it was."""
    with open(tmp_path / "err", "w") as err, \
            OrderlyEnd("xac1 test", "writing the state file", interrupt=True, err=err) as end:
        end.begin()
        end.ending()
        signal.raise_signal(sig)
        assert not end.stop.is_set() and end.signum is None
    assert messages(tmp_path / "err") == [f"xac1 test: {signal_name(sig)} ignored: writing the state file"]


def test_previous_handlers_come_back() -> None:
    """Leaving the block puts the handlers back as they were."""
    before = {sig: signal.getsignal(sig) for sig in SIGNALS}
    with OrderlyEnd("xac1 test", "ending"):
        assert all(signal.getsignal(sig) != before[sig] for sig in SIGNALS)
    assert {sig: signal.getsignal(sig) for sig in SIGNALS} == before


def test_inert_outside_the_main_thread() -> None:
    """Handlers can only be installed from the main thread: elsewhere the policy is inert, not an
    error, and ``stop`` is still an event its owner can set."""
    result: list[object] = []

    def body() -> None:
        with OrderlyEnd("xac1 test", "ending") as end:
            end.begin()
            end.stop.set()
            result.append(end.stop.is_set())

    before = signal.getsignal(signal.SIGTERM)
    thread = threading.Thread(target=body)
    thread.start()
    thread.join(5)
    assert result == [True] and signal.getsignal(signal.SIGTERM) == before


@pytest.mark.slow  # starts a process
def test_a_signal_landing_anywhere_inside_stop_wait_wakes_it() -> None:
    """``xac1 sim`` waits on ``end.stop`` in its main thread; the signal handler sets it in that same
    thread, wherever the signal lands. A lock-taking event deadlocks when it lands while ``wait()``
    holds the event's lock (``xac1 sim`` once hung on SIGTERM under load); ``stop`` takes none: at
    every line of ``wait()`` up to its ``select`` the signal wakes it at once, not at the end of its 5 s
    (where it lands just before ``select``, the wake-up fd does), and at every line after it (run once
    ``select`` ran out) the wait still ends with the flag set. A fresh interpreter, so a deadlock is a
    timeout, not a hung suite."""
    r = subprocess.run([sys.executable, "-c", SIGNAL_AT_EVERY_LINE_OF_WAIT], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    select_at, results = json.loads(r.stdout)
    assert len(results) >= 3  # the wait has lines to land on
    assert 1 < select_at < len(results)  # lines before select, select, and lines after it were landed on
    assert all(woke for _, woke, _ in results), results
    # at once, not after the 5 s wait (the margin is for a loaded CI machine's scheduling)
    assert max(took for _, _, took in results) < 2.5, results


# A signal raised at the n-th traced line executed inside ``end.stop.wait()``, for every n until the
# wait runs out of lines: the handler runs right there (``raise_signal`` runs it before returning). A
# line after the one calling ``select`` runs only once ``select`` has run out (nothing else wakes it), so
# those landings wait 0.05 s, not 5 s: a first wait with no signal finds where ``select`` is called.
SIGNAL_AT_EVERY_LINE_OF_WAIT = """
import json, os, select, signal, sys, time  # select: loaded, as for every wait but a process's first
from xac1_proto.signals import OrderlyEnd, StopFlag

WAIT = StopFlag.wait.__code__


def land(n, timeout):
    \"\"\"Wait with a SIGTERM raised at the n-th traced line (none for n = 0): the lines traced (in
    wait or not, line number), whether the wait woke with the flag set, when the signal landed.\"\"\"
    lines, landed = [], [None]

    def trace(frame, event, arg):
        if event == "line":
            lines.append((frame.f_code is WAIT, frame.f_lineno))
            if len(lines) == n:
                landed[0] = time.monotonic()
                signal.raise_signal(signal.SIGTERM)
        return trace

    with open(os.devnull, "w") as devnull, OrderlyEnd("t", "x", err=devnull) as end:
        end.begin()
        sys.settrace(trace)
        woke = end.stop.wait(timeout)
        sys.settrace(None)
    return lines, woke, landed[0]


unsignalled, _, _ = land(0, 0.05)
select_line = next(line for in_wait, line in unsignalled
                   if in_wait and "select.select(" in open(WAIT.co_filename).readlines()[line - 1])
select_at = unsignalled.index((True, select_line)) + 1
results = []
n = 1
while True:
    lines, woke, landed = land(n, 5.0 if n <= select_at else 0.05)
    if landed is None:  # the wait had fewer lines than n: every landing place was tried
        break
    results.append([n, woke, time.monotonic() - landed])
    n += 1
print(json.dumps([select_at, results]))
"""
