"""What the analyzer reports: one record per frame, per junk run and per missed answer, then a summary.

The records serialise to the pinned JSON lines schema (docs/output.md): ``FrameRecord`` ->
``{"type":"frame",...}``, ``JunkRecord`` -> ``{"type":"junk",...}``, ``TimeoutRecord`` ->
``{"type":"timeout",...}`` (the one violation that no frame carries: ``no-answer``), and the ``Tally``
that counts them gives the last line, ``{"type":"summary",...}``. Every record's ``sides`` lists, aligned
with ``violations``, whose fault each is (``host`` or ``device``: ``spec.VIOLATION_TABLE[code].side``);
the summary counts violations by side too (``by_side``). Records are inert data; the analyzer
builds them and the views print them.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from xac1_proto import Frame, spec
from xac1_proto.chunk import Direction

_FIELD_NAMES: dict[type, tuple[str, ...]] = {}  # frame class -> its field names (Frame.fields' order)


def _round_t(t: float | None) -> float | None:
    return None if t is None else round(t, 6)


def _ms(seconds: float | None) -> float | None:
    return None if seconds is None else round(seconds * 1000.0, 3)


def _with_notes(out: dict[str, Any], details: tuple[str, ...],
                line_errors: tuple[str, ...]) -> dict[str, Any]:
    """Add the optional keys of frame and junk records: ``details`` and ``line_errors``."""
    if details:
        out["details"] = list(details)
    if line_errors:
        out["line_errors"] = list(line_errors)
    return out


@dataclass(frozen=True)
class FrameRecord:
    """A frame seen on one line. ``i``: position among frame and junk records; ``t``: time of its first
    byte; ``header``: the spec header it was read as (a letter O read as the digit), None when unknown;
    ``frame``: the lenient decode (None when a field could not be read); ``violations``: codes, each once;
    ``details``: one human sentence per violation; ``reply_to``/``latency_ms``: on device frames, the
    command answered and the time from its last byte to this frame's first byte."""

    i: int
    t: float | None
    dir: Direction
    raw: bytes
    header: str | None
    frame: Frame | None
    violations: tuple[spec.ViolationCode, ...] = ()
    details: tuple[str, ...] = ()
    reply_to: int | None = None
    latency_s: float | None = None
    t_last: float | None = None
    line_errors: tuple[str, ...] = ()
    sides: tuple[spec.Side, ...] = ()
    window_s: float | None = None  # host frames: the answer window the rulebook gave it (not in JSON)

    type = "frame"

    @property
    def fields(self) -> dict[str, Any] | None:
        """``frame.fields()``: the field values by name in wire order (names looked up once a class)."""
        frame = self.frame
        if frame is None:
            return None
        names = _FIELD_NAMES.get(type(frame))
        if names is None:
            names = _FIELD_NAMES[type(frame)] = tuple(f.name for f in dataclasses.fields(frame))
        return {name: getattr(frame, name) for name in names}

    @property
    def latency_ms(self) -> float | None:
        return _ms(self.latency_s)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "frame", "i": self.i, "t": _round_t(self.t), "dir": self.dir,
                               "raw": self.raw.hex(), "header": self.header, "fields": self.fields,
                               "violations": list(self.violations), "sides": _sides(self)}
        if self.dir == "device":
            out["reply_to"] = self.reply_to
            out["latency_ms"] = self.latency_ms
        return _with_notes(out, self.details, self.line_errors)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


CAPTURE_ENDED = "capture-ended"  # JunkRecord.reason: the data ended inside this frame (no violation)


