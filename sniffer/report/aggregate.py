"""The session report's data: a streaming aggregator fed the analyzer's records one by one.

How this works. ``SessionAggregator.add(record)`` takes each ``FrameRecord``, ``JunkRecord`` and
``TimeoutRecord`` as the sniffer or the decoder makes it; it never judges the conversation (the
verdicts are the records' own; whose fault each is comes from ``spec.VIOLATION_TABLE[code].side``,
docs/protocol.md "Violation codes"). Memory is bounded whatever the capture's length:
- the first ``Limits.records`` records are kept whole (bytes, fields, details) for the timeline, and
  after them up to ``Limits.violation_records`` more records that carry a violation;
- every record also lands in ``TimeBins`` (per-second counts by side and by violation code; the bin
  width doubles when there are more than ``Limits.bins`` bins), which draws the whole capture;
- answer latency: a histogram per command with two significant digits of milliseconds (``LogHistogram``:
  at most 90 buckets a decade) and latency over time (points up to a cap, then per-bin mean and max);
- axis position, homing and alarm marks: points up to a cap, then every other point is dropped (the
  shape stays);
- the alarm history: the first ``Limits.alarms`` alarms, the rest counted.
What the conversation established is the engine's, never a model of the report's own: the aggregate asks
the engine that judged the records (``engine``, a ``Conversation``) for the latched alarm
(``knowledge.latched``: an alarm's span is the engine's latch, from the answer that latched it to the one
that cleared it) and a move's estimated time and start (``move_time`` and ``knowledge.position`` when the
command was judged: a move is drawn only from a start the engine knew). The positions drawn are those the
0RC, 0MP and 0MV answers give (a record's field, as its latency is; none for FFFFFF).
``feed(analyzer, chunk)`` passes a chunk through the analyzer a line at a time and asks the engine after
each line, so what it says belongs to that line's records (the records themselves do not depend on the
chunking); ``add(record)`` (the live sniffer, a chunk at a time) asks it after the record's chunk.
Without an engine, alarm spans and moves are left out.
Captures without time (raw files and the like) are drawn against the record number instead of time.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from xac1_proto import frames, spec
from xac1_proto.chunk import Chunk
from xac1_proto.conversation import UNKNOWN, Conversation, Fact

from ..records import FrameRecord, JunkRecord, Record, Tally, TimeoutRecord
from ..view import show_raw

if TYPE_CHECKING:
    from ..analyzer import Analyzer

_AXIS_ANSWERS = frozenset({"0RC", *spec.MOVE_HEADERS})  # answers after which the position is drawn


@dataclass(frozen=True)
class Limits:
    """How much the report keeps in full; beyond this it aggregates."""

    records: int = 3000  # records kept whole for the timeline
    violation_records: int = 1500  # further records with a violation kept whole
    bins: int = 2000  # time bins before their width doubles
    points: int = 5000  # latency points and axis points before thinning
    alarms: int = 500  # alarm history rows
    waiting: int = 4096  # commands remembered while they wait for their answer


class LogHistogram:
    """Counts of values rounded to two significant digits (bounded: at most 90 keys a decade)."""

    def __init__(self) -> None:
        self.counts: Counter[float] = Counter()
        self.n = 0

    @staticmethod
    def step(value: float) -> float:
        """The width of the bucket holding ``value``."""
        return 10.0 ** (math.floor(math.log10(value)) - 1) if value > 0 else 1e-3

    @classmethod
    def bucket(cls, value: float) -> float:
        """The lower edge of the bucket holding ``value``."""
        if value <= 0:
            return 0.0
        step = cls.step(value)
        return round(math.floor(value / step + 1e-9) * step, 12)

    def add(self, value: float) -> None:
        self.n += 1
        self.counts[self.bucket(value)] += 1

    def items(self) -> list[tuple[float, int]]:
        return sorted(self.counts.items())


class TimeBins:
    """Per-bin statistics (count, sum, max) under string keys; the bin width doubles past ``limit``."""

    def __init__(self, limit: int, width: float = 1.0) -> None:
        self.limit = limit
        self.width = width
        self.origin: float | None = None
        self.bins: dict[int, dict[str, list[float]]] = {}

    def add(self, x: float, key: str, value: float = 0.0) -> None:
        if self.origin is None:
            self.origin = math.floor(x)
        index = int((x - self.origin) // self.width)
        keys = self.bins.get(index)
        if keys is None:
            keys = self.bins[index] = {}
        stats = keys.get(key)
        if stats is None:
            keys[key] = [1, value, value]
        else:
            stats[0] += 1
            stats[1] += value
            if value > stats[2]:
                stats[2] = value
        while len(self.bins) > self.limit:
            self._coarsen()

    def _coarsen(self) -> None:
        merged: dict[int, dict[str, list[float]]] = {}
        for index, keys in self.bins.items():
            into = merged.setdefault(index // 2, {})
            for key, (n, total, top) in keys.items():
                if key in into:
                    have = into[key]
                    into[key] = [have[0] + n, have[1] + total, max(have[2], top)]
                else:
                    into[key] = [n, total, top]
        self.bins = merged
        self.width *= 2

    def start(self, index: int) -> float:
        return (self.origin or 0.0) + index * self.width

    def keys(self) -> list[str]:
        return sorted({k for keys in self.bins.values() for k in keys})

    def series(self, key: str) -> tuple[list[float], list[float], list[float], list[float]]:
        """Bin starts, counts, means and maxima of ``key`` (bins without it are left out)."""
        xs, counts, means, tops = [], [], [], []
        for index in sorted(self.bins):
            stats = self.bins[index].get(key)
            if stats:
                xs.append(self.start(index))
                counts.append(stats[0])
                means.append(stats[1] / stats[0])
                tops.append(stats[2])
        return xs, counts, means, tops


class Thinned:
    """A list of points that drops every other point when it grows past ``limit``."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.items: list[Any] = []
        self.stride = 1
        self._seen = 0

    def add(self, item: Any) -> None:
        self._seen += 1
        if (self._seen - 1) % self.stride:
            return
        self.items.append(item)
        if len(self.items) > self.limit:
            self.items = self.items[::2]
            self.stride *= 2

    @property
    def thinned(self) -> bool:
        return self.stride > 1


