"""The host side of a capture played against a device over a pyserial port (``xac1 replay``'s loop).

How it works: each captured host line is sent byte for byte, in order, paced as captured
(``xac1_proto.replay``: after the previous line's answer and its gap, or at its gap after the previous
line when it was sent back to back, overlap included; ``fast``: only waiting for each answer). While it
waits, everything the device sends is read and, with what is sent, fed to the sniffer's analyzer: the
one rulebook pairs each answer with its line and names every violation of the new conversation. A line
the motion guard refuses is not sent (``skipped``). At the end (or on ``stop``) the last answers are
awaited and each line's answers are compared with the captured ones (``xac1_proto.replay.compare``).

Which line an answer belongs to: the line the engine paired it with (the live host records are mapped to
the lines sent by their byte offsets in the host stream); device bytes it paired with none belong to the
last line sent before them (an answer that came late, or an extra one).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.replay import Answer, CapturedLine, Comparison, Script, compare
from xac1_proto.signals import StopRequest

from .analyzer import Analyzer
from .records import FrameRecord, JunkRecord, Record, TimeoutRecord

CAPTURED, FAST = "captured", "fast"
PACES = (CAPTURED, FAST)
QUIET_S = 0.05  # after the last window closed: the line quiet this long ends the replay
MAX_GAP_S = 600.0  # a captured gap longer than this is shortened to it (said in docs/replay.md)
STOPPED_LIMIT = 3  # answered lines in a row that got not a byte back: is the device still there?


class PortFailed(Exception):
    """The port failed while replaying (unplugged, closed); the message says what was being done."""


@dataclass
class LineResult:
    """One captured host line replayed: sent (``t_sent``) or ``skipped`` (why), the answers it got,
    the comparison with the captured ones and the violations the engine found in its exchange."""

    line: CapturedLine
    t_sent: float | None = None
    skipped: str | None = None
    got: list[Answer] = field(default_factory=list)
    violations: list[str] = field(default_factory=list)
    comparison: Comparison = field(default_factory=Comparison)

    @property
    def same(self) -> bool:
        return self.skipped is None and self.comparison.same


class Player:
    """Plays ``script`` on ``port`` (an open pyserial port); ``analyzer`` judges the new conversation
    (its answer window is the wait for an answer). ``check(raw)``: the motion guard (None or why
    not). ``alive()``: asked after ``STOPPED_LIMIT`` silent lines; False ends the replay (``stopped``).
    ``on_result``: each line's result in order, as soon as nothing more can change it (before the next
    line is sent, when nothing is owed; else at the end)."""

    def __init__(self, port: serial.Serial, script: Script, analyzer: Analyzer | None = None, *,
                 pace: str = CAPTURED, check: Callable[[bytes], str | None] | None = None,
                 alive: Callable[[], bool] | None = None, stop: StopRequest | None = None,
                 on_result: Callable[[LineResult], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if pace not in PACES:
            raise ValueError(f"pace must be one of {', '.join(PACES)}, got {pace!r}")
        self.port = port
        self.script = script
        self.pace = pace
        self.check = check or (lambda raw: None)
        self.alive = alive
        self.stop = stop
        self.on_result = on_result
        self.clock = clock
        self.analyzer = analyzer or Analyzer()
        self.results = [LineResult(line) for line in script.lines]
        self.records: list[Record] = []
        self.stopped = False  # the device stopped answering
        self.interrupted = False  # ``stop`` was set
        self._offsets: list[tuple[int, int]] = []  # host stream offset -> line number, per line sent
        self._host_bytes = 0  # host bytes sent so far
        self._host_seen = 0  # host bytes of the live host records so far
        self._line_of_i: dict[int, int] = {}  # live record number -> line number
        self._last_sent: int | None = None
        self._silent_run = 0
        self._final = 0  # lines before this one are compared and handed to ``on_result``

    # ---- the run ----

    def run(self) -> list[LineResult]:
        """Play every line (until ``stop`` or a device that stopped answering); the results."""
        lines = self.script.lines
        for line in lines:
            if self._stopping():
                break
            self._wait_before(line)
            if self._stopping():
                break
            why = self.check(line.raw)
            result = self.results[line.n]
            if why is not None:
                result.skipped = why
                continue
            if not self.analyzer.waiting and self._host_seen == self._host_bytes:
                self._settle(line.n)  # nothing is owed: what came so far is all the earlier lines get
            self._send(line)
            if self._answer_missing_run(line) and not self._still_there():
                self.stopped = True
                break
        self._finish()
        return self.played

    @property
    def played(self) -> list[LineResult]:
        """The lines sent or skipped so far (all of them unless the replay was cut short)."""
        return [r for r in self.results if r.t_sent is not None or r.skipped is not None]

    def _stopping(self) -> bool:
        if self.stop is not None and self.stop.is_set():
            self.interrupted = True
        return self.interrupted or self.stopped

    def _wait_before(self, line: CapturedLine) -> None:
        """Wait as the capture did before ``line`` (module docstring), reading all the while."""
        prev = self._last_sent
        if prev is None or line.n == 0:
            return
        previous = self.script.lines[line.n - 1]
        before = self.results[line.n - 1]
        if before.t_sent is None:  # the line before was skipped: no answer to wait for
            return
        overlap = not line.after_answer and bool(previous.answers)
        partial = not previous.raw.endswith(spec.FRAME_END)  # no LF: nothing can answer it alone
        if line.after_answer or (self.pace == FAST and not overlap and not partial):
            self._pump_until(lambda: self._settled(line.n - 1))
        gap = min(line.gap_s or 0.0, MAX_GAP_S) if self.pace == CAPTURED else 0.0
        if gap:
            answered = before.got[-1].t_last if before.got else None
            start = (answered if answered is not None else self.clock()) if line.after_answer \
                else before.t_sent
            deadline = start + gap
            self._pump_until(lambda: self.clock() >= deadline)

    def _settled(self, n: int) -> bool:
        """Has line ``n`` got as many answers as captured, or is its answer window closed?"""
        result = self.results[n]
        wanted = max(1, len(result.line.answers))
        return len(result.got) >= wanted or not self._owed(n)

    def _owed(self, n: int) -> bool:
        """Is line ``n`` still owed an answer by the engine (sent, its window open)? Bytes the analyzer
        has not framed yet (line noise with no LF waits for what follows) are owed one window."""
        if self._host_seen < self._host_bytes:
            sent = self.results[n].t_sent
            window = self.analyzer.conversation.no_answer_timeout
            return sent is not None and self.clock() < sent + window
        return self.analyzer.waiting

    def _pump_until(self, done: Callable[[], bool]) -> None:
        while not done():
            if self._stopping():
                return
            self._read()

    def _send(self, line: CapturedLine) -> None:
        now = self.clock()
        try:
            self.port.write(line.raw)
            self.port.flush()
        except OSError as exc:  # serial.SerialException is an OSError
            raise PortFailed(f"the port failed while sending captured line {line.n + 1}: {exc}") from None
        self.results[line.n].t_sent = now
        self._offsets.append((self._host_bytes, line.n))
        self._host_bytes += len(line.raw)
        self._last_sent = line.n
        self._take(self.analyzer.feed(Chunk(now, HOST, line.raw)))

    def _read(self) -> None:
        try:
            waiting = self.port.in_waiting
            data = self.port.read(max(1, waiting))
        except OSError as exc:
            raise PortFailed(f"the port failed while reading answers: {exc}") from None
        now = self.clock()
        if data:
            self._take(self.analyzer.feed(Chunk(now, DEVICE, data)))
        else:
            self._take(self.analyzer.tick(now))

    def _finish(self) -> None:
        """Wait for the last answers (not after a stop), then close the conversation and compare."""
        if not self.interrupted and not self.stopped and self._offsets:
            self._pump_until(lambda: not self._owed(self._offsets[-1][1]))
            quiet_from = self.clock()
            seen = self.analyzer.bytes_in(DEVICE)
            while self.clock() - quiet_from < QUIET_S and not self._stopping():
                self._read()
                if self.analyzer.bytes_in(DEVICE) != seen:
                    seen, quiet_from = self.analyzer.bytes_in(DEVICE), self.clock()
        self.close()

    def close(self) -> None:
        """End of the replay (also after a failure): the conversation closed, every line played final."""
        self._take(self.analyzer.close(self.clock()))
        self._settle(len(self.results))

    def _settle(self, upto: int) -> None:
        """Lines before ``upto`` (played ones: a prefix) are final: compared, handed to ``on_result``."""
        while self._final < upto:
            result = self.results[self._final]
            if result.t_sent is None and result.skipped is None:
                return  # not played: the replay was cut short here
            if result.t_sent is not None:
                result.comparison = compare(result.line.answers, result.got)
            if self.on_result is not None:
                self.on_result(result)
            self._final += 1

    # ---- records to lines ----

    def _take(self, records: list[Record]) -> None:
        for r in records:
            self.records.append(r)
            if isinstance(r, TimeoutRecord):
                n = self._line_of_i.get(r.command)
                if n is not None:
                    self.results[n].violations.append("no-answer")
                continue
            if r.dir == HOST:
                n = self._line_at(self._host_seen)
                self._host_seen += len(r.raw)
                if n is not None:
                    self._line_of_i[r.i] = n
                    self.results[n].violations += r.violations
                continue
            n = self._line_of_i.get(r.reply_to) if r.reply_to is not None else None
            if n is None:
                n = self._last_sent
            if n is None:
                continue  # before any line: nothing to compare it with (the records keep it)
            result = self.results[n]
            if isinstance(r, FrameRecord):
                result.got.append(Answer(r.raw, r.header, r.frame, r.t, r.t_last))
            elif isinstance(r, JunkRecord):
                result.got.append(Answer(r.raw, None, None, r.t, r.t))
            result.violations += r.violations

    def _line_at(self, offset: int) -> int | None:
        """The line sent whose bytes hold host stream ``offset``."""
        for start, n in reversed(self._offsets):
            if start <= offset:
                return n
        return None

    # ---- is the device still there? ----

    def _answer_missing_run(self, line: CapturedLine) -> bool:
        """After sending ``line``: have ``STOPPED_LIMIT`` lines in a row, answered in the capture and
        waited for now, got not a byte back?"""
        if line.n == 0 or self.alive is None:
            return False
        previous = self.results[line.n - 1]
        if previous.got:
            self._silent_run = 0
        elif previous.t_sent is not None and previous.line.answers and line.after_answer:
            self._silent_run += 1
        return self._silent_run >= STOPPED_LIMIT

    def _still_there(self) -> bool:
        """Asks ``alive`` (the device answers something); a run that goes on starts counting again."""
        self._silent_run = 0
        return self.alive is None or self.alive()
