"""One signal policy for every long-running command (sniff, proxy, sim, conformance).

How it works: SIGINT (Ctrl-C), SIGTERM (``kill``, ``timeout(1)``, a service stop) and SIGHUP (the
terminal or SSH session closed) all mean the same thing: end in order. ``OrderlyEnd`` is a context
manager that installs one handler for the three and restores the previous handlers on exit:

- a signal *before* ``begin()`` (start-up: imports, opening ports, nothing sent yet) raises
  ``Interrupted``; the command ends quietly with ``EXIT_EARLY`` (2), no traceback;
- the *first* signal after ``begin()`` sets ``stop`` (a loop polls it between two reads) and, with
  ``interrupt=True`` (code that blocks, like a pytest run), also raises ``Interrupted`` in the main
  thread; one line on stderr says what now happens (``what``: "flushing the recording ...");
- every *later* signal, and any signal once ``ending()`` was called, is ignored and said so: the
  ending (restore, summary, state file) is never cut short.

A signal is raised as ``Interrupted`` only at a safe point: never inside an import (a class being made
there would turn it into ``RuntimeError: Error calling __set_name__``), a garbage-collection callback or
a finalizer (Python drops it there, or prints it as "unraisable"). ``unsafe_point`` looks at the stack
the signal interrupted; when it is not safe, the raise waits: the signal is sent again a moment later
(``send_later``), and ``begin()`` raises one still owed, so a signal before the run began never lets it
begin.

Do the ending inside the ``with`` block: outside it the previous handlers are back. Handlers can only be
installed from the main thread; elsewhere (a test calling a command's ``run`` from a thread) the policy
is inert and ``stop`` is only set by whoever owns it. ``startup()`` is for the ``xac1`` dispatcher:
until a command installs its ``OrderlyEnd``, any of the three signals raises ``Interrupted`` (at a safe
point; while the command is still being loaded, ``running()`` not yet called, a signal inside an import
ends the process at once with exit 2, as the entry point does: nothing was opened);
once a command's policy was in place (``taking_over``), a signal after it was taken down comes
during the command's last words and is ignored, and said so; ``exiting()`` (the dispatcher, once the
command returned) ignores them while the process exits. A start-up signal whose ``Interrupted`` some
code swallowed is sent again when the command's policy takes over, so it is never lost.

Typical use::

    with OrderlyEnd("xac1 sniff", "stopping: the summary follows") as end:
        try:
            taps = open_taps()            # a signal here: Interrupted
        except Interrupted:
            return EXIT_EARLY
        end.begin()
        loop(stop=end.stop)               # a signal here: end.stop is set, the loop returns
        end.ending()                      # from here on signals are ignored (and said so)
        print_summary()
"""

from __future__ import annotations

import _thread  # (built in, as gc: a signal handler imports nothing, see ``unsafe_point``)
import contextlib
import gc
import os
import signal
import sys
import time
import weakref
from types import FrameType, TracebackType
from typing import Any, Final, Protocol, TextIO

SIGNALS: Final = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
EXIT_EARLY: Final = 2  # a signal before the run began: nothing was done


_IMPORT_FILES: Final = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")
_FINALIZER_NAMES: Final = ("__del__", "__set_name__")  # dropped, or turned into RuntimeError (3.11)