@dataclass
class Alarm:
    """One alarm as the answers show it: raised, how the host reacted, when it ended."""

    x: float  # time (or record number) of the alarm answer
    code: int
    meaning: str
    answered: str | None  # header of the command it answered
    record: int  # the alarm answer's i
    repeats: int = 0  # further alarm answers of the same code while latched
    reaction: str | None = None  # the host's next frame: what it was
    reaction_after: float | None = None  # seconds from the alarm answer to that frame
    ended: str | None = None  # what ended it (a reset answer, a normal answer)
    latched_for: float | None = None  # seconds from the alarm answer to the end


@dataclass
class _Command:
    x: float
    t: float | None
    header: str | None
    frame: frames.Frame | None
    kept: int | None  # index in ``records`` when kept whole
    move: tuple[float, int | None] | None = None  # a move: the engine's estimated time, its start position


@dataclass
class SessionAggregator:
    """Feed records with ``add``; read the aggregates after ``finish``. See the module docstring."""

    limits: Limits = field(default_factory=Limits)
    sources: list[tuple[str, str]] = field(default_factory=list)  # (file or port, format)
    no_answer_timeout: float = spec.NO_ANSWER_TIMEOUT_S
    engine: Conversation | None = None  # the engine that judged the records: asked what it established

    def __post_init__(self) -> None:
        self.summary: dict[str, Any] | None = None
        self.records: list[dict[str, Any]] = []  # kept whole, in order
        self.dropped_records = 0  # records not kept whole
        self.total_records = 0
        self.timed = True  # every record had a time so far
        self.t_first: float | None = None
        self.t_last: float | None = None
        self.marks: list[dict[str, Any]] = []  # one per violation code on a kept record
        self.mark_count = 0  # violation codes on all records
        self.sides: Counter[tuple[str, str]] = Counter()  # (code, side) -> records
        self.exchanges: list[dict[str, Any]] = []  # command -> answer, both ends kept
        self.exchange_count = 0
        self.unanswered: list[dict[str, Any]] = []  # command -> its no-answer deadline, both kept
        self.bins = TimeBins(self.limits.bins)
        self.latency_hist: dict[str, LogHistogram] = {}
        self.latency_points = Thinned(self.limits.points)  # (x, ms, header, kept)
        self.latency_bins = TimeBins(self.limits.bins)
        self.positions = Thinned(self.limits.points)  # (x, pos, header, kept)
        self.moves = Thinned(self.limits.points)  # (x_cmd, x_est_end, x_answer, start, end, header)
        self.homings = Thinned(self.limits.points)  # x
        self.alarm_marks = Thinned(self.limits.points)  # (x, code, kept)
        self.alarms: list[Alarm] = []
        self.alarm_count = 0
        self._waiting: dict[int, _Command] = {}
        self._latched: Fact[int] = Fact()  # the engine's latch when last asked
        self._open_alarm: Alarm | None = None
        self._await_reaction: Alarm | None = None
        self.finished = False

    # ---- input ----

    def feed(self, analyzer: Analyzer, chunk: Chunk) -> list[Record]:
        """``chunk`` through ``analyzer`` a line at a time, each line's records added with its engine asked
        right after that line (module docstring); returns the records, as ``analyzer.feed(chunk)`` would."""
        self.engine = analyzer.conversation
        lf = chunk.data.find(b"\n")
        if lf < 0 or lf == len(chunk.data) - 1:  # the usual chunk: one line, or a part of one
            return self._line_records(analyzer.feed(chunk))
        out: list[Record] = []
        for line in _lines(chunk):
            out += self._line_records(analyzer.feed(line))
        return out

    def _line_records(self, records: list[Record]) -> list[Record]:
        """The records of one line, the engine asked at the last (it stands right after it)."""
        last = len(records) - 1
        for k, record in enumerate(records):
            self._add(record, ask=k == last)
        return records

    def add(self, record: Record) -> None:
        """One record as the analyzer made it (the engine, if any, asked as it stands now)."""
        self._add(record, ask=True)

    def _add(self, record: Record, ask: bool) -> None:
        """One record; ``ask``: the engine stands right after it (what it established is the record's)."""
        engine = self.engine if ask else None
        self.total_records += 1
        if record.t is None:
            self.timed = False
        else:
            self.t_first = record.t if self.t_first is None else min(self.t_first, record.t)
            self.t_last = record.t if self.t_last is None else max(self.t_last, record.t)
        x = self._x(record)
        kept = self._keep(record, x)
        if record.violations:
            self._marks(record, x, kept)
        if isinstance(record, TimeoutRecord):
            command = self._waiting.pop(record.command, None)
            if command is not None and command.kept is not None and kept is not None:
                self.unanswered.append({"from": command.x, "to": x, "header": command.header})
            answered = None
        else:
            answered = self._line(record, x, kept, engine)
        if engine is not None:
            self._latch(engine.knowledge.latched, record, x, answered)

    def _marks(self, record: Record, x: float, kept: int | None) -> None:
        """A record's violations: counted by code and side (``spec.VIOLATION_TABLE[code].side``), binned,
        and marked where the record is kept whole."""
        for code in record.violations:
            side = spec.VIOLATION_TABLE[code].side(record.dir)
            self.sides[(code, side)] += 1
            self.mark_count += 1
            self.bins.add(x, "violation:" + code)
            if kept is not None:
                self.marks.append({"x": x, "side": side, "code": code, "record": kept})

    def _line(self, record: FrameRecord | JunkRecord, x: float, kept: int | None,
              engine: Conversation | None) -> str | None:
        """A frame or junk run: counted by direction, commands remembered until answered; the header of
        the command an answer replied to."""
        self.bins.add(x, f"{record.dir}:{record.type}")
        if isinstance(record, FrameRecord):
            if record.dir == "host":
                self._host_frame(record, x, kept, engine)
                return None
            return self._device_frame(record, x, kept, engine)
        if record.dir == "host" and record.raw.endswith(spec.FRAME_END):
            # a junk line: the device owes it an alarm answer (docs/protocol.md "Behaviour the vendor
            # text states"), so the rulebook may say no-answer for it
            self._waiting[record.i] = _Command(x, record.t, None, None, kept)
            if len(self._waiting) > self.limits.waiting:
                del self._waiting[next(iter(self._waiting))]
        return None

    def _x(self, record: Record) -> float:
        """Where a record goes on the time axis: its time, or its number in a capture without time."""
        if record.t is not None:
            return record.t
        if isinstance(record, TimeoutRecord):
            return record.command + 0.5
        return float(record.i)

    def _keep(self, record: Record, x: float) -> int | None:
        """Keep the record whole when the limits allow; its index in ``records``."""
        room = len(self.records) < self.limits.records
        extra = bool(record.violations) and \
            len(self.records) < self.limits.records + self.limits.violation_records
        if not (room or extra):
            self.dropped_records += 1
            return None
        self.records.append(_describe(record, x))
        return len(self.records) - 1

    def _host_frame(self, record: FrameRecord, x: float, kept: int | None,
                    engine: Conversation | None) -> None:
        move = None
        if engine is not None and record.header in spec.MOVE_HEADERS and record.frame is not None:
            start = engine.knowledge.position
            move = (engine.move_time(record.frame), start.value if start.judged else None)
        self._waiting[record.i] = _Command(x, record.t, record.header, record.frame, kept, move)
        if len(self._waiting) > self.limits.waiting:
            del self._waiting[next(iter(self._waiting))]
        alarm = self._await_reaction
        if alarm is not None:
            alarm.reaction = record.header or "an unknown frame"
            if record.t is not None and self.timed:
                alarm.reaction_after = record.t - alarm.x
            self._await_reaction = None

    def _device_frame(self, record: FrameRecord, x: float, kept: int | None,
                      engine: Conversation | None) -> str | None:
        """An answer: its exchange, its alarm or the axis position it gives; the header of the command it
        answered."""
        command = self._waiting.pop(record.reply_to, None) if record.reply_to is not None else None
        if command is not None:
            self._exchange(command, record, x, kept)
        frame = record.frame
        if isinstance(frame, frames.AlarmAnswer):
            self._alarm_answer(frame, x, kept)
        elif frame is not None and record.header in _AXIS_ANSWERS:
            self._axis_answer(record, frame, x, command, kept)
        return command.header if command is not None else None

    def _exchange(self, command: _Command, record: FrameRecord, x: float, kept: int | None) -> None:
        """A command answered: the exchange (drawn when both ends are kept) and its latency."""
        self.exchange_count += 1
        if command.kept is not None and kept is not None:
            self.exchanges.append({"from": command.x, "to": x, "header": command.header,
                                   "command": command.kept, "answer": kept})
        if record.latency_s is not None:
            header = command.header or "?"
            ms = record.latency_s * 1000.0
            self.latency_hist.setdefault(header, LogHistogram()).add(ms)
            self.latency_points.add((x, ms, header, kept))
            self.latency_bins.add(x, header, ms)

    def _alarm_answer(self, frame: frames.AlarmAnswer, x: float, kept: int | None) -> None:
        """An alarm answer: its mark; the latched alarm answered again is a repeat, and the host's next
        frame its reaction."""
        self.alarm_marks.add((x, frame.code, kept))
        alarm = self._open_alarm
        if alarm is not None and alarm.code == frame.code:
            alarm.repeats += 1
            self._await_reaction = alarm if alarm.reaction is None else None

    def _latch(self, latched: Fact[int], record: Record, x: float, answered: str | None) -> None:
        """The engine's latch after ``record`` (an answer to an ``answered`` command): an alarm span opens
        where it latches a code and ends where it clears, changes or becomes unknown."""
        before, self._latched = self._latched, latched
        if latched.value == before.value:
            return
        alarm = self._open_alarm
        if alarm is not None:
            alarm.ended = _why_ended(record, latched)
            alarm.latched_for = self._span(alarm, x)
            self._open_alarm = self._await_reaction = None
        if latched.value is None or not isinstance(record, FrameRecord):
            return
        self.alarm_count += 1
        alarm = Alarm(x, latched.value, spec.alarm_meaning(latched.value), answered, record.i)
        if len(self.alarms) < self.limits.alarms:
            self.alarms.append(alarm)
        self._open_alarm = self._await_reaction = alarm

    def _span(self, alarm: Alarm, x: float) -> float | None:
        return x - alarm.x if self.timed else None

    def _axis_answer(self, record: FrameRecord, frame: frames.Frame, x: float, command: _Command | None,
                     kept: int | None) -> None:
        """0RC, 0MP, 0MV answers: the position the answer gives (none for FFFFFF, "not homed"), the homing
        a 0MP0 answer reports, and the move from the start the engine knew over its estimate."""
        pos = getattr(frame, "pos", None)
        if pos is None or pos == spec.UNKNOWN_POSITION:
            return
        self.positions.add((x, pos, record.header, kept))
        if isinstance(frame, frames.MovePointAnswer) and frame.n == 0:
            self.homings.add(x)
        if command is not None and command.move is not None and command.move[1] is not None:
            estimate, start = command.move
            est_end = command.x + estimate if self.timed else x
            self.moves.add((command.x, min(est_end, x), x, start, pos, record.header))

    # ---- output ----

    def finish(self, summary: dict[str, Any] | None = None) -> None:
        """No more records; ``summary`` is the analyzer's own (the counts are its, never counted twice;
        none: nothing was analyzed)."""
        self.summary = summary if summary is not None else Tally().summary()
        self.finished = True

    @property
    def empty(self) -> bool:
        return self.total_records == 0

    @property
    def aggregated(self) -> bool:
        return self.dropped_records > 0

    def verdicts(self) -> list[dict[str, Any]]:
        """Violation counts by code and side, in the report order of docs/protocol.md."""
        order = list(spec.VIOLATION_TABLE)
        rows = []
        for (code, side), count in sorted(self.sides.items(), key=lambda kv: (order.index(kv[0][0])
                                          if kv[0][0] in order else len(order), kv[0][1])):
            vspec = spec.VIOLATION_TABLE.get(code)  # type: ignore[call-overload]
            rows.append({"code": code, "side": side, "count": count,
                         "severity": vspec.severity if vspec else "error",
                         "meaning": vspec.meaning if vspec else "",
                         "section": vspec.section if vspec else ""})
        return rows


