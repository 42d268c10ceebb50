"""The sniffer's analyzer: two byte streams in, one record per frame, junk run and missed answer out.

A thin layer over the one rulebook, ``xac1_proto.conversation.Conversation`` (every conversation rule,
with its docs/protocol.md section, lives there and only there). This module does what the engine does
not: it frames each direction with its own ``xac1_proto.Framer``, passes time along (``Chunk.t``,
``tick(now)``; a partial device frame that has been quiet for ``device_idle_flush`` comes out as junk,
and one still arriving keeps its command's answer window open), keeps the capture tool's line errors
(``Chunk.error``) with the bytes they flag (``line_errors`` on every record holding a flagged byte; they
are not violations), counts every verdict in ``Tally`` for the summary, and turns the verdicts into the
records of docs/output.md's JSON lines schema when the caller wants records: ``FrameRecord``, ``JunkRecord``,
``TimeoutRecord`` (``no-answer``), each with the side of each violation (``sides``). Nothing here reads
a clock.

One path: ``feed`` (a chunk; the live sniffer) and ``feed_many`` (a batch of chunks in one loop; decode)
both run each chunk through the one loop body of ``feed_many``. Records are made only where the output
needs them: ``feed_many`` without a list to fill (``xac1 decode --format summary``) counts the verdicts
and makes none.

Captures without time (raw files, interceptty without ``-T``, sigrok without a sample rate): order is all
there is; the engine's docstring says what it then concludes.
"""

from __future__ import annotations

from collections.abc import Iterator
from itertools import islice
from typing import Final

from xac1_proto import FrameBytes, Framer, Junk, motion, rules, spec
from xac1_proto.chunk import DEVICE, HOST, Chunk, Direction
from xac1_proto.conversation import BOTH, Conversation, Directions, Verdict

from .records import CAPTURE_ENDED, FrameRecord, JunkRecord, Record, Tally, TimeoutRecord

NO_ANSWER_TIMEOUT_S: Final = spec.NO_ANSWER_TIMEOUT_S  # docs/protocol.md silent item 17
DEVICE_IDLE_FLUSH_S: Final = 1.0  # a partial device frame this long quiet becomes junk
FEED_BATCH: Final = 1024  # chunks ``feed_many`` takes at most in one call
FEED_BYTES: Final = 1 << 18  # bytes after which ``feed_many`` returns (its records hold them)
FEED_VERDICTS: Final = 4096  # verdicts after which ``feed_many`` returns (short junk runs: many a chunk)


