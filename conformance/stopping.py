"""How a conformance run ends on a signal: SIGINT (Ctrl-C), SIGTERM (``kill``, ``timeout(1)``, a CI
timeout) and SIGHUP (the terminal or SSH session closed) all mean "stop, restore the device, report".

How it works: ``StopPolicy.install`` puts one handler on the three signals (main thread only). The
first signal raises ``Interrupted`` (a ``KeyboardInterrupt``, so pytest ends the session as for Ctrl-C
and the plugin restores the device and reports ``INCOMPLETE``, exit 2); every later signal is ignored
and said so on stderr, so the restore and the report are never cut short. It is
``xac1_proto.signals``' policy (the one of every long-running command: the same signals, the same
``Interrupted``), shaped for a pytest session: the interrupt is raised where pytest runs, and the
message goes to the process's own stderr, which pytest may have replaced.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from types import FrameType
from typing import Any

from xac1_proto.signals import SIGNALS, Interrupted, signal_name

__all__ = ["SIGNALS", "Interrupted", "StopPolicy", "signal_name"]


def _say(text: str) -> None:
    """One line on the process's stderr (pytest may have replaced ``sys.stderr``), straight to the file
    descriptor: safe inside a signal handler."""
    err = sys.__stderr__
    if err is None:
        return
    with contextlib.suppress(OSError, ValueError, RuntimeError):
        err.flush()
    with contextlib.suppress(OSError, ValueError, AttributeError):
        os.write(err.fileno(), (text + "\n").encode("utf-8", "replace"))


class StopPolicy:
    """First signal: ``Interrupted``; later signals: ignored, and said so (``what`` says what goes on)."""

    def __init__(self, program: str = "xac1 conformance") -> None:
        self.program = program
        self.signum: int | None = None
        self.what = "stopping: the device is restored, then the report follows"
        self.late: int | None = None  # the first signal that came while the ending was under way
        self._previous: dict[int, Any] = {}

    @property
    def signal_name(self) -> str | None:
        return None if self.signum is None else signal_name(self.signum)

    def install(self) -> StopPolicy:
        if threading.current_thread() is threading.main_thread() and not self._previous:
            for sig in SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def uninstall(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        self._previous.clear()

    def ending(self, what: str) -> None:
        """From now on every signal is ignored (it would cut ``what`` short)."""
        if self.signum is None:
            self.signum = -1  # no signal came: later ones are still only ignored
        self.what = what

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is not None:
            if self.signum == -1 and self.late is None:
                self.late = signum
            _say(f"{self.program}: {signal_name(signum)} ignored: {self.what}")
            return
        self.signum = signum
        _say(f"{self.program}: {signal_name(signum)}: {self.what}")
        raise Interrupted(signum)

    @property
    def interrupted_by(self) -> str | None:
        if self.signum is None or self.signum == -1:
            return None if self.late is None else signal_name(self.late)
        return signal_name(self.signum)
