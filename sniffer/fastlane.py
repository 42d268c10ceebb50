"""The analyzer's fast lane: a memo of clean exchanges, filled by the engine, never a second rulebook.

Most traffic is the same few exchanges over and over: a host chunk that is exactly one well-formed
command, then a device chunk that is exactly its well-formed answer, in time. The engine
(``xac1_proto.conversation.Conversation``) judges a command and its answer from three things only: the
bytes, its own state and what it knows of the device (``knowledge``). So when, from the *quiet* state
(nothing waiting, no move, no unreset alarm, no partial line on either framer, no line error pending),
the full path judged command bytes C and answer bytes A with no violation at all, the next (C, A) from
the quiet state with the same knowledge gets the same verdicts again, but for the per-event numbers and
times (``i``, ``t``, ``t_last``, ``reply_to``, ``latency_s``), and changes the knowledge in the same way
(a *transition*: 0RS learns the OUT ports that 0WS establishes again). This module keeps those verdicts,
as records, and the change in a memo and replays them:

- A host chunk that is a memoised C, from the quiet state and with the knowledge the memo was filled
  with, gets its record at once (the full path would give exactly that one record: a tick in the quiet
  state expires nothing). The chunk is *held*: neither the framers nor the engine have seen it yet.
- If the very next call is the feed of a device chunk that is a memoised answer to C, with no line
  error, in time (``t_host <= t_device <= t_host + window``, the engine's deadline, or both untimed),
  its record comes from the memo and the bookkeeping the full path would have done is done: event
  numbers, the engine's last time, the framers' byte counts, the device's last time, the tally, and
  the knowledge's change (``_Change``: the facts and points that differ), if the exchange made one.
- Anything else (another chunk, a late or different answer, ``tick``, ``close``, a question such as
  ``waiting``) first *replays* the held chunk through the full path, its record not given or counted
  again, and then goes on as without the fast lane. Every call returns the records it returns without
  the fast lane: holding changes when the engine sees a chunk, never what comes out or when.
- ``Analyzer.feed_many`` (decode's path) takes the chunks after a hit from their iterator in one loop
  (``stretch``): each exchange that is again a memoised command and its memoised answer in time gets its
  two records (or none, for an output that shows only the summary), its counts kept aside, and the
  bookkeeping of all of them is done once when the stretch ends, however it ends.

Validity: a memo belongs to one value of the knowledge; memos are kept by that value (a snapshot: the
facts, and the points copied), so traffic that goes back and forth between a few values (0RS learns the
OUT ports that 0WS then establishes) keeps its memos. Any full-path call may change the knowledge
(``dirty``): the next host chunk takes a snapshot; when the value changed, an empty memo is current
until an exchange is memoised, and then the kept memo of that value, if any, takes its place. An
exchange fills the memo of the knowledge it went in with only when both its records are clean and the
engine is quiet before and after it; one that changed the knowledge is kept with its change, and its
replay makes the memo of the knowledge after it current (kept by value: ``_switch``). Clean exchanges
that change the knowledge many times in a row with no hit between (new point values written one after
another) make the lane step aside for a while (``CHANGES``, ``BACKOFF``). Moves (0MP, 0MV) are
never memoised: their answer window depends on the knowledge and they change it. The engine must be
driven only through the analyzer (nothing here sees ``power_on`` or ``stop_input`` called on it
directly).

The reads memo (``sniffer.readset``): the full path of an observed exchange runs with the knowledge
traced, and a clean exchange is also kept by the values of the facts and points it read, with the values
it left in those it wrote. When the memo of the whole knowledge has no entry for a command, the reads
memo may answer it (held, as above) if it keeps the command's bytes with reads the knowledge holds, and
an answer to it whose reads hold too; its answer's writes are then written, and when the memo of the
knowledge holds exchanges already, or the knowledge has kept its value for ``SETTLED`` such exchanges,
the exchange is memoised by the whole knowledge as a full-path one would be (``_learn``), so that it
repeats in stretches. This is
what serves traffic whose anomalies keep changing the knowledge (a point forgotten after a garbled
answer): most exchanges never read what changed.

Not covered (they take the full path): ticks or other calls between a held command and its answer (the
live sniffer ticks on every poll), chunks with a line error or split frames, a command timed and its
answer not (or the reverse), times that are not finite or run backwards. Equivalence with the full path:
tests/test_fastlane_equivalence.py (``feed``), tests/test_feed_many_equivalence.py (``feed_many``) and
tests/test_readset.py (the reads memo).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from operator import attrgetter
from typing import Any, Final, Protocol

from xac1_proto import Framer, spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.conversation import Conversation, Knowledge

from . import readset
from .records import _MAX_LATENCY_S as MAX_LATENCY_S
from .records import _MAX_WAITING as MAX_WAITING
from .records import CleanExchange, FrameRecord, LatencyStats, Record, Tally

# Bounds (memory stays flat whatever the traffic: about 2 KB a memoised command): memos kept, one per
# value of the knowledge, the least recently used dropped first; memoised commands in all of them; answers
# memoised for one command.
MEMOS: Final = 128
COMMANDS: Final = 4096
ANSWERS: Final = 8
# Traffic whose clean exchanges each change the knowledge (new point values written, one after another)
# is never memoised: after CHANGES such exchanges with no hit or memoised exchange between, the next
# BACKOFF chunks take the full path without the lane's own checks, then it looks again; each time in a
# row it finds nothing, it steps aside twice as long (up to BACKOFF_MAX).
CHANGES: Final = 8
BACKOFF: Final = 64
BACKOFF_MAX: Final = 4096
# An exchange from the reads memo is memoised by the whole knowledge too (so that it repeats in stretches)
# when the memo of the knowledge it went in with holds exchanges already, or once the knowledge has stayed
# a value without one for SETTLED exchanges: while anomalies keep changing the knowledge to new values
# (every tenth exchange), an exchange seldom comes back before the value it was memoised under is gone.
SETTLED: Final = 16
_KNOWLEDGE_FIELDS: Final = tuple(f.name for f in dataclasses.fields(Knowledge))
_FACT_NAMES: Final = tuple(n for n in _KNOWLEDGE_FIELDS if n != "points")
_FACTS: Final = attrgetter(*_FACT_NAMES)
_MISSING: Final = object()
# the snapshot copies ``points``, the one mutable field; every other field is immutable (a new mutable
# field must be copied too: this stops the import until it is)
assert all(str(f.type).startswith("Fact[") or f.type in ("int", int) for f in dataclasses.fields(Knowledge)
           if f.name != "points")
_new: Final = object.__new__

# ``_clone`` gives a record a copy of its template's __dict__ (the setter of the ``__dict__`` slot: the
# frozen class refuses ``record.__dict__ = ...``): a frozen dataclass's __init__ sets each of its 14 fields
# with object.__setattr__, 5x slower, and filling the new record's own dict with ``update`` a quarter
# slower than the copy (measured). That needs plain instance dicts and no __post_init__.
assert "__slots__" not in FrameRecord.__dict__ and not hasattr(FrameRecord, "__post_init__")
_set_dict: Final = FrameRecord.__dict__["__dict__"].__set__


def _clone(template: FrameRecord, i: int, t: float | None, reply_to: int | None,
           latency_s: float | None) -> FrameRecord:
    """``dataclasses.replace(template, i=i, t=t, t_last=t, reply_to=reply_to, latency_s=latency_s)``."""
    fields = template.__dict__.copy()
    fields["i"] = i
    fields["t"] = fields["t_last"] = t
    fields["reply_to"] = reply_to
    fields["latency_s"] = latency_s
    record: FrameRecord = _new(FrameRecord)
    _set_dict(record, fields)
    return record


_LATE: Final = object()


def _latency(t_host: float | None, t: float | None, window: float) -> float | None | object:
    """The latency of a memoised answer at ``t`` to its command at ``t_host`` (None: both untimed), or
    ``_LATE`` when it is not in time as the full path would judge it: one timed and the other not, or
    outside the window (the engine's deadline is ``t_host + window``, that very sum)."""
    if t_host is None:
        return _LATE if t is not None else None
    if t is None or not t_host <= t <= t_host + window:
        return _LATE
    return t - t_host


def knowledge_snapshot(k: Knowledge) -> tuple[Any, ...]:
    """The knowledge's value, frozen: every field but ``points`` (facts are immutable), then ``points``
    copied (the one mutable field)."""
    return _FACTS(k), dict(k.points)


def _key(snapshot: tuple[Any, ...]) -> tuple[Any, ...]:
    """A knowledge snapshot as a dict key (facts are frozen dataclasses: hashable)."""
    facts, points = snapshot
    return facts, frozenset(points.items())


class _Answer:
    """A memoised clean answer: its record (a template) and, during a stretch (``FastLane.stretch``), the
    exchanges it completed that the tally has not counted yet (``n``; ``us``: their latencies, whole
    microseconds, as ``LatencyStats.add`` counts them)."""

    __slots__ = ("record", "change", "n", "us")

    def __init__(self, record: FrameRecord, change: _Change | None = None) -> None:
        self.record = record
        self.change = change
        self.n = 0
        self.us: list[int] = []


class _Change:
    """What a memoised exchange does to the knowledge (it came out as ``after``, went in as the knowledge
    of the memo holding it): the facts and points that differ, to set; the points to drop; ``after``'s
    value and key, to select its memo."""

    __slots__ = ("facts", "points", "dropped", "after", "key")

    def __init__(self, before: tuple[Any, ...], after: tuple[Any, ...]) -> None:
        (facts0, points0), (facts1, points1) = before, after
        self.facts = tuple((name, v) for name, v0, v in zip(_FACT_NAMES, facts0, facts1, strict=True)
                           if v != v0 or type(v) is not type(v0))
        self.points = {n: fact for n, fact in points1.items() if points0.get(n, _MISSING) != fact}
        self.dropped = tuple(n for n in points0 if n not in points1)
        self.after = after
        self.key: tuple[Any, ...] | None = None  # ``after`` as a memo key, made when first replayed

    def apply(self, k: Knowledge) -> None:
        """Make ``k`` (the memo's knowledge) what the exchange left."""
        for name, value in self.facts:
            setattr(k, name, value)
        points = k.points
        points.update(self.points)
        for n in self.dropped:
            del points[n]


class _Entry:
    """What the full path gave for a memoised command: its record (a template), the answer window it
    was given, and the clean answers seen to it, by the answer's bytes."""

    __slots__ = ("host", "window", "answers")

    def __init__(self, host: FrameRecord, window: float) -> None:
        self.host = host
        self.window = window
        self.answers: dict[bytes, _Answer] = {}


# a host chunk answered from a memo, not yet fed: (chunk, its entry in the memo or the reads memo, its i)
Held = tuple[Chunk, "_Entry | readset.Command", int]
# a clean command the full path judged: (chunk, its record, the knowledge before it, what it read and wrote
# of it); its answer may fill the memos
Observed = tuple[Chunk, FrameRecord, tuple[Any, ...], readset.Trace]


class Analyzer(Protocol):
    """What the fast lane reads and advances of ``sniffer.analyzer.Analyzer`` (named here, not imported:
    the analyzer imports this module)."""

    conversation: Conversation
    tally: Tally
    _framers: dict[str, Framer]
    _errors: dict[str, list[tuple[int, int, str]]]
    _device_since: float | None
    _device_last: float | None

    def feed(self, chunk: Chunk) -> list[Record]: ...

    def _feed(self, chunk: Chunk) -> list[Record]: ...


class _Uncounted(Tally):
    """The tally of a replayed host chunk: its record was counted when it was given."""

    def add(self, record: Record) -> None:
        pass


class FastLane:
    """The memo of clean exchanges for one ``Analyzer`` (see the module docstring). ``hits``: exchanges
    answered from the memo; ``replays``: held commands replayed through the full path.

    It reads and advances the analyzer's and the engine's private state (it stands in for their full
    path); every attribute it touches is one the full path touches for the same two chunks."""

    def __init__(self, analyzer: Analyzer) -> None:
        self.analyzer = analyzer
        self.hits = 0
        self.replays = 0
        self._conversation = analyzer.conversation
        self._host = analyzer._framers[HOST]
        self._device = analyzer._framers[DEVICE]
        self._errors = analyzer._errors
        self._memo: dict[bytes, _Entry] = {}  # the memo of the knowledge ``_snap``
        self._snap: tuple[Any, ...] | None = None
        self._registered = False  # is ``_memo`` kept in ``_memos`` (as ``_key``; else it is empty)?
        self._key: tuple[Any, ...] | None = None
        # the memo current before the last change of the knowledge: (snapshot, memo, key), if kept
        self._previous: tuple[Any, dict[bytes, _Entry], Any] | None = None
        self._memos: dict[tuple[Any, ...], dict[bytes, _Entry]] = {}  # by the knowledge (hashable), LRU
        self._commands = 0  # memoised commands in all memos
        self._dirty = True  # the full path ran since ``_snap`` was taken: the knowledge may differ
        self._held: Held | None = None
        self._observed: Observed | None = None
        self._changes = 0  # clean exchanges that changed the knowledge, none memoised or hit between
        # chunks the analyzer passes straight to the full path (``BACKOFF``): the lane steps aside; nothing
        # is held or observed meanwhile, and the knowledge is taken as changed when it steps back
        self.skip = 0
        self._backoff = BACKOFF  # the next time the lane steps aside, for this many chunks
        self._settled = 0  # exchanges since the knowledge last became a value without a kept memo
        self._ticked = 0  # commands held or observed that a tick cut off, none answered from the memo between
        self._uncounted = _Uncounted()
        self.reads = readset.ReadsMemo()  # the second memo: exchanges kept by what they read
        self._tracer = readset.Tracer()

    # ---- entry points (the analyzer's) ----

    def feed(self, chunk: Chunk) -> list[Record]:
        """``Analyzer.feed``, the checks of the chunk done: the records the full path would give."""
        held = self._held
        if held is not None:
            self._held = None
            out = self._answer(held, chunk)
            if out is not None:
                return out
            self._replay(held)
        a = self.analyzer
        observed = self._observed
        if observed is not None:
            self._observed = None
            with self._tracer.watching(self._conversation.knowledge) as trace:
                out = a._feed(chunk)
            self._learn(observed, chunk, out, trace)
            return out
        c = self._conversation
        t = chunk.t
        # the quiet state (framers' buffers read directly: ``pending`` is their length)
        if (chunk.dir == HOST and chunk.error is None and not c._queue and c._motion is None
                and not c._unreset_alarm and not self._host._buf and not self._device._buf
                and a._device_since is None and not self._errors[HOST] and not self._errors[DEVICE]
                and type(chunk.data) is bytes and (t is None or t - t == 0.0)):  # finite or no time
            return self._command(chunk)
        self._dirty = True
        return a._feed(chunk)

    def settle(self) -> None:
        """Before any call but ``feed`` (tick, close, questions): the held chunk goes the full path."""
        held = self._held
        if held is not None:
            self._held = None
            self._replay(held)

    def full_path(self) -> None:
        """Before a ``tick`` or ``close``: settle, and no exchange is being observed across it. Ticks that
        keep coming between commands and their answers (the live sniffer polls the taps, and an answer
        often comes a poll after its command) make the lane step aside, as exchanges that keep changing
        the knowledge do: holding only to replay, or watching only to forget, costs more than it saves."""
        held = self._held
        if held is not None:
            self._held = None
            self._replay(held, observe=False)  # the observation would end here anyway
        if held is not None or self._observed is not None:
            self._ticked += 1
            if self._ticked >= CHANGES:
                self._ticked, self.skip = 0, self._backoff
                self._backoff = min(2 * self._backoff, BACKOFF_MAX)
        self._observed = None
        self._dirty = True

    def can_stretch(self) -> bool:
        """Right after a hit (the state quiet, the memo current): may ``stretch`` go on inline?"""
        return (self._held is None and self._observed is None and not self.skip and not self._dirty
                and len(self.analyzer.tally._headers) < MAX_WAITING)

    def stretch(self, chunks: Iterator[Chunk], out: list[Record | CleanExchange], clean: bool, limit: int,
                lean: bool = False) -> int:
        """After a hit (``can_stretch``): take the following chunks while they are exchanges that hit too,
        up to ``limit`` chunks, giving each its two records (into ``out``; ``clean`` False: not made, only
        counted: they are clean frame records; ``lean``: a ``CleanExchange`` instead) and doing the
        bookkeeping ``feed`` would do for each, once at the end. The first chunks that are not such an
        exchange go to ``feed``. Returns the chunks taken.

        An exchange here is what ``feed`` followed by ``feed`` would answer from the memo: after a hit the
        state is quiet and the knowledge unchanged, so each hit leaves the next exchange the same checks:
        a host chunk (no line error, bytes, a finite time or none) that is a memoised command, then a
        device chunk (no line error, bytes) that is a memoised answer to it, in time."""
        a = self.analyzer
        c = self._conversation
        memo = self._memo
        i = c._next_i
        last = c._last_t
        device_last = a._device_last
        touched: list[tuple[FrameRecord, _Answer]] = []
        taken = pairs = 0
        rest: tuple[Chunk, ...] = ()  # chunks taken but not (yet) an exchange from the memo: to ``feed``
        new, set_dict, append = _new, _set_dict, out.append
        new_tuple = tuple.__new__
        try:
            while taken < limit:
                h = next(chunks, None)
                if h is None:
                    break
                taken += 1
                rest = (h,)
                t = h.t
                if (h.dir != HOST or h.error is not None or type(h.data) is not bytes
                        or (t is not None and t - t != 0.0)):
                    break
                entry = memo.get(h.data)
                if entry is None:
                    break
                d = next(chunks, None)
                if d is None:
                    break
                taken += 1
                rest = (h, d)
                if d.dir != DEVICE or d.error is not None or type(d.data) is not bytes:
                    break
                answer = entry.answers.get(d.data)
                if answer is None:
                    break
                td = d.t
                if t is None:
                    if td is not None:
                        break
                    latency = None
                elif td is None or not t <= td <= t + entry.window:  # the engine's deadline, its sum
                    break
                else:
                    latency = td - t
                    if last is None or t > last:  # max(last, t), then max(last, td): as ``_answer``
                        last = t
                    if td > last:
                        last = td
                    if latency <= MAX_LATENCY_S:  # as LatencyStats.add: a latency it counts
                        answer.us.append(round(latency * 1e6))
                rest = ()
                if lean:
                    append(new_tuple(CleanExchange, (entry.host, answer.record, i, t, td, latency)))
                elif clean:  # _clone, twice, inline
                    fields = entry.host.__dict__.copy()
                    fields["i"] = i
                    fields["t"] = fields["t_last"] = t
                    fields["reply_to"] = fields["latency_s"] = None
                    record = new(FrameRecord)
                    set_dict(record, fields)
                    append(record)
                    fields = answer.record.__dict__.copy()
                    fields["i"] = i + 1
                    fields["t"] = fields["t_last"] = td
                    fields["reply_to"] = i
                    fields["latency_s"] = latency
                    record = new(FrameRecord)
                    set_dict(record, fields)
                    append(record)
                if not answer.n:
                    touched.append((entry.host, answer))
                answer.n += 1
                i += 2
                device_last = td
                pairs += 1
                change = answer.change
                if change is not None:
                    change.apply(c.knowledge)
                    self._switch(change)
                    memo = self._memo
        finally:  # the bookkeeping of the exchanges taken, whatever ends the loop
            if pairs:
                c._next_i = i
                c._last_t = last
                c._answer_since = None
                a._device_last = device_last
                self.hits += pairs
                self._changes, self._backoff, self._ticked = 0, BACKOFF, 0
                self._count(touched, pairs)
            for chunk in rest:  # not an exchange from the memo (or the reader failed after it)
                out += a.feed(chunk)
        return taken

    def _count(self, touched: list[tuple[FrameRecord, _Answer]], pairs: int) -> None:
        """The tally and the framers' byte counts of a stretch's ``pairs`` exchanges, as ``feed`` counts
        them one by one (``Tally.add_clean_frame`` of the host record, then of its answer)."""
        tally = self.analyzer.tally
        commands, answers, latencies = tally.commands, tally.answers, tally.latencies
        host_bytes = device_bytes = 0
        for host, answer in touched:
            n, record = answer.n, answer.record
            answer.n = 0
            host_bytes += n * len(host.raw)
            device_bytes += n * len(record.raw)
            command = host.header or "?"
            commands[command] += n
            answers[record.header or "?"] += n
            us = answer.us
            if us:
                answer.us = []
                stats = latencies.get(command)
                if stats is None:
                    stats = latencies[command] = LatencyStats()
                stats.n += len(us)
                histogram = stats._us
                get = histogram.get
                for key in us:
                    histogram[key] = get(key, 0) + 1
        tally.frames[HOST] += pairs
        tally.frames[DEVICE] += pairs
        tally.bytes[HOST] += host_bytes
        tally.bytes[DEVICE] += device_bytes
        self._host._base += host_bytes
        self._device._base += device_bytes

    # ---- the command ----

    def _command(self, chunk: Chunk) -> list[Record]:
        """A host chunk from the quiet state: its record from the memo (held), or the full path,
        observed."""
        a = self.analyzer
        if self._dirty:
            self._select(knowledge_snapshot(self._conversation.knowledge))
        entry: _Entry | readset.Command | None = self._memo.get(chunk.data)
        if entry is None:
            entry = self.reads.command(chunk.data, self._conversation.knowledge)
        if entry is not None:
            i = self._conversation._next_i
            record = _clone(entry.host, i, chunk.t, None, None)
            a.tally.add_clean_frame(record)
            self._held = (chunk, entry, i)
            return [record]
        before = self._snap
        assert before is not None
        with self._tracer.watching(self._conversation.knowledge) as trace:
            out = a._feed(chunk)
        self._dirty = True
        self._observe(chunk, out, before, trace)
        return out

    def _select(self, now: tuple[Any, ...]) -> None:
        """The knowledge is ``now`` (a snapshot just taken): keep the current memo if it is that value's,
        else start afresh (``_fresh``)."""
        self._dirty = False
        if now != self._snap:
            self._fresh(now)

    def _fresh(self, now: tuple[Any, ...]) -> None:
        """The knowledge changed to ``now``. Back to the value before the last (0RS learns the OUT ports,
        0WS establishes them again): its memo, if still kept. Else an empty memo, not yet looked up among
        the kept ones: the look-up (a hash of every fact) waits for the first exchange to memoise, so
        traffic whose every exchange changes the knowledge (new point values written) never pays for it."""
        back = self._previous
        self._previous = (self._snap, self._memo, self._key) if self._registered else None
        self._dirty = False
        self._settled = 0
        if back is not None and back[0] == now and self._memos.get(back[2]) is back[1]:
            memo, key = back[1], back[2]
            self._memos[key] = self._memos.pop(key)  # the most recently used last
            self._snap, self._memo, self._key, self._registered = now, memo, key, True
            return
        self._snap, self._memo, self._key, self._registered = now, {}, None, False

    def _register(self) -> None:
        """The current memo is about to be filled: the kept memo of the same knowledge, if there is one,
        becomes the current one; the least recently used are dropped beyond ``MEMOS``."""
        assert self._snap is not None
        key = _key(self._snap)
        memos = self._memos
        memo = memos.pop(key, None)
        if memo is None:
            memo = self._memo  # empty: nothing is memoised before registering
            if len(memos) >= MEMOS:
                self._drop_oldest()
        memos[key] = memo  # the most recently used last
        self._memo, self._key, self._registered = memo, key, True

    def _drop_oldest(self) -> bool:
        """Forget the least recently used memo, never the current one; False when there is none other."""
        oldest = next(iter(self._memos), None)
        if oldest is None or self._memos[oldest] is self._memo:
            return False
        self._commands -= len(self._memos.pop(oldest))
        return True

    def _observe(self, chunk: Chunk, out: list[Record], before: tuple[Any, ...],
                 trace: readset.Trace) -> None:
        """Watch for the answer of a host chunk the full path judged clean (not a move)."""
        if len(out) == 1:
            record = out[0]
            if (type(record) is FrameRecord and not record.violations and not record.line_errors
                    and record.raw == chunk.data
                    and record.header not in spec.MOVE_HEADERS and record.window_s is not None
                    and not self._host._buf):
                self._observed = (chunk, record, before, trace)

    def _replay(self, held: Held, observe: bool = True) -> None:
        """The held chunk through the full path, as it would have gone; its record is not counted again
        (it was given and counted when the chunk came). Its answer may still fill the memo (``observe``)."""
        a = self.analyzer
        tally = a.tally
        a.tally = self._uncounted
        try:
            if observe:
                with self._tracer.watching(self._conversation.knowledge) as trace:
                    out = a._feed(held[0])
            else:
                a._feed(held[0])
        finally:
            a.tally = tally
        self.replays += 1
        self._dirty = True
        if observe:
            assert self._snap is not None
            self._observe(held[0], out, self._snap, trace)

    # ---- the answer ----

    def _answer(self, held: Held, chunk: Chunk) -> list[Record] | None:
        """The device chunk right after a held command: its record from the memo when it is a memoised
        answer in time, with the full path's bookkeeping done; else None (the caller replays)."""
        if chunk.dir != DEVICE or chunk.error is not None or type(chunk.data) is not bytes:
            return None
        command, entry, i = held
        if type(entry) is not _Entry:
            return self._answer_read(held, chunk)
        answer = entry.answers.get(chunk.data)
        if answer is None:
            return None
        latency = _latency(command.t, chunk.t, entry.window)
        if latency is _LATE:
            return None
        record = self._answered(command, chunk, answer.record, i, latency)  # type: ignore[arg-type]
        change = answer.change
        if change is not None:
            change.apply(self._conversation.knowledge)
            self._switch(change)
        return [record]

    def _answered(self, command: Chunk, chunk: Chunk, template: FrameRecord, i: int,
                  latency: float | None) -> FrameRecord:
        """The record of an answer from a memo (``template``), with what the full path would have done for
        the command and its answer: the two events numbered, time passed to the command's time then the
        answer's (the engine's tick, twice each: idempotent), the answer no longer arriving, the framers'
        byte counts, the device's last time, the tally."""
        t_host, t = command.t, chunk.t
        record = _clone(template, i + 1, t, i, latency)
        c = self._conversation
        c._next_i = i + 2
        if t is not None and t_host is not None:
            last = c._last_t
            last = t_host if last is None else max(last, t_host)
            c._last_t = max(last, t)
        c._answer_since = None
        self._host._base += len(command.data)
        self._device._base += len(chunk.data)
        self.analyzer._device_last = t
        self.analyzer.tally.add_clean_frame(record)
        self.hits += 1
        self._changes, self._backoff, self._ticked = 0, BACKOFF, 0
        return record

    def _answer_read(self, held: Held, chunk: Chunk) -> list[Record] | None:
        """``_answer`` for a command from the reads memo: the answer's record when the reads memo holds
        these bytes for the knowledge as it is, in time; what it wrote is written, and the exchange is
        memoised by the whole knowledge (``_learn``) when its memo holds exchanges or the knowledge has
        settled (``SETTLED``), so that its next time takes the plain memo."""
        command, entry, i = held
        assert isinstance(entry, readset.Command)
        c = self._conversation
        answer = entry.answer(chunk.data, c.knowledge)
        if answer is None:
            return None
        latency = _latency(command.t, chunk.t, entry.window)
        if latency is _LATE:
            return None
        t_host = command.t
        before = self._snap
        assert before is not None
        record = self._answered(command, chunk, answer.record, i, latency)  # type: ignore[arg-type]
        self.reads.hits += 1
        answer.writes.apply(c.knowledge)
        self._settled += 1
        if self._registered or self._settled >= SETTLED:
            host = _clone(entry.host, i, t_host, None, None)
            self._learn((command, host, before, None), chunk, [record], None)
        else:
            self._dirty = True  # the writes may have changed the knowledge: the next command looks
        return [record]

    def _learn(self, observed: tuple[Chunk, FrameRecord, tuple[Any, ...], readset.Trace | None], chunk: Chunk,
               out: list[Record], answered: readset.Trace | None) -> None:
        """After the chunk right after an observed command was fed (or answered from the reads memo:
        ``answered`` None): memoise the exchange when it is clean and leaves the engine quiet, with the
        change it made to the knowledge; and, traced, keep it in the reads memo."""
        self._dirty = True
        if len(out) != 1 or chunk.dir != DEVICE or chunk.error is not None or type(chunk.data) is not bytes:
            return
        command, host, before, asked = observed
        record = out[0]
        t_host, t = command.t, chunk.t
        if (t_host is None) != (t is None) or (t is not None and t_host is not None and not t_host <= t):
            return
        c = self._conversation
        if not (type(record) is FrameRecord and not record.violations and not record.line_errors
                and record.reply_to == host.i
                and record.raw == chunk.data and not c._queue and c._motion is None
                and not c._unreset_alarm and not self._device._buf and self.analyzer._device_since is None
                and not self._errors[HOST] and not self._errors[DEVICE]):
            return
        after = knowledge_snapshot(c.knowledge)
        if asked is not None and answered is not None:
            self.reads.keep(command.data, host, asked, chunk.data, record, answered, before, after)
        change = None
        if after != before:
            self._changes += 1
            if self._changes >= CHANGES:
                self._changes, self.skip = 0, self._backoff
                self._backoff = min(2 * self._backoff, BACKOFF_MAX)
                self._fresh(after)
                self._dirty = True  # for when the lane steps back
                return
            change = _Change(before, after)
        else:
            self._changes, self._backoff = 0, BACKOFF
        self._dirty = False
        self._store(command.data, host, chunk.data, record, change)
        if change is not None:
            self._fresh(after)  # as a knowledge change the full path made (no key made yet)

    def _store(self, command: bytes, host: FrameRecord, data: bytes, record: FrameRecord,
               change: _Change | None) -> None:
        """Memoise an exchange in the current memo (the knowledge it went in with), within the bounds."""
        if not self._registered:
            self._register()
        assert host.window_s is not None
        entry = self._memo.get(command)
        if entry is None:
            while self._commands >= COMMANDS:
                if not self._drop_oldest():
                    return
            entry = self._memo[command] = _Entry(host, host.window_s)
            self._commands += 1
        if len(entry.answers) < ANSWERS:
            entry.answers[data] = _Answer(record, change)

    def _switch(self, change: _Change) -> None:
        """The knowledge became ``change.after`` (an exchange changed it): its memo is current, the kept
        one if there is one (most recently used now), else an empty one (``_fresh``)."""
        key = change.key
        if key is None:
            key = change.key = _key(change.after)
        memos = self._memos
        memo = memos.pop(key, None)
        if memo is None:
            self._fresh(change.after)
            return
        memos[key] = memo
        self._previous = (self._snap, self._memo, self._key) if self._registered else None
        self._snap, self._memo, self._key, self._registered = change.after, memo, key, True
        self._dirty = False
