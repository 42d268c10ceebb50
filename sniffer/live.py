"""The live shell shared by ``xac1 sniff`` and ``xac1 proxy``: clock, analyzer, view and recording.

``Clock`` reads the monotonic clock and maps it to wall time once, so timestamps never jump when the
system clock is set. ``Session`` takes each chunk as it is seen: feeds the analyzer, writes the chunk to
the recording with the verdicts it completed (a pcapng recording keeps them as comments; written even
when the analysis fails, so a crash loses nothing) and prints the records; ``close()`` flushes, prints the
summary and closes the recording. When standard output goes away (``xac1 proxy | tee log`` and the
Ctrl-C that ends both), records are no longer printed; the recording, the report and the summary (then
on stderr) are still written. ``sniff`` is the tap loop: ``select`` over the two receive-only taps,
chunks put back in cause-and-effect order (``order.CausalOrder``: two taps deliver with different
delays) and judged at the time their poll began (a slow sniffer sees late, never out of order), a
tick every ``TICK_S`` for missed answers, framing-error marks kept (``Chunk.error``), and a clear
message when a tap goes away (with ``reconnect``: retried every ``RETRY_S`` while the other tap goes on).
"""

from __future__ import annotations

import functools
import os
import select
import threading
import time
from collections.abc import Callable
from typing import IO

from xac1_proto import spec
from xac1_proto.chunk import Chunk, Direction
from xac1_proto.recording import RecordingWriter
from xac1_proto.signals import StopRequest

from .analyzer import Analyzer
from .io.pcapng_writer import JsonlRecorder, Recorder
from .order import CausalOrder
from .records import Record
from .taps import PortGone, ReadOnlyPort
from .view import View, make_view

TICK_S = 0.05
RETRY_S = 0.5


class Clock:
    """Unix seconds from the monotonic clock, mapped to wall time once at creation."""

    def __init__(self) -> None:
        self._wall0 = time.time()
        self._mono0 = time.monotonic()

    def now(self) -> float:
        return self._wall0 + (time.monotonic() - self._mono0)


class Session:
    """Recording, analyzer and view for one run; see the module docstring."""

    def __init__(self, analyzer: Analyzer, view: View, recorder: Recorder | RecordingWriter | None = None,
                 on_record: Callable[[Record], None] | None = None, *, output: IO[str] | None = None,
                 err: IO[str] | None = None, program: str = "xac1") -> None:
        self.analyzer = analyzer
        self.view = view
        if isinstance(recorder, RecordingWriter):  # a JSON lines writer opened by hand
            recorder = JsonlRecorder.around(recorder)
        self.recorder = recorder
        self.on_record = on_record
        self.output = output  # the stream the view writes to (standard output), when known
        self.err = err
        self.program = program
        self.output_gone = False  # the view's reader went away (``| tee`` ended by the same Ctrl-C)
        self.closed = False

    def _show(self, show: Callable[[], None]) -> None:
        """Run one view call; when its reader has gone away (a closed pipe), stop printing and go on:
        the recording, the report and (on ``err``) the summary are still written."""
        if self.output_gone:
            return
        try:
            show()
        except BrokenPipeError:
            self.output_gone = True
            if self.output is not None:
                _discard(self.output)  # the interpreter's last flush of it must not fail either
            if self.err is not None:
                self.err.write(f"{self.program}: standard output went away (its pipe was closed): records "
                               f"are no longer printed; the recording and the report go on, the summary "
                               f"follows here\n")
                self.err.flush()

    def _out(self, records: list[Record]) -> None:
        for r in records:
            self._show(functools.partial(self.view.write, r))
            if self.on_record is not None:
                self.on_record(r)

    def chunk(self, chunk: Chunk) -> None:
        records: list[Record] = []
        try:
            records = self.analyzer.feed(chunk)
        finally:  # recorded even if the analysis fails; with the verdicts it completed
            if self.recorder is not None:
                self.recorder.write(chunk, records)
        self._out(records)

    def tick(self, now: float) -> None:
        records = self.analyzer.tick(now)
        if self.recorder is not None:  # also with none: held device bytes whose wire time has passed
            self.recorder.verdicts(records, now)
        self._out(records)

    def close(self, now: float | None, summary: bool = True) -> None:
        """Flush the analyzer, print the summary (unless ``summary`` is False), close the recording."""
        if self.closed:
            return
        self.closed = True
        try:
            records = self.analyzer.close(now)
            if records and self.recorder is not None:
                self.recorder.verdicts(records, now)
            self._out(records)
            if summary:
                self._show(lambda: self.view.summary(self.analyzer.summary()))
                if self.output_gone and self.err is not None:
                    make_view("text", self.err, color=False).summary(self.analyzer.summary())
        finally:
            if self.recorder is not None:
                self.recorder.close()