@dataclass(frozen=True)
class JunkRecord:
    """Bytes that form no frame (the ``garbage`` violation). ``reason`` is the framer's:
    ``no-frame-start``, ``truncated``, ``overflow``, ``flushed``; or ``capture-ended``: the data (a capture
    file, a proxy stopped) ended inside this frame, which is no one's fault: no violation, and on device
    bytes ``reply_to`` names the command whose answer was cut."""

    i: int
    t: float | None
    dir: Direction
    raw: bytes
    reason: str
    violations: tuple[spec.ViolationCode, ...] = ("garbage",)
    details: tuple[str, ...] = ()
    line_errors: tuple[str, ...] = ()
    sides: tuple[spec.Side, ...] = ()
    reply_to: int | None = None  # device junk inside a command's answer window: its garbled answer
    latency_s: float | None = None

    type = "junk"

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "junk", "i": self.i, "t": _round_t(self.t), "dir": self.dir,
                               "raw": self.raw.hex(), "violations": list(self.violations),
                               "sides": _sides(self), "reason": self.reason}
        if self.reply_to is not None:
            out["reply_to"] = self.reply_to
            out["latency_ms"] = _ms(self.latency_s)
        return _with_notes(out, self.details, self.line_errors)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


@dataclass(frozen=True)
class TimeoutRecord:
    """A command that got no answer in time (``no-answer``), reported when its deadline passed.
    ``command``: the command's ``i``; ``t``: the deadline (None when the source has no time and the
    verdict came at the end of the data); ``waited_s``: the timeout applied (None without time)."""

    command: int
    t: float | None
    header: str | None
    waited_s: float | None
    details: tuple[str, ...] = ()
    violations: tuple[spec.ViolationCode, ...] = ("no-answer",)
    dir: Direction = "host"
    sides: tuple[spec.Side, ...] = ()

    type = "timeout"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "timeout", "t": _round_t(self.t), "dir": self.dir, "command": self.command,
                "header": self.header, "waited_ms": _ms(self.waited_s),
                "violations": list(self.violations), "sides": _sides(self), "details": list(self.details)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


Record = FrameRecord | JunkRecord | TimeoutRecord


class CleanExchange(NamedTuple):
    """A clean command and its clean answer, answered from the fast lane's memo, that
    ``Analyzer.feed_many(lean=True)`` gives instead of their two records (an output of JSON lines needs
    none: ``JsonlView`` prints them from the memo's records): ``host`` and ``answer`` are the records they
    would be made from, the rest what differs; ``records()`` makes the two records."""

    host: FrameRecord
    answer: FrameRecord
    i: int
    t: float | None
    t_answer: float | None
    latency_s: float | None

    def records(self) -> tuple[FrameRecord, FrameRecord]:
        """The two records ``Analyzer.feed`` gives for this exchange."""
        i = self.i
        return (dataclasses.replace(self.host, i=i, t=self.t, t_last=self.t, reply_to=None, latency_s=None),
                dataclasses.replace(self.answer, i=i + 1, t=self.t_answer, t_last=self.t_answer, reply_to=i,
                                    latency_s=self.latency_s))


_MAX_LATENCY_S = 1e6  # a latency beyond this comes from damaged times and is not counted


def sides_of(record: Record) -> tuple[spec.Side, ...]:
    """Whose fault each violation of ``record`` is, aligned with ``record.violations``."""
    if len(record.sides) == len(record.violations):
        return record.sides
    sender: spec.Side = "device" if record.dir == "device" else "host"
    return tuple(spec.VIOLATION_TABLE[c].side(sender) for c in record.violations)


def _sides(record: Record) -> list[str]:
    return list(sides_of(record))


_MAX_WAITING = 4096  # commands the tally remembers while they wait for an answer