def _lines(chunk: Chunk) -> Iterator[Chunk]:
    """``chunk`` cut after each LF: pieces with its time, direction and line error."""
    data, start = chunk.data, 0
    end = data.find(b"\n") + 1
    while end:
        yield Chunk(chunk.t, chunk.dir, data[start:end], chunk.error)
        start, end = end, data.find(b"\n", end) + 1
    if start < len(data):
        yield Chunk(chunk.t, chunk.dir, data[start:], chunk.error)


def _why_ended(record: Record, latched: Fact[int]) -> str:
    """What ended an alarm's span: the record after which the engine's latch cleared, changed or became
    unknown."""
    if latched.status == UNKNOWN:
        return "unknown from here (the engine lost track: an answer missing or garbled)"
    frame = record.frame if isinstance(record, FrameRecord) else None
    if isinstance(frame, frames.AlarmAnswer):
        return f"followed by alarm {frame.code:02X}"
    if isinstance(record, FrameRecord) and record.header == spec.RESET_HEADER:
        return "reset (0%C answered)"
    return f"a {record.header or 'unknown'} answer" if isinstance(record, FrameRecord) else record.type


def _describe(record: Record, x: float) -> dict[str, Any]:
    """A record as the page shows it when its mark is clicked."""
    out: dict[str, Any] = {"type": record.type, "x": x, "t": record.t, "dir": record.dir,
                           "violations": list(record.violations), "details": list(record.details)}
    if isinstance(record, TimeoutRecord):
        out.update(i=None, command=record.command, header=record.header,
                   waited_ms=None if record.waited_s is None else round(record.waited_s * 1000, 3))
        return out
    out.update(i=record.i, bytes=show_raw(record.raw), hex=record.raw.hex(" "),
               line_errors=list(record.line_errors))
    if isinstance(record, JunkRecord):
        out.update(header=None, reason=record.reason)
    else:
        out.update(header=record.header, fields=record.fields, reply_to=record.reply_to,
                   latency_ms=record.latency_ms)
        if isinstance(record.frame, frames.AlarmAnswer):
            out["alarm"] = spec.alarm_meaning(record.frame.code)
    return out
