"""A signal while ``xac1`` is still loading (issue 24 item 8): the README promises a quiet exit 2 with
``xac1: stopped by SIGTERM`` for a signal before work begins, however early it comes. The entry point
installs the policy before its heavy imports.

The moment is made exact, not guessed with a sleep: the child is the console script's own entry point
(read from the installed metadata, as the ``xac1`` script does), with an audit hook that sends the
signal to the process itself when a given module's file is opened to be imported."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest
from conftest import ROOT

from xac1_proto.signals import SIGNALS, signal_name

CHILD = """
import importlib.metadata, os, signal, sys
sig, module = int(sys.argv[1]), sys.argv[2]
fired = []
def hook(event, args):  # the module's file (source or cached) being opened to import it
    if event == "open" and f"/{module}." in str(args[0]) and not fired:
        fired.append(1)
        os.kill(os.getpid(), sig)
sys.addaudithook(hook)
(entry,) = tuple(importlib.metadata.entry_points(group="console_scripts", name="xac1"))
sys.argv = ["xac1", *sys.argv[3:]]
sys.exit(entry.load()())
"""

# the first heavy import of the dispatcher; the module of the subcommand asked for
MOMENTS = ["argparse", "dataclasses", "decode_cli"]


@pytest.mark.slow
@pytest.mark.parametrize("module", MOMENTS)
@pytest.mark.parametrize("sig", SIGNALS, ids=signal_name)
def test_a_signal_while_loading_ends_quietly_with_exit_2(module: str, sig: int) -> None:
    """SIGINT, SIGTERM or SIGHUP while the entry point imports argparse, dataclasses, or the subcommand's
    module: ``xac1: stopped by <SIGNAL>`` and exit 2, no traceback, nothing on stdout (was: killed by
    the signal without a word, or a ``KeyboardInterrupt`` traceback)."""
    done = subprocess.run([sys.executable, "-c", CHILD, str(sig), module, "decode", "captures/socat-xv.log"],
                          cwd=ROOT, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert (done.returncode, done.stderr, done.stdout) == (2, f"xac1: stopped by {signal_name(sig)}\n", "")


@pytest.mark.slow  # starts a process
def test_the_entry_point_is_the_early_policy() -> None:
    """The console script ``xac1`` and ``python -m xac1_proto`` both start at ``xac1_proto.entry:main``,
    whose module imports nothing but ``os``, ``signal`` and ``types`` before the handlers are set."""
    import importlib.metadata

    (entry,) = tuple(importlib.metadata.entry_points(group="console_scripts", name="xac1"))
    assert entry.value == "xac1_proto.entry:main"
    assert "from .entry import main" in (ROOT / "xac1_proto" / "__main__.py").read_text()
    code = ("import sys; before = set(sys.modules); import xac1_proto.entry; "
            "print(sorted(m for m in set(sys.modules) - before))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    loaded = eval(done.stdout)  # noqa: S307 - our own child's printed list of names
    assert {m for m in loaded if not m.startswith(("xac1_proto", "__editable__"))} <= {"signal", "types"}, \
        loaded
    assert signal.SIGINT in SIGNALS


INSTALLING = """
import importlib.metadata, os, signal, sys
sig = int(sys.argv[1])
def profile(frame, event, arg):  # the dispatcher's policy has just set its handler for sig
    if (event == "return" and frame.f_code is signal.signal.__code__ and frame.f_locals["signalnum"] == sig
            and frame.f_back.f_code.co_name == "_install"):
        sys.setprofile(None)
        os.kill(os.getpid(), sig)
sys.setprofile(profile)
(entry,) = tuple(importlib.metadata.entry_points(group="console_scripts", name="xac1"))
sys.argv = ["xac1", *sys.argv[2:]]
sys.exit(entry.load()())
"""


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=signal_name)
def test_a_signal_while_the_dispatcher_installs_its_policy_ends_quietly(sig: int) -> None:
    """A signal handled just after the dispatcher set its handler for it, still inside ``startup()``:
    ``xac1: stopped by <SIGNAL>``, exit 2 (was: an ``Interrupted`` traceback and exit 1, seen by CI as
    ``xac1 sim`` sent SIGINT ~50 ms after its start)."""
    done = subprocess.run([sys.executable, "-c", INSTALLING, str(sig), "decode", "captures/socat-xv.log"],
                          cwd=ROOT, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert (done.returncode, done.stderr, done.stdout) == (2, f"xac1: stopped by {signal_name(sig)}\n", "")