@dataclass
class LatencyStats:
    """Count, min, median and max of latencies in bounded memory: a histogram of whole microseconds (the
    summary shows 1 us, so the median is exact), whose size grows with distinct values, not answers."""

    n: int = 0
    _us: Counter[int] = field(default_factory=Counter)

    def add(self, seconds: float) -> None:
        if not math.isfinite(seconds) or abs(seconds) > _MAX_LATENCY_S:
            return  # a damaged time, not a latency
        self.n += 1
        self._us[round(seconds * 1e6)] += 1

    def _nth(self, k: int, keys: list[int]) -> int:
        """The k-th smallest value (0-based), in microseconds."""
        seen = 0
        for key in keys:
            seen += self._us[key]
            if seen > k:
                return key
        raise IndexError(k)

    def stats_ms(self) -> dict[str, float | int]:
        keys = sorted(self._us)
        mid = (self._nth((self.n - 1) // 2, keys) + self._nth(self.n // 2, keys)) / 2
        return {"n": self.n, "min": keys[0] / 1000, "median": round(mid / 1000, 3), "max": keys[-1] / 1000}


@dataclass
class Tally:
    """Counts records as they go by; ``summary()`` is the schema's last line."""

    frames: Counter[str] = field(default_factory=Counter)  # by direction
    junk: int = 0
    bytes: Counter[str] = field(default_factory=Counter)  # by direction, frames and junk
    violations: Counter[str] = field(default_factory=Counter)
    by_side: dict[str, Counter[str]] = field(default_factory=lambda: {"host": Counter(), "device": Counter()})
    commands: Counter[str] = field(default_factory=Counter)  # host frames by header ("?" unknown)
    answers: Counter[str] = field(default_factory=Counter)  # device frames by header
    latencies: dict[str, LatencyStats] = field(default_factory=dict)  # by command header
    line_errors: int = 0  # frame and junk records carrying a line error
    unanswered: int = 0  # commands still waiting at the end with no verdict (capture cut short)
    _headers: dict[int, str] = field(default_factory=dict)  # host frame i -> header

    def add(self, record: Record) -> None:
        if record.violations:  # most records have none: skip the counters' per-call overhead
            self.violations.update(record.violations)
            for code, side in zip(record.violations, sides_of(record), strict=True):
                self.by_side[side][code] += 1
        if isinstance(record, FrameRecord):
            self.line_errors += bool(record.line_errors)
            self.add_clean_frame(record)
        elif isinstance(record, JunkRecord):
            self.junk += record.reason != CAPTURE_ENDED
            self.bytes[record.dir] += len(record.raw)
            self.line_errors += bool(record.line_errors)

    def add_clean_frame(self, record: FrameRecord) -> None:
        """``add`` for a frame record with no violation and no line error (the analyzer's fast lane
        gives only those; ``add`` counts every frame record's frame, header and latency here)."""
        direction = record.dir
        self.frames[direction] += 1
        self.bytes[direction] += len(record.raw)
        header = record.header or "?"
        if direction == "host":
            self.commands[header] += 1
            self._headers[record.i] = header
            if len(self._headers) > _MAX_WAITING:  # commands never answered: forget the oldest
                del self._headers[next(iter(self._headers))]
            return
        self.answers[header] += 1
        if record.reply_to is not None:
            command = self._headers.pop(record.reply_to, "?")
            if record.latency_s is not None:
                stats = self.latencies.get(command)
                if stats is None:
                    stats = self.latencies[command] = LatencyStats()
                stats.add(record.latency_s)

    def latency_stats(self) -> dict[str, dict[str, float | int]]:
        """Per command header: count, min, median, max latency in ms."""
        return {header: self.latencies[header].stats_ms() for header in sorted(self.latencies)
                if self.latencies[header].n}

    def summary(self) -> dict[str, Any]:
        ordered = sorted(self.violations.items(), key=lambda kv: list(spec.VIOLATIONS).index(kv[0])
                         if kv[0] in spec.VIOLATIONS else len(spec.VIOLATIONS))
        return {"type": "summary",
                "frames": {"host": self.frames["host"], "device": self.frames["device"]},
                "junk": self.junk,
                "violations": dict(ordered),
                "by_side": {side: {c: self.by_side[side][c] for c, _ in ordered if self.by_side[side][c]}
                            for side in ("host", "device")},
                "bytes": {"host": self.bytes["host"], "device": self.bytes["device"]},
                "commands": dict(sorted(self.commands.items())),
                "answers": dict(sorted(self.answers.items())),
                "latency_ms": self.latency_stats(),
                "line_errors": self.line_errors,
                "unanswered": self.unanswered}


def summary_json(summary: dict[str, Any]) -> str:
    return json.dumps(summary, separators=(",", ":"))
