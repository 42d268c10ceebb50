"""The sniffer's analyzer: two byte streams in, one record per frame, junk run and missed answer out.

A thin layer over the one rulebook, ``xac1_proto.conversation.Conversation`` (every conversation rule,
with its docs/protocol.md section, lives there and only there). This module does what the engine does
not: it frames each direction with its own ``xac1_proto.Framer``, passes time along (``Chunk.t``,
``tick(now)``; a partial device frame that has been quiet for ``device_idle_flush`` comes out as junk,
and one still arriving keeps its command's answer window open), keeps the capture tool's line errors
(``Chunk.error``) with the bytes they flag (``line_errors`` on every record holding a flagged byte; they
are not violations), and turns the engine's verdicts into the records of docs/output.md's JSON lines schema:
``FrameRecord``, ``JunkRecord``, ``TimeoutRecord`` (``no-answer``), each with the side of each violation
(``sides``), counted by ``Tally`` for the summary. Nothing here reads a clock.

Captures without time (raw files, interceptty without ``-T``, sigrok without a sample rate): order is all
there is; the engine's docstring says what it then concludes.

Speed (``fast``, on by default): ``sniffer.fastlane`` memoises what this full path gave for a clean
command and its answer from the quiet state and gives the same records again when the same two chunks
come back under the same knowledge (or the same values in the part of it they read: ``sniffer.readset``),
bookkeeping included; every call returns what it returns without it
(tests/test_fastlane_equivalence.py). ``feed_many`` (decode's path) takes runs of such exchanges from the
chunks' iterator in one loop (tests/test_feed_many_equivalence.py). The engine is driven only through the
analyzer.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Final

from xac1_proto import FrameBytes, Framer, Junk, motion, spec
from xac1_proto.chunk import DEVICE, HOST, Chunk, Direction
from xac1_proto.conversation import Conversation, Verdict

from .fastlane import FastLane
from .records import CAPTURE_ENDED, CleanExchange, FrameRecord, JunkRecord, Record, Tally, TimeoutRecord

NO_ANSWER_TIMEOUT_S: Final = spec.NO_ANSWER_TIMEOUT_S  # docs/protocol.md silent item 17
DEVICE_IDLE_FLUSH_S: Final = 1.0  # a partial device frame this long quiet becomes junk
FEED_BATCH: Final = 1024  # chunks ``feed_many`` takes at most (about) in one call
FEED_BYTES: Final = 1 << 18  # bytes after which ``feed_many`` returns (its records hold them)


class Analyzer:
    """Feed ``Chunk``s of both directions in the order seen; get records. See the module docstring.
    ``fast``: the memo of clean exchanges (the same records, sooner); off, every chunk takes the full
    path."""

    def __init__(self, no_answer_timeout: float = NO_ANSWER_TIMEOUT_S, storm_limit: int = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 device_idle_flush: float | None = DEVICE_IDLE_FLUSH_S, fast: bool = True) -> None:
        self.conversation = Conversation(no_answer_timeout=no_answer_timeout, storm_limit=storm_limit,
                                         speeds=speeds)
        self.device_idle_flush = device_idle_flush
        self.tally = Tally()
        self._framers: dict[str, Framer] = {HOST: Framer(), DEVICE: Framer()}
        self._errors: dict[str, list[tuple[int, int, str]]] = {HOST: [], DEVICE: []}
        self._device_since: float | None = None  # time of the oldest pending device byte
        self._device_last: float | None = None  # time of the latest device chunk
        self._closed = False
        # the memo of clean exchanges (sniffer/fastlane.py): the same records, sooner; None: off
        self.lane: FastLane | None = FastLane(self) if fast else None

    # ---- input ----

    def feed(self, chunk: Chunk) -> list[Record]:
        """Bytes seen on one line; the records they complete (time passing to ``chunk.t`` first)."""
        if self._closed:
            raise RuntimeError("the analyzer is closed")
        if chunk.dir not in (HOST, DEVICE):
            raise ValueError(f"chunk direction must be 'host' or 'device', got {chunk.dir!r}")
        lane = self.lane
        if lane is None:
            return self._feed(chunk)
        if lane.skip:  # the lane steps aside for a while (sniffer/fastlane.py, BACKOFF)
            lane.skip -= 1
            return self._feed(chunk)
        return lane.feed(chunk)

    def feed_many(self, chunks: Iterator[Chunk], out: list[Record | CleanExchange], clean: bool = True,
                  limit: int = FEED_BATCH, lean: bool = False) -> int:
        """``feed`` for the next chunks of ``chunks``, up to ``limit`` of them (one more to end an exchange)
        or ``FEED_BYTES``:
        their records, the same and in the same order as ``feed`` one chunk at a time, appended to ``out``
        as they are made (an exception, Ctrl-C included, loses none given so far). Returns the chunks
        taken: 0 at the end.
        ``clean`` False: clean frame records that the fast lane answers in bulk are counted, not made (an
        output of only the summary needs none); every other record still comes. ``lean``: such an exchange
        comes as one ``CleanExchange`` (the memo's records and the numbers: what a JSON lines view prints)
        instead of its two records.

        Faster than ``feed`` one chunk at a time: after an exchange answered from the memo, the next ones
        are taken in one loop (``FastLane.stretch``), their bookkeeping done once."""
        lane = self.lane
        feed = self.feed
        taken = 0
        size = 0
        for chunk in chunks:
            taken += 1
            size += len(chunk.data)
            if lane is None:
                out += feed(chunk)
            else:
                hits = lane.hits
                out += feed(chunk)
                if lane.hits != hits and taken < limit and lane.can_stretch():
                    taken += lane.stretch(chunks, out, clean, limit - taken, lean)
            if taken >= limit or size >= FEED_BYTES:  # records hold their bytes: memory stays bounded
                break
        return taken

    def _feed(self, chunk: Chunk) -> list[Record]:
        """The full path of ``feed`` (the fast lane's fallback)."""
        out: list[Record] = []
        if chunk.t is not None:
            out += self._tick(chunk.t)
        framer = self._framers[chunk.dir]
        if chunk.error and chunk.data:
            self._errors[chunk.dir].append((framer.bytes_in, framer.bytes_in + len(chunk.data), chunk.error))
        pending_before = framer.pending
        events = framer.feed(chunk.data, chunk.t)
        if chunk.dir == DEVICE and chunk.data:
            self._device_last = chunk.t
            if framer.pending == 0:
                self._device_since = None
            elif pending_before == 0:
                self._device_since = chunk.t  # else keep the older time: never expire too early
        for event in events:
            out += self._event(chunk.dir, event)
        return out

    def tick(self, now: float) -> list[Record]:
        """Time passes to ``now`` (unix seconds): missed answers and stalled device frames come out."""
        lane = self.lane
        if lane is not None and not lane.skip:  # stepping aside, it holds and observes nothing
            lane.full_path()
        return self._tick(now)

    def _tick(self, now: float) -> list[Record]:
        out: list[Record] = []
        framer = self._framers[DEVICE]
        if (self.device_idle_flush is not None and framer.pending and self._device_last is not None
                and now - self._device_last >= self.device_idle_flush):
            self._device_since = None
            for event in framer.flush():
                out += self._event(DEVICE, event)
        out += self._records(self.conversation.tick(now, self._device_since))
        return out

    def close(self, now: float | None = None) -> list[Record]:
        """End of data: partial frames come out as junk; a command still waiting is ``no-answer`` when
        its deadline passed by ``now`` (default: the last time seen) or when the data had no time."""
        out: list[Record] = []
        if self._closed:
            return out
        if self.lane is not None:
            self.lane.full_path()
        if now is not None:
            out += self._tick(now)
        for direction in (HOST, DEVICE):
            events = self._framers[direction].flush()
            cut = events[-1] if events and _inside_frame(events[-1]) else None
            for event in events:
                out += self._cut(direction, event) if event is cut else self._event(direction, event)
        self._device_since = None
        out += self._records(self.conversation.close(now))
        self.tally.unanswered += self.conversation.cut_short()
        self._closed = True
        return out

    @property
    def waiting(self) -> bool:
        """Does anything the host sent (a command, an error, a discarded line) wait for an answer?"""
        if self.lane is not None:
            self.lane.settle()
        return self.conversation.waiting

    @property
    def expecting_answer(self) -> bool:
        """Does a well-formed command wait for its answer (see the engine)?"""
        if self.lane is not None:
            self.lane.settle()
        return self.conversation.expecting_answer

    def bytes_in(self, direction: str) -> int:
        """Bytes fed so far on one line."""
        if self.lane is not None:
            self.lane.settle()
        return self._framers[direction].bytes_in

    def summary(self) -> dict[str, object]:
        """The summary record (schema's last line) for everything so far."""
        return self.tally.summary()

    # ---- events to the engine, verdicts to records ----

    def _event(self, direction: str, event: FrameBytes | Junk) -> list[Record]:
        c = self.conversation
        junk = isinstance(event, Junk)
        if isinstance(event, Junk) and direction == DEVICE:  # a flushed partial line may be an answer
            verdicts = c.device_junk(event.raw, event.t_first, event.t_last, event.reason == "flushed")
        elif direction == HOST:
            verdicts = (c.host_junk if junk else c.host_frame)(event.raw, event.t_first, event.t_last)
        else:
            verdicts = c.device_frame(event.raw, event.t_first, event.t_last)
        errors = self._line_errors(direction, event.offset, len(event.raw))
        reason = event.reason if isinstance(event, Junk) else ""
        return self._records(verdicts, errors, reason)

    def _cut(self, direction: Direction, event: FrameBytes | Junk) -> list[Record]:
        """The data ended inside this frame: a record that says so, no violation (the engine's)."""
        verdicts = self.conversation.ended_inside_frame(direction, event.raw, event.t_first, event.t_last)
        return self._records(verdicts, self._line_errors(direction, event.offset, len(event.raw)))

    def _records(self, verdicts: list[Verdict], errors: tuple[str, ...] = (),
                 reason: str = "") -> list[Record]:
        out: list[Record] = []
        for v in verdicts:
            record = to_record(v, errors, reason)
            self.tally.add(record)
            out.append(record)
        return out

    def _line_errors(self, direction: str, offset: int, length: int) -> tuple[str, ...]:
        ranges = self._errors[direction]
        if not ranges:  # the usual capture: no line errors at all
            return ()
        while ranges and ranges[0][1] <= offset:
            ranges.pop(0)
        return tuple(e for start, end, e in ranges if start < offset + length and end > offset)


def _inside_frame(event: FrameBytes | Junk) -> bool:
    """Is ``event`` (the last one flushed at the end of the data) a frame the data ended inside: a frame
    start with no LF yet, short of the longest line a frame may reach?"""
    return (isinstance(event, Junk) and event.reason in ("flushed", "no-frame-start")
            and event.raw[:1] in (spec.LEAD, spec.LETTER_O) and spec.LF not in event.raw)


def to_record(v: Verdict, line_errors: tuple[str, ...] = (), reason: str = "") -> Record:
    """The record of one verdict (the docs/output.md schema)."""
    if v.violations:
        details = tuple(x.message for x in v.violations)
        codes, sides = v.codes, v.sides
    else:  # the clean frame: the same empty tuples, without the generators
        details = codes = sides = ()
    if v.kind == "no-answer":
        assert v.reply_to is not None
        return TimeoutRecord(command=v.reply_to, t=v.t, header=v.header, waited_s=v.waited_s,
                             details=details, sides=sides)
    assert v.i is not None
    direction: Direction = v.sender
    if v.kind == "cut":
        return JunkRecord(i=v.i, t=v.t, dir=direction, raw=v.raw, reason=CAPTURE_ENDED, violations=(),
                          line_errors=line_errors, reply_to=v.reply_to, latency_s=None)
    if v.kind in ("host-junk", "device-junk"):
        return JunkRecord(i=v.i, t=v.t, dir=direction, raw=v.raw, reason=reason or "flushed",
                          violations=codes, details=details, line_errors=line_errors, sides=sides,
                          reply_to=v.reply_to, latency_s=v.latency_s)
    return FrameRecord(i=v.i, t=v.t, dir=direction, raw=v.raw, header=v.header, frame=v.frame,
                       violations=codes, details=details, reply_to=v.reply_to, latency_s=v.latency_s,
                       t_last=v.t_last, line_errors=line_errors, sides=sides,
                       window_s=v.waited_s if v.kind == "host-frame" else None)


def analyze(chunks: list[Chunk] | tuple[Chunk, ...], **options: object) -> list[Record]:
    """Every record of a whole capture (a convenience for tests and small files)."""
    analyzer = Analyzer(**options)  # type: ignore[arg-type]
    out: list[Record] = []
    for chunk in chunks:
        out += analyzer.feed(chunk)
    out += analyzer.close()
    return out
