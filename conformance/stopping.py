"""How a conformance run ends on a signal: SIGINT (Ctrl-C), SIGTERM (``kill``, ``timeout(1)``, a CI
timeout) and SIGHUP (the terminal or SSH session closed) all mean "stop, restore the device, report".

How it works: ``StopPolicy.install`` puts one handler on the three signals (main thread only). The
first signal raises ``Interrupted`` (a ``KeyboardInterrupt``, so pytest ends the session as for Ctrl-C
and the plugin restores the device and reports ``INCOMPLETE``, exit 2); every later signal is ignored
and said so on stderr, so the restore and the report are never cut short. It is
``xac1_proto.signals``' policy (the one of every long-running command: the same signals, the same
``Interrupted``), shaped for a pytest session: the interrupt is raised where pytest runs, and the
message goes to the process's own stderr, which pytest may have replaced.

One policy a process: ``xac1 conformance`` installs one before pytest starts and the plugin takes that
same one (``StopPolicy.shared``), so the first signal is the first whichever layer it lands in, and a
second one 20 ms later is ignored even once pytest has ended.

Before pytest's session has started (``xac1 conformance`` only) the first signal's words say that
nothing was sent yet; from the session's start (the plugin's ``pytest_collection``) they say the device
is restored and the report follows.
A raise is never made inside an import, a gc callback or a finalizer (``xac1_proto.signals.unsafe_point``):
the signal is sent again a moment later, where the run is.

A raise can be swallowed where Python cannot pass an exception on, so the policy keeps it from being
lost:
- during a garbage collection (a gc callback such as hypothesis' own, a finalizer: an I/O object's
  ``close`` run by the collector drops an exception without a word) the policy does not raise: its own
  gc callback knows a collection is under way, and when it ends the signal is sent again from a helper
  thread, so it is raised where the run is;
- elsewhere (a ``__del__`` or weakref callback run by a reference count) Python calls
  ``sys.unraisablehook``: the policy's hook recognises its own ``Interrupted``, prints no traceback,
  and sends the same signal again.
Both stop at ``ending()``. ``stopped_by`` keeps the first signal for the verdict whatever happened to
the raise, and the plugin's ``raise_if_lost`` stops the run before the next check if a raise was still
lost (a finalizer that drops exceptions, run by a reference count).
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading
from types import FrameType
from typing import Any

from xac1_proto.signals import SIGNALS, Interrupted, send_later, signal_name, taking_over, unsafe_point

__all__ = ["BEFORE_THE_RUN", "DURING_THE_RUN", "SIGNALS", "Interrupted", "StopPolicy", "signal_name"]

# what the first signal does, said on stderr: before pytest started (nothing sent, nothing to report),
# and once the plugin has the run (the device is restored, the report written)
BEFORE_THE_RUN = "stopping: nothing was sent yet; the run ends before it began"
DURING_THE_RUN = "stopping: the device is restored, then the report follows"

_in_place: list[StopPolicy] = []  # the installed policies, innermost last (the process's, first)


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

    def __init__(self, program: str = "xac1 conformance", what: str = DURING_THE_RUN) -> None:
        self.program = program
        self.signum: int | None = None
        self.what = what
        self.late: int | None = None  # the first signal that came while the ending was under way
        self._previous: dict[int, Any] = {}
        self._previous_unraisable: Any = None
        self._users = 0  # the takers of ``shared`` still holding it (each uninstalls once)
        self._raised: Interrupted | None = None  # the Interrupted last raised (to know it when swallowed)
        self._owed = False  # the first signal's Interrupted has not been raised where the run is yet
        # the first signal, sent again by the policy and not handled yet: one item each (a list, as its
        # ``append`` and ``pop`` are atomic: a collection in another thread may send one)
        self._in_flight: list[None] = []
        self._in_hook = False  # inside ``_unraisable``
        self._collecting = False  # a garbage collection is under way (a raise now would be lost)
        self._deferred = False  # a signal came during that collection: send it again at its end
        self._ended = False

    @classmethod
    def shared(cls, program: str = "xac1 conformance") -> StopPolicy:
        """The policy already in place in this process (``xac1 conformance`` installs one before pytest
        starts), so that a run has one first signal; else a new one, installed. Uninstall it once."""
        current = _in_place[-1] if _in_place else None
        if current is not None and signal.getsignal(signal.SIGINT) == current._handle:
            return current.take()
        return cls(program).install()

    def take(self) -> StopPolicy:
        """One more holder of this installed policy (``shared``); each holder uninstalls once."""
        self._users += 1
        return self

    @property
    def signal_name(self) -> str | None:
        return None if self.signum is None else signal_name(self.signum)

    @property
    def stopped_by(self) -> str | None:
        """The signal that interrupted the run (came before ``ending``), whether or not its raise
        reached pytest; None when none did."""
        return None if self.signum is None or self.signum == -1 else signal_name(self.signum)

    def install(self) -> StopPolicy:
        if threading.current_thread() is threading.main_thread() and not self._previous:
            for sig in SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
            self._previous_unraisable = sys.unraisablehook
            sys.unraisablehook = self._unraisable
            gc.callbacks.append(self._gc_phase)
            _in_place.append(self)
            taking_over()
        return self

    def uninstall(self) -> None:
        if self._users:
            self._users -= 1
            return
        for sig, handler in self._previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        if self._previous:
            sys.unraisablehook = self._previous_unraisable
            with contextlib.suppress(ValueError):
                gc.callbacks.remove(self._gc_phase)
            if self in _in_place:
                _in_place.remove(self)
        self._previous.clear()

    def ending(self, what: str) -> None:
        """From now on every signal is ignored (it would cut ``what`` short)."""
        if self.signum is None:
            self.signum = -1  # no signal came: later ones are still only ignored
        self.what = what
        self._ended = True

    def _interrupt(self) -> Interrupted:
        assert self.signum is not None
        self._raised = Interrupted(self.signum)
        return self._raised

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self._in_flight and signum == self.signum:  # the first signal, sent again by the policy
            self._in_flight.pop()
            self._deliver(frame)
            return
        if self.signum is not None:
            if self.signum == -1 and self.late is None:
                self.late = signum
            _say(f"{self.program}: {signal_name(signum)} ignored: {self.what}")
            return
        self.signum = signum
        _say(f"{self.program}: {signal_name(signum)}: {self.what}")
        self._owed = True
        self._deliver(frame)

    def _deliver(self, frame: FrameType | None) -> None:
        """Raise the owed ``Interrupted`` here, unless a raise here would be lost: inside the hook that
        sends the signal again, an import, a gc callback or a finalizer (``unsafe_point``: send it once
        more, a moment later), or during a garbage collection (at its end)."""
        if not self._owed or self._ended:
            return
        if self._in_hook or unsafe_point(frame):
            self._send_again()
        elif self._collecting:
            self._deferred = True
        else:
            self._owed = False
            raise self._interrupt()

    def _gc_phase(self, phase: str, info: dict[str, int]) -> None:
        """A gc callback: while a collection runs, a raise would land in a finalizer or another gc
        callback and be lost; a signal that came meanwhile is sent again once it has ended."""
        if phase == "start":
            self._collecting = True
            return
        self._collecting = False
        if self._deferred:
            self._deferred = False
            self._send_again()

    def raise_if_lost(self) -> None:
        """Between two checks: a first signal came but its ``Interrupted`` never reached pytest (a
        finalizer run by a reference count dropped it during a check): raise it now."""
        if self.stopped_by is not None and not self._ended:
            self._owed = False
            raise self._interrupt()

    def _send_again(self) -> None:
        """The first signal once more, from a bare helper thread (``threading.Thread.start`` would wait
        for it, and the signal could land inside that wait)."""
        if self._ended or self.signum is None or self.signum < 0:
            return
        self._in_flight.append(None)
        send_later(self.signum)

    def _unraisable(self, info: Any) -> None:
        """``sys.unraisablehook``: our ``Interrupted`` swallowed (a ``__del__``, a weakref callback) is
        raised again by sending the signal once more; anything else goes to the previous hook."""
        if info.exc_value is None or info.exc_value is not self._raised:
            (self._previous_unraisable or sys.__unraisablehook__)(info)
            return
        self._owed = True
        self._in_hook = True
        self._send_again()
        self._in_hook = False  # the last statement: nothing runs after it that could take the raise

    @property
    def interrupted_by(self) -> str | None:
        if self.signum is None or self.signum == -1:
            return None if self.late is None else signal_name(self.late)
        return signal_name(self.signum)