class Analyzer:
    """Feed ``Chunk``s of both directions in the order seen; get records. See the module docstring."""

    def __init__(self, no_answer_timeout: float = NO_ANSWER_TIMEOUT_S, storm_limit: int = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 device_idle_flush: float | None = DEVICE_IDLE_FLUSH_S,
                 readings: rules.Readings = rules.DEFAULT_READINGS, directions: Directions = BOTH) -> None:
        """``directions``: the lines the capture holds (``both``; ``host`` or ``device`` for a one-direction
        capture, which the engine judges only as far as one line's bytes show)."""
        self.conversation = Conversation(no_answer_timeout=no_answer_timeout, storm_limit=storm_limit,
                                         speeds=speeds, readings=readings, directions=directions)
        self.device_idle_flush = device_idle_flush
        self.tally = Tally()
        self._framers: dict[str, Framer] = {HOST: Framer(), DEVICE: Framer()}
        self._engine_frame = {HOST: self.conversation.host_frame, DEVICE: self.conversation.device_frame}
        self._errors: dict[str, list[tuple[int, int, str]]] = {HOST: [], DEVICE: []}
        self._device_since: float | None = None  # time of the oldest pending device byte
        self._device_partial = False  # device bytes wait in the framer (a frame still arriving)
        self._device_last: float | None = None  # time of the latest device chunk the framer cut
        self._closed = False
        self._judged: list[Verdict] = []  # verdicts not yet counted
        self._notes: dict[int, tuple[tuple[str, ...], str]] = {}  # index in _judged -> line errors, reason

    # ---- input ----

    def feed(self, chunk: Chunk) -> list[Record]:
        """Bytes seen on one line; the records they complete (time passing to ``chunk.t`` first)."""
        out: list[Record] = []
        self.feed_many(iter((chunk,)), out)
        return out

    def feed_many(self, chunks: Iterator[Chunk], out: list[Record] | None = None,
                  limit: int = FEED_BATCH) -> int:
        """``feed`` for the next chunks of ``chunks``, up to ``limit`` of them, ``FEED_BYTES`` or
        ``FEED_VERDICTS``, in one loop: their records, the same and in the same order as ``feed`` gives,
        appended to ``out`` (an exception, Ctrl-C included, loses none of the chunks taken); ``out`` None:
        no records are made, the verdicts are counted (the summary). Returns the chunks taken: 0 at the end.

        Each chunk, in one loop body: its bytes are framed by its line's framer, each frame goes to the
        engine's ``host_frame`` or ``device_frame`` and each junk run to its ``host_junk`` or
        ``device_junk``, with time passing to the chunk's time first, whatever its cut (a window that
        closed is closed, and a stalled device line is flushed). The usual chunk is one whole frame, with
        nothing pending on its line and no line error: the framer takes it at once
        (``Framer.take_frame``) and its arrival passes time in the engine (a frame's event ticks to its
        first byte's time; while a device frame is still arriving, ``_tick`` first: its start keeps its
        window open). Any other chunk the framer buffers and cuts (``_cut``), time passing first
        (``_tick``); the frames and junk runs it cuts carry the line errors of their bytes and the junk's
        reason (``_frame``, ``_junk``)."""
        if self._closed:
            raise RuntimeError("the analyzer is closed")
        framers, engine_frame, tick, judged = self._framers, self._engine_frame, self._tick, self._judged
        taken = size = 0
        try:
            for chunk in islice(chunks, limit):
                taken += 1
                t = chunk.t  # (one field a statement: four at once would build a tuple to unpack)
                direction = chunk.dir
                data = chunk.data
                error = chunk.error
                framer = framers.get(direction)
                if framer is None:
                    raise ValueError(f"chunk direction must be 'host' or 'device', got {direction!r}")
                if error and data:
                    self._errors[direction].append((framer.bytes_in, framer.bytes_in + len(data), error))
                if error or framer.take_frame(data) is None:  # (flagged bytes: their errors are noted)
                    if t is not None:  # time passes first, whatever the cut: a closed window is closed
                        tick(t)
                    self._cut(framer, direction, data, t)
                    size += len(data)
                    if size >= FEED_BYTES or len(judged) >= FEED_VERDICTS:  # memory stays bounded (a
                        break  # whole frame is at most MAX_FRAME bytes and a verdict or few)
                else:  # one whole frame (a device line's partial frame still arriving: its time first)
                    if t is not None and self._device_partial:
                        tick(t)
                    judged += engine_frame[direction](data, t, t)
        finally:
            self._emit(out)
        return taken

    def _cut(self, framer: Framer, direction: Direction, data: bytes, t: float | None) -> None:
        """Bytes that are not one whole frame: the framer buffers and cuts them; their events go to the
        engine. A device line's partial frame keeps the time it began (``_device_since``)."""
        pending_before = framer.pending
        events = framer.feed(data, t)
        if direction == DEVICE and data:
            self._device_last = t
            self._device_partial = bool(framer.pending)
            if not framer.pending:
                self._device_since = None
            elif not pending_before:
                self._device_since = t  # else keep the older time: never expire too early
        if events:
            self._judge(direction, events)

    def tick(self, now: float) -> list[Record]:
        """Time passes to ``now`` (unix seconds): missed answers and stalled device frames come out."""
        out: list[Record] = []
        try:
            self._tick(now)
        finally:
            self._emit(out)
        return out

    def _tick(self, now: float) -> None:
        framer = self._framers[DEVICE]
        flush, last = self.device_idle_flush, self._device_last
        if flush is not None and last is not None and now - last >= flush and framer.pending:
            self._device_since, self._device_partial = None, False
            self._judge(DEVICE, framer.flush())
        verdicts = self.conversation.tick(now, self._device_since)
        if verdicts:
            self._judged += verdicts

    def close(self, now: float | None = None) -> list[Record]:
        """End of data: partial frames come out as junk; a command still waiting is ``no-answer`` when
        its deadline passed by ``now`` (default: the last time seen) or when the data had no time."""
        out: list[Record] = []
        if self._closed:
            return out
        try:
            if now is not None:
                self._tick(now)
            for direction in (HOST, DEVICE):
                events = self._framers[direction].flush()
                if events and _inside_frame(events[-1]):  # the data ended inside this frame (issue 23)
                    self._judge(direction, events[:-1])
                    self._judge_cut(direction, events[-1])
                else:
                    self._judge(direction, events)
            self._device_since, self._device_partial = None, False
            self._judged += self.conversation.close(now)
        finally:
            self._emit(out)
        self.tally.unanswered += self.conversation.cut_short()
        self._closed = True
        return out

    @property
    def waiting(self) -> bool:
        """Does anything the host sent (a command, an error, a discarded line) wait for an answer?"""
        return self.conversation.waiting

    @property
    def expecting_answer(self) -> bool:
        """Does a well-formed command wait for its answer (see the engine)?"""
        return self.conversation.expecting_answer

    def bytes_in(self, direction: str) -> int:
        """Bytes fed so far on one line."""
        return self._framers[direction].bytes_in

    def summary(self) -> dict[str, object]:
        """The summary record (schema's last line) for everything so far."""
        return self.tally.summary()

    # ---- events to the engine, verdicts to the tally and to records ----

    def _judge(self, direction: str, events: list[FrameBytes | Junk]) -> None:
        """One line's events, in order, to the engine."""
        for event in events:
            if type(event) is FrameBytes:
                self._frame(direction, event.raw, event.offset, event.t_first, event.t_last)
            else:
                self._junk(direction, event)  # type: ignore[arg-type]

    def _frame(self, direction: str, raw: bytes, offset: int, t_first: float | None,
               t_last: float | None) -> None:
        """A frame to the engine: its verdicts kept, with the line errors of its bytes, until ``_emit``."""
        verdicts = self._engine_frame[direction](raw, t_first, t_last)
        if self._errors[direction]:
            self._note(verdicts, self._line_errors(direction, offset, len(raw)), "")
        self._judged += verdicts

    def _junk(self, direction: str, event: Junk) -> None:
        """A junk run to the engine: its verdicts kept, with the line errors of its bytes and the framer's
        reason, until ``_emit``."""
        c = self.conversation
        if direction == HOST:
            verdicts = c.host_junk(event.raw, event.t_first, event.t_last)
        else:  # a flushed partial line may be an answer
            verdicts = c.device_junk(event.raw, event.t_first, event.t_last, event.reason == "flushed")
        errors = self._line_errors(direction, event.offset, len(event.raw)) if self._errors[direction] else ()
        self._note(verdicts, errors, event.reason)
        self._judged += verdicts

    def _note(self, verdicts: list[Verdict], errors: tuple[str, ...], reason: str) -> None:
        """Keep the line errors and junk reason of the verdicts about to be judged (when there are any)."""
        if errors or reason:
            k = len(self._judged)
            self._notes.update(dict.fromkeys(range(k, k + len(verdicts)), (errors, reason)))

    def _emit(self, out: list[Record] | None) -> None:
        """The verdicts judged since the last call: counted, and made records into ``out`` (None: none)."""
        judged, notes = self._judged, self._notes
        if not judged:
            return
        self._judged, self._notes = [], {}
        self.tally.count(judged, sum(1 for k, (errors, _) in notes.items()  # a missed answer has no bytes
                                     if errors and judged[k].kind != "no-answer"))
        if out is None:
            return
        if not notes:
            out += map(to_record, judged)
        else:
            out += [to_record(v, *notes.get(k, _NO_NOTE)) for k, v in enumerate(judged)]

    def _judge_cut(self, direction: Direction, event: FrameBytes | Junk) -> None:
        """The data ended inside this frame: the engine's verdict that says so (no violation)."""
        verdicts = self.conversation.ended_inside_frame(direction, event.raw, event.t_first, event.t_last)
        if self._errors[direction]:
            self._note(verdicts, self._line_errors(direction, event.offset, len(event.raw)), "")
        self._judged += verdicts

    def _line_errors(self, direction: str, offset: int, length: int) -> tuple[str, ...]:
        ranges = self._errors[direction]
        while ranges and ranges[0][1] <= offset:
            ranges.pop(0)
        return tuple(e for start, end, e in ranges if start < offset + length and end > offset)