def _discard(stream: IO[str]) -> None:
    """Point ``stream``'s file descriptor at the null device (what is still buffered is dropped there)."""
    try:
        fd = stream.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
    except (OSError, ValueError, AttributeError):
        return
    try:
        os.dup2(null, fd)
    finally:
        os.close(null)


def _open(path: str, name: str, baud: int) -> ReadOnlyPort:
    return ReadOnlyPort(path, name, baud)


class _Taps:
    """The receive-only taps of a sniff: all opened at start (or none: PortGone for the caller), read
    when ready, and a tap that goes away closed and said; with ``reconnect`` it is tried again every
    RETRY_S while the other goes on."""

    def __init__(self, paths: dict[Direction, str], baud: int, reconnect: bool,
                 say: Callable[[str], None]) -> None:
        self.paths, self.baud, self.reconnect, self.say = paths, baud, reconnect, say
        self.ports: dict[Direction, ReadOnlyPort | None] = {}
        self.retry_at: dict[Direction, float] = {}
        for d, path in paths.items():
            try:
                self.ports[d] = _open(path, d, baud)
            except PortGone:  # at start: the caller reports it
                self.close()
                raise

    def reopen_due(self) -> None:
        """Open again each tap that went away whose retry time has come."""
        for d, port in self.ports.items():
            if port is None and time.monotonic() >= self.retry_at[d]:
                try:
                    self.ports[d] = _open(self.paths[d], d, self.baud)
                    self.say(f"{d} tap {self.paths[d]}: back, resuming")
                except PortGone:
                    self.retry_at[d] = time.monotonic() + RETRY_S

    def ready(self) -> list[tuple[Direction, ReadOnlyPort]]:
        """The open taps with bytes to read, after waiting at most TICK_S for one (when none is open,
        after TICK_S)."""
        live = {p.fileno(): (d, p) for d, p in self.ports.items() if p is not None}
        if not live:
            time.sleep(TICK_S)
            return []
        return [live[fd] for fd in select.select(list(live), [], [], TICK_S)[0]]

    def read(self, ready: list[tuple[Direction, ReadOnlyPort]], now: float) -> tuple[list[Chunk], bool]:
        """What the ready taps hold, as chunks seen at ``now`` (framing-error marks kept), and whether a
        tap went away meanwhile."""
        got: list[Chunk] = []
        gone = False
        for d, port in ready:
            try:
                got += [Chunk(now, d, data, error) for data, error in port.read()]
            except PortGone as exc:
                port.close()
                self.say(f"error: {exc}; everything seen so far is kept"
                         + (f"; waiting for it to come back (every {RETRY_S} s)" if self.reconnect else ""))
                self.ports[d] = None
                self.retry_at[d] = time.monotonic() + RETRY_S
                gone = True
        return got, gone

    def close(self) -> None:
        """Close every tap still open."""
        for port in self.ports.values():
            if port is not None:
                port.close()


def sniff(paths: dict[Direction, str], session: Session, clock: Clock, *, baud: int = spec.BAUD,
          reconnect: bool = False, stop: StopRequest | None = None,
          started: threading.Event | None = None, err: IO[str] | None = None) -> int:
    """Read both taps until ``stop`` (or Ctrl-C in the caller); 0, or 1 when a tap went away for good.
    Never writes to a tap. The caller closes the session."""
    stop = stop or threading.Event()

    def say(text: str) -> None:
        if err is not None:
            err.write(text + "\n")
            err.flush()

    taps = _Taps(paths, baud, reconnect, say)
    order = CausalOrder(session.chunk, lambda: session.analyzer.waiting,
                        lambda: session.analyzer.expecting_answer)
    if started is not None:
        started.set()
    say(f"sniff: host tap {paths.get('host')}, device tap {paths.get('device')}; Ctrl-C to stop")
    try:
        while not stop.is_set():
            taps.reopen_due()
            # Everything a tap held when this poll began is read by it: held chunks and missed answers
            # are judged at that time, so a sniffer slowed down (a busy machine) invents nothing.
            polled, polled_mono = clock.now(), time.monotonic()
            ready = taps.ready()
            got, gone = taps.read(ready, clock.now())
            order.push_poll(got, time.monotonic())
            if gone and not reconnect:
                return 1
            order.due(polled_mono)
            session.tick(polled)
        return 0
    finally:
        order.flush()
        taps.close()