def unsafe_point(frame: FrameType | None) -> str | None:
    """Why an exception raised where ``frame`` runs would be lost or turned into another error (inside
    an import, a garbage-collection callback, a finalizer); None at a safe point."""
    callbacks = {getattr(getattr(cb, "__func__", cb), "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code.co_filename in _IMPORT_FILES:
            return "an import"
        if code in callbacks:
            return "a garbage-collection callback"
        if code.co_name in _FINALIZER_NAMES or (code.co_filename.endswith("weakref.py")
                                                and code.co_name in ("__call__", "_exitfunc")):
            return "a finalizer"
        frame = frame.f_back
    return None


def _send(signum: int, delay: float) -> None:
    time.sleep(delay)
    os.kill(os.getpid(), signum)


def send_later(signum: int, delay: float = 0.002) -> None:
    """Send ``signum`` to this process again after ``delay`` seconds, from a bare helper thread
    (``threading.Thread.start`` waits for the thread, and the signal could land in that wait)."""
    _thread.start_new_thread(_send, (signum, delay))


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15 (the number itself for an unknown signal)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class StopRequest(Protocol):
    """What a loop polls to know it must end: an ``OrderlyEnd.stop``, or a ``threading.Event``."""

    def is_set(self) -> bool: ...


class StopFlag:
    """Set once, by a signal handler or any thread; polled or waited for by any thread.

    Unlike ``threading.Event`` it takes no lock: a handler runs in the main thread wherever the signal
    lands, and ``Event.set()`` there deadlocks when the main thread was inside ``Event.wait()`` holding
    the event's own lock (seen: ``xac1 sim`` hung on SIGTERM under load). Here ``set()`` stores a flag
    and writes a byte to a pipe, and ``wait()`` selects on that pipe. ``OrderlyEnd`` also makes the pipe
    the process's signal wake-up fd, so a signal that lands just before ``select`` (its Python handler
    not yet run) still wakes the wait at once; such a byte is drained and the handler decides."""

    def __init__(self) -> None:
        self._set = False
        self._r, self._w = os.pipe()
        os.set_blocking(self._r, False)
        os.set_blocking(self._w, False)
        weakref.finalize(self, _close_fds, self._r, self._w)

    @property
    def wakeup_fd(self) -> int:
        """The pipe's write end, for ``signal.set_wakeup_fd``."""
        return self._w

    def set(self) -> None:
        if not self._set:
            self._set = True
            with contextlib.suppress(OSError):  # a full pipe wakes the waiters as well
                os.write(self._w, b"!")

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float | None = None) -> bool:
        """Until the flag is set or ``timeout`` seconds passed; the flag."""
        import select  # here: the dispatcher imports this module, and ``xac1 parse`` loads no select

        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._set:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                break
            try:
                ready = select.select([self._r], [], [], remaining)[0]
            except (OSError, ValueError):  # closed: nothing more will wake it
                break
            if ready and not self._set:  # a signal's wake-up byte: its handler runs before we look again
                self._drain()
        return self._set

    def _drain(self) -> None:
        with contextlib.suppress(OSError):
            while os.read(self._r, 512):
                pass


def _close_fds(*fds: int) -> None:
    for fd in fds:
        with contextlib.suppress(OSError):
            os.close(fd)


class Interrupted(KeyboardInterrupt):
    """A signal ended what the main thread was doing; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal_name(signum))
        self.signum = signum

    @property
    def name(self) -> str:
        return signal_name(self.signum)


def _say(err: TextIO | None, text: str) -> None:
    """One line to ``err`` from a signal handler: straight to the file descriptor when there is one
    (a buffered stream may be in the middle of a write the handler interrupted)."""
    stream = sys.stderr if err is None else err
    line = text + "\n"
    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):
        with contextlib.suppress(OSError, ValueError, RuntimeError):
            stream.write(line)
            stream.flush()
        return
    with contextlib.suppress(OSError, ValueError, RuntimeError):
        stream.flush()
    with contextlib.suppress(OSError):
        os.write(fd, line.encode("utf-8", "replace"))


def _install(handler: Any) -> dict[int, Any]:
    """Set ``handler`` for the three signals; the handlers it replaced ({} outside the main thread,
    where Python cannot set handlers). ``threading`` is not imported for this: ``xac1 parse`` loads
    no thread module."""
    previous: dict[int, Any] = {}
    try:
        for sig in SIGNALS:
            previous[sig] = signal.signal(sig, handler)
    except ValueError:  # not the main thread: nothing was set
        return {}
    return previous


class _Dispatch:
    """The dispatcher's view of the run: still loading (parsing, importing the command: nothing
    opened), the start-up signal raised (None: none), whether a command's own policy has taken over."""

    loading = False
    raised: int | None = None
    taken_over = False


def _dispatcher_handler(signum: int, frame: FrameType | None) -> None:
    if _Dispatch.taken_over:  # the command's policy is down again: its last words are being said
        _say(None, f"xac1: {signal_name(signum)} ignored: the command has ended; its results stand")
        return
    if unsafe_point(frame):
        if _Dispatch.loading:  # nothing opened yet: end at once, as the entry point does
            _say(None, f"xac1: stopped by {signal_name(signum)}")
            os._exit(EXIT_EARLY)
        send_later(signum)
        return
    _Dispatch.raised = signum
    raise Interrupted(signum)


def startup() -> None:
    """Until a command installs its own ``OrderlyEnd``: SIGINT, SIGTERM and SIGHUP raise ``Interrupted``
    (the dispatcher turns it into a quiet ``EXIT_EARLY``); after its policy is taken down, they are
    ignored. No-op outside the main thread."""
    _Dispatch.raised, _Dispatch.taken_over, _Dispatch.loading = None, False, True
    _install(_dispatcher_handler)