_NO_NOTE: Final[tuple[tuple[str, ...], str]] = ((), "")


def _inside_frame(event: FrameBytes | Junk) -> bool:
    """Is ``event`` (the last one flushed at the end of the data) a frame the data ended inside: a frame
    start with no LF yet, short of the longest line a frame may reach?"""
    return (isinstance(event, Junk) and event.reason in ("flushed", "no-frame-start")
            and event.raw[:1] in (spec.LEAD, spec.LETTER_O) and spec.LF not in event.raw)


# a frame record from its fields in order, as ``FrameRecord._make`` builds it but with no Python frame of its
# own (every field is given): ``_tuple_new(FrameRecord, fields)``
_tuple_new: Final = tuple.__new__


def to_record(v: Verdict, line_errors: tuple[str, ...] = (), reason: str = "") -> Record:
    """The record of one verdict (the docs/output.md schema)."""
    kind, sender, i, raw, header, frame, violations, reply_to, latency_s, t, t_last, waited_s = v
    if violations:
        details = tuple(x.message for x in violations)
        codes, sides, severities = v.codes, v.sides, v.severities
    else:  # the clean frame: the same empty tuples, without the generators
        details = codes = sides = severities = ()
    if kind == "host-frame" or kind == "device-frame":
        return _tuple_new(FrameRecord, (i, t, sender, raw, header, frame, codes, details, reply_to, latency_s,
                                        t_last, line_errors, sides,
                                        waited_s if kind == "host-frame" else None, severities))
    if kind == "no-answer":
        assert v.reply_to is not None
        return TimeoutRecord(command=v.reply_to, t=v.t, header=v.header, waited_s=v.waited_s,
                             details=details, sides=sides, severities=severities)
    assert v.i is not None
    direction: Direction = v.sender
    if kind == "cut":
        return JunkRecord(i=v.i, t=v.t, dir=direction, raw=v.raw, reason=CAPTURE_ENDED, violations=(),
                          line_errors=line_errors, reply_to=v.reply_to, latency_s=None)
    return JunkRecord(i=v.i, t=v.t, dir=direction, raw=v.raw, reason=reason or "flushed",
                      violations=codes, details=details, line_errors=line_errors, sides=sides,
                      severities=severities,
                      reply_to=v.reply_to, latency_s=v.latency_s)


def analyze(chunks: list[Chunk] | tuple[Chunk, ...], **options: object) -> list[Record]:
    """Every record of a whole capture (a convenience for tests and small files)."""
    analyzer = Analyzer(**options)  # type: ignore[arg-type]
    out: list[Record] = []
    for chunk in chunks:
        out += analyzer.feed(chunk)
    out += analyzer.close()
    return out