def running() -> None:
    """The dispatcher has loaded the command and runs it: from now on a start-up signal that lands in
    an import waits for a safe point (the command may have opened something to close)."""
    _Dispatch.loading = False


def taking_over() -> None:
    """A command's own policy is being installed (``OrderlyEnd``, the conformance suite's
    ``StopPolicy``): a start-up signal raised before it and swallowed on the way is sent again, now
    for that policy; signals after it is taken down are ignored by the dispatcher."""
    _Dispatch.taken_over = True
    if _Dispatch.raised is not None:
        signum, _Dispatch.raised = _Dispatch.raised, None
        send_later(signum, 0)


def exiting() -> None:
    """The process is about to exit (its command has ended): further signals are ignored, so a late
    second Ctrl-C cannot turn a finished run's exit status into another. For the process's entry point
    only. No-op outside the main thread."""
    _install(signal.SIG_IGN)


class OrderlyEnd:
    """The signal policy of one run; see the module docstring.

    ``program`` starts every message (``xac1 sniff``); ``what`` says what the ending does. ``stop`` is set
    by the first signal; ``signum`` is that signal (None when none came); ``early`` is True when it came
    before ``begin()``."""

    def __init__(self, program: str, what: str, *, interrupt: bool = False,
                 err: TextIO | None = None) -> None:
        self.program = program
        self.what = what
        self.interrupt = interrupt
        self.err = err
        self.stop = StopFlag()
        self.signum: int | None = None
        self.early = False
        self._begun = False
        self._ending = False
        self._previous: dict[int, Any] = {}
        self._previous_wakeup: int | None = None
        self._owed: int | None = None  # a signal whose raise waits for a safe point (sent again)
        self._resent = 0  # signals sent again by this policy, not handled yet

    @property
    def signal_name(self) -> str | None:
        return None if self.signum is None else signal_name(self.signum)

    def begin(self) -> None:
        """The run has begun: from now on the first signal ends it in order instead of aborting it. A
        signal that came before, whose raise waited for a safe point, is raised here (main thread)."""
        if self._owed is not None and not self._begun:
            import threading

            if threading.current_thread() is threading.main_thread():
                deadline = time.monotonic() + 1.0
                while self._owed is not None and time.monotonic() < deadline:
                    time.sleep(0.001)  # the signal sent again: its handler raises it here
                if self._owed is not None:
                    signum, self._owed = self._owed, None
                    raise Interrupted(signum)
        self._begun = True

    def ending(self) -> None:
        """The ending is under way: from now on every signal is ignored, and said so."""
        self._ending = True

    def _raise(self, signum: int, frame: FrameType | None) -> None:
        """Raise ``Interrupted`` here; where that is not safe, once it is (the signal sent again)."""
        if self._ending:
            return
        if unsafe_point(frame):
            self._owed = signum
            self._resent += 1
            send_later(signum)
            return
        self._owed = None
        raise Interrupted(signum)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        name = signal_name(signum)
        if self._resent and signum == self.signum:  # ours, sent again
            self._resent -= 1
            if self._owed is not None:
                self._raise(signum, frame)
            return
        if self.signum is not None or self._ending:
            _say(self.err, f"{self.program}: {name} ignored: {self.what}")
            return
        self.signum = signum
        self.stop.set()
        if not self._begun:
            self.early = True
            self._raise(signum, frame)
            return
        _say(self.err, f"{self.program}: {name}: {self.what}")
        if self.interrupt:
            self._raise(signum, frame)

    def __enter__(self) -> OrderlyEnd:
        self._previous = _install(self._handle)
        if self._previous:
            taking_over()
        if self._previous:  # the main thread: a signal wakes ``stop.wait()`` even before its handler ran
            self._previous_wakeup = signal.set_wakeup_fd(self.stop.wakeup_fd)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._ending = True  # a signal of ours still on its way is taken here, never by the next handler
        deadline = time.monotonic() + 0.2
        while self._previous and self._resent and time.monotonic() < deadline:
            time.sleep(0.001)
        for sig, handler in self._previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        self._previous.clear()
        if self._previous_wakeup is not None:
            signal.set_wakeup_fd(self._previous_wakeup)
            self._previous_wakeup = None
